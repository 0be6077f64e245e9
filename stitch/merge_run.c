/* SPDX-License-Identifier: BSD-3-Clause */
/* The merge stage from files to files (a bracket to the radiance EXR with
 * its clipped and ghost masks and provenance), and the response alone. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/stitch.h"

void sl_merge_run_options_init(sl_merge_run_options *o)
{
    memset(o, 0, sizeof *o);
    sl_merge_options_init(&o->merge);
}

void sl_merge_run_result_free(sl_merge_run_result *res)
{
    sl_merge_result_free(&res->merge);
    free(res->json);
    res->json = NULL;
}

static const char *align_mode_name(sl_align_mode mode)
{
    return mode == SL_ALIGN_ON ? "on" : mode == SL_ALIGN_AUTO ? "auto" : "off";
}

/* The alignment for --json: mode, decision, why, and what it cost. */
static json_t *response_check_json(const sl_merge_response_check *rc)
{
    return json_pack("{s:b, s:b, s:f, s:f, s:I, s:s}", "plausible", rc->plausible, "monotone",
                     rc->monotone, "frame_rms_stops", rc->frame_rms_stops, "frame_p90_stops",
                     rc->frame_p90_stops, "compared", (json_int_t)rc->compared, "note", rc->note);
}

/* The refinement under the noise for --json: done or why not, and the
 * noise law it fitted per channel (var = gain * y + floor, y on 0..1). */
static json_t *refine_json(const sl_merge_result *res)
{
    return json_pack("{s:b, s:s, s:i, s:f, s:f, s:[f,f,f], s:[f,f,f]}", "refined",
                     res->response_refined, "note", res->response_refine_note, "series",
                     res->response_refine_series, "gain_nats", res->response_refine_gain_nats,
                     "moved_ln", res->response_refine_moved, "noise_gain",
                     res->response_noise_gain[0], res->response_noise_gain[1],
                     res->response_noise_gain[2], "noise_floor", res->response_noise_floor[0],
                     res->response_noise_floor[1], res->response_noise_floor[2]);
}

/* A refinement asked for and not made: one line saying why (--json has it too). */
static void log_unrefined(const sl_merge_run_options *o, const sl_merge_result *m)
{
    if (o->merge.refine_response && o->merge.response_mode == SL_RESPONSE_AUTO &&
        !m->response_refined)
        sl_log(SL_LOG_WARN, "%s: response %s: %s", o->out_path, m->response.source,
               m->response_refine_note);
}

static json_t *align_json(const sl_merge_result *res)
{
    return json_pack("{s:s, s:b, s:o, s:s, s:f, s:f, s:f}", "mode",
                     align_mode_name(res->align_mode), "aligned", res->aligned, "misalignment_px",
                     res->misalignment_px >= 0 ? json_real(res->misalignment_px) : json_null(),
                     "note", res->align_note, "measure_cpu_seconds", res->align_measure_cpu,
                     "cpu_seconds", res->timing.cpu[SL_MERGE_ALIGN], "wall_seconds",
                     res->timing.wall[SL_MERGE_ALIGN]);
}

/* Per frame in the given order, for the summary line: "ref", "+0.03,-0.28"
 * (dx,dy in px), "?" when it could not be estimated. */
static void shifts_text(const sl_merge_result *res, char *out, size_t size)
{
    size_t n = 0;
    out[0] = '\0';
    for (int i = 0; i < res->frame_count && n < size; i++) {
        const sl_align_transform *t = &res->frames[i].align;
        int k = !strcmp(t->note, "reference") ? snprintf(out + n, size - n, "%sref", i ? " " : "")
                : t->refused ? snprintf(out + n, size - n, "%s?", i ? " " : "")
                             : snprintf(out + n, size - n, "%s%+.2f,%+.2f", i ? " " : "", t->dx, t->dy);
        n += k > 0 ? (size_t)k : 0;
    }
}

static json_t *frames_json(const sl_merge_result *res, bool aligned)
{
    json_t *a = json_array();
    for (int i = 0; i < res->frame_count; i++) {
        const sl_merge_frame *f = &res->frames[i];
        json_t *o;
        json_array_append_new(
            a, o = json_pack("{s:s, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:b, s:i, s:f, s:f}", "path",
                         f->path, "time", f->time, "f_number", f->f_number, "iso", f->iso,
                         "exif_exposure", f->exif_exposure, "fitted_exposure",
                         f->fitted_exposure, "exposure", f->exposure, "disagreement_stops",
                         f->disagreement_stops, "disagrees", f->disagrees, "rank", f->rank,
                         "saturated_fraction", f->saturated_fraction, "black_fraction",
                         f->black_fraction));
        if (aligned)
            json_object_set_new(o, "align",
                                json_pack("{s:f, s:f, s:f, s:f, s:I, s:b, s:b, s:s}", "dx",
                                          f->align.dx, "dy", f->align.dy, "angle_deg",
                                          f->align.angle, "displacement_px",
                                          sl_align_displacement(&f->align, res->width, res->height), "pixels",
                                          (json_int_t)f->align.pixels, "applied", f->align.applied,
                                          "refused", f->align.refused, "note", f->align.note));
    }
    return a;
}

