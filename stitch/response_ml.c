/* SPDX-License-Identifier: BSD-3-Clause */
/* The self-calibrated curve refined by maximum likelihood under the
 * sensor's noise (docs/merge.md "Refining the curve under the noise").
 *
 * Debevec-Malik fits the curve to the codes' ratios, and with equal
 * exposure steps a whole family of curves (the equal-step class: any
 * periodic bend in ln exposure with the step's period) explains the ratios
 * equally well. The noise does not bend with them: a code's spread is set
 * by the sensor (variance A mu + B of the linear value mu), so the exact
 * 8-bit bins under that noise pin the class. Model, per series (one sample
 * position, one channel, the bracket's frames):
 *   - one inverse curve for the three channels: e[j], the linear value
 *     between codes j and j + 1, a cubic B-spline in ln e (the lowest
 *     FREE_EDGES edges each their own term); e[TOP - 1] held (the scale);
 *   - the series' radiance E (u = ln E) integrated out under the scene's
 *     density of u, re-estimated from the series between rounds (an EM
 *     step): a series seen in one frame tells the curve something only
 *     through how often the scene puts a pixel there;
 *   - frame r reads mu = E t_r plus noise of variance A_c mu + B_c;
 *   - code k in 1 .. TOP - 1 reads mu + noise in [e[k-1], e[k]); code 0 "at
 *     most e[0]"; codes TOP and up "at least e[TOP - 1]" (a camera's clip
 *     and its white-balance clip live there); an outlier term eps / 256;
 *   - series with a code in 1 .. TOP - 1 and another frame.
 * Maximised by Levenberg-Marquardt on the observed information (Newton),
 * each series' quadrature window and the density re-placed between
 * rounds. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"

enum {
    TOP = 250,         /* codes from here read "at least e[TOP - 1]" */
    EDGES = TOP,       /* e[0 .. TOP - 1] */
    FIXED = TOP - 1,   /* the edge held: the curve's scale */
    PARAMS = EDGES + 6, /* ln e, then ln A per channel, then ln B per channel */
    GRID = 40,         /* quadrature points per series */
    MAX_TOUCH = 2 * MERGE_MAX_FRAMES + 2,
};

#define EPS_OUT 1e-3     /* outlier share: a code any value can read */
enum { ROUNDS = 8, MIN_SERIES = 300 };
/* A refinement moving ln g further than this anywhere is not believed:
 * Debevec-Malik's curves are off by tens of percent, not by a factor. */
#define MAX_MOVE 0.7
enum { MOVE_FROM = 13 };
#define MIN_GAP 1e-4     /* ln e steps at least this much a code */

enum { OBS_BIN, OBS_BELOW, OBS_ABOVE };

typedef struct {
    uint8_t code, kind, rank, channel;
} ml_obs;

typedef struct {
    int first, count, channel;
    double lo, du; /* the quadrature window in u */
} ml_series;

typedef struct {
    const double *loge;
    ml_obs *obs;
    ml_series *series;
    int n_series, n_obs, frames;
    double *H; /* PARAMS x PARAMS */
    double *work;
    double *M; /* MAX_TOUCH x MAX_TOUCH: one series' Hessian */
    /* the scene's density of u per channel: dens[c][b] on bins of DENS_BIN
     * from dens_u0[c] (NULL: flat) */
    double *dens[3], dens_u0[3];
    int dens_bins[3];
} ml_ctx;

#define DENS_BIN 0.05

static double density_at(const ml_ctx *m, int c, double u)
{
    if (!m->dens[c])
        return 1;
    double t = (u - m->dens_u0[c]) / DENS_BIN - 0.5;
    int b = (int)floor(t);
    double f = t - b;
    int n = m->dens_bins[c];
    double lo = m->dens[c][b < 0 ? 0 : b >= n ? n - 1 : b];
    double hi = m->dens[c][b + 1 < 0 ? 0 : b + 1 >= n ? n - 1 : b + 1];
    return (1 - f) * lo + f * hi;
}

/* Beyond TAIL deviations a bin's probability is far below the outlier
 * term's (eps / 256): 0 or 1, without erfc. */
#define TAIL 7.0

static const double SQRT1_2 = 0.70710678118654752440;
static const double INV_SQRT_2PI = 0.39894228040143267794;

static double phi(double a) { return INV_SQRT_2PI * exp(-0.5 * a * a); }

/* Phi(hi) - Phi(lo) for lo <= hi, each tail from erfc so that far tails
 * keep their relative precision. */
