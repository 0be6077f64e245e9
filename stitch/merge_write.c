/* SPDX-License-Identifier: BSD-3-Clause */
/* The merged EXR and its clipped mask, with provenance attributes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "merge_private.h"

/* Masks are mostly zero: core's ZIP encoder writes their runs as matches
 * (the 24 MP bracket's mask: 183 KB against PIZ's 358 KB, less CPU). */
#define MASK_COMPRESSION SL_EXR_ZIP

/* Appends text to a growing string; false when out of memory. */
static bool append(char **s, size_t *len, const char *text)
{
    size_t n = strlen(text);
    char *t = realloc(*s, *len + n + 1);
    if (!t)
        return false;
    memcpy(t + *len, text, n + 1);
    *s = t;
    *len += n;
    return true;
}

static sl_result set_number(sl_meta *meta, const char *name, const char *fmt, double v, sl_error *err)
{
    char buf[64];
    snprintf(buf, sizeof buf, fmt, v);
    return sl_meta_set(meta, name, buf, err);
}

/* A count at the width of the largest it can be (the pixel count), so the
 * placeholder written before the pass has the final value's length. */
static sl_result set_count(sl_meta *meta, const char *name, int64_t v, const sl_merge_result *res,
                           sl_error *err)
{
    char buf[32];
    int width = snprintf(buf, sizeof buf, "%lld", (long long)res->width * res->height);
    snprintf(buf, sizeof buf, "%*lld", width, (long long)v);
    return sl_meta_set(meta, name, buf, err);
}

sl_result merge_output_meta(const char *path, const char *mask_path, const char *ghost_path,
                            const sl_merge_result *res, sl_meta *meta, sl_error *err)
{
    sl_meta_init(meta);
    meta->envmap = sl_is_latlong_shape(res->width, res->height) ? SL_ENVMAP_LATLONG
                                                                : SL_ENVMAP_NONE;
    sl_result r = sl_meta_set_color_space(meta, "lin_rec709", err);
    /* One line per frame: path, EXIF time, f-number, ISO, exposures. */
    char *frames = NULL, *curve = NULL, *align = NULL, line[4096 + 256];
    size_t fl = 0, cl = 0, al = 0;
    bool ok = true;
    for (int i = 0; i < res->frame_count && ok; i++) {
        const sl_merge_frame *f = &res->frames[i];
        snprintf(line, sizeof line,
                 "%s t=%.6g N=%.3g ISO=%.6g exif=%.6g fitted=%.6g used=%.6g off_stops=%.3f%s\n",
                 f->path, f->time, f->f_number, f->iso, f->exif_exposure, f->fitted_exposure,
                 f->exposure, f->disagreement_stops, f->disagrees ? " DISAGREES" : "");
        ok = append(&frames, &fl, line);
        if (ok && (f->align.pixels || f->align.note[0])) {
            snprintf(line, sizeof line, "%s dx=%.4f dy=%.4f angle_deg=%.5f%s%s\n", f->path,
                     f->align.dx, f->align.dy, f->align.angle, f->align.note[0] ? " " : "",
                     f->align.note);
            ok = append(&align, &al, line);
        }
    }
    for (int c = 0; c < 3 && ok; c++)
        for (int k = 0; k < res->response.nodes && ok; k++) {
            snprintf(line, sizeof line, k + 1 < res->response.nodes ? "%.6g " : "%.6g\n",
                     res->response.inverse[c * res->response.nodes + k]);
            ok = append(&curve, &cl, line);
        }
    if (!ok && !r)
        r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    char version[64];
    snprintf(version, sizeof version, "setlight %s", sl_version());
    if (!r)
        r = sl_meta_set(meta, "setlight:version", version, err);
    if (!r)
        r = sl_meta_set(meta, "setlight:merge:frames", frames ? frames : "", err);
    if (!r && align)
        r = sl_meta_set(meta, "setlight:merge:align", align, err);
    if (!r && res->align_note[0]) {
        char what[256];
        if (res->misalignment_px >= 0)
            snprintf(what, sizeof what, "%s; largest displacement %.3f px", res->align_note,
                     res->misalignment_px);
        else
            snprintf(what, sizeof what, "%s", res->align_note);
        r = sl_meta_set(meta, "setlight:merge:alignment", what, err);
    }
    if (!r)
        r = sl_meta_set(meta, "setlight:merge:response_source", res->response.source, err);
    if (!r)
        r = sl_meta_set(meta, "setlight:merge:response", curve ? curve : "", err);
    if (!r)
        r = set_number(meta, "setlight:merge:reference_exposure", "%.9g",
                       res->frames[res->reference].exposure, err);
    if (!r)
        r = merge_provenance_meta(meta, res, err);
    if (!r)
        r = merge_lens_meta(meta, res, err);
    if (!r)
        r = set_number(meta, "setlight:merge:clipped_fraction", "%.9e", res->clipped_fraction, err);
    if (!r)
        r = set_count(meta, "setlight:merge:clipped_pixels", res->clipped_pixels, res, err);
    if (!r && sl_is_latlong_shape(res->width, res->height))
        r = set_number(meta, "setlight:merge:clipped_solid_angle_sr", "%.9e",
                       res->clipped_solid_angle, err);
    if (!r && mask_path)
        r = sl_meta_set(meta, "setlight:merge:clipped_mask", mask_path, err);
    if (!r && (ghost_path || res->ghost.data))
        r = set_count(meta, "setlight:merge:ghost_pixels", res->ghost_pixels, res, err);
    if (!r && ghost_path)
        r = sl_meta_set(meta, "setlight:merge:ghost_mask", ghost_path, err);
    free(frames);
    free(curve);
    free(align);
    if (r)
        sl_meta_free(meta);
    return r;
}

