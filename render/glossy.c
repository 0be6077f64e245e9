/* SPDX-License-Identifier: BSD-3-Clause */
/* Closed form for glossy lobes: the radiance a rough conductor or plastic
 * reflects toward the viewer under the dome alone is the 2D integral of
 * the piecewise-constant lat-long against the lobe k(w) = f(wo, w) max(0, n.w)
 * for that pixel's (normal, view) pair. It is computed deterministically
 * over the irradiance mip levels' cells (irradiance.c), as the Lambert
 * closed form is:
 *
 * - a cell with power P (exact, analytic) contributes P k(d), d its
 *   power-weighted mean direction (exact when L is one point in the cell,
 *   a sun; second order in the cell size otherwise);
 * - its error is estimated as P times the range of k over the cell's
 *   centre, four corners, mean direction and, when the cell is wider than
 *   the lobe and within LOBE_REACH alphas of it, the mirror direction (the
 *   lobe's peak); cells wholly below the horizon add
 *   nothing, exactly;
 * - the cell with the largest error is split (mip level by level, then
 *   inside a texel, down to 1/256 of it) until the summed error is below
 *   tol x the value in every channel, so bright texels (a sun) under the
 *   lobe end at full resolution and beyond, and dim or far ones stay coarse.
 *
 * f is sl_bsdf_eval itself (GGX with Fresnel, the Kulla-Conty multiple
 * scattering term, the plastic's diffuse under its coat), in the frame the
 * integrator uses, so the closed form and the sampled renderer integrate
 * the same function. The error is an estimate, not a proven bound: a lobe
 * narrower than the sample points' spacing could hide between them, which
 * is why the mirror direction is always among them. */
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "glossy.h"
#include "microfacet.h"
#include "slot_heap.h"

/* fmin/fmax are libm calls without -ffinite-math-only; the quadrature's
 * values are finite. */
static inline double max2(double a, double b) { return a > b ? a : b; }
static inline double min2(double a, double b) { return a < b ? a : b; }

/* Cells kept at once; past it the error is what it is (reported). */
#define CELL_CAP 2048
/* A cell wider than the lobe is bounded by its min/max when the lobe's
 * mirror is within this many alphas of its cone, not only inside it: at
 * grazing views the lobe's tail reaches into a neighbouring wide cell that
 * the 5 points miss (Grace_Cathedral, metal 0.3, 71 degrees: 5.2% off at
 * an estimate of 0.34% with the mirror inside only). */
#define LOBE_REACH 2.0
/* Deepest split inside a texel (1/2^k of its width). */
#define SUBTEXEL_DEPTH 8

bool sl_glossy_applies(const sl_material *m)
{
    return (m->type == SL_MAT_CONDUCTOR || m->type == SL_MAT_PLASTIC) &&
           m->roughness >= SL_ROUGHNESS_DELTA;
}

typedef struct lobe {
    sl_glossy_view view;     /* the material and wo in the shading frame */
    double t[3], b[3], n[3]; /* the integrator's shading frame, in the map's frame */
    double mirror[3];        /* the lobe's peak (about), map frame */
    double cos_width;        /* cos of the lobe's narrowest width (alpha) */
    double reach;            /* LOBE_REACH x its widest alpha (radians) */
    double cos_reach, sin_reach;
} lobe;

/* k(w) = f(wo, w) max(0, n.w) per channel, w in the map's frame. */
static void kernel(const lobe *l, const double w[3], double k[3])
{
    double wl[3] = {v3_dot(w, l->t), v3_dot(w, l->b), v3_dot(w, l->n)};
    if (!(wl[2] > 0)) {
        k[0] = k[1] = k[2] = 0;
        return;
    }
    sl_glossy_kernel(&l->view, wl, k);
}

/* A cell's share for one lobe. */
typedef struct cell_lobe {
    double est[3], err[3];
    double k[5][3]; /* k at the centre and the four corners, reused by the children */
} cell_lobe;

/* The heap holds only the lobes in use: its stride ends after lb[lobes - 1]. */
typedef struct gcell {
    double key;
    int level, x, y;
    bool clipped; /* a mip cell cut by the map's edge: its centre is not its midpoint */
    double t0, t1, a, b;
    cell_lobe lb[SL_GLOSSY_BATCH];
} gcell;

