/* SPDX-License-Identifier: BSD-3-Clause */
/* Closed-form irradiance from the dome: E(n) = integral of L(w) max(0, n.w)
 * over the sphere, for the piecewise-constant lat-long the sampler uses.
 *
 * Each lat-long cell (a texel, a block of texels of a mip level, or a piece
 * of a texel) has an exact vector irradiance V = integral of L w dw and power
 * P = integral of L dw (both analytic in theta and longitude). A cell wholly
 * above n's horizon gives exactly n.V, one wholly below gives 0. Only cells
 * the horizon cuts are uncertain: with [lo, hi] bounding n.w over the cell's
 * bounding cone and mu = n.V / P, their share lies between P max(0, mu) and
 * P hi (mu - lo) / (hi - lo); the estimate takes n.w as linear over the
 * cell's two angles (clamped between those), the bound is the distance to
 * the farther end. The cut cells
 * with the largest bound are split (mip level by level, then inside texels,
 * a sun at full resolution) until the summed bound is below tol x E. */
#include <stdlib.h>
#include <string.h>

#include "glossy.h"
#include "irradiance.h"
#include "slot_heap.h"
#include "vec3.h"

/* Deepest split inside a texel (1/2^k of its width). */
#define SUBTEXEL_DEPTH 8
/* Cut cells kept at once; past it the bound is what it is (reported). */
#define HEAP_CAP 1024

typedef struct row_info {
    double t0, t1;         /* colatitude range */
    double ct, st;         /* cos, sin of the centre colatitude */
    double cr, sr;         /* cos, sin of the bounding-cone radius (standard width) */
    bool wide;             /* radius >= pi/2: always treated as cut */
    double r0, r1, r2;     /* texel level: integrals of sin, sin^2, cos sin over theta */
    double s0, c0, s1, c1; /* sin, cos of t0 and t1 (the glossy quadrature's corners) */
} row_info;

typedef struct col_info {
    double a, b;           /* longitude range (a < b) */
    double sl, cl;         /* sin, cos of the centre longitude */
    double s_int, c_int;   /* integrals of sin and cos of longitude over [a, b] */
    double sa, ca, sb, cb; /* sin, cos of a and b */
} col_info;

typedef struct cell_sum {
    double v[3][3]; /* per channel: integral of L w dw */
    double p[3];    /* per channel: integral of L dw */
} cell_sum;

typedef struct level {
    int w, h;
    row_info *rows;
    col_info *cols;
    cell_sum *cells; /* NULL at level 0 (texels are computed from the image) */
} level;

struct sl_irradiance {
    const sl_image *img;
    double rot[3][3];
    double intensity;
    int nlevels; /* levels 0 (texels) .. nlevels - 1 (top) */
    level *lv;
};

static void row_setup(row_info *r, double t0, double t1, double width)
{
    r->t0 = t0, r->t1 = t1;
    double tm = 0.5 * (t0 + t1);
    r->ct = cos(tm), r->st = sin(tm);
    double max_sin = (t0 <= 0.5 * SL_PI && t1 >= 0.5 * SL_PI) ? 1.0 : fmax(sin(t0), sin(t1));
    /* Along the centre meridian, then along the parallel: a path at least
     * as long as the great-circle distance to any point of the cell. */
    double radius = 0.5 * (t1 - t0) + 0.5 * max_sin * width + 1e-12;
    r->wide = radius >= 0.5 * SL_PI;
    r->cr = cos(radius), r->sr = sin(radius);
    r->r0 = cos(t0) - cos(t1);
    r->r1 = 0.5 * (t1 - t0) - 0.25 * (sin(2 * t1) - sin(2 * t0));
    r->s0 = sin(t0), r->c0 = cos(t0), r->s1 = sin(t1), r->c1 = cos(t1);
    r->r2 = 0.5 * (r->s1 * r->s1 - r->s0 * r->s0);
}

static void col_setup(col_info *c, double a, double b, double centre)
{
    c->a = a, c->b = b;
    c->sl = sin(centre), c->cl = cos(centre);
    c->sa = sin(a), c->ca = cos(a), c->sb = sin(b), c->cb = cos(b);
    c->s_int = c->ca - c->cb;
    c->c_int = c->sb - c->sa;
}

