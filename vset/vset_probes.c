/* SPDX-License-Identifier: BSD-3-Clause */
/* Probe photographs of the virtual set: a chrome ball, an 18% grey ball and
 * a ColorChecker, each rendered by render/ under the set's lat-long with a
 * pinhole camera at the capture point, so the chrome ball reflects the set
 * and the grey ball and the chart are lit by it.
 *
 * The chart is flat and the set at infinity, so every patch receives the
 * same irradiance E: the chart is rendered under a unit dome with cosine
 * sampling (each sample exactly the albedo it hits, no noise) and scaled by
 * E / pi summed over the lat-long's texels, then laid over the set seen
 * through the lens. Noise-free, and far cheaper than 25 rectangles under
 * small bright lights. */
#include <string.h>

#include "setlight/render.h"
#include "vset_internal.h"

const char *sl_vset_probe_name(sl_vset_probe_kind kind)
{
    return kind == SL_VSET_PROBE_CHROME ? "chrome" : kind == SL_VSET_PROBE_GREY ? "grey" : "chart";
}

void sl_vset_probe_default(sl_vset_probe *p, sl_vset_probe_kind kind, int width, int height)
{
    memset(p, 0, sizeof *p);
    p->kind = kind;
    sl_vset_lens_rectilinear(&p->lens, 200);
    /* A telephoto stopped down barely vignettes beyond cos^4. */
    p->lens.vignette_a = -0.03;
    p->view.yaw_deg = 180;
    p->distance_m = 2.0;
    p->size_m = kind == SL_VSET_PROBE_CHART ? 0.25 : 0.1;
    p->width = width;
    p->height = height;
    p->spp = kind == SL_VSET_PROBE_CHROME ? 8 : 64;
    p->seed = 1;
}

/* Chart layout as render's `chart` preset, in units of the frame width. */
#define CHART_ASPECT 0.68
#define CHART_PITCH 0.16
#define CHART_HALF 0.065

static void project(const sl_vset_probe *p, const double f[3], const double r[3],
                    const double u[3], const double pt[3], double fpx, double xy[2])
{
    double z = v3_dot(pt, f);
    xy[0] = 0.5 * p->width + fpx * v3_dot(pt, r) / z;
    xy[1] = 0.5 * p->height - fpx * v3_dot(pt, u) / z;
}

static sl_result add_chart(sl_scene *s, const sl_vset_probe *p, const double c[3],
                           const double f[3], const double r[3], const double u[3], double fpx,
                           sl_vset_probe_geometry *geo, sl_error *err)
{
    sl_material m;
    int idx;
    double w = p->size_m, hw = 0.5 * w, hh = 0.5 * w * CHART_ASPECT;
    sl_material_lambert(&m, 0.02, 0.02, 0.02);
    sl_result res = sl_scene_add_material(s, &m, &idx, err);
    double eu[3], ev[3];
    for (int k = 0; k < 3; k++) {
        eu[k] = hw * r[k];
        ev[k] = hh * u[k];
    }
    if (res || (res = sl_scene_add_rect(s, c, eu, ev, idx, err)))
        return res;
    static const double sx[4] = {-1, 1, 1, -1}, sy[4] = {1, 1, -1, -1};
    for (int i = 0; i < 4; i++) {
        double pt[3];
        for (int k = 0; k < 3; k++)
            pt[k] = c[k] + sx[i] * eu[k] + sy[i] * ev[k];
        project(p, f, r, u, pt, fpx, geo->outline[i]);
    }
    double pitch = CHART_PITCH * w, half = CHART_HALF * w;
    for (int i = 0; i < 24; i++) {
        int row = i / 6, col = i % 6;
        const double *a = SL_COLORCHECKER_LINEAR[i];
        sl_material_lambert(&m, a[0], a[1], a[2]);
        if ((res = sl_scene_add_material(s, &m, &idx, err)))
            return res;
        double pc[3], pu[3], pv[3];
        for (int k = 0; k < 3; k++) {
            /* Patch 1 at the top left as seen; patches stand proud of the frame. */
            pc[k] = c[k] + (col - 2.5) * pitch * r[k] + (1.5 - row) * pitch * u[k] -
                    2e-3 * w * f[k];
            pu[k] = half * r[k];
            pv[k] = half * u[k];
        }
        if ((res = sl_scene_add_rect(s, pc, pu, pv, idx, err)))
            return res;
        project(p, f, r, u, pc, fpx, geo->patch_centers[i]);
    }
    static const int corner_patch[4] = {0, 5, 23, 18};
    for (int i = 0; i < 4; i++) {
        geo->corners[i][0] = geo->patch_centers[corner_patch[i]][0];
        geo->corners[i][1] = geo->patch_centers[corner_patch[i]][1];
    }
    return SL_OK;
}