static double phi_between(double lo, double hi)
{
    if (lo > TAIL || hi < -TAIL)
        return 0;
    if (lo < -TAIL && hi > TAIL)
        return 1;
    if (lo >= 0)
        return 0.5 * (erfc(lo * SQRT1_2) - erfc(hi * SQRT1_2));
    if (hi <= 0)
        return 0.5 * (erfc(-hi * SQRT1_2) - erfc(-lo * SQRT1_2));
    return 1 - 0.5 * (erfc(-lo * SQRT1_2) + erfc(hi * SQRT1_2));
}

/* Adds sign * phi(a) (d a, d2 a - a da da^T) to dp, d2p for a = (e - mu) /
 * sd, e = exp(theta) in slot `slot` (0 or 1) of (theta_lo, theta_hi,
 * ln A, ln B); rA, rB: d ln sd / d ln A, d ln B. */
static void add_edge(double a, double e_sd, int slot, double rA, double rB, double sign,
                     double dp[4], double d2p[16])
{
    if (fabs(a) > TAIL)
        return; /* phi(a) below 1e-11: nothing to add */
    double da[4] = {0, 0, -a * rA, -a * rB};
    double d2a[16] = {0};
    da[slot] = e_sd;
    d2a[slot * 4 + slot] = e_sd;
    d2a[slot * 4 + 2] = d2a[2 * 4 + slot] = -e_sd * rA;
    d2a[slot * 4 + 3] = d2a[3 * 4 + slot] = -e_sd * rB;
    d2a[2 * 4 + 2] = a * (3 * rA * rA - rA);
    d2a[2 * 4 + 3] = d2a[3 * 4 + 2] = 3 * a * rA * rB;
    d2a[3 * 4 + 3] = a * (3 * rB * rB - rB);
    double f = sign * phi(a);
    for (int i = 0; i < 4; i++) {
        dp[i] += f * da[i];
        if (d2p)
            for (int j = 0; j < 4; j++)
                d2p[i * 4 + j] += f * (d2a[i * 4 + j] - a * da[i] * da[j]);
    }
}

/* Probability of observation o given linear value mu; d ln P and (with d2)
 * its second derivatives over (ln e[lo edge], ln e[hi edge], ln A, ln B). */
static double obs_prob(const ml_obs *o, const double *e, double mu, double A, double B, double d[4],
                       double *d2)
{
    double var = A * mu + B, sd = sqrt(var);
    double rA = A * mu / (2 * var), rB = B / (2 * var);
    double p, dp[4] = {0, 0, 0, 0}, d2p[16];
    if (d2)
        memset(d2p, 0, sizeof d2p);
    if (o->kind == OBS_BELOW) {
        double ah = (e[0] - mu) / sd;
        p = 0.5 * erfc(-ah * SQRT1_2);
        add_edge(ah, e[0] / sd, 1, rA, rB, 1, dp, d2 ? d2p : NULL);
    } else if (o->kind == OBS_ABOVE) {
        double al = (e[TOP - 1] - mu) / sd;
        p = 0.5 * erfc(al * SQRT1_2);
        add_edge(al, e[TOP - 1] / sd, 0, rA, rB, -1, dp, d2 ? d2p : NULL);
    } else {
        double el = e[o->code - 1], eh = e[o->code];
        double al = (el - mu) / sd, ah = (eh - mu) / sd;
        p = al < ah ? phi_between(al, ah) : 0;
        add_edge(ah, eh / sd, 1, rA, rB, 1, dp, d2 ? d2p : NULL);
        add_edge(al, el / sd, 0, rA, rB, -1, dp, d2 ? d2p : NULL);
    }
    double pp = (1 - EPS_OUT) * p + EPS_OUT / 256;
    double k = (1 - EPS_OUT) / pp;
    for (int i = 0; i < 4; i++)
        d[i] = k * dp[i];
    if (d2)
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++)
                d2[i * 4 + j] = k * d2p[i * 4 + j] - d[i] * d[j];
    return pp;
}

/* The parameters an observation's derivatives go to: ln e of its lower and
 * upper edge (-1 none or the fixed one), ln A_c, ln B_c. */
static void obs_params(const ml_obs *o, int idx[4])
{
    idx[0] = o->kind == OBS_BIN ? o->code - 1 : o->kind == OBS_ABOVE ? TOP - 1 : -1;
    idx[1] = o->kind == OBS_BIN ? o->code : o->kind == OBS_BELOW ? 0 : -1;
    for (int k = 0; k < 2; k++)
        if (idx[k] == FIXED)
            idx[k] = -1;
    idx[2] = EDGES + o->channel;
    idx[3] = EDGES + 3 + o->channel;
}

