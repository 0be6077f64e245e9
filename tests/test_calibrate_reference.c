/* SPDX-License-Identifier: BSD-3-Clause */
/* Chart reference files (--chart-reference FILE): X-Rite's published
 * CIELAB D50 values (ColorChecker Classic, after November 2014) against the
 * built-in table (X-Rite's sRGB rendering of the same), XYZ and RGB round
 * trips, and malformed files. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

static const double XRITE_LAB_D50[24][3] = {
    {37.54, 14.37, 14.92},  {64.66, 19.27, 17.50},  {49.32, -3.82, -22.54},
    {43.46, -12.74, 22.72}, {54.94, 9.61, -24.79},  {70.48, -32.26, -0.37},
    {62.73, 35.83, 56.50},  {39.43, 10.75, -45.17}, {50.57, 48.64, 16.67},
    {30.10, 22.54, -20.87}, {71.77, -24.13, 58.19}, {71.51, 18.24, 67.37},
    {28.37, 15.42, -49.80}, {54.38, -39.72, 32.27}, {42.43, 51.05, 28.62},
    {81.80, 2.67, 80.41},   {50.63, 51.28, -14.12}, {49.57, -29.71, -28.32},
    {95.19, -1.03, 2.93},   {81.29, -0.57, 0.44},   {66.89, -0.75, -0.06},
    {50.76, -0.13, 0.14},   {35.63, -0.46, -0.48},  {20.64, 0.07, -0.46},
};

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

static void test_lab_csv(void)
{
    const char *path = sl_test_path("ref_lab.csv");
    char buf[4096];
    size_t k = (size_t)snprintf(buf, sizeof buf, "# X-Rite ColorChecker Classic, post-2014\npatch,L,a,b\n");
    for (int p = 0; p < 24; p++)
        k += (size_t)snprintf(buf + k, sizeof buf - k, "%s, %.2f, %.2f, %.2f\n",
                              SL_COLORCHECKER_NAMES[p], XRITE_LAB_D50[p][0], XRITE_LAB_D50[p][1],
                              XRITE_LAB_D50[p][2]);
    write_text(path, buf);
    double ref[24][3];
    sl_chart_space sp;
    sl_error err;
    CHECK_OK(sl_chart_reference_read(path, ref, &sp, &err), &err);
    CHECK(sp == SL_CHART_SPACE_LAB_D50);
    /* The built-in table is X-Rite's 8-bit sRGB of the same chart: they agree
     * to the 8-bit rounding, except cyan, whose red is out of sRGB's gamut
     * (clipped to 0 in the table). */
    double mean = 0, worst = 0;
    int worst_p = 0;
    for (int p = 0; p < 24; p++) {
        double de = sl_chart_delta_e(ref[p], SL_COLORCHECKER_LINEAR[p]);
        if (p != 17) {
            mean += de / 23;
            if (de > worst)
                worst = de, worst_p = p;
        }
    }
    printf("  Lab D50 file vs built-in sRGB table: mean dE2000 %.3f, max %.3f (%s), cyan %.3f "
           "(red %.4f: out of gamut)\n",
           mean, worst, SL_COLORCHECKER_NAMES[worst_p],
           sl_chart_delta_e(ref[17], SL_COLORCHECKER_LINEAR[17]), ref[17][0]);
    CHECK(mean < 0.5);
    CHECK(worst < 1.5);
    CHECK(ref[17][0] < 0);
}

static void test_rgb_json_and_xyz(void)
{
    /* JSON, linear Rec.709: exact. */
    const char *path = sl_test_path("ref.json");
    char buf[8192];
    size_t k = (size_t)snprintf(buf, sizeof buf, "{\"space\": \"lin_rec709\", \"patches\": [");
    for (int p = 0; p < 24; p++)
        k += (size_t)snprintf(buf + k, sizeof buf - k, "%s[%.17g, %.17g, %.17g]", p ? ", " : "",
                              SL_COLORCHECKER_LINEAR[p][0] + 0.01, SL_COLORCHECKER_LINEAR[p][1],
                              SL_COLORCHECKER_LINEAR[p][2]);
    snprintf(buf + k, sizeof buf - k, "]}\n");
    write_text(path, buf);
    double ref[24][3];
    sl_error err;
    CHECK_OK(sl_chart_reference_read(path, ref, NULL, &err), &err);
    for (int p = 0; p < 24; p++)
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(ref[p][c], SL_COLORCHECKER_LINEAR[p][c] + (c == 0 ? 0.01 : 0), 1e-15);
    /* CSV, XYZ D50 with white Y = 100: back to the same RGB. */
    double adapt[3][3];
    sl_bradford(SL_WHITE_D65, SL_WHITE_D50, adapt);
    path = sl_test_path("ref_xyz.csv");
    k = (size_t)snprintf(buf, sizeof buf, "X;Y;Z\n");
    for (int p = 0; p < 24; p++) {
        double xyz[3], d50[3];
        sl_rec709_to_xyz(ref[p], xyz);
        sl_mat3_apply(adapt, xyz, d50);
        k += (size_t)snprintf(buf + k, sizeof buf - k, "%.12g;%.12g;%.12g\n", 100 * d50[0],
                              100 * d50[1], 100 * d50[2]);
    }
    write_text(path, buf);
    double back[24][3];
    sl_chart_space sp;
    CHECK_OK(sl_chart_reference_read(path, back, &sp, &err), &err);
    CHECK(sp == SL_CHART_SPACE_XYZ_D50);
    double worst = 0;
    for (int p = 0; p < 24; p++)
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(back[p][c] - ref[p][c]));
    printf("  XYZ D50 round trip: worst %.2e\n", worst);
    CHECK(worst < 1e-9);
}

static void test_bad_files(void)
{
    double ref[24][3];
    sl_error err;
    CHECK_RESULT(sl_chart_reference_read(sl_test_path("nope.csv"), ref, NULL, &err),
                 SL_ERR_NOT_FOUND, &err);
    CHECK(strstr(err.message, "nope.csv") != NULL);
    const char *path = sl_test_path("short.csv");
    write_text(path, "R,G,B\n0.1,0.1,0.1\n0.2,0.2,0.2\n");
    CHECK_RESULT(sl_chart_reference_read(path, ref, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "short.csv") && strstr(err.message, "24"));
    path = sl_test_path("word.csv");
    write_text(path, "R,G,B\n0.1,zero,0.1\n");
    CHECK_RESULT(sl_chart_reference_read(path, ref, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "word.csv:2") && strstr(err.message, "zero"));
    path = sl_test_path("header.csv");
    write_text(path, "H,S,V\n");
    CHECK_RESULT(sl_chart_reference_read(path, ref, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "header.csv:1") != NULL);
    path = sl_test_path("bad.json");
    write_text(path, "{\"space\": \"hsv\", \"patches\": []}");
    CHECK_RESULT(sl_chart_reference_read(path, ref, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "bad.json") && strstr(err.message, "space"));
    path = sl_test_path("trunc.json");
    write_text(path, "{\"space\": \"lab_d50\", \"patches\": [[1, 2");
    CHECK_RESULT(sl_chart_reference_read(path, ref, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "trunc.json") != NULL);
}

int main(void)
{
    RUN(test_lab_csv);
    RUN(test_rgb_json_and_xyz);
    RUN(test_bad_files);
    return sl_test_finish();
}
