/* SPDX-License-Identifier: BSD-3-Clause */
/* The closed form of a rig's lights (render/area_closed_form.c): Lambert's
 * polygon formula, the spherical cap and the disk's polygon bracket against
 * numerical quadrature (the horizon straddled, grazing, tiny and huge
 * lights); rig renders in closed form against the sampled renderer at high
 * spp; the control variate under a light partly hidden by another; no NaN
 * or negative pixel. */
#include <stdlib.h>
#include <string.h>

#include "../../render/area_closed_form.h"
#include "testing.h"

#if defined(__SANITIZE_ADDRESS__)
#define SANITIZED 1
#else
#define SANITIZED 0
#endif

/* Gauss-Legendre, 8 points on [-1, 1]. */
static const double GL_X[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                               -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                               0.7966664774136267,  0.9602898564975363};
static const double GL_W[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066578931601,
                               0.3626837833783620, 0.3626837833783620, 0.3137066578931601,
                               0.2223810344533745, 0.1012285362903763};

typedef double (*integrand)(const void *ctx, double a, double b);

/* Tensor Gauss-Legendre over [a0, a1] x [b0, b1] split into cells x cells. */
static double quad2(integrand f, const void *ctx, double a0, double a1, double b0, double b1, int cells)
{
    double sum = 0, ha = (a1 - a0) / cells, hb = (b1 - b0) / cells;
    for (int i = 0; i < cells; i++)
        for (int j = 0; j < cells; j++)
            for (int k = 0; k < 8; k++)
                for (int m = 0; m < 8; m++) {
                    double a = a0 + ha * (i + 0.5 + 0.5 * GL_X[k]);
                    double b = b0 + hb * (j + 0.5 + 0.5 * GL_X[m]);
                    sum += 0.25 * ha * hb * GL_W[k] * GL_W[m] * f(ctx, a, b);
                }
    return sum;
}

/* A rect in the plane through `foot` (the point of the plane nearest p, at
 * distance d) with axes ex, ey: x = d tan(alpha), y = d tan(beta) turns
 * the 1/r^2 falloff of a huge rect into a smooth integrand. */
typedef struct rect_q {
    double p[3], n[3], foot[3], ex[3], ey[3], d;
} rect_q;

static double rect_integrand(const void *ctx, double al, double be)
{
    const rect_q *q = ctx;
    double tx = tan(al), ty = tan(be), w[3];
    for (int i = 0; i < 3; i++)
        w[i] = q->foot[i] + q->d * (tx * q->ex[i] + ty * q->ey[i]) - q->p[i];
    double r = v3_length(w), c = v3_dot(q->n, w) / r;
    if (c <= 0)
        return 0;
    double sa = 1 + tx * tx, sb = 1 + ty * ty;
    return c * (q->d / r) / (r * r) * q->d * sa * q->d * sb;
}

/* Quadrature of the rect light's cosine-weighted solid angle from p. */
static double rect_quadrature(const sl_light *l, const double p[3], const double n[3])
{
    rect_q q;
    v3_copy(q.p, p);
    v3_copy(q.n, n);
    v3_copy(q.ex, l->axis_x);
    v3_copy(q.ey, l->axis_y);
    double r[3] = {p[0] - l->position[0], p[1] - l->position[1], p[2] - l->position[2]};
    double h = v3_dot(r, l->axis_z);
    q.d = fabs(h);
    for (int i = 0; i < 3; i++)
        q.foot[i] = p[i] - h * l->axis_z[i];
    double fx = v3_dot(r, l->axis_x), fy = v3_dot(r, l->axis_y);
    double x0 = -0.5 * l->width - fx, x1 = 0.5 * l->width - fx;
    double y0 = -0.5 * l->height - fy, y1 = 0.5 * l->height - fy;
    return quad2(rect_integrand, &q, atan(x0 / q.d), atan(x1 / q.d), atan(y0 / q.d), atan(y1 / q.d), 96);
}

