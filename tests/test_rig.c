/* SPDX-License-Identifier: BSD-3-Clause */
/* lightrig on synthetic lat-longs with known sources: detection, fitting,
 * selection, residual and ledger, positions, bad options. */
#include <stdlib.h>
#include <string.h>

#include "rig_scenes.h"
#include "setlight/lightrig.h"
#include "testing.h"

#define W 512
#define H 256

/* stage: textured walls, a rotated softbox, a coloured disk, a rectangle
 * across the longitude seam and a disk at the north pole. */
static int make_stage(sl_image *img, scene_light *L)
{
    sl_image_alloc(img, W, H, 3, NULL);
    sc_background(img, 0.5, true);
    sc_add(img, &L[0], 20, 30, 25, tan(6 * M_PI / 180), tan(3 * M_PI / 180), true,
           (double[3]){80, 80, 75});
    sc_add(img, &L[1], 40, -100, 0, 5 * M_PI / 180, 0, false, (double[3]){120, 90, 60});
    sc_add(img, &L[2], 10, 180, 0, tan(5 * M_PI / 180), tan(4 * M_PI / 180), true,
           (double[3]){60, 70, 90});
    sc_add(img, &L[3], 90, 0, 0, 6 * M_PI / 180, 0, false, (double[3]){100, 100, 100});
    return 4;
}

/* Finds the rig light nearest to a true one. */
static const sl_rig_light *nearest(const sl_rig *rig, const double d[3], double *angle)
{
    const sl_rig_light *best = NULL;
    *angle = 1e9;
    for (int i = 0; i < rig->light_count; i++) {
        double a = sc_angle(rig->lights[i].direction, d);
        if (a < *angle) {
            *angle = a;
            best = &rig->lights[i];
        }
    }
    return best;
}

static void check_found(const sl_rig *rig, const scene_light *L, int n, double sa_tol)
{
    for (int i = 0; i < n; i++) {
        double ang;
        const sl_rig_light *f = nearest(rig, L[i].dir, &ang);
        CHECK(f != NULL);
        if (!f)
            continue;
        CHECK_MSG(ang * 180 / M_PI < 1, "light %d: direction off by %.3f deg", i,
                  ang * 180 / M_PI);
        if (sa_tol > 0)
            CHECK_MSG(fabs(f->solid_angle / L[i].solid_angle - 1) < sa_tol,
                      "light %d: solid angle %.4g vs %.4g", i, f->solid_angle, L[i].solid_angle);
        for (int c = 0; c < 3; c++) {
            double p = L[i].rgb[c] * L[i].solid_angle;
            CHECK_MSG(fabs(f->integral[c] / p - 1) < 0.03, "light %d ch %d: power %.5g vs %.5g",
                      i, c, f->integral[c], p);
        }
        printf("  light %d: %s dir %.3f deg, solid angle %+.2f%%, power %+.2f%% (G)\n", i,
               sl_rig_shape_name(f->shape), ang * 180 / M_PI,
               100 * (f->solid_angle / L[i].solid_angle - 1),
               100 * (f->integral[1] / (L[i].rgb[1] * L[i].solid_angle) - 1));
    }
}