/* k at the points of one split, by their (colatitude, longitude): a
 * child's corner is often its parent's corner or centre or a sibling's
 * corner, so 4 children cost 12 new evaluations instead of 24. */
#define POINT_CACHE 16
typedef struct point_cache {
    int n;
    double t[POINT_CACHE], a[POINT_CACHE];
    double k[POINT_CACHE][SL_GLOSSY_BATCH][3];
} point_cache;

/* One integral over shared cells for nl lobes (neighbouring pixels): the
 * cells' geometry and the refinement are paid once, k per lobe. */
typedef struct gstate {
    const sl_irradiance *ir;
    int nl;
    lobe l[SL_GLOSSY_BATCH];
    double inv_scale[SL_GLOSSY_BATCH][3];
    sl_slot_heap h;
    double sum_est[SL_GLOSSY_BATCH][3], sum_err[SL_GLOSSY_BATCH][3];
    int64_t cells;
    int finest;
    int map_w, map_h;  /* texels */
    bool have_k_mirror[SL_GLOSSY_BATCH];
    double k_mirror[SL_GLOSSY_BATCH][3]; /* k at each lobe's peak, once per integral */
    int64_t kernel_calls;
    /* k at the corners of the start level's cells, (tw + 1) x (th + 1)
     * points in row order, when every cell of a level starts (else NULL). */
    double (*grid_k)[SL_GLOSSY_BATCH][3];
    bool *grid_have;
} gstate;

/* k of every lobe at w; lobes whose horizon the cell is wholly below
 * (below[i]) have k = 0 there without evaluating. */
static void kernel_counted(gstate *st, const bool *below, const double w[3], double k[][3])
{
    for (int i = 0; i < st->nl; i++) {
        if (below[i]) {
            k[i][0] = k[i][1] = k[i][2] = 0;
            continue;
        }
        st->kernel_calls++;
        kernel(&st->l[i], w, k[i]);
    }
}

/* Same parameters within rounding: the same direction. */
#define SAME_PARAM 1e-12

/* k of every lobe at corner `corner` of g, from the split's cache when it
 * has the point, or from the start level's corner grid (grid_at >= 0). */
static void point_k(gstate *st, point_cache *pc, const bool *below, double t, double a, const double w[3],
                    gcell *g, int corner, int grid_at)
{
    if (grid_at >= 0) {
        if (!st->grid_have[grid_at]) {
            /* A lobe this cell is wholly below has k = 0 at the corner
             * anyway: the grid holds the true k for every cell. */
            kernel_counted(st, below, w, st->grid_k[grid_at]);
            st->grid_have[grid_at] = true;
        }
        for (int l = 0; l < st->nl; l++)
            memcpy(g->lb[l].k[corner], st->grid_k[grid_at][l], sizeof st->grid_k[grid_at][l]);
        return;
    }
    for (int i = 0; pc && i < pc->n; i++)
        if (fabs(t - pc->t[i]) <= SAME_PARAM && fabs(a - pc->a[i]) <= SAME_PARAM) {
            for (int l = 0; l < st->nl; l++)
                memcpy(g->lb[l].k[corner], pc->k[i][l], sizeof pc->k[i][l]);
            return;
        }
    double k[SL_GLOSSY_BATCH][3];
    kernel_counted(st, below, w, k);
    for (int l = 0; l < st->nl; l++)
        memcpy(g->lb[l].k[corner], k[l], sizeof k[l]);
    if (pc && pc->n < POINT_CACHE) {
        pc->t[pc->n] = t, pc->a[pc->n] = a;
        memcpy(pc->k[pc->n], k, (size_t)st->nl * sizeof k[0]);
        pc->n++;
    }
}

static double cell_key(const gstate *st, const gcell *g)
{
    double key = 0;
    for (int l = 0; l < st->nl; l++)
        for (int c = 0; c < 3; c++)
            key = max2(key, g->lb[l].err[c] * st->inv_scale[l][c]);
    return key;
}

