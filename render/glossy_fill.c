/* SPDX-License-Identifier: BSD-3-Clause */
/* Glossy closed-form pixels at pixel centres, in two parts of the dome
 * (Lambert pixels are filled over normals, normal_fill.c):
 *
 * - the sun: the texels brighter than SUN_RATIO x the map's mean radiance
 *   (at most SUN_CAP of them), whose highlight moves across the ball faster
 *   than any lattice could follow. Evaluated at every pixel; few cells
 *   hold light, so an evaluation costs a handful of cells;
 * - the rest: its reflection varies slowly across the ball (the lobe, tens
 *   of degrees at roughness 0.3, averages it), so it is evaluated on a
 *   lattice of 16 x 16 px blocks and interpolated bilinearly
 *   where the block's centre and edge midpoints, evaluated too, agree with
 *   the interpolation; a block that fails is split in four, down to 4 x 4
 *   px; a block that crosses the silhouette (the corners would mix objects)
 *   is split too, and pixels no block interpolates are evaluated. Up to
 *   four neighbours of a row whose lobes nearly coincide are evaluated
 *   over one set of cells (sl_glossy_integrate_batch): the cells' geometry
 *   and refinement are then paid once.
 *
 * Tolerance shares of a pixel's error estimate: glossy, the rest's
 * quadrature half, the interpolation check a quarter (relative to the
 * rest) past twice the points' quadrature estimates, the sun a quarter of
 * the pixel's whole value.
 *
 * Under --time the rest is first evaluated for every pixel at
 * SL_GLOSSY_COARSE x the tolerance (the coarse pass: the same lattice and
 * evaluations, far fewer cells), so that a row the full plan does not
 * reach keeps that value and its error estimate instead of sampling. Its
 * blocks' check is at SL_GLOSSY_COARSE_CHECK x the tolerance and allows no
 * slack for the points' estimates: at that tolerance they are ~15x the
 * points' true error, and with the slack blocks passed 16% off at an
 * estimate of 7% (env_test.exr, metal 0.3). A block that fails tries the
 * biquadratic through its nine points, checked at its quarters' centres
 * (try_quadratic: four points, which the quarters need anyway if it fails
 * too). A block that fails both gives its
 * pixels its interpolation meanwhile (REST_PROVISIONAL), so a cut inside
 * the pass leaves to sampling only what no block has covered. The pixels
 * no block interpolates (the rim) come last: left to sampling by a cut,
 * their error is far smaller than the interior's failed blocks' would be
 * (docs/render.md). Then, time permitting, the interpolated pixels with
 * the largest error estimates are evaluated (refine_interpolated). */
#include <stdlib.h>
#include <string.h>

#include "glossy.h"
#include "scene_internal.h"
#include "vec3.h"

#define SUN_RATIO 100.0
#define SUN_CAP 1024
#define SUN_START_CELLS 4
#define BLOCK0 16
/* Rest evaluations share cells across at most this span of a row (px),
 * between pixels whose normals are within BATCH_TURN x the GGX alpha. */
#define BATCH_SPAN 4
#define BATCH_TURN 0.25
/* Below 4 px a block's nine points are more than the pixels it owns. */
#define BLOCK_MIN 4
/* A block interpolates only where the view's mirror direction turns by at
 * most this many GGX alphas across it: past that the nine points are
 * further apart than the lobe's blur and miss the reflection's features
 * (env_test.exr, metal 0.3, 256 px: an 8 px block at 65-69 degrees 4.7%
 * off at an estimate of 2.8%). */
#define BLOCK_TURN 4.0
#define REST_SHARE 0.5
#define INTERP_SHARE 0.25
#define SUN_SHARE 0.25
/* Before the rest is known, the sun is refined against this share of the
 * rest's mean radiance. */
#define SUN_FLOOR_SHARE 0.25
#define SUN_PASS_TOL 1e-2
/* Rows per band: each band is finished before the next starts. */
#define BAND_ROWS 16
/* The coarse pass's last step evaluates its interpolated pixels one by
 * one, the largest error estimates first, at REFINE_TOL x the plan's
 * tolerance (the quadrature's estimate then below most interpolations'),
 * until those left hold REFINE_LEFT of their squared estimates: their
 * estimates track their true errors (env_test.exr, metal 0.3: the 2866
 * pixels with 75% of the squared estimates carry 71% of the squared error;
 * docs/render.md). At most REFINE_MOST x the pass's own evaluations: where
 * the estimates are even (metal 0.8: 53 378 pixels for 75%) the full plan
 * is the better use of the time. A fifth rather than a quarter left: with
 * the biquadratic blocks metal 0.3 then refines 2713 pixels to 0.215%
 * against 2072 to 0.229%. */
#define REFINE_TOL 4.0
#define REFINE_LEFT 0.2
#define REFINE_MOST 0.25

/* ---- the split ---- */


void sl_glossy_dome_free(sl_glossy_dome *gd)
{
    sl_irradiance_free(gd->sun);
    sl_irradiance_free(gd->own_rest);
    sl_image_free(&gd->sun_dome.image);
    sl_image_free(&gd->rest_dome.image);
    free(gd->sun_cells);
    memset(gd, 0, sizeof *gd);
}

