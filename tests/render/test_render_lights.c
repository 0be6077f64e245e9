/* SPDX-License-Identifier: BSD-3-Clause */
/* Area and distant lights on the grey sphere against closed-form irradiance,
 * a 1e-6 sr rect light, shadows on the ground, chi-square of the light
 * samplers, UsdLux normalisation and rig files with bad input. */
#include <stdlib.h>
#include <string.h>

#include "../../render/sampler.h"
#include "../../render/scene_internal.h"
#include "../../render/vec3.h"
#include "testing.h"

/* Sanitizer builds run about 20x slower: fewer pixels, same per-pixel checks. */
#if defined(__SANITIZE_ADDRESS__)
#define VS_SIZE 6
#else
#define VS_SIZE 12
#endif

static void base_light(sl_light *l, sl_light_type type, const double pos[3], const double emit[3])
{
    memset(l, 0, sizeof *l);
    l->type = type;
    v3_copy(l->position, pos);
    for (int i = 0; i < 3; i++)
        l->axis_z[i] = -emit[i];
    v3_set(l->axis_y, 0, 1, 0);
    if (fabs(emit[1]) > 0.9)
        v3_set(l->axis_y, 0, 0, 1);
    v3_set(l->color, 1, 1, 1);
    l->intensity = 1;
}

typedef double (*irradiance_fn)(const double p[3], const double n[3], const sl_light *l);

/* Grey sphere lit by n lights; each pixel lit by every light (E(n) > 0 from
 * `irr` for each) against the sum of E over the lights with counts[i]. With
 * one light and one shape nothing occludes: no shadow rays. */
static double render_vs_lights(const sl_light *protos, int n_lights, const bool *counts,
                               irradiance_fn irr, int64_t spp, int64_t *shadow_rays)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", VS_SIZE, &err), &err);
    for (int i = 0; i < n_lights; i++) {
        sl_light l = protos[i];
        if (protos[i].texture.data) /* the scene takes over its own copy */
            CHECK_OK(sl_image_copy(&protos[i].texture, &l.texture, NULL), NULL);
        CHECK_OK(sl_scene_add_light(&s, &l, &err), &err);
    }
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.pixel_centers = true;
    o.closed_form = false; /* the sampler against the closed forms */
    sl_image img;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    CHECK(st.nonfinite_samples == 0);
    if (n_lights == 1)
        CHECK(st.shadow_rays == 0 && st.shadow_rays_skipped > 0); /* one shape: nothing occludes */
    if (shadow_rays)
        *shadow_rays = st.shadow_rays;
    double worst = 0;
    int lit = 0;
    for (int py = 0; py < VS_SIZE; py++)
        for (int px = 0; px < VS_SIZE; px++) {
            double x = 2.0 * (px + 0.5) / VS_SIZE - 1.0, y = 1.0 - 2.0 * (py + 0.5) / VS_SIZE;
            if (x * x + y * y >= 1)
                continue;
            double n[3] = {-x, y, -sqrt(1 - x * x - y * y)}, E = 0;
            bool all = true;
            for (int i = 0; i < n_lights; i++) {
                double e = irr(n, n, &s.lights[i]);
                all = all && e > 0;
                E += counts[i] ? e : 0.0;
            }
            if (!all)
                continue;
            double ref = 0.18 / SL_PI * E, val = sl_image_pixel(&img, px, py)[0];
            worst = fmax(worst, fabs(val - ref) / ref);
            lit++;
        }
    CHECK(lit > VS_SIZE);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    return worst;
}

static double render_vs(const sl_light *proto, irradiance_fn irr, int64_t spp, double *worst_out)
{
    static const bool one = true;
    *worst_out = render_vs_lights(proto, 1, &one, irr, spp, NULL);
    return *worst_out;
}

/* A uniform sphere fully above the horizon irradiates like a point:
 * E = L pi r^2 cos(beta) / d^2. Returns 0 when partly below the horizon. */
