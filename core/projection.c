/* SPDX-License-Identifier: BSD-3-Clause */
/* Mirror ball, angular map and OpenEXR cube map <-> direction, and
 * reprojection between any two projections. Conventions and diagrams are in
 * docs/geometry.md; every image uses u right, v down, texel centres at
 * (x + 0.5) / w. */
#include "projection_private.h"

#include <math.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const char *const proj_names[SL_PROJ_COUNT] = {"latlong", "mirrorball", "angular",
                                                      "cubemap"};

int sl_projection_from_name(const char *name)
{
    if (!name)
        return -1;
    for (int i = 0; i < SL_PROJ_COUNT; i++)
        if (strcmp(name, proj_names[i]) == 0)
            return i;
    return -1;
}

const char *sl_projection_name(sl_projection p)
{
    return (p >= 0 && p < SL_PROJ_COUNT) ? proj_names[p] : "unknown";
}

void sl_projection_size(sl_projection p, int latlong_width, int *width, int *height)
{
    int w = latlong_width;
    switch (p) {
    case SL_PROJ_MIRRORBALL:
    case SL_PROJ_ANGULAR:
        *width = w / 2;
        *height = w / 2;
        break;
    case SL_PROJ_CUBEMAP:
        *width = w / 4;
        *height = 6 * (w / 4);
        break;
    default:
        *width = w;
        *height = w / 2;
        break;
    }
}

/* Mirror ball and angular map share the same disc: image point (px, py) in
 * [-1,1] with py up, image right world -X, image up +Y (the view of a camera
 * looking along +Z with +Y up). The ball's centre reflects -Z (back toward
 * the camera) at angle 2 asin(r) from it. The angular map is Debevec's light
 * probe: its centre is the camera's forward direction +Z, at angle pi r from
 * it, its rim -Z; seen from inside it is an unmirrored view, as his
 * definition (centre forward, image right the viewer's right) and the
 * lat-longs other tools make from his probes have it (docs/geometry.md). */
static bool disc_to_dir(bool angular, double px, double py, double dir[3])
{
    double r2 = px * px + py * py;
    if (!(r2 <= 1.0 + 1e-12)) /* tolerance: points moved onto the rim by rounding */
        return false;
    if (r2 > 1.0)
        r2 = 1.0;
    if (angular) {
        double r = sqrt(r2);
        double theta = M_PI * r;
        double s = r > 0.0 ? sin(theta) / r : M_PI;
        dir[0] = -px * s;
        dir[1] = py * s;
        dir[2] = cos(theta);
    } else {
        /* Reflect the view vector (0,0,1) about the normal (-px, py, -sqrt(1-r^2)). */
        double nz = sqrt(1.0 - r2);
        dir[0] = -2.0 * px * nz;
        dir[1] = 2.0 * py * nz;
        dir[2] = 2.0 * r2 - 1.0;
    }
    return true;
}

static void dir_to_disc(bool angular, const double dir[3], double *px, double *py)
{
    double rho = hypot(dir[0], dir[1]);
    /* Angle from the disc's centre (+Z angular, -Z ball), stable everywhere. */
    double theta = atan2(rho, angular ? dir[2] : -dir[2]);
    double r = angular ? theta / M_PI : sin(0.5 * theta);
    if (rho > 0.0) {
        *px = -dir[0] / rho * r;
        *py = dir[1] / rho * r;
    } else {
        /* Straight at the centre direction is the centre; straight away from it
         * is the whole rim: pick its right end. */
        *px = r;
        *py = 0.0;
    }
}

/* OpenEXR's CubeMap::direction / pixelPosition with normalised in-face
 * coordinates a, b in [-1,1] and in-face image coordinates fx (right) and
 * fy (down) in [0,1]. */
