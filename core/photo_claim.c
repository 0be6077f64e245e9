/* SPDX-License-Identifier: BSD-3-Clause */
/* What a photo's header claims, checked before any decoder runs (and
 * before OpenImageIO is loaded): a JPEG, PNG, TIFF or Radiance header
 * whose pixels cannot come out of a file this small is corrupt, and an
 * image over the memory budget is refused. The densest each format can
 * pack pixels (docs/formats.md, "What a header may claim"):
 *  - JPEG (Huffman): at least one bit per 8x8 block of luma, even with
 *    progressive end-of-band runs: 512 pixels a byte. Arithmetic-coded
 *    JPEG can go below a bit a block: no floor, the budget only.
 *  - PNG: deflate gives at most 1032 bytes for one (258 per 2 bits).
 *  - TIFF: uncompressed 1, PackBits 64, LZW / deflate / JPEG at most 2048
 *    decoded bytes a byte (LZW ~1340, deflate 1032, JPEG 1536 for RGB);
 *    other compressions: the budget only.
 *  - Radiance RGBE: a run of 127 pixels costs 2 bytes per component,
 *    8 bytes for 127 pixels: 16 pixels a byte. */
#include "photo_private.h"

#include <ctype.h>
#include <inttypes.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

typedef struct claim {
    const char *format;
    int64_t width, height;
    int channels;          /* decoded channels (kept: at most 4) */
    double pixels_per_byte; /* densest packing; 0: no floor */
    char corrupt[96];       /* a structure the file cannot hold: why */
} claim;

static uint32_t be16(const unsigned char *p) { return (uint32_t)p[0] << 8 | p[1]; }
static uint32_t be32(const unsigned char *p) { return be16(p) << 16 | be16(p + 2); }

static bool jpeg_claim(FILE *f, claim *c)
{
    unsigned char b[8];
    /* Segments up to the frame header; APPn (EXIF, ICC) can come first. */
    for (int segments = 0; segments < 256; segments++) {
        int m;
        do {
            if ((m = fgetc(f)) == EOF)
                return false;
        } while (m != 0xff);
        do {
            if ((m = fgetc(f)) == EOF)
                return false;
        } while (m == 0xff);
        if (m == 0x01 || (m >= 0xd0 && m <= 0xd8))
            continue; /* no length */
        if (fread(b, 1, 2, f) != 2)
            return false;
        uint32_t len = be16(b);
        if (len < 2)
            return false;
        bool sof = m >= 0xc0 && m <= 0xcf && m != 0xc4 && m != 0xc8 && m != 0xcc;
        if (!sof) {
            if (fseek(f, (long)len - 2, SEEK_CUR))
                return false;
            continue;
        }
        if (len < 8 || fread(b, 1, 6, f) != 6)
            return false;
        c->format = "JPEG";
        c->height = be16(b + 1);
        c->width = be16(b + 3);
        c->channels = b[5] > 4 ? 4 : b[5];
        bool arithmetic = m >= 0xc9 && m != 0xcc;
        c->pixels_per_byte = arithmetic ? 0 : 512;
        return c->height > 0; /* 0: the height comes later (DNL) */
    }
    return false;
}

/* Every chunk's length but the pixels' against what is left of the
 * file: libpng allocates a text or ICC chunk's claimed length before
 * reading it (a 423-byte PNG claiming a 1.4 GB tEXt cost 5 s and 1.4 GB). */
static void png_chunks(FILE *f, int64_t file_size, claim *c)
{
    unsigned char h[8];
    int64_t at = 8;
    for (int n = 0; n < 1000000 && at + 12 <= file_size; n++) {
        if (fseek(f, (long)at, SEEK_SET) || fread(h, 1, 8, f) != 8)
            return;
        int64_t len = be32(h);
        /* A cut IDAT is streamed and reported at the rows it hits. */
        if (len > file_size - at - 12 && memcmp(h + 4, "IDAT", 4)) {
            snprintf(c->corrupt, sizeof c->corrupt,
                     "its %.4s chunk claims %" PRId64 " bytes, past the file's end", (char *)h + 4,
                     len);
            return;
        }
        if (!memcmp(h + 4, "IEND", 4))
            return;
        at += 12 + len;
    }
}

static bool png_claim(FILE *f, int64_t file_size, claim *c)
{
    unsigned char b[26];
    if (fread(b, 1, sizeof b, f) != sizeof b || memcmp(b + 12, "IHDR", 4))
        return false;
    static const int channels_of_type[7] = {1, 0, 3, 1, 2, 0, 4};
    int bits = b[24], type = b[25];
    if (type > 6 || !channels_of_type[type] || bits < 1 || bits > 16)
        return false;
    int ch = channels_of_type[type];
    c->format = "PNG";
    c->width = be32(b + 16);
    c->height = be32(b + 20);
    c->channels = type == 3 ? 4 : ch; /* a palette may expand to RGBA */
    c->pixels_per_byte = 1032.0 * 8.0 / (double)(ch * bits);
    png_chunks(f, file_size, c);
    return true;
}

static uint32_t tiff16(const unsigned char *p, bool le)
{
    return le ? (uint32_t)p[1] << 8 | p[0] : be16(p);
}
static uint32_t tiff32(const unsigned char *p, bool le)
{
    return le ? tiff16(p + 2, le) << 16 | tiff16(p, le) : be32(p);
}