void sl_irradiance_free(sl_irradiance *ir)
{
    if (!ir)
        return;
    for (int k = 0; k < ir->nlevels; k++) {
        free(ir->lv[k].rows);
        free(ir->lv[k].cols);
        free(ir->lv[k].cells);
    }
    free(ir->lv);
    free(ir);
}

/* A texel's sums from its row and column integrals. */
static void texel_sum(const sl_irradiance *ir, int x, int y, cell_sum *s)
{
    const row_info *r = &ir->lv[0].rows[y];
    const col_info *c = &ir->lv[0].cols[x];
    const float *L = sl_image_pixel(ir->img, x, y);
    double dw = c->b - c->a;
    for (int ch = 0; ch < 3; ch++) {
        s->v[ch][0] = L[ch] * r->r1 * c->s_int;
        s->v[ch][1] = L[ch] * r->r2 * dw;
        s->v[ch][2] = L[ch] * r->r1 * c->c_int;
        s->p[ch] = L[ch] * r->r0 * dw;
    }
}

static void cell_at(const sl_irradiance *ir, int k, int x, int y, cell_sum *s)
{
    if (k == 0)
        texel_sum(ir, x, y, s);
    else
        *s = ir->lv[k].cells[(size_t)y * ir->lv[k].w + x];
}

typedef struct level_job {
    const sl_irradiance *ir;
    int k;
} level_job;

static bool cell_zero(const cell_sum *c)
{
    for (int ch = 0; ch < 3; ch++)
        if (c->p[ch] != 0 || c->v[ch][0] != 0 || c->v[ch][1] != 0 || c->v[ch][2] != 0)
            return false;
    return true;
}

/* Level k's cell (x, y): the sum of its (up to) four children. A child
 * that is all zero adds nothing and is skipped, so a cell with no light is
 * never written: a sparse map (the sun alone) touches few of its levels'
 * pages, and the sums keep their bits (x + 0 = x). */
static void sum_cell(const sl_irradiance *ir, int k, int x, int y)
{
    const level *l = &ir->lv[k], *f = &ir->lv[k - 1];
    cell_sum *s = &l->cells[(size_t)y * l->w + x];
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            int cx = 2 * x + i, cy = 2 * y + j;
            if (cx >= f->w || cy >= f->h)
                continue;
            cell_sum c;
            cell_at(ir, k - 1, cx, cy, &c);
            if (cell_zero(&c))
                continue;
            for (int ch = 0; ch < 3; ch++) {
                for (int d = 0; d < 3; d++)
                    s->v[ch][d] += c.v[ch][d];
                s->p[ch] += c.p[ch];
            }
        }
}

/* Rows [begin, end) of level k's cells. */
static void sum_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const level_job *lj = ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < lj->ir->lv[lj->k].w; x++)
            sum_cell(lj->ir, lj->k, x, (int)y);
}

static int cmp_int64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* Level k's cells over the cells (y * width + x) of level k - 1 listed in
 * `at` (sorted, unique), the only ones with light; `at` becomes level k's
 * list. The cells sum as in sum_rows, so their bits are the same. */
static int64_t sum_listed(const sl_irradiance *ir, int k, int64_t *at, int64_t count)
{
    int fw = ir->lv[k - 1].w, w = ir->lv[k].w;
    for (int64_t i = 0; i < count; i++)
        at[i] = (at[i] / fw / 2) * w + (at[i] % fw) / 2;
    qsort(at, (size_t)count, sizeof *at, cmp_int64);
    int64_t n = 0;
    for (int64_t i = 0; i < count; i++)
        if (n == 0 || at[i] != at[n - 1])
            at[n++] = at[i];
    for (int64_t i = 0; i < n; i++)
        sum_cell(ir, k, (int)(at[i] % w), (int)(at[i] / w));
    return n;
}

sl_result sl_irradiance_build(const sl_dome *dome, sl_irradiance **out, sl_error *err)
{
    return sl_irradiance_build_sparse(dome, NULL, 0, out, err);
}

