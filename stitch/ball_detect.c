/* SPDX-License-Identifier: BSD-3-Clause */
/* Chrome-ball detection. Candidates come from a copy at most 640 px across
 * (OpenCV's Hough transform on a log-tonemapped 8-bit image, plus the frame
 * itself: a tight crop holds the ball edge to edge), each scored by the
 * median log-luminance step over rays from its centre for its radius, then
 * fitted from sub-pixel edge points along rays (strongest log-luminance
 * step, then the centroid of the linear-luminance step, which is where an
 * anti-aliased or blurred step edge really is) by a robust geometric
 * least-squares circle. A fitted outline is a ball when most rays find an
 * edge on it, its inside is not flat (a disc, a clock face) and no circle
 * shares its centre (a ring and its hole); circles inside a ball are its
 * reflections. The ball's outline is then fitted again on the full image,
 * with the standard error of its centre and radius. */
#include "merge_private.h" /* merge_select_kth */
#include "unwrap_private.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define MAX_CANDIDATES 128
#define MAX_FOUND 64
#define WORK_SIZE 640 /* px across the copy the candidates are searched on */
/* Fraction of the rays that reach past the circle inside the frame with an
 * edge on it. Measured: synthetic balls 0.65-0.8, the real iPhone probes
 * 0.59-0.61, clutter coincidences at most 0.37. */
#define MIN_SUPPORT 0.5
#define MIN_IN_FRAME 0.5 /* fraction of the rays that reach past the circle */
/* Rays in a row with an edge on the circle that make an arc of outline,
 * and the fraction of the rays in the frame that must lie in such arcs. */
#define ARC_RUN 6
#define MIN_ARC 0.4
#define CLIP_TOLERANCE 1.0 /* px the circle may pass the frame edge (fit error) */
/* Edge points within this many px of the fitted circle count as support:
 * clutter puts an edge somewhere near any circle, but not on it. */
#define SUPPORT_TOLERANCE 1.0
#define SUPPORT_PER_RADIUS 120.0
#define EDGE_HALF 1.5 /* px each side of an edge for its centroid */
#define SECOND_BALL_RATIO 0.8 /* support of a second ball against the best */
/* A second ball this much smaller than the largest is another object (a
 * smaller ornament, a grey ball), not a rival for the set's reflection. */
#define SMALLER_BALL_RATIO 0.7
#define INLIER_MIN 0.5 /* robust-fit inlier band (px), from 3 sigma clamped to these */
#define INLIER_MAX 2.0
/* A flat inside: this fraction of it within FLAT_BAND (log) of its median.
 * A chrome ball's reflection and its Fresnel rim never are; painted discs
 * and clock faces are. */
#define FLAT_FRACTION 0.8
#define FLAT_BAND 0.03
/* A circle sharing the centre (within this fraction of the radius) makes a
 * ring, a dial's bezel or a ring's hole, not a ball. */
#define CONCENTRIC 0.03
/* Support of an outline clean enough that what lies inside it is part of
 * the same thing (measured: discs and dials 0.87-0.97, clutter 0.5-0.56). */
#define CLEAN_SUPPORT 0.75
/* Once a whole ball is found, a candidate under this fraction of its
 * radius can change nothing: a rival is at least SMALLER_BALL_RATIO of the
 * probe's radius, the probe at least about 0.9 of this ball's (the same ball
 * refitted), and a fit moves a candidate's radius by a few percent. */
#define RIVAL_FLOOR 0.5
/* The copy's own Hough pass is skipped when the smallest ball sought is
 * this many px across or more on the half copy (found there at a quarter of
 * the cost; the classic transform's time grows fastest with size). */
#define HOUGH_MIN_R 16.0
/* Standard error (px) of the centre or radius above which the outline is
 * too weakly measured to unwrap; 0.1 % of the radius for large balls. */
#define WEAK_SD 0.25
#define WEAK_SD_PER_RADIUS 0.001

typedef struct det_image {
    int w, h;
    float *lum;  /* linear luminance */
    float *logl; /* log(lum + eps); NULL: computed from lum where sampled */
    double eps;
} det_image;

typedef struct fit {
    double cx, cy, r, rms;
    int inliers;
    double support; /* inliers over the rays, but those the frame ends just past the circle */
    double in_frame; /* fraction of the rays counted */
    double coverage; /* inliers over all rays: what tells two fits of one ball apart */
    double arc;      /* inliers in runs of ARC_RUN rays, over the rays in the frame */
    double sd;       /* largest standard error of cx, cy, r (px) */
} fit;

static double bilinear(const det_image *im, const float *p, double x, double y)
{
    return sl_bilinear_plane(p, im->w, im->h, x, y);
}

static double log_at(const det_image *im, double x, double y)
{
    return im->logl ? bilinear(im, im->logl, x, y) : log(bilinear(im, im->lum, x, y) + im->eps);
}

static bool in_frame(const det_image *im, double x, double y)
{
    return x >= 0.5 && y >= 0.5 && x <= im->w - 0.5 && y <= im->h - 0.5;
}

