/* SPDX-License-Identifier: BSD-3-Clause */
/* The EXR reader on the layouts renders and peers write: every compression
 * OpenEXR 3.1 has x {RGB, RGBA, RGB+Z, RGBA+Z, Y, two layers, RGB with a
 * subsampled extra channel} x {scanlines, 16x16 tiles} x {half, float,
 * half colour with float extras}, written by OpenEXR's C++ library
 * (exr_layouts_cxx.cpp). Each file read through sl_image_read (what info,
 * convert, rig, render --env, unwrap and calibrate --hdri read with) gives
 * the channels it picks, equal to OpenEXR's own decoding of them and to the
 * written values: exactly for the lossless compressions, within the
 * compression's loss for PXR24 (float), B44/B44A and DWAA/DWAB (half).
 * Channels the reader does not pick used to crash it (OpenEXR 3.1 writes
 * through the NULL pointer of a skipped channel). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "exr_layouts.h"
#include "testing.h"

enum { HALF = 1, FLOAT = 2 };

typedef struct compression {
    int code; /* exr_compression_t */
    const char *name;
    /* Largest relative error of a half / float sample (0: lossless). */
    double loss_half, loss_float;
} compression;

/* The losses measured on this test's images (smooth, 0.2 .. 1300; worst
 * B44 0.0078, DWA 0.022, both on the darkest channel) with some margin.
 * PXR24 keeps 15 of float's 23 mantissa bits (2^-16 relative; these values
 * have 11 and come back exact); B44 packs 4x4 blocks of half samples into
 * 14 bytes and stores float ones as they are; DWA quantizes DCT blocks of
 * colour channels (R, G, B, Y, any layer's) at OpenEXR's default quality
 * (45), float ones as half. */
static const compression compressions[] = {
    {0, "none", 0, 0},        {1, "rle", 0, 0},        {2, "zips", 0, 0},
    {3, "zip", 0, 0},         {4, "piz", 0, 0},        {5, "pxr24", 0, 1.6e-5},
    {6, "b44", 0.01, 0},      {7, "b44a", 0.01, 0},    {8, "dwaa", 0.03, 0.03},
    {9, "dwab", 0.03, 0.03},
};
#define N_COMPRESSIONS (int)(sizeof compressions / sizeof compressions[0])

typedef struct layout {
    const char *name;
    int nch;
    const char *names[6];
    int sampling[6]; /* 0: every pixel */
    /* What the reader gives: indices into names, in image channel order. */
    int picked_count;
    int picked[4];
} layout;

static const layout layouts[] = {
    {"rgb", 3, {"R", "G", "B"}, {0}, 3, {0, 1, 2}},
    {"rgba", 4, {"R", "G", "B", "A"}, {0}, 4, {0, 1, 2, 3}},
    {"rgbz", 4, {"R", "G", "B", "Z"}, {0}, 3, {0, 1, 2}},
    {"rgbaz", 5, {"R", "G", "B", "A", "Z"}, {0}, 4, {0, 1, 2, 3}},
    {"y", 1, {"Y"}, {0}, 1, {0}},
    /* The first layer in the channel list's (alphabetical) order. */
    {"layers",
     6,
     {"diffuse.R", "diffuse.G", "diffuse.B", "specular.R", "specular.G", "specular.B"},
     {0},
     3,
     {0, 1, 2}},
    {"subsampled", 4, {"R", "G", "B", "mask"}, {1, 1, 1, 2}, 3, {0, 1, 2}},
};
#define N_LAYOUTS (int)(sizeof layouts / sizeof layouts[0])

/* The channels of the file being written (for value()). */
static const layout *current;

/* Rounded to 11 significant bits: exact in half and in float. */
static float half_exact(double v)
{
    int e;
    double m = frexp(v, &e);
    return (float)ldexp(round(m * 2048) / 2048, e);
}

/* Smooth (lossy codecs work on blocks of it) and different in every channel,
 * with a scale per role so that a misplaced channel shows: a colour channel
 * 0.1 .. 7, the second layer eight times the first, A 0.1 .. 0.9, Z 100 .. 700. */
