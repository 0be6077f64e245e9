/* SPDX-License-Identifier: BSD-3-Clause */
/* The stitch's blend on the virtual set: fisheye views rendered through a
 * lens and head off their nominal values by known amounts, stitched by an
 * oracle told the true lens and poses (the floor the solved stitch is held
 * to), its error and energy against the truth; one view (a partial
 * lat-long), a moving person in one view, a masked nadir; and the file
 * call's refusals. */
#include "testing.h"

#include "setlight/vset.h"
#include "setlight/stitch.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define VIEW_W 960
#define VIEW_H 720
#define TRUTH_W 1536

/* A scene's truth and its views through the true lens at the true poses. */
typedef struct rig {
    sl_vset_scene scene;
    sl_lens nominal, lens;
    sl_view_pose nominal_pose[4], pose[4];
    sl_image views[4];
    int count;
    bool borrowed; /* the shared stage rig: not freed */
} rig;

static rig stage3; /* built once, shared by the tests that only read it */

static void true_lens(sl_lens *nominal, sl_lens *lens)
{
    sl_lens_nominal(nominal, SL_LENS_EQUISOLID, VIEW_W, VIEW_H, 8.0, 36.0);
    *lens = *nominal;
    lens->focal_px *= 1.015;
    lens->cx += 6.0;
    lens->cy -= 4.0;
    lens->k[0] = 0.02;
    lens->vignette[0] = -0.2;
    lens->circle_radius_px = sl_lens_radius(lens, 0.5 * M_PI);
}

static bool rig_build(rig *g, const char *scene, int count, sl_error *err);

static bool rig_make(rig *g, const char *scene, int count, sl_error *err)
{
    if (strcmp(scene, "stage") || count != 3)
        return rig_build(g, scene, count, err);
    if (!stage3.count && !rig_build(&stage3, scene, count, err))
        return false;
    *g = stage3;
    g->borrowed = true;
    return true;
}

static bool rig_build(rig *g, const char *scene, int count, sl_error *err)
{
    memset(g, 0, sizeof *g);
    sl_vset_desc d;
    if (sl_vset_preset(scene, &d, err) || sl_vset_scene_make(&d, TRUTH_W, &g->scene, err))
        return false;
    true_lens(&g->nominal, &g->lens);
    /* The head off the plan by known amounts (degrees). */
    static const double dyaw[4] = {0, 0.8, -0.6, 0.5}, dpitch[4] = {0, 0.4, -0.3, -0.4},
                        droll[4] = {0, -0.3, 0.5, 0.3};
    g->count = count;
    for (int i = 0; i < count; i++) {
        bool zenith = count == 4 && i == 3;
        g->nominal_pose[i] = (sl_view_pose){zenith ? 0 : 120.0 * i, zenith ? 90 : 0, 0};
        g->pose[i] = (sl_view_pose){g->nominal_pose[i].yaw_deg + dyaw[i],
                                    g->nominal_pose[i].pitch_deg + dpitch[i] * (zenith ? -1 : 1),
                                    droll[i]};
        if (sl_vset_view_image(&g->lens, &g->pose[i], &g->scene.latlong, 4, &g->views[i], err))
            return false;
    }
    return true;
}

static void rig_free(rig *g)
{
    if (g->borrowed)
        return;
    sl_vset_scene_free(&g->scene);
    for (int i = 0; i < 4; i++)
        sl_image_free(&g->views[i]);
}

/* rig_make, a failed check when it fails. */
static bool rig_checked(rig *g, const char *scene, int count)
{
    sl_error err;
    if (rig_make(g, scene, count, &err))
        return true;
    CHECK_MSG(false, "rig %s: %s", scene, err.message);
    rig_free(g);
    return false;
}

/* The oracle's views: the true lens and poses. */
static void oracle_views(const rig *g, sl_stitch_view *v)
{
    static const char *names[4] = {"view0", "view1", "view2", "view3"};
    for (int i = 0; i < g->count; i++)
        v[i] = (sl_stitch_view){names[i], &g->views[i], NULL, g->lens, g->pose[i]};
}

/* The views as the solve gets them: the nominal lens and the plan's poses. */
static void nominal_views(const rig *g, sl_stitch_view *v)
{
    oracle_views(g, v);
    for (int i = 0; i < g->count; i++) {
        v[i].lens = g->nominal;
        v[i].pose = g->nominal_pose[i];
    }
}

/* |L(st) - L(ref)| / L(ref) over latitudes within +-75 deg, sorted, for
 * the texels st saw (and ref, where it has alpha); *n gets their count. */