bool ball_circle_fit(const ball_point *p, const bool *use, int n, double c[3])
{
    double s[3][4] = {{0}};
    int m = 0;
    for (int i = 0; i < n; i++) {
        if (!use[i])
            continue;
        double x = p[i].x - c[0], y = p[i].y - c[1], z = x * x + y * y;
        double row[4] = {x, y, 1.0, -z};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 4; b++)
                s[a][b] += row[a] * row[b];
        m++;
    }
    if (m < 8)
        return false;
    /* Solve the 3x3 normal equations by Gaussian elimination with pivoting. */
    for (int k = 0; k < 3; k++) {
        int piv = k;
        for (int i = k + 1; i < 3; i++)
            if (fabs(s[i][k]) > fabs(s[piv][k]))
                piv = i;
        if (fabs(s[piv][k]) < 1e-300)
            return false;
        for (int b = 0; b < 4; b++) {
            double t = s[k][b];
            s[k][b] = s[piv][b];
            s[piv][b] = t;
        }
        for (int i = 0; i < 3; i++) {
            if (i == k)
                continue;
            double f = s[i][k] / s[k][k];
            for (int b = k; b < 4; b++)
                s[i][b] -= f * s[k][b];
        }
    }
    double D = s[0][3] / s[0][0], E = s[1][3] / s[1][1], F = s[2][3] / s[2][2];
    double cx = c[0] - D / 2, cy = c[1] - E / 2;
    double r2 = D * D / 4 + E * E / 4 - F;
    if (!(r2 > 0.0))
        return false;
    double r = sqrt(r2);
    for (int it = 0; it < 20; it++) {
        double jtj[3][3] = {{0}}, jtr[3] = {0};
        for (int i = 0; i < n; i++) {
            if (!use[i])
                continue;
            double dx = p[i].x - cx, dy = p[i].y - cy, d = hypot(dx, dy);
            if (d == 0.0)
                continue;
            double j[3] = {-dx / d, -dy / d, -1.0}, e = d - r;
            for (int a = 0; a < 3; a++) {
                jtr[a] += j[a] * e;
                for (int b = 0; b < 3; b++)
                    jtj[a][b] += j[a] * j[b];
            }
        }
        /* Cramer's rule on the 3x3 system jtj * delta = -jtr. */
        double det = jtj[0][0] * (jtj[1][1] * jtj[2][2] - jtj[1][2] * jtj[2][1]) -
                     jtj[0][1] * (jtj[1][0] * jtj[2][2] - jtj[1][2] * jtj[2][0]) +
                     jtj[0][2] * (jtj[1][0] * jtj[2][1] - jtj[1][1] * jtj[2][0]);
        if (fabs(det) < 1e-300)
            break;
        double delta[3];
        for (int k = 0; k < 3; k++) {
            double m3[3][3];
            memcpy(m3, jtj, sizeof m3);
            for (int a = 0; a < 3; a++)
                m3[a][k] = -jtr[a];
            delta[k] = (m3[0][0] * (m3[1][1] * m3[2][2] - m3[1][2] * m3[2][1]) -
                        m3[0][1] * (m3[1][0] * m3[2][2] - m3[1][2] * m3[2][0]) +
                        m3[0][2] * (m3[1][0] * m3[2][1] - m3[1][1] * m3[2][0])) /
                       det;
        }
        cx += delta[0];
        cy += delta[1];
        r += delta[2];
        if (fabs(delta[0]) + fabs(delta[1]) + fabs(delta[2]) < 1e-9)
            break;
    }
    c[0] = cx;
    c[1] = cy;
    c[2] = r;
    return isfinite(cx) && isfinite(cy) && r > 0.0;
}

/* Largest standard error of the centre and radius of the geometric fit c
 * through the points in use[]: sigma^2 (J^T J)^-1. */
static double circle_sd(const ball_point *p, const bool *use, int n, const double c[3])
{
    double jtj[3][3] = {{0}}, ss = 0.0;
    int m = 0;
    for (int i = 0; i < n; i++) {
        if (!use[i])
            continue;
        double dx = p[i].x - c[0], dy = p[i].y - c[1], d = hypot(dx, dy);
        if (d == 0.0)
            continue;
        double j[3] = {-dx / d, -dy / d, -1.0}, e = d - c[2];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                jtj[a][b] += j[a] * j[b];
        ss += e * e;
        m++;
    }
    double inv[3][3];
    if (m < 4 || !sl_mat3_invert(jtj, inv))
        return INFINITY;
    double s2 = ss / (m - 3), worst = 0.0;
    for (int k = 0; k < 3; k++)
        worst = fmax(worst, sqrt(fmax(0.0, s2 * inv[k][k])));
    return worst;
}

enum { RAY_OUT = -1, RAY_NONE = 0, RAY_EDGE = 1 };

/* Sub-pixel edge along one ray, searched in [r - win, r + win]: RAY_OUT
 * when the ray leaves the frame before it passes the circle. */
static int ray_edge(const det_image *im, double cx, double cy, double r, double win, double dx,
                    double dy, ball_point *out)
{
    double lo = r - win, hi = r + win;
    if (lo < 1.0)
        lo = 1.0;
    /* The window may end at the frame; the circle itself may not. */
    while (hi > lo && !in_frame(im, cx + (hi + EDGE_HALF + 0.5) * dx, cy + (hi + EDGE_HALF + 0.5) * dy))
        hi -= 0.25;
    if (hi < r + 1.0)
        return RAY_OUT;
    if (!in_frame(im, cx + (lo - EDGE_HALF - 0.5) * dx, cy + (lo - EDGE_HALF - 0.5) * dy))
        return RAY_OUT;
    /* The strongest step, discounted with its distance from the circle
     * (half at the window's end): clutter next to the outline must be
     * much stronger to win. */
    double best = -1.0, best_s = 0.0, best_g = 0.0;
    for (double s = lo; s <= hi; s += 0.25) {
        double g = fabs(log_at(im, cx + (s + 0.5) * dx, cy + (s + 0.5) * dy) -
                        log_at(im, cx + (s - 0.5) * dx, cy + (s - 0.5) * dy));
        double u = (s - r) / win, score = g / (1.0 + u * u);
        if (score > best) {
            best = score;
            best_g = g;
            best_s = s;
        }
    }
    if (best_g < 0.05) /* under 5% contrast per pixel: no edge here */
        return RAY_NONE;
    /* Centroid of the linear-luminance step across the edge: exact for a
     * box-filtered (anti-aliased) step edge, and blind to the log bias. */
    double s_edge = best_s;
    for (int pass = 0; pass < 2; pass++) {
        double m0 = 0.0, m1 = 0.0;
        double before = bilinear(im, im->lum, cx + (s_edge - EDGE_HALF) * dx,
                                 cy + (s_edge - EDGE_HALF) * dy);
        double last = bilinear(im, im->lum, cx + (s_edge + EDGE_HALF) * dx,
                               cy + (s_edge + EDGE_HALF) * dy);
        double sign = before >= last ? 1.0 : -1.0;
        for (double s = s_edge - EDGE_HALF + 0.125; s < s_edge + EDGE_HALF; s += 0.125) {
            double cur = bilinear(im, im->lum, cx + s * dx, cy + s * dy);
            double d = sign * (before - cur);
            if (d > 0.0) {
                m0 += d;
                m1 += d * (s - 0.0625);
            }
            before = cur;
        }
        if (m0 > 0.0)
            s_edge = m1 / m0;
    }
    out->x = cx + s_edge * dx;
    out->y = cy + s_edge * dy;
    return RAY_EDGE;
}

