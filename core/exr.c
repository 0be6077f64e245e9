/* SPDX-License-Identifier: BSD-3-Clause */
/* OpenEXR reading and writing through the OpenEXR C API (openexr.h),
 * chunk by chunk with the library's decode/encode pipelines.
 *
 * Reading picks one part (the first) and one set of channels: R,G,B[,A];
 * else Y[,A]; else the first layer (alphabetically) with L.R, L.G, L.B
 * [,L.A]. Tiled files are read at level 0 (the full-resolution mip/rip
 * level). The returned image covers the display window, the frame that
 * lat-long geometry refers to: data-window pixels land at their position,
 * pixels outside the data window are 0, and overscan outside the display
 * window is cropped. Scanline files with ZIP, ZIPS or no compression and
 * half/float channels are decoded here (libdeflate, then straight into the
 * image); DWAA/DWAB pixels, which the OpenEXR 3.1 C API cannot
 * decode, come through OpenImageIO (OpenEXR's C++ library) instead. */
#include "setlight/core.h"
#include "exr_oiio.h"
#include "exr_zip.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <libdeflate.h>
#include <openexr.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

/* Four samples at a time (GCC/Clang vector extensions). */
typedef float v4f_t __attribute__((vector_size(16)));
typedef uint32_t v4u_t __attribute__((vector_size(16)));
typedef int32_t v4i_t __attribute__((vector_size(16)));

/* Same limits as sl_image_alloc: a corrupt header must not allocate wildly. */
#define EXR_MAX_DIM 65536

/* OpenEXR reports problems through a callback that gets only the context;
 * the stream's user_data belongs to the default file reader, so the message
 * goes to a per-thread buffer for the call in progress. */
static _Thread_local char exr_message[512];

static void capture_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    (void)ctxt;
    if (exr_message[0])
        return;
    /* Messages can quote corrupt header bytes: keep one printable line. */
    const char *src = msg ? msg : exr_get_default_error_message(code);
    size_t n = 0;
    for (; src[n] && n < 160; n++)
        exr_message[n] = src[n] >= 0x20 && src[n] < 0x7f ? src[n] : '?';
    strcpy(exr_message + n, src[n] ? "..." : "");
}

static exr_context_initializer_t make_initializer(void)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = capture_error;
    init.max_image_width = EXR_MAX_DIM;
    init.max_image_height = EXR_MAX_DIM;
    init.max_tile_width = EXR_MAX_DIM;
    init.max_tile_height = EXR_MAX_DIM;
    return init;
}

/* The captured message, else the library's text for the code. */
static const char *exr_why(exr_result_t rv)
{
    return exr_message[0] ? exr_message : exr_get_default_error_message(rv);
}

static sl_result corrupt(sl_error *err, const char *path, exr_result_t rv)
{
    return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt EXR (%s)", path, exr_why(rv));
}

/* ------------------------------------------------------------------ */
/* Reading                                                             */
/* ------------------------------------------------------------------ */

typedef struct exr_pick {
    int count;            /* 1..4 output channels */
    const char *names[4]; /* file channel name for each output channel */
    exr_pixel_type_t types[4];
} exr_pick;

static const exr_attr_chlist_entry_t *find_channel(const exr_attr_chlist_t *cl, const char *name)
{
    for (int i = 0; i < cl->num_channels; i++)
        if (strcmp(cl->entries[i].name.str, name) == 0)
            return &cl->entries[i];
    return NULL;
}

/* Looks for prefix+R,G,B[,A] (or prefix+Y[,A] when luminance). */
static bool pick_layer(const exr_attr_chlist_t *cl, const char *prefix, bool luminance,
                       exr_pick *pick)
{
    static const char *rgba[4] = {"R", "G", "B", "A"};
    static const char *ya[2] = {"Y", "A"};
    const char *const *want = luminance ? ya : rgba;
    int needed = luminance ? 1 : 3, total = luminance ? 2 : 4;
    char name[512];
    memset(pick, 0, sizeof *pick);
    for (int c = 0; c < total; c++) {
        snprintf(name, sizeof name, "%s%s", prefix, want[c]);
        const exr_attr_chlist_entry_t *e = find_channel(cl, name);
        if (!e) {
            if (c < needed)
                return false;
            break;
        }
        pick->names[pick->count] = e->name.str;
        pick->types[pick->count] = e->pixel_type;
        pick->count++;
    }
    return true;
}

static bool pick_channels(const exr_attr_chlist_t *cl, exr_pick *pick)
{
    if (pick_layer(cl, "", false, pick) || pick_layer(cl, "", true, pick))
        return true;
    /* The channel list is sorted, so the first ".R" found is the first layer. */
    for (int i = 0; i < cl->num_channels; i++) {
        const char *n = cl->entries[i].name.str;
        size_t len = strlen(n);
        if (len < 3 || strcmp(n + len - 2, ".R") != 0 || len - 1 >= 512)
            continue;
        char prefix[512];
        memcpy(prefix, n, len - 1);
        prefix[len - 1] = 0;
        if (pick_layer(cl, prefix, false, pick))
            return true;
    }
    return false;
}

static void set_fixed(char *dst, size_t size, const char *src) { snprintf(dst, size, "%s", src); }

/* Fills meta from the header: envmap, chromaticities, standard camera
 * attributes and every other string attribute. */
static sl_result read_header_meta(exr_context_t ctx, const exr_pick *pick, sl_meta *meta,
                                  sl_error *err)
{
    set_fixed(meta->format, sizeof meta->format, "openexr");
    bool all_half = true, any_uint = false;
    for (int c = 0; c < pick->count; c++) {
        all_half = all_half && pick->types[c] == EXR_PIXEL_HALF;
        any_uint = any_uint || pick->types[c] == EXR_PIXEL_UINT;
    }
    meta->bits_per_sample = all_half ? 16 : 32;
    meta->is_float = !any_uint;

    int32_t count = 0;
    if (exr_get_attribute_count(ctx, 0, &count) != EXR_ERR_SUCCESS)
        count = 0;
    for (int32_t i = 0; i < count; i++) {
        const exr_attribute_t *a = NULL;
        exr_result_t rv = exr_get_attribute_by_index(ctx, 0, EXR_ATTR_LIST_FILE_ORDER, i, &a);
        if (rv != EXR_ERR_SUCCESS || !a)
            continue;
        const char *n = a->name;
        switch (a->type) {
        case EXR_ATTR_ENVMAP:
            if (strcmp(n, "envmap") == 0)
                meta->envmap = a->uc == EXR_ENVMAP_LATLONG ? SL_ENVMAP_LATLONG
                               : a->uc == EXR_ENVMAP_CUBE  ? SL_ENVMAP_CUBE
                                                           : SL_ENVMAP_NONE;
            break;
        case EXR_ATTR_CHROMATICITIES:
            if (strcmp(n, "chromaticities") == 0 && a->chromaticities) {
                const exr_attr_chromaticities_t *c = a->chromaticities;
                float v[8] = {c->red_x,  c->red_y,  c->green_x, c->green_y,
                              c->blue_x, c->blue_y, c->white_x, c->white_y};
                memcpy(meta->chromaticities, v, sizeof v);
                meta->has_chromaticities = true;
            }
            break;
        case EXR_ATTR_FLOAT:
            /* OpenEXR's standard attribute names (ImfStandardAttributes.h). */
            if (strcmp(n, "expTime") == 0)
                meta->exposure_time = a->f;
            else if (strcmp(n, "aperture") == 0)
                meta->f_number = a->f;
            else if (strcmp(n, "isoSpeed") == 0)
                meta->iso = a->f;
            else if (strcmp(n, "nominalFocalLength") == 0)
                meta->focal_length_mm = a->f;
            break;
        case EXR_ATTR_STRING:
            if (!a->string || !a->string->str)
                break;
            if (strcmp(n, "capDate") == 0)
                set_fixed(meta->datetime, sizeof meta->datetime, a->string->str);
            else if (strcmp(n, "cameraMake") == 0)
                set_fixed(meta->make, sizeof meta->make, a->string->str);
            else if (strcmp(n, "cameraModel") == 0)
                set_fixed(meta->model, sizeof meta->model, a->string->str);
            else if (strcmp(n, "lensModel") == 0)
                set_fixed(meta->lens, sizeof meta->lens, a->string->str);
            else {
                sl_result r = sl_meta_set(meta, n, a->string->str, err);
                if (r)
                    return r;
            }
            break;
        default:
            break;
        }
    }
    return SL_OK;
}

typedef struct exr_frame {
    exr_attr_box2i_t data;    /* data window */
    exr_attr_box2i_t display; /* display window = output frame */
} exr_frame;

/* Decodes one chunk whose pixels start at file coordinates (x0, y0) and
 * copies the part inside the display window into img. The scratch holds
 * pick->count + 1 planes of w * h floats: one per picked channel, and one
 * that every other channel is decoded into and overwrites (OpenEXR 3.1's
 * unpackers write through the pointer of a channel left NULL, "skipped" by
 * the API's documentation, for PIZ, RLE, PXR24, B44 and tiled files). */
