/* SPDX-License-Identifier: BSD-3-Clause */
/* The shadowed part of a Lambert pixel under the dome alone, with no
 * bounces: what the control variate sampled (closed form minus the blocked
 * light), computed instead. With no bounces a blocked direction adds
 * nothing, so the pixel is rho/pi (E - S), E the unoccluded irradiance
 * (irradiance.c, normal_fill.c) and S the integral of L(w) max(0, n.w)
 * over the directions the other shapes block.
 *
 * Seen from a point, a sphere blocks a spherical cap and a rect a convex
 * spherical quad (its corners' directions; each edge a great-circle arc).
 * The map's cells (irradiance.c's mip levels, each with its bounding cone)
 * are classified against them: a cone farther from the cap's axis than the
 * cap's radius plus its own is outside, one nearer than the difference
 * inside; a cone beyond one edge's great circle by more than its radius is
 * outside the quad, one inside every edge's by more than its radius inside.
 * Inside cells add what they add to the irradiance (exact above the
 * horizon), outside cells nothing; a cell that straddles an edge adds
 * between nothing and its whole share: its estimate is the share times the
 * part of the cell on the blocked side (the edge's function linear over
 * the cell's two angles), and the rest of that range is its bound. The cell with the largest bound is split (mip levels, then pieces
 * of a texel) until the bounds sum to the tolerance, so the refinement
 * follows the blocked set's outline and a sun's texels are split only
 * where a shadow's edge crosses them. */
#include <stdlib.h>
#include <string.h>

#include "glossy.h"
#include "shadow_fill.h"
#include "slot_heap.h"
#include "vec3.h"

/* Deepest split inside a texel (1/2^k of its width). */
#define SUBTEXEL_DEPTH 6
/* Open cells kept at once; past it the bound is what it is (reported). */
#define OPEN_CAP 4096
/* Tolerance shares: a point's quadrature (past the deadline a coarser
 * one: the bound is far above the true error, measured in
 * docs/render.md), a block's interpolation check. */
#define EVAL_SHARE 1.0
#define LATE_SHARE 4.0
#define INTERP_SHARE 0.25
#define BLOCK0 16
#define BLOCK_MIN 4

/* ---- the blocked directions ---- */

/* A rect's corners in order around it. */
static void rect_corners(const sl_shape *r, double k[4][3])
{
    static const double su[4] = {1, -1, -1, 1}, sv[4] = {1, 1, -1, -1};
    for (int i = 0; i < 4; i++)
        for (int d = 0; d < 3; d++)
            k[i][d] = r->center[d] + su[i] * r->u[d] + sv[i] * r->v[d];
}

/* The world vector a in the map's frame. */
static void to_map(const double rot[3][3], const double a[3], double out[3])
{
    m3_mul_transpose(rot, a, out);
}

static bool add_sphere(const sl_shape *b, const double rot[3][3], const double p[3], const double n[3],
                       sl_blocker *out, bool *none)
{
    double d[3] = {b->center[0] - p[0], b->center[1] - p[1], b->center[2] - p[2]};
    double D = v3_length(d);
    if (!(D > b->radius * (1.0 + 1e-9)))
        return false; /* p inside it (or on it): not a cap */
    out->edges = 0;
    out->sin_s = b->radius / D;
    out->cos_s = sqrt(fmax(0.0, 1.0 - out->sin_s * out->sin_s));
    double a[3] = {d[0] / D, d[1] / D, d[2] / D};
    /* wholly below the horizon: blocks nothing that counts */
    *none = v3_dot(n, a) <= -out->sin_s;
    to_map(rot, a, out->axis);
    return true;
}

