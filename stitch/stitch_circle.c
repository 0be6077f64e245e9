/* SPDX-License-Identifier: BSD-3-Clause */
/* The image circle of a circular fisheye view, on HDR radiance. The coarse
 * disc and the verdict "is this a fisheye at all" are sl_fisheye_check's;
 * here the edge is measured to a fraction of a pixel along many rays and a
 * circle fitted through it. The radiance is sampled where it is (bilinear
 * on the view itself, float or half): no copy of a 24 MP view is made. */
#include "stitch_blend_private.h"
#include "unwrap_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define RAYS 720
#define STEP 0.25         /* px between profile samples along a ray */
#define MIN_CONTRAST 4.0  /* the inside at least this many times the dark frame */
#define MIN_SUPPORT 0.5   /* fraction of the rays with an edge on the circle */
#define ROUNDS 3          /* ray casts, each from the previous fit */
#define CLEAN_MIN (RAYS / 4) /* clean steps that fit the circle alone... */
#define CLEAN_GAP_DEG 120.0 /* ...when no arc this long has none */
#define CLEAN_BINS 72

/* The radiance the circle is found on: a float image, or a half view
 * (its samples through the table: the same values). */
typedef struct lum_source {
    const sl_image *img;
    const stitch_half_image *half;
    const float *table;
    int width, height;
} lum_source;

static lum_source float_source(const sl_image *img)
{
    return (lum_source){img, NULL, NULL, img->width, img->height};
}

/* Luminance of pixel (x, y), inside the image; 0 where not finite or not
 * positive. Inline, and lum_row chooses half or float once a row: as
 * calls they cost the circle 14% more CPU. */
static inline double lum_finite(double l)
{
    return isfinite(l) && l > 0.0 ? l : 0.0;
}

static inline double lum_half(const lum_source *src, int x, int y)
{
    const uint16_t *h = src->half->rgb + ((size_t)y * src->width + (size_t)x) * 3;
    const float p[3] = {src->table[h[0]], src->table[h[1]], src->table[h[2]]};
    return lum_finite(sl_luminance_px(p));
}

static inline double lum_float(const lum_source *src, int x, int y)
{
    const float *p = sl_image_pixel(src->img, x, y);
    return lum_finite(src->img->channels >= 3 ? sl_luminance_px(p) : p[0]);
}

static double lum_at_pixel(const lum_source *src, int x, int y)
{
    x = x < 0 ? 0 : (x >= src->width ? src->width - 1 : x);
    y = y < 0 ? 0 : (y >= src->height ? src->height - 1 : y);
    return src->half ? lum_half(src, x, y) : lum_float(src, x, y);
}

/* lum_at_pixel of the first n pixels of row y (all inside the image). */
static void lum_row(const lum_source *src, int y, int n, double *out)
{
    if (src->half)
        for (int x = 0; x < n; x++)
            out[x] = lum_half(src, x, y);
    else
        for (int x = 0; x < n; x++)
            out[x] = lum_float(src, x, y);
}

/* The median of the 3 x 3 pixels round (x, y): a merge leaves hot pixels
 * and noise speckles in the dark frame, which would end a ray early; a
 * median keeps a step edge where it is. */
static double lum_median3(const lum_source *img, int x, int y)
{
    double v[9];
    int n = 0;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++)
            v[n++] = lum_at_pixel(img, x + dx, y + dy);
    /* the median of nine by 19 exchanges (Paeth's network, as in
     * Devillard's opt_med9), branch-free: the values are finite */
#define SORT2(a, b)                                                                             \
    do {                                                                                        \
        double lo = v[a] < v[b] ? v[a] : v[b], hi = v[a] < v[b] ? v[b] : v[a];                  \
        v[a] = lo, v[b] = hi;                                                                   \
    } while (0)
    static const uint8_t pairs[19][2] = {{1, 2}, {4, 5}, {7, 8}, {0, 1}, {3, 4}, {6, 7}, {1, 2},
                                         {4, 5}, {7, 8}, {0, 3}, {5, 8}, {4, 7}, {3, 6}, {1, 4},
                                         {2, 5}, {4, 7}, {4, 2}, {6, 4}, {4, 2}};
    for (int i = 0; i < 19; i++)
        SORT2(pairs[i][0], pairs[i][1]);