static void make_light(sl_light *l, sl_light_type type, const double pos[3], const double facing[3])
{
    memset(l, 0, sizeof *l);
    l->type = type;
    v3_copy(l->position, pos);
    /* Emits along -Z: axis_z points away from what it lights. */
    for (int i = 0; i < 3; i++)
        l->axis_z[i] = -facing[i];
    v3_normalize(l->axis_z);
    v3_set(l->axis_y, 0.3, 1, 0.2);
    double x[3];
    v3_cross(l->axis_y, l->axis_z, x);
    v3_normalize(x);
    v3_copy(l->axis_x, x);
    v3_cross(l->axis_z, l->axis_x, l->axis_y);
    v3_set(l->color, 1, 1, 1);
    l->intensity = 1;
    l->radiance[0] = l->radiance[1] = l->radiance[2] = 1;
}

/* Lambert's formula against quadrature: the horizon through the rect,
 * grazing, tiny (1e-8 sr) and huge (nearly a hemisphere) rects, behind. */
static void test_polygon_vs_quadrature(void)
{
    struct {
        const char *what;
        double pos[3], w, h, n[3];
    } cases[] = {
        {"facing, above", {0, 3, 0}, 1.0, 0.6, {0, 1, 0}},
        {"tilted normal", {0.5, 2, 0.3}, 2.0, 1.0, {0.4, 0.8, -0.2}},
        {"horizon through the middle", {0, 0.1, 2}, 3.0, 2.0, {0, 1, 0}},
        {"horizon near an edge", {1, 0.6, 1.5}, 1.0, 2.0, {0.2, 1, 0}},
        {"grazing: only a sliver above", {0, -0.45, 2}, 1.5, 1.0, {0, 1, 0}},
        {"tiny (~1e-8 sr)", {0.3, 5, 1}, 5e-4, 3e-4, {0.1, 1, 0.3}},
        {"huge (1000 x 1000 at 1)", {0.1, 1, 0.2}, 1000, 1000, {0, 1, 0}},
        {"huge, tilted normal", {0, 1, 0}, 500, 800, {0.7, 0.5, 0.1}},
    };
    double p[3] = {0, 0, 0};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        double n[3];
        v3_copy(n, cases[k].n);
        v3_normalize(n);
        sl_light l;
        double facing[3] = {-cases[k].pos[0], -cases[k].pos[1], -cases[k].pos[2]};
        if (k >= 6 || k == 2 || k == 4)
            v3_set(facing, 0, k == 2 || k == 4 ? 0 : -1, k == 2 || k == 4 ? -1 : 0);
        make_light(&l, SL_LIGHT_RECT, cases[k].pos, facing);
        l.width = cases[k].w, l.height = cases[k].h;
        double E[3], B[3];
        CHECK(sl_light_irradiance(&l, p, n, 1e-3, E, B));
        double q = rect_quadrature(&l, p, n);
        double rel = fabs(E[0] - q) / q;
        printf("  rect %-30s formula %.10g quadrature %.10g rel %.2e\n", cases[k].what, E[0], q, rel);
        CHECK_MSG(q > 0 && rel < 2e-6, "%s: %.10g vs %.10g", cases[k].what, E[0], q);
        CHECK(E[0] >= 0 && isfinite(E[0]));
        /* From behind (the light flipped): one-sided, exactly 0. */
        for (int i = 0; i < 3; i++)
            l.axis_z[i] = -l.axis_z[i];
        CHECK(sl_light_irradiance(&l, p, n, 1e-3, E, B) && E[0] == 0);
    }
    /* Wholly below the horizon: 0; the point on the rect's outline: 0, finite. */
    sl_light l;
    make_light(&l, SL_LIGHT_RECT, (double[3]){0, -2, 0}, (double[3]){0, 1, 0});
    l.width = l.height = 1;
    double E[3], B[3];
    CHECK(sl_light_irradiance(&l, p, (double[3]){0, 1, 0}, 1e-3, E, B) && E[0] == 0);
    make_light(&l, SL_LIGHT_RECT, (double[3]){0.5, 0, 1}, (double[3]){0, 0, -1});
    l.width = l.height = 1;
    CHECK(sl_light_irradiance(&l, p, (double[3]){0, 0, 1}, 1e-3, E, B) && isfinite(E[0]) && E[0] >= 0);
}

