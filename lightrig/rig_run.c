/* SPDX-License-Identifier: BSD-3-Clause */
/* The rig stage from files to files: area lights plus a residual dome
 * extracted from a lat-long, written as USD (and JSON, preview, textures)
 * with the validation renders' report, as one output set. */
#include <jansson.h>
#include <libgen.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "lightrig_private.h"

void sl_rig_run_options_init(sl_rig_run_options *o)
{
    memset(o, 0, sizeof *o);
    sl_rig_options_default(&o->rig);
    o->textures = SL_RIG_TEXTURES_AUTO;
    o->validate_width = 96;
}

void sl_rig_run_result_free(sl_rig_run_result *res)
{
    sl_rig_validation_free(&res->validation);
    sl_rig_free(&res->rig);
    free(res->json);
    res->json = NULL;
}

static bool has_suffix(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

/* The residual's name as the USD file should reference it: bare when both
 * sit in one folder, else absolute. */
static void dome_reference(const char *usda, const char *residual, char *out, size_t size)
{
    char a[PATH_MAX], b[PATH_MAX], ra[PATH_MAX], rb[PATH_MAX];
    snprintf(a, sizeof a, "%s", usda);
    snprintf(b, sizeof b, "%s", residual);
    const char *da = dirname(a), *db = dirname(b);
    if (realpath(da, ra) && realpath(db, rb) && strcmp(ra, rb) == 0) {
        snprintf(b, sizeof b, "%s", residual);
        snprintf(out, size, "%s", basename(b));
    } else if (residual[0] == '/' || !realpath(db, rb)) {
        snprintf(out, size, "%s", residual);
    } else {
        snprintf(b, sizeof b, "%s", residual);
        snprintf(out, size, "%s/%s", rb, basename(b));
    }
}

/* The rig as JSON at PATH for the validation renders, naming the files of
 * the output set as they are before the commit (their temporaries). */
static sl_result write_pending_rig_json(const sl_rig *rig, const char *path, const char *usda,
                                        const char *residual, sl_error *err)
{
    sl_rig pending = *rig;
    pending.lights = malloc((size_t)(rig->light_count ? rig->light_count : 1) *
                            sizeof *pending.lights);
    if (!pending.lights)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    char dir[PATH_MAX];
    snprintf(dir, sizeof dir, "%s", usda);
    const char *slash = strrchr(dir, '/');
    if (slash)
        dir[slash - dir + 1] = 0;
    else
        dir[0] = 0;
    for (int i = 0; i < rig->light_count; i++) {
        pending.lights[i] = rig->lights[i];
        if (!rig->lights[i].texture[0])
            continue;
        char final[2 * PATH_MAX];
        snprintf(final, sizeof final, "%s%s", dir, rig->lights[i].texture);
        const char *temp = sl_output_set_pending(final);
        const char *base = temp ? strrchr(temp, '/') : NULL;
        if (temp)
            snprintf(pending.lights[i].texture, sizeof pending.lights[i].texture, "%s",
                     base ? base + 1 : temp);
    }
    const char *res_temp = sl_output_set_pending(residual);
    char dome_ref[2 * PATH_MAX + 2];
    dome_reference(usda, res_temp ? res_temp : residual, dome_ref, sizeof dome_ref);
    sl_result r = sl_rig_write_json(&pending, path, dome_ref, err);
    free(pending.lights);
    return r;
}

/* What `setlight rig --json` prints: the run's numbers and the rig itself. */
static sl_result result_json(const sl_rig_run_options *o, sl_rig_run_result *res,
                             const char *dome_ref, sl_error *err)
{
    const sl_rig *rig = &res->rig;
    char *s = sl_rig_json_string(rig, dome_ref);
    json_t *rj = s ? json_loads(s, 0, NULL) : NULL;
    free(s);
    json_t *j = json_pack(
        "{s:s, s:s, s:s?, s:s, s:s?, s:s, s:i, s:i, s:I, s:I, s:f, s:f, s:f, s:b, s:f, s:o?}",
        "input", o->input_path, "output", o->out_path, "json", o->json_path, "residual",
        res->residual_path, "preview", o->preview_path, "method",
        o->rig.method == SL_RIG_METHOD_MEDIANCUT ? "mediancut" : "regions", "lights",
        rig->light_count, "skipped", rig->skipped_count, "nonfinite", (json_int_t)rig->nonfinite,
        "negative", (json_int_t)rig->negative, "median_luminance", rig->median_luminance,
        "threshold_luminance", rig->threshold_luminance, "relative_error", rig->relative_error,
        "black", res->black, "seconds", res->seconds, "rig", rj);
    if (j && res->validated) {
        const sl_rig_validation *v = &res->validation;
        json_t *vj = json_pack("{s:i, s:I, s:f, s:f, s:s, s:{}, s:{}, s:{}}", "width", v->width,
                               "spp", (json_int_t)v->spp, "seconds", v->seconds, "cpu_seconds",
                               v->cpu_seconds, "report", res->report_path, "render_seconds",
                               "noise", "beyond_noise");
        for (int k = 0; vj && k < SL_RIG_VALIDATE_SCENES; k++) {
            json_object_set_new(vj, v->scene[k], json_real(v->error[k]));
            json_object_set_new(json_object_get(vj, "render_seconds"), v->scene[k],
                                json_pack("{s:f, s:f}", "map", v->seconds_map[k], "rig",
                                          v->seconds_rig[k]));
            json_object_set_new(json_object_get(vj, "noise"), v->scene[k],
                                json_real(v->noise[k]));
            json_object_set_new(json_object_get(vj, "beyond_noise"), v->scene[k],
                                json_real(v->beyond_noise[k]));
        }
        json_object_set_new(j, "validation", vj);
    }
    res->json = j ? json_dumps(j, JSON_INDENT(2) | JSON_REAL_PRECISION(10)) : NULL;
    json_decref(j);
    return res->json ? SL_OK : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", o->out_path);
}

sl_result sl_rig_run(const sl_rig_run_options *o, sl_rig_run_result *res, sl_error *err_out)
{
    double t0 = sl_seconds();

    sl_image env = {0};
    sl_meta meta, out_meta;
    sl_meta_init(&meta);
    sl_meta_init(&out_meta);
    sl_rig_report_tmp report_tmp = {"", -1};
    sl_error err = {0};
    memset(res, 0, sizeof *res);
    if (!o->input_path || !o->out_path || !has_suffix(o->out_path, ".usda"))
        return sl_error_set(err_out, SL_ERR_USAGE, "rig needs an input map and a .usda output");
    /* The residual beside the USD unless named; the report beside it too. */
    const char *res_path = o->residual_path;
    if (!res_path) {
        snprintf(res->residual_path, sizeof res->residual_path, "%.*s_residual.exr",
                 (int)(strlen(o->out_path) - 5), o->out_path);
        res_path = res->residual_path;
    } else {
        snprintf(res->residual_path, sizeof res->residual_path, "%s", res_path);
    }
    char rep_dir[PATH_MAX], rep_name[PATH_MAX];
    {
        char a[PATH_MAX], b[PATH_MAX];
        snprintf(a, sizeof a, "%s", o->out_path);
        snprintf(b, sizeof b, "%s", o->out_path);
        snprintf(rep_dir, sizeof rep_dir, "%s", dirname(a));
        const char *base = basename(b);
        snprintf(rep_name, sizeof rep_name, "%.*s.validate", (int)(strlen(base) - 5), base);
    }
    if (o->validate_spp > 0 && sl_rig_validate_report_check(rep_dir, rep_name, err_out))
        return SL_ERR_USAGE;
    sl_result r = sl_check_input_file(o->input_path, &err);
    if (r || (r = sl_latlong_read(o->input_path, o->input_colorspace, &env, &meta, NULL, &err)))
        goto fail;
    /* The rig's files are one set, renamed into place together at the end:
     * an interrupt or a failure leaves every earlier one as it was. */
    char textures_glob[PATH_MAX];
    snprintf(textures_glob, sizeof textures_glob, "%.*s_light_*", (int)(strlen(o->out_path) - 5),
             o->out_path);
    const char *members[5] = {o->out_path, res_path, o->json_path, o->preview_path, textures_glob};
    if ((r = sl_output_set_begin(members, 5, &err)))
        goto fail;
    if ((r = sl_rig_extract(&env, &o->rig, &res->rig, &err))) {
        /* library messages name the stage; name the file too */
        sl_error e2;
        sl_error_set(&e2, err.code, "%s: %s", o->input_path, err.message);
        err = e2;
        goto fail;
    }
    if (res->rig.nonfinite)
        sl_log(SL_LOG_WARN, "%s: %lld NaN/Inf samples counted, set to 0 and left out", o->input_path,
               (long long)res->rig.nonfinite);
    if (res->rig.negative)
        sl_log(SL_LOG_WARN,
               "%s: %lld negative samples (outside Rec.709's gamut, or lossy compression) set "
               "to 0",
               o->input_path, (long long)res->rig.negative);
    res->black = !(res->rig.original[0] > 0 || res->rig.original[1] > 0 || res->rig.original[2] > 0);
    if (res->black)
        sl_log(SL_LOG_WARN, "%s: the map is black: the rig is empty (no lights, black dome)",
               o->input_path);
    else if (!res->rig.light_count)
        sl_log(SL_LOG_WARN,
               "%s: nothing above %g x the median luminance: the rig is the dome alone", o->input_path,
               o->rig.threshold);

    /* Outputs: the dome first, so the USD never names a missing file. */
    char buf[1024];
    const char *cs = sl_meta_color_space(&meta);
    if (cs) {
        if ((r = sl_meta_set_color_space(&out_meta, cs, &err)))
            goto fail;
    } else {
        sl_meta_set_rec709(&out_meta);
    }
    out_meta.envmap = SL_ENVMAP_LATLONG;
    snprintf(buf, sizeof buf, "setlight %s rig: residual dome (%d lights extracted)",
             sl_version(), res->rig.light_count);
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", o->input_path, &err)))
        goto fail;
    if (res->rig.nonfinite) {
        snprintf(buf, sizeof buf, "%lld", (long long)res->rig.nonfinite);
        if ((r = sl_meta_set(&out_meta, "setlight:nonfinite_replaced", buf, &err)))
            goto fail;
    }
    /* Float: half would round the dome by up to 0.05% per texel. */
    if ((r = sl_exr_write(res_path, &res->rig.residual, &out_meta, SL_PIXEL_FLOAT, &err)))
        goto fail;
    {
        /* beside the USD, named after it */
        char prefix[PATH_MAX];
        snprintf(prefix, sizeof prefix, "%.*s", (int)(strlen(o->out_path) - 5), o->out_path);
        if ((r = sl_rig_write_textures_mode(&res->rig, &env, prefix, o->textures, &err)))
            goto fail;
        for (int i = 0; i < res->rig.light_count; i++)
            sl_log(SL_LOG_INFO, "light %d (%s): %s%s", i + 1,
                   sl_rig_shape_name(res->rig.lights[i].shape),
                   res->rig.lights[i].texture[0] ? "textured, " : "", res->rig.lights[i].texture_reason);
    }
    char dome_ref[2 * PATH_MAX + 2];
    dome_reference(o->out_path, res_path, dome_ref, sizeof dome_ref);
    if ((r = sl_rig_write_usda(&res->rig, o->out_path, dome_ref, &err)))
        goto fail;
    if (o->json_path && (r = sl_rig_write_json(&res->rig, o->json_path, dome_ref, &err)))
        goto fail;
    if (o->preview_path && (r = sl_rig_write_preview(&res->rig, &env, o->preview_path, &err)))
        goto fail;
    if (o->validate_spp > 0) {
        int width = o->validate_width > 0 ? o->validate_width : 96;
        /* The renderer reads the rig as a file: res->rig.json when written, else
         * a temporary one beside the USD (the dome reference is relative to it). */
        char tmp[PATH_MAX];
        snprintf(tmp, sizeof tmp, "%.*s.validate.json", (int)(strlen(o->out_path) - 5), o->out_path);
        if ((r = write_pending_rig_json(&res->rig, tmp, o->out_path, res_path, &err)))
            goto fail;
        r = sl_rig_validate(&env, tmp, width, o->validate_spp, &res->validation, &err);
        remove(tmp);
        if (r)
            goto fail;
        sl_log(SL_LOG_INFO,
               "validation (%d px, %lld spp, relative RMSE rig against map): grey %.2f%%, "
               "chrome %.2f%%, shadow %.2f%% (beyond the renders' noise: %.2f%%, %.2f%%, "
               "%.2f%%)",
               res->validation.width, (long long)res->validation.spp, 100 * res->validation.error[0], 100 * res->validation.error[1], 100 * res->validation.error[2],
               100 * res->validation.beyond_noise[0], 100 * res->validation.beyond_noise[1], 100 * res->validation.beyond_noise[2]);
        char about[4096];
        snprintf(about, sizeof about,
                 "%s: %d lights (method %s, energy share %g%s), %d candidates left in the dome, "
                 "ledger closure error %.1e. Written as %s. Renders %d px wide, %lld spp, "
                 "direct light and one bounce, the map's and the rig's with the same seed; "
                 "compared on the objects (relative RMSE of rig against map). setlight %s.",
                 o->input_path, res->rig.light_count,
                 o->rig.method == SL_RIG_METHOD_MEDIANCUT ? "mediancut" : "regions", o->rig.energy,
                 o->textures == SL_RIG_TEXTURES_ALL    ? ", every rect textured"
                 : o->textures == SL_RIG_TEXTURES_NONE ? ", no textures"
                                                    : "",
                 res->rig.skipped_count, res->rig.relative_error, o->out_path, res->validation.width,
                 (long long)res->validation.spp, sl_version());
        if ((r = sl_rig_validate_write_report(rep_dir, rep_name, about, &res->validation, &res->rig, &env,
                                           &report_tmp, &err)))
            goto fail;
        sl_log(SL_LOG_INFO, "validation report: %.*s.validate.html",
               (int)(strlen(o->out_path) - 5), o->out_path);
    }

    r = sl_output_set_commit(&err);
    if (report_tmp.path[0])
        sl_temp_dir_remove(report_tmp.path, report_tmp.handle);
    report_tmp.path[0] = 0;
    if (r)
        goto fail;
    res->validated = o->validate_spp > 0;
    if (res->validated)
        snprintf(res->report_path, sizeof res->report_path, "%.*s.validate.html",
                 (int)(strlen(o->out_path) - 5), o->out_path);
    res->seconds = sl_seconds() - t0;
    if ((r = result_json(o, res, dome_ref, &err)))
        goto fail;
    sl_image_free(&env);
    sl_meta_free(&meta);
    sl_meta_free(&out_meta);
    return SL_OK;

fail:
    sl_output_set_abort();
    if (report_tmp.path[0])
        sl_temp_dir_remove(report_tmp.path, report_tmp.handle);
    sl_image_free(&env);
    sl_meta_free(&meta);
    sl_meta_free(&out_meta);
    if (err_out)
        *err_out = err;
    return r;
}
