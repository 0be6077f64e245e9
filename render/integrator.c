/* SPDX-License-Identifier: BSD-3-Clause */
/* Path integrator: next-event estimation from the dome and lights combined
 * with BSDF sampling by the power heuristic; delta lobes are followed exactly
 * by BSDF sampling only. `bounces` counts the surfaces a path may hit after
 * its first non-delta vertex. */
#include "area_closed_form.h"
#include "closed_form.h"
#include "glossy.h"
#include "integrator.h"
#include "sampler.h"
#include "scene_internal.h"
#include "vec3.h"

/* Delta (mirror) vertices allowed beyond the counted bounces. */
#define MAX_DELTA_VERTICES 16

void sl_integrator_init(sl_integrator *it, const sl_scene *scene, const sl_render_options *o)
{
    it->scene = scene;
    it->o = o;
    /* A lone rect, disk or sphere seen from outside cannot shadow itself for
     * directions above its tangent plane, so shadow rays are only needed with
     * two shapes or inside a sphere. */
    it->can_occlude = scene->shape_count > 1;
    it->light_sampling = o->strategy == SL_STRATEGY_MIS || o->strategy == SL_STRATEGY_LIGHT;
    it->dome_sampling = sl_dome_can_sample(&scene->dome) && it->light_sampling;
    it->cf = NULL;
    it->area_lights = 0;
    for (int i = 0; i < scene->light_count; i++)
        it->area_lights += scene->lights[i].type != SL_LIGHT_DISTANT;
}

/* Lights are objects: a rect, disk or sphere light between p and what a
 * shadow ray aims at (before tmax) blocks it, from either face, as it ends a
 * BSDF-sampled path. `self` is the light being sampled: its own emitter does
 * not shadow itself. */
static bool light_blocks(const sl_scene *scene, const double p[3], const double d[3], double tmax,
                         int self)
{
    for (int i = 0; i < scene->light_count; i++) {
        double t, Le[3];
        if (i != self && scene->lights[i].type != SL_LIGHT_DISTANT &&
            sl_light_intersect(&scene->lights[i], p, d, tmax, &t, Le))
            return true;
    }
    return false;
}

/* Direction for the next vertex by strategy; returns false when none. */
static bool sample_direction(const sl_integrator *it, const sl_material *m, const double wo[3],
                             const double u[3], sl_bsdf_sample_rec *bs)
{
    sl_strategy st = it->o->strategy;
    if (sl_bsdf_is_delta(m) || (st != SL_STRATEGY_UNIFORM && st != SL_STRATEGY_COSINE))
        return sl_bsdf_sample(m, wo, u, bs);
    double phi = 2.0 * SL_PI * u[1], cos_t, pdf;
    if (st == SL_STRATEGY_UNIFORM) {
        cos_t = 1.0 - u[0];
        pdf = 1.0 / (2.0 * SL_PI);
    } else {
        cos_t = sqrt(1.0 - u[0]);
        pdf = cos_t / SL_PI;
    }
    double sin_t = sqrt(fmax(0.0, 1.0 - cos_t * cos_t));
    v3_set(bs->wi, sin_t * cos(phi), sin_t * sin(phi), cos_t);
    if (!(pdf > 0) || cos_t <= 0)
        return false;
    bs->pdf = pdf;
    bs->delta = false;
    sl_bsdf_eval(m, wo, bs->wi, bs->f);
    return true;
}

/* Weight of emission found by a BSDF-sampled ray whose emitter light
 * sampling also reaches with pdf_light. */
static double emission_weight(const sl_integrator *it, bool prev_delta, double prev_pdf,
                              double pdf_light)
{
    if (prev_delta || !it->light_sampling)
        return 1.0;
    return it->o->strategy == SL_STRATEGY_LIGHT ? 0.0 : mis_power(prev_pdf, pdf_light);
}

/* Weight of light i's emission reached at distance t by a BSDF ray from o:
 * 1 when the vertex did not sample that light (culled, behind). */
static double light_weight(const sl_integrator *it, int i, uint64_t unsampled, bool prev_delta,
                           double prev_pdf, const double o[3], const double d[3], double t)
{
    if (i < 64 && (unsampled >> i & 1))
        return 1.0;
    return emission_weight(it, prev_delta, prev_pdf, sl_light_pdf(&it->scene->lights[i], o, d, t));
}

/* The dome's radiance a BSDF ray finds in direction d, and its MIS weight. */
static double dome_emission(const sl_integrator *it, const sl_dome *dome, const double d[3],
                            bool prev_delta, double prev_pdf, double Le[3])
{
    if (!sl_dome_can_sample(dome) || !it->dome_sampling) {
        sl_dome_radiance(dome, d, Le);
        return 1.0;
    }
    double pdf;
    sl_dome_radiance_pdf(dome, d, Le, &pdf);
    return emission_weight(it, prev_delta, prev_pdf, pdf);
}

