/* SPDX-License-Identifier: BSD-3-Clause */
/* Render statistics as JSON: error against time per pass, throughput and
 * what the integrator skipped (docs/render.md). */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"

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
        json_object_set_new(jo, "bound", json_string(t == SL_MAT_LAMBERT ? "proven" : "estimate"));
        json_array_append_new(per, jo);
    }
    json_object_set_new(jc, "per_object", per);
    json_object_set_new(jc, "interpolated_pixels", json_integer(cf->interpolated_pixels));
    json_object_set_new(jc, "tolerance", json_real(cf->tolerance));
    json_object_set_new(jc, "max_rel_bound", json_real(cf->max_rel_bound));
    json_object_set_new(jc, "max_footprint_error", json_real(cf->max_footprint_error));
    json_object_set_new(jc, "top_level", json_integer(cf->top_level));
    json_object_set_new(jc, "finest_level", json_integer(cf->finest_level));
    json_object_set_new(jc, "evaluations", json_integer(cf->evaluations));
    json_object_set_new(jc, "cells", json_integer(cf->cells));
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