static void test_stage(void)
{
    sl_image img;
    scene_light L[4];
    int n = make_stage(&img, L);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == n, "found %d lights, want %d (no false lights on the walls)",
              rig.light_count, n);
    check_found(&rig, L, n, 0.10);
    /* shapes: rectangles as rect, disks as disk */
    for (int i = 0; i < n; i++) {
        double ang;
        const sl_rig_light *f = nearest(&rig, L[i].dir, &ang);
        if (f)
            CHECK_MSG(f->shape == (L[i].rect ? SL_RIG_RECT : SL_RIG_DISK), "light %d is %s", i,
                      sl_rig_shape_name(f->shape));
    }
    /* The softbox: 12 x 6 degrees, rolled 25 degrees. */
    double ang;
    const sl_rig_light *sb = nearest(&rig, L[0].dir, &ang);
    if (sb) {
        CHECK_NEAR(sb->angular_size[0] * 180 / M_PI, 12, 1.2);
        CHECK_NEAR(sb->angular_size[1] * 180 / M_PI, 6, 0.9);
        double d[3], up[3] = {0, 1, 0}, e1[3];
        sc_dir(20, 30, d);
        e1[0] = up[1] * d[2] - up[2] * d[1];
        e1[1] = up[2] * d[0] - up[0] * d[2];
        e1[2] = up[0] * d[1] - up[1] * d[0];
        double l = sqrt(sc_dot(e1, e1));
        double roll = acos(fabs(sc_dot(e1, sb->axis_u)) / l) * 180 / M_PI;
        CHECK_MSG(fabs(roll - 25) < 3, "softbox roll %.2f deg, want 25", roll);
    }
    printf("  ledger relative error %.3g\n", rig.relative_error);
    CHECK(rig.relative_error < 1e-3);
    CHECK(rig.relative_error < 1e-6); /* exact by construction, up to rounding */
    /* The residual dome holds no light any more: its brightest texel is
     * under the detection threshold. */
    double maxl = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            const float *p = sl_image_pixel(&rig.residual, x, y);
            double v = sl_luminance_px(p);
            maxl = v > maxl ? v : maxl;
        }
    printf("  residual max luminance %.3g (threshold %.3g)\n", maxl, rig.threshold_luminance);
    CHECK(maxl < rig.threshold_luminance);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* exterior: sky and a sun of 0.53 degrees at 1e5 x the sky. */
static void test_sun(void)
{
    sl_image img;
    sl_image_alloc(&img, W, H, 3, NULL);
    sc_background(&img, 1.0, false);
    scene_light sun;
    sc_add(&img, &sun, 40, 60, 0, 0.265 * M_PI / 180, 0, false, (double[3]){1e5, 1e5, 0.95e5});
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 1);
    check_found(&rig, &sun, 1, 0.10);
    if (rig.light_count == 1)
        CHECK(rig.lights[0].shape == SL_RIG_DISTANT);
    printf("  ledger relative error %.3g\n", rig.relative_error);
    CHECK(rig.relative_error < 1e-3);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* night: a dark sky with many tiny, very bright lamps; none is lost to the
 * dome even with the default energy cut. */
static void test_night(void)
{
    sl_image img;
    sl_image_alloc(&img, W, H, 3, NULL);
    sc_background(&img, 0.01, true);
    scene_light L[8];
    int n = 8;
    for (int i = 0; i < n; i++) {
        double s = 1 + 0.3 * i; /* unequal: the energy cut would drop the faint ones */
        sc_add(&img, &L[i], -5 + 7 * (i % 3), -170 + 45 * i, 0, 0.2 * M_PI / 180, 0, false,
               (double[3]){2e4 * s, 1.6e4 * s, 0.9e4 * s});
    }
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == n, "night: %d lights, want %d", rig.light_count, n);
    check_found(&rig, L, n, 0);
    CHECK(rig.relative_error < 1e-3);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* A fixture seen as two fragments (a bar across it) is one light. */
static void test_fragments(void)
{
    sl_image img;
    sl_image_alloc(&img, W, H, 3, NULL);
    sc_background(&img, 0.5, false);
    scene_light a, b;
    sc_add(&img, &a, 0, 0, 0, tan(2 * M_PI / 180), tan(4 * M_PI / 180), true,
           (double[3]){100, 100, 100});
    sc_add(&img, &b, 0, 5, 0, tan(2 * M_PI / 180), tan(4 * M_PI / 180), true,
           (double[3]){100, 100, 100});
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 1, "fragments: %d lights", rig.light_count);
    if (rig.light_count == 1) {
        double d[3];
        sc_dir(0, 2.5, d);
        CHECK(sc_angle(rig.lights[0].direction, d) < 0.5 * M_PI / 180);
        CHECK_NEAR(rig.lights[0].integral[0] / (100 * (a.solid_angle + b.solid_angle)), 1, 0.03);
    }
    sl_rig_free(&rig);
    opt.merge_degrees = 0.1;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 2, "unmerged fragments: %d lights", rig.light_count);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* A lamp in front of the bright surface it lights (a white cyclorama at 20x
 * the sky, well above the threshold): the lamp alone is the light. */
