/* SPDX-License-Identifier: BSD-3-Clause */
/* Grey sphere: the HDRI's exposure and balance from a photographed sphere
 * and a virtual one rendered under the HDRI. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calibrate_internal.h"
#include "setlight/render.h"
#include "setlight/stitch.h"

void sl_grey_options_init(sl_grey_options *o)
{
    memset(o, 0, sizeof(*o));
    o->albedo = 0.18;
    o->inner = 0.85;
    o->spp = 256;
    o->seed = 1;
}

void sl_grey_fit_free(sl_grey_fit *fit)
{
    sl_image_free(&fit->photo);
    sl_image_free(&fit->render);
    sl_image_free(&fit->error);
}

/* Bilinear lookup of channel c at pixel coordinates (x, y); false when any
 * tap is outside, non-finite or clipped. */
static bool bilinear(const sl_image *img, double x, double y, double clip, float out[3])
{
    x -= 0.5, y -= 0.5;
    int x0 = (int)floor(x), y0 = (int)floor(y);
    if (x0 < 0 || y0 < 0 || x0 + 1 >= img->width || y0 + 1 >= img->height)
        return false;
    double fx = x - x0, fy = y - y0;
    double acc[3] = {0, 0, 0};
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            const float *p = img->data + (size_t)(y0 + j) * img->stride +
                             (size_t)(x0 + i) * img->channels;
            double w = (i ? fx : 1 - fx) * (j ? fy : 1 - fy);
            for (int c = 0; c < 3; c++) {
                if (!isfinite(p[c]) || (clip > 0 && p[c] >= clip))
                    return false;
                acc[c] += w * p[c];
            }
        }
    for (int c = 0; c < 3; c++)
        out[c] = (float)acc[c];
    return true;
}

sl_result sl_cal_grey_check(const sl_grey_options *o, const sl_image *photo, sl_cal_view *view,
                            sl_error *err)
{
    memset(view, 0, sizeof(*view));
    double cx = o->circle[0], cy = o->circle[1], rad = o->circle[2];
    if (!(rad >= 4) || !isfinite(cx) || !isfinite(cy))
        return sl_error_set(err, SL_ERR_USAGE, "grey sphere: circle radius %g too small (4 px at least)",
                            rad);
    if (!(o->albedo > 0 && o->albedo <= 1) || !(o->inner > 0 && o->inner <= 1) || o->spp < 1)
        return sl_error_set(err, SL_ERR_USAGE,
                            "grey sphere: albedo and inner fraction in (0, 1], spp >= 1");
    if (!(o->focal_px >= 0) || !(o->distance >= 0))
        return sl_error_set(err, SL_ERR_USAGE,
                            "grey sphere: focal length %g px and distance %g radii must be >= 0",
                            o->focal_px, o->distance);
    if (!photo || !photo->data || photo->channels < 3)
        return sl_error_set(err, SL_ERR_INPUT, "grey sphere photo: needs RGB");
    if (o->focal_px == 0 && o->distance == 0)
        return SL_OK;
    /* The pinhole's geometry is unwrap's: distance and direction of the
     * centre from the circle and focal length. */
    sl_ball_geometry g = {.camera = SL_BALL_PERSPECTIVE, .focal_px = o->focal_px,
                          .distance = o->distance};
    sl_ball_circle c = {.cx = cx, .cy = cy, .r = rad};
    sl_ball_view bv;
    sl_error e;
    sl_result r = sl_ball_view_init(&bv, photo->width, photo->height, &c, &g, &e);
    if (r)
        return sl_error_set(err, r, "grey sphere: %s", e.message);
    view->distance = bv.distance;
    view->tan_half = tan(bv.ball_angle);
    view->focal_px = bv.focal_px;
    /* Without a focal length the sphere is on the axis: the principal point
     * is the circle's centre. */
    view->ppx = o->focal_px > 0 ? 0.5 * photo->width : cx;
    view->ppy = o->focal_px > 0 ? 0.5 * photo->height : cy;
    memcpy(view->view_to_cam, bv.view_to_cam, sizeof(view->view_to_cam));
    return SL_OK;
}

int sl_cal_sphere_size(const sl_grey_options *o)
{
    int n = o->size > 0 ? o->size : (int)fmin(128, ceil(2 * o->circle[2]));
    return n < 8 ? 8 : n;
}

/* The validation camera's frame (+Z forward, +Y up, +X left) in the set. */
static void cam_to_world(const sl_grey_options *o, double m[3][3])
{
    sl_camera c;
    sl_camera_validation(&c, 1, 1, 2.0, o->azimuth_deg, o->elevation_deg);
    const double *f = c.forward, *u = c.up;
    double left[3] = {u[1] * f[2] - u[2] * f[1], u[2] * f[0] - u[0] * f[2],
                      u[0] * f[1] - u[1] * f[0]};
    for (int i = 0; i < 3; i++)
        m[i][0] = left[i], m[i][1] = u[i], m[i][2] = f[i];
}