static double irr_sphere(const double p[3], const double n[3], const sl_light *l)
{
    double d[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
    double dist = v3_length(d), cb = v3_dot(d, n) / dist, sa = l->radius / dist;
    if (cb <= sa + 0.02)
        return 0;
    return l->radiance[0] * SL_PI * l->radius * l->radius * cb / (dist * dist);
}

/* A cone of half-angle a fully above the horizon: E = L pi sin^2(a) cos(beta). */
static double irr_distant(const double p[3], const double n[3], const sl_light *l)
{
    (void)p;
    double a = 0.5 * l->angle_deg * SL_PI / 180, cb = v3_dot(l->axis_z, n);
    if (cb <= sin(a) + 0.02)
        return 0;
    return l->angle_deg > 0 ? l->radiance[0] * SL_PI * sin(a) * sin(a) * cb : l->radiance[0] * cb;
}

/* Small planar emitter far away: L A cos(theta_l) cos(beta) / d^2, to O((size/d)^2). */
static double irr_small_planar(const double p[3], const double n[3], const sl_light *l)
{
    double d[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
    double dist = v3_length(d);
    double cb = v3_dot(d, n) / dist, cl = v3_dot(d, l->axis_z) / dist;
    if (cb <= 0.02 || cl <= 0)
        return 0;
    double area = l->type == SL_LIGHT_RECT ? l->width * l->height : SL_PI * l->radius * l->radius;
    return l->radiance[0] * area * cl * cb / (dist * dist);
}

static void test_sphere_light(void)
{
    const double pos[3] = {1.5, 2.0, -3.0}, emit[3] = {0, -1, 0};
    sl_light l;
    base_light(&l, SL_LIGHT_SPHERE, pos, emit);
    l.radius = 0.5;
    l.intensity = 10;
    double worst;
    render_vs(&l, irr_sphere, 256, &worst);
    printf("  sphere light: worst %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
}

static void test_distant_lights(void)
{
    double dir[3] = {0.3, -0.5, 0.8}; /* toward +Z, down: lights the side facing the camera */
    v3_normalize(dir);
    const double pos[3] = {0, 0, 0};
    double worst;
    sl_light l;
    base_light(&l, SL_LIGHT_DISTANT, pos, dir);
    l.angle_deg = 0; /* delta: exact with one sample */
    l.intensity = 3;
    render_vs(&l, irr_distant, 2, &worst);
    printf("  delta distant: worst %.2e\n", worst);
    CHECK(worst < 1e-6);
    base_light(&l, SL_LIGHT_DISTANT, pos, dir);
    l.angle_deg = 10;
    l.intensity = 3;
    l.normalize = true; /* illuminance at normal incidence = 3 */
    render_vs(&l, irr_distant, 256, &worst);
    printf("  10 degree distant: worst %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
}

static void test_planar_lights(void)
{
    const double pos[3] = {-2, 3, -8}, emit[3] = {0.2, -0.3, 0.8};
    double e[3] = {emit[0], emit[1], emit[2]}, worst;
    v3_normalize(e);
    sl_light l;
    base_light(&l, SL_LIGHT_RECT, pos, e);
    l.width = 0.01, l.height = 0.0086; /* about 1e-6 sr from the sphere */
    l.intensity = 1e6;
    render_vs(&l, irr_small_planar, 16, &worst);
    printf("  1e-6 sr rect: worst %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
    base_light(&l, SL_LIGHT_DISK, pos, e);
    l.radius = 0.05;
    l.intensity = 1e4;
    render_vs(&l, irr_small_planar, 64, &worst);
    printf("  small disk: worst %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
}

/* A big rect close by: spherical-rectangle sampling against a brute-force
 * quadrature of the rect's area (cos cos / d^2). */
static double irr_rect_quadrature(const double p[3], const double n[3], const sl_light *l)
{
    const int N = 200;
    double E = 0;
    for (int a = 0; a < N; a++)
        for (int b = 0; b < N; b++) {
            double q[3], d[3];
            for (int i = 0; i < 3; i++) {
                q[i] = l->position[i] + ((a + 0.5) / N - 0.5) * l->width * l->axis_x[i] +
                       ((b + 0.5) / N - 0.5) * l->height * l->axis_y[i];
                d[i] = q[i] - p[i];
            }
            double r2 = v3_dot(d, d), r = sqrt(r2);
            double cb = v3_dot(d, n) / r, cl = v3_dot(d, l->axis_z) / r;
            if (cb <= 0)
                return 0; /* partly below the horizon: not compared */
            double tex = 1.0;
            if (l->texture.data) {
                int tx = (int)((a + 0.5) / N * l->texture.width);
                int ty = (int)((1.0 - (b + 0.5) / N) * l->texture.height); /* row 0 at +y */
                tex = sl_image_pixel(&l->texture, tx, ty)[0];
            }
            if (cl > 0)
                E += l->radiance[0] * tex * cb * cl / r2;
        }
    return E * l->width * l->height / (N * N);
}

static void test_big_rect(void)
{
    /* above and in front, facing the sphere, out of the camera's view */
    const double pos[3] = {0.3, 2.2, -1.8}, emit[3] = {-0.3, -2.2, 1.8};
    double e[3] = {emit[0], emit[1], emit[2]}, worst;
    v3_normalize(e);
    sl_light l;
    base_light(&l, SL_LIGHT_RECT, pos, e);
    l.width = 2, l.height = 1;
    l.intensity = 5;
    render_vs(&l, irr_rect_quadrature, 256, &worst);
    printf("  big rect: worst %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
}

/* Chi-square of sphere-light and rect-light direction sampling against
 * their pdf, binned over the light's own (s, t) or cone coordinates. */
static void test_light_sampler_chi2(void)
{
    enum { NB = 10, N = 100000 };
    const double p[3] = {0, 0, 0};
    const double pos[3] = {0.7, 0.4, 1.2}, emit[3] = {0, 0, -1};
    sl_light lights[2];
    base_light(&lights[0], SL_LIGHT_RECT, pos, emit);
    lights[0].width = 1.5, lights[0].height = 0.8;
    base_light(&lights[1], SL_LIGHT_SPHERE, pos, emit);
    lights[1].radius = 0.6;
    sl_scene s;
    sl_scene_init(&s);
    for (int k = 0; k < 2; k++)
        CHECK_OK(sl_scene_add_light(&s, &lights[k], NULL), NULL);
    for (int k = 0; k < 2; k++) {
        const sl_light *l = &s.lights[k];
        static double expected[NB * NB];
        static double observed[NB * NB];
        memset(expected, 0, sizeof expected);
        memset(observed, 0, sizeof observed);
        /* bins over the unit square of a parametrisation of the light as seen from p */
        double total = 0;
        const int SUB = 20;
        for (int a = 0; a < NB * SUB; a++)
            for (int b = 0; b < NB * SUB; b++) {
                double s0 = (a + 0.5) / (NB * SUB), t0 = (b + 0.5) / (NB * SUB), q[3], d[3];
                double jac;
                if (l->type == SL_LIGHT_RECT) {
                    for (int i = 0; i < 3; i++)
                        q[i] = l->position[i] + (s0 - 0.5) * l->width * l->axis_x[i] +
                               (t0 - 0.5) * l->height * l->axis_y[i];
                    for (int i = 0; i < 3; i++)
                        d[i] = q[i] - p[i];
                    double r = v3_length(d);
                    jac = l->width * l->height * fabs(v3_dot(d, l->axis_z)) / (r * r * r);
                    for (int i = 0; i < 3; i++)
                        d[i] /= r;
                    total += sl_light_pdf(l, p, d, r) * jac / (NB * SUB * NB * SUB);
                    expected[(a / SUB) * NB + b / SUB] += sl_light_pdf(l, p, d, r) * jac / (NB * SUB * NB * SUB);
                } else {
                    /* cone coordinates: s = (1 - cos) / (1 - cos max), t = phi / 2 pi; uniform */
                    expected[(a / SUB) * NB + b / SUB] += 1.0 / (NB * SUB * NB * SUB);
                    total += 1.0 / (NB * SUB * NB * SUB);
                }
            }
        CHECK_NEAR(total, 1.0, 2e-3);
        sl_sampler smp;
        int failed = 0;
        for (int n = 0; n < N; n++) {
            double u[2], wi[3], L[3], pdf, dist;
            bool delta;
            sl_sampler_start(&smp, 11 + k, (uint32_t)n, false);
            sl_sampler_2d(&smp, u);
            if (!sl_light_sample(l, p, u, wi, &dist, L, &pdf, &delta))
                failed++;
            int a, b;
            if (l->type == SL_LIGHT_RECT) {
                double q[3], r[3];
                for (int i = 0; i < 3; i++)
                    q[i] = p[i] + dist * wi[i], r[i] = q[i] - l->position[i];
                double ss = v3_dot(r, l->axis_x) / l->width + 0.5, tt = v3_dot(r, l->axis_y) / l->height + 0.5;
                a = (int)(ss * NB), b = (int)(tt * NB);
            } else {
                double axis[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
                double dd = v3_length(axis);
                for (int i = 0; i < 3; i++)
                    axis[i] /= dd;
                double sin2 = l->radius * l->radius / (dd * dd), omc = sin2 / (1 + sqrt(1 - sin2));
                frame f;
                frame_from_normal(&f, axis);
                double loc[3];
                frame_to_local(&f, wi, loc);
                double phi = atan2(loc[1], loc[0]);
                if (phi < 0)
                    phi += 2 * SL_PI;
                a = (int)((1 - loc[2]) / omc * NB), b = (int)(phi / (2 * SL_PI) * NB);
                if (!(fabs(pdf - 1.0 / (2 * SL_PI * omc)) <= 1e-9 * pdf))
                    failed++;
            }
            a = a < 0 ? 0 : a >= NB ? NB - 1 : a;
            b = b < 0 ? 0 : b >= NB ? NB - 1 : b;
            observed[a * NB + b]++;
        }
        CHECK(failed == 0);
        for (int i = 0; i < NB * NB; i++)
            expected[i] *= N / total;
        int dof;
        double pv = sl_test_chi2(observed, expected, NB * NB, &dof);
        printf("  %s light: dof %d, p %.3f\n", k ? "sphere" : "rect", dof, pv);
        CHECK(pv > 0.001);
    }
    sl_scene_free(&s);
}

/* (s, t) in the unit square of a point of the light seen from p, and the
 * solid angle per unit (s, t) there; the direction and its distance. */
static void param_dir(const sl_light *l, const double p[3], double s0, double t0, double d[3],
                      double *dist, double *jac)
{
    double q[3];
    if (l->type == SL_LIGHT_DISTANT) { /* cone coordinates about axis_z */
        double a = 0.5 * l->angle_deg * SL_PI / 180, omc = 1 - cos(a);
        double ct = 1 - s0 * omc, st = sqrt(fmax(0, 1 - ct * ct)), phi = 2 * SL_PI * t0;
        frame f;
        frame_from_normal(&f, l->axis_z);
        double loc[3] = {st * cos(phi), st * sin(phi), ct};
        frame_to_world(&f, loc, d);
        *dist = INFINITY;
        *jac = 2 * SL_PI * omc;
        return;
    }
    double area;
    if (l->type == SL_LIGHT_DISK) { /* polar, area-uniform in s */
        double r = l->radius * sqrt(s0), phi = 2 * SL_PI * t0;
        for (int i = 0; i < 3; i++)
            q[i] = l->position[i] + r * cos(phi) * l->axis_x[i] + r * sin(phi) * l->axis_y[i];
        area = SL_PI * l->radius * l->radius;
    } else {
        for (int i = 0; i < 3; i++)
            q[i] = l->position[i] + (s0 - 0.5) * l->width * l->axis_x[i] + (t0 - 0.5) * l->height * l->axis_y[i];
        area = l->width * l->height;
    }
    for (int i = 0; i < 3; i++)
        d[i] = q[i] - p[i];
    double r = v3_length(d);
    for (int i = 0; i < 3; i++)
        d[i] /= r;
    *dist = r;
    *jac = area * fabs(v3_dot(d, l->axis_z)) / (r * r);
}

/* Inverse of param_dir for a sampled direction. */
static void dir_param(const sl_light *l, const double p[3], const double wi[3], double dist, double *s0,
                      double *t0)
{
    double loc[3], r[3];
    if (l->type == SL_LIGHT_DISTANT) {
        double a = 0.5 * l->angle_deg * SL_PI / 180;
        frame f;
        frame_from_normal(&f, l->axis_z);
        frame_to_local(&f, wi, loc);
        *s0 = (1 - loc[2]) / (1 - cos(a));
        *t0 = atan2(loc[1], loc[0]) / (2 * SL_PI);
    } else {
        for (int i = 0; i < 3; i++)
            r[i] = p[i] + dist * wi[i] - l->position[i];
        double x = v3_dot(r, l->axis_x), y = v3_dot(r, l->axis_y);
        if (l->type == SL_LIGHT_DISK) {
            *s0 = (x * x + y * y) / (l->radius * l->radius);
            *t0 = atan2(y, x) / (2 * SL_PI);
        } else {
            *s0 = x / l->width + 0.5, *t0 = y / l->height + 0.5;
        }
    }
    if (*t0 < 0)
        *t0 += 1;
}

/* Chi-square of the disk (by area), distant cone and textured-rect samplers:
 * bins over the light's own (s, t), expected counts from integrating
 * sl_light_pdf over each bin (so the pdf the MIS weights use is checked too). */
static void test_light_sampler_chi2_more(void)
{
    enum { NB = 10, SUB = 20, N = 100000 };
    const double p[3] = {0.1, -0.2, 0.3};
    const double pos[3] = {0.7, 0.4, 1.2}, emit[3] = {-0.6, -0.2, -0.77};
    double e[3] = {emit[0], emit[1], emit[2]};
    v3_normalize(e);
    sl_light lights[3];
    base_light(&lights[0], SL_LIGHT_DISK, pos, e);
    lights[0].radius = 0.7;
    base_light(&lights[1], SL_LIGHT_DISTANT, pos, e);
    lights[1].angle_deg = 40;
    base_light(&lights[2], SL_LIGHT_RECT, pos, e);
    lights[2].width = 1.5, lights[2].height = 0.8;
    CHECK_OK(sl_image_alloc(&lights[2].texture, 8, 4, 3, NULL), NULL);
    sl_image_fill(&lights[2].texture, 0.5f);
    float *hot = sl_image_pixel(&lights[2].texture, 6, 1);
    hot[0] = hot[1] = hot[2] = 20.0f;
    sl_scene s;
    sl_scene_init(&s);
    for (int k = 0; k < 3; k++)
        CHECK_OK(sl_scene_add_light(&s, &lights[k], NULL), NULL);
    static const char *const names[3] = {"disk", "distant 40 deg", "textured rect"};
    for (int k = 0; k < 3; k++) {
        const sl_light *l = &s.lights[k];
        static double expected[NB * NB];
        static double observed[NB * NB];
        memset(expected, 0, sizeof expected);
        memset(observed, 0, sizeof observed);
        double total = 0;
        for (int a = 0; a < NB * SUB; a++)
            for (int b = 0; b < NB * SUB; b++) {
                double d[3], dist, jac;
                param_dir(l, p, (a + 0.5) / (NB * SUB), (b + 0.5) / (NB * SUB), d, &dist, &jac);
                double m = sl_light_pdf(l, p, d, dist) * jac / (NB * SUB * NB * SUB);
                expected[(a / SUB) * NB + b / SUB] += m;
                total += m;
            }
        CHECK_MSG(fabs(total - 1) < 3e-3, "%s: pdf integrates to %.5f", names[k], total);
        sl_sampler smp;
        int failed = 0;
        for (int n = 0; n < N; n++) {
            double u[2], wi[3], L[3], pdf, dist, s0, t0;
            bool delta;
            sl_sampler_start(&smp, 1000 + 37 * k, (uint32_t)n, false);
            sl_sampler_2d(&smp, u);
            if (!sl_light_sample(l, p, u, wi, &dist, L, &pdf, &delta) ||
                !(fabs(pdf - sl_light_pdf(l, p, wi, dist)) <= 1e-9 * pdf)) {
                failed++;
                continue;
            }
            dir_param(l, p, wi, dist, &s0, &t0);
            int a = (int)(s0 * NB), b = (int)(t0 * NB);
            a = a < 0 ? 0 : a >= NB ? NB - 1 : a;
            b = b < 0 ? 0 : b >= NB ? NB - 1 : b;
            observed[a * NB + b]++;
        }
        CHECK(failed == 0);
        for (int i = 0; i < NB * NB; i++)
            expected[i] *= N / total;
        int dof;
        double pv = sl_test_chi2(observed, expected, NB * NB, &dof);
        printf("  %s light: dof %d, p %.3f\n", names[k], dof, pv);
        CHECK(pv > 0.001);
    }
    sl_scene_free(&s);
}

/* A delta sun straight down: the ground under the sphere is in full shadow,
 * the ground far away gets rho/pi * E. */
static void test_shadow(void)
{
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "shadow", 40, NULL), NULL);
    const double pos[3] = {0, 0, 0}, down[3] = {0, -1, 0};
    sl_light l;
    base_light(&l, SL_LIGHT_DISTANT, pos, down);
    l.intensity = 2;
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    sl_camera_validation(&s.camera, 40, 40, 6.0, 0, 90); /* straight down */
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 2;
    o.pixel_centers = true;
    sl_image img;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, &img, &st, NULL), NULL);
    CHECK(st.shadow_rays > 0);
    /* Looking down, the sphere covers the middle; its top is lit, rho/pi * 2. */
    CHECK_NEAR(sl_image_pixel(&img, 20, 20)[0], 0.18 / SL_PI * 2, 1e-3);
    /* A corner sees the ground, unshadowed. */
    CHECK_NEAR(sl_image_pixel(&img, 1, 1)[0], 0.18 / SL_PI * 2, 1e-6);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    /* From below the ground would be unlit; from the side at the contact the ground is dark. */
    sl_camera_validation(&s.camera, 40, 40, 6.0, 0, 30);
    CHECK_OK(sl_render(&s, &o, &img, &st, NULL), NULL);
    sl_image_stats is;
    sl_image_stats_compute(&img, &is);
    CHECK(is.min[0] == 0); /* some ground pixels are in shadow */
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
}

/* Lights are scene objects for visibility. A 1 x 1 rect light 9 units to
 * the -X side of the grey sphere (out of the camera's view), fully behind a
 * 2 x 2 rect at 6 units (from every point of the sphere the line to any point
 * of the far light crosses the near one: off the axis by at most
 * 3/8 + 2/3 x 0.5 < 1 at x = -6): the far light
 * contributes nothing, whatever its power. Side by side, both contribute:
 * each pixel is the quadrature of both rects. A light's own emitter does not
 * shadow it (the near light alone still matches its quadrature). */
static void test_lights_occlude_lights(void)
{
    const double toward[3] = {1, 0, 0}; /* emitting toward the sphere */
    const double near_pos[3] = {-6, 0, 0}, far_pos[3] = {-9, 0, 0};
    sl_light near, far;
    base_light(&near, SL_LIGHT_RECT, near_pos, toward);
    near.width = near.height = 2;
    base_light(&far, SL_LIGHT_RECT, far_pos, toward);
    far.width = far.height = 1;
    far.intensity = 20; /* unblocked it would add about 2.5 times the near light */
    int64_t rays;
    sl_light pair[2] = {near, far};
    const bool near_only[2] = {true, false}, both[2] = {true, true};
    double worst = render_vs_lights(pair, 2, near_only, irr_rect_quadrature, 256, &rays);
    printf("  rect fully behind a rect: worst %.3f%% against the near light alone\n", 100 * worst);
    CHECK(worst < 0.01);
    CHECK(rays > 0); /* one shape, yet lights can block lights */
    /* Side by side, 3 apart: both light the sphere. */
    const double left[3] = {-6, 0, -1.5}, right[3] = {-6, 0, 1.5};
    base_light(&near, SL_LIGHT_RECT, left, toward);
    near.width = near.height = 1;
    base_light(&far, SL_LIGHT_RECT, right, toward);
    far.width = far.height = 1;
    far.intensity = 2;
    pair[0] = near, pair[1] = far;
    worst = render_vs_lights(pair, 2, both, irr_rect_quadrature, 256, &rays);
    printf("  two rects side by side: worst %.3f%% against both quadratures\n", 100 * worst);
    CHECK(worst < 0.01);
}

static void test_normalize_and_bad_lights(void)
{
    sl_scene s;
    sl_scene_init(&s);
    const double pos[3] = {0, 0, 0}, emit[3] = {0, -1, 0};
    sl_light l;
    base_light(&l, SL_LIGHT_RECT, pos, emit);
    l.width = 2, l.height = 4, l.intensity = 8, l.exposure = 1, l.normalize = true;
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    CHECK_NEAR(s.lights[0].radiance[1], 8 * 2.0 / 8.0, 1e-12);
    base_light(&l, SL_LIGHT_SPHERE, pos, emit);
    l.radius = -1;
    sl_error err = {0};
    CHECK_RESULT(sl_scene_add_light(&s, &l, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "radius") != NULL);
    base_light(&l, SL_LIGHT_DISK, pos, emit);
    l.radius = 1;
    l.intensity = NAN;
    CHECK_RESULT(sl_scene_add_light(&s, &l, &err), SL_ERR_INPUT, &err);
    CHECK(s.light_count == 1);

    /* Rig files (rig.json v1): a missing texture, wrong version, negative
     * values; then a distant and a placed sphere light. */
    const char *rig = sl_test_path("rig.json");
    static const char *const bad[][2] = {
        {"{\"version\": 1, \"dome\": {\"file\": null}, \"lights\": [{\"type\": \"rect\", "
         "\"direction\": [0, 1, 0], \"solid_angle\": 0.1, \"radiance\": [1, 1, 1], "
         "\"position\": [0, 3, 0], \"size\": [1, 1], \"texture\": \"nowhere.exr\"}]}",
         "lights[0].texture"},
        {"{\"version\": 3, \"dome\": {\"file\": null}, \"lights\": []}", "version"},
        {"{\"version\": 1, \"dome\": {\"file\": null}, \"lights\": [{\"type\": \"disk\", "
         "\"direction\": [0, 1, 0], \"solid_angle\": 0.1, \"radiance\": [1, -1, 1], "
         "\"position\": null, \"size\": null, \"texture\": null}]}",
         "lights[0].radiance"},
        {"{\"version\": 1, \"dome\": {\"file\": null}, \"lights\": [{\"type\": \"disk\", "
         "\"direction\": [0, 1, 0], \"solid_angle\": -0.1, \"radiance\": [1, 1, 1], "
         "\"position\": null, \"size\": null, \"texture\": null}]}",
         "lights[0].solid_angle"},
        {"{\"version\": 1, \"dome\": {\"file\": \"gone.exr\"}, \"lights\": []}", "dome.file"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        FILE *f = fopen(rig, "w");
        fputs(bad[k][0], f);
        fclose(f);
        CHECK_RESULT(sl_scene_read_rig(&s, rig, &err), SL_ERR_INPUT, &err);
        CHECK(strstr(err.message, "rig.json") && strstr(err.message, bad[k][1]));
        CHECK(s.light_count == 1);
    }
    FILE *f = fopen(rig, "w");
    fprintf(f, "{\"version\": 1, \"dome\": {\"file\": null}, \"lights\": ["
               "{\"type\": \"distant\", \"direction\": [0, 2, 0], \"solid_angle\": %.17g, "
               "\"radiance\": [3, 2, 1], \"integral\": [0, 0, 0], \"position\": null, "
               "\"size\": null, \"texture\": null},"
               "{\"type\": \"sphere\", \"direction\": [1, 0, 0], \"solid_angle\": 0.1, "
               "\"radiance\": [5, 5, 5], \"integral\": [0.5, 0.5, 0.5], \"position\": [4, 0, 0], "
               "\"size\": [0.6, 0.6], \"texture\": null}]}",
            2 * SL_PI * (1 - cos(0.01)));
    fclose(f);
    CHECK_OK(sl_scene_read_rig(&s, rig, &err), &err);
    CHECK(s.light_count == 3);
    CHECK(s.lights[1].type == SL_LIGHT_DISTANT && s.lights[2].type == SL_LIGHT_SPHERE);
    CHECK_NEAR(s.lights[1].angle_deg, 2 * 0.01 * 180 / SL_PI, 1e-9);
    CHECK_NEAR(s.lights[1].axis_z[1], 1, 1e-12); /* emits along -Z: down, from above */
    CHECK_NEAR(s.lights[1].radiance[0], 3, 1e-12);
    CHECK_NEAR(s.lights[2].radius, 0.3, 1e-12);
    CHECK_NEAR(s.lights[2].position[0], 4, 1e-12);
    CHECK_NEAR(s.lights[2].radiance[2], 5, 1e-12);
    CHECK(!s.dome.present);
    sl_scene_free(&s);
}

/* A light 1e5 times dimmer than another is culled at Lambert vertices, and
 * the image stays unbiased (BSDF sampling still finds it). Lights seen from
 * behind are skipped exactly. */
static void test_culling(void)
{
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "grey", 16, NULL), NULL);
    /* the bright sphere lights the +X half (image left), the dim rect the -X half */
    const double p1[3] = {6, 0, 0}, p2[3] = {-4, 0, -1}, p3[3] = {0, 0, 5};
    const double e1[3] = {-1, 0, 0}, e2[3] = {1, 0, 0.25}, away[3] = {0, 0, 1};
    sl_light l;
    base_light(&l, SL_LIGHT_SPHERE, p1, e1);
    l.radius = 0.5, l.intensity = 1e5;
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    base_light(&l, SL_LIGHT_RECT, p2, e2);
    l.width = l.height = 2, l.intensity = 1;
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    base_light(&l, SL_LIGHT_DISK, p3, away); /* faces away from the sphere */
    l.radius = 1;
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 256;
    sl_image a, b;
    sl_render_stats sa, sb;
    CHECK_OK(sl_render(&s, &o, &a, &sa, NULL), NULL);
    o.light_cull = 0;
    CHECK_OK(sl_render(&s, &o, &b, &sb, NULL), NULL);
    CHECK(sa.lights_culled > 0 && sb.lights_culled == 0);
    CHECK(sa.lights_behind > 0 && sb.lights_behind == sa.lights_behind);
    /* where only the dim rect is above the horizon it is not culled (the
     * bright light's bound is 0 there): same samples, same values */
    double suma = 0, sumb = 0, ta = 0, tb = 0;
    for (int y = 4; y < 12; y++)
        for (int x = 13; x < 15; x++)
            suma += sl_image_pixel(&a, x, y)[0], sumb += sl_image_pixel(&b, x, y)[0];
    for (int y = 0; y < 16; y++)
        for (int x = 0; x < 16; x++)
            ta += sl_image_pixel(&a, x, y)[0], tb += sl_image_pixel(&b, x, y)[0];
    printf("  culled %lld, behind %lld; dim-lit region %.6g vs %.6g, image %.6g vs %.6g without culling\n",
           (long long)sa.lights_culled, (long long)sa.lights_behind, suma, sumb, ta, tb);
    CHECK(sumb > 0);
    CHECK_NEAR(suma / sumb, 1.0, 1e-3);
    CHECK_NEAR(ta / tb, 1.0, 2e-3);
    sl_image_free(&a);
    sl_image_free(&b);
    sl_render_stats_free(&sa);
    sl_render_stats_free(&sb);
    sl_scene_free(&s);
}

/* An integrating sphere: a Lambert shell (rho = 0.5) lit by a small sphere
 * light at its centre. The wall's radiance after N bounces is
 * rho/pi * E * sum_{k<=N} rho^k with E = Le pi (r/R)^2 (the light blocks
 * about (r/R)^2 of the interreflections: 0.25% here). */
static void test_integrating_sphere(void)
{
    const double rho = 0.5, Le = 100, r = 0.05, R = 1;
    sl_scene s;
    sl_scene_init(&s);
    sl_material m;
    sl_material_lambert(&m, rho, rho, rho);
    int mi;
    const double c[3] = {0, 0, 0};
    CHECK_OK(sl_scene_add_material(&s, &m, &mi, NULL), NULL);
    CHECK_OK(sl_scene_add_sphere(&s, c, R, mi, NULL), NULL);
    const double emit[3] = {0, -1, 0};
    sl_light l;
    base_light(&l, SL_LIGHT_SPHERE, c, emit);
    l.radius = r, l.intensity = Le;
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    s.camera.type = SL_CAMERA_PERSPECTIVE;
    v3_set(s.camera.position, 0, 0.5, 0);
    v3_set(s.camera.forward, 0, 0, 1);
    v3_set(s.camera.up, 0, 1, 0);
    s.camera.fov_deg = 10;
    s.camera.width = s.camera.height = 4;
    const int bounces[] = {0, 1, 3, 30};
    for (int b = 0; b < 4; b++) {
        sl_render_options o;
        sl_render_options_init(&o);
        o.spp = 512;
        o.bounces = bounces[b];
        sl_image img;
        sl_render_stats st;
        CHECK_OK(sl_render(&s, &o, &img, &st, NULL), NULL);
        double sum = 0, series = 0;
        for (int k = 0; k <= bounces[b]; k++)
            series += pow(rho, k);
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++)
                sum += sl_image_pixel(&img, x, y)[1];
        double expect = rho / SL_PI * Le * SL_PI * (r / R) * (r / R) * series;
        printf("  %d bounces: %.6g, expected %.6g (%+.3f%%)\n", bounces[b], sum / 16, expect,
               100 * (sum / 16 / expect - 1));
        CHECK_NEAR(sum / 16 / expect, 1.0, bounces[b] ? 0.01 : 1e-3);
        CHECK(st.shadow_rays > 0); /* the inside of a lone sphere can occlude */
        sl_image_free(&img);
        sl_render_stats_free(&st);
    }
    sl_scene_free(&s);
}

/* A textured rect (one hot texel) is sampled by its texture and matches the
 * quadrature. */
static void test_textured_rect(void)
{
    const double pos[3] = {0.3, 2.2, -1.8}, emit[3] = {-0.3, -2.2, 1.8};
    double e[3] = {emit[0], emit[1], emit[2]}, worst;
    v3_normalize(e);
    sl_light l;
    base_light(&l, SL_LIGHT_RECT, pos, e);
    l.width = 2, l.height = 1, l.intensity = 1;
    CHECK_OK(sl_image_alloc(&l.texture, 8, 4, 3, NULL), NULL);
    sl_image_fill(&l.texture, 0.5f);
    float *hot = sl_image_pixel(&l.texture, 6, 1);
    hot[0] = hot[1] = hot[2] = 200.0f;
    render_vs(&l, irr_rect_quadrature, 4096, &worst);
    printf("  textured rect: worst %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
    sl_image_free(&l.texture);
}

int main(void)
{
    RUN(test_textured_rect);
    RUN(test_integrating_sphere);
    RUN(test_culling);
    RUN(test_sphere_light);
    RUN(test_distant_lights);
    RUN(test_planar_lights);
    RUN(test_big_rect);
    RUN(test_light_sampler_chi2);
    RUN(test_light_sampler_chi2_more);
    RUN(test_shadow);
    RUN(test_lights_occlude_lights);
    RUN(test_normalize_and_bad_lights);
    return sl_test_finish();
}