static void push(gstate *st, const gcell *g)
{
    for (int l = 0; l < st->nl; l++)
        for (int c = 0; c < 3; c++)
            st->sum_est[l][c] += g->lb[l].est[c], st->sum_err[l][c] += g->lb[l].err[c];
    sl_slot_heap_push(&st->h, g);
}

static void pop(gstate *st, gcell *top)
{
    sl_slot_heap_pop(&st->h, top);
    for (int l = 0; l < st->nl; l++)
        for (int c = 0; c < 3; c++)
            st->sum_est[l][c] -= top->lb[l].est[c], st->sum_err[l][c] -= top->lb[l].err[c];
}

/* Estimates a cell's share and its error for every lobe; false when it
 * adds nothing to any. pc: the split's known points (NULL: none); grid_at:
 * a start cell's corners in st->grid_k (NULL: not one). */
static bool estimate(gstate *st, const sl_dome_cell *c, point_cache *pc, const int *grid_at, gcell *g)
{
    st->cells++;
    if (!(c->p[0] > 0 || c->p[1] > 0 || c->p[2] > 0))
        return false;
    bool below[SL_GLOSSY_BATCH], any = false;
    for (int l = 0; l < st->nl; l++) {
        double ca = v3_dot(st->l[l].n, c->centre);
        below[l] = false;
        if (!c->wide) {
            double sa = sqrt(max2(0.0, 1.0 - ca * ca));
            double hi = ca > c->cos_r ? 1.0 : ca * c->cos_r + sa * c->sin_r;
            below[l] = hi <= 0; /* wholly below this lobe's horizon */
        }
        any |= !below[l];
    }
    if (!any)
        return false;
    double vl[3], d[3];
    for (int i = 0; i < 3; i++)
        vl[i] = 0.2126 * c->v[0][i] + 0.7152 * c->v[1][i] + 0.0722 * c->v[2][i];
    v3_copy(d, vl);
    if (!v3_normalize(d))
        v3_copy(d, c->centre);
    double kd[SL_GLOSSY_BATCH][3], kc[SL_GLOSSY_BATCH][3];
    kernel_counted(st, below, d, kd);
    kernel_counted(st, below, c->centre, kc);
    for (int l = 0; l < st->nl; l++)
        memcpy(g->lb[l].k[0], kc[l], sizeof kc[l]);
    const double pt[4] = {c->t0, c->t0, c->t1, c->t1}, pa[4] = {c->a, c->b, c->a, c->b};
    for (int i = 0; i < 4; i++)
        point_k(st, pc, below, pt[i], pa[i], c->corner[i], g, 1 + i, grid_at ? grid_at[i] : -1);
    /* How spread the cell's light is against a uniform cell's: 0 for a
     * point (a sun), where k(d) is exact, 1 for uniform light, where the
     * mean of k over the cell is the better estimate. */
    double pl = 0.2126 * c->p[0] + 0.7152 * c->p[1] + 0.0722 * c->p[2];
    double spread = pl > 0 && c->spread_uniform > 0
                        ? (1.0 - v3_length(vl) / pl) / c->spread_uniform
                        : 0.0;
    spread = min2(max2(spread, 0.0), 2.0);
    for (int l = 0; l < st->nl; l++) {
        const lobe *lp = &st->l[l];
        cell_lobe *b = &g->lb[l];
        double (*k)[3] = b->k;
        /* A cell wider than the lobe that its peak may reach: the sample
         * points cannot tell its shape. Narrower cells see a smooth k. */
        bool peak = !below[l] && (c->wide || (c->cos_r < lp->cos_width &&
                                              v3_dot(lp->mirror, c->centre) >=
                                                  c->cos_r * lp->cos_reach - c->sin_r * lp->sin_reach));
        if (peak && !st->have_k_mirror[l]) {
            st->kernel_calls++;
            kernel(lp, lp->mirror, st->k_mirror[l]);
            st->have_k_mirror[l] = true;
        }
        const double *km = st->k_mirror[l];
        for (int ch = 0; ch < 3; ch++) {
            b->est[ch] = c->p[ch] * kd[l][ch];
            if (peak) {
                /* The lobe's peak is in the cell: anything between its
                 * smallest and largest value. */
                double lo = min2(kd[l][ch], km[ch]), hi = max2(kd[l][ch], km[ch]);
                for (int i = 0; i < 5; i++)
                    lo = min2(lo, k[i][ch]), hi = max2(hi, k[i][ch]);
                b->err[ch] = c->p[ch] * (hi - lo);
            } else {
                /* k is smooth here: P k(d) errs in the second order (d is
                 * the mean direction, so the first-order term vanishes); its
                 * size is that of k(d) against the cell's mean of k (a
                 * quadratic's mean over a square: 2/3 of the centre, 1/12 of
                 * each corner). The estimate moves toward that mean as far
                 * as the cell's light is spread. */
                double mean = (8.0 * k[0][ch] + k[1][ch] + k[2][ch] + k[3][ch] + k[4][ch]) / 12.0;
                b->err[ch] = c->p[ch] * fabs(kd[l][ch] - mean);
                b->est[ch] += spread * c->p[ch] * (mean - k[0][ch]);
            }
        }
    }
    g->level = c->level, g->x = c->x, g->y = c->y;
    g->clipped = c->level > 0 && (((c->x + 1) << c->level) > st->map_w || ((c->y + 1) << c->level) > st->map_h);
    g->t0 = c->t0, g->t1 = c->t1, g->a = c->a, g->b = c->b;
    g->key = cell_key(st, g);
    return true;
}

