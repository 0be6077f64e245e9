/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_merge: frames checked, sampled, response recovered, exposures checked,
 * then merged a strip at a time (merge_pass.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "merge_private.h"
#include "warp_reader.h"

enum { SAMPLE_TARGET = 65536, SAMPLE_STRIP = 64, RESPONSE_NODES = 256 };

void sl_merge_options_init(sl_merge_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->samples = 4000;
    opt->noise_gain = 2e-5;
    opt->noise_floor = 1e-6;
    opt->black = 0.004;
    opt->tolerance_stops = 0.2;
    opt->seed = 1;
    opt->deghost_sigma = 5;
    opt->deghost_model_error = 0.05;
    opt->align = SL_ALIGN_AUTO;
    opt->align_auto_px = 0.5;
    opt->align_max_shift = 64;
    opt->align_max_angle = 2;
    opt->compression = SL_EXR_ZIP;
    opt->hold_mb = 384;
}

void sl_merge_result_free(sl_merge_result *res)
{
    if (!res)
        return;
    sl_image_free(&res->radiance);
    sl_image_free(&res->clipped);
    sl_image_free(&res->ghost);
    sl_response_free(&res->response);
    for (int i = 0; i < res->frame_count; i++)
        free(res->frames[i].path);
    free(res->frames);
    memset(res, 0, sizeof *res);
}

static int cmp_rank(const void *a, const void *b, void *ctx)
{
    const sl_merge_frame *f = ctx;
    double x = f[*(const int *)a].exif_exposure, y = f[*(const int *)b].exif_exposure;
    return (x > y) - (x < y);
}

/* Reads every frame's header; checks count, sizes, depths and exposures. */
static sl_result setup_frames(const char *const *paths, int count, const sl_merge_options *opt,
                              sl_merge_result *res, merge_ctx *m, sl_error *err)
{
    if (count < 2)
        return sl_error_set(err, SL_ERR_USAGE, "%s: a merge needs at least two frames",
                            count == 1 ? paths[0] : "(no frames)");
    if (count > MERGE_MAX_FRAMES)
        return sl_error_set(err, SL_ERR_USAGE, "%s: %d frames; a merge takes at most %d",
                            paths[count - 1], count, MERGE_MAX_FRAMES);
    res->frames = calloc((size_t)count, sizeof *res->frames);
    m->order = calloc((size_t)count, sizeof *m->order);
    m->block = calloc((size_t)count * 2, sizeof *m->block);
    if (!res->frames || !m->order || !m->block)
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    res->frame_count = count;
    bool all_n_iso = true;
    sl_result r = SL_OK;
    for (int i = 0; i < count && !r; i++) {
        sl_merge_frame *f = &res->frames[i];
        if (!(f->path = strdup(paths[i])))
            return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
        sl_photo_strips *rd;
        sl_photo_strip_info info;
        sl_meta meta;
        sl_meta_init(&meta);
        int w, h, ch;
        r = sl_photo_read_meta(paths[i], &meta, &w, &h, &ch, err);
        if (!r)
            r = sl_photo_strips_open(paths[i], &rd, &info, err);
        if (r) {
            sl_meta_free(&meta);
            break;
        }
        sl_photo_strips_close(rd);
        m->block[2 * i] = info.block_w;
        m->block[2 * i + 1] = info.block_h;
        m->marked_linear = (i == 0 || m->marked_linear) && sl_file_is_scene_linear(&meta);
        m->lossless = (i == 0 || m->lossless) && info.lossless;
        f->exif_time = meta.exposure_time;
        f->f_number = meta.f_number;
        f->iso = meta.iso;
        int orientation = meta.orientation;
        r = merge_lens_exif(paths, i, &meta, res, err);
        sl_meta_free(&meta);
        if (r)
            break;
        if (i == 0) {
            m->width = info.width;
            m->height = info.height;
            m->bits = info.bits;
            m->is_float = info.is_float;
            m->code_bytes = info.code_bytes;
            m->orientation = orientation;
            if (info.width < 4 || info.height < 4)
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: %dx%d is too small to merge (at least 4x4)", paths[i],
                                    info.width, info.height);
        } else if (info.width != m->width || info.height != m->height)
            return sl_error_set(err, SL_ERR_INPUT, "%s: %dx%d, but %s is %dx%d (frames differ in size)",
                                paths[i], info.width, info.height, paths[0], m->width, m->height);
        else if (orientation != m->orientation)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: EXIF orientation %d, but %s has %d (frames differ in "
                                "orientation)",
                                paths[i], orientation, paths[0], m->orientation);
        else if (info.bits != m->bits || info.is_float != m->is_float ||
                 info.code_bytes != m->code_bytes)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: %d-bit%s samples, but %s has %d-bit%s (mixed bit depths)",
                                paths[i], info.bits, info.is_float ? " float" : "", paths[0],
                                m->bits, m->is_float ? " float" : "");
        if (opt->times) {
            if (!(opt->times[i] > 0) || !isfinite(opt->times[i]))
                return sl_error_set(err, SL_ERR_USAGE, "%s: exposure time %g is not positive",
                                    paths[i], opt->times[i]);
            f->time = opt->times[i];
        } else if (f->exif_time > 0 && isfinite(f->exif_time))
            f->time = f->exif_time;
        else
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: no exposure time in EXIF (give --times)", paths[i]);
        if (opt->absolute && !(f->f_number > 0 && f->iso > 0))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: no %s in EXIF: absolute units need the f-number and ISO "
                                "of every frame",
                                paths[i], f->f_number > 0 ? "ISO" : "f-number");
        all_n_iso = all_n_iso && f->f_number > 0 && f->iso > 0;
    }
    if (r)
        return r;
    if (!m->is_float && m->bits > 16)
        m->is_float = true; /* 32-bit integer samples: no lookup table */
    for (int i = 0; i < count; i++) {
        sl_merge_frame *f = &res->frames[i];
        f->exif_exposure = all_n_iso ? f->time * f->iso / (f->f_number * f->f_number) : f->time;
        m->order[i] = i;
    }
    qsort_r(m->order, (size_t)count, sizeof *m->order, cmp_rank, res->frames);
    for (int q = 0; q < count; q++) {
        res->frames[m->order[q]].rank = q;
        if (q == 0)
            continue;
        const sl_merge_frame *a = &res->frames[m->order[q - 1]], *b = &res->frames[m->order[q]];
        if (b->exif_exposure <= a->exif_exposure * (1 + 1e-6))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: same exposure as %s (%g s at f/%g ISO %g): duplicate "
                                "exposure times",
                                b->path, a->path, b->time, b->f_number, b->iso);
    }
    return SL_OK;
}

/* Registers the frames (ordered by the exposures EXIF or --times give);
 * the misalignment is the registered frames' largest displacement. */