static exr_result_t decode_chunk(exr_context_t ctx, const exr_chunk_info_t *cinfo, int x0, int y0,
                                 const exr_pick *pick, const exr_frame *fr,
                                 exr_decode_pipeline_t *dec, bool *initialized, float *scratch,
                                 sl_image *img)
{
    exr_result_t rv = *initialized ? exr_decoding_update(ctx, 0, cinfo, dec)
                                   : exr_decoding_initialize(ctx, 0, cinfo, dec);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    *initialized = true;
    int w = cinfo->width, h = cinfo->height, nc = pick->count;
    size_t plane_size = (size_t)w * (size_t)h;
    for (int i = 0; i < dec->channel_count; i++) {
        exr_coding_channel_info_t *ch = &dec->channels[i];
        int c = 0;
        while (c < nc && strcmp(ch->channel_name, pick->names[c]) != 0)
            c++;
        /* Planar: OpenEXR 3.1's interleaved RGBA half fast path assumes
         * the pointers in the file's channel order (A,B,G,R) and swaps the
         * channels of interleaved RGBA output. */
        ch->decode_to_ptr = (uint8_t *)(scratch + (size_t)c * plane_size);
        ch->user_pixel_stride = (int32_t)sizeof(float);
        ch->user_line_stride = ch->width * (int32_t)sizeof(float);
        ch->user_data_type = EXR_PIXEL_FLOAT;
        ch->user_bytes_per_element = sizeof(float);
    }
    rv = exr_decoding_choose_default_routines(ctx, 0, dec);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_decoding_run(ctx, 0, dec);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    for (int y = 0; y < h; y++) {
        int fy = y0 + y;
        if (fy < fr->display.min.y || fy > fr->display.max.y)
            continue;
        for (int x = 0; x < w; x++) {
            int fx = x0 + x;
            if (fx < fr->display.min.x || fx > fr->display.max.x)
                continue;
            float *dst = sl_image_pixel(img, fx - fr->display.min.x, fy - fr->display.min.y);
            for (int c = 0; c < nc; c++)
                dst[c] = scratch[(size_t)c * plane_size + (size_t)y * (size_t)w + (size_t)x];
        }
    }
    return EXR_ERR_SUCCESS;
}

/* Chunks are decoded in parallel, each worker with its own pipeline and
 * scratch (OpenEXR's core API allows that on one context); they land in
 * disjoint parts of the image. */
typedef struct exr_decode_job {
    exr_context_t ctx;
    const exr_pick *pick;
    const exr_frame *fr;
    sl_image *img;
    uint16_t *rgb16; /* not NULL: half R, G, B land here packed, not in img */
    bool tiled;
    int32_t chunk_w, chunk_h, tiles_x;
    exr_result_t *rv; /* per chunk */
    /* Own scanline decoder (see zip_scanlines): the compression, and per
     * picked channel its byte offset in a line and its type. */
    bool own;
    exr_compression_t comp;
    size_t line_bytes, offset[4];
    bool half[4];
    struct own_scratch *scratch; /* per worker, kept from task to task */
    int workers;
} exr_decode_job;

/* A worker's buffers for zip_scanlines (a chunk of a 4096-wide float RGB
 * image is 800 KB: made once per worker, not per task, they are not
 * faulted in again and again). */
typedef struct own_scratch {
    struct libdeflate_decompressor *inflater;
    uint8_t *packed, *raw, *lines;
    size_t packed_cap, raw_cap, lines_cap;
} own_scratch;

static bool grow(uint8_t **buf, size_t *cap, size_t need)
{
    if (need <= *cap)
        return true;
    uint8_t *p = realloc(*buf, need);
    if (!p)
        return false;
    *buf = p;
    *cap = need;
    return true;
}

static float half_to_float(uint16_t h)
{
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16, e = (h >> 10) & 0x1fu, m = h & 0x3ffu, u;
    if (e == 0x1f)
        u = sign | 0x7f800000u | (m << 13);
    else if (e)
        u = sign | ((e + 112u) << 23) | (m << 13);
    else {
        float f = (float)m * 0x1p-24f; /* subnormal or zero: exact */
        return sign ? -f : f;
    }
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* Undoes the ZIP predictor (each byte stored as the difference to the
 * previous one, plus 128) in place, then the split of the even and odd
 * bytes of the n (even) bytes into two halves, into out. */
static void unzip_bytes(uint8_t *t, size_t n, uint8_t *out)
{
    size_t i = 1;
#ifdef __SSE2__
    /* Prefix sums of 16 bytes at a time, carrying the last one. */
    const __m128i bias = _mm_set1_epi8((char)0x80);
    __m128i carry = _mm_set1_epi8((char)t[0]);
    for (; i + 16 <= n; i += 16) {
        __m128i v = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(t + i)), bias);
        v = _mm_add_epi8(v, _mm_slli_si128(v, 1));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 2));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 4));
        v = _mm_add_epi8(v, _mm_slli_si128(v, 8));
        v = _mm_add_epi8(v, carry);
        _mm_storeu_si128((__m128i *)(t + i), v);
        /* The last byte to every lane, in registers (through memory the
         * next block waits on the store). */
        __m128i hi = _mm_shufflehi_epi16(_mm_unpackhi_epi8(v, v), 0xff);
        carry = _mm_unpackhi_epi64(hi, hi);
    }
#endif
    for (; i < n; i++)
        t[i] = (uint8_t)(t[i - 1] + t[i] - 128);
    const uint8_t *t1 = t, *t2 = t + n / 2;
    size_t j = 0;
#ifdef __SSE2__
    for (; j + 16 <= n / 2; j += 16) {
        __m128i a = _mm_loadu_si128((const __m128i *)(t1 + j));
        __m128i b = _mm_loadu_si128((const __m128i *)(t2 + j));
        _mm_storeu_si128((__m128i *)(out + 2 * j), _mm_unpacklo_epi8(a, b));
        _mm_storeu_si128((__m128i *)(out + 2 * j + 16), _mm_unpackhi_epi8(a, b));
    }
#endif
    for (; j < n / 2; j++) {
        out[2 * j] = t1[j];
        out[2 * j + 1] = t2[j];
    }
}

/* One ZIP/ZIPS/uncompressed scanline chunk (the file's layout: per line,
 * per channel in file order, the line's samples little-endian): its bytes
 * inflated with libdeflate (about three times zlib's speed), the byte
 * predictor and split undone as OpenEXR does, and the picked channels
 * written straight into the image. OpenEXR's own pipeline does the same
 * with zlib and two more copies. */
static exr_result_t zip_scanlines(const exr_decode_job *job, const exr_chunk_info_t *ci,
                                  own_scratch *s)
{
    size_t n = (size_t)ci->unpacked_size;
    /* stored as is: uncompressed files, and chunks compression did not shrink */
    bool stored = job->comp == EXR_COMPRESSION_NONE || ci->packed_size == n;
    if (ci->height <= 0 || n != job->line_bytes * (size_t)ci->height ||
        ci->packed_size > n + (n >> 3) + 1024 || (stored && ci->packed_size != n))
        return EXR_ERR_CORRUPT_CHUNK;
    if (!grow(&s->packed, &s->packed_cap, ci->packed_size ? ci->packed_size : 1) ||
        !grow(&s->raw, &s->raw_cap, n))
        return EXR_ERR_OUT_OF_MEMORY;
    exr_result_t rv = exr_read_chunk(job->ctx, 0, ci, s->packed);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    const uint8_t *lines = s->packed;
    if (!stored) {
        size_t got = 0;
        if (!s->inflater && !(s->inflater = libdeflate_alloc_decompressor()))
            return EXR_ERR_OUT_OF_MEMORY;
        if (libdeflate_zlib_decompress(s->inflater, s->packed, ci->packed_size, s->raw, n,
                                       &got) != LIBDEFLATE_SUCCESS ||
            got != n)
            return EXR_ERR_CORRUPT_CHUNK;
        if (!grow(&s->lines, &s->lines_cap, n))
            return EXR_ERR_OUT_OF_MEMORY;
        /* n is even: every sample is 2 or 4 bytes. */
        unzip_bytes(s->raw, n, s->lines);
        lines = s->lines;
    }
    const exr_frame *fr = job->fr;
    int x0 = fr->data.min.x > fr->display.min.x ? fr->data.min.x : fr->display.min.x;
    int x1 = fr->data.max.x < fr->display.max.x ? fr->data.max.x : fr->display.max.x;
    int nc = job->pick->count;
    for (int y = 0; y < ci->height; y++) {
        int fy = ci->start_y + y;
        if (fy < fr->display.min.y || fy > fr->display.max.y || x0 > x1)
            continue;
        const uint8_t *line = lines + (size_t)y * job->line_bytes;
        if (job->rgb16) { /* half planes to packed half RGB: the bits as stored */
            size_t row_px = (size_t)fr->display.max.x - fr->display.min.x + 1;
            uint16_t *d = job->rgb16 + ((size_t)(fy - fr->display.min.y) * row_px +
                                        (size_t)(x0 - fr->display.min.x)) * 3;
            size_t at = 2 * (size_t)(x0 - fr->data.min.x);
            const uint8_t *pr = line + job->offset[0] + at, *pg = line + job->offset[1] + at,
                          *pb = line + job->offset[2] + at;
            for (int i = 0; i <= x1 - x0; i++, d += 3) {
                memcpy(d, pr + 2 * (size_t)i, 2);
                memcpy(d + 1, pg + 2 * (size_t)i, 2);
                memcpy(d + 2, pb + 2 * (size_t)i, 2);
            }
            continue;
        }
        float *dst = sl_image_pixel(job->img, x0 - fr->display.min.x, fy - fr->display.min.y);
        int done = 0; /* pixels already interleaved */
        if (nc == 3 && !job->half[0] && !job->half[1] && !job->half[2]) {
            /* Float RGB: four pixels of the three planes shuffled at once. */
            size_t at = 4 * (size_t)(x0 - fr->data.min.x);
            const uint8_t *pr = line + job->offset[0] + at, *pg = line + job->offset[1] + at,
                          *pb = line + job->offset[2] + at;
            for (; done + 4 <= x1 - x0 + 1; done += 4) {
                v4f_t r, g, b;
                memcpy(&r, pr + 4 * (size_t)done, sizeof r);
                memcpy(&g, pg + 4 * (size_t)done, sizeof g);
                memcpy(&b, pb + 4 * (size_t)done, sizeof b);
                v4f_t rg = __builtin_shufflevector(r, g, 0, 4, 1, 5);
                v4f_t gb = __builtin_shufflevector(g, b, 1, 5, 2, 6);
                v4f_t rg3 = __builtin_shufflevector(r, g, 3, 7, 3, 7);
                v4f_t out[3] = {__builtin_shufflevector(rg, b, 0, 1, 4, 2),
                                __builtin_shufflevector(gb, r, 0, 1, 6, 2),
                                __builtin_shufflevector(rg3, b, 6, 0, 1, 7)};
                memcpy(dst + 3 * (size_t)done, out, sizeof out);
            }
        }
        for (int c = 0; c < nc; c++) {
            const uint8_t *src = line + job->offset[c];
            float *d = dst + c + (size_t)done * (size_t)nc;
            if (job->half[c]) {
                for (int x = x0; x <= x1; x++, d += nc) {
                    uint16_t h;
                    memcpy(&h, src + 2 * (size_t)(x - fr->data.min.x), 2);
                    *d = half_to_float(h);
                }
            } else {
                for (int x = x0 + done; x <= x1; x++, d += nc)
                    memcpy(d, src + 4 * (size_t)(x - fr->data.min.x), 4);
            }
        }
    }
    return EXR_ERR_SUCCESS;
}

