/* SPDX-License-Identifier: BSD-3-Clause */
/* The stitch's blend: fisheye views to one lat-long as a weighted mean of
 * their radiance (vignetting divided out), written a strip of rows at a
 * time, with a confidence channel, ghosts resolved to the best single view
 * and unseen or masked directions filled from the seen border. */
#include "stitch_blend_private.h"

#define IMATH_HALF_NO_LOOKUP_TABLE /* Imath's conversions alone, without libImath */
#include <Imath/half.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define DEG (M_PI / 180.0)
#define STRIP_ROWS 32
/* A view must weigh at least this in a texel to take part in the ghost test. */
#define GHOST_MIN_WEIGHT 0.25
/* A texel whose samples fall between view pixels differing by more than
 * this factor is sampled again more finely. */
#define HOT_CONTRAST 1.5

void sl_stitch_blend_options_init(sl_stitch_blend_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->max_width = 8192;
    opt->ramp_deg = 15.0;
    opt->ghost_ratio = 0.3;
    opt->noise_floor = -1.0;
}

int sl_stitch_default_width(const sl_lens *lens, int max_width)
{
    double w = 2.0 * M_PI * lens->focal_px;
    int width = (int)ceil(w / 8.0) * 8;
    if (max_width > 0 && width > max_width)
        width = max_width & ~1;
    return width < 16 ? 16 : width;
}

/* Samples per texel side: one view pixel apart on the horizon (shrinking
 * does not alias), and four times as fine on a view's hard edges, so the
 * energy of a sun a few pixels wide does not depend on where the samples
 * fall. Samples up to 10% further apart than the view's pixels count as
 * one per pixel: a 24 MP 8 mm view (8378 px around the horizon) into an
 * 8192-wide lat-long takes 1 x 1 samples per texel (4 x 4 on edges), not
 * 2 x 2 (5 x 5), for a 2% difference in density. */
static void auto_supersample(const stitch_view_prep *v, int count, int width, int *ss,
                             int *ss_hot)
{
    double f = 0;
    for (int i = 0; i < count; i++)
        f = fmax(f, v[i].lens.focal_px);
    double ratio = f * 2.0 * M_PI / width;
    int base = (int)ceil(ratio / 1.1 - 1e-9), hot = (int)ceil(4.0 * ratio / 1.1 - 1e-9);
    *ss = base < 1 ? 1 : (base > 8 ? 8 : base);
    *ss_hot = hot < *ss ? *ss : (hot > 8 ? 8 : hot);
}

/* Entries of a view's lens table: linear interpolation of the smooth
 * q(u) over them is within 1e-6 of r (a thousandth of a pixel). */
#define Q_ENTRIES 2049

static bool lens_table(stitch_view_prep *p)
{
    double u_max = 1.0 - cos(fmin(p->theta_max, M_PI));
    p->q_entries = Q_ENTRIES;
    p->u_step = fmax(u_max, 1e-9) / (Q_ENTRIES - 2); /* the last interval ends past u_max */
    p->q_table = malloc(Q_ENTRIES * sizeof *p->q_table);
    if (!p->q_table)
        return false;
    for (int i = 0; i < Q_ENTRIES; i++) {
        /* at u = 0 the limit, from a point a millionth of a step out */
        double u = i ? i * p->u_step : 1e-6 * p->u_step;
        double theta = 2.0 * asin(fmin(1.0, sqrt(0.5 * u)));
        double r = sl_lens_radius(&p->lens, fmin(theta, p->theta_max));
        p->q_table[i] = r >= 0.0 ? r * r / u : -1.0;
    }
    return true;
}

static float half_values[65536];
static pthread_once_t half_values_once = PTHREAD_ONCE_INIT;

static void half_values_fill(void)
{
    for (int h = 0; h < 65536; h++)
        half_values[h] = imath_half_to_float((imath_half_bits_t)h);
}

const float *stitch_half_table(void)
{
    pthread_once(&half_values_once, half_values_fill);
    return half_values;
}

/* Entries of a view's ramp table: sin(pi/2 (theta_max - theta) / ramp) at
 * even steps of cos(theta), nearly linear there (the weight, its square,
 * is not near the rim), so linear interpolation keeps the weight within
 * 1e-6 of its own value. */
#define RAMP_ENTRIES 4097

static bool ramp_table(stitch_view_prep *p)
{
    double span = p->cos_ramp - p->cos_max;
    if (!(span > 0.0))
        return true; /* no ramp: the weight is never looked up */
    p->ramp_entries = RAMP_ENTRIES;
    p->ramp_step_inv = (RAMP_ENTRIES - 1) / span;
    p->ramp_table = malloc(RAMP_ENTRIES * sizeof *p->ramp_table);
    if (!p->ramp_table)
        return false;
    for (int i = 0; i < RAMP_ENTRIES; i++) {
        double c = i == RAMP_ENTRIES - 1 ? p->cos_ramp : p->cos_max + i / p->ramp_step_inv;
        double theta = acos(fmax(-1.0, fmin(1.0, c)));
        p->ramp_table[i] = theta >= p->theta_max ? 0.0
                                                 : sin(0.5 * M_PI * (p->theta_max - theta) / p->ramp);
    }
    return true;
}

/* stitch_view_weight at cos(theta) = c: (1 + c) / 2, times the square of
 * the ramp's sine from the table over the ramp. */
static inline double ramp_weight(const stitch_view_prep *v, double c)
{
    if (c > v->cos_ramp)
        return 0.5 * (1.0 + c);
    if (!v->ramp_table)
        return stitch_view_weight(v, acos(c < 1.0 ? c : 1.0));
    double t = (c - v->cos_max) * v->ramp_step_inv;
    if (!(t > 0.0))
        return 0.0;
    int i = (int)t;
    double r = i >= v->ramp_entries - 1
                   ? v->ramp_table[v->ramp_entries - 1]
                   : v->ramp_table[i] + (t - i) * (v->ramp_table[i + 1] - v->ramp_table[i]);
    return 0.5 * (1.0 + c) * r * r;
}

sl_result stitch_prepare_views(const sl_stitch_view *views, int count,
                               const sl_stitch_blend_options *opt,
                               const stitch_half_image *half, bool scanned,
                               stitch_view_prep *prep, sl_error *err)
{
    if (count < 1 || count > SL_STITCH_MAX_VIEWS)
        return sl_error_set(err, SL_ERR_USAGE, "stitch: 1 to %d views, not %d",
                            SL_STITCH_MAX_VIEWS, count);
    for (int i = 0; i < count; i++) {
        const sl_stitch_view *v = &views[i];
        stitch_view_prep *p = &prep[i];
        memset(p, 0, sizeof *p);
        const char *name = v->name ? v->name : "view";
        const sl_image *img = v->radiance;
        const stitch_half_image *hv = half && half[i].rgb ? &half[i] : NULL;
        if (!hv && (!img || !img->data || img->channels < 3))
            return sl_error_set(err, SL_ERR_INPUT, "%s: not an RGB image", name);
        int iw = hv ? hv->width : img->width, ih = hv ? hv->height : img->height;
        if (iw != v->lens.width || ih != v->lens.height)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: the image is %dx%d but its lens is for %dx%d", name,
                                iw, ih, v->lens.width, v->lens.height);
        if (v->weight && (v->weight->width != iw || v->weight->height != ih))
            return sl_error_set(err, SL_ERR_INPUT, "%s: the confidence image is %dx%d, not %dx%d",
                                name, v->weight->width, v->weight->height, iw, ih);
        if (!(v->lens.focal_px > 0) || !(v->lens.max_theta_deg > 0))
            return sl_error_set(err, SL_ERR_INPUT, "%s: lens without a focal length or field",
                                name);
        int64_t bad = 0;
        for (int y = 0; !hv && !scanned && y < img->height; y++) {
            const float *row = sl_image_pixel(img, 0, y);
            for (int x = 0; x < img->width; x++)
                for (int c = 0; c < 3; c++)
                    bad += !isfinite(row[x * img->channels + c]);
        }
        if (bad)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: %lld NaN/Inf samples (a damaged file: merge never writes "
                                "them)",
                                name, (long long)bad);
        p->lens = v->lens;
        p->radiance = hv ? NULL : img;
        p->half = hv;
        p->half_table = hv ? stitch_half_table() : NULL;
        if (hv && hv->exp2) { /* every pattern's value times 2^exp2: exact in float */
            if (!(p->scaled_table = malloc(65536 * sizeof *p->scaled_table)))
                return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
            for (int k = 0; k < 65536; k++)
                p->scaled_table[k] = ldexpf(p->half_table[k], hv->exp2);
            p->half_table = p->scaled_table;
        }
        p->weight = v->weight;
        double m[3][3];
        sl_view_pose_matrix(&v->pose, m);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                p->to_cam[r][c] = m[c][r];
        for (int r = 0; r < 3; r++)
            p->axis[r] = m[r][2];
        double tmax = v->lens.max_theta_deg * DEG;
        double ramp = fmin(fmax(opt->ramp_deg, 0.0), v->lens.max_theta_deg) * DEG;
        p->theta_max = tmax;
        p->cos_max = cos(fmin(tmax, M_PI));
        p->ramp = ramp;
        p->cos_ramp = cos(fmax(0.0, tmax - ramp));
        if (!lens_table(p) || !ramp_table(p))
            return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
    }
    return SL_OK;
}