/* A series' likelihood at each of its GRID points (the scene's density
 * times its observations' probabilities, the trapezoid's end weights with
 * `trapezoid`) into prod; their sum returned. dl, d2l (or NULL): each
 * observation's derivatives at each point, at [k * GRID + q]. */
static double series_likelihood(const ml_ctx *m, const ml_series *s, const double *e, double A,
                                double B, bool trapezoid, double *prod, double *dl, double *d2l)
{
    const ml_obs *o = m->obs + s->first;
    double L = 0, t[MERGE_MAX_FRAMES], scratch[4];
    for (int k = 0; k < s->count; k++) /* mu at the window's start; times exp(du) a point */
        t[k] = exp(s->lo + m->loge[o[k].rank]);
    double step = exp(s->du), grow = 1;
    for (int q = 0; q < GRID; q++, grow *= step) {
        double u = s->lo + q * s->du;
        double p = (trapezoid && (q == 0 || q == GRID - 1) ? 0.5 : 1) * density_at(m, s->channel, u);
        for (int k = 0; k < s->count; k++) {
            size_t at = (size_t)k * GRID + q;
            p *= obs_prob(&o[k], e, t[k] * grow, A, B, dl ? dl + at * 4 : scratch,
                          d2l ? d2l + at * 16 : NULL);
        }
        prod[q] = p;
        L += p;
    }
    return L;
}

/* Log-likelihood of all series at parameters x; with g and H its gradient
 * and minus its Hessian (the observed information). */
static double evaluate(const ml_ctx *m, const double *x, double *g, double *H)
{
    double e[EDGES], A[3], B[3];
    for (int j = 0; j < EDGES; j++)
        e[j] = exp(x[j]);
    for (int c = 0; c < 3; c++)
        A[c] = exp(x[EDGES + c]), B[c] = exp(x[EDGES + 3 + c]);
    if (g)
        memset(g, 0, PARAMS * sizeof *g);
    if (H)
        memset(H, 0, (size_t)PARAMS * PARAMS * sizeof *H);
    double F = 0;
    double *dl = m->work;                               /* per obs, grid point: 4 */
    double *d2l = m->work + (size_t)m->frames * GRID * 4; /* and 16 */
    for (int i = 0; i < m->n_series; i++) {
        const ml_series *s = &m->series[i];
        const ml_obs *o = m->obs + s->first;
        int c = s->channel;
        double prod[GRID];
        double L = series_likelihood(m, s, e, A[c], B[c], true, prod, dl, g ? d2l : NULL);
        F += log(L * s->du);
        if (!g)
            continue;
        /* the series' parameters, and where each observation's four go */
        int idx[MAX_TOUCH], map[MERGE_MAX_FRAMES][4];
        int n = 0;
        for (int k = 0; k < s->count; k++) {
            int pi[4];
            obs_params(&o[k], pi);
            for (int t = 0; t < 4; t++) {
                map[k][t] = -1;
                if (pi[t] < 0)
                    continue;
                int at = 0;
                while (at < n && idx[at] != pi[t])
                    at++;
                if (at == n)
                    idx[n++] = pi[t];
                map[k][t] = at;
            }
        }
        /* score S = E[d]; Hessian of ln L = E[D + d d^T] - S S^T, over the
         * posterior of u (weights prod / L) */
        double S[MAX_TOUCH] = {0}, *M = m->M;
        memset(M, 0, (size_t)n * n * sizeof *M);
        for (int q = 0; q < GRID; q++) {
            double w = prod[q] / L;
            if (w < 1e-12)
                continue;
            double dq[MAX_TOUCH] = {0};
            for (int k = 0; k < s->count; k++) {
                size_t at = (size_t)k * GRID + q;
                const double *d = dl + at * 4, *d2 = d2l + at * 16;
                for (int t = 0; t < 4; t++) {
                    int a = map[k][t];
                    if (a < 0)
                        continue;
                    dq[a] += d[t];
                    for (int v = 0; v < 4; v++)
                        if (map[k][v] >= 0)
                            M[a * n + map[k][v]] += w * d2[t * 4 + v];
                }
            }
            for (int a = 0; a < n; a++) {
                S[a] += w * dq[a];
                for (int b = 0; b < n; b++)
                    M[a * n + b] += w * dq[a] * dq[b];
            }
        }
        for (int a = 0; a < n; a++) {
            g[idx[a]] += S[a];
            if (H)
                for (int b = 0; b < n; b++)
                    H[idx[a] * PARAMS + idx[b]] += S[a] * S[b] - M[a * n + b];
        }
    }
    return F;
}

/* Keeps ln e increasing by at least MIN_GAP a code, the fixed edge where it
 * is, and the noise terms in a sane range. */
