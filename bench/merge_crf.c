/* SPDX-License-Identifier: BSD-3-Clause */
/* The self-calibrated merge across real camera curves: for each curve of
 * the DoRF database (../shared/data/crf/dorfCurves.txt, 201 measured
 * camera and film responses), a 7x3-stop bracket of the virtual set's
 * exterior through that curve (8-bit codes in lossless TIFFs, Poisson noise
 * of a small sensor, read noise) merged self-calibrated and with the true
 * curve, against the ideal estimator (tests/vset_bracket.c: true curve,
 * exposures and noise model, judged at the noise-free value) and against the
 * realizable oracle (the same estimator judging at its own estimate from the
 * frames: the best merge of these frames) and against the null-space
 * oracle (the realizable oracle told the true curve with its component
 * periodic in ln exposure replaced by the one the fit's smoothness picks:
 * the best a self-calibration with no prior on curve shapes can do from
 * equal steps). Prints per curve the per-pixel median and p99 errors, their
 * ratios and the recovered curve's error; then how many curves are at the
 * goal (1.1x median, 1.2x p99) against each, the median ratios, the worst
 * curves, and the curves the null-space oracle meets the goal on and the
 * self-calibrated merge does not (the fit's own gap).
 *
 *   ./build/bench/bench_merge_crf [--width 1024] [--curves all|I,J,..] [--seed 3]
 *                                 [--well 4000] [--read 3] [--scene exterior]
 *                                 [--smoothness L] [--samples N] [--noise-free]
 *                                 [--sensor-noise: the merges told the sensor's noise]
 *                                 [--alt-stops S: steps alternate 3 and S stops
 *                                  (no null-space oracle: no equal steps)]
 *                                 [--prior off|lofo|builtin: the self-calibrated merge's
 *                                  curve-shape prior: off (the merge's default) or of the
 *                                  other curves, the tested curve's family left out
 *                                  (tests/vset_bracket.h vb_dorf_family), or the merge's own
 *                                  of all 201 (it has seen the curve)]
 *                                 [--distance: with --prior lofo, only each true curve's
 *                                  distance from its prior (sl_response_prior_distance)]
 *                                 [--prior-weight W] [--prior-components K] [--families]
 *                                 [--curve-file F: instead of the DoRF curves, one curve file
 *                                  (sl_vset_response_load); its prior is of all 201]
 *                                 [--realizable-variant oracle|observed|own-channel|
 *                                  no-raw-clip|no-near-clip|merge-like|merge-rules: the
 *                                  realizable oracle with one of the merge's simplifications,
 *                                  all of them, or all and the merge's code rules
 *                                  (tests/vset_bracket.h vb_realizable_variant); "realizable"
 *                                  is then that variant]
 *                                 [--merge-saturation Z: the merges' saturation code (their
 *                                  --saturation; the truth's clipped pixels stay at 0.95)]
 *                                 [--refine: the self-calibrated curve refined by maximum
 *                                  likelihood under the noise (the merge's refine_response)]
 *                                 [--self-response F: the "self-calibrated" merge is given
 *                                  the curve in F (a setlight-response JSON, e.g. a fit made
 *                                  outside from a kept bracket) instead of fitting one]
 *
 * BENCH_KEEP=DIR keeps the (last) bracket in DIR: its frames, times.txt, the true
 * curve's inverse at the 256 codes (truth.txt), the self-calibrated curve (self.json)
 * and the camera's raw noise model and colour matrix (camera.txt), for
 * bench/crf_class_likelihood.py.
 */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "setlight/stitch.h"
#include "testing.h"
#include "vset_bracket.h"

enum { MAX_CURVES = 256 };

typedef struct result {
    double self_median, self_p99, true_median, true_p99, ideal_median, ideal_p99, real_median,
        real_p99, null_median, null_p99, curve, null_curve;
    int named; /* frames the self-calibrated merge's exposure check names (EXIF is true) */
    bool prior_dropped;       /* the merge left the curve prior out (the data are too far) */
    double prior_distance[2]; /* the curves fitted without and with it: their distance */
} result;

