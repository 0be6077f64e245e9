/* SPDX-License-Identifier: BSD-3-Clause */
/* Writes render/energy_tables.c, the directional-albedo tables for the
 * Kulla-Conty compensation and the diffuse-under-coat lobe. Deterministic
 * (OpenMP only spreads independent quadratures over the cores).
 *   cc -O2 -std=c11 -fopenmp -Iinclude -Irender scripts/gen_energy_tables.c \
 *      render/energy_integrate.c render/fresnel.c render/microfacet.c -lm \
 *      -o /tmp/gen && /tmp/gen > render/energy_tables.c
 * tests/test_furnace.c recomputes entries and fails when the tables are stale. */
#include <math.h>
#include <stdio.h>

#include "energy.h"

#define K 128

typedef double slab[SL_E_NR][SL_E_NMU];

/* Fills one (roughness x mu) slab, then raises nodes so that the bilinear
 * interpolant is at least the true E at every cell centre. Compensation adds
 * 1 - E, so a table that errs high loses a little energy instead of creating
 * it; the averages are taken afterwards and stay exact for the interpolant. */
static double value(double mu, double r, double ior, double phi, double aniso)
{
    return aniso > 0.0 ? sl_energy_integrate_aniso(mu, phi, r, aniso, K)
                       : sl_energy_integrate(mu, r, ior, K);
}

static void fill(double ior, double phi, double aniso, slab e)
{
    static slab bump, centre;
#pragma omp parallel for collapse(2) schedule(dynamic)
    for (int j = 0; j < SL_E_NR; j++)
        for (int i = 0; i < SL_E_NMU; i++) {
            e[j][i] = value(sl_energy_mu_node(i), sl_energy_r_node(j), ior, phi, aniso);
            bump[j][i] = 0.0;
            if (j + 1 < SL_E_NR && i + 1 < SL_E_NMU)
                centre[j][i] = value(0.5 * (sl_energy_mu_node(i) + sl_energy_mu_node(i + 1)),
                                     0.5 * (sl_energy_r_node(j) + sl_energy_r_node(j + 1)), ior,
                                     phi, aniso);
        }
    for (int j = 0; j + 1 < SL_E_NR; j++)
        for (int i = 0; i + 1 < SL_E_NMU; i++) {
            double lerp = 0.25 * (e[j][i] + e[j][i + 1] + e[j + 1][i] + e[j + 1][i + 1]);
            double d = centre[j][i] - lerp;
            for (int a = 0; a < 2; a++)
                for (int b = 0; b < 2; b++)
                    bump[j + a][i + b] = fmax(bump[j + a][i + b], d);
        }
    for (int j = 0; j < SL_E_NR; j++)
        for (int i = 0; i < SL_E_NMU; i++)
            e[j][i] = fmin(e[j][i] + bump[j][i], 1.0);
}

/* The same bound across the index: the trilinear interpolant must reach the
 * true E at every (t, r, mu) cell centre. Slab t = 0 stays 0 (no interface),
 * so a cell touching it raises its other four corners twice as much. */
