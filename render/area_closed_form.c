/* SPDX-License-Identifier: BSD-3-Clause */
/* The closed form of a rig's lights at a Lambert point: a uniformly
 * emitting rect seen from p is a spherical polygon, whose cosine-weighted
 * solid angle after clipping at the tangent plane is Lambert's formula
 * (1/2 sum of edge angle x n . edge normal; Arvo 1995); spheres and cones
 * (distant lights) are spherical caps, exact with the horizon (Snyder 1996);
 * a disk lies between its inscribed and circumscribed polygons, which bound
 * it. A textured rect stays sampled. */
#include "area_closed_form.h"
#include "glossy.h"

/* Most sides of a disk's polygons (a relative gap of 1e-5). */
#define DISK_MAX_SIDES 1024

static double clamp1(double x) { return x < -1 ? -1 : x > 1 ? 1 : x; }

double sl_polygon_cosine_integral(const double (*v)[3], int nv, const double p[3], const double n[3])
{
    /* Vertices relative to p, clipped at n . r >= 0 (Sutherland-Hodgman):
     * a convex polygon gains at most one vertex. */
    double r[DISK_MAX_SIDES + 1][3];
    int m = 0;
    if (nv < 3 || nv > DISK_MAX_SIDES)
        return 0;
    for (int i = 0; i < nv; i++) {
        const double *a = v[i], *b = v[(i + 1) % nv];
        double ra[3] = {a[0] - p[0], a[1] - p[1], a[2] - p[2]};
        double rb[3] = {b[0] - p[0], b[1] - p[1], b[2] - p[2]};
        double da = v3_dot(n, ra), db = v3_dot(n, rb);
        if (da >= 0 && m <= DISK_MAX_SIDES)
            v3_copy(r[m++], ra);
        if ((da >= 0) != (db >= 0) && m <= DISK_MAX_SIDES) {
            double t = da / (da - db);
            for (int k = 0; k < 3; k++)
                r[m][k] = ra[k] + t * (rb[k] - ra[k]);
            m++;
        }
    }
    if (m < 3)
        return 0;
    for (int i = 0; i < m; i++)
        if (!v3_normalize(r[i]))
            return 0; /* p on the polygon's outline: no solid angle to speak of */
    double sum = 0;
    for (int i = 0; i < m; i++) {
        const double *a = r[i], *b = r[(i + 1) % m];
        double c[3];
        v3_cross(a, b, c);
        double s = v3_length(c);
        if (s > 0)
            sum += atan2(s, v3_dot(a, b)) / s * v3_dot(n, c);
    }
    return 0.5 * fabs(sum);
}

double sl_cap_cosine_integral(const double a[3], double sin2_sigma, const double n[3])
{
    double s2 = fmin(fmax(sin2_sigma, 0.0), 1.0), ss = sqrt(s2);
    double ct = clamp1(v3_dot(n, a)), st = sqrt(fmax(0.0, 1.0 - ct * ct));
    if (ct >= ss)
        return SL_PI * s2 * ct; /* wholly above the horizon */
    if (ct <= -ss || !(st > 0))
        return 0;
    /* The horizon cuts the cap (Snyder 1996, as in Lagarde and de Rousiers 2014). */
    double x = sqrt(fmax(0.0, 1.0 / s2 - 1.0)); /* cot sigma */
    double y = clamp1(-x * ct / st);
    double sy = st * sqrt(fmax(0.0, 1.0 - y * y));
    return fmax(0.0, (ct * acos(y) - x * sy) * s2 + atan2(sy, x));
}

bool sl_light_has_closed_form(const sl_light *l) { return !l->texture.data; }

/* The regular polygon of `sides` vertices at radius rad in the disk's plane. */
static void disk_polygon(const sl_light *l, int sides, double rad, double (*v)[3])
{
    for (int k = 0; k < sides; k++) {
        double phi = 2 * SL_PI * k / sides, c = rad * cos(phi), s = rad * sin(phi);
        for (int i = 0; i < 3; i++)
            v[k][i] = l->position[i] + c * l->axis_x[i] + s * l->axis_y[i];
    }
}

/* Disk: inscribed (radius r) and circumscribed (r / cos(pi/N)) polygons
 * hold the disk between them, so its integral lies between theirs; the
 * estimate interpolates by area (exact for a small disk). Gap ~ (pi/N)^2;
 * where the horizon cuts the disk the two differ more, and N grows until
 * the bound is within tol of the estimate (or N reaches its maximum). */
