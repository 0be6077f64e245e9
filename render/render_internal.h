/* SPDX-License-Identifier: BSD-3-Clause */
/* Private pieces of the renderer shared between its files. */
#ifndef SETLIGHT_RENDER_INTERNAL_H
#define SETLIGHT_RENDER_INTERNAL_H

#include <math.h>

#include "setlight/render.h"

#define SL_PI 3.14159265358979323846

static inline double v3_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void v3_cross(const double a[3], const double b[3], double out[3])
{
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2],
           z = a[0] * b[1] - a[1] * b[0];
    out[0] = x, out[1] = y, out[2] = z;
}
static inline double v3_length(const double a[3]) { return sqrt(v3_dot(a, a)); }
static inline bool v3_normalize(double a[3])
{
    double l = v3_length(a);
    if (!(l > 0) || !isfinite(l))
        return false;
    a[0] /= l, a[1] /= l, a[2] /= l;
    return true;
}
static inline void v3_set(double out[3], double x, double y, double z)
{
    out[0] = x, out[1] = y, out[2] = z;
}
static inline void v3_copy(double out[3], const double a[3])
{
    out[0] = a[0], out[1] = a[1], out[2] = a[2];
}
static inline bool v3_finite(const double a[3])
{
    return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
}
static inline void m3_mul(const double m[3][3], const double a[3], double out[3])
{
    double x = m[0][0] * a[0] + m[0][1] * a[1] + m[0][2] * a[2];
    double y = m[1][0] * a[0] + m[1][1] * a[1] + m[1][2] * a[2];
    double z = m[2][0] * a[0] + m[2][1] * a[1] + m[2][2] * a[2];
    out[0] = x, out[1] = y, out[2] = z;
}
static inline void m3_mul_transpose(const double m[3][3], const double a[3], double out[3])
{
    double x = m[0][0] * a[0] + m[1][0] * a[1] + m[2][0] * a[2];
    double y = m[0][1] * a[0] + m[1][1] * a[1] + m[2][1] * a[2];
    double z = m[0][2] * a[0] + m[1][2] * a[1] + m[2][2] * a[2];
    out[0] = x, out[1] = y, out[2] = z;
}
static inline double luminance709(const double c[3])
{
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}
/* Power heuristic with beta = 2. */
static inline double mis_power(double a, double b)
{
    double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0 ? a2 / (a2 + b2) : 0.0;
}

