/* SPDX-License-Identifier: BSD-3-Clause */
/* White furnace thresholds, the energy tables, and BSDF stability at extreme
 * roughness, incidence and index. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../render/energy.h"
#include "setlight/render.h"
#include "testing.h"

static sl_furnace furnace;

typedef struct range {
    double lo, hi;
} range;

static range family_range(const char *bsdf, bool comp)
{
    range r = {INFINITY, -INFINITY};
    for (int i = 0; i < furnace.count; i++) {
        const sl_furnace_case *k = &furnace.cases[i];
        if (strcmp(k->bsdf, bsdf) || k->compensated != comp)
            continue;
        r.lo = fmin(r.lo, k->albedo);
        r.hi = fmax(r.hi, k->albedo);
    }
    printf("  %-16s %-15s albedo %.4f .. %.4f\n", bsdf, comp ? "compensated" : "uncompensated",
           r.lo, r.hi);
    return r;
}

static void test_furnace_thresholds(void)
{
    sl_error err;
    CHECK_OK(sl_furnace_run(4096, &furnace, &err), &err);
    CHECK(furnace.count == 2 * 9 + 3 * 2 * 11 * 9);

    range r = family_range("lambert", true);
    CHECK(r.lo >= 0.995 && r.hi <= 1.005);
    r = family_range("conductor", true);
    CHECK(r.lo >= 0.99 && r.hi <= 1.01);
    r = family_range("conductor", false);
    CHECK(r.hi <= 1.0005);
    r = family_range("plastic", true);
    CHECK(r.lo >= 0.99);
    /* Never above 1 beyond the error of 4096-sample quadrature (see the
     * high-precision check below). */
    CHECK(r.hi <= 1.001);
    r = family_range("plastic", false);
    CHECK(r.hi <= 1.0);
    r = family_range("conductor_aniso", true);
    CHECK(r.lo >= 0.99 && r.hi <= 1.01);
    family_range("conductor_aniso", false);
    for (int i = 0; i < furnace.count; i++)
        CHECK(furnace.cases[i].expected == 1.0 && isfinite(furnace.cases[i].albedo));

    /* The cases nearest 1 from above, again with 65536 samples: the excess is
     * quadrature error, the tables bound E from above. */
    static const double one[3] = {1, 1, 1};
    static const double hot[][3] = {{0, 0.8, 0.2}, {0, 0.1, 0.05}, {1, 0.1, 1.0}, {1, 0.1, 0.05},
                                    {1, 0.3, 0.35}};
    for (int i = 0; i < 5; i++) {
        sl_material m;
        if (hot[i][0] == 0) {
            sl_material_conductor(&m, one, one, hot[i][1]);
            m.fresnel = SL_FRESNEL_ONE;
        } else {
            sl_material_plastic(&m, one, 1.5, hot[i][1]);
        }
        double a[3];
        sl_bsdf_albedo(&m, hot[i][2], 65536, a);
        CHECK_MSG(a[0] <= 1.0002, "%s roughness %.1f cos %.2f: albedo %.5f",
                  hot[i][0] == 0 ? "conductor" : "plastic", hot[i][1], hot[i][2], a[0]);
    }
}

/* Without compensation a white GGX conductor at roughness 1 loses about 60%
 * of the energy averaged over incidence (Kulla & Conty 2017, slide "energy
 * loss"), 69% at normal incidence. */
static void test_uncompensated_loss(void)
{
    sl_material m;
    static const double one[3] = {1, 1, 1};
    sl_material_conductor(&m, one, one, 1.0);
    m.fresnel = SL_FRESNEL_ONE;
    m.compensate = false;
    double avg = 0.0, a[3];
    const int n = 64;
    for (int i = 0; i < n; i++) {
        /* 2 int a(mu) mu dmu, midpoint rule in mu^2. */
        double mu = sqrt((i + 0.5) / n);
        sl_bsdf_albedo(&m, mu, 4096, a);
        avg += a[1] / n;
    }
    printf("  roughness 1, uncompensated: average loss %.1f%%\n", 100.0 * (1.0 - avg));
    CHECK(1.0 - avg > 0.55 && 1.0 - avg < 0.65);
    CHECK_NEAR(avg, sl_energy_e1_avg(1.0), 0.002);
    sl_bsdf_albedo(&m, 1.0, 4096, a);
    CHECK_NEAR(a[0], 0.307, 0.003);
}