static void project(double *x)
{
    for (int j = FIXED - 1; j >= 0; j--)
        x[j] = fmin(x[j], x[j + 1] - MIN_GAP);
    for (int k = EDGES; k < PARAMS; k++)
        x[k] = fmin(fmax(x[k], -30), 2);
}

/* Each series' quadrature window from the current curve and noise: where
 * every one of its codes' bins, widened by four deviations, overlaps. */
static void place_windows(ml_ctx *m, const double *x)
{
    for (int i = 0; i < m->n_series; i++) {
        ml_series *s = &m->series[i];
        int c = s->channel;
        double A = exp(x[EDGES + c]), B = exp(x[EDGES + 3 + c]);
        double lo = -INFINITY, hi = INFINITY, mid = 0;
        int bins = 0;
        for (int k = 0; k < s->count; k++) {
            const ml_obs *o = &m->obs[s->first + k];
            if (o->kind != OBS_BIN)
                continue;
            double el = exp(x[o->code - 1]), eh = exp(x[o->code]);
            double l = el - 4 * sqrt(A * el + B), h = eh + 4 * sqrt(A * eh + B);
            double t = m->loge[o->rank];
            double ul = log(fmax(l, el * 1e-3)) - t, uh = log(h) - t;
            lo = fmax(lo, ul);
            hi = fmin(hi, uh);
            mid += 0.5 * (x[o->code - 1] + x[o->code]) - t;
            bins++;
        }
        mid /= bins;
        if (!(hi > lo)) /* codes that disagree: an outlier among them */
            lo = mid - 0.1, hi = mid + 0.1;
        s->lo = lo;
        s->du = (hi - lo) / (GRID - 1);
    }
}

/* The curve as a cubic B-spline: ln e[j] = sum_k basis[j][k] y[k] for j >=
 * FREE_EDGES (knots even in ln(j + 4.5): dense in the toe, where ln e
 * bends most), the lowest FREE_EDGES edges their own terms (code 0's edge
 * sits apart, set by the black level and read noise), then the noise
 * terms. A spline cannot empty a code that the sample happens to miss,
 * which free edges do. */
enum { KNOTS = 40, FREE_EDGES = 2, SPLINE = KNOTS + 2, NY = SPLINE + FREE_EDGES + 6 };

typedef struct {
    double *x_of_y;                    /* PARAMS x NY */
    int first[PARAMS], count[PARAMS];  /* each row's run of nonzero terms */
} ml_basis;

static void bspline_row(double t, const double *knot, int nk, double *row)
{
    /* clamped cubic: knot vector with the ends repeated three more times */
    double kv[KNOTS + 6];
    for (int i = 0; i < 3; i++)
        kv[i] = knot[0], kv[nk + 3 + i] = knot[nk - 1];
    for (int i = 0; i < nk; i++)
        kv[3 + i] = knot[i];
    int nkv = nk + 6;
    double b[KNOTS + 6];
    t = fmin(fmax(t, knot[0]), knot[nk - 1] - 1e-12);
    for (int i = 0; i + 1 < nkv; i++)
        b[i] = t >= kv[i] && t < kv[i + 1];
    for (int d = 1; d <= 3; d++)
        for (int i = 0; i + d + 1 < nkv; i++) {
            double l = kv[i + d] > kv[i] ? (t - kv[i]) / (kv[i + d] - kv[i]) : 0;
            double r = kv[i + d + 1] > kv[i + 1] ? (kv[i + d + 1] - t) / (kv[i + d + 1] - kv[i + 1]) : 0;
            b[i] = l * b[i] + r * b[i + 1];
        }
    for (int i = 0; i < nk + 2; i++)
        row[i] = b[i];
}

static bool basis_init(ml_basis *B)
{
    B->x_of_y = calloc((size_t)PARAMS * NY, sizeof *B->x_of_y);
    if (!B->x_of_y)
        return false;
    double knot[KNOTS], lo = log(FREE_EDGES + 4.5), hi = log(EDGES - 1 + 4.5);
    for (int i = 0; i < KNOTS; i++)
        knot[i] = lo + (hi - lo) * i / (KNOTS - 1);
    for (int j = FREE_EDGES; j < EDGES; j++)
        bspline_row(log(j + 4.5), knot, KNOTS, B->x_of_y + (size_t)j * NY);
    for (int j = 0; j < FREE_EDGES; j++)
        B->x_of_y[(size_t)j * NY + SPLINE + j] = 1;
    for (int k = 0; k < 6; k++)
        B->x_of_y[(size_t)(EDGES + k) * NY + SPLINE + FREE_EDGES + k] = 1;
    for (int a = 0; a < PARAMS; a++) {
        int first = -1, last = -1;
        for (int k = 0; k < NY; k++)
            if (B->x_of_y[(size_t)a * NY + k] != 0)
                last = k, first = first < 0 ? k : first;
        B->first[a] = first < 0 ? 0 : first;
        B->count[a] = first < 0 ? 0 : last - first + 1;
    }
    return true;
}

