/* SPDX-License-Identifier: BSD-3-Clause */
/* A job graph (what `process --emit-jobs` writes, docs/process.md) as
 * `setlight job`, `process-report` and `process-index` read it: the bytes
 * straight to sl_pipeline_graph_parse, the call their loader makes (no file,
 * nothing run), then every job in dependency order. */
#include "fuzz.h"
#include "setlight/pipeline.h"

int sl_fuzz_job_graph(const uint8_t *data, size_t size)
{
    sl_pipeline_graph *graph = NULL;
    sl_error err = {0};
    if (sl_pipeline_graph_parse("jobs.json", (const char *)data, size, &graph, &err) == SL_OK) {
        int n = sl_pipeline_graph_job_count(graph);
        for (int k = 0; k < n; k++)
            if (!sl_pipeline_graph_job_id(graph, k))
                __builtin_trap(); /* a parsed graph names every job */
    }
    sl_pipeline_graph_free(graph);
    return 0;
}
