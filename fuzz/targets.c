/* SPDX-License-Identifier: BSD-3-Clause */
/* Every fuzz target by name (tests/test_fuzz_regressions.c replays them). */
#include "fuzz.h"

#define TARGET(name) {#name, sl_fuzz_##name}
const sl_fuzz_target sl_fuzz_targets[] = {
    TARGET(exr),        TARGET(hdr),           TARGET(photo),         TARGET(ingest),
    TARGET(scene_json), TARGET(vset_scene),    TARGET(rig_json),      TARGET(journal),
    TARGET(response_json), TARGET(response_text), TARGET(chart_reference), TARGET(lens_profile),
    TARGET(job_graph),
    {NULL, NULL},
};
