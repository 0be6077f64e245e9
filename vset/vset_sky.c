/* SPDX-License-Identifier: BSD-3-Clause */
/* Daylight for the virtual set: the Preetham, Shirley and Smits (1999)
 * analytic sky, a sun whose radiance comes from extraterrestrial
 * illuminance dimmed along the air mass, a textured ground lit by both,
 * black-body colours, and the procedural noise used for textures. */
#include <math.h>
#include <string.h>

#include "vset_internal.h"

/* Extraterrestrial solar illuminance (lux) and the ground observer's
 * camera height (m) over the ground plane. */
#define SUN_E0_LUX 128000.0
#define GROUND_HEIGHT_M 1.6

static double luminance(const double rgb[3])
{
    return 0.2126390059 * rgb[0] + 0.7151686788 * rgb[1] + 0.0721923154 * rgb[2];
}

void sl_vset_kelvin_rgb(double kelvin, double rgb[3])
{
    double t = kelvin < 1667 ? 1667 : kelvin > 25000 ? 25000 : kelvin;
    double t2 = t * t, t3 = t2 * t, x, y;
    if (t <= 4000)
        x = -0.2661239e9 / t3 - 0.2343589e6 / t2 + 0.8776956e3 / t + 0.179910;
    else
        x = -3.0258469e9 / t3 + 2.1070379e6 / t2 + 0.2226347e3 / t + 0.240390;
    double x2 = x * x, x3 = x2 * x;
    if (t <= 2222)
        y = -1.1063814 * x3 - 1.34811020 * x2 + 2.18555832 * x - 0.20219683;
    else if (t <= 4000)
        y = -0.9549476 * x3 - 1.37418593 * x2 + 2.09137015 * x - 0.16748867;
    else
        y = 3.0817580 * x3 - 5.87338670 * x2 + 3.75112997 * x - 0.37001483;
    double xyz[3] = {x / y, 1.0, (1.0 - x - y) / y};
    sl_xyz_to_rec709(xyz, rgb);
    for (int c = 0; c < 3; c++)
        if (rgb[c] < 0)
            rgb[c] = 0;
    double l = luminance(rgb);
    for (int c = 0; c < 3; c++)
        rgb[c] /= l;
}

void sl_vset_sun_radiance(double elevation_deg, double turbidity, double rgb[3])
{
    double el = elevation_deg < 0 ? 0 : elevation_deg;
    /* Kasten and Young (1989) relative optical air mass. */
    double m = 1.0 / (sin(el * VSET_DEG) + 0.50572 * pow(el + 6.07995, -1.6364));
    /* Angstrom turbidity from Preetham's relation, Rayleigh depth after
     * Leckner; effective wavelengths of the R, G, B channels in um. */
    double beta = 0.04608 * turbidity - 0.04586;
    static const double lambda[3] = {0.610, 0.550, 0.465};
    double r = 0.5 * VSET_SUN_DIAMETER_DEG * VSET_DEG;
    double omega = 2.0 * VSET_PI * (1.0 - cos(r));
    double l0 = SUN_E0_LUX / omega;
    double colour[3];
    sl_vset_kelvin_rgb(5778.0, colour);
    for (int c = 0; c < 3; c++) {
        double tau = 0.008735 * pow(lambda[c], -4.08) + beta * pow(lambda[c], -1.3);
        rgb[c] = l0 * colour[c] * exp(-m * tau);
    }
}

static double perez(const double k[5], double cos_theta, double gamma)
{
    double ct = cos_theta < 0.01 ? 0.01 : cos_theta;
    double cg = cos(gamma);
    return (1.0 + k[0] * exp(k[1] / ct)) * (1.0 + k[2] * exp(k[3] * gamma) + k[4] * cg * cg);
}

static void preetham_setup(vset_daylight *d)
{
    double t = d->turbidity;
    double ts = acos(d->sun_dir[1] > 1 ? 1 : d->sun_dir[1]);
    const double k[3][5] = {
        {0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, 0.1206 * t - 2.5771,
         -0.0670 * t + 0.3703},
        {-0.0193 * t - 0.2592, -0.0665 * t + 0.0008, -0.0004 * t + 0.2125, -0.0641 * t - 0.8989,
         -0.0033 * t + 0.0452},
        {-0.0167 * t - 0.2608, -0.0950 * t + 0.0092, -0.0079 * t + 0.2102, -0.0441 * t - 1.6537,
         -0.0109 * t + 0.0529}};
    memcpy(d->perez, k, sizeof k);
    double chi = (4.0 / 9.0 - t / 120.0) * (VSET_PI - 2.0 * ts);
    d->zenith[0] = 1000.0 * ((4.0453 * t - 4.9710) * tan(chi) - 0.2155 * t + 2.4192);
    double ts2 = ts * ts, ts3 = ts2 * ts, tt = t * t;
    d->zenith[1] = (0.00166 * ts3 - 0.00375 * ts2 + 0.00209 * ts) * tt +
                   (-0.02903 * ts3 + 0.06377 * ts2 - 0.03202 * ts + 0.00394) * t +
                   (0.11693 * ts3 - 0.21196 * ts2 + 0.06052 * ts + 0.25886);
    d->zenith[2] = (0.00275 * ts3 - 0.00610 * ts2 + 0.00317 * ts) * tt +
                   (-0.04214 * ts3 + 0.08970 * ts2 - 0.04153 * ts + 0.00516) * t +
                   (0.15346 * ts3 - 0.26756 * ts2 + 0.06670 * ts + 0.26688);
    for (int i = 0; i < 3; i++)
        d->norm[i] = perez(d->perez[i], 1.0, ts);
}