/* A spherical cap around axis a: (cos gamma, psi) quadrature. */
typedef struct cap_q {
    double a[3], t[3], b[3], n[3];
} cap_q;

static double cap_integrand(const void *ctx, double cg, double psi)
{
    const cap_q *q = ctx;
    double sg = sqrt(fmax(0.0, 1 - cg * cg)), w[3];
    for (int i = 0; i < 3; i++)
        w[i] = cg * q->a[i] + sg * (cos(psi) * q->t[i] + sin(psi) * q->b[i]);
    return fmax(0.0, v3_dot(q->n, w));
}

static void test_cap_vs_quadrature(void)
{
    struct {
        const char *what;
        double theta_deg, sigma_deg;
    } cases[] = {
        {"above", 30, 10},   {"straddling", 80, 20}, {"centred on the horizon", 90, 15},
        {"mostly below", 105, 30}, {"grazing sliver", 99.9, 10}, {"tiny", 89.999, 0.01},
        {"huge (80 deg)", 40, 80}, {"huge, straddling", 120, 85}, {"below", 120, 20},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        double th = cases[k].theta_deg * SL_PI / 180, sg = cases[k].sigma_deg * SL_PI / 180;
        cap_q q;
        v3_set(q.n, 0, 0, 1);
        v3_set(q.a, sin(th), 0, cos(th));
        v3_set(q.t, cos(th), 0, -sin(th));
        v3_set(q.b, 0, 1, 0);
        double exact = sl_cap_cosine_integral(q.a, sin(sg) * sin(sg), q.n);
        double quad = quad2(cap_integrand, &q, cos(sg), 1, 0, 2 * SL_PI, 200);
        /* A sliver is a sliver of the quadrature's cells too: allow 1e-10
         * of the whole cap's value there. */
        double tol = 2e-6 * quad + 1e-10 * SL_PI * sin(sg) * sin(sg);
        printf("  cap %-24s formula %.10g quadrature %.10g\n", cases[k].what, exact, quad);
        CHECK_MSG(fabs(exact - quad) <= tol + 1e-15, "%s: %.12g vs %.12g", cases[k].what, exact, quad);
    }
    /* Sphere and distant lights go through it: a sphere of radius 1 at 2 straight above. */
    sl_light l;
    make_light(&l, SL_LIGHT_SPHERE, (double[3]){0, 2, 0}, (double[3]){0, -1, 0});
    l.radius = 1;
    double E[3], B[3];
    CHECK(sl_light_irradiance(&l, (double[3]){0, 0, 0}, (double[3]){0, 1, 0}, 1e-3, E, B));
    CHECK_NEAR(E[0], SL_PI * 0.25, 1e-12); /* pi sin^2 sigma, sin sigma = 1/2 */
    /* Inside a sphere light: no closed form. */
    CHECK(!sl_light_irradiance(&l, (double[3]){0, 2.5, 0}, (double[3]){0, 1, 0}, 1e-3, E, B));
    make_light(&l, SL_LIGHT_DISTANT, (double[3]){0, 0, 0}, (double[3]){0, -1, 0});
    l.angle_deg = 0; /* delta: radiance is irradiance, times the cosine */
    CHECK(sl_light_irradiance(&l, (double[3]){0, 0, 0}, (double[3]){0, 0.6, 0.8}, 1e-3, E, B));
    CHECK_NEAR(E[0], 0.6, 1e-15);
}

/* The disk in polar coordinates on its plane. */
typedef struct disk_q {
    const sl_light *l;
    double p[3], n[3];
} disk_q;

static double disk_integrand(const void *ctx, double rho, double psi)
{
    const disk_q *q = ctx;
    double w[3];
    for (int i = 0; i < 3; i++)
        w[i] = q->l->position[i] + rho * (cos(psi) * q->l->axis_x[i] + sin(psi) * q->l->axis_y[i]) -
               q->p[i];
    double r = v3_length(w), c = v3_dot(q->n, w) / r, cl = fabs(v3_dot(q->l->axis_z, w)) / r;
    return c > 0 ? c * cl / (r * r) * rho : 0;
}

