/* SPDX-License-Identifier: BSD-3-Clause */
/* Fitting a light to a region: energy, direction, solid angle, shape from
 * second moments on the tangent plane; placement on a sphere or a room;
 * ranking and selection. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

const char *sl_rig_shape_name(sl_rig_shape s)
{
    switch (s) {
    case SL_RIG_RECT:
        return "rect";
    case SL_RIG_DISK:
        return "disk";
    case SL_RIG_SPHERE:
        return "sphere";
    case SL_RIG_DISTANT:
        return "distant";
    }
    return "?";
}

void sl_rig_options_default(sl_rig_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->method = SL_RIG_METHOD_REGIONS;
    opt->threshold = 8;
    opt->peak_fraction = 0.02;
    opt->max_solid_angle = 0.4;
    opt->energy = 0.9;
    opt->max_lights = 0;
    opt->merge_degrees = 2;
    opt->unresolved_degrees = 0.53;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void normalize(double v[3])
{
    double l = sqrt(dot(v, v));
    for (int i = 0; i < 3; i++)
        v[i] /= l;
}

/* Solid angle of a rectangle facing the viewer at unit distance, half-sides a, b. */
static double rect_solid_angle(double a, double b)
{
    return 4 * asin(a * b / sqrt((1 + a * a) * (1 + b * b)));
}

/* Disk of angular radius r: 2 pi (1 - cos r). */
static double cap_radius(double omega)
{
    double c = 1 - omega / (2 * M_PI);
    return acos(c < -1 ? -1 : c > 1 ? 1 : c);
}

/* Luminance of what the dome lost at (x, y); y outside the map: 0. */
static double lost_y(const sl_image *rgb, const sl_image *residual, int x, int y)
{
    if (y < 0 || y >= rgb->height)
        return 0;
    x = rig_wrap_x(x, rgb->width);
    const float *p = sl_image_pixel(rgb, x, y), *q = sl_image_pixel(residual, x, y);
    double e[3] = {(double)p[0] - q[0], (double)p[1] - q[1], (double)p[2] - q[2]};
    return sl_luminance(e);
}

/* Fraction of texel (x, y) the source covers, from its neighbours: a texel
 * at least `floor` whose 4 neighbours are all at least half as bright is
 * inside the source (whatever the source's gradient: a window's sky and
 * ground, a graded softbox); an edge texel shows the source over the
 * fraction its value is of the brightest texel around it (the source's local
 * level), and the soft-edge ring's noise over the fraction it is of floor. */
static double coverage(const sl_image *rgb, const sl_image *residual, int x, int y, double ly,
                       double floor_y)
{
    if (!(ly > 0))
        return 0;
    static const int n4[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    bool inside = ly >= floor_y;
    for (int k = 0; k < 4 && inside; k++) {
        int ny = y + n4[k][1];
        if (ny >= 0 && ny < rgb->height)
            inside = lost_y(rgb, residual, x + n4[k][0], ny) >= 0.5 * ly;
    }
    if (inside)
        return 1;
    double peak = fmax(ly, floor_y);
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++)
            peak = fmax(peak, lost_y(rgb, residual, x + dx, y + dy));
    return ly / peak;
}

/* Mean kurtosis of the marginals along the axes at phi and phi + 90
 * degrees, from the central moments (q: fourth, c: second, wsum: weight). */
static double rig_kurtosis2(const double q[5], double wsum, double cuu, double cuv, double cvv,
                            double phi)
{
    double k = 0;
    for (int i = 0; i < 2; i++, phi += M_PI / 2) {
        double c = cos(phi), s = sin(phi);
        double m4 = c * c * c * c * q[0] + 4 * c * c * c * s * q[1] + 6 * c * c * s * s * q[2] +
                    4 * c * s * s * s * q[3] + s * s * s * s * q[4];
        double m2 = c * c * cuu + 2 * c * s * cuv + s * s * cvv;
        k += 0.5 * (m4 / wsum) / (m2 * m2);
    }
    return k;
}

/* Texel i's solid angle times the fraction the source covers (ct[0]) and its
 * direction (ct[1..3]). */
static void covered(const sl_image *rgb, const sl_image *residual, int i, double floor_y,
                    double ct[4])
{
    int w = rgb->width, h = rgb->height, x = i % w, y = i / w;
    ct[0] = sl_latlong_texel_solid_angle(y, w, h) *
            coverage(rgb, residual, x, y, lost_y(rgb, residual, x, y), floor_y);
    rig_texel_dir(x, y, w, h, ct + 1);
}

