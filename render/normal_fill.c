/* SPDX-License-Identifier: BSD-3-Clause */
/* The rest of the map's irradiance at Lambert pixels, interpolated over the
 * sphere of normals rather than the image: irradiance depends on the normal
 * alone, so a sphere's rim (where the normal turns fast from pixel to pixel)
 * or a plane (one normal) costs no more than its interior.
 *
 * The sphere of normals is a cube's six faces, each a (u, v) square whose
 * direction (u, v, 1) is smooth: E is smooth across a face. Blocks are
 * checked as the image blocks of glossy_fill.c (centre and edge midpoints
 * against the bilinear interpolation of the corners); a block that fails is
 * split in four, down to 1/64 of a face (about 1.4 degrees). Only blocks
 * holding some point's normal are evaluated (the progressive fill below). */
#include <stdlib.h>
#include <string.h>

#include "glossy.h"
#include "vec3.h"

#define RES 128 /* the finest blocks per face edge: 2 x 64 */
#define BLOCK0 8 /* the first blocks per face edge */
#define VERTS ((RES + 1) * (RES + 1))

/* Face and (s, t) in [0, RES]^2 of a unit direction. */
static int to_face(const double n[3], double *s, double *t)
{
    int a = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(n[i]) > fabs(n[a]))
            a = i;
    double m = fabs(n[a]);
    int b = (a + 1) % 3, c = (a + 2) % 3;
    *s = fmin(RES, fmax(0.0, 0.5 * (n[b] / m + 1.0) * RES));
    *t = fmin(RES, fmax(0.0, 0.5 * (n[c] / m + 1.0) * RES));
    return 2 * a + (n[a] < 0);
}

static void from_face(int face, int i, int j, double n[3])
{
    int a = face / 2, b = (a + 1) % 3, c = (a + 2) % 3;
    n[a] = face & 1 ? -1.0 : 1.0;
    n[b] = 2.0 * i / RES - 1.0;
    n[c] = 2.0 * j / RES - 1.0;
    v3_normalize(n);
}

typedef struct normal_job {
    const sl_irradiance *rest;
    double quad_tol, deadline;
    double late_tol;             /* > 0: past the deadline evaluate to this instead of skipping */
    double (*val)[3], (*err)[3]; /* per vertex: face * VERTS + j * (RES + 1) + i */
    uint8_t *known;              /* 0 not asked, 1 queued, 2 evaluated */
    int32_t *queue;
    sl_irradiance_cost *worker_cost;
    int workers;
} normal_job;

static void eval_vertices(void *ctx, int64_t begin, int64_t end, int worker)
{
    normal_job *j = ctx;
    sl_irradiance_cost scratch = {0}, *cost = worker >= 0 && worker < j->workers ? &j->worker_cost[worker] : &scratch;
    for (int64_t k = begin; k < end; k++) {
        int v = j->queue[k];
        bool late = sl_seconds() > j->deadline;
        if (late && !(j->late_tol > 0)) {
            j->known[v] = 0; /* unknown: its blocks fail, their pixels are the caller's */
            continue;
        }
        int face = v / VERTS, r = v % VERTS;
        double n[3];
        from_face(face, r % (RES + 1), r / (RES + 1), n);
        sl_quad q = {.tol = late ? j->late_tol : j->quad_tol};
        sl_irradiance_integrate(j->rest, n, &q, j->val[v], j->err[v], cost);
        j->known[v] = 2;
    }
}

/* The nine points of a block (glossy_fill.c's order: corners, edge
 * midpoints, centre) in half-block units. */
static const int POINT[9][2] = {{0, 0}, {2, 0}, {0, 2}, {2, 2}, {1, 0}, {0, 1}, {2, 1}, {1, 2}, {1, 1}};

static int vertex(int face, int bx, int by, int S, int k)
{
    return face * VERTS + (by * S + POINT[k][1] * S / 2) * (RES + 1) + bx * S + POINT[k][0] * S / 2;
}

