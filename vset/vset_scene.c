/* SPDX-License-Identifier: BSD-3-Clause */
/* Virtual-set scenes: the built-in presets, validation, and the ground-
 * truth lat-long with its light list. Texels touched by a light's edge are
 * supersampled (at least 16 x 16, and 48 samples across the light's
 * smallest extent) with exact sub-texel solid angles, so each light's
 * integral over the texels matches radiance * solid angle closely without
 * any renormalisation. Lights earlier in the list are in front. */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "vset_internal.h"

#define EDGE_SS 16      /* least samples per side in texels on a light's edge */
#define EDGE_SS_MAX 160 /* most */
#define ACROSS 48       /* samples across a light's smallest extent, at least */
#define FILL_SS 2       /* texels away from lights */

static const char *const preset_names[] = {"exterior", "stage", "night", NULL};

const char *const *sl_vset_preset_names(void) { return preset_names; }

static sl_vset_light *add_light(sl_vset_desc *d, const char *name, sl_vset_shape shape,
                                double az, double el, double w, double h, double kelvin,
                                double lum)
{
    sl_vset_light *l = &d->lights[d->light_count++];
    memset(l, 0, sizeof *l);
    snprintf(l->name, sizeof l->name, "%s", name);
    l->shape = shape;
    l->emit = SL_VSET_EMIT_UNIFORM;
    l->azimuth_deg = az;
    l->elevation_deg = el;
    l->width_deg = w;
    l->height_deg = h;
    l->kelvin = kelvin;
    l->luminance = lum;
    return l;
}

static void desc_defaults(sl_vset_desc *d, const char *name)
{
    memset(d, 0, sizeof *d);
    snprintf(d->name, sizeof d->name, "%s", name);
    d->sun_azimuth_deg = 60;
    d->sun_elevation_deg = 35;
    d->turbidity = 3;
    d->ground_albedo = 0.2;
    d->room_illuminance = 150;
    d->dark_luminance = 1e-3;
}

sl_result sl_vset_preset(const char *name, sl_vset_desc *d, sl_error *err)
{
    if (!name || !*name)
        return sl_error_set(err, SL_ERR_USAGE, "no scene name given");
    if (!strcmp(name, "exterior")) {
        desc_defaults(d, name);
        d->background = SL_VSET_BG_SKY;
        sl_vset_light *sun = add_light(d, "sun", SL_VSET_SHAPE_DISK, 60, 35,
                                       VSET_SUN_DIAMETER_DEG, VSET_SUN_DIAMETER_DEG, 0, 0);
        sun->emit = SL_VSET_EMIT_SUN;
    } else if (!strcmp(name, "stage")) {
        /* A 4 ft two-tube fixture 2.3 m away, a 1 m softbox, three frosted
         * 60 mm bulbs and a window looking out on daylight. */
        desc_defaults(d, name);
        d->background = SL_VSET_BG_ROOM;
        d->sun_azimuth_deg = 150;
        d->sun_elevation_deg = 40;
        add_light(d, "kino_warm", SL_VSET_SHAPE_RECT, -42, 12, 0.8, 28, 3200, 1.2e4);
        add_light(d, "kino_cool", SL_VSET_SHAPE_RECT, -38, 12, 0.8, 28, 5600, 1.2e4);
        add_light(d, "softbox", SL_VSET_SHAPE_RECT, 35, 18, 22, 22, 5600, 3000);
        add_light(d, "bulb_1", SL_VSET_SHAPE_DISK, 150, 35, 1.5, 1.5, 2700, 1e5);
        add_light(d, "bulb_2", SL_VSET_SHAPE_DISK, -150, 42, 1.5, 1.5, 2700, 1e5);
        add_light(d, "bulb_3", SL_VSET_SHAPE_DISK, 178, 62, 1.5, 1.5, 2700, 1e5);
        sl_vset_light *w = add_light(d, "window", SL_VSET_SHAPE_RECT, 100, 5, 30, 40, 0, 0.8);
        w->emit = SL_VSET_EMIT_WINDOW;
    } else if (!strcmp(name, "night")) {
        desc_defaults(d, name);
        d->background = SL_VSET_BG_DARK;
        add_light(d, "sodium_lamp", SL_VSET_SHAPE_DISK, -70, 25, 0.4, 0.4, 2000, 1e5);
        add_light(d, "headlight", SL_VSET_SHAPE_DISK, 20, -2, 0.25, 0.25, 6000, 1e6);
        add_light(d, "lit_window", SL_VSET_SHAPE_RECT, 120, 8, 0.6, 0.8, 3000, 1e4);
        sl_vset_light *neon = add_light(d, "neon_sign", SL_VSET_SHAPE_RECT, -160, 12, 1.6,
                                        0.3, 0, 3e4);
        neon->rgb[0] = 1.0;
        neon->rgb[1] = 0.08;
        neon->rgb[2] = 0.25;
    } else {
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: unknown scene (built in: exterior, stage, night; or a .json file)",
                            name);
    }
    return SL_OK;
}