static void add(gstate *st, const sl_dome_cell *c, point_cache *pc, const int *grid_at)
{
    gcell g;
    if (estimate(st, c, pc, grid_at, &g))
        push(st, &g);
}

static void split(gstate *st, const gcell *g)
{
    /* The parent's corners and (unless the map's edge clips it) its
     * centre are corners of its children. */
    point_cache pcache = {0}, *pc = &pcache;
    const double gt[5] = {0.5 * (g->t0 + g->t1), g->t0, g->t0, g->t1, g->t1};
    const double ga[5] = {0.5 * (g->a + g->b), g->a, g->b, g->a, g->b};
    for (int i = g->clipped ? 1 : 0; i < 5; i++) {
        pc->t[pc->n] = gt[i], pc->a[pc->n] = ga[i];
        for (int l = 0; l < st->nl; l++)
            memcpy(pc->k[pc->n][l], g->lb[l].k[i], sizeof g->lb[l].k[i]);
        pc->n++;
    }
    sl_dome_cell c[4];
    int n = sl_irradiance_children(st->ir, g->level, g->x, g->y, g->t0, g->t1, g->a, g->b, c);
    for (int i = 0; i < n; i++)
        add(st, &c[i], pc, NULL);
    if (g->level - 1 < st->finest)
        st->finest = g->level - 1;
}

static void totals(gstate *st)
{
    memset(st->sum_est, 0, sizeof st->sum_est);
    memset(st->sum_err, 0, sizeof st->sum_err);
    for (int i = 0; i < st->h.count; i++) {
        const gcell *g = sl_slot_heap_at(&st->h, i);
        for (int l = 0; l < st->nl; l++)
            for (int c = 0; c < 3; c++)
                st->sum_est[l][c] += g->lb[l].est[c], st->sum_err[l][c] += g->lb[l].err[c];
    }
}

/* Every lobe within its tolerance. */
static bool error_met(const gstate *st, double tol, const double floor[3])
{
    for (int l = 0; l < st->nl; l++)
        for (int c = 0; c < 3; c++)
            if (st->sum_err[l][c] > 0 && st->sum_err[l][c] > tol * max2(0.0, st->sum_est[l][c] + floor[c]))
                return false;
    return true;
}

/* At most the top level's 16 x 8 cells or a start list's (kept as short). */
#define FIRST_MAX (SL_GLOSSY_START_MAX > 16 * 8 ? SL_GLOSSY_START_MAX : 16 * 8)
/* The top level's corners. */
#define GRID_MAX (17 * 9)

struct sl_glossy_scratch {
    gstate st;
    int64_t kernel_calls; /* over every integral made with it */
    gcell pool[CELL_CAP];
    gcell first[FIRST_MAX];
    int idx[2 * CELL_CAP];
    double grid_k[GRID_MAX][SL_GLOSSY_BATCH][3];
    bool grid_have[GRID_MAX];
};

