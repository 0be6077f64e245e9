/* SPDX-License-Identifier: BSD-3-Clause */
/* A virtual-set scene file (docs/virtual-set.md) as `simulate --scene
 * FILE.json` reads it (sl_vset_desc_read_json, which validates it). */
#include "fuzz.h"
#include "setlight/vset.h"

int sl_fuzz_vset_scene(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("vset.json", data, size);
    if (!path)
        return 0;
    sl_vset_desc desc;
    sl_error err = {0};
    sl_vset_desc_read_json(path, &desc, &err);
    return 0;
}