static void bound_in_t(slab ed[SL_E_NT])
{
    static slab bump[SL_E_NT], centre[SL_E_NT];
#pragma omp parallel for collapse(2) schedule(dynamic)
    for (int k = 0; k < SL_E_NT - 1; k++)
        for (int j = 0; j < SL_E_NR - 1; j++) {
            double t = 0.5 * (sl_energy_t_node(k) + sl_energy_t_node(k + 1));
            double ior = (1.0 + t) / (1.0 - t);
            double r = 0.5 * (sl_energy_r_node(j) + sl_energy_r_node(j + 1));
            for (int i = 0; i + 1 < SL_E_NMU; i++)
                centre[k][j][i] = sl_energy_integrate(
                    0.5 * (sl_energy_mu_node(i) + sl_energy_mu_node(i + 1)), r, ior, K);
        }
    for (int k = 0; k + 1 < SL_E_NT; k++) {
        for (int j = 0; j + 1 < SL_E_NR; j++)
            for (int i = 0; i + 1 < SL_E_NMU; i++) {
                double lerp = 0.0;
                for (int c = 0; c < 8; c++)
                    lerp += ed[k + (c >> 2)][j + ((c >> 1) & 1)][i + (c & 1)] / 8.0;
                double d = centre[k][j][i] - lerp;
                for (int c = 0; c < 8; c++) {
                    int kk = k + (c >> 2);
                    if (kk == 0)
                        continue;
                    double *b = &bump[kk][j + ((c >> 1) & 1)][i + (c & 1)];
                    *b = fmax(*b, k == 0 ? 2.0 * d : d);
                }
            }
    }
    for (int k = 1; k < SL_E_NT; k++)
        for (int j = 0; j < SL_E_NR; j++)
            for (int i = 0; i < SL_E_NMU; i++)
                ed[k][j][i] = fmin(ed[k][j][i] + bump[k][j][i], 1.0);
}

/* The same bound across anisotropy and azimuth (4-linear cells). The
 * isotropic table at y = 0 is shared and stays, so a cell touching it raises
 * its other corners twice as much. */
static void bound_in_a(slab e1, slab ea[SL_E_NA][SL_E_NPHI])
{
    static slab bump[SL_E_NA][SL_E_NPHI], centre[SL_E_NA][SL_E_NPHI];
    /* Cell (n, m, j, i) spans the anisotropy axis nodes n and n + 1 (node 0
     * is the isotropic table, node n >= 1 the slab n - 1). */
#pragma omp parallel for collapse(3) schedule(dynamic)
    for (int n = 0; n < SL_E_NA; n++)
        for (int m = 0; m < SL_E_NPHI - 1; m++)
            for (int j = 0; j < SL_E_NR - 1; j++) {
                double yc = 0.5 * (sl_energy_a_axis_y(n) + sl_energy_a_axis_y(n + 1));
                double aspect = 1.0 / (1.0 + yc), a = (1.0 - aspect * aspect) / 0.9;
                double phi = 0.5 * (sl_energy_phi_node(m) + sl_energy_phi_node(m + 1));
                double r = 0.5 * (sl_energy_r_node(j) + sl_energy_r_node(j + 1));
                for (int i = 0; i + 1 < SL_E_NMU; i++) {
                    double mu = 0.5 * (sl_energy_mu_node(i) + sl_energy_mu_node(i + 1));
                    centre[n][m][j][i] = value(mu, r, 0.0, phi, a);
                }
            }
    for (int n = 0; n < SL_E_NA; n++)
        for (int m = 0; m < SL_E_NPHI - 1; m++)
            for (int j = 0; j + 1 < SL_E_NR; j++)
                for (int i = 0; i + 1 < SL_E_NMU; i++) {
                    double lerp = 0.0;
                    for (int c = 0; c < 16; c++) {
                        int ll = n - 1 + (c >> 3), mm = m + ((c >> 2) & 1);
                        int jj = j + ((c >> 1) & 1), ii = i + (c & 1);
                        lerp += (ll < 0 ? e1[jj][ii] : ea[ll][mm][jj][ii]) / 16.0;
                    }
                    double d = centre[n][m][j][i] - lerp;
                    for (int c = 0; c < 16; c++) {
                        int ll = n - 1 + (c >> 3);
                        if (ll < 0)
                            continue;
                        double *b = &bump[ll][m + ((c >> 2) & 1)][j + ((c >> 1) & 1)][i + (c & 1)];
                        *b = fmax(*b, n == 0 ? 2.0 * d : d);
                    }
                }
    for (int l = 0; l < SL_E_NA; l++)
        for (int m = 0; m < SL_E_NPHI; m++)
            for (int j = 0; j < SL_E_NR; j++)
                for (int i = 0; i < SL_E_NMU; i++)
                    ea[l][m][j][i] = fmin(ea[l][m][j][i] + bump[l][m][j][i], 1.0);
}

