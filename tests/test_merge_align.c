/* SPDX-License-Identifier: BSD-3-Clause */
/* Merge alignment (sl_align_bracket, sl_merge with align): brackets of a
 * textured HDR scene seen through a camera that moved by known shifts and
 * rotations between frames; aligned, mostly clipped and near-black frames. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "merge_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

enum { BLOBS = 160, MAX_F = 7 };

typedef struct warp {
    double dx, dy, deg; /* reference position p is at R(deg)(p - c) + c + (dx, dy) in the frame */
} warp;

typedef struct blob {
    double x, y, sigma, stops;
} blob;

/* Smaller frames under sanitizers (same assertions; the still bracket's
 * dark frames need two thirds of the size to keep enough usable pixels). */
static int size(int full) { return sl_test_sanitized() ? full / 2 : full; }
static int size_still(int full) { return sl_test_sanitized() ? full * 2 / 3 : full; }


static double gauss(uint64_t *s)
{
    double u1 = sl_test_uniform(s) + 1e-300, u2 = sl_test_uniform(s);
    return sqrt(-2 * log(u1)) * cos(6.283185307179586 * u2);
}

/* Scene: log2 radiance = a slope plus Gaussian blobs of many sizes (no
 * period, so no false match), in stops around the middle exposure. */
typedef struct scene {
    int w, h;
    blob b[BLOBS];
} scene;

static void make_scene(scene *s, int w, int h, uint64_t seed)
{
    s->w = w;
    s->h = h;
    for (int i = 0; i < BLOBS; i++) {
        s->b[i].x = (sl_test_uniform(&seed) * 1.4 - 0.2) * w;
        s->b[i].y = (sl_test_uniform(&seed) * 1.4 - 0.2) * h;
        s->b[i].sigma = 3 + 30 * pow(sl_test_uniform(&seed), 2);
        s->b[i].stops = (sl_test_uniform(&seed) - 0.45) * 6;
    }
}

/* Renders frame pixels with the scene moved by `t`: pixel q shows the
 * reference position p = R^-1 (q - c - t) + c. */
static void render_stops(const scene *s, const warp *t, double *l2)
{
    int w = s->w, h = s->h;
    double th = t->deg * M_PI / 180, c = cos(th), sn = sin(th), cx = 0.5 * w, cy = 0.5 * h;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double qx = x + 0.5 - cx - t->dx, qy = y + 0.5 - cy - t->dy;
            double px = c * qx + sn * qy + cx, py = -sn * qx + c * qy + cy;
            l2[(size_t)y * w + x] = -2 + 3 * px / w - 2 * py / h;
        }
    for (int i = 0; i < BLOBS; i++) {
        const blob *b = &s->b[i];
        /* The blob's centre in the frame, and its reach. */
        double bx = b->x - cx, by = b->y - cy;
        double fx = c * bx - sn * by + cx + t->dx, fy = sn * bx + c * by + cy + t->dy;
        double reach = 4 * b->sigma;
        int x0 = (int)fmax(0, fx - reach), x1 = (int)fmin(w - 1, fx + reach);
        int y0 = (int)fmax(0, fy - reach), y1 = (int)fmin(h - 1, fy + reach);
        for (int y = y0; y <= y1; y++)
            for (int x = x0; x <= x1; x++) {
                double qx = x + 0.5 - cx - t->dx, qy = y + 0.5 - cy - t->dy;
                double px = c * qx + sn * qy + cx, py = -sn * qx + c * qy + cy;
                double d2 = (px - b->x) * (px - b->x) + (py - b->y) * (py - b->y);
                l2[(size_t)y * w + x] += b->stops * exp(-d2 / (2 * b->sigma * b->sigma));
            }
    }
}

/* One frame at `stops` relative to the middle exposure: gamma curve,
 * Poisson-Gaussian noise, 8 bits. */