static double *relative_errors(const sl_image *st, const sl_image *ref, size_t *n)
{
    double *e = malloc(sizeof(double) * (size_t)st->width * st->height);
    *n = 0;
    for (int y = 0; y < st->height; y++) {
        double lat = 90.0 - 180.0 * (y + 0.5) / st->height;
        if (fabs(lat) > 75.0)
            continue;
        for (int x = 0; x < st->width; x++) {
            const float *s = sl_image_pixel(st, x, y), *t = sl_image_pixel(ref, x, y);
            if (s[3] <= 0 || (ref->channels > 3 && t[3] <= 0))
                continue;
            double lt = sl_luminance_px(t);
            e[(*n)++] = fabs(sl_luminance_px(s) - lt) / fmax(lt, 1e-9);
        }
    }
    qsort(e, *n, sizeof *e, sl_cmp_double);
    return e;
}

/* Median and p95 of the relative luminance error against the truth (area
 * resampled to the stitch's size) over latitudes within +-75 deg, seen
 * texels only. */
static void error_vs_truth(const sl_image *st, const sl_image *truth_full, double *median,
                           double *p95)
{
    sl_image truth;
    sl_error err;
    *median = *p95 = INFINITY;
    if (sl_image_resample(truth_full, st->width, st->height, &truth, &err))
        return;
    size_t n;
    double *e = relative_errors(st, &truth, &n);
    if (n) {
        *median = e[n / 2];
        *p95 = e[(size_t)(0.95 * (n - 1))];
    }
    free(e);
    sl_image_free(&truth);
}

/* Integral of L over the texels the stitch saw, for the stitch and the truth. */
static void seen_power(const sl_image *st, const sl_image *truth_full, double ps[3], double pt[3])
{
    sl_image truth;
    sl_error err;
    for (int c = 0; c < 3; c++)
        ps[c] = pt[c] = 0;
    if (sl_image_resample(truth_full, st->width, st->height, &truth, &err))
        return;
    for (int y = 0; y < st->height; y++) {
        double sr = sl_latlong_texel_solid_angle(y, st->width, st->height);
        for (int x = 0; x < st->width; x++) {
            const float *s = sl_image_pixel(st, x, y), *t = sl_image_pixel(&truth, x, y);
            if (s[3] <= 0)
                continue;
            for (int c = 0; c < 3; c++) {
                ps[c] += sr * s[c];
                pt[c] += sr * t[c];
            }
        }
    }
    sl_image_free(&truth);
}

static bool all_finite_nonnegative(const sl_image *img)
{
    sl_image_stats st;
    sl_image_stats_compute(img, &st);
    return st.nan_count == 0 && st.inf_count == 0 && st.negative_count == 0;
}

/* (a) and (b): the oracle stitch of 3 and of 4 (+ zenith) views. */
static void oracle(const char *scene, int count)
{
    rig g;
    sl_error err;
    if (!rig_make(&g, scene, count, &err)) {
        CHECK_MSG(false, "rig %s: %s", scene, err.message);
        rig_free(&g);
        return;
    }
    sl_stitch_view v[4];
    oracle_views(&g, v);
    sl_image out;
    sl_stitch_coverage cov;
    CHECK_OK(sl_stitch_blend(v, count, NULL, &out, &cov, &err), &err);
    if (!out.data) {
        rig_free(&g);
        return;
    }
    double median, p95, ps[3], pt[3];
    error_vs_truth(&out, &g.scene.latlong, &median, &p95);
    seen_power(&out, &g.scene.latlong, ps, pt);
    double worst = 0;
    for (int c = 0; c < 3; c++)
        worst = fmax(worst, fabs(ps[c] / pt[c] - 1));
    printf("  oracle %s %d views: %dx%d, %d (%d on edges, %lld texels) samples, relative error median %.4f p95 %.4f "
           "(|lat| <= 75), power vs truth over the seen %.3f sr: %+.4f%% worst channel, "
           "filled %.4f sr, ghost texels %lld\n",
           scene, count, out.width, out.height, cov.supersample, cov.supersample_hot,
           (long long)cov.hot_texels, median, p95,
           cov.seen_sr, 100 * worst, cov.filled_sr, (long long)cov.ghost_texels);
    CHECK(all_finite_nonnegative(&out));
    /* The exterior's sun is 1.5 px across in these small views: its
     * energy is kept within 1% (0.55% measured), the rest within 0.5%. */
    CHECK(worst < (strcmp(scene, "exterior") ? 0.005 : 0.01));
    CHECK(median < 0.02);
    CHECK(p95 < 0.25);
    /* Every direction is within 90 deg of some view: seen, if only at the edge. */
    CHECK(cov.seen_sr > 4 * M_PI * 0.99);
    sl_image_free(&out);
    rig_free(&g);
}