/* Edge points around (cx, cy, r), then a robust fit; f gets the result. */
static bool refine(const det_image *im, double cx, double cy, double r, double win, int max_rays,
                   fit *f)
{
    memset(f, 0, sizeof *f);
    int n = (int)lround(2.0 * M_PI * r / 1.5);
    n = n < 48 ? 48 : (n > max_rays ? max_rays : n);
    ball_point *pts = malloc((size_t)n * sizeof *pts);
    int *ray_of = malloc((size_t)n * sizeof *ray_of); /* point -> its ray */
    bool *on = calloc((size_t)n, sizeof *on);          /* ray -> an inlier */
    bool *use = malloc((size_t)n * sizeof *use);
    double *res = malloc((size_t)n * sizeof *res);
    double *sorted = malloc((size_t)n * sizeof *sorted);
    bool ok = false;
    if (!pts || !use || !res || !sorted || !ray_of || !on)
        goto done;
    int m = 0, inside = 0;
    for (int i = 0; i < n; i++) {
        double a = 2.0 * M_PI * (i + 0.5) / n;
        int k = ray_edge(im, cx, cy, r, win, cos(a), sin(a), &pts[m]);
        /* A ray that leaves the frame just past a circle still inside it
         * (a tight crop) says nothing; one whose circle point is off the
         * frame counts as a miss (a circle mostly off the frame has little). */
        double px = cx + r * cos(a), py = cy + r * sin(a);
        bool excused = k == RAY_OUT && px >= -CLIP_TOLERANCE && py >= -CLIP_TOLERANCE &&
                       px <= im->w + CLIP_TOLERANCE && py <= im->h + CLIP_TOLERANCE;
        inside += !excused;
        ray_of[m] = i;
        m += k == RAY_EDGE;
    }
    double c[3] = {cx, cy, r};
    for (int i = 0; i < m; i++)
        use[i] = true;
    for (int pass = 0; pass < 4; pass++) {
        if (!ball_circle_fit(pts, use, m, c))
            goto done;
        for (int i = 0; i < m; i++)
            res[i] = fabs(hypot(pts[i].x - c[0], pts[i].y - c[1]) - c[2]);
        memcpy(sorted, res, (size_t)m * sizeof *sorted);
        qsort(sorted, (size_t)m, sizeof *sorted, sl_cmp_double);
        double limit = 3.0 * 1.4826 * sorted[m / 2];
        limit = limit < INLIER_MIN ? INLIER_MIN : (limit > INLIER_MAX ? INLIER_MAX : limit);
        for (int i = 0; i < m; i++)
            use[i] = res[i] <= limit;
    }
    /* A circle fit of a real outline scatters more as the ball grows: the
     * perspective ellipse (axes differ by ~r (1/cos(off-axis) - 1)), lens
     * distortion and texture next to the rim all scale with the radius. */
    double tol = fmax(SUPPORT_TOLERANCE, c[2] / SUPPORT_PER_RADIUS);
    double ss = 0.0;
    for (int i = 0; i < m; i++) {
        use[i] = use[i] && res[i] <= tol;
        if (use[i]) {
            ss += res[i] * res[i];
            f->inliers++;
            on[ray_of[i]] = true;
        }
    }
    /* An outline is edge after edge along it; chance edges near a circle
     * in clutter are scattered: count the inliers in runs of ARC_RUN rays. */
    int arc = 0;
    for (int i = 0; i < n; i++) {
        if (!on[i])
            continue;
        int back = 0, fwd = 0;
        while (back < ARC_RUN && on[(i - back - 1 + n) % n])
            back++;
        while (fwd < ARC_RUN && on[(i + fwd + 1) % n])
            fwd++;
        arc += back + fwd + 1 >= ARC_RUN;
    }
    f->cx = c[0];
    f->cy = c[1];
    f->r = c[2];
    f->rms = f->inliers ? sqrt(ss / f->inliers) : 0.0;
    f->in_frame = (double)inside / n;
    f->support = inside ? (double)f->inliers / inside : 0.0;
    f->coverage = (double)f->inliers / n;
    f->arc = inside ? (double)arc / inside : 0.0;
    f->sd = circle_sd(pts, use, m, c);
    ok = f->inliers >= 24 && f->in_frame >= MIN_IN_FRAME;
done:
    free(pts);
    free(ray_of);
    free(on);
    free(use);
    free(res);
    free(sorted);
    return ok;
}


