/* SPDX-License-Identifier: BSD-3-Clause */
/* The stitch's HTML report (setlight stitch --report FILE.html): the
 * summary on top (the lens solved and its change from the nominal one, the
 * pairs, the reprojection error, the solid angle filled), the coverage and
 * confidence map, and the views' thumbnails with their image circles. */
#include "stitch_blend_private.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The preview's auto exposure (median luminance to mid grey), in stops. */
static double mid_grey_stops(const sl_image *img)
{
    sl_preview_options po = {.auto_exposure = true};
    sl_preview_result pr;
    sl_image pic = {0};
    sl_error ignored;
    double stops = sl_preview_image(img, &po, &pic, &pr, &ignored) ? 0.0 : pr.exposure_stops;
    sl_image_free(&pic);
    return stops;
}

/* The circle drawn in red (full scale at the given exposure). */
static void draw_circle(sl_image *img, const double c[3], double stops)
{
    float red = (float)exp2(-stops);
    int steps = (int)(2.0 * M_PI * c[2] * 2.0) + 8;
    for (int i = 0; i < steps; i++) {
        double a = 2.0 * M_PI * i / steps;
        int x = (int)floor(c[0] + c[2] * cos(a)), y = (int)floor(c[1] + c[2] * sin(a));
        if (x < 0 || y < 0 || x >= img->width || y >= img->height)
            continue;
        float *p = sl_image_pixel(img, x, y);
        p[0] = red;
        p[1] = p[2] = 0.0f;
    }
}

/* Confidence as a picture: grey level = confidence, red where filled. */
static sl_result confidence_picture(const stitch_report_images *img, sl_image *out, sl_error *err)
{
    sl_result r = sl_image_alloc(out, img->map.width, img->map.height, 3, err);
    if (r)
        return r;
    for (int y = 0; y < out->height; y++)
        for (int x = 0; x < out->width; x++) {
            float a = sl_image_pixel(&img->map, x, y)[3];
            float f = sl_image_pixel(&img->filled, x, y)[0];
            float *o = sl_image_pixel(out, x, y);
            o[0] = a + f * (1.0f - a);
            o[1] = o[2] = a * (1.0f - f);
        }
    return SL_OK;
}

static void summary(sl_report *rep, const sl_stitch_result *res, const char *out_path)
{
    const sl_lens *n = &res->lens_nominal, *l = &res->lens;
    const sl_stitch_coverage *c = &res->coverage;
    sl_report_text(rep, "%s: %dx%d lat-long from %d views. %s.", out_path, c->width, c->height,
                   res->view_count, res->solve_note[0] ? res->solve_note : "not solved");
    sl_report_text(rep,
                   "Lens (%s): %s, focal %.2f px (%+.3f%% from the nominal %.2f px), centre "
                   "(%.2f, %.2f) px (moved %.2f, %.2f px), k1 %.5f, k2 %.5f, vignetting v1 "
                   "%.4f v2 %.4f, field %.1f deg, circle radius %.1f px.",
                   res->lens_source, sl_lens_projection_name(l->projection), l->focal_px,
                   n->focal_px > 0 ? 100.0 * (l->focal_px / n->focal_px - 1.0) : 0.0,
                   n->focal_px, l->cx, l->cy, l->cx - n->cx, l->cy - n->cy, l->k[0], l->k[1],
                   l->vignette[0], l->vignette[1], l->max_theta_deg, l->circle_radius_px);
    if (res->solved)
        sl_report_text(rep, "Reprojection error: RMS %.3f px, max %.3f px over %d matches; %d "
                            "pairs solved, %d placed by their radiance, %d fell back to the "
                            "nominal rotation.%s%s",
                       res->solve.rms_px, res->solve.max_px, res->solve.inliers,
                       res->solve.pairs_solved, res->solve.pairs_radiance,
                       res->solve.pairs_fallback,
                       res->solve.lens_held ? " " : "",
                       res->solve.lens_held ? res->solve.lens_note : "");
    if (res->solved && res->solve.circle_views > 0)
        sl_report_text(rep, "Optical centre: %s; the circles' (%.2f, %.2f) +- %.3f px.",
                       res->solve.centre_note, res->solve.circle_centre[0],
                       res->solve.circle_centre[1], res->solve.circle_sigma[0]);
    double sphere = 4.0 * M_PI;
    sl_report_text(rep,
                   "Coverage: seen %.3f sr, filled %.3f sr (%.2f%% of the sphere; %.3f sr "
                   "masked), confidence under 0.5 %.3f sr, %lld ghost texels (%.4f sr).",
                   c->seen_sr, c->filled_sr, 100.0 * c->filled_sr / sphere, c->masked_sr,
                   c->low_sr, (long long)c->ghost_texels, c->ghost_sr);
    int rounded = 0;
    int64_t below = 0, flushed = 0;
    for (int i = 0; i < res->view_count; i++) {
        rounded += res->views[i].half_rounded;
        below += res->views[i].below_half_normal;
        flushed += res->views[i].flushed_to_zero;
    }
    if (rounded)
        sl_report_text(rep, "Views held as half (%d, each scaled by a power of two): rounding "
                            "up to 0.05%% relative; %lld samples under half's normal range "
                            "(coarser), %lld flushed to 0.",
                       rounded, (long long)below, (long long)flushed);
}

