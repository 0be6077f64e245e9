/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight core: image buffers, metadata, EXR and photo I/O, colour,
 * lat-long and projection geometry, sampling distributions, errors,
 * logging, progress, threads and atomic file output.
 *
 * Conventions (docs/conventions.md is the long form):
 *  - Every fallible function returns an sl_result and, when `err` is not
 *    NULL, fills it with a one-line message that names the file and the
 *    problem. Libraries never print and never exit.
 *  - Ownership: a function that fills an `sl_image *out` or `sl_meta *out`
 *    hands the caller memory to release with sl_image_free / sl_meta_free.
 *    Out-parameters are zeroed first, so freeing after a failure is safe.
 *  - Pixels are scene-linear float, interleaved, `channels` per pixel.
 *  - Lat-long images use OpenEXR's orientation (+Y up, centre column +Z,
 *    a quarter width in +X) with texel centres at (x + 0.5) / width.
 */
#ifndef SETLIGHT_CORE_H
#define SETLIGHT_CORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------ */
/* Results and errors                                                  */
/* ------------------------------------------------------------------ */

typedef int32_t sl_result;

enum {
    SL_OK = 0,
    SL_ERR_USAGE,       /* bad argument or option value (exit 2) */
    SL_ERR_NOT_FOUND,   /* input file missing or not a regular file (exit 3) */
    SL_ERR_INPUT,       /* input data invalid: corrupt, wrong format, wrong shape (exit 3) */
    SL_ERR_IO,          /* reading or writing failed at the OS level (exit 1) */
    SL_ERR_NOMEM,       /* allocation failed (exit 1) */
    SL_ERR_UNSUPPORTED, /* feature not available in this build (exit 1) */
    SL_ERR_CANCELLED,   /* stopped by the user (exit 1) */
    SL_ERR_CAMERA,      /* camera refused, busy past retries, disconnected (exit 1) */
    SL_ERR_INTERNAL,    /* invariant broken: a bug (exit 1) */
    SL_ERR_COUNT
};

#define SL_ERROR_MESSAGE_MAX 1024

typedef struct sl_error {
    sl_result code;
    char message[SL_ERROR_MESSAGE_MAX];
} sl_error;

/* Static, never freed. */
const char *sl_result_name(sl_result code);
/* CLI exit code for a result: 0, 1, 2 or 3 (see docs/conventions.md). */
int sl_result_exit_code(sl_result code);