static void test_lamp_on_cyc(void)
{
    sl_image img;
    sl_image_alloc(&img, W, H, 3, NULL);
    sc_background(&img, 0.5, false);
    scene_light cyc, lamp;
    sc_add(&img, &cyc, 0, -60, 0, tan(40 * M_PI / 180), tan(15 * M_PI / 180), true,
           (double[3]){10, 10, 10});
    sc_add(&img, &lamp, 10, -50, 0, 3 * M_PI / 180, 0, false, (double[3]){2000, 1900, 1700});
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 1, "lamp on cyc: %d lights", rig.light_count);
    if (rig.light_count >= 1) {
        double ang = sc_angle(rig.lights[0].direction, lamp.dir);
        CHECK_MSG(ang < M_PI / 180, "lamp direction off by %.2f deg", ang * 180 / M_PI);
        CHECK_NEAR(rig.lights[0].integral[1] / (1900 * lamp.solid_angle), 1, 0.03);
        CHECK_NEAR(rig.lights[0].solid_angle / lamp.solid_angle, 1, 0.10);
    }
    CHECK(rig.relative_error < 1e-6);
    sl_rig_free(&rig);
    /* without the peak rule the cyc joins the lamp and pulls it off */
    opt.peak_fraction = 0;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 1 && sc_angle(rig.lights[0].direction, lamp.dir) > 2 * M_PI / 180);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* A wide bright patch (a lit wall, a sky) stays in the dome. */
static void test_wide(void)
{
    sl_image img;
    sl_image_alloc(&img, W, H, 3, NULL);
    sc_background(&img, 0.5, false);
    scene_light wall;
    sc_add(&img, &wall, 10, 90, 0, tan(25 * M_PI / 180), tan(20 * M_PI / 180), true,
           (double[3]){20, 20, 20});
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 0 && rig.skipped_count == 1);
    if (rig.skipped_count == 1) {
        CHECK(strstr(rig.skipped[0].reason, "area") != NULL);
        CHECK_NEAR(rig.skipped[0].solid_angle / wall.solid_angle, 1, 0.05);
    }
    CHECK_NEAR(rig.dome[1] / rig.original[1], 1, 1e-9);
    sl_rig_free(&rig);
    opt.max_solid_angle = 0;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 1 && rig.lights[0].shape == SL_RIG_RECT);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

static void test_selection(void)
{
    sl_image img;
    scene_light L[4];
    make_stage(&img, L);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    sl_error err;
    opt.energy = 0.5;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count >= 1 && rig.light_count < 4);
    CHECK(rig.light_count + rig.skipped_count == 4);
    double kept = 0, kept_g = 0;
    for (int i = 0; i < rig.light_count; i++) {
        const sl_rig_light *a = &rig.lights[i], *b = &rig.lights[i ? i - 1 : 0];
        kept += a->share;
        kept_g += a->share_glossy;
        /* ranked by the larger of the grey and glossy shares */
        CHECK(fmax(a->share, a->share_glossy) <= fmax(b->share, b->share_glossy));
    }
    CHECK(kept >= 0.5 && kept_g >= 0.5);
    /* smallest set: without its last light it would not reach the share */
    const sl_rig_light *last = &rig.lights[rig.light_count - 1];
    CHECK(kept - last->share < 0.5 || kept_g - last->share_glossy < 0.5);
    for (int i = 0; i < rig.skipped_count; i++)
        CHECK(strstr(rig.skipped[i].reason, "energy") != NULL);
    CHECK(rig.relative_error < 1e-6);
    sl_rig_free(&rig);

    opt.energy = 1;
    opt.max_lights = 2;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 2 && rig.skipped_count == 2);
    for (int i = 0; i < rig.skipped_count; i++)
        CHECK(strstr(rig.skipped[i].reason, "--max-lights 2") != NULL);
    CHECK(rig.relative_error < 1e-6);
    /* the skipped lights stay in the dome: its integral grows by theirs */
    double dome_g = rig.dome[1], skipped_g = 0;
    for (int i = 0; i < rig.skipped_count; i++)
        skipped_g += rig.skipped[i].integral[1];
    sl_rig_free(&rig);
    opt.max_lights = 0;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_NEAR(dome_g / (rig.dome[1] + skipped_g), 1, 1e-3);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* A 40-degree soft source with 92% of the power and a small bright lamp
 * with 8%: a grey sphere is 92% lit by the soft one alone, but a GGX 0.3
 * sphere's highlights only 90%- (a wide source spreads its highlight), so
 * --energy 0.9 keeps the lamp, --energy 0.88 does not. */
