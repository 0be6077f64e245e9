/* SPDX-License-Identifier: BSD-3-Clause */
/* Lens profiles: a solved sl_lens with the camera and lens it belongs to,
 * how it was solved and its residual, as JSON (docs/formats.md, "Lens
 * profiles"), so that a shoot's later setups reuse the first one's solve. */
#include "setlight/stitch.h"

#include "merge_private.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define PROFILE_FORMAT "setlight-lens"

static const char *const source_names[SL_LENS_SOURCE_COUNT] = {"nominal", "overlaps",
                                                               "chessboard"};

int sl_lens_source_from_name(const char *name)
{
    for (int i = 0; name && i < SL_LENS_SOURCE_COUNT; i++)
        if (strcmp(name, source_names[i]) == 0)
            return i;
    return -1;
}

const char *sl_lens_source_name(sl_lens_source source)
{
    return (source >= 0 && source < SL_LENS_SOURCE_COUNT) ? source_names[source] : "unknown";
}

/* Samples of the field tested for a monotone radius and a positive vignetting gain. */
#define FIELD_SAMPLES 512

sl_result sl_lens_check(const sl_lens *lens, const char *where, sl_error *err)
{
    if (lens->projection < 0 || lens->projection >= SL_LENS_PROJECTION_COUNT)
        return sl_error_set(err, SL_ERR_INPUT, "%s: unknown projection", where);
    if (lens->width <= 0 || lens->height <= 0)
        return sl_error_set(err, SL_ERR_INPUT, "%s: image size %dx%d is not positive", where,
                            lens->width, lens->height);
    double values[] = {lens->focal_px,    lens->cx,          lens->cy,
                       lens->k[0],        lens->k[1],        lens->k[2],
                       lens->vignette[0], lens->vignette[1], lens->vignette[2],
                       lens->max_theta_deg, lens->circle_radius_px};
    for (size_t i = 0; i < sizeof values / sizeof values[0]; i++)
        if (!isfinite(values[i]))
            return sl_error_set(err, SL_ERR_INPUT, "%s: a lens value is not a finite number",
                                where);
    if (!(lens->focal_px > 0))
        return sl_error_set(err, SL_ERR_INPUT, "%s: focal_px %g is not positive", where,
                            lens->focal_px);
    if (lens->cx < 0 || lens->cx > lens->width || lens->cy < 0 || lens->cy > lens->height)
        return sl_error_set(err, SL_ERR_INPUT, "%s: optical centre (%g, %g) is off the %dx%d image",
                            where, lens->cx, lens->cy, lens->width, lens->height);
    double limit = lens->projection == SL_LENS_RECTILINEAR    ? 89.999
                   : lens->projection == SL_LENS_ORTHOGRAPHIC ? 90.0
                                                              : 180.0;
    if (!(lens->max_theta_deg > 0) || lens->max_theta_deg > limit)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: max_theta_deg %g is outside (0, %g] for a %s lens", where,
                            lens->max_theta_deg, limit, sl_lens_projection_name(lens->projection));
    if (lens->circle_radius_px < 0)
        return sl_error_set(err, SL_ERR_INPUT, "%s: circle_radius_px %g is negative", where,
                            lens->circle_radius_px);
    /* The radial correction must keep r(theta) increasing over the whole
     * field, or two rays land on one pixel and the inverse is ambiguous. */
    double prev = -1.0, theta_max = lens->max_theta_deg * (M_PI / 180.0);
    for (int i = 0; i <= FIELD_SAMPLES; i++) {
        double theta = theta_max * i / FIELD_SAMPLES;
        double r = sl_lens_radius(lens, theta);
        if (!(r > prev))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: radial correction k = (%g, %g, %g) makes the radius stop "
                                "increasing at %.1f deg off-axis",
                                where, lens->k[0], lens->k[1], lens->k[2],
                                theta * (180.0 / M_PI));
        prev = r;
        double s2 = (r / lens->focal_px) * (r / lens->focal_px);
        const double *v = lens->vignette;
        if (!(1.0 + s2 * (v[0] + s2 * (v[1] + s2 * v[2])) > 0))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: vignetting (%g, %g, %g) is not positive at %.1f deg off-axis",
                                where, v[0], v[1], v[2], theta * (180.0 / M_PI));
    }
    return SL_OK;
}

