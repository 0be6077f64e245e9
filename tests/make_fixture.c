/* SPDX-License-Identifier: BSD-3-Clause */
/* Writes synthetic images for the CLI tests (darktable-style synthetic
 * fixtures: every value known, bad values on purpose).
 *   make_fixture KIND OUT [W H]
 * KIND: latlong   smooth RGB lat-long (2:1), envmap attribute set
 *       sun       black lat-long with one 1e5 texel at +Z... and a sky of 1
 *       nan       lat-long with NaN and Inf samples, as a PFM file written here
 *                 byte by byte (setlight's own writers never write NaN)
 *       wide      a 3:1 image with no envmap attribute
 *       wideenv   the same with the envmap attribute saying lat-long
 *       conf      a 3:2 grey of 3.7 with a confidence ramp (0 to 1 across) as
 *                 its fourth channel, no envmap attribute
 *       png       an 8-bit PNG (write OUT with any name, e.g. x.exr)
 *       plain     the latlong one without the envmap attribute
 *       code128   8-bit code 128 everywhere, no envmap (OUT .png, .jpg or .tif)
 *       lens OUT IN SECONDS LENS FOCAL-MM   IN as a linear TIFF bracket frame with EXIF
 *       ball...   chrome-ball photos, see ball_fixture.h
 *       fisheye   make_fixture fisheye OUT W H YAW [PITCH [SCENE]]: the virtual
 *                 stage (or SCENE: "flat" for a featureless grey) through an
 *                 8 mm equisolid on a 36 mm sensor looking at YAW, PITCH (deg)

 *       chart...  chart photos and walls that are not one, see chart_fixture.h */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ball_fixture.h"
#include "chart_fixture.h"
#include "setlight/vset.h"
#include "setlight/core.h"
#include "setlight/pipeline.h"

/* Portable float map: header, then little-endian float rows bottom to top. */
static sl_result write_pfm(const char *path, const sl_image *img, sl_error *err)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot write", path);
    fprintf(f, "PF\n%d %d\n-1.0\n", img->width, img->height);
    for (int y = img->height - 1; y >= 0; y--)
        fwrite(sl_image_pixel(img, 0, y), sizeof(float), (size_t)img->width * 3, f);
    return fclose(f) == 0 ? SL_OK : sl_error_set(err, SL_ERR_IO, "%s: write failed", path);
}