static float value(int c, int x, int y)
{
    const char *name = current->names[c];
    const char *role = strrchr(name, '.') ? strrchr(name, '.') + 1 : name;
    double scale = strcmp(role, "R") == 0   ? 1.0
                   : strcmp(role, "G") == 0 ? 2.5
                   : strcmp(role, "B") == 0 ? 0.6
                   : strcmp(role, "Y") == 0 ? 1.5
                   : strcmp(role, "A") == 0 ? 0.36
                   : strcmp(role, "Z") == 0 ? 250.0
                                            : 40.0;
    if (strncmp(name, "specular.", 9) == 0)
        scale *= 8;
    return half_exact(scale * (1.5 + sin(0.21 * x + 0.13 * y + 1.7 * c)) * (x + y + 40) / 60.0);
}

/* Worst relative error per compression and type (0 half, 1 float), for the
 * summary line docs/formats.md quotes. */
static double worst[N_COMPRESSIONS][2];

/* Writes l (the channels of lay) to the test folder as `name` and reads it
 * back with sl_image_read; false, with a failed check, when either fails. */
static bool write_read(const char *name, const exr_layout *l, const layout *lay, sl_image *img)
{
    char why[256] = "";
    current = lay;
    bool written = exr_layout_write(sl_test_path(name), l, value, why, sizeof why);
    CHECK_MSG(written, "%s: not written: %s", name, why);
    if (!written)
        return false;
    sl_error err;
    sl_result r = sl_image_read(sl_test_path(name), img, NULL, &err);
    CHECK_MSG(r == SL_OK, "%s: %s", name, sl_test_errmsg(&err));
    return r == SL_OK;
}

/* Writes the layout, reads it with sl_image_read and checks its pixels. */
static void check_one(int k, const layout *lay, bool tiled, int colour_type, int extra_type)
{
    const compression *comp = &compressions[k];
    bool subsampled = false;
    exr_layout l = {.compression = comp->code, .tile = tiled ? 16 : 0, .nch = lay->nch};
    for (int c = 0; c < lay->nch; c++) {
        bool extra = true;
        for (int p = 0; p < lay->picked_count; p++)
            extra = extra && lay->picked[p] != c;
        l.channels[c] = (exr_layout_channel){lay->names[c], extra ? extra_type : colour_type,
                                             lay->sampling[c]};
        subsampled = subsampled || lay->sampling[c] > 1;
    }
    /* Odd sizes: partial tiles and chunks; subsampling needs even ones. */
    l.width = subsampled ? 38 : 37;
    l.height = subsampled ? 40 : 41;
    char name[96], why[256] = "";
    snprintf(name, sizeof name, "%s_%s_%s_%d%d.exr", lay->name, comp->name,
             tiled ? "tiled" : "lines", colour_type, extra_type);
    sl_image img = {0};
    if (!write_read(name, &l, lay, &img))
        return;
    const char *path = sl_test_path(name);
    CHECK_MSG(img.width == l.width && img.height == l.height && img.channels == lay->picked_count,
              "%s: read %dx%d, %d channels", name, img.width, img.height, img.channels);
    float *ref = malloc(sizeof *ref * (size_t)l.width * (size_t)l.height);
    for (int p = 0; p < lay->picked_count && img.channels == lay->picked_count && ref; p++) {
        int c = lay->picked[p];
        bool decoded = exr_layout_decode(path, lay->names[c], ref, l.width, l.height, why,
                                         sizeof why);
        CHECK_MSG(decoded, "%s: OpenEXR cannot decode %s: %s", name, lay->names[c], why);
        int type = l.channels[c].type;
        double loss = type == HALF ? comp->loss_half : comp->loss_float, rel = 0;
        int unlike_openexr = 0;
        for (int y = 0; y < l.height; y++)
            for (int x = 0; x < l.width; x++) {
                float got = sl_image_pixel(&img, x, y)[p], want = value(c, x, y);
                unlike_openexr += decoded && got != ref[(size_t)y * (size_t)l.width + (size_t)x];
                rel = fmax(rel, fabs((double)got - want) / want);
                if (isnan(got))
                    rel = INFINITY;
            }
        CHECK_MSG(unlike_openexr == 0, "%s: %s: %d samples unlike OpenEXR's decoding", name,
                  lay->names[c], unlike_openexr);
        CHECK_MSG(rel <= loss, "%s: %s: relative error %.3g over %.3g", name, lay->names[c], rel,
                  loss);
        double *w = &worst[k][type == HALF ? 0 : 1];
        *w = fmax(*w, rel);
    }
    free(ref);
    sl_image_free(&img);
    unlink(path);
}

