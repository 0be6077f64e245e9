/* SPDX-License-Identifier: BSD-3-Clause */
/* Chrome-ball photo to lat-long: per output texel, a solid-angle-weighted
 * average of the photo over the texel's footprint on the ball, divided by
 * the ball's reflectance, with a confidence from the mapping's resolution. */
#include "unwrap_private.h"

#include <assert.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE__
#include <xmmintrin.h>
#endif
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define SUB_MAX 16
#define RING_SAMPLES 720
/* Photo pixels whose centre lies closer than this to the outline mix ball
 * and background (anti-aliasing, blur, fit error); they are never read. */
#define RIM_MARGIN 0.7
/* Sample points are kept this far inside the outline. */
#define RIM_CLAMP 0.7
/* Footprints up to this many photo pixels per texel (along u, v and their
 * longer principal axis) are sampled with the mapping taken as linear
 * across the texel, with at most FAST_MAX_SAMPLES samples along an axis
 * (1.21 px apart at the longest). */
#define FAST_MAX_EXTENT 48.0
#define FAST_MAX_SAMPLES 40
/* ... and bending less than this many pixels over two texels. */
#define FAST_MAX_BEND 0.5
#define REFL_TABLE 1024
/* A thread's unit of work: ROW_GRAIN rows by TILES_PER_UNIT tiles. Rows
 * many enough that a tile's photo pixels are read from memory about once
 * (8 rows: 5-8% more CPU); tiles few enough that the exact texels around
 * the point behind the ball (up to 64 K instructions each, in a few
 * units) do not keep one thread busy while the other waits at the strip's
 * end. */
#define ROW_GRAIN 32
#define TILES_PER_UNIT 4
#define TILE_W 256
/* Rows handed to a sink at a time: a few row chunks per thread, so that a
 * strip keeps the threads busy to its end. Two strips are in memory: one
 * being unwrapped, one with the sink. */
#define STRIP_ROWS 256

typedef float v4f __attribute__((vector_size(16)));
typedef int v4i __attribute__((vector_size(16)));
typedef double v2d __attribute__((vector_size(16)));
typedef long long v2l __attribute__((vector_size(16)));

/* Test switches (unwrap_private.h). */
static bool portable_rows_only, rim_table_off;

typedef struct unwrap_ctx {
    const sl_image *photo; /* RGB, finite */
    const sl_ball_view *view;
    const sl_reflectance *refl;
    int width, height, channels; /* the whole lat-long */
    float *rows;                 /* the output rows being done, from row0 */
    size_t stride;
    int row0, nrows;             /* the rows being done: row0 .. row0 + nrows - 1 */
    double blind_fill[3];
    double world_to_view[3][3];
    double *column;             /* per output column: world_to_view (sin lon, 0, cos lon) */
    double inv_refl[3];         /* constant reflectance */
    v4f inv_refl_f;             /* the same in float */
    double *refl_table;         /* conductor: 1 / R at cos = i / REFL_TABLE, 3 per entry */
    float *rim;                 /* photo_lookup() on the clamp circle, RGB per entry (rim_lookup) */
    int rim_n;                  /* entries, a multiple of 4, plus one repeating the first */
    double rim_z;               /* orthographic: directions with -wv[2] below it are clamped */
    double single2, smooth2;    /* the discs' squared photo radii, or -1 (discs_init) */
} unwrap_ctx;

static inline float *out_pixel(const unwrap_ctx *c, int x, int y)
{
    return c->rows + (size_t)(y - c->row0) * c->stride + (size_t)x * (size_t)c->channels;
}

/* A pixel's RGB is loaded as one 4-wide vector; with 3 channels the fourth
 * lane is the next pixel's R (unused; that pixel exists: taps lie inside the
 * ball, the ball inside the image). */

