/* SPDX-License-Identifier: BSD-3-Clause */
/* The rest of the map's irradiance at Lambert pixels, interpolated over the
 * sphere of normals rather than the image: irradiance depends on the normal
 * alone, so a sphere's rim (where the normal turns fast from pixel to pixel)
 * or a plane (one normal) costs no more than its interior.
 *
 * The sphere of normals is a cube's six faces, each a (u, v) square whose
 * direction (u, v, 1) is smooth: E is smooth across a face. Blocks of
 * 1/8 of a face (about 11 degrees) are checked as the image blocks of
 * glossy_fill.c (centre and edge midpoints against the bilinear
 * interpolation of the corners, sl_fill_check); a block that fails is split
 * in four, down to 1/64 of a face (about 1.4 degrees). Only blocks holding
 * some pixel's normal are evaluated. Pixels that no block interpolates keep
 * their state: the caller evaluates them one by one. The grid keeps its
 * evaluated points from call to call, so the caller can fill the image band
 * by band at the cost of one call: whether a pixel is interpolated, and its
 * value, depend on its normal alone, not on the other pixels of the call. */
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
        if (sl_seconds() > j->deadline) {
            j->known[v] = 0; /* unknown: its blocks fail, their pixels are the caller's */
            continue;
        }
        int face = v / VERTS, r = v % VERTS;
        double n[3];
        from_face(face, r % (RES + 1), r / (RES + 1), n);
        sl_quad q = {.tol = j->quad_tol};
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

struct sl_normal_grid {
    normal_job j;
    double interp_tol;
    /* Per block of the current level: 0 none, 1 holds a pixel left, 2
     * interpolated; its error. Scratch of each call. */
    uint8_t *block;
    double (*block_err)[3];
};

void sl_normal_grid_free(sl_normal_grid *g)
{
    if (!g)
        return;
    free(g->j.val);
    free(g->j.err);
    free(g->j.known);
    free(g->j.queue);
    free(g->j.worker_cost);
    free(g->block);
    free(g->block_err);
    free(g);
}

sl_result sl_normal_grid_new(const sl_irradiance *rest, double quad_tol, double interp_tol,
                             sl_normal_grid **out, sl_error *err)
{
    sl_normal_grid *g = calloc(1, sizeof *g);
    *out = NULL;
    if (!g)
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the irradiance over normals");
    normal_job *j = &g->j;
    j->rest = rest;
    j->quad_tol = quad_tol;
    g->interp_tol = interp_tol;
    j->workers = sl_threads_get();
    j->val = malloc(6 * (size_t)VERTS * sizeof *j->val);
    j->err = malloc(6 * (size_t)VERTS * sizeof *j->err);
    j->known = calloc(6 * (size_t)VERTS, 1);
    j->queue = malloc(6 * (size_t)VERTS * sizeof *j->queue);
    j->worker_cost = calloc((size_t)j->workers, sizeof *j->worker_cost);
    g->block = malloc(6 * (size_t)RES * RES);
    g->block_err = malloc(6 * (size_t)RES * RES * sizeof *g->block_err);
    if (!j->val || !j->err || !j->known || !j->queue || !j->worker_cost || !g->block || !g->block_err) {
        sl_normal_grid_free(g);
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the irradiance over normals");
    }
    *out = g;
    return SL_OK;
}

sl_result sl_normal_grid_fill(sl_normal_grid *g, const double (*n)[3], const size_t *pix, int64_t count,
                              double (*out)[3], double (*out_err)[3], uint8_t *interpolated,
                              double deadline, sl_irradiance_cost *cost, sl_error *err)
{
    normal_job *jp = &g->j;
    jp->deadline = deadline;
    uint8_t *block = g->block;
    double(*block_err)[3] = g->block_err;
    /* Per pixel: face and (s, t). */
    int *face = malloc((size_t)(count > 0 ? count : 1) * sizeof *face);
    double (*st)[2] = malloc((size_t)(count > 0 ? count : 1) * sizeof *st);
    sl_result res = SL_OK;
    if (!face || !st) {
        res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the irradiance over normals");
        goto done;
    }
    for (int w = 0; w < jp->workers; w++)
        jp->worker_cost[w] = (sl_irradiance_cost){.finest_level = sl_irradiance_top_level(jp->rest)};
    for (int64_t i = 0; i < count; i++) {
        face[i] = to_face(n[pix[i]], &st[i][0], &st[i][1]);
        interpolated[pix[i]] = 0;
    }
    for (int G = BLOCK0; G <= RES / 2; G *= 2) {
        int S = RES / G;
        memset(block, 0, 6 * (size_t)G * G);
        for (int64_t i = 0; i < count; i++)
            if (!interpolated[pix[i]]) {
                int bx = (int)fmin(G - 1, st[i][0] / S), by = (int)fmin(G - 1, st[i][1] / S);
                block[((size_t)face[i] * G + by) * G + bx] = 1;
            }
        int64_t nq = 0;
        for (int b = 0; b < 6 * G * G; b++)
            for (int k = 0; k < 9 && block[b]; k++) {
                int v = vertex(b / (G * G), b % G, (b / G) % G, S, k);
                if (!jp->known[v])
                    jp->known[v] = 1, jp->queue[nq++] = v;
            }
        sl_parallel_for(nq, 16, eval_vertices, jp);
        for (int b = 0; b < 6 * G * G; b++) {
            if (!block[b])
                continue;
            double v[9][3], e[9][3];
            bool all = true;
            for (int k = 0; k < 9 && all; k++) {
                int q = vertex(b / (G * G), b % G, (b / G) % G, S, k);
                all = jp->known[q] == 2;
                memcpy(v[k], jp->val[q], sizeof v[k]);
                memcpy(e[k], jp->err[q], sizeof e[k]);
            }
            if (all && sl_fill_check(v, e, g->interp_tol, 0.0, block_err[b]))
                block[b] = 2;
        }
        for (int64_t i = 0; i < count; i++) {
            size_t p = pix[i];
            if (interpolated[p])
                continue;
            int bx = (int)fmin(G - 1, st[i][0] / S), by = (int)fmin(G - 1, st[i][1] / S);
            int b = (face[i] * G + by) * G + bx;
            if (block[b] != 2)
                continue;
            double fx = st[i][0] / S - bx, fy = st[i][1] / S - by;
            double wts[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
            for (int c = 0; c < 3; c++) {
                double s = 0;
                for (int k = 0; k < 4; k++)
                    s += wts[k] * jp->val[vertex(face[i], bx, by, S, k)][c];
                out[p][c] = s;
                out_err[p][c] = block_err[b][c];
            }
            interpolated[p] = 1;
        }
    }
    for (int w = 0; w < jp->workers; w++) {
        cost->evaluations += jp->worker_cost[w].evaluations;
        cost->cells += jp->worker_cost[w].cells;
        if (jp->worker_cost[w].evaluations && jp->worker_cost[w].finest_level < cost->finest_level)
            cost->finest_level = jp->worker_cost[w].finest_level;
    }
done:
    free(face);
    free(st);
    return res;
}