void stitch_release_views(stitch_view_prep *prep, int count)
{
    for (int i = 0; i < count; i++) {
        free(prep[i].q_table);
        prep[i].q_table = NULL;
        free(prep[i].ramp_table);
        prep[i].ramp_table = NULL;
        free(prep[i].scaled_table);
        prep[i].scaled_table = NULL;
    }
}


double stitch_view_weight(const stitch_view_prep *v, double theta)
{
    if (theta >= v->theta_max)
        return 0.0;
    double w = 0.5 * (1.0 + cos(theta));
    double d = v->theta_max - theta;
    if (v->ramp > 0 && d < v->ramp) {
        double s = sin(0.5 * M_PI * d / v->ramp);
        w *= s * s;
    }
    return w;
}

/* Bilinear lookup of channels [0, n) at pixel position (x, y) (pixel
 * centres at +0.5), clamped to the image; *contrast (may be NULL) the ratio
 * of the largest to the smallest of the four pixels' channel 1 (or 0). */
static inline void bilinear(const sl_image *img, double x, double y, int n, double *out,
                            double *contrast)
{
    sl_bilinear b = sl_bilinear_at(img->width, img->height, x, y);
    const float *p00 = sl_image_pixel(img, b.x0, b.y0), *p10 = sl_image_pixel(img, b.x1, b.y0);
    const float *p01 = sl_image_pixel(img, b.x0, b.y1), *p11 = sl_image_pixel(img, b.x1, b.y1);
    double w00 = (1 - b.ay) * (1 - b.ax), w10 = (1 - b.ay) * b.ax;
    double w01 = b.ay * (1 - b.ax), w11 = b.ay * b.ax;
    for (int c = 0; c < n; c++)
        out[c] = w00 * p00[c] + w10 * p10[c] + w01 * p01[c] + w11 * p11[c];
    if (contrast) {
        int g = n > 1 ? 1 : 0;
        float a = p00[g], bb = p10[g], c = p01[g], d = p11[g];
        float lo0 = a < bb ? a : bb, lo1 = c < d ? c : d, hi0 = a < bb ? bb : a,
              hi1 = c < d ? d : c;
        float lo = lo0 < lo1 ? lo0 : lo1, hi = hi0 < hi1 ? hi1 : hi0;
        *contrast = hi / (lo > 1e-30f ? (double)lo : 1e-30);
    }
}

/* The four pixels of a bilinear lookup in a half view. */
static inline void half_corners(const stitch_half_image *img, const sl_bilinear *b,
                                const uint16_t **h00, const uint16_t **h10,
                                const uint16_t **h01, const uint16_t **h11)
{
    size_t w = (size_t)img->width;
    *h00 = img->rgb + ((size_t)b->y0 * w + b->x0) * 3;
    *h10 = img->rgb + ((size_t)b->y0 * w + b->x1) * 3;
    *h01 = img->rgb + ((size_t)b->y1 * w + b->x0) * 3;
    *h11 = img->rgb + ((size_t)b->y1 * w + b->x1) * 3;
}

/* bilinear() of a half view's RGB, each sample converted by the table:
 * the same sums as on the float view it was made from. */
static inline void bilinear_half(const stitch_half_image *img, const float *table, double x,
                                 double y, double *out, double *contrast)
{
    sl_bilinear b = sl_bilinear_at(img->width, img->height, x, y);
    const uint16_t *h00, *h10, *h01, *h11;
    half_corners(img, &b, &h00, &h10, &h01, &h11);
    double w00 = (1 - b.ay) * (1 - b.ax), w10 = (1 - b.ay) * b.ax;
    double w01 = b.ay * (1 - b.ax), w11 = b.ay * b.ax;
    for (int c = 0; c < 3; c++)
        out[c] = w00 * table[h00[c]] + w10 * table[h10[c]] + w01 * table[h01[c]] +
                 w11 * table[h11[c]];
    float a = table[h00[1]], bb = table[h10[1]], c = table[h01[1]], d = table[h11[1]];
    float lo0 = a < bb ? a : bb, lo1 = c < d ? c : d, hi0 = a < bb ? bb : a, hi1 = c < d ? d : c;
    float lo = lo0 < lo1 ? lo0 : lo1, hi = hi0 < hi1 ? hi1 : hi0;
    *contrast = hi / (lo > 1e-30f ? (double)lo : 1e-30);
}

/* A view's merge confidence at (x, y), within [0, 1]. */
static inline double confidence_at(const sl_image *weight, double x, double y)
{
    double conf;
    bilinear(weight, x, y, 1, &conf, NULL);
    return conf < 0.0 ? 0.0 : (conf > 1.0 ? 1.0 : conf);
}

