/* SPDX-License-Identifier: BSD-3-Clause */
/* The stitch stage from files to files: HDR fisheye views (and an optional
 * nadir mask) to one lat-long with its provenance, the solve's and the
 * coverage's numbers as the result. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/stitch.h"

void sl_stitch_run_options_init(sl_stitch_run_options *o)
{
    memset(o, 0, sizeof *o);
    sl_stitch_options_init(&o->stitch);
}

void sl_stitch_run_result_free(sl_stitch_run_result *res)
{
    sl_stitch_result_free(&res->stitch);
    free(res->json);
    res->json = NULL;
}

static json_t *lens_json(const sl_lens *l)
{
    return json_pack("{s:s, s:i, s:i, s:f, s:f, s:f, s:[f, f, f], s:[f, f, f], s:f, s:f}",
                     "projection", sl_lens_projection_name(l->projection), "width", l->width,
                     "height", l->height, "focal_px", l->focal_px, "cx", l->cx, "cy", l->cy, "k",
                     l->k[0], l->k[1], l->k[2], "vignette", l->vignette[0], l->vignette[1],
                     l->vignette[2], "max_theta_deg", l->max_theta_deg, "circle_radius_px",
                     l->circle_radius_px);
}

static json_t *result_json(const sl_stitch_result *res, const char *out_path)
{
    const sl_stitch_coverage *c = &res->coverage;
    json_t *views = json_array(), *pairs = json_array(), *timing = json_object();
    for (int i = 0; i < res->view_count; i++) {
        const sl_stitch_view_result *v = &res->views[i];
        json_t *vj = json_pack("{s:s, s:[f, f, f], s:[f, f, f], s:f, s:b, s:s}", "path", v->path,
                               "nominal_ypr_deg", v->nominal.yaw_deg, v->nominal.pitch_deg,
                               v->nominal.roll_deg, "ypr_deg", v->pose.yaw_deg,
                               v->pose.pitch_deg, v->pose.roll_deg, "contributes_sr",
                               c->view_sr[i], "clipped_mask_weighted", v->confidence, "held",
                               !v->held_as_half   ? "float"
                               : v->half_rounded ? "half, rounded"
                                                 : "half");
        if (vj && v->half_rounded)
            json_object_update_new(
                vj, json_pack("{s:i, s:f, s:I, s:I}", "half_scale_exp2", v->half_exp2,
                              "rounding_max_relative", ldexp(1.0, -11), "below_half_normal",
                              (json_int_t)v->below_half_normal, "flushed_to_zero",
                              (json_int_t)v->flushed_to_zero));
        json_array_append_new(views, vj);
    }
    for (int i = 0; res->solved && i < res->solve.pairs; i++) {
        const sl_stitch_pair *p = &res->solve.pair[i];
        json_array_append_new(
            pairs, json_pack("{s:s, s:s, s:i, s:i, s:s, s:b, s:f, s:f, s:s}", "a",
                             res->views[p->a].path, "b", res->views[p->b].path, "matches",
                             p->matches, "inliers", p->inliers, "status",
                             sl_stitch_pair_status_name(p->status), "fallback", p->fallback,
                             "rms_px", p->rms_px, "max_px", p->max_px, "why", p->why));
    }
    for (int p = 0; p < SL_STITCH_PHASES; p++)
        json_object_set_new(timing, sl_stitch_phase_name((sl_stitch_phase)p),
                            json_pack("{s:f, s:f}", "wall", res->wall[p], "cpu", res->cpu[p]));
    json_object_set_new(timing, "total",
                        json_pack("{s:f, s:f}", "wall", res->seconds, "cpu", res->cpu_seconds));
    if (res->solved) /* the solve's stages, wall seconds */
        json_object_set_new(timing, "solve_stages",
                            json_pack("{s:f, s:f, s:f, s:f}", "features",
                                      res->solve.seconds_features, "match",
                                      res->solve.seconds_match, "adjust",
                                      res->solve.seconds_adjust, "radiance",
                                      res->solve.seconds_radiance));
    const sl_lens *n = &res->lens_nominal, *l = &res->lens;
    json_t *j = json_pack(
        "{s:s, s:i, s:i, s:o, s:o, s:s, s:{s:f, s:f, s:f}, s:b, s:s, s:o, s:o}", "output",
        out_path, "width", c->width, "height", c->height, "lens_nominal", lens_json(n), "lens",
        lens_json(l), "lens_source", res->lens_source, "lens_change", "focal_percent",
        100.0 * (l->focal_px / n->focal_px - 1.0), "cx_px", l->cx - n->cx, "cy_px",
        l->cy - n->cy, "solved", res->solved, "solve_note", res->solve_note, "views", views,
        "pairs", pairs);
    if (res->solved)
        json_object_set_new(j, "reprojection",
                            json_pack("{s:f, s:f, s:i, s:i, s:i, s:i}", "rms_px",
                                      res->solve.rms_px, "max_px", res->solve.max_px, "matches",
                                      res->solve.inliers, "pairs_solved", res->solve.pairs_solved,
                                      "pairs_fallback", res->solve.pairs_fallback,
                                      "pairs_radiance", res->solve.pairs_radiance));
    if (res->solved && res->solve.radiance_lens_samples > 0)
        json_object_set_new(j, "radiance_lens",
                            json_pack("{s:b, s:i, s:[f, f], s:f}", "kept",
                                      res->solve.radiance_lens, "samples",
                                      res->solve.radiance_lens_samples, "rms_log",
                                      res->solve.radiance_lens_rms[0],
                                      res->solve.radiance_lens_rms[1], "focal_change_percent",
                                      100.0 * res->solve.radiance_lens_focal_change));
    if (res->solved && res->solve.circle_views > 0) {
        const sl_stitch_solve_result *sr = &res->solve;
        json_t *centre = json_pack(
            "{s:b, s:s, s:i, s:[f, f], s:[f, f]}", "from_circle", sr->centre_from_circle, "note",
            sr->centre_note, "circle_views", sr->circle_views, "circle_px", sr->circle_centre[0],
            sr->circle_centre[1], "circle_sigma_px", sr->circle_sigma[0], sr->circle_sigma[1]);
        /* the overlaps' own centre only where they solved one */
        if (centre && sr->overlap_sigma[0] > 0.0)
            json_object_update_new(
                centre, json_pack("{s:[f, f], s:[f, f]}", "overlap_px", sr->overlap_centre[0],
                                  sr->overlap_centre[1], "overlap_sigma_px", sr->overlap_sigma[0],
                                  sr->overlap_sigma[1]));
        json_object_set_new(j, "centre", centre);
    }
    if (res->circle_found)
        json_object_set_new(j, "circle",
                            json_pack("{s:f, s:f, s:f, s:f, s:f}", "cx", res->circle.cx, "cy",
                                      res->circle.cy, "radius", res->circle.radius, "rms_px",
                                      res->circle.rms_px, "support", res->circle.support));
    json_object_set_new(
        j, "coverage",
        json_pack("{s:f, s:f, s:f, s:f, s:f, s:I, s:f, s:i, s:i, s:I}", "seen_sr", c->seen_sr,
                  "filled_sr", c->filled_sr, "filled_percent", 100.0 * c->filled_sr / (4 * M_PI),
                  "masked_sr", c->masked_sr, "low_confidence_sr", c->low_sr, "ghost_texels",
                  (json_int_t)c->ghost_texels, "ghost_sr", c->ghost_sr, "supersample",
                  c->supersample, "supersample_edges", c->supersample_hot, "edge_texels",
                  (json_int_t)c->hot_texels));
    json_object_set_new(j, "float_samples", json_boolean(res->float_samples));
    json_object_set_new(j, "timing", timing);
    return j;
}