/* Control variate, on a BSDF ray leaving the object's camera vertex: the
 * closed form counted every source unshadowed, so each closed-form source
 * the ray points at but does not reach first (the dome and distant lights
 * behind whatever it hits, area lights behind the first one) is taken off,
 * with the weight its emission would have had. */
static void cv_take_off_hidden(const sl_integrator *it, const double o[3], const double d[3],
                               double tfirst, int first_light, bool prev_delta, double prev_pdf,
                               uint64_t unsampled, const double beta[3], double L[3])
{
    const sl_scene *scene = it->scene;
    if (isinf(tfirst))
        return; /* nothing in the way */
    if (scene->dome.present) {
        double Ld[3], w = dome_emission(it, &scene->dome, d, prev_delta, prev_pdf, Ld);
        for (int k = 0; k < 3; k++)
            L[k] -= beta[k] * w * Ld[k];
    }
    for (int i = 0; i < scene->light_count; i++) {
        const sl_light *l = &scene->lights[i];
        double t, Le[3];
        if (i == first_light || !sl_light_has_closed_form(l) ||
            !sl_light_intersect(l, o, d, INFINITY, &t, Le) || !(t > tfirst))
            continue;
        double w = light_weight(it, i, unsampled, prev_delta, prev_pdf, o, d, t);
        for (int k = 0; k < 3; k++)
            L[k] -= beta[k] * w * Le[k];
    }
}