static void add_rect(const sl_shape *b, const double rot[3][3], const double p[3], const double n[3],
                     sl_blocker *out, bool *none)
{
    double k[4][3], g[3] = {b->center[0] - p[0], b->center[1] - p[1], b->center[2] - p[2]};
    rect_corners(b, k);
    double scale = 1e-12 * (v3_length(b->u) + v3_length(b->v) + v3_length(g));
    /* Edge-on (p in its plane) or wholly below the horizon: no solid angle
     * above it. */
    *none = fabs(v3_dot(b->normal, g)) <= scale;
    bool above = false;
    for (int i = 0; i < 4; i++) {
        for (int d = 0; d < 3; d++)
            k[i][d] -= p[d];
        above |= v3_dot(n, k[i]) > 0;
    }
    *none |= !above;
    if (*none)
        return;
    out->edges = 4;
    for (int i = 0; i < 4; i++) {
        double e[3];
        v3_cross(k[i], k[(i + 1) % 4], e);
        if (v3_dot(e, g) < 0)
            e[0] = -e[0], e[1] = -e[1], e[2] = -e[2];
        v3_normalize(e);
        to_map(rot, e, out->edge[i]);
    }
}

bool sl_blockers_at(const sl_scene *scene, const sl_irradiance *ir, int shape, const double p[3],
                    const double n[3], sl_blockers *out)
{
    double rot[3][3], intensity;
    sl_irradiance_frame(ir, rot, &intensity);
    out->count = 0;
    for (int i = 0; i < scene->shape_count; i++) {
        if (i == shape)
            continue;
        const sl_shape *b = &scene->shapes[i];
        bool none = false;
        if (out->count == SL_BLOCKERS_MAX)
            return false;
        sl_blocker *bl = &out->b[out->count];
        if (b->type == SL_SHAPE_SPHERE) {
            if (!add_sphere(b, rot, p, n, bl, &none))
                return false;
        } else if (b->type == SL_SHAPE_RECT) {
            add_rect(b, rot, p, n, bl, &none);
        } else {
            /* a disk: fine when wholly below the horizon */
            double g[3] = {b->center[0] - p[0], b->center[1] - p[1], b->center[2] - p[2]};
            double c = v3_dot(n, b->normal);
            if (v3_dot(n, g) + b->radius * sqrt(fmax(0.0, 1.0 - c * c)) > 0)
                return false;
            none = true;
        }
        out->count += !none;
    }
    return true;
}

static double ramp2(double z) { return z > 0 ? 0.5 * z * z : 0.0; }

/* Share of U, V uniform on [-1, 1] with mu + a U + b V > 0 (a, b >= 0):
 * how much of a small cell lies on the positive side of a function linear
 * in its two angles. */
static double step_share(double mu, double a, double b)
{
    if (mu >= a + b)
        return 1.0;
    if (mu <= -(a + b))
        return 0.0;
    double big = a > b ? a : b, small = a > b ? b : a;
    if (small < 1e-4 * big) /* one angle: linear across the cell */
        return fmin(1.0, fmax(0.0, 0.5 + 0.5 * mu / big));
    return (ramp2(mu + a + b) - ramp2(mu + a - b) - ramp2(mu - a + b) + ramp2(mu - a - b)) / (4.0 * a * b);
}

/* A cell's centre direction and its derivatives along colatitude and
 * longitude times the half-widths: g(w) ~ g(c) + (g'.dt) U + (g'.dl) V. */
typedef struct cell_span {
    double dt[3], dl[3];
} cell_span;

static void span_of(const sl_dome_cell *c, cell_span *sp)
{
    double ct = c->centre[1], st = sqrt(fmax(0.0, 1.0 - ct * ct));
    double cl = st > 0 ? c->centre[2] / st : 1.0, sl = st > 0 ? c->centre[0] / st : 0.0;
    double ht = 0.5 * (c->t1 - c->t0), hl = 0.5 * (c->b - c->a);
    v3_set(sp->dt, ct * sl * ht, -st * ht, ct * cl * ht);
    v3_set(sp->dl, st * cl * hl, 0, -st * sl * hl);
}

/* Where a cell's cone lies against a blocker: 1 inside, -1 outside, 0
 * straddling, with *share the estimated part of the cell on the blocked
 * side (the edge's function linear over the cell). Decided in cosines
 * (cos(s -+ r) for a cap, sin r against an edge plane). */