/* Fill `err` (if not NULL) with code and printf-formatted message; returns code. */
sl_result sl_error_set(sl_error *err, sl_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
void sl_error_clear(sl_error *err);

/* ------------------------------------------------------------------ */
/* Logging and progress (stderr only; quiet suppresses info and progress) */
/* ------------------------------------------------------------------ */

typedef enum { SL_LOG_DEBUG, SL_LOG_INFO, SL_LOG_WARN, SL_LOG_ERROR } sl_log_level;

void sl_log_set_level(sl_log_level min_level);
void sl_log_set_quiet(bool quiet);
bool sl_log_is_quiet(void);
void sl_log(sl_log_level level, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* A note on how an input was taken (linearised, assumed a lat-long): logged
 * at once, or, while notes are held (the CLI holds them for a run), kept,
 * each text once, until sl_log_release_notes prints them (the run
 * succeeded) or drops them (a refusal stays one line on stderr). */
void sl_log_note(sl_log_level level, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
void sl_log_hold_notes(bool hold);
void sl_log_release_notes(bool print);

/* A progress bar drawn on stderr only when stderr is a terminal and not quiet. */
typedef struct sl_progress {
    const char *label;
    int64_t total;
    int64_t done;
    double start_seconds;
    double last_draw_seconds;
    bool enabled;
} sl_progress;

void sl_progress_begin(sl_progress *p, const char *label, int64_t total);
void sl_progress_add(sl_progress *p, int64_t amount); /* thread-safe */
void sl_progress_end(sl_progress *p);

/* Monotonic wall clock, process CPU time and the calling thread's CPU
 * time, in seconds. */
double sl_seconds(void);
double sl_cpu_seconds(void);
double sl_thread_cpu_seconds(void);

/* ------------------------------------------------------------------ */
/* Threads: deterministic parallel loops                               */
/* ------------------------------------------------------------------ */

/* 0 = number of online cores. Applies to later sl_parallel_for calls. */
void sl_threads_set(int count);
int sl_threads_get(void);

/* Calls fn(ctx, begin, end, worker) over [0, count) in chunks of `grain`
 * items. Chunks are fixed by count and grain alone, never by thread count,
 * so work that writes per-chunk or per-item results is deterministic. */
typedef void (*sl_range_fn)(void *ctx, int64_t begin, int64_t end, int worker);
void sl_parallel_for(int64_t count, int64_t grain, sl_range_fn fn, void *ctx);

/* ------------------------------------------------------------------ */
/* Atomic file output                                                  */
/* ------------------------------------------------------------------ */

/* Writes go to a temporary name in the same folder that keeps the final
 * extension (libraries choose formats by it): `dir/.name.sl-tmp-PID-N.ext`.
 * Commit fsyncs it and renames it over the final path (or, for a member of
 * the open output set, hands it to the set); abort removes it. A commit or
 * begin after an interrupt is SL_ERR_CANCELLED. */
typedef struct sl_atomic_file {
    char final_path[4096];
    char temp_path[4096];
    int slot; /* in the registry of temporaries; -1 none */
} sl_atomic_file;

sl_result sl_atomic_begin(sl_atomic_file *f, const char *final_path, sl_error *err);
sl_result sl_atomic_commit(sl_atomic_file *f, sl_error *err); /* fsyncs, renames */
void sl_atomic_abort(sl_atomic_file *f);

/* Removes what a process killed outright (SIGKILL, a crash, power) left for
 * final_path: its `.name.sl-tmp-PID-N.ext` temporaries and output-set
 * `.old` files whose PID is no process on this machine (a live writer's are
 * kept). For a caller that owns final_path, e.g. a job about to write its
 * outputs. Returns how many files it removed. */
int sl_atomic_sweep(const char *final_path);

/* Interrupts. Every temporary (sl_atomic_begin, sl_temp_dir_create) is
 * registered while it exists; sl_interrupt_install (the CLI calls it first
 * thing) makes SIGINT, SIGTERM and SIGHUP remove them all, never rename a
 * partial file into place, and end the process by the signal itself
 * (status 128 + signal: 130, 143, 129), so a calling script stops too. A
 * rename already under way (a whole file, or an output set's renames)
 * finishes first. A signal ignored at start (nohup) stays ignored. */
void sl_interrupt_install(void);
/* mkdtemp(template_path), registered: a handle for sl_temp_dir_remove, or
 * -1 with errno set (EINTR after an interrupt). */
int sl_temp_dir_create(char *template_path);
/* Removes the folder and what is in it, and unregisters it. */
void sl_temp_dir_remove(const char *path, int handle);

/* Output sets: a command's outputs are replaced together. Between begin
 * and commit, an sl_atomic_commit of a member keeps its complete, fsynced
 * temporary instead of renaming it; sl_output_set_commit then renames them
 * all, after hard-linking each old file aside, and on a failed rename puts
 * the old files back (or removes the new ones where there were none):
 * either every member is new or every member is as before. Members are
 * exact paths or prefixes ending in '*' (NULL entries are skipped); files
 * not matching commit at once. A set begun while one is open joins it
 * (its commit is the outer one's; its abort drops every pending file). The window:
 * a crash (SIGKILL, power) inside the rename loop, a few system calls
 * long, can leave some renamed and the old files beside as *.sl-tmp-*.old;
 * where hard links are not supported a failed rename cannot be undone. */
sl_result sl_output_set_begin(const char *const *members, int count, sl_error *err);
/* The temporary holding a member's new content until the commit (to read
 * an output back before it is in place), or NULL when none is pending. */
const char *sl_output_set_pending(const char *final_path);
sl_result sl_output_set_commit(sl_error *err);
/* Removes every pending temporary; the old outputs stay. */
void sl_output_set_abort(void);
/* Adds a complete file or folder the caller made (inside a registered
 * temporary folder, sl_temp_dir_create) to the open set: renamed over
 * final_path at the commit (an earlier folder moved aside, then removed).
 * It stays the caller's to remove when the set fails. */
sl_result sl_output_set_adopt(const char *final_path, const char *temp_path, sl_error *err);

/* Removes a folder and everything in it (a temporary or replaced output
 * folder), best effort: what cannot be removed stays. */
void sl_remove_tree(const char *path);

/* Writes a whole text/binary buffer atomically. */
sl_result sl_write_file_atomic(const char *path, const void *data, size_t size, sl_error *err);

/* A module (shared object) this build made, dlopen'd: looked for next to
 * the executable, then one folder up (a build tree or an install moved as a
 * whole: setlight in build/, tests in build/tests/), then at built_path.
 * NULL when it cannot be loaded (dlerror() says why). */
void *sl_module_open(const char *built_path);

/* ------------------------------------------------------------------ */
/* Memory budget: what a header claims is checked before allocating    */
/* ------------------------------------------------------------------ */

/* The bytes a run may spend on what it reads (docs/conventions.md): set by
 * the CLI from --max-memory-mb or SETLIGHT_MAX_MEMORY_MB; 0 restores the
 * default, half the machine's RAM (or of a smaller cgroup limit). */
void sl_memory_budget_set(uint64_t bytes);
uint64_t sl_memory_budget(void);
uint64_t sl_memory_budget_default(void);
/* SL_ERR_INPUT naming `path`, `what` (e.g. "a 40000x20000 RGB image"), the
 * bytes it needs and the budget, when `bytes` is over the budget. */
sl_result sl_memory_check(uint64_t bytes, const char *path, const char *what, sl_error *err);
/* sl_check_input_file, and SL_ERR_INPUT naming the file and `what` it is
 * (e.g. "rig JSON") when it is over max_bytes: a file parsed whole (JSON,
 * a journal) is refused before its parser allocates for it. */
sl_result sl_check_input_size(const char *path, uint64_t max_bytes, const char *what,
                              sl_error *err);
/* The largest JSON file a reader parses whole (rig, scene): 16 MiB, four
 * times a rig of the most lights (4096 at about 1 kB each); parsing one
 * costs about 15 times its size. */
#define SL_MAX_JSON_BYTES ((uint64_t)16 << 20)

/* Checks that `path` names an existing, readable, non-empty regular file.
 * SL_ERR_NOT_FOUND for missing or a directory, SL_ERR_INPUT for empty. */
sl_result sl_check_input_file(const char *path, sl_error *err);

/* ------------------------------------------------------------------ */
/* Image buffers                                                       */
/* ------------------------------------------------------------------ */

typedef struct sl_image {
    int width;
    int height;
    int channels;  /* 1..4 */
    size_t stride; /* floats per row, >= width * channels */
    float *data;   /* owned; freed by sl_image_free */
} sl_image;

sl_result sl_image_alloc(sl_image *img, int width, int height, int channels, sl_error *err);
/* Asks the kernel to back the whole 2 MB pages inside a block of `bytes`
 * with huge pages where the system allows it (before the block is first
 * written): lookups that follow curves through a large image otherwise miss
 * the TLB on almost every row. sl_image_alloc does it for its images. */
void sl_advise_huge_pages(void *data, size_t bytes);
/* The opposite, for a block not yet written that is written once in order
 * and read mostly in order: on the 2-core VM this project is measured on,
 * a fresh 2 MB page costs about four times as much to fault in as its 512
 * small ones (430 MB: 0.52-0.71 s against 0.16 s). */
void sl_advise_small_pages(void *data, size_t bytes);
void sl_image_free(sl_image *img);
static inline float *sl_image_pixel(const sl_image *img, int x, int y)
{
    return img->data + (size_t)y * img->stride + (size_t)x * (size_t)img->channels;
}
/* A bilinear lookup at pixel position (x, y) (pixel centres at +0.5; x, y
 * finite) of a width x height grid, clamped to its edges: the two columns
 * and rows and the weights of the second ones, so a value is
 * (1-ay) ((1-ax) v[y0][x0] + ax v[y0][x1]) + ay ((1-ax) v[y1][x0] + ax v[y1][x1]).
 * Inline: per-pixel lookups of the stitch's blend and the ball finder. */
typedef struct sl_bilinear {
    int x0, x1, y0, y1;
    double ax, ay;
} sl_bilinear;
static inline sl_bilinear sl_bilinear_at(int width, int height, double x, double y)
{
    double fx = x - 0.5, fy = y - 0.5;
    int x0 = (int)fx, y0 = (int)fy;
    x0 -= fx < x0; /* floor, without a libm call */
    y0 -= fy < y0;
    sl_bilinear b = {x0, x0 + 1, y0, y0 + 1, fx - x0, fy - y0};
    if (x0 < 0 || b.x1 >= width) {
        b.x0 = x0 < 0 ? 0 : (x0 >= width ? width - 1 : x0);
        b.x1 = b.x1 < 0 ? 0 : (b.x1 >= width ? width - 1 : b.x1);
    }
    if (y0 < 0 || b.y1 >= height) {
        b.y0 = y0 < 0 ? 0 : (y0 >= height ? height - 1 : y0);
        b.y1 = b.y1 < 0 ? 0 : (b.y1 >= height ? height - 1 : b.y1);
    }
    return b;
}
/* The lookup of a one-channel plane of width x height floats, row after row. */
static inline double sl_bilinear_plane(const float *plane, int width, int height, double x,
                                       double y)
{
    sl_bilinear b = sl_bilinear_at(width, height, x, y);
    const float *r0 = plane + (size_t)b.y0 * width, *r1 = plane + (size_t)b.y1 * width;
    double top = r0[b.x0] * (1 - b.ax) + r0[b.x1] * b.ax;
    double bot = r1[b.x0] * (1 - b.ax) + r1[b.x1] * b.ax;
    return top * (1 - b.ay) + bot * b.ay;
}
sl_result sl_image_copy(const sl_image *src, sl_image *dst, sl_error *err);
void sl_image_fill(sl_image *img, float value);

/* Copies the rectangle [x, x+w) x [y, y+h); it must lie inside src. */
sl_result sl_image_crop(const sl_image *src, int x, int y, int w, int h, sl_image *dst,
                        sl_error *err);

/* Resamples to width x height. Shrinking is area-weighted (each output
 * pixel is the exact area average of the input it covers), so the mean and
 * the total energy per unit area are kept; enlarging is bilinear. */
sl_result sl_image_resample(const sl_image *src, int width, int height, sl_image *dst,
                            sl_error *err);

/* New image with `channels` channels: drops extra channels, repeats a single
 * channel to RGB, fills a missing alpha with 1. */
sl_result sl_image_convert_channels(const sl_image *src, int channels, sl_image *dst,
                                    sl_error *err);
/* In place: a grey image (with its alpha) becomes RGB(A), as a change of
 * primaries (sl_color_convert) needs; RGB(A) is left as it is. Errors name
 * `path`. */
sl_result sl_image_ensure_rgb(sl_image *img, const char *path, sl_error *err);

typedef struct sl_image_stats {
    double min[4], max[4];  /* over finite values */
    double mean[4];         /* over finite values */
    double sum[4];          /* compensated sum over finite values */
    int64_t finite_count[4];
    int64_t nan_count;      /* samples, all channels */
    int64_t inf_count;
    int64_t negative_count;
} sl_image_stats;

void sl_image_stats_compute(const sl_image *img, sl_image_stats *stats);

/* Replaces NaN and Inf samples with `value`; returns how many were replaced. */
int64_t sl_image_sanitize(sl_image *img, float value);

/* ------------------------------------------------------------------ */
/* Metadata                                                            */
/* ------------------------------------------------------------------ */

typedef enum { SL_ENVMAP_NONE = 0, SL_ENVMAP_LATLONG, SL_ENVMAP_CUBE } sl_envmap;

typedef struct sl_attr {
    char *name;  /* e.g. "setlight:inputs" */
    char *value;
} sl_attr;

typedef struct sl_meta {
    /* what the file is */
    char format[32];       /* "openexr", "jpeg", "tiff", "png", "raw", ... */
    int bits_per_sample;   /* 8, 16, 32 (float), 16 for half */
    bool is_float;
    sl_envmap envmap;
    bool has_chromaticities;
    float chromaticities[8]; /* red xy, green xy, blue xy, white xy */
    char colorspace[64];   /* OCIO name if known, else "" */
    /* EXIF; 0 or "" when absent */
    double exposure_time;  /* seconds */
    double f_number;
    double iso;
    double focal_length_mm;
    char make[64];
    char model[64];
    char lens[128];
    char datetime[32];     /* "YYYY:MM:DD HH:MM:SS" as in EXIF */
    int orientation;       /* EXIF 1..8, 0 unknown */
    /* other string attributes; setlight's own are "setlight:*" */
    sl_attr *attrs;
    int attr_count;
} sl_meta;

void sl_meta_init(sl_meta *meta);
void sl_meta_free(sl_meta *meta);
sl_result sl_meta_copy(const sl_meta *src, sl_meta *dst, sl_error *err);
/* Sets or replaces a string attribute (copies both strings). */
sl_result sl_meta_set(sl_meta *meta, const char *name, const char *value, sl_error *err);
/* NULL if absent. */
const char *sl_meta_get(const sl_meta *meta, const char *name);
/* The Rec.709 / sRGB primaries with D65 white, as EXR chromaticities. */
void sl_meta_set_rec709(sl_meta *meta);

/* ------------------------------------------------------------------ */
/* TIFF directories (EXIF's APP1 payload, TIFF and DNG headers)        */
/* ------------------------------------------------------------------ */

/* A TIFF structure in memory; every read is bounds-checked against n. */
typedef struct sl_tiff {
    const unsigned char *p;
    size_t n;
    bool big; /* "MM" byte order */
} sl_tiff;
/* false unless p starts with a TIFF header; *ifd0 is its first IFD's offset. */
bool sl_tiff_open(const unsigned char *p, size_t n, sl_tiff *t, unsigned long *ifd0);
bool sl_tiff_u16(const sl_tiff *t, size_t at, unsigned *v);
bool sl_tiff_u32(const sl_tiff *t, size_t at, unsigned long *v);
/* The entry `tag` of the IFD at `ifd`: its type, count and the offset of its
 * value (inline values sit in the entry itself), inside the buffer. */
bool sl_tiff_find(const sl_tiff *t, unsigned long ifd, unsigned tag, unsigned *type,
                  unsigned long *count, size_t *value_at);
/* The same for the i-th entry of the IFD (any tag); false past the last. */
bool sl_tiff_entry(const sl_tiff *t, unsigned long ifd, unsigned i, unsigned *tag,
                   unsigned *type, unsigned long *count, size_t *value_at);

/* ------------------------------------------------------------------ */
/* Image files                                                         */
/* ------------------------------------------------------------------ */

typedef enum { SL_PIXEL_HALF = 0, SL_PIXEL_FLOAT = 1 } sl_pixel_type;

/* OpenEXR through its C API (openexr.h). Reads scanline or tiled, half,
 * float or uint channels; RGB(A), Y, or any single layer of R,G,B[,A]. */
sl_result sl_exr_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err);
/* A file of half R, G, B channels only (no A, no layer), scanline, ZIP or
 * uncompressed, data window = display window (what merge writes), read
 * without float: *rgb gets its samples' bits as stored, 3 a pixel, rows
 * packed (malloc'd), and meta as sl_exr_read's. Any other file, or a damaged header: SL_OK with *rgb
 * NULL (sl_exr_read reads it, or says what is wrong). */
sl_result sl_exr_read_half_rgb(const char *path, uint16_t **rgb, int *width, int *height,
                               sl_meta *meta, sl_error *err);
/* Writes atomically. Writes `envmap`, `chromaticities` (Rec.709 unless
 * meta says otherwise) and every attr as a string attribute. meta may be NULL. */
sl_result sl_exr_write(const char *path, const sl_image *img, const sl_meta *meta,
                       sl_pixel_type type, sl_error *err);
/* Lossless EXR compressions; sl_exr_write uses ZIP, which core compresses
 * itself (Huffman and runs, no LZ77 search: about 2.5 times less CPU than
 * OpenEXR's PIZ on noisy HDR data, a similar size; docs/formats.md). */
typedef enum {
    SL_EXR_ZIP = 0,
    SL_EXR_PIZ = 1,
    SL_EXR_NONE = 2,
    SL_EXR_RLE = 3
} sl_exr_compression;

/* "zip", "piz", "none", "rle" (the options' names); "unknown" otherwise. */
const char *sl_exr_compression_name(sl_exr_compression c);
/* (No ZIPS: OpenEXR 3.1.5's C decoder misreads half ZIPS files that its
 * C++ library reads correctly; test_exr_stream found it.) */
/* sl_exr_write with a chosen compression; chunks are compressed in parallel. */
sl_result sl_exr_write_compressed(const char *path, const sl_image *img, const sl_meta *meta,
                                  sl_pixel_type type, sl_exr_compression compression,
                                  sl_error *err);
/* The same written a few rows at a time (no whole image held): rows in
 * order, buffered until a batch of chunks is compressed in parallel and
 * written. Nothing is at `path` before sl_exr_stream_finish; any failure
 * aborts the stream (it must not be used again). */
typedef struct sl_exr_stream sl_exr_stream;
sl_result sl_exr_stream_open(const char *path, int width, int height, int channels,
                             const sl_meta *meta, sl_pixel_type type,
                             sl_exr_compression compression, sl_exr_stream **stream,
                             sl_error *err);
/* The next `count` rows, width * channels floats each, `stride` floats apart. */
sl_result sl_exr_stream_write(sl_exr_stream *stream, const float *rows, int count, size_t stride,
                              sl_error *err);
/* After the last row: replaces the values of `update`'s attributes (each
 * one of meta's, same length: e.g. counts known only at the end, written
 * first as fixed-width placeholders) and moves the file into place. Frees
 * the stream. update may be NULL. */
sl_result sl_exr_stream_finish(sl_exr_stream *stream, const sl_meta *update, sl_error *err);
/* Removes the partial file and frees the stream (NULL is fine). */
void sl_exr_stream_abort(sl_exr_stream *stream);

/* Camera and photo formats: PNG and JPEG through libpng and libjpeg as OpenImageIO reads them,
 * the others (TIFF, HDR, DNG, camera raw via LibRaw) through OpenImageIO, loaded on first use
 * (docs/performance.md). Integer formats come back scaled to [0, 1] with no
 * transfer function removed: a JPEG stays sRGB-encoded, camera raw is read
 * linear (no tone curve, camera white balance, Rec.709 output). */
sl_result sl_photo_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err);
/* Reads metadata only (no pixels). */
sl_result sl_photo_read_meta(const char *path, sl_meta *meta, int *width, int *height,
                             int *channels, sl_error *err);
/* Writes PNG/JPEG/TIFF (by extension) atomically with EXIF from meta.
 * bits: 8 or 16 (TIFF/PNG), 32 for float TIFF. Values are written as given
 * (clamped to [0,1] for integer formats): encode sRGB before if you want it. */
sl_result sl_photo_write(const char *path, const sl_image *img, const sl_meta *meta, int bits,
                         sl_error *err);

/* A photo read a strip of rows at a time (bounded memory), opened exactly
 * as sl_photo_read opens it (camera raw linear). Rows come as RGB float
 * (grey repeated, alpha dropped), width * 3 floats per row, and must be
 * asked for in increasing order. */
typedef struct sl_photo_strips sl_photo_strips;
typedef struct sl_photo_strip_info {
    int width, height;
    int file_channels;
    int bits;      /* bits per sample in the file */
    bool is_float; /* float or half samples */
    int code_bytes; /* integer samples: 1 (uint8) or 2 (uint16) container; else 0 */
    /* JPEG: its MCU in pixels (8x8 blocks; 16x16 with 4:2:0 chroma, 16x8
     * with 4:2:2), aligned to the image origin: DCT ringing and chroma bleed
     * stay inside it. 0 for formats without lossy blocks. */
    int block_w, block_h;
    /* Integer codes stored exactly (PNG, TIFF not JPEG-compressed, PNM, BMP,
     * Targa, SGI): no lossy codec rings below the clip code. False for
     * JPEG, HEIF, WebP and formats not known to be lossless. */
    bool lossless;
} sl_photo_strip_info;
sl_result sl_photo_strips_open(const char *path, sl_photo_strips **strips,
                               sl_photo_strip_info *info, sl_error *err);
sl_result sl_photo_strips_read(sl_photo_strips *strips, int y0, int y1, float *rgb, sl_error *err);
/* The same rows as the file's integer codes, uint8_t or uint16_t by
 * info.code_bytes (code / 255 or / 65535 is what sl_photo_strips_read
 * gives); no conversion to float, which costs more than a JPEG's decoding. */
sl_result sl_photo_strips_read_codes(sl_photo_strips *strips, int y0, int y1, void *rgb,
                                     sl_error *err);
void sl_photo_strips_close(sl_photo_strips *strips);

/* Any image: EXR through sl_exr_read, anything else through sl_photo_read.
 * Chooses by content (magic bytes), not by extension, so a PNG named .exr
 * is reported as such. */
sl_result sl_image_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err);
/* By extension: .exr -> sl_exr_write(SL_PIXEL_HALF unless float asked),
 * others -> sl_photo_write. */