static double smoothness; /* --smoothness: the merge's lambda (0: its default) */
static int samples;       /* --samples: response samples per channel (0: its default) */
static bool sensor_noise; /* --sensor-noise: the merges get the sensor's noise model */
static double well_e, read_e;
static const sl_response_prior *prior; /* --prior lofo: the curve under test's */
static bool prior_on;                  /* --prior lofo or builtin */
static double prior_weight;            /* --prior-weight (0: the merge's default) */
static double merge_saturation;        /* --merge-saturation: the merges' (0: their default) */
static const char *self_response; /* --self-response: the self-calibrated merge given this */
static bool refine;               /* --refine: the self-calibrated curve refined under the noise */

/* BENCH_KEEP: where the bracket stays (NULL: a temporary folder, removed), and
 * what bench/crf_class_likelihood.py reads there beside the frames. */
static const char *keep_dir;

static void keep_bracket(const char *dir, const vb_bracket *b, const sl_response *fitted)
{
    char path[600];
    sl_error err;
    snprintf(path, sizeof path, "%s/self.json", dir);
    if (sl_response_write(path, fitted, &err))
        fprintf(stderr, "BENCH_KEEP: %s\n", err.message);
    snprintf(path, sizeof path, "%s/times.txt", dir);
    FILE *f = fopen(path, "w");
    for (int i = 0; f && i < b->frames; i++)
        fprintf(f, "%s %.9g\n", b->paths[i], b->times[i]);
    if (f)
        fclose(f);
    /* the raw noise's variance at raw value x, gain x + floor (the camera's own
     * model at the bracket's ISO), and the raw bits; then the colour matrix's
     * rows, each with its channel's white-balance gain */
    const sl_vset_camera *cam = &b->cam;
    double sd0 = sl_vset_sensor_noise_std(cam, b->iso, 0), sd1 = sl_vset_sensor_noise_std(cam, b->iso, 1);
    snprintf(path, sizeof path, "%s/camera.txt", dir);
    if ((f = fopen(path, "w"))) {
        fprintf(f, "%.9g %.9g %d\n", sd1 * sd1 - sd0 * sd0, sd0 * sd0, cam->raw_bits);
        for (int i = 0; i < 3; i++)
            fprintf(f, "%.9g %.9g %.9g  %.9g\n", cam->ccm[i][0], cam->ccm[i][1], cam->ccm[i][2],
                    cam->wb[i]);
        fclose(f);
    }
    snprintf(path, sizeof path, "%s/truth.txt", dir); /* linear value at code k / 255 */
    if ((f = fopen(path, "w"))) {
        for (int k = 0; k < 256; k++)
            fprintf(f, "%.9g\n", sl_vset_response_invert(&b->cam.response, k / 255.0));
        fclose(f);
    }
}

static int merge_score(const vb_bracket *b, const sl_response *given, vb_stats *px, double *curve,
                       int *named, bool *prior_dropped, double *prior_distance)
{
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = given ? SL_RESPONSE_GIVEN : SL_RESPONSE_AUTO;
    opt.response = given;
    opt.response_prior = prior;
    opt.use_response_prior = prior_on;
    opt.response_prior_weight = prior_weight;
    opt.smoothness = smoothness;
    opt.refine_response = refine;
    opt.saturation = merge_saturation;
    if (samples > 0)
        opt.samples = samples;
    if (sensor_noise) {
        opt.noise_gain = 1 / well_e;
        opt.noise_floor = (read_e / well_e) * (read_e / well_e);
    }
    sl_merge_result res;
    sl_error err;
    if (vb_merge(b, &opt, &res, &err)) {
        fprintf(stderr, "merge: %s\n", err.message);
        return 1;
    }
    *px = vb_compare(&res.radiance, b, 1, true);
    *named = res.disagreeing_frames;
    *prior_dropped = res.response_prior_dropped;
    prior_distance[0] = res.response_prior_distance[0];
    prior_distance[1] = res.response_prior_distance[1];
    double wz;
    if (keep_dir && curve)
        keep_bracket(keep_dir, b, &res.response);
    if (curve)
        *curve = vb_response_error(&res.response, &b->cam.response, b->code_lo, b->code_hi, &wz);
    sl_merge_result_free(&res);
    return 0;
}