static double luminance(const double *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* One pass over the lat-long at one width: the geometry shared by its rows. */
typedef struct blend_pass {
    const stitch_view_prep *views;
    int count;
    const sl_stitch_blend_options *opt;
    int width, height, ss;
    int ss_hot;                /* samples per side where a view has a hard edge */
    double *sin_lon, *cos_lon; /* width * ss sub-columns */
    double *sin_lat, *cos_lat; /* height * ss sub-rows */
    double *sin_lon_hot, *cos_lon_hot, *sin_lat_hot, *cos_lat_hot; /* the same at ss_hot */
    double nadir_lat;          /* latitudes below are masked; -inf: none */
    double noise_floor;
    bool ghosts;
    const sl_image *fill;      /* coarse filled lat-long, or NULL */
    float *rows;               /* STRIP_ROWS rows of width * 4: the strip being blended */
    int y0;                    /* first row of the strip */
    stitch_row_stats *stats;   /* per row of the strip */
    stitch_ray_view rays[SL_STITCH_MAX_VIEWS]; /* the views for the float row loop */
    float *sin_lon_f, *cos_lon_f;              /* sin_lon, cos_lon in float */
    float *sin_lon_hot_f, *cos_lon_hot_f;      /* sin_lon_hot, cos_lon_hot in float */
    struct row_scratch *scratch;               /* per worker */
    bool f16c;                                 /* half lookups through F16C */
    int workers;
} blend_pass;

static bool masked(const blend_pass *p, double u, double v, double lat)
{
    if (lat < p->nadir_lat)
        return true;
    const sl_image *m = p->opt->mask;
    if (!m)
        return false;
    int mx = (int)(u * m->width), my = (int)(v * m->height);
    mx = mx < 0 ? 0 : (mx >= m->width ? m->width - 1 : mx);
    my = my < 0 ? 0 : (my >= m->height ? m->height - 1 : my);
    return sl_image_pixel(m, mx, my)[0] > 0.5f;
}

/* The columns of one lat-long row a view can see: every texel within
 * half_cols of centre (wrapping round), or all, or none. */
typedef struct row_span {
    bool all, none;
    double centre, half_cols;
} row_span;

/* The largest cosine between a view's axis (latitude sin_a / cos_a) and a
 * direction dlon off its longitude, over latitudes [lat0, lat1]:
 * sin_a sin(lat) + cos_a cos(dlon) cos(lat) = R cos(lat - lat*). */
static double max_cos_in_band(double sin_a, double cos_a, double dlon, double lat0, double lat1)
{
    double a = sin_a, b = cos_a * cos(dlon);
    double peak = atan2(a, b);
    if (peak >= lat0 && peak <= lat1)
        return hypot(a, b);
    return fmax(a * sin(lat0) + b * cos(lat0), a * sin(lat1) + b * cos(lat1));
}

/* Per view, the columns of row y its field reaches: its cosine to a
 * direction falls as the longitude moves away from its axis's (cos(lat)
 * >= 0), so the reach is found by bisection, then widened by a column so
 * no sample the view sees is skipped. */
static void row_spans(const blend_pass *p, int y, row_span *span)
{
    const int W = p->width, H = p->height;
    double lat0 = M_PI * (0.5 - (y + 1.0) / H), lat1 = M_PI * (0.5 - (double)y / H);
    for (int k = 0; k < p->count; k++) {
        const stitch_view_prep *v = &p->views[k];
        row_span *s = &span[k];
        double sin_a = fmax(-1.0, fmin(1.0, v->axis[1])), cos_a = sqrt(1.0 - sin_a * sin_a);
        double floor_cos = v->cos_max - 1e-9;
        s->all = max_cos_in_band(sin_a, cos_a, M_PI, lat0, lat1) >= floor_cos;
        s->none = !s->all && max_cos_in_band(sin_a, cos_a, 0.0, lat0, lat1) < floor_cos;
        if (s->all || s->none)
            continue;
        double lo = 0.0, hi = M_PI; /* reached at lo, not at hi */
        for (int it = 0; it < 40; it++) {
            double mid = 0.5 * (lo + hi);
            if (max_cos_in_band(sin_a, cos_a, mid, lat0, lat1) >= floor_cos)
                lo = mid;
            else
                hi = mid;
        }
        /* column x's centre is at longitude pi (1 - 2 (x + 0.5) / W) */
        double lon_a = atan2(v->axis[0], v->axis[2]);
        s->centre = (0.5 - lon_a / (2.0 * M_PI)) * W - 0.5;
        s->half_cols = hi / (2.0 * M_PI) * W + 1.5;
    }
}

static inline bool span_has(const row_span *s, int x, int W)
{
    if (s->all)
        return true;
    if (s->none)
        return false;
    double d = x - s->centre; /* centre in [-0.5, W): d in (-W, W + 0.5) */
    if (d < 0.0)
        d += W;
    else if (d >= W)
        d -= W;
    return d <= s->half_cols || W - d <= s->half_cols;
}

/* seen[x] = span_has(s, x, W) for every column, span_has asked only at
 * the arc's two ends: the columns within half_cols of the centre are one
 * run round the seam. */
static void span_fill(const row_span *s, int W, bool *seen)
{
    if (s->all || s->none || 2.0 * s->half_cols + 4.0 >= W) {
        for (int x = 0; x < W; x++)
            seen[x] = span_has(s, x, W);
        return;
    }
    memset(seen, 0, (size_t)W);
    /* the arc (lo, hi) in unwrapped columns, each end moved to where
     * span_has changes */
    int lo = (int)floor(s->centre - s->half_cols), hi = (int)ceil(s->centre + s->half_cols);
#define WRAP(x) (((x) % W + W) % W)
    while (span_has(s, WRAP(lo), W))
        lo--;
    while (!span_has(s, WRAP(lo + 1), W) && lo + 1 < hi)
        lo++;
    while (span_has(s, WRAP(hi), W))
        hi++;
    while (!span_has(s, WRAP(hi - 1), W) && hi - 1 > lo)
        hi--;
    /* fewer than W columns: one run, or two across the seam */
    int a = WRAP(lo + 1), len = hi - lo - 1;
#undef WRAP
    int first = a + len <= W ? len : W - a;
    memset(seen + a, 1, (size_t)first);
    memset(seen, 1, (size_t)(len - first));
}

/* Adds texel (x, y)'s ss x ss samples to the views' sums; true when a
 * sample fell on a high-contrast spot of a view (worth more samples).
 * seen: the views whose field reaches the texel. */
static bool texel_samples(const blend_pass *p, int x, int y, int ss, const bool *seen,
                          double *acc_w, double (*acc_l)[3], double *area, double *masked_area)
{
    const int W = p->width, H = p->height, n = p->count;
    bool hot = false;
    bool base = ss == p->ss;
    const double *slon = base ? p->sin_lon : p->sin_lon_hot, *clon = base ? p->cos_lon : p->cos_lon_hot;
    const double *slat = base ? p->sin_lat : p->sin_lat_hot, *clat = base ? p->cos_lat : p->cos_lat_hot;
    const bool masking = p->opt->mask || p->nadir_lat > -INFINITY;
    for (int j = 0; j < ss; j++) {
        double v = (y + (j + 0.5) / ss) / H, lat = M_PI * (0.5 - v);
        double sin_lat = slat[y * ss + j], cos_lat = clat[y * ss + j];
        for (int i = 0; i < ss; i++) {
            double a = cos_lat;
            *area += a;
            if (masking && masked(p, (x + (i + 0.5) / ss) / W, v, lat)) {
                *masked_area += a;
                continue;
            }
            double sin_lon = slon[x * ss + i], cos_lon = clon[x * ss + i];
            double d[3] = {sin_lon * cos_lat, sin_lat, cos_lon * cos_lat};
            for (int k = 0; k < n; k++) {
                if (!seen[k])
                    continue;
                const stitch_view_prep *vw = &p->views[k];
                double c = vw->axis[0] * d[0] + vw->axis[1] * d[1] + vw->axis[2] * d[2];
                if (c < vw->cos_max)
                    continue;
                double ray[3], px, py, r2;
                for (int r = 0; r < 3; r++)
                    ray[r] = vw->to_cam[r][0] * d[0] + vw->to_cam[r][1] * d[1] +
                             vw->to_cam[r][2] * d[2];
                if (!stitch_view_pixel(vw, ray, &px, &py, &r2))
                    continue;
                double w = ramp_weight(vw, c);
                if (vw->weight)
                    w *= confidence_at(vw->weight, px, py);
                if (!(w > 0))
                    continue;
                double rgb[3], contrast;
                if (vw->half)
                    bilinear_half(vw->half, vw->half_table, px, py, rgb, &contrast);
                else
                    bilinear(vw->radiance, px, py, 3, rgb, &contrast);
                hot |= contrast > HOT_CONTRAST;
                double s2 = r2 / (vw->lens.focal_px * vw->lens.focal_px);
                const double *vg = vw->lens.vignette;
                double g = 1.0 + s2 * (vg[0] + s2 * (vg[1] + s2 * vg[2])); /* sl_lens_vignette */
                if (!(g > 1e-6))
                    continue;
                w *= a;
                acc_w[k] += w;
                double wg = w / g;
                for (int ch = 0; ch < 3; ch++)
                    acc_l[k][ch] += rgb[ch] > 0.0 ? wg * rgb[ch] : 0.0;
            }
        }
    }
    return hot;
}

/* What a worker's rows are computed in: per sample of a sub-row the view
 * pixel, weight and 1 / gain (stitch_rays), per texel and view the sums. */
typedef struct row_scratch {
    float *px, *py, *weight, *inv_gain; /* width * ss */
    double *acc;                        /* count * width * 4: weight, then RGB */
    double *masked_area;                /* width */
    bool *hot;                          /* width */
    bool *seen;                         /* width * count */
    bool *skip;                         /* width * ss: masked samples */
    /* the row's hot texels, their ss_hot samples per sub-row packed */
    int *hot_x;                          /* width: the hot texels' columns */
    float *hot_sin, *hot_cos;            /* width * ss_hot: their longitudes */
    float *hot_px, *hot_py, *hot_weight, *hot_inv_gain; /* width * ss_hot */
    bool *hot_skip;                      /* width * ss_hot */
    double *hot_acc;                     /* count * width * 4 */
    double *hot_masked_area;             /* width */
} row_scratch;

static void scratch_free(row_scratch *s)
{
    free(s->px), free(s->py), free(s->weight), free(s->inv_gain);
    free(s->acc), free(s->masked_area), free(s->hot), free(s->seen), free(s->skip);
    free(s->hot_x), free(s->hot_sin), free(s->hot_cos), free(s->hot_px), free(s->hot_py);
    free(s->hot_weight), free(s->hot_inv_gain), free(s->hot_skip), free(s->hot_acc);
    free(s->hot_masked_area);
    memset(s, 0, sizeof *s);
}

static bool scratch_alloc(row_scratch *s, int width, int ss, int ss_hot, int count)
{
    size_t n = (size_t)width * ss, nh = (size_t)width * ss_hot;
    s->px = malloc(n * sizeof(float));
    s->py = malloc(n * sizeof(float));
    s->weight = malloc(n * sizeof(float));
    s->inv_gain = malloc(n * sizeof(float));
    s->acc = malloc((size_t)width * count * 4 * sizeof(double));
    s->masked_area = malloc((size_t)width * sizeof(double));
    s->hot = malloc((size_t)width);
    s->seen = malloc((size_t)width * count);
    s->skip = malloc(n);
    s->hot_x = malloc((size_t)width * sizeof(int));
    s->hot_sin = malloc(nh * sizeof(float));
    s->hot_cos = malloc(nh * sizeof(float));
    s->hot_px = malloc(nh * sizeof(float));
    s->hot_py = malloc(nh * sizeof(float));
    s->hot_weight = malloc(nh * sizeof(float));
    s->hot_inv_gain = malloc(nh * sizeof(float));
    s->hot_skip = malloc(nh);
    s->hot_acc = malloc((size_t)width * count * 4 * sizeof(double));
    s->hot_masked_area = malloc((size_t)width * sizeof(double));
    if (s->px && s->py && s->weight && s->inv_gain && s->acc && s->masked_area && s->hot &&
        s->seen && s->skip && s->hot_x && s->hot_sin && s->hot_cos && s->hot_px && s->hot_py &&
        s->hot_weight && s->hot_inv_gain && s->hot_skip && s->hot_acc && s->hot_masked_area)
        return true;
    scratch_free(s);
    return false;
}

/* Whether four pixels' G differ by more than HOT_CONTRAST (as bilinear()'s
 * contrast; no libm calls: fminf is not inlined). */
static inline bool hot_pixels(float a, float b, float c, float d)
{
    float lo0 = a < b ? a : b, lo1 = c < d ? c : d, hi0 = a < b ? b : a, hi1 = c < d ? d : c;
    float lo = lo0 < lo1 ? lo0 : lo1, hi = hi0 < hi1 ? hi1 : hi0;
    return hi > HOT_CONTRAST * (lo > 1e-30f ? lo : 1e-30f);
}

/* The half view's bilinear lookup in float (the table's values, the
 * weights of sl_bilinear_at); true when its four pixels' G differ by more
 * than HOT_CONTRAST. */
static inline __attribute__((always_inline)) bool fetch_half(const stitch_half_image *img, const float *table, float x, float y,
                              float rgb[3])
{
    sl_bilinear b = sl_bilinear_at(img->width, img->height, x, y);
    const uint16_t *h00, *h10, *h01, *h11;
    half_corners(img, &b, &h00, &h10, &h01, &h11);
    float ax = (float)b.ax, ay = (float)b.ay;
    float w00 = (1 - ay) * (1 - ax), w10 = (1 - ay) * ax, w01 = ay * (1 - ax), w11 = ay * ax;
    for (int c = 0; c < 3; c++)
        rgb[c] = w00 * table[h00[c]] + w10 * table[h10[c]] + w01 * table[h01[c]] +
                 w11 * table[h11[c]];
    return hot_pixels(table[h00[1]], table[h10[1]], table[h01[1]], table[h11[1]]);
}

#ifdef STITCH_HAVE_F16C_ASM
/* fetch_half() with each corner's RGB converted at once: two loads and two
 * conversions a row instead of twelve table lookups, the same float
 * operations in the same order (scaling by 2^exp2 is exact): the same
 * bytes. A corner's fourth half is the next pixel's red, so the view's
 * last pixel takes the table. */
static inline __attribute__((always_inline)) bool fetch_half_f16c(const stitch_half_image *img,
                                                                  const float *table,
                                                                  float scale_by, float x,
                                                                  float y, float rgb[3])
{
    sl_bilinear b = sl_bilinear_at(img->width, img->height, x, y);
    if (b.y1 == img->height - 1 && b.x1 == img->width - 1)
        return fetch_half(img, table, x, y, rgb);
    const uint16_t *h00, *h10, *h01, *h11;
    half_corners(img, &b, &h00, &h10, &h01, &h11);
    __m128 scale = _mm_set1_ps(scale_by);
    __m128 p00 = _mm_mul_ps(stitch_halves_to_floats(h00), scale);
    __m128 p10 = _mm_mul_ps(stitch_halves_to_floats(h10), scale);
    __m128 p01 = _mm_mul_ps(stitch_halves_to_floats(h01), scale);
    __m128 p11 = _mm_mul_ps(stitch_halves_to_floats(h11), scale);
    float ax = (float)b.ax, ay = (float)b.ay;
    float w00 = (1 - ay) * (1 - ax), w10 = (1 - ay) * ax, w01 = ay * (1 - ax), w11 = ay * ax;
    __m128 v = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(w00), p00),
                                                _mm_mul_ps(_mm_set1_ps(w10), p10)),
                                     _mm_mul_ps(_mm_set1_ps(w01), p01)),
                          _mm_mul_ps(_mm_set1_ps(w11), p11));
    float out[4], lo[4], hi[4];
    _mm_storeu_ps(out, v);
    _mm_storeu_ps(lo, _mm_min_ps(_mm_min_ps(p00, p10), _mm_min_ps(p01, p11)));
    _mm_storeu_ps(hi, _mm_max_ps(_mm_max_ps(p00, p10), _mm_max_ps(p01, p11)));
    rgb[0] = out[0], rgb[1] = out[1], rgb[2] = out[2];
    return hi[1] > HOT_CONTRAST * (lo[1] > 1e-30f ? lo[1] : 1e-30f); /* as hot_pixels() */
}
#endif

