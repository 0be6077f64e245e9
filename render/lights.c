/* SPDX-License-Identifier: BSD-3-Clause */
/* Area and distant lights: validation, radiance, solid-angle sampling
 * (spherical rectangles after Urena, Fajardo and King, "An Area-Preserving
 * Parametrization for Spherical Rectangles", EGSR 2013; cones for spheres
 * and distant lights; area sampling for disks) and ray hits for MIS. */
#include <stdlib.h>
#include <string.h>

#include "scene_internal.h"
#include "vec3.h"

static double one_minus_cos_cone(double sin2)
{
    /* 1 - sqrt(1 - s) without cancellation for tiny cones */
    return sin2 / (1.0 + sqrt(fmax(0.0, 1.0 - sin2)));
}

sl_result sl_scene_add_light(sl_scene *scene, sl_light *l, sl_error *err)
{
    const char *bad = NULL;
    if (!v3_finite(l->position) || !v3_finite(l->axis_z) || !v3_finite(l->axis_y))
        bad = "position and axes must be finite";
    else if (!v3_finite(l->color) || l->color[0] < 0 || l->color[1] < 0 || l->color[2] < 0)
        bad = "color must be finite and >= 0";
    else if (!isfinite(l->intensity) || l->intensity < 0 || !isfinite(l->exposure) ||
             fabs(l->exposure) > 200)
        bad = "intensity must be finite and >= 0, exposure finite";
    else if (l->type == SL_LIGHT_RECT && !(l->width > 0 && l->height > 0 && isfinite(l->width) &&
                                           isfinite(l->height)))
        bad = "rect width and height must be > 0";
    else if ((l->type == SL_LIGHT_DISK || l->type == SL_LIGHT_SPHERE) &&
             !(l->radius > 0 && isfinite(l->radius)))
        bad = "radius must be > 0";
    else if (l->type == SL_LIGHT_DISTANT && !(l->angle_deg >= 0 && l->angle_deg < 180))
        bad = "distant angle must be >= 0 and < 180 degrees";
    else if (l->type > SL_LIGHT_DISTANT)
        bad = "unknown light type";
    else if (l->texture.data && l->type != SL_LIGHT_RECT)
        bad = "only rect lights take a texture";
    double z[3], y[3], x[3];
    v3_copy(z, l->axis_z);
    v3_copy(y, l->axis_y);
    if (!bad && !v3_normalize(z))
        bad = "axis_z must not be zero";
    if (!bad) {
        v3_cross(y, z, x);
        if (!v3_normalize(x))
            bad = "axis_y must not be parallel to axis_z";
    }
    if (bad) {
        sl_image_free(&l->texture);
        return sl_error_set(err, SL_ERR_INPUT, "light %d: %s", scene->light_count, bad);
    }
    v3_cross(z, x, y);
    v3_copy(l->axis_x, x);
    v3_copy(l->axis_y, y);
    v3_copy(l->axis_z, z);
    double scale = l->intensity * exp2(l->exposure);
    if (l->normalize) {
        double area = 1.0;
        switch (l->type) {
        case SL_LIGHT_RECT: area = l->width * l->height; break;
        case SL_LIGHT_DISK: area = SL_PI * l->radius * l->radius; break;
        case SL_LIGHT_SPHERE: area = 4.0 * SL_PI * l->radius * l->radius; break;
        case SL_LIGHT_DISTANT: {
            double a = 0.5 * l->angle_deg * SL_PI / 180.0;
            area = l->angle_deg > 0 ? SL_PI * sin(a) * sin(a) : 1.0;
            break;
        }
        }
        scale /= area; /* a delta distant light's intensity is its illuminance either way */
    }
    for (int c = 0; c < 3; c++)
        l->radiance[c] = l->color[c] * scale;
    memset(&l->texture_dist, 0, sizeof l->texture_dist);
    if (l->texture.data) {
        /* Sample the rect in proportion to the texture's luminance: bad texels are 0. */
        const sl_image *tx = &l->texture;
        double *func = malloc((size_t)tx->width * (size_t)tx->height * sizeof *func);
        if (!func) {
            sl_image_free(&l->texture);
            return sl_error_set(err, SL_ERR_NOMEM, "light %d: out of memory", scene->light_count);
        }
        for (int y = 0; y < tx->height; y++)
            for (int x = 0; x < tx->width; x++) {
                float *p = sl_image_pixel(tx, x, y);
                for (int c = 0; c < tx->channels; c++)
                    if (!isfinite(p[c]) || p[c] < 0)
                        p[c] = 0;
                double rgb[3] = {p[0], p[tx->channels >= 3 ? 1 : 0], p[tx->channels >= 3 ? 2 : 0]};
                func[(size_t)y * tx->width + x] = fmax(luminance709(rgb), 1e-3 * fmax(rgb[0], fmax(rgb[1], rgb[2])));
            }
        sl_result r = sl_distrib2d_init(&l->texture_dist, func, tx->width, tx->height, err);
        free(func);
        if (r) {
            sl_image_free(&l->texture);
            return r;
        }
    }
    sl_light *nl = realloc(scene->lights, (size_t)(scene->light_count + 1) * sizeof *nl);
    if (!nl) {
        sl_image_free(&l->texture);
        sl_distrib2d_free(&l->texture_dist);
        return sl_error_set(err, SL_ERR_NOMEM, "scene: out of memory for lights");
    }
    scene->lights = nl;
    nl[scene->light_count++] = *l;
    memset(&l->texture, 0, sizeof l->texture);
    memset(&l->texture_dist, 0, sizeof l->texture_dist);
    return SL_OK;
}