bool rig_fit_region(const sl_image *rgb, const sl_image *residual, const int *texels, int count,
                    const sl_rig_options *opt, sl_rig_light *L)
{
    int w = rgb->width, h = rgb->height;
    memset(L, 0, sizeof *L);
    L->texels = count;
    sl_ksum integ[3] = {{0}}, ysum = {0}, omega_sum = {0};
    double dsum[3] = {0, 0, 0}, ct[4], *dv = ct + 1;
    /* Texels under 10% of the region's brightest are the edge or a glow
     * around the source, counted by the fraction they are of that: an
     * aureole is not counted as the source (a grey sphere under a
     * cloud-dimmed sun, adams_place_bridge, went from 1.9% to 5.2% off with
     * 2%), a window's ground and sky are (stage window: 0.355 sr exact). */
    double floor_y = 0;
    for (int t = 0; t < count; t++)
        floor_y = fmax(floor_y, lost_y(rgb, residual, texels[t] % w, texels[t] / w));
    floor_y *= 0.1;
    for (int t = 0; t < count; t++) {
        int x = texels[t] % w, y = texels[t] / w;
        double om = sl_latlong_texel_solid_angle(y, w, h);
        const float *p = sl_image_pixel(rgb, x, y), *q = sl_image_pixel(residual, x, y);
        double e[3];
        for (int c = 0; c < 3; c++) {
            e[c] = (double)p[c] - (double)q[c];
            sl_ksum_add(&integ[c], e[c] * om);
        }
        sl_ksum_add(&ysum, sl_luminance(e) * om);
        covered(rgb, residual, texels[t], floor_y, ct);
        sl_ksum_add(&omega_sum, ct[0]);
        for (int a = 0; a < 3; a++)
            dsum[a] += ct[0] * dv[a];
    }
    for (int c = 0; c < 3; c++)
        L->integral[c] = sl_ksum_value(&integ[c]);
    double omega = sl_ksum_value(&omega_sum);
    if (!(sl_ksum_value(&ysum) > 0) || !(omega > 0) || !(dot(dsum, dsum) > 0))
        return false;
    /* The geometric centre: a graded source's energy centroid leans toward
     * its bright side (the stage window: 3.7 degrees). */
    memcpy(L->direction, dsum, sizeof dsum);
    normalize(L->direction);

    /* Tangent frame and second moments of the covered area's gnomonic projection. */
    double *d = L->direction, e1[3], e2[3], helper[3] = {0, 1, 0};
    if (fabs(d[1]) > 0.9) {
        helper[0] = 1;
        helper[1] = 0;
    }
    cross(helper, d, e1);
    normalize(e1);
    cross(d, e1, e2);
    double m[6] = {0}; /* sum w, wx, wy, wxx, wxy, wyy */
    for (int t = 0; t < count; t++) {
        covered(rgb, residual, texels[t], floor_y, ct);
        double z = dot(dv, d);
        /* the tangent plane holds the texels within ~87 degrees */
        if (z < 0.05)
            continue;
        double wt = ct[0], u = dot(dv, e1) / z, v = dot(dv, e2) / z;
        m[0] += wt;
        m[1] += wt * u;
        m[2] += wt * v;
        m[3] += wt * u * u;
        m[4] += wt * u * v;
        m[5] += wt * v * v;
    }
    double mu = m[1] / m[0], mv = m[2] / m[0];
    double cuu = m[3] / m[0] - mu * mu, cuv = m[4] / m[0] - mu * mv, cvv = m[5] / m[0] - mv * mv;
    double tr = 0.5 * (cuu + cvv), det = sqrt(0.25 * (cuu - cvv) * (cuu - cvv) + cuv * cuv);
    double l1 = tr + det, l2 = tr - det;
    /* Central fourth moments in the (e1, e2) frame, for the kurtosis of the
     * marginal along any axis: 1.8 for a uniform rectangle's side, 2.0 for a
     * disk's (semicircle law). */
    double q[5] = {0}; /* uuuu, uuuv, uuvv, uvvv, vvvv */
    for (int t = 0; t < count; t++) {
        covered(rgb, residual, texels[t], floor_y, ct);
        double z = dot(dv, d);
        if (z < 0.05)
            continue;
        double u = dot(dv, e1) / z - mu, v = dot(dv, e2) / z - mv;
        q[0] += ct[0] * u * u * u * u;
        q[1] += ct[0] * u * u * u * v;
        q[2] += ct[0] * u * u * v * v;
        q[3] += ct[0] * u * v * v * v;
        q[4] += ct[0] * v * v * v * v;
    }
    /* Orientation: the major axis; for a near-square the eigenvectors are
     * arbitrary, so the axis whose marginals are flattest (a square's sides). */
    double th = 0.5 * atan2(2 * cuv, cuu - cvv), aspect = l2 > 0 ? sqrt(l1 / l2) : 1e3;
    double kurt = rig_kurtosis2(q, m[0], cuu, cuv, cvv, th);
    if (aspect <= 1.3)
        for (int k = 0; k < 90; k++) {
            double phi = k * M_PI / 180, kk = rig_kurtosis2(q, m[0], cuu, cuv, cvv, phi);
            if (kk < kurt - 1e-9) {
                kurt = kk;
                th = phi;
            }
        }
    for (int a = 0; a < 3; a++)
        L->axis_u[a] = cos(th) * e1[a] + sin(th) * e2[a];
    cross(d, L->axis_u, L->axis_v);

    double eq_texel = (2 * M_PI / w) * (M_PI / h);
    if (omega < 4.5 * eq_texel) {
        /* Smaller than the texels can show: the map cannot tell its size. */
        L->shape = SL_RIG_DISTANT;
        double r = 0.5 * opt->unresolved_degrees * M_PI / 180;
        L->solid_angle = 2 * M_PI * (1 - cos(r));
        L->angular_size[0] = L->angular_size[1] = 2 * r;
    } else {
        L->solid_angle = omega;
        if (aspect > 1.3 || !(kurt > 1.9)) {
            L->shape = SL_RIG_RECT;
            /* Half-sides from the variances (a^2/3), scaled to the solid angle. */
            double c = cos(th), sn = sin(th);
            double vu = c * c * cuu + 2 * c * sn * cuv + sn * sn * cvv;
            double vv = sn * sn * cuu - 2 * c * sn * cuv + c * c * cvv;
            double a0 = sqrt(3 * vu), b0 = sqrt(3 * (vv > 0 ? vv : vu * 1e-6));
            double lo = 0, hi = 1;
            while (rect_solid_angle(hi * a0, hi * b0) < omega && hi < 1e6)
                hi *= 2;
            for (int it = 0; it < 100; it++) {
                double s = 0.5 * (lo + hi);
                if (rect_solid_angle(s * a0, s * b0) < omega)
                    lo = s;
                else
                    hi = s;
            }
            double s = 0.5 * (lo + hi);
            L->angular_size[0] = 2 * atan(s * a0);
            L->angular_size[1] = 2 * atan(s * b0);
        } else {
            L->shape = SL_RIG_DISK;
            L->angular_size[0] = L->angular_size[1] = 2 * cap_radius(omega);
        }
    }
    for (int c = 0; c < 3; c++)
        L->radiance[c] = L->integral[c] / L->solid_angle;
    return true;
}

