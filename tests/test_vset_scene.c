/* SPDX-License-Identifier: BSD-3-Clause */
/* Virtual-set scenes: light integrals against their analytic values, the
 * sun's size and brightness, determinism, and scene JSON errors. */
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "testing.h"

#define PI 3.14159265358979323846

/* Integral of an image over the sphere, per channel, in double. */
static void integral(const sl_image *img, double out[3])
{
    for (int c = 0; c < 3; c++) {
        double s = 0;
        for (int y = 0; y < img->height; y++) {
            double lat0 = PI * (0.5 - (double)y / img->height);
            double lat1 = PI * (0.5 - (double)(y + 1) / img->height);
            double dw = 2 * PI / img->width * (sin(lat0) - sin(lat1)), row = 0;
            for (int x = 0; x < img->width; x++)
                row += sl_image_pixel(img, x, y)[c];
            s += row * dw;
        }
        out[c] = s;
    }
}

/* Largest relative difference between light i's texel integral at `width`
 * and its declared integral. `declared` is a scene made from d (any width). */
static double light_error_in(const sl_vset_desc *d, const sl_vset_scene *declared, int i,
                             int width)
{
    sl_image img;
    sl_error err;
    const sl_vset_light *l = &declared->desc.lights[i];
    double worst = 0, got[3];
    if (sl_vset_light_image(d, i, width, &img, &err) != SL_OK)
        return 1e9;
    integral(&img, got);
    for (int c = 0; c < 3; c++)
        if (l->integral[c] > 0)
            worst = fmax(worst, fabs(got[c] / l->integral[c] - 1));
    sl_image_free(&img);
    return worst;
}

static double light_error(const sl_vset_desc *d, int i, int width)
{
    sl_error err;
    sl_vset_scene sc;
    if (sl_vset_scene_make(d, 16, &sc, &err) != SL_OK)
        return 1e9;
    double e = light_error_in(d, &sc, i, width);
    sl_vset_scene_free(&sc);
    return e;
}

static void test_sun(void)
{
    sl_vset_desc d;
    sl_error err;
    CHECK_OK(sl_vset_preset("exterior", &d, &err), &err);
    sl_vset_scene sc;
    CHECK_OK(sl_vset_scene_make(&d, 256, &sc, &err), &err);
    const sl_vset_light *sun = &sc.desc.lights[0];
    double r = 0.265 * PI / 180;
    CHECK_NEAR(sun->solid_angle, 2 * PI * (1 - cos(r)), 1e-12);
    CHECK(sl_luminance(sun->radiance) > 5e8 && sl_luminance(sun->radiance) < 2e9);
    /* Sun to sky: against the zenith and against the mean sky. */
    double zen[3], up[3] = {0, 1, 0};
    sl_vset_sky_radiance(sun->dir, d.turbidity, up, zen);
    double ratio = sl_luminance(sun->radiance) / sl_luminance(zen);
    printf("  sun %.3g cd/m^2, zenith %.4g, ratio %.3g\n", sl_luminance(sun->radiance), sl_luminance(zen), ratio);
    CHECK(ratio > 5e4 && ratio < 5e5);
    sl_vset_scene_free(&sc);
    /* Exact-coverage antialiasing: integral within 1% at small and full. */
    double e_small = light_error(&d, 0, SL_VSET_SMALL_WIDTH);
    double e_full = light_error(&d, 0, SL_VSET_FULL_WIDTH);
    printf("  sun integral error: small %.2e, full %.2e\n", e_small, e_full);
    CHECK(e_small < 0.01);
    CHECK(e_full < 0.01);
    /* Sun low on the horizon, where texels are widest. */
    d.lights[0].elevation_deg = 3;
    d.lights[0].azimuth_deg = -100;
    double e_low = light_error(&d, 0, SL_VSET_SMALL_WIDTH);
    CHECK(e_low < 0.01);
}

static void test_every_light_integral(void)
{
    for (const char *const *n = sl_vset_preset_names(); *n; n++) {
        sl_vset_desc d;
        sl_error err;
        sl_vset_scene sc;
        CHECK_OK(sl_vset_preset(*n, &d, &err), &err);
        CHECK_OK(sl_vset_scene_make(&d, 16, &sc, &err), &err);
        for (int i = 0; i < d.light_count; i++) {
            double e = light_error_in(&d, &sc, i, SL_VSET_SMALL_WIDTH);
            printf("  %s/%s: integral error %.2e\n", *n, d.lights[i].name, e);
            CHECK_MSG(e < 0.01, "%s/%s: integral off by %.3g", *n, d.lights[i].name, e);
        }
        sl_vset_scene_free(&sc);
    }
}