static void oracle_stage_3(void) { oracle("stage", 3); }
static void oracle_exterior_3(void) { oracle("exterior", 3); }
static void oracle_stage_4(void) { oracle("stage", 4); }

/* One row of the solved stitch against the oracle: nominal lens and poses
 * in, the solve, then the same blend; its error against the truth beside
 * the oracle's (told the true lens and poses). */
typedef struct solved_row {
    const char *scene;
    int count;
    double om, op, sm, sp; /* median and p95: oracle, solved */
    double diff_median;    /* median relative difference solved vs oracle stitch */
    int pairs_solved, pairs_fallback, pairs_radiance;
    double rms_px, focal, k1, centre_px, rot_deg;
    bool lens_held, centre_from_circle, radiance_lens, ok;
} solved_row;

/* The largest angle (degrees) between a view's solved and true rotation
 * relative to view 0. */
static double rotation_error_deg(const rig *g, const sl_stitch_view *v)
{
    double worst = 0, s0[3][3], t0[3][3];
    sl_view_pose_matrix(&v[0].pose, s0);
    sl_view_pose_matrix(&g->pose[0], t0);
    for (int i = 1; i < g->count; i++) {
        double si[3][3], ti[3][3], tr = 0;
        sl_view_pose_matrix(&v[i].pose, si);
        sl_view_pose_matrix(&g->pose[i], ti);
        /* trace of (S0^T Si)^T (T0^T Ti) */
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) {
                double a = 0, b = 0;
                for (int k = 0; k < 3; k++) {
                    a += s0[k][r] * si[k][c];
                    b += t0[k][r] * ti[k][c];
                }
                tr += a * b;
            }
        worst = fmax(worst, acos(fmin(1, fmax(-1, 0.5 * (tr - 1)))) * 180 / M_PI);
    }
    return worst;
}

/* Median relative luminance difference of two stitches (within +-75 deg,
 * texels both saw). */
static double median_difference(const sl_image *a, const sl_image *b)
{
    size_t n;
    double *e = relative_errors(a, b, &n);
    double m = n ? e[n / 2] : INFINITY;
    free(e);
    return m;
}

/* Which part carries the error: the true values put back one group at a
 * time (docs/stitch.md, "Accuracy of the solved stitch"). */
static void substitute(const rig *g, const sl_stitch_view *v, const sl_stitch_solve_result *sr,
                       const sl_stitch_blend_options *o, double om, double op)
{
    for (int p = 0; p < sr->pairs; p++)
        printf("   pair %d-%d: %s, %d matches %d inliers rms %.3f why %s\n", sr->pair[p].a,
               sr->pair[p].b, sl_stitch_pair_status_name(sr->pair[p].status), sr->pair[p].matches,
               sr->pair[p].inliers, sr->pair[p].rms_px, sr->pair[p].why);
    printf("   lens f %.3f/%.3f c %.2f,%.2f / %.2f,%.2f k %.4f %.4f / %.4f v %.4f %.4f / %.4f vs %d\n",
           v[0].lens.focal_px, g->lens.focal_px, v[0].lens.cx, v[0].lens.cy, g->lens.cx, g->lens.cy,
           v[0].lens.k[0], v[0].lens.k[1], g->lens.k[0], v[0].lens.vignette[0],
           v[0].lens.vignette[1], g->lens.vignette[0], sr->vignette_samples);
    for (int i = 0; i < g->count; i++)
        printf("   pose %d: solved %.3f %.3f %.3f true %.3f %.3f %.3f gain %.4f features %d\n", i,
               v[i].pose.yaw_deg, v[i].pose.pitch_deg, v[i].pose.roll_deg, g->pose[i].yaw_deg,
               g->pose[i].pitch_deg, g->pose[i].roll_deg, sr->gain[i], sr->features[i]);
    const char *label[7] = {"true vignette, solved geometry", "true lens, solved poses",
                            "solved lens, true poses", "solved lens+true vignette, true poses",
                            "true focal+k, solved rest", "true circle radius, solved rest",
                            "true centre, solved rest"};
    printf("   circle radius %.3f / %.3f, max theta %.3f / %.3f\n", v[0].lens.circle_radius_px,
           g->lens.circle_radius_px, v[0].lens.max_theta_deg, g->lens.max_theta_deg);
    for (int k = 0; k < 7; k++) {
        sl_stitch_view w[4];
        for (int i = 0; i < g->count; i++) {
            w[i] = v[i];
            if (k == 0 || k == 3)
                memcpy(w[i].lens.vignette, g->lens.vignette, sizeof g->lens.vignette);
            if (k == 1)
                w[i].lens = g->lens;
            if (k == 2 || k == 3)
                w[i].pose = g->pose[i];
            if (k == 4) {
                w[i].lens.focal_px = g->lens.focal_px;
                memcpy(w[i].lens.k, g->lens.k, sizeof g->lens.k);
            }
            if (k == 5)
                w[i].lens.circle_radius_px = g->lens.circle_radius_px;
            if (k == 6) {
                w[i].lens.cx = g->lens.cx;
                w[i].lens.cy = g->lens.cy;
            }
        }
        sl_image x;
        sl_error err;
        if (sl_stitch_blend(w, g->count, o, &x, NULL, &err) == SL_OK) {
            double xm, xp;
            error_vs_truth(&x, &g->scene.latlong, &xm, &xp);
            printf("   %s: median %.5f (%.2fx) p95 %.4f (%.2fx)\n", label[k], xm, xm / om, xp,
                   xp / op);
            sl_image_free(&x);
        }
    }
}