static int radius_search(const det_image *im, double cx, double cy, double rmin, double rmax,
                         double out[3])
{
    enum { RAYS = 90 };
    const double step = 1.0;
    int nr = (int)((rmax - rmin) / step) + 1;
    if (nr < 3)
        return 0;
    float *g = malloc(sizeof(float) * RAYS * (size_t)nr);
    double *col = malloc(sizeof(double) * RAYS);
    double *score = malloc(sizeof(double) * (size_t)nr);
    float *prof = malloc(sizeof(float) * ((size_t)nr + 2));
    float *steps = malloc(sizeof(float) * (size_t)nr);
    int found = 0;
    if (!g || !col || !score || !prof || !steps)
        goto done;
    for (int a = 0; a < RAYS; a++) {
        double ang = 2.0 * M_PI * (a + 0.5) / RAYS, dx = cos(ang), dy = sin(ang);
        float *row = g + (size_t)a * nr;
        /* The log luminance every pixel from rmin - 1: the step over 2 px
         * at radius s is prof[j + 2] - prof[j] (a blurred edge's too). */
        for (int j = 0; j < nr + 2; j++) {
            double s = rmin - 1.0 + j * step;
            prof[j] = in_frame(im, cx + s * dx, cy + s * dy) ? (float)log_at(im, cx + s * dx, cy + s * dy)
                                                               : NAN;
        }
        for (int j = 0; j < nr; j++)
            steps[j] = isnan(prof[j + 2]) || isnan(prof[j]) ? -1.0f : fabsf(prof[j + 2] - prof[j]);
        /* Max-filtered by 3 px (the centre's error); -1 outside the frame. */
        for (int j = 0; j < nr; j++) {
            float best = steps[j] < 0.0f ? -1.0f : 0.0f;
            if (best < 0.0f) {
                row[j] = best;
                continue;
            }
            for (int k = j - 3; k <= j + 3; k++)
                if (k >= 0 && k < nr && steps[k] > best)
                    best = steps[k];
            row[j] = best;
        }
    }
    for (int j = 0; j < nr; j++) {
        int m = 0;
        for (int a = 0; a < RAYS; a++) {
            float v = g[(size_t)a * nr + j];
            if (v >= 0.0f)
                col[m++] = v;
        }
        if (m < RAYS / 3) {
            score[j] = 0.0;
            continue;
        }
        score[j] = merge_select_kth(col, m, m / 2);
    }
    for (int pick = 0; pick < 3; pick++) {
        int best = -1;
        for (int j = 0; j < nr; j++) {
            bool near = false;
            for (int q = 0; q < pick; q++)
                near = near || fabs(rmin + j * step - out[q]) < 10.0;
            if (near)
                continue;
            if (best < 0 || score[j] > score[best])
                best = j;
        }
        if (best < 0 || score[best] < 0.05)
            break;
        out[found++] = rmin + best * step;
    }
done:
    free(g);
    free(col);
    free(score);
    free(prof);
    free(steps);
    return found;
}

static void det_free(det_image *im)
{
    free(im->lum);
    free(im->logl);
    memset(im, 0, sizeof *im);
}

/* The full-size luminance (non-finite and negative as 0) and the log's
 * offset: small against the scene's median and its brightest, but at most
 * 5% of the 90th percentile: a night frame's lamps (reflected in the ball)
 * are millions of times its sky, and an offset from them alone would
 * flatten the whole frame's log (no edge left anywhere). */
static sl_result full_image(const sl_image *photo, det_image *im, sl_error *err)
{
    size_t n = (size_t)photo->width * photo->height;
    im->w = photo->width;
    im->h = photo->height;
    im->lum = malloc(n * sizeof(float));
    size_t ns = n < 65536 ? n : 65536;
    double *sample = malloc(ns * sizeof(double));
    if (!im->lum || !sample) {
        free(sample);
        return sl_error_set(err, SL_ERR_NOMEM, "ball detection: out of memory");
    }
    for (int y = 0; y < photo->height; y++)
        for (int x = 0; x < photo->width; x++) {
            const float *p = sl_image_pixel(photo, x, y);
            double l = photo->channels >= 3 ? sl_luminance_px(p)
                                            : p[0];
            im->lum[(size_t)y * photo->width + x] = isfinite(l) && l > 0.0 ? (float)l : 0.0f;
        }
    for (size_t i = 0; i < ns; i++)
        sample[i] = im->lum[i * (n / ns)];
    qsort(sample, ns, sizeof *sample, sl_cmp_double);
    im->eps = fmax(1e-3 * sample[ns / 2], fmin(1e-4 * sample[ns - 1], 0.05 * sample[ns - 1 - ns / 10]));
    if (!(im->eps > 0.0))
        im->eps = 1e-9;
    free(sample);
    return SL_OK;
}

/* The search copy: `full` box-averaged by `factor`, its log and the 8-bit
 * tonemapped log for the Hough transform. */
static sl_result work_image(const det_image *full, int factor, det_image *im,
                            unsigned char **gray, sl_error *err)
{
    im->w = full->w / factor;
    im->h = full->h / factor;
    im->eps = full->eps;
    size_t n = (size_t)im->w * im->h;
    im->lum = calloc(n, sizeof(float));
    im->logl = malloc(n * sizeof(float));
    *gray = malloc(n);
    size_t ns = n < 65536 ? n : 65536;
    double *sample = malloc(ns * sizeof(double));
    if (!im->lum || !im->logl || !*gray || !sample) {
        free(sample);
        return sl_error_set(err, SL_ERR_NOMEM, "ball detection: out of memory");
    }
    for (int y = 0; y < im->h * factor; y++)
        for (int x = 0; x < im->w * factor; x++)
            im->lum[(size_t)(y / factor) * im->w + x / factor] += full->lum[(size_t)y * full->w + x];
    for (size_t i = 0; i < n; i++) {
        im->lum[i] /= (float)(factor * factor);
        im->logl[i] = (float)log(im->lum[i] + im->eps);
    }
    for (size_t i = 0; i < ns; i++)
        sample[i] = im->logl[i * (n / ns)];
    qsort(sample, ns, sizeof *sample, sl_cmp_double);
    double lo = sample[ns / 100], hi = sample[ns - 1 - ns / 200];
    free(sample);
    double scale = hi > lo ? 255.0 / (hi - lo) : 1.0;
    for (size_t i = 0; i < n; i++) {
        double g = (im->logl[i] - lo) * scale;
        (*gray)[i] = (unsigned char)(g < 0.0 ? 0.0 : (g > 255.0 ? 255.0 : g + 0.5));
    }
    return SL_OK;
}

/* Fraction of the inside (to 0.9 radii) within FLAT_BAND of its median log
 * luminance. */
/* Fraction of the annulus between radii a and b (in units of f's radius)
 * within FLAT_BAND of its median log luminance. */
