/* SPDX-License-Identifier: BSD-3-Clause */
/* The shortcuts the merge's fit takes give the answers of the long way bit
 * for bit: the curve looked up per 8-bit code (merge_code_curve) against
 * its evaluation, the lower middle of an even count taken from what the
 * selection leaves below the upper one, and the exposure check's ratios
 * against medians by sorting. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../stitch/merge_private.h"
#include "testing.h"

/* A gamma-like inverse response, different per channel. */
static void make_curve(sl_response *resp, double *inv, int nodes)
{
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < nodes; k++)
            inv[c * nodes + k] = pow((double)k / (nodes - 1), 2.2 + 0.1 * c);
    resp->channels = 3;
    resp->nodes = nodes;
    resp->inverse = inv;
}

static void test_code_curve(void)
{
    enum { NODES = 256 };
    double inv[3 * NODES];
    sl_response resp = {0};
    make_curve(&resp, inv, NODES);
    merge_samples s = {.code_step = 1.0 / 255};
    merge_code_curve t;
    merge_code_curve_init(&t, &s, &resp);
    CHECK(t.codes);
    int same = 0;
    for (int k = 0; k < 256; k++) {
        float z = (float)k * (1.0f / 255); /* as the sample pass stores a code */
        CHECK(merge_code_of(&t, z) == k);
        for (int c = 0; c < 3; c++) {
            double y = merge_code_curve_y(&t, &resp, c, z), want = merge_response_at(&resp, c, z);
            same += memcmp(&y, &want, sizeof y) == 0;
            double ly = t.log_y[c][k];
            CHECK(k == 0 ? isnan(ly) : ly == log(want));
        }
        CHECK(k == 0 ? isinf(t.log_z[k]) : t.log_z[k] == log(z));
    }
    CHECK_MSG(same == 3 * 256, "%d of 768 codes looked up as evaluated", same);
    /* Values that are no code's are evaluated. */
    float off[] = {0.5f + 1e-4f, 0.3f, -0.1f, 1.5f, NAN, nextafterf(1.0f / 255, 1)};
    for (size_t i = 0; i < sizeof off / sizeof off[0]; i++) {
        CHECK(merge_code_of(&t, off[i]) == -1);
        if (!isnan(off[i]))
            CHECK(merge_code_curve_y(&t, &resp, 1, off[i]) ==
                  merge_response_at(&resp, 1, off[i]));
    }
    /* 16-bit and float samples: no tables, everything evaluated. */
    merge_samples s16 = {.code_step = 1.0 / 65535}, sf = {.code_step = 0};
    merge_code_curve_init(&t, &s16, &resp);
    CHECK(!t.codes && merge_code_of(&t, 0.5f) == -1);
    merge_code_curve_init(&t, &sf, NULL);
    CHECK(!t.codes && merge_code_of(&t, 0.0f) == -1);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* With ties and without: after selecting the k-th smallest, v[0..k) holds
 * the k smallest, so their largest is the (k-1)-th. */
static void test_select_leaves_smallest(void)
{
    uint64_t state = 7;
    for (int trial = 0; trial < 200; trial++) {
        int n = 2 + (int)(sl_splitmix64(&state) % 300), k = n / 2;
        double *v = malloc((size_t)n * sizeof *v), *sorted = malloc((size_t)n * sizeof *sorted);
        for (int i = 0; i < n; i++)
            v[i] = trial % 2 ? (double)(sl_splitmix64(&state) % 7)
                             : (double)(sl_splitmix64(&state) >> 11) * 0x1.0p-53;
        memcpy(sorted, v, (size_t)n * sizeof *v);
        qsort(sorted, (size_t)n, sizeof *sorted, cmp_double);
        CHECK(merge_select_kth(v, n, k) == sorted[k]);
        double lower = v[0];
        for (int i = 1; i < k; i++)
            lower = v[i] > lower ? v[i] : lower;
        CHECK_MSG(lower == sorted[k - 1], "n %d: lower middle %g, sorted %g", n, lower,
                  sorted[k - 1]);
        free(v);
        free(sorted);
    }
}

/* Two frames a stop apart through the curve: the measured ratio is the
 * median of the pairs' ratios (an even count: the mean of the middle two). */
static void test_fit_ratios_median(void)
{
    enum { NODES = 256, COUNT = 500 };
    double inv[3 * NODES];
    sl_response resp = {0};
    make_curve(&resp, inv, NODES);
    merge_samples s = {.count = COUNT, .frames = 2, .code_step = 1.0 / 255};
    s.z = calloc((size_t)COUNT * 2 * 3, sizeof *s.z);
    s.spoilt = calloc((size_t)COUNT * 2, 1);
    uint64_t state = 11;
    double want[3 * COUNT];
    int n = 0;
    for (int i = 0; i < COUNT; i++)
        for (int c = 0; c < 3; c++) {
            int k0 = 40 + (int)(sl_splitmix64(&state) % 120);
            int k1 = k0 + 20 + (int)(sl_splitmix64(&state) % 40);
            s.z[(i * 2) * 3 + c] = (float)k0 * (1.0f / 255);
            s.z[(i * 2 + 1) * 3 + c] = (float)k1 * (1.0f / 255);
        }
    /* The same selection of pairs as the check: every channel of these is
     * well exposed; ratios by evaluating the curve. */
    for (int i = 0; i < COUNT; i++)
        for (int c = 0; c < 3; c++)
            want[n++] = merge_response_at(&resp, c, s.z[(i * 2 + 1) * 3 + c]) /
                        merge_response_at(&resp, c, s.z[(i * 2) * 3 + c]);
    qsort(want, (size_t)n, sizeof *want, cmp_double);
    double median = 0.5 * (want[n / 2 - 1] + want[n / 2]);
    double log_exif[2] = {0, log(2)}, ratio[2] = {0};
    CHECK(merge_fit_ratios(&s, &resp, 0.004, 0.95, log_exif, ratio) == 1);
    CHECK_MSG(ratio[0] == median, "ratio %.17g, median by sorting %.17g", ratio[0], median);
    free(s.z);
    free(s.spoilt);
}

int main(void)
{
    RUN(test_code_curve);
    RUN(test_select_leaves_smallest);
    RUN(test_fit_ratios_median);
    return sl_test_finish();
}
