/* SPDX-License-Identifier: BSD-3-Clause */
/* A rig.json (what `rig --json` writes, docs/lightrig.md) as `render --rig`
 * reads it (sl_scene_read_rig). Its textures and dome file resolve next to
 * it, where no image is: those references fail as missing files. */
#include "fuzz.h"
#include "setlight/render.h"

int sl_fuzz_rig_json(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("rig.json", data, size);
    if (!path)
        return 0;
    sl_scene scene;
    sl_scene_init(&scene);
    sl_error err = {0};
    sl_scene_read_rig(&scene, path, &err);
    sl_scene_free(&scene);
    return 0;
}