/* Whether zip_scanlines can read this part; fills the job's layout. */
static bool own_decoder(exr_context_t ctx, const exr_attr_chlist_t *cl, exr_decode_job *job)
{
    const uint16_t one = 1;
    uint8_t low;
    memcpy(&low, &one, 1);
    exr_storage_t storage;
    if (!low || job->tiled || exr_get_storage(ctx, 0, &storage) != EXR_ERR_SUCCESS ||
        storage != EXR_STORAGE_SCANLINE ||
        exr_get_compression(ctx, 0, &job->comp) != EXR_ERR_SUCCESS ||
        (job->comp != EXR_COMPRESSION_NONE && job->comp != EXR_COMPRESSION_ZIP &&
         job->comp != EXR_COMPRESSION_ZIPS))
        return false;
    size_t w = (size_t)job->fr->data.max.x - (size_t)job->fr->data.min.x + 1, at = 0;
    int found = 0;
    for (int i = 0; i < cl->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[i];
        if (e->x_sampling != 1 || e->y_sampling != 1)
            return false;
        for (int c = 0; c < job->pick->count; c++)
            if (strcmp(e->name.str, job->pick->names[c]) == 0) {
                if (e->pixel_type != EXR_PIXEL_HALF && e->pixel_type != EXR_PIXEL_FLOAT)
                    return false;
                job->offset[c] = at;
                job->half[c] = e->pixel_type == EXR_PIXEL_HALF;
                found++;
            }
        at += w * (e->pixel_type == EXR_PIXEL_HALF ? 2 : 4);
    }
    job->line_bytes = at;
    return found == job->pick->count;
}

static exr_result_t decode_one(const exr_decode_job *job, int64_t k, exr_decode_pipeline_t *dec,
                               bool *initialized, float *scratch)
{
    exr_chunk_info_t cinfo;
    const exr_frame *fr = job->fr;
    exr_result_t rv;
    if (!job->tiled) {
        rv = exr_read_scanline_chunk_info(job->ctx, 0, fr->data.min.y + (int)k * job->chunk_h,
                                          &cinfo);
        if (rv == EXR_ERR_SUCCESS)
            rv = decode_chunk(job->ctx, &cinfo, fr->data.min.x, cinfo.start_y, job->pick, fr, dec,
                              initialized, scratch, job->img);
        return rv;
    }
    int tx = (int)(k % job->tiles_x), ty = (int)(k / job->tiles_x);
    rv = exr_read_tile_chunk_info(job->ctx, 0, tx, ty, 0, 0, &cinfo);
    if (rv == EXR_ERR_SUCCESS)
        rv = decode_chunk(job->ctx, &cinfo, fr->data.min.x + tx * job->chunk_w,
                          fr->data.min.y + ty * job->chunk_h, job->pick, fr, dec, initialized,
                          scratch, job->img);
    return rv;
}

/* Chunks begin .. end - 1 through zip_scanlines. */
static void own_chunks(exr_decode_job *job, int64_t begin, int64_t end, own_scratch *s)
{
    for (int64_t k = begin; k < end; k++) {
        exr_chunk_info_t cinfo;
        exr_result_t rv = exr_read_scanline_chunk_info(
            job->ctx, 0, job->fr->data.min.y + (int)k * job->chunk_h, &cinfo);
        job->rv[k] = rv == EXR_ERR_SUCCESS ? zip_scanlines(job, &cinfo, s) : rv;
    }
}

static void own_scratch_free(own_scratch *s)
{
    if (s->inflater)
        libdeflate_free_decompressor(s->inflater);
    free(s->packed);
    free(s->raw);
    free(s->lines);
    memset(s, 0, sizeof *s);
}

static void decode_chunks(void *ctx, int64_t begin, int64_t end, int worker)
{
    exr_decode_job *job = ctx;
    if (job->own) {
        if (worker < job->workers) {
            own_chunks(job, begin, end, &job->scratch[worker]);
        } else {
            own_scratch one = {0};
            own_chunks(job, begin, end, &one);
            own_scratch_free(&one);
        }
        return;
    }
    float *scratch = malloc((size_t)job->chunk_w * (size_t)job->chunk_h *
                            (size_t)(job->pick->count + 1) * sizeof(float));
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    bool initialized = false;
    for (int64_t k = begin; k < end; k++)
        job->rv[k] = scratch ? decode_one(job, k, &dec, &initialized, scratch)
                             : EXR_ERR_OUT_OF_MEMORY;
    if (initialized)
        exr_decoding_destroy(job->ctx, &dec);
    free(scratch);
}

static sl_result read_pixels(exr_context_t ctx, const char *path, const exr_attr_chlist_t *cl,
                             const exr_pick *pick, const exr_frame *fr, sl_image *img,
                             uint16_t *rgb16, sl_error *err)
{
    exr_storage_t storage;
    exr_result_t rv = exr_get_storage(ctx, 0, &storage);
    if (rv != EXR_ERR_SUCCESS)
        return corrupt(err, path, rv);
    if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED)
        return sl_error_set(err, SL_ERR_INPUT, "%s: deep EXR data is not supported", path);

    int dw = fr->data.max.x - fr->data.min.x + 1;
    int32_t chunk_w = dw, chunk_h = 1, tiles_x = 1, tiles_y = 1;
    if (storage == EXR_STORAGE_SCANLINE) {
        rv = exr_get_scanlines_per_chunk(ctx, 0, &chunk_h);
    } else {
        int32_t lw = 0, lh = 0;
        rv = exr_get_tile_sizes(ctx, 0, 0, 0, &chunk_w, &chunk_h);
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_get_level_sizes(ctx, 0, 0, 0, &lw, &lh);
        if (rv == EXR_ERR_SUCCESS && (chunk_w <= 0 || chunk_h <= 0 || lw <= 0 || lh <= 0))
            rv = EXR_ERR_INVALID_ATTR;
        if (rv == EXR_ERR_SUCCESS) {
            tiles_x = (lw + chunk_w - 1) / chunk_w;
            tiles_y = (lh + chunk_h - 1) / chunk_h;
            /* Chunks never exceed the level: size the scratch by that, not
             * by a (possibly corrupt) tile size. */
            chunk_w = chunk_w < lw ? chunk_w : lw;
            chunk_h = chunk_h < lh ? chunk_h : lh;
        }
    }
    if (rv != EXR_ERR_SUCCESS)
        return corrupt(err, path, rv);
    if (chunk_h <= 0 || chunk_h > EXR_MAX_DIM || chunk_w <= 0 || chunk_w > EXR_MAX_DIM)
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt EXR (chunk size %dx%d)",
                            path, (int)chunk_w, (int)chunk_h);
    int64_t chunks = storage == EXR_STORAGE_SCANLINE
                         ? ((int64_t)fr->data.max.y - fr->data.min.y + chunk_h) / chunk_h
                         : (int64_t)tiles_x * tiles_y;
    exr_decode_job job = {.ctx = ctx, .pick = pick, .fr = fr, .img = img, .rgb16 = rgb16,
                          .tiled = storage == EXR_STORAGE_TILED, .chunk_w = chunk_w,
                          .chunk_h = chunk_h, .tiles_x = tiles_x};
    job.own = own_decoder(ctx, cl, &job);
    if (rgb16 && !job.own) /* only zip_scanlines writes packed half */
        return SL_ERR_UNSUPPORTED;
    int workers = sl_threads_get();
    job.rv = malloc(sizeof *job.rv * (size_t)chunks);
    job.scratch = calloc((size_t)workers, sizeof *job.scratch);
    job.workers = workers;
    if (!job.rv || !job.scratch) {
        free(job.rv);
        free(job.scratch);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for EXR chunks", path);
    }
    /* Grain: a few MB of pixels per task. */
    int64_t per_chunk = (int64_t)chunk_w * chunk_h * pick->count;
    sl_parallel_for(chunks, 1 + (1 << 20) / per_chunk, decode_chunks, &job);
    sl_result r = SL_OK;
    for (int64_t k = 0; k < chunks && !r; k++)
        if (job.rv[k] != EXR_ERR_SUCCESS) {
            /* The first bad chunk again, here, for the library's message. */
            exr_message[0] = 0;
            decode_chunks(&job, k, k + 1, 0);
            r = corrupt(err, path, job.rv[k]);
        }
    for (int i = 0; i < workers; i++)
        own_scratch_free(&job.scratch[i]);
    free(job.scratch);
    free(job.rv);
    return r;
}