static json_t *real_array(const double *v, int n)
{
    json_t *a = json_array();
    for (int i = 0; a && i < n; i++)
        json_array_append_new(a, json_real(v[i]));
    return a;
}

sl_result sl_lens_profile_write(const char *path, const sl_lens_profile *p, sl_error *err)
{
    sl_result r = sl_lens_check(&p->lens, path, err);
    if (r)
        return r;
    const sl_lens *l = &p->lens;
    json_t *o = json_pack(
        "{s:s, s:i, s:s, s:s, s:s, s:f, s:f, s:i, s:i, s:i, s:s, s:f, s:f, s:f, s:o, s:o, s:f, "
        "s:f}",
        "format", PROFILE_FORMAT, "version", 1, "camera", p->camera, "lens", p->lens_name,
        "source", sl_lens_source_name(p->source), "rms_px", p->rms_px, "max_px", p->max_px,
        "images", p->images, "width", l->width, "height", l->height, "projection",
        sl_lens_projection_name(l->projection), "focal_px", l->focal_px, "cx", l->cx, "cy", l->cy,
        "k", real_array(l->k, 3), "vignette", real_array(l->vignette, 3), "max_theta_deg",
        l->max_theta_deg, "circle_radius_px", l->circle_radius_px);
    /* 17 digits: a profile read back gives the same doubles, so a reused
     * solve stitches bit for bit as the setup that made it. */
    return stitch_json_write(path, o, 17, err);
}

/* Field getters: each names the file and the field in its one-line error. */
static sl_result get_number(json_t *o, const char *path, const char *key, double *out,
                            sl_error *err)
{
    json_t *v = json_object_get(o, key);
    if (!v)
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is missing", path, key);
    if (!json_is_number(v) || !isfinite(json_number_value(v)))
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is not a finite number", path,
                            key);
    *out = json_number_value(v);
    return SL_OK;
}

static sl_result get_int(json_t *o, const char *path, const char *key, int *out, sl_error *err)
{
    json_t *v = json_object_get(o, key);
    if (!v)
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is missing", path, key);
    if (!json_is_integer(v) || json_integer_value(v) < 0 || json_integer_value(v) > 1000000)
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is not an integer in [0, 1e6]",
                            path, key);
    *out = (int)json_integer_value(v);
    return SL_OK;
}

static sl_result get_string(json_t *o, const char *path, const char *key, char *out, size_t size,
                            sl_error *err)
{
    json_t *v = json_object_get(o, key);
    if (!v)
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is missing", path, key);
    if (!json_is_string(v))
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is not a string", path, key);
    snprintf(out, size, "%s", json_string_value(v));
    return SL_OK;
}

static sl_result get_triple(json_t *o, const char *path, const char *key, double out[3],
                            sl_error *err)
{
    json_t *v = json_object_get(o, key);
    if (!v)
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is missing", path, key);
    bool ok = json_is_array(v) && json_array_size(v) == 3;
    for (size_t i = 0; ok && i < 3; i++) {
        json_t *x = json_array_get(v, i);
        ok = json_is_number(x) && isfinite(json_number_value(x));
        if (ok)
            out[i] = json_number_value(x);
    }
    if (!ok)
        return sl_error_set(err, SL_ERR_INPUT, "%s: field \"%s\" is not three finite numbers",
                            path, key);
    return SL_OK;
}