sl_result sl_irradiance_build_sparse(const sl_dome *dome, const int64_t *texels, int64_t count,
                                     sl_irradiance **out, sl_error *err)
{
    *out = NULL;
    const sl_image *img = &dome->image;
    int W = img->width, H = img->height;
    if (!dome->present || W < 2 || H < 1)
        return sl_error_set(err, SL_ERR_INPUT, "irradiance: no dome");
    /* Level 1 and up: about a third of a texel's 96 bytes per texel. */
    sl_result res = sl_memory_check((uint64_t)W * (uint64_t)H * 40, "dome", "the irradiance mip levels", err);
    if (res)
        return res;
    sl_irradiance *ir = calloc(1, sizeof *ir);
    int n = 1;
    while (((W + (1 << (n - 1)) - 1) >> (n - 1)) > 16 && n < 30)
        n++;
    if (!ir || !(ir->lv = calloc((size_t)n, sizeof *ir->lv))) {
        free(ir);
        return sl_error_set(err, SL_ERR_NOMEM, "irradiance: out of memory");
    }
    int64_t *at = NULL; /* the sparse map's cells with light, level by level */
    if (texels && !(at = malloc((size_t)(count > 0 ? count : 1) * sizeof *at))) {
        free(ir->lv);
        free(ir);
        return sl_error_set(err, SL_ERR_NOMEM, "irradiance: out of memory");
    }
    if (texels)
        memcpy(at, texels, (size_t)count * sizeof *at);
    ir->img = img;
    ir->nlevels = n;
    memcpy(ir->rot, dome->rot, sizeof ir->rot);
    ir->intensity = dome->intensity;
    for (int k = 0; k < n; k++) {
        level *l = &ir->lv[k];
        int span = 1 << k;
        l->w = (W + span - 1) >> k;
        l->h = (H + span - 1) >> k;
        l->rows = malloc((size_t)l->h * sizeof *l->rows);
        l->cols = malloc((size_t)l->w * sizeof *l->cols);
        if (k > 0)
            l->cells = calloc((size_t)l->w * (size_t)l->h, sizeof *l->cells);
        if (!l->rows || !l->cols || (k > 0 && !l->cells)) {
            sl_irradiance_free(ir);
            free(at);
            return sl_error_set(err, SL_ERR_NOMEM, "irradiance: out of memory for the mip levels");
        }
        double width = fmin(2.0 * SL_PI, 2.0 * SL_PI * span / W);
        for (int y = 0; y < l->h; y++) {
            int y0 = y * span, y1 = y0 + span < H ? y0 + span : H;
            row_setup(&l->rows[y], SL_PI * y0 / H, SL_PI * y1 / H, width);
        }
        for (int x = 0; x < l->w; x++) {
            int x0 = x * span, x1 = x0 + span < W ? x0 + span : W;
            /* Longitude falls as u grows (core's lat-long). A clipped last
             * column keeps the standard cell's centre: its cone covers it. */
            double b = SL_PI * (1.0 - 2.0 * x0 / W), a = SL_PI * (1.0 - 2.0 * x1 / W);
            col_setup(&l->cols[x], a, b, SL_PI * (1.0 - (2.0 * x0 + span) / W));
        }
        if (k == 0)
            continue;
        level_job lj = {ir, k};
        if (at)
            count = sum_listed(ir, k, at, count);
        else
            sl_parallel_for(l->h, 16, sum_rows, &lj);
    }
    free(at);
    *out = ir;
    return SL_OK;
}

int sl_irradiance_top_level(const sl_irradiance *ir) { return ir->nlevels - 1; }

void sl_irradiance_cost_add(sl_irradiance_cost *cost, int64_t evaluations, int64_t cells, int finest)
{
    cost->evaluations += evaluations;
    cost->cells += cells;
    if (evaluations > 0 && finest < cost->finest_level)
        cost->finest_level = finest;
}

/* A cell the horizon may cut. level >= 0: block (x, y) of that mip level;
 * level < 0: a piece of texel (x, y), split -level times, at [t0, t1] x [a, b]. */
typedef struct cut_cell {
    double key; /* largest bound over the channels, scaled */
    double mid[3], bnd[3];
    int level, x, y;
    double t0, t1, a, b;
} cut_cell;

typedef struct eval_state {
    const sl_irradiance *ir;
    double n[3];            /* normal in the map's frame */
    double exact[3];        /* cells wholly above the horizon */
    double inv_scale[3];
    cut_cell pool[HEAP_CAP]; /* cut cells; heap holds their indices */
    int heap[HEAP_CAP];
    int free_list[HEAP_CAP];
    sl_slot_heap h;
    sl_open_sums sums; /* over the heap */
    int64_t cells;
    int finest;
} eval_state;

static void heap_push(eval_state *st, const cut_cell *c)
{
    sl_open_sums_add(&st->sums, c->mid, c->bnd, 1.0);
    sl_slot_heap_push(&st->h, c);
}

