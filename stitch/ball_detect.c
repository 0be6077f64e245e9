/* SPDX-License-Identifier: BSD-3-Clause */
/* Chrome-ball detection: Hough candidates on a log-tonemapped 8-bit copy,
 * then per candidate sub-pixel edge points on the HDR image along rays from
 * its centre (strongest log-luminance step, then the 50% crossing of the
 * linear luminance, which is where an anti-aliased or blurred step edge
 * really is) and a robust geometric least-squares circle fit. A candidate is
 * a ball when most rays find an edge on the fitted circle. */
#include "unwrap_private.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define MAX_CANDIDATES 128
/* Fraction of in-frame rays with an edge on the circle. Measured: synthetic
 * balls 0.65-0.8, the real iPhone probes 0.59-0.61, clutter coincidences
 * at most 0.37. */
#define MIN_SUPPORT 0.5
#define CLIP_TOLERANCE 1.0 /* px the circle may pass the frame edge (fit error) */
/* Edge points within this many px of the fitted circle count as support:
 * clutter puts an edge somewhere near any circle, but not on it. */
#define SUPPORT_TOLERANCE 1.0
#define SUPPORT_PER_RADIUS 120.0
#define EDGE_HALF 1.5 /* px each side of an edge for its centroid */
#define SECOND_BALL_RATIO 0.8
#define INLIER_MIN 0.5 /* robust-fit inlier band (px), from 3 sigma clamped to these */
#define INLIER_MAX 2.0

typedef struct det_image {
    int w, h;
    float *lum;  /* linear luminance */
    float *logl; /* log(lum + eps) */
} det_image;

typedef struct fit {
    double cx, cy, r, rms;
    int inliers;
    double support;
} fit;

static double bilinear(const det_image *im, const float *p, double x, double y)
{
    double fx = x - 0.5, fy = y - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    int x1 = x0 + 1, y1 = y0 + 1;
    x0 = x0 < 0 ? 0 : (x0 >= im->w ? im->w - 1 : x0);
    x1 = x1 < 0 ? 0 : (x1 >= im->w ? im->w - 1 : x1);
    y0 = y0 < 0 ? 0 : (y0 >= im->h ? im->h - 1 : y0);
    y1 = y1 < 0 ? 0 : (y1 >= im->h ? im->h - 1 : y1);
    double a = p[(size_t)y0 * im->w + x0] * (1 - tx) + p[(size_t)y0 * im->w + x1] * tx;
    double b = p[(size_t)y1 * im->w + x0] * (1 - tx) + p[(size_t)y1 * im->w + x1] * tx;
    return a * (1 - ty) + b * ty;
}