static void test_scene_sanity(void)
{
    for (const char *const *n = sl_vset_preset_names(); *n; n++) {
        sl_vset_desc d;
        sl_error err;
        sl_vset_scene a, b;
        CHECK_OK(sl_vset_preset(*n, &d, &err), &err);
        sl_threads_set(1);
        CHECK_OK(sl_vset_scene_make(&d, 256, &a, &err), &err);
        sl_threads_set(2);
        CHECK_OK(sl_vset_scene_make(&d, 256, &b, &err), &err);
        sl_threads_set(0);
        CHECK(a.latlong.width == 256 && a.latlong.height == 128);
        CHECK(memcmp(a.latlong.data, b.latlong.data,
                     a.latlong.stride * (size_t)a.latlong.height * sizeof(float)) == 0);
        sl_image_stats st;
        sl_image_stats_compute(&a.latlong, &st);
        CHECK(st.nan_count == 0 && st.inf_count == 0 && st.negative_count == 0);
        CHECK(st.min[0] > 0 || strcmp(*n, "stage") == 0 || strcmp(*n, "night") == 0);
        double tot[3];
        integral(&a.latlong, tot);
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(tot[c] / a.total[c], 1, 1e-9);
        char *js = sl_vset_lights_json(&a);
        CHECK(js && strstr(js, "\"integral_rgb\"") && strstr(js, d.lights[0].name));
        free(js);
        sl_vset_scene_free(&a);
        sl_vset_scene_free(&b);
    }
}

/* night: L = dark * (1 + y/2) * tint integrates to 4 pi dark tint; lights
 * replace the background over their own solid angle. */
static void test_night_total(void)
{
    sl_vset_desc d;
    sl_error err;
    sl_vset_scene sc;
    CHECK_OK(sl_vset_preset("night", &d, &err), &err);
    CHECK_OK(sl_vset_scene_make(&d, 1024, &sc, &err), &err);
    double tint[3];
    sl_vset_kelvin_rgb(9000, tint);
    for (int c = 0; c < 3; c++) {
        double expect = 4 * PI * d.dark_luminance * tint[c];
        for (int i = 0; i < sc.desc.light_count; i++) {
            const sl_vset_light *l = &sc.desc.lights[i];
            expect += l->integral[c] -
                      d.dark_luminance * tint[c] * (1 + 0.5 * l->dir[1]) * l->solid_angle;
        }
        printf("  night total[%d] %.6g expected %.6g\n", c, sc.total[c], expect);
        CHECK_NEAR(sc.total[c] / expect, 1, 0.002);
    }
    /* The stiff case: sources 1e7..1e9 times brighter than the surroundings. */
    for (int i = 0; i < sc.desc.light_count; i++)
        CHECK(sl_luminance(sc.desc.lights[i].radiance) > 1e3 * 1e3 * d.dark_luminance);
    sl_vset_scene_free(&sc);
}

/* Textured walls must not look like lights. */
static void test_stage_walls(void)
{
    sl_vset_desc d;
    sl_error err;
    sl_vset_scene sc;
    CHECK_OK(sl_vset_preset("stage", &d, &err), &err);
    const int w = 256;
    CHECK_OK(sl_vset_scene_make(&d, w, &sc, &err), &err);
    sl_image mask;
    CHECK_OK(sl_image_alloc(&mask, w, w / 2, 3, &err), &err);
    double dimmest = 1e30;
    for (int i = 0; i < sc.desc.light_count; i++) {
        sl_image li;
        CHECK_OK(sl_vset_light_image(&d, i, w, &li, &err), &err);
        for (size_t k = 0; k < (size_t)w * (w / 2) * 3; k++)
            mask.data[k] += li.data[k];
        sl_image_free(&li);
        dimmest = fmin(dimmest, sl_luminance(sc.desc.lights[i].radiance));
    }
    double wall_max = 0;
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            const float *m = sl_image_pixel(&mask, x, y), *p = sl_image_pixel(&sc.latlong, x, y);
            if (m[0] + m[1] + m[2] == 0) {
                double v[3] = {p[0], p[1], p[2]};
                wall_max = fmax(wall_max, sl_luminance(v));
            }
        }
    printf("  stage: brightest wall %.3g cd/m^2, dimmest light %.3g\n", wall_max, dimmest);
    CHECK(wall_max > 1 && wall_max < 0.05 * dimmest);
    /* Kino pair: one warm, one cool. */
    const sl_vset_light *warm = &sc.desc.lights[0], *cool = &sc.desc.lights[1];
    CHECK(warm->radiance[0] > warm->radiance[2] && cool->radiance[2] > warm->radiance[2]);
    sl_image_free(&mask);
    sl_vset_scene_free(&sc);
}

