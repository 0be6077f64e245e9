/* SPDX-License-Identifier: BSD-3-Clause */
/* Colour math against published reference values, and OpenColorIO
 * conversions through the shipped config. */
#include <stdlib.h>
#include <string.h>

#include "testing.h"

static void mat_of(void (*f)(const double[3], double[3]), double m[3][3])
{
    for (int c = 0; c < 3; c++) {
        double in[3] = {0, 0, 0}, out[3];
        in[c] = 1.0;
        f(in, out);
        for (int r = 0; r < 3; r++)
            m[r][c] = out[r];
    }
}

static void check_matrix(const double got[3][3], const double want[3][3], double tol)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(got[r][c], want[r][c], tol);
}

static void test_srgb_curve(void)
{
    /* ((0.5 + 0.055) / 1.055)^2.4 and 1.055 * 0.18^(1/2.4) - 0.055 */
    CHECK_NEAR(sl_srgb_to_linear(0.5f), 0.214041140, 1e-7);
    CHECK_NEAR(sl_linear_to_srgb(0.18f), 0.461356129, 1e-7);
    CHECK_NEAR(sl_srgb_to_linear(0.02f), 0.02 / 12.92, 1e-9);
    CHECK_NEAR(sl_linear_to_srgb(0.002f), 0.002 * 12.92, 1e-8);
    CHECK(sl_srgb_to_linear(0.0f) == 0.0f);
    CHECK_NEAR(sl_srgb_to_linear(1.0f), 1.0, 1e-7);
    CHECK_NEAR(sl_linear_to_srgb(1.0f), 1.0, 1e-7);
    /* IEC 61966-2-1's rounded breakpoints leave a jump of about 1.4e-7 at
     * 0.04045 encoded and 1e-8 at 0.0031308 linear; nothing larger. */
    CHECK_NEAR(sl_srgb_to_linear(nextafterf(0.04045f, 0.0f)),
               sl_srgb_to_linear(nextafterf(0.04045f, 1.0f)), 2e-7);
    CHECK_NEAR(sl_linear_to_srgb(nextafterf(0.0031308f, 0.0f)),
               sl_linear_to_srgb(nextafterf(0.0031308f, 1.0f)), 5e-8);
    /* Round trip, including negative and HDR values, to float precision. */
    double worst = 0.0;
    for (int i = -100; i <= 2000; i++) {
        float v = (float)i / 100.0f;
        float back = sl_srgb_to_linear(sl_linear_to_srgb(v));
        double rel = fabs((double)back - v) / fmax(fabs((double)v), 1e-3);
        worst = fmax(worst, rel);
    }
    CHECK_MSG(worst < 1e-6, "sRGB round trip relative error %.3g", worst);
    /* Monotonic over [0, 1]. */
    bool monotonic = true;
    for (int i = 1; i <= 4096; i++)
        if (sl_linear_to_srgb((float)i / 4096.0f) <= sl_linear_to_srgb((float)(i - 1) / 4096.0f))
            monotonic = false;
    CHECK(monotonic);
}

static void test_rec709_xyz(void)
{
    double m[3][3], inv[3][3];
    mat_of(sl_rec709_to_xyz, m);
    mat_of(sl_xyz_to_rec709, inv);
    /* The matrix from BT.709 primaries and D65 xy, to 8 decimals
     * (Wikipedia "sRGB", reverse transformation; colour-science). */
    static const double exact[3][3] = {
        {0.41239080, 0.35758434, 0.18048079},
        {0.21263901, 0.71516868, 0.07219232},
        {0.01933082, 0.11919478, 0.95053215},
    };
    static const double exact_inv[3][3] = {
        {3.24096994, -1.53738318, -0.49861076},
        {-0.96924364, 1.87596750, 0.04155506},
        {0.05563008, -0.20397696, 1.05697151},
    };
    check_matrix(m, exact, 6e-9);
    check_matrix(inv, exact_inv, 6e-9);
    /* IEC 61966-2-1:1999 equation (F.7), rounded to 4 decimals. */
    static const double iec[3][3] = {
        {0.4124, 0.3576, 0.1805},
        {0.2126, 0.7152, 0.0722},
        {0.0193, 0.1192, 0.9505},
    };
    check_matrix(m, iec, 1e-4);
    /* White maps to D65 and back. */
    double one[3] = {1, 1, 1}, w[3], back[3];
    sl_rec709_to_xyz(one, w);
    for (int i = 0; i < 3; i++)
        CHECK_NEAR(w[i], SL_WHITE_D65[i], 1e-15);
    CHECK_NEAR(SL_WHITE_D65[0], 0.95045592705167, 1e-14); /* OCIO's WHITEPOINT::D65_XYZ */
    CHECK_NEAR(SL_WHITE_D65[2], 1.08905775075988, 1e-14);
    /* Round trips. */
    double worst = 0.0;
    for (int i = 0; i < 100; i++) {
        double rgb[3] = {sin(i) * 3.0, cos(0.7 * i) * 10.0, 0.01 * i}, xyz[3];
        sl_rec709_to_xyz(rgb, xyz);
        sl_xyz_to_rec709(xyz, back);
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(back[c] - rgb[c]));
    }
    CHECK_MSG(worst < 1e-12, "RGB->XYZ->RGB error %.3g", worst);
}