void sl_vset_irradiance(const sl_image *ll, const double n[3], double e[3])
{
    e[0] = e[1] = e[2] = 0;
    for (int y = 0; y < ll->height; y++) {
        double dw = sl_latlong_texel_solid_angle(y, ll->width, ll->height);
        for (int x = 0; x < ll->width; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / ll->width, (y + 0.5) / ll->height, d);
            double c = v3_dot(d, n);
            if (c <= 0)
                continue;
            const float *p = sl_image_pixel(ll, x, y);
            for (int k = 0; k < 3; k++)
                e[k] += p[k] * c * dw;
        }
    }
}

/* The chart's render (RGB = albedo x coverage + 1 - coverage, alpha =
 * coverage) made radiance: chart x E / pi over the set behind it. */
static void compose_chart(const sl_vset_probe *p, const sl_image *ll, const double f[3],
                          sl_image *img)
{
    double n[3] = {-f[0], -f[1], -f[2]}, e[3];
    sl_vset_irradiance(ll, n, e);
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *px = sl_image_pixel(img, x, y);
            double a = px[3], bg[3] = {0, 0, 0};
            for (int j = 0; j < 2; j++)
                for (int i = 0; i < 2; i++) {
                    double d[3], u, v;
                    float t[4];
                    sl_vset_lens_to_dir(&p->lens, &p->view, img->width, img->height,
                                        x + 0.25 + 0.5 * i, y + 0.25 + 0.5 * j, d);
                    sl_dir_to_latlong(d, &u, &v);
                    sl_latlong_lookup(ll, u, v, t);
                    for (int k = 0; k < 3; k++)
                        bg[k] += 0.25 * t[k];
                }
            for (int k = 0; k < 3; k++)
                px[k] = (float)((px[k] - (1 - a)) * e[k] / VSET_PI + (1 - a) * bg[k]);
        }
}