sl_result sl_glossy_dome_build(const sl_dome *dome, const sl_irradiance *whole, sl_glossy_dome *gd,
                               sl_error *err)
{
    memset(gd, 0, sizeof *gd);
    gd->rest = whole;
    const sl_image *img = &dome->image;
    int W = img->width, H = img->height;
    /* Mean radiance (luminance) over the sphere, and the candidates. */
    double power = 0, sun_power = 0;
    int64_t count = 0, cap = 1024;
    sl_ranked *cand = malloc((size_t)cap * sizeof *cand);
    if (!cand)
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the dome split");
    for (int y = 0; y < H; y++) {
        double dw = (cos(SL_PI * y / H) - cos(SL_PI * (y + 1) / H)) * 2.0 * SL_PI / W;
        for (int x = 0; x < W; x++)
            power += sl_luminance_px(sl_image_pixel(img, x, y)) * dw;
    }
    double threshold = SUN_RATIO * power / (4.0 * SL_PI);
    for (int y = 0; y < H && threshold > 0; y++)
        for (int x = 0; x < W; x++) {
            double lum = sl_luminance_px(sl_image_pixel(img, x, y));
            if (!(lum > threshold))
                continue;
            if (count == cap) {
                sl_ranked *grown = realloc(cand, (size_t)(2 * cap) * sizeof *cand);
                if (!grown) {
                    free(cand);
                    return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the dome split");
                }
                cand = grown, cap *= 2;
            }
            cand[count++] = (sl_ranked){lum, (int64_t)y * W + x};
        }
    if (count == 0) {
        free(cand);
        return SL_OK;
    }
    qsort(cand, (size_t)count, sizeof *cand, sl_cmp_ranked_desc);
    if (count > SUN_CAP)
        count = SUN_CAP;
    sl_result res;
    gd->sun_dome = *dome, gd->rest_dome = *dome;
    memset(&gd->sun_dome.image, 0, sizeof(sl_image));
    memset(&gd->rest_dome.image, 0, sizeof(sl_image));
    gd->sun_dome.sampler = gd->rest_dome.sampler = NULL;
    if ((res = sl_image_copy(img, &gd->rest_dome.image, err)) ||
        (res = sl_image_alloc(&gd->sun_dome.image, W, H, img->channels, err))) {
        free(cand);
        sl_glossy_dome_free(gd);
        return res;
    }
    /* sl_image_alloc's image is zero: only the sun's texels are written,
     * and only their cells' ancestors are summed. */
    for (int64_t k = 0; k < count; k++) {
        int x = (int)(cand[k].index % W), y = (int)(cand[k].index / W);
        float *r = sl_image_pixel(&gd->rest_dome.image, x, y), *s = sl_image_pixel(&gd->sun_dome.image, x, y);
        double dw = (cos(SL_PI * y / H) - cos(SL_PI * (y + 1) / H)) * 2.0 * SL_PI / W;
        sun_power += cand[k].value * dw;
        for (int c = 0; c < img->channels; c++)
            s[c] = r[c], r[c] = 0.0f;
    }
    int64_t *sun_at = malloc((size_t)count * sizeof *sun_at);
    for (int64_t k = 0; sun_at && k < count; k++)
        sun_at[k] = cand[k].index;
    gd->sun_texels = count;
    gd->sun_share = power > 0 ? sun_power / power : 0;
    res = sun_at ? sl_irradiance_build_sparse(&gd->sun_dome, sun_at, count, &gd->sun, err)
                 : sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the dome split");
    free(sun_at);
    free(cand);
    if (res || (res = sl_irradiance_build(&gd->rest_dome, &gd->own_rest, err))) {
        sl_glossy_dome_free(gd);
        return res;
    }
    gd->rest = gd->own_rest;
    /* The refinement starts at the finest level where the sun spans at most
     * SUN_START_CELLS cells: a pixel far from its highlight costs no more. */
    int top = sl_irradiance_top_level(gd->sun), tw, th;
    sl_irradiance_level_size(gd->sun, top, &tw, &th);
    gd->sun_cells = malloc((size_t)tw * th * sizeof *gd->sun_cells);
    if (!gd->sun_cells) {
        sl_glossy_dome_free(gd);
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the dome split");
    }
    for (int level = 0; level <= top; level++) {
        int lw, lh, n = 0, most = level == top ? tw * th : SUN_START_CELLS;
        sl_irradiance_level_size(gd->sun, level, &lw, &lh);
        for (int y = 0; y < lh && n <= most; y++)
            for (int x = 0; x < lw && n <= most; x++) {
                sl_dome_cell c;
                sl_irradiance_cell(gd->sun, level, x, y, &c);
                if (c.p[0] > 0 || c.p[1] > 0 || c.p[2] > 0) {
                    if (n < most)
                        gd->sun_cells[n] = y * lw + x;
                    n++;
                }
            }
        if (n <= SUN_START_CELLS || level == top) {
            gd->sun_level = level;
            gd->sun_cell_count = n;
            break;
        }
    }
    return SL_OK;
}

/* ---- the pixels ---- */

/* A pixel's rest in a pass: none yet, evaluated, interpolated by a block
 * that passed its check, or (coarse pass) interpolated by one that failed
 * it, with the difference it found as the error, until a finer block or
 * the pixel's own evaluation replaces it; or (coarse pass) interpolated,
 * then evaluated by the refinement. */
enum { REST_NONE, REST_EVALUATED, REST_INTERPOLATED, REST_PROVISIONAL, REST_REFINED };

/* Known at the pass's tolerance. */
static bool rest_known(uint8_t state)
{
    return state == REST_EVALUATED || state == REST_INTERPOLATED || state == REST_REFINED;
}

typedef struct fill_job {
    const sl_closed_form *cf;
    const sl_scene *scene;
    sl_glossy_pixels *px;
    int w, h;
    sl_irradiance_cost *row_cost;
    double tol;       /* the pass's tolerance: the plan's, or the coarse pass's */
    double check_tol; /* the blocks' check: the pass's interpolation tolerance */
    double slack;     /* the blocks' check: x the points' largest error estimate allowed */
    double deadline;  /* --time: the pass's rows not started by then are cut */
    int row_limit;    /* tests: rows from this one on are cut as by the deadline (0: none) */
    int row0;         /* finish_rows: the band's first row */
    uint8_t *row_cut; /* per image row: ran into the deadline */
    uint8_t *need;    /* per pixel: its rest to be evaluated in this pass */
    uint8_t *rest_state; /* REST_NONE ... REST_PROVISIONAL */
    double (*rest)[3], (*rest_err)[3];
    uint8_t *coarse_state; /* the coarse pass's rest_state, rest and rest_err, or NULL */
    double (*coarse)[3], (*coarse_err)[3];
    double (*sun)[3], (*sun_err)[3]; /* glossy pixels: their sun, before the rest */
    uint8_t *sun_state;              /* 1: sun evaluated at sun_floor's scale */
    double sun_floor[3];             /* the sun pass's refinement scale (the rest unknown yet) */
    double sun_tol;                  /* the sun pass's tolerance */
    bool provisional;  /* the coarse pass: a failed block's pixels keep its interpolation meanwhile */
    bool quadratic;    /* the coarse pass: a failed block tries its nine points' biquadratic first */
    int block_limit;   /* tests: the lattice stops after its blocks of this size, all rows cut */
    sl_ranked *order;      /* the refinement's pixels, in order */
    int *batch_start;      /* its batches: order[batch_start[b] .. batch_start[b + 1]) */
    sl_irradiance_cost *worker_cost; /* its costs, per worker (its batches share rows) */
    sl_glossy_scratch **scratch; /* per worker */
    int workers;
    bool failed;      /* no memory for a scratch: the rows are left to sampling */
} fill_job;

