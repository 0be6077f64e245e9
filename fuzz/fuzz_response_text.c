/* SPDX-License-Identifier: BSD-3-Clause */
/* A camera-response text file as `simulate --response FILE` reads it
 * (sl_vset_response_load): the DoRF database format (name, type, "I =",
 * samples, "B =", samples) or plain "I B" lines; then applied and inverted
 * across the range as the simulated camera does. */
#include "fuzz.h"
#include "setlight/vset.h"

int sl_fuzz_response_text(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("crf.txt", data, size);
    if (!path)
        return 0;
    sl_vset_response resp;
    sl_error err = {0};
    if (sl_vset_response_load(path, NULL, &resp, &err) == SL_OK)
        for (int k = 0; k <= 256; k++) {
            (void)sl_vset_response_apply(&resp, k / 256.0);
            (void)sl_vset_response_invert(&resp, k / 256.0);
        }
    return 0;
}