/* Whether the part goes to OpenEXR's C++ library: the 3.1 C API has no DWA
 * decoder, and returns wrong pixels for B44 files with float or uint
 * channels and for files with a subsampled channel (test_exr_layouts
 * compares with the C++ library's decoding). */
static bool needs_cxx_decoder(const exr_attr_chlist_t *cl, exr_compression_t comp)
{
    if (comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB)
        return true;
    for (int i = 0; i < cl->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[i];
        if (e->x_sampling != 1 || e->y_sampling != 1 ||
            ((comp == EXR_COMPRESSION_B44 || comp == EXR_COMPRESSION_B44A) &&
             e->pixel_type != EXR_PIXEL_HALF))
            return true;
    }
    return false;
}

static sl_result window_size(const exr_attr_box2i_t *b, int *w, int *h)
{
    int64_t ww = (int64_t)b->max.x - b->min.x + 1, hh = (int64_t)b->max.y - b->min.y + 1;
    if (ww <= 0 || hh <= 0 || ww > EXR_MAX_DIM || hh > EXR_MAX_DIM)
        return SL_ERR_INPUT;
    *w = (int)ww;
    *h = (int)hh;
    return SL_OK;
}

sl_result sl_exr_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    sl_result r = sl_check_input_file(path, err);
    if (r)
        return r;

    exr_message[0] = 0;
    exr_context_initializer_t init = make_initializer();
    exr_context_t ctx = NULL;
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    /* OpenEXRCore reports some damage (an attribute whose size disagrees
     * with its type) and reads on; OpenEXR's C++ library, which reads DWA
     * and subsampled files, would then allocate what the attribute claims
     * (a 1.5 KB file claiming 1.7 GB cost 8.5 s and 1.8 GB). */
    if (rv == EXR_ERR_SUCCESS && exr_message[0])
        rv = EXR_ERR_CORRUPT_CHUNK;
    if (rv != EXR_ERR_SUCCESS) {
        exr_finish(&ctx);
        return corrupt(err, path, rv);
    }

    const exr_attr_chlist_t *cl = NULL;
    exr_frame fr;
    exr_pick pick;
    bool yc = false;
    int w = 0, h = 0, dw = 0, dh = 0;
    rv = exr_get_channels(ctx, 0, &cl);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_data_window(ctx, 0, &fr.data);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_display_window(ctx, 0, &fr.display);
    if (rv != EXR_ERR_SUCCESS || !cl) {
        r = corrupt(err, path, rv);
    } else if (window_size(&fr.display, &w, &h) || window_size(&fr.data, &dw, &dh)) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: truncated or corrupt EXR (display window %dx%d, data window %dx%d: "
                         "empty or over %d)",
                         path, fr.display.max.x - fr.display.min.x + 1,
                         fr.display.max.y - fr.display.min.y + 1, fr.data.max.x - fr.data.min.x + 1,
                         fr.data.max.y - fr.data.min.y + 1, EXR_MAX_DIM);
    } else if (!pick_channels(cl, &pick)) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: EXR has no R,G,B, Y or layer.R,G,B channels",
                         path);
    } else if (strcmp(pick.names[0], "Y") == 0 &&
               (find_channel(cl, "RY") || find_channel(cl, "BY"))) {
        /* Luminance/chroma (what OpenEXR's RGBA interface writes with
         * WRITE_YC): its RGBA interface turns it back into RGB; reading Y
         * alone would silently turn a colour image grey. */
        static const char *const rgba[4] = {"R", "G", "B", "A"};
        const exr_attr_chlist_entry_t *ry = find_channel(cl, "RY"), *by = find_channel(cl, "BY");
        if (!ry || !by || ry->x_sampling != 2 || ry->y_sampling != 2 || by->x_sampling != 2 ||
            by->y_sampling != 2)
            r = sl_error_set(err, SL_ERR_INPUT,
                             "%s: luminance/chroma EXR without both RY and BY sampled 2 x 2 "
                             "(the only layout OpenEXR turns back into RGB)",
                             path);
        yc = true;
        pick.count = find_channel(cl, "A") ? 4 : 3;
        for (int c = 0; c < pick.count; c++) {
            pick.names[c] = rgba[c];
            pick.types[c] = EXR_PIXEL_HALF;
        }
    } else {
        for (int c = 0; c < pick.count && !r; c++) {
            const exr_attr_chlist_entry_t *e = find_channel(cl, pick.names[c]);
            if (e->x_sampling != 1 || e->y_sampling != 1)
                r = sl_error_set(err, SL_ERR_UNSUPPORTED,
                                 "%s: subsampled EXR channel %s is not supported", path,
                                 pick.names[c]);
        }
    }
    /* The image covers the display window, padded with zeros the file does
     * not store: a small data window in a huge display window is refused
     * here when the padding is over the budget, never allocated. */
    if (!r) {
        char what[128];
        snprintf(what, sizeof what, "the %dx%d display window (data window %dx%d)", w, h, dw, dh);
        r = sl_memory_check((uint64_t)w * (uint64_t)h * (uint64_t)pick.count * sizeof(float), path,
                            what, err);
    }
    if (!r && (r = sl_image_alloc(img, w, h, pick.count, NULL)) != SL_OK)
        sl_error_set(err, r, "%s: cannot allocate a %dx%d EXR image", path, w, h);
    exr_compression_t comp = EXR_COMPRESSION_NONE;
    if (!r && (rv = exr_get_compression(ctx, 0, &comp)) != EXR_ERR_SUCCESS)
        r = corrupt(err, path, rv);
    if (!r && (yc || needs_cxx_decoder(cl, comp)))
        r = sl_exr_read_pixels_oiio(path, pick.names, pick.count, fr.display.min.x,
                                    fr.display.min.y, img, err);
    else if (!r)
        r = read_pixels(ctx, path, cl, &pick, &fr, img, NULL, err);
    if (!r && meta)
        r = read_header_meta(ctx, &pick, meta, err);
    exr_finish(&ctx);
    if (r) {
        sl_image_free(img);
        if (meta)
            sl_meta_free(meta);
        return r;
    }
    /* Half and float files can hold NaN/Inf; they are the caller's to count. */
    return SL_OK;
}