/* Radiance leaving point q of the light toward -d (d travels into the light). */
static void emitted(const sl_light *l, const double q[3], const double d[3], double L[3])
{
    L[0] = L[1] = L[2] = 0;
    if ((l->type == SL_LIGHT_RECT || l->type == SL_LIGHT_DISK) && v3_dot(d, l->axis_z) <= 0)
        return;
    v3_copy(L, l->radiance);
    if (l->type == SL_LIGHT_RECT && l->texture.data) {
        double r[3] = {q[0] - l->position[0], q[1] - l->position[1], q[2] - l->position[2]};
        double s = v3_dot(r, l->axis_x) / l->width + 0.5, t = 0.5 - v3_dot(r, l->axis_y) / l->height;
        const sl_image *tx = &l->texture;
        int x = (int)(s * tx->width), y = (int)(t * tx->height);
        x = x < 0 ? 0 : x >= tx->width ? tx->width - 1 : x;
        y = y < 0 ? 0 : y >= tx->height ? tx->height - 1 : y;
        const float *p = sl_image_pixel(tx, x, y);
        for (int c = 0; c < 3; c++)
            L[c] *= p[tx->channels >= 3 ? c : 0];
    }
}

/* Spherical rectangle seen from p. */
typedef struct sphrect {
    double x[3], y[3], z[3], o[3];
    double x0, y0, z0, x1, y1, b0, b1, k, S;
} sphrect;

static void sphrect_init(sphrect *q, const sl_light *l, const double p[3])
{
    double ex = l->width, ey = l->height;
    double s[3], d[3];
    for (int i = 0; i < 3; i++) {
        s[i] = l->position[i] - 0.5 * ex * l->axis_x[i] - 0.5 * ey * l->axis_y[i];
        d[i] = s[i] - p[i];
    }
    v3_copy(q->o, p);
    v3_copy(q->x, l->axis_x);
    v3_copy(q->y, l->axis_y);
    v3_copy(q->z, l->axis_z);
    q->z0 = v3_dot(d, q->z);
    if (q->z0 > 0) {
        for (int i = 0; i < 3; i++)
            q->z[i] = -q->z[i];
        q->z0 = -q->z0;
    }
    q->x0 = v3_dot(d, q->x), q->y0 = v3_dot(d, q->y);
    q->x1 = q->x0 + ex, q->y1 = q->y0 + ey;
    double z0 = q->z0, x0 = q->x0, y0 = q->y0, x1 = q->x1, y1 = q->y1;
    double n0[3] = {0, z0, -y0}, n1[3] = {-z0, 0, x1}, n2[3] = {0, -z0, y1}, n3[3] = {z0, 0, -x0};
    v3_normalize(n0), v3_normalize(n1), v3_normalize(n2), v3_normalize(n3);
    double g0 = acos(fmax(-1, fmin(1, -v3_dot(n0, n1))));
    double g1 = acos(fmax(-1, fmin(1, -v3_dot(n1, n2))));
    double g2 = acos(fmax(-1, fmin(1, -v3_dot(n2, n3))));
    double g3 = acos(fmax(-1, fmin(1, -v3_dot(n3, n0))));
    q->b0 = n0[2], q->b1 = n2[2];
    q->k = 2.0 * SL_PI - g2 - g3;
    q->S = g0 + g1 - q->k;
}

