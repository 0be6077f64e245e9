/* SPDX-License-Identifier: BSD-3-Clause */
/* The blend's inner loop: a run of lat-long samples on one sub-row to one
 * view's pixel positions, blend weights and vignetting, in float and as
 * structure of arrays, 8 samples at a time with AVX2 (gathers for the lens
 * and ramp tables) where the processor has it. The same operations as
 * stitch_view_pixel() and ramp_weight() in double. */
#include "stitch_blend_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

bool stitch_ray_view_init(const stitch_view_prep *p, stitch_ray_view *v)
{
    memset(v, 0, sizeof *v);
    v->q = malloc((size_t)p->q_entries * sizeof *v->q);
    int ramp_n = p->ramp_table ? p->ramp_entries : 2;
    v->ramp = malloc(((size_t)ramp_n + 1) * sizeof *v->ramp);
    if (!v->q || !v->ramp) {
        stitch_ray_view_free(v);
        return false;
    }
    for (int i = 0; i < p->q_entries; i++)
        v->q[i] = (float)p->q_table[i];
    /* no ramp: the weight is (1 + c) / 2 inside the field, 0 on its edge */
    for (int i = 0; i < ramp_n; i++)
        v->ramp[i] = p->ramp_table ? (float)p->ramp_table[i] : (float)i;
    v->ramp[ramp_n] = v->ramp[ramp_n - 1]; /* the last interval's right end, read at its end */
    v->ramp_last = (float)(ramp_n - 1);
    v->ramp_step_inv = p->ramp_table ? (float)p->ramp_step_inv : 1.0f;
    v->q_last = (float)(p->q_entries - 1);
    v->u_step_inv = (float)(1.0 / p->u_step);
    for (int r = 0; r < 3; r++) {
        v->axis[r] = (float)p->axis[r];
        for (int c = 0; c < 3; c++)
            v->to_cam[r][c] = (float)p->to_cam[r][c];
    }
    v->cos_max = (float)p->cos_max;
    v->cos_ramp = (float)p->cos_ramp;
    const sl_lens *l = &p->lens;
    v->cx = (float)l->cx;
    v->cy = (float)l->cy;
    v->width = (float)l->width;
    v->height = (float)l->height;
    v->circle_r2 = l->circle_radius_px > 0.0
                       ? (float)(l->circle_radius_px * l->circle_radius_px)
                       : INFINITY;
    v->inv_f2 = (float)(1.0 / (l->focal_px * l->focal_px));
    for (int i = 0; i < 3; i++)
        v->vignette[i] = (float)l->vignette[i];
    return true;
}

void stitch_ray_view_free(stitch_ray_view *v)
{
    free(v->q);
    free(v->ramp);
    memset(v, 0, sizeof *v);
}

/* One sample: the portable loop and the AVX2 loop's tail (the same float
 * operations in the same order as the AVX2 lanes: the same bytes). */