static bool finite_in(double v, double lo, double hi) { return isfinite(v) && v >= lo && v <= hi; }

sl_result sl_vset_desc_validate(const sl_vset_desc *d, sl_error *err)
{
    const char *n = d->name[0] ? d->name : "scene";
    if ((int)d->background < SL_VSET_BG_SKY || (int)d->background > SL_VSET_BG_DARK)
        return sl_error_set(err, SL_ERR_INPUT, "%s: unknown background", n);
    if (!finite_in(d->turbidity, 1.7, 10))
        return sl_error_set(err, SL_ERR_INPUT, "%s: turbidity %g outside 1.7..10", n,
                            d->turbidity);
    if (!finite_in(d->ground_albedo, 0, 1))
        return sl_error_set(err, SL_ERR_INPUT, "%s: ground_albedo %g outside 0..1", n,
                            d->ground_albedo);
    if (!finite_in(d->room_illuminance, 0, 1e6))
        return sl_error_set(err, SL_ERR_INPUT, "%s: room_illuminance %g outside 0..1e6", n,
                            d->room_illuminance);
    if (!finite_in(d->dark_luminance, 0, 1e6))
        return sl_error_set(err, SL_ERR_INPUT, "%s: dark_luminance %g outside 0..1e6", n,
                            d->dark_luminance);
    if (!finite_in(d->sun_azimuth_deg, -360, 360) || !finite_in(d->sun_elevation_deg, 1, 90))
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: sun azimuth must be -360..360 and elevation 1..90 degrees", n);
    if (d->light_count < 0 || d->light_count > SL_VSET_MAX_LIGHTS)
        return sl_error_set(err, SL_ERR_INPUT, "%s: %d lights (at most %d)", n, d->light_count,
                            SL_VSET_MAX_LIGHTS);
    int suns = 0;
    for (int i = 0; i < d->light_count; i++) {
        const sl_vset_light *l = &d->lights[i];
        const char *ln = l->name[0] ? l->name : "light";
        if (!finite_in(l->azimuth_deg, -360, 360) || !finite_in(l->elevation_deg, -90, 90))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: light %s: azimuth must be -360..360, elevation -90..90", n, ln);
        if (l->shape == SL_VSET_SHAPE_DISK) {
            if (!(isfinite(l->width_deg) && l->width_deg > 0 && l->width_deg < 180))
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: diameter %g must be > 0 and < 180 degrees", n,
                                    ln, l->width_deg);
        } else if (l->shape == SL_VSET_SHAPE_RECT) {
            if (!(isfinite(l->width_deg) && l->width_deg > 0 && l->width_deg < 160 &&
                  isfinite(l->height_deg) && l->height_deg > 0 && l->height_deg < 160))
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: width and height (%g, %g) must be > 0 and < 160 degrees",
                                    n, ln, l->width_deg, l->height_deg);
            if (!finite_in(l->roll_deg, -360, 360))
                return sl_error_set(err, SL_ERR_INPUT, "%s: light %s: roll outside -360..360", n,
                                    ln);
        } else {
            return sl_error_set(err, SL_ERR_INPUT, "%s: light %s: unknown shape", n, ln);
        }
        switch (l->emit) {
        case SL_VSET_EMIT_SUN:
            suns++;
            if (l->shape != SL_VSET_SHAPE_DISK || d->background != SL_VSET_BG_SKY)
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: a sun must be a disk over a sky background", n,
                                    ln);
            if (!finite_in(l->elevation_deg, 1, 90))
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: sun elevation %g outside 1..90 degrees", n, ln,
                                    l->elevation_deg);
            break;
        case SL_VSET_EMIT_WINDOW:
            if (!finite_in(l->luminance, 0, 1) || l->luminance == 0)
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: window transmission %g must be in (0, 1]", n,
                                    ln, l->luminance);
            break;
        case SL_VSET_EMIT_UNIFORM:
            if (!(isfinite(l->luminance) && l->luminance > 0 && l->luminance <= 1e12))
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: luminance %g must be > 0 (cd/m^2)", n, ln,
                                    l->luminance);
            if (l->kelvin != 0 && !finite_in(l->kelvin, 1667, 25000))
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: light %s: kelvin %g outside 1667..25000", n, ln,
                                    l->kelvin);
            if (l->kelvin == 0) {
                double s = 0;
                for (int c = 0; c < 3; c++) {
                    if (!finite_in(l->rgb[c], 0, 1e6))
                        return sl_error_set(err, SL_ERR_INPUT,
                                            "%s: light %s: rgb values must be >= 0", n, ln);
                    s += l->rgb[c];
                }
                if (s <= 0)
                    return sl_error_set(err, SL_ERR_INPUT,
                                        "%s: light %s: needs kelvin or a non-black rgb", n, ln);
            }
            break;
        default:
            return sl_error_set(err, SL_ERR_INPUT, "%s: light %s: unknown emission", n, ln);
        }
    }
    if (suns > 1)
        return sl_error_set(err, SL_ERR_INPUT, "%s: %d suns (at most one)", n, suns);
    return SL_OK;
}