#undef SORT2
    return v[4];
}

/* The medians a ray's profile used last: its samples are a quarter pixel
 * apart, so each pixel's median serves several of them. */
#define MEDIAN_SLOTS 16
typedef struct median_cache {
    int x[MEDIAN_SLOTS], y[MEDIAN_SLOTS];
    double v[MEDIAN_SLOTS];
} median_cache;

static void median_cache_clear(median_cache *c)
{
    for (int i = 0; i < MEDIAN_SLOTS; i++)
        c->x[i] = c->y[i] = -1000000;
}

static double median_at(const lum_source *img, int x, int y, median_cache *c)
{
    int slot = (int)(((unsigned)x * 5u + (unsigned)y * 3u) % MEDIAN_SLOTS);
    if (c->x[slot] != x || c->y[slot] != y) {
        c->x[slot] = x;
        c->y[slot] = y;
        c->v[slot] = lum_median3(img, x, y);
    }
    return c->v[slot];
}

/* Bilinear between pixel centres; (x, y) in pixel coordinates. */
static double lum_at(const lum_source *img, double x, double y, median_cache *c)
{
    double fx = x - 0.5, fy = y - 0.5;
    int ix = (int)floor(fx), iy = (int)floor(fy);
    double ax = fx - ix, ay = fy - iy;
    return (1 - ay) * ((1 - ax) * median_at(img, ix, iy, c) + ax * median_at(img, ix + 1, iy, c)) +
           ay * ((1 - ax) * median_at(img, ix, iy + 1, c) +
                 ax * median_at(img, ix + 1, iy + 1, c));
}

static double median_of(const double *v, int n, double *scratch)
{
    if (n <= 0)
        return 0.0;
    memcpy(scratch, v, (size_t)n * sizeof *v);
    qsort(scratch, (size_t)n, sizeof *scratch, sl_cmp_double);
    return n % 2 ? scratch[n / 2] : 0.5 * (scratch[n / 2 - 1] + scratch[n / 2]);
}

static double mean_between(const double *prof, int n, double t0, double a, double b)
{
    int i0 = (int)ceil((a - t0) / STEP), i1 = (int)floor((b - t0) / STEP);
    double s = 0.0;
    int m = 0;
    for (int i = i0 < 0 ? 0 : i0; i <= i1 && i < n; i++, m++)
        s += prof[i];
    return m ? s / m : -1.0;
}

/* The outermost point where the profile falls through `level`, as a
 * distance from the centre; -1 if none. */
static double crossing(const double *prof, int n, double t0, double level)
{
    for (int j = n - 2; j >= 0; j--)
        if (prof[j] >= level && prof[j + 1] < level)
            return t0 + STEP * (j + (prof[j] - level) / (prof[j] - prof[j + 1]));
    return -1.0;
}

/* Whether the profile is a clean step at te: flat (within STEP_FLAT of
 * `in`) over STEP_BAND px inside its blur (te - d), and never above that
 * level between there and the edge. The scene's own structure within a
 * pixel or two of the rim (a panel's edge, a bright line) moves the
 * halfway point along that stretch of the rim by tenths of a pixel, all
 * the same way: a bias the fit's residuals do not show. */
#define STEP_FLAT 0.1
#define STEP_BAND 3.0
static bool clean_step(const double *prof, int n, double t0, double te, double d, double in)
{
    int i0 = (int)ceil((te - d - STEP_BAND - t0) / STEP), i1 = (int)floor((te - t0) / STEP);
    int inner = (int)floor((te - d - t0) / STEP);
    i0 = i0 < 0 ? 0 : i0;
    if (inner - i0 < (int)(1.0 / STEP) || i1 >= n || !(in > 0.0))
        return false;
    for (int i = i0; i <= i1; i++) {
        if (prof[i] > (1.0 + STEP_FLAT) * in)
            return false;
        if (i <= inner && prof[i] < (1.0 - STEP_FLAT) * in)
            return false;
    }
    return true;
}