/* A half view's lookup, through F16C where the pass has it (scale: the
 * view's 2^exp2, made once by the caller: ldexpf is a library call). */
static inline __attribute__((always_inline)) bool fetch_half_any(const stitch_half_image *img,
                                                                 const float *table, bool f16c,
                                                                 float scale, float x, float y,
                                                                 float rgb[3])
{
#ifdef STITCH_HAVE_F16C_ASM
    if (f16c)
        return fetch_half_f16c(img, table, scale, x, y, rgb);
#else
    (void)f16c, (void)scale;
#endif
    return fetch_half(img, table, x, y, rgb);
}

/* The same of a float view. */
static inline __attribute__((always_inline)) bool fetch_float(const sl_image *img, float x, float y, float rgb[3])
{
    sl_bilinear b = sl_bilinear_at(img->width, img->height, x, y);
    const float *p00 = sl_image_pixel(img, b.x0, b.y0), *p10 = sl_image_pixel(img, b.x1, b.y0);
    const float *p01 = sl_image_pixel(img, b.x0, b.y1), *p11 = sl_image_pixel(img, b.x1, b.y1);
    float ax = (float)b.ax, ay = (float)b.ay;
    float w00 = (1 - ay) * (1 - ax), w10 = (1 - ay) * ax, w01 = ay * (1 - ax), w11 = ay * ax;
    for (int c = 0; c < 3; c++)
        rgb[c] = w00 * p00[c] + w10 * p10[c] + w01 * p01[c] + w11 * p11[c];
    return hot_pixels(p00[1], p10[1], p01[1], p11[1]);
}

bool stitch_blend_reference = false;

/* One sample of view vw at its pixel (x, y), blend weight w, vignetting
 * 1 / gain inv_gain and area a, added to its texel's sums acc (weight,
 * then RGB). Returns whether its four pixels' G differ by more than
 * HOT_CONTRAST (false where its confidence is 0: not looked up). */