static bool tiff_claim(FILE *f, claim *c)
{
    unsigned char h[8], e[12];
    if (fread(h, 1, 8, f) != 8)
        return false;
    bool le = h[0] == 'I';
    if (tiff16(h + 2, le) != 42) /* BigTIFF (43): the budget only, through OpenImageIO */
        return false;
    if (fseek(f, (long)tiff32(h + 4, le), SEEK_SET) || fread(h, 1, 2, f) != 2)
        return false;
    uint32_t entries = tiff16(h, le), compression = 1, spp = 1, bits = 1;
    c->width = c->height = 0;
    for (uint32_t i = 0; i < entries && i < 4096; i++) {
        if (fread(e, 1, 12, f) != 12)
            return false;
        uint32_t tag = tiff16(e, le), type = tiff16(e + 2, le);
        /* SHORT values sit in the first two bytes of the value field; a
         * BitsPerSample list longer than two is elsewhere: taken as 8. */
        uint32_t v = type == 3 ? tiff16(e + 8, le) : tiff32(e + 8, le);
        if (tag == 258 && tiff32(e + 4, le) > 2)
            v = 8;
        if (tag == 256)
            c->width = v;
        else if (tag == 257)
            c->height = v;
        else if (tag == 258)
            bits = v;
        else if (tag == 259)
            compression = v;
        else if (tag == 277)
            spp = v;
    }
    if (bits < 1 || bits > 64 || spp < 1 || spp > 64)
        return false;
    double ratio = compression == 1       ? 1
                   : compression == 32773 ? 64 /* PackBits */
                   : compression == 5 || compression == 6 || compression == 7 ||
                           compression == 8 || compression == 32946
                       ? 2048 /* LZW, JPEG, deflate */
                       : 0;
    c->format = "TIFF";
    c->channels = spp > 4 ? 4 : (int)spp;
    c->pixels_per_byte = ratio * 8.0 / ((double)spp * (double)bits);
    return true;
}

static bool rgbe_claim(FILE *f, claim *c)
{
    char line[256];
    if (!fgets(line, sizeof line, f) || strncmp(line, "#?", 2))
        return false;
    /* Header lines up to an empty one, then "-Y H +X W" (any orientation). */
    for (int lines = 0; lines < 1024; lines++) {
        if (!fgets(line, sizeof line, f))
            return false;
        if (line[0] == '\n')
            break;
    }
    char ya, xa;
    long h, w;
    if (!fgets(line, sizeof line, f) ||
        sscanf(line, "%*[-+]%c %ld %*[-+]%c %ld", &ya, &h, &xa, &w) != 4)
        return false;
    if (toupper((unsigned char)ya) == 'X') {
        long t = h;
        h = w;
        w = t;
    }
    c->format = "Radiance";
    c->width = w;
    c->height = h;
    c->channels = 3;
    c->pixels_per_byte = 16;
    return true;
}

static sl_result claim_check(const char *path, bool with_budget, sl_error *err)
{
    struct stat st;
    FILE *f = fopen(path, "rb");
    if (!f || fstat(fileno(f), &st)) {
        if (f)
            fclose(f);
        return SL_OK; /* the reader says what is wrong */
    }
    unsigned char m[4] = {0};
    size_t n = fread(m, 1, sizeof m, f);
    claim c = {0};
    bool known = false;
    if (n >= 2 && m[0] == 0xff && m[1] == 0xd8)
        known = !fseek(f, 2, SEEK_SET) && jpeg_claim(f, &c);
    else if (n == 4 && m[0] == 0x89 && !memcmp(m + 1, "PNG", 3))
        known = !fseek(f, 0, SEEK_SET) && png_claim(f, (int64_t)st.st_size, &c);
    else if (n == 4 && (!memcmp(m, "II", 2) || !memcmp(m, "MM", 2)))
        known = !fseek(f, 0, SEEK_SET) && tiff_claim(f, &c);
    else if (n >= 2 && m[0] == '#' && m[1] == '?')
        known = !fseek(f, 0, SEEK_SET) && rgbe_claim(f, &c);
    fclose(f);
    if (known && c.corrupt[0])
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt %s: %s", path, c.format,
                            c.corrupt);
    /* A size the decoder would refuse anyway is left to it. */
    if (!known || c.width <= 0 || c.height <= 0)
        return SL_OK;
    double pixels = (double)c.width * (double)c.height;
    double most = (double)st.st_size * c.pixels_per_byte;
    if (c.pixels_per_byte > 0 && pixels > most)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: truncated or corrupt %s: its header claims %" PRId64 "x%" PRId64
                            " pixels, more than a %lld-byte %s file can hold (%.0f at most)",
                            path, c.format, c.width, c.height, (long long)st.st_size, c.format,
                            most);
    if (!with_budget)
        return SL_OK;
    char what[96];
    snprintf(what, sizeof what, "a %" PRId64 "x%" PRId64 " %s image", c.width, c.height, c.format);
    return sl_memory_check((uint64_t)c.width * (uint64_t)c.height * (uint64_t)c.channels *
                               sizeof(float),
                           path, what, err);
}

sl_result sl_photo_claim_check(const char *path, sl_error *err)
{
    return claim_check(path, true, err);
}

sl_result sl_photo_structure_check(const char *path, sl_error *err)
{
    return claim_check(path, false, err);
}