/* The edge along one ray from (cx, cy) near radius r, searched within +-w:
 * where the radiance is halfway between the inside just within the edge
 * and the dark frame just outside it. -1 when the ray has no clear edge
 * there (leaves the frame, a dark or clipped stretch of the rim); *clean
 * says whether it is a clean step (clean_step). */
static double ray_edge(const lum_source *img, double cx, double cy, double r, double w,
                       double dx, double dy, double *prof, double *scratch, double *blur,
                       bool *clean)
{
    *blur = -1.0;
    *clean = false;
    double t0 = r - w;
    int n = (int)(2.0 * w / STEP) + 1;
    median_cache cache;
    median_cache_clear(&cache);
    for (int j = 0; j < n; j++) {
        double t = t0 + j * STEP, x = cx + t * dx, y = cy + t * dy;
        if (x < 0.5 || y < 0.5 || x > img->width - 0.5 || y > img->height - 0.5)
            return -1.0; /* the circle meets the frame's edge here */
        prof[j] = lum_at(img, x, y, &cache);
    }
    int q = n / 4;
    double in = median_of(prof, q, scratch), out = median_of(prof + n - q, q, scratch);
    if (!(in > MIN_CONTRAST * out) || !(in > 0.0))
        return -1.0;
    double te = crossing(prof, n, t0, 0.5 * (in + out));
    if (te < 0.0)
        return -1.0;
    /* Again with the levels right beside this edge, beyond its blur (a real
     * lens's rim is soft over several pixels): the scene's texture and the
     * vignetting change the inside from place to place. */
    double hi = crossing(prof, n, t0, out + 0.9 * (in - out));
    double lo = crossing(prof, n, t0, out + 0.1 * (in - out));
    double d = hi > 0.0 && lo > hi ? fmax(2.0, 1.0 + 0.5 * (lo - hi)) : 2.0;
    *blur = hi > 0.0 && lo > hi ? lo - hi : -1.0;
    double li = mean_between(prof, n, t0, te - d - 0.5, te - d + 0.5);
    double lout = mean_between(prof, n, t0, te + d - 0.5, te + d + 0.5);
    if (li > MIN_CONTRAST * lout && lout >= 0.0) {
        double t2 = crossing(prof, n, t0, 0.5 * (li + lout));
        if (t2 > 0.0 && fabs(t2 - te) < d)
            te = t2;
        *clean = clean_step(prof, n, t0, te, d, li);
    }
    return te > r - 0.75 * w && te < r + 0.75 * w ? te : -1.0;
}

/* Least-squares circle through the edge points, dropping those far from it
 * (robust scale from the median absolute residual) until none is. */
static bool robust_fit(const ball_point *pts, bool *use, int n, double c[3], int *inliers,
                       double *rms, double *scratch)
{
    for (int i = 0; i < n; i++)
        use[i] = true;
    for (int pass = 0; pass < 8; pass++) {
        if (!ball_circle_fit(pts, use, n, c))
            return false;
        int m = 0;
        for (int i = 0; i < n; i++)
            if (use[i])
                scratch[m++] = fabs(hypot(pts[i].x - c[0], pts[i].y - c[1]) - c[2]);
        double *sorted = scratch + n;
        double tol = fmax(0.25, 3.0 * 1.4826 * median_of(scratch, m, sorted));
        bool changed = false;
        for (int i = 0; i < n; i++) {
            bool keep = fabs(hypot(pts[i].x - c[0], pts[i].y - c[1]) - c[2]) <= tol;
            changed = changed || keep != use[i];
            use[i] = keep;
        }
        if (!changed)
            break;
    }
    if (!ball_circle_fit(pts, use, n, c))
        return false;
    double ss = 0.0;
    int m = 0;
    for (int i = 0; i < n; i++)
        if (use[i]) {
            double e = hypot(pts[i].x - c[0], pts[i].y - c[1]) - c[2];
            ss += e * e;
            m++;
        }
    *inliers = m;
    *rms = m ? sqrt(ss / m) : 0.0;
    return true;
}