static sl_glossy_scratch *scratch_for(fill_job *j, int worker)
{
    if (worker < 0 || worker >= j->workers)
        return NULL;
    if (!j->scratch[worker])
        j->scratch[worker] = sl_glossy_scratch_new();
    return j->scratch[worker];
}

static const sl_glossy_material *material_of(const fill_job *j, size_t pix)
{
    return &j->cf->gmat[j->scene->shapes[j->cf->shape[pix]].material];
}

/* The rest (the pixel's radiance from the map less its sun) at pixels
 * pix[0..count-1] of one row, over shared cells. */
static void eval_rest(fill_job *j, const size_t *pix, int count, sl_glossy_scratch *s, sl_irradiance_cost *cost)
{
    sl_glossy_quad q = {.tol = REST_SHARE * j->tol};
    const sl_glossy_material *gm[SL_GLOSSY_BATCH] = {0};
    double n[SL_GLOSSY_BATCH][3], wo[SL_GLOSSY_BATCH][3], out[SL_GLOSSY_BATCH][3], err[SL_GLOSSY_BATCH][3];
    for (int i = 0; i < count; i++) {
        gm[i] = material_of(j, pix[i]);
        memcpy(n[i], j->px->n[pix[i]], sizeof n[i]);
        memcpy(wo[i], j->px->wo[pix[i]], sizeof wo[i]);
    }
    sl_glossy_integrate_batch(j->cf->gdome->rest, gm, (const double(*)[3])n, (const double(*)[3])wo, count, &q, s,
                              out, err, cost);
    for (int i = 0; i < count; i++) {
        memcpy(j->rest[pix[i]], out[i], sizeof out[i]);
        memcpy(j->rest_err[pix[i]], err[i], sizeof err[i]);
        j->rest_state[pix[i]] = REST_EVALUATED;
    }
}

/* Pixels p and q share cells well when their lobes nearly coincide: the
 * same material, normals within BATCH_TURN x its GGX alpha (at the rim,
 * where the normal turns by degrees per pixel, they do not), views
 * likewise. */
static bool lobes_overlap(const fill_job *j, size_t p, size_t q)
{
    const sl_glossy_material *gm = material_of(j, p);
    if (gm != material_of(j, q))
        return false;
    double turn = BATCH_TURN * fmin(gm->ggx.ax, gm->ggx.ay), c = cos(turn);
    return v3_dot(j->px->n[p], j->px->n[q]) >= c && v3_dot(j->px->wo[p], j->px->wo[q]) >= c;
}

/* The rests of row y's pixels whose rest is still to do: the image
 * blocks' points (need, points) or the pixels no block interpolated, in
 * batches of neighbours: at most SL_GLOSSY_BATCH pixels of one material
 * within BATCH_SPAN px, whose lobes overlap, so their shared cells are
 * about those of each one alone. False when cut by the deadline. */
static bool rest_of_row(fill_job *j, int64_t y, bool points, double deadline, sl_glossy_scratch *s)
{
    size_t pix[SL_GLOSSY_BATCH];
    int count = 0;
    for (int x = 0; x <= j->w; x++) {
        size_t p = (size_t)y * j->w + x;
        bool want = x < j->w && (points ? j->need[p] && j->rest_state[p] != REST_EVALUATED
                                        : j->px->state[p] == SL_GLOSSY_PENDING && !rest_known(j->rest_state[p]));
        /* the batch so far is done when this pixel cannot join it */
        if (count > 0 && (x == j->w || (int)(p - pix[0]) > BATCH_SPAN ||
                          (want && (count == SL_GLOSSY_BATCH || !lobes_overlap(j, pix[0], p))))) {
            if (sl_seconds() > deadline)
                return false;
            eval_rest(j, pix, count, s, &j->row_cost[y]);
            count = 0;
        }
        if (want)
            pix[count++] = p;
    }
    return true;
}

/* Evaluates the rest at every pixel marked in need (the image blocks'
 * points), row by row. */
static void rest_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill_job *j = ctx;
    sl_glossy_scratch *s = scratch_for(j, worker);
    for (int64_t y = begin; y < end; y++) {
        if (j->row_limit > 0 && y >= j->row_limit)
            j->row_cut[y] = 1; /* tests: cut before the rest's plan reaches it */
        if (j->row_cut[y])
            continue;
        if (!s || !rest_of_row(j, y, true, j->deadline, s)) {
            j->row_cut[y] = 1; /* left to sampling */
            j->failed |= !s;
        }
    }
}

/* Past the deadline a pass starts no more parallel loops: under load each
 * one's threads took milliseconds to be scheduled, 0.07-0.09 s of wall
 * time for the full plan's empty loops after a cut. */
static bool past_deadline(const fill_job *j)
{
    return sl_seconds() > j->deadline;
}

typedef struct block {
    int x0, y0;
} block;

/* A pixel whose rest the image blocks interpolate: every pending one. */
static bool image_blocked(const fill_job *j, size_t p)
{
    return j->px->state[p] == SL_GLOSSY_PENDING;
}

static bool pending_on(const fill_job *j, int x, int y, int shape)
{
    if (x < 0 || y < 0 || x >= j->w || y >= j->h)
        return false;
    size_t p = (size_t)y * j->w + x;
    return image_blocked(j, p) && j->cf->shape[p] == shape && !j->row_cut[y];
}