static int run_curve(const char *dorf, const char *name, const vb_spec *base, const char *dir,
                     result *out)
{
    sl_error err;
    sl_vset_response resp;
    if (sl_vset_response_load(dorf, name, &resp, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    vb_spec sp = *base;
    sp.response = &resp;
    vb_bracket b;
    if (vb_make(dir, "crf", &sp, &b, &err)) {
        fprintf(stderr, "%s: %s\n", resp.name, err.message);
        vb_free(&b);
        return 1;
    }
    sl_response truth = {0};
    int rc = sl_response_linear(&truth, 256, &err) != SL_OK;
    for (int c = 0; c < 3 && !rc; c++)
        for (int k = 0; k < 256; k++)
            truth.inverse[c * 256 + k] = sl_vset_response_invert(&resp, k / 255.0);
    vb_stats self, tru, ideal = vb_compare(&b.oracle, &b, 1, false);
    vb_stats real = vb_compare(&b.realizable, &b, 1, false);
    vb_stats null = {0, NAN, NAN, 1};
    if (b.null_space.data)
        null = vb_compare(&b.null_space, &b, 1, true);
    int named = 0, named_true;
    bool dropped = false, dropped_true;
    double distance[2] = {0, 0}, distance_true[2];
    sl_response given = {0};
    if (!rc && self_response && sl_response_read(self_response, &given, &err)) {
        fprintf(stderr, "%s\n", err.message);
        rc = 1;
    }
    rc = rc ||
         merge_score(&b, self_response ? &given : NULL, &self, &out->curve, &named, &dropped,
                     distance) ||
         merge_score(&b, &truth, &tru, NULL, &named_true, &dropped_true, distance_true);
    *out = (result){self.median, self.p99,  tru.median,  tru.p99,    ideal.median,
                    ideal.p99,   real.median, real.p99, null.median, null.p99,
                    out->curve,  b.null_space.data ? b.null_space_curve : NAN, named, dropped, {distance[0], distance[1]}};
    sl_response_free(&truth);
    sl_response_free(&given);
    vb_free(&b);
    return rc;
}

static double median_of(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, vb_cmp_double);
    return n ? v[n / 2] : NAN;
}

int main(int argc, char **argv)
{
    vb_spec sp = {.scene = "exterior", .frames = 7, .stops = 3, .jpeg = true, .lossless = true,
                  .width = 1024, .saturation = 0.95, .seed = 3, .full_well_e = 4000,
                  .read_noise_e = 3, .realizable = true, .null_space = true};
    const char *curves = "all";
    static const struct option longs[] = {{"width", 1, 0, 'w'}, {"curves", 1, 0, 'c'},
                                          {"seed", 1, 0, 's'},  {"well", 1, 0, 'f'},
                                          {"read", 1, 0, 'r'},  {"scene", 1, 0, 'S'},
                                          {"smoothness", 1, 0, 'L'}, {"noise-free", 0, 0, 'N'},
                                          {"samples", 1, 0, 'n'},
                                          {"sensor-noise", 0, 0, 'z'},
                                          {"alt-stops", 1, 0, 'a'},
                                          {"prior", 1, 0, 'p'},
                                          {"prior-weight", 1, 0, 'W'},
                                          {"prior-components", 1, 0, 'K'},
                                          {"families", 0, 0, 'F'},
                                          {"curve-file", 1, 0, 'C'},
                                          {"distance", 0, 0, 'D'},
                                          {"realizable-variant", 1, 0, 'V'},
                                          {"merge-saturation", 1, 0, 'M'},
                                          {"self-response", 1, 0, 'R'},
                                          {"refine", 0, 0, 'f' + 256},
                                          {0, 0, 0, 0}};
    /* In the order of vb_realizable_variant. */
    static const char *const variants[] = {"oracle",       "observed",   "own-channel",
                                           "no-raw-clip",  "no-near-clip", "merge-like",
                                           "merge-rules"};
    enum { VARIANTS = (int)(sizeof variants / sizeof *variants) };
    bool lofo = false, families = false, distance = false;
    const char *curve_file = NULL;
    int components = 16;
    for (int o; (o = getopt_long(argc, argv, "", longs, NULL)) != -1;) {
        if (o == 'w')
            sp.width = atoi(optarg);
        else if (o == 'c')
            curves = optarg;
        else if (o == 's')
            sp.seed = strtoull(optarg, NULL, 10);
        else if (o == 'f')
            sp.full_well_e = atof(optarg);
        else if (o == 'r')
            sp.read_noise_e = atof(optarg);
        else if (o == 'S')
            sp.scene = optarg;
        else if (o == 'L')
            smoothness = atof(optarg);
        else if (o == 'z')
            sensor_noise = true;
        else if (o == 'n')
            samples = atoi(optarg);
        else if (o == 'N')
            sp.noise_free = true;
        else if (o == 'a')
            sp.alt_stops = atof(optarg);
        else if (o == 'p' && (strcmp(optarg, "lofo") == 0 || strcmp(optarg, "off") == 0 ||
                              strcmp(optarg, "builtin") == 0))
            lofo = strcmp(optarg, "lofo") == 0, prior_on = strcmp(optarg, "off") != 0;
        else if (o == 'W')
            prior_weight = atof(optarg);
        else if (o == 'K')
            components = atoi(optarg);
        else if (o == 'F')
            families = true;
        else if (o == 'C')
            curve_file = optarg;
        else if (o == 'D')
            distance = true;
        else if (o == 'M')
            merge_saturation = atof(optarg);
        else if (o == 'R')
            self_response = optarg;
        else if (o == 'f' + 256)
            refine = true;
        else if (o == 'V') {
            int v = 0;
            while (v < VARIANTS && strcmp(optarg, variants[v]) != 0)
                v++;
            if (v == VARIANTS)
                return 2;
            sp.realizable_variant = (vb_realizable_variant)v;
        } else
            return 2;
    }
    char dorf[1024];
    snprintf(dorf, sizeof dorf, "%s/crf/dorfCurves.txt", SETLIGHT_SHARED_DATA);
    static char names[MAX_CURVES][128];
    int count = vb_dorf_names(dorf, names, MAX_CURVES);
    if (count <= 0) {
        fprintf(stderr, "bench_merge_crf: %s: cannot read the DoRF curves\n", dorf);
        return 1;
    }
    if (families) {
        char family[128];
        for (int i = 0; i < count; i++) {
            vb_dorf_family(names[i], family, sizeof family);
            printf("%3d %-32s %s\n", i, names[i], family);
        }
        return 0;
    }
    /* Every curve's inverse table, for the priors. */
    static sl_response inverse[MAX_CURVES];
    sl_error err;
    if (lofo && vb_dorf_inverses(dorf, names, count, inverse, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    int pick[MAX_CURVES], n = 0;
    if (curve_file) /* one curve, in slot count: its name from the file */
        snprintf(names[count], sizeof names[count], "%s", curve_file), pick[n++] = count;
    else if (strcmp(curves, "all") == 0)
        for (int i = 0; i < count; i++)
            pick[n++] = i;
    else
        for (char *s = (char *)curves; *s && n < MAX_CURVES; s += *s == ',') {
            char *end;
            long i = strtol(s, &end, 10);
            if (end == s || i < 0 || i >= count)
                return 2;
            pick[n++] = (int)i;
            s = end;
        }
    sl_vset_scene scene;
    if (vb_scene(sp.scene, sp.width, &scene, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    sp.latlong = &scene.latlong;
    well_e = sp.full_well_e, read_e = sp.read_noise_e;
    char dir[600] = "/tmp/bench_merge_crf_XXXXXX";
    keep_dir = getenv("BENCH_KEEP");
    if (keep_dir) {
        snprintf(dir, sizeof dir, "%s", keep_dir);
        mkdir(dir, 0777); /* or there already */
    } else if (!mkdtemp(dir))
        return 1;
    printf("# %s %dx%d, %d x %d stops", sp.scene, sp.width, sp.width / 2, sp.frames, sp.stops);
    if (sp.alt_stops > 0)
        printf(" alternating with %g", sp.alt_stops);
    printf(", 8-bit lossless, well %.0f e, read %.1f e, seed %llu", sp.full_well_e,
           sp.read_noise_e, (unsigned long long)sp.seed);
    printf(", curve prior %s", !prior_on ? "off" : lofo ? "of the other families" : "built in");
    if (lofo)
        printf(" (%d components)", components);
    if (prior_weight > 0)
        printf(" at weight %g", prior_weight);
    if (sensor_noise)
        printf(", merges told the sensor's noise");
    if (merge_saturation > 0)
        printf(", merges' saturation code %g", merge_saturation);
    if (self_response)
        printf(", \"self-calibrated\": given %s", self_response);
    if (refine)
        printf(", self-calibrated curve refined under the noise");
    printf(", realizable oracle: %s\n", variants[sp.realizable_variant]);
    printf("# index name: per pixel median / p99 %%: self-calibrated, true curve, ideal, "
           "realizable, null-space; median, p99 ratios: self / ideal, realizable / ideal, "
           "self / realizable, null-space / ideal, self / null-space; curve error %%: "
           "self-calibrated, null-space; frames named; curve prior dropped (1), the curve's "
           "distance from it fitted without and with it\n");
    /* The ratios, per comparison: self / ideal, true curve / ideal,
     * realizable / ideal, self / realizable, true curve / realizable. */
    enum { SELF_IDEAL, TRUE_IDEAL, REAL_IDEAL, SELF_REAL, TRUE_REAL, NULL_IDEAL, SELF_NULL,
           RATIOS };
    static const char *const label[RATIOS] = {
        "self-calibrated / ideal",      "true curve / ideal",      "realizable / ideal",
        "self-calibrated / realizable", "true curve / realizable", "null-space / ideal",
        "self-calibrated / null-space"};
    /* Curves by who meets the goal against the ideal estimator: the
     * null-space oracle and the self-calibrated merge. */
    int both = 0, null_only = 0, self_only = 0, neither = 0;
    char gap[4096] = "";
    static double rmed[RATIOS][MAX_CURVES], rp99[RATIOS][MAX_CURVES];
    double worst[RATIOS] = {0};
    int worst_i[RATIOS] = {0}, at_goal[RATIOS] = {0}, done = 0, failed = 0;
    for (int j = 0; j < n; j++) {
        result r;
        sl_response_prior *own = NULL;
        const char *name = curve_file ? NULL : names[pick[j]];
        if (lofo && vb_dorf_prior(inverse, names, count, name, components, &own, &err)) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        prior = own;
        if (distance && own) { /* the true curve's distance from its prior; no merge */
            sl_vset_response resp;
            sl_response inv = {0};
            if (!sl_vset_response_load(curve_file ? curve_file : dorf, name, &resp, &err) &&
                !vb_response_inverse(&resp, &inv, &err))
                printf("%3d %-32s %.3f\n", pick[j], names[pick[j]],
                       sl_response_prior_distance(own, &inv, 0));
            sl_response_free(&inv);
            sl_response_prior_free(own);
            continue;
        }
        int bad = run_curve(curve_file ? curve_file : dorf, name, &sp, dir, &r);
        sl_response_prior_free(own);
        prior = NULL;
        if (bad) {
            failed++;
            continue;
        }
        double num[RATIOS][2] = {{r.self_median, r.self_p99}, {r.true_median, r.true_p99},
                                 {r.real_median, r.real_p99}, {r.self_median, r.self_p99},
                                 {r.true_median, r.true_p99}, {r.null_median, r.null_p99},
                                 {r.self_median, r.self_p99}};
        double den[RATIOS][2] = {{r.ideal_median, r.ideal_p99}, {r.ideal_median, r.ideal_p99},
                                 {r.ideal_median, r.ideal_p99}, {r.real_median, r.real_p99},
                                 {r.real_median, r.real_p99},   {r.ideal_median, r.ideal_p99},
                                 {r.null_median, r.null_p99}};
        for (int k = 0; k < RATIOS; k++) {
            double m = num[k][0] / den[k][0], p = num[k][1] / den[k][1];
            rmed[k][done] = m;
            rp99[k][done] = p;
            at_goal[k] += m <= 1.1 && p <= 1.2;
            /* The worst curve: furthest over the goal (1.1x median, 1.2x p99). */
            double over = fmax(m / 1.1, p / 1.2);
            if (over > worst[k])
                worst[k] = over, worst_i[k] = pick[j];
        }
        bool self_ok = rmed[SELF_IDEAL][done] <= 1.1 && rp99[SELF_IDEAL][done] <= 1.2;
        bool null_ok = rmed[NULL_IDEAL][done] <= 1.1 && rp99[NULL_IDEAL][done] <= 1.2;
        both += self_ok && null_ok, self_only += self_ok && !null_ok;
        neither += !self_ok && !null_ok;
        if (null_ok && !self_ok) {
            size_t at = strlen(gap);
            snprintf(gap + at, sizeof gap - at, "%s%d", null_only++ ? "," : "", pick[j]);
        }
        printf("%3d %-32s %.2f / %.2f  %.2f / %.2f  %.2f / %.2f  %.2f / %.2f  %.2f / %.2f  "
               "%.3f %.3f  %.3f %.3f  %.3f %.3f  %.3f %.3f  %.3f %.3f  %.2f %.2f  %d  %d %.3f %.3f\n",
               pick[j], names[pick[j]], 100 * r.self_median, 100 * r.self_p99,
               100 * r.true_median, 100 * r.true_p99, 100 * r.ideal_median, 100 * r.ideal_p99,
               100 * r.real_median, 100 * r.real_p99, 100 * r.null_median, 100 * r.null_p99,
               rmed[SELF_IDEAL][done], rp99[SELF_IDEAL][done], rmed[REAL_IDEAL][done],
               rp99[REAL_IDEAL][done], rmed[SELF_REAL][done], rp99[SELF_REAL][done],
               rmed[NULL_IDEAL][done], rp99[NULL_IDEAL][done], rmed[SELF_NULL][done],
               rp99[SELF_NULL][done], 100 * r.curve, 100 * r.null_curve, r.named, r.prior_dropped,
               r.prior_distance[0], r.prior_distance[1]);
        fflush(stdout);
        done++;
    }
    printf("# %d curves (%d failed)\n", done, failed);
    bool null_space = !(sp.alt_stops > 0) || sp.alt_stops == sp.stops;
    for (int k = 0; k < RATIOS && done; k++) {
        if (!null_space && (k == NULL_IDEAL || k == SELF_NULL))
            continue;
        double maxm = 0, maxp = 0;
        for (int i = 0; i < done; i++)
            maxm = fmax(maxm, rmed[k][i]), maxp = fmax(maxp, rp99[k][i]);
        printf("# %-28s at the goal on %3d of %d; median ratio: median %.3f, max %.3f; p99 "
               "ratio: median %.3f, max %.3f; worst curve %d %s (%.3f of the goal)\n",
               label[k], at_goal[k], done, median_of(rmed[k], done), maxm,
               median_of(rp99[k], done), maxp, worst_i[k], names[worst_i[k]], worst[k]);
    }
    if (null_space)
        printf("# against the ideal estimator: both the null-space oracle and self-calibrated at "
               "the goal on %d, the null-space oracle alone on %d (the fit's own gap: %s), "
               "self-calibrated alone on %d, neither on %d\n",
               both, null_only, null_only ? gap : "none", self_only, neither);
    sl_vset_scene_free(&scene);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "%s %s", keep_dir ? "true" : "rm -rf", dir);
    return system(cmd) == 0 && !failed ? 0 : 1;
}