sl_result sl_exr_read_half_rgb(const char *path, uint16_t **rgb, int *width, int *height,
                               sl_meta *meta, sl_error *err)
{
    *rgb = NULL;
    *width = *height = 0;
    sl_meta_init(meta);
    exr_message[0] = 0;
    exr_context_initializer_t init = make_initializer();
    exr_context_t ctx = NULL;
    /* Anything this does not read (a damaged header too) is left to
     * sl_exr_read, which says what is wrong with it. */
    if (exr_start_read(&ctx, path, &init) != EXR_ERR_SUCCESS || exr_message[0]) {
        exr_finish(&ctx);
        return SL_OK;
    }
    const exr_attr_chlist_t *cl = NULL;
    exr_frame fr;
    exr_pick pick;
    exr_compression_t comp = EXR_COMPRESSION_NONE;
    int w = 0, h = 0;
    bool fits = exr_get_channels(ctx, 0, &cl) == EXR_ERR_SUCCESS && cl &&
                exr_get_data_window(ctx, 0, &fr.data) == EXR_ERR_SUCCESS &&
                exr_get_display_window(ctx, 0, &fr.display) == EXR_ERR_SUCCESS &&
                exr_get_compression(ctx, 0, &comp) == EXR_ERR_SUCCESS &&
                !window_size(&fr.display, &w, &h) &&
                !memcmp(&fr.data, &fr.display, sizeof fr.data) && pick_channels(cl, &pick) &&
                pick.count == 3 && !strcmp(pick.names[0], "R") &&
                !needs_cxx_decoder(cl, comp);
    for (int c = 0; fits && c < 3; c++)
        fits = pick.types[c] == EXR_PIXEL_HALF;
    sl_result r = SL_OK;
    size_t bytes = (size_t)w * (size_t)h * 3 * sizeof(uint16_t);
    if (fits)
        r = sl_memory_check(bytes, path, "the half RGB view", err);
    uint16_t *px = fits && !r ? malloc(bytes) : NULL;
    if (fits && !r && !px)
        r = sl_error_set(err, SL_ERR_NOMEM, "%s: cannot allocate a %dx%d half image", path, w, h);
    if (px) {
        /* In 4 KB pages: on the 2-core VM fresh 2 MB pages cost more to fault
         * in than the stitch's lookups gain from them (docs/stitch.md, Speed). */
        r = read_pixels(ctx, path, cl, &pick, &fr, NULL, px, err);
        if (r == SL_ERR_UNSUPPORTED) { /* not a layout zip_scanlines reads */
            free(px);
            px = NULL;
            r = SL_OK;
        }
    }
    if (px && !r)
        r = read_header_meta(ctx, &pick, meta, err);
    exr_finish(&ctx);
    if (r) {
        free(px);
        sl_meta_free(meta);
        return r;
    }
    if (!px)
        return SL_OK;
    *rgb = px;
    *width = w;
    *height = h;
    return SL_OK;
}

/* ------------------------------------------------------------------ */
/* Writing                                                             */
/* ------------------------------------------------------------------ */

static float sanitize(float v, float limit)
{
    if (isnan(v))
        return 0.0f;
    return v > limit ? limit : v < -limit ? -limit : v;
}

/* Float to half, rounded to nearest even like OpenEXR's own conversion
 * (F. Giesen's float_to_half_fast3_rtne); done here, branch-light, because
 * the library's per-sample conversion cost as much as PIZ itself. */
static uint16_t half_bits(float f)
{
    const uint32_t f32infty = 255u << 23, f16max = (127u + 16u) << 23;
    const uint32_t magic_bits = ((127u - 15u) + (23u - 10u) + 1u) << 23;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    uint32_t sign = u & 0x80000000u;
    u ^= sign;
    uint16_t o;
    if (u >= f16max)
        o = u > f32infty ? 0x7e00 : 0x7c00;
    else if (u < (113u << 23)) {
        /* Subnormal or zero: let the float adder round the mantissa. */
        float v, magic;
        memcpy(&v, &u, sizeof v);
        memcpy(&magic, &magic_bits, sizeof magic);
        v += magic;
        memcpy(&u, &v, sizeof u);
        o = (uint16_t)(u - magic_bits);
    } else {
        uint32_t odd = (u >> 13) & 1;
        u += ((uint32_t)(15 - 127) << 23) + 0xfff + odd;
        o = (uint16_t)(u >> 13);
    }
    return (uint16_t)(o | (sign >> 16));
}

/* sanitize and half_bits for four samples at a time: the same bits (after
 * the clamp to +-65504 no sample takes the Inf/NaN branch). */
static inline __attribute__((always_inline)) void half_bits4(v4f_t f, uint16_t *dst)
{
    const v4f_t limit = {65504.0f, 65504.0f, 65504.0f, 65504.0f};
    const uint32_t magic_bits = ((127u - 15u) + (23u - 10u) + 1u) << 23;
    f = (v4f_t)((v4i_t)f & (f == f)); /* NaN -> 0 */
#ifdef __SSE2__
    f = (v4f_t)_mm_max_ps(_mm_min_ps((__m128)f, (__m128)limit), (__m128)-limit);
#else
    v4i_t hi = f > limit, lo = f < -limit;
    f = (v4f_t)((hi & (v4i_t)limit) | (lo & (v4i_t)-limit) | (~(hi | lo) & (v4i_t)f));
#endif
    v4u_t u = (v4u_t)f, sign = u & 0x80000000u;
    u ^= sign;
    v4u_t normal = (u + (uint32_t)((15 - 127) * (1 << 23)) + 0xfffu + ((u >> 13) & 1u)) >> 13;
    v4f_t magic = (v4f_t)((v4u_t){0, 0, 0, 0} + magic_bits);
    v4u_t subnormal = (v4u_t)((v4f_t)u + magic) - magic_bits;
    v4u_t small = (v4u_t)(u < (113u << 23));
    v4u_t o = ((small & subnormal) | (~small & normal)) | (sign >> 16);
#ifdef __SSE2__
    /* The four 16-bit values packed at once: shifted into the signed
     * range for the saturating pack, shifted back after. */
    __m128i t = _mm_sub_epi32((__m128i)o, _mm_set1_epi32(0x8000));
    t = _mm_xor_si128(_mm_packs_epi32(t, t), _mm_set1_epi16((short)0x8000));
    _mm_storel_epi64((__m128i *)dst, t);
#else
    for (int i = 0; i < 4; i++)
        dst[i] = (uint16_t)o[i];
#endif
}

const char *sl_exr_compression_name(sl_exr_compression c)
{
    static const char *const names[] = {"zip", "piz", "none", "rle"};
    return (int)c >= 0 && (int)c < (int)(sizeof names / sizeof names[0]) ? names[c] : "unknown";
}

static exr_compression_t exr_compression(sl_exr_compression c)
{
    switch (c) {
    case SL_EXR_PIZ:
        return EXR_COMPRESSION_PIZ;
    case SL_EXR_NONE:
        return EXR_COMPRESSION_NONE;
    case SL_EXR_RLE:
        return EXR_COMPRESSION_RLE;
    case SL_EXR_ZIP:
        break;
    }
    return EXR_COMPRESSION_ZIP;
}

