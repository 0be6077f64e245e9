/* SPDX-License-Identifier: BSD-3-Clause */
/* The unwrap stage from files to files: one or two chrome-ball photos to
 * a lat-long EXR with its provenance in the header (streamed row by row
 * when nothing follows the unwrap). */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/stitch.h"

void sl_unwrap_run_options_init(sl_unwrap_run_options *o)
{
    memset(o, 0, sizeof *o);
    o->photo_count = 1;
    sl_reflectance_constant(&o->pair.views[0].reflectance, 1, 1, 1);
    o->pair.search_deg = 20;
    o->pair.occluder_deg = 20;
    sl_ball_lens_init(&o->camera);
    o->confidence = true;
    o->compression = SL_EXR_ZIP;
}

void sl_unwrap_run_result_free(sl_unwrap_run_result *res)
{
    free(res->json);
    res->json = NULL;
}

static void reflectance_text(const sl_reflectance *r, char *buf, size_t size)
{
    if (r->kind == SL_REFLECTANCE_CONDUCTOR)
        snprintf(buf, size, "conductor n=%g,%g,%g k=%g,%g,%g", r->n[0], r->n[1], r->n[2],
                 r->k[0], r->k[1], r->k[2]);
    else
        snprintf(buf, size, "%g,%g,%g", r->value[0], r->value[1], r->value[2]);
}

/* One photo: read as scene-linear (an 8/16-bit one linearised with a
 * warning, as every command reads), its circle
 * given or detected, and its focal length in pixels. */
typedef struct view_in {
    const char *path;
    const char *colorspace; /* --input-colorspace, NULL: the file's */
    sl_image photo;
    sl_meta meta;
    bool ldr, detected; /* ldr: 8/16-bit, linearised from input_space */
    char input_space[64];
    int64_t nonfinite;
} view_in;

static sl_result load_view(view_in *v, sl_unwrap_options *o, bool have_circle,
                           const sl_ball_lens *bc, sl_error *err)
{
    sl_read_info info;
    sl_result r = sl_image_read_linear(v->path, v->colorspace, &v->photo, &v->meta, &info, err);
    if (r)
        return r;
    v->ldr = info.converted && !v->meta.is_float;
    snprintf(v->input_space, sizeof v->input_space, "%s", info.colorspace);
    /* A fisheye is refused in one line (the reading's notes are dropped then). */
    sl_fisheye_evidence fisheye;
    if ((r = sl_fisheye_check(&v->photo, false, v->path, &fisheye, err)))
        return r;
    /* Geometry: focal length in pixels of this image (lens or field of view),
     * distance in ball radii. */
    double focal_px, distance;
    sl_ball_lens_geometry(bc, v->photo.width, v->meta.focal_length_mm, &focal_px, &distance);
    if (focal_px > 0)
        o->geometry.focal_px = focal_px;
    if (distance > 0)
        o->geometry.distance = distance;
    v->detected = !have_circle;
    if (have_circle) {
        const sl_ball_circle *c = &o->circle;
        if (c->cx - c->r < 0 || c->cy - c->r < 0 || c->cx + c->r > v->photo.width ||
            c->cy + c->r > v->photo.height)
            return sl_error_set(err, SL_ERR_USAGE, "--circle %g,%g,%g is not inside the %dx%d image %s",
                                c->cx, c->cy, c->r, v->photo.width, v->photo.height, v->path);
        return SL_OK;
    }
    /* A remapped probe would be "found" as a ball filling its frame and
     * unwrapped with the wrong projection: only --circle says it is a ball. */
    bool is_map;
    if ((r = sl_probe_map_check(&v->photo, v->path, &is_map, err)))
        return r;
    return sl_ball_detect(&v->photo, v->path, &o->circle, err);
}

static void view_free(view_in *v)
{
    sl_image_free(&v->photo);
    sl_meta_free(&v->meta);
}