sl_result merge_mask_meta(const char *path, const sl_merge_result *res, sl_meta *meta,
                          sl_error *err)
{
    sl_meta_init(meta);
    meta->envmap = sl_is_latlong_shape(res->width, res->height) ? SL_ENVMAP_LATLONG
                                                                : SL_ENVMAP_NONE;
    sl_result r = sl_meta_set(meta, "setlight:merge:mask_of", path, err);
    if (r)
        sl_meta_free(meta);
    return r;
}

sl_result sl_merge_write(const char *path, const char *mask_path, const char *ghost_path,
                         const sl_merge_result *res, sl_error *err)
{
    if (ghost_path && !res->ghost.data)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no ghost mask without deghost", ghost_path);
    sl_meta meta;
    sl_result r = merge_output_meta(path, mask_path, ghost_path, res, &meta, err);
    if (r)
        return r;
    const char *side_path[2] = {mask_path, ghost_path};
    const sl_image *side_img[2] = {&res->clipped, &res->ghost};
    bool written[2] = {false, false};
    for (int i = 0; i < 2 && !r; i++) {
        if (!side_path[i])
            continue;
        sl_meta mm;
        r = merge_mask_meta(path, res, &mm, err);
        if (!r)
            r = sl_exr_write_compressed(side_path[i], side_img[i], &mm, SL_PIXEL_HALF,
                                        MASK_COMPRESSION, err);
        written[i] = !r;
        sl_meta_free(&mm);
    }
    if (!r)
        r = sl_exr_write_compressed(path, &res->radiance, &meta, res->pixel_type,
                                    res->compression, err);
    for (int i = 0; i < 2 && r; i++)
        if (written[i])
            unlink(side_path[i]); /* no half-written set */
    sl_meta_free(&meta);
    return r;
}

sl_result sl_merge_to_exr(const char *const *paths, int count, const sl_merge_options *opt_in,
                          const char *path, const char *mask_path, const char *ghost_path,
                          sl_merge_result *out, sl_error *err)
{
    merge_clock t0 = merge_clock_start();
    sl_merge_options opt = merge_options_or_default(opt_in);
    merge_ctx m;
    memset(&m, 0, sizeof m);
    memset(out, 0, sizeof *out);
    merge_sink sink = {NULL, NULL, NULL};
    sl_meta meta, final;
    sl_meta_init(&meta);
    sl_meta_init(&final);
    sl_result r = ghost_path && !opt.deghost
                      ? sl_error_set(err, SL_ERR_USAGE, "%s: no ghost mask without deghost",
                                     ghost_path)
                      : merge_prepare(paths, count, &opt, true, &m, out, err);
    if (!r)
        r = merge_output_meta(path, mask_path, ghost_path, out, &meta, err);
    const char *side_path[2] = {mask_path, ghost_path};
    sl_exr_stream **side[2] = {&sink.mask, &sink.ghost};
    for (int i = 0; i < 2 && !r; i++) {
        if (!side_path[i])
            continue;
        sl_meta mm;
        r = merge_mask_meta(path, out, &mm, err);
        if (!r)
            r = sl_exr_stream_open(side_path[i], out->width, out->height, i ? 1 : 3, &mm,
                                   SL_PIXEL_HALF, MASK_COMPRESSION, side[i], err);
        sl_meta_free(&mm);
    }
    if (!r)
        r = sl_exr_stream_open(path, out->width, out->height, 3, &meta, out->pixel_type,
                               out->compression, &sink.radiance, err);
    if (!r)
        r = merge_pass(&m, &opt, &sink, out, err);
    if (!r)
        r = merge_output_meta(path, mask_path, ghost_path, out, &final, err);
    merge_clock finish = merge_clock_start();
    /* Masks first, then the radiance; a failure removes them all. */
    bool written[2] = {false, false};
    for (int i = 0; i < 2; i++) {
        if (!*side[i])
            continue;
        if (!r) {
            r = sl_exr_stream_finish(*side[i], NULL, err);
            written[i] = !r;
        } else
            sl_exr_stream_abort(*side[i]);
    }
    if (!r)
        r = sl_exr_stream_finish(sink.radiance, &final, err);
    else
        sl_exr_stream_abort(sink.radiance);
    for (int i = 0; i < 2 && r; i++)
        if (written[i])
            unlink(side_path[i]);
    merge_clock_charge(&out->timing, finish, SL_MERGE_WRITE);
    sl_meta_free(&meta);
    sl_meta_free(&final);
    merge_ctx_free(&m);
    if (r)
        sl_merge_result_free(out);
    merge_clock_finish(out, t0);
    return r;
}