static void x_from_y(const ml_basis *B, const double *y, double *x)
{
    for (int a = 0; a < PARAMS; a++) {
        double v = 0;
        for (int k = 0; k < NY; k++)
            v += B->x_of_y[(size_t)a * NY + k] * y[k];
        x[a] = v;
    }
}

/* y whose curve is nearest x's in least squares (the start). */
static bool y_from_x(const ml_basis *B, const double *x, double *y)
{
    double *A = calloc((size_t)NY * NY, sizeof *A);
    if (!A)
        return false;
    for (int k = 0; k < NY; k++) {
        y[k] = 0;
        for (int a = 0; a < PARAMS; a++)
            y[k] += B->x_of_y[(size_t)a * NY + k] * x[a];
        for (int l = 0; l < NY; l++) {
            double v = 0;
            for (int a = 0; a < PARAMS; a++)
                v += B->x_of_y[(size_t)a * NY + k] * B->x_of_y[(size_t)a * NY + l];
            A[k * NY + l] = v + (k == l ? 1e-10 : 0);
        }
    }
    bool ok = merge_cholesky_solve(A, y, NY);
    free(A);
    return ok;
}

/* The curve increasing (ln e up from code to code) and the noise sane. */
static bool admissible(const double *x)
{
    for (int j = 1; j < EDGES; j++)
        if (!(x[j] > x[j - 1]))
            return false;
    for (int k = EDGES; k < PARAMS; k++)
        if (!(x[k] > -30 && x[k] < 2))
            return false;
    return true;
}

/* F, gradient and information over y from those over x. */
static double evaluate_y(const ml_ctx *m, const ml_basis *B, const double *y, double *x, double *gy,
                         double *Hy, double *gx, double *tmp)
{
    x_from_y(B, y, x);
    if (!admissible(x))
        return -INFINITY;
    double F = evaluate(m, x, gy ? gx : NULL, gy ? m->H : NULL);
    if (!gy)
        return F;
    const double *T = B->x_of_y;
    for (int k = 0; k < NY; k++) {
        double v = 0;
        for (int a = 0; a < PARAMS; a++)
            v += T[(size_t)a * NY + k] * gx[a];
        gy[k] = v;
    }
    /* tmp = H T (PARAMS x NY), then Hy = T^T tmp; T's rows hold a run of
     * four spline terms at most (B->first, B->count) */
    memset(tmp, 0, (size_t)PARAMS * NY * sizeof *tmp);
    for (int a = 0; a < PARAMS; a++)
        for (int b = 0; b < PARAMS; b++) {
            double h = m->H[(size_t)a * PARAMS + b];
            if (h != 0)
                for (int k = B->first[b]; k < B->first[b] + B->count[b]; k++)
                    tmp[(size_t)a * NY + k] += h * T[(size_t)b * NY + k];
        }
    memset(Hy, 0, (size_t)NY * NY * sizeof *Hy);
    for (int a = 0; a < PARAMS; a++)
        for (int k = B->first[a]; k < B->first[a] + B->count[a]; k++)
            for (int l = 0; l < NY; l++)
                Hy[k * NY + l] += T[(size_t)a * NY + k] * tmp[(size_t)a * NY + l];
    return F;
}

/* One Levenberg-Marquardt climb (Newton on the observed information) over
 * the active parameters y. Returns the final log-likelihood. */
