/* SPDX-License-Identifier: BSD-3-Clause */
/* Progressive rendering. Samples go alternately into two half-buffers with
 * independent scrambles; after each pass the difference of the halves
 * estimates the error of their mean. Each pixel's samples depend only on the
 * seed, the pixel and the sample index, so any thread count gives the same
 * bytes. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "closed_form.h"
#include "integrator.h"
#include "sampler.h"

void sl_render_options_init(sl_render_options *o)
{
    memset(o, 0, sizeof *o);
    o->spp = 64;
    o->strategy = SL_STRATEGY_MIS;
    o->low_discrepancy = true;
    o->seed = 1;
    o->light_cull = 1e-3;
    o->closed_form = true;
}

static const char *const strategy_names[SL_STRATEGY_COUNT] = {"mis", "uniform", "cosine", "bsdf",
                                                               "light"};

int sl_strategy_from_name(const char *name)
{
    for (int i = 0; i < SL_STRATEGY_COUNT; i++)
        if (name && !strcmp(name, strategy_names[i]))
            return i;
    return -1;
}

const char *sl_strategy_name(sl_strategy s)
{
    return s >= 0 && s < SL_STRATEGY_COUNT ? strategy_names[s] : "unknown";
}

void sl_render_stats_free(sl_render_stats *stats)
{
    if (!stats)
        return;
    free(stats->passes);
    memset(stats, 0, sizeof *stats);
}

sl_result sl_relative_rmse(const sl_image *img, const sl_image *ref, double *out, sl_error *err)
{
    *out = 0;
    if (img->width != ref->width || img->height != ref->height || img->channels < 3 ||
        ref->channels < 3)
        return sl_error_set(err, SL_ERR_INPUT,
                            "reference is %dx%d with %d channels, the render %dx%d with %d",
                            ref->width, ref->height, ref->channels, img->width, img->height,
                            img->channels);
    double num = 0, den = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *a = sl_image_pixel(img, x, y), *b = sl_image_pixel(ref, x, y);
            for (int c = 0; c < 3; c++) {
                if (!isfinite(b[c]))
                    continue;
                double d = (double)a[c] - b[c];
                num += d * d;
                den += (double)b[c] * b[c];
            }
        }
    *out = den > 0 ? sqrt(num / den) : (num > 0 ? INFINITY : 0);
    return SL_OK;
}

typedef struct job {
    sl_integrator it;
    const sl_scene *scene;
    double *sum[2];  /* RGBA sums per half-buffer */
    uint32_t end; /* this pass takes every active pixel to this many samples per half */
    uint32_t *n_px;  /* samples per half each pixel has (adaptive: stopped pixels keep theirs) */
    uint8_t *done;   /* adaptive sampling: the pixel has stopped */
    sl_counters *rows; /* per-row counters: integer sums, order-free */
} job;

static void render_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    job *j = ctx;
    const sl_camera *cam = &j->scene->camera;
    for (int64_t y = begin; y < end; y++) {
        sl_counters *c = &j->rows[y];
        for (int x = 0; x < cam->width; x++) {
            uint64_t pixel = (uint64_t)y * (uint64_t)cam->width + (uint64_t)x;
            if (j->done[pixel])
                continue;
            if (j->it.cf && j->it.cf->mode[pixel] == SL_PIXEL_EXACT)
                continue; /* nothing to sample */
            /* A pixel stopped and taken up again catches up from its own count. */
            uint32_t first = j->n_px[pixel];
            j->n_px[pixel] = j->end;
            for (int h = 0; h < 2; h++) {
                uint64_t seed = sl_hash_combine(sl_hash_combine(j->it.o->seed, pixel), (uint64_t)h);
                double acc[4] = {0, 0, 0, 0};
                for (uint32_t i = first; i < j->end; i++) {
                    sl_sampler s;
                    double rgba[4];
                    sl_sampler_start(&s, seed, i, j->it.o->low_discrepancy);
                    sl_integrate_sample(&j->it, &s, x, (int)y, rgba, c);
                    for (int k = 0; k < 4; k++)
                        acc[k] += rgba[k];
                }
                double *dst = j->sum[h] + pixel * 4;
                for (int k = 0; k < 4; k++)
                    dst[k] += acc[k];
            }
        }
    }
}