/* Below this solid angle the rectangle is sampled by area: the spherical
 * construction loses its digits and the two agree there anyway. */
#define SPHRECT_MIN 1e-9

static void sphrect_sample(const sphrect *q, const double u[2], double out[3])
{
    double au = u[0] * q->S + q->k;
    double fu = (cos(au) * q->b0 - q->b1) / sin(au);
    double cu = copysign(1.0, fu) / sqrt(fu * fu + q->b0 * q->b0);
    cu = fmax(-1.0, fmin(1.0, cu));
    double xu = -(cu * q->z0) / sqrt(fmax(1e-300, 1.0 - cu * cu));
    xu = fmax(q->x0, fmin(q->x1, xu));
    double d = sqrt(xu * xu + q->z0 * q->z0);
    double h0 = q->y0 / sqrt(d * d + q->y0 * q->y0), h1 = q->y1 / sqrt(d * d + q->y1 * q->y1);
    double hv = h0 + u[1] * (h1 - h0), hv2 = hv * hv;
    double yv = hv2 < 1.0 - 1e-12 ? hv * d / sqrt(1.0 - hv2) : q->y1;
    yv = fmax(q->y0, fmin(q->y1, yv));
    for (int i = 0; i < 3; i++)
        out[i] = q->o[i] + xu * q->x[i] + yv * q->y[i] + q->z0 * q->z[i];
}

/* Uniform point on a disk of radius r in the (x, y) plane (concentric map). */
static void disk_point(const sl_light *l, const double u[2], double out[3])
{
    double a = 2 * u[0] - 1, b = 2 * u[1] - 1, r, phi;
    if (a == 0 && b == 0)
        r = 0, phi = 0;
    else if (fabs(a) > fabs(b))
        r = a, phi = SL_PI / 4 * (b / a);
    else
        r = b, phi = SL_PI / 2 - SL_PI / 4 * (a / b);
    r *= l->radius;
    for (int i = 0; i < 3; i++)
        out[i] = l->position[i] + r * cos(phi) * l->axis_x[i] + r * sin(phi) * l->axis_y[i];
}

/* Direction in a cone around axis with 1 - cos(theta_max) = omc. */
static void cone_dir(const double axis[3], double omc, const double u[2], double out[3])
{
    double one_minus = u[0] * omc; /* 1 - cos theta */
    double ct = 1.0 - one_minus, st = sqrt(fmax(0.0, one_minus * (2.0 - one_minus)));
    double phi = 2 * SL_PI * u[1];
    frame f;
    frame_from_normal(&f, axis);
    double local[3] = {st * cos(phi), st * sin(phi), ct};
    frame_to_world(&f, local, out);
    v3_normalize(out);
}

static bool sphere_cone(const sl_light *l, const double p[3], double axis[3], double *omc,
                        double *dist)
{
    for (int i = 0; i < 3; i++)
        axis[i] = l->position[i] - p[i];
    double d = v3_length(axis);
    if (!(d > l->radius * (1 + 1e-9)))
        return false;
    for (int i = 0; i < 3; i++)
        axis[i] /= d;
    *omc = one_minus_cos_cone((l->radius / d) * (l->radius / d));
    *dist = d;
    return true;
}