static void solved_case(solved_row *row)
{
    rig g;
    sl_error err;
    row->ok = false;
    if (!rig_checked(&g, row->scene, row->count))
        return;
    int n = row->count;
    sl_stitch_view v[4];
    oracle_views(&g, v);
    sl_image oracle_img = {0}, solved_img = {0};
    CHECK_OK(sl_stitch_blend(v, n, NULL, &oracle_img, NULL, &err), &err);
    nominal_views(&g, v);
    sl_stitch_solve_result sr;
    CHECK_OK(sl_stitch_solve(v, n, NULL, &sr, &err), &err);
    sl_stitch_blend_options o;
    sl_stitch_blend_options_init(&o);
    o.width = oracle_img.width;
    CHECK_OK(sl_stitch_blend(v, n, &o, &solved_img, NULL, &err), &err);
    if (oracle_img.data && solved_img.data) {
        error_vs_truth(&oracle_img, &g.scene.latlong, &row->om, &row->op);
        error_vs_truth(&solved_img, &g.scene.latlong, &row->sm, &row->sp);
        row->diff_median = median_difference(&solved_img, &oracle_img);
        row->pairs_solved = sr.pairs_solved;
        row->pairs_fallback = sr.pairs_fallback;
        row->pairs_radiance = sr.pairs_radiance;
        row->rms_px = sr.rms_px;
        row->focal = v[0].lens.focal_px / g.lens.focal_px - 1;
        row->k1 = v[0].lens.k[0];
        row->centre_px = hypot(v[0].lens.cx - g.lens.cx, v[0].lens.cy - g.lens.cy);
        row->rot_deg = rotation_error_deg(&g, v);
        row->lens_held = sr.lens_held;
        row->radiance_lens = sr.radiance_lens;
        row->centre_from_circle = sr.centre_from_circle;
        row->ok = true;
        printf("  centre: %s; vignette %d samples, rms log ratio %.5f; lens: %s; by radiance %s: "
               "%d samples, log residual %.5f -> %.5f, focal %+.4f%%; %.2f s\n",
               sr.centre_note, sr.vignette_samples, sr.vignette_rms_log, sr.lens_note,
               sr.radiance_lens ? "kept" : "not kept", sr.radiance_lens_samples,
               sr.radiance_lens_rms[0], sr.radiance_lens_rms[1],
               100 * sr.radiance_lens_focal_change, sr.seconds_radiance);
        printf("  %s %d: %d pairs solved, %d fell back, %d from radiance, RMS %.3f px, "
               "focal %+.3f%%, k1 %.4f, "
               "centre %.3f px, rotations %.4f deg; median %.5f (oracle %.5f, %.2fx, %+.5f), "
               "p95 %.4f (oracle %.4f, %.2fx); solved vs oracle stitch median %.5f\n",
               row->scene, n, sr.pairs_solved, sr.pairs_fallback, sr.pairs_radiance, sr.rms_px,
               100 * row->focal,
               row->k1, row->centre_px, row->rot_deg, row->sm, row->om, row->sm / row->om,
               row->sm - row->om, row->sp, row->op, row->sp / row->op, row->diff_median);
        if (getenv("SETLIGHT_STITCH_SUBSTITUTE"))
            substitute(&g, v, &sr, &o, row->om, row->op);
    }
    sl_stitch_solve_result_free(&sr);
    sl_image_free(&oracle_img);
    sl_image_free(&solved_img);
    rig_free(&g);
}