sl_result sl_cal_render_sphere(const sl_image *env, const sl_grey_options *o, const sl_cal_view *v,
                               int n, sl_image *out, sl_error *err)
{
    memset(out, 0, sizeof(*out));
    sl_scene s;
    sl_scene_init(&s);
    /* The "grey" preset with the photographed sphere's albedo and view. */
    sl_material mat;
    sl_material_lambert(&mat, o->albedo, o->albedo, o->albedo);
    int mi = 0;
    const double origin[3] = {0, 0, 0};
    sl_result r = sl_scene_add_material(&s, &mat, &mi, err);
    if (!r)
        r = sl_scene_add_sphere(&s, origin, 1.0, mi, err);
    if (!r) {
        sl_camera_validation(&s.camera, n, n, 2.0, o->azimuth_deg, o->elevation_deg);
        if (v->distance > 0) {
            /* The pinhole looks at the centre; the outline fills the frame. */
            double cw[3][3], fwd[3], up[3];
            cam_to_world(o, cw);
            for (int i = 0; i < 3; i++) {
                fwd[i] = up[i] = 0;
                for (int j = 0; j < 3; j++)
                    for (int k = 0; k < 3; k++) {
                        fwd[i] += cw[i][j] * v->view_to_cam[j][k] * (k == 2);
                        up[i] += cw[i][j] * v->view_to_cam[j][k] * (k == 1);
                    }
            }
            s.camera.type = SL_CAMERA_PERSPECTIVE;
            s.camera.fov_deg = 2 * atan(v->tan_half) * 180 / M_PI;
            for (int i = 0; i < 3; i++) {
                s.camera.forward[i] = fwd[i];
                s.camera.up[i] = up[i];
                s.camera.position[i] = -v->distance * fwd[i];
            }
        }
        r = sl_scene_set_dome(&s, env, 0, 1, "HDRI", err);
    }
    sl_render_options ro;
    sl_render_options_init(&ro);
    ro.spp = o->spp;
    ro.seed = o->seed;
    ro.bounces = 0; /* a convex sphere cannot see itself */
    if (!r)
        r = sl_render(&s, &ro, out, NULL, err);
    sl_scene_free(&s);
    return r;
}

/* Virtual image point (su, sv in [-1, 1], right and down) -> photo pixel. */
static void to_photo(const sl_grey_options *o, const sl_cal_view *v, double su, double sv,
                     double *x, double *y)
{
    if (v->distance == 0) {
        *x = o->circle[0] + su * o->circle[2];
        *y = o->circle[1] + sv * o->circle[2];
        return;
    }
    /* The virtual camera's right is -X of the view frame, as the photo's. */
    double d[3] = {-su * v->tan_half, -sv * v->tan_half, 1}, dc[3];
    sl_mat3_apply(v->view_to_cam, d, dc);
    *x = v->ppx - v->focal_px * dc[0] / dc[2];
    *y = v->ppy - v->focal_px * dc[1] / dc[2];
}

void sl_cal_resample_photo(const sl_image *photo, const sl_grey_options *o, const sl_cal_view *v,
                           sl_image *out)
{
    int n = out->width;
    double rad = o->circle[2];
    /* The circle spans the virtual camera's image; each virtual pixel is
     * the mean of k x k bilinear taps over its footprint (k photo pixels
     * across it), so a photo larger than the render averages its noise. */
    int k = (int)ceil(2 * rad / n);
    if (k < 1)
        k = 1;
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++) {
            float *ph = out->data + (size_t)y * out->stride + (size_t)x * 4;
            double u = (x + 0.5) / n * 2 - 1, v0 = (y + 0.5) / n * 2 - 1;
            bool in = u * u + v0 * v0 < o->inner * o->inner;
            double acc[3] = {0, 0, 0};
            for (int j = 0; in && j < k; j++)
                for (int i = 0; in && i < k; i++) {
                    double su = (x + (i + 0.5) / k) / n * 2 - 1, sv = (y + (j + 0.5) / k) / n * 2 - 1;
                    double px, py;
                    float t[3];
                    to_photo(o, v, su, sv, &px, &py);
                    in = bilinear(photo, px, py, o->clip_level, t);
                    for (int c = 0; c < 3; c++)
                        acc[c] += t[c];
                }
            ph[3] = in ? 1.0f : 0.0f;
            for (int c = 0; c < 3; c++)
                ph[c] = in ? (float)(acc[c] / (k * k)) : 0.0f;
        }
}

