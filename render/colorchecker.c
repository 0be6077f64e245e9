/* SPDX-License-Identifier: BSD-3-Clause */
/* ColorChecker Classic reference albedos. Source: X-Rite's post-November-2014
 * ColorChecker Classic specification as 8-bit sRGB (D65), in the table
 * xrite_post-2014.csv of github:mathandy/python-macduff-colorchecker-detector
 * (color_data/, commit 555e3c7ca6a7); decoded here with the sRGB transfer
 * function to linear Rec.709. The values below are round(decoded, 6). */
#include "setlight/render.h"

const char *const SL_COLORCHECKER_NAMES[24] = {
    "dark skin", "light skin", "blue sky", "foliage", "blue flower", "bluish green",
    "orange", "purplish blue", "moderate red", "purple", "yellow green", "orange yellow",
    "blue", "green", "red", "yellow", "magenta", "cyan",
    "white 9.5", "neutral 8", "neutral 6.5", "neutral 5", "neutral 3.5", "black 2",
};

/* 8-bit sRGB source values, in order: */
/* (116,79,65) (197,144,127) (91,120,155) (91,108,64) (131,127,175) (95,189,172) (224,124,48) (69,90,167)
   (197,80,95) (93,58,104) (156,187,58) (227,161,39) (40,62,145) (61,147,70) (178,54,57) (236,199,15)
   (191,79,146) (0,133,165) (241,242,235) (201,202,201) (161,163,163) (121,121,121) (83,84,85) (50,50,50) */
const double SL_COLORCHECKER_LINEAR[24][3] = {
    {0.174647, 0.078187, 0.052861},
    {0.558340, 0.278894, 0.212231},
    {0.104616, 0.187821, 0.327778},
    {0.104616, 0.149960, 0.051269},
    {0.226966, 0.212231, 0.428690},
    {0.114435, 0.508881, 0.412543},
    {0.745404, 0.201556, 0.029557},
    {0.059511, 0.102242, 0.386429},
    {0.558340, 0.080220, 0.114435},
    {0.109462, 0.042311, 0.138432},
    {0.332452, 0.496933, 0.042311},
    {0.768151, 0.356400, 0.020289},
    {0.021219, 0.048172, 0.283149},
    {0.046665, 0.291771, 0.061246},
    {0.445201, 0.036889, 0.040915},
    {0.838799, 0.571125, 0.004777},
    {0.520996, 0.078187, 0.287441},
    {0.000000, 0.234551, 0.376262},
    {0.879622, 0.887923, 0.830770},
    {0.584078, 0.590619, 0.584078},
    {0.356400, 0.366253, 0.366253},
    {0.191202, 0.191202, 0.191202},
    {0.086500, 0.088656, 0.090842},
    {0.031896, 0.031896, 0.031896},
};