static inline v4f load4(const float *p)
{
    v4f v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* Exactly one pixel (the rim lookups may touch the image's last pixel).
 * Built in registers: through memory, the 12-byte copy and the 16-byte
 * load stall store forwarding (half the rim lookups' time). */
static inline v4f load3(const float *p)
{
#ifdef __SSE__
    __m128 lo = _mm_loadl_pi(_mm_setzero_ps(), (const __m64 *)p);
    return (v4f)_mm_movelh_ps(lo, _mm_load_ss(p + 2));
#else
    return (v4f){p[0], p[1], p[2], 0.0f};
#endif
}

/* Three float stores: a wider store through a may-alias type (__m64,
 * memcpy) would make the compiler reload the photo's pointer and stride
 * and the view after every texel. */
static inline void store3(float *p, v4f v)
{
    p[0] = v[0];
    p[1] = v[1];
    p[2] = v[2];
}

/* floor() and ceil() for coordinates and counts (|v| < 2^63): the same
 * values, without the general routines' cost (without SSE4.1 each is a
 * long sequence; the exact texels behind the ball take two floors per
 * sub-sample, every multi-sample texel two ceils of extents up to 16). */
static inline double floor_coord(double v)
{
    double t = (double)(int64_t)v;
    return t > v ? t - 1.0 : t;
}

static inline double ceil_coord(double v)
{
    double t = (double)(int64_t)v;
    return t < v ? t + 1.0 : t;
}

/* A point's "diamond angle" around the ball's centre, 0 to 4 (a quarter
 * turn per unit, monotonic in the angle, no trigonometry), from its offset. */
static inline double diamond_angle(double dx, double dy)
{
    double s = fabs(dx) + fabs(dy);
    if (!(s > 0.0))
        return 0.0;
    if (dy >= 0.0)
        return dx >= 0.0 ? dy / s : 1.0 - dx / s;
    return dx < 0.0 ? 2.0 - dy / s : 3.0 + dx / s;
}

/* The offset (unnormalised) of diamond angle a. */
static inline void diamond_offset(double a, double *dx, double *dy)
{
    int q = (int)a;
    double f = a - q;
    const double ox[4] = {1.0 - f, -f, f - 1.0, f}, oy[4] = {f, 1.0 - f, -f, f - 1.0};
    q &= 3;
    *dx = ox[q];
    *dy = oy[q];
}

/* photo_lookup() of a point pulled onto the clamp circle, from the table
 * of it around the circle (at most 1/8 px apart along it), linearly
 * interpolated: the samples of the texels around the point behind the ball
 * all land there (each through the clamp's square root, division and the
 * masked bilinear lookup before). */
static inline v4f rim_lookup(const unwrap_ctx *c, double dx, double dy)
{
    double t = diamond_angle(dx, dy) * (0.25 * c->rim_n);
    int i = (int)t;
    i = i < c->rim_n ? i : c->rim_n - 1;
    float f = (float)(t - i);
    const float *p = c->rim + 3 * (size_t)i;
    v4f a = load3(p);
    return a + (load3(p + 3) - a) * f;
}

/* Bilinear lookup of the ball's own pixels, taps closer than the rim
 * margin to the outline left out; *inside is false when the point had to
 * be pulled inside the rim margin. The point then lies on a circle around
 * the centre inside the image, so every tap does too. */
static inline __attribute__((always_inline)) v4f photo_lookup(const unwrap_ctx *c, double x,
                                                              double y, bool *inside)
{
    const sl_ball_view *v = c->view;
    const sl_image *img = c->photo;
    double dx = x - v->cx, dy = y - v->cy, d2 = dx * dx + dy * dy, lim = v->r - RIM_CLAMP;
    *inside = true;
    if (d2 > lim * lim) {
        if (c->rim) {
            *inside = false;
            return rim_lookup(c, dx, dy);
        }
        double f = lim / sqrt(d2);
        x = v->cx + dx * f;
        y = v->cy + dy * f;
        *inside = false;
    }
    double fx = x - 0.5, fy = y - 0.5;
    double x0 = floor_coord(fx), y0 = floor_coord(fy);
    float tx = (float)(fx - x0), ty = (float)(fy - y0);
    double keep = v->r - RIM_MARGIN, ex = x0 + 0.5 - v->cx, ey = y0 + 0.5 - v->cy;
    /* Through int64_t: a double's conversion to size_t takes a branch. */
    const float *p = img->data + (int64_t)y0 * (int64_t)img->stride + (int64_t)x0 * 3;
    v4f w = {(1.0f - tx) * (1.0f - ty), tx * (1.0f - ty), (1.0f - tx) * ty, tx * ty};
    /* Keep the taps whose centres are inside the margin: both columns'
     * squared offsets at once, their masks clearing the other weights. */
    v2d qx = {ex, ex + 1.0}, k2 = {keep * keep, keep * keep};
    qx *= qx;
    v2l in0 = qx + ey * ey <= k2, in1 = qx + (ey + 1.0) * (ey + 1.0) <= k2;
    w = (v4f)((v4i)w & __builtin_shufflevector((v4i)in0, (v4i)in1, 0, 2, 4, 6));
    float wsum = w[0] + w[1] + w[2] + w[3];
    if (wsum > 0.0f)
        return (load3(p) * w[0] + load3(p + 3) * w[1] + load3(p + img->stride) * w[2] +
                load3(p + img->stride + 3) * w[3]) *
               (1.0f / wsum);
    /* No tap inside: the pixel under the point. */
    int xi = (int)floor(x), yi = (int)floor(y);
    xi = xi < 0 ? 0 : (xi >= img->width ? img->width - 1 : xi);
    yi = yi < 0 ? 0 : (yi >= img->height ? img->height - 1 : yi);
    return load3(sl_image_pixel(img, xi, yi));
}

/* A view-frame direction to the photo: ball_view_map_local, with a shorter
 * orthographic formula away from the singular point behind the ball. */
static inline void map_local(const unwrap_ctx *c, const double wv[3], ball_hit *hit)
{
    double z = -wv[2];
    if (c->view->distance == 0.0 && z > -0.9999) {
        /* Unit direction: the pixel offset is r sin(phi/2) / sin(phi) =
         * r / (2 cos(phi/2)) times (wv0, wv1), cos(phi/2) = sqrt((1 + z) / 2). */
        double ct = sqrt(0.5 * (1.0 + z)), k = c->view->r * 0.5 / ct;
        hit->x = c->view->cx - k * wv[0];
        hit->y = c->view->cy - k * wv[1];
        hit->cos_incidence = ct;
        hit->blind = false;
        return;
    }
    ball_view_map_local(c->view, wv, hit);
}

static inline void inv_reflectance(const unwrap_ctx *c, double cosi, double out[3])
{
    if (!c->refl_table) {
        memcpy(out, c->inv_refl, sizeof c->inv_refl);
        return;
    }
    double t = cosi * REFL_TABLE;
    int i = (int)t;
    i = i < 0 ? 0 : (i >= REFL_TABLE ? REFL_TABLE - 1 : i);
    double f = t - i;
    const double *a = c->refl_table + 3 * i;
    for (int k = 0; k < 3; k++)
        out[k] = a[k] + f * (a[k + 3] - a[k]);
}

/* Radiance seen in the view-frame direction wv, and whether the photo
 * really shows it. The blind cone gets the median of the rim, flat: a rim
 * pixel next to a bright source must not be stretched over the whole cone,
 * and no detail is invented. */
static bool radiance(const unwrap_ctx *c, const double wv[3], double out[3])
{
    if (c->rim && c->view->distance == 0.0 && -wv[2] < c->rim_z) {
        /* Orthographic, landing past the clamp circle (sin^2(t/2) = (1 - z)
         * / 2 > (lim / R)^2): the circle's table at the direction's angle,
         * without mapping it (the texels around the point behind the ball
         * are all such samples). */
        double inv[3];
        v4f val = rim_lookup(c, -wv[0], -wv[1]);
        inv_reflectance(c, sqrt(0.5 * (1.0 - wv[2])), inv);
        for (int k = 0; k < 3; k++)
            out[k] = val[k] * inv[k];
        return false;
    }
    ball_hit h;
    map_local(c, wv, &h);
    if (h.blind) {
        memcpy(out, c->blind_fill, sizeof c->blind_fill);
        return false;
    }
    double inv[3];
    bool seen;
    v4f val = photo_lookup(c, h.x, h.y, &seen);
    inv_reflectance(c, h.cos_incidence, inv);
    for (int k = 0; k < 3; k++)
        out[k] = val[k] * inv[k];
    return seen;
}

static void pixel_of(const unwrap_ctx *c, double u, double v, double xy[2])
{
    double d[3];
    ball_hit h;
    sl_latlong_to_dir(u, v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v), d);
    ball_view_map(c->view, d, &h);
    xy[0] = h.x;
    xy[1] = h.y;
}

static int sub_count(double extent_px)
{
    double n = ceil(2.0 * extent_px);
    return n < 2.0 ? 2 : (n > SUB_MAX ? SUB_MAX : (int)n);
}

/* The exact texel: every sub-sample mapped on its own, the rim and the blind
 * cone handled per sample. */
static void texel_exact(const unwrap_ctx *c, int x, int y, float *p)
{
    int w = c->width, h = c->height;
    double ref = c->view->centre_px_per_rad;
    double uc = (x + 0.5) / w, vc = (y + 0.5) / h;
    /* The texel's footprint in the photo: its extent sets the sampling, and
     * per radian (longitude and latitude steps are orthogonal on the
     * sphere) it is the mapping's Jacobian. */
    double a[2], b[2], j[2][2];
    pixel_of(c, uc - 0.5 / w, vc, a);
    pixel_of(c, uc + 0.5 / w, vc, b);
    int nu = sub_count(hypot(b[0] - a[0], b[1] - a[1]));
    double lon_step = 2.0 * M_PI / w * cos(M_PI * (0.5 - vc));
    j[0][0] = (b[0] - a[0]) / lon_step;
    j[1][0] = (b[1] - a[1]) / lon_step;
    pixel_of(c, uc, vc - 0.5 / h, a);
    pixel_of(c, uc, vc + 0.5 / h, b);
    int nv = sub_count(hypot(b[0] - a[0], b[1] - a[1]));
    j[0][1] = (b[0] - a[0]) / (M_PI / h);
    j[1][1] = (b[1] - a[1]) / (M_PI / h);
    /* The sub-sample grid is separable: its trigonometry once per column
     * and row (the same values sl_latlong_to_dir gives). */
    const double(*m)[3] = c->world_to_view;
    double col[SUB_MAX][3]; /* world_to_view (sin lon, 0, cos lon) per sub-column */
    for (int i = 0; i < nu; i++) {
        double lon = M_PI * (1.0 - 2.0 * ((x + (i + 0.5) / nu) / w));
        double sn = sin(lon), cs = cos(lon);
        for (int k = 0; k < 3; k++)
            col[i][k] = m[k][0] * sn + m[k][2] * cs;
    }
    double acc[3] = {0, 0, 0}, wsum = 0.0, seen_w = 0.0;
    for (int jj = 0; jj < nv; jj++) {
        double lat = M_PI * (0.5 - (y + (jj + 0.5) / nv) / h);
        double wt = cos(lat), sl = sin(lat); /* wt: solid angle per unit (u, v) */
        for (int i = 0; i < nu; i++) {
            double val[3], wv[3];
            for (int k = 0; k < 3; k++)
                wv[k] = wt * col[i][k] + sl * m[k][1];
            if (radiance(c, wv, val))
                seen_w += wt;
            for (int k = 0; k < 3; k++)
                acc[k] += wt * val[k];
            wsum += wt;
        }
    }
    for (int k = 0; k < 3; k++)
        p[k] = (float)(acc[k] / wsum);
    if (c->channels == 4) {
        double conf = ref > 0.0 ? smaller_singular_value(j) / ref : 0.0;
        p[3] = (float)((conf > 1.0 ? 1.0 : conf) * seen_w / wsum);
    }
}

/* Samples along a footprint axis of extent e px: spread over e - 1 px (the
 * lookup's kernel covers the last pixel) at most 1.25 px apart. Lookups one
 * pixel apart sum to a constant; at 1.25 px the sum of (pixel-wide)
 * bilinear tents ripples by about +-2.6%, the price of a quarter fewer
 * lookups. */
static int fast_count(double extent_px)
{
    double n = extent_px <= 1.25 ? 1.0 : ceil_coord((extent_px - 1.0) / 1.25) + 1.0;
    return n > FAST_MAX_SAMPLES ? FAST_MAX_SAMPLES : (int)n;
}

/* The photo the fast path reads is RGB (read in place or copied so). */
#define NC 3

static inline v4f splat(v4f v, int i)
{
#ifdef __clang__ /* no shuffle by a variable mask */
    return (v4f){v[i], v[i], v[i], v[i]};
#else
    return __builtin_shuffle(v, (v4i){i, i, i, i});
#endif
}

/* Bilinear lookup at a point whose four taps are all ball pixels clear of
 * the rim margin (checked by the caller). */
static inline v4f bilinear(const sl_image *img, double x, double y)
{
    double fx = x - 0.5, fy = y - 0.5;
    int x0 = (int)fx, y0 = (int)fy;
    float tx = (float)(fx - x0), ty = (float)(fy - y0);
    const float *p0 = img->data + (size_t)y0 * img->stride + (size_t)x0 * NC;
    const float *p1 = p0 + img->stride;
    v4f top = load4(p0) * (1.0f - tx) + load4(p0 + NC) * tx;
    v4f bot = load4(p1) * (1.0f - tx) + load4(p1 + NC) * tx;
    return top * (1.0f - ty) + bot * ty;
}

/* Keys' cubic convolution kernel with a = -0.75 (a little sharper than
 * Catmull-Rom's -0.5; measured on the peers' 1024 ball: front 0.182% vs
 * 0.187%): the weights of the four taps at distances 1 + t, t, 1 - t, 2 - t,
 * the outer two from the kernel's 1 < |t| < 2 piece, all in one vector. */
#define KEYS_A -0.75f
static inline v4f keys_weights(float t)
{
    const v4f a = {KEYS_A, KEYS_A + 2.0f, KEYS_A + 2.0f, KEYS_A};
    const v4f b = {-5.0f * KEYS_A, -(KEYS_A + 3.0f), -(KEYS_A + 3.0f), -5.0f * KEYS_A};
    const v4f c = {8.0f * KEYS_A, 0.0f, 0.0f, 8.0f * KEYS_A};
    const v4f d = {-4.0f * KEYS_A, 1.0f, 1.0f, -4.0f * KEYS_A};
    v4f u = (v4f){1.0f, 0.0f, 1.0f, 2.0f} + (v4f){1.0f, 1.0f, -1.0f, -1.0f} * t;
    return ((a * u + b) * u + c) * u + d;
}

/* minps/maxps where there is SSE (the masks cost four instructions). */
static inline v4f vmin(v4f a, v4f b)
{
#ifdef __SSE__
    return (v4f)_mm_min_ps((__m128)a, (__m128)b);
#else
    v4i m = a < b;
    return (v4f)((m & (v4i)a) | (~m & (v4i)b));
#endif
}

static inline v4f vmax(v4f a, v4f b)
{
#ifdef __SSE__
    return (v4f)_mm_max_ps((__m128)a, (__m128)b);
#else
    v4i m = a > b;
    return (v4f)((m & (v4i)a) | (~m & (v4i)b));
#endif
}

/* Cubic lookup where the photo is magnified (sharper than the
 * bilinear tent), clamped to the range of the four nearest pixels so that
 * it never rings around a bright source. All 16 taps must be ball pixels
 * clear of the rim margin (checked by the caller). Written out row by row
 * (the rows are independent; the inner four taps are the clamp's too). */
/* The 4x4 taps' top-left pixel for the point (x, y), and the point's
 * offsets (tx, ty) from the pixel centre above and left of it. */
static inline __attribute__((always_inline)) const float *
cubic_taps(const sl_image *img, double x, double y, float *tx, float *ty)
{
    double fx = x - 0.5, fy = y - 0.5;
    int x0 = (int)fx, y0 = (int)fy;
    *tx = (float)(fx - x0);
    *ty = (float)(fy - y0);
    return img->data + (size_t)(y0 - 1) * img->stride + (size_t)(x0 - 1) * NC;
}

static inline __attribute__((always_inline)) v4f bicubic(const sl_image *img, double x,
                                                         double y)
{
    float tx, ty;
    const float *p = cubic_taps(img, x, y, &tx, &ty);
    v4f wx = keys_weights(tx), wy = keys_weights(ty);
    v4f w0 = splat(wx, 0), w1 = splat(wx, 1), w2 = splat(wx, 2), w3 = splat(wx, 3);
    const float *q = p + img->stride, *r = q + img->stride, *s = r + img->stride;
    v4f q1 = load4(q + NC), q2 = load4(q + 2 * NC), r1 = load4(r + NC), r2 = load4(r + 2 * NC);
    v4f rp = load4(p) * w0 + load4(p + NC) * w1 + load4(p + 2 * NC) * w2 + load4(p + 3 * NC) * w3;
    v4f rq = load4(q) * w0 + q1 * w1 + q2 * w2 + load4(q + 3 * NC) * w3;
    v4f rr = load4(r) * w0 + r1 * w1 + r2 * w2 + load4(r + 3 * NC) * w3;
    v4f rs = load4(s) * w0 + load4(s + NC) * w1 + load4(s + 2 * NC) * w2 + load4(s + 3 * NC) * w3;
    v4f acc = rp * splat(wy, 0) + rq * splat(wy, 1) + rr * splat(wy, 2) + rs * splat(wy, 3);
    v4f lo = vmin(vmin(q1, q2), vmin(r1, r2)), hi = vmax(vmax(q1, q2), vmax(r1, r2));
    return vmin(vmax(acc, lo), hi);
}

#if (defined(__x86_64__) || defined(__i386__)) && defined(__SSE2__) && \
    (defined(__clang__) || __GNUC__ >= 12)
#define HAVE_ROWS_WIDE 1
/* bicubic() where the processor has AVX2 and FMA, rows first: a tap row's
 * four RGB pixels are 12 contiguous floats, loaded as 8 + 4 and summed over
 * the four rows with the y weights (fused multiply-adds), then weighted
 * along x and folded to RGB. The same weights and taps as bicubic(),
 * summed in another order (within a few float ulps; test_unwrap compares
 * the two). */
typedef float v8f __attribute__((vector_size(32)));

/* Eight floats (through a pointer: a 32-byte vector returned by value
 * would change the ABI where AVX is not enabled). */
static inline void load8(v8f *v, const float *p)
{
    memcpy(v, p, sizeof *v);
}

#define LOW4(v) __builtin_shufflevector((v), (v), 0, 1, 2, 3)
#define HIGH4(v) __builtin_shufflevector((v), (v), 4, 5, 6, 7)
#define PERM8(v, ...) __builtin_shufflevector((v), (v), __VA_ARGS__)

static inline __attribute__((always_inline)) v4f bicubic8(const sl_image *img, double x,
                                                          double y)
{
    /* cubic_taps() for x and y at once (coordinates are positive: the
     * truncation is the floor). */
    __m128d f = _mm_sub_pd(_mm_set_pd(y, x), _mm_set1_pd(0.5));
    __m128i i0 = _mm_cvttpd_epi32(f);
    __m128 t = _mm_cvtpd_ps(_mm_sub_pd(f, _mm_cvtepi32_pd(i0)));
    int x0 = ((v4i)i0)[0], y0 = ((v4i)i0)[1];
    const float *p = img->data + (ptrdiff_t)(y0 - 1) * (ptrdiff_t)img->stride + (x0 - 1) * NC;
    /* keys_weights() of the x fraction in the low half, of the y fraction
     * in the high half. */
#define K8(a, b, c, d) {a, b, c, d, a, b, c, d}
    const v8f ka = K8(KEYS_A, KEYS_A + 2.0f, KEYS_A + 2.0f, KEYS_A);
    const v8f kb = K8(-5.0f * KEYS_A, -(KEYS_A + 3.0f), -(KEYS_A + 3.0f), -5.0f * KEYS_A);
    const v8f kc = K8(8.0f * KEYS_A, 0.0f, 0.0f, 8.0f * KEYS_A);
    const v8f kd = K8(-4.0f * KEYS_A, 1.0f, 1.0f, -4.0f * KEYS_A);
    const v8f u0 = K8(1.0f, 0.0f, 1.0f, 2.0f), us = K8(1.0f, 1.0f, -1.0f, -1.0f);
#undef K8
    v8f u = us * __builtin_shufflevector((v4f)t, (v4f)t, 0, 0, 0, 0, 1, 1, 1, 1) + u0;
    v8f wxy = ((ka * u + kb) * u + kc) * u + kd;
    const float *q = p + img->stride, *r = q + img->stride, *s = r + img->stride;
    v8f wy0 = PERM8(wxy, 4, 4, 4, 4, 4, 4, 4, 4), wy1 = PERM8(wxy, 5, 5, 5, 5, 5, 5, 5, 5);
    v8f wy2 = PERM8(wxy, 6, 6, 6, 6, 6, 6, 6, 6), wy3 = PERM8(wxy, 7, 7, 7, 7, 7, 7, 7, 7);
    /* Floats 0-7 (R0 G0 B0 R1 G1 B1 R2 G2) and 8-11 (B2 R3 G3 B3) of the
     * rows, summed over the rows. */
    v8f lp, lq, lr, ls;
    load8(&lp, p);
    load8(&lq, q);
    load8(&lr, r);
    load8(&ls, s);
    v8f a8 = ((lp * wy0 + lq * wy1) + lr * wy2) + ls * wy3;
    v4f a4 = ((load4(p + 8) * LOW4(wy0) + load4(q + 8) * LOW4(wy1)) + load4(r + 8) * LOW4(wy2)) +
             load4(s + 8) * LOW4(wy3);
    v8f h8 = a8 * PERM8(wxy, 0, 0, 0, 1, 1, 1, 2, 2);
    v4f h4 = a4 * __builtin_shufflevector(wxy, wxy, 2, 3, 3, 3);
    /* (R0 G0 B0 .) + (R1 G1 B1 .) + (R2 G2 B2 .) + (R3 G3 B3 .) */
    v4f c0 = LOW4(h8), hi = HIGH4(h8);
    v4f c1 = __builtin_shufflevector(c0, hi, 3, 4, 5, 6);
    v4f c2 = __builtin_shufflevector(hi, h4, 2, 3, 4, 5);
    v4f c3 = __builtin_shufflevector(h4, h4, 1, 2, 3, 3);
    v4f acc = (c0 + c1) + (c2 + c3);
    v4f q1 = load4(q + NC), q2 = load4(q + 2 * NC), r1 = load4(r + NC), r2 = load4(r + 2 * NC);
    v4f lo = vmin(vmin(q1, q2), vmin(r1, r2)), hi4 = vmax(vmax(q1, q2), vmax(r1, r2));
    return vmin(vmax(acc, lo), hi4);
}
#undef PERM8
#endif

/* The cubic lookup, 8 wide in the row loop built for AVX2 and FMA. */
static inline __attribute__((always_inline)) v4f cubic_lookup(const sl_image *img, double x,
                                                              double y, bool wide)
{
#ifdef HAVE_ROWS_WIDE
    if (wide)
        return bicubic8(img, x, y);
#endif
    (void)wide;
    return bicubic(img, x, y);
}

/* Texel centres of one lat-long row mapped to the photo. */
typedef struct centre {
    double x, y, cosi;
    float e2; /* squared distance from the ball's centre, px^2 (the discs' test) */
    bool blind;
} centre;

/* Columns x0 .. x1 - 1 of row y (x wraps around) into row[0 ..]; whether
 * any of them is blind. Inlined into the row loop, so that the loop built
 * for AVX2 maps with AVX2 too. */
static inline __attribute__((always_inline)) bool map_row(const unwrap_ctx *c, int y, int x0,
                                                          int x1, centre *row)
{
    bool any_blind = false;
    int w = c->width, h = c->height;
    double lat = M_PI * (0.5 - (y + 0.5) / h), cl = cos(lat), sl = sin(lat);
    const double(*m)[3] = c->world_to_view;
    row -= x0;
    int x = x0;
#ifdef __SSE2__
    /* Orthographic, away from the singular point: map_local's short formula
     * for two centres at a time (the square root and the division are the
     * row's cost; packed, they cost about what one does). */
    const sl_ball_view *v = c->view;
    if (v->distance == 0.0 && x0 >= 0 && x1 <= w) {
        const v2d one = {1.0, 1.0}, half = {0.5, 0.5}, rk = {0.5 * v->r, 0.5 * v->r};
        for (; x + 1 < x1; x += 2) {
            const double *c0 = c->column + 3 * (size_t)x, *c1 = c0 + 3;
            v2d w0 = {cl * c0[0] + sl * m[0][1], cl * c1[0] + sl * m[0][1]};
            v2d w1 = {cl * c0[1] + sl * m[1][1], cl * c1[1] + sl * m[1][1]};
            v2d z = {-(cl * c0[2] + sl * m[2][1]), -(cl * c1[2] + sl * m[2][1])};
            if (!(z[0] > -0.9999 && z[1] > -0.9999))
                break;
            v2d ct = (v2d)_mm_sqrt_pd((__m128d)(half * (one + z))), k = rk / ct;
            v2d px = v->cx - k * w0, py = v->cy - k * w1;
            v2d e2 = k * k * (w0 * w0 + w1 * w1);
            for (int i = 0; i < 2; i++) {
                row[x + i].x = px[i];
                row[x + i].y = py[i];
                row[x + i].cosi = ct[i];
                row[x + i].e2 = (float)e2[i];
                row[x + i].blind = false;
            }
        }
    }
#endif
    for (; x < x1; x++) {
        int xw = x < 0 ? x + w : (x >= w ? x - w : x);
        const double *col = c->column + 3 * (size_t)xw;
        double wv[3];
        for (int k = 0; k < 3; k++)
            wv[k] = cl * col[k] + sl * m[k][1];
        ball_hit hit;
        map_local(c, wv, &hit);
        row[x].x = hit.x;
        row[x].y = hit.y;
        row[x].cosi = hit.cos_incidence;
        double ex = hit.x - c->view->cx, ey = hit.y - c->view->cy;
        row[x].e2 = (float)(ex * ex + ey * ey);
        row[x].blind = hit.blind;
        any_blind |= hit.blind;
    }
    return any_blind;
}

/* A texel's radiance val written to p (RGB): the ball's reflectance at
 * incidence cosi divided out. */
static inline __attribute__((always_inline)) void store_radiance(const unwrap_ctx *c,
                                                                  double cosi, v4f val, float *p)
{
    if (c->refl_table) {
        double inv[3];
        inv_reflectance(c, cosi, inv);
        for (int k = 0; k < 3; k++)
            p[k] = (float)(val[k] * inv[k]);
    } else {
        /* Exact in float too when the reflectance is 1 (the default). */
        store3(p, val * c->inv_refl_f);
    }
}

/* What the texels of one row share. */
typedef struct row_geom {
    int y;
    bool inner_row;   /* has rows above and below */
    bool maybe_blind; /* a centre of the row or those next to it is blind */
    bool confidence;
    double vscale, cos_lat, sin_lat, lon_step, lat_step, ref, keep;
    double inner_any; /* keep less the lookup's reach and the largest fast footprint */
    double single2;   /* squared photo radius inside which a texel is one lookup, or -1 */
    double smooth2;   /* squared photo radius inside which the tests are passed, or -1 */
} row_geom;

/* The disc of the photo (squared radius from the ball's centre, px^2) inside
 * which every texel's footprint is certain to pass the fast path's tests
 * as one cubic lookup, so that texel() need not compute them (where
 * discs_init() allows; -1 where the bound does not hold).
 * Orthographic ball of radius R: a direction at angle t from the view axis
 * lands at r = R sin(t/2), and the mapping stretches by at most
 * R / (2 cos(t/2)) px per radian (tangentially). A texel step is at most
 * 2 pi / W radians along u and v, so both footprint extents stay within
 * 1.25 px while R / (2 cos(t/2)) 2 pi / W <= 1.25 / 1.05 (5% for the
 * central differences and rounding), i.e. (r/R)^2 <= 1 - q^2 with
 * q = 1.05 pi R / (1.25 W). Kept to r <= 0.8 R (cos(t/2) >= 0.6) and to
 * W >= 1024, where the bend over two texels (of order R (2 pi / W)^2 /
 * cos^3(t/2) < 0.05 px) is far under FAST_MAX_BEND, and inside inner_any
 * (far from the rim). Debug builds check every such texel against the
 * full tests (assert in texel()). */
static double single_lookup_disc(const unwrap_ctx *c, double inner_any)
{
    const sl_ball_view *v = c->view;
    double q = 1.05 * M_PI * v->r / (1.25 * c->width);
    if (q >= 1.0)
        return -1.0;
    double rho2 = fmin(1.0 - q * q, 0.8 * 0.8);
    double r2 = rho2 * v->r * v->r;
    return fmin(r2, inner_any * inner_any);
}

/* The disc of the photo (squared radius, px^2) inside which every texel is
 * certain to pass the fast path's extent and bend tests and to lie far
 * enough from the rim for unchecked cubic lookups, so that texel() need
 * only compute its footprint's extents (one lookup or several); -1 where
 * no radius passes. Orthographic ball of radius R,
 * c = cos(t/2) = sqrt(1 - (r/R)^2) at photo radius r: the mapping
 * stretches by at most R / (2c) px per radian, so a texel step (at most
 * 2 pi / W radians) spans at most R / (2c) 2 pi / W px; the second
 * difference over one texel step each side (the bend test) is at most
 * R (2 pi / W)^2 (1.125 / c + 0.5 / c^2 + 0.25 / c^3) (the mapping's
 * second derivative along the lat-long's circles). Kept to extents under
 * half of FAST_MAX_EXTENT, bends under a fifth of FAST_MAX_BEND, r <= 0.97 R
 * and inside inner_any. Debug builds check every such texel against the
 * full tests (assert in texel()). */
static double smooth_disc(const unwrap_ctx *c, double inner_any)
{
    const sl_ball_view *v = c->view;
    double step = 2.0 * M_PI / c->width;
    for (double rho = 0.97; rho > 0.0; rho -= 0.01) {
        double cc = sqrt(1.0 - rho * rho);
        double extent = v->r / (2.0 * cc) * step * 1.05;
        double bend = v->r * step * step * (1.125 / cc + 0.5 / (cc * cc) + 0.25 / (cc * cc * cc));
        if (extent <= 0.5 * FAST_MAX_EXTENT && bend <= 0.2 * FAST_MAX_BEND)
            return fmin(rho * rho * v->r * v->r, inner_any * inner_any);
    }
    return -1.0;
}

/* Both discs, once per unwrap: only for an orthographic ball, without the
 * confidence channel (it needs every texel's extents), at 1024 texels wide
 * or more, and with room inside the rim for the largest fast footprint. */
static void discs_init(unwrap_ctx *c)
{
    double inner_any = c->view->r - RIM_MARGIN - 2.9 - FAST_MAX_EXTENT;
    c->single2 = c->smooth2 = -1.0;
    if (c->view->distance != 0.0 || c->channels == 4 || c->width < 1024 || inner_any <= 0.0)
        return;
    c->single2 = single_lookup_disc(c, inner_any);
    c->smooth2 = smooth_disc(c, inner_any);
}

/* Column groups of a row chunk: the units across the lat-long. */
static int unit_columns(const unwrap_ctx *c)
{
    int group_w = TILE_W * TILES_PER_UNIT;
    return (c->width + group_w - 1) / group_w;
}

/* One texel from its centre ce, its neighbours in the row ce[-1] and ce[1],
 * and the centres above and below. Where the footprint is clear of the
 * blind cone and at most a few photo pixels wide, the mapping is linear
 * across the texel: sub-samples are placed with the centres' differences
 * (checked against the rim only when the footprint comes near it);
 * elsewhere the texel is done exactly. */
static inline __attribute__((always_inline)) void texel(const unwrap_ctx *c, const row_geom *g,
                                                         int x, const centre *ce,
                                                         const centre *up, const centre *down,
                                                         float *p, bool wide)
{
    const centre *l = ce - 1, *r = ce + 1;
    double e2 = ce->e2;
    bool single = e2 <= g->single2;
#ifdef NDEBUG
    if (single) {
        store_radiance(c, ce->cosi, cubic_lookup(c->photo, ce->x, ce->y, wide), p);
        return;
    }
#endif
    bool smooth = e2 <= g->smooth2;
    /* Photo pixels per texel step along u and v. */
    double du[2] = {0.5 * (r->x - l->x), 0.5 * (r->y - l->y)};
    double dv[2] = {g->vscale * (down->x - up->x), g->vscale * (down->y - up->y)};
    double eu2 = du[0] * du[0] + du[1] * du[1], ev2 = dv[0] * dv[0] + dv[1] * dv[1];
    bool checked = false, cubic = true;
#ifdef NDEBUG
    if (!smooth) {
#else
    {
#endif
        if (g->maybe_blind &&
            (ce->blind || l->blind || r->blind || up->blind || down->blind)) {
            assert(!single && !smooth);
            texel_exact(c, x, g->y, p);
            return;
        }
        /* Curvature of the mapping: how far the centre is from its
         * neighbours' midpoints. */
        double cu = fabs(r->x + l->x - 2.0 * ce->x) + fabs(r->y + l->y - 2.0 * ce->y);
        double cv = g->inner_row ? fabs(down->x + up->x - 2.0 * ce->x) +
                                       fabs(down->y + up->y - 2.0 * ce->y)
                                 : 0.0;
        if (eu2 > FAST_MAX_EXTENT * FAST_MAX_EXTENT ||
            ev2 > FAST_MAX_EXTENT * FAST_MAX_EXTENT || cu > FAST_MAX_BEND ||
            cv > FAST_MAX_BEND) {
            assert(!single && !smooth);
            texel_exact(c, x, g->y, p);
            return;
        }
        /* Farthest point of the footprint from the ball's centre (a corner:
         * distance is convex), plus the lookup's reach: bilinear taps lie
         * within sqrt(2) px of the point, the cubic's within 2 sqrt(2). Near
         * the rim each sample is checked and clamped like the exact path's.
         * Most texels are far from the rim: the triangle inequality settles
         * them without the corners, most of them even with the largest
         * footprint (no square roots). */
        double inner = g->inner_any;
        if (inner < 0.0 || e2 > inner * inner)
            inner = g->keep - 2.9 - 0.5 * (sqrt(eu2) + sqrt(ev2));
        if (inner < 0.0 || e2 > inner * inner) {
            double far2 = 0.0, ex = ce->x - c->view->cx, ey = ce->y - c->view->cy;
            for (int q = 0; q < 4; q++) {
                double a = q & 1 ? 0.5 : -0.5, b = q & 2 ? 0.5 : -0.5;
                double qx = ex + a * du[0] + b * dv[0], qy = ey + a * du[1] + b * dv[1];
                double d2 = qx * qx + qy * qy;
                far2 = d2 > far2 ? d2 : far2;
            }
            double far = sqrt(far2);
            checked = far + 1.5 > g->keep;
            cubic = far + 2.9 <= g->keep;
        }
        assert(!smooth || (cubic && !checked));
    }
    double seen = 1.0;
    v4f val;
    if (eu2 <= 1.25 * 1.25 && ev2 <= 1.25 * 1.25) {
        /* The lookup's kernel is about as wide as the footprint. */
        assert(cubic || !single);
        if (cubic) {
            val = cubic_lookup(c->photo, ce->x, ce->y, wide);
        } else if (checked) {
            bool in;
            val = photo_lookup(c, ce->x, ce->y, &in);
            seen = in ? 1.0 : 0.0;
        } else {
            val = bilinear(c->photo, ce->x, ce->y);
        }
    } else {
        /* The lookup's kernel already spans about a pixel: samples
         * cover the footprint less that pixel, along its principal axes
         * (the singular vectors of the texel's Jacobian [du dv]). Near the
         * singular point behind the ball the footprints are long and thin
         * and slanted to the texel grid: samples along their length only,
         * where a grid along u and v would fill the parallelogram's box.
         * Along the grid (du, dv orthogonal) the samples are the grid's. */
        assert(!single);
        double s = du[0] * dv[0] + du[1] * dv[1], hd = 0.5 * (eu2 - ev2);
        double disc = sqrt(hd * hd + s * s), tr = 0.5 * (eu2 + ev2);
        double l2 = tr - disc;
        /* Unit eigenvector of J^T J for the larger eigenvalue, in texel
         * units (a along u, b along v), from its better-conditioned row.
         * Its length and e1 from one packed square root, the length's
         * inverse and s1 from one packed division (perf put 5% of the
         * command's samples on the four roots and three divisions before). */
        double va = hd >= 0.0 ? hd + disc : s, vb = hd >= 0.0 ? s : disc - hd;
        double vn = va * va + vb * vb;
        v2d root = {tr + disc, vn};
#ifdef __SSE2__
        root = (v2d)_mm_sqrt_pd((__m128d)root);
#else
        root = (v2d){sqrt(root[0]), sqrt(root[1])};
#endif
        double e1 = root[0];
        if (e1 > FAST_MAX_EXTENT) {
            texel_exact(c, x, g->y, p);
            return;
        }
        /* Samples along the axes: n2 is 1 unless e2 > 1.25 px. */
        int n1 = fast_count(e1), n2 = l2 > 1.25 * 1.25 ? fast_count(sqrt(l2)) : 1;
        v2d quo = (v2d){1.0, e1 - 1.0} /
                  (v2d){vn > 0.0 ? root[1] : 1.0, n1 > 1 ? e1 * (n1 - 1) : 1.0};
        if (vn > 0.0) {
            va *= quo[0];
            vb *= quo[0];
        } else {
            va = 1.0;
            vb = 0.0;
        }
        double s1 = n1 > 1 ? quo[1] : 0.0, s2 = 0.0;
        if (n2 > 1) {
            double e2 = sqrt(l2);
            s2 = (e2 - 1.0) / (e2 * (n2 - 1));
        }
        /* Photo offsets per unit along the axes (lengths e1, e2). */
        double p0x = va * du[0] + vb * dv[0], p0y = va * du[1] + vb * dv[1];
        double p1x = va * dv[0] - vb * du[0], p1y = va * dv[1] - vb * du[1];
        v4f acc = {0, 0, 0, 0};
        double wsum = 0.0, seen_w = 0.0;
        /* Solid angle per unit v at the sample's latitude (first order):
         * linear in the sample's b. */
        double wb = g->sin_lat * g->lat_step;
        for (int j = 0; j < n2; j++) {
            double t2 = (j - 0.5 * (n2 - 1)) * s2;
            double rx = ce->x + t2 * p1x, ry = ce->y + t2 * p1y;
            double rb = g->cos_lat + wb * (t2 * va);
            for (int i = 0; i < n1; i++) {
                double t1 = (i - 0.5 * (n1 - 1)) * s1;
                double sx = rx + t1 * p0x, sy = ry + t1 * p0y;
                double wt = rb + wb * (t1 * vb);
                v4f v;
                if (cubic) {
                    v = cubic_lookup(c->photo, sx, sy, wide);
                } else if (!checked) {
                    v = bilinear(c->photo, sx, sy);
                } else {
                    bool in;
                    v = photo_lookup(c, sx, sy, &in);
                    seen_w += in ? wt : 0.0;
                }
                acc += v * (float)wt;
                wsum += wt;
            }
        }
        val = acc * (float)(1.0 / wsum);
        if (checked)
            seen = seen_w / wsum;
    }
    store_radiance(c, ce->cosi, val, p);
    if (g->confidence) {
        double j[2][2] = {{du[0] / g->lon_step, dv[0] / g->lat_step},
                          {du[1] / g->lon_step, dv[1] / g->lat_step}};
        double conf = g->ref > 0.0 ? smaller_singular_value(j) / g->ref : 0.0;
        p[3] = (float)((conf > 1.0 ? 1.0 : conf) * seen);
    }
}

/* Rows in chunks, each done in tiles TILE_W texels wide: a tile's rows
 * read nearby photo pixels, which stay in cache from one row to the next
 * (a whole row's path through the photo does not). The texel centres of a
 * tile and the rows and columns around it are mapped first, so each centre
 * is mapped once (plus a border per tile). */
static inline __attribute__((always_inline)) void rows_body(const unwrap_ctx *c, int64_t first,
                                                             int64_t last, int x0, int x1,
                                                             bool wide)
{
    int w = c->width, h = c->height;
    int64_t begin = c->row0 + first, end = c->row0 + last;
    int nrows = (int)(end - begin) + 2, tw = TILE_W + 2;
    centre *buf = malloc(sizeof(centre) * (size_t)nrows * (size_t)tw);
    bool *blind = calloc((size_t)nrows, sizeof *blind); /* per buf row */
    if (!buf || !blind) {
        free(buf);
        free(blind);
        /* No memory for the fast path: the exact one needs none. */
        for (int64_t y = begin; y < end; y++)
            for (int x = x0; x < x1; x++)
                texel_exact(c, x, (int)y, out_pixel(c, x, (int)y));
        return;
    }
    row_geom g = {.confidence = c->channels == 4, .lat_step = M_PI / h,
                  .ref = c->view->centre_px_per_rad, .keep = c->view->r - RIM_MARGIN};
    g.inner_any = g.keep - 2.9 - FAST_MAX_EXTENT;
    g.single2 = c->single2;
    g.smooth2 = c->smooth2;
    for (int xb = x0; xb < x1; xb += TILE_W) {
        int xe = xb + TILE_W < x1 ? xb + TILE_W : x1;
        /* buf row i holds image row begin - 1 + i, columns xb - 1 .. xe. */
        for (int i = 0; i < nrows; i++) {
            int y = (int)begin - 1 + i;
            if (y >= 0 && y < h)
                blind[i] = map_row(c, y, xb - 1, xe + 1, buf + (size_t)i * tw);
        }
        for (int y = (int)begin; y < end; y++) {
            const centre *row = buf + (size_t)(y - begin + 1) * tw + 1 - xb;
            const centre *up = y > 0 ? row - tw : row, *down = y + 1 < h ? row + tw : row;
            double lat = M_PI * (0.5 - (y + 0.5) / h);
            g.y = y;
            g.inner_row = y > 0 && y + 1 < h;
            g.maybe_blind = blind[y - begin] || blind[y - begin + 1] || blind[y - begin + 2];
            g.vscale = g.inner_row ? 0.5 : 1.0;
            g.cos_lat = cos(lat);
            g.sin_lat = sin(lat);
            g.lon_step = 2.0 * M_PI / w * g.cos_lat;
            float *p = out_pixel(c, xb, y);
            for (int x = xb; x < xe; x++, p += c->channels)
                texel(c, &g, x, row + x, up + x, down + x, p, wide);
        }
    }
    free(buf);
    free(blind);
}

/* Units first .. last - 1 (row chunk major, then column groups). */
static inline __attribute__((always_inline)) void units_body(const unwrap_ctx *c, int64_t first,
                                                              int64_t last, bool wide)
{
    int group_w = TILE_W * TILES_PER_UNIT, groups = unit_columns(c);
    for (int64_t k = first; k < last; k++) {
        int64_t r0 = k / groups * ROW_GRAIN, r1 = r0 + ROW_GRAIN;
        int x0 = (int)(k % groups) * group_w, x1 = x0 + group_w;
        rows_body(c, r0, r1 < c->nrows ? r1 : c->nrows, x0, x1 < c->width ? x1 : c->width,
                  wide);
    }
}

static void unwrap_rows(void *ctx, int64_t first, int64_t last, int worker)
{
    (void)worker;
    units_body(ctx, first, last, false);
}

#ifdef HAVE_ROWS_WIDE
/* The same rows built for AVX2 and FMA, used where the processor has them
 * (the cubic lookups 8 wide with fused multiply-adds). */
__attribute__((target("avx2,fma"))) static void unwrap_rows_wide(void *ctx, int64_t first,
                                                                 int64_t last, int worker)
{
    (void)worker;
    units_body(ctx, first, last, true);
}
#endif

static void tables_free(unwrap_ctx *c)
{
    free(c->column);
    free(c->refl_table);
    free(c->rim);
}

/* The clamp circle's table for rim_lookup(): photo_lookup() at rim_n
 * diamond angles (entries 1/8 px apart along the circle at most: a diamond
 * angle step turns by at most twice a quarter turn's average). Without
 * memory for it, photo_lookup() clamps each point itself. */
static void rim_init(unwrap_ctx *c)
{
    double lim = c->view->r - RIM_CLAMP;
    if (!(lim > 1.0) || rim_table_off)
        return;
    double n = 4.0 * ceil(16.0 * lim);
    if (n > 1 << 24)
        return;
    int rim_n = (int)n;
    float *rim = malloc(sizeof(float) * 3 * ((size_t)rim_n + 1));
    if (!rim)
        return;
    for (int i = 0; i <= rim_n; i++) {
        double dx, dy, a = 4.0 * (i % rim_n) / rim_n;
        diamond_offset(a, &dx, &dy);
        double k = lim / sqrt(dx * dx + dy * dy);
        bool in;
        v4f v = photo_lookup(c, c->view->cx + k * dx, c->view->cy + k * dy, &in);
        for (int j = 0; j < 3; j++)
            rim[3 * (size_t)i + (size_t)j] = v[j];
    }
    c->rim = rim;
    c->rim_n = rim_n;
    double q = lim / c->view->r;
    c->rim_z = 1.0 - 2.0 * q * q;
}

/* Per-column directions in the view frame and the reflectance. */
static sl_result tables_init(unwrap_ctx *c, sl_error *err)
{
    int w = c->width;
    c->column = malloc(sizeof(double) * 3 * (size_t)w);
    bool ok = c->column != NULL;
    if (ok && c->refl->kind == SL_REFLECTANCE_CONDUCTOR)
        ok = (c->refl_table = malloc(sizeof(double) * 3 * (REFL_TABLE + 1))) != NULL;
    if (!ok) {
        tables_free(c);
        return sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
    }
    for (int x = 0; x < w; x++) {
        double lon = M_PI * (1.0 - 2.0 * (x + 0.5) / w);
        double sn = sin(lon), cs = cos(lon);
        for (int k = 0; k < 3; k++)
            c->column[3 * x + k] = c->world_to_view[k][0] * sn + c->world_to_view[k][2] * cs;
    }
    double rf[3];
    sl_reflectance_eval(c->refl, 1.0, rf);
    for (int k = 0; k < 3; k++)
        c->inv_refl[k] = 1.0 / rf[k];
    c->inv_refl_f = (v4f){(float)c->inv_refl[0], (float)c->inv_refl[1], (float)c->inv_refl[2], 0};
    for (int i = 0; c->refl_table && i <= REFL_TABLE; i++) {
        sl_reflectance_eval(c->refl, (double)i / REFL_TABLE, rf);
        for (int k = 0; k < 3; k++)
            c->refl_table[3 * i + k] = 1.0 / rf[k];
    }
    return SL_OK;
}

/* An image in memory the kernel may back with huge pages: lookups that
 * follow curves through a large photo otherwise miss the TLB on almost
 * every row. Freed by sl_image_free (free). */
/* NaN/Inf among the samples the unwrap reads (RGB, or the one grey
 * channel), counted per row in parallel (a whole photo is a few hundred MB). */
typedef struct nonfinite_job {
    const sl_image *img;
    int64_t *rows;
} nonfinite_job;

static void count_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const nonfinite_job *j = ctx;
    const sl_image *img = j->img;
    int nc = img->channels >= 3 ? 3 : 1;
    for (int64_t y = begin; y < end; y++) {
        const float *row = sl_image_pixel(img, 0, (int)y);
        int64_t n = 0;
        if (img->channels == nc) {
            /* Every sample: NaN and Inf are the all-ones exponent, tested
             * on the bits four at a time. */
            size_t count = (size_t)img->width * (size_t)nc, i = 0;
            v4i acc = {0, 0, 0, 0};
            const v4i expo = {0x7f800000, 0x7f800000, 0x7f800000, 0x7f800000};
            for (; i + 4 <= count; i += 4) {
                v4i b;
                memcpy(&b, row + i, sizeof b);
                acc -= (b & expo) == expo;
            }
            n = (int64_t)acc[0] + acc[1] + acc[2] + acc[3];
            for (; i < count; i++)
                n += !isfinite(row[i]);
            j->rows[y] = n;
            continue;
        }
        for (int x = 0; x < img->width; x++)
            for (int k = 0; k < nc; k++)
                n += !isfinite(row[(size_t)x * (size_t)img->channels + (size_t)k]);
        j->rows[y] = n;
    }
}

static int64_t count_nonfinite(const sl_image *img, sl_error *err)
{
    nonfinite_job j = {img, malloc(sizeof(int64_t) * (size_t)img->height)};
    if (!j.rows) {
        sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
        return -1;
    }
    sl_parallel_for(img->height, 64, count_rows, &j);
    int64_t n = 0;
    for (int y = 0; y < img->height; y++)
        n += j.rows[y];
    free(j.rows);
    return n;
}

/* Rows of pair[0] into the RGB image pair[1], NaN/Inf as 0. */
static void copy_rgb_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const sl_image *const *pair = ctx;
    const sl_image *photo = pair[0], *rgb = pair[1];
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < photo->width; x++) {
            const float *s = sl_image_pixel(photo, x, (int)y);
            float *d = sl_image_pixel(rgb, x, (int)y);
            for (int k = 0; k < 3; k++) {
                float v = s[photo->channels >= 3 ? k : 0];
                d[k] = isfinite(v) ? v : 0.0f;
            }
        }
}