static inline __attribute__((always_inline)) bool add_sample(const blend_pass *p,
                                                             const stitch_view_prep *vw,
                                                             float scale, float x, float y,
                                                             float w, float inv_gain, double a,
                                                             double *acc)
{
    double wd = w;
    if (vw->weight && !((wd *= confidence_at(vw->weight, x, y)) > 0))
        return false;
    float rgb[3];
    bool hot = vw->half ? fetch_half_any(vw->half, vw->half_table, p->f16c, scale, x, y, rgb)
                        : fetch_float(vw->radiance, x, y, rgb);
    if (!(inv_gain > 0.0f))
        return hot;
    wd *= a;
    acc[0] += wd;
    double wg = wd * inv_gain;
    for (int ch = 0; ch < 3; ch++)
        acc[1 + ch] += rgb[ch] > 0.0f ? wg * rgb[ch] : 0.0;
    return hot;
}

/* Samples ahead whose view pixels are fetched into the cache. */
#define PREFETCH_AHEAD 16

/* Asks for the cache lines a lookup at (x, y) will read: the first load of
 * a view pixel is what the sample loops wait on. */
static inline void prefetch_pixel(const stitch_half_image *hv, float x, float y)
{
    int px = (int)x, py = (int)y;
    px = px < 1 ? 0 : (px >= hv->width ? hv->width - 1 : px - 1);
    py = py < 1 ? 0 : (py >= hv->height ? hv->height - 1 : py - 1);
    const uint16_t *row = hv->rgb + ((size_t)py * hv->width + px) * 3;
    __builtin_prefetch(row);
    __builtin_prefetch(row + (size_t)hv->width * 3);
}

/* The row's base samples of view k over texels [x0, x1): their pixels and
 * weights 8 at a time (stitch_rays), then each sample's lookup added to its
 * texel's sums. */
static void run_samples(const blend_pass *p, row_scratch *sc, int k, int y, int j, int x0, int x1)
{
    const int ss = p->ss;
    const stitch_view_prep *vw = &p->views[k];
    int s0 = x0 * ss, ns = (x1 - x0) * ss;
    double *acc_k = sc->acc + (size_t)k * p->width * 4;
    if (j == 0) /* the run's texels: only they are read for this view */
        memset(acc_k + (size_t)x0 * 4, 0, (size_t)(x1 - x0) * 4 * sizeof(double));
    float sin_lat = (float)p->sin_lat[y * ss + j], cos_lat = (float)p->cos_lat[y * ss + j];
    double a = p->cos_lat[y * ss + j];
    stitch_rays(&p->rays[k], p->sin_lon_f + s0, p->cos_lon_f + s0, sin_lat, cos_lat, ns,
                sc->px + s0, sc->py + s0, sc->weight + s0, sc->inv_gain + s0);
    const stitch_half_image *hv = vw->half;
    const float scale = hv ? ldexpf(1.0f, hv->exp2) : 1.0f;
    for (int s = s0; s < s0 + ns; s++) {
        if (hv && s + PREFETCH_AHEAD < s0 + ns && sc->weight[s + PREFETCH_AHEAD] > 0.0f)
            prefetch_pixel(hv, sc->px[s + PREFETCH_AHEAD], sc->py[s + PREFETCH_AHEAD]);
        if (sc->weight[s] > 0.0f && !sc->skip[s])
            sc->hot[s / ss] |= add_sample(p, vw, scale, sc->px[s], sc->py[s], sc->weight[s],
                                          sc->inv_gain[s], a, acc_k + (size_t)(s / ss) * 4);
    }
}

/* Adds every texel's base samples of row y to the sums in sc (area: the
 * texels' common area). The views run over the row one after the other,
 * each over the columns its field reaches. */
static void row_samples(const blend_pass *p, int y, row_scratch *sc, double *area)
{
    const int W = p->width, H = p->height, ss = p->ss, n = p->count;
    const bool masking = p->opt->mask || p->nadir_lat > -INFINITY;
    memset(sc->hot, 0, (size_t)W);
    *area = 0;
    for (int j = 0; j < ss; j++)
        for (int i = 0; i < ss; i++)
            *area += p->cos_lat[y * ss + j];
    for (int x = 0; x < W; x++)
        sc->masked_area[x] = 0;
    for (int j = 0; j < ss; j++) {
        double v = (y + (j + 0.5) / ss) / H, lat = M_PI * (0.5 - v);
        memset(sc->skip, 0, (size_t)W * ss);
        for (int s = 0; masking && s < W * ss; s++)
            if (masked(p, (s / ss + (s % ss + 0.5) / ss) / W, v, lat)) {
                sc->skip[s] = true;
                sc->masked_area[s / ss] += p->cos_lat[y * ss + j];
            }
        for (int k = 0; k < n; k++) {
            const bool *seen = sc->seen + (size_t)k * W;
            for (int x = 0; x < W;) {
                if (!seen[x]) {
                    x++;
                    continue;
                }
                int x1 = x;
                while (x1 < W && seen[x1])
                    x1++;
                run_samples(p, sc, k, y, j, x, x1);
                x = x1;
            }
        }
    }
}

/* The row's nhot hot texels (columns sc->hot_x) sampled ss_hot x ss_hot as
 * the base samples are (stitch_rays in float, the sums in double): their
 * samples packed one texel after another, each sub-row through each view
 * once, each lookup added to its texel's sums in sc->hot_acc. */
static void hot_samples(const blend_pass *p, int y, row_scratch *sc, int nhot)
{
    const int W = p->width, H = p->height, hs = p->ss_hot, n = p->count, ns = nhot * hs;
    const bool masking = p->opt->mask || p->nadir_lat > -INFINITY;
    memset(sc->hot_acc, 0, (size_t)n * nhot * 4 * sizeof(double));
    memset(sc->hot_masked_area, 0, (size_t)nhot * sizeof(double));
    bool reaches[SL_STITCH_MAX_VIEWS] = {false}; /* views that see one of them */
    for (int t = 0; t < nhot; t++) {
        size_t from = (size_t)sc->hot_x[t] * hs;
        memcpy(sc->hot_sin + (size_t)t * hs, p->sin_lon_hot_f + from, (size_t)hs * sizeof(float));
        memcpy(sc->hot_cos + (size_t)t * hs, p->cos_lon_hot_f + from, (size_t)hs * sizeof(float));
        for (int k = 0; k < n; k++)
            reaches[k] |= sc->seen[(size_t)k * W + sc->hot_x[t]];
    }
    for (int j = 0; j < hs; j++) {
        int row = y * hs + j;
        double v = (y + (j + 0.5) / hs) / H, lat = M_PI * (0.5 - v), a = p->cos_lat_hot[row];
        for (int s = 0; s < ns; s++) {
            int x = sc->hot_x[s / hs];
            sc->hot_skip[s] = masking && masked(p, (x + (s % hs + 0.5) / hs) / W, v, lat);
            if (sc->hot_skip[s])
                sc->hot_masked_area[s / hs] += a;
        }
        float sin_lat = (float)p->sin_lat_hot[row], cos_lat = (float)p->cos_lat_hot[row];
        for (int k = 0; k < n; k++) {
            const stitch_view_prep *vw = &p->views[k];
            const bool *seen = sc->seen + (size_t)k * W;
            if (!reaches[k])
                continue;
            stitch_rays(&p->rays[k], sc->hot_sin, sc->hot_cos, sin_lat, cos_lat, ns, sc->hot_px,
                        sc->hot_py, sc->hot_weight, sc->hot_inv_gain);
            double *acc_k = sc->hot_acc + (size_t)k * nhot * 4;
            const stitch_half_image *hv = vw->half;
            const float scale = hv ? ldexpf(1.0f, hv->exp2) : 1.0f;
            for (int s = 0; s < ns; s++) {
                if (hv && s + PREFETCH_AHEAD < ns && sc->hot_weight[s + PREFETCH_AHEAD] > 0.0f)
                    prefetch_pixel(hv, sc->hot_px[s + PREFETCH_AHEAD], sc->hot_py[s + PREFETCH_AHEAD]);
                if (sc->hot_weight[s] > 0.0f && !sc->hot_skip[s] && seen[sc->hot_x[s / hs]])
                    add_sample(p, vw, scale, sc->hot_px[s], sc->hot_py[s], sc->hot_weight[s],
                               sc->hot_inv_gain[s], a, acc_k + (size_t)(s / hs) * 4);
            }
        }
    }
}