/* NaN (not measured) as null. */
static json_t *number(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

static json_t *circle_json(const sl_ball_circle *c, bool detected)
{
    return json_pack("{s:f, s:f, s:f, s:f, s:f, s:i, s:b}", "cx", c->cx, "cy", c->cy, "r", c->r,
                     "residual", c->residual, "uncertainty", c->uncertainty, "edge_points",
                     c->edge_points, "detected", detected);
}

/* The output: its header from everything known before the pixels, and
 * the stream the rows go to when they are written as they are done. */
typedef struct out_job {
    const char *path;
    const view_in *views;
    int nviews;
    const sl_unwrap_pair_options *po;
    const sl_unwrap_pair_info *pinfo;
    int camera;
    bool confidence, have_patch;
    const double *patch;
    sl_pixel_type type;
    sl_exr_compression compression;
    sl_meta *meta;
    sl_exr_stream *stream;
    double write_s, write_cpu; /* time in the rows' conversion, encoding and writing */
} out_job;

/* The reflectance as the header and the JSON give it. */
static void reflectance_desc(const out_job *j, char *buf, size_t size)
{
    reflectance_text(&j->po->views[0].reflectance, buf, size);
    if (j->have_patch) {
        size_t len = strlen(buf);
        snprintf(buf + len, size - len, " (from a patch at %g,%g, %g deg)", j->patch[0],
                 j->patch[1], j->patch[2]);
    }
}

static sl_result output_meta(const out_job *j, sl_error *err)
{
    const view_in *views = j->views;
    const sl_unwrap_pair_options *po = j->po;
    const sl_unwrap_pair_info *pinfo = j->pinfo;
    int nviews = j->nviews;
    j->meta->envmap = SL_ENVMAP_LATLONG;
    char buf[1024], refl[160];
    reflectance_desc(j, refl, sizeof refl);
    const char *cs = sl_meta_color_space(&views[0].meta);
    if (!cs || !strcmp(cs, "srgb"))
        cs = "lin_rec709";
    struct {
        const char *name;
        char value[256];
    } attrs[16];
    int na = 0;
    for (int i = 0; i < nviews; i++) {
        const sl_unwrap_options *oi = &po->views[i];
        const sl_unwrap_info *ii = &pinfo->views[i];
        snprintf(attrs[na].value, sizeof attrs[na].value, "%.4f,%.4f,%.4f", oi->circle.cx,
                 oi->circle.cy, oi->circle.r);
        attrs[na++].name = i ? "setlight:ball2_circle" : "setlight:ball_circle";
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "%s, fit residual %.3f px, standard error %.3f px, %d edge points",
                 views[i].detected ? "detected" : "given", oi->circle.residual,
                 oi->circle.uncertainty, oi->circle.edge_points);
        attrs[na++].name = i ? "setlight:ball2_circle_source" : "setlight:ball_circle_source";
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "%s, focal %.3f px, distance %.4f ball radii, ball %.3f deg, off axis %.3f deg",
                 j->camera == SL_BALL_PERSPECTIVE ? "perspective" : "orthographic", ii->focal_px,
                 ii->distance, ii->ball_angle_deg, ii->off_axis_deg);
        attrs[na++].name = i ? "setlight:ball2_camera" : "setlight:ball_camera";
        snprintf(attrs[na].value, sizeof attrs[na].value, "azimuth %g, elevation %g, roll %g deg",
                 i ? pinfo->azimuth_deg : oi->geometry.azimuth_deg, oi->geometry.elevation_deg,
                 oi->geometry.roll_deg);
        attrs[na++].name = i ? "setlight:camera2_orientation" : "setlight:camera_orientation";
    }
    if (nviews == 2) {
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "view 2 azimuth %.3f deg (given %.3f, searched +-%g), median |log| luminance "
                 "difference %.4f (%.4f as given), overlap %.3f of the sphere, occluder cones "
                 "%g deg",
                 pinfo->azimuth_deg, pinfo->azimuth_given_deg, po->search_deg, pinfo->residual,
                 pinfo->residual_given, pinfo->overlap_fraction, po->occluder_deg);
        attrs[na++].name = "setlight:two_views";
    }
    snprintf(attrs[na].value, sizeof attrs[na].value, "%s", refl);
    attrs[na++].name = "setlight:ball_reflectance";
    snprintf(attrs[na].value, sizeof attrs[na].value, "%.3f", pinfo->views[0].blind_angle_deg);
    attrs[na++].name = "setlight:blind_cone_deg";
    if (j->confidence) {
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "confidence: resolution relative to the ball centre, 0 where unseen");
        attrs[na++].name = "setlight:alpha";
    }
    if (views[0].ldr || views[1].ldr) {
        const view_in *v = views[0].ldr ? &views[0] : &views[1];
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "8/16-bit input linearised from %s through OpenColorIO", v->input_space);
        attrs[na++].name = "setlight:input_note";
    }
    snprintf(buf, sizeof buf, "setlight %s unwrap", sl_version());
    sl_result r;
    if ((r = sl_meta_set(j->meta, "setlight:command", buf, err)) ||
        (r = sl_meta_set(j->meta, "setlight:source", views[0].path, err)) ||
        (nviews == 2 && (r = sl_meta_set(j->meta, "setlight:source2", views[1].path, err))) ||
        (r = sl_meta_set_color_space(j->meta, cs, err)))
        return r;
    for (int i = 0; i < na; i++)
        if ((r = sl_meta_set(j->meta, attrs[i].name, attrs[i].value, err)))
            return r;
    return SL_OK;
}