static void test_glossy_rank(void)
{
    sl_image img;
    scene_light L[2];
    sl_image_alloc(&img, W, H, 3, NULL);
    sc_background(&img, 0.05, false);
    sc_add(&img, &L[0], 30, 40, 0, 20 * M_PI / 180, 0, false, (double[3]){20, 20, 20});
    double soft = 20 * L[0].solid_angle, lamp_rad = soft * (0.08 / 0.92);
    double r = 1.5 * M_PI / 180, om = 2 * M_PI * (1 - cos(r));
    double lv = lamp_rad / om;
    sc_add(&img, &L[1], 20, -80, 0, r, 0, false, (double[3]){lv, lv, lv});
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 0.9;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 2, "%d lights kept", rig.light_count);

    if (rig.light_count == 2) {
        const sl_rig_light *big = &rig.lights[0], *lamp = &rig.lights[1];
        if (big->solid_angle < lamp->solid_angle) {
            const sl_rig_light *t = big;
            big = lamp;
            lamp = t;
        }
        printf("  soft source: grey %.3f glossy %.3f; lamp: grey %.3f glossy %.3f\n",
               big->share, big->share_glossy, lamp->share, lamp->share_glossy);
        CHECK(big->share > 0.9 && big->share_glossy < 0.9);
        CHECK_NEAR(big->share + lamp->share, 1, 1e-9);
        CHECK_NEAR(big->share_glossy + lamp->share_glossy, 1, 1e-9);
    }
    sl_rig_free(&rig);
    opt.energy = 0.88;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 1 && rig.skipped_count == 1, "energy 0.88: %d lights kept",
              rig.light_count);
    if (rig.skipped_count == 1)
        CHECK(strstr(rig.skipped[0].reason, "glossy") != NULL);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* Solid angle of a w x h rectangle at distance t facing the viewer. */
static double rect_omega(double w, double h, double t)
{
    double a = w / (2 * t), b = h / (2 * t);
    return 4 * asin(a * b / sqrt((1 + a * a) * (1 + b * b)));
}