/* The solved stitch against the oracle on every rig the issue names, each
 * held to the goal (median 1.15x, p95 1.25x the oracle's; measured
 * in docs/stitch.md, "Accuracy of the solved stitch"): 1.00-1.04x and
 * 1.00-1.01x.
 * - exterior 4: the zenith sees sky (30 features, 0-1 matches a pair): its
 *   3 pairs are placed by their radiance (the zenith within 0.006 deg); at
 *   its nominal pose, 0.45 deg off, the stitch was 5.5x / 1.18x.
 * - every rig: the lens refined by the overlaps' smooth radiance; without
 *   it the exterior's solved focal (+0.04%), k1 (0.0193) and vignetting
 *   traded against each other: 1.72x / 1.02x (exterior 3), and the stage 4
 *   rig's focal was +0.095%.
 * - stage 4 (+ zenith): without the centre gate's floor on the overlaps'
 *   sigma the circles' centre is refused at 6.5 sigma and the side views'
 *   pitch trades with the centre: 1.81x / 1.14x. */
typedef struct solved_goal {
    const char *scene;
    int count, solved, fallback, radiance;
    bool centre_from_circle;
    double median_x, p95_x; /* the bound on solved / oracle */
} solved_goal;

static void solved_vs_oracle(void)
{
    static const solved_goal goal[4] = {{"stage", 3, 3, 0, 0, true, 1.15, 1.25},
                                        {"stage", 4, 5, 1, 0, true, 1.15, 1.25},
                                        {"exterior", 3, 3, 0, 0, true, 1.15, 1.25},
                                        {"exterior", 4, 3, 0, 3, true, 1.15, 1.25}};
    int cases = sl_test_sanitized() ? 1 : 4;
    for (int c = 0; c < cases; c++) {
        const solved_goal *q = &goal[c];
        solved_row r = {.scene = q->scene, .count = q->count};
        solved_case(&r);
        if (!r.ok)
            continue;
        CHECK_MSG(!r.lens_held, "%s %d: lens held", r.scene, r.count);
        CHECK_MSG(r.radiance_lens, "%s %d: lens not refined by radiance", r.scene, r.count);
        CHECK_MSG(r.pairs_solved == q->solved && r.pairs_fallback == q->fallback &&
                      r.pairs_radiance == q->radiance,
                  "%s %d: %d pairs solved, %d fell back, %d from radiance", r.scene, r.count,
                  r.pairs_solved, r.pairs_fallback, r.pairs_radiance);
        CHECK_MSG(r.rot_deg < 0.05, "%s %d: rotations %.4f deg off", r.scene, r.count, r.rot_deg);
        CHECK_MSG(r.centre_from_circle == q->centre_from_circle, "%s %d: centre from circle %d",
                  r.scene, r.count, r.centre_from_circle);
        CHECK_MSG(r.sm <= q->median_x * r.om, "%s %d: median %.2fx", r.scene, r.count, r.sm / r.om);
        CHECK_MSG(r.sp <= q->p95_x * r.op, "%s %d: p95 %.2fx", r.scene, r.count, r.sp / r.op);
    }
}

/* The centre of a lens 6, -4 px off its nominal one, solved on the smooth
 * stage: with the image circles' centre within 0.2 px (a stage view whose
 * rim carries a panel's edge has its circle moved 0.3 px and is left out);
 * from the overlaps alone 0.15 px off, the side views' pitch 0.04 deg; and
 * with circles 3 px off the lens's centre (a decentred lens), the circles'
 * centre is refused as disagreeing with the overlaps and the overlaps'
 * solution kept. */