/* A texel's sums per view from acc (view k's at acc + k * view_stride, 4
 * doubles: weight, then RGB), zero for the views that do not reach it. */
static void take_sums(const double *acc, size_t view_stride, const bool *seen, int n,
                      double *acc_w, double (*acc_l)[3])
{
    for (int k = 0; k < n; k++) {
        const double *a = acc + (size_t)k * view_stride;
        acc_w[k] = seen[k] ? a[0] : 0.0;
        for (int ch = 0; ch < 3; ch++)
            acc_l[k][ch] = seen[k] ? a[1 + ch] : 0.0;
    }
}

static void blend_row(const blend_pass *p, int y, float *out, stitch_row_stats *st,
                      row_scratch *sc)
{
    const int W = p->width, H = p->height, n = p->count;
    memset(st, 0, sizeof *st);
    double texel_sr = sl_latlong_texel_solid_angle(y, W, H);
    row_span span[SL_STITCH_MAX_VIEWS];
    row_spans(p, y, span);
    for (int k = 0; k < n; k++)
        span_fill(&span[k], W, sc->seen + (size_t)k * W);
    double row_area = 0, hot_area = 0;
    int nhot = 0, hot_next = 0; /* the row's hot texels; the next one's slot in sc->hot_acc */
    if (!stitch_blend_reference) {
        row_samples(p, y, sc, &row_area);
        for (int x = 0; p->ss_hot > p->ss && x < W; x++)
            if (sc->hot[x])
                sc->hot_x[nhot++] = x;
        if (nhot > 0) {
            hot_samples(p, y, sc, nhot);
            for (int j = 0; j < p->ss_hot; j++)
                for (int i = 0; i < p->ss_hot; i++)
                    hot_area += p->cos_lat_hot[y * p->ss_hot + j];
        }
    }
    /* the row's two areas' inverses once (a texel's own in the reference loop) */
    double inv_row_area = row_area > 0 ? 1.0 / row_area : 0.0;
    double inv_hot_area = hot_area > 0 ? 1.0 / hot_area : 0.0;
    /* the row's sums in locals, not through st: the same order, from 0 */
    double seen_sr = 0, low_sr = 0, seen_power[3] = {0, 0, 0}, power[3] = {0, 0, 0};
    double view_sr[SL_STITCH_MAX_VIEWS] = {0};
    for (int x = 0; x < W; x++) {
        bool seen[SL_STITCH_MAX_VIEWS];
        for (int k = 0; k < n; k++)
            seen[k] = sc->seen[(size_t)k * W + x];
        double acc_w[SL_STITCH_MAX_VIEWS], acc_l[SL_STITCH_MAX_VIEWS][3];
        double area = row_area, inv_area = inv_row_area, masked_area = 0;
        bool hot;
        if (stitch_blend_reference) {
            memset(acc_w, 0, (size_t)n * sizeof *acc_w);
            memset(acc_l, 0, (size_t)n * sizeof *acc_l);
            area = 0;
            hot = texel_samples(p, x, y, p->ss, seen, acc_w, acc_l, &area, &masked_area);
        } else {
            take_sums(sc->acc + (size_t)x * 4, (size_t)W * 4, seen, n, acc_w, acc_l);
            masked_area = sc->masked_area[x];
            hot = sc->hot[x];
        }
        /* A bright small source or a hard edge: sampled finer (hot_samples;
         * the reference loop in double, one sample at a time), so its energy
         * does not depend on where the samples fall. */
        if (hot && p->ss_hot > p->ss) {
            if (stitch_blend_reference) {
                memset(acc_w, 0, (size_t)n * sizeof *acc_w);
                memset(acc_l, 0, (size_t)n * sizeof *acc_l);
                area = masked_area = 0;
                texel_samples(p, x, y, p->ss_hot, seen, acc_w, acc_l, &area, &masked_area);
            } else {
                int t = hot_next++;
                take_sums(sc->hot_acc + (size_t)t * 4, (size_t)nhot * 4, seen, n, acc_w, acc_l);
                area = hot_area;
                inv_area = inv_hot_area;
                masked_area = sc->hot_masked_area[t];
            }
            st->hot_texels++;
        }
        if (stitch_blend_reference)
            inv_area = 1.0 / area;
        /* Per view: its mean weight over the texel; the mean radiance of
         * the views weighing GHOST_MIN_WEIGHT or more only when there are
         * two of them (the ghost test needs two). */
        double wsum = 0, best_w = 0, lmin = INFINITY, lmax = 0;
        int best = -1, good = 0;
        for (int k = 0; k < n; k++) {
            if (!(acc_w[k] > 0))
                continue;
            double wk = acc_w[k] * inv_area;
            wsum += wk;
            if (wk > best_w) {
                best_w = wk;
                best = k;
            }
            good += wk >= GHOST_MIN_WEIGHT;
        }
        for (int k = 0; good >= 2 && p->ghosts && k < n; k++) {
            if (!(acc_w[k] > 0) || !(acc_w[k] * inv_area >= GHOST_MIN_WEIGHT))
                continue;
            double inv_w = 1.0 / acc_w[k];
            double l[3] = {acc_l[k][0] * inv_w, acc_l[k][1] * inv_w, acc_l[k][2] * inv_w};
            double y_k = luminance(l); /* finite, >= 0: no libm fmin */
            lmin = y_k < lmin ? y_k : lmin;
            lmax = y_k > lmax ? y_k : lmax;
        }
        float *o = out + (size_t)x * 4;
        if (wsum > 0) {
            bool ghost = p->ghosts && good >= 2 &&
                         lmax - lmin > p->opt->ghost_ratio * lmax + p->noise_floor;
            double sw = 0, sl[3] = {0, 0, 0};
            for (int k = 0; k < n; k++) {
                if (!(acc_w[k] > 0) || (ghost && k != best))
                    continue;
                sw += acc_w[k];
                for (int ch = 0; ch < 3; ch++)
                    sl[ch] += acc_l[k][ch];
            }
            double inv_sw = 1.0 / sw;
            for (int ch = 0; ch < 3; ch++)
                o[ch] = (float)(sl[ch] * inv_sw);
            o[3] = (float)(wsum < 1.0 ? wsum : 1.0); /* no libm call */
            seen_sr += texel_sr;
            if (wsum < 0.5)
                low_sr += texel_sr;
            if (ghost) {
                st->ghost_texels++;
                st->ghost_sr += texel_sr;
            }
            for (int k = 0; k < n; k++)
                if (acc_w[k] > 0)
                    view_sr[k] += texel_sr;
            for (int ch = 0; ch < 3; ch++)
                seen_power[ch] += texel_sr * o[ch];
        } else {
            float f[4] = {0, 0, 0, 0};
            if (p->fill)
                sl_latlong_lookup(p->fill, (x + 0.5) / W, (y + 0.5) / H, f);
            for (int ch = 0; ch < 3; ch++)
                o[ch] = fmaxf(0.0f, f[ch]);
            o[3] = 0.0f;
            st->filled_sr += texel_sr;
            st->filled_texels++;
            if (masked_area > 0.5 * area)
                st->masked_sr += texel_sr;
        }
        for (int ch = 0; ch < 3; ch++)
            power[ch] += texel_sr * o[ch];
    }
    st->seen_sr = seen_sr;
    st->low_sr = low_sr;
    for (int ch = 0; ch < 3; ch++) {
        st->seen_power[ch] = seen_power[ch];
        st->power[ch] = power[ch];
    }
    for (int k = 0; k < n; k++)
        st->view_sr[k] = view_sr[k];
}