static sl_result write_frame(const char *path, const scene *s, const warp *t, double stops,
                             uint64_t seed, sl_error *err)
{
    int w = s->w, h = s->h;
    double *l2 = malloc((size_t)w * h * sizeof *l2);
    sl_image img = {0};
    sl_result r = l2 ? sl_image_alloc(&img, w, h, 3, err) : SL_ERR_NOMEM;
    if (!r) {
        render_stops(s, t, l2);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                for (int c = 0; c < 3; c++) {
                    double lin = exp2(l2[(size_t)y * w + x] + stops - 3) * (1 + 0.1 * (c - 1));
                    lin += sqrt(2e-5 * fmin(lin, 1) + 1e-6) * gauss(&seed);
                    sl_image_pixel(&img, x, y)[c] = (float)mf_curve_forward(MF_GAMMA, lin);
                }
        r = sl_photo_write(path, &img, NULL, 8, err);
    }
    sl_image_free(&img);
    free(l2);
    return r;
}

typedef struct bracket {
    int n;
    char paths[MAX_F][512];
    const char *ptr[MAX_F];
    double exposure[MAX_F];
    warp t[MAX_F];
} bracket;

static void make_bracket(bracket *b, const char *name, const scene *s, int n, double stops,
                         double offset, const warp *t)
{
    sl_error err;
    b->n = n;
    for (int k = 0; k < n; k++) {
        double st = offset + stops * (k - (n - 1) / 2.0);
        b->t[k] = t[k];
        b->exposure[k] = exp2(st) / 30;
        snprintf(b->paths[k], sizeof b->paths[k], "%s", sl_test_path(name));
        size_t len = strlen(b->paths[k]);
        snprintf(b->paths[k] + len, sizeof b->paths[k] - len, "_%d.png", k);
        b->ptr[k] = b->paths[k];
        CHECK_OK(write_frame(b->paths[k], s, &t[k], st, 17 + (uint64_t)k * 1000003, &err), &err);
    }
}

/* The bracket registered with the default options. */
static void align_default(const bracket *b, sl_align_transform *out)
{
    sl_error err;
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    CHECK_OK(sl_align_bracket(b->ptr, b->n, b->exposure, &opt, out, &err), &err);
}

/* Largest displacement error over the frame's corners (pixels). */
static double corner_error(const sl_align_transform *got, const warp *want, int w, int h)
{
    double worst = 0, cx = 0.5 * w, cy = 0.5 * h;
    for (int k = 0; k < 4; k++) {
        double px = (k & 1 ? w : 0) - cx, py = (k & 2 ? h : 0) - cy;
        double a = got->angle * M_PI / 180, b = want->deg * M_PI / 180;
        double ex = (cos(a) * px - sin(a) * py + got->dx) - (cos(b) * px - sin(b) * py + want->dx);
        double ey = (sin(a) * px + cos(a) * py + got->dy) - (sin(b) * px + cos(b) * py + want->dy);
        worst = fmax(worst, hypot(ex, ey));
    }
    return worst;
}

static void test_known_warp(void)
{
    scene s;
    make_scene(&s, size(480), size(360), 7);
    const warp t[5] = {{20, -13, 1}, {-20, 7.4, -0.5}, {0, 0, 0}, {12.3, 19.6, 0.8}, {-17.75, -20, -1}};
    bracket b;
    make_bracket(&b, "align_warp", &s, 5, 2, 0, t);
    sl_align_transform out[5];
    align_default(&b, out);
    double worst = 0;
    for (int k = 0; k < 5; k++) {
        double e = corner_error(&out[k], &t[k], s.w, s.h);
        printf("  frame %d: got (%.3f, %.3f, %.4f deg) want (%.2f, %.2f, %.2f deg): %.3f px at "
               "the corners, %lld px used %s\n",
               k, out[k].dx, out[k].dy, out[k].angle, t[k].dx, t[k].dy, t[k].deg, e,
               (long long)out[k].pixels, out[k].note);
        worst = fmax(worst, e);
        CHECK(k == 2 ? !out[k].applied : out[k].applied);
    }
    CHECK(worst <= 0.25);
    CHECK(!strcmp(out[2].note, "reference"));
}

/* Frames that did not move: a 99.9% clipped longest frame and a dark
 * shortest one must not produce a shift (OpenCV's AlignMTB reports up to
 * 63 px on such frames). */