sl_result sl_image_write(const char *path, const sl_image *img, const sl_meta *meta,
                         sl_pixel_type exr_type, sl_error *err);

/* ------------------------------------------------------------------ */
/* Colour                                                              */
/* ------------------------------------------------------------------ */

float sl_srgb_to_linear(float v);
float sl_linear_to_srgb(float v);

/* Linear Rec.709 (D65) <-> CIE XYZ (Y of white = 1). */
void sl_rec709_to_xyz(const double rgb[3], double xyz[3]);
void sl_xyz_to_rec709(const double xyz[3], double rgb[3]);
/* Linear RGB with these EXR chromaticities (red, green, blue, white xy) ->
 * linear Rec.709 D65: through XYZ, the white adapted by Bradford. */
void sl_chromaticities_to_rec709(const float xy[8], double m[3][3]);
/* Bradford chromatic adaptation matrix from one white (XYZ) to another. */
void sl_bradford(const double src_white_xyz[3], const double dst_white_xyz[3], double m[3][3]);
extern const double SL_WHITE_D65[3];
extern const double SL_WHITE_D50[3];
/* XYZ -> CIELAB relative to `white` (XYZ with Y = 1), and back. */
void sl_xyz_to_lab(const double xyz[3], const double white[3], double lab[3]);
void sl_lab_to_xyz(const double lab[3], const double white[3], double xyz[3]);
/* CIEDE2000 colour difference (kL = kC = kH = 1). */
double sl_ciede2000(const double lab1[3], const double lab2[3]);

