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

static double luma(const double v[3]) { return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]; }

sl_result demo_stage_rig(demo *d, char *note, size_t n, sl_error *err)
{
    sl_image ll = {0};
    sl_rig rig;
    memset(&rig, 0, sizeof rig);
    json_t *lights = NULL;
    sl_rig_validation val;
    memset(&val, 0, sizeof val);
    sl_result r = demo_hdri(d, &ll, err);
    if (r)
        return r;
    sl_rig_options o;
    sl_rig_options_default(&o);
    /* Every fixture, not only the few carrying 90% of the energy. */
    o.energy = 0.99;
    double t0 = sl_seconds();
    if ((r = sl_rig_extract(&ll, &o, &rig, err)))
        goto done;
    double secs = sl_seconds() - t0;
    char path[4300];
    /* The rig as `setlight rig` writes it (dome, textures of graded rect
     * lights, rig.json naming them), so the renderer reads it back whole. */
    snprintf(path, sizeof path, "%s/rig_residual.exr", d->dir);
    if ((r = sl_exr_write(path, &rig.residual, NULL, SL_PIXEL_FLOAT, err)))
        goto done;
    snprintf(path, sizeof path, "%s/rig", d->dir);
    if ((r = sl_rig_write_textures_mode(&rig, &ll, path, SL_RIG_TEXTURES_AUTO, err)))
        goto done;
    snprintf(path, sizeof path, "%s/rig.json", d->dir);
    if ((r = sl_rig_write_json(&rig, path, "rig_residual.exr", err)))
        goto done;
    snprintf(path, sizeof path, "%s/rig_preview.png", d->dir);
    if ((r = sl_rig_write_preview(&rig, &ll, path, err)))
        goto done;
    if (!(lights = demo_load_json(d->capture, "truth/lights.json", err))) {
        r = err ? err->code : SL_ERR_INPUT;
        goto done;
    }
    sl_report_section(d->rep, "Rig");
    sl_report_text(d->rep,
                   "Light rig from the stitched hdri.exr (energy share 0.99) in %.2f s: %d lights, "
                   "%d candidates left in "
                   "the dome. Ledger: original %.5g, lights %.5g + dome %.5g (luminance "
                   "integrals), closure error %.1e. Each truth light against the rig light "
                   "nearest in direction (rig.json, rig_preview.png):",
                   secs, rig.light_count, rig.skipped_count, luma(rig.original),
                   luma(rig.lights_sum), luma(rig.dome), rig.relative_error);
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
        for (int k = 0; k < rig.light_count; k++) {
            const double *rd = rig.lights[k].direction;
            double c = td[0] * rd[0] + td[1] * rd[1] + td[2] * rd[2];
            if (c > best_cos) {
                best_cos = c;
                best = k;
            }
        }
        double angle = best >= 0 ? acos(fmin(1, best_cos)) * 180 / M_PI : 0;
        char c[7][64];
        snprintf(c[0], 64, "%s", json_string_value(json_object_get(l, "name")));
        snprintf(c[4], 64, "%.4g", luma(ti));
        /* Within 5 degrees: the same fixture (the rig merges fragments closer than 2). */
        if (best >= 0 && angle < 5) {
            matched++;
            worst_angle = fmax(worst_angle, angle);
            snprintf(c[1], 64, "%d", best + 1);
            snprintf(c[2], 64, "%s", sl_rig_shape_name(rig.lights[best].shape));
            snprintf(c[3], 64, "%.2f", angle);
            snprintf(c[5], 64, "%.4g", luma(rig.lights[best].integral));
            snprintf(c[6], 64, "%.3f", luma(rig.lights[best].integral) / luma(ti));
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
    /* The validation, small enough to keep the demo quick. */
    bool tiny = d->size == SL_VSET_SIZE_TINY;
    int textured = 0;
    for (int k = 0; k < rig.light_count; k++)
        textured += rig.lights[k].texture[0] != 0;
    snprintf(path, sizeof path, "%s/rig.json", d->dir);
    if ((r = sl_rig_validate(&ll, path, tiny ? 32 : 64, tiny ? 16 : 64, &val, err)))
        goto done;
    sl_report_text(d->rep,
                   "Validation as `setlight rig --validate` does it: grey, chrome and shadow "
                   "rendered under the stitched HDRI and under the rig read back from rig.json "
                   "(rig_residual.exr as the dome, %d graded light%s textured), %d px, %lld "
                   "spp, %.1f s (%.1f CPU s) in all. Relative RMSE of rig against map: grey %.3f%%, chrome "
                   "%.3f%%, shadow %.3f%%; beyond the Monte Carlo noise of this sample count: "
                   "grey %.3f%%, chrome %.3f%%, shadow %.3f%%.",
                   textured, textured == 1 ? "" : "s", val.width, (long long)val.spp,
                   val.seconds, val.cpu_seconds, 100 * val.error[0], 100 * val.error[1], 100 * val.error[2],
                   100 * val.beyond_noise[0], 100 * val.beyond_noise[1],
                   100 * val.beyond_noise[2]);
    if ((r = sl_rig_validate_report(d->rep, &val, "rig_validate_", err)))
        goto done;
    snprintf(note, n,
             "%d lights; %d of %zu truth lights matched (worst %.2f deg); ledger %.1e; rig "
             "against map beyond noise: grey %.2f%%, chrome %.2f%%, shadow %.2f%%",
             rig.light_count, matched, json_array_size(arr), worst_angle, rig.relative_error,
             100 * val.beyond_noise[0], 100 * val.beyond_noise[1], 100 * val.beyond_noise[2]);
done:
    sl_rig_validation_free(&val);
    json_decref(lights);
    sl_rig_free(&rig);
    sl_image_free(&ll);
    return r;
}