/* The vertex arrays of every face; false without memory. */
static bool normal_job_alloc(normal_job *j, const sl_irradiance *rest, double quad_tol)
{
    size_t nv = 6 * (size_t)VERTS;
    *j = (normal_job){.rest = rest, .quad_tol = quad_tol, .workers = sl_threads_get()};
    j->val = malloc(nv * sizeof *j->val);
    j->err = malloc(nv * sizeof *j->err);
    j->known = calloc(nv, 1);
    j->queue = malloc(nv * sizeof *j->queue);
    j->worker_cost = calloc((size_t)j->workers, sizeof *j->worker_cost);
    return j->val && j->err && j->known && j->queue && j->worker_cost;
}

static void normal_job_free(normal_job *j)
{
    free(j->val);
    free(j->err);
    free(j->known);
    free(j->queue);
    free(j->worker_cost);
}

/* ---- the progressive fill (normal_fill.h) ----
 *
 * A --time cut must leave every point a value and an honest bound, so the
 * fill is coarse to fine over the whole object rather than band by band:
 * the first pass interpolates the rest over blocks of 1/8 of a face (about
 * 11 degrees: some 800 evaluations for a hemisphere of normals) and
 * integrates the sun at every point; then the block with the largest share
 * of the squared error is split first. A block is final when its check
 * passes, and points of a failed finest block are evaluated one by one. */
#include "normal_fill.h"
#include "slot_heap.h"

/* The first pass's blocks per face edge: the largest that may be final
 * (about 11 degrees); at 45 or 22 degrees the first pass's error was 12 or
 * 4 times larger (rooitou_park, test_render_time) for a few hundred
 * evaluations saved. */
#define COARSE BLOCK0
#define CELLS (RES / 2)   /* the finest blocks per face edge */
#define REST_SHARE 0.5    /* of the tolerance: the rest's quadrature bound */
#define INTERP_SHARE 0.25 /* the interpolation check */
#define SUN_SHARE 0.25    /* the sun's bound, of the point's whole irradiance */
#define SUN_LATE_TOL 1e30 /* the sun past the deadline: no refinement */
#define LATE_TOL 0.05    /* the tolerance of the first pass's evaluations past the deadline */
/* Refinement batches: enough new points to keep every thread busy. */
#define BATCH_POINTS 32

typedef struct pblock {
    double key;          /* its squared error summed over its points, relative */
    int face, G, bx, by; /* G blocks per face edge; G = 0: the points one by one */
    int64_t first, end;  /* its points in sorted order */
} pblock;

typedef struct fill {
    const sl_glossy_dome *gd;
    sl_lambert_points *pts;
    double tol, deadline;
    normal_job j;               /* the rest at grid vertices */
    int64_t *order;             /* points sorted by face and Morton code of their finest block */
    int64_t *offset;            /* first sorted point of each finest block (6 x CELLS^2 + 1) */
    double (*st)[2];            /* (s, t) of each point */
    uint8_t *face;
    double (*rest)[3], (*rest_err)[3];
    double (*sun)[3], (*sun_err)[3];
    int64_t *own;               /* points to evaluate one by one in this batch */
    sl_irradiance_cost *worker_cost;
    int workers;
} fill;

static uint32_t morton(uint32_t x, uint32_t y)
{
    uint32_t m = 0;
    for (int b = 0; b < 16; b++)
        m |= ((x >> b) & 1u) << (2 * b) | ((y >> b) & 1u) << (2 * b + 1);
    return m;
}

static int cell_of(double s)
{
    int c = (int)(s / (RES / CELLS));
    return c < CELLS ? c : CELLS - 1;
}

/* The block's points: a contiguous run of the Morton order. */
static void block_range(const fill *f, pblock *b)
{
    int shift = 0;
    while ((CELLS >> shift) > b->G)
        shift++;
    size_t base = (size_t)b->face * CELLS * CELLS + ((size_t)morton((uint32_t)b->bx, (uint32_t)b->by) << (2 * shift));
    b->first = f->offset[base];
    b->end = f->offset[base + ((size_t)1 << (2 * shift))];
}

/* The interpolation's error at the block's edge midpoints and centre plus
 * the points' quadrature bounds; true when within tol of the value. */