void rig_place_light(sl_rig_light *L, const sl_rig_options *opt)
{
    bool room = opt->room[0] > 0 && opt->room[1] > 0 && opt->room[2] > 0;
    if (L->shape == SL_RIG_DISTANT || (!room && !(opt->distance > 0)))
        return;
    const double *d = L->direction;
    double t = opt->distance;
    if (room) {
        double lo[3] = {-opt->room[0] / 2, -opt->capture_height, -opt->room[1] / 2};
        double hi[3] = {opt->room[0] / 2, opt->room[2] - opt->capture_height, opt->room[1] / 2};
        t = INFINITY;
        for (int a = 0; a < 3; a++) {
            if (d[a] > 1e-12)
                t = fmin(t, hi[a] / d[a]);
            else if (d[a] < -1e-12)
                t = fmin(t, lo[a] / d[a]);
        }
    }
    L->has_position = true;
    for (int a = 0; a < 3; a++)
        L->position[a] = t * d[a];
    /* Facing the capture point, sized to keep the solid angle. */
    if (L->shape == SL_RIG_RECT) {
        L->size[0] = 2 * t * tan(L->angular_size[0] / 2);
        L->size[1] = 2 * t * tan(L->angular_size[1] / 2);
    } else {
        /* Round: a sphere (a bulb lights the whole room) of the same cap. */
        L->shape = SL_RIG_SPHERE;
        L->size[0] = L->size[1] = 2 * t * sin(L->angular_size[0] / 2);
    }
}


/* GGX roughness of the glossy sphere the lights are ranked for. */
#define RIG_GLOSSY_ALPHA 0.3

/* A light's glossy contribution: the peak of its highlight on a GGX sphere
 * (alpha 0.3, white Fresnel, seen along the normal with the light behind
 * the viewer): radiance x the share of the lobe the light covers, which for
 * a cap of angular radius r (half-vectors within r/2) is
 * tan^2(r/2) / (alpha^2 + tan^2(r/2)). A small light's is its power over
 * 4 pi alpha^2 (as for grey); a large soft one's saturates at its radiance. */
static double glossy_score(const sl_rig_light *L)
{
    double t = tan(0.5 * cap_radius(L->solid_angle)), a2 = RIG_GLOSSY_ALPHA * RIG_GLOSSY_ALPHA;
    double y = sl_luminance(L->integral) / L->solid_angle;
    return (y > 0 ? y : 0) * t * t / (a2 + t * t);
}

