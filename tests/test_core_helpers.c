/* SPDX-License-Identifier: BSD-3-Clause */
/* core's small shared helpers: JSON file load and atomic write, luminance,
 * cmp_double, splitmix64, compensated sums, conductor Fresnel, sl_text. */
#include <complex.h>
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testing.h"

static void write_text(const char *path, const char *text)
{
    sl_error err;
    CHECK_OK(sl_write_file_atomic(path, text, strlen(text), &err), &err);
}

static void test_json_files(void)
{
    sl_error err;
    json_t *root = (json_t *)1;
    CHECK_RESULT(sl_json_load_file(sl_test_path("nowhere.json"), "test JSON", 0, &root, &err),
                 SL_ERR_NOT_FOUND, &err);
    CHECK(root == NULL && strstr(err.message, "nowhere.json") != NULL);

    const char *bad = sl_test_path("bad.json");
    write_text(bad, "{\"a\": 1,\n \"b\": }\n");
    CHECK_RESULT(sl_json_load_file(bad, "test JSON", 0, &root, &err), SL_ERR_INPUT, &err);
    CHECK(root == NULL && strstr(err.message, "bad.json: line 2: JSON syntax error") != NULL);

    const char *twice = sl_test_path("twice.json");
    write_text(twice, "{\"a\": 1, \"a\": 2}");
    CHECK_OK(sl_json_load_file(twice, "test JSON", 0, &root, &err), &err);
    json_decref(root);
    CHECK_RESULT(sl_json_load_file(twice, "test JSON", JSON_REJECT_DUPLICATES, &root, &err),
                 SL_ERR_INPUT, &err);

    /* Written whole with a final newline, and read back the same. */
    const char *out = sl_test_path("out.json");
    json_t *o = json_pack("{s:f, s:[i, i]}", "x", 0.5, "v", 1, 2);
    CHECK_OK(sl_json_write_atomic(out, o, JSON_COMPACT | JSON_PRESERVE_ORDER, &err), &err);
    FILE *f = fopen(out, "rb");
    char buf[64] = {0};
    size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    if (f)
        fclose(f);
    CHECK_MSG(!strcmp(buf, "{\"x\":0.5,\"v\":[1,2]}\n"), "wrote '%s' (%zu bytes)", buf, n);
    CHECK_OK(sl_json_load_file(out, "test JSON", 0, &root, &err), &err);
    CHECK(root && json_equal(root, o));
    json_decref(root);
    /* A missing output folder is a usage error (docs/conventions.md). */
    const char *nowhere = sl_test_path("no/such/dir/x.json");
    CHECK_RESULT(sl_json_write_atomic(nowhere, o, 0, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "no/such/dir/x.json") != NULL);
    json_decref(o);
}

/* A job's output by the end of its name: the first match, NULL for none. */
static void test_json_string_ending(void)
{
    json_t *a = json_pack("[s,i,s,s]", "/d/stitch/hdri.exr", 3, "/d/calibrate/hdri.exr",
                          "/d/calibrate.result.json");
    CHECK(!strcmp(sl_json_string_ending(a, "/hdri.exr") ? sl_json_string_ending(a, "/hdri.exr") : "", "/d/stitch/hdri.exr"));
    CHECK(!strcmp(sl_json_string_ending(a, ".result.json") ? sl_json_string_ending(a, ".result.json") : "", "/d/calibrate.result.json"));
    CHECK(sl_json_string_ending(a, "/rig.json") == NULL);
    CHECK(sl_json_string_ending(a, "a longer suffix than any of the paths in the array") == NULL);
    CHECK(sl_json_string_ending(NULL, ".exr") == NULL);
    json_decref(a);
}

static void test_luminance(void)
{
    const double d[3] = {1, 1, 1}, r[3] = {2, 0, 0};
    CHECK_NEAR(sl_luminance(d), 1.0, 1e-15);
    CHECK(sl_luminance(r) == 0.4252);
    const float p[3] = {0.25f, 0.5f, 4.0f};
    CHECK(sl_luminance_px(p) == 0.2126 * 0.25 + 0.7152 * 0.5 + 0.0722 * 4.0);
    CHECK(sl_luminancef(p) == 0.2126f * 0.25f + 0.7152f * 0.5f + 0.0722f * 4.0f);
}

static void test_cmp_double(void)
{
    double v[] = {3, -1, 2.5, -1, 1e300, -INFINITY, 0};
    qsort(v, 7, sizeof v[0], sl_cmp_double);
    const double want[] = {-INFINITY, -1, -1, 0, 2.5, 3, 1e300};
    for (int i = 0; i < 7; i++)
        CHECK(v[i] == want[i]);
    double a = 1, b = 2;
    CHECK(sl_cmp_double(&a, &b) == -1 && sl_cmp_double(&b, &a) == 1 && sl_cmp_double(&a, &a) == 0);
}