static int classify(const sl_blocker *b, const sl_dome_cell *c, double *share)
{
    double cr = c->cos_r, sr = c->sin_r;
    cell_span sp;
    if (b->edges == 0) {
        double ca = v3_dot(c->centre, b->axis);
        if (!c->wide && b->sin_s * cr >= b->cos_s * sr && ca >= b->cos_s * cr + b->sin_s * sr)
            return 1; /* s >= r and the centre within s - r of the axis */
        if (!c->wide && ca <= b->cos_s * cr - b->sin_s * sr)
            return -1; /* the centre beyond s + r (< pi: both below pi / 2) */
        span_of(c, &sp);
        *share = step_share(ca - b->cos_s, fabs(v3_dot(b->axis, sp.dt)), fabs(v3_dot(b->axis, sp.dl)));
        return 0;
    }
    double least = 1;
    for (int i = 0; i < b->edges; i++) {
        double d = v3_dot(c->centre, b->edge[i]);
        if (!c->wide && d <= -sr)
            return -1;
        least = d < least ? d : least;
    }
    if (!c->wide && least >= sr)
        return 1;
    /* inside every edge: at most the least share of them */
    span_of(c, &sp);
    *share = 1;
    for (int i = 0; i < b->edges; i++) {
        const double *e = b->edge[i];
        *share = fmin(*share, step_share(v3_dot(c->centre, e), fabs(v3_dot(e, sp.dt)), fabs(v3_dot(e, sp.dl))));
    }
    return 0;
}

/* ---- the quadrature ---- */

typedef struct open_cell {
    double key; /* largest bound over the channels, scaled */
    double mid[3], bnd[3];
    int level, x, y;
    double t0, t1, a, b;
    unsigned mask; /* blockers it straddles; 0: wholly inside one */
} open_cell;

typedef struct quad_state {
    const sl_irradiance *ir;
    const sl_blockers *bl;
    double n[3];     /* map frame */
    double exact[3]; /* cells wholly blocked and above the horizon */
    double inv_scale[3];
    open_cell pool[OPEN_CAP];
    int heap[OPEN_CAP], free_list[OPEN_CAP];
    sl_slot_heap h;
    sl_open_sums sums;
    int64_t cells;
    int finest;
} quad_state;

/* Adds cell c: inside (its parent was wholly blocked) or tested against
 * the blockers in mask. */
static void add_cell(quad_state *st, const sl_dome_cell *c, unsigned mask, bool inside)
{
    st->cells++;
    double share = 0;
    unsigned left = 0;
    for (int i = 0; i < st->bl->count && !inside; i++) {
        if (!(mask >> i & 1u))
            continue;
        double s = 0;
        int side = classify(&st->bl->b[i], c, &s);
        inside = side > 0;
        if (side == 0)
            left |= 1u << i, share = s > share ? s : share;
    }
    if (!inside && !left)
        return;
    double lower[3], est[3], upper[3];
    int side = sl_irradiance_cell_share(st->n, c, lower, est, upper);
    if (side < 0)
        return;
    if (inside && side > 0) {
        for (int ch = 0; ch < 3; ch++)
            st->exact[ch] += est[ch];
        return;
    }
    open_cell o = {.level = c->level, .x = c->x, .y = c->y, .t0 = c->t0, .t1 = c->t1, .a = c->a, .b = c->b,
                   .mask = inside ? 0u : left};
    for (int ch = 0; ch < 3; ch++) {
        if (inside) {
            o.mid[ch] = est[ch];
            o.bnd[ch] = fmax(upper[ch] - est[ch], est[ch] - lower[ch]);
        } else { /* between none of it and all of it */
            o.mid[ch] = share * est[ch];
            o.bnd[ch] = fmax(o.mid[ch], upper[ch] - o.mid[ch]);
        }
        o.key = fmax(o.key, o.bnd[ch] * st->inv_scale[ch]);
    }
    if (o.key > 0 || o.mid[0] > 0 || o.mid[1] > 0 || o.mid[2] > 0) {
        sl_open_sums_add(&st->sums, o.mid, o.bnd, 1.0);
        sl_slot_heap_push(&st->h, &o);
    }
}

static void split(quad_state *st, const open_cell *o)
{
    sl_dome_cell c[4];
    int n = sl_irradiance_children(st->ir, o->level, o->x, o->y, o->t0, o->t1, o->a, o->b, c);
    for (int i = 0; i < n; i++)
        add_cell(st, &c[i], o->mask, o->mask == 0);
    if (o->level - 1 < st->finest)
        st->finest = o->level - 1;
}

