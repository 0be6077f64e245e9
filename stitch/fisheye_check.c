/* SPDX-License-Identifier: BSD-3-Clause */
/* Is this round image a circular fisheye photo? A fisheye lens draws its
 * image circle on a frame that stays black around it, with a dark band on
 * every side (the circle is smaller than the frame), and its light falls
 * off toward the circle's edge (vignetting). A chrome ball sits in the set
 * (the frame around it is the scene, not black), and the round images that
 * are dark outside on purpose (angular maps, mirror-ball maps) fill their
 * square frame edge to edge. Works on a copy at most 400 px across: the
 * evidence is large-scale. */
#include "unwrap_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define WORK_SIZE 400
#define RAYS 180
/* The frame's border is black: its 90th percentile under this fraction of
 * the disc centre's median (measured: fisheye JPEGs 0.005-0.008, a
 * simulated fisheye 0.07; ball crops 2-10). */
#define BORDER_DARK 0.15
#define OUTSIDE_DARK 0.95  /* fraction of the frame beyond the disc that is dark */
#define MIN_MARGIN 0.02    /* dark band on every side, in disc radii (measured 0.06-0.09) */
#define RIM_BRIGHT 1.5     /* a ball's Fresnel rim is brighter than its inside */
#define MIN_ROUND 0.6      /* fraction of rays whose edge is on the fitted circle */

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

static float quantile(float *v, size_t n, double q)
{
    if (!n)
        return 0.0f;
    qsort(v, n, sizeof *v, cmp_float);
    size_t i = (size_t)(q * (double)(n - 1) + 0.5);
    return v[i];
}

typedef struct small_image {
    int w, h;
    float *lum;
} small_image;

static double lum_at(const small_image *s, double x, double y)
{
    int ix = (int)floor(x), iy = (int)floor(y);
    ix = ix < 0 ? 0 : (ix >= s->w ? s->w - 1 : ix);
    iy = iy < 0 ? 0 : (iy >= s->h ? s->h - 1 : iy);
    return s->lum[(size_t)iy * s->w + ix];
}

/* Luminance box-averaged down to at most WORK_SIZE px across. */
static sl_result shrink(const sl_image *photo, bool srgb, small_image *s, int *factor,
                        sl_error *err)
{
    int big = photo->width > photo->height ? photo->width : photo->height;
    int f = (big + WORK_SIZE - 1) / WORK_SIZE;
    s->w = photo->width / f;
    s->h = photo->height / f;
    s->lum = calloc((size_t)s->w * s->h, sizeof(float));
    if (!s->lum)
        return sl_error_set(err, SL_ERR_NOMEM, "fisheye check: out of memory");
    for (int y = 0; y < s->h * f; y++)
        for (int x = 0; x < s->w * f; x++) {
            const float *p = sl_image_pixel(photo, x, y);
            double c[3];
            for (int k = 0; k < 3; k++) {
                double v = p[photo->channels >= 3 ? k : 0];
                c[k] = srgb ? sl_srgb_to_linear((float)v) : v;
            }
            double l = sl_luminance(c);
            s->lum[(size_t)(y / f) * s->w + x / f] += isfinite(l) && l > 0.0 ? (float)l : 0.0f;
        }
    for (size_t i = 0; i < (size_t)s->w * s->h; i++)
        s->lum[i] /= (float)(f * f);
    *factor = f;
    return SL_OK;
}

/* The bright disc: along rays from the frame centre, walking in from the
 * frame's edge, the first sample above `level`; a robust circle through
 * those points. False when they do not make a circle. */
static bool find_disc(const small_image *s, double level, double c[3])
{
    ball_point pts[RAYS];
    bool use[RAYS];
    int n = 0;
    double cx = 0.5 * s->w, cy = 0.5 * s->h, half = 0.5 * (s->w < s->h ? s->w : s->h);
    for (int i = 0; i < RAYS; i++) {
        double a = 2.0 * M_PI * (i + 0.5) / RAYS, dx = cos(a), dy = sin(a);
        /* distance to the frame's edge along the ray */
        double tx = dx > 0 ? (s->w - cx) / dx : (dx < 0 ? -cx / dx : 1e30);
        double ty = dy > 0 ? (s->h - cy) / dy : (dy < 0 ? -cy / dy : 1e30);
        double t = fmin(tx, ty) - 0.5;
        for (; t > 0.2 * half; t -= 0.5)
            if (lum_at(s, cx + t * dx, cy + t * dy) >= level)
                break;
        if (t > 0.2 * half) {
            pts[n].x = cx + t * dx;
            pts[n].y = cy + t * dy;
            n++;
        }
    }
    if (n < MIN_ROUND * RAYS)
        return false;
    c[0] = cx;
    c[1] = cy;
    c[2] = half;
    for (int i = 0; i < n; i++)
        use[i] = true;
    int inliers = 0;
    for (int pass = 0; pass < 4; pass++) {
        if (!ball_circle_fit(pts, use, n, c))
            return false;
        double tol = fmax(1.5, 0.02 * c[2]);
        inliers = 0;
        for (int i = 0; i < n; i++) {
            use[i] = fabs(hypot(pts[i].x - c[0], pts[i].y - c[1]) - c[2]) <= tol;
            inliers += use[i];
        }
    }
    return inliers >= MIN_ROUND * RAYS;
}

