/* SPDX-License-Identifier: BSD-3-Clause */
/* `setlight demo` rig stage: area lights and a residual dome extracted from
 * the stitched HDRI, each truth light matched to the rig light nearest in
 * direction, the energy ledger, and the validation renders under map and
 * rig. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "demo.h"
#include "setlight/lightrig.h"

sl_result demo_stage_rig(demo *d, char *note, size_t n, sl_error *err)
{
    json_t *lights = NULL;
    bool tiny = d->size == SL_VSET_SIZE_TINY;
    /* The stage as `setlight rig --validate` runs it, on the stitched HDRI:
     * dome, textures of graded rect lights, rig.json naming them, preview,
     * and the validation renders read back from the rig's files. */
    char usda[4300], json_path[4300], preview[4300], path[4300];
    snprintf(usda, sizeof usda, "%s/rig.usda", d->dir);
    snprintf(json_path, sizeof json_path, "%s/rig.json", d->dir);
    snprintf(preview, sizeof preview, "%s/rig_preview.png", d->dir);
    sl_rig_run_options ro;
    sl_rig_run_options_init(&ro);
    ro.input_path = d->hdri;
    ro.out_path = usda;
    ro.json_path = json_path;
    ro.preview_path = preview;
    /* Every fixture, not only the few carrying 90% of the energy. */
    ro.rig.energy = 0.99;
    /* The validation, small enough to keep the demo quick. */
    ro.validate_width = tiny ? 32 : 64;
    ro.validate_spp = tiny ? 16 : 64;
    sl_rig_run_result res;
    sl_result r = sl_rig_run(&ro, &res, err);
    const sl_rig *rigp = &res.rig;
    const sl_rig_validation *valp = &res.validation;
    if (r)
        goto done;
    double secs = res.seconds;
    if (!(lights = demo_load_json(d->capture, "truth/lights.json", err))) {
        r = err ? err->code : SL_ERR_INPUT;
        goto done;
    }
    sl_report_section(d->rep, "Rig");
    sl_report_text(d->rep,
                   "Light rig from the stitched hdri.exr (energy share 0.99) in %.2f s with its files and validation: %d lights, "
                   "%d candidates left in "
                   "the dome. Ledger: original %.5g, lights %.5g + dome %.5g (luminance "
                   "integrals), closure error %.1e. Each truth light against the rig light "
                   "nearest in direction (rig.json, rig_preview.png):",
                   secs, rigp->light_count, rigp->skipped_count, sl_luminance(rigp->original),
                   sl_luminance(rigp->lights_sum), sl_luminance(rigp->dome), rigp->relative_error);
    static const char *const head[] = {"truth light", "rig light", "shape", "angle (deg)",
                                       "integral Y truth", "integral Y rig", "ratio"};
    sl_report_table_begin(d->rep, 7, head);
    json_t *arr = json_object_get(lights, "lights");
    int matched = 0;
    double worst_angle = 0;
    for (size_t i = 0; i < json_array_size(arr); i++) {
        json_t *l = json_array_get(arr, i), *dir = json_object_get(l, "direction"),
               *in = json_object_get(l, "integral_rgb");
        double td[3], ti[3];
        for (int c = 0; c < 3; c++) {
            td[c] = json_number_value(json_array_get(dir, (size_t)c));
            ti[c] = json_number_value(json_array_get(in, (size_t)c));
        }
        int best = -1;
        double best_cos = -2;
        for (int k = 0; k < rigp->light_count; k++) {
            const double *rd = rigp->lights[k].direction;
            double c = td[0] * rd[0] + td[1] * rd[1] + td[2] * rd[2];
            if (c > best_cos) {
                best_cos = c;
                best = k;
            }
        }
        double angle = best >= 0 ? acos(fmin(1, best_cos)) * 180 / M_PI : 0;
        char c[7][64];
        snprintf(c[0], 64, "%s", json_string_value(json_object_get(l, "name")));
        snprintf(c[4], 64, "%.4g", sl_luminance(ti));
        /* Within 5 degrees: the same fixture (the rig merges fragments closer than 2). */
        if (best >= 0 && angle < 5) {
            matched++;
            worst_angle = fmax(worst_angle, angle);
            snprintf(c[1], 64, "%d", best + 1);
            snprintf(c[2], 64, "%s", sl_rig_shape_name(rigp->lights[best].shape));
            snprintf(c[3], 64, "%.2f", angle);
            snprintf(c[5], 64, "%.4g", sl_luminance(rigp->lights[best].integral));
            snprintf(c[6], 64, "%.3f", sl_luminance(rigp->lights[best].integral) / sl_luminance(ti));
        } else {
            snprintf(c[1], 64, "(dome)");
            c[2][0] = 0;
            snprintf(c[3], 64, best >= 0 ? "%.1f" : "-", angle);
            c[5][0] = c[6][0] = 0;
        }
        const char *cells[7] = {c[0], c[1], c[2], c[3], c[4], c[5], c[6]};
        sl_report_table_row(d->rep, cells);
    }
    sl_report_table_end(d->rep);
    /* The preview as the report shows it: its PNG is sRGB, the report re-encodes. */
    snprintf(path, sizeof path, "%s/rig_preview.png", d->dir);
    sl_image prev;
    sl_meta pm;
    if ((r = sl_photo_read(path, &prev, &pm, err)))
        goto done;
    sl_meta_free(&pm);
    for (size_t i = 0; i < (size_t)prev.width * prev.height * prev.channels; i++)
        prev.data[i] = sl_srgb_to_linear(prev.data[i]);
    r = sl_report_image(d->rep, "rig_preview.png", &prev, 0,
                        "the stitched HDRI with the rig's lights outlined and numbered", err);
    sl_image_free(&prev);
    if (r)
        goto done;
    int textured = 0;
    for (int k = 0; k < rigp->light_count; k++)
        textured += rigp->lights[k].texture[0] != 0;
    sl_report_text(d->rep,
                   "Validation as `setlight rig --validate` does it: grey, chrome and shadow "
                   "rendered under the stitched HDRI and under the rig read back from rig.json "
                   "(rig_residual.exr as the dome, %d graded light%s textured), %d px, %lld "
                   "spp, %.1f s (%.1f CPU s) in all. Relative RMSE of rig against map: grey %.3f%%, chrome "
                   "%.3f%%, shadow %.3f%%; beyond the Monte Carlo noise of this sample count: "
                   "grey %.3f%%, chrome %.3f%%, shadow %.3f%%.",
                   textured, textured == 1 ? "" : "s", valp->width, (long long)valp->spp,
                   valp->seconds, valp->cpu_seconds, 100 * valp->error[0], 100 * valp->error[1], 100 * valp->error[2],
                   100 * valp->beyond_noise[0], 100 * valp->beyond_noise[1],
                   100 * valp->beyond_noise[2]);
    if ((r = sl_rig_validate_report(d->rep, valp, "rig_validate_", err)))
        goto done;
    snprintf(note, n,
             "%d lights; %d of %zu truth lights matched (worst %.2f deg); ledger %.1e; rig "
             "against map beyond noise: grey %.2f%%, chrome %.2f%%, shadow %.2f%%",
             rigp->light_count, matched, json_array_size(arr), worst_angle, rigp->relative_error,
             100 * valp->beyond_noise[0], 100 * valp->beyond_noise[1], 100 * valp->beyond_noise[2]);
done:
    sl_rig_run_result_free(&res);
    json_decref(lights);
    return r;
}