/* Sums over the open cells, from scratch (running sums drift by rounding). */
static void open_totals(const quad_state *st, double mid[3], double bnd[3])
{
    for (int ch = 0; ch < 3; ch++)
        mid[ch] = bnd[ch] = 0;
    for (int i = 0; i < st->h.count; i++) {
        const open_cell *o = sl_slot_heap_at(&st->h, i);
        for (int ch = 0; ch < 3; ch++)
            mid[ch] += o->mid[ch], bnd[ch] += o->bnd[ch];
    }
}

void sl_shadow_integrate(const sl_irradiance *ir, const sl_blockers *bl, const double n[3], const sl_quad *q,
                         double S[3], double bound[3], sl_irradiance_cost *cost)
{
    for (int ch = 0; ch < 3; ch++)
        S[ch] = bound[ch] = 0;
    if (bl->count == 0)
        return; /* nothing blocked: exactly 0 */
    quad_state *st = malloc(sizeof *st);
    if (!st) { /* no room to integrate: the bound says so */
        bound[0] = bound[1] = bound[2] = INFINITY;
        return;
    }
    double rot[3][3], intensity;
    sl_irradiance_frame(ir, rot, &intensity);
    st->ir = ir, st->bl = bl;
    to_map(rot, n, st->n);
    v3_normalize(st->n);
    st->h = (sl_slot_heap){.pool = st->pool, .stride = sizeof st->pool[0], .heap = st->heap,
                           .free_list = st->free_list};
    st->cells = 0;
    st->finest = sl_irradiance_top_level(ir);
    double floor[3];
    for (int ch = 0; ch < 3; ch++) {
        st->exact[ch] = st->sums.mid[ch] = st->sums.bnd[ch] = 0;
        floor[ch] = q->floor && intensity > 0 ? fmax(0.0, q->floor[ch] / intensity) : 0.0;
        st->inv_scale[ch] = floor[ch] > 0 ? 1.0 / floor[ch] : 1.0;
    }
    unsigned all = (1u << bl->count) - 1u;
    int top = sl_irradiance_top_level(ir), tw, th;
    sl_irradiance_level_size(ir, top, &tw, &th);
    for (int y = 0; y < th; y++)
        for (int x = 0; x < tw; x++) {
            sl_dome_cell c;
            sl_irradiance_cell(ir, top, x, y, &c);
            add_cell(st, &c, all, false);
        }
    int steps = 0;
    while (st->h.count > 0 && st->h.count + 4 <= OPEN_CAP) {
        if (++steps % 128 == 0)
            open_totals(st, st->sums.mid, st->sums.bnd);
        bool met = true;
        for (int ch = 0; ch < 3; ch++) {
            double value = fmax(0.0, st->exact[ch] + st->sums.mid[ch] - st->sums.bnd[ch]);
            met &= st->sums.bnd[ch] <= q->tol * (value + floor[ch]);
        }
        const open_cell *worst = sl_slot_heap_at(&st->h, 0);
        if (met || worst->level <= -SUBTEXEL_DEPTH || worst->key <= 0)
            break;
        open_cell o;
        sl_slot_heap_pop(&st->h, &o);
        sl_open_sums_add(&st->sums, o.mid, o.bnd, -1.0);
        split(st, &o);
    }
    double mid[3], bnd[3];
    open_totals(st, mid, bnd);
    for (int ch = 0; ch < 3; ch++) {
        S[ch] = fmax(0.0, st->exact[ch] + mid[ch]) * intensity;
        bound[ch] = bnd[ch] * intensity;
    }
    if (cost)
        sl_irradiance_cost_add(cost, 1, st->cells, st->finest);
    free(st);
}

/* ---- the pixels ---- */