/* The block's nine points (corners, edge midpoints, centre) as offsets in
 * units of half the block. */
static const int POINT[9][2] = {{0, 0}, {2, 0}, {0, 2}, {2, 2}, {1, 0}, {0, 1}, {2, 1}, {1, 2}, {1, 1}};

/* The view's mirror direction at pixel p. */
static void mirror_at(const fill_job *j, size_t p, double m[3])
{
    const double *n = j->px->n[p], *wo = j->px->wo[p];
    double cn = v3_dot(n, wo);
    for (int i = 0; i < 3; i++)
        m[i] = 2.0 * cn * n[i] - wo[i];
}

/* Narrow: the mirror direction turns by at most BLOCK_TURN x the lobe's
 * width across the block's diagonals, so the reflection, the map blurred
 * by the lobe, is smooth at the nine points' spacing. */
static bool block_narrow(const fill_job *j, const block *b, int S)
{
    size_t p0 = (size_t)b->y0 * j->w + b->x0;
    const sl_glossy_material *gm = material_of(j, p0);
    double c = cos(BLOCK_TURN * fmin(gm->ggx.ax, gm->ggx.ay)), m[4][3];
    for (int k = 0; k < 4; k++)
        mirror_at(j, (size_t)(b->y0 + (k >> 1) * S) * j->w + (size_t)(b->x0 + (k & 1) * S), m[k]);
    return v3_dot(m[0], m[3]) >= c && v3_dot(m[1], m[2]) >= c;
}

/* Whole: every pixel of the closed block on the corner's object. */
static bool block_whole(const fill_job *j, const block *b, int S)
{
    /* the corner's bounds first: a block may start past the image's edge */
    if (b->x0 < 0 || b->y0 < 0 || b->x0 >= j->w || b->y0 >= j->h ||
        !pending_on(j, b->x0, b->y0, j->cf->shape[(size_t)b->y0 * j->w + b->x0]))
        return false;
    int shape = j->cf->shape[(size_t)b->y0 * j->w + b->x0];
    for (int y = b->y0; y <= b->y0 + S; y++)
        for (int x = b->x0; x <= b->x0 + S; x++)
            if (!pending_on(j, x, y, shape))
                return false;
    return true;
}

bool sl_fill_check(const double v[9][3], const double e[9][3], const double (*scale)[3], double tol, double slack,
                   double err[3])
{
    if (!scale)
        scale = v;
    bool pass = true;
    for (int c = 0; c < 3; c++) {
        /* Interpolations at the edge midpoints (top, left, right, bottom)
         * and the centre. */
        double lin[5] = {0.5 * (v[0][c] + v[1][c]), 0.5 * (v[0][c] + v[2][c]), 0.5 * (v[1][c] + v[3][c]),
                         0.5 * (v[2][c] + v[3][c]), 0.25 * (v[0][c] + v[1][c] + v[2][c] + v[3][c])};
        double bmax = 0;
        for (int k = 0; k < 9; k++)
            bmax = fmax(bmax, e[k][c]);
        /* The points' own quadrature errors are in the difference too:
         * past them (slack x the largest), the interpolation's error must
         * be within its share. */
        double d = 0;
        for (int k = 0; k < 5; k++) {
            double dk = fabs(lin[k] - v[4 + k][c]);
            pass &= dk <= tol * scale[4 + k][c] + slack * bmax;
            d = fmax(d, dk);
        }
        err[c] = bmax + d;
    }
    return pass;
}

