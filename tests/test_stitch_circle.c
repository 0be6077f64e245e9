/* SPDX-License-Identifier: BSD-3-Clause */
/* The image circle of fisheye views: the virtual set's true lens (off its
 * nominal centre and focal length) through exterior (a sun in the circle),
 * stage and night, rendered and also shot and merged; not-fisheye images
 * refused; the real Sigma 8mm frames when the shared data is there. "True"
 * is the circle where theta = 90 deg through the true lens: centre (cx, cy),
 * radius circle_radius_px. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/stitch.h"
#include "testing.h"

static void scene_latlong(const char *name, int width, sl_vset_scene *sc)
{
    sl_vset_desc desc;
    sl_error err;
    CHECK_OK(sl_vset_preset(name, &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, width, sc, &err), &err);
}

/* Distance of the found circle's centre from the lens's, and of its radius. */
static void circle_error(const sl_stitch_circle *c, const sl_lens *lens, double *centre,
                         double *radius)
{
    *centre = hypot(c->cx - lens->cx, c->cy - lens->cy);
    *radius = fabs(c->radius - lens->circle_radius_px);
}

/* Rendered views through the true lens, at the head's true poses. */
static void rendered_views(void)
{
    static const char *const scenes[] = {"exterior", "stage", "night"};
    static const sl_view_pose plans[] = {{0, 0, 0}, {60, 0, 0}, {0, 90, 0}};
    double worst_c = 0, worst_r = 0;
    for (int s = 0; s < 3; s++) {
        sl_vset_scene sc;
        scene_latlong(scenes[s], 512, &sc);
        for (int v = 0; v < 3; v++) {
            const int w = v == 2 ? 600 : 720, h = v == 2 ? 400 : 480;
            sl_lens lens, nominal;
            sl_vset_fisheye_true(&lens, w, h);
            sl_vset_fisheye_nominal(&nominal, w, h);
            sl_view_pose pose;
            sl_vset_head_pose(7, v, &plans[v], &pose);
            sl_image img;
            sl_error err;
            CHECK_OK(sl_vset_view_image(&lens, &pose, &sc.latlong, 2, &img, &err), &err);
            sl_stitch_circle c;
            CHECK_OK(sl_stitch_circle_find(&img, scenes[s], &nominal, &c, &err), &err);
            double ec, er;
            circle_error(&c, &lens, &ec, &er);
            printf("  %-8s yaw %5.1f pitch %4.1f %dx%d: centre %.3f,%.3f (true %.3f,%.3f) "
                   "radius %.3f (true %.3f): off %.3f px, radius %.3f px; rms %.3f px, "
                   "%.1f%% of rays; %.4f x nominal\n",
                   scenes[s], pose.yaw_deg, pose.pitch_deg, w, h, c.cx, c.cy, lens.cx, lens.cy,
                   c.radius, lens.circle_radius_px, ec, er, c.rms_px, 100 * c.support,
                   c.radius_vs_nominal);
            worst_c = fmax(worst_c, ec);
            worst_r = fmax(worst_r, er);
            CHECK(c.support > 0.8);
            CHECK_NEAR(c.radius_vs_nominal, lens.circle_radius_px / nominal.circle_radius_px,
                       0.005);
            sl_image_free(&img);
        }
        sl_vset_scene_free(&sc);
    }
    printf("  rendered: worst centre %.3f px, worst radius %.3f px\n", worst_c, worst_r);
    CHECK(worst_c < 0.5);
    CHECK(worst_r < 0.5);
}

static void check_refused(const sl_image *img, const char *name)
{
    sl_stitch_circle c;
    sl_error err;
    CHECK_RESULT(sl_stitch_circle_find(img, name, NULL, &c, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, name) == err.message && strstr(err.message, "no image circle"),
              "message: %s", err.message);
    CHECK(strchr(err.message, '\n') == NULL);
    printf("  refused: %s\n", err.message);
}