static exr_result_t write_header(exr_context_t ctx, const sl_image *img, const sl_meta *meta,
                                 sl_pixel_type type, sl_exr_compression compression)
{
    static const char *names[4][4] = {{"Y"}, {"Y", "A"}, {"R", "G", "B"}, {"R", "G", "B", "A"}};
    int part = 0;
    exr_result_t rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    exr_attr_box2i_t win;
    memset(&win, 0, sizeof win);
    win.max.x = img->width - 1;
    win.max.y = img->height - 1;
    exr_attr_v2f_t center;
    memset(&center, 0, sizeof center);
    rv = exr_initialize_required_attr(ctx, part, &win, &win, 1.0f, &center, 1.0f,
                                      EXR_LINEORDER_INCREASING_Y,
                                      exr_compression(compression));
    /* Names over 31 bytes (setlight:* can be) need the long-name flag. */
    bool long_names = false;
    for (int i = 0; meta && i < meta->attr_count; i++)
        long_names = long_names || strlen(meta->attrs[i].name) > 31;
    if (rv == EXR_ERR_SUCCESS && long_names)
        rv = exr_set_longname_support(ctx, 1);
    exr_pixel_type_t pt = type == SL_PIXEL_FLOAT ? EXR_PIXEL_FLOAT : EXR_PIXEL_HALF;
    for (int c = 0; c < img->channels && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(ctx, part, names[img->channels - 1][c], pt,
                             EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    exr_attr_chromaticities_t chroma = {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f};
    if (meta && meta->has_chromaticities)
        memcpy(&chroma, meta->chromaticities, sizeof chroma);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_attr_set_chromaticities(ctx, part, "chromaticities", &chroma);
    if (!meta)
        return rv;
    if (rv == EXR_ERR_SUCCESS && meta->envmap != SL_ENVMAP_NONE)
        rv = exr_attr_set_envmap(ctx, part, "envmap",
                                 meta->envmap == SL_ENVMAP_CUBE ? EXR_ENVMAP_CUBE
                                                                : EXR_ENVMAP_LATLONG);
    /* EXIF-like fields under OpenEXR's standard attribute names. */
    struct {
        const char *name;
        double value;
    } floats[] = {
        {"expTime", meta->exposure_time},
        {"aperture", meta->f_number},
        {"isoSpeed", meta->iso},
        {"nominalFocalLength", meta->focal_length_mm},
    };
    for (size_t i = 0; i < sizeof floats / sizeof floats[0] && rv == EXR_ERR_SUCCESS; i++)
        if (floats[i].value > 0)
            rv = exr_attr_set_float(ctx, part, floats[i].name, (float)floats[i].value);
    struct {
        const char *name;
        const char *value;
    } strings[] = {
        {"capDate", meta->datetime},
        {"cameraMake", meta->make},
        {"cameraModel", meta->model},
        {"lensModel", meta->lens},
    };
    for (size_t i = 0; i < sizeof strings / sizeof strings[0] && rv == EXR_ERR_SUCCESS; i++)
        if (strings[i].value[0])
            rv = exr_attr_set_string(ctx, part, strings[i].name, strings[i].value);
    for (int i = 0; i < meta->attr_count && rv == EXR_ERR_SUCCESS; i++)
        rv = exr_attr_set_string(ctx, part, meta->attrs[i].name, meta->attrs[i].value);
    return rv;
}

/* One chunk packed and compressed; the bytes are kept for the in-order write.
 * The buffer stays with the slot from batch to batch (a chunk of an
 * 8192-wide image is 800 KB: not faulted in anew for every chunk). */
typedef struct exr_chunk_out {
    int y;
    bool zero; /* all-zero pixels, a full chunk */
    void *bytes;
    size_t cap;
    uint64_t size;
    exr_result_t rv;
} exr_chunk_out;

/* Room for n bytes in the slot's buffer. */
static bool chunk_room(exr_chunk_out *o, size_t n)
{
    if (!n)
        n = 1;
    if (n <= o->cap)
        return true;
    free(o->bytes);
    o->cap = 0;
    if (!(o->bytes = malloc(n)))
        return false;
    o->cap = n;
    return true;
}

/* An EXR written a batch of rows at a time: rows are sanitised into the
 * batch buffer in the file's layout (per line, per channel in file order),
 * its chunks compressed in parallel, then written in order. ZIP chunks are
 * compressed by core (exr_zip.c: about a third of PIZ's time, and
 * smaller on noisy HDR data); the others by OpenEXR. */
struct sl_exr_stream {
    sl_atomic_file f;
    exr_context_t ctx;
    sl_meta meta;        /* the header's attributes, for sl_exr_stream_finish */
    char *path;
    int width, height, channels, lines;
    float limit;
    bool half;
    void *buf;           /* batch_rows rows from row0, float or half as the file */
    int batch_rows, row0, rows; /* rows buffered */
    int first;           /* first chunk of the batch being encoded */
    exr_chunk_out *out;  /* per chunk of a batch */
    int batch_chunks;    /* out's length */
    /* An all-zero chunk of `lines` rows compresses to the same bytes
     * wherever it is (masks are mostly such chunks): kept once made. */
    void *zero_bytes;
    uint64_t zero_size;
    bool own_zip;
    int workers;
    exr_zip_scratch *zip; /* per worker */
    /* The file's written pages handed to the disk a batch at a time, so
     * the commit's fsync does not wait for all of them at the end, and
     * its blocks reserved up front (-1: not opened; then the fsync does
     * it all and the writes allocate as they go). */
    int writeback_fd;
};

/* Keeps the compressed bytes instead of writing them (the caller writes in order). */
static exr_result_t keep_chunk(exr_encode_pipeline_t *enc)
{
    exr_chunk_out *o = enc->encoding_user_data;
    if (!chunk_room(o, enc->compressed_bytes))
        return EXR_ERR_OUT_OF_MEMORY;
    memcpy(o->bytes, enc->compressed_buffer, enc->compressed_bytes);
    o->size = enc->compressed_bytes;
    return EXR_ERR_SUCCESS;
}

/* Chunks are written later, in order, so none has to wait for its turn. */
static exr_result_t no_wait(exr_encode_pipeline_t *enc)
{
    (void)enc;
    return EXR_ERR_SUCCESS;
}

/* Whether n bytes are all zero; stops at the first 256-byte stretch that is
 * not (an image's chunks mostly are not: scanning each to its end was a
 * pass over the whole output). */
static bool all_zero(const uint8_t *p, size_t n)
{
    uint64_t acc = 0, v;
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        memcpy(&v, p + i, 8);
        acc |= v;
        if ((i & 255) == 248 && acc)
            return false;
    }
    for (; i < n; i++)
        acc |= p[i];
    return acc == 0;
}

/* A chunk's raw lines through exr_zip_chunk (stored as they are when that
 * is not shorter). */
static exr_result_t own_zip_chunk(sl_exr_stream *s, const uint8_t *rows, size_t n, int worker,
                                  exr_chunk_out *o)
{
    exr_zip_scratch one, *z = worker < s->workers ? &s->zip[worker] : &one;
    memset(&one, 0, sizeof one);
    size_t size = 0;
    if (!chunk_room(o, n) || !exr_zip_chunk(rows, n, z, o->bytes, &size)) {
        exr_zip_free(&one);
        return EXR_ERR_OUT_OF_MEMORY;
    }
    exr_zip_free(&one);
    if (!size)
        memcpy(o->bytes, rows, size = n);
    o->size = size;
    return EXR_ERR_SUCCESS;
}

static void encode_chunks(void *ctx, int64_t begin, int64_t end, int worker)
{
    sl_exr_stream *s = ctx;
    int nc = s->channels, w = s->width;
    for (int64_t k = begin; k < end; k++) {
        exr_chunk_out *o = &s->out[k];
        o->y = (int)(s->first + k) * s->lines;
        exr_chunk_info_t cinfo;
        exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
        o->rv = exr_write_scanline_chunk_info(s->ctx, 0, o->y, &cinfo);
        if (o->rv != EXR_ERR_SUCCESS)
            continue;
        size_t bytes = s->half ? 2 : 4, line = (size_t)w * (size_t)nc * bytes;
        const uint8_t *rows = (const uint8_t *)s->buf + (size_t)(o->y - s->row0) * line;
        o->zero = cinfo.height == s->lines && all_zero(rows, (size_t)cinfo.height * line);
        if (o->zero && s->zero_bytes) {
            bool room = chunk_room(o, s->zero_size);
            if (room)
                memcpy(o->bytes, s->zero_bytes, s->zero_size);
            o->size = s->zero_size;
            o->rv = room ? EXR_ERR_SUCCESS : EXR_ERR_OUT_OF_MEMORY;
            continue;
        }
        if (s->own_zip) {
            o->rv = own_zip_chunk(s, rows, (size_t)cinfo.height * line, worker, o);
            continue;
        }
        o->rv = exr_encoding_initialize(s->ctx, 0, &cinfo, &enc);
        if (o->rv != EXR_ERR_SUCCESS)
            continue;
        /* The buffer holds each line's channels one after another, in the
         * file's order (the order enc.channels come in). */
        for (int i = 0; i < enc.channel_count; i++) {
            exr_coding_channel_info_t *ch = &enc.channels[i];
            ch->encode_from_ptr = rows + (size_t)i * (size_t)w * bytes;
            ch->user_pixel_stride = (int32_t)bytes;
            ch->user_line_stride = (int32_t)line;
            ch->user_data_type = s->half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)bytes;
        }
        o->rv = exr_encoding_choose_default_routines(s->ctx, 0, &enc);
        enc.write_fn = keep_chunk;
        enc.yield_until_ready_fn = no_wait;
        enc.encoding_user_data = o;
        if (o->rv == EXR_ERR_SUCCESS)
            o->rv = exr_encoding_run(s->ctx, 0, &enc);
        exr_encoding_destroy(s->ctx, &enc);
    }
}

/* Compresses the buffered rows' chunks in parallel (the bulk of the time)
 * and writes them in order. */
static exr_result_t flush_batch(sl_exr_stream *s)
{
    int n = (s->rows + s->lines - 1) / s->lines;
    s->first = s->row0 / s->lines;
    for (int k = 0; k < n; k++) {
        s->out[k].zero = false;
        s->out[k].size = 0;
        s->out[k].rv = EXR_ERR_SUCCESS;
    }
    sl_parallel_for(n, 1, encode_chunks, s);
    exr_result_t rv = EXR_ERR_SUCCESS;
    for (int k = 0; k < n; k++) {
        if (rv == EXR_ERR_SUCCESS)
            rv = s->out[k].rv;
        if (rv == EXR_ERR_SUCCESS && s->out[k].zero && !s->zero_bytes &&
            (s->zero_bytes = malloc(s->out[k].size ? s->out[k].size : 1))) {
            memcpy(s->zero_bytes, s->out[k].bytes, s->out[k].size);
            s->zero_size = s->out[k].size;
        }
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_write_scanline_chunk(s->ctx, 0, s->out[k].y, s->out[k].bytes, s->out[k].size);
    }
#ifdef SYNC_FILE_RANGE_WRITE
    if (rv == EXR_ERR_SUCCESS && s->writeback_fd >= 0) /* starts it, does not wait */
        sync_file_range(s->writeback_fd, 0, 0, SYNC_FILE_RANGE_WRITE);
#endif
    s->row0 += s->rows;
    s->rows = 0;
    return rv;
}

/* The file's blocks reserved at once, past its end, for as many bytes as
 * the pixels uncompressed (no less than ZIP writes: a chunk that does not
 * compress is stored raw): ext4 then allocates no blocks write by write.
 * Best effort: without it the writes allocate as they go. */
static void reserve_blocks(sl_exr_stream *s, int lines, sl_pixel_type type)
{
#ifdef FALLOC_FL_KEEP_SIZE
    off_t end = s->writeback_fd >= 0 ? lseek(s->writeback_fd, 0, SEEK_END) : -1;
    int64_t chunks = (s->height + lines - 1) / lines;
    int64_t bytes = (int64_t)s->width * s->height * s->channels *
                        (type == SL_PIXEL_HALF ? 2 : 4) +
                    chunks * 16; /* each chunk's offset, line and size */
    if (end >= 0)
        (void)fallocate(s->writeback_fd, FALLOC_FL_KEEP_SIZE, end, (off_t)bytes);
#else
    (void)s, (void)lines, (void)type;
#endif
}