void sl_integrate_sample(const sl_integrator *it, sl_sampler *s, int px, int py, double rgba[4],
                         sl_counters *c)
{
    const sl_scene *scene = it->scene;
    const sl_camera *cam = &scene->camera;
    const sl_render_options *o = it->o;
    double jit[2] = {0.5, 0.5};
    if (!o->pixel_centers)
        sl_sampler_2d(s, jit);
    else
        s->dim++;
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0;
    double org[3], dir[3];
    if (!sl_camera_ray(cam, (px + jit[0]) / cam->width, (py + jit[1]) / cam->height, org, dir))
        return;
    c->camera_rays++;

    /* Control variate (closed_form.c): the pixel's closed form holds the
     * dome's unshadowed light on its object, so at that object's camera
     * vertex only shadowed directions are sampled, with a minus sign. */
    int cv_shape = -1, sun_shape = -1;
    bool cv_vertex = false, cv_prev = false, cv_hit = false;
    double org0[3], dir0[3];
    /* Sun exact (closed_form.c): at the object's camera vertex the dome is
     * the map without its sun, for the light samples and for the emission
     * its BSDF ray finds, so the sun is never counted twice. */
    const sl_dome *dome = &scene->dome, *prev_dome = dome;
    if (it->cf) {
        size_t pix = (size_t)py * (size_t)cam->width + (size_t)px;
        if (it->cf->mode[pix] == SL_PIXEL_CONTROL)
            cv_shape = it->cf->shape[pix];
        if (it->cf->mode[pix] == SL_PIXEL_SUN)
            sun_shape = it->cf->shape[pix];
        v3_copy(org0, org);
        v3_copy(dir0, dir);
    }
    double beta[3] = {1, 1, 1}, L[3] = {0, 0, 0};
    bool prev_delta = true; /* the camera: what it sees directly gets full weight */
    double prev_pdf = 0;
    uint64_t prev_unsampled = 0;
    int nondelta = 0;
    for (int vertex = 0; vertex <= o->bounces + MAX_DELTA_VERTICES; vertex++) {
        sl_hit hit;
        bool hit_shape = sl_scene_intersect(scene, org, dir, 0.0, INFINITY, &hit);
        double tmax = hit_shape ? hit.t : INFINITY;
        /* The nearest area light in front of the shapes absorbs the ray. */
        int nearest = -1;
        double Ln[3] = {0, 0, 0};
        for (int i = 0; i < scene->light_count; i++) {
            double t, Le[3];
            if (scene->lights[i].type != SL_LIGHT_DISTANT &&
                sl_light_intersect(&scene->lights[i], org, dir, tmax, &t, Le)) {
                nearest = i;
                tmax = t;
                v3_copy(Ln, Le);
            }
        }
        if (cv_prev)
            cv_take_off_hidden(it, org, dir, nearest >= 0 ? tmax : hit_shape ? hit.t : INFINITY,
                               nearest, prev_delta, prev_pdf, prev_unsampled, beta, L);
        if (nearest >= 0 && cv_prev && sl_light_has_closed_form(&scene->lights[nearest]))
            break; /* unshadowed: in the closed form */
        if (nearest >= 0) {
            double w = light_weight(it, nearest, prev_unsampled, prev_delta, prev_pdf, org, dir, tmax);
            for (int k = 0; k < 3; k++)
                L[k] += beta[k] * w * Ln[k];
            break;
        }
        if (!hit_shape && !cv_prev && (vertex > 0 || scene->background_env))
            for (int i = 0; i < scene->light_count; i++) {
                const sl_light *l = &scene->lights[i];
                double t, Le[3];
                if (l->type == SL_LIGHT_DISTANT && sl_light_intersect(l, org, dir, INFINITY, &t, Le)) {
                    double w = light_weight(it, i, prev_unsampled, prev_delta, prev_pdf, org, dir, t);
                    for (int k = 0; k < 3; k++)
                        L[k] += beta[k] * w * Le[k];
                }
            }
        if (!hit_shape) {
            double Le[3];
            if (vertex == 0) {
                if (scene->background_env) {
                    sl_dome_background(&scene->dome, dir, Le);
                    v3_copy(L, Le);
                }
                break;
            }
            if (cv_prev)
                break; /* unshadowed: in the closed form */
            double w = dome_emission(it, prev_dome, dir, prev_delta, prev_pdf, Le);
            for (int k = 0; k < 3; k++)
                L[k] += beta[k] * w * Le[k];
            break;
        }
        if (vertex == 0) {
            rgba[3] = 1;
            cv_vertex = cv_hit = hit.shape == cv_shape;
            if (hit.shape == sun_shape)
                dome = &it->cf->rest_dome;
        }
        const sl_material *m = &scene->materials[scene->shapes[hit.shape].material];
        bool delta = sl_bsdf_is_delta(m);
        /* Mirror chains are free up to the first non-delta vertex; after it
         * every surface counts, so direct lighting has no caustic paths
         * (diffuse -> mirror -> sun), which only MIS-less sampling could find. */
        if (nondelta > o->bounces)
            break;
        frame fr;
        frame_from_normal(&fr, hit.n);
        double wo_world[3] = {-dir[0], -dir[1], -dir[2]}, wo[3];
        frame_to_local(&fr, wo_world, wo);
        if (wo[2] <= 0)
            break; /* grazing: rounding put the viewer below the surface */

        double u_light[2], u_bsdf[3], u_tmp[2];
        sl_sampler_2d(s, u_light);
        sl_sampler_2d(s, u_tmp);
        u_bsdf[0] = u_tmp[0], u_bsdf[1] = u_tmp[1];
        u_bsdf[2] = sl_sampler_1d(s);
        double u_rr = sl_sampler_1d(s);

        if (!delta && it->dome_sampling && sl_dome_can_sample(dome)) {
            double wi[3], Le[3], pdf_l, pdf_mis;
            if (sl_dome_sample(dome, u_light, wi, Le, &pdf_l, &pdf_mis)) {
                double wil[3], f[3];
                frame_to_local(&fr, wi, wil);
                if (wil[2] > 0 && (Le[0] > 0 || Le[1] > 0 || Le[2] > 0))
                    sl_bsdf_eval(m, wo, wil, f);
                else
                    f[0] = f[1] = f[2] = 0;
                if (f[0] <= 0 && f[1] <= 0 && f[2] <= 0) {
                    c->zero_weight++;
                } else {
                    bool blocked = false;
                    if (it->can_occlude || hit.inside || it->area_lights > 0) {
                        double so[3];
                        sl_offset_origin(hit.p, hit.n, wi, so);
                        c->shadow_rays++;
                        blocked = light_blocks(scene, so, wi, INFINITY, -1) ||
                                  sl_scene_occluded(scene, so, wi, INFINITY);
                    } else {
                        c->shadow_skipped++;
                    }
                    if (blocked == cv_vertex) {
                        double w = o->strategy == SL_STRATEGY_MIS
                                       ? mis_power(pdf_mis, sl_bsdf_pdf(m, wo, wil))
                                       : 1.0;
                        double sign = cv_vertex ? -1.0 : 1.0;
                        for (int k = 0; k < 3; k++)
                            L[k] += sign * beta[k] * f[k] * wil[2] * Le[k] * w / pdf_l;
                    }
                }
            }
        }

        /* Lights not sampled here: emission found from this vertex gets weight 1. */
        uint64_t unsampled = 0;
        if (!delta && it->light_sampling && scene->light_count > 0) {
            /* Cull lights far dimmer than the brightest, at Lambert vertices
             * only (glossy lobes can favour a dim light) and for the first
             * 64 lights (a bit mask remembers them for the next hit). */
            bool cull = o->light_cull > 0 && m->type == SL_MAT_LAMBERT && scene->light_count > 1;
            double bound[64], top = 0;
            for (int i = 0; i < scene->light_count && i < 64; i++) {
                bool behind;
                bound[i] = sl_light_irradiance_bound(&scene->lights[i], hit.p, hit.n, &behind);
                if (behind) {
                    unsampled |= 1ull << i;
                    c->behind++;
                }
                top = fmax(top, bound[i]);
            }
            if (cull && isfinite(top))
                for (int i = 0; i < scene->light_count && i < 64; i++)
                    if (!(unsampled >> i & 1) && bound[i] < o->light_cull * top) {
                        unsampled |= 1ull << i;
                        c->culled++;
                    }
        }
        if (!delta && it->light_sampling)
            for (int i = 0; i < scene->light_count; i++) {
                const sl_light *l = &scene->lights[i];
                double u_l[2], wi[3], Le[3], pdf_l, dist, wil[3], f[3];
                bool dl;
                sl_sampler_2d(s, u_l);
                if (i < 64 && (unsampled >> i & 1))
                    continue;
                if (!sl_light_sample(l, hit.p, u_l, wi, &dist, Le, &pdf_l, &dl))
                    continue;
                frame_to_local(&fr, wi, wil);
                if (wil[2] > 0 && (Le[0] > 0 || Le[1] > 0 || Le[2] > 0))
                    sl_bsdf_eval(m, wo, wil, f);
                else
                    f[0] = f[1] = f[2] = 0;
                if (f[0] <= 0 && f[1] <= 0 && f[2] <= 0) {
                    c->zero_weight++;
                    continue;
                }
                int others = it->area_lights - (l->type != SL_LIGHT_DISTANT);
                bool blocked = false;
                if (it->can_occlude || hit.inside || others > 0) {
                    double so[3], tmax = isinf(dist) ? INFINITY : dist * (1 - 1e-9);
                    sl_offset_origin(hit.p, hit.n, wi, so);
                    c->shadow_rays++;
                    blocked = (others > 0 && light_blocks(scene, so, wi, tmax, i)) ||
                              sl_scene_occluded(scene, so, wi, tmax);
                } else {
                    c->shadow_skipped++;
                }
                /* At a control variate's vertex a closed-form light counts
                 * only where it is blocked, with a minus sign. */
                bool cf_light = cv_vertex && sl_light_has_closed_form(l);
                if (blocked != cf_light)
                    continue;
                double w = (dl || o->strategy == SL_STRATEGY_LIGHT) ? 1.0
                                                                    : mis_power(pdf_l, sl_bsdf_pdf(m, wo, wil));
                double sign = cf_light ? -1.0 : 1.0;
                for (int k = 0; k < 3; k++)
                    L[k] += sign * beta[k] * f[k] * wil[2] * Le[k] * w / pdf_l;
            }

        sl_bsdf_sample_rec bs;
        if (!sample_direction(it, m, wo, u_bsdf, &bs) || !(bs.pdf > 0))
            break;
        double cos_i = fabs(bs.wi[2]);
        bool any = false;
        for (int k = 0; k < 3; k++) {
            beta[k] *= bs.f[k] * cos_i / bs.pdf;
            any = any || beta[k] > 0;
        }
        if (!any)
            break;
        if (!delta) {
            nondelta++;
            /* Russian roulette once past two non-delta vertices. */
            if (nondelta > 2) {
                double q = fmin(1.0, fmax(beta[0], fmax(beta[1], beta[2])));
                if (u_rr >= q)
                    break;
                for (int k = 0; k < 3; k++)
                    beta[k] /= q;
            }
        }
        cv_prev = cv_vertex;
        cv_vertex = false;
        prev_dome = dome;
        dome = &scene->dome;
        prev_delta = bs.delta;
        prev_pdf = bs.pdf;
        prev_unsampled = unsampled;
        double wi_world[3];
        frame_to_world(&fr, bs.wi, wi_world);
        sl_offset_origin(hit.p, hit.n, wi_world, org);
        v3_copy(dir, wi_world);
        c->bsdf_rays++;
    }
    if (cv_shape >= 0 && !cv_hit) {
        /* Something else covers this sample: its full value, minus the
         * closed form's integrand here, keeps the pixel's mean right. */
        sl_hit ha;
        double Lcf[3], bound[3];
        double wo0[3] = {-dir0[0], -dir0[1], -dir0[2]};
        if (sl_shape_intersect(scene, cv_shape, org0, dir0, &ha) &&
            sl_closed_form_radiance_at(it->cf, scene, cv_shape, ha.p, ha.n, wo0, Lcf, bound, NULL))
            for (int k = 0; k < 3; k++)
                L[k] -= Lcf[k];
    }
    if (!v3_finite(L)) {
        c->nonfinite++;
        return;
    }
    for (int k = 0; k < 3; k++)
        rgba[k] = L[k];
}
