/* SPDX-License-Identifier: BSD-3-Clause */
/* `setlight demo`: reading the simulated capture back. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "demo.h"

json_t *demo_load_json(const char *dir, const char *name, sl_error *err)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    json_t *j;
    sl_json_load_file(path, "JSON", 0, &j, err);
    return j;
}

static sl_result read_latlong(const char *path, sl_image *ll, sl_error *err)
{
    sl_meta meta;
    sl_result r = sl_exr_read(path, ll, &meta, err);
    sl_meta_free(&meta);
    return r;
}

sl_result demo_truth_latlong(const demo *d, sl_image *ll, sl_error *err)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/truth/latlong.exr", d->capture);
    return read_latlong(path, ll, err);
}

sl_result demo_hdri(const demo *d, sl_image *ll, sl_error *err) { return read_latlong(d->hdri, ll, err); }

sl_result demo_camera(const demo *d, double m[3][3], double *k, sl_error *err)
{
    json_t *cam = demo_load_json(d->capture, "truth/camera.json", err);
    if (!cam)
        return err ? err->code : SL_ERR_INPUT;
    json_t *rows = json_object_get(cam, "output_from_rec709");
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            m[i][j] = json_number_value(json_array_get(json_array_get(rows, (size_t)i), (size_t)j));
    *k = json_number_value(json_object_get(cam, "k"));
    json_decref(cam);
    if (!(*k > 0))
        return sl_error_set(err, SL_ERR_INPUT, "%s/truth/camera.json: no exposure constant k",
                            d->capture);
    return SL_OK;
}

sl_result demo_camera_inverse(const demo *d, double minv[3][3], double *k, sl_error *err)
{
    double m[3][3];
    sl_result r = demo_camera(d, m, k, err);
    if (r)
        return r;
    if (!sl_mat3_invert(m, minv))
        return sl_error_set(err, SL_ERR_INPUT, "%s/truth/camera.json: singular output matrix",
                            d->capture);
    return SL_OK;
}

void demo_set_units(const float *p, double exposure, const double minv[3][3], float *out)
{
    double v[3] = {p[0] / exposure, p[1] / exposure, p[2] / exposure}, o[3];
    sl_mat3_apply(minv, v, o);
    for (int c = 0; c < 3; c++)
        out[c] = (float)o[c];
}

static json_t *find_kind(json_t *arr, const char *kind)
{
    for (size_t i = 0; i < json_array_size(arr); i++) {
        json_t *p = json_array_get(arr, i);
        const char *s = json_string_value(json_object_get(p, "kind"));
        if (s && !strcmp(s, kind))
            return p;
    }
    return NULL;
}

sl_result demo_merge_probe(const demo *d, const char *kind, bool middle_only,
                           sl_merge_result *res, json_t **truth, double *exposure, sl_error *err)
{
    memset(res, 0, sizeof *res);
    *truth = NULL;
    *exposure = 0;
    double m[3][3], k;
    sl_result r = demo_camera(d, m, &k, err);
    if (r)
        return r;
    json_t *cap = demo_load_json(d->capture, "capture.json", err);
    json_t *tp = cap ? demo_load_json(d->capture, "truth/probes.json", err) : NULL;
    if (!cap || !tp) {
        json_decref(cap);
        return err ? err->code : SL_ERR_INPUT;
    }
    json_t *probe = find_kind(json_object_get(cap, "probes"), kind);
    json_t *t = find_kind(json_object_get(tp, "probes"), kind);
    json_t *frames = json_object_get(probe, "frames");
    size_t count = json_array_size(frames);
    if (!probe || !t || count == 0 || count > 16) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s/capture.json: no %s probe frames", d->capture,
                         kind);
        goto done;
    }
    char paths[16][4300];
    const char *ptrs[16];
    size_t first = middle_only ? count / 2 : 0;
    if (middle_only)
        count = 1;
    for (size_t i = 0; i < count; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/probes/%s_linear.tif", d->capture,
                 json_string_value(json_object_get(json_array_get(frames, first + i), "name")));
        ptrs[i] = paths[i];
    }
    if (middle_only) {
        sl_meta meta;
        if ((r = sl_photo_read(ptrs[0], &res->radiance, &meta, err)))
            goto done;
        sl_meta_free(&meta);
    } else {
        sl_merge_options o;
        sl_merge_options_init(&o);
        o.response_mode = SL_RESPONSE_LINEAR;
        if ((r = sl_merge(ptrs, (int)count, &o, res, err)))
            goto done;
    }
    json_t *ref = json_array_get(frames, first + (size_t)res->reference);
    double t_s = json_number_value(json_object_get(ref, "exposure_time_s"));
    double n = json_number_value(json_object_get(ref, "f_number"));
    double iso = json_number_value(json_object_get(ref, "iso"));
    *exposure = k * t_s * (iso / 100.0) / (n * n);
    *truth = json_incref(t);
done:
    json_decref(cap);
    json_decref(tp);
    return r;
}

double demo_stops(double lavg) { return log2(0.18 / (lavg > 0 ? lavg : 1)); }