static void test_aligned_frames(void)
{
    scene s;
    make_scene(&s, size_still(400), size_still(300), 11);
    warp t[7];
    memset(t, 0, sizeof t);
    bracket b;
    make_bracket(&b, "align_still", &s, 7, 3, 0.5, t);
    sl_align_transform out[7];
    align_default(&b, out);
    double worst = 0;
    for (int k = 0; k < 7; k++) {
        double e = corner_error(&out[k], &t[k], s.w, s.h);
        printf("  frame %d: (%.3f, %.3f, %.4f deg) %lld px used %s%s\n", k, out[k].dx, out[k].dy,
               out[k].angle, (long long)out[k].pixels, out[k].applied ? "applied " : "",
               out[k].note);
        worst = fmax(worst, e);
    }
    CHECK(worst <= 0.2);
}

/* A frame eight stops under the rest: nothing to align on, so it stays
 * where it is, with a note, and the merge still runs. */
static void test_dark_frame(void)
{
    sl_error err;
    scene s;
    make_scene(&s, size(320), size(240), 5);
    const warp t[3] = {{0, 0, 0}, {0, 0, 0}, {6, -4, 0.3}};
    bracket b;
    make_bracket(&b, "align_dark", &s, 3, 2, 0, t);
    /* Replace frame 0 by a nearly black one (12 stops under the middle). */
    CHECK_OK(write_frame(b.paths[0], &s, &t[0], -12, 99, &err), &err);
    b.exposure[0] = exp2(-12) / 30;
    sl_align_transform out[3];
    align_default(&b, out);
    printf("  dark frame: (%.3f, %.3f) %s; frame 2 error %.3f px\n", out[0].dx, out[0].dy,
           out[0].note, corner_error(&out[2], &t[2], s.w, s.h));
    CHECK(!out[0].applied);
    CHECK(strstr(out[0].note, "too few") != NULL);
    CHECK(hypot(out[0].dx, out[0].dy) < 1e-9);
    CHECK(corner_error(&out[2], &t[2], s.w, s.h) <= 0.25);
}

/* A handheld bracket's shortest frame sees little but the lamps, and each
 * frame moved its own way. It is measured on those pixels, not placed where
 * its neighbour is (which put a room's 1/4000 s frame 4 px off): with 2.2%
 * of its pixels well exposed; with 0.95%, where the bitmaps' coarse-to-fine
 * match stops 5 px off and the fit must be taken over it; and with 0.27%. */
static void test_dark_frames_moved(void)
{
    scene s;
    /* Full size under sanitizers too: smaller, the frame's other pixels
     * make up more than 5% of it. */
    make_scene(&s, 400, 300, 23);
    /* Two dozen small sharp lamps, 7-9 stops over the scene. */
    for (int i = 0; i < 24; i++) {
        s.b[i].sigma = 1.5 + 0.1 * (i % 20);
        s.b[i].stops = 7 + 0.08 * i;
    }
    const warp t[7] = {{1, 3, 0}, {-3, -1, 0}, {2, -2, 0}, {0, 0, 0}, {0.5, 0.5, 0}, {0, 0, 0}, {0, 0, 0}};
    /* The bracket's offset in stops, and the shortest frame's usable share
     * it must come under. */
    const struct {
        double offset, share;
    } cases[] = {{0.5, 0.05}, {-0.5, 0.01}, {-1.5, 0.005}};
    for (int c = 0; c < 3; c++) {
        char name[64];
        snprintf(name, sizeof name, "align_dark_moved_%d", c);
        bracket b;
        make_bracket(&b, name, &s, 7, 3, cases[c].offset, t);
        sl_align_transform out[7];
        align_default(&b, out);
        printf("  offset %+.1f stops\n", cases[c].offset);
        for (int k = 0; k < 3; k++) {
            double e = corner_error(&out[k], &t[k], s.w, s.h);
            printf("  frame %d: (%.3f, %.3f, %.4f deg) want (%.0f, %.0f): %.3f px at the "
                   "corners, %lld px used (%.2f%%) %s\n",
                   k, out[k].dx, out[k].dy, out[k].angle, t[k].dx, t[k].dy, e,
                   (long long)out[k].pixels, 100.0 * out[k].pixels / (s.w * s.h), out[k].note);
            CHECK_MSG(!out[k].refused && out[k].applied, "frame %d: %s", k, out[k].note);
            CHECK(e <= 0.3);
        }
        CHECK(out[0].pixels < cases[c].share * s.w * s.h);
    }
}

/* Median relative error of a merge's green against the scene as the
 * reference frame sees it, away from the border moved frames miss. */