void sl_fill_bilinear(const double v[4][3], double fx, double fy, double out[3])
{
    double wts[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    for (int c = 0; c < 3; c++)
        out[c] = wts[0] * v[0][c] + wts[1] * v[1][c] + wts[2] * v[2][c] + wts[3] * v[3][c];
}

/* The rests at a block's nine points; false while one is not evaluated. */
static bool block_points(const fill_job *j, const block *b, int S, double v[9][3], double e[9][3])
{
    for (int k = 0; k < 9; k++) {
        size_t p = (size_t)(b->y0 + POINT[k][1] * S / 2) * j->w + (size_t)(b->x0 + POINT[k][0] * S / 2);
        if (j->rest_state[p] != REST_EVALUATED)
            return false;
        memcpy(v[k], j->rest[p], sizeof v[k]);
        memcpy(e[k], j->rest_err[p], sizeof e[k]);
    }
    return true;
}

/* The biquadratic through a block's nine points (POINT's order) at (fx,
 * fy) in [0, 1]^2: Lagrange's basis on 0, 1/2, 1 along each axis. */
static void biquadratic(const double v[9][3], double fx, double fy, double out[3])
{
    /* POINT's index of the grid node (i, j), in half blocks */
    static const int AT[3][3] = {{0, 5, 2}, {4, 8, 7}, {1, 6, 3}};
    double bx[3] = {2 * (fx - 0.5) * (fx - 1), -4 * fx * (fx - 1), 2 * fx * (fx - 0.5)};
    double by[3] = {2 * (fy - 0.5) * (fy - 1), -4 * fy * (fy - 1), 2 * fy * (fy - 0.5)};
    for (int c = 0; c < 3; c++) {
        out[c] = 0;
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
                out[c] += bx[i] * by[k] * v[AT[i][k]][c];
    }
}

/* Gives a block's own pixels [x0, x0 + S)^2 not evaluated the bilinear
 * interpolation of its corners or (quadratic) the biquadratic of its nine
 * points, clamped at zero (it may undershoot), with error err. */
static void fill_block(fill_job *j, const block *b, int S, const double v[9][3], bool quadratic,
                       const double err[3], uint8_t state)
{
    for (int y = b->y0; y < b->y0 + S; y++)
        for (int x = b->x0; x < b->x0 + S; x++) {
            size_t q = (size_t)y * j->w + x;
            if (j->rest_state[q] == REST_EVALUATED)
                continue;
            double fx = (double)(x - b->x0) / S, fy = (double)(y - b->y0) / S;
            if (quadratic) {
                biquadratic(v, fx, fy, j->rest[q]);
                for (int c = 0; c < 3; c++)
                    j->rest[q][c] = fmax(0.0, j->rest[q][c]);
            } else {
                sl_fill_bilinear(v, fx, fy, j->rest[q]);
            }
            memcpy(j->rest_err[q], err, 3 * sizeof *err);
            j->rest_state[q] = state;
        }
}

/* Checks a whole block's interpolation at its centre and edge midpoints;
 * on success fills its own pixels [x0, x0 + S)^2 not evaluated. On
 * failure, in the coarse pass, they keep it provisionally (REST_PROVISIONAL,
 * the difference found as its error), for a cut that leaves them there. */
static bool try_block(fill_job *j, const block *b, int S)
{
    double v[9][3], e[9][3], bmax[3];
    if (!block_points(j, b, S, v, e))
        return false;
    bool pass = sl_fill_check((const double(*)[3])v, (const double(*)[3])e, NULL, INTERP_SHARE * j->check_tol,
                              j->slack, bmax);
    if (!pass && !j->provisional)
        return false;
    fill_block(j, b, S, (const double(*)[3])v, false, bmax, pass ? REST_INTERPOLATED : REST_PROVISIONAL);
    return pass;
}

/* The centres of a block's four quarters (px offsets, S / 4 and 3 S / 4):
 * the check points of its biquadratic, and the quarters' own centres if
 * it fails. */
static size_t quarter_centre(const fill_job *j, const block *b, int S, int k)
{
    return (size_t)(b->y0 + S / 4 + (k >> 1) * S / 2) * j->w + (size_t)(b->x0 + S / 4 + (k & 1) * S / 2);
}

/* A block whose bilinear check failed, in the coarse pass: the
 * biquadratic through its nine points checked at its quarters' centres,
 * as try_block checks the bilinear (the same tolerance, no slack), fills
 * its pixels on success (the largest difference plus the points' largest
 * estimate as their error). Four evaluations instead of the quarters'
 * sixteen new points. */
static bool try_quadratic(fill_job *j, const block *b, int S)
{
    double v[9][3], e[9][3], q[4][3], bmax[3] = {0, 0, 0}, d[3] = {0, 0, 0};
    if (!block_points(j, b, S, v, e))
        return false;
    for (int k = 0; k < 13; k++) {
        const double *ek = e[k < 9 ? k : 0];
        if (k >= 9) {
            size_t p = quarter_centre(j, b, S, k - 9);
            if (j->rest_state[p] != REST_EVALUATED)
                return false;
            memcpy(q[k - 9], j->rest[p], sizeof q[0]);
            ek = j->rest_err[p];
        }
        for (int c = 0; c < 3; c++)
            bmax[c] = fmax(bmax[c], ek[c]);
    }
    bool pass = true;
    double tol = INTERP_SHARE * j->check_tol;
    for (int k = 0; k < 4; k++) {
        double at[3];
        biquadratic((const double(*)[3])v, 0.25 + 0.5 * (k & 1), 0.25 + 0.5 * (k >> 1), at);
        for (int c = 0; c < 3; c++) {
            double dk = fabs(at[c] - q[k][c]);
            pass &= dk <= tol * q[k][c] + j->slack * bmax[c];
            d[c] = fmax(d[c], dk);
        }
    }
    if (!pass)
        return false;
    for (int c = 0; c < 3; c++)
        d[c] += bmax[c];
    fill_block(j, b, S, (const double(*)[3])v, true, d, REST_INTERPOLATED);
    return true;
}

/* The sun at every glossy pixel, first: a --time cut then leaves each one
 * its exact sun and only the rest to sample. The rest is not known yet, so
 * the refinement is scaled by a quarter of the rest's mean radiance
 * (sun_floor); finish_rows refines again where the pixel's own rest asks
 * for more. Never cut: the sun is a few cells per pixel. */
static void sun_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill_job *j = ctx;
    const sl_glossy_dome *gd = j->cf->gdome;
    sl_glossy_scratch *s = scratch_for(j, worker);
    if (!s) {
        j->failed = true;
        return;
    }
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->w; x++) {
            size_t pix = (size_t)y * j->w + x;
            if (j->px->state[pix] != SL_GLOSSY_PENDING)
                continue;
            sl_quad q = {.tol = SUN_SHARE * j->sun_tol, .floor = j->sun_floor, .start_cells = gd->sun_cells,
                         .start_count = gd->sun_cell_count, .start_level = gd->sun_level};
            sl_glossy_integrate(gd->sun, material_of(j, pix), j->px->n[pix], j->px->wo[pix], &q, s, j->sun[pix],
                                j->sun_err[pix], &j->row_cost[y]);
            j->sun_state[pix] = 1;
        }
}

/* Each row in full, in image order: the rest at every pixel no block
 * interpolated, then the sun at every pixel, and the pixel's totals. A
 * --time cut leaves the rows finished before it at the tolerance and the
 * others with the best rest known (keep_cut_rows). */