static void print_slab(slab e)
{
    for (int j = 0; j < SL_E_NR; j++) {
        printf("{");
        for (int i = 0; i < SL_E_NMU; i++)
            printf("%s%.8ef", i ? (i % 6 ? ", " : ",\n  ") : "", e[j][i]);
        printf("},\n");
    }
}

int main(void)
{
    static slab e1, ed[SL_E_NT], ea[SL_E_NA][SL_E_NPHI];
    printf("/* SPDX-License-Identifier: BSD-3-Clause */\n"
           "/* Generated by scripts/gen_energy_tables.c (%d x %d stratified VNDF samples per\n"
           " * entry, nodes raised to bound the interpolant from above); do not edit. */\n"
           "#include \"energy.h\"\n\n", K, K);
    fill(0.0, 0.0, 0.0, e1);
    printf("const float sl_energy_e1_table[SL_E_NR][SL_E_NMU] = {\n");
    print_slab(e1);
    printf("};\n\nconst float sl_energy_e1_avg_table[SL_E_NR] = {\n");
    for (int j = 0; j < SL_E_NR; j++)
        printf("%.8ef,%s", sl_energy_average(e1[j]), j % 6 == 5 ? "\n" : " ");
    printf("};\n\nconst float sl_energy_ed_table[SL_E_NT][SL_E_NR][SL_E_NMU] = {\n");
    for (int k = 0; k < SL_E_NT; k++) {
        if (k == 0) {
            for (int j = 0; j < SL_E_NR; j++)
                for (int i = 0; i < SL_E_NMU; i++)
                    ed[k][j][i] = 0.0; /* index 1: no interface, no reflection */
        } else {
            fill(sl_energy_t_ior(k), 0.0, 0.0, ed[k]);
        }
    }
    bound_in_t(ed);
    for (int k = 0; k < SL_E_NT; k++) {
        printf("{\n");
        print_slab(ed[k]);
        printf("},\n");
    }
    printf("};\n\nconst float sl_energy_ed_avg_table[SL_E_NT][SL_E_NR] = {\n");
    for (int k = 0; k < SL_E_NT; k++) {
        printf("{");
        for (int j = 0; j < SL_E_NR; j++)
            printf("%.8ef,%s", sl_energy_average(ed[k][j]), j % 6 == 5 ? "\n" : " ");
        printf("},\n");
    }
    for (int l = 0; l < SL_E_NA; l++)
        for (int m = 0; m < SL_E_NPHI; m++)
            fill(0.0, sl_energy_phi_node(m), sl_energy_a_node(l), ea[l][m]);
    bound_in_a(e1, ea);
    printf("};\n\nconst float sl_energy_ea_table[SL_E_NA][SL_E_NPHI][SL_E_NR][SL_E_NMU] = {\n");
    for (int l = 0; l < SL_E_NA; l++) {
        printf("{\n");
        for (int m = 0; m < SL_E_NPHI; m++) {
            printf("{\n");
            print_slab(ea[l][m]);
            printf("},\n");
        }
        printf("},\n");
    }
    /* Trapezoid over the azimuth nodes: exact for the piecewise-linear interpolant. */
    printf("};\n\nconst float sl_energy_ea_avg_table[SL_E_NA][SL_E_NR] = {\n");
    for (int l = 0; l < SL_E_NA; l++) {
        printf("{");
        for (int j = 0; j < SL_E_NR; j++) {
            double avg = 0.0;
            for (int m = 0; m < SL_E_NPHI; m++)
                avg += (m == 0 || m == SL_E_NPHI - 1 ? 0.5 : 1.0) * sl_energy_average(ea[l][m][j]);
            printf("%.8ef,%s", avg / (SL_E_NPHI - 1), j % 6 == 5 ? "\n" : " ");
        }
        printf("},\n");
    }
    printf("};\n");
    return 0;
}