typedef struct shadow_job {
    const sl_scene *scene;
    const sl_irradiance *ir;
    double tol;
    sl_shadow_pixels *px;
    double deadline;
    uint8_t *need;    /* this pass's points */
    uint8_t *refused; /* sl_blockers_at refused the pixel: it stays pending */
    uint8_t *smooth;  /* in a block that passed its check */
    uint8_t *grid;    /* box filter: pixels to take a 3 x 3 grid's mean */
    sl_irradiance_cost *row_cost;
} shadow_job;

/* S at image point (sx, sy) of pixel pix's shape, to the finer tolerance
 * until the deadline; false when the point misses the shape or its
 * blockers are refused. */
static bool eval_point(shadow_job *j, size_t pix, double sx, double sy, double S[3], double B[3],
                       sl_irradiance_cost *cost)
{
    const sl_camera *cam = &j->scene->camera;
    double o[3], d[3];
    sl_hit h;
    sl_blockers bl;
    int shape = j->px->shape[pix];
    if (!sl_camera_ray(cam, sx / cam->width, sy / cam->height, o, d) || !sl_shape_intersect(j->scene, shape, o, d, &h) ||
        !sl_blockers_at(j->scene, j->ir, shape, h.p, h.n, &bl))
        return false;
    sl_quad q = {.tol = (sl_seconds() > j->deadline ? LATE_SHARE : EVAL_SHARE) * j->tol, .floor = j->px->floor[pix]};
    sl_shadow_integrate(j->ir, &bl, h.n, &q, S, B, cost);
    return true;
}

/* The pixel's S: at its centre, or with box the mean of a 3 x 3 grid
 * (its middle point the centre). A pixel that cannot be had is marked
 * refused. */
#define GRID 3
static void eval_pixel(shadow_job *j, size_t pix, bool box, sl_irradiance_cost *cost)
{
    sl_shadow_pixels *px = j->px;
    int x = (int)(pix % (size_t)px->w), y = (int)(pix / (size_t)px->w);
    if (!box) {
        if (eval_point(j, pix, x + 0.5, y + 0.5, px->S[pix], px->bound[pix], cost))
            px->state[pix] = SL_SHADOW_DONE;
        else
            j->refused[pix] = 1;
        return;
    }
    double mean[3] = {0, 0, 0}, bmean[3] = {0, 0, 0}, centre[3] = {0, 0, 0};
    for (int k = 0; k < GRID * GRID; k++) {
        double S[3], B[3];
        if (!eval_point(j, pix, x + (k % GRID + 0.5) / GRID, y + (k / GRID + 0.5) / GRID, S, B, cost)) {
            /* a sub-point off the shape (rounding at a corner): no box
             * mean, so the pixel stays a control variate */
            j->refused[pix] = 1;
            px->state[pix] = SL_SHADOW_PENDING;
            return;
        }
        for (int c = 0; c < 3; c++) {
            mean[c] += S[c] / (GRID * GRID), bmean[c] += B[c] / (GRID * GRID);
            if (k == GRID * GRID / 2)
                centre[c] = S[c];
        }
    }
    for (int c = 0; c < 3; c++) {
        px->S[pix][c] = mean[c];
        px->bound[pix][c] = bmean[c] + fabs(centre[c] - mean[c]) / 8.0;
    }
    px->state[pix] = SL_SHADOW_DONE;
}

/* Evaluates the pixels marked in need (or, need NULL, every pending one),
 * row by row. */
static void eval_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    shadow_job *j = ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->px->w; x++) {
            size_t pix = (size_t)y * (size_t)j->px->w + (size_t)x;
            /* a block's point another block interpolated: evaluated again;
             * last (grid), the box filter's 3 x 3 grids */
            uint8_t s = j->px->state[pix];
            bool want = j->grid ? j->grid[pix]
                        : j->need ? j->need[pix] && (s == SL_SHADOW_PENDING || s == SL_SHADOW_INTERPOLATED)
                                  : s == SL_SHADOW_PENDING;
            if (!want || j->refused[pix])
                continue;
            eval_pixel(j, pix, j->grid != NULL, &j->row_cost[y]);
        }
}

/* A block's nine points: corners, edge midpoints, centre (sl_fill_check's
 * order), in halves of its size. */
static const int POINT[9][2] = {{0, 0}, {2, 0}, {0, 2}, {2, 2}, {1, 0}, {0, 1}, {2, 1}, {1, 2}, {1, 1}};

