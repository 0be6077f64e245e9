/* SPDX-License-Identifier: BSD-3-Clause */
/* A response-curve file as `merge --response CRF.json` reads it
 * (sl_response_read, docs/merge.md), then evaluated across its range as
 * the merge does. */
#include "fuzz.h"
#include "setlight/stitch.h"

int sl_fuzz_response_json(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("crf.json", data, size);
    if (!path)
        return 0;
    sl_response resp = {0};
    sl_error err = {0};
    if (sl_response_read(path, &resp, &err) == SL_OK) {
        for (int c = 0; c < resp.channels; c++)
            for (int z = 0; z <= 256; z++)
                (void)sl_response_eval(&resp, c, z / 256.0);
        sl_response_free(&resp);
    }
    return 0;
}
