/* SPDX-License-Identifier: BSD-3-Clause */
/* Render statistics as JSON: error against time per pass, throughput and
 * what the integrator skipped (docs/render.md). */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"

/* A mip level of the dome's cells in words: k > 0 blocks of 2^k x 2^k
 * texels, 0 a texel, k < 0 pieces 1/2^-k of a texel on a side. */
static void level_words(int k, char *buf, size_t size)
{
    if (k > 0)
        snprintf(buf, size, "%dx%d texels", 1 << (k > 30 ? 30 : k), 1 << (k > 30 ? 30 : k));
    else if (k == 0)
        snprintf(buf, size, "single texels");
    else
        snprintf(buf, size, "1/%d texel", 1 << (-k > 30 ? 30 : -k));
}

const char *sl_closed_form_describe(const sl_closed_form_stats *st, char *buf, size_t size)
{
    char top[48], fine[48], lights[96] = "", cut[352] = "", coarse[192] = "";
    size_t n = 0;
    if (st->evaluations > 0 && st->cells > 0) {
        level_words(st->top_level, top, sizeof top);
        level_words(st->finest_level, fine, sizeof fine);
        if (st->finest_level < st->top_level)
            n = (size_t)snprintf(buf, size, "dome cells of %s, split down to %s where the horizon cuts them",
                                 top, fine);
        else
            n = (size_t)snprintf(buf, size, "dome cells of %s", top);
    } else {
        n = (size_t)snprintf(buf, size, "no dome cells evaluated");
    }
    if (st->lights_exact + st->lights_sampled > 0)
        snprintf(lights, sizeof lights, "; rig lights: %d exact, %d sampled (textured)", st->lights_exact,
                 st->lights_sampled);
    if (st->cut_by_time)
        snprintf(cut, sizeof cut,
                 "; --time ran out while planning: %lld of %lld closed-form pixels refined to the "
                 "tolerance (the others keep a coarser value and its bound), %lld left to sampling (%lld "
                 "of them glossy with the sun exact, the rest of the map sampled)",
                 (long long)st->at_tolerance_pixels, (long long)(st->exact_pixels + st->control_variate_pixels),
                 (long long)st->cut_pixels, (long long)st->sun_exact_pixels);
    if (st->coarse_pixels > 0)
        snprintf(coarse, sizeof coarse,
                 "; --time ran out: %lld pixels keep the coarse pass's value and bound (tolerance %g; "
                 "%lld of them a failed block's interpolation)",
                 (long long)st->coarse_pixels, st->coarse_tolerance, (long long)st->provisional_pixels);
    if (n < size)
        snprintf(buf + n, size - n, "%s%s%s", lights, cut, coarse);
    return buf;
}