static double flat_fraction(const det_image *im, const fit *f, double a, double b)
{
    enum { GRID = 64 };
    double v[GRID * GRID];
    int n = 0;
    for (int j = 0; j < GRID; j++)
        for (int i = 0; i < GRID; i++) {
            double u = b * (2.0 * (i + 0.5) / GRID - 1.0), w = b * (2.0 * (j + 0.5) / GRID - 1.0);
            double d2 = u * u + w * w;
            if (d2 > b * b || d2 < a * a)
                continue;
            v[n++] = log_at(im, f->cx + u * f->r, f->cy + w * f->r);
        }
    if (n < 16)
        return 0.0;
    qsort(v, (size_t)n, sizeof *v, sl_cmp_double);
    double med = v[n / 2];
    int near = 0;
    for (int i = 0; i < n; i++)
        near += fabs(v[i] - med) <= FLAT_BAND;
    return (double)near / n;
}

/* True when f is a ring, a dial's bezel or a ring's hole: another
 * well-supported circle shares its centre, inside it or outside it, and
 * the band between the two is flat (a ball's reflection is not, even
 * where its horizon draws a circle round its centre). */
static bool is_ring(const det_image *im, const fit *f)
{
    const double spans[2][2] = {{0.25, 0.92}, {1.08, 2.5}};
    for (int s = 0; s < 2; s++) {
        double radii[3];
        int nr = radius_search(im, f->cx, f->cy, spans[s][0] * f->r, spans[s][1] * f->r, radii);
        for (int k = 0; k < nr; k++) {
            fit g;
            if (!refine(im, f->cx, f->cy, radii[k], 3.0, 512, &g) || g.support < MIN_SUPPORT ||
                hypot(g.cx - f->cx, g.cy - f->cy) >= CONCENTRIC * f->r)
                continue;
            double lo = fmin(g.r, f->r) / f->r, hi = fmax(g.r, f->r) / f->r, pad = 2.0 / f->r;
            if (flat_fraction(im, f, lo + pad, hi - pad) >= FLAT_FRACTION)
                return true;
        }
    }
    return false;
}

typedef struct found_list {
    fit balls[MAX_FOUND];  /* outlines that look like balls */
    fit others[MAX_FOUND]; /* round things that do not: discs, rings, dials */
    int nballs, nothers;
} found_list;

static bool inside(const fit *a, const fit *b) /* a within b, give or take 3% */
{
    return hypot(a->cx - b->cx, a->cy - b->cy) + a->r < b->r + fmax(2.0, 0.03 * b->r);
}

/* Fits one candidate and files it: a ball, another round thing, or nothing. */
/* Where the candidates are searched and where they are measured. */
typedef struct search {
    const det_image *work; /* the copy, pixels `factor` full pixels wide */
    const det_image *full;
    int factor;
    double min_r; /* on the copy: smaller outlines meet chance edges in clutter */
    found_list *found;
} search;

/* Walks a candidate in to an outline on `im`: a quick look with few rays
 * and a window of `first` px each side (most candidates end there), then
 * `then` of the radius (3 px at least), then fits with 3 px windows until
 * the circle stops moving. False when no outline is there. */
static bool walk_in(const det_image *im, double cx, double cy, double r, double first, double then,
                    fit *f)
{
    if (!refine(im, cx, cy, r, first, 128, f) || f->support < 0.4 * MIN_SUPPORT ||
        !refine(im, f->cx, f->cy, f->r, fmax(3.0, then * f->r), 512, f))
        return false;
    /* A start a few pixels off walks in over a few fits. */
    for (int it = 0; it < 6; it++) {
        fit g;
        if (!refine(im, f->cx, f->cy, f->r, 3.0, 1024, &g))
            return false;
        double moved = hypot(g.cx - f->cx, g.cy - f->cy) + fabs(g.r - f->r);
        *f = g;
        if (moved < 0.2 || f->support < 0.6 * MIN_SUPPORT)
            break;
    }
    return f->support >= MIN_SUPPORT && f->arc >= MIN_ARC;
}

static void file_fit(const search *sc, const det_image *im, const fit *fitted);

/* Fits one candidate on the copy (windows of `window` of r, then 1.5%),
 * then on the full image, and files it: a ball, another round thing, or
 * nothing. Fits are in full pixels. */
static void consider(const search *sc, double cx, double cy, double r, double window)
{
    fit f;
    if (!walk_in(sc->work, cx, cy, r, fmax(3.0, window * r), 0.015, &f) ||
        f.r < sc->min_r)
        return;
    /* Clutter a few copy pixels wide meets any circle; on the full image
     * it is `factor` times sparser. The window covers the copy's error. */
    if (sc->factor > 1) {
        int k = sc->factor;
        if (!refine(sc->full, f.cx * k, f.cy * k, f.r * k, fmax(3.0, 1.5 * k), 1024, &f) ||
            !refine(sc->full, f.cx, f.cy, f.r, 3.0, 1024, &f) || f.support < MIN_SUPPORT ||
            f.arc < MIN_ARC)
            return;
    }
    file_fit(sc, sc->factor > 1 ? sc->full : sc->work, &f);
}

/* The frame's own candidate, a tight crop's ball of about radius r (copy
 * px) centred in it. On a copy of a large frame the clutter in the corners,
 * averaged, blurs into the outline and pulls the fit past the frame (a
 * 3000 px frame); so on the full image too: the radii where the most rays
 * from the frame's centre cross a step (a median, blind to a hot spot on a
 * few rays), each walked in with 3 px windows (a wide one there meets
 * sharp clutter on every ray). */
static void consider_frame(const search *sc, double r)
{
    const det_image *full = sc->full;
    int k = sc->factor;
    double cx = 0.5 * full->w, cy = 0.5 * full->h, radii[3];
    int n = k > 1 ? radius_search(full, cx, cy, 0.95 * r * k, 1.05 * r * k, radii) : 0;
    for (int i = 0; i < n; i++) {
        fit f;
        if (walk_in(full, cx, cy, radii[i], 3.0, 0.0, &f) && f.r >= sc->min_r * k)
            file_fit(sc, full, &f);
    }
    consider(sc, 0.5 * sc->work->w, 0.5 * sc->work->h, r, 0.05);
}