static sl_result align_frames(const char *const *paths, int count, const sl_merge_options *opt,
                              sl_merge_result *res, sl_error *err)
{
    merge_clock clock = merge_clock_start();
    double e[MERGE_MAX_FRAMES] = {0};
    sl_align_transform t[MERGE_MAX_FRAMES];
    for (int i = 0; i < count; i++)
        e[i] = res->frames[i].exif_exposure;
    sl_result r = sl_align_bracket(paths, count, e, opt, t, err);
    res->misalignment_px = 0;
    for (int i = 0; i < count && !r; i++) {
        res->frames[i].align = t[i];
        res->aligned = res->aligned || t[i].applied;
        if (!t[i].refused)
            res->misalignment_px = fmax(res->misalignment_px, sl_align_displacement(&t[i], res->width, res->height));
    }
    merge_clock_charge(&res->timing, clock, SL_MERGE_ALIGN);
    return r;
}

static const char *base_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

/* The frames' largest displacement and the largest counted one (beyond
 * twice the spread: sl_align_sure_displacement), with their frames (-1:
 * none), over the frames not refused and not `skip`. */
typedef struct largest_motion {
    double moved, counted;
    int worst, sure;
} largest_motion;

static largest_motion find_largest_motion(const sl_merge_result *res, int skip)
{
    largest_motion l = {-1, 0, -1, -1};
    for (int i = 0; i < res->frame_count; i++) {
        const sl_align_transform *t = &res->frames[i].align;
        if (t->refused || i == skip)
            continue;
        double d = sl_align_displacement(t, res->width, res->height);
        double c = sl_align_sure_displacement(t, res->width, res->height);
        if (d > l.moved) {
            l.moved = d;
            l.worst = i;
        }
        if (c > l.counted) {
            l.counted = c;
            l.sure = i;
        }
    }
    return l;
}

/* SL_ALIGN_AUTO, after registering: the registration's own estimates must
 * show the motion the quick measurement saw (a frame moved beyond twice its
 * spread and the threshold), or no frame is resampled. On a sky over a
 * horizon the measurement of a dark frame can find tens of pixels along the
 * horizon where the registration, with more rounds of the tone map, finds a
 * doubtful few (docs/merge.md "Alignment"); resampling a still frame by them
 * would move its sun. */
static void keep_confirmed_registration(sl_merge_result *res, const char *const *paths,
                                        double measured, double auto_px)
{
    /* Frames left as they are (the reference among them) sit within 0.05 px:
     * the largest motion is an applied frame's whenever one was. */
    largest_motion l = find_largest_motion(res, -1);
    if (l.sure >= 0 && l.counted > auto_px)
        return;
    bool resampling = res->aligned;
    for (int i = 0; i < res->frame_count; i++)
        res->frames[i].align.applied = false;
    res->aligned = false;
    res->misalignment_px = resampling ? l.moved : measured; /* the closer look's */
    if (!resampling)
        snprintf(res->align_note, sizeof res->align_note,
                 "auto: measured %.2f px, but registration found nothing to resample: merged as "
                 "shot",
                 measured);
    else
        snprintf(res->align_note, sizeof res->align_note,
                 "auto: measured %.2f px; registered, %.32s moves %.2f px, spread %.2f px "
                 "(not beyond twice it and %.2g px): merged as shot",
                 measured, base_name(paths[l.worst]), l.moved,
                 res->frames[l.worst].align.shift_spread_px, auto_px);
}

/* SL_ALIGN_AUTO after the first sample pass: the misalignment measured on
 * the planes that pass filled, and whether it calls for registration. */
static sl_result measure_alignment(merge_ctx *m, const char *const *paths,
                                   const sl_merge_options *opt, sl_merge_result *res,
                                   bool *needed, sl_error *err)
{
    merge_clock clock = merge_clock_start();
    int count = res->frame_count, scale = m->measure[0].scale;
    double e[MERGE_MAX_FRAMES] = {0};
    sl_align_transform t[MERGE_MAX_FRAMES];
    for (int i = 0; i < count; i++)
        e[i] = res->frames[i].exif_exposure;
    sl_result r = align_measure(m->measure, count, paths, e, opt, m->width, m->height, t, err);
    for (int i = 0; i < count; i++)
        align_plane_free(&m->measure[i]);
    free(m->measure);
    m->measure = NULL;
    merge_clock_charge(&res->timing, clock, SL_MERGE_ALIGN);
    if (r)
        return r;
    /* A frame counts as moved by the motion beyond twice its spread only:
     * resampling blurs, and smooth content can fake a shift (docs/merge.md,
     * "Alignment"). worst: the largest displacement; sure: the largest
     * counted one. */
    for (int i = 0; i < count; i++) {
        t[i].applied = false;
        res->frames[i].align = t[i];
    }
    largest_motion l = find_largest_motion(res, m->order[(count - 1) / 2]);
    int worst = l.worst, sure = l.sure;
    double moved = l.moved, counted = l.counted;
    res->misalignment_px = moved;
    *needed = counted > opt->align_auto_px;
    if (worst < 0)
        snprintf(res->align_note, sizeof res->align_note,
                 "auto: misalignment not measurable (too few pixels well exposed in "
                 "neighbouring frames): merged as shot");
    else if (*needed)
        snprintf(res->align_note, sizeof res->align_note,
                 "auto: %.40s moved %.2f px (measured at 1/%d size; above %.2g px): registered",
                 base_name(paths[sure]), counted, scale, opt->align_auto_px);
    else if (moved > opt->align_auto_px)
        snprintf(res->align_note, sizeof res->align_note,
                 "auto: %.32s seems moved %.2f px, within twice the fit's spread (%.2f px, "
                 "%.3f deg: little texture?): merged as shot",
                 base_name(paths[worst]), moved, t[worst].shift_spread_px,
                 t[worst].angle_spread_deg);
    else
        snprintf(res->align_note, sizeof res->align_note,
                 "auto: frames within %.2f px of the reference (measured at 1/%d size; at most "
                 "%.2g px): merged as shot",
                 moved, scale, opt->align_auto_px);
    for (int i = 0; i < count && !*needed; i++)
        if (!res->frames[i].align.note[0])
            snprintf(res->frames[i].align.note, sizeof res->frames[i].align.note,
                     "not resampled: bracket within %.2g px", opt->align_auto_px);
    return SL_OK;
}

/* Integer frames that need no warp are read as codes (no float conversion),
 * classified through a table. */
static sl_result choose_codes(merge_ctx *m, const sl_merge_result *res, sl_error *err)
{
    m->codes = m->code_bytes > 0 && !m->is_float;
    for (int i = 0; i < res->frame_count; i++)
        m->codes = m->codes && !res->frames[i].align.applied;
    if (!m->codes)
        return SL_OK;
    int n = m->code_bytes == 1 ? 256 : 65536;
    if (!(m->code_class = malloc((size_t)n)))
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    float scale = 1.0f / (float)(n - 1);
    for (int q = 0; q < n; q++) {
        float z = (float)q * scale;
        m->code_class[q] = (uint8_t)((z >= m->saturation) | (z <= m->black) << 1);
    }
    return SL_OK;
}

