/* SPDX-License-Identifier: BSD-3-Clause */
/* `setlight demo` stitch stage: each fisheye view's bracket merged (as
 * `setlight merge` writes it), the views stitched from their EXIF lens alone
 * (`setlight stitch`), the lat-long taken back to the set's units through the
 * camera model, and scored against the truth: solved lens and head against
 * truth/camera.json, texel error and energy against truth/latlong.exr. The
 * HDRI it writes (hdri.exr) is what calibrate, rig and render use. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "demo.h"

sl_result demo_diff_luminance(const double *a, const double *b, const unsigned char *keep,
                              int width, int height, demo_diff *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    double *rel = malloc(sizeof(double) * (size_t)width * height);
    if (!rel)
        return sl_error_set(err, SL_ERR_NOMEM, "demo: out of memory comparing lat-longs");
    double ea = 0, eb = 0;
    int count = 0;
    for (int y = 0; y < height; y++) {
        double dw = sl_latlong_texel_solid_angle(y, width, height);
        for (int x = 0; x < width; x++) {
            size_t i = (size_t)y * width + x;
            if (!keep[i])
                continue;
            ea += a[i] * dw;
            eb += b[i] * dw;
            out->solid_angle += dw;
            rel[count++] = fabs(a[i] / (b[i] > 1e-9 ? b[i] : 1e-9) - 1);
        }
    }
    if (count > 0) {
        qsort(rel, (size_t)count, sizeof *rel, sl_cmp_double);
        out->median = rel[count / 2];
        out->p95 = rel[(int)(0.95 * (count - 1))];
        out->energy = eb > 0 ? ea / eb - 1 : 0;
    }
    out->texels = count;
    free(rel);
    return SL_OK;
}

/* The reference frame's exposure k t (ISO/100) / N^2 of one view: merged
 * value = exposure * output_from_rec709 * radiance. */
static double frame_exposure(json_t *f, double k)
{
    double t = json_number_value(json_object_get(f, "exposure_time_s"));
    double n = json_number_value(json_object_get(f, "f_number"));
    double iso = json_number_value(json_object_get(f, "iso"));
    return k * t * (iso / 100.0) / (n * n);
}

/* Angle in degrees between two poses' rotations. */
static double pose_angle(const sl_view_pose *a, const sl_view_pose *b)
{
    double ma[3][3], mb[3][3];
    sl_view_pose_matrix(a, ma);
    sl_view_pose_matrix(b, mb);
    double tr = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            tr += ma[j][i] * mb[j][i];
    return acos(fmax(-1, fmin(1, (tr - 1) / 2))) * 180 / M_PI;
}

/* Merges each view's bracket (linear TIFFs, linear response) to
 * DIR/stitch_viewV.exr with its clipped mask beside it; *exposure gets the
 * views' common reference exposure. */