static void test_bradford(void)
{
    /* Lindbloom, "Chromatic Adaptation", Bradford D65 -> D50 with his
     * ASTM E308 whites D65 (0.95047, 1, 1.08883), D50 (0.96422, 1, 0.82521). */
    static const double d65[3] = {0.95047, 1.0, 1.08883}, d50[3] = {0.96422, 1.0, 0.82521};
    static const double lindbloom[3][3] = {
        {1.0478112, 0.0228866, -0.0501270},
        {0.0295424, 0.9904844, -0.0170491},
        {-0.0092345, 0.0150436, 0.7521316},
    };
    static const double lindbloom_inv[3][3] = {
        {0.9555766, -0.0230393, 0.0631636},
        {-0.0282895, 1.0099416, 0.0210077},
        {0.0122982, -0.0204830, 1.3299098},
    };
    double m[3][3], mi[3][3];
    sl_bradford(d65, d50, m);
    sl_bradford(d50, d65, mi);
    check_matrix(m, lindbloom, 1e-6);
    check_matrix(mi, lindbloom_inv, 1e-6);
    /* Source white lands exactly on the destination white; same white is identity. */
    double w[3];
    for (int r = 0; r < 3; r++)
        w[r] = m[r][0] * d65[0] + m[r][1] * d65[1] + m[r][2] * d65[2];
    for (int i = 0; i < 3; i++)
        CHECK_NEAR(w[i], d50[i], 1e-14);
    double id[3][3];
    sl_bradford(SL_WHITE_D50, SL_WHITE_D50, id);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(id[r][c], r == c ? 1.0 : 0.0, 1e-14);
}

static void test_lab(void)
{
    double lab[3], xyz[3];
    sl_xyz_to_lab(SL_WHITE_D65, SL_WHITE_D65, lab);
    CHECK_NEAR(lab[0], 100.0, 1e-12);
    CHECK_NEAR(lab[1], 0.0, 1e-12);
    CHECK_NEAR(lab[2], 0.0, 1e-12);
    /* sRGB red in Lab D65: (53.24, 80.09, 67.20), e.g. Lindbloom's calculator
     * and colour-science; the published figures use ASTM D65, ours the xy
     * white, which moves them by less than 0.01. */
    double red[3] = {1, 0, 0};
    sl_rec709_to_xyz(red, xyz);
    sl_xyz_to_lab(xyz, SL_WHITE_D65, lab);
    printf("  sRGB red in Lab D65: %.4f %.4f %.4f\n", lab[0], lab[1], lab[2]);
    CHECK_NEAR(lab[0], 53.24, 0.01);
    CHECK_NEAR(lab[1], 80.09, 0.01);
    CHECK_NEAR(lab[2], 67.20, 0.01);
    /* 18% grey: Y = 0.18 gives L* = 116 * 0.18^(1/3) - 16 = 49.4961. */
    double grey[3] = {0.18 * SL_WHITE_D65[0], 0.18, 0.18 * SL_WHITE_D65[2]};
    sl_xyz_to_lab(grey, SL_WHITE_D65, lab);
    CHECK_NEAR(lab[0], 49.49610, 1e-4);
    CHECK_NEAR(lab[1], 0.0, 1e-12);
    /* Below the CIE epsilon the linear segment applies: L* = kappa * Y. */
    double dark[3] = {0.001 * SL_WHITE_D50[0], 0.001, 0.001 * SL_WHITE_D50[2]};
    sl_xyz_to_lab(dark, SL_WHITE_D50, lab);
    CHECK_NEAR(lab[0], 24389.0 / 27.0 * 0.001, 1e-12);
    /* Round trips on both sides of epsilon. */
    double worst = 0.0;
    for (int i = 0; i < 200; i++) {
        double p[3] = {0.0005 + 0.005 * i, 0.0003 + 0.004 * i * (i % 3), 0.0002 * i * i};
        double back[3];
        sl_xyz_to_lab(p, SL_WHITE_D50, lab);
        sl_lab_to_xyz(lab, SL_WHITE_D50, back);
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(back[c] - p[c]));
    }
    CHECK_MSG(worst < 1e-12, "XYZ->Lab->XYZ error %.3g", worst);
}