static inline void ray_one(const stitch_ray_view *v, float sin_lon, float cos_lon, float sin_lat,
                           float cos_lat, float *px, float *py, float *weight, float *inv_gain)
{
    float d0 = sin_lon * cos_lat, d2 = cos_lon * cos_lat;
    float c = v->axis[0] * d0 + v->axis[1] * sin_lat + v->axis[2] * d2;
    float rx = v->to_cam[0][0] * d0 + v->to_cam[0][1] * sin_lat + v->to_cam[0][2] * d2;
    float ry = v->to_cam[1][0] * d0 + v->to_cam[1][1] * sin_lat + v->to_cam[1][2] * d2;
    float rz = v->to_cam[2][0] * d0 + v->to_cam[2][1] * sin_lat + v->to_cam[2][2] * d2;
    /* the lens: q(u) = r^2 / u at u = 1 - cos(theta) */
    float u = 1.0f - rz, t = u * v->u_step_inv;
    bool in = c >= v->cos_max && t >= 0.0f && t < v->q_last && rz > -1.0f;
    float tq = t > 0.0f ? (t < v->q_last ? t : v->q_last - 1.0f) : 0.0f; /* inside the table */
    int i = (int)tq;
    float q0 = v->q[i], q1 = v->q[i + 1];
    float qt = q0 + (tq - (float)i) * (q1 - q0), rr = u * qt;
    in = in && q0 >= 0.0f && q1 >= 0.0f && rr <= v->circle_r2;
    /* r / sin(theta) = sqrt(q / (1 + z)) */
    float k2 = qt / (1.0f + rz), k = sqrtf(k2 > 0.0f ? k2 : 0.0f);
    float x = v->cx + k * rx, y = v->cy + k * ry;
    in = in && x >= 0.0f && y >= 0.0f && x <= v->width && y <= v->height;
    /* the edge ramp's sine from its table over cos(theta) */
    float tr = (c - v->cos_max) * v->ramp_step_inv;
    tr = tr > 0.0f ? (tr < v->ramp_last ? tr : v->ramp_last) : 0.0f;
    int j = (int)tr;
    float sn = v->ramp[j] + (tr - (float)j) * (v->ramp[j + 1] - v->ramp[j]);
    float wt = 0.5f * (1.0f + c) * (c > v->cos_ramp ? 1.0f : sn * sn);
    /* the vignetting's gain at r^2 (sl_lens_vignette) */
    float s2 = rr * v->inv_f2;
    float g = 1.0f + s2 * (v->vignette[0] + s2 * (v->vignette[1] + s2 * v->vignette[2]));
    *px = x;
    *py = y;
    *weight = in ? wt : 0.0f;
    *inv_gain = g > 1e-6f ? 1.0f / g : 0.0f;
}

#if (defined(__x86_64__) || defined(__i386__)) && !defined(__clang__) && __GNUC__ >= 12
#define HAVE_RAYS_AVX2 1
#include <immintrin.h>
/* ray_one() 8 samples at a time, the table lookups gathers. No fused
 * multiply-adds: the same bytes as ray_one(). */