static void finish_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill_job *j = ctx;
    const sl_glossy_dome *gd = j->cf->gdome;
    sl_glossy_scratch *s = scratch_for(j, worker);
    for (int64_t y = j->row0 + begin; y < j->row0 + end; y++) {
        if (j->row_cut[y])
            continue;
        if (sl_seconds() > j->deadline || (j->row_limit > 0 && y >= j->row_limit) || !s) {
            j->row_cut[y] = 1;
            j->failed |= !s;
            continue;
        }
        /* A row the deadline cuts keeps what its pixels have (keep_cut_rows):
         * a row of pixels evaluated one by one at the full tolerance would
         * overrun it by up to ~0.1 s. */
        if (!rest_of_row(j, y, false, j->deadline, s)) {
            j->row_cut[y] = 1;
            continue;
        }
        for (int x = 0; x < j->w; x++) {
            size_t pix = (size_t)y * j->w + x;
            if (j->px->state[pix] != SL_GLOSSY_PENDING)
                continue;
            double sun[3] = {0, 0, 0}, serr[3] = {0, 0, 0};
            const double *floor = j->rest[pix]; /* the sun's tolerance scale */
            sl_quad q = {.tol = SUN_SHARE * j->cf->tol, .floor = floor, .start_cells = gd->sun_cells,
                         .start_count = gd->sun_cell_count, .start_level = gd->sun_level};
            bool reuse = j->sun_state[pix];
            for (int c = 0; c < 3 && reuse; c++)
                reuse = j->sun_err[pix][c] <= q.tol * (floor[c] + j->sun[pix][c]);
            if (reuse)
                memcpy(sun, j->sun[pix], sizeof sun), memcpy(serr, j->sun_err[pix], sizeof serr);
            else if (gd->sun)
                sl_glossy_integrate(gd->sun, material_of(j, pix), j->px->n[pix], j->px->wo[pix], &q, s,
                                    sun, serr, &j->row_cost[y]);
            for (int c = 0; c < 3; c++) {
                j->px->value[pix][c] = floor[c] + sun[c];
                j->cf->bound[pix][c] = (float)(j->rest_err[pix][c] + serr[c]);
            }
            j->px->state[pix] = j->rest_state[pix] == REST_INTERPOLATED ? SL_GLOSSY_INTERPOLATED : SL_GLOSSY_DONE;
        }
    }
}

/* Band by band in image order, each row of a band in full: a --time cut
 * keeps every band finished before it. */
static void finish_bands(fill_job *j)
{
    for (int y0 = 0; y0 < j->h; y0 += BAND_ROWS) {
        int y1 = y0 + BAND_ROWS < j->h ? y0 + BAND_ROWS : j->h;
        if (past_deadline(j)) { /* as finish_rows would, without its threads */
            memset(j->row_cut + y0, 1, (size_t)(j->h - y0));
            break;
        }
        j->row0 = y0;
        sl_parallel_for(y1 - y0, 1, finish_rows, j);
    }
}

/* The map's mean radiance per channel (intensity applied). */
static void rest_mean(const sl_irradiance *ir, double out[3])
{
    double rot[3][3], intensity;
    int top = sl_irradiance_top_level(ir), tw, th;
    sl_irradiance_frame(ir, rot, &intensity);
    sl_irradiance_level_size(ir, top, &tw, &th);
    out[0] = out[1] = out[2] = 0;
    for (int y = 0; y < th; y++)
        for (int x = 0; x < tw; x++) {
            sl_dome_cell c;
            sl_irradiance_cell(ir, top, x, y, &c);
            for (int k = 0; k < 3; k++)
                out[k] += c.p[k] * intensity / (4.0 * SL_PI);
        }
}

/* The glossy pixels of the rows a --time cut left: the sun (exact, or none
 * in the map) plus the rest the full plan's blocks gave, else the coarse
 * pass's (flagged coarse), each with its error estimate; with no rest the
 * sun is exact and the rest of the map is left to sampling (SL_PIXEL_SUN,
 * value the sun, bound its error estimate). */
static void keep_cut_rows(fill_job *j)
{
    bool sun = j->cf->gdome->sun != NULL;
    for (int y = 0; y < j->h; y++)
        for (int x = 0; x < j->w && j->row_cut[y]; x++) {
            size_t pix = (size_t)y * j->w + x;
            /* A control variate's sun may be shadowed: it stays sampled. */
            if (j->px->state[pix] != SL_GLOSSY_PENDING || (sun && !j->sun_state[pix]) ||
                j->cf->mode[pix] != SL_PIXEL_EXACT)
                continue;
            const uint8_t *state = j->rest_state;
            const double(*rest)[3] = j->rest, (*rest_err)[3] = j->rest_err;
            if (!state[pix] && j->coarse_state && j->coarse_state[pix])
                state = j->coarse_state, rest = j->coarse, rest_err = j->coarse_err;
            bool has_rest = state[pix] != 0;
            if (!has_rest && !sun)
                continue; /* nothing known: sampled */
            for (int c = 0; c < 3; c++) {
                j->px->value[pix][c] = (sun ? j->sun[pix][c] : 0.0) + (has_rest ? rest[pix][c] : 0.0);
                j->cf->bound[pix][c] = (float)((sun ? j->sun_err[pix][c] : 0.0) + (has_rest ? rest_err[pix][c] : 0.0));
            }
            if (has_rest) {
                bool evaluated = state[pix] == REST_EVALUATED || state[pix] == REST_REFINED;
                j->px->state[pix] = evaluated ? SL_GLOSSY_DONE : SL_GLOSSY_INTERPOLATED;
                if (state == j->coarse_state)
                    j->px->coarse[pix] = state[pix] == REST_PROVISIONAL ? SL_GLOSSY_COARSE_PROVISIONAL
                                         : state[pix] == REST_REFINED   ? SL_GLOSSY_COARSE_REFINED
                                                                        : SL_GLOSSY_COARSE_KEPT;
            } else {
                j->cf->mode[pix] = SL_PIXEL_SUN;
            }
        }
}

/* The rest of every pixel of the rows not cut whose rest no block gave
 * (the coarse pass's last step). */
static void rest_left_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill_job *j = ctx;
    sl_glossy_scratch *s = scratch_for(j, worker);
    for (int64_t y = begin; y < end; y++) {
        if (j->row_cut[y])
            continue;
        if (!s || (j->row_limit > 0 && y >= j->row_limit) || !rest_of_row(j, y, false, j->deadline, s)) {
            j->row_cut[y] = 1;
            j->failed |= !s;
        }
    }
}

/* Evaluates the refinement's batches until the deadline. */
static void refine_batches(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill_job *j = ctx;
    sl_glossy_scratch *s = scratch_for(j, worker);
    for (int64_t b = begin; b < end && s && sl_seconds() <= j->deadline; b++) {
        size_t pix[SL_GLOSSY_BATCH];
        int count = j->batch_start[b + 1] - j->batch_start[b];
        for (int i = 0; i < count; i++)
            pix[i] = (size_t)j->order[j->batch_start[b] + i].index;
        eval_rest(j, pix, count, s, &j->worker_cost[worker]);
        for (int i = 0; i < count; i++)
            j->rest_state[pix[i]] = REST_REFINED;
    }
}