int unwrap_auto_width(const sl_ball_view *view)
{
    /* One texel per photo pixel where the ball looks back at the camera. */
    int width = 4 * (int)ceil(2.0 * M_PI * view->centre_px_per_rad / 4.0);
    return width < 16 ? 16 : (width > 65536 ? 65536 : width);
}

/* An unwrap under way: the geometry, the photo as read, the tables. */
typedef struct unwrap_run {
    unwrap_ctx c;
    sl_ball_view *view;
    sl_image rgb; /* the photo's RGB copy when it needs one */
} unwrap_run;

static void unwrap_stop(unwrap_run *u)
{
    tables_free(&u->c);
    sl_image_free(&u->rgb);
    free(u->view);
}

/* Everything but the rows; fills info (may be NULL). */
static sl_result unwrap_start(const sl_image *photo, const sl_unwrap_options *opt,
                              unwrap_run *u, sl_unwrap_info *info, sl_error *err)
{
    memset(u, 0, sizeof *u);
    if (info)
        memset(info, 0, sizeof *info);
    if (!photo || !photo->data || !opt)
        return sl_error_set(err, SL_ERR_USAGE, "unwrap: no photo");
    const sl_reflectance *refl = &opt->reflectance;
    for (int k = 0; k < 3; k++) {
        bool bad = refl->kind == SL_REFLECTANCE_CONDUCTOR
                       ? !(refl->n[k] > 0.0 && refl->k[k] >= 0.0 && isfinite(refl->n[k]) &&
                           isfinite(refl->k[k]))
                       : !(refl->value[k] > 0.0 && isfinite(refl->value[k]));
        if (bad)
            return sl_error_set(err, SL_ERR_USAGE,
                                "ball reflectance must be positive and finite");
    }
    if (opt->width != 0 && (opt->width < 8 || opt->width > 65536 || opt->width % 2))
        return sl_error_set(err, SL_ERR_USAGE,
                            "lat-long width must be even, from 8 to 65536, not %d", opt->width);
    sl_ball_view *view = u->view = malloc(sizeof *view);
    if (!view)
        return sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
    sl_result r = sl_ball_view_init(view, photo->width, photo->height, &opt->circle,
                                    &opt->geometry, err);
    if (r)
        goto fail;
    /* An RGB photo without NaN/Inf is read in place; otherwise an RGB copy
     * with them replaced by 0. */
    int64_t nonfinite = count_nonfinite(photo, err);
    if (nonfinite < 0) {
        r = SL_ERR_NOMEM;
        goto fail;
    }
    const sl_image *src = photo;
    if (photo->channels != 3 || nonfinite) {
        if ((r = sl_image_alloc(&u->rgb, photo->width, photo->height, 3, err)))
            goto fail;
        const sl_image *pair[2] = {photo, &u->rgb};
        sl_parallel_for(photo->height, 64, copy_rgb_rows, pair);
        src = &u->rgb;
    }

    int width = opt->width ? opt->width : unwrap_auto_width(view);
    unwrap_ctx *c = &u->c;
    c->photo = src;
    c->view = view;
    c->refl = refl;
    c->width = width;
    c->height = width / 2;
    c->channels = opt->no_confidence ? 3 : 4;
    double v2w[3][3];
    sl_mat3_mul(view->cam_to_world, view->view_to_cam, v2w);
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            c->world_to_view[i][k] = v2w[k][i];
    double *ring = malloc(sizeof(double) * 3 * RING_SAMPLES);
    if (!ring) {
        r = sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
        goto fail;
    }
    for (int i = 0; i < RING_SAMPLES; i++) {
        /* The edge of the visible range, where the blind cone starts. */
        double psi = 2.0 * M_PI * (i + 0.5) / RING_SAMPLES, phi = view->phi_max;
        double dv[3] = {sin(phi) * cos(psi), sin(phi) * sin(psi), -cos(phi)}, dc[3], dw[3];
        for (int k = 0; k < 3; k++)
            dc[k] = view->view_to_cam[k][0] * dv[0] + view->view_to_cam[k][1] * dv[1] +
                    view->view_to_cam[k][2] * dv[2];
        for (int k = 0; k < 3; k++)
            dw[k] = view->cam_to_world[k][0] * dc[0] + view->cam_to_world[k][1] * dc[1] +
                    view->cam_to_world[k][2] * dc[2];
        ball_hit h;
        double rf[3];
        bool in;
        ball_view_map(view, dw, &h);
        v4f val = photo_lookup(c, h.x, h.y, &in);
        sl_reflectance_eval(refl, h.cos_incidence, rf);
        for (int k = 0; k < 3; k++)
            ring[k * RING_SAMPLES + i] = val[k] / rf[k];
    }
    for (int k = 0; k < 3; k++) {
        qsort(ring + k * RING_SAMPLES, RING_SAMPLES, sizeof(double), sl_cmp_double);
        c->blind_fill[k] = 0.5 * (ring[k * RING_SAMPLES + RING_SAMPLES / 2 - 1] +
                                  ring[k * RING_SAMPLES + RING_SAMPLES / 2]);
    }
    free(ring);
    if ((r = tables_init(c, err)))
        goto fail;
    rim_init(c);
    discs_init(c);

    if (info) {
        info->width = c->width;
        info->height = c->height;
        info->distance = view->distance;
        info->focal_px = view->focal_px;
        info->ball_angle_deg = view->ball_angle * 180.0 / M_PI;
        info->blind_angle_deg = info->ball_angle_deg;
        info->off_axis_deg = view->off_axis * 180.0 / M_PI;
        info->centre_px_per_rad = view->centre_px_per_rad;
        info->blind_fraction = 0.5 * (1.0 - cos(view->ball_angle));
        info->nonfinite = nonfinite;
    }
    return SL_OK;
fail:
    unwrap_stop(u);
    if (info)
        memset(info, 0, sizeof *info);
    return r;
}