static void test_positions(void)
{
    sl_image img;
    scene_light L[4];
    make_stage(&img, L);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    opt.room[0] = 8;
    opt.room[1] = 6;
    opt.room[2] = 4;
    opt.capture_height = 1.5;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    for (int i = 0; i < rig.light_count; i++) {
        const sl_rig_light *f = &rig.lights[i];
        CHECK(f->has_position);
        const double *p = f->position;
        /* on the box: one coordinate on a wall, the others inside */
        double m = fmax(fmax(fabs(p[0]) / 4, fabs(p[2]) / 3),
                        p[1] > 0 ? p[1] / 2.5 : -p[1] / 1.5);
        CHECK_NEAR(m, 1, 1e-9);
        double t = sqrt(sc_dot(p, p));
        CHECK_NEAR(sc_dot(p, f->direction) / t, 1, 1e-12);
        double om = f->shape == SL_RIG_RECT
                        ? rect_omega(f->size[0], f->size[1], t)
                        : 2 * M_PI * (1 - sqrt(1 - pow(f->size[0] / (2 * t), 2)));
        CHECK_NEAR(om / f->solid_angle, 1, 1e-6);
        CHECK(f->shape == SL_RIG_RECT || f->shape == SL_RIG_SPHERE);
    }
    sl_rig_free(&rig);
    opt.room[0] = opt.room[1] = opt.room[2] = 0;
    opt.distance = 3;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    for (int i = 0; i < rig.light_count; i++)
        CHECK_NEAR(sqrt(sc_dot(rig.lights[i].position, rig.lights[i].position)), 3, 1e-9);
    sl_rig_free(&rig);
    /* a room that does not contain the capture point */
    opt.distance = 0;
    opt.room[0] = 8;
    opt.room[1] = 6;
    opt.room[2] = 2;
    opt.capture_height = 2.5;
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "does not contain") != NULL);
    CHECK(rig.lights == NULL && rig.light_count == 0);
    sl_image_free(&img);
}

static void test_bad_maps(void)
{
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    sl_error err;
    sl_image img;
    /* black: an empty rig */
    sl_image_alloc(&img, 64, 32, 3, NULL);
    sl_image_fill(&img, 0);
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 0 && rig.relative_error == 0 && rig.original[0] == 0);
    sl_rig_free(&rig);
    /* NaN and Inf: counted and treated as 0 */
    sc_background(&img, 0.5, false);
    sl_image_pixel(&img, 3, 4)[0] = NAN;
    sl_image_pixel(&img, 10, 20)[1] = INFINITY;
    sl_image_pixel(&img, 11, 20)[2] = -INFINITY;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.nonfinite == 3);
    CHECK(isfinite(rig.original[0]) && rig.relative_error < 1e-6);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++)
            for (int c = 0; c < 3; c++)
                CHECK_MSG(isfinite(sl_image_pixel(&rig.residual, x, y)[c]),
                          "residual %d,%d not finite", x, y);
    sl_rig_free(&rig);
    sl_image_free(&img);
    /* not 2:1 */
    sl_image_alloc(&img, 60, 32, 3, NULL);
    sl_image_fill(&img, 1);
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "2:1") != NULL);
    sl_image_free(&img);
    /* too small, and the smallest accepted */
    sl_image_alloc(&img, 6, 3, 3, NULL);
    sl_image_fill(&img, 1);
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "too small") != NULL);
    sl_image_free(&img);
    sl_image_alloc(&img, 8, 4, 3, NULL);
    sl_image_fill(&img, 1);
    sl_image_pixel(&img, 3, 1)[1] = 1000;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 1 && rig.relative_error < 1e-6);
    sl_rig_free(&rig);
    sl_image_free(&img);
    /* bad options */
    sl_image_alloc(&img, 64, 32, 3, NULL);
    sl_image_fill(&img, 1);
    opt.max_lights = -1;
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_USAGE, &err);
    sl_rig_options_default(&opt);
    opt.energy = 1.5;
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_USAGE, &err);
    sl_image_free(&img);
}

/* Median cut with the same number of lights: exact ledger, and a grey
 * sphere's irradiance further from the map's than the rig's. */
static void test_mediancut(void)
{
    sl_image img;
    scene_light L[4];
    make_stage(&img, L);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig, mc;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    opt.method = SL_RIG_METHOD_MEDIANCUT;
    opt.max_lights = rig.light_count;
    CHECK_OK(sl_rig_extract(&img, &opt, &mc, &err), &err);
    CHECK(mc.light_count == rig.light_count);
    CHECK(mc.relative_error < 1e-6);
    CHECK(mc.dome[0] == 0);
    double e_rig = rig_rmse(&img, &rig), e_mc = rig_rmse(&img, &mc);
    printf("  grey-sphere irradiance relative RMSE: rig %.4f%%, median cut (%d lights) %.4f%%\n",
           100 * e_rig, mc.light_count, 100 * e_mc);
    CHECK(e_rig < 0.01);
    CHECK(e_rig < e_mc);
    sl_rig_free(&mc);
    /* power-of-two counts follow Debevec: equal-energy regions */
    opt.max_lights = 16;
    CHECK_OK(sl_rig_extract(&img, &opt, &mc, &err), &err);
    CHECK(mc.light_count == 16);
    for (int i = 0; i < mc.light_count; i++)
        CHECK_MSG(fabs(mc.lights[i].share * 16 - 1) < 0.5, "median cut share %g",
                  mc.lights[i].share);
    sl_rig_free(&mc);
    sl_rig_free(&rig);
    sl_image_free(&img);
}

