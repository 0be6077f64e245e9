/* SPDX-License-Identifier: BSD-3-Clause */
/* The self-calibrated merge across real camera curves: brackets of the
 * virtual set's exterior made through a dozen of the DoRF database's 201
 * measured responses (../shared/data/crf/dorfCurves.txt; skipped when it is
 * absent), 7x3 stops, 8-bit codes in lossless TIFFs, the noise of a small
 * sensor (4000-electron well, 3 electrons of read noise). The merge's
 * per-pixel median and p99 error, with the true curve and self-calibrated,
 * against the ideal estimator's on the same frames (true curve, exposures
 * and noise model: tests/vset_bracket.c) and the realizable oracle's (the
 * same estimator judging weights and clips at its own estimate from the
 * frames instead of the noise-free value: the best merge of these frames).
 * bench/merge_crf.c runs all 201 (docs/merge.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/stitch.h"
#include "testing.h"
#include "vset_bracket.h"

enum { MAX_CURVES = 256, PICKED = 12 };

/* The merge with the true curve and the sensor's noise model over the ideal
 * estimator, per pixel: measured 0.91-1.28 (median) and 1.00-1.35 (p99),
 * the steep pushed film the worst (its weights: the realizable oracle,
 * below, is within 1.02 / 1.01 of the ideal there). */
#define TRUE_MEDIAN_FACTOR 1.3
#define TRUE_P99_FACTOR 1.4
/* Self-calibrated (goal not met, docs/merge.md "Real camera curves"): over
 * the dozen, the median of the median ratios (measured 1.42), the worst
 * (1.95) and the median of the p99 ratios (1.06). */
#define SELF_MEDIAN_GUARD 1.6
#define SELF_WORST_GUARD 2.2
#define SELF_P99_GUARD 1.15
/* The realizable oracle over the ideal estimator: measured 1.007-1.071
 * (median) and 1.000-1.011 (p99), so the goal (1.1 / 1.2) is within reach
 * of a merge of the frames on every one of the dozen; it can lose to the
 * ideal estimator (less knowledge), not beat it beyond chance. */
#define REAL_MEDIAN_FACTOR 1.1
#define REAL_P99_FACTOR 1.05
#define REAL_FLOOR 0.98
/* Self-calibrated over the realizable oracle: curves at the goal (1.1 /
 * 1.2; measured 4 of the 12: kaf3000CD, both Portras, agfacolor-futura),
 * the median of the median ratios (1.356; 1.407 when the curve took every
 * measured exposure), the worst (1.915) and the median p99 ratio (1.047). */
#define SELF_REAL_AT_GOAL 4
#define SELF_REAL_MEDIAN_GUARD 1.38
#define SELF_REAL_WORST_GUARD 2.0
#define SELF_REAL_P99_GUARD 1.1

typedef struct keyed {
    double key;
    int index;
} keyed;

static int cmp_keyed(const void *a, const void *b)
{
    double x = ((const keyed *)a)->key, y = ((const keyed *)b)->key;
    return (x > y) - (x < y);
}

/* The dozen: the curves ranked by the code they give 18% grey (0.03 for
 * "gamma+2.6" to 0.87 for a pushed film), every (n-1)/11-th rank, so they
 * span the set's gammas from one end to the other. */
static int pick_curves(const char *dorf, char (*names)[128], int count,
                       sl_vset_response *picked)
{
    keyed *k = malloc((size_t)count * sizeof *k);
    if (!k)
        return 0;
    int n = 0;
    for (int i = 0; i < count; i++) {
        sl_error err;
        sl_vset_response r;
        if (sl_vset_response_load(dorf, names[i], &r, &err) == SL_OK)
            k[n++] = (keyed){sl_vset_response_apply(&r, 0.18), i};
    }
    qsort(k, (size_t)n, sizeof *k, cmp_keyed);
    int m = 0;
    for (int j = 0; j < PICKED && n >= PICKED; j++) {
        sl_error err;
        int i = k[(int)lround((double)j * (n - 1) / (PICKED - 1))].index;
        CHECK_OK(sl_vset_response_load(dorf, names[i], &picked[m], &err), &err);
        m++;
    }
    free(k);
    return m;
}

