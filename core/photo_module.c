/* SPDX-License-Identifier: BSD-3-Clause */
/* OpenImageIO's photo calls (photo_private.h's sl_oiio_*, and DWA EXR
 * pixels) forward to core/photo_cxx.cpp, built as the setlight_oiio module
 * and loaded on the first call: linked in, OpenImageIO's ~260 libraries
 * cost every process ~0.3 s of CPU at start-up binding their symbols,
 * whether it reads a photo or not. The module calls back into core through
 * the executable's exported symbols. Sanitizer builds link photo_cxx.cpp
 * in (SETLIGHT_OIIO_MODULE undefined): the same calls, no loading. */
#include "setlight/core.h"
#include "exr_oiio.h"
#include "photo_private.h"

#include <pthread.h>
#include <stdio.h>
#include <string.h>

#ifdef SETLIGHT_OIIO_MODULE
#include <dlfcn.h>
#endif

typedef struct oiio_api {
    sl_result (*read)(const char *, sl_image *, sl_meta *, sl_error *);
    sl_result (*read_meta)(const char *, sl_meta *, int *, int *, int *, sl_error *);
    sl_result (*write)(const char *, const sl_image *, const sl_meta *, int, sl_error *);
    sl_result (*exr_pixels)(const char *, const char *const *, int, int, int, sl_image *,
                            sl_error *);
    sl_result (*strips_open)(const char *, sl_oiio_strips **, sl_photo_strip_info *, sl_error *);
    sl_result (*strips_read)(sl_oiio_strips *, int, int, float *, sl_error *);
    sl_result (*strips_read_codes)(sl_oiio_strips *, int, int, void *, sl_error *);
    void (*strips_close)(sl_oiio_strips *);
} oiio_api;
static oiio_api api;
static char load_error[512];
static pthread_once_t load_once = PTHREAD_ONCE_INIT;
static int start_count;

int sl_oiio_start_count(void) { return start_count; }

#ifdef SETLIGHT_OIIO_MODULE

/* What the module uses from core, so that every executable that can load
 * it has (and exports) these. */
__attribute__((used)) static const void *const module_needs[] = {
    (const void *)sl_atomic_abort,  (const void *)sl_atomic_begin,
    (const void *)sl_atomic_commit, (const void *)sl_check_input_file,
    (const void *)sl_color_space_name, (const void *)sl_error_set,
    (const void *)sl_image_alloc,   (const void *)sl_image_free,
    (const void *)sl_meta_free,     (const void *)sl_meta_init,
    (const void *)sl_meta_set,      (const void *)sl_memory_check,
    (const void *)sl_icc_linear_rec709, (const void *)sl_icc_linear_space,
};

static void load(void)
{
    start_count++;
    sl_log(SL_LOG_DEBUG, "starting OpenImageIO (%s)", SETLIGHT_OIIO_MODULE);
    void *h = sl_module_open(SETLIGHT_OIIO_MODULE);
    if (!h) {
        const char *why = dlerror();
        snprintf(load_error, sizeof load_error, "%s", why ? why : SETLIGHT_OIIO_MODULE);
        return;
    }
    /* dlsym returns void *; POSIX guarantees it converts to a function pointer. */
#define SYM(field, name) *(void **)&api.field = dlsym(h, name)
    SYM(read, "sl_oiio_module_read");
    SYM(read_meta, "sl_oiio_module_read_meta");
    SYM(write, "sl_oiio_module_write");
    SYM(exr_pixels, "sl_oiio_module_exr_pixels");
    SYM(strips_open, "sl_oiio_module_strips_open");
    SYM(strips_read, "sl_oiio_module_strips_read");
    SYM(strips_read_codes, "sl_oiio_module_strips_read_codes");
    SYM(strips_close, "sl_oiio_module_strips_close");
#undef SYM
    if (!api.read || !api.read_meta || !api.write || !api.exr_pixels || !api.strips_open ||
        !api.strips_read || !api.strips_read_codes || !api.strips_close) {
        snprintf(load_error, sizeof load_error, "%s: entry points missing", SETLIGHT_OIIO_MODULE);
        memset(&api, 0, sizeof api);
    }
}