static void test_ciede2000_sharma(void)
{
    /* Sharma, Wu, Dalal (2005), Table 1: L1 a1 b1 L2 a2 b2 dE00, all 34 pairs
     * (also ciede2000testdata.txt on Sharma's Rochester page). */
    static const double t[34][7] = {
        {50.0000, 2.6772, -79.7751, 50.0000, 0.0000, -82.7485, 2.0425},
        {50.0000, 3.1571, -77.2803, 50.0000, 0.0000, -82.7485, 2.8615},
        {50.0000, 2.8361, -74.0200, 50.0000, 0.0000, -82.7485, 3.4412},
        {50.0000, -1.3802, -84.2814, 50.0000, 0.0000, -82.7485, 1.0000},
        {50.0000, -1.1848, -84.8006, 50.0000, 0.0000, -82.7485, 1.0000},
        {50.0000, -0.9009, -85.5211, 50.0000, 0.0000, -82.7485, 1.0000},
        {50.0000, 0.0000, 0.0000, 50.0000, -1.0000, 2.0000, 2.3669},
        {50.0000, -1.0000, 2.0000, 50.0000, 0.0000, 0.0000, 2.3669},
        {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0009, 7.1792},
        {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0010, 7.1792},
        {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0011, 7.2195},
        {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0012, 7.2195},
        {50.0000, -0.0010, 2.4900, 50.0000, 0.0009, -2.4900, 4.8045},
        {50.0000, -0.0010, 2.4900, 50.0000, 0.0010, -2.4900, 4.8045},
        {50.0000, -0.0010, 2.4900, 50.0000, 0.0011, -2.4900, 4.7461},
        {50.0000, 2.5000, 0.0000, 50.0000, 0.0000, -2.5000, 4.3065},
        {50.0000, 2.5000, 0.0000, 73.0000, 25.0000, -18.0000, 27.1492},
        {50.0000, 2.5000, 0.0000, 61.0000, -5.0000, 29.0000, 22.8977},
        {50.0000, 2.5000, 0.0000, 56.0000, -27.0000, -3.0000, 31.9030},
        {50.0000, 2.5000, 0.0000, 58.0000, 24.0000, 15.0000, 19.4535},
        {50.0000, 2.5000, 0.0000, 50.0000, 3.1736, 0.5854, 1.0000},
        {50.0000, 2.5000, 0.0000, 50.0000, 3.2972, 0.0000, 1.0000},
        {50.0000, 2.5000, 0.0000, 50.0000, 1.8634, 0.5757, 1.0000},
        {50.0000, 2.5000, 0.0000, 50.0000, 3.2592, 0.3350, 1.0000},
        {60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644},
        {63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630},
        {61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731},
        {35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645},
        {22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373},
        {36.4612, 47.8580, 18.3852, 36.2715, 50.5065, 21.2231, 1.4146},
        {90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441},
        {90.9257, -0.5406, -0.9208, 88.6381, -0.8985, -0.7239, 1.5381},
        {6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377},
        {2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082},
    };
    double worst = 0.0;
    for (int i = 0; i < 34; i++) {
        double d = sl_ciede2000(&t[i][0], &t[i][3]);
        double d_swapped = sl_ciede2000(&t[i][3], &t[i][0]);
        CHECK_MSG(fabs(d - t[i][6]) <= 1e-4, "pair %d: %.6f vs %.4f", i + 1, d, t[i][6]);
        CHECK_NEAR(d, d_swapped, 1e-12); /* the formula is symmetric */
        worst = fmax(worst, fabs(d - t[i][6]));
    }
    printf("  CIEDE2000 worst |error| over 34 pairs: %.2e\n", worst);
    double same[3] = {40, 10, -20};
    CHECK(sl_ciede2000(same, same) == 0.0);
}