static cut_cell heap_pop(eval_state *st)
{
    cut_cell top;
    sl_slot_heap_pop(&st->h, &top);
    sl_open_sums_add(&st->sums, top.mid, top.bnd, -1.0);
    return top;
}

static double cube6(double z) { return z > 0 ? z * z * z / 6.0 : 0.0; }
static double square2(double z) { return z > 0 ? 0.5 * z * z : 0.0; }

/* Mean of max(0, mu + a U + b V) for U, V uniform on [-1, 1]: n.w over a
 * small cell, linear in its two angles. */
static double mean_positive_part(double mu, double a, double b)
{
    if (mu >= a + b)
        return mu;
    if (mu <= -(a + b))
        return 0.0;
    double big = fmax(a, b), small = fmin(a, b);
    if (small < 1e-4 * big)
        return (square2(mu + big) - square2(mu - big)) / (2.0 * big);
    return (cube6(mu + a + b) - cube6(mu + a - b) - cube6(mu - a + b) + cube6(mu - a - b)) /
           (4.0 * a * b);
}

/* How much of a cell's light (sums v, p; centre direction c, cone radius
 * cos/sin; span: cos, sin of the centre colatitude and longitude, and the
 * half-widths) falls on normal n in max(0, n.w): -1 wholly below the
 * horizon (nothing), 1 wholly above (exactly n.V: est only), 0 cut, with
 * lower <= exact <= upper per channel and est between them. */
static int horizon_share(const double n[3], const double (*v)[3], const double p[3], const double c[3],
                         double cr, double sr, bool wide, const double span[6], double lower[3],
                         double est[3], double upper[3])
{
    double ca = v3_dot(n, c);
    double lo = -1, hi = 1;
    if (!wide) {
        double sa = sqrt(fmax(0.0, 1.0 - ca * ca));
        lo = ca < -cr ? -1.0 : ca * cr - sa * sr; /* cos(a + r) */
        hi = ca > cr ? 1.0 : ca * cr + sa * sr;   /* cos(a - r) */
    }
    if (hi < 0)
        return -1;
    if (lo > 0) {
        for (int ch = 0; ch < 3; ch++)
            est[ch] = v3_dot(n, v[ch]);
        return 1;
    }
    double ct = span[0], stt = span[1], cl = span[2], sl = span[3];
    double dt[3] = {ct * sl, -stt, ct * cl}, dl[3] = {stt * cl, 0, -stt * sl};
    double ht = fabs(v3_dot(n, dt)) * span[4], hl = fabs(v3_dot(n, dl)) * span[5];
    double mu_prev = NAN, ratio = 0;
    for (int ch = 0; ch < 3; ch++) {
        /* With mu = n.V / P the mean of n.w over the cell: max(0, x) lies
         * above max(0, mu) on average (Jensen) and below its chord over
         * [lo, hi]. */
        double A = v3_dot(n, v[ch]), P = p[ch];
        double low = A > 0 ? A : 0.0, up = hi > lo ? hi * (A - lo * P) / (hi - lo) : low;
        up = up > low ? up : low;
        /* The estimate: n.w linear over the cell's angles, clamped to the
         * bounds. A texel's channels share mu: computed once. */
        double e = 0;
        if (P > 0) {
            double mu = A / P;
            if (mu != mu_prev)
                ratio = mean_positive_part(mu, ht, hl), mu_prev = mu;
            e = P * ratio;
        }
        est[ch] = e < low ? low : e > up ? up : e;
        lower[ch] = low, upper[ch] = up;
    }
    return 0;
}

int sl_irradiance_cell_share(const double n[3], const sl_dome_cell *c, double lower[3], double est[3],
                             double upper[3])
{
    double ct = c->centre[1], st = sqrt(fmax(0.0, 1.0 - ct * ct));
    double span[6] = {ct, st, st > 0 ? c->centre[2] / st : 1.0, st > 0 ? c->centre[0] / st : 0.0,
                      0.5 * (c->t1 - c->t0), 0.5 * (c->b - c->a)};
    int side = horizon_share(n, (const double(*)[3])c->v, c->p, c->centre, c->cos_r, c->sin_r, c->wide, span,
                             lower, est, upper);
    for (int ch = 0; ch < 3 && side != 0; ch++)
        lower[ch] = upper[ch] = est[ch] = side > 0 ? est[ch] : 0.0;
    return side;
}