/* ---- geometry of one light ------------------------------------------ */

typedef struct light_geo {
    double c[3], right[3], up[3];
    double tx, ty;    /* rect half extents, as tangents */
    double cos_r;     /* disk */
    double bound;     /* angular radius of a cap holding the whole light */
    double min_extent; /* smallest angular extent, radians */
    double rgb[3];    /* uniform radiance */
    sl_vset_emit emit;
    double transmission;
} light_geo;

typedef struct scene_ctx {
    const sl_vset_desc *desc;
    vset_daylight day;
    light_geo geo[SL_VSET_MAX_LIGHTS];
    int count;
    int only; /* -1: everything; else only this light on black */
    sl_image *img;
    double night_tint[3];
} scene_ctx;

static void light_frame(const sl_vset_light *l, light_geo *g)
{
    vset_azel_dir(l->azimuth_deg, l->elevation_deg, g->c);
    double az = l->azimuth_deg * VSET_DEG, roll = l->roll_deg * VSET_DEG;
    double r0[3] = {-cos(az), 0, sin(az)}, u0[3];
    v3_cross(r0, g->c, u0);
    for (int k = 0; k < 3; k++) {
        g->right[k] = cos(roll) * r0[k] + sin(roll) * u0[k];
        g->up[k] = -sin(roll) * r0[k] + cos(roll) * u0[k];
    }
    if (l->shape == SL_VSET_SHAPE_DISK) {
        double r = 0.5 * l->width_deg * VSET_DEG;
        g->cos_r = cos(r);
        g->bound = r;
        g->min_extent = 2 * r;
    } else {
        g->tx = tan(0.5 * l->width_deg * VSET_DEG);
        g->ty = tan(0.5 * l->height_deg * VSET_DEG);
        g->bound = atan(sqrt(g->tx * g->tx + g->ty * g->ty));
        g->min_extent = fmin(l->width_deg, l->height_deg) * VSET_DEG;
    }
}

