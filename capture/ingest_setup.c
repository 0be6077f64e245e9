/* SPDX-License-Identifier: BSD-3-Clause */
/* What the frames of one bracket must share to merge: the camera body, the
 * lens and its focal length, and the picture's size, orientation and
 * encoding. Ingest groups frames of one setup only, and says why two
 * setups were kept apart. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "capture_private.h"

static void copy_trimmed(char *dst, size_t size, const char *src)
{
    while (*src == ' ')
        src++;
    size_t n = strlen(src);
    while (n > 0 && src[n - 1] == ' ')
        n--;
    if (n >= size)
        n = size - 1;
    memcpy(dst, src, n);
    dst[n] = 0;
}

void sl_frame_setup_fill(sl_frame_setup *s, const sl_meta *meta, const sl_exif_extra *extra,
                         int width, int height)
{
    memset(s, 0, sizeof *s);
    copy_trimmed(s->make, sizeof s->make, meta->make);
    copy_trimmed(s->model, sizeof s->model, meta->model);
    copy_trimmed(s->serial, sizeof s->serial, extra->serial);
    copy_trimmed(s->lens, sizeof s->lens, meta->lens[0] ? meta->lens : extra->lens);
    copy_trimmed(s->lens_serial, sizeof s->lens_serial, extra->lens_serial);
    s->focal_mm = isfinite(meta->focal_length_mm) && meta->focal_length_mm > 0
                      ? meta->focal_length_mm
                      : 0;
    s->width = width;
    s->height = height;
    s->orientation = meta->orientation;
    copy_trimmed(s->format, sizeof s->format, meta->format);
    s->bits = meta->bits_per_sample;
    s->is_float = meta->is_float;
}

/* Appends "; " and a formatted part to buf. */
static void add(char *buf, size_t size, const char *fmt, const char *a, const char *b)
{
    size_t n = strlen(buf);
    if (n + 1 >= size)
        return;
    snprintf(buf + n, size - n, "%s", n ? "; " : "");
    n = strlen(buf);
    snprintf(buf + n, size - n, fmt, a, b);
}

static const char *or_none(const char *s)
{
    return s[0] ? s : "none";
}

/* 'text', or none when empty. */
static const char *quoted(char *buf, size_t size, const char *s)
{
    snprintf(buf, size, s[0] ? "'%s'" : "none", s);
    return buf;
}

/* The camera as people name it: the model, with the make when the model
 * does not start with it ("Canon EOS REBEL T2i", "NIKON CORPORATION D850"). */
static void camera_name(char *buf, size_t size, const sl_frame_setup *s)
{
    if (!s->make[0] || !strncasecmp(s->model, s->make, strlen(s->make)))
        snprintf(buf, size, "%s", s->model);
    else
        snprintf(buf, size, "%s %s", s->make, s->model);
}

/* EXIF orientations 5..8 turn the picture a quarter: its width is the
 * stored height. */
static bool turned(int orientation)
{
    return orientation >= 5 && orientation <= 8;
}

bool sl_frame_setup_differs(const sl_frame_setup *a, const sl_frame_setup *b, char *why,
                            size_t size)
{
    why[0] = 0;
    char x[160], y[160], qx[164], qy[164];
    if (strcasecmp(a->make, b->make) || strcasecmp(a->model, b->model)) {
        camera_name(x, sizeof x, a);
        camera_name(y, sizeof y, b);
        add(why, size, "camera %s vs %s", quoted(qx, sizeof qx, x), quoted(qy, sizeof qy, y));
    }
    if (strcmp(a->serial, b->serial))
        add(why, size, "body serial %s vs %s", or_none(a->serial), or_none(b->serial));
    if (strcmp(a->lens, b->lens))
        add(why, size, "lens %s vs %s", quoted(qx, sizeof qx, a->lens),
            quoted(qy, sizeof qy, b->lens));
    if (strcmp(a->lens_serial, b->lens_serial))
        add(why, size, "lens serial %s vs %s", or_none(a->lens_serial), or_none(b->lens_serial));
    if (a->focal_mm > 0 && b->focal_mm > 0 &&
        fabs(a->focal_mm - b->focal_mm) > 0.01 * fmax(a->focal_mm, b->focal_mm)) {
        snprintf(x, sizeof x, "%g", a->focal_mm);
        snprintf(y, sizeof y, "%g", b->focal_mm);
        add(why, size, "focal length %s vs %s mm", x, y);
    }
    if (a->width != b->width || a->height != b->height) {
        snprintf(x, sizeof x, "%dx%d", a->width, a->height);
        snprintf(y, sizeof y, "%dx%d", b->width, b->height);
        bool same_picture = turned(a->orientation) != turned(b->orientation) &&
                            a->width == b->height && a->height == b->width;
        add(why, size,
            same_picture ? "image size %s vs %s (one turned in camera)"
                         : "image size %s vs %s",
            x, y);
    }
    if (a->orientation != b->orientation) {
        snprintf(x, sizeof x, "%d", a->orientation);
        snprintf(y, sizeof y, "%d", b->orientation);
        add(why, size, "EXIF orientation %s vs %s", x, y);
    }
    if (strcasecmp(a->format, b->format))
        add(why, size, "file format %s vs %s", or_none(a->format), or_none(b->format));
    else if (a->bits != b->bits || a->is_float != b->is_float) {
        snprintf(x, sizeof x, "%d-bit%s", a->bits, a->is_float ? " float" : "");
        snprintf(y, sizeof y, "%d-bit%s", b->bits, b->is_float ? " float" : "");
        add(why, size, "samples %s vs %s", x, y);
    }
    return why[0] != 0;
}

static json_t *text_or_null(const char *s)
{
    return s[0] ? json_string(s) : json_null();
}

json_t *sl_frame_setup_json(const sl_frame_setup *s)
{
    json_t *j = json_object();
    json_object_set_new(j, "make", text_or_null(s->make));
    json_object_set_new(j, "model", text_or_null(s->model));
    json_object_set_new(j, "serial", text_or_null(s->serial));
    json_object_set_new(j, "lens", text_or_null(s->lens));
    json_object_set_new(j, "lens_serial", text_or_null(s->lens_serial));
    json_object_set_new(j, "focal_length_mm", s->focal_mm > 0 ? json_real(s->focal_mm) : json_null());
    json_object_set_new(j, "width", json_integer(s->width));
    json_object_set_new(j, "height", json_integer(s->height));
    json_object_set_new(j, "orientation", json_integer(s->orientation));
    json_object_set_new(j, "format", text_or_null(s->format));
    json_object_set_new(j, "bits", json_integer(s->bits));
    return j;
}