static sl_result merge_views(demo *d, json_t *frames, int views, double k, char (*out)[4300],
                             double *exposure, double *seconds, sl_error *err)
{
    sl_result r;
    *seconds = 0;
    for (int v = 0; v < views; v++) {
        char paths[64][4300];
        const char *ptrs[64];
        json_t *fs[64];
        int count = 0;
        for (size_t i = 0; i < json_array_size(frames) && count < 64; i++) {
            json_t *f = json_array_get(frames, i);
            if (json_integer_value(json_object_get(f, "view")) != v)
                continue;
            snprintf(paths[count], sizeof paths[count], "%s/hdri/%s_linear.tif", d->capture,
                     json_string_value(json_object_get(f, "name")));
            ptrs[count] = paths[count];
            fs[count++] = f;
        }
        if (count == 0)
            return sl_error_set(err, SL_ERR_INPUT, "%s/capture.json: no frames of view %d",
                                d->capture, v);
        char mask[4400];
        snprintf(out[v], sizeof out[v], "%s/stitch_view%d.exr", d->dir, v);
        snprintf(mask, sizeof mask, "%s/stitch_view%d_clipped.exr", d->dir, v);
        sl_merge_options o;
        sl_merge_options_init(&o);
        o.response_mode = SL_RESPONSE_LINEAR;
        /* At the default 0.004 a read-noise spike of the shortest frame in a
         * black area is the only sample with weight, and a few hundred
         * times the reference's scale: hot pixels outside the image circle
         * that hide it from the circle search. 0.01 is beyond the noise. */
        o.black = 0.01;
        sl_merge_result res;
        r = sl_merge_to_exr(ptrs, count, &o, out[v], mask, NULL, &res, err);
        if (!r) {
            double e = frame_exposure(fs[res.reference], k);
            *seconds += res.seconds;
            /* The stitch blends the views' values as they are: one scale for all. */
            if (v == 0)
                *exposure = e;
            else if (fabs(e / *exposure - 1) > 1e-6)
                r = sl_error_set(err, SL_ERR_INPUT,
                                 "%s: its reference exposure differs from view 0's", out[v]);
        }
        sl_merge_result_free(&res);
        if (r)
            return r;
    }
    return SL_OK;
}

static void lens_from_json(json_t *j, sl_lens *l)
{
    l->focal_px = json_number_value(json_object_get(j, "focal_px"));
    l->cx = json_number_value(json_object_get(j, "cx"));
    l->cy = json_number_value(json_object_get(j, "cy"));
    for (int i = 0; i < 3; i++) {
        l->k[i] = json_number_value(json_array_get(json_object_get(j, "k"), (size_t)i));
        l->vignette[i] =
            json_number_value(json_array_get(json_object_get(j, "vignette"), (size_t)i));
    }
    l->circle_radius_px = json_number_value(json_object_get(j, "circle_radius_px"));
}

/* Vignetting gain at the image circle, s = r / f. */
static double vignette_at_circle(const sl_lens *l, double radius)
{
    double s2 = radius * radius / (l->focal_px * l->focal_px);
    return 1 + l->vignette[0] * s2 + l->vignette[1] * s2 * s2 + l->vignette[2] * s2 * s2 * s2;
}