/* ---------------- OpenColorIO ---------------- */

static void make_image(sl_image *img, int w, int h, int channels, size_t pad)
{
    sl_error err;
    CHECK_OK(sl_image_alloc(img, w, h, channels, &err), &err);
    if (pad) {
        /* Re-lay the rows with padding after each to exercise the stride. */
        free(img->data);
        img->stride = (size_t)w * (size_t)channels + pad;
        img->data = malloc(img->stride * (size_t)h * sizeof(float));
        for (size_t i = 0; i < img->stride * (size_t)h; i++)
            img->data[i] = 12345.0f;
    }
}

static void test_ocio_names(void)
{
    const char *path = sl_color_config_path();
    CHECK(path && strstr(path, "config.ocio") != NULL);
    CHECK(sl_test_file_exists(path));

    const char *const *list = sl_color_space_list();
    int n = 0;
    bool have_acescg = false;
    for (; list[n]; n++)
        have_acescg |= strcmp(list[n], "acescg") == 0;
    CHECK(n == 10);
    CHECK(n > 0 && strcmp(list[0], "lin_rec709") == 0);
    CHECK(have_acescg);

    static const char *const pairs[][2] = {
        {"lin_rec709", "lin_rec709"}, {"linear", "lin_rec709"},
        {"Linear Rec.709 (sRGB)", "lin_rec709"}, {"LIN_SRGB", "lin_rec709"},
        {"scene_linear", "lin_rec709"}, /* role */
        {"sRGB - Texture", "srgb"}, {"srgb_texture", "srgb"}, {"SRGB", "srgb"},
        {"ACEScg", "acescg"}, {"ACES2065-1", "aces2065-1"}, {"aces", "aces2065-1"},
        {"acescct", "acescct"}, {"compositing_log", "acescct"},
        {"cie_xyz_d65", "cie_xyz_d65"}, {"data", "raw"}, {"Raw", "raw"},
    };
    for (size_t i = 0; i < sizeof pairs / sizeof pairs[0]; i++) {
        const char *got = sl_color_space_name(pairs[i][0]);
        CHECK_MSG(got && strcmp(got, pairs[i][1]) == 0, "'%s' -> '%s', expected '%s'",
                  pairs[i][0], got ? got : "(null)", pairs[i][1]);
    }
    CHECK(sl_color_space_name("xyz") == NULL);
    CHECK(sl_color_space_name("") == NULL);
    CHECK(sl_color_space_name(NULL) == NULL);
}

/* Converts the unit vectors and returns the matrix (row = output channel). */
static void ocio_matrix(const char *from, const char *to, double m[3][3])
{
    sl_image img;
    sl_error err;
    make_image(&img, 3, 1, 3, 0);
    for (int p = 0; p < 3; p++)
        for (int c = 0; c < 3; c++)
            img.data[p * 3 + c] = p == c ? 1.0f : 0.0f;
    CHECK_OK(sl_color_convert(&img, from, to, &err), &err);
    for (int p = 0; p < 3; p++)
        for (int c = 0; c < 3; c++)
            m[c][p] = img.data[p * 3 + c];
    sl_image_free(&img);
}