/* One node as scripts/gen_energy_tables.c makes it: the quadrature value
 * raised by the largest shortfall of the bilinear interpolant at the centres
 * of the cells around it, capped at 1. */
static double node_value(double ior, int j, int i)
{
    double raw[3][3] = {{0}};
    for (int a = -1; a <= 1; a++)
        for (int b = -1; b <= 1; b++)
            if (j + a >= 0 && j + a < SL_E_NR && i + b >= 0 && i + b < SL_E_NMU)
                raw[a + 1][b + 1] = sl_energy_integrate(sl_energy_mu_node(i + b),
                                                        sl_energy_r_node(j + a), ior, 128);
    double bump = 0.0;
    for (int cj = j - 1; cj <= j; cj++)
        for (int ci = i - 1; ci <= i; ci++) {
            if (cj < 0 || ci < 0 || cj + 1 >= SL_E_NR || ci + 1 >= SL_E_NMU)
                continue;
            double mu = 0.5 * (sl_energy_mu_node(ci) + sl_energy_mu_node(ci + 1));
            double r = 0.5 * (sl_energy_r_node(cj) + sl_energy_r_node(cj + 1));
            int a = cj - j + 1, b = ci - i + 1;
            double lerp = 0.25 * (raw[a][b] + raw[a][b + 1] + raw[a + 1][b] + raw[a + 1][b + 1]);
            bump = fmax(bump, sl_energy_integrate(mu, r, ior, 128) - lerp);
        }
    return fmin(raw[1][1] + bump, 1.0);
}