/* Median over rays of the mean luminance in [a, b] radii of the disc. */
static double ring_mean(const small_image *s, const double c[3], double a, double b,
                        float *per_ray)
{
    for (int i = 0; i < RAYS; i++) {
        double ang = 2.0 * M_PI * (i + 0.5) / RAYS, sum = 0.0;
        int m = 0;
        for (double t = a * c[2]; t <= b * c[2]; t += 0.5, m++)
            sum += lum_at(s, c[0] + t * cos(ang), c[1] + t * sin(ang));
        per_ray[i] = m ? (float)(sum / m) : 0.0f;
    }
    return quantile(per_ray, RAYS, 0.5);
}

/* A light-probe map (angular or mirror-ball, as published probes and
 * converters write them) is a disc inscribed in its square frame with every
 * pixel beyond it black: remapping leaves nothing there. A photo of a ball,
 * even cropped to the ball, shows the set in the corners. */
#define MAP_SQUARE 0.01    /* |width - height| within this of the size */
#define MAP_BLACK 1e-5     /* black: luminance under this of the disc's median */
/* Fraction of the corners that is black: Debevec's probes sign a corner
 * (measured: Grace 0.976). */
#define MAP_CORNERS 0.9
#define MAP_FILLED 0.9     /* fraction of the disc's outer ring that is not */

static double pixel_luminance(const sl_image *img, int x, int y)
{
    const float *p = sl_image_pixel(img, x, y);
    return img->channels >= 3 ? sl_luminance_px(p) : p[0];
}

/* Row y's pixels whose centres lie within radius r of (cx, cy): [lo, hi). */
static void chord(double cx, double cy, double r, int w, int y, int *lo, int *hi)
{
    double dy = y + 0.5 - cy, half = dy * dy < r * r ? sqrt(r * r - dy * dy) : -1.0;
    *lo = (int)fmax(0.0, fmin(w, ceil(cx - half - 0.5)));
    *hi = (int)fmax(*lo, fmin(w, floor(cx + half - 0.5) + 1.0));
}

static sl_result probe_map(const sl_image *photo, bool *is_map, sl_error *err)
{
    *is_map = false;
    int w = photo ? photo->width : 0, h = photo ? photo->height : 0;
    if (w < 16 || h < 16 || abs(w - h) > fmax(1.0, MAP_SQUARE * (w > h ? w : h)))
        return SL_OK;
    double cx = 0.5 * w, cy = 0.5 * h, r = 0.5 * (w < h ? w : h);
    /* Every pixel of a copy at most WORK_SIZE across would do, but the
     * corners' test must see single non-black pixels: sample the photo. */
    int step = (w > WORK_SIZE ? w / WORK_SIZE : 1);
    size_t disc_n = 0, cap = ((size_t)(w / step) + 1) * ((size_t)(h / step) + 1);
    float *disc = malloc(cap * sizeof *disc);
    if (!disc)
        return sl_error_set(err, SL_ERR_NOMEM, "probe map check: out of memory");
    for (int y = step / 2; y < h; y += step)
        for (int x = step / 2; x < w; x += step) {
            double d = hypot(x + 0.5 - cx, y + 0.5 - cy);
            if (d < 0.9 * r)
                disc[disc_n++] = (float)pixel_luminance(photo, x, y);
        }
    double median = quantile(disc, disc_n, 0.5);
    free(disc);
    if (!(median > 0.0))
        return SL_OK;
    double black = MAP_BLACK * median;
    /* The corners: per row, the pixels left and right of the circle's chord
     * (r plus a margin for its anti-aliased edge). Their count first, so
     * that a photo, whose corners show the set, stops at the first tenth
     * found lit. */
    double edge = fmax(1.5, 0.01 * r), outer = r + edge;
    size_t corners = 0, corners_lit = 0;
    for (int y = 0; y < h; y++) {
        int lo, hi;
        chord(cx, cy, outer, w, y, &lo, &hi);
        corners += (size_t)(lo + w - hi);
    }
    size_t lit_max = (size_t)((1.0 - MAP_CORNERS) * (double)corners);
    for (int y = 0; y < h && corners_lit <= lit_max; y++) {
        int lo, hi;
        chord(cx, cy, outer, w, y, &lo, &hi);
        /* NaN counts as nothing there */
        for (int x = 0; x < lo; x++)
            corners_lit += pixel_luminance(photo, x, y) > black;
        for (int x = hi; x < w; x++)
            corners_lit += pixel_luminance(photo, x, y) > black;
    }
    /* The disc's outer ring, 0.95-0.99 r, along 720 rays. */
    size_t ring = 0, ring_lit = 0;
    for (int i = 0; i < 720; i++) {
        double a = 2.0 * M_PI * (i + 0.5) / 720.0;
        for (double f = 0.95; f < 0.995; f += 0.01) {
            int x = (int)floor(cx + f * r * cos(a)), y = (int)floor(cy + f * r * sin(a));
            if (x < 0 || y < 0 || x >= w || y >= h)
                continue;
            ring++;
            ring_lit += pixel_luminance(photo, x, y) > black;
        }
    }
    *is_map = corners > 0 && ring > 0 && corners_lit <= lit_max &&
              ring_lit >= MAP_FILLED * ring;
    return SL_OK;
}