/* The reserved blocks past the file's end given back. */
static exr_result_t release_reserve(sl_exr_stream *s)
{
    if (s->writeback_fd < 0)
        return EXR_ERR_SUCCESS;
    off_t end = lseek(s->writeback_fd, 0, SEEK_END);
    return end >= 0 && ftruncate(s->writeback_fd, end) == 0 ? EXR_ERR_SUCCESS
                                                              : EXR_ERR_WRITE_IO;
}

static sl_result stream_fail(sl_exr_stream *s, exr_result_t rv, sl_error *err)
{
    /* Attribute problems come from the caller's meta, not the disk. */
    bool bad_attr = rv == EXR_ERR_ATTR_TYPE_MISMATCH || rv == EXR_ERR_INVALID_ATTR ||
                    rv == EXR_ERR_NAME_TOO_LONG || rv == EXR_ERR_INVALID_ARGUMENT;
    sl_result r = sl_error_set(err,
                               rv == EXR_ERR_OUT_OF_MEMORY ? SL_ERR_NOMEM
                               : bad_attr                  ? SL_ERR_USAGE
                                                           : SL_ERR_IO,
                               "%s: cannot write EXR (%s)", s->path, exr_why(rv));
    sl_exr_stream_abort(s);
    return r;
}

sl_result sl_exr_stream_open(const char *path, int width, int height, int channels,
                             const sl_meta *meta, sl_pixel_type type,
                             sl_exr_compression compression, sl_exr_stream **out, sl_error *err)
{
    *out = NULL;
    if (width <= 0 || height <= 0 || channels < 1 || channels > 4 || width > EXR_MAX_DIM ||
        height > EXR_MAX_DIM)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no image to write", path ? path : "(null)");
    if (type != SL_PIXEL_HALF && type != SL_PIXEL_FLOAT)
        return sl_error_set(err, SL_ERR_USAGE, "%s: unknown EXR pixel type %d", path, (int)type);
    if (compression < SL_EXR_ZIP || compression > SL_EXR_RLE)
        return sl_error_set(err, SL_ERR_USAGE, "%s: unknown EXR compression %d", path,
                            (int)compression);
    sl_exr_stream *s = calloc(1, sizeof *s);
    if (!s || !(s->path = strdup(path))) {
        free(s);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    s->writeback_fd = -1;
    sl_meta_init(&s->meta);
    sl_result r = meta ? sl_meta_copy(meta, &s->meta, err) : SL_OK;
    if (!r)
        r = sl_atomic_begin(&s->f, path, err);
    if (r) {
        sl_meta_free(&s->meta);
        free(s->path);
        free(s);
        return r;
    }
    s->width = width;
    s->height = height;
    s->channels = channels;
    /* Half cannot hold more than 65504: clamp rather than write Inf. */
    s->limit = type == SL_PIXEL_HALF ? 65504.0f : FLT_MAX;
    s->half = type == SL_PIXEL_HALF;
    exr_message[0] = 0;
    exr_context_initializer_t init = make_initializer();
    sl_image shape = {.width = width, .height = height, .channels = channels};
    exr_result_t rv = exr_start_write(&s->ctx, s->f.temp_path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS)
        rv = write_header(s->ctx, &shape, meta, type, compression);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_write_header(s->ctx);
    if (rv == EXR_ERR_SUCCESS)
        s->writeback_fd = open(s->f.temp_path, O_WRONLY | O_CLOEXEC);
    int32_t lines = 1;
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_scanlines_per_chunk(s->ctx, 0, &lines);
    if (rv == EXR_ERR_SUCCESS)
        reserve_blocks(s, lines, type);
    if (rv != EXR_ERR_SUCCESS)
        return stream_fail(s, rv, err);
    /* Eight chunks per thread a batch: enough to keep every thread busy. */
    int batch = 8 * sl_threads_get();
    s->lines = lines;
    s->batch_rows = batch * lines < height ? batch * lines : height;
    s->buf = malloc((size_t)s->batch_rows * (size_t)width * (size_t)channels * (s->half ? 2 : 4));
    s->out = calloc((size_t)batch, sizeof *s->out);
    s->batch_chunks = s->out ? batch : 0;
    s->own_zip = compression == SL_EXR_ZIP;
    s->workers = sl_threads_get();
    s->zip = calloc((size_t)s->workers, sizeof *s->zip);
    if (!s->buf || !s->out || !s->zip)
        return stream_fail(s, EXR_ERR_OUT_OF_MEMORY, err);
    *out = s;
    return SL_OK;
}

/* Four RGB pixels (12 floats at src) as their B, G and R planes. */
static inline __attribute__((always_inline)) void rgb4_planes(const float *src, v4f_t plane[3])
{
    v4f_t a, b, c;
    memcpy(&a, src, sizeof a);
    memcpy(&b, src + 4, sizeof b);
    memcpy(&c, src + 8, sizeof c);
    v4f_t r = __builtin_shufflevector(a, b, 0, 3, 6, 6);
    v4f_t g = __builtin_shufflevector(a, b, 1, 4, 7, 7);
    v4f_t bl = __builtin_shufflevector(a, b, 2, 5, 5, 5);
    plane[0] = __builtin_shufflevector(bl, c, 0, 1, 4, 7);
    plane[1] = __builtin_shufflevector(g, c, 0, 1, 2, 6);
    plane[2] = __builtin_shufflevector(r, c, 0, 1, 2, 5);
}

/* (clang 14's __builtin_cpu_supports does not know "f16c") */
#if (defined(__x86_64__) || defined(__i386__)) && !defined(__clang__) && __GNUC__ >= 12
#define HAVE_F16C_ROWS 1
#include <immintrin.h>
/* One RGB row's pixels 0 .. w - w % 4 into half planes B, G, R (w apart)
 * with the processor's conversion (F16C): the same bits as half_bits4()
 * (round to nearest even; checked over every finite float), a fifth of its
 * instructions. Returns the pixels done. */
__attribute__((target("f16c"))) static size_t rgb_row_f16c(const float *src, uint16_t *dst,
                                                           size_t w, size_t plane_w)
{
    const __m128 limit = _mm_set1_ps(65504.0f), neg = _mm_set1_ps(-65504.0f);
    size_t done = 0;
    for (; done + 4 <= w; done += 4) {
        v4f_t plane[3];
        rgb4_planes(src + 3 * done, plane);
        for (int k = 0; k < 3; k++) {
            v4f_t f = (v4f_t)((v4i_t)plane[k] & (plane[k] == plane[k])); /* NaN -> 0 */
            __m128 v = _mm_max_ps(_mm_min_ps((__m128)f, limit), neg);
            _mm_storel_epi64((__m128i *)(dst + (size_t)k * plane_w + done),
                             _mm_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT));
        }
    }
    return done;
}

/* The same eight pixels at a time where the processor has AVX2: each plane
 * from two blends of the three loaded vectors and one permute. */
__attribute__((target("avx2,f16c"))) static size_t rgb_row_avx2(const float *src, uint16_t *dst,
                                                               size_t w)
{
    const __m256 limit = _mm256_set1_ps(65504.0f), neg = _mm256_set1_ps(-65504.0f);
    /* Lanes of a (0-7), b (8-15), c (16-23) holding R: 0 9 18 3 12 21 6 15 */
    const __m256i r_idx = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5);
    const __m256i g_idx = _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6);
    const __m256i b_idx = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
    size_t done = 0;
    for (; done + 8 <= w; done += 8) {
        const float *p = src + 3 * done;
        __m256 a = _mm256_loadu_ps(p), b = _mm256_loadu_ps(p + 8), c = _mm256_loadu_ps(p + 16);
        /* [a0 b1 c2 a3 b4 c5 a6 b7], [c0 a1 b2 c3 a4 b5 c6 a7], [b0 c1 a2 b3 c4 a5 b6 c7] */
        __m256 r = _mm256_blend_ps(_mm256_blend_ps(a, b, 0x92), c, 0x24);
        __m256 g = _mm256_blend_ps(_mm256_blend_ps(a, b, 0x24), c, 0x49);
        __m256 bl = _mm256_blend_ps(_mm256_blend_ps(a, b, 0x49), c, 0x92);
        __m256 plane[3] = {_mm256_permutevar8x32_ps(bl, b_idx), _mm256_permutevar8x32_ps(g, g_idx),
                           _mm256_permutevar8x32_ps(r, r_idx)};
        for (int k = 0; k < 3; k++) {
            __m256 f = _mm256_and_ps(plane[k], _mm256_cmp_ps(plane[k], plane[k], _CMP_ORD_Q));
            __m256 v = _mm256_max_ps(_mm256_min_ps(f, limit), neg);
            _mm_storeu_si128((__m128i *)(dst + (size_t)k * w + done),
                             _mm256_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT));
        }
    }
    return done + rgb_row_f16c(src + 3 * done, dst + done, w - done, w);
}
#endif