sl_result sl_render_stats_write_json(const sl_render_stats *st, const sl_render_options *o,
                                     const char *path, sl_error *err)
{
    json_t *root = json_object(), *passes = json_array();
    json_object_set_new(root, "strategy", json_string(sl_strategy_name(o->strategy)));
    json_object_set_new(root, "low_discrepancy", json_boolean(o->low_discrepancy));
    json_object_set_new(root, "bounces", json_integer(o->bounces));
    json_object_set_new(root, "seed", json_integer((json_int_t)o->seed));
    json_object_set_new(root, "spp", json_integer(st->spp));
    json_object_set_new(root, "seconds", json_real(st->seconds));
    json_object_set_new(root, "cpu_seconds", json_real(st->cpu_seconds));
    json_object_set_new(root, "samples_per_second", json_real(st->samples_per_second));
    json_object_set_new(root, "samples", json_integer(st->samples));
    json_object_set_new(root, "pixels_stopped_early", json_integer(st->pixels_stopped_early));
    json_object_set_new(root, "stop_reason", json_string(st->stop_reason));
    json_object_set_new(root, "camera_rays", json_integer(st->camera_rays));
    json_object_set_new(root, "shadow_rays", json_integer(st->shadow_rays));
    json_object_set_new(root, "bsdf_rays", json_integer(st->bsdf_rays));
    json_object_set_new(root, "shadow_rays_skipped", json_integer(st->shadow_rays_skipped));
    json_object_set_new(root, "zero_weight_skipped", json_integer(st->zero_weight_skipped));
    json_object_set_new(root, "lights_culled", json_integer(st->lights_culled));
    json_object_set_new(root, "lights_behind", json_integer(st->lights_behind));
    json_object_set_new(root, "nonfinite_samples", json_integer(st->nonfinite_samples));
    json_object_set_new(root, "dome_bad_texels", json_integer(st->dome_bad_texels));
    json_object_set_new(root, "dome_sampled", json_boolean(st->dome_sampled));
    const sl_closed_form_stats *cf = &st->closed_form;
    json_t *jc = json_object(), *objs = json_array();
    json_object_set_new(jc, "used", json_boolean(cf->used));
    json_object_set_new(jc, "reason", cf->reason[0] ? json_string(cf->reason) : json_null());
    json_object_set_new(jc, "exact_pixels", json_integer(cf->exact_pixels));
    json_object_set_new(jc, "control_variate_pixels", json_integer(cf->control_variate_pixels));
    json_object_set_new(jc, "sampled_pixels", json_integer(cf->sampled_pixels));
    for (int i = 0; i < cf->object_count; i++)
        json_array_append_new(objs, json_integer(cf->objects[i]));
    json_object_set_new(jc, "objects", objs);
    static const char *const kind[SL_MAT_COUNT] = {"lambert", "conductor", "plastic"};
    json_t *per = json_array();
    for (int i = 0; i < cf->object_count; i++) {
        json_t *jo = json_object();
        sl_material_type t = cf->object_material[i];
        json_object_set_new(jo, "shape", json_integer(cf->objects[i]));
        json_object_set_new(jo, "material", json_string(t < SL_MAT_COUNT ? kind[t] : "?"));
        json_object_set_new(jo, "exact_pixels", json_integer(cf->object_exact[i]));
        json_object_set_new(jo, "control_variate_pixels", json_integer(cf->object_control[i]));
        json_object_set_new(jo, "max_rel_bound", json_real(cf->object_max_rel_bound[i]));
        json_object_set_new(jo, "interpolated_pixels", json_integer(cf->object_interpolated[i]));
        json_object_set_new(jo, "bound", json_string(t == SL_MAT_LAMBERT && !cf->object_interpolated[i]
                                                         ? "proven"
                                                         : "estimate"));
        json_array_append_new(per, jo);
    }
    json_object_set_new(jc, "per_object", per);
    json_object_set_new(jc, "interpolated_pixels", json_integer(cf->interpolated_pixels));
    json_object_set_new(jc, "sun_texels", json_integer(cf->sun_texels));
    json_object_set_new(jc, "sun_share", json_real(cf->sun_share));
    json_object_set_new(jc, "tolerance", json_real(cf->tolerance));
    json_object_set_new(jc, "max_rel_bound", json_real(cf->max_rel_bound));
    json_object_set_new(jc, "rms_rel_bound", json_real(cf->rms_rel_bound));
    json_object_set_new(jc, "at_tolerance_share",
                        json_real(cf->exact_pixels + cf->control_variate_pixels > 0
                                      ? (double)cf->at_tolerance_pixels /
                                            (double)(cf->exact_pixels + cf->control_variate_pixels)
                                      : 1.0));
    json_object_set_new(jc, "max_footprint_error", json_real(cf->max_footprint_error));
    json_object_set_new(jc, "top_level", json_integer(cf->top_level));
    json_object_set_new(jc, "finest_level", json_integer(cf->finest_level));
    json_object_set_new(jc, "evaluations", json_integer(cf->evaluations));
    json_object_set_new(jc, "cells", json_integer(cf->cells));
    json_object_set_new(jc, "lights_exact", json_integer(cf->lights_exact));
    json_object_set_new(jc, "lights_sampled", json_integer(cf->lights_sampled));
    json_object_set_new(jc, "cut_by_time", json_boolean(cf->cut_by_time));
    json_object_set_new(jc, "cut_pixels", json_integer(cf->cut_pixels));
    json_object_set_new(jc, "sun_exact_pixels", json_integer(cf->sun_exact_pixels));
    json_object_set_new(jc, "coarse_pixels", json_integer(cf->coarse_pixels));
    json_object_set_new(jc, "coarse_tolerance", json_real(cf->coarse_tolerance));
    json_object_set_new(jc, "provisional_pixels", json_integer(cf->provisional_pixels));
    json_object_set_new(jc, "refined_pixels", json_integer(cf->refined_pixels));
    json_object_set_new(jc, "shadow_exact_pixels", json_integer(cf->shadow_exact_pixels));
    json_object_set_new(jc, "shadow_evaluations", json_integer(cf->shadow_evaluations));
    json_object_set_new(jc, "shadow_cells", json_integer(cf->shadow_cells));
    char words[640];
    json_object_set_new(jc, "summary", json_string(sl_closed_form_describe(cf, words, sizeof words)));
    json_object_set_new(jc, "seconds", json_real(cf->seconds));
    json_object_set_new(root, "closed_form", jc);
    for (int i = 0; i < st->pass_count; i++) {
        const sl_render_pass *p = &st->passes[i];
        json_t *jp = json_object();
        json_object_set_new(jp, "spp", json_integer(p->spp));
        json_object_set_new(jp, "seconds", json_real(p->seconds));
        json_object_set_new(jp, "est_rel_rmse", json_real(p->est_rel_rmse));
        json_object_set_new(jp, "ref_rel_rmse", p->ref_rel_rmse >= 0 ? json_real(p->ref_rel_rmse) : json_null());
        json_array_append_new(passes, jp);
    }
    json_object_set_new(root, "passes", passes);
    char *text = json_dumps(root, JSON_INDENT(2) | JSON_REAL_PRECISION(8));
    json_decref(root);
    if (!text)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory formatting statistics", path);
    size_t n = strlen(text);
    text[n] = '\n';
    sl_result r = sl_write_file_atomic(path, text, n + 1, err);
    free(text);
    return r;
}
