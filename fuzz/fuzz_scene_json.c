/* SPDX-License-Identifier: BSD-3-Clause */
/* A render scene file (docs/render.md) as `render --scene FILE.json` reads
 * it (sl_scene_read_json), 64 pixels wide. */
#include "fuzz.h"
#include "setlight/render.h"

int sl_fuzz_scene_json(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("scene.json", data, size);
    if (!path)
        return 0;
    sl_scene scene;
    sl_scene_init(&scene);
    sl_error err = {0};
    sl_scene_read_json(&scene, path, 64, &err);
    sl_scene_free(&scene);
    return 0;
}