static void test_disk_bracket(void)
{
    struct {
        const char *what;
        double pos[3], radius, n[3];
    } cases[] = {
        {"facing", {0, 2, 0}, 0.5, {0, 1, 0}},
        {"straddling the horizon", {0, 0.2, 2}, 1.0, {0, 1, 0}},
        {"grazing", {0.5, -0.9, 2}, 1.0, {0, 1, 0}},
        {"tiny", {0, 4, 1}, 1e-3, {0.2, 1, 0}},
        {"huge", {0, 1, 0}, 300, {0.3, 1, 0}},
    };
    double p[3] = {0, 0, 0};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        sl_light l;
        double facing[3] = {0, -1, 0};
        if (k == 1 || k == 2)
            v3_set(facing, 0, 0, -1);
        make_light(&l, SL_LIGHT_DISK, cases[k].pos, facing);
        l.radius = cases[k].radius;
        double n[3];
        v3_copy(n, cases[k].n);
        v3_normalize(n);
        disk_q q = {.l = &l};
        v3_copy(q.p, p);
        v3_copy(q.n, n);
        /* rho = R sin(s) clusters nodes at the rim; huge disks: rho = d tan. */
        double quad = quad2(disk_integrand, &q, 0, l.radius, 0, 2 * SL_PI, 160);
        for (double tol = 1e-2; tol >= 1e-4; tol /= 10) {
            double E[3], B[3];
            CHECK(sl_light_irradiance(&l, p, n, tol, E, B));
            printf("  disk %-24s tol %.0e: %.10g +- %.2e, quadrature %.10g (error %.2e)\n", cases[k].what,
                   tol, E[0], B[0], quad, fabs(E[0] - quad));
            CHECK_MSG(fabs(E[0] - quad) <= B[0] + 1e-6 * quad, "%s: outside its bound", cases[k].what);
            CHECK_MSG(B[0] <= 0.1 * tol * E[0] * 1.01 || k == 2, "%s: bound %.3g", cases[k].what, B[0]);
        }
    }
}

/* A grey ball 24 px (pixel centres), optionally under a dome, lit by lights. */
static void render_pair(const sl_light *lights, int n, bool dome, int64_t spp, sl_image *cf,
                        sl_render_stats *scf, sl_image *sampled, sl_render_stats *ssam)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", 24, &err), &err);
    if (dome) {
        sl_image env;
        CHECK_OK(sl_image_alloc(&env, 32, 16, 3, NULL), NULL);
        for (size_t i = 0; i < 32 * 16 * 3; i++)
            env.data[i] = (float)(0.2 + 0.1 * (i % 3) + 0.3 * ((i / 3) % 32 < 16));
        CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", &err), &err);
        sl_image_free(&env);
    }
    for (int i = 0; i < n; i++) {
        sl_light l = lights[i];
        if (lights[i].texture.data)
            CHECK_OK(sl_image_copy(&lights[i].texture, &l.texture, NULL), NULL);
        CHECK_OK(sl_scene_add_light(&s, &l, &err), &err);
    }
    sl_render_options o;
    sl_render_options_init(&o);
    o.pixel_centers = true;
    o.spp = spp;
    CHECK_OK(sl_render(&s, &o, cf, scf, &err), &err);
    if (sampled) {
        o.closed_form = false;
        CHECK_OK(sl_render(&s, &o, sampled, ssam, &err), &err);
    }
    sl_scene_free(&s);
}

static void check_clean(const sl_image *img, const sl_render_stats *st, const char *what)
{
    int bad = 0;
    for (size_t i = 0; i < (size_t)img->width * img->height * img->channels; i++)
        bad += !(isfinite(img->data[i]) && img->data[i] >= 0);
    CHECK_MSG(bad == 0 && st->nonfinite_samples == 0, "%s: %d bad values, %lld non-finite samples", what,
              bad, (long long)st->nonfinite_samples);
}

