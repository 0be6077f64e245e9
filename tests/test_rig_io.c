/* SPDX-License-Identifier: BSD-3-Clause */
/* lightrig outputs read back: the USD file parsed for every prim and
 * attribute we write, rig.json against its schema, the preview PNG; and the
 * ledger on every real HDRI in the shared data (when present). */
#include <dirent.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "rig_scenes.h"
#include "setlight/lightrig.h"
#include "testing.h"

#define W 256
#define H 128

static void make_scene(sl_image *img)
{
    scene_light L[3];
    sl_image_alloc(img, W, H, 3, NULL);
    sc_background(img, 0.5, true);
    sc_add(img, &L[0], 20, 30, 25, tan(8 * M_PI / 180), tan(4 * M_PI / 180), true,
           (double[3]){80, 80, 75});
    sc_add(img, &L[1], 40, -100, 0, 6 * M_PI / 180, 0, false, (double[3]){120, 90, 60});
    sc_add(img, &L[2], 30, 170, 0, 0.25 * M_PI / 180, 0, false, (double[3]){1e5, 1e5, 9e4});
}

/* A parsed prim: type, name and its attribute lines. */
typedef struct prim {
    char type[32], name[64];
    char *attrs[32];
    int nattr;
} prim;

static const char *attr(const prim *p, const char *name)
{
    size_t n = strlen(name);
    for (int i = 0; i < p->nattr; i++) {
        const char *s = strstr(p->attrs[i], name);
        if (s && s[n] == ' ' && s[n + 1] == '=' && (s == p->attrs[i] || s[-1] == ' '))
            return s + n + 3;
    }
    return NULL;
}

static double attr_num(const prim *p, const char *name)
{
    const char *v = attr(p, name);
    return v ? strtod(v, NULL) : NAN;
}

/* "(a, b, c)" -> 3 numbers; matrices "( (..), (..) ...)" -> 16. */
static int attr_nums(const prim *p, const char *name, double *out, int max)
{
    const char *v = attr(p, name);
    int n = 0;
    while (v && *v && n < max) {
        while (*v && !(*v == '-' || (*v >= '0' && *v <= '9')))
            v++;
        if (!*v)
            break;
        char *end;
        out[n++] = strtod(v, &end);
        v = end;
    }
    return n;
}

/* Parses the USDA text we write: header, prims `def Type "name"` with
 * attribute lines, balanced braces. Returns the prim count (-1 if malformed). */
static int parse_usda(char *text, prim *prims, int max)
{
    if (strncmp(text, "#usda 1.0\n", 10) != 0)
        return -1;
    int n = 0, depth = 0, cur = -1;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        while (*line == ' ')
            line++;
        if (!strcmp(line, "{")) {
            depth++;
            continue;
        }
        if (!strcmp(line, "}")) {
            depth--;
            cur = -1;
            if (depth < 0)
                return -1;
            continue;
        }
        char type[32], name[64];
        if (sscanf(line, "def %31s \"%63[^\"]\"", type, name) == 2) {
            if (depth == 1 && n < max) {
                cur = n++;
                snprintf(prims[cur].type, sizeof prims[cur].type, "%s", type);
                snprintf(prims[cur].name, sizeof prims[cur].name, "%s", name);
                prims[cur].nattr = 0;
            }
            continue;
        }
        if (cur >= 0 && prims[cur].nattr < 32)
            prims[cur].attrs[prims[cur].nattr++] = line;
    }
    return depth == 0 ? n : -1;
}