static bool light_contains(const sl_vset_light *l, const light_geo *g, const double d[3])
{
    double z = v3_dot(d, g->c);
    if (l->shape == SL_VSET_SHAPE_DISK)
        return z >= g->cos_r;
    if (z <= 0)
        return false;
    return fabs(v3_dot(d, g->right)) <= g->tx * z && fabs(v3_dot(d, g->up)) <= g->ty * z;
}

static void light_radiance(const scene_ctx *s, int i, const double d[3], double rgb[3])
{
    const light_geo *g = &s->geo[i];
    if (g->emit == SL_VSET_EMIT_WINDOW) {
        vset_daylight_radiance(&s->day, d, rgb);
        for (int c = 0; c < 3; c++)
            rgb[c] *= g->transmission;
    } else {
        memcpy(rgb, g->rgb, sizeof g->rgb);
    }
}

/* ---- backgrounds ----------------------------------------------------- */

static void room_radiance(const scene_ctx *s, const double d[3], double rgb[3])
{
    /* A 10 x 4.2 x 12 m stage, camera 1.6 m above the floor. */
    static const double lo[3] = {-5, -1.6, -6}, hi[3] = {5, 2.6, 6};
    double t = DBL_MAX;
    int axis = 0;
    for (int k = 0; k < 3; k++) {
        if (d[k] == 0)
            continue;
        double tk = (d[k] > 0 ? hi[k] : lo[k]) / d[k];
        if (tk < t) {
            t = tk;
            axis = k;
        }
    }
    double p[3] = {d[0] * t, d[1] * t, d[2] * t};
    double albedo, tint[3] = {1, 1, 1};
    if (axis == 1 && d[1] < 0) {
        /* Wooden floor: 20 cm planks along x, each its own shade, with grain. */
        double plank = floor(p[2] / 0.2);
        double shade = 0.25 + 0.15 * vset_uniform(21, 0, (uint64_t)(int64_t)(plank + 1000));
        double grain = vset_fbm(p[0] * 0.7, p[2] * 12.0, 4, 22) - 0.5;
        double gap = fabs(p[2] / 0.2 - plank - 0.5) > 0.47 ? 0.4 : 1.0;
        albedo = shade * (1.0 + 0.5 * grain) * gap;
        tint[0] = 1.25;
        tint[1] = 0.95;
        tint[2] = 0.65;
    } else if (axis == 1) {
        /* Black ceiling with a lighting grid every metre. */
        double gx = fabs(p[0] - floor(p[0]) - 0.5), gz = fabs(p[2] - floor(p[2]) - 0.5);
        albedo = (gx > 0.47 || gz > 0.47) ? 0.3 : 0.06;
    } else {
        /* Painted plaster walls with a dark skirting board. */
        double a = axis == 0 ? p[2] : p[0];
        double blotch = vset_fbm(a * 0.9, p[1] * 0.9, 5, 23 + (uint64_t)axis) - 0.5;
        albedo = p[1] < -1.45 ? 0.08 : 0.45 * (1.0 + 0.35 * blotch);
        tint[0] = 1.05;
        tint[1] = 1.0;
        tint[2] = 0.92;
    }
    double e = s->desc->room_illuminance * (1.0 - 0.25 * (p[1] + 1.6) / 4.2);
    for (int c = 0; c < 3; c++)
        rgb[c] = albedo * tint[c] * e / VSET_PI;
}

static void background(const scene_ctx *s, const double d[3], double rgb[3])
{
    switch (s->desc->background) {
    case SL_VSET_BG_SKY:
        vset_daylight_radiance(&s->day, d, rgb);
        break;
    case SL_VSET_BG_ROOM:
        room_radiance(s, d, rgb);
        break;
    default:
        for (int c = 0; c < 3; c++)
            rgb[c] = s->desc->dark_luminance * (1.0 + 0.5 * d[1]) * s->night_tint[c];
        break;
    }
}