static bool block_error(const double v[9][3], const double e[9][3], double tol, double err[3])
{
    bool ok = true;
    for (int c = 0; c < 3; c++) {
        double lin[5] = {0.5 * (v[0][c] + v[1][c]), 0.5 * (v[0][c] + v[2][c]), 0.5 * (v[1][c] + v[3][c]),
                         0.5 * (v[2][c] + v[3][c]), 0.25 * (v[0][c] + v[1][c] + v[2][c] + v[3][c])};
        double bmax = 0, d = 0;
        for (int k = 0; k < 9; k++)
            bmax = fmax(bmax, e[k][c]);
        for (int k = 0; k < 5; k++) {
            double dk = fabs(lin[k] - v[4 + k][c]);
            ok &= dk <= tol * v[4 + k][c];
            d = fmax(d, dk);
        }
        err[c] = bmax + d;
    }
    return ok;
}

/* Relative squared error of a block's points, the refinement's order. */
static double block_key(const fill *f, const pblock *b, const double err[3])
{
    double worst = 0;
    for (int64_t i = b->first; i < b->end; i++) {
        const double *E = f->pts->E[f->order[i]];
        for (int c = 0; c < 3; c++) {
            double total = f->rest[f->order[i]][c] + f->sun[f->order[i]][c] + E[c];
            if (total > 0)
                worst = fmax(worst, err[c] / total);
        }
    }
    return worst * worst * (double)(b->end - b->first);
}

/* Interpolates the block's points from its corners; false (nothing
 * changed) when a point of it is not evaluated (the deadline). Pushes it to
 * the heap unless it is final. */
static bool settle_block(fill *f, pblock *b, sl_slot_heap *heap)
{
    normal_job *j = &f->j;
    int S = RES / b->G;
    double v[9][3], e[9][3], err[3];
    for (int k = 0; k < 9; k++) {
        int q = vertex(b->face, b->bx, b->by, S, k);
        if (j->known[q] != 2)
            return false;
        memcpy(v[k], j->val[q], sizeof v[k]);
        memcpy(e[k], j->err[q], sizeof e[k]);
    }
    bool final = block_error(v, e, INTERP_SHARE * f->tol, err) && b->G >= BLOCK0;
    for (int64_t i = b->first; i < b->end; i++) {
        int64_t p = f->order[i];
        double fx = f->st[p][0] / S - b->bx, fy = f->st[p][1] / S - b->by;
        sl_fill_bilinear((const double(*)[3])v, fmin(1.0, fx), fmin(1.0, fy), f->rest[p]);
        memcpy(f->rest_err[p], err, sizeof err);
        f->pts->interpolated[p] = 1;
        f->pts->at_tol[p] = final;
    }
    if (!final) {
        b->key = block_key(f, b, err);
        if (b->G == CELLS)
            b->G = 0; /* no finer block: its points one by one */
        sl_slot_heap_push(heap, b);
    }
    return true;
}

static void queue_block(fill *f, const pblock *b, int64_t *nq)
{
    int S = RES / b->G;
    for (int k = 0; k < 9; k++) {
        int v = vertex(b->face, b->bx, b->by, S, k);
        if (!f->j.known[v])
            f->j.known[v] = 1, f->j.queue[(*nq)++] = v;
    }
}

static void eval_own(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill *f = ctx;
    sl_irradiance_cost scratch = {0}, *cost = worker >= 0 && worker < f->workers ? &f->worker_cost[worker] : &scratch;
    for (int64_t k = begin; k < end; k++) {
        int64_t p = f->own[k];
        if (sl_seconds() > f->deadline)
            continue; /* keeps its interpolation */
        sl_quad q = {.tol = REST_SHARE * f->tol};
        sl_irradiance_integrate(f->gd->rest, f->pts->n[p], &q, f->rest[p], f->rest_err[p], cost);
        f->pts->interpolated[p] = 0;
        f->pts->at_tol[p] = 1;
    }
}

/* The sun at each point's own normal, to its share of the point's whole
 * irradiance (the rest known by now); past the deadline its few start
 * cells alone (each exact when wholly above or below the horizon), their
 * bound saying what is left. */