sl_glossy_scratch *sl_glossy_scratch_new(void) { return calloc(1, sizeof(sl_glossy_scratch)); }
int64_t sl_glossy_scratch_kernel_calls(const sl_glossy_scratch *s) { return s->kernel_calls; }
void sl_glossy_scratch_free(sl_glossy_scratch *s) { free(s); }

/* The lobe of (n, wo) in the map's frame; false when wo is below the
 * shading horizon (the pixel reflects nothing). */
static bool lobe_init(lobe *l, const sl_glossy_material *gm, const double rot[3][3], const double n_world[3],
                      const double wo_world[3])
{
    frame fr;
    double wo[3];
    frame_from_normal(&fr, n_world);
    frame_to_local(&fr, wo_world, wo);
    sl_glossy_view_init(&l->view, gm, wo);
    m3_mul_transpose(rot, fr.t, l->t);
    m3_mul_transpose(rot, fr.b, l->b);
    m3_mul_transpose(rot, fr.n, l->n);
    double cn = v3_dot(n_world, wo_world), mw[3];
    for (int i = 0; i < 3; i++)
        mw[i] = 2.0 * cn * n_world[i] - wo_world[i];
    m3_mul_transpose(rot, mw, l->mirror);
    v3_normalize(l->mirror);
    sl_ggx g = sl_ggx_make(gm->m->roughness, gm->m->anisotropy);
    l->cos_width = cos(fmin(g.ax, g.ay));
    l->reach = LOBE_REACH * fmax(g.ax, g.ay);
    /* cos(radius + reach) for a cell's cone: its cos and sin are known */
    l->cos_reach = cos(l->reach), l->sin_reach = sin(l->reach);
    return wo[2] > 0;
}