static void circle_centre(void)
{
    rig g;
    sl_error err;
    if (!rig_checked(&g, "stage", 3))
        return;
    sl_stitch_circle circles[3];
    for (int i = 0; i < 3; i++)
        CHECK_OK(sl_stitch_circle_find(&g.views[i], "view", NULL, &circles[i], &err), &err);
    double off[3] = {0, 0, 0}, pitch[3] = {0, 0, 0};
    bool used[3] = {false, false, false};
    for (int run = 0; run < 3; run++) {
        sl_stitch_view v[3];
        nominal_views(&g, v);
        for (int i = 0; i < 3; i++)
            circles[i].cx += run == 2 ? 3.0 : 0.0; /* run 2: a circle off the axis */
        sl_stitch_solve_options o;
        sl_stitch_solve_options_init(&o);
        o.centre_from_circle = run != 1;
        o.circles = run == 2 ? circles : NULL;
        sl_stitch_solve_result sr;
        CHECK_OK(sl_stitch_solve(v, 3, &o, &sr, &err), &err);
        off[run] = hypot(sr.lens.cx - g.lens.cx, sr.lens.cy - g.lens.cy);
        for (int i = 1; i < 3; i++)
            pitch[run] = fmax(pitch[run], fabs(sr.pose[i].pitch_deg - g.pose[i].pitch_deg));
        used[run] = sr.centre_from_circle;
        printf("  circles' centre %s: centre %.3f px off, side pitch %.4f deg off, RMS %.3f px; "
               "%s\n",
               run == 0 ? "on" : run == 1 ? "off" : "3 px off the axis", off[run], pitch[run],
               sr.rms_px, sr.centre_note);
        if (run == 2)
            CHECK(strstr(sr.centre_note, "sigma from the overlaps': not used") != NULL);
        sl_stitch_solve_result_free(&sr);
    }
    CHECK(used[0] && off[0] < 0.2 && pitch[0] < 0.01);
    CHECK(!used[1] && off[1] > 0.1 && pitch[1] > 0.03);
    CHECK(!used[2] && fabs(off[2] - off[1]) < 0.01);
    rig_free(&g);
}

/* (c) One view: a partial lat-long, the rest filled and flagged. */
static void one_view(void)
{
    rig g;
    sl_error err;
    if (!rig_checked(&g, "stage", 1))
        return;
    sl_stitch_view v[1];
    oracle_views(&g, v);
    sl_image out;
    sl_stitch_coverage cov;
    CHECK_OK(sl_stitch_blend(v, 1, NULL, &out, &cov, &err), &err);
    if (out.data) {
        printf("  one view: seen %.4f sr, filled %.4f sr (hemisphere %.4f)\n", cov.seen_sr,
               cov.filled_sr, 2 * M_PI);
        CHECK_NEAR(cov.seen_sr, 2 * M_PI, 0.02 * 2 * M_PI);
        CHECK_NEAR(cov.seen_sr + cov.filled_sr, 4 * M_PI, 1e-6);
        CHECK(all_finite_nonnegative(&out));
        /* Behind the view (-Z) nothing was seen: confidence 0 and a fill. */
        const float *back = sl_image_pixel(&out, 0, out.height / 2);
        CHECK(back[3] == 0.0f);
        CHECK(back[1] > 0.0f);
        const float *front = sl_image_pixel(&out, out.width / 2, out.height / 2);
        CHECK(front[3] > 0.9f);
    }
    sl_image_free(&out);
    rig_free(&g);
}

/* (d) A person walks through view 1 where view 2 sees the same place
 * better: the stitch takes view 2 there, and says how much it took alone. */
static void moving_person(void)
{
    rig g;
    sl_error err;
    if (!rig_checked(&g, "stage", 3))
        return;
    /* A direction 70 deg off view 1's axis toward view 2 (50 deg off its
     * axis), on the horizon: azimuth 120 + 70 = 190. */
    double az = 190.0 * M_PI / 180.0, dir[3] = {sin(az), 0.0, cos(az)};
    double m[3][3], ray[3], px, py;
    sl_view_pose_matrix(&g.pose[1], m);
    for (int r = 0; r < 3; r++)
        ray[r] = m[0][r] * dir[0] + m[1][r] * dir[1] + m[2][r] * dir[2];
    CHECK(sl_lens_ray_to_pixel(&g.lens, ray, &px, &py));
    const int radius = 14;
    sl_image walked = {0};
    sl_stitch_view v[3];
    oracle_views(&g, v);
    sl_stitch_blend_options o;
    sl_stitch_blend_options_init(&o);
    double err_on[2] = {0, 0};
    int64_t ghosts[2] = {0, 0};
    sl_image clean = {0};
    CHECK_OK(sl_stitch_blend(v, 3, &o, &clean, NULL, &err), &err);
    if (!clean.data || sl_image_copy(&g.views[1], &walked, &err) != SL_OK) {
        rig_free(&g);
        return;
    }
    v[1].radiance = &walked;
    for (int y = (int)py - radius; y <= (int)py + radius; y++)
        for (int x = (int)px - radius / 2; x <= (int)px + radius / 2; x++) {
            float *p = sl_image_pixel(&walked, x, y);
            p[0] = p[0] * 0.05f + 3.0f; /* a bright coat */
            p[1] = p[1] * 0.05f + 0.5f;
            p[2] = p[2] * 0.05f + 0.2f;
        }
    double u, vv;
    sl_dir_to_latlong(dir, &u, &vv);
    for (int pass = 0; pass < 2; pass++) {
        o.ghost_ratio = pass == 0 ? 0.3 : 0.0; /* pass 1: the test off */
        sl_image out;
        sl_stitch_coverage cov;
        CHECK_OK(sl_stitch_blend(v, 3, &o, &out, &cov, &err), &err);
        if (!out.data)
            break;
        int cx = (int)(u * out.width), cy = (int)(vv * out.height);
        /* Worst relative difference from the stitch without the person
         * over its footprint in the lat-long. */
        for (int y = cy - 12; y <= cy + 12; y++)
            for (int x = cx - 12; x <= cx + 12; x++) {
                const float *s = sl_image_pixel(&out, x, y), *t = sl_image_pixel(&clean, x, y);
                err_on[pass] = fmax(err_on[pass], fabs(sl_luminance_px(s) - sl_luminance_px(t)) / fmax(sl_luminance_px(t), 1e-6));
            }
        ghosts[pass] = cov.ghost_texels;
        sl_image_free(&out);
    }
    sl_image_free(&clean);
    sl_image_free(&walked);
    printf("  moving person: worst relative difference from the stitch without it %.3f with "
           "the ghost test (%lld ghost texels), %.3f without\n",
           err_on[0], (long long)ghosts[0], err_on[1]);
    CHECK(err_on[1] > 0.3); /* without the test the person is blended in */
    CHECK(err_on[0] < 0.5 * 0.3 + 0.01); /* below the test's 0.3: blended */
    CHECK(ghosts[0] > 50);
    rig_free(&g);
}