/* Files a fitted outline (full pixels, measured on `im`): a ball, another
 * round thing, or nothing. */
static void file_fit(const search *sc, const det_image *im, const fit *fitted)
{
    found_list *fl = sc->found;
    fit f = *fitted;
    for (int j = 0; j < fl->nballs; j++) {
        const fit *b = &fl->balls[j];
        if (hypot(f.cx - b->cx, f.cy - b->cy) < 0.5 * fmax(f.r, b->r) &&
            fabs(f.r - b->r) < 0.1 * fmax(f.r, b->r)) {
            if (f.coverage > b->coverage)
                fl->balls[j] = f; /* the same ball, better fitted */
            return;
        }
        if (inside(&f, b))
            return; /* a round reflection in a ball */
    }
    for (int j = 0; j < fl->nothers; j++)
        if (inside(&f, &fl->others[j]) || hypot(f.cx - fl->others[j].cx, f.cy - fl->others[j].cy) <
                                              CONCENTRIC * fmax(f.r, fl->others[j].r))
            return; /* part of a disc, ring or dial seen before */
    double flat = flat_fraction(im, &f, 0.0, 0.9);
    bool ball = flat < FLAT_FRACTION && !is_ring(im, &f);
    if (!ball) {
        /* Only a clean outline hides what lies inside it. */
        if (f.support >= CLEAN_SUPPORT && fl->nothers < MAX_FOUND)
            fl->others[fl->nothers++] = f;
        return;
    }
    /* Balls seen before inside this one were its reflections. */
    int k = 0;
    for (int j = 0; j < fl->nballs; j++)
        if (!inside(&fl->balls[j], &f))
            fl->balls[k++] = fl->balls[j];
    fl->nballs = k;
    if (fl->nballs < MAX_FOUND)
        fl->balls[fl->nballs++] = f;
}

/* Circle candidates (x, y, r) on the copy, OpenCV's pixel centres on
 * integers: the accurate transform on the copy (on the half copy when the
 * smallest ball sought is HOUGH_MIN_R there), the classic one on copies of
 * half and a quarter its size (fine clutter averages out there, a ball
 * stays round, and the classic transform's time falls with the size),
 * interleaved. -1 when OpenCV failed. */
static int hough_levels(int w0, int h0, const unsigned char *gray, double min_r, double max_r,
                        bool alt_first, double edge_threshold, float *cand, int max_cand);

/* Local texture: the mean log-luminance step over 9x9 px, tonemapped.
 * Clutter is busy where a ball's reflection is smooth (and the reverse):
 * a ball as bright as the clutter around it still stands out here. */
static unsigned char *texture_map(const det_image *im)
{
    int w = im->w, h = im->h;
    float *e = calloc((size_t)w * h, sizeof *e), *tmp = calloc((size_t)w * h, sizeof *tmp);
    unsigned char *out = malloc((size_t)w * h);
    if (!e || !tmp || !out) {
        free(e);
        free(tmp);
        free(out);
        return NULL;
    }
    for (int y = 1; y < h - 1; y++)
        for (int x = 1; x < w - 1; x++) {
            const float *p = im->logl + (size_t)y * w + x;
            e[(size_t)y * w + x] = fabsf(p[1] - p[-1]) + fabsf(p[w] - p[-w]);
        }
    enum { R = 4 };
    for (int y = 0; y < h; y++) /* box blur: rows, then columns */
        for (int x = 0; x < w; x++) {
            double sum = 0.0;
            for (int k = -R; k <= R; k++)
                sum += e[(size_t)y * w + (x + k < 0 ? 0 : (x + k >= w ? w - 1 : x + k))];
            tmp[(size_t)y * w + x] = (float)(sum / (2 * R + 1));
        }
    float top = 0.0f;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double sum = 0.0;
            for (int k = -R; k <= R; k++)
                sum += tmp[(size_t)(y + k < 0 ? 0 : (y + k >= h ? h - 1 : y + k)) * w + x];
            e[(size_t)y * w + x] = (float)(sum / (2 * R + 1));
            top = fmaxf(top, e[(size_t)y * w + x]);
        }
    for (size_t i = 0; i < (size_t)w * h; i++)
        out[i] = (unsigned char)(top > 0.0f ? 255.0f * sqrtf(e[i] / top) + 0.5f : 0.0f);
    free(e);
    free(tmp);
    return out;
}

/* Candidates from the tonemapped copy and from its texture map, alternated. */
static int hough_candidates(const det_image *im, const unsigned char *gray, double min_r,
                            double max_r, float *cand)
{
    enum { HALF = MAX_CANDIDATES / 2 };
    float a[3 * HALF], b[3 * HALF];
    int na = hough_levels(im->w, im->h, gray, min_r, max_r, true, 100.0, a, HALF);
    unsigned char *tex = texture_map(im);
    if (!tex)
        return -1;
    /* the texture's edges are soft (a 9 px average) */
    int nb = hough_levels(im->w, im->h, tex, min_r, max_r, false, 30.0, b, HALF);
    free(tex);
    if (na < 0 || nb < 0)
        return -1;
    int n = 0;
    for (int i = 0; i < na || i < nb; i++) {
        if (i < na)
            memcpy(cand + 3 * n++, a + 3 * i, 3 * sizeof *cand);
        if (i < nb)
            memcpy(cand + 3 * n++, b + 3 * i, 3 * sizeof *cand);
    }
    return n;
}