static void test_splitmix64(void)
{
    /* Vigna's reference splitmix64.c from state 0. */
    uint64_t s = 0;
    CHECK(sl_splitmix64(&s) == 0xe220a8397b1dcdafull);
    CHECK(sl_splitmix64(&s) == 0x6e789e6aa1b965f4ull);
    CHECK(sl_splitmix64(&s) == 0x06c45d188009454full);
    CHECK(s == 3 * SL_SPLITMIX64_INCREMENT);
    CHECK(sl_splitmix64_hash(0) == 0xe220a8397b1dcdafull);
    uint64_t t = 0;
    CHECK(sl_test_rand(&t) == 0xe220a8397b1dcdafull);
}

static void test_ksum(void)
{
    /* A naive sum loses the 1 entirely; Kahan's (without Neumaier's
     * branch) too, since the large addend comes second. */
    const double v[] = {1.0, 1e100, 1.0, -1e100};
    sl_ksum k = {0};
    double naive = 0;
    for (int i = 0; i < 4; i++) {
        sl_ksum_add(&k, v[i]);
        naive += v[i];
    }
    CHECK(naive == 0.0);
    CHECK(sl_ksum_value(&k) == 2.0);
    sl_ksum tenth = {0};
    for (int i = 0; i < 1000000; i++)
        sl_ksum_add(&tenth, 0.1);
    CHECK(fabs(sl_ksum_value(&tenth) - 100000.0) <= 1e-10);
}

/* The textbook complex-arithmetic form of the exact conductor reflectance. */
static double fresnel_complex(double cos_i, double n, double k)
{
    double complex eta = n + k * I;
    double complex cos_t = csqrt(1.0 - (1.0 - cos_i * cos_i) / (eta * eta));
    double complex rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    double complex rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    double a = cabs(rp), b = cabs(rs);
    return 0.5 * (a * a + b * b);
}

static void test_fresnel_conductor(void)
{
    /* Chrome (n, k) per channel as the unwrap's ball, gold, aluminium. */
    const double nk[][2] = {{3.1, 3.3}, {0.18, 3.4}, {1.35, 7.5}, {2.0, 0.0}};
    double worst = 0;
    for (size_t m = 0; m < sizeof nk / sizeof nk[0]; m++) {
        double n = nk[m][0], k = nk[m][1];
        double f0 = ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k);
        CHECK_NEAR(sl_fresnel_conductor(1.0, n, k), f0, 1e-14);
        CHECK_NEAR(sl_fresnel_conductor(0.0, n, k), 1.0, 1e-14);
        for (int i = 1; i < 100; i++) {
            double c = i / 100.0;
            double e = fabs(sl_fresnel_conductor(c, n, k) - fresnel_complex(c, n, k));
            worst = e > worst ? e : worst;
        }
    }
    CHECK_MSG(worst < 1e-13, "closed form vs complex form: %.3g", worst);
    /* Clamped outside [0, 1]. */
    CHECK(sl_fresnel_conductor(1.5, 3.1, 3.3) == sl_fresnel_conductor(1.0, 3.1, 3.3));
}

static void test_text(void)
{
    sl_text t = {0};
    CHECK(sl_text_add(&t, "ab", 2) && sl_text_add_str(&t, "c") &&
          sl_text_printf(&t, "%d-%s", 42, "x"));
    CHECK(t.len == 7 && !strcmp(t.s, "abc42-x"));
    /* Longer than any stack buffer a formatter could use: nothing cut. */
    char word[5001];
    memset(word, 'w', sizeof word - 1);
    word[sizeof word - 1] = 0;
    CHECK(sl_text_printf(&t, "[%s]", word));
    CHECK(t.len == 7 + 5002 && strlen(t.s) == t.len && t.s[7] == '[' && t.s[t.len - 1] == ']');
    /* A failed text (out of memory) refuses every later append, keeping what it has. */
    t.failed = true;
    CHECK(!sl_text_add_str(&t, "more") && !sl_text_printf(&t, "%d", 1));
    CHECK(t.len == 7 + 5002);
    sl_text_free(&t);
    CHECK(!t.s && !t.len && !t.failed);
}

int main(void)
{
    RUN(test_json_files);
    RUN(test_json_string_ending);
    RUN(test_luminance);
    RUN(test_cmp_double);
    RUN(test_splitmix64);
    RUN(test_ksum);
    RUN(test_fresnel_conductor);
    RUN(test_text);
    return sl_test_finish();
}