/* (e) A masked nadir: filled smoothly from the ring around it, flagged. */
static void nadir_mask(void)
{
    rig g;
    sl_error err;
    if (!rig_checked(&g, "stage", 3))
        return;
    sl_stitch_view v[3];
    oracle_views(&g, v);
    sl_stitch_blend_options o;
    sl_stitch_blend_options_init(&o);
    o.nadir_mask_deg = 20;
    sl_image out;
    sl_stitch_coverage cov;
    CHECK_OK(sl_stitch_blend(v, 3, &o, &out, &cov, &err), &err);
    if (out.data) {
        double cap = 2 * M_PI * (1 - cos(20 * M_PI / 180));
        printf("  nadir mask 20 deg: masked %.4f sr (cap %.4f), filled %.4f sr\n", cov.masked_sr,
               cap, cov.filled_sr);
        CHECK_NEAR(cov.masked_sr, cap, 0.03 * cap);
        CHECK(all_finite_nonnegative(&out));
        /* Flagged below -70 deg; the fill within the range of the ring just above. */
        double ring_min = INFINITY, ring_max = 0, fill_min = INFINITY, fill_max = 0;
        int64_t unflagged = 0;
        for (int y = 0; y < out.height; y++) {
            double lat = 90.0 - 180.0 * (y + 0.5) / out.height;
            for (int x = 0; x < out.width; x++) {
                const float *p = sl_image_pixel(&out, x, y);
                if (lat < -70.5) {
                    unflagged += p[3] != 0.0f;
                    fill_min = fmin(fill_min, sl_luminance_px(p));
                    fill_max = fmax(fill_max, sl_luminance_px(p));
                } else if (lat < -67 && lat > -69.5) {
                    ring_min = fmin(ring_min, sl_luminance_px(p));
                    ring_max = fmax(ring_max, sl_luminance_px(p));
                }
            }
        }
        CHECK(unflagged == 0);
        printf("  ring luminance %.4g..%.4g, fill %.4g..%.4g\n", ring_min, ring_max, fill_min,
               fill_max);
        CHECK(fill_min >= 0.5 * ring_min && fill_max <= 1.5 * ring_max);
    }
    sl_image_free(&out);
    rig_free(&g);
}