/* The coarse pass's interpolated pixels (rows not cut) with the largest
 * squared error estimates, holding all but REFINE_LEFT of their sum, at
 * most `most` of them, evaluated one by one (neighbours of a row in
 * batches) at j->tol. */
static sl_result refine_interpolated(fill_job *j, int64_t most)
{
    if (past_deadline(j))
        return SL_OK;
    size_t npix = (size_t)j->w * j->h, n = 0;
    j->order = malloc(npix * sizeof *j->order);
    j->batch_start = malloc((npix + 1) * sizeof *j->batch_start);
    j->worker_cost = calloc((size_t)j->workers, sizeof *j->worker_cost);
    if (!j->order || !j->batch_start || !j->worker_cost)
        return SL_ERR_NOMEM;
    double total = 0;
    for (size_t p = 0; p < npix; p++) {
        uint8_t st = j->rest_state[p];
        if (j->px->state[p] != SL_GLOSSY_PENDING || j->row_cut[p / j->w] ||
            (st != REST_INTERPOLATED && st != REST_PROVISIONAL))
            continue;
        const double *e = j->rest_err[p];
        j->order[n] = (sl_ranked){e[0] * e[0] + e[1] * e[1] + e[2] * e[2], (int64_t)p};
        total += j->order[n++].value;
    }
    qsort(j->order, n, sizeof *j->order, sl_cmp_ranked_desc);
    /* The batches: a block's pixels share one estimate, so they come
     * together, row by row. */
    int nbatch = 0;
    double left = total;
    for (size_t i = 0; i < n && (int64_t)i < most && left > REFINE_LEFT * total; i++) {
        size_t p = (size_t)j->order[i].index;
        bool join = false;
        if (nbatch > 0) {
            size_t p0 = (size_t)j->order[j->batch_start[nbatch - 1]].index;
            int count = (int)i - j->batch_start[nbatch - 1];
            join = p / j->w == p0 / j->w && p > (size_t)j->order[i - 1].index && p - p0 <= BATCH_SPAN &&
                   count < SL_GLOSSY_BATCH && lobes_overlap(j, p0, p);
        }
        if (!join)
            j->batch_start[nbatch++] = (int)i;
        j->batch_start[nbatch] = (int)i + 1;
        left -= j->order[i].value;
    }
    sl_parallel_for(nbatch, 1, refine_batches, j);
    /* Its cost counts in its first pixel's row. */
    for (int w = 0; w < j->workers && nbatch > 0; w++) {
        const sl_irradiance_cost *c = &j->worker_cost[w];
        sl_irradiance_cost_add(&j->row_cost[j->order[0].index / j->w], c->evaluations, c->cells, c->finest_level);
    }
    return SL_OK;
}

/* Evaluates the rests marked in need and clears it; whole: all of them,
 * deadline or not (the first level of blocks). */
static void eval_needed(fill_job *j, bool whole)
{
    double deadline = j->deadline;
    int row_limit = j->row_limit; /* the tests' stand-in for it */
    if (whole)
        j->deadline = INFINITY, j->row_limit = 0;
    sl_parallel_for(j->h, 1, rest_rows, j);
    j->deadline = deadline, j->row_limit = row_limit;
    memset(j->need, 0, (size_t)j->w * j->h);
}

/* The image blocks at j->tol: every whole 16 px block's nine points, then
 * the blocks whose check failed split in four, down to BLOCK_MIN; the
 * blocks that pass interpolate their pixels' rest. cur and next hold room
 * for every 2 x 2 block. */
static void lattice(fill_job *j, block *cur, block *next, block *fail)
{
    int w = j->w, h = j->h, ncur = 0;
    size_t npix = (size_t)w * h;
    for (int y = 0; y < h; y += BLOCK0)
        for (int x = 0; x < w; x += BLOCK0)
            cur[ncur++] = (block){x, y};
    for (int S = BLOCK0; S >= BLOCK_MIN && ncur > 0; S /= 2) {
        /* The coarse pass's first level always completes, as the Lambert
         * fill's first pass does: its points are few (metal 0.3 at 512 px:
         * 1497, 0.09 CPU s) and give most pixels a value (90 201 of 131 788),
         * while sampling them at the first pass's 2 spp would cost more
         * (about 0.2 CPU s) and be far off (docs/render.md). */
        bool whole_level = j->provisional && S == BLOCK0;
        if (!whole_level && past_deadline(j))
            break;
        /* The nine points of every whole block. */
        int nnext = 0, nfail = 0;
        for (int i = 0; i < ncur; i++) {
            if (!block_whole(j, &cur[i], S) || !block_narrow(j, &cur[i], S))
                continue;
            for (int k = 0; k < 9; k++)
                j->need[(size_t)(cur[i].y0 + POINT[k][1] * S / 2) * w + (cur[i].x0 + POINT[k][0] * S / 2)] = 1;
        }
        eval_needed(j, whole_level);
        for (int i = 0; i < ncur; i++) {
            const block *b = &cur[i];
            bool any = false;
            for (int y = b->y0; y < b->y0 + S && y < h && !any; y++)
                for (int x = b->x0; x < b->x0 + S && x < w && !any; x++) {
                    size_t p = (size_t)y * w + x;
                    any = image_blocked(j, p) && !rest_known(j->rest_state[p]) && !j->row_cut[y];
                }
            bool checked = any && block_whole(j, b, S) && block_narrow(j, b, S);
            if (!any || (checked && try_block(j, b, S)))
                continue;
            if (checked && j->quadratic) {
                fail[nfail++] = *b;
                for (int k = 0; k < 4; k++)
                    j->need[quarter_centre(j, b, S, k)] = 1;
                continue;
            }
            for (int k = 0; k < 4 && S > BLOCK_MIN; k++)
                next[nnext++] = (block){b->x0 + (k & 1) * S / 2, b->y0 + (k >> 1) * S / 2};
        }
        /* The failed blocks' biquadratics, their check points evaluated
         * first (the first level's always, as its points); those that fail
         * too are split, and their quarters' centres are already known. */
        if (nfail > 0 && (whole_level || !past_deadline(j)))
            eval_needed(j, whole_level);
        memset(j->need, 0, npix); /* also when the deadline skipped them */
        for (int i = 0; i < nfail; i++) {
            if (try_quadratic(j, &fail[i], S))
                continue;
            for (int k = 0; k < 4 && S > BLOCK_MIN; k++)
                next[nnext++] = (block){fail[i].x0 + (k & 1) * S / 2, fail[i].y0 + (k >> 1) * S / 2};
        }
        block *t = cur;
        cur = next, next = t;
        ncur = nnext;
        if (j->block_limit >= S) { /* tests: as if the deadline came now */
            memset(j->row_cut, 1, (size_t)h);
            break;
        }
    }
}