/* Integer frames (read as codes) kept whole from the sample pass for the
 * merge pass, as many as fit the budget: the merge then decodes only the
 * others. 384 MB holds five 24-megapixel 8-bit frames, within 0.6 GB. */
static sl_result hold_frames(merge_ctx *m, sl_merge_result *res, double budget_mb, sl_error *err)
{
    if (!m->codes || !(budget_mb > 0))
        return SL_OK;
    if (!(m->held = calloc((size_t)res->frame_count, sizeof *m->held)))
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    m->held_slots = res->frame_count;
    size_t frame = (size_t)m->width * (size_t)m->height * 3 * (size_t)m->code_bytes;
    double left = budget_mb * 1e6;
    for (int i = 0; i < res->frame_count && left >= (double)frame; i++) {
        /* Not fitting in memory after all is no failure: that frame is decoded
         * twice. Huge pages: faulting the held frames in 4 kB pages cost the
         * kernel about 0.2 CPU s. */
        size_t align = (size_t)2 << 20, bytes = (frame + align - 1) / align * align;
        void *held = NULL;
        if (posix_memalign(&held, align, bytes))
            break;
#ifdef MADV_HUGEPAGE
        madvise(held, bytes, MADV_HUGEPAGE);
#endif
        m->held[i] = held;
        left -= (double)frame;
        res->held_frames++;
    }
    return SL_OK;
}

/* Sample positions: one jittered pixel per cell of a grid over the frame. */
static sl_result choose_positions(merge_ctx *m, const sl_merge_result *res, uint64_t seed,
                                  sl_error *err)
{
    int64_t pixels = (int64_t)m->width * m->height;
    int gw, gh;
    if (pixels <= SAMPLE_TARGET) {
        gw = m->width;
        gh = m->height;
    } else {
        gw = (int)ceil(sqrt((double)SAMPLE_TARGET * m->width / m->height));
        gw = gw > m->width ? m->width : gw;
        gh = SAMPLE_TARGET / gw;
        gh = gh > m->height ? m->height : gh < 1 ? 1 : gh;
    }
    m->samples.count = gw * gh;
    m->sample_pos = malloc((size_t)m->samples.count * sizeof *m->sample_pos);
    if (!m->sample_pos)
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    uint64_t state = seed;
    int n = 0;
    for (int cy = 0; cy < gh; cy++) {
        int y0 = (int)((int64_t)cy * m->height / gh), y1 = (int)((int64_t)(cy + 1) * m->height / gh);
        for (int cx = 0; cx < gw; cx++) {
            int x0 = (int)((int64_t)cx * m->width / gw), x1 = (int)((int64_t)(cx + 1) * m->width / gw);
            int x = x0 + (int)(sl_splitmix64(&state) % (uint64_t)(x1 - x0));
            int y = y0 + (int)(sl_splitmix64(&state) % (uint64_t)(y1 - y0));
            /* Where an aligned frame does not reach, its edge is repeated: no sample there. */
            bool covered = true;
            for (int i = 0; i < res->frame_count && covered; i++)
                covered = merge_frame_covers(&res->frames[i].align, m->width, m->height, x, y);
            if (covered)
                m->sample_pos[n++] = (int64_t)y * m->width + x;
        }
    }
    m->samples.count = n;
    /* Cells in one grid row may pick different rows: sort so strips meet them in order. */
    for (int i = 1; i < n; i++) {
        int64_t v = m->sample_pos[i];
        int j = i - 1;
        while (j >= 0 && m->sample_pos[j] > v) {
            m->sample_pos[j + 1] = m->sample_pos[j];
            j--;
        }
        m->sample_pos[j + 1] = v;
    }
    return SL_OK;
}

typedef struct sample_job {
    merge_ctx *m;
    sl_merge_result *res;
    sl_error *errs;
    sl_result *results;
    double *task_cpu; /* per worker and phase: CPU seconds of its tasks */
} sample_job;

/* sample_frame's counts over 8-bit codes (cls: code_class, thresholds on
 * the code: saturated from one code up, black up to one), five pixels per
 * 16-byte load: the brightest and darkest channel of each pixel compared
 * with the thresholds. Returns how many pixels it counted (the caller
 * counts the rest); the same counts as the per-pixel table lookups. */
static int64_t count_classes_u8(const uint8_t *q, int64_t n, const uint8_t *cls, int64_t *sat,
                                int64_t *white, int64_t *black)
{
    int64_t p = 0;
#ifdef __SSE2__
    int s = 0, b = -1;
    while (s < 256 && !(cls[s] & 1))
        s++;
    while (b < 255 && cls[b + 1] & 2)
        b++;
    if (s > 255 || b < 0)
        return 0;
    const __m128i vs = _mm_set1_epi8((char)s), vb = _mm_set1_epi8((char)b);
    /* Byte counters at each pixel's first channel (0, 3, 6, 9, 12), summed
     * out before they can overflow. */
    const __m128i first = _mm_setr_epi8(1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 0);
    int64_t ns = 0, nw = 0, nb = 0;
    while (p * 3 + 16 <= n * 3) {
        __m128i cs = _mm_setzero_si128(), cw = cs, cb = cs;
        for (int k = 0; k < 255 && p * 3 + 16 <= n * 3; k++, p += 5, q += 15) {
            __m128i v = _mm_loadu_si128((const __m128i *)q), v1 = _mm_srli_si128(v, 1),
                    v2 = _mm_srli_si128(v, 2);
            __m128i hi = _mm_max_epu8(v, _mm_max_epu8(v1, v2)),
                    lo = _mm_min_epu8(v, _mm_min_epu8(v1, v2));
            cs = _mm_add_epi8(cs, _mm_and_si128(_mm_cmpeq_epi8(_mm_max_epu8(hi, vs), hi), first));
            cw = _mm_add_epi8(cw, _mm_and_si128(_mm_cmpeq_epi8(_mm_max_epu8(lo, vs), lo), first));
            cb = _mm_add_epi8(cb, _mm_and_si128(_mm_cmpeq_epi8(_mm_min_epu8(hi, vb), hi), first));
        }
        __m128i zero = _mm_setzero_si128(), t;
        t = _mm_sad_epu8(cs, zero);
        ns += _mm_cvtsi128_si32(t) + _mm_cvtsi128_si32(_mm_srli_si128(t, 8));
        t = _mm_sad_epu8(cw, zero);
        nw += _mm_cvtsi128_si32(t) + _mm_cvtsi128_si32(_mm_srli_si128(t, 8));
        t = _mm_sad_epu8(cb, zero);
        nb += _mm_cvtsi128_si32(t) + _mm_cvtsi128_si32(_mm_srli_si128(t, 8));
    }
    *sat += ns;
    *white += nw;
    *black += nb;
#else
    (void)q, (void)n, (void)cls, (void)sat, (void)white, (void)black;
#endif
    return p;
}

/* One frame: reads it strip by strip, keeps the sample positions' values
 * and counts saturated, black and white pixels. */