void sl_glossy_integrate_batch(const sl_irradiance *ir, const sl_glossy_material *const *gm,
                               const double (*n_world)[3], const double (*wo_world)[3], int count,
                               const sl_glossy_quad *q, sl_glossy_scratch *scratch, double (*out)[3],
                               double (*err)[3], sl_irradiance_cost *cost)
{
    memset(out, 0, (size_t)count * sizeof *out);
    memset(err, 0, (size_t)count * sizeof *err);
    double rot[3][3], intensity;
    sl_irradiance_frame(ir, rot, &intensity);
    gstate *st = &scratch->st;
    gcell *pool = scratch->pool;
    memset(st, 0, sizeof *st);
    st->ir = ir;
    sl_irradiance_level_size(ir, 0, &st->map_w, &st->map_h);
    /* Only the lobes given: pixels whose view is below their horizon
     * reflect nothing and take no part. */
    int map[SL_GLOSSY_BATCH];
    for (int i = 0; i < count && i < SL_GLOSSY_BATCH; i++)
        if (lobe_init(&st->l[st->nl], gm[i], rot, n_world[i], wo_world[i]))
            map[st->nl++] = i;
    size_t stride = offsetof(gcell, lb) + (size_t)st->nl * sizeof(cell_lobe);
    st->h = (sl_slot_heap){.pool = pool, .stride = stride, .heap = scratch->idx,
                           .free_list = scratch->idx + CELL_CAP};
    int top = sl_irradiance_top_level(ir), tw, th;
    st->finest = top;
    static const double zero[3] = {0, 0, 0};
    /* The floor is in the map's units (intensity not applied). */
    double floor[3] = {0, 0, 0};
    for (int c = 0; c < 3 && q->floor && intensity > 0; c++)
        floor[c] = q->floor[c] / intensity;
    if (st->nl > 0) {
        sl_irradiance_level_size(ir, top, &tw, &th);
        for (int l = 0; l < st->nl; l++)
            for (int c = 0; c < 3; c++)
                st->inv_scale[l][c] = 1;
        int level = top;
        if (q->start_cells) {
            level = q->start_level;
            sl_irradiance_level_size(ir, level, &tw, &th);
        }
        int ncells = q->start_cells ? q->start_count : tw * th;
        /* Every cell of the level: each corner is evaluated once, not by
         * each of the up to four cells around it (the same directions bit
         * for bit: neighbours' row and column bounds are the same numbers).
         * Corner (t0, a) of cell (x, y) is grid point (x + 1, y): longitude
         * falls as x grows. */
        if (!q->start_cells && (tw + 1) * (th + 1) <= GRID_MAX) {
            st->grid_k = scratch->grid_k, st->grid_have = scratch->grid_have;
            memset(scratch->grid_have, 0, (size_t)(tw + 1) * (th + 1) * sizeof *scratch->grid_have);
        }
        for (int i = 0; i < ncells; i++) {
            int t = q->start_cells ? q->start_cells[i] : i, x = t % tw, y = t / tw;
            sl_dome_cell c;
            sl_irradiance_cell(ir, level, x, y, &c);
            const int at[4] = {y * (tw + 1) + x + 1, y * (tw + 1) + x, (y + 1) * (tw + 1) + x + 1,
                               (y + 1) * (tw + 1) + x};
            add(st, &c, NULL, st->grid_k ? at : NULL);
        }
        /* Cells are ranked by their error relative to the first estimate. */
        for (int l = 0; l < st->nl; l++)
            for (int c = 0; c < 3; c++) {
                double scale = st->sum_est[l][c] + st->sum_err[l][c] + floor[c];
                st->inv_scale[l][c] = scale > 0 ? 1.0 / scale : 0.0;
            }
        /* The first cells are in slots 0..n-1. */
        int n = st->h.count;
        gcell *first = scratch->first;
        for (int i = 0; i < n; i++)
            memcpy(&first[i], (const char *)pool + (size_t)i * stride, stride);
        sl_slot_heap_clear(&st->h);
        memset(st->sum_est, 0, sizeof st->sum_est);
        memset(st->sum_err, 0, sizeof st->sum_err);
        for (int i = 0; i < n; i++) {
            first[i].key = cell_key(st, &first[i]);
            push(st, &first[i]);
        }
        int steps = 0;
        while (st->h.count > 0 && st->h.count + 4 <= CELL_CAP) {
            if (++steps % 128 == 0)
                totals(st);
            if (error_met(st, q->tol, q->floor ? floor : zero))
                break;
            const gcell *worst = sl_slot_heap_at(&st->h, 0);
            if (worst->level <= -SUBTEXEL_DEPTH || worst->key <= 0)
                break;
            gcell g;
            pop(st, &g);
            split(st, &g);
        }
        totals(st);
        for (int l = 0; l < st->nl; l++)
            for (int c = 0; c < 3; c++) {
                int i = map[l];
                out[i][c] = fmax(0.0, st->sum_est[l][c]) * intensity;
                /* The Fresnel table's interpolation error, relative. */
                err[i][c] = (st->sum_err[l][c] + gm[i]->fresnel_rel_error * fabs(st->sum_est[l][c])) * intensity;
            }
    }
    scratch->kernel_calls += st->kernel_calls;
    if (cost)
        sl_irradiance_cost_add(cost, count, st->cells, st->finest);
}

void sl_glossy_integrate(const sl_irradiance *ir, const sl_glossy_material *gm,
                         const double n_world[3], const double wo_world[3], const sl_glossy_quad *q,
                         sl_glossy_scratch *scratch, double out[3], double err[3],
                         sl_irradiance_cost *cost)
{
    sl_glossy_integrate_batch(ir, &gm, (const double(*)[3])n_world, (const double(*)[3])wo_world, 1, q,
                              scratch, (double(*)[3])out, (double(*)[3])err, cost);
}

void sl_glossy_eval(const sl_irradiance *ir, const sl_material *m, const double n[3],
                    const double wo[3], double tol, double out[3], double err[3],
                    sl_irradiance_cost *cost)
{
    sl_glossy_material gm;
    sl_glossy_scratch *s = sl_glossy_scratch_new();
    if (!s || sl_glossy_material_init(&gm, m, NULL)) { /* no room to integrate: the error says so */
        sl_glossy_scratch_free(s);
        out[0] = out[1] = out[2] = 0;
        err[0] = err[1] = err[2] = INFINITY;
        return;
    }
    sl_glossy_quad q = {.tol = tol};
    sl_glossy_integrate(ir, &gm, n, wo, &q, s, out, err, cost);
    sl_glossy_material_free(&gm);
    sl_glossy_scratch_free(s);
}