void unwrap_use_rim_table(bool on)
{
    rim_table_off = !on;
}

void unwrap_use_portable_rows(bool on)
{
    portable_rows_only = on;
}

/* Rows y0 .. y1 - 1 into `rows` (stride floats apart). */
static void unwrap_strip(unwrap_run *u, float *rows, size_t stride, int y0, int y1)
{
    u->c.rows = rows;
    u->c.stride = stride;
    u->c.row0 = y0;
    u->c.nrows = y1 - y0;
    sl_range_fn rows_fn = unwrap_rows;
#ifdef HAVE_ROWS_WIDE
    if (!portable_rows_only && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        rows_fn = unwrap_rows_wide;
#endif
    int64_t units = (int64_t)(y1 - y0 + ROW_GRAIN - 1) / ROW_GRAIN * unit_columns(&u->c);
    sl_parallel_for(units, 1, rows_fn, &u->c);
}

sl_result sl_unwrap(const sl_image *photo, const sl_unwrap_options *opt, sl_image *out,
                    sl_unwrap_info *info, sl_error *err)
{
    memset(out, 0, sizeof *out);
    unwrap_run u;
    sl_result r = unwrap_start(photo, opt, &u, info, err);
    if (r)
        return r;
    r = sl_image_alloc(out, u.c.width, u.c.height, u.c.channels, err);
    if (!r)
        unwrap_strip(&u, out->data, out->stride, 0, out->height);
    unwrap_stop(&u);
    return r;
}

/* Strips go to the sink from a thread of its own while the next strip is
 * unwrapped: the sink's work (e.g. compressing and writing) fills the
 * cores where a strip's parallel loop runs out of rows, and vice versa.
 * With one thread, the strips go to the sink in turn. */
typedef struct strip_handoff {
    pthread_mutex_t lock;
    pthread_cond_t cond;
    bool threaded;
    const sl_unwrap_sink *sink;
    sl_error *err;
    sl_image buf[2];
    int rows[2]; /* rows in buf[i] waiting for the sink; 0: free */
    bool done;   /* no more strips */
    sl_result r; /* the sink's first failure */
} strip_handoff;

static void *strip_writer(void *arg)
{
    strip_handoff *h = arg;
    pthread_mutex_lock(&h->lock);
    for (int b = 0;; b = 1 - b) {
        while (!h->rows[b] && !h->done)
            pthread_cond_wait(&h->cond, &h->lock);
        if (!h->rows[b])
            break;
        sl_result r = h->r;
        pthread_mutex_unlock(&h->lock);
        /* After a failure the strips are dropped, so the unwrap never waits. */
        if (!r)
            r = h->sink->rows(h->sink->user, h->buf[b].data, h->rows[b], h->buf[b].stride, h->err);
        pthread_mutex_lock(&h->lock);
        h->r = r;
        h->rows[b] = 0;
        pthread_cond_broadcast(&h->cond);
    }
    pthread_mutex_unlock(&h->lock);
    return NULL;
}

/* Waits until buffer b is free; the sink's failure, if any. */
static sl_result strip_wait(strip_handoff *h, int b)
{
    if (!h->threaded)
        return h->r;
    pthread_mutex_lock(&h->lock);
    while (h->rows[b] && !h->r)
        pthread_cond_wait(&h->cond, &h->lock);
    sl_result r = h->r;
    pthread_mutex_unlock(&h->lock);
    return r;
}

static void strip_ready(strip_handoff *h, int b, int rows)
{
    if (!h->threaded) {
        h->r = h->sink->rows(h->sink->user, h->buf[b].data, rows, h->buf[b].stride, h->err);
        return;
    }
    pthread_mutex_lock(&h->lock);
    h->rows[b] = rows;
    pthread_cond_broadcast(&h->cond);
    pthread_mutex_unlock(&h->lock);
}

sl_result sl_unwrap_stream(const sl_image *photo, const sl_unwrap_options *opt,
                           const sl_unwrap_sink *sink, sl_unwrap_info *info, sl_error *err)
{
    sl_unwrap_info own;
    if (!info)
        info = &own;
    unwrap_run u;
    sl_result r = unwrap_start(photo, opt, &u, info, err);
    if (r)
        return r;
    strip_handoff hand;
    memset(&hand, 0, sizeof hand);
    hand.sink = sink;
    hand.err = err;
    int h = u.c.height, rows = h < STRIP_ROWS ? h : STRIP_ROWS;
    bool overlap = h > rows && sl_threads_get() > 1;
    if (!(r = sink->begin(sink->user, info, u.c.channels, err)))
        r = sl_image_alloc(&hand.buf[0], u.c.width, rows, u.c.channels, err);
    if (!r && overlap)
        r = sl_image_alloc(&hand.buf[1], u.c.width, rows, u.c.channels, err);
    pthread_t writer;
    if (!r && overlap) {
        pthread_mutex_init(&hand.lock, NULL);
        pthread_cond_init(&hand.cond, NULL);
        hand.threaded = pthread_create(&writer, NULL, strip_writer, &hand) == 0;
        if (!hand.threaded) {
            pthread_cond_destroy(&hand.cond);
            pthread_mutex_destroy(&hand.lock);
        }
    }
    /* Without the writer thread, one buffer in turn. */
    for (int y = 0, b = 0; y < h && !r; y += rows, b = hand.threaded ? 1 - b : 0) {
        int n = h - y < rows ? h - y : rows;
        if ((r = strip_wait(&hand, b)))
            break;
        unwrap_strip(&u, hand.buf[b].data, hand.buf[b].stride, y, y + n);
        strip_ready(&hand, b, n);
    }
    if (hand.threaded) {
        pthread_mutex_lock(&hand.lock);
        hand.done = true;
        pthread_cond_broadcast(&hand.cond);
        pthread_mutex_unlock(&hand.lock);
        pthread_join(writer, NULL);
        pthread_cond_destroy(&hand.cond);
        pthread_mutex_destroy(&hand.lock);
    }
    if (!r)
        r = hand.r;
    sl_image_free(&hand.buf[0]);
    sl_image_free(&hand.buf[1]);
    unwrap_stop(&u);
    return r;
}
