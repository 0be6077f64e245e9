/* SPDX-License-Identifier: BSD-3-Clause */
/* JPEG blocks spoilt by a saturated pixel. A JPEG codes 8x8 blocks of
 * luma and, with subsampled chroma, 16x16 (4:2:0) or 16x8 (4:2:2) blocks
 * of colour (the MCU), aligned to the image origin. A clipped light's
 * DCT ringing and its colour, averaged into the block's chroma, spread
 * over the block's other pixels, whose codes then stop being a function
 * of their exposure. */
#include <string.h>

#include "merge_private.h"

/* A block overexposed by more than this factor (linear, over the saturation
 * code's value) is spoilt. */
#define SPOIL_EXCESS 2.0

void merge_block_max(const void *buf, int code_bytes, double top, int width, int rows, int bw,
                     int bh, float *out)
{
    int nbx = (width + bw - 1) / bw, nby = (rows + bh - 1) / bh;
    memset(out, 0, (size_t)nbx * nby * sizeof *out);
    float scale = code_bytes ? (float)(1 / top) : 1.0f;
    for (int y = 0; y < rows; y++) {
        float *row = out + (size_t)(y / bh) * nbx;
        size_t at = (size_t)y * width * 3;
        for (int x = 0; x < width; x++, at += 3) {
            float v;
            if (code_bytes == 1) {
                const uint8_t *q = (const uint8_t *)buf + at;
                int k = q[0] > q[1] ? q[0] : q[1];
                v = (float)(k > q[2] ? k : q[2]) * scale;
            } else if (code_bytes == 2) {
                const uint16_t *q = (const uint16_t *)buf + at;
                int k = q[0] > q[1] ? q[0] : q[1];
                v = (float)(k > q[2] ? k : q[2]) * scale;
            } else {
                const float *f = (const float *)buf + at;
                v = fmaxf(f[0], fmaxf(f[1], f[2]));
            }
            if (v > row[x / bw])
                row[x / bw] = v;
        }
    }
}

/* The brightest code of frame i's block holding pixel pos. */
static float block_at(const merge_ctx *m, int i, int64_t pos)
{
    int bw = m->block[2 * i], bh = m->block[2 * i + 1];
    int x = (int)(pos % m->width), y = (int)(pos / m->width);
    return m->block_max[i][(size_t)(y / bh) * ((m->width + bw - 1) / bw) + x / bw];
}

bool merge_block_spoilt(const merge_ctx *m, const sl_response *resp, const double *loge, int r,
                        int64_t pos)
{
    int i = m->order[r];
    if (!m->block_max[i] || block_at(m, i, pos) < m->saturation)
        return false;
    int s = r > 0 ? m->order[r - 1] : -1;
    if (s < 0 || !m->block_max[s])
        return true;
    float z = block_at(m, s, pos);
    if (z >= m->saturation)
        return true;
    double y = 0, ysat = 0;
    for (int c = 0; c < 3; c++) {
        y = fmax(y, sl_response_eval(resp, c, z));
        ysat = fmax(ysat, sl_response_eval(resp, c, m->saturation));
    }
    return y * exp(loge[r] - loge[r - 1]) > SPOIL_EXCESS * ysat;
}