static int hough_levels(int w0, int h0, const unsigned char *gray, double min_r, double max_r,
                        bool alt_first, double edge_threshold, float *cand, int max_cand)
{
    enum { LEVELS = 3, PER = MAX_CANDIDATES / LEVELS, ASK = 4 * PER };
    float found[LEVELS][3 * ASK];
    int count[LEVELS] = {0};
    unsigned char *level = malloc((size_t)w0 * h0);
    if (!level)
        return -1;
    memcpy(level, gray, (size_t)w0 * h0);
    int w = w0, h = h0;
    int first = min_r / 2.0 >= HOUGH_MIN_R ? 1 : 0;
    for (int l = 0; l < LEVELS; l++) {
        int scale = 1 << l;
        if (l > 0) { /* halve in place */
            int hw = w / 2, hh = h / 2;
            for (int y = 0; y < hh; y++)
                for (int x = 0; x < hw; x++) {
                    const unsigned char *p = level + (size_t)2 * y * w + 2 * x;
                    level[(size_t)y * hw + x] = (unsigned char)((p[0] + p[1] + p[w] + p[w + 1] + 2) / 4);
                }
            w = hw;
            h = hh;
        }
        if (max_r / scale < 4.0 || w < 16 || h < 16 || l < first || (l == 0 && !alt_first))
            continue;
        /* The tonemap: the accurate transform at the finest level, the
         * classic one below it; the texture map (soft): both, from the half
         * copy down. Centres only 4 px apart on the copy: a clutter peak
         * must not hide the ball's. */
        int kinds = BALL_HOUGH_CLASSIC | BALL_HOUGH_ALT;
        if (alt_first && l == 0)
            kinds = BALL_HOUGH_ALT;
        else if (alt_first && l > first)
            kinds = BALL_HOUGH_CLASSIC;
        count[l] = ball_hough_cxx(level, w, h, fmax(3.0, min_r / scale), max_r / scale,
                                  fmax(1.0, 4.0 / scale), kinds, edge_threshold, found[l], ASK);
        if (count[l] < 0) {
            free(level);
            return -1;
        }
        /* A strong round thing draws many near copies of itself: one kept
         * per centre, so the cap leaves room for the others. */
        int kept = 0;
        for (int i = 0; i < count[l] && kept < PER; i++) {
            /* a level's pixel centre x + 0.5 is scale (x + 0.5) on the copy */
            float x = scale * (found[l][3 * i] + 0.5f) - 0.5f;
            float y = scale * (found[l][3 * i + 1] + 0.5f) - 0.5f, r = found[l][3 * i + 2] * scale;
            bool copy = false;
            for (int j = 0; j < kept && !copy; j++)
                copy = hypotf(x - found[l][3 * j], y - found[l][3 * j + 1]) <
                       4.0f + 0.1f * fminf(r, found[l][3 * j + 2]);
            if (copy)
                continue;
            found[l][3 * kept] = x;
            found[l][3 * kept + 1] = y;
            found[l][3 * kept + 2] = r;
            kept++;
        }
        count[l] = kept;
    }
    free(level);
    int n = 0;
    for (int i = 0; i < PER; i++)
        for (int l = 0; l < LEVELS; l++)
            if (i < count[l] && n < max_cand) {
                memcpy(cand + 3 * n, found[l] + 3 * i, 3 * sizeof *cand);
                n++;
            }
    return n;
}

static bool is_cut(const fit *b, int width, int height)
{
    return b->cx - b->r < -CLIP_TOLERANCE || b->cy - b->r < -CLIP_TOLERANCE ||
           b->cx + b->r > width + CLIP_TOLERANCE || b->cy + b->r > height + CLIP_TOLERANCE;
}

/* The largest ball found so far that the frame does not cut, or NULL. */
static const fit *largest_whole(const found_list *fl, int width, int height)
{
    const fit *best = NULL;
    for (int j = 0; j < fl->nballs; j++)
        if (!is_cut(&fl->balls[j], width, height) && (!best || fl->balls[j].r > best->r))
            best = &fl->balls[j];
    return best;
}

/* The farthest point from (x, y) of the centres where a whole circle of
 * radius rho fits in the frame; -1 when none does. */
static double farthest_centre(double x, double y, double rho, int width, int height)
{
    double x0 = rho - CLIP_TOLERANCE, x1 = width - rho + CLIP_TOLERANCE;
    double y0 = rho - CLIP_TOLERANCE, y1 = height - rho + CLIP_TOLERANCE;
    if (x0 > x1 || y0 > y1)
        return -1.0;
    return hypot(fmax(fabs(x - x0), fabs(x - x1)), fmax(fabs(y - y0), fabs(y - y1)));
}

/* Whether the frame has room for a ball that would change the answer
 * given the whole ball b: one about as large elsewhere (it would be the
 * probe, b its reflection or a lesser object) or one of RIVAL_FLOOR of its
 * radius beside it (a rival). A ball filling a tight crop leaves none, and
 * then the Hough passes can find nothing that matters. */
static bool room_for_another(const fit *b, int width, int height)
{
    double large = 0.9 * b->r, rival = RIVAL_FLOOR * b->r;
    return farthest_centre(b->cx, b->cy, large, width, height) > 0.5 * b->r ||
           farthest_centre(b->cx, b->cy, rival, width, height) > b->r + 0.9 * rival;
}

/* The Hough candidates (and the frame's centre again), each with the best
 * radii along rays from it and the transform's own, fitted and filed. A
 * whole ball found bounds what is worth searching for: nothing under
 * RIVAL_FLOOR of its radius, nothing at all when it fills the frame.
 * -1 when OpenCV failed. */