/* Wall and CPU seconds per phase and in all; "process_cpu" adds the
 * process's start-up (loading the libraries) to the merge's CPU. */
static json_t *timing_json(const sl_merge_result *res)
{
    json_t *o = json_object();
    for (int p = 0; p < SL_MERGE_PHASES; p++)
        json_object_set_new(o, sl_merge_phase_name((sl_merge_phase)p),
                            json_pack("{s:f, s:f}", "wall", res->timing.wall[p], "cpu",
                                      res->timing.cpu[p]));
    json_object_set_new(o, "total",
                        json_pack("{s:f, s:f}", "wall", res->seconds, "cpu", res->cpu_seconds));
    json_object_set_new(o, "process_cpu", json_real(sl_cpu_seconds()));
    return o;
}

static void log_frames(const sl_merge_result *res, bool aligned, double auto_px)
{
    for (int i = 0; i < res->frame_count; i++) {
        const sl_merge_frame *f = &res->frames[i];
        if (aligned && !strcmp(f->align.note, "reference"))
            sl_log(SL_LOG_INFO, "%s: alignment reference", f->path);
        else if (aligned && f->align.refused)
            sl_log(SL_LOG_WARN,
                   "%s: %s: not aligned; %s where its neighbour in exposure is (shift %+.2f, "
                   "%+.2f px, rotation %+.3f deg)",
                   f->path, f->align.note, f->align.applied ? "resampled" : "left",
                   f->align.dx, f->align.dy, f->align.angle);
        else if (aligned)
            sl_log(SL_LOG_INFO, "%s: shift %+.2f, %+.2f px, rotation %+.3f deg%s%s", f->path,
                   f->align.dx, f->align.dy, f->align.angle, f->align.note[0] ? "; " : "",
                   f->align.note);
        if (f->disagrees)
            sl_log(SL_LOG_WARN,
                   "%s: exposure from the pixels is %+.2f stops off what EXIF/--times says",
                   f->path, f->disagreement_stops);
    }
    if (res->fitted_ratios < res->frame_count - 1)
        sl_log(SL_LOG_WARN, "%d of %d exposure steps could not be measured from the pixels",
               res->frame_count - 1 - res->fitted_ratios, res->frame_count - 1);
    /* The camera moved and the frames were registered without being asked:
     * say so, and how to have them merged as shot. */
    if (res->align_mode == SL_ALIGN_AUTO && res->aligned)
        sl_log(SL_LOG_WARN, "frames registered before merging: %s (--align=off merges them as shot)",
               res->align_note);
    else if (res->align_mode == SL_ALIGN_AUTO &&
             (res->misalignment_px < 0 || res->misalignment_px > auto_px))
        sl_log(SL_LOG_WARN, "%s (--align=on registers them anyway)", res->align_note);
}

/* "dir/name.exr" -> "dir/name_SUFFIX.exr" */
static char *sidecar_path(const char *out, const char *suffix)
{
    size_t n = strlen(out);
    const char *dot = strrchr(out, '.'), *slash = strrchr(out, '/');
    size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - out) : n;
    char *p = malloc(n + strlen(suffix) + 8);
    if (p)
        snprintf(p, n + strlen(suffix) + 8, "%.*s_%s.exr", (int)stem, out, suffix);
    return p;
}