static double disk_integral(const sl_light *l, const double p[3], const double n[3], double tol,
                            double *bound)
{
    static _Thread_local double v[DISK_MAX_SIDES][3];
    int sides = (int)ceil(SL_PI / sqrt(fmax(tol, 1e-6)));
    sides = sides < 16 ? 16 : sides > DISK_MAX_SIDES ? DISK_MAX_SIDES : sides;
    for (;;) {
        double c = cos(SL_PI / sides);
        disk_polygon(l, sides, l->radius, v);
        double in = sl_polygon_cosine_integral((const double(*)[3])v, sides, p, n);
        disk_polygon(l, sides, l->radius / c, v);
        double out = sl_polygon_cosine_integral((const double(*)[3])v, sides, p, n);
        double a_in = 0.5 * sides * sin(2 * SL_PI / sides), a_out = sides * tan(SL_PI / sides);
        double f = (SL_PI - a_in) / (a_out - a_in);
        double est = in + f * (out - in);
        *bound = fmax(est - in, out - est);
        if (*bound <= tol * est || sides >= DISK_MAX_SIDES)
            return est;
        sides = sides * 4 > DISK_MAX_SIDES ? DISK_MAX_SIDES : sides * 4;
    }
}

bool sl_light_irradiance(const sl_light *l, const double p[3], const double n[3], double tol,
                         double E[3], double bound[3])
{
    double g = 0, b = 0; /* cosine-weighted solid angle and its bound */
    E[0] = E[1] = E[2] = bound[0] = bound[1] = bound[2] = 0;
    double d[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
    switch (l->type) {
    case SL_LIGHT_DISTANT:
        if (l->angle_deg == 0) {
            g = fmax(0.0, v3_dot(n, l->axis_z)); /* radiance is irradiance */
        } else {
            double s = sin(0.5 * l->angle_deg * SL_PI / 180.0);
            g = sl_cap_cosine_integral(l->axis_z, s * s, n);
        }
        break;
    case SL_LIGHT_SPHERE: {
        double dist = v3_length(d);
        if (!(dist > l->radius * (1 + 1e-9)))
            return false;
        for (int i = 0; i < 3; i++)
            d[i] /= dist;
        g = sl_cap_cosine_integral(d, (l->radius / dist) * (l->radius / dist), n);
        break;
    }
    case SL_LIGHT_RECT: {
        if (!sl_light_has_closed_form(l))
            return false;
        if (v3_dot(d, l->axis_z) <= 0)
            break; /* the back of a one-sided light */
        double v[4][3];
        const double sx[4] = {-0.5, 0.5, 0.5, -0.5}, sy[4] = {-0.5, -0.5, 0.5, 0.5};
        for (int k = 0; k < 4; k++)
            for (int i = 0; i < 3; i++)
                v[k][i] = l->position[i] + sx[k] * l->width * l->axis_x[i] +
                          sy[k] * l->height * l->axis_y[i];
        g = sl_polygon_cosine_integral((const double(*)[3])v, 4, p, n);
        break;
    }
    case SL_LIGHT_DISK:
        if (v3_dot(d, l->axis_z) > 0)
            g = disk_integral(l, p, n, 0.1 * tol, &b); /* cheap: a tenth of the share */
        break;
    }
    if (!isfinite(g) || !isfinite(b))
        return false;
    /* Rounding of the formula itself, a few ulps of its terms. */
    b += 1e-12 * fmax(g, 1e-300);
    for (int c = 0; c < 3; c++) {
        E[c] = l->radiance[c] * g;
        bound[c] = l->radiance[c] * b;
    }
    return true;
}

bool sl_lights_irradiance(const sl_scene *scene, const double p[3], const double n[3], double tol,
                          double E[3], double bound[3])
{
    for (int c = 0; c < 3; c++)
        E[c] = bound[c] = 0;
    for (int i = 0; i < scene->light_count; i++) {
        const sl_light *l = &scene->lights[i];
        double El[3], Bl[3];
        if (!sl_light_has_closed_form(l))
            continue;
        if (!sl_light_irradiance(l, p, n, tol, El, Bl))
            return false;
        for (int c = 0; c < 3; c++)
            E[c] += El[c], bound[c] += Bl[c];
    }
    return true;
}

bool sl_closed_form_radiance_at(const sl_closed_form *cf, const sl_scene *scene, int shape,
                                const double p[3], const double n[3], const double wo[3],
                                double out[3], double bound[3], sl_irradiance_cost *cost)
{
    const sl_material *m = &scene->materials[scene->shapes[shape].material];
    if (m->type != SL_MAT_LAMBERT) {
        /* Glossy: the dome alone, integrated against the lobe (glossy.c). */
        if (!cf->ir || scene->light_count || !sl_glossy_applies(m))
            return false;
        sl_glossy_eval(cf->ir, m, n, wo, cf->tol, out, bound, cost);
        return true;
    }
    double E[3], B[3], Ed[3] = {0, 0, 0}, Bd[3] = {0, 0, 0};
    if (!sl_lights_irradiance(scene, p, n, cf->tol, E, B))
        return false;
    if (cf->ir)
        sl_irradiance_eval(cf->ir, n, cf->tol, Ed, Bd, cost);
    for (int c = 0; c < 3; c++) {
        E[c] += Ed[c], B[c] += Bd[c];
        out[c] = m->base_color[c] / SL_PI * E[c];
        bound[c] = m->base_color[c] / SL_PI * B[c];
    }
    return true;
}

/* Distance from q to a shape (0 inside a sphere or on a rect/disk). */
static double shape_distance(const sl_shape *s, const double q[3])
{
    double r[3] = {q[0] - s->center[0], q[1] - s->center[1], q[2] - s->center[2]};
    if (s->type == SL_SHAPE_SPHERE)
        return fmax(0.0, v3_length(r) - s->radius);
    double in[3], off;
    if (s->type == SL_SHAPE_RECT) {
        double uu = v3_dot(s->u, s->u), vv = v3_dot(s->v, s->v);
        double a = fmax(-1.0, fmin(1.0, v3_dot(r, s->u) / uu));
        double b = fmax(-1.0, fmin(1.0, v3_dot(r, s->v) / vv));
        for (int i = 0; i < 3; i++)
            in[i] = r[i] - a * s->u[i] - b * s->v[i];
        return v3_length(in);
    }
    off = v3_dot(r, s->normal);
    for (int i = 0; i < 3; i++)
        in[i] = r[i] - off * s->normal[i];
    double rad = v3_length(in), out = fmax(0.0, rad - s->radius);
    return sqrt(out * out + off * off);
}

const char *sl_closed_form_lights_unfit(const sl_scene *scene)
{
    int exact = 0, sampled = 0;
    sl_closed_form_count_lights(scene, &exact, &sampled);
    if (!scene->dome.present && exact == 0)
        return scene->light_count ? "no dome and no light with a closed form (textured rects are sampled)"
                                  : "no dome";
    for (int i = 0; i < scene->light_count; i++) {
        const sl_light *l = &scene->lights[i];
        if (l->type != SL_LIGHT_SPHERE)
            continue;
        for (int k = 0; k < scene->shape_count; k++)
            if (!(shape_distance(&scene->shapes[k], l->position) > l->radius * (1 + 1e-6)))
                return "a sphere light touches an object (no closed form inside it)";
    }
    return NULL;
}

void sl_closed_form_count_lights(const sl_scene *scene, int *exact, int *sampled)
{
    *exact = *sampled = 0;
    for (int i = 0; i < scene->light_count; i++) {
        if (sl_light_has_closed_form(&scene->lights[i]))
            ++*exact;
        else
            ++*sampled;
    }
}

/* Not wholly below the tangent plane of every point (margin: normals turn
 * between a sphere's corner points, so points between them reach a little
 * farther; a distant light's cone test holds between the corners as it is). */
static bool light_above(const sl_light *l, const sl_hit *pts, int npts, double margin)
{
    for (int i = 0; i < npts; i++) {
        const double *p = pts[i].p, *n = pts[i].n;
        if (l->type == SL_LIGHT_DISTANT) {
            if (v3_dot(n, l->axis_z) > -sin(0.5 * l->angle_deg * SL_PI / 180.0))
                return true;
            continue;
        }
        double R = l->type == SL_LIGHT_RECT ? 0.5 * sqrt(l->width * l->width + l->height * l->height)
                                            : l->radius;
        double d[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
        if (v3_dot(n, d) + R > -margin)
            return true;
    }
    return false;
}

bool sl_lights_may_shadow(const sl_scene *scene, const sl_hit *pts, int npts, double margin)
{
    if (scene->light_count == 0)
        return false;
    /* The corner normals' spread sets the margin for the lights' distances. */
    double cmin = 1, far = 0;
    for (int i = 1; i < npts; i++)
        cmin = fmin(cmin, v3_dot(pts[0].n, pts[i].n));
    for (int k = 0; k < scene->light_count; k++) {
        const sl_light *l = &scene->lights[k];
        if (l->type == SL_LIGHT_DISTANT)
            continue;
        double d[3] = {l->position[0] - pts[0].p[0], l->position[1] - pts[0].p[1],
                       l->position[2] - pts[0].p[2]};
        far = fmax(far, v3_length(d) + fmax(l->radius, 0.5 * (l->width + l->height)));
    }
    if (cmin < 1)
        margin = fmax(margin, cmin > 0.5 ? 2.0 * far * (1.0 / cmin - 1.0) : INFINITY);
    int area_above = 0, sources_above = scene->dome.present ? 1 : 0;
    for (int k = 0; k < scene->light_count; k++) {
        const sl_light *l = &scene->lights[k];
        if (!light_above(l, pts, npts, margin))
            continue;
        if (!sl_light_has_closed_form(l))
            return true; /* its light is sampled */
        area_above += l->type != SL_LIGHT_DISTANT;
        sources_above++;
    }
    /* An area light above the horizon may hide part of another source. */
    return area_above > 0 && sources_above >= 2;
}