/* A rectilinear view, a lat-long and a chrome ball have no image circle. */
static void refusals(void)
{
    sl_vset_scene sc;
    scene_latlong("stage", 512, &sc);
    sl_error err;
    sl_lens rect;
    sl_lens_nominal(&rect, SL_LENS_RECTILINEAR, 360, 240, 24, 36);
    sl_view_pose pose = {30, 5, 0};
    sl_image img;
    CHECK_OK(sl_vset_view_image(&rect, &pose, &sc.latlong, 2, &img, &err), &err);
    check_refused(&img, "rectilinear.exr");
    sl_image_free(&img);
    check_refused(&sc.latlong, "latlong.exr");
    /* The chrome ball, cropped tight round it. */
    sl_vset_probe p;
    sl_vset_probe_geometry g;
    sl_vset_probe_default(&p, SL_VSET_PROBE_CHROME, 240, 160);
    p.spp = 2;
    CHECK_OK(sl_vset_probe_render(&p, &sc.latlong, &img, &g, &err), &err);
    int half = (int)ceil(g.r * 1.15), x0 = (int)(g.cx - half), y0 = (int)(g.cy - half);
    sl_image crop;
    CHECK_OK(sl_image_alloc(&crop, 2 * half, 2 * half, 3, &err), &err);
    for (int y = 0; y < crop.height; y++)
        for (int x = 0; x < crop.width; x++)
            memcpy(sl_image_pixel(&crop, x, y), sl_image_pixel(&img, x0 + x, y0 + y),
                   3 * sizeof(float));
    check_refused(&crop, "ball.exr");
    sl_image_free(&crop);
    sl_image_free(&img);
    /* A black frame. */
    CHECK_OK(sl_image_alloc(&img, 64, 48, 3, &err), &err);
    check_refused(&img, "black.exr");
    sl_image_free(&img);
    sl_vset_scene_free(&sc);
}

/* The real Sigma 8mm on a Canon 6D Mark II, read as linear. */
static void real_sigma(void)
{
    static const char *const frames[] = {"IMG_2843.JPG", "IMG_2900.JPG", "IMG_2901.JPG",
                                         "IMG_2920.JPG", "IMG_2921.JPG"};
    sl_stitch_circle first = {0};
    for (int i = 0; i < 5; i++) {
        char rel[256];
        snprintf(rel, sizeof rel, "fisheye/sigma8mm_canon6d/%s", frames[i]);
        const char *path = sl_test_data(rel);
        if (!path)
            return;
        sl_image img;
        sl_meta meta;
        sl_read_info info;
        sl_error err;
        CHECK_OK(sl_image_read_linear(path, NULL, &img, &meta, &info, &err), &err);
        sl_stitch_circle c;
        CHECK_OK(sl_stitch_circle_find(&img, frames[i], NULL, &c, &err), &err);
        printf("  %s %dx%d (%s %s, %g mm): circle %.2f,%.2f r %.2f, rms %.3f px, %.1f%% of "
               "rays\n",
               frames[i], img.width, img.height, meta.model, meta.lens, meta.focal_length_mm,
               c.cx, c.cy, c.radius, c.rms_px, 100 * c.support);
        /* The rim is soft over ~15 px and has a bright flare ring: fewer
         * rays than on the virtual set, but one camera and lens give one
         * circle in every frame. */
        CHECK(c.support > 0.6 && c.rms_px < 1.5);
        if (i == 0)
            first = c;
        double moved = hypot(c.cx - first.cx, c.cy - first.cy);
        CHECK_MSG(moved < 1.0 && fabs(c.radius - first.radius) < 1.0,
                  "%s: circle %.2f px from the first frame's, radius %+.2f px", frames[i], moved,
                  c.radius - first.radius);
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
}

/* The night scene as `setlight simulate --scene night --size tiny` shoots
 * it (long exposures at ISO 400) and merged: the frame's border is read and
 * shot noise round a low level, not black, and the night sky inside is
 * only about 14 times that level (its 90th percentile is 0.17-0.18 of the
 * centre's median, over sl_fisheye_check's 0.15). The circle's edge is
 * still a step: found on the true lens's circle, and again with more read
 * noise added (sigma 0.15 of the inside's median, a darker night or a
 * higher ISO); noise with no circle in it is refused. */
static double gauss(uint64_t *state)
{
    double u1 = ((double)(sl_splitmix64(state) >> 11) + 1.0) / 9007199254740993.0;
    double u2 = (double)(sl_splitmix64(state) >> 11) / 9007199254740992.0;
    return sqrt(-2.0 * log(u1)) * cos(2.0 * M_PI * u2);
}

static void add_noise(sl_image *img, double sigma, uint64_t seed)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            double n = sigma * gauss(&seed); /* one read noise for the three channels */
            for (int c = 0; c < 3; c++)
                p[c] = p[c] + n > 0.0 ? (float)(p[c] + n) : 0.0f;
        }
}