sl_result sl_probe_map_check(const sl_image *photo, const char *name, bool *is_map,
                             sl_error *err)
{
    sl_result r = probe_map(photo, is_map, err);
    if (r || !*is_map)
        return r;
    return sl_error_set(err, SL_ERR_INPUT,
                        "%s: a disc filling its frame on pure black is a light-probe map, not a "
                        "photo of a ball; convert it with 'setlight convert --from angular' "
                        "(Debevec's probes) or '--from mirrorball', or give --circle to unwrap "
                        "it as a photo",
                        name ? name : "image");
}

sl_result sl_fisheye_check(const sl_image *photo, bool srgb, const char *name,
                           sl_fisheye_evidence *ev, sl_error *err)
{
    memset(ev, 0, sizeof *ev);
    if (!name)
        name = "image";
    if (!photo || photo->width < 16 || photo->height < 16)
        return SL_OK;
    small_image s = {0};
    int f = 1;
    sl_result r = shrink(photo, srgb, &s, &f, err);
    if (r)
        return r;
    size_t n = (size_t)s.w * s.h;
    float *tmp = malloc(n * sizeof *tmp);
    if (!tmp) {
        free(s.lum);
        return sl_error_set(err, SL_ERR_NOMEM, "fisheye check: out of memory");
    }
    /* The disc centre's level and the frame border's. */
    double half = 0.5 * (s.w < s.h ? s.w : s.h);
    size_t m = 0;
    for (int y = 0; y < s.h; y++)
        for (int x = 0; x < s.w; x++)
            if (hypot(x + 0.5 - 0.5 * s.w, y + 0.5 - 0.5 * s.h) < 0.5 * half)
                tmp[m++] = s.lum[(size_t)y * s.w + x];
    double centre = quantile(tmp, m, 0.5);
    m = 0;
    for (int y = 0; y < s.h; y++)
        for (int x = 0; x < s.w; x++)
            if (x < 2 || y < 2 || x >= s.w - 2 || y >= s.h - 2)
                tmp[m++] = s.lum[(size_t)y * s.w + x];
    double border = quantile(tmp, m, 0.9);
    ev->border_level = centre > 0.0 ? border / centre : INFINITY;
    double c[3];
    /* The disc's edge halfway (in log) between the black and the inside. */
    double level = sqrt(fmax(border, 1e-3 * centre) * centre);
    if (centre > 0.0 && ev->border_level < BORDER_DARK && find_disc(&s, level, c)) {
        ev->round = true;
        ev->cx = c[0] * f;
        ev->cy = c[1] * f;
        ev->r = c[2] * f;
        size_t out = 0, dark = 0;
        for (int y = 0; y < s.h; y++)
            for (int x = 0; x < s.w; x++)
                if (hypot(x + 0.5 - c[0], y + 0.5 - c[1]) > 1.03 * c[2] + 1.0) {
                    out++;
                    dark += s.lum[(size_t)y * s.w + x] < level;
                }
        ev->dark_outside = out ? (double)dark / out : 0.0;
        ev->margin = fmin(fmin(c[0] - c[2], c[1] - c[2]),
                          fmin(s.w - c[0] - c[2], s.h - c[1] - c[2])) / c[2];
        double inner = ring_mean(&s, c, 0.80, 0.90, tmp);
        double rim = ring_mean(&s, c, 0.95, 0.985, tmp);
        ev->rim_ratio = inner > 0.0 ? rim / inner : INFINITY;
        ev->fisheye = ev->dark_outside >= OUTSIDE_DARK && ev->margin >= MIN_MARGIN &&
                      ev->rim_ratio < RIM_BRIGHT;
    }
    /* An angular map whose back hemisphere is dark shows a disc smaller than
     * its frame at the level above; lit to its frame's edge it is a map. */
    if (ev->fisheye && !(r = probe_map(photo, &ev->map, err)))
        ev->fisheye = !ev->map;
    if (r) {
        free(tmp);
        free(s.lum);
        return r;
    }
    free(tmp);
    free(s.lum);
    if (ev->fisheye)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: looks like a circular fisheye image (dark outside its image "
                            "circle at %.0f,%.0f r %.0f, no rim reflection); use 'setlight "
                            "stitch'",
                            name, ev->cx, ev->cy, ev->r);
    return SL_OK;
}