static void check_usda(const sl_rig *rig, const char *path)
{
    char *text = sl_test_read_file(path, NULL);
    CHECK(text != NULL);
    if (!text)
        return;
    prim p[40];
    int n = parse_usda(text, p, 40);
    CHECK_MSG(n == rig->light_count + 1, "usda: %d prims for %d lights", n, rig->light_count);
    if (n < 1) {
        free(text);
        return;
    }
    CHECK(!strcmp(p[0].type, "DomeLight"));
    const char *tex = attr(&p[0], "asset inputs:texture:file");
    CHECK(tex && !strcmp(tex, "@dome.exr@"));
    const char *fmt = attr(&p[0], "token inputs:texture:format");
    CHECK(fmt && !strcmp(fmt, "\"latlong\""));
    for (int i = 0; i + 1 < n && i < rig->light_count; i++) {
        const sl_rig_light *L = &rig->lights[i];
        const prim *q = &p[i + 1];
        /* a rect at infinity: a RectLight 1e4 m away of its angular size */
        bool far = !L->has_position && L->shape == SL_RIG_RECT;
        double tu = tan(L->angular_size[0] / 2), tv = tan(L->angular_size[1] / 2);
        double far_omega = 4 * asin(tu * tv / sqrt((1 + tu * tu) * (1 + tv * tv)));
        const char *want = L->shape == SL_RIG_RECT    ? "RectLight"
                           : !L->has_position         ? "DistantLight"
                           : L->shape == SL_RIG_SPHERE ? "SphereLight"
                                                       : "DiskLight";
        CHECK_MSG(!strcmp(q->type, want), "prim %d is %s, want %s", i, q->type, want);
        double in = attr_num(q, "float inputs:intensity");
        double ex = attr_num(q, "float inputs:exposure");
        double col[3];
        CHECK(attr_nums(q, "color3f inputs:color", col, 3) == 3);
        const char *norm = attr(q, "bool inputs:normalize");
        CHECK(norm && !strcmp(norm, "0"));
        /* the power: radiance x the shape's exact solid angle */
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(in * pow(2, ex) * col[c] * (far ? far_omega : L->solid_angle) /
                           L->integral[c], 1, 1e-6);
        const char *inf = attr(q, "custom bool setlight:atInfinity");
        CHECK(inf && !strcmp(inf, L->has_position ? "0" : "1"));
        double m[16];
        CHECK(attr_nums(q, "matrix4d xformOp:transform", m, 16) == 16);
        const char *order = attr(q, "uniform token[] xformOpOrder");
        CHECK(order && strstr(order, "xformOp:transform"));
        /* rows: X = width axis, Y, Z = toward the light (it emits along -Z) */
        for (int a = 0; a < 3; a++) {
            CHECK_NEAR(m[8 + a], L->direction[a], 1e-12);
            CHECK_NEAR(m[12 + a],
                       L->has_position ? L->position[a] : far ? 1e4 * L->direction[a] : 0, 1e-9);
        }
        double cx[3] = {m[1] * m[6] - m[2] * m[5], m[2] * m[4] - m[0] * m[6],
                        m[0] * m[5] - m[1] * m[4]};
        for (int a = 0; a < 3; a++)
            CHECK_NEAR(cx[a], m[8 + a], 1e-9); /* right-handed, orthonormal */
        if (!strcmp(q->type, "DistantLight")) {
            double ang = attr_num(q, "float inputs:angle") * M_PI / 180;
            CHECK_NEAR(2 * M_PI * (1 - cos(ang / 2)) / L->solid_angle, 1, 1e-5);
        } else if (!strcmp(q->type, "RectLight")) {
            double wh[2] = {far ? 2e4 * tu : L->size[0], far ? 2e4 * tv : L->size[1]};
            CHECK_NEAR(attr_num(q, "float inputs:width"), wh[0], 1e-6 * wh[0]);
            if (far) {
                /* seen from the capture point: the light's solid angle and
                 * its width along the rows' X axis (axis_u) */
                CHECK_NEAR(far_omega / L->solid_angle, 1, 1e-6);
                for (int a = 0; a < 3; a++)
                    CHECK_NEAR(m[a], L->axis_u[a], 1e-12);
            }
            const char *tf = attr(q, "asset inputs:texture:file");
            if (L->texture[0]) {
                char want[300];
                snprintf(want, sizeof want, "@%s@", L->texture);
                CHECK(tf && !strcmp(tf, want));
            } else {
                CHECK(tf == NULL);
            }
            CHECK_NEAR(attr_num(q, "float inputs:height"), wh[1], 1e-6 * wh[1]);
        } else {
            CHECK_NEAR(attr_num(q, "float inputs:radius"), L->size[0] / 2, 1e-6 * L->size[0]);
        }
    }
    free(text);
}

static void check_json(const sl_rig *rig, const char *path)
{
    json_error_t je;
    json_t *root = json_load_file(path, 0, &je);
    CHECK_MSG(root != NULL, "rig.json: %s", je.text);
    if (!root)
        return;
    CHECK(json_integer_value(json_object_get(root, "version")) == 2);
    CHECK(json_object_size(root) == 5);
    json_t *lights = json_object_get(root, "lights");
    CHECK((int)json_array_size(lights) == rig->light_count);
    static const char *keys[] = {"type",     "direction", "solid_angle",  "radiance",
                                 "integral", "position",  "size",         "texture",
                                 "axis_u",   "angular_size", "share",     "share_glossy",
                                 "textured", "texture_variation", "texture_reason"};
    for (int i = 0; i < rig->light_count && i < (int)json_array_size(lights); i++) {
        json_t *l = json_array_get(lights, i);
        CHECK(json_object_size(l) == 15);
        for (int k = 0; k < 15; k++)
            CHECK_MSG(json_object_get(l, keys[k]) != NULL, "light lacks %s", keys[k]);
        CHECK(!strcmp(json_string_value(json_object_get(l, "type")),
                      sl_rig_shape_name(rig->lights[i].shape)));
        for (int c = 0; c < 3; c++) {
            CHECK(json_real_value(json_array_get(json_object_get(l, "integral"), c)) ==
                  rig->lights[i].integral[c]);
            CHECK(json_real_value(json_array_get(json_object_get(l, "direction"), c)) ==
                  rig->lights[i].direction[c]);
            CHECK(json_real_value(json_array_get(json_object_get(l, "axis_u"), c)) ==
                  rig->lights[i].axis_u[c]);
        }
        for (int c = 0; c < 2; c++)
            CHECK_NEAR(json_real_value(json_array_get(json_object_get(l, "angular_size"), c)),
                       rig->lights[i].angular_size[c] * 180 / M_PI, 1e-12);
        CHECK(json_real_value(json_object_get(l, "share_glossy")) ==
              rig->lights[i].share_glossy);
    }
    json_t *ledger = json_object_get(root, "ledger");
    for (int c = 0; c < 3; c++) {
        double o = json_real_value(json_array_get(json_object_get(ledger, "original"), c));
        double li = json_real_value(json_array_get(json_object_get(ledger, "lights"), c));
        double d = json_real_value(json_array_get(json_object_get(ledger, "dome"), c));
        CHECK_NEAR((li + d) / o, 1, 1e-9);
    }
    CHECK(!strcmp(json_string_value(json_object_get(json_object_get(root, "dome"), "file")),
                  "dome.exr"));
    CHECK(json_is_array(json_object_get(root, "skipped")));
    json_decref(root);
}