static void check_on_truth(const sl_image *img, const char *name, double tolerance_px)
{
    sl_lens truth;
    sl_vset_fisheye_true(&truth, img->width, img->height);
    sl_stitch_circle c;
    sl_error err;
    CHECK_OK(sl_stitch_circle_find(img, name, NULL, &c, &err), &err);
    double off = hypot(c.cx - truth.cx, c.cy - truth.cy);
    printf("  %s %dx%d: circle %.3f,%.3f r %.3f (true %.3f,%.3f r %.3f): off %.3f px, radius "
           "%+.3f px; rms %.3f px, %.1f%% of rays\n",
           name, img->width, img->height, c.cx, c.cy, c.radius, truth.cx, truth.cy,
           truth.circle_radius_px, off, c.radius - truth.circle_radius_px, c.rms_px,
           100 * c.support);
    CHECK(off < tolerance_px);
    CHECK_NEAR(c.radius, truth.circle_radius_px, tolerance_px);
    CHECK(c.support > 0.6);
}

static void night_shot(void)
{
    sl_vset_desc desc;
    sl_vset_capture_opts o;
    sl_error err;
    CHECK_OK(sl_vset_preset("night", &desc, &err), &err);
    sl_vset_capture_defaults(&o, &desc, SL_VSET_SIZE_TINY);
    o.probe_width = 0;
    o.views = 1;
    o.force = true;
    const char *dir = sl_test_path("night_capture");
    CHECK_OK(sl_vset_capture_write(&o, dir, NULL, &err), &err);
    char paths[16][4096];
    const char *ptrs[16];
    int n = o.brackets < 16 ? o.brackets : 16;
    for (int i = 0; i < n; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/hdri/IMG_%04d_linear.tif", dir, 1 + i);
        ptrs[i] = paths[i];
    }
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_merge_result m;
    CHECK_OK(sl_merge(ptrs, n, &opt, &m, &err), &err);
    if (!m.radiance.data)
        return;
    check_on_truth(&m.radiance, "night", 0.5);

    /* The inside's level: the median luminance within half the circle. */
    sl_lens truth;
    sl_vset_fisheye_true(&truth, m.radiance.width, m.radiance.height);
    double *inside = malloc((size_t)m.radiance.width * m.radiance.height * sizeof *inside);
    int k = 0;
    for (int y = 0; inside && y < m.radiance.height; y++)
        for (int x = 0; x < m.radiance.width; x++)
            if (hypot(x + 0.5 - truth.cx, y + 0.5 - truth.cy) < 0.5 * truth.circle_radius_px)
                inside[k++] = sl_luminance_px(sl_image_pixel(&m.radiance, x, y));
    qsort(inside, (size_t)k, sizeof *inside, sl_cmp_double);
    double level = k ? inside[k / 2] : 0.0;
    free(inside);
    CHECK(level > 0.0);
    add_noise(&m.radiance, 0.15 * level, 19);
    check_on_truth(&m.radiance, "night + read noise", 1.0);

    /* Noise alone: no circle, whether round the night sky's level or
     * round black (half the pixels clamped to 0). */
    sl_image noise;
    CHECK_OK(sl_image_alloc(&noise, m.radiance.width, m.radiance.height, 3, &err), &err);
    for (int y = 0; y < noise.height; y++)
        for (int x = 0; x < noise.width; x++)
            for (int c = 0; c < 3; c++)
                sl_image_pixel(&noise, x, y)[c] = (float)level;
    add_noise(&noise, 0.3 * level, 23);
    check_refused(&noise, "noise.exr");
    memset(noise.data, 0, (size_t)noise.width * noise.height * 3 * sizeof(float));
    add_noise(&noise, level, 29);
    check_refused(&noise, "black_noise.exr");
    sl_image_free(&noise);
    sl_merge_result_free(&m);
}

int main(void)
{
    RUN(rendered_views);
    RUN(night_shot);
    RUN(refusals);
    RUN(real_sigma);
    return sl_test_finish();
}