static double climb(ml_ctx *m, const ml_basis *B, double *y, const bool *active, int iterations,
                    double tol, int *steps)
{
    double *x = malloc(PARAMS * sizeof *x), *gx = malloc(PARAMS * sizeof *gx),
           *tmp = malloc((size_t)PARAMS * NY * sizeof *tmp), *g = malloc(NY * sizeof *g),
           *H = malloc((size_t)NY * NY * sizeof *H), *A = malloc((size_t)NY * NY * sizeof *A),
           *step = malloc(NY * sizeof *step), *yn = malloc(NY * sizeof *yn);
    double F = NAN;
    if (!x || !gx || !tmp || !g || !H || !A || !step || !yn)
        goto done;
    F = evaluate_y(m, B, y, x, g, H, gx, tmp);
    double lambda = 1e-3;
    int small = 0;
    for (int it = 0; it < iterations; it++) {
        bool better = false;
        double Fn = F;
        for (int tries = 0; tries < 12 && !better; tries++) {
            for (int a = 0; a < NY; a++) {
                for (int b = 0; b < NY; b++)
                    A[a * NY + b] = active[a] && active[b] ? H[a * NY + b] : 0;
                double d = H[a * NY + a];
                A[a * NY + a] = active[a] ? d + lambda * fabs(d) + 1e-9 : 1;
                step[a] = active[a] ? g[a] : 0;
            }
            if (!merge_cholesky_solve(A, step, NY)) {
                lambda = fmax(lambda * 10, 1e-6);
                continue;
            }
            for (int a = 0; a < NY; a++)
                yn[a] = y[a] + step[a];
            Fn = evaluate_y(m, B, yn, x, NULL, NULL, NULL, NULL);
            if (Fn > F)
                better = true;
            else
                lambda = fmax(lambda * 10, 1e-6);
        }
        if (!better)
            break;
        memcpy(y, yn, NY * sizeof *y);
        ++*steps;
        double gain = Fn - F;
        F = evaluate_y(m, B, y, x, g, H, gx, tmp);
        lambda = fmax(lambda / 10, 1e-7);
        small = gain < tol ? small + 1 : 0;
        if (small >= 2)
            break;
    }
done:
    free(x);
    free(gx);
    free(tmp);
    free(g);
    free(H);
    free(A);
    free(step);
    free(yn);
    return F;
}

/* The observations of sample position i's channel c, in rank order, into
 * o; returns how many, 0 when none of its codes is in 1 .. TOP - 1 or only
 * one frame says anything. */
static int series_obs(const merge_samples *s, int i, int c, ml_obs *o)
{
    int f = s->frames, n = 0, bins = 0;
    int prev_kind = -1;
    for (int r = 0; r < f; r++) {
        if (s->spoilt[(size_t)i * f + r])
            continue;
        const float *v = s->z + ((size_t)i * f + r) * 3;
        int code = (int)(v[c] * 255.0f + 0.5f);
        int top = (int)(merge_zmax(s, i, r) * 255.0f + 0.5f);
        ml_obs ob = {(uint8_t)code, OBS_BIN, (uint8_t)r, (uint8_t)c};
        if (code >= TOP)
            ob.kind = OBS_ABOVE;
        else if (top >= TOP)
            continue; /* another channel's clip may have moved this one */
        else if (code == 0)
            ob.kind = OBS_BELOW;
        /* of a run of zeros only the last, of clipped ones only the first,
         * counts: the others follow from it */
        if (ob.kind == OBS_BELOW && prev_kind == OBS_BELOW)
            n--;
        if (ob.kind == OBS_ABOVE && prev_kind == OBS_ABOVE)
            continue;
        prev_kind = ob.kind;
        bins += ob.kind == OBS_BIN;
        o[n++] = ob;
    }
    return bins >= 1 && n >= 2 ? n : 0;
}

/* The scene's density of u per channel from the series' posteriors under
 * the current curve (an EM step for the mixing density), a little
 * smoothed. First call (no density yet): each window spread evenly. */
static bool update_density(ml_ctx *m, const double *x)
{
    double e[EDGES];
    for (int j = 0; j < EDGES; j++)
        e[j] = exp(x[j]);
    for (int c = 0; c < 3; c++) {
        double lo = INFINITY, hi = -INFINITY;
        for (int i = 0; i < m->n_series; i++)
            if (m->series[i].channel == c) {
                lo = fmin(lo, m->series[i].lo);
                hi = fmax(hi, m->series[i].lo + (GRID - 1) * m->series[i].du);
            }
        if (!(hi > lo))
            continue;
        int n = (int)ceil((hi - lo) / DENS_BIN) + 3;
        double *h = calloc((size_t)n, sizeof *h);
        if (!h)
            return false;
        double u0 = lo - DENS_BIN;
        for (int i = 0; i < m->n_series; i++) {
            const ml_series *s = &m->series[i];
            if (s->channel != c)
                continue;
            double w[GRID], L = GRID;
            if (m->dens[c])
                L = series_likelihood(m, s, e, exp(x[EDGES + c]), exp(x[EDGES + 3 + c]), false, w,
                                      NULL, NULL);
            else
                for (int q = 0; q < GRID; q++)
                    w[q] = 1;
            for (int q = 0; q < GRID; q++) {
                int b = (int)((s->lo + q * s->du - u0) / DENS_BIN);
                h[b < 0 ? 0 : b >= n ? n - 1 : b] += w[q] / L;
            }
        }
        double *sm = calloc((size_t)n, sizeof *sm), total = 0;
        if (!sm) {
            free(h);
            return false;
        }
        for (int b = 0; b < n; b++) {
            double v = 0.5 * h[b] + 0.25 * (h[b > 0 ? b - 1 : b] + h[b + 1 < n ? b + 1 : b]);
            sm[b] = v + 1e-6;
            total += sm[b];
        }
        for (int b = 0; b < n; b++)
            sm[b] /= total * DENS_BIN;
        free(h);
        free(m->dens[c]);
        m->dens[c] = sm;
        m->dens_u0[c] = u0;
        m->dens_bins[c] = n;
    }
    return true;
}