/* Orthonormal frame with n as +Z (Duff et al. 2017). */
typedef struct frame {
    double t[3], b[3], n[3];
} frame;
void frame_from_normal(frame *f, const double n[3]);
static inline void frame_to_local(const frame *f, const double v[3], double out[3])
{
    double x = v3_dot(v, f->t), y = v3_dot(v, f->b), z = v3_dot(v, f->n);
    out[0] = x, out[1] = y, out[2] = z;
}
static inline void frame_to_world(const frame *f, const double v[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = f->t[i] * v[0] + f->b[i] * v[1] + f->n[i] * v[2];
}

/* ---- random numbers and sample sequences (sampler.c) ---- */
uint64_t sl_hash64(uint64_t x);
static inline uint64_t sl_hash_combine(uint64_t a, uint64_t b)
{
    return sl_hash64(a ^ (b + 0x9e3779b97f4a7c15ull + (a << 6) + (a >> 2)));
}

/* One stream of sample values for one pixel sample. Low-discrepancy mode:
 * each pair of dimensions is a 2D Sobol sequence with hash-based Owen
 * scrambling and its own index shuffle (Burley 2020), so sample `index` of a
 * pixel is well stratified against the other indices of that pixel. */
typedef struct sl_sampler {
    uint64_t seed;
    uint32_t index;
    uint32_t dim;
    bool ld;
    uint64_t state; /* random mode: PCG state */
} sl_sampler;

void sl_sampler_start(sl_sampler *s, uint64_t pixel_seed, uint32_t index, bool low_discrepancy);
void sl_sampler_2d(sl_sampler *s, double out[2]);
double sl_sampler_1d(sl_sampler *s);

/* ---- shapes (shapes.c) ---- */
typedef struct sl_hit {
    double t;
    double p[3];
    double n[3]; /* geometric normal, facing the incoming ray */
    int shape;
    bool inside; /* a sphere seen from inside: its concave side can occlude */
} sl_hit;

/* Nearest hit with t in (tmin, tmax). */
bool sl_scene_intersect(const sl_scene *scene, const double o[3], const double d[3], double tmin,
                        double tmax, sl_hit *hit);
bool sl_scene_occluded(const sl_scene *scene, const double o[3], const double d[3], double tmax);
/* Nearest hit of the ray on one shape alone (others ignored). */
bool sl_shape_intersect(const sl_scene *scene, int shape, const double o[3], const double d[3],
                        sl_hit *hit);
/* Ray origin nudged off a surface at p (normal n) toward direction d. */
void sl_offset_origin(const double p[3], const double n[3], const double d[3], double out[3]);

/* ---- camera (camera.c) ---- */
/* Ray through image position (sx, sy) in [0,1]^2 (y down); false outside a fisheye circle. */
bool sl_camera_ray(const sl_camera *cam, double sx, double sy, double o[3], double d[3]);

/* ---- dome (dome.c) ---- */
/* Radiance (intensity applied) arriving from world direction d, piecewise constant per texel. */
void sl_dome_radiance(const sl_dome *dome, const double d[3], double L[3]);
/* Bilinear radiance for what the camera sees directly. */
void sl_dome_background(const sl_dome *dome, const double d[3], double L[3]);
/* True when the dome has energy to importance-sample. */
bool sl_dome_can_sample(const sl_dome *dome);
/* Samples a world direction; pdf is per solid angle (the estimator's);
 * mis_pdf (may be NULL) is the value sl_dome_radiance_pdf gives for the same
 * direction, for MIS weights. False (pdf 0) at a pole. */
bool sl_dome_sample(const sl_dome *dome, const double u[2], double wi[3], double L[3], double *pdf,
                    double *mis_pdf);
/* Solid-angle pdf in double precision (tests). */
double sl_dome_pdf(const sl_dome *dome, const double wi[3]);
/* Radiance and the MIS pdf at once (one lookup); only when sl_dome_can_sample. */
void sl_dome_radiance_pdf(const sl_dome *dome, const double d[3], double L[3], double *pdf);
void sl_dome_free(sl_dome *dome);

/* ---- lights (lights.c) ---- */
/* Samples a direction toward the light from p; dist is the distance to the
 * sampled point (INFINITY for distant lights). delta: a direction with no
 * solid angle (pdf is then 1 and L is irradiance). */
bool sl_light_sample(const sl_light *l, const double p[3], const double u[2], double wi[3],
                     double *dist, double L[3], double *pdf, bool *delta);
/* Solid-angle pdf of sl_light_sample for direction wi hitting the light at dist. */
double sl_light_pdf(const sl_light *l, const double p[3], const double wi[3], double dist);
/* A ray (o, d) reaching the light before tmax: distance and emitted radiance. */
bool sl_light_intersect(const sl_light *l, const double o[3], const double d[3], double tmax,
                        double *t, double L[3]);

/* Upper bound of the irradiance the light can deliver at p with normal n
 * (max channel), INFINITY when none is known (p inside its bounding sphere,
 * a texture). *behind: p sees only the back of a one-sided light or the light
 * is wholly below the horizon: exactly 0. */
double sl_light_irradiance_bound(const sl_light *l, const double p[3], const double n[3],
                                 bool *behind);

/* ---- integrator (integrator.c) ---- */
typedef struct sl_closed_form sl_closed_form; /* closed_form.c, below */
typedef struct sl_counters {
    int64_t camera_rays, shadow_rays, bsdf_rays, shadow_skipped, zero_weight, nonfinite;
    int64_t culled, behind;
} sl_counters;

typedef struct sl_integrator {
    const sl_scene *scene;
    const sl_render_options *o;
    bool can_occlude; /* more than one shape: a shadow ray could hit something
                         (a lone sphere can also shadow its own inside) */
    bool light_sampling; /* strategy samples lights and the dome */
    bool dome_sampling;
    int area_lights; /* rect, disk and sphere lights: they block the shadow rays of
                        other lights and of the dome */
    const sl_closed_form *cf; /* NULL: every pixel sampled */
} sl_integrator;

void sl_integrator_init(sl_integrator *it, const sl_scene *scene, const sl_render_options *o);
/* One camera sample: rgb radiance and alpha (coverage). */
void sl_integrate_sample(const sl_integrator *it, sl_sampler *s, int px, int py, double rgba[4],
                         sl_counters *c);

/* ---- closed-form irradiance from the dome (irradiance.c) ---- */
typedef struct sl_irradiance sl_irradiance;
typedef struct sl_irradiance_cost {
    int64_t evaluations, cells; /* normals evaluated, lat-long cells visited */
    int finest_level;           /* finest cell split to: mip level, < 0 inside a texel */
} sl_irradiance_cost;
/* Mip levels of the dome's exact cell sums (intensity and rotation kept). */
sl_result sl_irradiance_build(const sl_dome *dome, sl_irradiance **out, sl_error *err);
void sl_irradiance_free(sl_irradiance *ir);
int sl_irradiance_top_level(const sl_irradiance *ir);
/* E[c] = integral of L max(0, n.w) dw for the world normal n, and bound[c]
 * >= |E - exact| per channel, refined until bound <= tol x E (or no room). */
void sl_irradiance_eval(const sl_irradiance *ir, const double n[3], double tol, double E[3],
                        double bound[3], sl_irradiance_cost *cost);

/* ---- closed form per pixel (closed_form.c) ---- */
enum { SL_PIXEL_SAMPLED = 0, SL_PIXEL_EXACT, SL_PIXEL_CONTROL };
struct sl_closed_form {
    sl_irradiance *ir;
    double tol;
    uint8_t *mode;     /* per pixel: SL_PIXEL_* */
    int32_t *shape;    /* the object an exact or control pixel shows */
    float (*value)[3]; /* its closed-form value, pixel filter applied */
    float (*bound)[3]; /* proven quadrature bound + pixel-filter estimate */
};

/* Decides per pixel what is exact, what is a control variate and what is
 * sampled, and computes the closed-form values. Not applicable is not an
 * error: every pixel is then sampled and stats->reason says why. */
sl_result sl_closed_form_plan(sl_closed_form *cf, const sl_scene *scene, const sl_render_options *o,
                              sl_closed_form_stats *stats, sl_error *err);
void sl_closed_form_free(sl_closed_form *cf);
/* Lambert radiance rho/pi E(n) of a shape's material at world normal n. */
void sl_closed_form_radiance(const sl_closed_form *cf, const sl_scene *scene, int shape,
                             const double n[3], double out[3], double bound[3],
                             sl_irradiance_cost *cost);

#endif