sl_result sl_merge_run(const sl_merge_run_options *o, sl_merge_run_result *res, sl_error *err)
{
    memset(res, 0, sizeof *res);
    if (!o->out_path || o->frame_count < 1 || !o->frame_paths)
        return sl_error_set(err, SL_ERR_USAGE, "merge needs the bracket's frames and an output");
    char *mask = o->no_mask ? NULL : o->mask_path ? strdup(o->mask_path)
                                                  : sidecar_path(o->out_path, "clipped");
    char *ghost = !o->merge.deghost ? NULL : o->ghost_path ? strdup(o->ghost_path)
                                                           : sidecar_path(o->out_path, "ghost");
    sl_merge_result *m = &res->merge;
    sl_result r = (!o->no_mask && !mask) || (o->merge.deghost && !ghost)
                      ? sl_error_set(err, SL_ERR_NOMEM, "out of memory")
                      : sl_merge_to_exr(o->frame_paths, o->frame_count, &o->merge, o->out_path,
                                        mask, ghost, m, err);
    if (r) {
        free(mask);
        free(ghost);
        return r;
    }
    snprintf(res->mask_path, sizeof res->mask_path, "%s", mask ? mask : "");
    snprintf(res->ghost_path, sizeof res->ghost_path, "%s", ghost ? ghost : "");
    bool measured = m->align_mode != SL_ALIGN_OFF;
    log_frames(m, measured, o->merge.align_auto_px);
    char shifts[64 * 24] = "";
    if (measured)
        shifts_text(m, shifts, sizeof shifts);
    sl_log(SL_LOG_INFO,
           "%s: %d frames, response %s, %lld pixels clipped in every frame (%.4f%%), "
           "shifts (px) %s (%s), %.2f s",
           o->out_path, m->frame_count, m->response.source, (long long)m->clipped_pixels,
           100 * m->clipped_fraction, measured ? shifts : "not measured",
           m->aligned ? "aligned" : "merged as shot", m->seconds);
    const sl_merge_response_check *rc = &m->response_check;
    if (!rc->plausible)
        sl_log(SL_LOG_WARN, "%s: response %s: %s", o->out_path, m->response.source, rc->note);
    log_unrefined(o, m);
    json_t *j = json_pack(
        "{s:s, s:s?, s:s?, s:I, s:i, s:i, s:s, s:o, s:s, s:o, s:o, s:i, s:I, s:[I,I,I], s:f, s:f, s:I, s:I, s:I, s:s, s:f, s:{s:f, s:f, s:f, s:f}, s:{s:s, s:s, s:f, s:s}, s:i, s:f, s:o}",
        "output", o->out_path, "mask", mask, "ghost_mask", ghost, "ghost_pixels",
        (json_int_t)m->ghost_pixels, "width", m->width, "height", m->height, "response",
        m->response.source, "response_check", response_check_json(rc), "exposures", o->merge.exposures == SL_EXPOSURES_DATA ? "data" : "exif",
        "frames", frames_json(m, measured), "align", align_json(m), "reference_frame",
        m->reference, "clipped_pixels", (json_int_t)m->clipped_pixels, "clipped_samples",
        (json_int_t)m->clipped_samples[0], (json_int_t)m->clipped_samples[1],
        (json_int_t)m->clipped_samples[2], "clipped_fraction", m->clipped_fraction,
        "clipped_solid_angle_sr", m->clipped_solid_angle, "underexposed_samples",
        (json_int_t)m->underexposed_samples, "disagreeing_frames",
        (json_int_t)m->disagreeing_frames, "nonfinite_samples", (json_int_t)m->nonfinite_samples,
        "units", m->absolute ? "cd/m^2" : "relative", "output_exposure", m->output_exposure,
        "weights", "noise_gain", m->noise_gain, "noise_floor", m->noise_floor, "black", m->black,
        "saturation", m->saturation, "encoding", "pixels",
        m->pixel_type == SL_PIXEL_HALF ? "half" : "float", "compression",
        sl_exr_compression_name(m->compression), "max_value", m->max_value, "why",
        m->encoding_note, "frames_decoded_once", m->held_frames, "seconds", m->seconds, "timing",
        timing_json(m));
    free(mask);
    free(ghost);
    if (j)
        json_object_set_new(j, "response_refine", refine_json(m));
    res->json = j ? json_dumps(j, JSON_INDENT(2)) : NULL;
    json_decref(j);
    /* The files are in place; only the summary could not be made. */
    return res->json ? SL_OK : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", o->out_path);
}

sl_result sl_response_run(const sl_merge_run_options *o, sl_merge_run_result *res, sl_error *err)
{
    memset(res, 0, sizeof *res);
    if (!o->out_path || o->frame_count < 1 || !o->frame_paths)
        return sl_error_set(err, SL_ERR_USAGE, "response needs the bracket's frames and an output");
    sl_merge_result *m = &res->merge;
    sl_result r = sl_merge_response(o->frame_paths, o->frame_count, &o->merge, m, err);
    if (!r)
        r = sl_response_write(o->out_path, &m->response, err);
    if (r)
        return r;
    log_frames(m, m->align_mode != SL_ALIGN_OFF, o->merge.align_auto_px);
    double mid[3];
    for (int c = 0; c < 3; c++)
        mid[c] = sl_response_eval(&m->response, c, 0.5);
    if (!m->response_check.plausible)
        sl_log(SL_LOG_WARN, "%s: response %s: %s", o->out_path, m->response.source,
               m->response_check.note);
    log_unrefined(o, m);
    json_t *j = json_pack("{s:s, s:s, s:o, s:i, s:[f,f,f], s:o, s:o, s:I, s:f, s:o}", "output",
                          o->out_path, "source", m->response.source, "response_check",
                          response_check_json(&m->response_check), "nodes", m->response.nodes,
                          "linear_at_half", mid[0], mid[1], mid[2], "frames",
                          frames_json(m, m->align_mode != SL_ALIGN_OFF), "align", align_json(m),
                          "disagreeing_frames", (json_int_t)m->disagreeing_frames, "seconds",
                          m->seconds, "timing", timing_json(m));
    if (j)
        json_object_set_new(j, "response_refine", refine_json(m));
    res->json = j ? json_dumps(j, JSON_INDENT(2)) : NULL;
    json_decref(j);
    return res->json ? SL_OK : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", o->out_path);
}