sl_result sl_stitch_run(const sl_stitch_run_options *o, sl_stitch_run_result *res, sl_error *err)
{
    memset(res, 0, sizeof *res);
    if (!o->out_path || o->view_count < 1 || !o->view_paths)
        return sl_error_set(err, SL_ERR_USAGE, "stitch needs at least one view and an output");
    sl_stitch_options so = o->stitch;
    sl_image mask = {0};
    sl_result r;
    if (o->mask_path) {
        if ((r = sl_image_read(o->mask_path, &mask, NULL, err)))
            return r;
        if (!sl_is_latlong_shape(mask.width, mask.height)) {
            sl_error_set(err, SL_ERR_INPUT, "%s: the nadir mask is %dx%d, not a 2:1 lat-long",
                         o->mask_path, mask.width, mask.height);
            sl_image_free(&mask);
            return SL_ERR_INPUT;
        }
        so.blend.mask = &mask;
    }
    sl_stitch_result *s = &res->stitch;
    r = sl_stitch(o->view_paths, o->view_count, o->out_path, &so, s, err);
    sl_image_free(&mask);
    if (r)
        return r;
    const sl_stitch_coverage *cv = &s->coverage;
    sl_log(SL_LOG_INFO, "%s: %dx%d from %d views; %s", o->out_path, cv->width, cv->height,
           o->view_count, s->solve_note[0] ? s->solve_note : "solved");
    for (int i = 0; s->solved && i < s->solve.pairs; i++) {
        const sl_stitch_pair *p = &s->solve.pair[i];
        if (p->fallback)
            sl_log(SL_LOG_WARN, "%s and %s: %s, nominal rotation kept (%s)",
                   s->views[p->a].path, s->views[p->b].path,
                   sl_stitch_pair_status_name(p->status), p->why);
    }
    sl_log(SL_LOG_INFO, "coverage: seen %.3f sr, filled %.3f sr (%.2f%% of the sphere, %.3f sr "
                        "masked), %lld ghost texels",
           cv->seen_sr, cv->filled_sr, 100.0 * cv->filled_sr / (4 * M_PI), cv->masked_sr,
           (long long)cv->ghost_texels);
    for (int i = 0; i < o->view_count; i++) {
        const sl_stitch_view_result *v = &s->views[i];
        if (v->half_rounded)
            sl_log(SL_LOG_INFO, "%s: held as half (x 2^%d): rounding up to 0.05%% relative; "
                                "%lld samples under half's normal range (under about 1e-9 of "
                                "its peak), %lld of them flushed to 0",
                   v->path, v->half_exp2, (long long)v->below_half_normal,
                   (long long)v->flushed_to_zero);
    }
    json_t *j = result_json(s, o->out_path);
    res->json = j ? json_dumps(j, JSON_INDENT(2)) : NULL;
    json_decref(j);
    /* The file is in place; only the summary could not be made. */
    return res->json ? SL_OK : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", o->out_path);
}