/* Artist tags: an exclude leaves a light in the dome, an include makes a
 * light of a region under the threshold. */
static void test_tags(void)
{
    sl_image img;
    scene_light L[4], faint;
    make_stage(&img, L);
    sc_add(&img, &faint, 50, 120, 0, 4 * M_PI / 180, 0, false, (double[3]){2, 2, 2});
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    sl_error err;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 4, "faint patch found without a tag: %d lights", rig.light_count);
    double dome0 = rig.dome[1];
    sl_rig_free(&rig);

    opt.exclude[0][0] = 40.3; /* near, not exactly on, the disk's centre */
    opt.exclude[0][1] = -100.5;
    opt.exclude_count = 1;
    opt.include[0][0] = 50;
    opt.include[0][1] = 120;
    opt.include_count = 1;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_MSG(rig.light_count == 4 && rig.skipped_count == 1, "tags: %d lights, %d skipped",
              rig.light_count, rig.skipped_count);
    if (rig.skipped_count == 1) {
        CHECK(strstr(rig.skipped[0].reason, "--exclude 40.3,-100.5") != NULL);
        CHECK(sc_angle(rig.skipped[0].direction, L[1].dir) < M_PI / 180);
    }
    double ang;
    const sl_rig_light *f = nearest(&rig, faint.dir, &ang);
    CHECK(f && ang < M_PI / 180);
    if (f) {
        /* its power above the sky behind it */
        double bg = 0.5 * (0.6 + 0.4 * sin(50 * M_PI / 180)) * 0.9;
        printf("  included faint light: dir %.3f deg, power %+.2f%%\n", ang * 180 / M_PI,
               100 * (f->integral[1] / ((2 - bg) * faint.solid_angle) - 1));
        CHECK_NEAR(f->integral[1] / ((2 - bg) * faint.solid_angle), 1, 0.03);
    }
    nearest(&rig, L[1].dir, &ang);
    CHECK(ang > 10 * M_PI / 180); /* the excluded disk is not a light */
    CHECK(rig.relative_error < 1e-6);
    /* the excluded disk went back to the dome, the faint one left it */
    CHECK(rig.dome[1] > dome0 + 0.9 * L[1].rgb[1] * L[1].solid_angle - f->integral[1] - 0.05);
    sl_rig_free(&rig);

    /* more includes than --max-lights; an include where the map is black */
    opt.max_lights = 1;
    opt.include[1][0] = 20;
    opt.include[1][1] = 30;
    opt.include_count = 2;
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_USAGE, &err);
    opt.max_lights = 0;
    opt.include[0][0] = 95;
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_USAGE, &err);
    sl_image_fill(&img, 0);
    opt.include[0][0] = 0;
    opt.include_count = 1;
    opt.exclude_count = 0;
    CHECK_RESULT(sl_rig_extract(&img, &opt, &rig, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "black") != NULL);
    sl_image_free(&img);
}

int main(void)
{
    RUN(test_stage);
    RUN(test_sun);
    RUN(test_night);
    RUN(test_fragments);
    RUN(test_lamp_on_cyc);
    RUN(test_wide);
    RUN(test_selection);
    RUN(test_glossy_rank);
    RUN(test_positions);
    RUN(test_bad_maps);
    RUN(test_mediancut);
    RUN(test_tags);
    return sl_test_finish();
}