/* The dark frame's noise floor, taken off the coarse copy when the frame's
 * border is noise round a low level: a long exposure at night leaves read
 * and shot noise there, not black, and the inside (a night sky) is only a
 * few times brighter, so the border's 90th percentile against the centre's
 * median (sl_fisheye_check's test) would call the frame bright. The floor
 * is the border's median plus FLOOR_SIGMAS robust deviations (from its
 * median absolute deviation): a step edge stays a step above it; a light
 * leak or a scene on part of the border stays above it too. A border whose
 * median is not under BORDER_FLOOR_MAX of the centre's is no dark frame
 * and is left as it is (a chrome ball's crop, a lat-long). */
#define FLOOR_SIGMAS 3.0
#define BORDER_FLOOR_MAX 0.15 /* sl_fisheye_check's BORDER_DARK */
#define BORDER_BAND 2         /* px of the coarse copy, as sl_fisheye_check's */

static double floor_of(const sl_image *lum, double *scratch)
{
    int w = lum->width, h = lum->height, nb = 0, nc = 0;
    double half = 0.5 * (w < h ? w : h);
    double *border = scratch, *centre = scratch + (size_t)w * h;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double v = sl_image_pixel(lum, x, y)[0];
            if (x < BORDER_BAND || y < BORDER_BAND || x >= w - BORDER_BAND || y >= h - BORDER_BAND)
                border[nb++] = v;
            else if (hypot(x + 0.5 - 0.5 * w, y + 0.5 - 0.5 * h) < 0.5 * half)
                centre[nc++] = v;
        }
    double *sorted = centre + nc;
    double level = median_of(border, nb, sorted), inside = median_of(centre, nc, sorted);
    if (!(inside > 0.0) || !(level < BORDER_FLOOR_MAX * inside))
        return 0.0;
    for (int i = 0; i < nb; i++)
        border[i] = fabs(border[i] - level);
    return level + FLOOR_SIGMAS * 1.4826 * median_of(border, nb, sorted);
}

/* Luminance block-averaged to at most COARSE_SIZE px across, then 3 x 3
 * median filtered, less the dark frame's noise floor, for
 * sl_fisheye_check's coarse disc: its walk in from the frame's edge stops
 * at the first bright pixel, a merge's hot pixel too. */
