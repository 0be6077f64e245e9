/* SPDX-License-Identifier: BSD-3-Clause */
/* Frames kept between the passes without their saturated pixels: a long
 * exposure is mostly saturated, and the merge gives a saturated pixel of
 * any frame but the shortest no weight and never reads its codes, so such a
 * frame costs a bit per pixel plus its unsaturated pixels instead of a
 * second decode. */
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"

sl_result merge_packed_init(merge_packed *pk, int height, size_t cap)
{
    memset(pk, 0, sizeof *pk);
    pk->cap = cap;
    /* Untouched pages cost nothing: the cap is reserved, not filled. */
    pk->data = malloc(cap);
    pk->row_end = calloc((size_t)height, sizeof *pk->row_end);
    if (!pk->data || !pk->row_end) {
        merge_packed_free(pk);
        return SL_ERR_NOMEM;
    }
    return SL_OK;
}

void merge_packed_free(merge_packed *pk)
{
    free(pk->data);
    free(pk->row_end);
    memset(pk, 0, sizeof *pk);
}

bool merge_pack_rows(merge_packed *pk, const uint8_t *codes, int width, int rows, int sat_code)
{
    size_t bitmap = ((size_t)width + 7) / 8;
    for (int y = 0; y < rows && pk->data; y++) {
        const uint8_t *q = codes + (size_t)y * width * 3;
        size_t at = pk->rows ? pk->row_end[pk->rows - 1] : 0;
        if (at + bitmap + (size_t)width * 3 > pk->cap) {
            merge_packed_free(pk); /* over its budget: decoded again */
            return false;
        }
        uint8_t *bits = pk->data + at, *out = bits + bitmap;
        memset(bits, 0, bitmap);
        for (int x = 0; x < width; x++, q += 3) {
            int qm = q[0] > q[1] ? q[0] : q[1];
            if ((qm > q[2] ? qm : q[2]) >= sat_code) {
                bits[x >> 3] |= (uint8_t)(1 << (x & 7));
                continue;
            }
            memcpy(out, q, 3);
            out += 3;
        }
        pk->row_end[pk->rows++] = (size_t)(out - pk->data);
    }
    return pk->data != NULL;
}

void merge_unpack_rows(const merge_packed *pk, int width, int y0, int y1, uint8_t *codes)
{
    size_t bitmap = ((size_t)width + 7) / 8;
    for (int y = y0; y < y1; y++) {
        const uint8_t *bits = pk->data + (y ? pk->row_end[y - 1] : 0), *in = bits + bitmap;
        uint8_t *q = codes + (size_t)(y - y0) * width * 3;
        for (int x = 0; x < width; x++, q += 3) {
            if (bits[x >> 3] >> (x & 7) & 1) {
                memset(q, 255, 3);
                continue;
            }
            memcpy(q, in, 3);
            in += 3;
        }
    }
}
