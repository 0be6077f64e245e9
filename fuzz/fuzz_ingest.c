/* SPDX-License-Identifier: BSD-3-Clause */
/* A photo on a card as `ingest` reads it (sl_ingest): OpenImageIO's
 * metadata, then capture's own EXIF/TIFF reader for what that does not
 * carry (SubSecTimeOriginal, body and lens serials, maker notes), then the
 * grouping and session.json. The photo is named by its magic bytes. */
#include <string.h>
#include <sys/stat.h>

#include "fuzz.h"
#include "setlight/capture.h"

int sl_fuzz_ingest(const uint8_t *data, size_t size)
{
    char card[4096 + 16], dst[4096 + 16];
    snprintf(card, sizeof card, "%s/card", sl_fuzz_dir());
    snprintf(dst, sizeof dst, "%s/ingested", sl_fuzz_dir());
    sl_remove_tree(dst);
    mkdir(card, 0700);
    const char *name = size >= 4 && !memcmp(data, "II*", 4)     ? "card/IMG_0001.tif"
                       : size >= 4 && !memcmp(data, "MM\0*", 4) ? "card/IMG_0001.tif"
                                                                : "card/IMG_0001.jpg";
    if (!sl_fuzz_file(name, data, size))
        return 0;
    int frames = 0, views = 0;
    sl_error err = {0};
    sl_ingest(card, dst, 0, NULL, &frames, &views, &err);
    return 0;
}