static void test_layouts(void)
{
    /* half, float, and half colour with float extras (renders' usual Z). */
    static const int types[3][2] = {{HALF, HALF}, {FLOAT, FLOAT}, {HALF, FLOAT}};
    for (int k = 0; k < N_COMPRESSIONS; k++)
        for (int i = 0; i < N_LAYOUTS; i++)
            for (int tiled = 0; tiled < 2; tiled++) {
                /* OpenEXR allows subsampling in scanline files only. */
                if (tiled && strcmp(layouts[i].name, "subsampled") == 0)
                    continue;
                for (int t = 0; t < 3; t++)
                    check_one(k, &layouts[i], tiled, types[t][0], types[t][1]);
            }
    for (int k = 0; k < N_COMPRESSIONS; k++)
        printf("  %-6s worst relative error: half %.2g, float %.2g\n", compressions[k].name,
               worst[k][0], worst[k][1]);
}

/* Data windows other than the display window, through each decoder: core's
 * own (ZIP), OpenEXR's C API (PIZ, tiled RLE) and its C++ library (float
 * B44, a subsampled mask). The image is the display window: overscan
 * cropped, what the data window leaves out black. */
static void test_windows(void)
{
    static const struct {
        int compression, tile, type;
        const layout *lay;
    } cases[] = {
        {3, 0, HALF, &layouts[2]}, {4, 0, HALF, &layouts[2]},  {1, 16, HALF, &layouts[3]},
        {6, 0, FLOAT, &layouts[2]}, {3, 0, HALF, &layouts[6]},
    };
    /* Overscan all round, then a window inside the display (origins even:
     * the mask is sampled 2 x 2). */
    static const int windows[2][4] = {{-4, -2, 46, 30}, {6, 4, 20, 12}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++)
        for (int wi = 0; wi < 2; wi++) {
            const layout *lay = cases[k].lay;
            exr_layout l = {.width = windows[wi][2], .height = windows[wi][3],
                            .data_x = windows[wi][0], .data_y = windows[wi][1],
                            .display_w = 38, .display_h = 24,
                            .compression = cases[k].compression, .tile = cases[k].tile,
                            .nch = lay->nch};
            for (int c = 0; c < lay->nch; c++)
                l.channels[c] = (exr_layout_channel){lay->names[c], cases[k].type,
                                                     lay->sampling[c]};
            char name[64];
            snprintf(name, sizeof name, "window_%zu_%d.exr", k, wi);
            sl_image img = {0};
            if (!write_read(name, &l, lay, &img))
                continue;
            CHECK(img.width == 38 && img.height == 24 && img.channels == lay->picked_count);
            int bad = 0;
            for (int y = 0; y < img.height && img.width == 38 && img.height == 24; y++)
                for (int x = 0; x < img.width; x++) {
                    bool inside = x >= l.data_x && x < l.data_x + l.width && y >= l.data_y &&
                                  y < l.data_y + l.height;
                    for (int p = 0; p < img.channels; p++)
                        bad += sl_image_pixel(&img, x, y)[p] !=
                               (inside ? value(lay->picked[p], x, y) : 0.0f);
                }
            CHECK_MSG(bad == 0, "%s: %d samples differ", name, bad);
            sl_image_free(&img);
        }
}

/* Picked channels that are subsampled (a chroma-subsampled image) cannot be
 * read as full-resolution colour: refused with the file and channel named. */
