/* SPDX-License-Identifier: BSD-3-Clause */
/* The photo calls (sl_photo_*, DWA EXR pixels) forward to the OpenImageIO
 * module (core/photo_cxx.cpp built as setlight_oiio), loaded on the first
 * call: linked in, OpenImageIO's ~260 libraries cost every process ~0.3 s
 * of CPU at start-up binding their symbols, whether it reads a photo or
 * not. The module calls back into core through the executable's exported
 * symbols. */
#include "setlight/core.h"
#include "exr_oiio.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#ifndef SETLIGHT_OIIO_MODULE
#error "SETLIGHT_OIIO_MODULE: path of the setlight_oiio module"
#endif

static struct {
    sl_result (*read)(const char *, sl_image *, sl_meta *, sl_error *);
    sl_result (*read_meta)(const char *, sl_meta *, int *, int *, int *, sl_error *);
    sl_result (*write)(const char *, const sl_image *, const sl_meta *, int, sl_error *);
    sl_result (*exr_pixels)(const char *, const char *const *, int, int, int, sl_image *,
                            sl_error *);
    sl_result (*strips_open)(const char *, sl_photo_strips **, sl_photo_strip_info *, sl_error *);
    sl_result (*strips_read)(sl_photo_strips *, int, int, float *, sl_error *);
    sl_result (*strips_read_codes)(sl_photo_strips *, int, int, void *, sl_error *);
    void (*strips_close)(sl_photo_strips *);
} api;
static char load_error[512];
static pthread_once_t load_once = PTHREAD_ONCE_INIT;

/* What the module uses from core, so that every executable that can load
 * it has (and exports) these. */
__attribute__((used)) static const void *const module_needs[] = {
    (const void *)sl_atomic_abort,  (const void *)sl_atomic_begin,
    (const void *)sl_atomic_commit, (const void *)sl_check_input_file,
    (const void *)sl_color_space_name, (const void *)sl_error_set,
    (const void *)sl_image_alloc,   (const void *)sl_image_free,
    (const void *)sl_meta_free,     (const void *)sl_meta_init,
    (const void *)sl_meta_set,
};

/* The module next to the executable (a build tree or an install moved as a
 * whole: setlight in build/, tests in build/tests/), else where it was built. */
static void *open_module(void)
{
    const char *base = strrchr(SETLIGHT_OIIO_MODULE, '/');
    base = base ? base + 1 : SETLIGHT_OIIO_MODULE;
    char exe[4096];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    char *slash = n > 0 ? (exe[n] = 0, strrchr(exe, '/')) : NULL;
    if (slash) {
        *slash = 0;
        const char *const rel[] = {"", "/.."};
        for (int i = 0; i < 2; i++) {
            char path[4400];
            snprintf(path, sizeof path, "%s%s/%s", exe, rel[i], base);
            void *h = access(path, R_OK) == 0 ? dlopen(path, RTLD_NOW | RTLD_LOCAL) : NULL;
            if (h)
                return h;
        }
    }
    return dlopen(SETLIGHT_OIIO_MODULE, RTLD_NOW | RTLD_LOCAL);
}

static void load(void)
{
    void *h = open_module();
    if (!h) {
        const char *why = dlerror();
        snprintf(load_error, sizeof load_error, "%s", why ? why : SETLIGHT_OIIO_MODULE);
        return;
    }
    /* dlsym returns void *; POSIX guarantees it converts to a function pointer. */
#define SYM(field, name) *(void **)&api.field = dlsym(h, name)
    SYM(read, "sl_oiio_photo_read");
    SYM(read_meta, "sl_oiio_photo_read_meta");
    SYM(write, "sl_oiio_photo_write");
    SYM(exr_pixels, "sl_oiio_exr_read_pixels");
    SYM(strips_open, "sl_oiio_strips_open");
    SYM(strips_read, "sl_oiio_strips_read");
    SYM(strips_read_codes, "sl_oiio_strips_read_codes");
    SYM(strips_close, "sl_oiio_strips_close");
#undef SYM
    if (!api.read || !api.read_meta || !api.write || !api.exr_pixels || !api.strips_open ||
        !api.strips_read || !api.strips_read_codes || !api.strips_close) {
        snprintf(load_error, sizeof load_error, "%s: entry points missing", SETLIGHT_OIIO_MODULE);
        memset(&api, 0, sizeof api);
    }
}

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

sl_result sl_photo_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    if (loaded(path, err))
        return api.read(path, img, meta, err);
    memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    return SL_ERR_UNSUPPORTED;
}

sl_result sl_photo_read_meta(const char *path, sl_meta *meta, int *width, int *height,
                             int *channels, sl_error *err)
{
    if (loaded(path, err))
        return api.read_meta(path, meta, width, height, channels, err);
    if (meta)
        sl_meta_init(meta);
    if (width)
        *width = 0;
    if (height)
        *height = 0;
    if (channels)
        *channels = 0;
    return SL_ERR_UNSUPPORTED;
}

sl_result sl_photo_write(const char *path, const sl_image *img, const sl_meta *meta, int bits,
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

sl_result sl_photo_strips_open(const char *path, sl_photo_strips **strips,
                               sl_photo_strip_info *info, sl_error *err)
{
    if (loaded(path, err))
        return api.strips_open(path, strips, info, err);
    *strips = NULL;
    memset(info, 0, sizeof *info);
    return SL_ERR_UNSUPPORTED;
}

/* Strips exist only once the module is loaded. */
sl_result sl_photo_strips_read(sl_photo_strips *strips, int y0, int y1, float *rgb, sl_error *err)
{
    return api.strips_read(strips, y0, y1, rgb, err);
}

sl_result sl_photo_strips_read_codes(sl_photo_strips *strips, int y0, int y1, void *rgb,
                                     sl_error *err)
{
    return api.strips_read_codes(strips, y0, y1, rgb, err);
}

void sl_photo_strips_close(sl_photo_strips *strips)
{
    if (strips)
        api.strips_close(strips);
}