static void pair_table(sl_report *rep, const sl_stitch_result *res)
{
    static const char *const head[] = {"pair", "overlap (sr)", "matches", "inliers",
                                       "status", "RMS / max (px)", "why"};
    sl_report_table_begin(rep, 7, head);
    for (int p = 0; p < res->solve.pairs; p++) {
        const sl_stitch_pair *pr = &res->solve.pair[p];
        char c[5][64];
        snprintf(c[0], sizeof c[0], "%d-%d", pr->a + 1, pr->b + 1);
        snprintf(c[1], sizeof c[1], "%.3f", pr->overlap_sr);
        snprintf(c[2], sizeof c[2], "%d", pr->matches);
        snprintf(c[3], sizeof c[3], "%d", pr->inliers);
        snprintf(c[4], sizeof c[4], "%.3f / %.3f", pr->rms_px, pr->max_px);
        const char *row[] = {c[0], c[1], c[2], c[3],
                             pr->fallback ? "fell back to the nominal rotation"
                                          : sl_stitch_pair_status_name(pr->status),
                             c[4], pr->why};
        sl_report_table_row(rep, row);
    }
    sl_report_table_end(rep);
}

static void view_table(sl_report *rep, const sl_stitch_result *res)
{
    static const char *const head[] = {"view", "file", "nominal yaw, pitch, roll",
                                       "used yaw, pitch, roll", "features"};
    sl_report_table_begin(rep, 5, head);
    for (int i = 0; i < res->view_count; i++) {
        const sl_stitch_view_result *v = &res->views[i];
        char c[4][96];
        snprintf(c[0], sizeof c[0], "%d", i + 1);
        snprintf(c[1], sizeof c[1], "%.3f, %.3f, %.3f", v->nominal.yaw_deg, v->nominal.pitch_deg,
                 v->nominal.roll_deg);
        snprintf(c[2], sizeof c[2], "%.3f, %.3f, %.3f", v->pose.yaw_deg, v->pose.pitch_deg,
                 v->pose.roll_deg);
        snprintf(c[3], sizeof c[3], "%d",
                 res->solved && res->solve.features && i < res->solve.views
                     ? res->solve.features[i] : 0);
        const char *row[] = {c[0], v->path, c[1], c[2], c[3]};
        sl_report_table_row(rep, row);
    }
    sl_report_table_end(rep);
}

sl_result stitch_report_write(const char *path, const sl_stitch_result *res,
                              const stitch_report_images *img, const char *out_path,
                              sl_error *err)
{
    /* FILE.html: the page is DIR/NAME.html, its images DIR/NAME_*.png. */
    char dir[4096], name[1024];
    const char *slash = strrchr(path, '/');
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - path) : 1, slash ? path : ".");
    if (slash && slash == path)
        snprintf(dir, sizeof dir, "/");
    snprintf(name, sizeof name, "%s", slash ? slash + 1 : path);
    size_t len = strlen(name);
    if (len > 5 && !strcmp(name + len - 5, ".html"))
        name[len - 5] = '\0';
    sl_report *rep = NULL;
    sl_result r = sl_report_new(&rep, dir, name, "setlight stitch", err);
    if (r)
        return r;
    sl_report_top_begin(rep);
    summary(rep, res, out_path);
    sl_report_top_end(rep);
    char file[1200];
    sl_image pic = {0};
    sl_report_section(rep, "Coverage and confidence");
    if (!(r = confidence_picture(img, &pic, err))) {
        snprintf(file, sizeof file, "%s_confidence.png", name);
        r = sl_report_image(rep, file, &pic, 0,
                            "confidence: white 1 (seen well) to black 0 (the circles' edges); "
                            "red: filled, no view saw it",
                            err);
        sl_image_free(&pic);
    }
    if (!r) {
        snprintf(file, sizeof file, "%s_latlong.png", name);
        r = sl_report_image(rep, file, &img->map, mid_grey_stops(&img->map),
                            "the stitched lat-long, median to mid grey", err);
    }
    if (!r && res->solved) {
        sl_report_section(rep, "Pairs");
        pair_table(rep, res);
    }
    if (!r) {
        sl_report_section(rep, "Views");
        view_table(rep, res);
    }
    for (int i = 0; !r && i < res->view_count; i++) {
        if (!img->thumb[i].data)
            continue;
        sl_image t = {0};
        if ((r = sl_image_copy(&img->thumb[i], &t, err)))
            break;
        double stops = mid_grey_stops(&t);
        if (img->circle[i][2] > 0)
            draw_circle(&t, img->circle[i], stops);
        char caption[1200];
        snprintf(caption, sizeof caption, "view %d: %s%s", i + 1, res->views[i].path,
                 img->circle[i][2] > 0 ? ", its image circle in red" : "");
        snprintf(file, sizeof file, "%s_view%d.png", name, i + 1);
        r = sl_report_image(rep, file, &t, stops, caption, err);
        sl_image_free(&t);
    }
    if (r) {
        sl_report_free(rep);
        return r;
    }
    return sl_report_finish(rep, err);
}