static int search_candidates(const search *sc, const unsigned char *gray, double max_r)
{
    const det_image *im = sc->work;
    found_list *fl = sc->found;
    int width = sc->full->w, height = sc->full->h, factor = sc->factor;
    double fx = 0.5 * im->w, fy = 0.5 * im->h, floor_r = sc->min_r;
    const fit *known = largest_whole(fl, width, height);
    if (known && !room_for_another(known, width, height))
        return 0;
    if (known)
        floor_r = fmax(floor_r, RIVAL_FLOOR * known->r / factor);
    float cand[3 * MAX_CANDIDATES];
    int nc = hough_candidates(im, gray, floor_r, max_r, cand);
    if (nc < 0)
        return -1;
    double tried[MAX_CANDIDATES + 1][2] = {{fx, fy}};
    int nt = 1;
    for (int i = -1; i < nc; i++) {
        /* OpenCV puts pixel centres on integers. */
        double cx = i < 0 ? fx : cand[3 * i] + 0.5, cy = i < 0 ? fy : cand[3 * i + 1] + 0.5;
        bool seen = false;
        for (int t = i < 0 ? nt : 0; t < nt; t++)
            if (hypot(cx - tried[t][0], cy - tried[t][1]) < 3.0)
                seen = true;
        if (seen)
            continue;
        if (i >= 0) {
            tried[nt][0] = cx;
            tried[nt][1] = cy;
            nt++;
        }
        /* A Hough circle inside a ball is a reflection; inside a disc, ring
         * or dial, part of it. */
        fit hc = {.cx = cx * factor, .cy = cy * factor, .r = i < 0 ? 0.0 : cand[3 * i + 2] * factor};
        bool within = false;
        for (int j = 0; j < fl->nballs && !within; j++)
            within = inside(&hc, &fl->balls[j]);
        for (int j = 0; j < fl->nothers && !within; j++)
            within = inside(&hc, &fl->others[j]);
        if (within)
            continue;
        if ((known = largest_whole(fl, width, height)))
            floor_r = fmax(floor_r, RIVAL_FLOOR * known->r / factor);
        /* The transform's own radius too: its centre may be a few pixels
         * off, which blurs the search's radius profile. */
        double radii[4];
        int nrad = radius_search(im, cx, cy, floor_r, max_r, radii);
        if (i >= 0)
            radii[nrad++] = cand[3 * i + 2];
        for (int k = 0; k < nrad; k++)
            if (radii[k] >= floor_r)
                consider(sc, cx, cy, radii[k], k < nrad - (i >= 0) ? 0.05 : 0.12);
    }
    return nc;
}

static int cmp_radius(const void *a, const void *b)
{
    double x = ((const fit *)a)->r, y = ((const fit *)b)->r;
    return x > y ? -1 : x < y;
}

sl_result sl_ball_detect(const sl_image *photo, const char *name, sl_ball_circle *circle,
                         sl_error *err)
{
    memset(circle, 0, sizeof *circle);
    if (!name)
        name = "image";
    if (!photo || photo->width < 16 || photo->height < 16)
        return sl_error_set(err, SL_ERR_INPUT, "%s: too small to hold a chrome ball", name);
    det_image full = {0}, im = {0};
    unsigned char *gray = NULL;
    found_list *fl = calloc(1, sizeof *fl);
    if (!fl)
        return sl_error_set(err, SL_ERR_NOMEM, "ball detection: out of memory");
    sl_result r = full_image(photo, &full, err);
    if (r)
        goto done;
    int big = photo->width > photo->height ? photo->width : photo->height;
    int factor = (big + WORK_SIZE - 1) / WORK_SIZE;
    if ((r = work_image(&full, factor, &im, &gray, err)))
        goto done;
    int small = im.w < im.h ? im.w : im.h, wbig = im.w > im.h ? im.w : im.h;
    double min_r = small / 10.0 > 6.0 ? small / 10.0 : 6.0;
    search sc = {&im, &full, factor, min_r, fl};
    /* The frame first: a tight crop's ball touches its four sides. */
    consider_frame(&sc, 0.5 * small);
    consider_frame(&sc, 0.5 * wbig);
    if (search_candidates(&sc, gray, 0.6 * wbig) < 0) {
        r = sl_error_set(err, SL_ERR_INTERNAL, "%s: OpenCV circle detection failed", name);
        goto done;
    }
    int nf = fl->nballs;
    if (nf == 0) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: no chrome ball found (give its outline with --circle cx,cy,r)",
                         name);
        goto done;
    }
    /* A ball cut by the frame is reported only when no whole one is found. */
    int whole = 0;
    for (int j = 0; j < nf; j++)
        if (!is_cut(&fl->balls[j], photo->width, photo->height)) {
            fit t = fl->balls[whole];
            fl->balls[whole++] = fl->balls[j];
            fl->balls[j] = t;
        }
    if (whole)
        nf = whole;
    /* The largest ball is the probe; a rival is nearly as large and nearly
     * as well supported (small circles meet chance edges in clutter). */
    qsort(fl->balls, (size_t)nf, sizeof *fl->balls, cmp_radius);
    fit *b = &fl->balls[0];
    int rivals = 0;
    for (int j = 1; j < nf && whole; j++)
        if (fl->balls[j].r >= SMALLER_BALL_RATIO * b->r &&
            fl->balls[j].support >= SECOND_BALL_RATIO * b->support &&
            /* two balls do not overlap: that is an arc of reflection */
            hypot(fl->balls[j].cx - b->cx, fl->balls[j].cy - b->cy) >
                b->r + 0.9 * fl->balls[j].r)
            fl->balls[1 + rivals++] = fl->balls[j];
    if (rivals) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: %d balls found (%.1f,%.1f r %.1f and %.1f,%.1f r %.1f); crop to "
                         "one or give --circle",
                         name, rivals + 1, b->cx, b->cy, b->r, fl->balls[1].cx, fl->balls[1].cy,
                         fl->balls[1].r);
        goto done;
    }
    circle->cx = b->cx;
    circle->cy = b->cy;
    circle->r = b->r;
    circle->residual = b->rms;
    circle->edge_points = b->inliers;
    circle->uncertainty = b->sd;
    if (is_cut(b, photo->width, photo->height)) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: the ball at %.1f,%.1f r %.1f is cut by the frame edge; a clipped "
                         "ball cannot be unwrapped",
                         name, b->cx, b->cy, b->r);
        goto done;
    }
    if (!(b->sd <= fmax(WEAK_SD, WEAK_SD_PER_RADIUS * b->r))) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: the ball's outline at %.1f,%.1f r %.1f fits only weakly (standard "
                         "error %.2f px); give it with --circle cx,cy,r",
                         name, b->cx, b->cy, b->r, b->sd);
        goto done;
    }
    /* Within the tolerance: the fit may graze the edge; keep it inside. */
    circle->r = fmin(b->r, fmin(fmin(b->cx, b->cy), fmin(photo->width - b->cx,
                                                          photo->height - b->cy)));
done:
    det_free(&full);
    det_free(&im);
    free(gray);
    free(fl);
    return r;
}