/* Classifies a cell (sums s, centre direction c, cone radius cos/sin) and
 * adds it: exactly when wholly above or below the horizon, else as a cut
 * cell whose geometry is in *geo. */
static void add_cell(eval_state *st, const cell_sum *s, const double c[3], double cr, double sr,
                     bool wide, const double span[6], const cut_cell *geo)
{
    st->cells++;
    double lower[3], est[3], upper[3];
    int side = horizon_share(st->n, (const double(*)[3])s->v, s->p, c, cr, sr, wide, span, lower, est, upper);
    if (side < 0)
        return;
    if (side > 0) {
        for (int ch = 0; ch < 3; ch++)
            st->exact[ch] += est[ch];
        return;
    }
    cut_cell cell = *geo;
    cell.key = 0;
    for (int ch = 0; ch < 3; ch++) {
        cell.mid[ch] = est[ch];
        cell.bnd[ch] = upper[ch] - est[ch] > est[ch] - lower[ch] ? upper[ch] - est[ch] : est[ch] - lower[ch];
        double key = cell.bnd[ch] * st->inv_scale[ch];
        cell.key = key > cell.key ? key : cell.key;
    }
    if (cell.key > 0 || cell.mid[0] > 0 || cell.mid[1] > 0 || cell.mid[2] > 0)
        heap_push(st, &cell);
}

static void add_block(eval_state *st, int k, int x, int y)
{
    const level *l = &st->ir->lv[k];
    const row_info *r = &l->rows[y];
    const col_info *co = &l->cols[x];
    cell_sum s;
    cell_at(st->ir, k, x, y, &s);
    double c[3] = {r->st * co->sl, r->ct, r->st * co->cl};
    double span[6] = {r->ct, r->st, co->cl, co->sl, 0.5 * (r->t1 - r->t0), 0.5 * (co->b - co->a)};
    cut_cell geo = {.level = k, .x = x, .y = y};
    add_cell(st, &s, c, r->cr, r->sr, r->wide, span, &geo);
}

/* A piece [t0, t1] x [a, b] of texel (x, y): its sums from the same
 * integrals as a texel's. */
static void piece_sum(const sl_irradiance *ir, int x, int y, double t0, double t1, double a,
                      double b, row_info *r, col_info *co, cell_sum *s)
{
    row_setup(r, t0, t1, b - a);
    col_setup(co, a, b, 0.5 * (a + b));
    const float *L = sl_image_pixel(ir->img, x, y);
    for (int ch = 0; ch < 3; ch++) {
        s->v[ch][0] = L[ch] * r->r1 * co->s_int;
        s->v[ch][1] = L[ch] * r->r2 * (b - a);
        s->v[ch][2] = L[ch] * r->r1 * co->c_int;
        s->p[ch] = L[ch] * r->r0 * (b - a);
    }
}

static void add_piece(eval_state *st, int level, int x, int y, double t0, double t1, double a,
                      double b)
{
    row_info r;
    col_info co;
    cell_sum s;
    piece_sum(st->ir, x, y, t0, t1, a, b, &r, &co, &s);
    double c[3] = {r.st * co.sl, r.ct, r.st * co.cl};
    cut_cell geo = {.level = level, .x = x, .y = y, .t0 = t0, .t1 = t1, .a = a, .b = b};
    double span[6] = {r.ct, r.st, co.cl, co.sl, 0.5 * (t1 - t0), 0.5 * (b - a)};
    add_cell(st, &s, c, r.cr, r.sr, r.wide, span, &geo);
}

static void split(eval_state *st, const cut_cell *c)
{
    if (c->level > 0) {
        const level *f = &st->ir->lv[c->level - 1];
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++)
                if (2 * c->x + i < f->w && 2 * c->y + j < f->h)
                    add_block(st, c->level - 1, 2 * c->x + i, 2 * c->y + j);
    } else {
        double t0 = c->t0, t1 = c->t1, a = c->a, b = c->b;
        if (c->level == 0) {
            t0 = st->ir->lv[0].rows[c->y].t0, t1 = st->ir->lv[0].rows[c->y].t1;
            a = st->ir->lv[0].cols[c->x].a, b = st->ir->lv[0].cols[c->x].b;
        }
        double tm = 0.5 * (t0 + t1), am = 0.5 * (a + b);
        add_piece(st, c->level - 1, c->x, c->y, t0, tm, a, am);
        add_piece(st, c->level - 1, c->x, c->y, t0, tm, am, b);
        add_piece(st, c->level - 1, c->x, c->y, tm, t1, a, am);
        add_piece(st, c->level - 1, c->x, c->y, tm, t1, am, b);
    }
    int lv = c->level - 1;
    if (lv < st->finest)
        st->finest = lv;
}