static double median_error(const sl_merge_result *res, const scene *s, const double *l2)
{
    double *e = malloc((size_t)s->w * s->h * sizeof *e);
    size_t n = 0;
    for (int y = 30; y < s->h - 30; y++)
        for (int x = 30; x < s->w - 30; x++) {
            double truth = exp2(l2[(size_t)y * s->w + x] - 3);
            e[n++] = fabs(sl_image_pixel(&res->radiance, x, y)[1] / truth - 1);
        }
    qsort(e, n, sizeof *e, sl_cmp_double);
    double m = e[n / 2];
    free(e);
    return m;
}

/* The merge with align: the warped bracket comes out as accurate as the
 * same bracket taken without moving the camera. */
static void test_merge_aligned(void)
{
    sl_error err;
    scene s;
    make_scene(&s, size(360), size(270), 3);
    const warp moved[5] = {{9.5, -6, 0.7}, {-12, 4.25, -0.4}, {0, 0, 0}, {7, 11, 0.5}, {-15, -8, -0.9}};
    warp still[5];
    memset(still, 0, sizeof still);
    bracket bm, bs;
    make_bracket(&bm, "align_mm", &s, 5, 2, 0, moved);
    make_bracket(&bs, "align_ms", &s, 5, 2, 0, still);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = SL_RESPONSE_AUTO;
    double times[5];
    for (int k = 0; k < 5; k++)
        times[k] = bm.exposure[k];
    opt.times = times;
    sl_merge_result rs, rm, ru;
    opt.align = SL_ALIGN_OFF;
    CHECK_OK(sl_merge(bs.ptr, 5, &opt, &rs, &err), &err);
    CHECK_OK(sl_merge(bm.ptr, 5, &opt, &ru, &err), &err);
    opt.align = true; /* the former bool: on */
    CHECK_OK(sl_merge(bm.ptr, 5, &opt, &rm, &err), &err);
    double *l2 = malloc((size_t)s.w * s.h * sizeof *l2);
    render_stops(&s, &still[0], l2);
    double med[3] = {median_error(&rs, &s, l2), median_error(&rm, &s, l2), median_error(&ru, &s, l2)};
    free(l2);
    printf("  median relative error: still %.4f, moved and aligned %.4f, moved unaligned %.4f\n",
           med[0], med[1], med[2]);
    CHECK(med[1] < 1.5 * med[0] + 0.005);
    CHECK(med[2] > 5 * med[1]);
    /* PNG codes are saturated at the clip code, until resampling blends
     * clipped pixels into their neighbours (at the clip code the aligned
     * merge's median error was 4x the still one's at half size). */
    CHECK_MSG(rs.saturation == 1 && ru.saturation == 1 && rm.saturation == 0.95,
              "saturation %g still, %g unaligned, %g aligned", rs.saturation, ru.saturation,
              rm.saturation);
    for (int k = 0; k < 5; k++)
        printf("  frame %d: (%.3f, %.3f, %.4f deg) %.3f px at the corners %s\n", k,
               rm.frames[k].align.dx, rm.frames[k].align.dy, rm.frames[k].align.angle,
               corner_error(&rm.frames[k].align, &moved[k], s.w, s.h), rm.frames[k].align.note);
    for (int k = 0; k < 5; k++)
        CHECK(k == 2 || (rm.frames[k].align.applied &&
                         corner_error(&rm.frames[k].align, &moved[k], s.w, s.h) <= 0.25));
    sl_merge_result_free(&rs);
    sl_merge_result_free(&rm);
    sl_merge_result_free(&ru);
}


/* The recovered curve against the camera's (gamma, 1 at white): the
 * largest |ln ratio| over the codes the bracket exposes well. */
static double curve_error(const sl_response *resp)
{
    double worst = 0;
    for (double z = 0.1; z <= 0.9; z += 0.01)
        worst = fmax(worst, fabs(log(sl_response_eval(resp, 1, z) / mf_curve_inverse(MF_GAMMA, z))));
    return worst;
}

/* Auto alignment (the default): a bracket shot hand-held, moved by integer
 * and sub-pixel shifts, is measured, registered and merged as well as the
 * same bracket shot still; the still one is measured and left alone; with
 * alignment off the moved one is far worse and its recovered curve bent. */