static void sample_frame(void *ctx, int64_t begin, int64_t end, int worker)
{
    sample_job *job = ctx;
    double *task_cpu = job->task_cpu + (size_t)worker * SL_MERGE_PHASES, t0 = sl_thread_cpu_seconds();
    double decode = 0, measure = 0;
    merge_ctx *m = job->m;
    int cb = m->codes ? m->code_bytes : 0;
    float code_scale = cb ? 1.0f / (cb == 1 ? 255.0f : 65535.0f) : 0;
    for (int64_t i = begin; i < end; i++) {
        sl_merge_frame *f = &job->res->frames[i];
        int rank = f->rank, w = m->width;
        merge_frame_reader *rd = NULL;
        size_t bytes = (size_t)SAMPLE_STRIP * w * 3 * (cb ? (size_t)cb : sizeof(float));
        void *buf = malloc(bytes);
        sl_result r = buf ? merge_frame_open(f->path, &f->align, SAMPLE_STRIP, &rd, &job->errs[i])
                          : sl_error_set(&job->errs[i], SL_ERR_NOMEM, "merge: out of memory");
        int64_t sat = 0, black = 0, white = 0;
        int s = 0;
        float *bmax = m->block_max[i];
        int bw = m->block[2 * i], bh = m->block[2 * i + 1], nbx = bw ? (w + bw - 1) / bw : 0;
        for (int y0 = 0; y0 < m->height && !r; y0 += SAMPLE_STRIP) {
            int y1 = y0 + SAMPLE_STRIP < m->height ? y0 + SAMPLE_STRIP : m->height;
            /* A held frame is decoded straight into its place. */
            void *strip = m->held && m->held[i] ? m->held[i] + (size_t)y0 * w * 3 * cb : buf;
            double t = sl_thread_cpu_seconds();
            r = cb ? merge_frame_read_codes(rd, y0, y1, strip, &job->errs[i])
                   : merge_frame_read(rd, y0, y1, strip, &job->errs[i]);
            decode += sl_thread_cpu_seconds() - t;
            if (r)
                break;
            if (m->measure) {
                t = sl_thread_cpu_seconds();
                align_plane_add(&m->measure[i], strip, cb, w, y0, y1, m->black, m->saturation);
                measure += sl_thread_cpu_seconds() - t;
            }
            int64_t n = (int64_t)(y1 - y0) * w;
            const uint8_t *cls = m->code_class;
            if (cb == 1) {
                const uint8_t *q = strip;
                int64_t p = count_classes_u8(q, n, cls, &sat, &white, &black);
                for (q += p * 3; p < n; p++, q += 3) {
                    int any = cls[q[0]] | cls[q[1]] | cls[q[2]], all = cls[q[0]] & cls[q[1]] & cls[q[2]];
                    sat += any & 1;
                    white += all & 1;
                    black += all >> 1;
                }
            } else
                for (int64_t p = 0; p < n; p++) {
                    int k[3];
                    for (int c = 0; c < 3; c++) {
                        float v = cb ? 0 : ((const float *)strip)[p * 3 + c];
                        k[c] = cb ? cls[merge_code(strip, cb, (size_t)p * 3 + c)]
                                  : (v >= m->saturation) | (v <= m->black) << 1;
                    }
                    int any = k[0] | k[1] | k[2], all = k[0] & k[1] & k[2];
                    sat += any & 1;
                    white += all & 1;
                    black += all >> 1;
                }
            /* SAMPLE_STRIP is a multiple of every JPEG block height: strips start on a block row. */
            if (bmax)
                merge_block_max(strip, cb, cb == 1 ? 255 : 65535, w, y1 - y0, bw, bh,
                                bmax + (size_t)(y0 / bh) * nbx);
            int64_t end_pos = (int64_t)y1 * w;
            for (; s < m->samples.count && m->sample_pos[s] < end_pos; s++) {
                size_t at = (size_t)(m->sample_pos[s] - (int64_t)y0 * w) * 3;
                float *dst = m->samples.z + ((size_t)s * m->samples.frames + rank) * 3;
                for (int c = 0; c < 3; c++) {
                    float v = cb ? (float)merge_code(strip, cb, at + c) * code_scale
                                 : ((const float *)strip)[at + c];
                    dst[c] = isfinite(v) ? v : 0.0f;
                }
            }
        }
        merge_frame_close(rd);
        free(buf);
        job->results[i] = r;
        double pixels = (double)m->width * m->height;
        f->saturated_fraction = sat / pixels;
        f->black_fraction = black / pixels;
        m->white_pixels[i] = white;
    }
    task_cpu[SL_MERGE_DECODE] += decode;
    task_cpu[SL_MERGE_ALIGN] += measure;
    task_cpu[SL_MERGE_SAMPLE] += sl_thread_cpu_seconds() - t0 - decode - measure;
}

static sl_result sample_pass(merge_ctx *m, sl_merge_result *res, sl_error *err)
{
    int count = res->frame_count;
    m->samples.frames = count;
    m->samples.code_step =
        m->is_float || m->bits < 1 || m->bits > 16 ? 0 : 1.0 / ((1 << m->bits) - 1);
    m->samples.z = calloc((size_t)m->samples.count * count * 3, sizeof *m->samples.z);
    m->samples.spoilt = calloc((size_t)m->samples.count * count, 1);
    for (int i = 0; i < count; i++)
        m->samples.coded = m->samples.coded || m->block[2 * i];
    m->white_pixels = calloc((size_t)count, sizeof *m->white_pixels);
    m->block_max = calloc((size_t)count, sizeof *m->block_max);
    for (int i = 0; i < count && m->block_max; i++) {
        /* A moved frame's blocks are not on the output grid: not judged. */
        int bw = m->block[2 * i], bh = m->block[2 * i + 1];
        if (bw && !res->frames[i].align.applied &&
            !(m->block_max[i] = malloc((size_t)((m->width + bw - 1) / bw) *
                                       (size_t)((m->height + bh - 1) / bh) * sizeof(float))))
            break;
    }
    sl_error *errs = calloc((size_t)count, sizeof *errs);
    sl_result *results = calloc((size_t)count, sizeof *results);
    int threads = sl_threads_get();
    double *task_cpu = calloc((size_t)threads * SL_MERGE_PHASES, sizeof *task_cpu);
    sl_result r = SL_OK;
    bool blocks = m->block_max != NULL;
    for (int i = 0; i < count && blocks; i++)
        blocks = !m->block[2 * i] || res->frames[i].align.applied || m->block_max[i];
    if (!m->samples.z || !m->samples.spoilt || !m->white_pixels || !blocks || !errs || !results ||
        !task_cpu)
        r = sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    if (!r) {
        sample_job job = {m, res, errs, results, task_cpu};
        merge_clock clock = merge_clock_start();
        sl_parallel_for(count, 1, sample_frame, &job);
        merge_clock_split(&res->timing, clock, task_cpu, threads);
        for (int i = 0; i < count && !r; i++)
            if ((r = results[i]) && err)
                *err = errs[i];
    }
    free(errs);
    free(results);
    free(task_cpu);
    if (r)
        return r;
    bool all_black = true, all_white = true;
    for (int i = 0; i < count; i++) {
        all_black = all_black && res->frames[i].black_fraction >= 1;
        all_white = all_white && m->white_pixels[i] == (int64_t)m->width * m->height;
    }
    if (all_black)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s .. %s: every frame is black (no value above %g)", res->frames[0].path,
                            res->frames[count - 1].path, m->black);
    if (all_white)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s .. %s: every frame is saturated (no value below %g)",
                            res->frames[0].path, res->frames[count - 1].path, m->saturation);
    return SL_OK;
}

