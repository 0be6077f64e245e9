/* SPDX-License-Identifier: BSD-3-Clause */
/* The fuzz targets: one function per parser a user can feed a file to, each
 * taking the file's bytes through the library call a command makes on it.
 * fuzz/main.c wraps one as libFuzzer's entry point (-DSETLIGHT_FUZZ=ON);
 * tests/test_fuzz_regressions.c replays the kept inputs through all of them
 * in the ordinary build. A target returns 0; a bug shows as a crash or a
 * sanitizer report. */
#ifndef SETLIGHT_FUZZ_H
#define SETLIGHT_FUZZ_H

#include <stddef.h>
#include <stdint.h>

#include "setlight/core.h"

typedef int (*sl_fuzz_fn)(const uint8_t *data, size_t size);

typedef struct sl_fuzz_target {
    const char *name; /* fuzz_<name>.c, fuzz/corpus/<name>/, tests/fuzz_regressions/<name>/ */
    sl_fuzz_fn run;
} sl_fuzz_target;

/* Every target, ended by {NULL, NULL}. */
extern const sl_fuzz_target sl_fuzz_targets[];

/* Once per process: quiet logs, one thread (each input costs the same and
 * runs the same way every time), a private folder for the inputs. */
void sl_fuzz_init(void);
/* The bytes as the file `name` in that folder (replaced each call); its path,
 * valid until the next call. NULL when it cannot be written. */
const char *sl_fuzz_file(const char *name, const uint8_t *data, size_t size);
/* The private folder (a session folder for the journal target). */
const char *sl_fuzz_dir(void);
/* The bytes as the image file `name`, read by `read` (an image and its
 * metadata, freed after). */
typedef sl_result (*sl_fuzz_image_reader)(const char *path, sl_image *img, sl_meta *meta,
                                          sl_error *err);
void sl_fuzz_image(const char *name, const uint8_t *data, size_t size, sl_fuzz_image_reader read);

#define SL_FUZZ_DECLARE(name) int sl_fuzz_##name(const uint8_t *data, size_t size);
SL_FUZZ_DECLARE(exr)
SL_FUZZ_DECLARE(hdr)
SL_FUZZ_DECLARE(photo)
SL_FUZZ_DECLARE(ingest)
SL_FUZZ_DECLARE(scene_json)
SL_FUZZ_DECLARE(vset_scene)
SL_FUZZ_DECLARE(rig_json)
SL_FUZZ_DECLARE(journal)
SL_FUZZ_DECLARE(response_json)
SL_FUZZ_DECLARE(response_text)
SL_FUZZ_DECLARE(chart_reference)
SL_FUZZ_DECLARE(lens_profile)
SL_FUZZ_DECLARE(job_graph)
#undef SL_FUZZ_DECLARE

#endif