/* The OCIO config shipped with setlight (SETLIGHT_OCIO_CONFIG overrides). */
const char *sl_color_config_path(void);
/* Canonical name of a colour space (aliases accepted), or NULL if unknown. */
const char *sl_color_space_name(const char *name);
/* Names of the colour spaces in the config, NULL-terminated, static. */
const char *const *sl_color_space_list(void);
/* Converts RGB(A) pixels in place through OpenColorIO. Alpha untouched.
 * SL_ERR_USAGE naming the space when either name is unknown. */
sl_result sl_color_convert(sl_image *img, const char *from, const char *to, sl_error *err);
/* How a colour space encodes light: "scene-linear", "sdr-video", "log", ...
 * (OCIO's encoding), "data" for data spaces, "" when the config says
 * nothing; NULL when the name is unknown. Static. */
const char *sl_color_space_encoding(const char *name);
/* Converts RGB(A) pixels in place from a colour space to a display's view
 * (OCIO's DisplayViewTransform; the shipped config has display sRGB with
 * views Standard and Raw). display/view NULL: the config's default display
 * and that display's default view; names match case-insensitively. Alpha
 * untouched. `applied` (may be NULL) gets "display/view". SL_ERR_USAGE
 * listing the known ones when the display or view is unknown. img NULL:
 * only checks the names. */