void sl_cube_face_to_dir(int face, double fx, double fy, double dir[3])
{
    double a = 0.0, b = 0.0;
    switch (face) {
    case 0: /* +X: x = min + pif.y, y = max - pif.x */
    case 1: /* -X: x = max - pif.y, y = max - pif.x */
        a = 1.0 - 2.0 * fy;
        b = face == 0 ? 2.0 * fx - 1.0 : 1.0 - 2.0 * fx;
        dir[0] = face == 0 ? 1.0 : -1.0;
        dir[1] = a;
        dir[2] = b;
        break;
    case 2: /* +Y: x = min + pif.x, y = max - pif.y */
    case 3: /* -Y: x = min + pif.x, y = min + pif.y */
        a = 2.0 * fx - 1.0;
        b = face == 2 ? 1.0 - 2.0 * fy : 2.0 * fy - 1.0;
        dir[0] = a;
        dir[1] = face == 2 ? 1.0 : -1.0;
        dir[2] = b;
        break;
    default: /* +Z: x = max - pif.x, -Z: x = min + pif.x; both y = max - pif.y */
        a = face == 4 ? 1.0 - 2.0 * fx : 2.0 * fx - 1.0;
        b = 1.0 - 2.0 * fy;
        dir[0] = a;
        dir[1] = b;
        dir[2] = face == 4 ? 1.0 : -1.0;
        break;
    }
    double n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    dir[0] /= n;
    dir[1] /= n;
    dir[2] /= n;
}

int sl_dir_to_cube_face(const double dir[3], double *fx, double *fy)
{
    double ax = fabs(dir[0]), ay = fabs(dir[1]), az = fabs(dir[2]);
    int face;
    double a, b;
    if (ax >= ay && ax >= az) {
        if (ax == 0.0) {
            *fx = 0.5;
            *fy = 0.5;
            return 0;
        }
        face = dir[0] > 0.0 ? 0 : 1;
        a = dir[1] / ax;
        b = dir[2] / ax;
    } else if (ay >= az) {
        face = dir[1] > 0.0 ? 2 : 3;
        a = dir[0] / ay;
        b = dir[2] / ay;
    } else {
        face = dir[2] > 0.0 ? 4 : 5;
        a = dir[0] / az;
        b = dir[1] / az;
    }
    double pa = 0.5 * (a + 1.0), pb = 0.5 * (b + 1.0); /* pif / (sof) in [0,1] */
    switch (face) {
    case 0: *fx = pb; *fy = 1.0 - pa; break;
    case 1: *fx = 1.0 - pb; *fy = 1.0 - pa; break;
    case 2: *fx = pa; *fy = 1.0 - pb; break;
    case 3: *fx = pa; *fy = pb; break;
    case 4: *fx = 1.0 - pa; *fy = 1.0 - pb; break;
    default: *fx = pa; *fy = 1.0 - pb; break;
    }
    return face;
}

bool sl_projection_to_dir(sl_projection p, double u, double v, double dir[3])
{
    if (!(u >= 0.0 && u <= 1.0 && v >= 0.0 && v <= 1.0))
        return false;
    switch (p) {
    case SL_PROJ_LATLONG:
        sl_latlong_to_dir(u, v, dir);
        return true;
    case SL_PROJ_MIRRORBALL:
    case SL_PROJ_ANGULAR:
        return disc_to_dir(p == SL_PROJ_ANGULAR, 2.0 * u - 1.0, 1.0 - 2.0 * v, dir);
    case SL_PROJ_CUBEMAP: {
        double f = v * 6.0;
        int face = (int)f;
        if (face > 5)
            face = 5;
        sl_cube_face_to_dir(face, u, f - face, dir);
        return true;
    }
    default:
        return false;
    }
}

bool sl_dir_to_projection(sl_projection p, const double dir[3], double *u, double *v)
{
    if (!(isfinite(dir[0]) && isfinite(dir[1]) && isfinite(dir[2])) ||
        (dir[0] == 0.0 && dir[1] == 0.0 && dir[2] == 0.0))
        return false;
    switch (p) {
    case SL_PROJ_LATLONG:
        sl_dir_to_latlong(dir, u, v);
        return true;
    case SL_PROJ_MIRRORBALL:
    case SL_PROJ_ANGULAR: {
        double px, py;
        dir_to_disc(p == SL_PROJ_ANGULAR, dir, &px, &py);
        *u = 0.5 * (px + 1.0);
        *v = 0.5 * (1.0 - py);
        return true;
    }
    case SL_PROJ_CUBEMAP: {
        double fx, fy;
        int face = sl_dir_to_cube_face(dir, &fx, &fy);
        *u = fx;
        *v = (face + fy) / 6.0;
        return true;
    }
    default:
        return false;
    }
}