/* Every pixel of the closed block [x0, x0 + size]^2 pending on one shape. */
static bool whole_block(const shadow_job *j, int x0, int y0, int size)
{
    const sl_shadow_pixels *px = j->px;
    if (x0 + size >= px->w || y0 + size >= px->h)
        return false;
    int shape = px->shape[(size_t)y0 * px->w + x0];
    for (int y = y0; y <= y0 + size; y++)
        for (int x = x0; x <= x0 + size; x++) {
            size_t p = (size_t)y * px->w + x;
            if (px->state[p] == SL_SHADOW_NONE || px->shape[p] != shape)
                return false;
        }
    return true;
}

/* Interpolates the block's pixels from its corners when its nine points
 * were evaluated and agree. */
static bool fill_block(shadow_job *j, int x0, int y0, int size)
{
    sl_shadow_pixels *px = j->px;
    double v[9][3], e[9][3], scale[9][3], err[3];
    for (int k = 0; k < 9; k++) {
        size_t p = (size_t)(y0 + POINT[k][1] * size / 2) * px->w + (size_t)(x0 + POINT[k][0] * size / 2);
        if (px->state[p] != SL_SHADOW_DONE)
            return false;
        memcpy(v[k], px->S[p], sizeof v[k]);
        memcpy(e[k], px->bound[p], sizeof e[k]);
        memcpy(scale[k], px->floor[p], sizeof scale[k]);
    }
    /* No slack for the points' bounds: they are far above their true error. */
    if (!sl_fill_check(v, e, (const double(*)[3])scale, INTERP_SHARE * j->tol, 0.0, err))
        return false;
    for (int y = y0; y <= y0 + size; y++)
        for (int x = x0; x <= x0 + size; x++)
            j->smooth[(size_t)y * px->w + x] = 1;
    for (int y = y0; y < y0 + size; y++)
        for (int x = x0; x < x0 + size; x++) {
            size_t p = (size_t)y * px->w + x;
            if (px->state[p] != SL_SHADOW_PENDING)
                continue;
            sl_fill_bilinear((const double(*)[3])v, (double)(x - x0) / size, (double)(y - y0) / size, px->S[p]);
            memcpy(px->bound[p], err, sizeof err);
            px->state[p] = SL_SHADOW_INTERPOLATED;
        }
    return true;
}

static bool any_pending(const shadow_job *j, int x0, int y0, int size)
{
    for (int y = y0; y < y0 + size && y < j->px->h; y++)
        for (int x = x0; x < x0 + size && x < j->px->w; x++)
            if (j->px->state[(size_t)y * j->px->w + x] == SL_SHADOW_PENDING)
                return true;
    return false;
}

/* The box filter's mean of S over each pixel no passed block covers: its
 * centre plus the 5-point Laplacian term (sum of the 4 neighbours' centre
 * values - 4 x centre) / 24 where the neighbours show the same shape and
 * have S (the term's size its error estimate, as closed_form.c's filter),
 * else a 3 x 3 grid's mean. */
static sl_result box_means(shadow_job *j, sl_error *err)
{
    sl_shadow_pixels *px = j->px;
    int w = px->w, h = px->h;
    size_t npix = (size_t)w * h;
    double(*centre)[3] = malloc(npix * sizeof *centre);
    j->grid = calloc(npix, 1);
    if (!centre || !j->grid) {
        free(centre);
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the shadowed pixels");
    }
    memcpy(centre, px->S, npix * sizeof *centre);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t p = (size_t)y * w + x;
            if (px->state[p] != SL_SHADOW_DONE || j->smooth[p])
                continue;
            bool inner = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
            const size_t nb[4] = {p - 1, p + 1, p - (size_t)w, p + (size_t)w};
            for (int k = 0; k < 4 && inner; k++)
                inner = (px->state[nb[k]] == SL_SHADOW_DONE || px->state[nb[k]] == SL_SHADOW_INTERPOLATED) &&
                        px->shape[nb[k]] == px->shape[p];
            double lap[3] = {0, 0, 0};
            for (int c = 0; c < 3 && inner; c++) {
                lap[c] = (centre[nb[0]][c] + centre[nb[1]][c] + centre[nb[2]][c] + centre[nb[3]][c] -
                          4.0 * centre[p][c]) / 24.0;
                /* a shadow's edge: the correction is no estimate there */
                inner = fabs(lap[c]) <= INTERP_SHARE * j->tol * px->floor[p][c];
            }
            if (!inner) {
                j->grid[p] = 1;
                continue;
            }
            for (int c = 0; c < 3; c++) {
                px->S[p][c] = centre[p][c] + lap[c];
                px->bound[p][c] += fabs(lap[c]);
            }
        }
    free(centre);
    sl_parallel_for(h, 1, eval_rows, j);
    j->grid = (free(j->grid), NULL);
    return SL_OK;
}