static void test_outputs(void)
{
    sl_image img;
    make_scene(&img);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    sl_error err;
    /* at infinity */
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 3);
    CHECK_OK(sl_rig_write_usda(&rig, sl_test_path("inf.usda"), "dome.exr", &err), &err);
    check_usda(&rig, sl_test_path("inf.usda"));
    CHECK_OK(sl_rig_write_json(&rig, sl_test_path("inf.json"), "dome.exr", &err), &err);
    check_json(&rig, sl_test_path("inf.json"));
    /* preview: the map's size, outlines in the first light's colour */
    CHECK_OK(sl_rig_write_preview(&rig, &img, sl_test_path("preview.png"), &err), &err);
    sl_image pv;
    sl_meta meta;
    CHECK_OK(sl_photo_read(sl_test_path("preview.png"), &pv, &meta, &err), &err);
    CHECK(pv.width == W && pv.height == H);
    int outline = 0;
    for (int y = 0; y < pv.height; y++)
        for (int x = 0; x < pv.width; x++) {
            const float *p = sl_image_pixel(&pv, x, y);
            outline += p[0] > 0.99f && fabsf(p[1] - 0.2f) < 0.01f && fabsf(p[2] - 0.2f) < 0.01f;
        }
    CHECK_MSG(outline > 20, "preview: %d outline pixels of light 1", outline);
    sl_image_free(&pv);
    sl_meta_free(&meta);
    sl_rig_free(&rig);
    /* in a room: Rect and Sphere lights with positions */
    opt.room[0] = 10;
    opt.room[1] = 8;
    opt.room[2] = 5;
    opt.capture_height = 1.6;
    CHECK_OK(sl_rig_extract(&img, &opt, &rig, &err), &err);
    CHECK_OK(sl_rig_write_textures(&rig, &img, sl_test_path("room"), &err), &err);
    CHECK_OK(sl_rig_write_usda(&rig, sl_test_path("room.usda"), "dome.exr", &err), &err);
    check_usda(&rig, sl_test_path("room.usda"));
    CHECK_OK(sl_rig_write_json(&rig, sl_test_path("room.json"), "dome.exr", &err), &err);
    /* the softbox's texture: uniform, so every inner pixel is near the mean (1) */
    for (int i = 0; i < rig.light_count; i++) {
        const sl_rig_light *L = &rig.lights[i];
        CHECK((L->shape == SL_RIG_RECT) == (L->texture[0] != 0));
        if (!L->texture[0])
            continue;
        char want[64];
        snprintf(want, sizeof want, "room_light_%02d.exr", i + 1);
        CHECK_MSG(!strcmp(L->texture, want), "texture %s, want %s", L->texture, want);
        sl_image tex;
        sl_meta tm;
        CHECK_OK(sl_exr_read(sl_test_path(L->texture), &tex, &tm, &err), &err);
        CHECK(tex.width == 64 && tex.height >= 30 && tex.height <= 34); /* 16 x 8 degrees */
        if (tex.width == 64) {
            /* the map's blur (1.4 degree texels) dims the border: the plateau
             * is a little above the mean, and flat */
            const float *c = sl_image_pixel(&tex, 32, tex.height / 2);
            const float *q = sl_image_pixel(&tex, 20, tex.height / 2);
            CHECK_NEAR(c[1], 1, 0.15);
            CHECK_NEAR(q[1] / c[1], 1, 0.02);
            CHECK_NEAR(c[0] / c[1], 1, 0.01);
            printf("  softbox texture: plateau %.3f x the mean\n", c[1]);
        }
        sl_image_free(&tex);
        sl_meta_free(&tm);
    }
    int rects = 0, spheres = 0, distant = 0;
    for (int i = 0; i < rig.light_count; i++) {
        rects += rig.lights[i].shape == SL_RIG_RECT;
        spheres += rig.lights[i].shape == SL_RIG_SPHERE;
        distant += rig.lights[i].shape == SL_RIG_DISTANT && !rig.lights[i].has_position;
    }
    CHECK(rects == 1 && spheres == 1 && distant == 1);
    /* a name USD cannot hold as an asset path */
    CHECK_RESULT(sl_rig_write_usda(&rig, sl_test_path("bad.usda"), "a@b.exr", &err), SL_ERR_USAGE,
                 &err);
    CHECK(!sl_test_file_exists(sl_test_path("bad.usda")));
    sl_rig_free(&rig);
    sl_image_free(&img);
    /* usd-core's usdcat, when installed, must accept the file */
    if (system("command -v usdcat >/dev/null 2>&1") == 0) {
        char cmd[4200];
        snprintf(cmd, sizeof cmd, "usdcat '%s' >/dev/null", sl_test_path("room.usda"));
        CHECK(system(cmd) == 0);
    } else {
        sl_test_skip("usdcat not installed: USD checked by the parser here only");
    }
}