/* Agreement within the sampled render's estimate (both renders' noise). */
static void check_agree(const sl_image *a, const sl_render_stats *sa, const sl_image *b,
                        const sl_render_stats *sb, const char *what)
{
    double diff;
    CHECK_OK(sl_relative_rmse(a, b, &diff, NULL), NULL);
    double ea = sa->passes[sa->pass_count - 1].est_rel_rmse;
    double eb = sb->passes[sb->pass_count - 1].est_rel_rmse;
    printf("  %-40s closed form vs sampled %.4f%% (estimates: closed form %.4f%%, sampled %.4f%%; "
           "%lld exact, %lld control variate px)\n",
           what, 100 * diff, 100 * ea, 100 * eb, (long long)sa->closed_form.exact_pixels,
           (long long)sa->closed_form.control_variate_pixels);
    /* The closed form's estimate counts its proven bound, far above its
     * true error: a quarter of it is allowed, as test_render_closed_form. */
    CHECK_MSG(diff <= 2.0 * sqrt(0.0625 * ea * ea + eb * eb), "%s: %.4f%% apart", what, 100 * diff);
    check_clean(a, sa, what);
}

/* Each light type alone: the ball's covered pixels exact, equal to the
 * sampled renderer at high spp; with a dome: control variates. */
static void test_rig_exact_vs_sampled(void)
{
    int64_t spp = SANITIZED ? 256 : 1024;
    sl_light l[5];
    make_light(&l[0], SL_LIGHT_RECT, (double[3]){1, 2, -2}, (double[3]){-1, -2, 2});
    l[0].width = 1.5, l[0].height = 0.8;
    make_light(&l[1], SL_LIGHT_DISK, (double[3]){-2, 0.5, -2}, (double[3]){2, -0.5, 2});
    l[1].radius = 0.7;
    make_light(&l[2], SL_LIGHT_SPHERE, (double[3]){0, 3, -1}, (double[3]){0, -1, 0});
    l[2].radius = 0.6;
    make_light(&l[3], SL_LIGHT_DISTANT, (double[3]){0, 0, 0}, (double[3]){-0.3, -0.5, 1});
    l[3].angle_deg = 20;
    make_light(&l[4], SL_LIGHT_DISTANT, (double[3]){0, 0, 0}, (double[3]){0.6, 0.2, 1});
    const char *names[5] = {"rect", "disk", "sphere", "distant 20 deg", "distant delta"};
    for (int k = 0; k < 5; k++) {
        for (int c = 0; c < 3; c++)
            l[k].radiance[c] = l[k].color[c] = 2.0 + c;
        sl_image a, b;
        sl_render_stats sa, sb;
        render_pair(&l[k], 1, false, spp, &a, &sa, &b, &sb);
        CHECK_MSG(sa.closed_form.used && sa.closed_form.exact_pixels > 300 &&
                      sa.closed_form.control_variate_pixels == 0 && sa.closed_form.lights_exact == 1,
                  "%s: %s, %lld exact", names[k], sa.closed_form.reason,
                  (long long)sa.closed_form.exact_pixels);
        check_agree(&a, &sa, &b, &sb, names[k]);
        sl_image_free(&a), sl_image_free(&b);
        sl_render_stats_free(&sa), sl_render_stats_free(&sb);
    }
    /* All five and a dome: every light may hide some of the dome. */
    sl_image a, b;
    sl_render_stats sa, sb;
    render_pair(l, 5, true, spp, &a, &sa, &b, &sb);
    CHECK(sa.closed_form.used && sa.closed_form.control_variate_pixels > 300 &&
          sa.closed_form.lights_exact == 5);
    check_agree(&a, &sa, &b, &sb, "five lights and a dome");
    sl_image_free(&a), sl_image_free(&b);
    sl_render_stats_free(&sa), sl_render_stats_free(&sb);
}

/* A rect light half hidden behind a smaller one in front of it: the closed
 * form counts both whole, the control variate takes the hidden part off.
 * The unshadowed sum is far from the truth, so a control variate that
 * forgot the occlusion would fail. A textured rect beside them is sampled. */