/* A fisheye view of the virtual stage (or of a flat grey) for the stitch. */
static int fisheye_fixture(int argc, char **argv)
{
    if (argc < 6) {
        fprintf(stderr, "usage: make_fixture fisheye OUT W H YAW [PITCH [SCENE]]\n");
        return 2;
    }
    int w = atoi(argv[3]), h = atoi(argv[4]);
    sl_view_pose pose = {atof(argv[5]), argc > 6 ? atof(argv[6]) : 0.0, 0.0};
    const char *scene = argc > 7 ? argv[7] : "stage";
    sl_error err;
    sl_vset_desc d;
    sl_vset_scene sc;
    memset(&sc, 0, sizeof sc);
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, w, h, 8.0, 36.0);
    sl_image view = {0};
    sl_result r;
    if (!strcmp(scene, "flat")) {
        r = sl_image_alloc(&sc.latlong, 64, 32, 3, &err);
        if (!r)
            sl_image_fill(&sc.latlong, 0.5f);
    } else {
        r = sl_vset_preset(scene, &d, &err);
        if (!r)
            r = sl_vset_scene_make(&d, 1024, &sc, &err);
    }
    if (!r)
        r = sl_vset_view_image(&lens, &pose, &sc.latlong, 2, &view, &err);
    if (!r)
        r = sl_exr_write(argv[2], &view, NULL, SL_PIXEL_FLOAT, &err);
    if (r)
        fprintf(stderr, "make_fixture: %s\n", err.message);
    sl_image_free(&view);
    if (!strcmp(scene, "flat"))
        sl_image_free(&sc.latlong);
    else
        sl_vset_scene_free(&sc);
    return r ? 1 : 0;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: make_fixture KIND OUT [W H]\n");
        return 2;
    }
    const char *kind = argv[1], *out = argv[2];
    /* make_fixture latlong-error TEST.exr REF.exr BAND-DEG: prints the median
     * luminance ratio, median relative error, and that error once the ratio is
     * divided out, within BAND-DEG of the horizon (sl_pipeline_latlong_compare), for the process tests' score against a
     * virtual set's truth. */
    if (!strcmp(kind, "latlong-error")) {
        double ratio, rel, scaled;
        sl_error e;
        if (argc != 5) {
            fprintf(stderr, "usage: make_fixture latlong-error TEST REF BAND-DEG\n");
            return 2;
        }
        if (sl_pipeline_latlong_compare(out, argv[3], atof(argv[4]), &ratio, &rel, &scaled,
                                        &e)) {
            fprintf(stderr, "make_fixture: %s\n", e.message);
            return 1;
        }
        printf("%.6g %.6f %.6f\n", ratio, rel, scaled);
        return 0;
    }
    if (!strncmp(kind, "ball", 4))
        return ball_fixture_main(kind, out);
    if (!strncmp(kind, "chart", 5))
        return chart_fixture_main(kind, out);
    /* make_fixture exif OUT IN SECONDS F-NUMBER ISO: IN (EXR) with exposure metadata.
     * make_fixture lens OUT IN SECONDS LENS FOCAL-MM: IN (any image) as a 16-bit
     * linear TIFF frame of a bracket, exposed for SECONDS (IN's brightest value
     * at 1 s just saturates), with its lens and camera EXIF. */
    bool lens = !strcmp(kind, "lens");
    if (lens || !strcmp(kind, "exif")) {
        if (argc < 7) {
            fprintf(stderr, "usage: make_fixture %s OUT IN SECONDS %s\n", kind,
                    lens ? "LENS FOCAL-MM" : "F-NUMBER ISO");
            return 2;
        }
        sl_image im;
        sl_meta md, in;
        sl_error e;
        sl_meta_init(&md);
        sl_result rr = sl_image_read(argv[3], &im, &in, &e);
        if (!rr) {
            sl_meta_free(&in);
            sl_meta_set_rec709(&md);
            md.exposure_time = atof(argv[4]);
            if (lens) {
                snprintf(md.lens, sizeof md.lens, "%s", argv[5]);
                md.focal_length_mm = atof(argv[6]);
                snprintf(md.make, sizeof md.make, "Canon");
                snprintf(md.model, sizeof md.model, "Canon EOS 5D Mark II");
                size_t n = (size_t)im.width * im.height * im.channels;
                float top = 0;
                for (size_t i = 0; i < n; i++)
                    top = im.data[i] > top ? im.data[i] : top;
                for (size_t i = 0; i < n; i++)
                    im.data[i] *= (float)(md.exposure_time / top);
                rr = sl_photo_write(out, &im, &md, 16, &e);
            } else {
                md.f_number = atof(argv[5]);
                md.iso = atof(argv[6]);
                rr = sl_exr_write(out, &im, &md, SL_PIXEL_FLOAT, &e);
            }
            sl_image_free(&im);
        }
        sl_meta_free(&md);
        if (rr)
            fprintf(stderr, "make_fixture: %s\n", e.message);
        return rr ? 1 : 0;
    }
    if (!strcmp(kind, "fisheye"))
        return fisheye_fixture(argc, argv);
    int w = argc > 3 ? atoi(argv[3]) : 64, h = argc > 4 ? atoi(argv[4]) : w / 2;
    bool conf = !strcmp(kind, "conf");
    if (!strcmp(kind, "wide") || !strcmp(kind, "wideenv"))
        h = w / 3;
    if (conf)
        h = 2 * w / 3;
    sl_image img;
    sl_meta meta;
    sl_error err;
    sl_meta_init(&meta);
    if (sl_image_alloc(&img, w, h, conf ? 4 : 3, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(&img, x, y);
            double u = (x + 0.5) / w, v = (y + 0.5) / h;
            p[0] = (float)(0.2 + 0.8 * u);
            p[1] = (float)(0.2 + 0.8 * v);
            p[2] = (float)(0.5 + 0.4 * sin(6.283185307179586 * u));
            if (conf) {
                p[0] = p[1] = p[2] = 3.7f;
                p[3] = (float)x / (float)(w > 1 ? w - 1 : 1);
            }
        }
    if (!strcmp(kind, "sun") || !strcmp(kind, "sunclip") || !strcmp(kind, "sunmask")) {
        /* sunclip: the sun clipped at 100 as a merge leaves it, naming its
         * mask (sunmask: 1 at the sun) as the merge does. */
        sl_image_fill(&img, kind[3] == 'm' ? 0.0f : 1.0f);
        float *p = sl_image_pixel(&img, w / 2, h / 4);
        p[0] = p[1] = p[2] = kind[3] == 'c' ? 100.0f : kind[3] == 'm' ? 1.0f : 1e5f;
        if (kind[3] == 'c' && sl_meta_set(&meta, "setlight:merge:clipped_mask", "sunmask.exr", &err)) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
    }
    if (!strcmp(kind, "nan")) {
        sl_image_pixel(&img, 1, 1)[0] = NAN;
        sl_image_pixel(&img, 2, 1)[1] = INFINITY;
        sl_image_pixel(&img, 3, 2)[2] = -INFINITY;
    }
    if (!strcmp(kind, "code128"))
        sl_image_fill(&img, 128.0f / 255.0f);
    if (strcmp(kind, "wide") != 0 && strcmp(kind, "plain") != 0 && strcmp(kind, "code128") != 0 &&
        !conf)
        meta.envmap = SL_ENVMAP_LATLONG;
    sl_meta_set_rec709(&meta);
    sl_result r;
    if (!strcmp(kind, "png")) {
        /* sl_photo_write picks the format by extension: write .png, then rename. */
        char tmp[4096];
        snprintf(tmp, sizeof tmp, "%s.tmp.png", out);
        r = sl_photo_write(tmp, &img, &meta, 8, &err);
        if (!r && rename(tmp, out) != 0)
            r = sl_error_set(&err, SL_ERR_IO, "%s: rename failed", out);
    } else if (!strcmp(kind, "code128")) {
        r = sl_photo_write(out, &img, NULL, 8, &err);
    } else if (!strcmp(kind, "nan"))
        r = write_pfm(out, &img, &err);
    else
        r = sl_exr_write(out, &img, &meta, SL_PIXEL_FLOAT, &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
    if (r) {
        fprintf(stderr, "make_fixture: %s\n", err.message);
        return 1;
    }
    return 0;
}