sl_result sl_color_display_view(sl_image *img, const char *from, const char *display,
                                const char *view, char *applied, size_t applied_size,
                                sl_error *err);
/* The EXR chromaticities (red, green, blue, white xy) of a colour space
 * (name or alias); false when it has none (raw) or is unknown. */
bool sl_color_space_chromaticities(const char *name, float xy[8]);
/* Names the colour space of an image from its metadata: the setlight:colorspace
 * attribute, then meta->colorspace when OCIO knows it, then chromaticities that
 * match a known space. NULL when the file says nothing. */
const char *sl_meta_color_space(const sl_meta *meta);
/* Sets meta->colorspace, setlight:colorspace and matching chromaticities. */
sl_result sl_meta_set_color_space(sl_meta *meta, const char *name, sl_error *err);

/* ------------------------------------------------------------------ */
/* Images as scene-linear radiance: the one way every command reads    */
/* ------------------------------------------------------------------ */

/* setlight's working space: scene-linear Rec.709 primaries, D65. */
#define SL_WORKING_SPACE "lin_rec709"

/* What reading did to a file (docs/color.md). */
typedef struct sl_read_info {
    char colorspace[64];     /* the file's colour space (OCIO name), or "chromaticities" */
    bool colorspace_assumed; /* the file names none: taken from its sample type */
    bool converted;          /* the pixels were converted to the working space */
    bool encoded;            /* ... from a non-linear encoding (sRGB, gamma, log) */
    bool latlong_assumed;    /* a 2:1 image without envmap attribute, taken as a lat-long */
} sl_read_info;

/* The colour space an image file's pixels are in: the one it names
 * (sl_meta_color_space, or OpenImageIO's oiio:ColorSpace: "sRGB" for JPEG and
 * PNG, "GammaCorrected2.2" for a PNG gAMA), else from its samples: sRGB for
 * 8/16-bit integer photos, the working space for float samples and camera
 * raw (*assumed set). NULL when the file names a space the config does not
 * know or has chromaticities of no known space. */
const char *sl_file_color_space(const sl_meta *meta, bool *assumed);
/* The file says its samples are linear light: float samples, camera raw
 * (read linear), or a scene-linear colour space it names (e.g. a linear
 * ICC profile); an assumed space does not count. */
bool sl_file_is_scene_linear(const sl_meta *meta);

/* ICC profiles: the mark of a linear-light file. sl_icc_linear_rec709 writes
 * a v4 matrix/TRC profile of Rec.709 primaries with identity tone curves
 * (what a raw converter embeds in a linear export; sl_photo_write puts it
 * in a TIFF whose meta names lin_rec709) to `out` when `size` suffices, and
 * returns its length. sl_icc_linear_space returns SL_WORKING_SPACE for a
 * profile with identity TRCs and Rec.709 primaries, else NULL. */
size_t sl_icc_linear_rec709(unsigned char *out, size_t size);
const char *sl_icc_linear_space(const unsigned char *profile, size_t size);

/* Converts an image just read (img and meta from sl_image_read of `path`) to
 * the working space: through OpenColorIO from its colour space (`from` when
 * not NULL, else sl_file_color_space), or by the 3x3 matrix of its EXR
 * chromaticities when they match no named space. A one- or two-channel
 * image needing conversion becomes RGB(A). When the pixels change, one note
 * (sl_log_note) says so (a warning for 8/16-bit files: not HDR, clipped
 * highlights), and meta then names the working space. A named space the
 * config does not know: SL_ERR_INPUT naming the file (`from` unknown:
 * SL_ERR_USAGE). info may be NULL. */
sl_result sl_image_linearize(sl_image *img, sl_meta *meta, const char *path, const char *from,
                             sl_read_info *info, sl_error *err);
/* sl_image_read then sl_image_linearize. meta and info may be NULL. */
sl_result sl_image_read_linear(const char *path, const char *from, sl_image *img, sl_meta *meta,
                               sl_read_info *info, sl_error *err);
/* An environment map: sl_image_read_linear, and meta->envmap decided: the
 * file's envmap attribute when it has one, else a 2:1 image is a lat-long
 * (a note says so), else SL_ENVMAP_NONE. */
sl_result sl_env_read(const char *path, const char *from, sl_image *img, sl_meta *meta,
                      sl_read_info *info, sl_error *err);