/* The committed tables must be what scripts/gen_energy_tables.c makes. */
static void test_tables_current(void)
{
    static const int e1_at[][2] = {{0, 0}, {5, 3}, {20, 10}, {31, 31}, {12, 27}};
    for (int i = 0; i < 5; i++) {
        int j = e1_at[i][0], mu = e1_at[i][1];
        CHECK_NEAR(sl_energy_e1_table[j][mu], node_value(0.0, j, mu), 1e-6);
    }
    /* Anisotropic tables: also raised across anisotropy and azimuth, so check
     * the guarantees: nodes never below the quadrature, centres of the 4-D cells
     * never below the true E. */
    static const int ea_at[][4] = {{0, 0, 10, 5}, {3, 4, 31, 31}, {2, 1, 20, 3}};
    for (int i = 0; i < 3; i++) {
        int l = ea_at[i][0], m = ea_at[i][1], j = ea_at[i][2], mu = ea_at[i][3];
        double raw = sl_energy_integrate_aniso(sl_energy_mu_node(mu), sl_energy_phi_node(m),
                                               sl_energy_r_node(j), sl_energy_a_node(l), 128);
        CHECK(sl_energy_ea_table[l][m][j][mu] >= raw - 1e-6);
        CHECK(sl_energy_ea_table[l][m][j][mu] <= fmax(raw + 0.1, 1.0));
    }
    static const int ea_cells[][4] = {{-1, 0, 20, 25}, {0, 3, 25, 12}, {2, 1, 12, 28}};
    for (int i = 0; i < 3; i++) {
        int l = ea_cells[i][0], m = ea_cells[i][1], j = ea_cells[i][2], mu = ea_cells[i][3];
        double ya = l < 0 ? 0.0 : sl_energy_a_y(sl_energy_a_node(l));
        double yc = 0.5 * (ya + sl_energy_a_y(sl_energy_a_node(l + 1)));
        double aspect = 1.0 / (1.0 + yc), a = (1.0 - aspect * aspect) / 0.9;
        double phi = 0.5 * (sl_energy_phi_node(m) + sl_energy_phi_node(m + 1));
        double mc = 0.5 * (sl_energy_mu_node(mu) + sl_energy_mu_node(mu + 1));
        double r = 0.5 * (sl_energy_r_node(j) + sl_energy_r_node(j + 1));
        CHECK(sl_energy_ea(mc, phi, r, a) >= sl_energy_integrate_aniso(mc, phi, r, a, 128) - 1e-6);
    }
    /* The anisotropic average is the trapezoid over azimuth of the row averages. */
    double avg = 0.0, rowa[SL_E_NMU];
    for (int m = 0; m < SL_E_NPHI; m++) {
        for (int i = 0; i < SL_E_NMU; i++)
            rowa[i] = sl_energy_ea_table[1][m][13][i];
        avg += (m == 0 || m == SL_E_NPHI - 1 ? 0.5 : 1.0) * sl_energy_average(rowa);
    }
    CHECK_NEAR(sl_energy_ea_avg_table[1][13], avg / (SL_E_NPHI - 1), 1e-6);
    CHECK_NEAR(sl_energy_a_node(SL_E_NA - 1), 1.0, 1e-12);
    CHECK_NEAR(sl_energy_ea(0.3, 0.2, 0.5, 0.0), sl_energy_e1(0.3, 0.5), 1e-12);
    /* The coat table is also raised across the index (trilinear cells), so
     * check what that guarantees: nodes never below the quadrature, cell
     * centres never below the true E (away from the cap at 1), slab t = 0 zero. */
    static const int ed_at[][3] = {{3, 10, 5}, {1, 31, 31}, {9, 2, 17}, {18, 20, 1}};
    for (int i = 0; i < 4; i++) {
        int t = ed_at[i][0], j = ed_at[i][1], mu = ed_at[i][2];
        double raw = sl_energy_integrate(sl_energy_mu_node(mu), sl_energy_r_node(j),
                                         sl_energy_t_ior(t), 128);
        CHECK(sl_energy_ed_table[t][j][mu] >= raw - 1e-6);
        CHECK(sl_energy_ed_table[t][j][mu] <= fmax(raw + 0.3, 1.0));
    }
    static const int cells[][3] = {{0, 9, 4}, {3, 12, 20}, {9, 5, 2}, {10, 20, 8}, {18, 28, 30}};
    for (int i = 0; i < 5; i++) {
        int t = cells[i][0], j = cells[i][1], mu = cells[i][2];
        double tc = 0.5 * (sl_energy_t_node(t) + sl_energy_t_node(t + 1));
        double ior = (1.0 + tc) / (1.0 - tc);
        double m = 0.5 * (sl_energy_mu_node(mu) + sl_energy_mu_node(mu + 1));
        double r = 0.5 * (sl_energy_r_node(j) + sl_energy_r_node(j + 1));
        CHECK(sl_energy_ed(m, r, ior) >= sl_energy_integrate(m, r, ior, 128) - 1e-6);
    }
    for (int j = 0; j < SL_E_NR; j++)
        CHECK(sl_energy_ed_table[0][j][SL_E_NMU / 2] == 0.0f);
    /* Averages are exact for the interpolant: check one against the rows. */
    double row[SL_E_NMU];
    for (int i = 0; i < SL_E_NMU; i++)
        row[i] = sl_energy_e1_table[17][i];
    CHECK_NEAR(sl_energy_e1_avg_table[17], sl_energy_average(row), 1e-6);
    /* Interpolation reproduces the nodes. */
    CHECK_NEAR(sl_energy_e1(sl_energy_mu_node(7), sl_energy_r_node(11)),
               sl_energy_e1_table[11][7], 1e-7);
    /* Known limits: a mirror reflects all (F = 1), no interface reflects nothing. */
    CHECK_NEAR(sl_energy_e1(0.5, 0.0), 1.0, 1e-7);
    CHECK_NEAR(sl_energy_ed(0.5, 0.5, 1.0), 0.0, 1e-7);
    double e_smooth = sl_energy_ed(1.0, 0.0, 1.5); /* raised a little, never below */
    CHECK(e_smooth >= 0.04 && e_smooth < 0.042);
}