static void blend_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    blend_pass *p = ctx;
    for (int64_t r = begin; r < end; r++)
        blend_row(p, p->y0 + (int)r, p->rows + (size_t)r * p->width * 4, &p->stats[r],
                  &p->scratch[worker]);
}

static void add_stats(sl_stitch_coverage *cov, const stitch_row_stats *s, int n)
{
    cov->seen_sr += s->seen_sr;
    cov->filled_sr += s->filled_sr;
    cov->masked_sr += s->masked_sr;
    cov->low_sr += s->low_sr;
    cov->ghost_texels += s->ghost_texels;
    cov->ghost_sr += s->ghost_sr;
    cov->filled_texels += s->filled_texels;
    cov->hot_texels += s->hot_texels;
    for (int k = 0; k < n; k++)
        cov->view_sr[k] += s->view_sr[k];
    for (int c = 0; c < 3; c++) {
        cov->power[c] += s->power[c];
        cov->seen_power[c] += s->seen_power[c];
    }
}

/* sin and cos of pi (a + b t) at the n sub-sample centres t = (c + 0.5) / n. */
static bool angle_table(int n, double a, double b, double **sin_out, double **cos_out)
{
    *sin_out = malloc((size_t)n * sizeof(double));
    *cos_out = malloc((size_t)n * sizeof(double));
    if (!*sin_out || !*cos_out)
        return false;
    for (int c = 0; c < n; c++) {
        double angle = M_PI * (a + b * (c + 0.5) / n);
        (*sin_out)[c] = sin(angle);
        (*cos_out)[c] = cos(angle);
    }
    return true;
}

static sl_result pass_init(blend_pass *p, const stitch_view_prep *views, int count,
                           const sl_stitch_blend_options *opt, int width, int ss, int ss_hot,
                           sl_error *err)
{
    memset(p, 0, sizeof *p);
    p->views = views;
    p->count = count;
    p->opt = opt;
    p->width = width;
    p->height = width / 2;
    p->ss = ss;
    p->ss_hot = ss_hot;
    p->nadir_lat = opt->nadir_mask_deg > 0 ? (opt->nadir_mask_deg - 90.0) * DEG : -INFINITY;
    p->rows = malloc((size_t)STRIP_ROWS * width * 4 * sizeof(float));
    p->stats = malloc(STRIP_ROWS * sizeof(stitch_row_stats));
    /* The sub-samples' sines and cosines, once per pass, not per texel. */
    bool ok = angle_table(width * ss, 1.0, -2.0, &p->sin_lon, &p->cos_lon) &&
              angle_table(p->height * ss, 0.5, -1.0, &p->sin_lat, &p->cos_lat) &&
              angle_table(width * ss_hot, 1.0, -2.0, &p->sin_lon_hot, &p->cos_lon_hot) &&
              angle_table(p->height * ss_hot, 0.5, -1.0, &p->sin_lat_hot, &p->cos_lat_hot);
    p->sin_lon_f = malloc((size_t)width * ss * sizeof(float));
    p->cos_lon_f = malloc((size_t)width * ss * sizeof(float));
    p->sin_lon_hot_f = malloc((size_t)width * ss_hot * sizeof(float));
    p->cos_lon_hot_f = malloc((size_t)width * ss_hot * sizeof(float));
    ok = ok && p->sin_lon_f && p->cos_lon_f && p->sin_lon_hot_f && p->cos_lon_hot_f;
    for (int i = 0; ok && i < width * ss; i++) {
        p->sin_lon_f[i] = (float)p->sin_lon[i];
        p->cos_lon_f[i] = (float)p->cos_lon[i];
    }
    for (int i = 0; ok && i < width * ss_hot; i++) {
        p->sin_lon_hot_f[i] = (float)p->sin_lon_hot[i];
        p->cos_lon_hot_f[i] = (float)p->cos_lon_hot[i];
    }
    for (int k = 0; ok && k < count; k++)
        ok = stitch_ray_view_init(&views[k], &p->rays[k]);
    p->workers = sl_threads_get();
#ifdef STITCH_HAVE_F16C_ASM
    p->f16c = !stitch_rays_portable_only && stitch_cpu_f16c();
#endif
    p->scratch = ok ? calloc((size_t)p->workers, sizeof *p->scratch) : NULL;
    for (int w = 0; p->scratch && w < p->workers; w++)
        ok = ok && scratch_alloc(&p->scratch[w], width, ss, ss_hot, count);
    if (!ok || !p->rows || !p->stats || !p->scratch)
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory for a %d wide lat-long",
                            width);
    return SL_OK;
}

static void pass_free(blend_pass *p)
{
    free(p->sin_lon);
    free(p->cos_lon);
    free(p->sin_lat);
    free(p->cos_lat);
    free(p->sin_lon_hot);
    free(p->cos_lon_hot);
    free(p->sin_lat_hot);
    free(p->cos_lat_hot);
    free(p->rows);
    free(p->stats);
    free(p->sin_lon_f);
    free(p->cos_lon_f);
    free(p->sin_lon_hot_f);
    free(p->cos_lon_hot_f);
    for (int k = 0; k < p->count; k++)
        stitch_ray_view_free(&p->rays[k]);
    for (int w = 0; p->scratch && w < p->workers; w++)
        scratch_free(&p->scratch[w]);
    free(p->scratch);
}

/* Strips handed to the sink (the file's conversion, compression and
 * in-order write) on a thread of its own, up to SINK_QUEUE strips behind
 * the blend: its bursts (every 8 strips a batch's chunks compressed, the
 * last ones on one core, then written in order on one) do not hold the
 * blend, and the blend's strips keep the other core busy meanwhile. The
 * sink sees the strips in order, one call at a time, as without it.
 * Deeper, the strips leave the cache before they are written (10: the
 * blend's CPU time about 0.1 s more than with 4; 2: the blend stalls again). */
#define SINK_QUEUE 4

typedef struct sink_queue {
    sl_stitch_rows_fn sink;
    void *user;
    size_t stride;
    float *buf[SINK_QUEUE];
    int y0[SINK_QUEUE], count[SINK_QUEUE];
    int head, tail; /* strips queued: [tail, head), each in buf[i % SINK_QUEUE] */
    bool closed;    /* no more strips come */
    sl_result status;
    sl_error err;
    pthread_mutex_t lock;
    pthread_cond_t changed;
    pthread_t thread;
} sink_queue;

static void *sink_main(void *arg)
{
    sink_queue *q = arg;
    pthread_mutex_lock(&q->lock);
    for (;;) {
        while (q->tail == q->head && !q->closed)
            pthread_cond_wait(&q->changed, &q->lock);
        if (q->tail == q->head)
            break;
        int i = q->tail % SINK_QUEUE;
        pthread_mutex_unlock(&q->lock);
        sl_error err;
        sl_result r = q->sink(q->user, q->buf[i], q->y0[i], q->count[i], q->stride, &err);
        pthread_mutex_lock(&q->lock);
        q->tail++;
        if (r && !q->status) {
            q->status = r;
            q->err = err;
        }
        pthread_cond_broadcast(&q->changed);
        if (r)
            break;
    }
    pthread_mutex_unlock(&q->lock);
    return NULL;
}