/* A lat-long: sl_env_read, and SL_ERR_INPUT naming the file when it is a cube
 * map or not 2:1 (nothing is returned then). */
sl_result sl_latlong_read(const char *path, const char *from, sl_image *img, sl_meta *meta,
                          sl_read_info *info, sl_error *err);

/* ------------------------------------------------------------------ */
/* Previews: scene-linear images as 8-bit pictures for people          */
/* ------------------------------------------------------------------ */

/* Auto exposure puts the median luminance here (scene-linear mid grey). */
#define SL_PREVIEW_MID_GREY 0.18

typedef struct sl_preview_options {
    const char *colorspace; /* the image's colour space; NULL: lin_rec709 */
    bool auto_exposure;     /* median luminance of the non-black texels -> mid grey */
    double exposure_stops;  /* otherwise: pixels times 2^stops */
    const char *view;       /* view of the default display; NULL: its default */
} sl_preview_options;

typedef struct sl_preview_result {
    double exposure_stops;   /* applied */
    double median_luminance; /* auto: of the texels with luminance > 0 (lin_rec709) */
    char view[128];          /* "display/view" applied */
} sl_preview_result;

/* The picture: RGB only (grey repeated; an alpha, confidence or mask channel
 * is never copied), converted to lin_rec709, scaled by 2^stops, through the
 * display view, clamped to [0, 1]. */
sl_result sl_preview_image(const sl_image *img, const sl_preview_options *opt, sl_image *out,
                           sl_preview_result *res, sl_error *err);
/* sl_preview_image written atomically as 8-bit PNG, JPEG or TIFF (by extension). */
sl_result sl_preview_write(const char *path, const sl_image *img, const sl_meta *meta,
                           const sl_preview_options *opt, sl_preview_result *res, sl_error *err);

/* ------------------------------------------------------------------ */
/* Geometry: lat-long and projections                                  */
/* ------------------------------------------------------------------ */

/* (u, v) in [0,1]^2, u along the width, v down the height.
 * longitude = pi * (1 - 2u), latitude = pi * (0.5 - v),
 * dir = (sin lon cos lat, sin lat, cos lon cos lat). */
void sl_latlong_to_dir(double u, double v, double dir[3]);
void sl_dir_to_latlong(const double dir[3], double *u, double *v);
/* Exact solid angle of one texel in row y of a width x height lat-long. */
double sl_latlong_texel_solid_angle(int y, int width, int height);
/* Bilinear lookup with longitude wrap and pole clamping. out gets channels floats. */
void sl_latlong_lookup(const sl_image *img, double u, double v, float *out);
/* True when width == 2 * height. */
bool sl_is_latlong_shape(int width, int height);

typedef enum {
    SL_PROJ_LATLONG = 0,
    SL_PROJ_MIRRORBALL, /* orthographic view of a mirror sphere, camera looking along +Z
                           (+Y up, image right -X): centre reflects -Z, rim +Z */
    SL_PROJ_ANGULAR,    /* Debevec light-probe angular map, same image axes (right -X,
                           up +Y): centre +Z (forward), angle from it pi r, rim -Z */
    SL_PROJ_CUBEMAP,    /* OpenEXR's cube map: six square faces stacked vertically
                           (width w, height 6w) in the order +X -X +Y -Y +Z -Z */
    SL_PROJ_COUNT
} sl_projection;

/* "latlong", "mirrorball", "angular", "cubemap"; -1 if unknown. */
int sl_projection_from_name(const char *name);
const char *sl_projection_name(sl_projection p);

/* Image coordinates (u,v in [0,1]) <-> direction for a projection. Returns
 * false where the (u,v) is outside the projection's valid area. */
bool sl_projection_to_dir(sl_projection p, double u, double v, double dir[3]);
bool sl_dir_to_projection(sl_projection p, const double dir[3], double *u, double *v);
/* Output size for a projection given a lat-long width: lat-long w x w/2,
 * mirror ball and angular w/2 x w/2, cube map faces of w/4 (w/4 x 6w/4). */
void sl_projection_size(sl_projection p, int latlong_width, int *width, int *height);

/* Small 3x3 linear algebra in double, row-major; out may alias an input. */
void sl_mat3_mul(const double a[3][3], const double b[3][3], double out[3][3]);
void sl_mat3_apply(const double m[3][3], const double v[3], double out[3]);
/* Inverse by cofactors; false (out untouched) when singular. */
bool sl_mat3_invert(const double m[3][3], double out[3][3]);
/* Eigenvalues of a symmetric 3x3, descending. */
void sl_mat3_sym_eigenvalues(const double a[3][3], double ev[3]);

/* Row-major 3x3 rotation: world_dir = rot * map_dir. Right-handed: a
 * positive angle about Y turns +Z toward +X. Euler: rot = Ry(yaw) Rx(pitch)
 * Rz(roll) (roll first); positive pitch turns +Y toward +Z. */
void sl_rotation_y(double degrees, double rot[3][3]);
void sl_rotation_euler(double yaw_deg, double pitch_deg, double roll_deg, double rot[3][3]);

/* Reprojects src (projection `from`) into a new image of projection `to`
 * whose lat-long-equivalent width is `width`. rot may be NULL; content at
 * source direction s lands at rot * s. Each output pixel is supersampled
 * (ss x ss) so that shrinking does not alias. */
sl_result sl_reproject(const sl_image *src, sl_projection from, sl_projection to, int width,
                       const double rot[3][3], sl_image *dst, sl_error *err);

/* ------------------------------------------------------------------ */
/* Lenses and view poses (fisheye and rectilinear views)               */
/* ------------------------------------------------------------------ */

/* Ideal radius r0 = f g(theta) of a ray theta off the optical axis. */
typedef enum {
    SL_LENS_EQUISOLID = 0, /* g = 2 sin(theta/2): 8 mm circular fisheyes (Sigma 8mm) */
    SL_LENS_EQUIDISTANT,   /* g = theta */
    SL_LENS_STEREOGRAPHIC, /* g = 2 tan(theta/2) */
    SL_LENS_ORTHOGRAPHIC,  /* g = sin theta (theta <= 90 deg) */
    SL_LENS_RECTILINEAR,   /* g = tan theta (theta < 90 deg) */
    SL_LENS_PROJECTION_COUNT
} sl_lens_projection;

/* "equisolid", "equidistant", "stereographic", "orthographic", "rectilinear";
 * -1 if unknown. */
int sl_lens_projection_from_name(const char *name);
const char *sl_lens_projection_name(sl_lens_projection p);