sl_result sl_grey_sphere_fit(const sl_image *hdri, const sl_image *photo, const sl_grey_options *opt,
                             sl_grey_fit *fit, sl_error *err)
{
    memset(fit, 0, sizeof(*fit));
    sl_grey_options o;
    if (opt)
        o = *opt;
    else
        sl_grey_options_init(&o);
    sl_cal_view view;
    sl_result r = sl_cal_grey_check(&o, photo, &view, err);
    if (r)
        return r;
    int n = sl_cal_sphere_size(&o);
    r = sl_cal_render_sphere(hdri, &o, &view, n, &fit->render, err);
    if (!r)
        r = sl_image_alloc(&fit->photo, n, n, 4, err);
    if (!r)
        r = sl_image_alloc(&fit->error, n, n, 4, err);
    size_t cnt = (size_t)n * n;
    double *ratio = r ? NULL : malloc(cnt * 3 * sizeof(double));
    if (!r && !ratio)
        r = sl_error_set(err, SL_ERR_NOMEM, "grey sphere: out of memory");
    if (r) {
        free(ratio);
        sl_grey_fit_free(fit);
        return r;
    }
    sl_cal_resample_photo(photo, &o, &view, &fit->photo);
    size_t k = 0;
    for (size_t q = 0; q < cnt; q++) {
        float *ph = fit->photo.data + q * 4;
        const float *re = fit->render.data + q * 4;
        if (ph[3] != 0 && !(re[0] > 0 && re[1] > 0 && re[2] > 0))
            ph[3] = 0, ph[0] = ph[1] = ph[2] = 0;
        if (ph[3] == 0)
            continue;
        for (int c = 0; c < 3; c++)
            ratio[k * 3 + c] = ph[c] / re[c];
        k++;
    }
    if (k < 16) {
        free(ratio);
        sl_grey_fit_free(fit);
        return sl_error_set(err, SL_ERR_INPUT,
                            "grey sphere: only %zu usable pixels inside the circle", k);
    }
    double med[3];
    double *tmp = malloc(k * sizeof(double));
    if (!tmp) {
        free(ratio);
        sl_grey_fit_free(fit);
        return sl_error_set(err, SL_ERR_NOMEM, "grey sphere: out of memory");
    }
    for (int c = 0; c < 3; c++) {
        for (size_t i = 0; i < k; i++)
            tmp[i] = ratio[i * 3 + c];
        qsort(tmp, k, sizeof(double), sl_cmp_double);
        med[c] = tmp[k / 2];
    }
    /* Least squares over the inliers, and the error before and after. */
    double spr[3] = {0}, srr[3] = {0};
    size_t i = 0;
    for (size_t p = 0; p < cnt; p++) {
        float *ph = fit->photo.data + p * 4; /* n x n, stride n * 4 */
        if (ph[3] == 0)
            continue;
        bool ok = true;
        for (int c = 0; c < 3; c++)
            ok = ok && fabs(ratio[i * 3 + c] / med[c] - 1) < 0.2;
        i++;
        if (!ok) {
            ph[3] = 0;
            fit->rejected++;
            continue;
        }
        const float *re = fit->render.data + p * 4;
        for (int c = 0; c < 3; c++) {
            spr[c] += (double)ph[c] * re[c];
            srr[c] += (double)re[c] * re[c];
        }
        fit->pixels++;
    }
    free(ratio);
    for (int c = 0; c < 3; c++)
        fit->gain[c] = srr[c] > 0 ? spr[c] / srr[c] : 0;
    fit->scale = sl_luminance(fit->gain);
    if (!(fit->scale > 0) || !isfinite(fit->scale) || fit->pixels < 16) {
        free(tmp);
        sl_grey_fit_free(fit);
        return sl_error_set(err, SL_ERR_INPUT,
                            "grey sphere: no consistent ratio between photo and render");
    }
    for (int c = 0; c < 3; c++)
        fit->balance[c] = fit->gain[c] / fit->scale;
    double e0 = 0, e1 = 0, ref = 0;
    size_t m = 0;
    for (size_t p = 0; p < cnt; p++) {
        float *ph = fit->photo.data + p * 4, *re = fit->render.data + p * 4,
              *er = fit->error.data + p * 4;
        double before[3];
        for (int c = 0; c < 3; c++) {
            before[c] = re[c] * fit->scale;
            re[c] = (float)(re[c] * fit->gain[c]);
        }
        er[3] = ph[3];
        if (ph[3] == 0) {
            er[0] = er[1] = er[2] = 0;
            continue;
        }
        double l = sl_luminance_px(ph);
        for (int c = 0; c < 3; c++) {
            e0 += (before[c] - ph[c]) * (before[c] - ph[c]);
            e1 += ((double)re[c] - ph[c]) * ((double)re[c] - ph[c]);
            ref += (double)ph[c] * ph[c];
            er[c] = (float)(l > 0 ? (re[c] - ph[c]) / l : 0);
        }
        tmp[m++] = fabs(sl_luminance_px(er));
    }
    qsort(tmp, m, sizeof(double), sl_cmp_double);
    fit->error_p95 = m ? tmp[(size_t)(0.95 * (double)(m - 1))] : 0;
    free(tmp);
    fit->rel_rmse_before = sqrt(e0 / ref);
    fit->rel_rmse_after = sqrt(e1 / ref);
    return SL_OK;
}