static sl_result profile_from_json(json_t *o, const char *path, sl_lens_profile *p, sl_error *err)
{
    char format[32], projection[32], source[32];
    int version = 0;
    sl_result r;
    if ((r = get_string(o, path, "format", format, sizeof format, err)))
        return r;
    if (strcmp(format, PROFILE_FORMAT) != 0)
        return sl_error_set(err, SL_ERR_INPUT, "%s: format is \"%s\", not \"" PROFILE_FORMAT "\"",
                            path, format);
    if ((r = get_int(o, path, "version", &version, err)))
        return r;
    if (version != 1)
        return sl_error_set(err, SL_ERR_INPUT, "%s: version %d is not 1", path, version);
    sl_lens *l = &p->lens;
    if ((r = get_string(o, path, "camera", p->camera, sizeof p->camera, err)) ||
        (r = get_string(o, path, "lens", p->lens_name, sizeof p->lens_name, err)) ||
        (r = get_string(o, path, "source", source, sizeof source, err)) ||
        (r = get_number(o, path, "rms_px", &p->rms_px, err)) ||
        (r = get_number(o, path, "max_px", &p->max_px, err)) ||
        (r = get_int(o, path, "images", &p->images, err)) ||
        (r = get_int(o, path, "width", &l->width, err)) ||
        (r = get_int(o, path, "height", &l->height, err)) ||
        (r = get_string(o, path, "projection", projection, sizeof projection, err)) ||
        (r = get_number(o, path, "focal_px", &l->focal_px, err)) ||
        (r = get_number(o, path, "cx", &l->cx, err)) ||
        (r = get_number(o, path, "cy", &l->cy, err)) ||
        (r = get_triple(o, path, "k", l->k, err)) ||
        (r = get_triple(o, path, "vignette", l->vignette, err)) ||
        (r = get_number(o, path, "max_theta_deg", &l->max_theta_deg, err)) ||
        (r = get_number(o, path, "circle_radius_px", &l->circle_radius_px, err)))
        return r;
    int s = sl_lens_source_from_name(source);
    if (s < 0)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: source \"%s\" is not nominal, overlaps or chessboard", path,
                            source);
    p->source = (sl_lens_source)s;
    int proj = sl_lens_projection_from_name(projection);
    if (proj < 0)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: unknown projection \"%s\" (equisolid, equidistant, "
                            "stereographic, orthographic, rectilinear)",
                            path, projection);
    l->projection = (sl_lens_projection)proj;
    return sl_lens_check(l, path, err);
}

sl_result sl_lens_profile_read(const char *path, sl_lens_profile *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    json_t *o;
    sl_result r = stitch_json_read(path, &o, err);
    if (r)
        return r;
    r = json_is_object(o) ? profile_from_json(o, path, out, err)
                          : sl_error_set(err, SL_ERR_INPUT, "%s: not a JSON object", path);
    json_decref(o);
    if (r)
        memset(out, 0, sizeof *out);
    return r;
}

/* One camera named two ways: equal, or the longer is the shorter with words
 * in front ("Canon Canon EOS 6D Mark II", make + model as EXIF has them, and
 * "Canon EOS 6D Mark II"; "NIKON CORPORATION NIKON D850" and "NIKON D850"). */
static bool same_name(const char *a, const char *b)
{
    size_t na = strlen(a), nb = strlen(b);
    if (na < nb) {
        const char *t = a;
        a = b;
        b = t;
        size_t n = na;
        na = nb;
        nb = n;
    }
    return strcasecmp(a + (na - nb), b) == 0 && (na == nb || a[na - nb - 1] == ' ');
}

bool sl_lens_profile_fits(const sl_lens_profile *p, int width, int height, const char *camera,
                          const char *lens, sl_lens *fitted, char *why, size_t why_size)
{
    if (why_size)
        why[0] = '\0';
    if (camera && camera[0] && p->camera[0] && !same_name(camera, p->camera)) {
        snprintf(why, why_size, "the profile is for camera \"%s\", the view is from \"%s\"",
                 p->camera, camera);
        return false;
    }
    if (lens && lens[0] && p->lens_name[0] && !same_name(lens, p->lens_name)) {
        snprintf(why, why_size, "the profile is for lens \"%s\", the view is from \"%s\"",
                 p->lens_name, lens);
        return false;
    }
    const sl_lens *l = &p->lens;
    /* Same aspect ratio to half a pixel of the larger side: a downsized copy
     * of the same frame. */
    double aspect_gap = fabs((double)width * l->height - (double)height * l->width) /
                        (double)(l->height > height ? l->height : height);
    if (width <= 0 || height <= 0 || aspect_gap > 0.5) {
        snprintf(why, why_size, "the profile is for %dx%d images, the view is %dx%d", l->width,
                 l->height, width, height);
        return false;
    }
    sl_lens scaled = *l;
    if (width != l->width || height != l->height) {
        double s = (double)width / l->width;
        scaled.width = width;
        scaled.height = height;
        scaled.focal_px *= s;
        scaled.cx *= s;
        scaled.cy *= s;
        scaled.circle_radius_px *= s;
        snprintf(why, why_size,
                 "the profile is for %dx%d images: focal length, centre and circle scaled by %.6g "
                 "to %dx%d",
                 l->width, l->height, s, width, height);
    }
    if (fitted)
        *fitted = scaled;
    return true;
}