static void test_control_variate_occluded(void)
{
    int64_t spp = SANITIZED ? 256 : 1024;
    sl_light l[3];
    /* Above the ball, out of the camera's view. */
    make_light(&l[0], SL_LIGHT_RECT, (double[3]){0, 6, -1}, (double[3]){0, -1, 0});
    l[0].width = 4, l[0].height = 4;
    make_light(&l[1], SL_LIGHT_RECT, (double[3]){1, 3, -1}, (double[3]){0, -1, 0});
    l[1].width = 2, l[1].height = 3;
    for (int c = 0; c < 3; c++)
        l[0].radiance[c] = l[0].color[c] = 4, l[1].radiance[c] = l[1].color[c] = 0.5;
    sl_image a, b;
    sl_render_stats sa, sb;
    render_pair(l, 2, false, spp, &a, &sa, &b, &sb);
    CHECK(sa.closed_form.used && sa.closed_form.control_variate_pixels > 300);
    check_agree(&a, &sa, &b, &sb, "rect partly behind a rect");
    /* The same lights apart (no occlusion) differ: the occlusion mattered. */
    double unshadowed = 0, shadowed = 0;
    for (int y = 0; y < 24; y++)
        for (int x = 0; x < 24; x++) {
            float *p = sl_image_pixel(&a, x, y);
            if (p[3] < 1)
                continue;
            double px = 1 - 2 * (x + 0.5) / 24, py = 1 - 2 * (y + 0.5) / 24, r2 = px * px + py * py;
            if (r2 >= 1)
                continue;
            double pt[3] = {px, py, -sqrt(1 - r2)}, E[3], B[3], sum = 0;
            for (int k = 0; k < 2; k++) {
                CHECK(sl_light_irradiance(&l[k], pt, pt, 1e-3, E, B));
                sum += E[0];
            }
            unshadowed += 0.18 / SL_PI * sum;
            shadowed += p[0];
        }
    printf("  occluded: image %.4f against %.4f unshadowed\n", shadowed, unshadowed);
    CHECK(shadowed < 0.9 * unshadowed);
    sl_image_free(&a), sl_image_free(&b);
    sl_render_stats_free(&sa), sl_render_stats_free(&sb);

    /* A textured rect with the two: its light is sampled (control variate). */
    make_light(&l[2], SL_LIGHT_RECT, (double[3]){-2, 1, -2}, (double[3]){2, -1, 2});
    l[2].width = l[2].height = 1;
    CHECK_OK(sl_image_alloc(&l[2].texture, 2, 2, 3, NULL), NULL);
    for (int t = 0; t < 12; t++)
        l[2].texture.data[t] = (float)(1 + t % 4);
    render_pair(l, 3, false, spp, &a, &sa, &b, &sb);
    CHECK(sa.closed_form.lights_exact == 2 && sa.closed_form.lights_sampled == 1);
    check_agree(&a, &sa, &b, &sb, "and a textured rect (sampled)");
    sl_image_free(&l[2].texture);
    sl_image_free(&a), sl_image_free(&b);
    sl_render_stats_free(&sa), sl_render_stats_free(&sb);
}

/* Lights that graze the ball, cut by its horizon, a light edge-on, a huge
 * one: no NaN, no negative pixel, exact pixels everywhere the ball is covered. */
static void test_no_nan_or_negative(void)
{
    sl_light l[3];
    make_light(&l[0], SL_LIGHT_RECT, (double[3]){0, 0, -1.5}, (double[3]){0, 1, 0}); /* edge-on */
    l[0].width = 2, l[0].height = 2;
    make_light(&l[1], SL_LIGHT_DISK, (double[3]){3, 0, 0}, (double[3]){-1, 0, 0});
    l[1].radius = 50;
    make_light(&l[2], SL_LIGHT_SPHERE, (double[3]){0, 1.2, 0}, (double[3]){0, -1, 0});
    l[2].radius = 0.1;
    sl_image a;
    sl_render_stats sa;
    render_pair(l, 3, true, 8, &a, &sa, NULL, NULL);
    check_clean(&a, &sa, "grazing lights");
    CHECK(sa.closed_form.used);
    sl_image_free(&a);
    sl_render_stats_free(&sa);
}

int main(void)
{
    RUN(test_polygon_vs_quadrature);
    RUN(test_cap_vs_quadrature);
    RUN(test_disk_bracket);
    RUN(test_rig_exact_vs_sampled);
    RUN(test_control_variate_occluded);
    RUN(test_no_nan_or_negative);
    return sl_test_finish();
}