/* Radiance of one sample direction: the first light holding it, else the
 * background (or black when drawing one light alone). */
static void sample(const scene_ctx *s, const int *near, int nnear, const double d[3],
                   double rgb[3])
{
    for (int k = 0; k < nnear; k++) {
        int i = near[k];
        if (light_contains(&s->desc->lights[i], &s->geo[i], d)) {
            light_radiance(s, i, d, rgb);
            return;
        }
    }
    if (s->only >= 0)
        rgb[0] = rgb[1] = rgb[2] = 0;
    else
        background(s, d, rgb);
}

/* Mean radiance over texel (x, y) with n x n samples weighted by their
 * exact solid angles. */
static void texel_mean(const scene_ctx *s, const int *near, int nnear, int x, int y, int n,
                       double out[3])
{
    int w = s->img->width, h = s->img->height;
    double acc[3] = {0, 0, 0}, wsum = 0;
    for (int j = 0; j < n; j++) {
        double v0 = (y + (double)j / n) / h, v1 = (y + (double)(j + 1) / n) / h;
        double wt = sin(VSET_PI * (0.5 - v0)) - sin(VSET_PI * (0.5 - v1));
        for (int i = 0; i < n; i++) {
            /* Jittered within each cell (fixed by position) so that edges
             * aligned with the texel grid do not alias. */
            uint64_t id = ((uint64_t)y * (uint64_t)w + (uint64_t)x) * 65536u + (uint64_t)(j * n + i);
            double v = v0 + (v1 - v0) * vset_uniform(7, 1, id);
            double u = (x + (i + vset_uniform(7, 2, id)) / n) / w, d[3], rgb[3];
            sl_latlong_to_dir(u, v, d);
            sample(s, near, nnear, d, rgb);
            for (int c = 0; c < 3; c++)
                acc[c] += wt * rgb[c];
        }
        wsum += wt * n;
    }
    for (int c = 0; c < 3; c++)
        out[c] = acc[c] / wsum;
}

/* True when a texel of angular half-diagonal `half` around d lies wholly
 * outside a rect light. On the light's plane a displacement of angle a
 * moves at most a (1 + x^2 + y^2), so that margin is conservative. */
static bool rect_misses(const light_geo *g, const double d[3], double half)
{
    if (g->tx == 0)
        return false; /* a disk: the cap test is already exact */
    double z = v3_dot(d, g->c);
    if (z < 0.2)
        return false;
    double x = v3_dot(d, g->right) / z, y = v3_dot(d, g->up) / z;
    double m = 1.2 * half * (1.0 + x * x + y * y) + 1e-9;
    return fabs(x) > g->tx + m || fabs(y) > g->ty + m;
}