/* Adds the wall and CPU time since t, c to the output's writing time. */
static void writing_took(out_job *j, double t, double c)
{
    j->write_s += sl_seconds() - t;
    j->write_cpu += sl_cpu_seconds() - c;
}

/* sl_unwrap_sink: the header once the geometry is known, then the rows. */
static sl_result stream_begin(void *user, const sl_unwrap_info *info, int channels,
                              sl_error *err)
{
    out_job *j = user;
    double t = sl_seconds(), c = sl_cpu_seconds();
    sl_result r = output_meta(j, err);
    if (!r)
        r = sl_exr_stream_open(j->path, info->width, info->height, channels, j->meta, j->type,
                               j->compression, &j->stream, err);
    writing_took(j, t, c);
    return r;
}

/* Called while the next rows are unwrapped (sl_unwrap_stream overlaps
 * the two): its time is the unwrap stage's, not the writing's. */
static sl_result stream_rows(void *user, const float *rows, int count, size_t stride,
                             sl_error *err)
{
    out_job *j = user;
    sl_result r = sl_exr_stream_write(j->stream, rows, count, stride, err);
    if (r)
        j->stream = NULL; /* a failed write aborts the stream */
    return r;
}

sl_result sl_unwrap_run(const sl_unwrap_run_options *ro, sl_unwrap_run_result *res,
                        sl_error *err_out)
{
    memset(res, 0, sizeof *res);
    int nviews = ro->photo_count;
    if (!ro->out_path || nviews < 1 || nviews > 2 || !ro->photo_paths[0] ||
        (nviews == 2 && !ro->photo_paths[1]))
        return sl_error_set(err_out, SL_ERR_USAGE, "unwrap needs one or two ball photos and an output");
    sl_unwrap_pair_options po = ro->pair;
    sl_unwrap_options *o = &po.views[0], *o2 = &po.views[1];
    double t0 = sl_seconds(), cpu0 = sl_cpu_seconds();

    view_in views[2];
    memset(views, 0, sizeof views);
    views[0].colorspace = views[1].colorspace = ro->input_colorspace;
    views[0].path = ro->photo_paths[0];
    views[1].path = nviews == 2 ? ro->photo_paths[1] : NULL;
    sl_image out = {0};
    sl_meta out_meta;
    sl_meta_init(&out_meta);
    out_job job;
    memset(&job, 0, sizeof job);
    sl_error err = {0};
    sl_result r;

    if ((r = load_view(&views[0], o, ro->have_circle[0], &ro->camera, &err)))
        goto fail;
    if (nviews == 2) {
        o2->geometry = o->geometry;
        o2->geometry.focal_px = 0;
        o2->geometry.azimuth_deg = ro->have_camera2[0] ? ro->camera2[0] : o->geometry.azimuth_deg + 90.0;
        if (ro->have_camera2[1])
            o2->geometry.elevation_deg = ro->camera2[1];
        if (ro->have_camera2[2])
            o2->geometry.roll_deg = ro->camera2[2];
        o2->reflectance = o->reflectance;
        o2->width = o->width;
        if ((r = load_view(&views[1], o2, ro->have_circle[1], &ro->camera, &err)))
            goto fail;
    }
    int camera = ro->camera.camera;
    if (camera < 0)
        camera = o->geometry.focal_px > 0 || o->geometry.distance > 0 ? SL_BALL_PERSPECTIVE
                                                                     : SL_BALL_ORTHOGRAPHIC;
    o->geometry.camera = o2->geometry.camera = (sl_ball_camera)camera;

    /* The patch is found with the confidence, the merge weighs by it. */
    o->no_confidence = !ro->confidence && !ro->have_patch && nviews == 1;
    double t1 = sl_seconds(), cpu1 = sl_cpu_seconds();
    sl_unwrap_pair_info pinfo;
    memset(&pinfo, 0, sizeof pinfo);
    sl_unwrap_info *info = &pinfo.views[0];
    double refl_patch[3] = {0, 0, 0};
    job = (out_job){.path = ro->out_path, .views = views, .nviews = nviews, .po = &po,
                    .pinfo = &pinfo, .camera = camera, .confidence = ro->confidence,
                    .have_patch = ro->have_patch, .patch = ro->patch,
                    .type = ro->write_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF,
                    .compression = ro->compression, .meta = &out_meta};
    /* One photo, nothing to do after the unwrap: rows go to the file as
     * they are done (no whole lat-long in memory, encoding strip by strip). */
    bool streamed = nviews == 1 && !ro->have_patch;
    if (streamed) {
        sl_unwrap_sink sink = {stream_begin, stream_rows, &job};
        r = sl_unwrap_stream(&views[0].photo, o, &sink, info, &err);
        if (!r) {
            double ts = sl_seconds(), cs = sl_cpu_seconds();
            r = sl_exr_stream_finish(job.stream, NULL, &err);
            job.stream = NULL;
            writing_took(&job, ts, cs);
        }
        if (r)
            goto fail;
    } else {
        if (nviews == 2)
            r = sl_unwrap_pair(&views[0].photo, &views[1].photo, &po, &out, &pinfo, &err);
        else
            r = sl_unwrap(&views[0].photo, o, &out, info, &err);
        if (r)
            goto fail;
    }
    if (ro->have_patch) {
        double az = ro->patch[0] * M_PI / 180.0, el = ro->patch[1] * M_PI / 180.0;
        double dir[3] = {sin(az) * cos(el), sin(el), cos(az) * cos(el)};
        if ((r = sl_unwrap_patch_reflectance(&out, dir, ro->patch[2] * M_PI / 180.0, ro->patch + 3,
                                             refl_patch, &err))) {
            char why[sizeof err.message];
            snprintf(why, sizeof why, "%s", err.message);
            sl_error_set(&err, r, "%s: %s", views[0].path, why);
            goto fail;
        }
        for (int y = 0; y < out.height; y++)
            for (int x = 0; x < out.width; x++) {
                float *p = sl_image_pixel(&out, x, y);
                for (int k = 0; k < 3; k++)
                    p[k] = (float)(p[k] / refl_patch[k]);
            }
        sl_reflectance_constant(&o->reflectance, refl_patch[0], refl_patch[1], refl_patch[2]);
        sl_log(SL_LOG_INFO, "ball reflectance from the patch: %.4f, %.4f, %.4f", refl_patch[0],
               refl_patch[1], refl_patch[2]);
    }
    /* The streamed unwrap's time includes its rows' conversion, encoding
     * and writing (overlapped with it), not the file's opening and finish. */
    double t_unwrap = sl_seconds() - t1 - job.write_s;
    double cpu_unwrap = sl_cpu_seconds() - cpu1 - job.write_cpu;
    for (int i = 0; i < nviews; i++)
        if (pinfo.views[i].nonfinite)
            sl_log(SL_LOG_WARN, "%s: %lld NaN/Inf samples replaced by 0", views[i].path,
                   (long long)pinfo.views[i].nonfinite);
    if (nviews == 2 && po.search_deg > 0)
        sl_log(SL_LOG_INFO,
               "%s: view 2 azimuth %.3f deg (given %.3f), median log luminance difference "
               "%.4f (%.4f as given) over %.1f%% of the sphere",
               views[1].path, pinfo.azimuth_deg, pinfo.azimuth_given_deg, pinfo.residual,
               pinfo.residual_given, 100.0 * pinfo.overlap_fraction);
    if (!streamed) {
        if (!ro->confidence && out.channels == 4) {
            sl_image rgb;
            if ((r = sl_image_convert_channels(&out, 3, &rgb, &err)))
                goto fail;
            sl_image_free(&out);
            out = rgb;
        }
        double t3 = sl_seconds(), c3 = sl_cpu_seconds();
        if ((r = output_meta(&job, &err)) ||
            (r = sl_exr_write_compressed(ro->out_path, &out, &out_meta, job.type, ro->compression, &err)))
            goto fail;
        writing_took(&job, t3, c3);
    }
    char refl[160];
    reflectance_desc(&job, refl, sizeof refl);
    int out_w = streamed ? info->width : out.width, out_h = streamed ? info->height : out.height;

    res->info = pinfo;
    res->circle[0] = o->circle;
    res->circle[1] = o2->circle;
    res->detected[0] = views[0].detected;
    res->detected[1] = views[1].detected;
    res->camera = (sl_ball_camera)camera;
    res->width = out_w;
    res->height = out_h;
    res->reflectance = o->reflectance;
    memcpy(res->patch_reflectance, refl_patch, sizeof refl_patch);
    res->streamed = streamed;
    res->ldr_linearised = views[0].ldr || views[1].ldr;
    res->read_detect_s = t1 - t0;
    res->read_detect_cpu = cpu1 - cpu0;
    res->unwrap_s = t_unwrap;
    res->unwrap_cpu = cpu_unwrap;
    res->write_s = job.write_s;
    res->write_cpu = job.write_cpu;
    res->seconds = sl_seconds() - t0;
    {
        json_t *j = json_pack(
            "{s:s, s:s, s:o, s:s, s:f, s:f, s:f, s:f, s:f, s:i, s:i, s:s, s:f, s:I, s:b, s:f, "
            "s:{s:f, s:f, s:f, s:f, s:f, s:f, s:b}}",
            "input", views[0].path, "output", ro->out_path, "circle",
            circle_json(&o->circle, views[0].detected), "camera",
            camera == SL_BALL_PERSPECTIVE ? "perspective" : "orthographic", "focal_px",
            info->focal_px, "distance_radii", info->distance, "ball_angle_deg",
            info->ball_angle_deg, "off_axis_deg", info->off_axis_deg, "centre_px_per_rad",
            info->centre_px_per_rad, "width", out_w, "height", out_h, "reflectance",
            refl, "blind_fraction", info->blind_fraction, "nonfinite_replaced",
            (json_int_t)(pinfo.views[0].nonfinite + pinfo.views[1].nonfinite), "ldr_linearised",
            res->ldr_linearised, "seconds", res->seconds, "timing", "read_detect",
            t1 - t0, "read_detect_cpu", cpu1 - cpu0, "unwrap", t_unwrap, "unwrap_cpu", cpu_unwrap,
            "write", job.write_s, "write_cpu", job.write_cpu, "streamed", streamed);
        json_object_set_new(j, "encoding",
                            json_pack("{s:s, s:s}", "pixel", ro->write_float ? "float" : "half",
                                      "compression", sl_exr_compression_name(ro->compression)));
        if (ro->have_patch)
            json_object_set_new(j, "reflectance_patch",
                                json_pack("{s:[f, f, f], s:[f, f, f]}", "radiance", ro->patch[3],
                                          ro->patch[4], ro->patch[5], "reflectance", refl_patch[0],
                                          refl_patch[1], refl_patch[2]));
        if (nviews == 2)
            json_object_set_new(
                j, "view2",
                json_pack("{s:s, s:o, s:f, s:f, s:o, s:o, s:o, s:f, s:f}", "input",
                          views[1].path, "circle", circle_json(&o2->circle, views[1].detected),
                          "azimuth_given_deg", pinfo.azimuth_given_deg, "azimuth_deg",
                          pinfo.azimuth_deg, "residual_given", number(pinfo.residual_given),
                          "residual", number(pinfo.residual), "overlap_fraction",
                          number(pinfo.overlap_fraction),
                          "focal_px", pinfo.views[1].focal_px, "distance_radii",
                          pinfo.views[1].distance));
        res->json = j ? json_dumps(j, JSON_INDENT(2)) : NULL;
        json_decref(j);
    }
    if (!res->json) {
        /* The file is in place; only the summary could not be made. */
        r = sl_error_set(&err, SL_ERR_NOMEM, "%s: out of memory", ro->out_path);
        goto fail;
    }
    view_free(&views[0]);
    view_free(&views[1]);
    sl_image_free(&out);
    sl_meta_free(&out_meta);
    return SL_OK;

fail:
    sl_exr_stream_abort(job.stream);
    view_free(&views[0]);
    view_free(&views[1]);
    sl_image_free(&out);
    sl_meta_free(&out_meta);
    if (err_out)
        *err_out = err;
    return r;
}