/* The ledger on one real HDRI (skipped when it is not a 2:1 lat-long). */
static bool ledger_one(const char *path, const char *name)
{
    sl_image img = {0}, small = {0};
    sl_meta meta;
    sl_error err;
    if (sl_image_read(path, &img, &meta, &err) || !sl_is_latlong_shape(img.width, img.height)) {
        sl_image_free(&img);
        sl_meta_free(&meta);
        return false;
    }
    /* Area-weighted shrinking (to 512 wide, 256 under sanitizers) keeps the
     * energy; the ledger is about the rig, not the resolution. */
    int maxw = sl_test_sanitized() ? 256 : 512;
    const sl_image *use = &img;
    if (img.width > maxw) {
        CHECK_OK(sl_image_resample(&img, maxw, maxw / 2, &small, &err), &err);
        use = &small;
    }
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    CHECK_OK(sl_rig_extract(use, &opt, &rig, &err), &err);
    printf("  %s: %d lights, %d skipped, %lld negative, ledger %.3g\n", name, rig.light_count,
           rig.skipped_count, (long long)rig.negative, rig.relative_error);
    CHECK_MSG(rig.relative_error < 1e-3, "%s: ledger %.3g", name, rig.relative_error);
    /* a grey sphere under the rig against under the map, and median cut
     * with as many lights */
    if (rig.light_count > 0) {
        sl_rig mc;
        opt.method = SL_RIG_METHOD_MEDIANCUT;
        opt.max_lights = rig.light_count;
        CHECK_OK(sl_rig_extract(use, &opt, &mc, &err), &err);
        double er = rig_rmse(use, &rig), em = rig_rmse(use, &mc);
        printf("    grey sphere relative RMSE: rig %.4f%%, median cut %.2f%% (%d lights)\n",
               100 * er, 100 * em, mc.light_count);
        /* 1% holds where the lights are compact; a large soft window or
         * sky patch as one uniform shape costs up to a few % (textured
         * lights at infinity are not written yet) */
        CHECK_MSG(er < 0.05 && (er < em || em < 1e-6),
                  "%s: grey sphere rig %.4g vs median cut %.4g", name, er, em);
        sl_rig_free(&mc);
    }
    sl_rig_free(&rig);
    sl_image_free(&small);
    sl_image_free(&img);
    sl_meta_free(&meta);
    return true;
}

/* The ledger on every real HDRI in the shared data and its subfolders. */
static void test_real_hdris(void)
{
    const char *root = sl_test_data("hdri");
    if (!root)
        return;
    int count = 0;
    static const char *subs[] = {"", "/blender_studiolights", "/exr_variants", "/small",
                                 "/synthetic"};
    for (int k = 0; k < 5; k++) {
        char dir[4200];
        snprintf(dir, sizeof dir, "%s%s", root, subs[k]);
        DIR *d = opendir(dir);
        if (!d)
            continue;
        struct dirent *e;
        while ((e = readdir(d))) {
            const char *dot = strrchr(e->d_name, '.');
            if (!dot || (strcasecmp(dot, ".exr") && strcasecmp(dot, ".hdr")))
                continue;
            char path[8500];
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            count += ledger_one(path, e->d_name);
        }
        closedir(d);
    }
    if (!count)
        sl_test_skip("no lat-long HDRIs in the shared data");
}

int main(void)
{
    RUN(test_outputs);
    RUN(test_real_hdris);
    return sl_test_finish();
}