static void scene_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const scene_ctx *s = ctx;
    int w = s->img->width, h = s->img->height;
    for (int64_t yy = begin; yy < end; yy++) {
        int y = (int)yy;
        double lat0 = VSET_PI * (0.5 - (double)y / h), lat1 = VSET_PI * (0.5 - (y + 1.0) / h);
        double eq = (lat0 > 0 && lat1 < 0) ? 1.0 : fmax(cos(lat0), cos(lat1));
        double half = sqrt(pow(0.5 * VSET_PI / h, 2) + pow(VSET_PI / w * eq, 2)) * 1.05;
        /* Lights whose latitude band misses this row are skipped for it. */
        double latc = VSET_PI * (0.5 - (y + 0.5) / h);
        int row_lights[SL_VSET_MAX_LIGHTS], nrow = 0;
        double cos_reach[SL_VSET_MAX_LIGHTS];
        for (int i = 0; i < s->count; i++) {
            if (s->only >= 0 && i != s->only)
                continue;
            double latl = asin(fmax(-1.0, fmin(1.0, s->geo[i].c[1])));
            double reach = s->geo[i].bound + half;
            if (fabs(latc - latl) > reach)
                continue;
            cos_reach[nrow] = reach >= VSET_PI ? -1.0 : cos(reach);
            row_lights[nrow++] = i;
        }
        if (s->only >= 0 && nrow == 0)
            continue; /* the image is already black */
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            int near[SL_VSET_MAX_LIGHTS], nnear = 0, n = EDGE_SS;
            for (int k = 0; k < nrow; k++) {
                int i = row_lights[k];
                if (v3_dot(d, s->geo[i].c) >= cos_reach[k] && !rect_misses(&s->geo[i], d, half)) {
                    near[nnear++] = i;
                    double need = ceil(ACROSS * 2 * half / s->geo[i].min_extent);
                    if (need > n)
                        n = need > EDGE_SS_MAX ? EDGE_SS_MAX : (int)need;
                }
            }
            /* A texel wholly inside a single light needs no edge sampling. */
            if (nnear == 1) {
                const sl_vset_light *l = &s->desc->lights[near[0]];
                const light_geo *g = &s->geo[near[0]];
                bool inside = true;
                for (int k = 0; k < 4 && inside; k++) {
                    double cd[3];
                    sl_latlong_to_dir((double)(x + (k & 1)) / w, (double)(y + (k >> 1)) / h, cd);
                    inside = light_contains(l, g, cd);
                }
                if (inside && light_contains(l, g, d))
                    n = FILL_SS;
            }
            double rgb[3];
            if (nnear > 0)
                texel_mean(s, near, nnear, x, y, n, rgb);
            else if (s->only >= 0)
                rgb[0] = rgb[1] = rgb[2] = 0;
            else
                texel_mean(s, near, 0, x, y, FILL_SS, rgb);
            float *px = sl_image_pixel(s->img, x, y);
            for (int c = 0; c < 3; c++)
                px[c] = (float)rgb[c];
        }
    }
}

/* Exact solid angle of a camera-facing rectangle of half tangents tx, ty. */
static double rect_solid_angle(double tx, double ty)
{
    return 4.0 * atan(tx * ty / sqrt(1.0 + tx * tx + ty * ty));
}

static void ctx_init(scene_ctx *s, sl_vset_desc *d)
{
    memset(s, 0, sizeof *s);
    s->desc = d;
    s->only = -1;
    s->count = d->light_count;
    for (int i = 0; i < d->light_count; i++)
        if (d->lights[i].emit == SL_VSET_EMIT_SUN) {
            d->sun_azimuth_deg = d->lights[i].azimuth_deg;
            d->sun_elevation_deg = d->lights[i].elevation_deg;
        }
    vset_daylight_init(&s->day, d->sun_azimuth_deg, d->sun_elevation_deg, d->turbidity,
                       d->ground_albedo);
    sl_vset_kelvin_rgb(9000, s->night_tint);
    for (int i = 0; i < d->light_count; i++) {
        sl_vset_light *l = &d->lights[i];
        light_geo *g = &s->geo[i];
        light_frame(l, g);
        g->emit = l->emit;
        memcpy(l->dir, g->c, sizeof l->dir);
        l->solid_angle = l->shape == SL_VSET_SHAPE_DISK ? 2.0 * VSET_PI * (1.0 - g->cos_r)
                                                        : rect_solid_angle(g->tx, g->ty);
        if (l->emit == SL_VSET_EMIT_SUN) {
            memcpy(g->rgb, s->day.sun_rgb, sizeof g->rgb);
        } else if (l->emit == SL_VSET_EMIT_UNIFORM) {
            double col[3];
            if (l->kelvin > 0) {
                sl_vset_kelvin_rgb(l->kelvin, col);
            } else {
                double y = 0.2126390059 * l->rgb[0] + 0.7151686788 * l->rgb[1] +
                           0.0721923154 * l->rgb[2];
                for (int c = 0; c < 3; c++)
                    col[c] = y > 0 ? l->rgb[c] / y : 0;
            }
            for (int c = 0; c < 3; c++)
                g->rgb[c] = col[c] * l->luminance;
        } else {
            g->transmission = l->luminance;
        }
        if (l->emit != SL_VSET_EMIT_WINDOW) {
            for (int c = 0; c < 3; c++) {
                l->radiance[c] = g->rgb[c];
                l->integral[c] = g->rgb[c] * l->solid_angle;
            }
        } else {
            /* Integrate the view through the window over its own plane:
             * d omega = dx dy / (1 + x^2 + y^2)^(3/2). */
            const int n = 160;
            double acc[3] = {0, 0, 0};
            double dx = 2 * g->tx / n, dy = 2 * g->ty / n;
            for (int j = 0; j < n; j++) {
                double py = -g->ty + (j + 0.5) * dy;
                for (int k = 0; k < n; k++) {
                    double px = -g->tx + (k + 0.5) * dx, dir[3], rgb[3];
                    for (int c = 0; c < 3; c++)
                        dir[c] = g->c[c] + px * g->right[c] + py * g->up[c];
                    double q = 1.0 + px * px + py * py;
                    double dw = dx * dy / (q * sqrt(q));
                    v3_normalize(dir);
                    vset_daylight_radiance(&s->day, dir, rgb);
                    for (int c = 0; c < 3; c++)
                        acc[c] += rgb[c] * g->transmission * dw;
                }
            }
            for (int c = 0; c < 3; c++) {
                l->integral[c] = acc[c];
                l->radiance[c] = acc[c] / l->solid_angle;
            }
        }
    }
}