static void test_ocio_matrices(void)
{
    /* Rec.709 -> ACEScg (AP1) with Bradford D65 -> ACES white: colour-science
     * matrix_RGB_to_RGB(sRGB, ACEScg, "Bradford"), the matrix of OCIO's
     * "UTILITY - ACES-AP1_to_LINEAR-REC709_BFD" and the ACES CG config. The
     * 4-decimal figures 0.6131 0.3395 0.0474 / 0.0702 0.9164 0.0134 /
     * 0.0206 0.1096 0.8698 round these; CAT02 would differ in the 4th decimal. */
    static const double to_ap1[3][3] = {
        {0.6130974024, 0.3395231462, 0.0473794514},
        {0.0701937225, 0.9163538791, 0.0134523985},
        {0.0206155929, 0.1095697729, 0.8698146342},
    };
    /* Rec.709 -> ACES2065-1 (AP0), Bradford: the "Linear Rec.709 (sRGB)"
     * matrix of OCIO's ACES CG config (cg-config-v1.0.0_aces-v1.3_ocio-v2.1). */
    static const double to_ap0[3][3] = {
        {0.439632981919491, 0.382988698151554, 0.177378319928955},
        {0.0897764429588424, 0.813439428748981, 0.0967841282921771},
        {0.0175411703831727, 0.111546553302387, 0.87091227631444},
    };
    /* ACEScg -> Rec.709, the inverse (same sources). */
    static const double from_ap1[3][3] = {
        {1.7050509927, -0.6217921207, -0.0832588720},
        {-0.1302564175, 1.1408047366, -0.0105483191},
        {-0.0240033568, -0.1289689761, 1.1529723329},
    };
    double m[3][3];
    /* float32 processing: a few ulps of the largest entry. */
    ocio_matrix("lin_rec709", "acescg", m);
    check_matrix(m, to_ap1, 1e-6);
    ocio_matrix("lin_rec709", "aces2065-1", m);
    check_matrix(m, to_ap0, 1e-6);
    ocio_matrix("ACEScg", "linear", m);
    check_matrix(m, from_ap1, 2e-6);
    /* The XYZ space agrees with the pure-C Rec.709 matrix (the Bradford
     * steps to ACES white and back cancel). */
    double c[3][3];
    mat_of(sl_rec709_to_xyz, c);
    ocio_matrix("lin_rec709", "cie_xyz_d65", m);
    check_matrix(m, c, 1e-6);
}

static void test_ocio_srgb(void)
{
    sl_error err;
    sl_image img;
    const int n = 4097; /* [0, 2] in steps of 1/2048 */
    make_image(&img, n, 1, 3, 0);
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            img.data[i * 3 + c] = (float)i / 2048.0f;
    CHECK_OK(sl_color_convert(&img, "lin_rec709", "srgb", &err), &err);
    /* OCIO's ExponentWithLinearTransform (as in the ACES configs) puts the
     * breakpoint where the pieces meet with equal slope (12.9232 below
     * 0.00304) instead of IEC's rounded 12.92 below 0.0031308: the curves
     * differ by up to 9.8e-6 near there, by float rounding elsewhere. */
    double worst_low = 0.0, worst = 0.0;
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            double d = fabs(img.data[i * 3 + c] - sl_linear_to_srgb((float)i / 2048.0f));
            if (i <= 20)
                worst_low = fmax(worst_low, d);
            else
                worst = fmax(worst, d);
        }
    printf("  lin_rec709 -> srgb vs sl_linear_to_srgb: worst %.2e below 0.01, %.2e on [0.01,2]\n",
           worst_low, worst);
    CHECK_MSG(worst_low < 1.1e-5, "OCIO sRGB differs from IEC curve by %.3g", worst_low);
    CHECK_MSG(worst < 5e-7, "OCIO sRGB differs from IEC curve by %.3g", worst);
    CHECK_OK(sl_color_convert(&img, "srgb", "lin_rec709", &err), &err);
    worst = 0.0;
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            double v = (double)i / 2048.0;
            worst = fmax(worst, fabs(img.data[i * 3 + c] - v) / fmax(v, 1e-3));
        }
    printf("  lin_rec709 -> srgb -> lin_rec709 relative error: %.2e\n", worst);
    CHECK_MSG(worst < 2e-6, "sRGB round trip relative error %.3g", worst);
    sl_image_free(&img);

    /* Encoded 0.5 decodes to 0.2140 linear; negative values continue the
     * linear segment (slope 12.9232 in OCIO, 12.92 in IEC) in both. */
    make_image(&img, 1, 1, 3, 0);
    img.data[0] = img.data[1] = 0.5f;
    img.data[2] = -0.1f;
    CHECK_OK(sl_color_convert(&img, "sRGB - Texture", "scene_linear", &err), &err);
    CHECK_NEAR(img.data[0], 0.214041140, 1e-6);
    CHECK_NEAR(img.data[2], sl_srgb_to_linear(-0.1f), 2e-5);
    sl_image_free(&img);
}