/* Interpolated E against direct quadrature off the nodes. */
static void test_table_accuracy(void)
{
    double worst = 0.0;
    for (int j = 0; j < 8; j++)
        for (int i = 0; i < 8; i++) {
            double r = 0.1 + 0.9 * (j + 0.37) / 8.0, mu = 0.01 + 0.99 * (i + 0.61) / 8.0;
            double d1 = fabs(sl_energy_integrate(mu, r, 0.0, 48) - sl_energy_e1(mu, r));
            double dd = fabs(sl_energy_integrate(mu, r, 1.5, 48) - sl_energy_ed(mu, r, 1.5));
            worst = fmax(worst, fmax(d1, dd));
        }
    printf("  table interpolation, roughness >= 0.1, mu >= 0.01: worst |dE| = %.5f\n", worst);
    /* Cell centres are bounded from above by construction, except where the
     * cap at E = 1 bites (roughness below ~0.03 at grazing). */
    for (int j = 5; j < SL_E_NR - 1; j += 6)
        for (int i = 2; i < SL_E_NMU - 1; i += 9) {
            double mu = 0.5 * (sl_energy_mu_node(i) + sl_energy_mu_node(i + 1));
            double r = 0.5 * (sl_energy_r_node(j) + sl_energy_r_node(j + 1));
            CHECK(sl_energy_e1(mu, r) >= sl_energy_integrate(mu, r, 0.0, 128) - 1e-6);
            CHECK(sl_energy_ed(mu, r, 1.5) >= sl_energy_integrate(mu, r, 1.5, 128) - 1e-6);
        }
    CHECK(worst < 0.003);
}

static bool finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* No NaN/Inf and bounded values at roughness 0 ... 1, grazing 1e-6 and index
 * 1.0001 ... 400, for every material type, with and without compensation. */
static void test_stability(void)
{
    static const double rough[] = {0.0, 1e-7, 1e-4, 1e-2, 1.0};
    static const double coss[] = {1e-6, 1e-3, 0.5, 1.0};
    static const double iors[] = {1.0001, 1.5, 400.0};
    static const double col[3] = {0.9, 0.5, 0.1};
    int bad = 0, cases = 0;
    double max_albedo = 0.0;
    for (int t = 0; t < SL_MAT_COUNT; t++)
        for (int r = 0; r < 5; r++)
            for (int q = 0; q < 3; q++)
                for (int an = 0; an < 2; an++)
                    for (int comp = 0; comp < 2; comp++) {
                        sl_material m;
                        if (t == SL_MAT_LAMBERT)
                            sl_material_lambert(&m, col[0], col[1], col[2]);
                        else if (t == SL_MAT_CONDUCTOR)
                            sl_material_conductor(&m, col, col, rough[r]);
                        else
                            sl_material_plastic(&m, col, iors[q], rough[r]);
                        if (t == SL_MAT_CONDUCTOR && q > 0) {
                            m.fresnel = SL_FRESNEL_DIELECTRIC;
                            m.ior = iors[q];
                        }
                        m.anisotropy = an ? 0.9 : 0.0;
                        m.compensate = comp;
                        CHECK_OK(sl_material_check(&m, NULL), NULL);
                        for (int a = 0; a < 4; a++) {
                            double so = sqrt(1.0 - coss[a] * coss[a]);
                            double wo[3] = {so * 0.6, so * 0.8, coss[a]};
                            for (int b = 0; b < 4; b++) {
                                double si = sqrt(1.0 - coss[b] * coss[b]);
                                double wi[3] = {-si, 0.0, coss[b]}, f[3];
                                sl_bsdf_eval(&m, wo, wi, f);
                                double p = sl_bsdf_pdf(&m, wo, wi);
                                cases++;
                                if (!finite3(f) || f[0] < 0 || f[1] < 0 || f[2] < 0 ||
                                    !isfinite(p) || p < 0)
                                    bad++;
                            }
                            for (int k = 0; k < 16; k++) {
                                double u[3] = {(k + 0.5) / 16, fmod(0.618 * k, 1.0),
                                               fmod(0.5 + 0.382 * k, 1.0)};
                                sl_bsdf_sample_rec s;
                                cases++;
                                if (sl_bsdf_sample(&m, wo, u, &s) &&
                                    (!finite3(s.wi) || !finite3(s.f) || !isfinite(s.pdf) ||
                                     !(s.pdf > 0) || s.wi[2] <= 0 ||
                                     fabs(s.wi[0] * s.wi[0] + s.wi[1] * s.wi[1] +
                                          s.wi[2] * s.wi[2] - 1.0) > 1e-9))
                                    bad++;
                            }
                            double al[3];
                            sl_bsdf_albedo(&m, coss[a], 256, al);
                            cases++;
                            if (!finite3(al) || al[0] < 0)
                                bad++;
                            else
                                max_albedo = fmax(max_albedo, fmax(al[0], fmax(al[1], al[2])));
                        }
                    }
    printf("  stability: %d evaluations, %d bad, largest albedo %.3f\n", cases, bad,
           max_albedo);
    CHECK(bad == 0);
    CHECK(max_albedo < 2.0);
}