sl_result sl_glossy_fill(const sl_closed_form *cf, const sl_scene *scene, sl_glossy_pixels *px,
                         int w, int h, sl_irradiance_cost *row_cost, const sl_glossy_limits *lim,
                         uint8_t *row_cut, sl_error *err)
{
    size_t npix = (size_t)w * h;
    fill_job j = {.cf = cf, .scene = scene, .px = px, .w = w, .h = h, .row_cost = row_cost, .row_cut = row_cut};
    /* A plan that may be cut (the deadline, or the tests' stand-in) gets
     * the coarse pass first. */
    bool coarse = isfinite(lim->deadline) || lim->row_limit > 0 || lim->coarse_row_limit > 0 ||
                  lim->coarse_block_limit > 0;
    j.workers = sl_threads_get();
    j.scratch = calloc((size_t)j.workers, sizeof *j.scratch);
    j.need = calloc(npix, 1);
    j.rest_state = calloc(npix, 1);
    j.rest = malloc(npix * sizeof *j.rest);
    j.rest_err = malloc(npix * sizeof *j.rest_err);
    j.sun = malloc(npix * sizeof *j.sun);
    j.sun_err = malloc(npix * sizeof *j.sun_err);
    j.sun_state = calloc(npix, 1);
    if (coarse) {
        j.coarse_state = calloc(npix, 1);
        j.coarse = malloc(npix * sizeof *j.coarse);
        j.coarse_err = malloc(npix * sizeof *j.coarse_err);
    }
    /* At most every 2 x 2 block at once. */
    size_t nblocks = ((size_t)w / 2 + 1) * ((size_t)h / 2 + 1);
    block *cur = malloc(nblocks * sizeof *cur), *next = malloc(nblocks * sizeof *next);
    block *fail = malloc(nblocks * sizeof *fail);
    sl_result res = SL_OK;
    if (!j.scratch || !j.need || !j.rest_state || !j.rest || !j.rest_err || !j.sun || !j.sun_err ||
        !j.sun_state || !cur || !next || !fail || (coarse && (!j.coarse_state || !j.coarse || !j.coarse_err))) {
        res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the glossy pixels");
        goto done;
    }
    if (cf->gdome->sun) {
        rest_mean(cf->gdome->rest, j.sun_floor);
        for (int c = 0; c < 3; c++)
            j.sun_floor[c] *= SUN_FLOOR_SHARE;
        /* Under a deadline every pixel's sun first at no finer than the
         * default tolerance: a finished row refines it to its own. */
        j.sun_tol = isfinite(lim->deadline) ? fmax(cf->tol, SUN_PASS_TOL) : cf->tol;
        sl_parallel_for(h, 1, sun_rows, &j);
    }
    int64_t sun_evaluations = 0;
    for (int y = 0; y < h; y++)
        sun_evaluations += row_cost[y].evaluations;
    if (coarse) {
        /* The coarse pass: every pixel's rest, to the deadline; then its
         * values are kept aside for the rows the full plan does not reach
         * (which gets what time it leaves). */
        j.tol = SL_GLOSSY_COARSE * cf->tol, j.check_tol = SL_GLOSSY_COARSE_CHECK * cf->tol, j.slack = 0;
        j.deadline = lim->deadline, j.row_limit = lim->coarse_row_limit;
        j.provisional = true, j.quadratic = true, j.block_limit = lim->coarse_block_limit;
        lattice(&j, cur, next, fail);
        if (!past_deadline(&j))
            sl_parallel_for(h, 1, rest_left_rows, &j);
        j.tol = REFINE_TOL * cf->tol;
        int64_t evaluations = 0; /* the coarse pass's */
        for (int y = 0; y < h; y++)
            evaluations += row_cost[y].evaluations;
        if (refine_interpolated(&j, (int64_t)(REFINE_MOST * (double)(evaluations - sun_evaluations)))) {
            res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the glossy pixels");
            goto done;
        }
        uint8_t *ts = j.coarse_state;
        double(*tv)[3] = j.coarse, (*te)[3] = j.coarse_err;
        j.coarse_state = j.rest_state, j.coarse = j.rest, j.coarse_err = j.rest_err;
        j.rest_state = ts, j.rest = tv, j.rest_err = te;
    }
    j.tol = j.check_tol = cf->tol, j.slack = 2.0;
    j.deadline = lim->deadline, j.row_limit = lim->row_limit;
    j.provisional = false, j.quadratic = false, j.block_limit = 0;
    lattice(&j, cur, next, fail);
    finish_bands(&j);
    keep_cut_rows(&j);
done:
    for (int i = 0; j.scratch && i < j.workers; i++)
        sl_glossy_scratch_free(j.scratch[i]);
    free(j.scratch);
    free(j.need);
    free(j.rest_state);
    free(j.rest);
    free(j.rest_err);
    free(j.coarse_state);
    free(j.coarse);
    free(j.coarse_err);
    free(j.sun);
    free(j.sun_err);
    free(j.sun_state);
    free(j.order);
    free(j.batch_start);
    free(j.worker_cost);
    free(cur);
    free(next);
    free(fail);
    return res;
}