static void check_clean(const sl_image *img)
{
    sl_image_stats st;
    sl_image_stats_compute(img, &st);
    CHECK(st.nan_count == 0 && st.inf_count == 0 && st.negative_count == 0);
}

static void test_dorf_curves(void)
{
    char dorf[1024];
    snprintf(dorf, sizeof dorf, "%s/crf/dorfCurves.txt", SETLIGHT_SHARED_DATA);
    static char names[MAX_CURVES][128];
    int count = vb_dorf_names(dorf, names, MAX_CURVES);
    if (count <= 0) {
        printf("  skipped: %s absent\n", dorf);
        return;
    }
    CHECK(count == 201);
    static sl_vset_response curves[PICKED];
    int m = pick_curves(dorf, names, count, curves);
    CHECK(m == PICKED);
    sl_error err;
    sl_vset_scene scene;
    CHECK_OK(vb_scene("exterior", 256, &scene, &err), &err);
    if (!scene.latlong.data)
        return;
    double self_median[PICKED], self_p99[PICKED], real_median[PICKED], real_p99[PICKED];
    int scored = 0, at_goal = 0;
    for (int i = 0; i < m; i++) {
        vb_spec sp = {.scene = "exterior", .response = &curves[i], .frames = 7, .stops = 3,
                      .jpeg = true, .lossless = true, .width = 256, .saturation = 0.95,
                      .seed = 3, .full_well_e = 4000, .read_noise_e = 3,
                      .latlong = &scene.latlong, .realizable = true};
        vb_bracket b;
        CHECK_OK(vb_make(sl_test_tmpdir(), "crf", &sp, &b, &err), &err);
        sl_response truth = {0};
        CHECK_OK(sl_response_linear(&truth, 256, &err), &err);
        for (int c = 0; c < 3 && truth.inverse; c++)
            for (int k = 0; k < 256; k++)
                truth.inverse[c * 256 + k] = sl_vset_response_invert(&curves[i], k / 255.0);
        sl_merge_options opt;
        sl_merge_options_init(&opt);
        sl_merge_result self, given;
        opt.response_mode = SL_RESPONSE_AUTO;
        CHECK_OK(vb_merge(&b, &opt, &self, &err), &err);
        /* With the true curve, also the sensor's noise model (what --noise
         * gives): the merge's default is a 50000-electron well's. */
        opt.response_mode = SL_RESPONSE_GIVEN;
        opt.response = &truth;
        opt.noise_gain = 1 / sp.full_well_e;
        opt.noise_floor = (sp.read_noise_e / sp.full_well_e) * (sp.read_noise_e / sp.full_well_e);
        CHECK_OK(vb_merge(&b, &opt, &given, &err), &err);
        if (self.radiance.data && given.radiance.data && b.oracle.data) {
            vb_stats got = vb_compare(&self.radiance, &b, 1, true);
            vb_stats tru = vb_compare(&given.radiance, &b, 1, false);
            vb_stats ideal = vb_compare(&b.oracle, &b, 1, false);
            vb_stats real = vb_compare(&b.realizable, &b, 1, false);
            double wz, curve = vb_response_error(&self.response, &curves[i], b.code_lo, b.code_hi, &wz);
            double rm = got.median / ideal.median, rp = got.p99 / ideal.p99;
            double tm = tru.median / ideal.median, tp = tru.p99 / ideal.p99;
            double om = real.median / ideal.median, op = real.p99 / ideal.p99;
            double sm = got.median / real.median, spp = got.p99 / real.p99;
            printf("  %-30s grey code %.3f: ideal %.2f / %.2f%%; true curve / ideal %.3f / %.3f; "
                   "realizable / ideal %.3f / %.3f; self-calibrated / ideal %.3f / %.3f, "
                   "/ realizable %.3f / %.3f, curve within %.2f%% (worst at z %.3f), "
                   "%d frames named\n",
                   curves[i].name, sl_vset_response_apply(&curves[i], 0.18), 100 * ideal.median,
                   100 * ideal.p99, tm, tp, om, op, rm, rp, sm, spp, 100 * curve, wz,
                   (int)self.disagreeing_frames);
            CHECK_MSG(tm <= TRUE_MEDIAN_FACTOR, "%s: true curve median %.3f x the ideal", curves[i].name, tm);
            CHECK_MSG(tp <= TRUE_P99_FACTOR, "%s: true curve p99 %.3f x the ideal", curves[i].name, tp);
            CHECK_MSG(om <= REAL_MEDIAN_FACTOR && om >= REAL_FLOOR,
                      "%s: realizable oracle median %.3f x the ideal", curves[i].name, om);
            CHECK_MSG(op <= REAL_P99_FACTOR && op >= REAL_FLOOR,
                      "%s: realizable oracle p99 %.3f x the ideal", curves[i].name, op);
            real_median[scored] = sm;
            real_p99[scored] = spp;
            at_goal += sm <= 1.1 && spp <= 1.2;
            check_clean(&self.radiance);
            self_median[scored] = rm;
            self_p99[scored++] = rp;
        }
        sl_merge_result_free(&self);
        sl_merge_result_free(&given);
        sl_response_free(&truth);
        vb_free(&b);
    }
    CHECK(scored == PICKED);
    qsort(self_median, (size_t)scored, sizeof(double), vb_cmp_double);
    qsort(self_p99, (size_t)scored, sizeof(double), vb_cmp_double);
    if (scored) {
        double mm = self_median[scored / 2], mp = self_p99[scored / 2];
        printf("  self-calibrated over the ideal estimator, median of %d curves: median %.3f "
               "(worst %.3f), p99 %.3f (worst %.3f)\n",
               scored, mm, self_median[scored - 1], mp, self_p99[scored - 1]);
        CHECK_MSG(mm <= SELF_MEDIAN_GUARD, "self-calibrated median ratio %.3f", mm);
        CHECK_MSG(self_median[scored - 1] <= SELF_WORST_GUARD,
                  "self-calibrated worst median ratio %.3f", self_median[scored - 1]);
        CHECK_MSG(mp <= SELF_P99_GUARD, "self-calibrated p99 ratio %.3f", mp);
        qsort(real_median, (size_t)scored, sizeof(double), vb_cmp_double);
        qsort(real_p99, (size_t)scored, sizeof(double), vb_cmp_double);
        double rm = real_median[scored / 2], rp = real_p99[scored / 2];
        printf("  self-calibrated over the realizable oracle: %d of %d curves at the goal; median "
               "%.3f (worst %.3f), p99 %.3f (worst %.3f)\n",
               at_goal, scored, rm, real_median[scored - 1], rp, real_p99[scored - 1]);
        CHECK_MSG(at_goal >= SELF_REAL_AT_GOAL, "%d curves at the goal", at_goal);
        CHECK_MSG(rm <= SELF_REAL_MEDIAN_GUARD, "self-calibrated / realizable median ratio %.3f", rm);
        CHECK_MSG(real_median[scored - 1] <= SELF_REAL_WORST_GUARD,
                  "self-calibrated / realizable worst median ratio %.3f", real_median[scored - 1]);
        CHECK_MSG(rp <= SELF_REAL_P99_GUARD, "self-calibrated / realizable p99 ratio %.3f", rp);
    }
    sl_vset_scene_free(&scene);
}

int main(void)
{
    RUN(test_dorf_curves);
    return sl_test_finish();
}