static void test_ocio_rgba_and_stride(void)
{
    sl_error err;
    sl_image dense, padded;
    const int w = 7, h = 5;
    make_image(&dense, w, h, 4, 0);
    make_image(&padded, w, h, 4, 3);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float v[4] = {0.1f * (float)x, 0.05f * (float)y + 0.3f, 2.0f - 0.2f * (float)x,
                          (float)(x - y) * 0.75f};
            memcpy(sl_image_pixel(&dense, x, y), v, sizeof v);
            memcpy(sl_image_pixel(&padded, x, y), v, sizeof v);
        }
    sl_image orig;
    CHECK_OK(sl_image_copy(&dense, &orig, &err), &err);
    CHECK_OK(sl_color_convert(&dense, "lin_rec709", "acescg", &err), &err);
    CHECK_OK(sl_color_convert(&padded, "lin_rec709", "acescg", &err), &err);
    bool alpha_same = true, stride_same = true, padding_kept = true, changed = false;
    for (int y = 0; y < h; y++) {
        for (int x = 0; x < w; x++) {
            const float *d = sl_image_pixel(&dense, x, y), *p = sl_image_pixel(&padded, x, y);
            const float *o = sl_image_pixel(&orig, x, y);
            alpha_same &= d[3] == o[3] && p[3] == o[3];
            stride_same &= memcmp(d, p, 4 * sizeof(float)) == 0;
            changed |= fabsf(d[0] - o[0]) > 1e-3f;
        }
        for (size_t k = (size_t)w * 4; k < padded.stride; k++)
            padding_kept &= padded.data[(size_t)y * padded.stride + k] == 12345.0f;
    }
    CHECK(alpha_same);
    CHECK(stride_same);
    CHECK(padding_kept);
    CHECK(changed);
    /* Pixel (3, 2) through the published matrix. */
    static const double to_ap1[3][3] = {
        {0.6130974024, 0.3395231462, 0.0473794514},
        {0.0701937225, 0.9163538791, 0.0134523985},
        {0.0206155929, 0.1095697729, 0.8698146342},
    };
    const float *o = sl_image_pixel(&orig, 3, 2), *d = sl_image_pixel(&dense, 3, 2);
    for (int r = 0; r < 3; r++)
        CHECK_NEAR(d[r], to_ap1[r][0] * o[0] + to_ap1[r][1] * o[1] + to_ap1[r][2] * o[2], 2e-6);
    sl_image_free(&dense);
    sl_image_free(&padded);
    sl_image_free(&orig);
}

static void test_ocio_errors(void)
{
    sl_error err;
    sl_image img;
    make_image(&img, 2, 2, 3, 0);
    sl_image_fill(&img, 0.5f);
    CHECK_RESULT(sl_color_convert(&img, "xyz", "acescg", &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "'xyz'") != NULL);
    CHECK(strstr(err.message, "lin_rec709, srgb, acescg") != NULL);
    CHECK(strstr(err.message, "raw") != NULL);
    CHECK_RESULT(sl_color_convert(&img, "acescg", "nope", &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "'nope'") != NULL);
    CHECK_RESULT(sl_color_convert(&img, NULL, "acescg", &err), SL_ERR_USAGE, &err);
    bool untouched = true;
    for (int i = 0; i < 12; i++)
        untouched &= img.data[i] == 0.5f;
    CHECK(untouched);
    /* Data is never converted; same space is a no-op. */
    CHECK_OK(sl_color_convert(&img, "raw", "srgb", &err), &err);
    CHECK_OK(sl_color_convert(&img, "acescg", "ACEScg", &err), &err);
    for (int i = 0; i < 12; i++)
        untouched &= img.data[i] == 0.5f;
    CHECK(untouched);
    sl_image_free(&img);

    /* One or two channels are refused rather than guessed at. */
    make_image(&img, 2, 2, 1, 0);
    CHECK_RESULT(sl_color_convert(&img, "srgb", "lin_rec709", &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "1 channel") != NULL);
    sl_image_free(&img);
    sl_image empty = {0};
    CHECK_RESULT(sl_color_convert(&empty, "srgb", "lin_rec709", &err), SL_ERR_USAGE, &err);
}