static void sky_radiance(const vset_daylight *d, const double dir[3], double rgb[3])
{
    double up[3] = {dir[0], dir[1] < 0 ? 0 : dir[1], dir[2]};
    v3_normalize(up);
    double cg = v3_dot(up, d->sun_dir);
    double gamma = acos(cg > 1 ? 1 : cg < -1 ? -1 : cg);
    double v[3];
    for (int i = 0; i < 3; i++)
        v[i] = d->zenith[i] * perez(d->perez[i], up[1], gamma) / d->norm[i];
    double Y = v[0] > 0 ? v[0] : 0, x = v[1], y = v[2];
    double xyz[3] = {x / y * Y, Y, (1.0 - x - y) / y * Y};
    sl_xyz_to_rec709(xyz, rgb);
    for (int c = 0; c < 3; c++)
        if (rgb[c] < 0)
            rgb[c] = 0;
}

void sl_vset_sky_radiance(const double sun_dir[3], double turbidity, const double dir[3],
                          double rgb[3])
{
    vset_daylight d;
    memset(&d, 0, sizeof d);
    memcpy(d.sun_dir, sun_dir, sizeof d.sun_dir);
    d.turbidity = turbidity;
    preetham_setup(&d);
    sky_radiance(&d, dir, rgb);
}

void vset_daylight_init(vset_daylight *d, double sun_az_deg, double sun_el_deg,
                        double turbidity, double ground_albedo)
{
    memset(d, 0, sizeof *d);
    vset_azel_dir(sun_az_deg, sun_el_deg, d->sun_dir);
    d->turbidity = turbidity;
    d->albedo = ground_albedo;
    preetham_setup(d);
    sl_vset_sun_radiance(sun_el_deg, turbidity, d->sun_rgb);
    /* Sky irradiance on the ground: midpoint rule over the hemisphere,
     * fine enough for lighting the ground "approximately". */
    const int nt = 32, np = 64;
    double sky[3] = {0, 0, 0};
    for (int i = 0; i < nt; i++) {
        double th = (i + 0.5) * (0.5 * VSET_PI / nt);
        double dw = sin(th) * (0.5 * VSET_PI / nt) * (2.0 * VSET_PI / np);
        for (int j = 0; j < np; j++) {
            double ph = (j + 0.5) * (2.0 * VSET_PI / np), dir[3], rgb[3];
            dir[0] = sin(th) * sin(ph);
            dir[1] = cos(th);
            dir[2] = sin(th) * cos(ph);
            sky_radiance(d, dir, rgb);
            for (int c = 0; c < 3; c++)
                sky[c] += rgb[c] * cos(th) * dw;
        }
    }
    double r = 0.5 * VSET_SUN_DIAMETER_DEG * VSET_DEG;
    double omega = 2.0 * VSET_PI * (1.0 - cos(r));
    double cs = d->sun_dir[1] > 0 ? d->sun_dir[1] : 0;
    for (int c = 0; c < 3; c++)
        d->ground_irr[c] = sky[c] + d->sun_rgb[c] * omega * cs;
}

void vset_daylight_radiance(const vset_daylight *d, const double dir[3], double rgb[3])
{
    if (dir[1] >= 0) {
        sky_radiance(d, dir, rgb);
        return;
    }
    /* Ground plane below the camera: grass and soil patches whose contrast
     * fades with distance so the horizon does not alias. */
    double dist = GROUND_HEIGHT_M / -dir[1];
    double px = dir[0] * dist, pz = dir[2] * dist;
    double fade = 1.0 / (1.0 + (dist / 40.0) * (dist / 40.0));
    double detail = vset_fbm(px * 0.8, pz * 0.8, 5, 11) - 0.5;
    double patch = vset_fbm(px * 0.07, pz * 0.07, 3, 12);
    static const double grass[3] = {0.75, 1.0, 0.45}, soil[3] = {1.15, 0.95, 0.75};
    double a = d->albedo * (1.0 + fade * 0.9 * detail);
    double mix = 0.5 + fade * (patch - 0.5) * 1.6;
    mix = mix < 0 ? 0 : mix > 1 ? 1 : mix;
    for (int c = 0; c < 3; c++) {
        double tint = mix * grass[c] + (1.0 - mix) * soil[c];
        rgb[c] = a * tint * d->ground_irr[c] / VSET_PI;
    }
}

static double lattice(int64_t ix, int64_t iy, uint64_t salt)
{
    return vset_uniform(salt, (uint64_t)ix * 0x9E3779B1ull, (uint64_t)iy);
}

double vset_value_noise(double x, double y, uint64_t salt)
{
    double fx = floor(x), fy = floor(y);
    int64_t ix = (int64_t)fx, iy = (int64_t)fy;
    double tx = x - fx, ty = y - fy;
    tx = tx * tx * (3.0 - 2.0 * tx);
    ty = ty * ty * (3.0 - 2.0 * ty);
    double a = lattice(ix, iy, salt), b = lattice(ix + 1, iy, salt);
    double c = lattice(ix, iy + 1, salt), e = lattice(ix + 1, iy + 1, salt);
    return (a + (b - a) * tx) + ((c + (e - c) * tx) - (a + (b - a) * tx)) * ty;
}

double vset_fbm(double x, double y, int octaves, uint64_t salt)
{
    double sum = 0, amp = 0.5, norm = 0;
    for (int i = 0; i < octaves; i++) {
        sum += amp * vset_value_noise(x, y, salt + (uint64_t)i);
        norm += amp;
        amp *= 0.5;
        x = 2.03 * x + 17.1;
        y = 2.03 * y - 5.3;
    }
    return sum / norm;
}