/* The file call: views as EXR files, the output's attributes, refusals. */
static void files(void)
{
    rig g;
    sl_error err;
    if (!rig_checked(&g, "stage", 3))
        return;
    const char *paths[3];
    char names[3][64];
    for (int i = 0; i < 3; i++) {
        snprintf(names[i], sizeof names[i], "view%d.exr", i);
        paths[i] = strdup(sl_test_path(names[i]));
        CHECK_OK(sl_exr_write(paths[i], &g.views[i], NULL, SL_PIXEL_FLOAT, &err), &err);
    }
    char out[4096];
    snprintf(out, sizeof out, "%s", sl_test_path("stitched.exr"));
    sl_stitch_options o;
    sl_stitch_options_init(&o);
    o.lens = &g.lens;
    for (int i = 0; i < 3; i++) {
        o.yaw_deg[i] = g.pose[i].yaw_deg;
        o.pitch_deg[i] = g.pose[i].pitch_deg;
        o.roll_deg[i] = g.pose[i].roll_deg;
    }
    o.yaw_count = o.pitch_count = o.roll_count = 3;
    o.solve = false;
    sl_stitch_result res;
    CHECK_OK(sl_stitch(paths, 3, out, &o, &res, &err), &err);
    sl_image img;
    sl_meta meta;
    CHECK_OK(sl_exr_read(out, &img, &meta, &err), &err);
    CHECK(img.channels == 4 && img.width == res.coverage.width);
    CHECK(meta.envmap == SL_ENVMAP_LATLONG);
    CHECK(meta.has_chromaticities);
    const char *covtxt = sl_meta_get(&meta, "setlight:stitch:coverage");
    CHECK(covtxt && strstr(covtxt, "seen 1.25"));
    CHECK(sl_meta_get(&meta, "setlight:stitch:views") != NULL);
    /* The same pixels as the in-memory blend (half in the file). */
    sl_stitch_view v[3];
    oracle_views(&g, v);
    sl_image mem;
    CHECK_OK(sl_stitch_blend(v, 3, NULL, &mem, NULL, &err), &err);
    double worst = 0;
    for (int y = 0; mem.data && y < img.height; y += 7)
        for (int x = 0; x < img.width; x += 5) {
            const float *a = sl_image_pixel(&img, x, y), *b = sl_image_pixel(&mem, x, y);
            double e = fabs(a[1] - b[1]) / fmax(fabs(b[1]), 1e-3);
            worst = fmax(worst, e);
        }
    printf("  file vs memory: worst relative difference %.2g (half samples)\n", worst);
    CHECK(worst < 2e-3);
    sl_image_free(&mem);
    sl_image_free(&img);
    sl_meta_free(&meta);

    /* Refusals: nothing left at the output. */
    unlink(out);
    sl_stitch_options bad = o;
    bad.yaw_deg[1] = 180;
    bad.yaw_deg[2] = 180;
    bad.pitch_deg[1] = bad.pitch_deg[2] = 0;
    const char *two[2] = {paths[0], paths[1]};
    CHECK_RESULT(sl_stitch(two, 2, out, &bad, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "do not overlap") && strstr(err.message, "view1.exr"));
    CHECK(access(out, F_OK) != 0);
    /* No lens information: the views carry no EXIF. */
    sl_stitch_options nolens;
    sl_stitch_options_init(&nolens);
    CHECK_RESULT(sl_stitch(paths, 3, out, &nolens, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "view0.exr") && strstr(err.message, "--focal-mm"));
    /* A NaN sample (setlight's writers never write one: refused in memory). */
    sl_image nan_view;
    CHECK_OK(sl_image_copy(&g.views[2], &nan_view, &err), &err);
    sl_image_pixel(&nan_view, VIEW_W / 2, VIEW_H / 2)[1] = NAN;
    v[2].radiance = &nan_view;
    v[2].name = "nan.exr";
    CHECK_RESULT(sl_stitch_blend(v, 3, NULL, &mem, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "nan.exr") && strstr(err.message, "NaN"));
    CHECK(mem.data == NULL);
    /* A view of another size. */
    sl_image small;
    CHECK_OK(sl_image_resample(&g.views[2], VIEW_W / 2, VIEW_H / 2, &small, &err), &err);
    const char *small_path = strdup(sl_test_path("small.exr"));
    CHECK_OK(sl_exr_write(small_path, &small, NULL, SL_PIXEL_FLOAT, &err), &err);
    const char *mixed[3] = {paths[0], paths[1], small_path};
    CHECK_RESULT(sl_stitch(mixed, 3, out, &o, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "small.exr") && strstr(err.message, "480x360"));
    CHECK(access(out, F_OK) != 0);
    sl_image_free(&small);
    sl_image_free(&nan_view);
    free((void *)small_path);
    for (int i = 0; i < 3; i++)
        free((void *)paths[i]);
    rig_free(&g);
}

int main(void)
{
    RUN(oracle_stage_3);
    RUN(oracle_exterior_3);
    RUN(oracle_stage_4);
    RUN(solved_vs_oracle);
    RUN(circle_centre);
    RUN(one_view);
    RUN(moving_person);
    RUN(nadir_mask);
    RUN(files);
    stage3.borrowed = false;
    rig_free(&stage3);
    return sl_test_finish();
}