/* One lens on one camera body, in the pixels of a width x height image
 * ((0,0) is the top-left corner of the top-left pixel). A ray theta off the
 * axis lands at the distance r = f q (1 + k1 q^2 + k2 q^4 + k3 q^6),
 * q = g(theta), from the optical centre, in the ray's own azimuth. The
 * camera frame is OpenCV's: x image right, y image down, z forward (the
 * optical axis); right-handed. */
typedef struct sl_lens {
    sl_lens_projection projection;
    int width, height;
    double focal_px;      /* f, in pixels */
    double cx, cy;        /* optical centre in pixels (nominal: width/2, height/2) */
    double k[3];          /* radial correction k1, k2, k3 (0: the ideal projection) */
    double vignette[3];   /* gain V = 1 + v1 s^2 + v2 s^4 + v3 s^6, s = r / f, r the
                             pixel's distance from the centre (0: no falloff) */
    double max_theta_deg; /* rays further off-axis are not seen */
    double circle_radius_px; /* image circle about (cx, cy); 0 when the image has none */
} sl_lens;

/* Nominal lens from the photo's own numbers: focal_px = focal_mm * width /
 * sensor_width_mm, centre at the image centre, no correction, no falloff.
 * max_theta: 90 deg for the fisheye projections, the frame's corner for a
 * rectilinear lens; circle_radius_px: where theta = max_theta for a fisheye
 * whose circle fits inside the frame, else 0. */
void sl_lens_nominal(sl_lens *lens, sl_lens_projection p, int width, int height,
                     double focal_mm, double sensor_width_mm);
/* Distance from the centre, in pixels, of a ray theta (radians) off the axis;
 * -1 when the lens cannot image it. */
double sl_lens_radius(const sl_lens *lens, double theta);
/* Inverse of sl_lens_radius; -1 outside the lens's field. */
double sl_lens_theta(const sl_lens *lens, double radius_px);
/* Unit ray in the camera frame seen at pixel position (x, y); false outside
 * the image circle or the field. */
bool sl_lens_pixel_to_ray(const sl_lens *lens, double x, double y, double ray[3]);
/* Pixel position of a camera-frame ray (need not be unit); false when the
 * lens does not see it (beyond max_theta or off the frame). */
bool sl_lens_ray_to_pixel(const sl_lens *lens, const double ray[3], double *x, double *y);
/* Vignetting gain at pixel position (x, y): the photo's radiance is the
 * scene's times this. */
double sl_lens_vignette(const sl_lens *lens, double x, double y);

/* Where a view points: yaw (azimuth of the optical axis, 0 = +Z, 90 = +X),
 * pitch (its elevation, up positive) and roll (about the axis; positive turns
 * image right toward image up), all in degrees. At (0, 0, 0) image right is
 * -X and image up +Y, so the view looks like the middle of the lat-long. */
typedef struct sl_view_pose {
    double yaw_deg, pitch_deg, roll_deg;
} sl_view_pose;

/* world_dir = cam_to_world * camera_ray, a rotation: the columns are the
 * camera's right, down and forward axes in the world. */
void sl_view_pose_matrix(const sl_view_pose *pose, double cam_to_world[3][3]);
/* Inverse of sl_view_pose_matrix for any rotation matrix (at pitch +-90 the
 * yaw is taken as 0). */
void sl_view_pose_from_matrix(const double cam_to_world[3][3], sl_view_pose *pose);

/* ------------------------------------------------------------------ */
/* Sampling distributions (built in double precision)                  */
/* ------------------------------------------------------------------ */

typedef struct sl_distrib1d {
    int n;
    double *func;  /* n non-negative values */
    double *cdf;   /* n + 1 values, cdf[0] = 0, cdf[n] = 1 */
    double integral; /* sum(func) / n: the integral over [0,1] */
    int *guide;    /* n + 1 cut points: guide[k] = bin of u = k / n (search starts) */
} sl_distrib1d;

/* A zero or all-zero function gives a uniform distribution with integral 0.
 * NaN, Inf or negative values are SL_ERR_INPUT. */
sl_result sl_distrib1d_init(sl_distrib1d *d, const double *func, int n, sl_error *err);
void sl_distrib1d_free(sl_distrib1d *d);
/* Continuous sample in [0,1); pdf over [0,1]; offset = bin index. */
double sl_distrib1d_sample(const sl_distrib1d *d, double u, double *pdf, int *offset);
/* Discrete sample of a bin; pmf = func[i] / sum. */
int sl_distrib1d_sample_discrete(const sl_distrib1d *d, double u, double *pmf);
double sl_distrib1d_pdf(const sl_distrib1d *d, double x);

typedef struct sl_distrib2d {
    int nu, nv;
    sl_distrib1d *conditional; /* nv rows of nu */
    sl_distrib1d marginal;     /* over v */
} sl_distrib2d;

/* func is nv rows of nu values, row-major. */
sl_result sl_distrib2d_init(sl_distrib2d *d, const double *func, int nu, int nv, sl_error *err);
void sl_distrib2d_free(sl_distrib2d *d);
/* Returns (u, v) in [0,1)^2 and the pdf over the unit square. */
void sl_distrib2d_sample(const sl_distrib2d *d, double u0, double u1, double uv[2], double *pdf);
double sl_distrib2d_pdf(const sl_distrib2d *d, double u, double v);

/* Chi-square goodness of fit: p-value of `stat` with `dof` degrees of freedom. */
double sl_chi2_pvalue(double stat, int dof);

/* ------------------------------------------------------------------ */
/* Text built piece by piece                                           */
/* ------------------------------------------------------------------ */

/* A growing NUL-terminated string; {0} is empty (s NULL until the first
 * append). Out of memory sets `failed`, keeps what was there, and makes
 * every later append fail: check once at the end. */
typedef struct sl_text {
    char *s;
    size_t len, cap;
    bool failed;
} sl_text;