static void test_auto_alignment(void)
{
    sl_error err;
    scene s;
    /* Two thirds under sanitizers: at half size the longest frame keeps too
     * few usable pixels to be measured. */
    make_scene(&s, size_still(360), size_still(270), 3);
    const warp moved[5] = {{3, -2, 0}, {-1.5, 0.75, 0}, {0, 0, 0}, {0.25, -1.5, 0}, {-4, 1.25, 0}};
    warp still[5];
    memset(still, 0, sizeof still);
    bracket bm, bs;
    make_bracket(&bm, "auto_moved", &s, 5, 2, 0, moved);
    make_bracket(&bs, "auto_still", &s, 5, 2, 0, still);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    CHECK(opt.align == SL_ALIGN_AUTO && opt.align_auto_px == 0.5);
    opt.response_mode = SL_RESPONSE_AUTO;
    double times[5];
    for (int k = 0; k < 5; k++)
        times[k] = bm.exposure[k];
    opt.times = times;
    sl_merge_result rs, ra, ro, rmeasure;
    CHECK_OK(sl_merge(bs.ptr, 5, &opt, &rs, &err), &err);
    CHECK_OK(sl_merge(bm.ptr, 5, &opt, &ra, &err), &err);
    /* The measurement alone: a threshold nothing reaches. */
    opt.align_auto_px = 1e6;
    CHECK_OK(sl_merge_response(bm.ptr, 5, &opt, &rmeasure, &err), &err);
    opt.align_auto_px = 0.5;
    opt.align = SL_ALIGN_OFF;
    CHECK_OK(sl_merge(bm.ptr, 5, &opt, &ro, &err), &err);
    printf("  still: %s (%.3f px)\n  moved: %s (%.3f px)\n", rs.align_note, rs.misalignment_px,
           ra.align_note, ra.misalignment_px);
    CHECK(rs.align_mode == SL_ALIGN_AUTO && !rs.aligned);
    CHECK(rs.misalignment_px >= 0 && rs.misalignment_px < 0.5);
    CHECK(ra.aligned && strstr(ra.align_note, "registered") != NULL);
    CHECK(!ro.aligned && ro.misalignment_px < 0 && ro.align_mode == SL_ALIGN_OFF);
    CHECK(!rmeasure.aligned);
    for (int k = 0; k < 5; k++) {
        double em = corner_error(&rmeasure.frames[k].align, &moved[k], s.w, s.h);
        double er = corner_error(&ra.frames[k].align, &moved[k], s.w, s.h);
        printf("  frame %d: truth (%.2f, %.2f); measured (%.3f, %.3f, %.4f deg) spread %.2f px "
               "%.3f deg, %.3f px off; registered (%.3f, %.3f), %.3f px off\n",
               k, moved[k].dx, moved[k].dy, rmeasure.frames[k].align.dx,
               rmeasure.frames[k].align.dy, rmeasure.frames[k].align.angle,
               rmeasure.frames[k].align.shift_spread_px, rmeasure.frames[k].align.angle_spread_deg,
               em, ra.frames[k].align.dx, ra.frames[k].align.dy, er);
        CHECK(em <= 0.15);
        CHECK(er <= 0.25);
        CHECK(k == 2 || ra.frames[k].align.applied);
        CHECK(!rmeasure.frames[k].align.applied);
    }
    double *l2 = malloc((size_t)s.w * s.h * sizeof *l2);
    render_stops(&s, &still[0], l2);
    double es = median_error(&rs, &s, l2), ea = median_error(&ra, &s, l2),
           eo = median_error(&ro, &s, l2);
    free(l2);
    double cs = curve_error(&rs.response), ca = curve_error(&ra.response),
           co = curve_error(&ro.response);
    printf("  median radiance error: still %.4f, moved auto %.4f, moved off %.4f\n", es, ea, eo);
    printf("  curve error (max |ln|): still %.4f, moved auto %.4f, moved off %.4f\n", cs, ca, co);
    CHECK(ea < 1.5 * es + 0.005);
    CHECK(eo > 5 * ea);
    CHECK(ca < 1.5 * cs + 0.01);
    CHECK(co > 2 * ca);
    sl_merge_result_free(&rs);
    sl_merge_result_free(&ra);
    sl_merge_result_free(&ro);
    sl_merge_result_free(&rmeasure);
}

