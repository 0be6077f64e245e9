/* SPDX-License-Identifier: BSD-3-Clause */
/* Colour math in double precision: the sRGB transfer curve, Rec.709 <-> XYZ,
 * Bradford adaptation, CIELAB and CIEDE2000. Image conversions between named
 * colour spaces go through OpenColorIO (ocio_cxx.cpp). */
#include "setlight/core.h"

#include <math.h>
#include <pthread.h>

/* White points as XYZ (Y = 1) from their CIE 1931 xy chromaticities, the same
 * way OpenColorIO builds its builtin matrices, so our math and the OCIO config
 * agree: D65 (0.3127, 0.3290) per ITU-R BT.709 and IEC 61966-2-1,
 * D50 (0.3457, 0.3585) per ISO 3664 / ICC. */
const double SL_WHITE_D65[3] = {0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290};
const double SL_WHITE_D50[3] = {0.3457 / 0.3585, 1.0, (1.0 - 0.3457 - 0.3585) / 0.3585};

/* IEC 61966-2-1: linear segment of slope 12.92 below 0.0031308 (encoded
 * 0.04045), 1.055 v^(1/2.4) - 0.055 above. Negative values continue the
 * linear segment and values above 1 the power law, so HDR data round-trips. */
float sl_srgb_to_linear(float v)
{
    double e = v;
    if (e <= 0.04045)
        return (float)(e / 12.92);
    return (float)pow((e + 0.055) / 1.055, 2.4);
}

float sl_linear_to_srgb(float v)
{
    double l = v;
    if (l <= 0.0031308)
        return (float)(l * 12.92);
    return (float)(1.055 * pow(l, 1.0 / 2.4) - 0.055);
}

/* RGB -> XYZ from primaries and white chromaticities (SMPTE RP 177): the
 * columns are the primaries' xyz scaled so that RGB (1,1,1) gives white. */
static void rgb_to_xyz_from_xy(const double xy[4][2], double m[3][3])
{
    double p[3][3];
    for (int c = 0; c < 3; c++) {
        p[0][c] = xy[c][0] / xy[c][1];
        p[1][c] = 1.0;
        p[2][c] = (1.0 - xy[c][0] - xy[c][1]) / xy[c][1];
    }
    double w[3] = {xy[3][0] / xy[3][1], 1.0, (1.0 - xy[3][0] - xy[3][1]) / xy[3][1]};
    double pinv[3][3], s[3];
   sl_mat3_invert(p, pinv);
    sl_mat3_apply(pinv, w, s);
    for (int i = 0; i < 3; i++)
        for (int c = 0; c < 3; c++)
            m[i][c] = p[i][c] * s[c];
}

static double rec709_to_xyz_m[3][3], xyz_to_rec709_m[3][3];
static pthread_once_t rec709_once = PTHREAD_ONCE_INIT;

static void rec709_init(void)
{
    /* ITU-R BT.709-6 primaries, D65 white. */
    static const double xy[4][2] = {{0.64, 0.33}, {0.30, 0.60}, {0.15, 0.06}, {0.3127, 0.3290}};
    rgb_to_xyz_from_xy(xy, rec709_to_xyz_m);
   sl_mat3_invert(rec709_to_xyz_m, xyz_to_rec709_m);
}

void sl_chromaticities_to_rec709(const float xy[8], double m[3][3])
{
    const double p[4][2] = {{xy[0], xy[1]}, {xy[2], xy[3]}, {xy[4], xy[5]}, {xy[6], xy[7]}};
    const double white[3] = {xy[6] / xy[7], 1.0, (1.0 - xy[6] - xy[7]) / xy[7]};
    double to_xyz[3][3], adapt[3][3];
    pthread_once(&rec709_once, rec709_init);
    rgb_to_xyz_from_xy(p, to_xyz);
    sl_bradford(white, SL_WHITE_D65, adapt);
    sl_mat3_mul(adapt, to_xyz, m);
    sl_mat3_mul(xyz_to_rec709_m, m, m);
}

void sl_rec709_to_xyz(const double rgb[3], double xyz[3])
{
    pthread_once(&rec709_once, rec709_init);
    sl_mat3_apply(rec709_to_xyz_m, rgb, xyz);
}

void sl_xyz_to_rec709(const double xyz[3], double rgb[3])
{
    pthread_once(&rec709_once, rec709_init);
    sl_mat3_apply(xyz_to_rec709_m, xyz, rgb);
}

/* Bradford cone response (Lam 1985) with the 4-decimal coefficients that
 * Lindbloom, ICC v4 and OpenColorIO all use. */
void sl_bradford(const double src_white_xyz[3], const double dst_white_xyz[3], double m[3][3])
{
    static const double ma[3][3] = {
        {0.8951, 0.2664, -0.1614},
        {-0.7502, 1.7135, 0.0367},
        {0.0389, -0.0685, 1.0296},
    };
    double ma_inv[3][3], src[3], dst[3];
   sl_mat3_invert(ma, ma_inv);
    sl_mat3_apply(ma, src_white_xyz, src);
    sl_mat3_apply(ma, dst_white_xyz, dst);
    double scale[3][3] = {{dst[0] / src[0], 0, 0}, {0, dst[1] / src[1], 0}, {0, 0, dst[2] / src[2]}};
    sl_mat3_mul(scale, ma, m);
    sl_mat3_mul(ma_inv, m, m);
}