/* Sums over the cut cells, from scratch. */
static void totals(const eval_state *st, double mid[3], double B[3])
{
    for (int ch = 0; ch < 3; ch++)
        mid[ch] = 0, B[ch] = 0;
    for (int i = 0; i < st->h.count; i++) {
        const cut_cell *c = sl_slot_heap_at(&st->h, i);
        for (int ch = 0; ch < 3; ch++) {
            mid[ch] += c->mid[ch];
            B[ch] += c->bnd[ch];
        }
    }
}

static bool bound_met(const double E[3], const double B[3], const double floor[3], double tol)
{
    for (int ch = 0; ch < 3; ch++)
        if (B[ch] > tol * (fmax(0.0, E[ch] - B[ch]) + floor[ch]) && B[ch] > 0)
            return false;
    return true;
}

void sl_irradiance_eval(const sl_irradiance *ir, const double n_world[3], double tol, double E[3],
                        double bound[3], sl_irradiance_cost *cost)
{
    sl_quad q = {.tol = tol};
    sl_irradiance_integrate(ir, n_world, &q, E, bound, cost);
}

void sl_irradiance_integrate(const sl_irradiance *ir, const double n_world[3], const sl_quad *q,
                             double E[3], double bound[3], sl_irradiance_cost *cost)
{
    eval_state *st = malloc(sizeof *st);
    if (!st) { /* no room to refine: the bound says so */
        E[0] = E[1] = E[2] = 0;
        bound[0] = bound[1] = bound[2] = INFINITY;
        return;
    }
    st->ir = ir;
    m3_mul_transpose(ir->rot, n_world, st->n);
    v3_normalize(st->n);
    st->h = (sl_slot_heap){.pool = st->pool, .stride = sizeof st->pool[0], .heap = st->heap,
                           .free_list = st->free_list};
    memset(&st->sums, 0, sizeof st->sums);
    st->cells = 0;
    st->finest = ir->nlevels - 1;
    /* The floor is in the map's units (intensity not applied). */
    double floor[3] = {0, 0, 0};
    for (int ch = 0; ch < 3; ch++) {
        st->exact[ch] = 0, st->inv_scale[ch] = 1;
        if (q->floor && ir->intensity > 0)
            floor[ch] = fmax(0.0, q->floor[ch] / ir->intensity);
    }
    if (q->start_cells) {
        const level *l = &ir->lv[q->start_level];
        for (int i = 0; i < q->start_count; i++)
            add_block(st, q->start_level, q->start_cells[i] % l->w, q->start_cells[i] / l->w);
        if (q->start_level < st->finest)
            st->finest = q->start_level;
    } else {
        const level *top = &ir->lv[ir->nlevels - 1];
        for (int y = 0; y < top->h; y++)
            for (int x = 0; x < top->w; x++)
                add_block(st, ir->nlevels - 1, x, y);
    }
    double B[3];
    totals(st, E, B);
    /* Cut cells are ranked by their bound relative to the first estimate. */
    for (int ch = 0; ch < 3; ch++) {
        double scale = st->exact[ch] + E[ch] + B[ch] + floor[ch];
        st->inv_scale[ch] = scale > 0 ? 1.0 / scale : 0.0;
    }
    /* At most the top level's 16 x 8 cells or the start list's. */
    int n = st->h.count;
    cut_cell first[SL_QUAD_START_MAX > 16 * 8 ? SL_QUAD_START_MAX : 16 * 8];
    for (int i = 0; i < n; i++)
        first[i] = *(const cut_cell *)sl_slot_heap_at(&st->h, i);
    sl_slot_heap_clear(&st->h);
    memset(&st->sums, 0, sizeof st->sums);
    for (int i = 0; i < n; i++) {
        first[i].key = 0;
        for (int ch = 0; ch < 3; ch++)
            first[i].key = fmax(first[i].key, first[i].bnd[ch] * st->inv_scale[ch]);
        heap_push(st, &first[i]);
    }
    int steps = 0;
    while (st->h.count > 0 && st->h.count + 4 <= HEAP_CAP) {
        /* Running sums drift by rounding: recompute them now and then. */
        if (++steps % 128 == 0)
            totals(st, st->sums.mid, st->sums.bnd);
        double sumE[3];
        for (int ch = 0; ch < 3; ch++)
            sumE[ch] = st->exact[ch] + st->sums.mid[ch];
        if (bound_met(sumE, st->sums.bnd, floor, q->tol))
            break;
        const cut_cell *worst = sl_slot_heap_at(&st->h, 0);
        if (worst->level <= -SUBTEXEL_DEPTH || worst->key <= 0)
            break;
        cut_cell c = heap_pop(st);
        split(st, &c);
    }
    totals(st, E, B);
    for (int ch = 0; ch < 3; ch++) {
        E[ch] = fmax(0.0, st->exact[ch] + E[ch]) * ir->intensity;
        bound[ch] = B[ch] * ir->intensity;
    }
    if (cost)
        sl_irradiance_cost_add(cost, 1, st->cells, st->finest);
    free(st);
}