/* Real brackets (skipped without the shared data): the measurement on a
 * hand-held bracket and on two tripod ones, with the response alone (the
 * measurement happens in its sample pass). */
static void measure_real(const char *dir, const char *name, const char *const *files, int n,
                         const double *times, sl_merge_result *res)
{
    sl_error err;
    char paths[16][1024];
    const char *ptr[16];
    for (int k = 0; k < n; k++) {
        snprintf(paths[k], sizeof paths[k], "%s/%s", dir, files[k]);
        ptr[k] = paths[k];
    }
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.times = times;
    CHECK_OK(sl_merge_response(ptr, n, &opt, res, &err), &err);
    printf("  %s: %s; largest %.3f px; measurement %.3f CPU s, decoding %.3f\n", name,
           res->align_note, res->misalignment_px, res->align_measure_cpu,
           res->timing.cpu[SL_MERGE_DECODE]);
}

static void test_real_brackets(void)
{
    if (sl_test_sanitized()) {
        sl_test_skip("real brackets under sanitizers (too slow)");
        return;
    }
    const char *dir = sl_test_data("brackets/stack_ghost");
    if (!dir)
        return;
    char base[1024];
    snprintf(base, sizeof base, "%s/..", dir);
    sl_merge_result res;
    const char *ghost[3] = {"stack_ghost/IMG_0959.JPG", "stack_ghost/IMG_0960.JPG",
                            "stack_ghost/IMG_0961.JPG"};
    measure_real(base, "stack_ghost", ghost, 3, NULL, &res);
    /* OpenCV's findTransformECC on the same frames: IMG_0960 dy -0.24 ..
     * -0.29, IMG_0961 dy -0.23 .. -0.33 (intensity, gradient). */
    CHECK(!res.aligned && res.misalignment_px < 0.5);
    CHECK(!strcmp(res.frames[0].align.note, "reference"));
    CHECK(fabs(res.frames[1].align.dy + 0.28) < 0.1 && fabs(res.frames[1].align.dx) < 0.1);
    CHECK(fabs(res.frames[2].align.dy + 0.31) < 0.1 && fabs(res.frames[2].align.dx) < 0.1);
    sl_merge_result_free(&res);
    const char *room[7];
    char names[7][64];
    for (int k = 0; k < 7; k++) {
        snprintf(names[k], sizeof names[k], "stack_room/stack_room_exp_%d.jpg", k);
        room[k] = names[k];
    }
    measure_real(base, "stack_room", room, 7, NULL, &res);
    CHECK(!res.aligned);
    sl_merge_result_free(&res);
    const char *mem[16];
    char mnames[16][64];
    double times[16];
    for (int k = 0; k < 16; k++) {
        snprintf(mnames[k], sizeof mnames[k], "memorial/memorial%04d.png", 61 + k);
        mem[k] = mnames[k];
        times[k] = exp2(5 - k);
    }
    measure_real(base, "memorial", mem, 16, times, &res);
    CHECK(!res.aligned);
    sl_merge_result_free(&res);
}

static void test_bad_options(void)
{
    sl_error err;
    scene s;
    make_scene(&s, 64, 48, 1);
    warp t[2];
    memset(t, 0, sizeof t);
    bracket b;
    make_bracket(&b, "align_bad", &s, 2, 2, 0, t);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_align_transform out[2];
    opt.align_max_angle = 30;
    CHECK(sl_align_bracket(b.ptr, 2, b.exposure, &opt, out, &err) == SL_ERR_USAGE);
    CHECK(strstr(err.message, b.paths[0]) != NULL);
    sl_merge_options_init(&opt);
    const char *missing[2] = {b.ptr[0], sl_test_path("align_missing.png")};
    CHECK(sl_align_bracket(missing, 2, b.exposure, &opt, out, &err) != SL_OK);
    CHECK(strstr(err.message, "align_missing.png") != NULL);
    CHECK(sl_align_bracket(b.ptr, 1, b.exposure, &opt, out, &err) == SL_ERR_USAGE);
}

int main(void)
{
    RUN(test_known_warp);
    RUN(test_aligned_frames);
    RUN(test_dark_frame);
    RUN(test_dark_frames_moved);
    RUN(test_merge_aligned);
    RUN(test_auto_alignment);
    RUN(test_real_brackets);
    RUN(test_bad_options);
    return sl_test_finish();
}