/* CIE 15:2004 with the exact rational constants (CIE 15 and Lindbloom)
 * instead of the rounded 0.008856 / 903.3, so Lab is continuous. */
#define LAB_EPSILON (216.0 / 24389.0)
#define LAB_KAPPA (24389.0 / 27.0)

static double lab_f(double t)
{
    return t > LAB_EPSILON ? cbrt(t) : (LAB_KAPPA * t + 16.0) / 116.0;
}

static double lab_f_inv(double f)
{
    double f3 = f * f * f;
    return f3 > LAB_EPSILON ? f3 : (116.0 * f - 16.0) / LAB_KAPPA;
}

void sl_xyz_to_lab(const double xyz[3], const double white[3], double lab[3])
{
    double fx = lab_f(xyz[0] / white[0]);
    double fy = lab_f(xyz[1] / white[1]);
    double fz = lab_f(xyz[2] / white[2]);
    lab[0] = 116.0 * fy - 16.0;
    lab[1] = 500.0 * (fx - fy);
    lab[2] = 200.0 * (fy - fz);
}

void sl_lab_to_xyz(const double lab[3], const double white[3], double xyz[3])
{
    double fy = (lab[0] + 16.0) / 116.0;
    double fx = fy + lab[1] / 500.0;
    double fz = fy - lab[2] / 200.0;
    double yr = lab[0] > LAB_KAPPA * LAB_EPSILON ? fy * fy * fy : lab[0] / LAB_KAPPA;
    xyz[0] = lab_f_inv(fx) * white[0];
    xyz[1] = yr * white[1];
    xyz[2] = lab_f_inv(fz) * white[2];
}

static double deg(double rad) { return rad * (180.0 / M_PI); }
static double rad(double deg) { return deg * (M_PI / 180.0); }

/* Sharma, Wu and Dalal, "The CIEDE2000 Color-Difference Formula:
 * Implementation Notes, Supplementary Test Data, and Mathematical
 * Observations", Color Res. Appl. 30(1), 2005, equations (1)-(17). */
double sl_ciede2000(const double lab1[3], const double lab2[3])
{
    const double pow25_7 = 6103515625.0; /* 25^7 */
    double c1 = hypot(lab1[1], lab1[2]);
    double c2 = hypot(lab2[1], lab2[2]);
    double cbar7 = pow(0.5 * (c1 + c2), 7.0);
    double g = 0.5 * (1.0 - sqrt(cbar7 / (cbar7 + pow25_7)));
    double a1p = (1.0 + g) * lab1[1];
    double a2p = (1.0 + g) * lab2[1];
    double c1p = hypot(a1p, lab1[2]);
    double c2p = hypot(a2p, lab2[2]);
    /* Hue is undefined for a neutral; eq. (4) sets it to 0. */
    double h1p = (a1p == 0.0 && lab1[2] == 0.0) ? 0.0 : deg(atan2(lab1[2], a1p));
    double h2p = (a2p == 0.0 && lab2[2] == 0.0) ? 0.0 : deg(atan2(lab2[2], a2p));
    if (h1p < 0.0)
        h1p += 360.0;
    if (h2p < 0.0)
        h2p += 360.0;

    double dlp = lab2[0] - lab1[0];
    double dcp = c2p - c1p;
    double cc = c1p * c2p;
    double dhp = 0.0;
    if (cc != 0.0) {
        dhp = h2p - h1p;
        if (dhp > 180.0)
            dhp -= 360.0;
        else if (dhp < -180.0)
            dhp += 360.0;
    }
    double dHp = 2.0 * sqrt(cc) * sin(rad(dhp) / 2.0);

    double lbarp = 0.5 * (lab1[0] + lab2[0]);
    double cbarp = 0.5 * (c1p + c2p);
    double hbarp = h1p + h2p;
    if (cc != 0.0) {
        if (fabs(h1p - h2p) <= 180.0)
            hbarp *= 0.5;
        else if (hbarp < 360.0)
            hbarp = 0.5 * (hbarp + 360.0);
        else
            hbarp = 0.5 * (hbarp - 360.0);
    }
    double t = 1.0 - 0.17 * cos(rad(hbarp - 30.0)) + 0.24 * cos(rad(2.0 * hbarp)) +
               0.32 * cos(rad(3.0 * hbarp + 6.0)) - 0.20 * cos(rad(4.0 * hbarp - 63.0));
    double dtheta = 30.0 * exp(-((hbarp - 275.0) / 25.0) * ((hbarp - 275.0) / 25.0));
    double cbarp7 = pow(cbarp, 7.0);
    double rc = 2.0 * sqrt(cbarp7 / (cbarp7 + pow25_7));
    double l50 = (lbarp - 50.0) * (lbarp - 50.0);
    double sl = 1.0 + 0.015 * l50 / sqrt(20.0 + l50);
    double sc = 1.0 + 0.045 * cbarp;
    double sh = 1.0 + 0.015 * cbarp * t;
    double rt = -sin(rad(2.0 * dtheta)) * rc;
    double tl = dlp / sl, tc = dcp / sc, th = dHp / sh;
    return sqrt(tl * tl + tc * tc + th * th + rt * tc * th);
}