static void eval_sun(void *ctx, int64_t begin, int64_t end, int worker)
{
    fill *f = ctx;
    const sl_glossy_dome *gd = f->gd;
    sl_irradiance_cost scratch = {0}, *cost = worker >= 0 && worker < f->workers ? &f->worker_cost[worker] : &scratch;
    for (int64_t p = begin; p < end; p++) {
        double floor[3];
        for (int c = 0; c < 3; c++)
            floor[c] = f->rest[p][c] + f->pts->E[p][c];
        bool late = sl_seconds() > f->deadline;
        sl_quad q = {.tol = late ? SUN_LATE_TOL : SUN_SHARE * f->tol, .floor = floor, .start_cells = gd->sun_cells,
                     .start_count = gd->sun_cell_count, .start_level = gd->sun_level};
        sl_irradiance_integrate(gd->sun, f->pts->n[p], &q, f->sun[p], f->sun_err[p], cost);
        if (late)
            f->pts->at_tol[p] = 0;
    }
}

static void fill_free(fill *f)
{
    normal_job_free(&f->j);
    free(f->order);
    free(f->offset);
    free(f->st);
    free(f->face);
    free(f->rest);
    free(f->rest_err);
    free(f->sun);
    free(f->sun_err);
    free(f->own);
    free(f->worker_cost);
}

/* Evaluates the queued vertices and points, in parallel. */
static void run_batch(fill *f, int64_t nq, int64_t nown)
{
    f->j.deadline = f->deadline;
    sl_parallel_for(nq, 4, eval_vertices, &f->j);
    sl_parallel_for(nown, 4, eval_own, f);
}