/* The image is the mean of the halves, plus the closed-form value of
 * exact, control-variate and sun-exact pixels, and the estimated relative RMSE, which
 * counts each exact or control-variate pixel's proven bound as error too;
 * var_px gets each pixel's squared noise estimate sum_c ((A - B)/2)^2 (the
 * bound left out: sampling cannot lower it), and *mean_m2 the mean over
 * pixels of sum_c M^2. */
static void resolve(const double *sa, const double *sb, const uint32_t *n_px,
                    const sl_closed_form *cf, int w, int h, sl_image *out, double *var_px,
                    double *est, double *mean_m2)
{
    double num = 0, den = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t px = (size_t)y * (size_t)w + (size_t)x, i = px * 4;
            int mode = cf && cf->mode ? cf->mode[px] : SL_PIXEL_SAMPLED;
            double inv = n_px[px] > 0 ? 1.0 / (double)n_px[px] : 0.0, var = 0, bound = 0;
            float *p = sl_image_pixel(out, x, y);
            for (int k = 0; k < 4; k++) {
                double a = sa[i + k] * inv, b = sb[i + k] * inv, m = 0.5 * (a + b);
                if (mode == SL_PIXEL_EXACT)
                    a = b = m = k < 3 ? cf->value[px][k] : 1.0;
                else if ((mode == SL_PIXEL_CONTROL || mode == SL_PIXEL_SUN) && k < 3)
                    m += cf->value[px][k];
                /* A control variate's noise may dip below zero: never written. */
                p[k] = (float)fmax(0.0, m);
                if (k < 3) {
                    var += 0.25 * (a - b) * (a - b);
                    if (mode != SL_PIXEL_SAMPLED)
                        bound += (double)cf->bound[px][k] * cf->bound[px][k];
                    den += m * m;
                }
            }
            var_px[px] = var;
            num += var + bound;
        }
    *est = den > 0 ? sqrt(num / den) : 0;
    *mean_m2 = den / ((double)w * h);
}

/* Adaptive sampling with --target-error E: a pixel stops once the error
 * estimate pooled over its 3 x 3 neighbourhood (one pixel's two halves are
 * too few to trust) is within its share of the target, E^2 x the mean of
 * M^2: when every pixel is there, the whole image is. Pixels with no
 * variance at all (background, a mirror at its centre) stop at once. Stopping
 * looks only at A - B, which is uncorrelated with the mean (A + B)/2, and
 * stopped pixels stay in the error estimate. Returns the pixels still active. */
#define ADAPTIVE_MIN_HALF 8
static int64_t stop_converged(const double *var_px, double limit, int w, int h, uint8_t *done)
{
    int64_t active = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t px = (size_t)y * (size_t)w + (size_t)x;
            if (done[px])
                continue;
            double sum = 0;
            int n = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                        continue;
                    sum += var_px[(size_t)yy * (size_t)w + (size_t)xx];
                    n++;
                }
            if (sum <= limit * n)
                done[px] = 2; /* stopped at this pass: marked 1 below */
            else
                active++;
        }
    for (size_t px = 0; px < (size_t)w * (size_t)h; px++)
        done[px] = done[px] ? 1 : 0;
    return active;
}

static sl_result push_pass(sl_render_stats *st, const sl_render_pass *p, sl_error *err)
{
    sl_render_pass *np = realloc(st->passes, (size_t)(st->pass_count + 1) * sizeof *np);
    if (!np)
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for pass statistics");
    st->passes = np;
    st->passes[st->pass_count++] = *p;
    return SL_OK;
}

