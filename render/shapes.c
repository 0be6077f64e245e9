/* SPDX-License-Identifier: BSD-3-Clause */
/* Ray intersection with the analytic shapes, in double precision. */
#include "scene_internal.h"
#include "vec3.h"

void frame_from_normal(frame *f, const double n[3])
{
    double sign = copysign(1.0, n[2]);
    double a = -1.0 / (sign + n[2]);
    double b = n[0] * n[1] * a;
    v3_set(f->t, 1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]);
    v3_set(f->b, b, sign + n[1] * n[1] * a, -n[1]);
    v3_copy(f->n, n);
}

/* Sphere with the numerically careful quadratic of Haines et al., "Precision
 * Improvements for Ray/Sphere Intersection", Ray Tracing Gems (2019). */
static bool hit_sphere(const sl_shape *s, const double o[3], const double d[3], double tmin,
                       double tmax, double *t)
{
    double f[3] = {o[0] - s->center[0], o[1] - s->center[1], o[2] - s->center[2]};
    double a = v3_dot(d, d);
    double b = -v3_dot(f, d);
    double l[3] = {f[0] + b / a * d[0], f[1] + b / a * d[1], f[2] + b / a * d[2]};
    double r2 = s->radius * s->radius;
    double disc = r2 - v3_dot(l, l);
    if (disc < 0)
        return false;
    double c = v3_dot(f, f) - r2;
    double q = b + copysign(sqrt(a * disc), b);
    double t0 = q != 0 ? c / q : 0, t1 = q / a;
    if (t0 > t1) {
        double tmp = t0;
        t0 = t1, t1 = tmp;
    }
    if (t0 > tmin && t0 < tmax) {
        *t = t0;
        return true;
    }
    if (t1 > tmin && t1 < tmax) {
        *t = t1;
        return true;
    }
    return false;
}

static bool hit_plane(const sl_shape *s, const double o[3], const double d[3], double tmin,
                      double tmax, double *t)
{
    double dn = v3_dot(d, s->normal);
    if (dn == 0)
        return false;
    double co[3] = {s->center[0] - o[0], s->center[1] - o[1], s->center[2] - o[2]};
    double tt = v3_dot(co, s->normal) / dn;
    if (!(tt > tmin && tt < tmax))
        return false;
    double q[3] = {o[0] + tt * d[0] - s->center[0], o[1] + tt * d[1] - s->center[1],
                   o[2] + tt * d[2] - s->center[2]};
    if (s->type == SL_SHAPE_DISK) {
        double in[3];
        double qn = v3_dot(q, s->normal);
        for (int i = 0; i < 3; i++)
            in[i] = q[i] - qn * s->normal[i];
        if (v3_dot(in, in) > s->radius * s->radius)
            return false;
    } else {
        if (fabs(v3_dot(q, s->u)) > v3_dot(s->u, s->u) || fabs(v3_dot(q, s->v)) > v3_dot(s->v, s->v))
            return false;
    }
    *t = tt;
    return true;
}

static bool hit_shape(const sl_shape *s, const double o[3], const double d[3], double tmin,
                      double tmax, double *t)
{
    return s->type == SL_SHAPE_SPHERE ? hit_sphere(s, o, d, tmin, tmax, t)
                                      : hit_plane(s, o, d, tmin, tmax, t);
}

/* Point, normal facing the ray and inside flag of a hit at t on shape i. */
static void fill_hit(const sl_scene *scene, int i, const double o[3], const double d[3], double t,
                     sl_hit *hit)
{
    const sl_shape *s = &scene->shapes[i];
    hit->t = t;
    hit->shape = i;
    for (int k = 0; k < 3; k++)
        hit->p[k] = o[k] + t * d[k];
    if (s->type == SL_SHAPE_SPHERE) {
        for (int k = 0; k < 3; k++)
            hit->n[k] = (hit->p[k] - s->center[k]) / s->radius;
        v3_normalize(hit->n);
        /* Project onto the surface so secondary rays start from it. */
        for (int k = 0; k < 3; k++)
            hit->p[k] = s->center[k] + s->radius * hit->n[k];
        /* Spheres are thin shells: seen from inside, the normal faces in. */
        hit->inside = v3_dot(d, hit->n) > 0;
        if (hit->inside)
            for (int k = 0; k < 3; k++)
                hit->n[k] = -hit->n[k];
    } else {
        hit->inside = false;
        double sign = v3_dot(d, s->normal) > 0 ? -1.0 : 1.0;
        for (int k = 0; k < 3; k++)
            hit->n[k] = sign * s->normal[k];
    }
}

bool sl_scene_intersect(const sl_scene *scene, const double o[3], const double d[3], double tmin,
                        double tmax, sl_hit *hit)
{
    int best = -1;
    double t;
    for (int i = 0; i < scene->shape_count; i++)
        if (hit_shape(&scene->shapes[i], o, d, tmin, tmax, &t)) {
            tmax = t;
            best = i;
        }
    if (best < 0)
        return false;
    fill_hit(scene, best, o, d, tmax, hit);
    return true;
}

bool sl_shape_intersect(const sl_scene *scene, int shape, const double o[3], const double d[3],
                        sl_hit *hit)
{
    double t;
    if (!hit_shape(&scene->shapes[shape], o, d, 0.0, INFINITY, &t))
        return false;
    fill_hit(scene, shape, o, d, t, hit);
    return true;
}

bool sl_scene_occluded(const sl_scene *scene, const double o[3], const double d[3], double tmax)
{
    double t;
    for (int i = 0; i < scene->shape_count; i++)
        if (hit_shape(&scene->shapes[i], o, d, 0.0, tmax, &t))
            return true;
    return false;
}

void sl_offset_origin(const double p[3], const double n[3], const double d[3], double out[3])
{
    double scale = 1e-9 * (1.0 + fabs(p[0]) + fabs(p[1]) + fabs(p[2]));
    double s = v3_dot(d, n) < 0 ? -scale : scale;
    for (int i = 0; i < 3; i++)
        out[i] = p[i] + s * n[i];
}