static void test_subsampled_colour_refused(void)
{
    static const layout lay = {"rgb_sub", 3, {"R", "G", "B"}, {2, 2, 2}, 3, {0, 1, 2}};
    exr_layout l = {.width = 38, .height = 40, .compression = 4, .nch = 3};
    for (int c = 0; c < 3; c++)
        l.channels[c] = (exr_layout_channel){lay.names[c], HALF, 2};
    const char *path = sl_test_path("rgb_subsampled.exr");
    char why[256] = "";
    current = &lay;
    CHECK_MSG(exr_layout_write(path, &l, value, why, sizeof why), "not written: %s", why);
    sl_error err;
    sl_image img = {0};
    sl_result r = sl_image_read(path, &img, NULL, &err);
    CHECK(r != SL_OK && img.data == NULL);
    CHECK(r == SL_OK || (strstr(err.message, path) && strstr(err.message, "subsampled")));
    sl_image_free(&img);
}

/* Luminance/chroma files as OpenEXR's RGBA interface writes them (Y, and
 * RY, BY sampled 2 x 2; with A for WRITE_YCA): read back as colour, sample
 * for sample what OpenEXR's own RGBA decoding gives, and in flat areas the
 * colour written (chroma subsampling loses only at edges). */
static void test_luminance_chroma(void)
{
    enum { W = 96, H = 96 };
    for (int channels = 3; channels <= 4; channels++) {
        static float px[W * H * 4], ref[W * H * 4];
        /* Four flat quadrants of saturated colours. */
        static const float colour[4][4] = {{0.9f, 0.2f, 0.05f, 1.0f},
                                           {0.1f, 0.6f, 0.3f, 0.5f},
                                           {0.05f, 0.1f, 2.5f, 0.25f},
                                           {40.0f, 30.0f, 20.0f, 1.0f}};
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int c = 0; c < channels; c++)
                    px[(y * W + x) * channels + c] =
                        colour[(y >= H / 2) * 2 + (x >= W / 2)][c];
        char name[32], why[256] = "";
        snprintf(name, sizeof name, "yc%d.exr", channels);
        const char *path = sl_test_path(name);
        bool written = exr_layout_write_yc(path, px, W, H, channels, why, sizeof why);
        CHECK_MSG(written, "%s: not written: %s", name, why);
        CHECK(exr_layout_decode_rgba(path, ref, W, H, why, sizeof why));
        sl_error err;
        sl_image img = {0};
        sl_result r = sl_image_read(path, &img, NULL, &err);
        CHECK_MSG(r == SL_OK, "%s: %s", name, sl_test_errmsg(&err));
        if (r != SL_OK)
            continue;
        CHECK(img.width == W && img.height == H && img.channels == channels);
        int unlike_openexr = 0;
        double flat_err = 0;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int c = 0; c < img.channels; c++) {
                    float got = sl_image_pixel(&img, x, y)[c];
                    unlike_openexr += got != ref[(y * W + x) * 4 + c];
                    /* Away from the quadrants' edges (the chroma filter's reach). */
                    if (abs(2 * x - W + 1) > 40 && abs(2 * y - H + 1) > 40) {
                        float want = px[(y * W + x) * channels + c];
                        flat_err = fmax(flat_err, fabs(got - want) / want);
                    }
                }
        CHECK_MSG(unlike_openexr == 0, "%s: %d samples unlike OpenEXR's RGBA decoding", name,
                  unlike_openexr);
        /* The RGBA interface keeps 7 mantissa bits of Y and 5 of RY, BY by
         * default (RgbaOutputFile::setYCRounding), amplified in the
         * smallest channel of a saturated colour (measured 0.05): still far
         * from any swapped or grey channel. */
        CHECK_MSG(flat_err < 0.1, "%s: flat colour off by %.3g", name, flat_err);
        printf("  %s: flat areas within %.2g of the colour written\n", name, flat_err);
        sl_image_free(&img);
        unlink(path);
    }
}

int main(void)
{
    RUN(test_layouts);
    RUN(test_windows);
    RUN(test_subsampled_colour_refused);
    RUN(test_luminance_chroma);
    return sl_test_finish();
}
