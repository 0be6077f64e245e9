/* SPDX-License-Identifier: BSD-3-Clause */
/* The one ICC profile setlight writes, and the one question it asks of a
 * profile: is this file's data linear light? Raw converters (darktable,
 * RawTherapee, dcraw's -4 -T with a profile) mark their linear TIFF exports
 * with a matrix/TRC profile whose tone curves are the identity; that mark,
 * not the file name, tells a linear export from a display-referred one. */
#include "setlight/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void put32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)(v >> 24);
    p[1] = (unsigned char)(v >> 16);
    p[2] = (unsigned char)(v >> 8);
    p[3] = (unsigned char)v;
}

static uint32_t get32(const unsigned char *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static void put_s15(unsigned char *p, double v)
{
    put32(p, (uint32_t)(int32_t)lround(v * 65536.0));
}

static double get_s15(const unsigned char *p)
{
    return (int32_t)get32(p) / 65536.0;
}

/* Rec.709 primaries adapted to the PCS white D50 (Bradford), as in the
 * sRGB profiles; chad is Bradford D65 -> D50. */
static const double colorant[3][3] = {
    {0.436066, 0.222488, 0.013916}, {0.385147, 0.716873, 0.097076}, {0.143066, 0.060608, 0.714096}};
static const double chad[9] = {1.047882, 0.022918, -0.050217, 0.029586, 0.990478,
                               -0.017075, -0.009247, 0.015075, 0.751678};
static const char profile_name[] = "Linear Rec.709 (setlight)";

/* An mluc (ICC v4 text) tag of one en-US record. */
static size_t put_text(unsigned char *p, const char *s)
{
    size_t n = strlen(s);
    memcpy(p, "mluc", 4);
    put32(p + 4, 0);
    put32(p + 8, 1);
    put32(p + 12, 12);
    memcpy(p + 16, "enUS", 4);
    put32(p + 20, (uint32_t)(2 * n));
    put32(p + 24, 28);
    for (size_t i = 0; i < n; i++) {
        p[28 + 2 * i] = 0;
        p[29 + 2 * i] = (unsigned char)s[i];
    }
    return (28 + 2 * n + 3) & ~(size_t)3;
}

static size_t put_xyz(unsigned char *p, const double xyz[3])
{
    memcpy(p, "XYZ ", 4);
    put32(p + 4, 0);
    for (int i = 0; i < 3; i++)
        put_s15(p + 8 + 4 * i, xyz[i]);
    return 20;
}

size_t sl_icc_linear_rec709(unsigned char *out, size_t size)
{
    enum { TAGS = 10 };
    unsigned char buf[1024];
    memset(buf, 0, sizeof buf);
    size_t at = 128 + 4 + 12 * TAGS;
    struct {
        const char *sig;
        size_t offset, size;
    } tag[TAGS];
    int n = 0;
#define ADD(SIG, LEN)                                                                      \
    do {                                                                                   \
        size_t len_ = (LEN);                                                               \
        tag[n].sig = (SIG);                                                                \
        tag[n].offset = at;                                                                \
        tag[n++].size = len_;                                                              \
        at += len_;                                                                        \
    } while (0)
    ADD("desc", put_text(buf + at, profile_name));
    ADD("cprt", put_text(buf + at, "No copyright, use freely"));
    ADD("wtpt", put_xyz(buf + at, SL_WHITE_D50));
    ADD("rXYZ", put_xyz(buf + at, colorant[0]));
    ADD("gXYZ", put_xyz(buf + at, colorant[1]));
    ADD("bXYZ", put_xyz(buf + at, colorant[2]));
    memcpy(buf + at, "sf32", 4);
    for (int i = 0; i < 9; i++)
        put_s15(buf + at + 8 + 4 * i, chad[i]);
    ADD("chad", 44);
    /* curv with no entries: the identity. The three TRCs share it. */
    memcpy(buf + at, "curv", 4);
    size_t trc = at;
    ADD("rTRC", 12);
    tag[n].sig = "gTRC";
    tag[n].offset = trc;
    tag[n++].size = 12;
    tag[n].sig = "bTRC";
    tag[n].offset = trc;
    tag[n++].size = 12;
#undef ADD
    put32(buf, (uint32_t)at);
    put32(buf + 8, 0x04300000); /* version 4.3 */
    memcpy(buf + 12, "mntr", 4);
    memcpy(buf + 16, "RGB ", 4);
    memcpy(buf + 20, "XYZ ", 4);
    buf[24 + 1] = (unsigned char)(2026 & 0xff); /* date 2026-01-01: fixed, same bytes */
    buf[24] = (unsigned char)(2026 >> 8);
    buf[27] = 1;
    buf[29] = 1;
    memcpy(buf + 36, "acsp", 4);
    for (int i = 0; i < 3; i++)
        put_s15(buf + 68 + 4 * i, SL_WHITE_D50[i]);
    put32(buf + 128, TAGS);
    for (int i = 0; i < TAGS; i++) {
        memcpy(buf + 132 + 12 * i, tag[i].sig, 4);
        put32(buf + 136 + 12 * i, (uint32_t)tag[i].offset);
        put32(buf + 140 + 12 * i, (uint32_t)tag[i].size);
    }
    if (out && size >= at)
        memcpy(out, buf, at);
    return at;
}

/* A TRC tag that is the identity: curv with no entries, curv with one
 * entry gamma 1.0 (u8Fixed8 0x0100), or para type 0 with gamma 1. */
static bool linear_trc(const unsigned char *p, size_t size, uint32_t offset, uint32_t len)
{
    if (offset > size || len < 12 || len > size - offset)
        return false;
    const unsigned char *t = p + offset;
    if (!memcmp(t, "curv", 4)) {
        uint32_t count = get32(t + 8);
        if (count == 0)
            return true;
        return count == 1 && len >= 14 && t[12] == 1 && t[13] == 0;
    }
    if (!memcmp(t, "para", 4) && len >= 16) {
        unsigned type = (unsigned)t[8] << 8 | t[9];
        return type == 0 && fabs(get_s15(t + 12) - 1.0) < 1e-3;
    }
    return false;
}

/* The tag's XYZ, or false. */
static bool xyz_tag(const unsigned char *p, size_t size, uint32_t offset, uint32_t len,
                    double xyz[3])
{
    if (offset > size || len < 20 || len > size - offset || memcmp(p + offset, "XYZ ", 4))
        return false;
    for (int i = 0; i < 3; i++)
        xyz[i] = get_s15(p + offset + 8 + 4 * i);
    return true;
}

const char *sl_icc_linear_space(const unsigned char *p, size_t size)
{
    if (!p || size < 132 || memcmp(p + 36, "acsp", 4) || memcmp(p + 16, "RGB ", 4))
        return NULL;
    uint32_t count = get32(p + 128);
    if (count > (size - 132) / 12)
        return NULL;
    int linear = 0, primaries = 0;
    for (uint32_t i = 0; i < count; i++) {
        const unsigned char *e = p + 132 + 12 * i;
        uint32_t offset = get32(e + 4), len = get32(e + 8);
        for (int c = 0; c < 3; c++) {
            static const char *trc[3] = {"rTRC", "gTRC", "bTRC"}, *col[3] = {"rXYZ", "gXYZ", "bXYZ"};
            double xyz[3];
            if (!memcmp(e, trc[c], 4) && linear_trc(p, size, offset, len))
                linear |= 1 << c;
            if (!memcmp(e, col[c], 4) && xyz_tag(p, size, offset, len, xyz) &&
                fabs(xyz[0] - colorant[c][0]) < 2e-3 && fabs(xyz[1] - colorant[c][1]) < 2e-3 &&
                fabs(xyz[2] - colorant[c][2]) < 2e-3)
                primaries |= 1 << c;
        }
    }
    /* Linear light with other primaries is still linear, but no space of
     * the config names it: not claimed. */
    return linear == 7 && primaries == 7 ? SL_WORKING_SPACE : NULL;
}