bool sl_light_sample(const sl_light *l, const double p[3], const double u[2], double wi[3],
                     double *dist, double L[3], double *pdf, bool *delta)
{
    double q[3] = {0, 0, 0}; /* every light type sets it; the compiler cannot see the switch is whole */
    *delta = false;
    *pdf = 0;
    switch (l->type) {
    case SL_LIGHT_DISTANT: {
        double a = 0.5 * l->angle_deg * SL_PI / 180.0;
        *dist = INFINITY;
        v3_copy(L, l->radiance);
        if (l->angle_deg == 0) {
            v3_copy(wi, l->axis_z);
            *pdf = 1;
            *delta = true;
            return true;
        }
        double omc = one_minus_cos_cone(sin(a) * sin(a));
        cone_dir(l->axis_z, omc, u, wi);
        *pdf = 1.0 / (2 * SL_PI * omc);
        return true;
    }
    case SL_LIGHT_SPHERE: {
        double axis[3], omc, d;
        if (!sphere_cone(l, p, axis, &omc, &d))
            return false;
        cone_dir(axis, omc, u, wi);
        /* distance to the near side of the sphere along wi */
        double b = d * v3_dot(wi, axis), disc = l->radius * l->radius - (d * d - b * b);
        *dist = b - sqrt(fmax(0.0, disc));
        for (int i = 0; i < 3; i++)
            q[i] = p[i] + *dist * wi[i];
        *pdf = 1.0 / (2 * SL_PI * omc);
        emitted(l, q, wi, L);
        return true;
    }
    case SL_LIGHT_RECT: {
        if (l->texture.data) {
            double st[2], pa;
            sl_distrib2d_sample(&l->texture_dist, u[0], u[1], st, &pa);
            for (int i = 0; i < 3; i++)
                q[i] = l->position[i] + (st[0] - 0.5) * l->width * l->axis_x[i] +
                       (0.5 - st[1]) * l->height * l->axis_y[i];
            break;
        }
        sphrect sr;
        sphrect_init(&sr, l, p);
        if (sr.S > SPHRECT_MIN) {
            sphrect_sample(&sr, u, q);
        } else {
            for (int i = 0; i < 3; i++)
                q[i] = l->position[i] + (u[0] - 0.5) * l->width * l->axis_x[i] +
                       (u[1] - 0.5) * l->height * l->axis_y[i];
        }
        break;
    }
    case SL_LIGHT_DISK:
        disk_point(l, u, q);
        break;
    }
    for (int i = 0; i < 3; i++)
        wi[i] = q[i] - p[i];
    double d = v3_length(wi);
    if (!(d > 0))
        return false;
    for (int i = 0; i < 3; i++)
        wi[i] /= d;
    *dist = d;
    emitted(l, q, wi, L);
    *pdf = sl_light_pdf(l, p, wi, d);
    return *pdf > 0;
}

double sl_light_pdf(const sl_light *l, const double p[3], const double wi[3], double dist)
{
    switch (l->type) {
    case SL_LIGHT_DISTANT: {
        if (l->angle_deg == 0)
            return 0;
        double a = 0.5 * l->angle_deg * SL_PI / 180.0;
        if (v3_dot(wi, l->axis_z) < cos(a))
            return 0;
        return 1.0 / (2 * SL_PI * one_minus_cos_cone(sin(a) * sin(a)));
    }
    case SL_LIGHT_SPHERE: {
        double axis[3], omc, d;
        if (!sphere_cone(l, p, axis, &omc, &d))
            return 0;
        return 1.0 / (2 * SL_PI * omc);
    }
    case SL_LIGHT_RECT: {
        double c = fabs(v3_dot(wi, l->axis_z));
        if (l->texture.data) {
            /* area pdf of the texture distribution at the point, to solid angle */
            double r[3];
            for (int i = 0; i < 3; i++)
                r[i] = p[i] + dist * wi[i] - l->position[i];
            double s = v3_dot(r, l->axis_x) / l->width + 0.5, t = 0.5 - v3_dot(r, l->axis_y) / l->height;
            s = fmin(fmax(s, 0.0), 1.0), t = fmin(fmax(t, 0.0), 1.0);
            double pa = sl_distrib2d_pdf(&l->texture_dist, s, t) / (l->width * l->height);
            return c > 0 ? pa * dist * dist / c : 0;
        }
        sphrect sr;
        sphrect_init(&sr, l, p);
        if (sr.S > SPHRECT_MIN)
            return 1.0 / sr.S;
        return c > 0 ? dist * dist / (c * l->width * l->height) : 0;
    }
    case SL_LIGHT_DISK: {
        double c = fabs(v3_dot(wi, l->axis_z));
        return c > 0 ? dist * dist / (c * SL_PI * l->radius * l->radius) : 0;
    }
    }
    return 0;
}