#define COARSE_SIZE 800
static sl_result coarse_copy(const lum_source *img, sl_image *out, int *factor, sl_error *err)
{
    int big = img->width > img->height ? img->width : img->height;
    int f = (big + COARSE_SIZE - 1) / COARSE_SIZE;
    sl_image mean = {0};
    sl_result r = sl_image_alloc(&mean, img->width / f, img->height / f, 1, err);
    if (!r)
        r = sl_image_alloc(out, mean.width, mean.height, 1, err);
    if (r) {
        sl_image_free(&mean);
        return r;
    }
    /* Each block's sum in lum_at_pixel's order (row by row, left to right)
     * with the rows' luminances taken once: every pixel is inside. */
    int n = mean.width * f;
    double *lum = malloc((size_t)n * sizeof *lum), *sum = malloc((size_t)mean.width * sizeof *sum);
    if (!lum || !sum) {
        free(lum), free(sum);
        sl_image_free(&mean), sl_image_free(out);
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory finding the image circle");
    }
    for (int y = 0; y < mean.height; y++) {
        for (int x = 0; x < mean.width; x++)
            sum[x] = 0.0;
        for (int j = 0; j < f; j++) {
            lum_row(img, y * f + j, n, lum);
            for (int x = 0; x < mean.width; x++)
                for (int i = 0; i < f; i++)
                    sum[x] += lum[x * f + i];
        }
        for (int x = 0; x < mean.width; x++)
            sl_image_pixel(&mean, x, y)[0] = (float)(sum[x] / (f * f));
    }
    free(lum), free(sum);
    lum_source means = float_source(&mean);
    for (int y = 0; y < out->height; y++)
        for (int x = 0; x < out->width; x++)
            sl_image_pixel(out, x, y)[0] = (float)lum_median3(&means, x, y);
    sl_image_free(&mean);
    *factor = f;
    double *scratch = malloc(3 * (size_t)out->width * out->height * sizeof *scratch);
    if (!scratch) {
        sl_image_free(out);
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory finding the image circle");
    }
    double floor_level = floor_of(out, scratch);
    free(scratch);
    if (floor_level > 0.0)
        for (int y = 0; y < out->height; y++)
            for (int x = 0; x < out->width; x++) {
                float *p = sl_image_pixel(out, x, y);
                p[0] = p[0] > floor_level ? (float)(p[0] - floor_level) : 0.0f;
            }
    return SL_OK;
}