static bool eligible(const sl_rig_light *L, int tag, const sl_rig_options *opt)
{
    bool wide = opt->max_solid_angle > 0 && L->solid_angle > opt->max_solid_angle;
    return tag > 0 || (tag == 0 && !wide);
}

sl_result rig_select(sl_rig_light *cand, int count, const sl_rig_options *opt, const int *tags,
                     bool *keep, sl_rig_skip **skipped, int *skipped_count, sl_error *err)
{
    *skipped = NULL;
    *skipped_count = 0;
    sl_ranked *r = malloc((size_t)(count ? count : 1) * sizeof *r);
    if (!r)
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d lights)", count);
    /* Two contributions: to a grey (Lambertian) sphere, whose total
     * reflected light is proportional to the luminous power whatever the
     * direction, and to a glossy sphere's highlights, which favour small
     * bright sources over large soft ones of the same power. */
    double total = 0, total_g = 0, *gl = malloc((size_t)(count ? count : 1) * sizeof *gl);
    if (!gl) {
        free(r);
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d lights)", count);
    }
    for (int i = 0; i < count; i++) {
        double y = sl_luminance(cand[i].integral);
        gl[i] = glossy_score(&cand[i]);
        total += y > 0 ? y : 0;
        total_g += gl[i];
    }
    for (int i = 0; i < count; i++) {
        double y = sl_luminance(cand[i].integral);
        cand[i].share = total > 0 && y > 0 ? y / total : 0;
        cand[i].share_glossy = total_g > 0 ? gl[i] / total_g : 0;
        /* ranked by the larger of its two shares */
        r[i].value = fmax(cand[i].share, cand[i].share_glossy);
        r[i].index = i;
    }
    qsort(r, (size_t)count, sizeof *r, sl_cmp_ranked_desc);
    *skipped = calloc((size_t)(count ? count : 1), sizeof **skipped);
    if (!*skipped) {
        free(r);
        free(gl);
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d lights)", count);
    }
    /* The cut is on the contributions of the candidates that may become
     * lights: not excluded by hand, not wider than a fixture; the kept set
     * reaches --energy of both. */
    double acc = 0, acc_g = 0, elig = 0, elig_g = 0;
    int kept = 0, forced = 0;
    for (int i = 0; i < count; i++) {
        forced += tags[i] > 0;
        if (eligible(&cand[i], tags[i], opt)) {
            elig += cand[i].share;
            elig_g += cand[i].share_glossy;
        }
    }
    for (int i = 0; i < count; i++) {
        sl_rig_light *L = &cand[r[i].index];
        int tag = tags[r[i].index];
        char reason[160] = "";
        bool k;
        if (tag < 0) {
            k = false;
            snprintf(reason, sizeof reason, "--exclude %g,%g", opt->exclude[-tag - 1][0],
                     opt->exclude[-tag - 1][1]);
        } else if (tag > 0) {
            k = true; /* tagged by hand: kept whatever its energy */
            forced--;
        } else if (opt->max_solid_angle > 0 && L->solid_angle > opt->max_solid_angle) {
            k = false;
            snprintf(reason, sizeof reason,
                     "area: %.3g sr is wider than a fixture (--max-solid-angle %g); the dome "
                     "renders it exactly",
                     L->solid_angle, opt->max_solid_angle);
        } else if (opt->max_lights > 0 && kept + forced >= opt->max_lights) {
            k = false;
            snprintf(reason, sizeof reason, "--max-lights %d reached", opt->max_lights);
        } else if (acc < opt->energy * elig * (1 - 1e-12) ||
                   acc_g < opt->energy * elig_g * (1 - 1e-12)) {
            k = true;
        } else if (L->shape == SL_RIG_DISTANT && L->share >= 0.005) {
            /* Tiny, very bright sources are what a dome renders worst and
             * what casts the sharpest shadows: not left in it by the cut
             * (stars and glints under 0.5% of the energy are). */
            k = true;
        } else {
            k = false;
            snprintf(reason, sizeof reason,
                     "energy: the kept lights already carry %.1f%% of the directional energy "
                     "for a grey sphere and %.1f%% for a glossy one (--energy %g)",
                     100 * acc / elig, 100 * acc_g / elig_g, opt->energy);
        }
        keep[r[i].index] = k;
        if (k) {
            kept++;
            acc += L->share;
            acc_g += L->share_glossy;
            continue;
        }
        sl_rig_skip *s = &(*skipped)[(*skipped_count)++];
        memcpy(s->direction, L->direction, sizeof s->direction);
        memcpy(s->integral, L->integral, sizeof s->integral);
        s->solid_angle = L->solid_angle;
        s->share = L->share;
        s->share_glossy = L->share_glossy;
        snprintf(s->reason, sizeof s->reason, "%s", reason);
    }
    free(r);
    free(gl);
    return SL_OK;
}
