/* SPDX-License-Identifier: BSD-3-Clause */
/* Cube-face helpers shared by projection.c and reproject.c. Faces are
 * numbered in OpenEXR's order 0..5 = +X -X +Y -Y +Z -Z; fx (right) and fy
 * (down) are in-face image coordinates in [0,1]. */
#ifndef SETLIGHT_CORE_PROJECTION_PRIVATE_H
#define SETLIGHT_CORE_PROJECTION_PRIVATE_H

#include "setlight/core.h"

void sl_cube_face_to_dir(int face, double fx, double fy, double dir[3]);
int sl_dir_to_cube_face(const double dir[3], double *fx, double *fy);

#endif