/* Runs a pass over every row, strip by strip, into sink (or into `whole`). */
static sl_result pass_run(blend_pass *p, sl_stitch_rows_fn sink, void *user, sl_image *whole,
                          sl_stitch_coverage *cov, sl_error *err)
{
    sink_queue q = {.sink = sink, .user = user, .stride = (size_t)p->width * 4};
    bool queued = false; /* else each strip goes to the sink here, in turn */
    if (!whole) {
        bool ok = true;
        for (int i = 0; i < SINK_QUEUE; i++)
            ok &= (q.buf[i] = malloc((size_t)STRIP_ROWS * q.stride * sizeof(float))) != NULL;
        queued = ok && !pthread_mutex_init(&q.lock, NULL);
        if (queued && pthread_cond_init(&q.changed, NULL)) {
            pthread_mutex_destroy(&q.lock);
            queued = false;
        }
        if (queued && pthread_create(&q.thread, NULL, sink_main, &q)) {
            pthread_cond_destroy(&q.changed);
            pthread_mutex_destroy(&q.lock);
            queued = false;
        }
    }
    float *own_rows = p->rows;
    sl_result res = SL_OK;
    for (int y0 = 0; y0 < p->height && !res; y0 += STRIP_ROWS) {
        int count = p->height - y0 < STRIP_ROWS ? p->height - y0 : STRIP_ROWS;
        int slot = 0;
        if (queued) { /* a free buffer, unless the sink failed */
            pthread_mutex_lock(&q.lock);
            while (q.head - q.tail >= SINK_QUEUE && !q.status)
                pthread_cond_wait(&q.changed, &q.lock);
            res = q.status;
            slot = q.head % SINK_QUEUE;
            pthread_mutex_unlock(&q.lock);
            if (res)
                break;
            p->rows = q.buf[slot];
        }
        p->y0 = y0;
        sl_parallel_for(count, 1, blend_rows, p);
        for (int r = 0; r < count; r++)
            add_stats(cov, &p->stats[r], p->count);
        if (whole) {
            for (int r = 0; r < count; r++)
                memcpy(sl_image_pixel(whole, 0, y0 + r), p->rows + (size_t)r * p->width * 4,
                       (size_t)p->width * 4 * sizeof(float));
        } else if (queued) {
            pthread_mutex_lock(&q.lock);
            q.y0[slot] = y0;
            q.count[slot] = count;
            q.head++;
            pthread_cond_broadcast(&q.changed);
            pthread_mutex_unlock(&q.lock);
        } else {
            res = sink(user, p->rows, y0, count, q.stride, err);
        }
    }
    if (queued) { /* the strips queued written (or the sink's error) */
        pthread_mutex_lock(&q.lock);
        q.closed = true;
        pthread_cond_broadcast(&q.changed);
        pthread_mutex_unlock(&q.lock);
        pthread_join(q.thread, NULL);
        if (q.status) {
            res = q.status;
            *err = q.err;
        }
        pthread_cond_destroy(&q.changed);
        pthread_mutex_destroy(&q.lock);
    }
    p->rows = own_rows;
    for (int i = 0; i < SINK_QUEUE; i++)
        free(q.buf[i]);
    return res;
}

/* The coarse lat-long the fill and the noise floor come from: the blend
 * without the ghost test, at most 256 wide, unseen texels filled. */
static sl_result coarse_fill(const stitch_view_prep *views, int count,
                             const sl_stitch_blend_options *opt, int width, int ss,
                             sl_image *coarse, double *median_y, sl_error *err)
{
    int cw = width < 256 ? width : 256;
    int css = (int)ceil((double)ss * width / cw);
    css = css > 8 ? 8 : css;
    blend_pass p;
    sl_result r = pass_init(&p, views, count, opt, cw, css, css, err);
    if (!r)
        r = sl_image_alloc(coarse, cw, cw / 2, 4, err);
    sl_stitch_coverage cov;
    memset(&cov, 0, sizeof cov);
    if (!r)
        r = pass_run(&p, NULL, NULL, coarse, &cov, err);
    pass_free(&p);
    if (r)
        return r;
    /* Median luminance of the seen texels (for the ghost test's floor). */
    size_t n = (size_t)coarse->width * coarse->height, m = 0;
    float *lum = malloc(n * sizeof(float));
    if (!lum)
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
    for (int y = 0; y < coarse->height; y++)
        for (int x = 0; x < coarse->width; x++) {
            const float *px = sl_image_pixel(coarse, x, y);
            if (px[3] > 0) {
                double rgb[3] = {px[0], px[1], px[2]};
                lum[m++] = (float)luminance(rgb);
            }
        }
    *median_y = m ? stitch_median(lum, m) : 0.0;
    free(lum);
    return stitch_fill(coarse, err);
}

sl_result sl_stitch_blend_stream(const sl_stitch_view *views, int count,
                                 const sl_stitch_blend_options *opt_in, sl_stitch_rows_fn sink,
                                 void *user, sl_stitch_coverage *cov, sl_error *err)
{
    return stitch_blend_run(views, count, NULL, false, opt_in, sink, user, NULL, cov, err);
}

static sl_result blend_prepared(const stitch_view_prep *prep, int count,
                                const sl_stitch_blend_options *optp, sl_stitch_rows_fn sink,
                                void *user, sl_image *whole, sl_stitch_coverage *cov_out,
                                sl_error *err);

sl_result stitch_blend_run(const sl_stitch_view *views, int count,
                           const stitch_half_image *half, bool scanned,
                           const sl_stitch_blend_options *opt_in, sl_stitch_rows_fn sink,
                           void *user, sl_image *whole, sl_stitch_coverage *cov_out,
                           sl_error *err)
{
    sl_stitch_blend_options opt;
    if (opt_in)
        opt = *opt_in;
    else
        sl_stitch_blend_options_init(&opt);
    sl_stitch_coverage cov;
    memset(&cov, 0, sizeof cov);
    if (cov_out)
        memset(cov_out, 0, sizeof *cov_out);
    stitch_view_prep prep[SL_STITCH_MAX_VIEWS];
    memset(prep, 0, sizeof prep);
    sl_result r = stitch_prepare_views(views, count, &opt, half, scanned, prep, err);
    if (!r)
        r = blend_prepared(prep, count, &opt, sink, user, whole, &cov, err);
    stitch_release_views(prep, count < SL_STITCH_MAX_VIEWS ? count : SL_STITCH_MAX_VIEWS);
    if (!r && cov_out)
        *cov_out = cov;
    return r;
}

/* The blend of prepared views (stitch_blend_run's body). */
static sl_result blend_prepared(const stitch_view_prep *prep, int count,
                                const sl_stitch_blend_options *optp, sl_stitch_rows_fn sink,
                                void *user, sl_image *whole, sl_stitch_coverage *cov_out,
                                sl_error *err)
{
    const sl_stitch_blend_options opt = *optp;
    sl_stitch_coverage cov;
    memset(&cov, 0, sizeof cov);
    sl_result r = SL_OK;
    int width = opt.width > 0 ? opt.width : sl_stitch_default_width(&prep[0].lens, opt.max_width);
    if (width < 16 || width % 2)
        return sl_error_set(err, SL_ERR_USAGE, "stitch: the width must be even and at least 16, "
                                               "not %d", width);
    if (opt.mask && !sl_is_latlong_shape(opt.mask->width, opt.mask->height))
        return sl_error_set(err, SL_ERR_INPUT, "stitch: the mask is %dx%d, not a 2:1 lat-long",
                            opt.mask->width, opt.mask->height);
    int ss = opt.supersample, ss_hot = opt.supersample;
    if (ss <= 0)
        auto_supersample(prep, count, width, &ss, &ss_hot);
    else
        ss = ss_hot = ss > 8 ? 8 : ss;

    if (whole && (r = sl_image_alloc(whole, width, width / 2, 4, err)))
        return r;
    sl_image coarse = {0};
    double median_y = 0;
    if ((r = coarse_fill(prep, count, &opt, width, ss, &coarse, &median_y, err)))
        goto done;
    blend_pass p;
    if ((r = pass_init(&p, prep, count, &opt, width, ss, ss_hot, err))) {
        pass_free(&p);
        goto done;
    }
    p.fill = &coarse;
    p.ghosts = opt.ghost_ratio > 0 && count > 1;
    p.noise_floor = opt.noise_floor >= 0 ? opt.noise_floor : 1e-3 * median_y;
    r = pass_run(&p, sink, user, whole, &cov, err);
    pass_free(&p);
    cov.width = width;
    cov.height = width / 2;
    cov.supersample = ss;
    cov.supersample_hot = ss_hot;
    if (!r && cov_out)
        *cov_out = cov;
done:
    sl_image_free(&coarse);
    if (r && whole)
        sl_image_free(whole);
    return r;
}

sl_result sl_stitch_blend(const sl_stitch_view *views, int count,
                          const sl_stitch_blend_options *opt, sl_image *out,
                          sl_stitch_coverage *cov, sl_error *err)
{
    memset(out, 0, sizeof *out);
    return stitch_blend_run(views, count, NULL, false, opt, NULL, NULL, out, cov, err);
}