sl_result sl_vset_probe_render(const sl_vset_probe *p, const sl_image *latlong,
                               sl_image *radiance, sl_vset_probe_geometry *geo, sl_error *err)
{
    memset(radiance, 0, sizeof *radiance);
    sl_vset_probe_geometry g;
    memset(&g, 0, sizeof g);
    if (geo)
        memset(geo, 0, sizeof *geo);
    if (p->lens.type != SL_VSET_LENS_RECTILINEAR || !(p->lens.focal_mm > 0) ||
        !(p->lens.sensor_width_mm > 0))
        return sl_error_set(err, SL_ERR_USAGE, "probe %s: needs a rectilinear lens",
                            sl_vset_probe_name(p->kind));
    if (p->width < 16 || p->height < 16 || p->width > 16384 || p->height > 16384 || p->spp < 1)
        return sl_error_set(err, SL_ERR_USAGE, "probe %s: size %dx%d or %lld spp invalid",
                            sl_vset_probe_name(p->kind), p->width, p->height,
                            (long long)p->spp);
    if (!(p->size_m > 0) || !(p->distance_m > p->size_m))
        return sl_error_set(err, SL_ERR_USAGE,
                            "probe %s: size %g m must be positive and less than the distance %g m",
                            sl_vset_probe_name(p->kind), p->size_m, p->distance_m);
    double f[3], r[3], u[3], c[3];
    vset_view_frame(&p->view, f, r, u);
    for (int k = 0; k < 3; k++)
        c[k] = p->distance_m * f[k];
    g.focal_px = p->lens.focal_mm * p->width / p->lens.sensor_width_mm;

    sl_scene s;
    sl_scene_init(&s);
    snprintf(s.name, sizeof s.name, "vset-%s", sl_vset_probe_name(p->kind));
    sl_camera *cam = &s.camera;
    cam->type = SL_CAMERA_PERSPECTIVE;
    for (int k = 0; k < 3; k++) {
        cam->position[k] = 0;
        cam->forward[k] = f[k];
        cam->up[k] = u[k];
    }
    cam->fov_deg = 2.0 * atan(0.5 * p->lens.sensor_width_mm / p->lens.focal_mm) / VSET_DEG;
    cam->width = p->width;
    cam->height = p->height;
    s.background_env = true;

    sl_result res = SL_OK;
    if (p->kind == SL_VSET_PROBE_CHART) {
        res = add_chart(&s, p, c, f, r, u, g.focal_px, &g, err);
    } else {
        sl_material m;
        int idx;
        if (p->kind == SL_VSET_PROBE_CHROME)
            sl_material_chrome(&m);
        else
            sl_material_lambert(&m, 0.18, 0.18, 0.18);
        double rad = 0.5 * p->size_m;
        res = sl_scene_add_material(&s, &m, &idx, err);
        if (!res)
            res = sl_scene_add_sphere(&s, c, rad, idx, err);
        double a = asin(rad / p->distance_m);
        g.cx = 0.5 * p->width;
        g.cy = 0.5 * p->height;
        g.r = g.focal_px * tan(a);
        g.ball_angle_deg = a / VSET_DEG;
    }
    sl_image unit = {0};
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = p->spp;
    o.seed = p->seed;
    if (p->kind == SL_VSET_PROBE_CHART) {
        o.strategy = SL_STRATEGY_COSINE;
        if (!res)
            res = sl_image_alloc(&unit, 8, 4, 3, err);
        for (int i = 0; !res && i < 8 * 4 * 3; i++)
            unit.data[i] = 1.0f;
    }
    if (!res)
        res = sl_scene_set_dome(&s, p->kind == SL_VSET_PROBE_CHART ? &unit : latlong, 0, 1,
                                "virtual set lat-long", err);
    sl_image_free(&unit);
    sl_render_stats st;
    memset(&st, 0, sizeof st);
    sl_image img = {0};
    if (!res)
        res = sl_render(&s, &o, &img, &st, err);
    if (!res && p->kind == SL_VSET_PROBE_CHART)
        compose_chart(p, latlong, f, &img);
    if (!res)
        res = sl_image_alloc(radiance, p->width, p->height, 3, err);
    if (!res) {
        for (int y = 0; y < p->height; y++)
            for (int x = 0; x < p->width; x++) {
                double v = sl_vset_lens_vignette(&p->lens, p->width, p->height, x + 0.5, y + 0.5);
                const float *src = sl_image_pixel(&img, x, y);
                float *dst = sl_image_pixel(radiance, x, y);
                for (int k = 0; k < 3; k++)
                    dst[k] = (float)(v * src[k]);
            }
        g.spp = st.spp;
        g.seconds = st.seconds;
        g.render_rel_rmse = st.pass_count ? st.passes[st.pass_count - 1].est_rel_rmse : 0;
        if (geo)
            *geo = g;
    }
    sl_render_stats_free(&st);
    sl_image_free(&img);
    sl_scene_free(&s);
    if (res)
        sl_image_free(radiance);
    return res;
}