/* ---- cells for the glossy quadrature (glossy.h) ---- */

void sl_irradiance_frame(const sl_irradiance *ir, double rot[3][3], double *intensity)
{
    memcpy(rot, ir->rot, sizeof ir->rot);
    *intensity = ir->intensity;
}

void sl_irradiance_level_size(const sl_irradiance *ir, int k, int *w, int *h)
{
    *w = ir->lv[k].w, *h = ir->lv[k].h;
}

static void dome_cell_fill(sl_dome_cell *c, const row_info *r, const col_info *co,
                           const cell_sum *s)
{
    for (int ch = 0; ch < 3; ch++) {
        c->p[ch] = s->p[ch];
        for (int d = 0; d < 3; d++)
            c->v[ch][d] = s->v[ch][d];
    }
    v3_set(c->centre, r->st * co->sl, r->ct, r->st * co->cl);
    c->cos_r = r->cr, c->sin_r = r->sr, c->wide = r->wide;
    double dw = co->b - co->a, vx = r->r1 * co->s_int, vy = r->r2 * dw, vz = r->r1 * co->c_int;
    double pu = r->r0 * dw;
    c->spread_uniform = pu > 0 ? 1.0 - sqrt(vx * vx + vy * vy + vz * vz) / pu : 0.0;
    c->t0 = r->t0, c->t1 = r->t1, c->a = co->a, c->b = co->b;
    v3_set(c->corner[0], r->s0 * co->sa, r->c0, r->s0 * co->ca);
    v3_set(c->corner[1], r->s0 * co->sb, r->c0, r->s0 * co->cb);
    v3_set(c->corner[2], r->s1 * co->sa, r->c1, r->s1 * co->ca);
    v3_set(c->corner[3], r->s1 * co->sb, r->c1, r->s1 * co->cb);
}

void sl_irradiance_cell(const sl_irradiance *ir, int k, int x, int y, sl_dome_cell *c)
{
    cell_sum s;
    cell_at(ir, k, x, y, &s);
    dome_cell_fill(c, &ir->lv[k].rows[y], &ir->lv[k].cols[x], &s);
    c->level = k, c->x = x, c->y = y;
}

void sl_irradiance_piece(const sl_irradiance *ir, int level, int x, int y, double t0, double t1,
                         double a, double b, sl_dome_cell *c)
{
    row_info r;
    col_info co;
    cell_sum s;
    piece_sum(ir, x, y, t0, t1, a, b, &r, &co, &s);
    dome_cell_fill(c, &r, &co, &s);
    c->level = level, c->x = x, c->y = y;
}

int sl_irradiance_children(const sl_irradiance *ir, int k, int x, int y, double t0, double t1, double a,
                           double b, sl_dome_cell out[4])
{
    int n = 0;
    if (k > 0) {
        const level *f = &ir->lv[k - 1];
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++)
                if (2 * x + i < f->w && 2 * y + j < f->h)
                    sl_irradiance_cell(ir, k - 1, 2 * x + i, 2 * y + j, &out[n++]);
        return n;
    }
    double tm = 0.5 * (t0 + t1), am = 0.5 * (a + b);
    const double t[3] = {t0, tm, t1}, al[3] = {a, am, b};
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++)
            sl_irradiance_piece(ir, k - 1, x, y, t[j], t[j + 1], al[i], al[i + 1], &out[n++]);
    return n;
}