typedef struct convert_job {
    sl_exr_stream *s;
    const float *rows;
    size_t stride;
} convert_job;

/* Sanitises rows into the batch buffer (after the rows already there),
 * each line's channels one after another in the file's order: sorted by
 * name (B, G, R; A first), i.e. the interleaved channels backwards. */
static void convert_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const convert_job *job = ctx;
    sl_exr_stream *s = job->s;
    size_t w = (size_t)s->width, nc = (size_t)s->channels;
    for (int64_t j = begin; j < end; j++) {
        const float *src = job->rows + (size_t)j * job->stride;
        size_t at = (size_t)(s->rows + j) * w * nc, done = 0;
#ifdef HAVE_F16C_ROWS
        if (s->half && nc == 3 && __builtin_cpu_supports("avx2") &&
            __builtin_cpu_supports("f16c"))
            done = rgb_row_avx2(src, (uint16_t *)s->buf + at, w);
        else if (s->half && nc == 3 && __builtin_cpu_supports("f16c"))
            done = rgb_row_f16c(src, (uint16_t *)s->buf + at, w, w);
#endif
        if (s->half && nc == 3 && done == 0) {
            /* RGB: four pixels' three vectors shuffled into R, G and B. */
            uint16_t *dst = (uint16_t *)s->buf + at;
            for (; done + 4 <= w; done += 4) {
                v4f_t plane[3];
                rgb4_planes(src + 3 * done, plane);
                for (int k = 0; k < 3; k++)
                    half_bits4(plane[k], dst + (size_t)k * w + done);
            }
        }
        for (size_t f = 0; f < nc; f++) {
            const float *p = src + done * nc + (nc - 1 - f);
            if (s->half) {
                uint16_t *dst = (uint16_t *)s->buf + at + f * w;
                size_t x = done;
                for (; x + 4 <= w; x += 4, p += 4 * nc)
                    half_bits4((v4f_t){p[0], p[nc], p[2 * nc], p[3 * nc]}, dst + x);
                for (; x < w; x++, p += nc)
                    dst[x] = half_bits(sanitize(*p, s->limit));
            } else {
                float *dst = (float *)s->buf + at + f * w;
                for (size_t x = 0; x < w; x++, p += nc)
                    dst[x] = sanitize(*p, s->limit);
            }
        }
    }
}

sl_result sl_exr_stream_write(sl_exr_stream *s, const float *rows, int count, size_t stride,
                              sl_error *err)
{
    if (count < 0 || s->row0 + s->rows + count > s->height) {
        sl_result r = sl_error_set(err, SL_ERR_USAGE, "%s: %d rows more than the image's %d",
                                   s->path, s->row0 + s->rows + count - s->height, s->height);
        sl_exr_stream_abort(s);
        return r;
    }
    while (count > 0) {
        int take = s->batch_rows - s->rows < count ? s->batch_rows - s->rows : count;
        convert_job job = {s, rows, stride};
        sl_parallel_for(take, 4, convert_rows, &job);
        s->rows += take;
        rows += (size_t)take * stride;
        count -= take;
        if (s->rows == s->batch_rows || s->row0 + s->rows == s->height) {
            exr_result_t rv = flush_batch(s);
            if (rv != EXR_ERR_SUCCESS)
                return stream_fail(s, rv, err);
        }
    }
    return SL_OK;
}

/* Rewrites string attributes in the finished file's header, each value
 * the same length as the one written (the header cannot grow). */
static sl_result patch_header(sl_exr_stream *s, const sl_meta *update, sl_error *err)
{
    int changed = 0;
    for (int i = 0; i < update->attr_count; i++) {
        const char *old = sl_meta_get(&s->meta, update->attrs[i].name);
        if (!old || strlen(old) != strlen(update->attrs[i].value))
            return sl_error_set(err, SL_ERR_USAGE,
                                "%s: attribute %s can only be replaced by a value of the "
                                "length written",
                                s->path, update->attrs[i].name);
        changed += strcmp(old, update->attrs[i].value) != 0;
    }
    if (!changed)
        return SL_OK;
    FILE *fp = fopen(s->f.temp_path, "r+b");
    if (!fp)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot reopen to finish the header", s->path);
    /* Header: magic, version, then name\0 type\0 size value ... until an empty name. */
    size_t cap = 1 << 16, len = 0;
    char *h = NULL;
    sl_result r = SL_OK;
    long pos = 8;
    for (;;) {
        if (len < cap) {
            char *t = realloc(h, cap);
            if (!t) {
                r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", s->path);
                break;
            }
            h = t;
            if (fseek(fp, (long)len, SEEK_SET) == 0)
                len += fread(h + len, 1, cap - len, fp);
        }
        /* Parse attributes that lie whole within what was read. */
        size_t at = (size_t)pos;
        const char *name = h + at;
        size_t nl = at < len ? strnlen(name, len - at) : 0;
        if (at >= len || (nl == len - at)) {
            if (len < cap) {
                r = sl_error_set(err, SL_ERR_IO, "%s: header ends early", s->path);
                break;
            }
            cap *= 2;
            continue;
        }
        if (nl == 0)
            break; /* end of header */
        const char *tname = name + nl + 1;
        size_t tl = (size_t)(tname - h) < len ? strnlen(tname, len - (size_t)(tname - h)) : 0;
        size_t vat = (size_t)(tname - h) + tl + 1 + 4;
        if (vat > len) {
            if (len < cap) {
                r = sl_error_set(err, SL_ERR_IO, "%s: header ends early", s->path);
                break;
            }
            cap *= 2;
            continue;
        }
        const unsigned char *sz = (const unsigned char *)h + vat - 4;
        size_t size = (size_t)sz[0] | (size_t)sz[1] << 8 | (size_t)sz[2] << 16 | (size_t)sz[3] << 24;
        const char *value = sl_meta_get(update, name);
        if (value && strcmp(tname, "string") == 0 && size == strlen(value)) {
            if (fseek(fp, (long)vat, SEEK_SET) != 0 || fwrite(value, 1, size, fp) != size) {
                r = sl_error_set(err, SL_ERR_IO, "%s: cannot finish the header: %s", s->path,
                                 strerror(errno));
                break;
            }
        }
        pos = (long)(vat + size);
    }
    free(h);
    if (fclose(fp) != 0 && !r)
        r = sl_error_set(err, SL_ERR_IO, "%s: cannot finish the header: %s", s->path,
                         strerror(errno));
    return r;
}

sl_result sl_exr_stream_finish(sl_exr_stream *s, const sl_meta *update, sl_error *err)
{
    if (s->row0 + s->rows != s->height) {
        sl_result r = sl_error_set(err, SL_ERR_USAGE, "%s: %d of %d rows written", s->path,
                                   s->row0 + s->rows, s->height);
        sl_exr_stream_abort(s);
        return r;
    }
    /* exr_finish writes the chunk offset table: it can fail too. */
    exr_result_t rv = exr_finish(&s->ctx);
    if (rv == EXR_ERR_SUCCESS)
        rv = release_reserve(s);
    if (rv != EXR_ERR_SUCCESS)
        return stream_fail(s, rv, err);
    sl_result r = update ? patch_header(s, update, err) : SL_OK;
    if (r) {
        sl_exr_stream_abort(s);
        return r;
    }
    r = sl_atomic_commit(&s->f, err);
    sl_exr_stream_abort(s); /* frees; the file is in place or gone */
    return r;
}

void sl_exr_stream_abort(sl_exr_stream *s)
{
    if (!s)
        return;
    if (s->ctx)
        exr_finish(&s->ctx);
    if (s->writeback_fd >= 0)
        close(s->writeback_fd);
    if (s->f.temp_path[0])
        sl_atomic_abort(&s->f);
    sl_meta_free(&s->meta);
    free(s->path);
    free(s->buf);
    for (int k = 0; s->out && k < s->batch_chunks; k++)
        free(s->out[k].bytes);
    free(s->out);
    free(s->zero_bytes);
    for (int i = 0; s->zip && i < s->workers; i++)
        exr_zip_free(&s->zip[i]);
    free(s->zip);
    free(s);
}

sl_result sl_exr_write(const char *path, const sl_image *img, const sl_meta *meta,
                       sl_pixel_type type, sl_error *err)
{
    return sl_exr_write_compressed(path, img, meta, type, SL_EXR_ZIP, err);
}

sl_result sl_exr_write_compressed(const char *path, const sl_image *img, const sl_meta *meta,
                                  sl_pixel_type type, sl_exr_compression compression,
                                  sl_error *err)
{
    if (!img || !img->data || img->width <= 0 || img->height <= 0 || img->channels < 1 ||
        img->channels > 4)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no image to write", path ? path : "(null)");
    sl_exr_stream *s;
    sl_result r = sl_exr_stream_open(path, img->width, img->height, img->channels, meta, type,
                                     compression, &s, err);
    if (!r)
        r = sl_exr_stream_write(s, img->data, img->height, img->stride, err);
    return r ? r : sl_exr_stream_finish(s, NULL, err);
}