static void test_furnace_json(void)
{
    char *text = NULL;
    sl_error err;
    CHECK_OK(sl_furnace_json(&furnace, &text, &err), &err);
    json_error_t jerr;
    json_t *root = text ? json_loads(text, 0, &jerr) : NULL;
    CHECK(root != NULL);
    json_t *cases = json_object_get(root, "cases");
    CHECK(json_is_array(cases) && (int)json_array_size(cases) == furnace.count);
    json_t *c = json_array_get(cases, 30);
    CHECK(json_is_string(json_object_get(c, "bsdf")));
    CHECK(json_is_real(json_object_get(c, "roughness")));
    CHECK(json_is_real(json_object_get(c, "cos_theta")));
    CHECK(json_is_boolean(json_object_get(c, "compensated")));
    CHECK_NEAR(json_real_value(json_object_get(c, "albedo")), furnace.cases[30].albedo, 1e-7);
    CHECK(json_real_value(json_object_get(c, "expected")) == 1.0);
    json_decref(root);
    free(text);
    sl_furnace_free(&furnace);
    CHECK(furnace.cases == NULL && furnace.count == 0);
    sl_furnace f;
    CHECK_RESULT(sl_furnace_run(3, &f, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "samples") != NULL && f.cases == NULL);
}

/* The compensated anisotropic conductor off the furnace's anisotropy 0.8:
 * anisotropies on and between the table's nodes, roughness 0.1 .. 1 and the
 * furnace's angles (wo along the stretched axis), within 1 +- 0.01 (the loss was
 * 1.9% at roughness 0.9 - 1 when the tables had 4 x 5 anisotropy and azimuth
 * nodes). */
static void test_aniso_furnace_scan(void)
{
    static const double aniso[] = {0.1, 0.2, 0.35, 0.5, 0.65, 0.8, 0.9, 1.0};
    static const double coss[] = {0.02, 0.1, 0.2, 0.35, 0.5, 0.7, 1.0};
    static const double one[3] = {1, 1, 1};
    double lo = INFINITY, hi = -INFINITY, at_lo[3] = {0};
    for (int a = 0; a < 8; a++)
        for (int r = 1; r <= 10; r++)
            for (int c = 0; c < 7; c++) {
                sl_material m;
                sl_material_conductor(&m, one, one, r / 10.0);
                m.fresnel = SL_FRESNEL_ONE;
                m.anisotropy = aniso[a];
                double al[3];
                sl_bsdf_albedo(&m, coss[c], 4096, al);
                if (al[0] < lo) {
                    lo = al[0];
                    at_lo[0] = aniso[a], at_lo[1] = r / 10.0, at_lo[2] = coss[c];
                }
                hi = fmax(hi, al[0]);
            }
    printf("  anisotropic conductor, anisotropy 0.1 .. 1: albedo %.4f .. %.4f (lowest at "
           "anisotropy %.2f, roughness %.1f, cos %.2f)\n",
           lo, hi, at_lo[0], at_lo[1], at_lo[2]);
    CHECK(lo >= 0.99 && hi <= 1.01);
}

int main(void)
{
    RUN(test_furnace_thresholds);
    RUN(test_aniso_furnace_scan);
    RUN(test_uncompensated_loss);
    RUN(test_tables_current);
    RUN(test_table_accuracy);
    RUN(test_stability);
    RUN(test_furnace_json);
    return sl_test_finish();
}