sl_result merge_refine_response(const merge_samples *s, const double *log_exposure,
                                int max_positions, sl_response *resp, merge_refine_report *rep,
                                sl_error *err)
{
    memset(rep, 0, sizeof *rep);
    if (!(fabs(s->code_step * 255 - 1) < 1e-9) || s->coded || resp->nodes != 256) {
        snprintf(rep->note, sizeof rep->note, "not 8-bit lossless codes: not refined");
        return SL_OK;
    }
    int f = s->frames;
    /* every k-th position, k from the count: spread over the frame */
    int stride = s->count > max_positions ? (s->count + max_positions - 1) / max_positions : 1;
    int cap = (s->count / stride + 1) * 3;
    ml_ctx m = {.loge = log_exposure, .frames = f};
    ml_basis B = {0};
    m.series = malloc((size_t)cap * sizeof *m.series);
    m.obs = malloc((size_t)cap * f * sizeof *m.obs);
    m.H = malloc((size_t)PARAMS * PARAMS * sizeof *m.H);
    m.work = malloc((size_t)f * GRID * 20 * sizeof *m.work);
    m.M = malloc((size_t)MAX_TOUCH * MAX_TOUCH * sizeof *m.M);
    double *x = malloc(PARAMS * sizeof *x), *y = malloc(NY * sizeof *y);
    double *x0 = malloc(PARAMS * sizeof *x0); /* the first curve, for the verdict */
    bool *active = malloc(NY * sizeof *active);
    double *out = NULL;
    sl_result result = SL_OK;
    if (!m.series || !m.obs || !m.H || !m.work || !m.M || !x || !x0 || !y || !active || !basis_init(&B)) {
        result = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        goto done;
    }
    /* green alone, when it has enough: its noise follows A mu + B best (the
     * colour matrix amplifies it least and mixes little of the others into
     * it; red and blue's noise grows with the other channels' values, and
     * the curve bent to meet that: Ektachrome-64CDRed 0.98x the ideal with
     * all three, 0.83x with green, docs/merge.md) */
    for (int pass = 0; pass < 2 && m.n_series < MIN_SERIES; pass++) {
        m.n_series = m.n_obs = 0;
        for (int i = 0; i < s->count; i += stride)
            for (int c = pass ? 0 : 1; c < (pass ? 3 : 2); c++) {
                int n = series_obs(s, i, c, m.obs + m.n_obs);
                if (!n)
                    continue;
                m.series[m.n_series++] = (ml_series){m.n_obs, n, c, 0, 0};
                m.n_obs += n;
            }
    }
    rep->series = m.n_series;
    if (m.n_series < MIN_SERIES) {
        snprintf(rep->note, sizeof rep->note, "%d series with a code in 1-249: too few, not refined",
                 m.n_series);
        goto done;
    }
    /* start: the fitted curve's edges (mean of neighbouring codes) */
    const double *inv = resp->inverse + 1 * resp->nodes; /* one curve for the three */
    for (int j = 0; j < EDGES; j++)
        x[j] = log(fmax(0.5 * (inv[j] + inv[j + 1]), 1e-9));
    for (int c = 0; c < 3; c++)
        x[EDGES + c] = log(1e-3), x[EDGES + 3 + c] = log(3e-6);
    project(x);
    memcpy(x0, x, PARAMS * sizeof *x0);
    if (!y_from_x(&B, x, y)) {
        snprintf(rep->note, sizeof rep->note, "start curve not representable: not refined");
        goto done;
    }
    x_from_y(&B, y, x);
    for (int pass = 0; pass < 4 && !admissible(x); pass++) {
        /* the spline of a kinked start folds: made increasing, refitted */
        project(x);
        y_from_x(&B, x, y);
        x_from_y(&B, y, x);
    }
    if (!admissible(x)) {
        /* still folding: spline coefficients made increasing (a B-spline
         * with increasing coefficients increases), the free edges below */
        for (int k = 1; k < SPLINE; k++)
            y[k] = fmax(y[k], y[k - 1] + MIN_GAP);
        x_from_y(&B, y, x);
        for (int j = FREE_EDGES - 1; j >= 0; j--)
            y[SPLINE + j] = fmin(y[SPLINE + j], x[j + 1] - MIN_GAP);
        x_from_y(&B, y, x);
    }
    if (!admissible(x)) {
        snprintf(rep->note, sizeof rep->note,
                 "not refined: the first curve bends where the spline cannot follow");
        goto done;
    }
    place_windows(&m, x);
    if (!update_density(&m, x) || !update_density(&m, x)) {
        result = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        goto done;
    }
    /* the noise first, the curve held: its start is far off */
    for (int k = 0; k < NY; k++)
        active[k] = k >= SPLINE + FREE_EDGES;
    int steps = 0;
    rep->start_loglik = climb(&m, &B, y, active, 30, 0.01, &steps);
    for (int k = 0; k < NY; k++)
        active[k] = k != SPLINE - 1; /* the last spline coefficient: the scale */
    double F = rep->start_loglik;
    for (int round = 0; round < ROUNDS; round++) {
        x_from_y(&B, y, x);
        place_windows(&m, x);
        if (!update_density(&m, x)) {
            result = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
            goto done;
        }
        double Fr = climb(&m, &B, y, active, 50, 0.01, &steps);
        bool settled = round > 2 && fabs(Fr - F) < 0.5;
        F = Fr;
        if (settled)
            break;
    }
    x_from_y(&B, y, x);
    rep->loglik = F;
    rep->steps = steps;
    if (steps == 0) {
        snprintf(rep->note, sizeof rep->note, "not refined: no step made the frames likelier");
        goto done;
    }
    bool used[3] = {false, false, false};
    for (int i = 0; i < m.n_series; i++)
        used[m.series[i].channel] = true;
    for (int c = 0; c < 3; c++) { /* 0: that channel's series were not read */
        rep->noise_gain[c] = used[c] ? exp(x[EDGES + c]) : 0;
        rep->noise_floor[c] = used[c] ? exp(x[EDGES + 3 + c]) : 0;
    }
    /* The refined curve stands only where the frames find it likelier than
     * the first, both under the fitted noise and scene (their windows each
     * its own): a fit that wandered keeps the first curve, and says so. */
    memcpy(x0 + EDGES, x + EDGES, 6 * sizeof *x0);
    place_windows(&m, x0);
    double F_first = evaluate(&m, x0, NULL, NULL);
    place_windows(&m, x);
    double F_refined = evaluate(&m, x, NULL, NULL);
    rep->start_loglik = F_first;
    rep->loglik = F_refined;
    if (!(F_refined > F_first + 1)) {
        snprintf(rep->note, sizeof rep->note,
                 "not refined: the frames find it no likelier than the first (%+.1f nats)",
                 F_refined - F_first);
        goto done;
    }
    /* the refined inverse at codes: the geometric mean of a code's edges;
     * code 0 and codes TOP - 1 up keep the start curve's shape beyond them */
    int nodes = resp->nodes;
    out = malloc((size_t)3 * nodes * sizeof *out);
    if (!out) {
        result = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        goto done;
    }
    for (int k = 1; k < TOP - 1; k++)
        out[k] = exp(0.5 * (x[k - 1] + x[k]));
    out[0] = out[1] * inv[0] / fmax(inv[1], 1e-12);
    for (int k = TOP - 1; k < nodes; k++)
        out[k] = out[TOP - 2] * inv[k] / fmax(inv[TOP - 2], 1e-12);
    double moved = 0;
    for (int k = MOVE_FROM; k < TOP - 1; k++) /* the toe's codes say little: left out */
        moved = fmax(moved, fabs(log(out[k] / out[TOP - 2]) - log(inv[k] / inv[TOP - 2])));
    rep->moved = moved;
    if (!(moved < MAX_MOVE)) {
        snprintf(rep->note, sizeof rep->note,
                 "not refined: it moved the curve by %.0f%% (more than %.0f%%)",
                 100 * (exp(moved) - 1), 100 * (exp(MAX_MOVE) - 1));
        goto done;
    }
    rep->refined = true;
    snprintf(rep->note, sizeof rep->note, "refined under the noise: %d series, %d steps",
             m.n_series, steps);
    sl_response refined;
    merge_response_finish(out, nodes, resp->source, &refined);
    out = NULL;
    sl_response_free(resp);
    *resp = refined;
done:
    free(out);
    for (int c = 0; c < 3; c++)
        free(m.dens[c]);
    free(B.x_of_y);
    free(m.series);
    free(m.obs);
    free(m.H);
    free(m.work);
    free(m.M);
    free(x);
    free(x0);
    free(y);
    free(active);
    return result;
}
