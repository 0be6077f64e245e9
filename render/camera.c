/* SPDX-License-Identifier: BSD-3-Clause */
/* Orthographic, perspective and equisolid fisheye cameras. Image right is
 * forward x up, so a camera looking along +Z with +Y up has -X on its right,
 * as a camera photographing a mirror ball does (core's SL_PROJ_MIRRORBALL). */
#include "scene_internal.h"
#include "vec3.h"

void sl_camera_validation(sl_camera *cam, int width, int height, double ortho_width,
                          double azimuth_deg, double elevation_deg)
{
    double az = azimuth_deg * SL_PI / 180.0, el = elevation_deg * SL_PI / 180.0;
    /* Unturned: forward +Z, up +Y. Azimuth turns forward toward +X; elevation
     * raises the camera so that it looks down at the origin. */
    double fwd[3] = {sin(az) * cos(el), -sin(el), cos(az) * cos(el)};
    double up[3] = {sin(az) * sin(el), cos(el), cos(az) * sin(el)};
    cam->type = SL_CAMERA_ORTHOGRAPHIC;
    for (int i = 0; i < 3; i++) {
        cam->forward[i] = fwd[i];
        cam->up[i] = up[i];
        cam->position[i] = -10.0 * fwd[i];
    }
    cam->ortho_width = ortho_width;
    cam->fov_deg = 0;
    cam->width = width;
    cam->height = height;
}

bool sl_camera_ray(const sl_camera *cam, double sx, double sy, double o[3], double d[3])
{
    double right[3];
    v3_cross(cam->forward, cam->up, right);
    double aspect = (double)cam->height / (double)cam->width;
    double x = 2.0 * sx - 1.0, y = (1.0 - 2.0 * sy) * aspect;
    switch (cam->type) {
    case SL_CAMERA_ORTHOGRAPHIC: {
        double h = 0.5 * cam->ortho_width;
        for (int i = 0; i < 3; i++) {
            o[i] = cam->position[i] + h * (x * right[i] + y * cam->up[i]);
            d[i] = cam->forward[i];
        }
        return true;
    }
    case SL_CAMERA_PERSPECTIVE: {
        double t = tan(0.5 * cam->fov_deg * SL_PI / 180.0);
        for (int i = 0; i < 3; i++) {
            o[i] = cam->position[i];
            d[i] = cam->forward[i] + t * (x * right[i] + y * cam->up[i]);
        }
        return v3_normalize(d);
    }
    case SL_CAMERA_FISHEYE: {
        double r = sqrt(x * x + y * y);
        double theta_max = 0.5 * cam->fov_deg * SL_PI / 180.0;
        if (r > 1.0)
            return false;
        double s = r * sin(0.5 * theta_max);
        double theta = 2.0 * asin(s > 1.0 ? 1.0 : s);
        double ct = cos(theta), st = sin(theta);
        double cx = r > 0 ? x / r : 0, cy = r > 0 ? y / r : 0;
        for (int i = 0; i < 3; i++) {
            o[i] = cam->position[i];
            d[i] = ct * cam->forward[i] + st * (cx * right[i] + cy * cam->up[i]);
        }
        return v3_normalize(d);
    }
    }
    return false;
}