static double median_inplace(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, sl_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Robust line y = a + g x (Theil-Sen: median of pairwise slopes, then the
 * median intercept); g = 1 when not fitted or too few points. */
static void robust_line(const double *x, const double *y, int n, bool fit_slope, double *a,
                        double *g, double *scratch)
{
    *g = 1;
    int k = 0;
    if (fit_slope && n >= 3) {
        for (int i = 0; i < n; i++)
            for (int j = i + 1; j < n; j++)
                if (x[j] != x[i])
                    scratch[k++] = (y[j] - y[i]) / (x[j] - x[i]);
        if (k)
            *g = median_inplace(scratch, k);
        if (!(*g > 0.1))
            *g = 1;
    }
    for (int i = 0; i < n; i++)
        scratch[i] = y[i] - *g * x[i];
    *a = median_inplace(scratch, n);
}

/* Fits neighbour ratios, chains them into exposures and compares with EXIF.
 * Each run of fitted ratios is put on the EXIF scale by a robust line
 * through (EXIF, fitted) log exposures, so one lying frame stands out
 * instead of moving the others. With a recovered response the line's slope
 * is fitted too: curve and exposures are only known up to a common power
 * (Grossberg and Nayar), which EXIF, taken as mostly right, pins down. */
static void check_exposures(merge_ctx *m, sl_merge_result *res, const sl_merge_options *opt)
{
    int count = res->frame_count;
    double *ratio = m->ratio;
    double log_exif[MERGE_MAX_FRAMES] = {0};
    for (int k = 0; k < count; k++)
        log_exif[k] = log(res->frames[m->order[k]].exif_exposure);
    res->fitted_ratios = merge_fit_ratios(&m->samples, &res->response, m->black, m->saturation,
                                          log_exif, ratio);
    res->disagreeing_frames = 0;
    bool fit_slope = opt->response_mode == SL_RESPONSE_AUTO ||
                     opt->response_mode == SL_RESPONSE_ROBERTSON;
    int q = 0;
    while (q < count) {
        int end = q; /* run [q, end]: ratios q..end-1 all fitted */
        while (end + 1 < count && ratio[end] > 0)
            end++;
        int n = end - q + 1;
        double lf = 0, *lx = m->offsets;
        for (int k = q; k <= end; k++) {
            if (k > q)
                lf += log(ratio[k - 1]);
            m->log_fit[k] = lf;
            lx[k - q] = log(res->frames[m->order[k]].exif_exposure);
        }
        double a = 0, g = 1;
        if (n >= 2)
            robust_line(lx, m->log_fit + q, n, fit_slope, &a, &g, m->scratch);
        /* The frames this line names are outliers: the line is fitted again
         * without them, so a lie does not tilt it (a median of pairwise
         * slopes still leans towards the slopes the lying frame is in). If
         * the new line names a frame the first one kept, the data were
         * noisy rather than one frame lying: the first line stays. */
        double tol = opt->tolerance_stops * log(2), ky[MERGE_MAX_FRAMES], kx[MERGE_MAX_FRAMES];
        int kept = 0;
        for (int k = q; k <= end && n >= 2; k++)
            if (fabs((m->log_fit[k] - a) / g - lx[k - q]) <= tol) {
                ky[kept] = m->log_fit[k];
                kx[kept++] = lx[k - q];
            }
        if (kept >= 2 && kept < n) {
            double a2, g2;
            robust_line(kx, ky, kept, fit_slope, &a2, &g2, m->scratch);
            bool same = true;
            for (int k = 0; k < kept; k++)
                same = same && fabs((ky[k] - a2) / g2 - kx[k]) <= tol;
            if (same) {
                a = a2;
                g = g2;
            }
        }
        for (int k = q; k <= end; k++) {
            sl_merge_frame *f = &res->frames[m->order[k]];
            if (n < 2) {
                f->fitted_exposure = 0;
                f->disagreement_stops = 0;
                f->disagrees = false;
                continue;
            }
            f->fitted_exposure = exp((m->log_fit[k] - a) / g);
            f->disagreement_stops = log2(f->fitted_exposure / f->exif_exposure);
            f->disagrees = fabs(f->disagreement_stops) > opt->tolerance_stops;
            res->disagreeing_frames += f->disagrees;
        }
        q = end + 1;
    }
    for (int i = 0; i < count; i++) {
        sl_merge_frame *f = &res->frames[i];
        f->exposure = opt->exposures == SL_EXPOSURES_DATA && f->fitted_exposure > 0
                          ? f->fitted_exposure
                          : f->exif_exposure;
    }
}

/* The exposure a frame's curve is fitted with: EXIF, or with use_fitted
 * the measured one. Lossless frames take the measured one only where the
 * check names the frame: a step is measured where the shorter frame reads
 * low, noisy codes, the codes the curve is least sure of, so an honest
 * frame's measured exposure repeats the curve's own error there and the
 * curve fitted to it keeps it (the DoRF curves through a 4000-electron
 * sensor: shortest frames measured 0.03-0.5 stops off; "Real camera
 * curves" in docs/merge.md). JPEG frames take every measured one: each
 * frame's coding (chroma bleed around its clipped areas) moves its codes
 * its own way, and a measured exposure absorbs that (the stage's 5x2 JPEG
 * curve 1.2% off this way, 8% with EXIF). */
static double curve_exposure(const merge_ctx *m, const sl_merge_frame *f, bool use_fitted)
{
    return use_fitted && f->fitted_exposure > 0 && (m->samples.coded || f->disagrees)
               ? f->fitted_exposure
               : f->exif_exposure;
}

/* Marks each frame's samples whose JPEG block is spoilt by a clipped pixel
 * (merge_block_spoilt), judged through resp and the exposures (fitted ones
 * when asked and known), for the exposure check and the response fit. The
 * first curve is fitted before any is known, from every sample; the later
 * rounds leave the spoilt ones out. */
static void mark_spoilt(merge_ctx *m, const sl_merge_result *res, const sl_response *resp,
                        bool use_fitted)
{
    int f = res->frame_count;
    bool any = false;
    double loge[MERGE_MAX_FRAMES];
    for (int q = 0; q < f; q++) {
        const sl_merge_frame *fr = &res->frames[m->order[q]];
        loge[q] = log(curve_exposure(m, fr, use_fitted));
        any = any || m->block_max[m->order[q]];
    }
    if (!any)
        return;
    /* The blocks' codes once (the rounds change only the curve and the
     * exposures): finding them was a tenth of a small JPEG bracket's fit. */
    size_t n = (size_t)m->samples.count * (size_t)f;
    if (!m->spoil_codes && (m->spoil_codes = malloc(n * 2 * sizeof *m->spoil_codes)))
        for (int i = 0; i < m->samples.count; i++)
            for (int q = 0; q < f; q++)
                merge_block_codes(m, q, m->sample_pos[i], m->spoil_codes + 2 * ((size_t)i * f + q));
    if (m->spoil_codes) {
        merge_block_spoilt_all(m, resp, loge, m->spoil_codes, m->samples.spoilt);
        return;
    }
    for (int i = 0; i < m->samples.count; i++)
        for (int q = 0; q < f; q++)
            m->samples.spoilt[(size_t)i * f + q] = merge_block_spoilt(m, resp, loge, q, m->sample_pos[i]);
}

/* The curve-shape prior's strength against the fit's rows (their weight per
 * unit of likelihood under the noise model), chosen by cross-validation on
 * the DoRF curves with each curve's family left out of its prior
 * (docs/merge.md "Real camera curves"). Far above 1: the default noise
 * model (a 50000-electron well) and the bias noise puts into the fitted
 * curve make the rows look surer than they are. */
#define PRIOR_WEIGHT 1000
/* The prior is dropped when the curve fitted without it is further from it
 * than this (sl_response_prior_distance): a camera unlike the curves it was
 * made of. DoRF's curves fitted with their own family left out of the
 * prior: median 0.42, at most 4.4 but for gamma+0.2 (43); a hybrid
 * log-gamma curve: 7.9 and 19 (test_merge_crf, bench_merge_crf). */
#define PRIOR_FAR 6
/* Sample positions the refinement under the noise reads (three series each). */
#define REFINE_POSITIONS 2000

/* The self-calibrated curve refined by maximum likelihood under the
 * sensor's noise (response_ml.c), with the exposures it was fitted with. */
static sl_result refine_response(merge_ctx *m, sl_merge_result *res, const sl_merge_options *opt,
                                 const double *loge, sl_error *err)
{
    res->response_refined = false;
    snprintf(res->response_refine_note, sizeof res->response_refine_note, "%s",
             opt->response_mode == SL_RESPONSE_ROBERTSON ? "robertson: not refined"
                                                         : "not refined (not asked)");
    if (opt->response_mode == SL_RESPONSE_ROBERTSON || !opt->refine_response)
        return SL_OK;
    merge_refine_report rep;
    sl_result r = merge_refine_response(&m->samples, loge, REFINE_POSITIONS, &res->response,
                                        &rep, err);
    if (r)
        return r;
    res->response_refined = rep.refined;
    if (rep.refined) {
        char source[sizeof res->response.source];
        snprintf(source, sizeof source, "%.44s, refined", res->response.source);
        memcpy(res->response.source, source, sizeof source);
    }
    snprintf(res->response_refine_note, sizeof res->response_refine_note, "%s", rep.note);
    res->response_refine_series = rep.series;
    res->response_refine_gain_nats = rep.loglik - rep.start_loglik;
    res->response_refine_moved = rep.moved;
    for (int c = 0; c < 3; c++) {
        res->response_noise_gain[c] = rep.noise_gain[c];
        res->response_noise_floor[c] = rep.noise_floor[c];
    }
    return SL_OK;
}

static sl_result recover_response(merge_ctx *m, sl_merge_result *res, const sl_merge_options *opt,
                                  bool use_fitted, sl_error *err)
{
    double *loge = m->offsets;
    for (int q = 0; q < res->frame_count; q++) {
        const sl_merge_frame *f = &res->frames[m->order[q]];
        loge[q] = log(curve_exposure(m, f, use_fitted));
    }
    /* Wider steps leave more of the curve to smoothness: 10 at 3 stops, 5.4 at 2. */
    double lambda = opt->smoothness;
    if (lambda == 0) {
        double widest = 0;
        for (int q = 1; q < res->frame_count; q++)
            widest = fmax(widest, (loge[q] - loge[q - 1]) / log(2));
        lambda = 10 * pow(fmin(fmax(widest, 1), 4) / 3, 1.5);
    }
    sl_response fitted;
    if (opt->response_mode == SL_RESPONSE_ROBERTSON) {
        sl_result r = merge_fit_robertson(&m->samples, loge, RESPONSE_NODES, opt->samples,
                                          m->black, m->saturation, opt->seed, &fitted, err);
        if (r)
            return r;
    } else {
        sl_result r = merge_fit_response(&m->samples, loge, RESPONSE_NODES, lambda, opt->samples,
                                         m->black, m->saturation, opt->noise_gain,
                                         opt->noise_floor, opt->seed, NULL, 0, &fitted, err);
        if (r)
            return r;
        const sl_response_prior *prior = !opt->use_response_prior ? NULL
                                         : opt->response_prior     ? opt->response_prior
                                                                   : &merge_prior_dorf;
        res->response_prior[0] = 0;
        res->response_prior_dropped = false;
        res->response_prior_distance[0] = res->response_prior_distance[1] = 0;
        if (prior) {
            snprintf(res->response_prior, sizeof res->response_prior, "%s", prior->name);
            double far = sl_response_prior_distance(prior, &fitted, 0);
            res->response_prior_distance[0] = far;
            res->response_prior_dropped = !(far <= PRIOR_FAR);
            if (res->response_prior_dropped)
                snprintf(fitted.source, sizeof fitted.source,
                         "debevec-malik, prior %.12s dropped (curve far from it)", prior->name);
        }
        if (prior && !res->response_prior_dropped) {
            sl_response with;
            double w = opt->response_prior_weight > 0 ? opt->response_prior_weight : PRIOR_WEIGHT;
            r = merge_fit_response(&m->samples, loge, RESPONSE_NODES, lambda, opt->samples,
                                   m->black, m->saturation, opt->noise_gain, opt->noise_floor,
                                   opt->seed, prior, w, &with, err);
            if (r) {
                sl_response_free(&fitted);
                return r;
            }
            res->response_prior_distance[1] = sl_response_prior_distance(prior, &with, 0);
            sl_response_free(&fitted);
            fitted = with;
            snprintf(fitted.source, sizeof fitted.source, "debevec-malik, prior %.40s",
                     prior->name);
        }
    }
    sl_response_free(&res->response);
    res->response = fitted;
    /* Refined in every round: the exposures measured next are measured
     * through it (measured through the first curve's bends, they kept
     * agfa-scala-200xCDPush1 at 1.55x the ideal instead of 1.04x). */
    return refine_response(m, res, opt, loge, err);
}

/* Half (10-bit mantissa, largest 65504, normal down to 2^-14 then steps of
 * 2^-24) when it can hold every value the merge can make and its rounding
 * stays below a quarter of the noise model's deviation: relative rounding
 * (at most 2^-11, deviation 2^-11 / sqrt(3)) against the relative noise of
 * a sample at saturation averaged over every frame, and the step at the
 * bottom (2^-24, deviation 2^-24 / sqrt(12)) against the noise floor in the
 * longest frame. Float frames have no bound: float. */
static void choose_encoding(const merge_ctx *m, sl_merge_result *res, const sl_merge_options *opt)
{
    int f = res->frame_count;
    double e_short = res->frames[m->order[0]].exposure / res->output_exposure;
    double e_long = res->frames[m->order[f - 1]].exposure / res->output_exposure;
    double top = 0;
    for (int c = 0; c < 3; c++)
        top = fmax(top, sl_response_eval(&res->response, c, 1.0));
    res->max_value = m->is_float ? 0 : top / e_short;
    double rel_noise = sqrt(opt->noise_gain + opt->noise_floor) / sqrt(f);
    double abs_noise = sqrt(opt->noise_floor) / e_long;
    bool fits = res->max_value > 0 && res->max_value < 65504;
    bool fine = ldexp(1, -11) / sqrt(3) <= rel_noise / 4 && ldexp(1, -24) / sqrt(12) <= abs_noise / 4;
    res->compression = opt->compression;
    if (opt->pixels == SL_MERGE_PIXELS_HALF || opt->pixels == SL_MERGE_PIXELS_FLOAT) {
        res->pixel_type = opt->pixels == SL_MERGE_PIXELS_HALF ? SL_PIXEL_HALF : SL_PIXEL_FLOAT;
        snprintf(res->encoding_note, sizeof res->encoding_note, "%s as asked",
                 res->pixel_type == SL_PIXEL_HALF ? "half" : "float");
        return;
    }
    res->pixel_type = fits && fine ? SL_PIXEL_HALF : SL_PIXEL_FLOAT;
    if (m->is_float)
        snprintf(res->encoding_note, sizeof res->encoding_note, "float: float frames, no bound");
    else if (!fits)
        snprintf(res->encoding_note, sizeof res->encoding_note,
                 "float: values up to %.6g, beyond half's 65504", res->max_value);
    else
        snprintf(res->encoding_note, sizeof res->encoding_note,
                 "%s: values up to %.6g; half rounding %s a quarter of the noise",
                 fine ? "half" : "float", res->max_value, fine ? "below" : "above");
}

/* What only the fit needed, freed before the merge pass (its peak memory):
 * 17 MB on a 24-megapixel bracket of 7 (peak 546 -> 538 MB). */
static void release_samples(merge_ctx *m)
{
    free(m->sample_pos);
    free(m->samples.z);
    free(m->samples.spoilt);
    for (int i = 0; m->block_max && i < m->samples.frames; i++)
        free(m->block_max[i]);
    free(m->block_max);
    free(m->spoil_codes);
    m->spoil_codes = NULL;
    m->sample_pos = NULL;
    m->samples.z = NULL;
    m->samples.spoilt = NULL;
    m->block_max = NULL;
}

void merge_ctx_free(merge_ctx *m)
{
    free(m->order);
    free(m->code_class);
    for (int i = 0; i < m->held_slots; i++)
        free(m->held[i]);
    free(m->held);
    release_samples(m);
    free(m->block);
    free(m->white_pixels);
    free(m->ratio);
    free(m->offsets);
    free(m->log_fit);
    free(m->prev_fit);
    free(m->scratch);
    for (int i = 0; m->measure && i < m->measure_frames; i++)
        align_plane_free(&m->measure[i]);
    free(m->measure);
    memset(m, 0, sizeof *m);
}

/* Undoes the sample pass (and the codes and held frames it chose) for a
 * second pass over registered frames. */
static void reset_sample_pass(merge_ctx *m, sl_merge_result *res)
{
    release_samples(m);
    for (int i = 0; i < m->held_slots; i++)
        free(m->held[i]);
    free(m->held);
    free(m->code_class);
    free(m->white_pixels);
    m->held = NULL;
    m->held_slots = 0;
    m->code_class = NULL;
    m->white_pixels = NULL;
    res->held_frames = 0;
}

/* The frames' codes, held frames, sample positions and sample pass; with
 * `measure` the pass also fills the alignment measurement's planes. */
static sl_result sample_frames(merge_ctx *m, sl_merge_result *res, const sl_merge_options *opt,
                               bool hold, bool measure, sl_error *err)
{
    sl_result r = choose_codes(m, res, err);
    if (!r && hold)
        r = hold_frames(m, res, opt->hold_mb, err);
    if (!r)
        r = choose_positions(m, res, opt->seed, err);
    if (!r && measure) {
        if (!(m->measure = calloc((size_t)res->frame_count, sizeof *m->measure)))
            r = sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
        else
            m->measure_frames = res->frame_count;
        for (int i = 0; i < res->frame_count && !r; i++)
            r = align_plane_init(&m->measure[i], m->width, m->height, err);
    }
    if (!r)
        r = sample_pass(m, res, err);
    return r;
}

/* The saturation the frames call for when the options leave it 0. Frames
 * alignment has resampled are lossless codes no more: the resampling blends
 * a clipped pixel into its neighbours' codes below the clip code
 * (test_merge_align: at the clip code the aligned bracket's median error was
 * 4x the still one's). */
static void default_saturation_of(merge_ctx *m, sl_merge_options *opt, bool resampled)
{
    m->saturation = opt->saturation =
        merge_saturation_default(opt->response_mode, m->lossless && !resampled);
}

sl_result merge_prepare(const char *const *paths, int count, const sl_merge_options *opt_in,
                        bool hold, merge_ctx *m, sl_merge_result *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    memset(m, 0, sizeof *m);
    sl_merge_options opt = merge_options_or_default(opt_in);
    m->black = opt.black;
    if (!(opt.saturation == 0 || opt.saturation > opt.black + 0.1) || !(opt.black >= 0) ||
        !(opt.saturation <= 1) ||
        !(opt.noise_gain >= 0) || !(opt.noise_floor > 0) || !(opt.smoothness >= 0) ||
        opt.samples < 16 || !(opt.tolerance_stops > 0) || !(opt.deghost_sigma > 0) ||
        !(opt.deghost_model_error >= 0) || !(opt.align_auto_px >= 0) ||
        (opt.align != SL_ALIGN_OFF && opt.align != SL_ALIGN_ON && opt.align != SL_ALIGN_AUTO))
        return sl_error_set(err, SL_ERR_USAGE,
                            "merge: options out of range (0 <= black < saturation - 0.1, "
                            "saturation <= 1, noise floor > 0, smoothness >= 0, samples >= 16)");
    if (opt.response_mode == SL_RESPONSE_GIVEN && (!opt.response || opt.response->channels != 3))
        return sl_error_set(err, SL_ERR_USAGE, "merge: a given response needs three curves");
    sl_result r = setup_frames(paths, count, &opt, out, m, err);
    /* Frames whose files say they are linear (camera raw, a linear
     * export's ICC profile) need no curve: one fitted to them can only
     * add error. */
    bool linear_by_file = !r && opt.response_mode == SL_RESPONSE_AUTO && m->marked_linear && !m->is_float;
    if (linear_by_file)
        opt.response_mode = SL_RESPONSE_LINEAR;
    bool default_saturation = opt.saturation == 0;
    if (default_saturation)
        default_saturation_of(m, &opt, false);
    m->saturation = opt.saturation;
    if (!r && default_saturation && !(opt.saturation > opt.black + 0.1))
        r = sl_error_set(err, SL_ERR_USAGE,
                         "merge: --black %g is too close to the saturation code %g (0 <= black < "
                         "saturation - 0.1)",
                         opt.black, opt.saturation);
    bool recovered = opt.response_mode == SL_RESPONSE_AUTO || opt.response_mode == SL_RESPONSE_ROBERTSON;
    if (!r && m->is_float && recovered)
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: float samples are linear already: use --response linear", paths[0]);
    if (!r) {
        m->ratio = calloc((size_t)count, sizeof *m->ratio);
        m->offsets = calloc((size_t)count, sizeof *m->offsets);
        m->log_fit = calloc((size_t)count, sizeof *m->log_fit);
        m->prev_fit = calloc((size_t)count, sizeof *m->prev_fit);
        m->scratch = calloc((size_t)count * count, sizeof *m->scratch);
        if (!m->ratio || !m->offsets || !m->log_fit || !m->prev_fit || !m->scratch)
            r = sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    }
    out->align_mode = opt.align;
    out->misalignment_px = -1;
    out->width = m->width;
    out->height = m->height;
    if (!r && opt.align == SL_ALIGN_ON) {
        r = align_frames(paths, count, &opt, out, err);
        snprintf(out->align_note, sizeof out->align_note, "on: %s", out->aligned ? "registered" : "nothing to resample");
        if (default_saturation && out->aligned)
            default_saturation_of(m, &opt, true);
    } else if (opt.align == SL_ALIGN_OFF)
        snprintf(out->align_note, sizeof out->align_note, "off: not measured, merged as shot");
    if (!r)
        r = sample_frames(m, out, &opt, hold, opt.align == SL_ALIGN_AUTO, err);
    if (!r && opt.align == SL_ALIGN_AUTO) {
        bool needed = false;
        r = measure_alignment(m, paths, &opt, out, &needed, err);
        out->align_measure_cpu = out->timing.cpu[SL_MERGE_ALIGN];
        if (!r && needed) {
            double measured = out->misalignment_px;
            r = align_frames(paths, count, &opt, out, err);
            if (!r)
                keep_confirmed_registration(out, paths, measured, opt.align_auto_px);
            /* Resampled frames: samples, codes and held frames from them. */
            if (!r && out->aligned) {
                if (default_saturation)
                    default_saturation_of(m, &opt, true);
                reset_sample_pass(m, out);
                r = sample_frames(m, out, &opt, hold, false, err);
            }
        }
    }
    if (r)
        return r;
    merge_clock fit = merge_clock_start();
    switch (opt.response_mode) {
    case SL_RESPONSE_LINEAR:
        r = sl_response_linear(&out->response, RESPONSE_NODES, err);
        if (!r && linear_by_file)
            snprintf(out->response.source, sizeof out->response.source, "linear (as the files say)");
        break;
    case SL_RESPONSE_GIVEN:
        out->response.inverse = malloc((size_t)opt.response->nodes * 3 * sizeof(double));
        if (!out->response.inverse)
            return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
        memcpy(out->response.inverse, opt.response->inverse,
               (size_t)opt.response->nodes * 3 * sizeof(double));
        out->response.channels = 3;
        out->response.nodes = opt.response->nodes;
        memcpy(out->response.source, opt.response->source, sizeof out->response.source);
        break;
    case SL_RESPONSE_AUTO:
    case SL_RESPONSE_ROBERTSON:
        r = recover_response(m, out, &opt, false, err);
        break;
    }
    if (r)
        return r;
    mark_spoilt(m, out, &out->response, false);
    check_exposures(m, out, &opt);
    /* A recovered curve bends to fit whatever exposures it was given, so a
     * lying frame would hide in it: alternate the curve and the measured
     * exposures it takes (curve_exposure) until those settle (each round
     * removes most of the error; when it takes none the first curve stands). */
    for (int i = 0; i < count; i++)
        m->prev_fit[i] = out->frames[i].exif_exposure;
    for (int round = 0; round < 8 && recovered && out->fitted_ratios > 0; round++) {
        double moved = 0;
        for (int i = 0; i < count; i++)
            moved = fmax(moved, fabs(log2(curve_exposure(m, &out->frames[i], true) / m->prev_fit[i])));
        if (moved < 0.002)
            break;
        for (int i = 0; i < count; i++)
            m->prev_fit[i] = curve_exposure(m, &out->frames[i], true);
        mark_spoilt(m, out, &out->response, true);
        if ((r = recover_response(m, out, &opt, true, err)))
            return r;
        mark_spoilt(m, out, &out->response, true);
        check_exposures(m, out, &opt);
    }
    out->reference = m->order[(count - 1) / 2];
    out->bits = m->bits;
    out->noise_gain = opt.noise_gain;
    out->noise_floor = opt.noise_floor;
    out->black = opt.black;
    out->saturation = opt.saturation;
    out->absolute = opt.absolute;
    out->output_exposure = opt.absolute ? SL_MERGE_K_SAT : out->frames[out->reference].exposure;
    out->width = m->width;
    out->height = m->height;
    choose_encoding(m, out, &opt);
    merge_judge_response(m, out, recovered);
    release_samples(m);
    merge_clock_charge(&out->timing, fit, SL_MERGE_FIT);
    return SL_OK;
}

sl_result sl_merge_response(const char *const *paths, int count, const sl_merge_options *opt,
                            sl_merge_result *out, sl_error *err)
{
    merge_clock t0 = merge_clock_start();
    merge_ctx m;
    sl_result r = merge_prepare(paths, count, opt, false, &m, out, err);
    merge_ctx_free(&m);
    if (r)
        sl_merge_result_free(out);
    merge_clock_finish(out, t0);
    return r;
}

sl_result sl_merge(const char *const *paths, int count, const sl_merge_options *opt_in,
                   sl_merge_result *out, sl_error *err)
{
    merge_clock t0 = merge_clock_start();
    sl_merge_options opt = merge_options_or_default(opt_in);
    merge_ctx m;
    sl_result r = merge_prepare(paths, count, &opt, true, &m, out, err);
    if (!r)
        r = merge_pass(&m, &opt, NULL, out, err);
    merge_ctx_free(&m);
    if (r)
        sl_merge_result_free(out);
    merge_clock_finish(out, t0);
    return r;
}
