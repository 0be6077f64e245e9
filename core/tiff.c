/* SPDX-License-Identifier: BSD-3-Clause */
/* TIFF directories in memory (core.h): EXIF in JPEGs (photo_jpeg.c), and
 * capture's reading of serial numbers and sub-second times. */
#include "setlight/core.h"

#include <string.h>

bool sl_tiff_u16(const sl_tiff *t, size_t at, unsigned *v)
{
    if (at > t->n || t->n - at < 2)
        return false;
    const unsigned char *q = t->p + at;
    *v = t->big ? (unsigned)(q[0] << 8 | q[1]) : (unsigned)(q[1] << 8 | q[0]);
    return true;
}

bool sl_tiff_u32(const sl_tiff *t, size_t at, unsigned long *v)
{
    if (at > t->n || t->n - at < 4)
        return false;
    const unsigned char *q = t->p + at;
    *v = t->big ? (unsigned long)q[0] << 24 | (unsigned long)q[1] << 16 |
                      (unsigned long)q[2] << 8 | q[3]
                : (unsigned long)q[3] << 24 | (unsigned long)q[2] << 16 |
                      (unsigned long)q[1] << 8 | q[0];
    return true;
}

bool sl_tiff_entry(const sl_tiff *t, unsigned long ifd, unsigned i, unsigned *tag,
                   unsigned *type, unsigned long *count, size_t *value_at)
{
    unsigned n;
    if (!sl_tiff_u16(t, ifd, &n) || i >= n)
        return false;
    size_t e = ifd + 2 + 12 * (size_t)i;
    if (!sl_tiff_u16(t, e, tag) || !sl_tiff_u16(t, e + 2, type) || !sl_tiff_u32(t, e + 4, count))
        return false;
    static const int size[] = {0, 1, 1, 2, 4, 8, 1, 1, 2, 4, 8, 4, 8};
    if (*type >= 13 || *count > t->n)
        return false;
    size_t bytes = (size_t)size[*type] * *count;
    unsigned long off;
    if (bytes <= 4)
        *value_at = e + 8;
    else if (sl_tiff_u32(t, e + 8, &off))
        *value_at = off;
    else
        return false;
    return *value_at <= t->n && bytes <= t->n - *value_at;
}

bool sl_tiff_find(const sl_tiff *t, unsigned long ifd, unsigned tag, unsigned *type,
                  unsigned long *count, size_t *value_at)
{
    unsigned n, tg;
    if (!sl_tiff_u16(t, ifd, &n))
        return false;
    for (unsigned i = 0; i < n; i++) {
        size_t e = ifd + 2 + 12 * (size_t)i;
        if (!sl_tiff_u16(t, e, &tg))
            return false;
        if (tg == tag)
            return sl_tiff_entry(t, ifd, i, &tg, type, count, value_at);
    }
    return false;
}

bool sl_tiff_open(const unsigned char *p, size_t n, sl_tiff *t, unsigned long *ifd0)
{
    if (n < 8 || (memcmp(p, "MM\0*", 4) && memcmp(p, "II*\0", 4)))
        return false;
    *t = (sl_tiff){p, n, p[0] == 'M'};
    return sl_tiff_u32(t, 4, ifd0);
}