sl_result sl_shadow_fill(const sl_scene *scene, const sl_irradiance *ir, double tol, sl_shadow_pixels *px,
                         double deadline, sl_irradiance_cost *cost, sl_error *err)
{
    int w = px->w, h = px->h;
    size_t npix = (size_t)w * h;
    shadow_job j = {.scene = scene, .ir = ir, .tol = tol, .px = px, .deadline = deadline};
    j.need = calloc(npix, 1);
    j.refused = calloc(npix, 1);
    j.smooth = calloc(npix, 1);
    j.row_cost = calloc((size_t)h, sizeof *j.row_cost);
    /* at most one block per BLOCK_MIN x BLOCK_MIN tile of the image */
    size_t nblocks = ((size_t)w / BLOCK_MIN + 1) * ((size_t)h / BLOCK_MIN + 1);
    int *cur = malloc(2 * nblocks * sizeof *cur), *next = malloc(2 * nblocks * sizeof *next);
    sl_result res = SL_OK;
    if (!j.need || !j.refused || !j.smooth || !j.row_cost || !cur || !next) {
        res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the shadowed pixels");
        goto done;
    }
    for (int y = 0; y < h; y++)
        j.row_cost[y].finest_level = sl_irradiance_top_level(ir);
    int ncur = 0;
    for (int y = 0; y < h; y += BLOCK0)
        for (int x = 0; x < w; x += BLOCK0)
            cur[2 * ncur] = x, cur[2 * ncur + 1] = y, ncur++;
    for (int size = BLOCK0; size >= BLOCK_MIN && ncur > 0; size /= 2) {
        for (int i = 0; i < ncur; i++)
            if (whole_block(&j, cur[2 * i], cur[2 * i + 1], size))
                for (int k = 0; k < 9; k++)
                    j.need[(size_t)(cur[2 * i + 1] + POINT[k][1] * size / 2) * w +
                           (size_t)(cur[2 * i] + POINT[k][0] * size / 2)] = 1;
        sl_parallel_for(h, 1, eval_rows, &j);
        memset(j.need, 0, npix);
        int nnext = 0;
        for (int i = 0; i < ncur; i++) {
            int x0 = cur[2 * i], y0 = cur[2 * i + 1];
            if (!any_pending(&j, x0, y0, size) || (whole_block(&j, x0, y0, size) && fill_block(&j, x0, y0, size)))
                continue;
            for (int k = 0; k < 4 && size > BLOCK_MIN; k++) {
                int cx = x0 + (k & 1) * size / 2, cy = y0 + (k >> 1) * size / 2;
                if (cx < w && cy < h)
                    next[2 * nnext] = cx, next[2 * nnext + 1] = cy, nnext++;
            }
        }
        int *t = cur;
        cur = next, next = t;
        ncur = nnext;
    }
    /* What no block interpolated: one by one. */
    j.need = (free(j.need), NULL);
    sl_parallel_for(h, 1, eval_rows, &j);
    if (px->box && (res = box_means(&j, err)))
        goto done;
    for (int y = 0; y < h; y++)
        sl_irradiance_cost_add(cost, j.row_cost[y].evaluations, j.row_cost[y].cells, j.row_cost[y].finest_level);
done:
    free(j.need);
    free(j.refused);
    free(j.smooth);
    free(j.row_cost);
    free(cur);
    free(next);
    return res;
}
