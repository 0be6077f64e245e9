/* SPDX-License-Identifier: BSD-3-Clause */
/* Fresnel terms. The exact conductor formula is core's (shared with the
 * unwrap); the artist mapping is Gulbrandsen, "Artist Friendly Metallic
 * Fresnel", JCGT 3(4) 2014. */
#include "fresnel.h"

#include <math.h>

/* Reflectances this close to 1 are a perfect reflector (Gulbrandsen's n_max
 * diverges at r = 1). */
#define SL_R_MAX (1.0 - 1e-9)

double sl_fresnel_schlick(double f0, double cos_i)
{
    double m = fmin(fmax(1.0 - cos_i, 0.0), 1.0);
    double m2 = m * m;
    return f0 + (1.0 - f0) * m2 * m2 * m;
}

double sl_fresnel_dielectric(double cos_i, double eta)
{
    cos_i = fmin(fmax(cos_i, 0.0), 1.0);
    double sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0)
        return 1.0;
    double cos_t = sqrt(1.0 - sin2_t);
    double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

void sl_fresnel_artist_nk(double r, double g, double *n, double *k)
{
    r = fmin(fmax(r, 0.0), 0.9999);
    g = fmin(fmax(g, 0.0), 1.0);
    double sr = sqrt(r);
    double n_min = (1.0 - r) / (1.0 + r);
    double n_max = (1.0 + sr) / (1.0 - sr);
    *n = g * n_min + (1.0 - g) * n_max;
    double k2 = (r * (*n + 1.0) * (*n + 1.0) - (*n - 1.0) * (*n - 1.0)) / (1.0 - r);
    *k = sqrt(fmax(0.0, k2));
}

/* The artist mapping per channel, kept per thread for the last material:
 * it is evaluated with every conductor BSDF value (same bytes). */
typedef struct nk_memo {
    bool valid;
    double r, g, n, k;
} nk_memo;

static void artist_nk_memo(int c, double r, double g, double *n, double *k)
{
    static _Thread_local nk_memo memo[3];
    nk_memo *e = &memo[c];
    if (!e->valid || e->r != r || e->g != g) {
        sl_fresnel_artist_nk(r, g, &e->n, &e->k);
        e->r = r, e->g = g, e->valid = true;
    }
    *n = e->n, *k = e->k;
}

void sl_fresnel_eval(const sl_material *m, double cos_i, double f[3])
{
    for (int c = 0; c < 3; c++) {
        switch (m->fresnel) {
        case SL_FRESNEL_SCHLICK:
            f[c] = sl_fresnel_schlick(m->base_color[c], cos_i);
            break;
        case SL_FRESNEL_ARTIST:
            if (m->base_color[c] >= SL_R_MAX) {
                f[c] = 1.0;
            } else {
                double n, k;
                artist_nk_memo(c, m->base_color[c], m->edge_tint[c], &n, &k);
                f[c] = sl_fresnel_conductor(cos_i, n, k);
            }
            break;
        case SL_FRESNEL_DIELECTRIC:
            f[c] = sl_fresnel_dielectric(cos_i, m->ior);
            break;
        default:
            f[c] = 1.0;
            break;
        }
    }
}

/* The quadrature costs 24 conductor evaluations and every compensated
 * BSDF evaluation needs it: each thread keeps the last material's answer. */
typedef struct favg_memo {
    bool valid;
    sl_fresnel_mode fresnel;
    double base_color[3], edge_tint[3], ior, favg[3];
} favg_memo;

static bool memo_matches(const favg_memo *c, const sl_material *m)
{
    if (!c->valid || c->fresnel != m->fresnel || c->ior != m->ior)
        return false;
    for (int i = 0; i < 3; i++)
        if (c->base_color[i] != m->base_color[i] || c->edge_tint[i] != m->edge_tint[i])
            return false;
    return true;
}

void sl_fresnel_average(const sl_material *m, double favg[3])
{
    if (m->fresnel == SL_FRESNEL_ONE) {
        favg[0] = favg[1] = favg[2] = 1.0;
        return;
    }
    if (m->fresnel == SL_FRESNEL_SCHLICK) {
        /* 2 int (F0 + (1-F0)(1-mu)^5) mu dmu = F0 + (1-F0)/21 */
        for (int c = 0; c < 3; c++)
            favg[c] = m->base_color[c] + (1.0 - m->base_color[c]) / 21.0;
        return;
    }
    static _Thread_local favg_memo memo;
    if (memo_matches(&memo, m)) {
        for (int c = 0; c < 3; c++)
            favg[c] = memo.favg[c];
        return;
    }
    /* 8-point Gauss-Legendre on [0, 1]: F is smooth, error below 1e-4 (tested). */
    static const double x[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267,
                                0.9602898564975363};
    static const double w[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745,
                                0.1012285362903763};
    favg[0] = favg[1] = favg[2] = 0.0;
    for (int i = 0; i < 8; i++) {
        double mu = 0.5 + 0.5 * (i < 4 ? -x[3 - i] : x[i - 4]);
        double wt = 0.5 * (i < 4 ? w[3 - i] : w[i - 4]);
        double f[3];
        sl_fresnel_eval(m, mu, f);
        for (int c = 0; c < 3; c++)
            favg[c] += 2.0 * wt * f[c] * mu;
    }
    memo.valid = true;
    memo.fresnel = m->fresnel;
    memo.ior = m->ior;
    for (int c = 0; c < 3; c++) {
        memo.base_color[c] = m->base_color[c];
        memo.edge_tint[c] = m->edge_tint[c];
        memo.favg[c] = favg[c];
    }
}