sl_result sl_lambert_fill(const sl_glossy_dome *gd, double tol, sl_lambert_points *pts, double deadline,
                          int64_t eval_limit, sl_lambert_fill_stats *st, sl_error *err)
{
    memset(st, 0, sizeof *st);
    int64_t n = pts->count;
    fill f = {.gd = gd, .pts = pts, .tol = tol, .deadline = deadline};
    size_t ncells = 6 * (size_t)CELLS * CELLS, np = (size_t)(n > 0 ? n : 1);
    f.workers = sl_threads_get();
    bool ok = normal_job_alloc(&f.j, gd->rest, REST_SHARE * tol);
    f.worker_cost = calloc((size_t)f.workers, sizeof *f.worker_cost);
    f.order = malloc(np * sizeof *f.order);
    f.offset = calloc(ncells + 1, sizeof *f.offset);
    f.st = malloc(np * sizeof *f.st);
    f.face = malloc(np);
    f.rest = calloc(np, sizeof *f.rest);
    f.rest_err = calloc(np, sizeof *f.rest_err);
    f.sun = calloc(np, sizeof *f.sun);
    f.sun_err = calloc(np, sizeof *f.sun_err);
    f.own = malloc(np * sizeof *f.own);
    /* Open blocks: at most the finest ones, each once as a block and once
     * as its points. */
    size_t pool_size = 2 * ncells;
    pblock *pool = malloc(pool_size * sizeof *pool);
    int *heap_slots = malloc(pool_size * sizeof *heap_slots), *free_slots = malloc(pool_size * sizeof *free_slots);
    uint32_t *key = malloc(np * sizeof *key);
    sl_result res = SL_OK;
    if (!ok || !f.worker_cost || !f.order ||
        !f.offset || !f.st || !f.face || !f.rest || !f.rest_err || !f.sun || !f.sun_err || !f.own || !pool ||
        !heap_slots || !free_slots || !key) {
        res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the Lambert fill");
        goto done;
    }
    for (int w = 0; w < f.workers; w++)
        f.j.worker_cost[w] = f.worker_cost[w] =
            (sl_irradiance_cost){.finest_level = sl_irradiance_top_level(gd->rest)};
    /* Sort the points by face and finest block (counting sort, Morton order). */
    for (int64_t p = 0; p < n; p++) {
        f.face[p] = (uint8_t)to_face(pts->n[p], &f.st[p][0], &f.st[p][1]);
        key[p] = (uint32_t)f.face[p] * CELLS * CELLS +
                 morton((uint32_t)cell_of(f.st[p][0]), (uint32_t)cell_of(f.st[p][1]));
        f.offset[key[p] + 1]++;
    }
    for (size_t c = 0; c < ncells; c++)
        f.offset[c + 1] += f.offset[c];
    {
        size_t *fillpos = malloc(ncells * sizeof *fillpos);
        if (!fillpos) {
            res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the Lambert fill");
            goto done;
        }
        for (size_t c = 0; c < ncells; c++)
            fillpos[c] = (size_t)f.offset[c];
        for (int64_t p = 0; p < n; p++)
            f.order[fillpos[key[p]]++] = p;
        free(fillpos);
    }
    sl_slot_heap heap = {.pool = pool, .stride = sizeof(pblock), .heap = heap_slots, .free_list = free_slots};
    /* First pass: every coarse block holding a point, all of them settled
     * (no deadline: a few dozen evaluations). */
    int64_t nq = 0;
    pblock coarse[6 * COARSE * COARSE];
    int ncoarse = 0;
    for (int face = 0; face < 6; face++)
        for (int by = 0; by < COARSE; by++)
            for (int bx = 0; bx < COARSE; bx++) {
                pblock b = {.face = face, .G = COARSE, .bx = bx, .by = by};
                block_range(&f, &b);
                if (b.end > b.first) {
                    coarse[ncoarse++] = b;
                    queue_block(&f, &b, &nq);
                }
            }
    /* Every point needs these: past the deadline they are made coarser,
     * their bounds saying so, rather than left out. */
    f.j.deadline = deadline;
    f.j.late_tol = LATE_TOL;
    sl_parallel_for(nq, 4, eval_vertices, &f.j);
    f.j.late_tol = 0;
    st->coarse_evaluations = nq;
    /* Values first (the sun's tolerance takes the rest as its floor), then
     * the order of refinement (its key takes the sun). */
    for (int i = 0; i < ncoarse; i++) {
        coarse[i].G = COARSE;
        settle_block(&f, &coarse[i], &heap);
    }
    if (gd->sun)
        sl_parallel_for(n, 64, eval_sun, &f);
    sl_slot_heap_clear(&heap);
    for (int i = 0; i < ncoarse; i++) {
        coarse[i].G = COARSE;
        settle_block(&f, &coarse[i], &heap);
    }
    /* Refinement, the largest error first, in batches. */
    int64_t refined = 0;
    while (heap.count > 0) {
        if (sl_seconds() > deadline || (eval_limit > 0 && refined >= eval_limit)) {
            st->cut = true;
            break;
        }
        pblock batch[BATCH_POINTS];
        int nb = 0;
        int64_t nown = 0;
        nq = 0;
        while (heap.count > 0 && nb < BATCH_POINTS && nq + nown < BATCH_POINTS) {
            pblock b;
            sl_slot_heap_pop(&heap, &b);
            if (b.G == 0) {
                for (int64_t i = b.first; i < b.end; i++)
                    f.own[nown++] = f.order[i];
                continue; /* settled by its evaluations */
            }
            for (int k = 0; k < 4; k++) {
                pblock c = {.face = b.face, .G = 2 * b.G, .bx = 2 * b.bx + (k & 1), .by = 2 * b.by + (k >> 1)};
                block_range(&f, &c);
                if (c.end > c.first)
                    queue_block(&f, &c, &nq);
            }
            batch[nb++] = b;
        }
        run_batch(&f, nq, nown);
        refined += nq + nown;
        for (int i = 0; i < nb; i++)
            for (int k = 0; k < 4; k++) {
                pblock c = {.face = batch[i].face, .G = 2 * batch[i].G, .bx = 2 * batch[i].bx + (k & 1),
                            .by = 2 * batch[i].by + (k >> 1)};
                block_range(&f, &c);
                if (c.end > c.first && !settle_block(&f, &c, &heap))
                    st->cut = true; /* the deadline: the parent's values stay */
            }
    }
    /* Totals. */
    for (int64_t p = 0; p < n; p++)
        for (int c = 0; c < 3; c++) {
            pts->E[p][c] += f.rest[p][c] + f.sun[p][c];
            pts->bound[p][c] += f.rest_err[p][c] + f.sun_err[p][c];
        }
    st->cost.finest_level = sl_irradiance_top_level(gd->rest);
    for (int w = 0; w < f.workers; w++)
        for (int k = 0; k < 2; k++) {
            const sl_irradiance_cost *c = k ? &f.worker_cost[w] : &f.j.worker_cost[w];
            sl_irradiance_cost_add(&st->cost, c->evaluations, c->cells, c->finest_level);
        }
done:
    fill_free(&f);
    free(pool);
    free(heap_slots);
    free(free_slots);
    free(key);
    return res;
}