bool sl_light_intersect(const sl_light *l, const double o[3], const double d[3], double tmax,
                        double *t, double L[3])
{
    double q[3];
    if (l->type == SL_LIGHT_DISTANT) {
        if (!isinf(tmax) || l->angle_deg == 0)
            return false;
        double a = 0.5 * l->angle_deg * SL_PI / 180.0;
        if (v3_dot(d, l->axis_z) < cos(a))
            return false;
        *t = INFINITY;
        v3_copy(L, l->radiance);
        return true;
    }
    if (l->type == SL_LIGHT_SPHERE) {
        sl_shape s = {.type = SL_SHAPE_SPHERE, .radius = l->radius};
        v3_copy(s.center, l->position);
        sl_scene one = {.shapes = &s, .shape_count = 1};
        sl_hit h;
        if (!sl_scene_intersect(&one, o, d, 0.0, tmax, &h))
            return false;
        *t = h.t;
        emitted(l, h.p, d, L);
        return true;
    }
    double dn = v3_dot(d, l->axis_z);
    if (dn == 0)
        return false;
    double co[3] = {l->position[0] - o[0], l->position[1] - o[1], l->position[2] - o[2]};
    double tt = v3_dot(co, l->axis_z) / dn;
    if (!(tt > 0 && tt < tmax))
        return false;
    for (int i = 0; i < 3; i++)
        q[i] = o[i] + tt * d[i];
    double r[3] = {q[0] - l->position[0], q[1] - l->position[1], q[2] - l->position[2]};
    double x = v3_dot(r, l->axis_x), y = v3_dot(r, l->axis_y);
    if (l->type == SL_LIGHT_RECT ? (fabs(x) > 0.5 * l->width || fabs(y) > 0.5 * l->height)
                                 : (x * x + y * y > l->radius * l->radius))
        return false;
    *t = tt;
    emitted(l, q, d, L);
    return true;
}

double sl_light_irradiance_bound(const sl_light *l, const double p[3], const double n[3],
                                 bool *behind)
{
    *behind = false;
    double Lmax = fmax(l->radiance[0], fmax(l->radiance[1], l->radiance[2]));
    if (l->type == SL_LIGHT_DISTANT) {
        double a = 0.5 * l->angle_deg * SL_PI / 180.0;
        if (v3_dot(l->axis_z, n) <= -sin(a)) {
            *behind = true;
            return 0;
        }
        if (l->angle_deg == 0)
            return Lmax;
        return Lmax * 2 * SL_PI * one_minus_cos_cone(sin(a) * sin(a));
    }
    double d[3] = {p[0] - l->position[0], p[1] - l->position[1], p[2] - l->position[2]};
    double R = l->type == SL_LIGHT_RECT ? 0.5 * sqrt(l->width * l->width + l->height * l->height)
                                        : l->radius;
    if ((l->type != SL_LIGHT_SPHERE && v3_dot(d, l->axis_z) >= 0) || v3_dot(d, n) >= R) {
        *behind = true; /* the back of a one-sided light, or wholly below the horizon */
        return 0;
    }
    if (l->texture.data)
        return INFINITY;
    double dist2 = v3_dot(d, d);
    if (!(dist2 > R * R * (1 + 1e-9)))
        return INFINITY;
    return Lmax * 2 * SL_PI * one_minus_cos_cone(R * R / dist2);
}