static sl_result check_width(int width, sl_error *err)
{
    if (width < 16 || width > 16384 || width % 2)
        return sl_error_set(err, SL_ERR_USAGE, "lat-long width %d must be even and 16..16384",
                            width);
    return SL_OK;
}

static void image_integral(const sl_image *img, double total[3])
{
    for (int c = 0; c < 3; c++) {
        double sum = 0, comp = 0;
        for (int y = 0; y < img->height; y++) {
            double row = 0;
            for (int x = 0; x < img->width; x++)
                row += sl_image_pixel(img, x, y)[c];
            double t = row * sl_latlong_texel_solid_angle(y, img->width, img->height) - comp;
            double s2 = sum + t;
            comp = (s2 - sum) - t;
            sum = s2;
        }
        total[c] = sum;
    }
}

sl_result sl_vset_scene_make(const sl_vset_desc *desc, int width, sl_vset_scene *scene,
                             sl_error *err)
{
    memset(scene, 0, sizeof *scene);
    sl_result r = check_width(width, err);
    if (r)
        return r;
    if ((r = sl_vset_desc_validate(desc, err)))
        return r;
    scene->desc = *desc;
    if ((r = sl_image_alloc(&scene->latlong, width, width / 2, 3, err)))
        return r;
    scene_ctx s;
    ctx_init(&s, &scene->desc);
    s.img = &scene->latlong;
    sl_parallel_for(scene->latlong.height, 4, scene_rows, &s);
    image_integral(&scene->latlong, scene->total);
    return SL_OK;
}

void sl_vset_scene_free(sl_vset_scene *scene)
{
    if (!scene)
        return;
    sl_image_free(&scene->latlong);
    memset(scene, 0, sizeof *scene);
}

sl_result sl_vset_light_image(const sl_vset_desc *desc, int index, int width, sl_image *out,
                              sl_error *err)
{
    memset(out, 0, sizeof *out);
    sl_result r = check_width(width, err);
    if (r)
        return r;
    if ((r = sl_vset_desc_validate(desc, err)))
        return r;
    if (index < 0 || index >= desc->light_count)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no light %d", desc->name, index);
    if ((r = sl_image_alloc(out, width, width / 2, 3, err)))
        return r;
    sl_vset_desc d = *desc;
    scene_ctx s;
    ctx_init(&s, &d);
    s.only = index;
    s.img = out;
    sl_parallel_for(out->height, 4, scene_rows, &s);
    return SL_OK;
}