sl_result demo_stage_stitch(demo *d, char *note, size_t n, sl_error *err)
{
    json_t *cap = demo_load_json(d->capture, "capture.json", err);
    json_t *cam = cap ? demo_load_json(d->capture, "truth/camera.json", err) : NULL;
    if (!cam) {
        json_decref(cap);
        return err ? err->code : SL_ERR_INPUT;
    }
    sl_stitch_result *sres = calloc(1, sizeof *sres), *ores = NULL;
    sl_image st = {0}, ll = {0}, hdri = {0}, orc = {0};
    double *a = NULL, *b = NULL;
    unsigned char *keep = NULL;
    char(*views)[4300] = calloc(SL_STITCH_MAX_VIEWS, sizeof *views);
    double minv[3][3], k, exposure = 1, merge_s = 0;
    sl_result r = SL_OK;
    if (!sres || !views) {
        r = sl_error_set(err, SL_ERR_NOMEM, "demo stitch: out of memory");
        goto done;
    }
    int count = (int)json_integer_value(json_object_get(cap, "views")) +
                (json_is_true(json_object_get(cap, "zenith")) ? 1 : 0);
    if (count < 1 || count > SL_STITCH_MAX_VIEWS) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s/capture.json: %d views", d->capture, count);
        goto done;
    }
    if ((r = demo_camera_inverse(d, minv, &k, err)) || (r = demo_truth_latlong(d, &ll, err)))
        goto done;
    if ((r = merge_views(d, json_object_get(cap, "frames"), count, k, views, &exposure,
                         &merge_s, err)))
        goto done;

    /* The stitch as a wrangler runs it: the views, the lens from their EXIF,
     * the nominal (evenly spaced) yaws; the lat-long at the truth's size so
     * the two compare texel by texel. */
    const char *ptrs[SL_STITCH_MAX_VIEWS];
    for (int v = 0; v < count; v++)
        ptrs[v] = views[v];
    sl_stitch_options so;
    sl_stitch_options_init(&so);
    so.blend.width = ll.width;
    so.pixel_type = SL_PIXEL_FLOAT;
    char out[4300], lens_path[4300];
    snprintf(out, sizeof out, "%s/stitch.exr", d->dir);
    snprintf(lens_path, sizeof lens_path, "%s/stitch_lens.json", d->dir);
    so.save_lens = lens_path;
    if ((r = sl_stitch(ptrs, count, out, &so, sres, err)))
        goto done;
    sl_meta meta;
    if ((r = sl_exr_read(out, &st, &meta, err)))
        goto done;
    sl_meta_free(&meta);
    if (st.width != ll.width || st.height != ll.height || st.channels < 4) {
        r = sl_error_set(err, SL_ERR_INTERNAL, "%s: %dx%d with %d channels, not %dx%d RGBA",
                         out, st.width, st.height, st.channels, ll.width, ll.height);
        goto done;
    }

    /* Back to the set's units: radiance = M^-1 * stitched / exposure; the
     * confidence (A) kept for the cross-check. */
    if ((r = sl_image_alloc(&hdri, st.width, st.height, 3, err)))
        goto done;
    sl_image_free(&d->confidence);
    if ((r = sl_image_alloc(&d->confidence, st.width, st.height, 1, err)))
        goto done;
    int64_t bad = 0;
    for (int y = 0; y < st.height; y++)
        for (int x = 0; x < st.width; x++) {
            const float *p = sl_image_pixel(&st, x, y);
            float *q = sl_image_pixel(&hdri, x, y);
            demo_set_units(p, exposure, (const double(*)[3])minv, q);
            for (int c = 0; c < 3; c++) {
                bad += !isfinite(p[c]) || p[c] < 0;
                /* The inverse matrix can take a saturated colour's dark
                 * channel a hair below 0; radiance is never negative. */
                q[c] = fmaxf(0, q[c]);
            }
            *sl_image_pixel(&d->confidence, x, y) = p[3];
        }
    if (bad) {
        r = sl_error_set(err, SL_ERR_INTERNAL, "%s: %lld negative or non-finite samples", out,
                         (long long)bad);
        goto done;
    }
    snprintf(d->hdri, sizeof d->hdri, "%s/hdri.exr", d->dir);
    if ((r = sl_exr_write(d->hdri, &hdri, NULL, SL_PIXEL_FLOAT, err)))
        goto done;

    /* Against the truth, texel by texel: the directions a view saw (A > 0)
     * within 75 degrees of the horizon, and the energy over all it saw. */
    size_t texels = (size_t)ll.width * ll.height;
    a = malloc(sizeof(double) * texels);
    b = malloc(sizeof(double) * texels);
    keep = malloc(texels);
    if (!a || !b || !keep) {
        r = sl_error_set(err, SL_ERR_NOMEM, "demo stitch: out of memory");
        goto done;
    }
    for (int y = 0; y < ll.height; y++) {
        double lat = 90 - 180 * (y + 0.5) / ll.height;
        for (int x = 0; x < ll.width; x++) {
            size_t i = (size_t)y * ll.width + x;
            a[i] = sl_luminance_px(sl_image_pixel(&hdri, x, y));
            b[i] = sl_luminance_px(sl_image_pixel(&ll, x, y));
            keep[i] = fabs(lat) <= 75 && *sl_image_pixel(&d->confidence, x, y) > 0;
        }
    }
    demo_diff texel;
    if ((r = demo_diff_luminance(a, b, keep, ll.width, ll.height, &texel, err)))
        goto done;

    /* The oracle: the same views stitched with the true lens and head
     * (truth/camera.json), nothing solved: what a perfect solve would give,
     * compared over the same texels. */
    sl_lens truth = sres->lens;
    lens_from_json(json_object_get(cam, "lens"), &truth);
    json_t *tv = json_object_get(cam, "views");
    sl_stitch_options oo;
    sl_stitch_options_init(&oo);
    oo.blend.width = ll.width;
    oo.lens = &truth;
    oo.solve = false;
    oo.yaw_count = oo.pitch_count = oo.roll_count = count;
    for (int v = 0; v < count; v++) {
        json_t *j = json_array_get(tv, (size_t)v);
        oo.yaw_deg[v] = json_number_value(json_object_get(j, "yaw_deg"));
        oo.pitch_deg[v] = json_number_value(json_object_get(j, "pitch_deg"));
        oo.roll_deg[v] = json_number_value(json_object_get(j, "roll_deg"));
    }
    char oracle_path[4300];
    snprintf(oracle_path, sizeof oracle_path, "%s/stitch_oracle.exr", d->dir);
    if (!(ores = calloc(1, sizeof *ores))) {
        r = sl_error_set(err, SL_ERR_NOMEM, "demo stitch: out of memory");
        goto done;
    }
    if ((r = sl_stitch(ptrs, count, oracle_path, &oo, ores, err)) ||
        (r = sl_exr_read(oracle_path, &orc, &meta, err)))
        goto done;
    sl_meta_free(&meta);
    for (int y = 0; y < orc.height && y < ll.height; y++)
        for (int x = 0; x < orc.width && x < ll.width; x++) {
            float q[3];
            demo_set_units(sl_image_pixel(&orc, x, y), exposure, (const double(*)[3])minv, q);
            a[(size_t)y * ll.width + x] = sl_luminance_px(q);
        }
    demo_diff oracle;
    if ((r = demo_diff_luminance(a, b, keep, ll.width, ll.height, &oracle, err)))
        goto done;
    for (size_t i = 0; i < texels; i++)
        a[i] = sl_luminance_px(hdri.data + 3 * i);
    for (size_t i = 0; i < texels; i++)
        keep[i] = d->confidence.data[i] > 0;
    demo_diff seen;
    if ((r = demo_diff_luminance(a, b, keep, ll.width, ll.height, &seen, err)))
        goto done;
    memset(keep, 1, texels);
    demo_diff whole;
    if ((r = demo_diff_luminance(a, b, keep, ll.width, ll.height, &whole, err)))
        goto done;

    /* The solve against what really happened (truth/camera.json). */
    sl_lens nominal = sres->lens_nominal;
    const sl_lens *got = &sres->lens;
    double focal_err = got->focal_px / truth.focal_px - 1;
    double centre_err = hypot(got->cx - truth.cx, got->cy - truth.cy);
    double vig_err = vignette_at_circle(got, truth.circle_radius_px) /
                         vignette_at_circle(&truth, truth.circle_radius_px) -
                     1;
    double worst_rot = 0, worst_rot_nominal = 0;
    for (int v = 1; v < count; v++) {
        json_t *j = json_array_get(tv, (size_t)v);
        sl_view_pose tp = {json_number_value(json_object_get(j, "yaw_deg")),
                           json_number_value(json_object_get(j, "pitch_deg")),
                           json_number_value(json_object_get(j, "roll_deg"))};
        worst_rot = fmax(worst_rot, pose_angle(&sres->views[v].pose, &tp));
        worst_rot_nominal = fmax(worst_rot_nominal, pose_angle(&sres->views[v].nominal, &tp));
    }
    const sl_stitch_solve_result *sv = &sres->solve;
    const sl_stitch_coverage *cov = &sres->coverage;

    sl_report_section(d->rep, "Stitch");
    sl_report_text(d->rep,
                   "The HDRI itself: each of the %d fisheye views' bracket merged (linear "
                   "TIFFs, %.2f s in all: stitch_viewN.exr with its clipped mask), then "
                   "stitched from the lens their EXIF states (%s) and the planned yaws, in "
                   "%.2f s, to stitch.exr (%dx%d, camera RGB, confidence in A); taken back to "
                   "cd/m^2 through the exposure and the camera's output matrix as hdri.exr, "
                   "the lat-long calibrate, rig and render use.",
                   count, merge_s, sres->lens_source, sres->seconds, st.width, st.height);
    if (sres->solved && sv->pairs_solved == 0)
        sl_report_text(d->rep,
                       "Solve from the overlaps: no pair had enough good matches (table), so "
                       "every pair fell back to the nominal rotation and the lens kept its "
                       "nominal focal length, distortion and vignetting; its centre is the "
                       "image circles'. Against the truth (truth/camera.json): focal %+.2f%%, "
                       "centre %.2f px off, vignetting at the circle %+.2f%%, worst view "
                       "rotation %.3f deg off.",
                       100 * focal_err, centre_err, 100 * vig_err, worst_rot);
    else if (sres->solved)
        sl_report_text(d->rep,
                       "Solve from the overlaps (%d features in view 0, %d inliers, %d of %d "
                       "pairs solved, %d fell back to the nominal rotation): reprojection "
                       "RMS %.3f px, max %.2f px. Against the true lens and head "
                       "(truth/camera.json): focal %.2f px, nominal %.2f (%+.2f%% off the "
                       "truth), solved %+.3f%% off; centre %.2f px off (nominal %.2f px); "
                       "vignetting at the circle %+.2f%% off (nominal %+.2f%%); worst view "
                       "rotation %.3f deg off (nominal %.3f deg). Lens saved as "
                       "stitch_lens.json.",
                       sv->features ? sv->features[0] : 0, sv->inliers, sv->pairs_solved,
                       sv->pairs, sv->pairs_fallback, sv->rms_px, sv->max_px, truth.focal_px,
                       nominal.focal_px, 100 * (nominal.focal_px / truth.focal_px - 1),
                       100 * focal_err, centre_err,
                       hypot(nominal.cx - truth.cx, nominal.cy - truth.cy), 100 * vig_err,
                       100 * (1 / vignette_at_circle(&truth, truth.circle_radius_px) - 1),
                       worst_rot, worst_rot_nominal);
    else
        sl_report_text(d->rep, "Not solved: %s. The nominal lens and poses are used.",
                       sres->solve_note);
    if (sres->solved && sv->pairs > 0) {
        static const char *const head[] = {"pair", "overlap (sr)", "matches", "inliers",
                                           "RMS (px)", "status"};
        sl_report_table_begin(d->rep, 6, head);
        for (int i = 0; i < sv->pairs; i++) {
            const sl_stitch_pair *p = &sv->pair[i];
            char c[6][200];
            snprintf(c[0], 200, "%d-%d", p->a, p->b);
            snprintf(c[1], 200, "%.2f", p->overlap_sr);
            snprintf(c[2], 200, "%d", p->matches);
            snprintf(c[3], 200, "%d", p->inliers);
            snprintf(c[4], 200, "%.3f", p->rms_px);
            snprintf(c[5], 200, "%s%s%s", sl_stitch_pair_status_name(p->status),
                     p->fallback ? ": fell back, " : "", p->fallback ? p->why : "");
            const char *cells[6] = {c[0], c[1], c[2], c[3], c[4], c[5]};
            sl_report_table_row(d->rep, cells);
        }
        sl_report_table_end(d->rep);
    }
    sl_report_text(d->rep,
                   "Coverage: %.3f sr seen, %.3f sr filled from the seen border (%.1f%% of "
                   "the sphere), %.3f sr seen at confidence under 0.5; %lld texels where views "
                   "disagreed (best single view taken).",
                   cov->seen_sr, cov->filled_sr, 100 * cov->filled_sr / (4 * M_PI), cov->low_sr,
                   (long long)cov->ghost_texels);
    sl_report_text(d->rep,
                   "hdri.exr against truth/latlong.exr: luminance texel by texel within 75 "
                   "deg of the horizon where seen (%.2f sr): median relative error %.2f%%, "
                   "95th percentile %.2f%%. Energy over the seen sphere (%.2f sr) %+.2f%%, "
                   "over the whole sphere (fill included) %+.2f%%. No negative or non-finite "
                   "sample. The oracle (the same views stitched with the true lens and head, "
                   "stitch_oracle.exr) over the same texels: median %.2f%%, 95th percentile "
                   "%.2f%%; the stitch against it: %.2fx and %.2fx.",
                   texel.solid_angle, 100 * texel.median, 100 * texel.p95, seen.solid_angle,
                   100 * seen.energy, 100 * whole.energy, 100 * oracle.median, 100 * oracle.p95,
                   texel.median / fmax(oracle.median, 1e-12), texel.p95 / fmax(oracle.p95, 1e-12));
    json_t *fallen = json_array();
    for (int i = 0; sres->solved && i < sv->pairs; i++)
        if (sv->pair[i].fallback)
            json_array_append_new(fallen, json_pack("{s:i, s:i, s:s}", "a", sv->pair[i].a, "b",
                                                    sv->pair[i].b, "why", sv->pair[i].why));
    json_object_set_new(
        d->facts, "stitch",
        json_pack("{s:s, s:i, s:i, s:o, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f}",
                  "hdri", d->hdri, "views", count, "pairs_solved",
                  sres->solved ? sv->pairs_solved : 0, "fallback", fallen, "rms_px",
                  sres->solved ? sv->rms_px : -1.0, "focal_vs_truth_percent", 100 * focal_err,
                  "centre_vs_truth_px", centre_err, "vignette_vs_truth_percent", 100 * vig_err,
                  "rotation_vs_truth_deg", worst_rot, "seen_sr", cov->seen_sr, "filled_sr",
                  cov->filled_sr, "median_rel_error", texel.median, "p95_rel_error", texel.p95,
                  "energy_seen", 1 + seen.energy, "energy_sphere", 1 + whole.energy,
                  "oracle_median_rel_error", oracle.median, "oracle_p95_rel_error", oracle.p95));
    if ((r = sl_report_image(d->rep, "stitch_hdri.png", &hdri, demo_stops(d->lavg),
                             "hdri.exr: the stitched HDRI, cd/m^2", err)))
        goto done;
    char fell[200] = "";
    if (sres->solved && sv->pairs_fallback > 0)
        snprintf(fell, sizeof fell, " (%d fell back to nominal)", sv->pairs_fallback);
    if (sres->solved)
        snprintf(note, n,
                 "%d views, %d of %d pairs solved%s, %.2f px RMS; focal %+.2f%%, rotations "
                 "%.2f deg off the truth; vs truth median %.1f%%, p95 %.1f%% (oracle %.1f%%, "
                 "%.1f%%), energy %+.2f%%",
                 count, sv->pairs_solved, sv->pairs, fell, sv->rms_px, 100 * focal_err,
                 worst_rot, 100 * texel.median, 100 * texel.p95, 100 * oracle.median,
                 100 * oracle.p95, 100 * seen.energy);
    else
        snprintf(note, n, "%d views, not solved (%s); vs truth median %.1f%%, p95 %.1f%%",
                 count, sres->solve_note, 100 * texel.median, 100 * texel.p95);
done:
    if (sres)
        sl_stitch_result_free(sres);
    free(sres);
    if (ores)
        sl_stitch_result_free(ores);
    free(ores);
    sl_image_free(&orc);
    free(views);
    free(a);
    free(b);
    free(keep);
    sl_image_free(&st);
    sl_image_free(&ll);
    sl_image_free(&hdri);
    json_decref(cap);
    json_decref(cam);
    return r;
}