/* The true error against the reference, the pass kept, the caller told. */
static sl_result record_pass(sl_render_stats *st, sl_render_pass *p, const sl_image *out,
                             const sl_render_options *o, sl_error *err)
{
    sl_result r;
    if (o->reference && (r = sl_relative_rmse(out, o->reference, &p->ref_rel_rmse, err)))
        return r;
    if ((r = push_pass(st, p, err)))
        return r;
    if (o->on_pass)
        o->on_pass(o->on_pass_ctx, p);
    return SL_OK;
}

sl_result sl_render(const sl_scene *scene, const sl_render_options *o, sl_image *out,
                    sl_render_stats *stats, sl_error *err)
{
    /* --time budgets the whole call: the closed form's set-up included. */
    double t0 = sl_seconds(), c0 = sl_cpu_seconds();
    memset(out, 0, sizeof *out);
    sl_render_stats local;
    if (!stats)
        stats = &local;
    memset(stats, 0, sizeof *stats);
    const sl_camera *cam = &scene->camera;
    if (cam->width < 1 || cam->height < 1)
        return sl_error_set(err, SL_ERR_USAGE, "render: image size %dx%d must be at least 1x1",
                            cam->width, cam->height);
    if (o->spp < 0 || !(o->time_limit >= 0) || !(o->target_error >= 0) || o->bounces < 0 ||
        !(o->light_cull >= 0 && o->light_cull < 1) ||
        o->strategy < 0 || o->strategy >= SL_STRATEGY_COUNT)
        return sl_error_set(err, SL_ERR_USAGE, "render: negative or invalid stop condition");
    if (o->spp == 0 && o->time_limit == 0 && o->target_error == 0)
        return sl_error_set(err, SL_ERR_USAGE, "render: no stop condition (spp, time or target error)");
    for (int i = 0; i < scene->shape_count; i++)
        if (scene->shapes[i].material < 0 || scene->shapes[i].material >= scene->material_count)
            return sl_error_set(err, SL_ERR_INPUT, "render: shape %d has no material", i);
    if (o->reference && (o->reference->width != cam->width || o->reference->height != cam->height ||
                         o->reference->channels < 3))
        return sl_error_set(err, SL_ERR_INPUT,
                            "render: reference is %dx%d, the render %dx%d (needs RGB)",
                            o->reference->width, o->reference->height, cam->width, cam->height);

    sl_result r = sl_image_alloc(out, cam->width, cam->height, 4, err);
    if (r)
        return r;
    size_t npix = (size_t)cam->width * (size_t)cam->height;
    job j = {.scene = scene};
    sl_integrator_init(&j.it, scene, o);
    sl_closed_form cf;
    if ((r = sl_closed_form_plan(&cf, scene, o, &stats->closed_form, err))) {
        sl_image_free(out);
        if (stats == &local)
            sl_render_stats_free(stats);
        return r;
    }
    if (stats->closed_form.used)
        j.it.cf = &cf;
    bool to_sample = stats->closed_form.sampled_pixels + stats->closed_form.control_variate_pixels > 0;
    j.sum[0] = calloc(npix * 4, sizeof(double));
    j.sum[1] = calloc(npix * 4, sizeof(double));
    j.rows = calloc((size_t)cam->height, sizeof *j.rows);
    j.n_px = calloc(npix, sizeof *j.n_px);
    j.done = calloc(npix, 1);
    double *var_px = malloc(npix * sizeof *var_px);
    if (!j.sum[0] || !j.sum[1] || !j.rows || !j.n_px || !j.done || !var_px) {
        r = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for %dx%d buffers", cam->width,
                         cam->height);
        goto done;
    }
    /* Halves grow 1, 1, 2, 4, ... samples per pass so totals stay powers of two. */
    int64_t half_target = o->spp > 0 ? (o->spp + 1) / 2 : INT64_MAX;
    if (half_target > (int64_t)UINT32_MAX)
        half_target = UINT32_MAX;
    int64_t n_half = 0;
    double t_sampling = sl_seconds();
    strcpy(stats->stop_reason, "spp");
    if (!to_sample) {
        /* Every pixel is exact: one pass with no samples reports the bound. */
        sl_render_pass pass = {.spp = 0, .ref_rel_rmse = -1};
        double mean_m2;
        resolve(j.sum[0], j.sum[1], j.n_px, &cf, cam->width, cam->height, out, var_px,
                &pass.est_rel_rmse, &mean_m2);
        pass.seconds = sl_seconds() - t0;
        if ((r = record_pass(stats, &pass, out, o, err)))
            goto done;
        strcpy(stats->stop_reason, "exact");
    }
    while (to_sample) {
        int64_t add = n_half > 0 ? n_half : 1;
        if (add > half_target - n_half)
            add = half_target - n_half;
        double elapsed = sl_seconds() - t0;
        if (o->time_limit > 0 && n_half > 0) {
            double per = (sl_seconds() - t_sampling) / (double)n_half;
            int64_t fit = per > 0 ? (int64_t)((o->time_limit - elapsed) / per) : add;
            if (fit < add)
                add = fit;
        }
        if (add <= 0) {
            strcpy(stats->stop_reason, "time");
            break;
        }
        j.end = (uint32_t)(n_half + add);
        sl_parallel_for(cam->height, 1, render_rows, &j);
        n_half += add;
        sl_render_pass pass = {.spp = 2 * n_half, .ref_rel_rmse = -1};
        double mean_m2;
        resolve(j.sum[0], j.sum[1], j.n_px, j.it.cf, cam->width, cam->height, out, var_px,
                &pass.est_rel_rmse, &mean_m2);
        pass.seconds = sl_seconds() - t0;
        if ((r = record_pass(stats, &pass, out, o, err)))
            goto done;
        if (n_half >= half_target) {
            strcpy(stats->stop_reason, "spp");
            break;
        }
        if (o->target_error > 0 && pass.est_rel_rmse <= o->target_error) {
            strcpy(stats->stop_reason, "target-error");
            break;
        }
        if (o->target_error > 0 && n_half >= ADAPTIVE_MIN_HALF &&
            stop_converged(var_px, o->target_error * o->target_error * mean_m2, cam->width,
                           cam->height, j.done) == 0)
            /* All stopped yet the pooled estimates were optimistic: go on
             * with every pixel rather than report an error above the target. */
            memset(j.done, 0, npix);
        if (o->time_limit > 0 && pass.seconds >= o->time_limit) {
            strcpy(stats->stop_reason, "time");
            break;
        }
    }
    stats->spp = 2 * n_half;
    for (size_t px = 0; px < npix; px++) {
        stats->samples += 2 * (int64_t)j.n_px[px];
        stats->pixels_stopped_early +=
            j.n_px[px] < n_half && !(j.it.cf && cf.mode[px] == SL_PIXEL_EXACT);
    }
    stats->seconds = sl_seconds() - t0;
    stats->cpu_seconds = sl_cpu_seconds() - c0;
    stats->samples_per_second =
        stats->seconds > 0 ? (double)stats->samples / stats->seconds : 0;
    for (int y = 0; y < cam->height; y++) {
        stats->camera_rays += j.rows[y].camera_rays;
        stats->shadow_rays += j.rows[y].shadow_rays;
        stats->bsdf_rays += j.rows[y].bsdf_rays;
        stats->shadow_rays_skipped += j.rows[y].shadow_skipped;
        stats->zero_weight_skipped += j.rows[y].zero_weight;
        stats->nonfinite_samples += j.rows[y].nonfinite;
        stats->lights_culled += j.rows[y].culled;
        stats->lights_behind += j.rows[y].behind;
    }
    stats->dome_bad_texels = scene->dome.bad_texels;
    stats->dome_sampled = j.it.dome_sampling;
    r = SL_OK;
done:
    sl_closed_form_free(&cf);
    free(j.sum[0]);
    free(j.sum[1]);
    free(j.rows);
    free(j.n_px);
    free(j.done);
    free(var_px);
    if (r)
        sl_image_free(out);
    if (r || stats == &local)
        sl_render_stats_free(stats);
    return r;
}