static sl_result circle_find(const lum_source *radiance, const char *name,
                             const sl_lens *nominal, sl_stitch_circle *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (!name)
        name = "view";
    if (radiance->width < 16 || radiance->height < 16)
        return sl_error_set(err, SL_ERR_INPUT, "%s: no image circle: the image is too small",
                            name);
    sl_fisheye_evidence ev;
    sl_error check_err;
    sl_image coarse = {0};
    int f = 1;
    sl_result r = coarse_copy(radiance, &coarse, &f, err);
    if (r)
        return r;
    r = sl_fisheye_check(&coarse, false, name, &ev, &check_err);
    sl_image_free(&coarse);
    if (r && !ev.fisheye)
        return sl_error_set(err, r, "%s", check_err.message);
    ev.cx *= f;
    ev.cy *= f;
    ev.r *= f;
    if (!ev.fisheye) {
        const char *why = !isfinite(ev.border_level) ? "the image is black"
                          : !ev.round ? (ev.border_level >= 0.15
                                           ? "the frame's border is not dark"
                                           : "no bright disc on a dark frame")
                          : ev.dark_outside < 0.95 ? "the frame beyond the disc is not dark"
                          : ev.margin < 0.02       ? "the disc touches the frame's edge"
                                                   : "its rim is brighter than its inside "
                                                     "(a chrome ball)";
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: no image circle: %s (not a circular fisheye view)", name, why);
    }
    double c[3] = {ev.cx, ev.cy, ev.r};
    ball_point *pts = malloc(RAYS * sizeof *pts);
    bool *use = malloc(2 * RAYS * sizeof *use);
    int max_n = (int)(2.0 * fmax(8.0, 0.04 * ev.r) / STEP) + 2;
    double *blurs = malloc(RAYS * sizeof *blurs);
    double *prof = malloc((size_t)max_n * sizeof *prof);
    double *scratch = malloc((size_t)(max_n > 2 * RAYS ? max_n : 2 * RAYS) * sizeof *scratch);
    bool *clean = malloc(RAYS * sizeof *clean);
    ball_point *clean_pts = malloc(RAYS * sizeof *clean_pts);
    if (!pts || !use || !prof || !scratch || !blurs || !clean || !clean_pts) {
        free(clean);
        free(clean_pts);
        free(blurs);
        free(pts);
        free(use);
        free(prof);
        free(scratch);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory finding the image circle",
                            name);
    }
    /* The coarse disc is from a copy up to 400 px across: a few of its
     * pixels wide is where the edge can be; later rounds look closer. */
    double w = fmax(8.0, 0.04 * ev.r);
    int n = 0, inliers = 0;
    double rms = 0.0;
    bool fitted = false;
    for (int round = 0; round < ROUNDS; round++) {
        n = 0;
        int nb = 0;
        for (int i = 0; i < RAYS; i++) {
            double a = 2.0 * M_PI * (i + 0.5) / RAYS, dx = cos(a), dy = sin(a), blur;
            double t = ray_edge(radiance, c[0], c[1], c[2], w, dx, dy, prof, scratch, &blur,
                                &clean[n]);
            if (t > 0.0) {
                pts[n].x = c[0] + t * dx;
                pts[n].y = c[1] + t * dy;
                n++;
                if (blur > 0.0)
                    blurs[nb++] = blur;
            }
        }
        /* The next round looks closer, but never closer than the edge is wide. */
        double edge_width = median_of(blurs, nb, scratch);
        double next[3] = {c[0], c[1], c[2]};
        fitted = n >= 8 && robust_fit(pts, use, n, next, &inliers, &rms, scratch);
        if (!fitted)
            break;
        /* The centre and radius from the clean steps alone when they go
         * round the circle (no gap over CLEAN_GAP_DEG): the support and the
         * spread stay those of every edge point. */
        int m = 0;
        bool bin[CLEAN_BINS] = {false};
        for (int i = 0; i < n; i++)
            if (clean[i] && use[i]) {
                clean_pts[m++] = pts[i];
                double a = atan2(pts[i].y - next[1], pts[i].x - next[0]) + M_PI;
                bin[(int)(a / (2.0 * M_PI) * CLEAN_BINS) % CLEAN_BINS] = true;
            }
        int gap = 0, run = 0;
        for (int k = 0; k < 2 * CLEAN_BINS; k++) {
            run = bin[k % CLEAN_BINS] ? 0 : run + 1;
            gap = run > gap ? run : gap;
        }
        double clean_fit[3] = {next[0], next[1], next[2]}, clean_rms;
        int clean_inliers;
        if (m >= CLEAN_MIN && gap * 360.0 / CLEAN_BINS <= CLEAN_GAP_DEG &&
            robust_fit(clean_pts, use + n, m, clean_fit, &clean_inliers, &clean_rms, scratch))
            memcpy(next, clean_fit, sizeof next);
        memcpy(c, next, sizeof c);
        w = fmax(fmax(4.0, 2.0 * edge_width + 2.0), fmin(w, 4.0 * rms + 3.0));
        w = fmin(w, fmax(8.0, 0.04 * ev.r));
    }
    free(blurs);
    free(pts);
    free(use);
    free(prof);
    free(scratch);
    free(clean);
    free(clean_pts);
    if (!fitted || inliers < MIN_SUPPORT * RAYS)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: no image circle: only %d of %d rays have an edge on one circle",
                            name, fitted ? inliers : n, RAYS);
    out->cx = c[0];
    out->cy = c[1];
    out->radius = c[2];
    out->rms_px = rms;
    out->rays = RAYS;
    out->edges = inliers;
    out->support = (double)inliers / RAYS;
    if (nominal && nominal->circle_radius_px > 0.0)
        out->radius_vs_nominal = c[2] / nominal->circle_radius_px;
    return SL_OK;
}

sl_result sl_stitch_circle_find(const sl_image *radiance, const char *name,
                                const sl_lens *nominal, sl_stitch_circle *out, sl_error *err)
{
    if (!radiance || !radiance->data) {
        memset(out, 0, sizeof *out);
        return sl_error_set(err, SL_ERR_INPUT, "%s: no image circle: the image is too small",
                            name ? name : "view");
    }
    lum_source src = float_source(radiance);
    return circle_find(&src, name, nominal, out, err);
}

sl_result stitch_circle_find_half(const stitch_half_image *img, const char *name,
                                  sl_stitch_circle *out, sl_error *err)
{
    lum_source src = {NULL, img, stitch_half_table(), img->width, img->height};
    return circle_find(&src, name, NULL, out, err);
}
