/* SPDX-License-Identifier: BSD-3-Clause */
/* What the tests of core's own photo readers (test_photo_jpeg.c,
 * test_photo_tiff.c) share: pixels compared to the bit, and stderr caught
 * in a file while a decoder runs (libjpeg and libtiff print by default). */
#ifndef SETLIGHT_TEST_PHOTO_COMMON_H
#define SETLIGHT_TEST_PHOTO_COMMON_H

#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "../core/photo_private.h"
#include "testing.h"

static inline bool photo_same_pixels(const sl_image *a, const sl_image *b)
{
    return a->width == b->width && a->height == b->height && a->channels == b->channels &&
           a->data && b->data &&
           memcmp(a->data, b->data,
                  sizeof(float) * (size_t)a->width * (size_t)a->height * (size_t)a->channels) == 0;
}

/* name written with the first `keep` bytes, then read: refused as
 * SL_ERR_INPUT with one line naming the file and saying `what`, nothing
 * returned, OpenImageIO not started to say so. */
static inline void photo_check_refused(const char *name, const char *bytes, size_t keep,
                                       const char *what)
{
    sl_error err;
    const char *path = sl_test_path(name);
    CHECK_OK(sl_write_file_atomic(path, bytes, keep, &err), &err);
    sl_image img;
    sl_meta meta;
    int before = sl_oiio_start_count();
    memset(&err, 0, sizeof err);
    CHECK_RESULT(sl_photo_read(path, &img, &meta, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, path) && strstr(err.message, what) &&
                  !strchr(err.message, '\n'),
              "%s: %s", name, err.message);
    CHECK(img.data == NULL && meta.attrs == NULL);
    CHECK(sl_oiio_start_count() == before);
}

typedef struct stderr_catch {
    int saved;
    FILE *caught;
} stderr_catch;

/* From here on, stderr goes to the test's stderr.txt. */
static inline stderr_catch stderr_catch_begin(void)
{
    fflush(stderr);
    stderr_catch c = {dup(2), freopen(sl_test_path("stderr.txt"), "w", stderr)};
    return c;
}

/* stderr back; what was printed meanwhile (free it), *printed its length. */
static inline char *stderr_catch_end(stderr_catch *c, size_t *printed)
{
    fflush(stderr);
    if (c->caught)
        dup2(c->saved, 2);
    close(c->saved);
    *printed = 0;
    return sl_test_read_file(sl_test_path("stderr.txt"), printed);
}

#endif