static void test_ocio_config_override(void)
{
    sl_error err;
    sl_image img;
    make_image(&img, 2, 1, 3, 0);
    sl_image_fill(&img, 0.25f);

    const char *missing = sl_test_path("missing/config.ocio");
    setenv("SETLIGHT_OCIO_CONFIG", missing, 1);
    CHECK(strcmp(sl_color_config_path(), missing) == 0);
    CHECK_RESULT(sl_color_convert(&img, "lin_rec709", "acescg", &err), SL_ERR_NOT_FOUND, &err);
    CHECK(strstr(err.message, missing) != NULL);
    CHECK(strstr(err.message, "SETLIGHT_OCIO_CONFIG") != NULL);
    CHECK(sl_color_convert(&img, "lin_rec709", "acescg", NULL) == SL_ERR_NOT_FOUND);
    CHECK(img.data[0] == 0.25f);
    CHECK(sl_color_space_name("lin_rec709") == NULL);
    CHECK(sl_color_space_list()[0] == NULL);

    const char *broken = sl_test_path("broken.ocio");
    static const char garbage[] = "ocio_profile_version: 2.1\ncolorspaces: [this is not\n";
    CHECK_OK(sl_write_file_atomic(broken, garbage, sizeof garbage - 1, &err), &err);
    setenv("SETLIGHT_OCIO_CONFIG", broken, 1);
    CHECK_RESULT(sl_color_convert(&img, "lin_rec709", "acescg", &err), SL_ERR_INPUT, &err);
    CHECK(strncmp(err.message, broken, strlen(broken)) == 0);
    CHECK(img.data[0] == 0.25f);

    /* A user config: its own names, loaded next to the shipped one. */
    const char *mine = sl_test_path("mine.ocio");
    static const char config[] =
        "ocio_profile_version: 2.1\n"
        "roles:\n  default: lin\n  scene_linear: lin\n  data: lin\n"
        "displays:\n  d:\n    - !<View> {name: v, colorspace: lin}\n"
        "colorspaces:\n"
        "  - !<ColorSpace>\n    name: lin\n"
        "  - !<ColorSpace>\n    name: twice\n"
        "    to_scene_reference: !<MatrixTransform> {matrix: [0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, "
        "0, 0.5, 0, 0, 0, 0, 1]}\n";
    CHECK_OK(sl_write_file_atomic(mine, config, sizeof config - 1, &err), &err);
    setenv("SETLIGHT_OCIO_CONFIG", mine, 1);
    CHECK_OK(sl_color_convert(&img, "lin", "twice", &err), &err);
    CHECK_NEAR(img.data[0], 0.5, 1e-7);
    CHECK(sl_color_space_name("TWICE") != NULL);
    CHECK(sl_color_space_name("acescg") == NULL);
    CHECK_RESULT(sl_color_convert(&img, "lin", "acescg", &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "known: lin, twice") != NULL);

    unsetenv("SETLIGHT_OCIO_CONFIG");
    CHECK(strcmp(sl_color_space_name("aces"), "aces2065-1") == 0);
    CHECK_OK(sl_color_convert(&img, "lin_rec709", "lin_rec709", &err), &err);
    sl_image_free(&img);
}

static void test_ocio_threads_deterministic(void)
{
    sl_error err;
    sl_image a, b;
    const int w = 400, h = 300; /* several 64k-pixel chunks */
    make_image(&a, w, h, 3, 0);
    for (size_t i = 0; i < (size_t)w * h * 3; i++)
        a.data[i] = (float)((i * 2654435761u) % 100000u) / 25000.0f;
    CHECK_OK(sl_image_copy(&a, &b, &err), &err);
    sl_threads_set(1);
    CHECK_OK(sl_color_convert(&a, "lin_rec709", "srgb", &err), &err);
    sl_threads_set(4);
    CHECK_OK(sl_color_convert(&b, "lin_rec709", "srgb", &err), &err);
    sl_threads_set(0);
    CHECK(memcmp(a.data, b.data, (size_t)w * h * 3 * sizeof(float)) == 0);
    sl_image_free(&a);
    sl_image_free(&b);
}

int main(void)
{
    RUN(test_srgb_curve);
    RUN(test_rec709_xyz);
    RUN(test_bradford);
    RUN(test_lab);
    RUN(test_ciede2000_sharma);
    RUN(test_ocio_names);
    RUN(test_ocio_matrices);
    RUN(test_ocio_srgb);
    RUN(test_ocio_rgba_and_stride);
    RUN(test_ocio_errors);
    RUN(test_ocio_config_override);
    RUN(test_ocio_threads_deterministic);
    return sl_test_finish();
}