/* Each returns false when the text has failed. */
bool sl_text_add(sl_text *t, const char *s, size_t n);
bool sl_text_add_str(sl_text *t, const char *s);
bool sl_text_printf(sl_text *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void sl_text_free(sl_text *t);

/* ------------------------------------------------------------------ */
/* Reports: one HTML page with PNG images and SVG plots                */
/* ------------------------------------------------------------------ */

typedef struct sl_report sl_report; /* opaque */

/* Starts a report whose page will be DIR/NAME.html; images and plots are
 * written beside it. */
sl_result sl_report_new(sl_report **rep, const char *dir, const char *name, const char *title,
                        sl_error *err);
/* Writes the page atomically and frees the report (also on failure). */
sl_result sl_report_finish(sl_report *rep, sl_error *err);
void sl_report_free(sl_report *rep);
void sl_report_section(sl_report *rep, const char *title);
/* A paragraph; the text is escaped. */
void sl_report_text(sl_report *rep, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* A PNG of a lin_rec709 image: sl_preview_write at 2^stops through the
 * default view (sRGB). Written as DIR/FILE (e.g. "merge.png") and shown
 * with its caption; an image under 256 px wide is enlarged by whole pixels
 * to at least that. */
sl_result sl_report_image(sl_report *rep, const char *file, const sl_image *img, double stops,
                          const char *caption, sl_error *err);
/* A picture already written (by another step) at DIR/FILE, a path
 * relative to the page, shown WIDTH px wide (0: its own width). */
void sl_report_figure(sl_report *rep, const char *file, int width, const char *caption);
/* A paragraph linking to FILE (a path relative to the page) with TEXT. */
void sl_report_link(sl_report *rep, const char *file, const char *text);
/* A table: header then rows, every cell text (escaped). */
void sl_report_table_begin(sl_report *rep, int columns, const char *const *header);
void sl_report_table_row(sl_report *rep, const char *const *cells);
void sl_report_table_end(sl_report *rep);

typedef struct sl_plot_series {
    const char *label;
    const double *x, *y;
    int count;
} sl_plot_series;

/* An SVG line plot written as DIR/FILE and shown in the page. Log axes skip
 * non-positive values. */
sl_result sl_report_plot(sl_report *rep, const char *file, const char *title, const char *xlabel,
                         const char *ylabel, bool log_x, bool log_y, const sl_plot_series *series,
                         int series_count, sl_error *err);
/* One series of a bar chart: a value for each label (NaN: no bar). */
typedef struct sl_bar_series {
    const char *label;
    const double *values;
} sl_bar_series;

/* An SVG bar chart written as DIR/FILE and shown in the page: one group of
 * bars (one a series) for each of COUNT labels. Where notes[i] is set, the
 * group is drawn faint and marked excluded, and the note (why) is listed
 * beside the chart. notes may be NULL. */
sl_result sl_report_bars(sl_report *rep, const char *file, const char *title, const char *ylabel,
                         const char *const *labels, const char *const *notes, int count,
                         const sl_bar_series *series, int series_count, sl_error *err);
/* The summary at the top of the page: what is written between these two
 * calls goes after the title and the text before the first section, above
 * the sections written before it. */
void sl_report_top_begin(sl_report *rep);
void sl_report_top_end(sl_report *rep);
/* Writes an SVG plot file without a report (for commands like converge). */
sl_result sl_plot_write_svg(const char *path, const char *title, const char *xlabel,
                            const char *ylabel, bool log_x, bool log_y,
                            const sl_plot_series *series, int series_count, sl_error *err);

/* ------------------------------------------------------------------ */
/* Small shared helpers: JSON files, luminance, sorting, random         */
/* numbers, compensated sums, conductor Fresnel                         */
/* ------------------------------------------------------------------ */

/* jansson's value type (jansson.h), for the JSON file helpers. */
struct json_t;
/* Reads a JSON file parsed whole: sl_check_input_size against
 * SL_MAX_JSON_BYTES (`what` names the kind of file, e.g. "rig JSON"),
 * then jansson with its decoding `flags` (e.g. JSON_REJECT_DUPLICATES).
 * SL_ERR_INPUT "PATH: line N: JSON syntax error: ..." when it does not
 * parse. *out is the caller's to json_decref. */
sl_result sl_json_load_file(const char *path, const char *what, size_t flags,
                            struct json_t **out, sl_error *err);
/* Writes `root` with jansson's encoding `flags` and a final newline,
 * atomically (sl_write_file_atomic). Does not take the reference. */
sl_result sl_json_write_atomic(const char *path, const struct json_t *root, size_t flags,
                               sl_error *err);
/* The first string of a JSON array that ends with `suffix` (a job's output
 * by its file name), or NULL. */
const char *sl_json_string_ending(const struct json_t *array, const char *suffix);

/* Relative luminance of linear Rec.709 RGB (BT.709's Y row to 4 places). */
static inline double sl_luminance(const double rgb[3])
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}
/* The same of a float pixel, computed in double. */
static inline double sl_luminance_px(const float *p)
{
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}
/* The same in float arithmetic, for float buffers. */
static inline float sl_luminancef(const float *p)
{
    return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
}

/* qsort comparator of doubles, ascending (NaNs compare equal to all). */
int sl_cmp_double(const void *a, const void *b);

/* A value and where it came from, for ranking: sl_cmp_ranked_desc sorts
 * the largest value first, ties by index (a stable, repeatable order). */
typedef struct sl_ranked {
    double value;
    int64_t index;
} sl_ranked;
int sl_cmp_ranked_desc(const void *a, const void *b);

/* SplitMix64 (Steele, Lea and Flood 2014): sl_splitmix64_mix is its
 * bijective finaliser; sl_splitmix64 advances a state and returns the next
 * value; sl_splitmix64_hash(x) = mix(x + increment), a 64-bit hash. */
#define SL_SPLITMIX64_INCREMENT 0x9e3779b97f4a7c15ull
static inline uint64_t sl_splitmix64_mix(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static inline uint64_t sl_splitmix64(uint64_t *state)
{
    return sl_splitmix64_mix(*state += SL_SPLITMIX64_INCREMENT);
}
static inline uint64_t sl_splitmix64_hash(uint64_t x)
{
    return sl_splitmix64_mix(x + SL_SPLITMIX64_INCREMENT);
}

/* Neumaier's compensated sum (Kahan's, right also when an addend is larger
 * than the running sum): the total is sum + c. Zero-initialise. */
typedef struct sl_ksum {
    double sum, c;
} sl_ksum;
static inline void sl_ksum_add(sl_ksum *k, double v)
{
    double t = k->sum + v;
    if (__builtin_fabs(k->sum) >= __builtin_fabs(v))
        k->c += (k->sum - t) + v;
    else
        k->c += (v - t) + k->sum;
    k->sum = t;
}
static inline double sl_ksum_value(const sl_ksum *k)
{
    return k->sum + k->c;
}

/* Unpolarised Fresnel reflectance of a conductor of complex index n + ik
 * seen from air, at the cosine of incidence cos_i (clamped to [0, 1]): the
 * exact formula in real arithmetic (as pbrt-v3's FrConductor). The
 * renderer's metals and the unwrap's chrome ball share it. */
double sl_fresnel_conductor(double cos_i, double n, double k);

/* ------------------------------------------------------------------ */
/* Version                                                             */
/* ------------------------------------------------------------------ */

const char *sl_version(void);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_CORE_H */