#else /* photo_cxx.cpp linked in, under these names (CMakeLists.txt) */

sl_result sl_oiio_module_read(const char *, sl_image *, sl_meta *, sl_error *);
sl_result sl_oiio_module_read_meta(const char *, sl_meta *, int *, int *, int *, sl_error *);
sl_result sl_oiio_module_write(const char *, const sl_image *, const sl_meta *, int, sl_error *);
sl_result sl_oiio_module_exr_pixels(const char *, const char *const *, int, int, int, sl_image *,
                                    sl_error *);
sl_result sl_oiio_module_strips_open(const char *, sl_oiio_strips **, sl_photo_strip_info *,
                                     sl_error *);
sl_result sl_oiio_module_strips_read(sl_oiio_strips *, int, int, float *, sl_error *);
sl_result sl_oiio_module_strips_read_codes(sl_oiio_strips *, int, int, void *, sl_error *);
void sl_oiio_module_strips_close(sl_oiio_strips *);

static void load(void)
{
    static const oiio_api linked = {
        sl_oiio_module_read,        sl_oiio_module_read_meta,   sl_oiio_module_write,
        sl_oiio_module_exr_pixels,  sl_oiio_module_strips_open, sl_oiio_module_strips_read,
        sl_oiio_module_strips_read_codes, sl_oiio_module_strips_close,
    };
    start_count++;
    api = linked;
}

#endif

/* Loads the module once; false with err set when it cannot be. */
static bool loaded(const char *path, sl_error *err)
{
    pthread_once(&load_once, load);
    if (api.read)
        return true;
    sl_error_set(err, SL_ERR_UNSUPPORTED, "%s: cannot load the OpenImageIO module (%s)",
                 path ? path : "(null)", load_error);
    return false;
}

sl_result sl_oiio_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    if (loaded(path, err))
        return api.read(path, img, meta, err);
    memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    return SL_ERR_UNSUPPORTED;
}

sl_result sl_oiio_read_meta(const char *path, sl_meta *meta, int *width, int *height,
                             int *channels, sl_error *err)
{
    /* Unloaded, the outputs stay as core/photo.c set them: nothing read. */
    return loaded(path, err) ? api.read_meta(path, meta, width, height, channels, err)
                             : SL_ERR_UNSUPPORTED;
}

sl_result sl_oiio_write(const char *path, const sl_image *img, const sl_meta *meta, int bits,
                         sl_error *err)
{
    return loaded(path, err) ? api.write(path, img, meta, bits, err) : SL_ERR_UNSUPPORTED;
}

sl_result sl_exr_read_pixels_oiio(const char *path, const char *const *names, int count, int x0,
                                  int y0, sl_image *img, sl_error *err)
{
    return loaded(path, err) ? api.exr_pixels(path, names, count, x0, y0, img, err)
                             : SL_ERR_UNSUPPORTED;
}

sl_result sl_oiio_strips_open(const char *path, sl_oiio_strips **strips,
                               sl_photo_strip_info *info, sl_error *err)
{
    if (loaded(path, err))
        return api.strips_open(path, strips, info, err);
    *strips = NULL;
    memset(info, 0, sizeof *info);
    return SL_ERR_UNSUPPORTED;
}

/* Strips exist only once the module is loaded. */
sl_result sl_oiio_strips_read(sl_oiio_strips *strips, int y0, int y1, float *rgb, sl_error *err)
{
    return api.strips_read(strips, y0, y1, rgb, err);
}

sl_result sl_oiio_strips_read_codes(sl_oiio_strips *strips, int y0, int y1, void *rgb,
                                     sl_error *err)
{
    return api.strips_read_codes(strips, y0, y1, rgb, err);
}

void sl_oiio_strips_close(sl_oiio_strips *strips)
{
    if (strips)
        api.strips_close(strips);
}