__attribute__((target("avx2"))) static int rays_avx2(const stitch_ray_view *v,
                                                    const float *sin_lon, const float *cos_lon,
                                                    float sin_lat, float cos_lat, int n,
                                                    float *px, float *py, float *weight,
                                                    float *inv_gain)
{
#define SPLAT(x) _mm256_set1_ps(x)
#define ADD _mm256_add_ps
#define SUB _mm256_sub_ps
#define MUL _mm256_mul_ps
#define CMP(a, b, op) _mm256_cmp_ps(a, b, op)
#define SEL(mask, a, b) _mm256_blendv_ps(b, a, mask) /* mask ? a : b */
    const __m256 zero = _mm256_setzero_ps(), one = SPLAT(1.0f), cl = SPLAT(cos_lat);
    const __m256 ax1 = SPLAT(v->axis[1] * sin_lat), m01 = SPLAT(v->to_cam[0][1] * sin_lat),
                 m11 = SPLAT(v->to_cam[1][1] * sin_lat), m21 = SPLAT(v->to_cam[2][1] * sin_lat);
    const __m256 cos_max = SPLAT(v->cos_max), q_last = SPLAT(v->q_last);
    int s = 0;
    for (; s + 8 <= n; s += 8) {
        __m256 d0 = MUL(_mm256_loadu_ps(sin_lon + s), cl), d2 = MUL(_mm256_loadu_ps(cos_lon + s), cl);
        __m256 c = ADD(ADD(MUL(SPLAT(v->axis[0]), d0), ax1), MUL(SPLAT(v->axis[2]), d2));
        __m256 rx = ADD(ADD(MUL(SPLAT(v->to_cam[0][0]), d0), m01), MUL(SPLAT(v->to_cam[0][2]), d2));
        __m256 ry = ADD(ADD(MUL(SPLAT(v->to_cam[1][0]), d0), m11), MUL(SPLAT(v->to_cam[1][2]), d2));
        __m256 rz = ADD(ADD(MUL(SPLAT(v->to_cam[2][0]), d0), m21), MUL(SPLAT(v->to_cam[2][2]), d2));
        __m256 u = SUB(one, rz), t = MUL(u, SPLAT(v->u_step_inv));
        __m256 in = _mm256_and_ps(_mm256_and_ps(CMP(c, cos_max, _CMP_GE_OQ), CMP(t, zero, _CMP_GE_OQ)),
                                  _mm256_and_ps(CMP(t, q_last, _CMP_LT_OQ),
                                                CMP(rz, SPLAT(-1.0f), _CMP_GT_OQ)));
        __m256 tq = SEL(CMP(t, zero, _CMP_GT_OQ),
                        SEL(CMP(t, q_last, _CMP_LT_OQ), t, SUB(q_last, one)), zero);
        __m256i i = _mm256_cvttps_epi32(tq);
        __m256 q0 = _mm256_i32gather_ps(v->q, i, 4), q1 = _mm256_i32gather_ps(v->q + 1, i, 4);
        __m256 qt = ADD(q0, MUL(SUB(tq, _mm256_cvtepi32_ps(i)), SUB(q1, q0))), rr = MUL(u, qt);
        in = _mm256_and_ps(in, _mm256_and_ps(_mm256_and_ps(CMP(q0, zero, _CMP_GE_OQ),
                                                           CMP(q1, zero, _CMP_GE_OQ)),
                                             CMP(rr, SPLAT(v->circle_r2), _CMP_LE_OQ)));
        __m256 k2 = _mm256_div_ps(qt, ADD(one, rz));
        __m256 k = _mm256_sqrt_ps(SEL(CMP(k2, zero, _CMP_GT_OQ), k2, zero));
        __m256 x = ADD(SPLAT(v->cx), MUL(k, rx)), y = ADD(SPLAT(v->cy), MUL(k, ry));
        in = _mm256_and_ps(in, _mm256_and_ps(_mm256_and_ps(CMP(x, zero, _CMP_GE_OQ),
                                                           CMP(y, zero, _CMP_GE_OQ)),
                                             _mm256_and_ps(CMP(x, SPLAT(v->width), _CMP_LE_OQ),
                                                           CMP(y, SPLAT(v->height), _CMP_LE_OQ))));
        __m256 tr = MUL(SUB(c, cos_max), SPLAT(v->ramp_step_inv));
        __m256 ramp_last = SPLAT(v->ramp_last);
        tr = SEL(CMP(tr, zero, _CMP_GT_OQ), SEL(CMP(tr, ramp_last, _CMP_LT_OQ), tr, ramp_last), zero);
        __m256i j = _mm256_cvttps_epi32(tr);
        __m256 r0 = _mm256_i32gather_ps(v->ramp, j, 4), r1 = _mm256_i32gather_ps(v->ramp + 1, j, 4);
        __m256 sn = ADD(r0, MUL(SUB(tr, _mm256_cvtepi32_ps(j)), SUB(r1, r0)));
        __m256 wt = MUL(MUL(SPLAT(0.5f), ADD(one, c)),
                        SEL(CMP(c, SPLAT(v->cos_ramp), _CMP_GT_OQ), one, MUL(sn, sn)));
        __m256 s2 = MUL(rr, SPLAT(v->inv_f2));
        __m256 g = ADD(one, MUL(s2, ADD(SPLAT(v->vignette[0]),
                                        MUL(s2, ADD(SPLAT(v->vignette[1]),
                                                    MUL(s2, SPLAT(v->vignette[2])))))));
        _mm256_storeu_ps(px + s, x);
        _mm256_storeu_ps(py + s, y);
        _mm256_storeu_ps(weight + s, _mm256_and_ps(in, wt));
        _mm256_storeu_ps(inv_gain + s, _mm256_and_ps(CMP(g, SPLAT(1e-6f), _CMP_GT_OQ),
                                                     _mm256_div_ps(one, g)));
    }
#undef SPLAT
#undef ADD
#undef SUB
#undef MUL
#undef CMP
#undef SEL
    return s;
}
#endif

bool stitch_rays_portable_only = false;

void stitch_rays(const stitch_ray_view *v, const float *sin_lon, const float *cos_lon,
                 float sin_lat, float cos_lat, int n, float *px, float *py, float *weight,
                 float *inv_gain)
{
    int s = 0;
#ifdef HAVE_RAYS_AVX2
    if (!stitch_rays_portable_only && __builtin_cpu_supports("avx2"))
        s = rays_avx2(v, sin_lon, cos_lon, sin_lat, cos_lat, n, px, py, weight, inv_gain);
#endif
    for (; s < n; s++)
        ray_one(v, sin_lon[s], cos_lon[s], sin_lat, cos_lat, px + s, py + s, weight + s,
                inv_gain + s);
}