static bool in_frame(const det_image *im, double x, double y)
{
    return x >= 0.5 && y >= 0.5 && x <= im->w - 0.5 && y <= im->h - 0.5;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
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

/* Sub-pixel edge along one ray, searched in [r - win, r + win]. */
static bool ray_edge(const det_image *im, double cx, double cy, double r, double win, double dx,
                     double dy, ball_point *out)
{
    double lo = r - win, hi = r + win;
    if (lo < 1.0)
        lo = 1.0;
    /* The window may end at the frame; the circle itself may not. */
    while (hi > lo && !in_frame(im, cx + (hi + EDGE_HALF + 0.5) * dx, cy + (hi + EDGE_HALF + 0.5) * dy))
        hi -= 0.25;
    if (hi < r + 1.0)
        return false;
    if (!in_frame(im, cx + (lo - EDGE_HALF - 0.5) * dx, cy + (lo - EDGE_HALF - 0.5) * dy))
        return false;
    double best = -1.0, best_s = 0.0;
    for (double s = lo; s <= hi; s += 0.25) {
        double g = bilinear(im, im->logl, cx + (s + 0.5) * dx, cy + (s + 0.5) * dy) -
                   bilinear(im, im->logl, cx + (s - 0.5) * dx, cy + (s - 0.5) * dy);
        if (fabs(g) > best) {
            best = fabs(g);
            best_s = s;
        }
    }
    if (best < 0.05) /* under 5% contrast per pixel: no edge here */
        return false;
    /* Centroid of the linear-luminance step across the edge: exact for a
     * box-filtered (anti-aliased) step edge, and blind to the log bias. */
    double s_edge = best_s;
    for (int pass = 0; pass < 2; pass++) {
        double m0 = 0.0, m1 = 0.0, sign = 0.0;
        double prev = bilinear(im, im->lum, cx + (s_edge - EDGE_HALF) * dx,
                               cy + (s_edge - EDGE_HALF) * dy);
        double last = bilinear(im, im->lum, cx + (s_edge + EDGE_HALF) * dx,
                               cy + (s_edge + EDGE_HALF) * dy);
        sign = prev >= last ? 1.0 : -1.0;
        for (double s = s_edge - EDGE_HALF + 0.125; s < s_edge + EDGE_HALF; s += 0.125) {
            double cur = bilinear(im, im->lum, cx + s * dx, cy + s * dy);
            double d = sign * (prev - cur);
            if (d > 0.0) {
                m0 += d;
                m1 += d * (s - 0.0625);
            }
            prev = cur;
        }
        if (m0 > 0.0)
            s_edge = m1 / m0;
    }
    out->x = cx + s_edge * dx;
    out->y = cy + s_edge * dy;
    return true;
}

/* Edge points around (cx, cy, r), then a robust fit; f gets the result. */
static bool refine(const det_image *im, double cx, double cy, double r, double win, int max_rays,
                   fit *f)
{
    memset(f, 0, sizeof *f);
    int n = (int)lround(2.0 * M_PI * r / 1.5);
    n = n < 48 ? 48 : (n > max_rays ? max_rays : n);
    ball_point *pts = malloc((size_t)n * sizeof *pts);
    bool *use = malloc((size_t)n * sizeof *use);
    double *res = malloc((size_t)n * sizeof *res);
    bool ok = false;
    if (!pts || !use || !res)
        goto done;
    int m = 0;
    for (int i = 0; i < n; i++) {
        double a = 2.0 * M_PI * (i + 0.5) / n;
        if (ray_edge(im, cx, cy, r, win, cos(a), sin(a), &pts[m]))
            m++;
    }
    double c[3] = {cx, cy, r};
    for (int i = 0; i < m; i++)
        use[i] = true;
    for (int pass = 0; pass < 4; pass++) {
        if (!ball_circle_fit(pts, use, m, c))
            goto done;
        for (int i = 0; i < m; i++)
            res[i] = fabs(hypot(pts[i].x - c[0], pts[i].y - c[1]) - c[2]);
        double *sorted = malloc((size_t)m * sizeof *sorted);
        if (!sorted)
            goto done;
        memcpy(sorted, res, (size_t)m * sizeof *sorted);
        qsort(sorted, (size_t)m, sizeof *sorted, cmp_double);
        double limit = 3.0 * 1.4826 * sorted[m / 2];
        free(sorted);
        limit = limit < INLIER_MIN ? INLIER_MIN : (limit > INLIER_MAX ? INLIER_MAX : limit);
        for (int i = 0; i < m; i++)
            use[i] = res[i] <= limit;
    }
    /* A circle fit of a real outline scatters more as the ball grows: the
     * perspective ellipse (axes differ by ~r (1/cos(off-axis) - 1)), lens
     * distortion and texture next to the rim all scale with the radius. */
    double tol = fmax(SUPPORT_TOLERANCE, c[2] / SUPPORT_PER_RADIUS);
    double ss = 0.0;
    for (int i = 0; i < m; i++)
        if (use[i] && res[i] <= tol) {
            ss += res[i] * res[i];
            f->inliers++;
        }
    f->cx = c[0];
    f->cy = c[1];
    f->r = c[2];
    f->rms = f->inliers ? sqrt(ss / f->inliers) : 0.0;
    f->support = (double)f->inliers / n; /* over all rays: a circle mostly off the frame has little */
    ok = f->inliers >= 24;
done:
    free(pts);
    free(use);
    free(res);
    return ok;
}

/* Hough's radius for a centre is often a clutter ring. Along rays from the
 * centre, the ball's outline is an edge at the same radius on most rays,
 * clutter edges are not: score each radius by the median over rays of the
 * log-luminance step there (max-filtered by 3 px for the centre's error) and
 * return the best three radii at least 10 px apart. */
static int radius_search(const det_image *im, double cx, double cy, double rmin, double rmax,
                         double out[3])
{
    enum { RAYS = 90 };
    const double step = 0.5;
    int nr = (int)((rmax - rmin) / step) + 1;
    if (nr < 3)
        return 0;
    float *g = malloc(sizeof(float) * RAYS * (size_t)nr);
    float *col = malloc(sizeof(float) * RAYS);
    double *score = malloc(sizeof(double) * (size_t)nr);
    int found = 0;
    if (!g || !col || !score)
        goto done;
    for (int a = 0; a < RAYS; a++) {
        double ang = 2.0 * M_PI * (a + 0.5) / RAYS, dx = cos(ang), dy = sin(ang);
        float *row = g + (size_t)a * nr;
        for (int j = 0; j < nr; j++) {
            double s = rmin + j * step;
            if (!in_frame(im, cx + (s + 0.5) * dx, cy + (s + 0.5) * dy)) {
                row[j] = -1.0f; /* outside the frame */
                continue;
            }
            row[j] = (float)fabs(bilinear(im, im->logl, cx + (s + 0.5) * dx, cy + (s + 0.5) * dy) -
                                 bilinear(im, im->logl, cx + (s - 0.5) * dx, cy + (s - 0.5) * dy));
        }
    }
    for (int j = 0; j < nr; j++) {
        int m = 0;
        for (int a = 0; a < RAYS; a++) {
            const float *row = g + (size_t)a * nr;
            if (row[j] < 0.0f)
                continue;
            float best = 0.0f;
            for (int k = j - 6; k <= j + 6; k++)
                if (k >= 0 && k < nr && row[k] > best)
                    best = row[k];
            col[m++] = best;
        }
        if (m < RAYS / 3) {
            score[j] = 0.0;
            continue;
        }
        /* median by partial insertion: m <= 90 */
        for (int i = 1; i < m; i++) {
            float v = col[i];
            int k = i - 1;
            while (k >= 0 && col[k] > v) {
                col[k + 1] = col[k];
                k--;
            }
            col[k + 1] = v;
        }
        score[j] = col[m / 2];
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
    return found;
}

static sl_result build_images(const sl_image *photo, det_image *im, unsigned char **gray,
                              sl_error *err)
{
    size_t n = (size_t)photo->width * photo->height;
    im->w = photo->width;
    im->h = photo->height;
    im->lum = malloc(n * sizeof(float));
    im->logl = malloc(n * sizeof(float));
    *gray = malloc(n);
    size_t ns = n < 65536 ? n : 65536;
    double *sample = malloc(ns * sizeof(double));
    if (!im->lum || !im->logl || !*gray || !sample) {
        free(sample);
        return sl_error_set(err, SL_ERR_NOMEM, "ball detection: out of memory");
    }
    for (int y = 0; y < photo->height; y++)
        for (int x = 0; x < photo->width; x++) {
            const float *p = sl_image_pixel(photo, x, y);
            double l = photo->channels >= 3 ? 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
                                            : p[0];
            im->lum[(size_t)y * photo->width + x] = isfinite(l) && l > 0.0 ? (float)l : 0.0f;
        }
    for (size_t i = 0; i < ns; i++)
        sample[i] = im->lum[i * (n / ns)];
    qsort(sample, ns, sizeof *sample, cmp_double);
    double eps = fmax(1e-3 * sample[ns / 2], 1e-4 * sample[ns - 1]);
    if (!(eps > 0.0))
        eps = 1e-9;
    for (size_t i = 0; i < n; i++)
        im->logl[i] = (float)log(im->lum[i] + eps);
    for (size_t i = 0; i < ns; i++)
        sample[i] = im->logl[i * (n / ns)];
    qsort(sample, ns, sizeof *sample, cmp_double);
    double lo = sample[ns / 100], hi = sample[ns - 1 - ns / 200];
    free(sample);
    double scale = hi > lo ? 255.0 / (hi - lo) : 1.0;
    for (size_t i = 0; i < n; i++) {
        double g = (im->logl[i] - lo) * scale;
        (*gray)[i] = (unsigned char)(g < 0.0 ? 0.0 : (g > 255.0 ? 255.0 : g + 0.5));
    }
    return SL_OK;
}

static int cmp_support(const void *a, const void *b)
{
    double x = ((const fit *)a)->support, y = ((const fit *)b)->support;
    return x > y ? -1 : x < y;
}

/* Fits one candidate; a ball is added to found[], merged with the same ball
 * found before or with a round reflection inside it (the better supported
 * outline stays). */
static void consider(const det_image *im, double cx, double cy, double r, fit *found, int *nf)
{
    fit f;
    /* A quick look with few rays first; most candidates end there. */
    if (!refine(im, cx, cy, r, fmax(3.0, 0.05 * r), 128, &f) || f.support < 0.4 * MIN_SUPPORT ||
        !refine(im, f.cx, f.cy, f.r, 3.0, 1024, &f) || f.support < MIN_SUPPORT)
        return;
    for (int j = 0; j < *nf; j++) {
        double d = hypot(f.cx - found[j].cx, f.cy - found[j].cy);
        double rs = fmin(f.r, found[j].r), rb = fmax(f.r, found[j].r);
        if (d < 0.5 * rb || d + rs < rb + 2.0) {
            if (f.support > found[j].support)
                found[j] = f;
            return;
        }
    }
    found[(*nf)++] = f;
}

sl_result sl_ball_detect(const sl_image *photo, const char *name, sl_ball_circle *circle,
                         sl_error *err)
{
    memset(circle, 0, sizeof *circle);
    if (!name)
        name = "image";
    if (!photo || photo->width < 16 || photo->height < 16)
        return sl_error_set(err, SL_ERR_INPUT, "%s: too small to hold a chrome ball", name);
    det_image im = {0};
    unsigned char *gray = NULL;
    sl_result r = build_images(photo, &im, &gray, err);
    if (r)
        goto done;
    int small = photo->width < photo->height ? photo->width : photo->height;
    int big = photo->width > photo->height ? photo->width : photo->height;
    double min_r = small / 10.0 > 6.0 ? small / 10.0 : 6.0;
    float cand[3 * MAX_CANDIDATES];
    /* Centres only 4 px apart: a clutter peak must not hide the ball's. */
    int nc = ball_hough_cxx(gray, photo->width, photo->height, min_r, 0.6 * big, 4.0, cand,
                            MAX_CANDIDATES);
    if (nc < 0) {
        r = sl_error_set(err, SL_ERR_INTERNAL, "%s: OpenCV circle detection failed", name);
        goto done;
    }
    fit found[3 * MAX_CANDIDATES];
    double tried[MAX_CANDIDATES][2];
    int nf = 0, nt = 0;
    for (int i = 0; i < nc; i++) {
        /* OpenCV puts pixel centres on integers. */
        double cx = cand[3 * i] + 0.5, cy = cand[3 * i + 1] + 0.5;
        bool seen = false;
        for (int t = 0; t < nt; t++)
            if (hypot(cx - tried[t][0], cy - tried[t][1]) < 3.0)
                seen = true;
        if (seen)
            continue;
        tried[nt][0] = cx;
        tried[nt][1] = cy;
        nt++;
        double radii[3];
        int nrad = radius_search(&im, cx, cy, min_r, 0.6 * big, radii);
        for (int k = 0; k < nrad; k++)
            consider(&im, cx, cy, radii[k], found, &nf);
    }
    /* Best supported first; a second outline counts as a ball only when it is
     * nearly as well supported (small circles meet chance edges in clutter). */
    qsort(found, (size_t)nf, sizeof *found, cmp_support);
    while (nf > 1 && found[nf - 1].support < SECOND_BALL_RATIO * found[0].support)
        nf--;
    if (nf == 0) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: no chrome ball found (give its outline with --circle cx,cy,r)",
                         name);
        goto done;
    }
    if (nf > 1) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: %d balls found (%.1f,%.1f r %.1f and %.1f,%.1f r %.1f); crop to "
                         "one or give --circle",
                         name, nf, found[0].cx, found[0].cy, found[0].r, found[1].cx,
                         found[1].cy, found[1].r);
        goto done;
    }
    fit *b = &found[0];
    circle->cx = b->cx;
    circle->cy = b->cy;
    circle->r = b->r;
    circle->residual = b->rms;
    circle->edge_points = b->inliers;
    if (b->cx - b->r < -CLIP_TOLERANCE || b->cy - b->r < -CLIP_TOLERANCE ||
        b->cx + b->r > photo->width + CLIP_TOLERANCE ||
        b->cy + b->r > photo->height + CLIP_TOLERANCE) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: the ball at %.1f,%.1f r %.1f is cut by the frame edge; a clipped "
                         "ball cannot be unwrapped",
                         name, b->cx, b->cy, b->r);
        goto done;
    }
    /* Within the tolerance: the fit may graze the edge; keep it inside. */
    circle->r = fmin(b->r, fmin(fmin(b->cx, b->cy), fmin(photo->width - b->cx,
                                                          photo->height - b->cy)));
done:
    free(im.lum);
    free(im.logl);
    free(gray);
    return r;
}