static void test_kelvin(void)
{
    double rgb[3];
    /* The Planckian locus at 6504 K, xy (0.3135, 0.3236), sits just below
     * D65: near white, a little magenta. */
    sl_vset_kelvin_rgb(6504, rgb);
    CHECK_NEAR(rgb[0], 1, 0.06);
    CHECK_NEAR(rgb[1], 1, 0.02);
    CHECK_NEAR(rgb[2], 1, 0.06);
    CHECK(rgb[0] > rgb[1] && rgb[2] > rgb[1]);
    sl_vset_kelvin_rgb(3200, rgb);
    CHECK(rgb[0] > rgb[1] && rgb[1] > rgb[2]);
    CHECK_NEAR(0.2126390059 * rgb[0] + 0.7151686788 * rgb[1] + 0.0721923154 * rgb[2], 1, 1e-9);
}

static const char *write_text(const char *name, const char *text)
{
    const char *p = sl_test_path(name);
    FILE *f = fopen(p, "w");
    fputs(text, f);
    fclose(f);
    return p;
}

static void expect_bad(const char *name, const char *text, const char *needle)
{
    const char *p = write_text(name, text);
    sl_vset_desc d;
    sl_error err;
    CHECK_RESULT(sl_vset_desc_read_json(p, &d, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, p) != NULL, "message does not name the file: %s", err.message);
    CHECK_MSG(strstr(err.message, needle) != NULL, "'%s' not in: %s", needle, err.message);
}

static void test_json(void)
{
    const char *good = write_text(
        "good.json",
        "{\"name\": \"alley\", \"background\": \"dark\", \"dark_luminance\": 0.01,\n"
        " \"lights\": [\n"
        "  {\"type\": \"disk\", \"name\": \"lamp\", \"azimuth\": 10, \"elevation\": 20,\n"
        "   \"diameter\": 0.5, \"kelvin\": 2700, \"luminance\": 1e5},\n"
        "  {\"type\": \"rect\", \"azimuth\": -30, \"elevation\": 5, \"width\": 4, \"height\": 2,\n"
        "   \"roll\": 15, \"rgb\": [1, 0.2, 0.1], \"luminance\": 500}]}\n");
    sl_vset_desc d;
    sl_error err;
    CHECK_OK(sl_vset_desc_read_json(good, &d, &err), &err);
    CHECK(strcmp(d.name, "alley") == 0 && d.background == SL_VSET_BG_DARK);
    CHECK(d.light_count == 2 && strcmp(d.lights[1].name, "rect") == 0);
    CHECK(d.lights[1].shape == SL_VSET_SHAPE_RECT && d.lights[1].roll_deg == 15);
    CHECK(d.dark_luminance == 0.01);
    CHECK(light_error(&d, 1, 512) < 0.01);

    expect_bad("syntax.json", "{\"background\": \"dark\", \"lights\": [}\n", "line 1");
    expect_bad("type.json", "{\"background\": \"dark\", \"lights\": [{\"type\": \"disk\", "
                            "\"azimuth\": \"north\", \"elevation\": 1, \"diameter\": 1, "
                            "\"kelvin\": 3000, \"luminance\": 10}]}",
               "lights[0].azimuth: expected a number");
    expect_bad("negative.json", "{\"background\": \"dark\", \"lights\": [{\"type\": \"disk\", "
                                "\"azimuth\": 0, \"elevation\": 1, \"diameter\": -2, "
                                "\"kelvin\": 3000, \"luminance\": 10}]}",
               "diameter -2");
    expect_bad("missing.json", "{\"background\": \"dark\", \"lights\": [{\"type\": \"disk\", "
                               "\"azimuth\": 0, \"elevation\": 1, \"diameter\": 1, "
                               "\"kelvin\": 3000}]}",
               "missing field \"luminance\"");
    expect_bad("nolights.json", "{\"background\": \"sky\"}", "missing field \"lights\"");
    expect_bad("unknown.json", "{\"background\": \"dark\", \"lights\": [], \"colour\": 1}",
               "unknown field \"colour\"");
    expect_bad("twosuns.json", "{\"background\": \"sky\", \"lights\": ["
                               "{\"type\": \"sun\", \"azimuth\": 0, \"elevation\": 30},"
                               "{\"type\": \"sun\", \"azimuth\": 90, \"elevation\": 30}]}",
               "2 suns");
    expect_bad("notobject.json", "[1, 2]", "expected a JSON object");

    CHECK_RESULT(sl_vset_desc_read_json(sl_test_path("absent.json"), &d, &err),
                 SL_ERR_NOT_FOUND, &err);
    CHECK_RESULT(sl_vset_preset("studio", &d, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "studio") != NULL);
    sl_vset_scene sc;
    CHECK_OK(sl_vset_preset("night", &d, &err), &err);
    CHECK_RESULT(sl_vset_scene_make(&d, 1023, &sc, &err), SL_ERR_USAGE, &err);
    CHECK(sc.latlong.data == NULL);
}

int main(void)
{
    RUN(test_kelvin);
    RUN(test_sun);
    RUN(test_every_light_integral);
    RUN(test_scene_sanity);
    RUN(test_night_total);
    RUN(test_stage_walls);
    RUN(test_json);
    return sl_test_finish();
}
