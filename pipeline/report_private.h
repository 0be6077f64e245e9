/* SPDX-License-Identifier: BSD-3-Clause */
/* The setups' summaries: what the report, the index and --json show. */
#ifndef SETLIGHT_PIPELINE_REPORT_PRIVATE_H
#define SETLIGHT_PIPELINE_REPORT_PRIVATE_H

#include "pipeline_private.h"

/* A setup's summary (new reference): its status and reason, outputs, key
 * numbers from its jobs' results, warnings from their logs, each job's
 * status and cost. entry: the planner's (OUT/setups.json); status: job id
 * -> state of this run, or NULL to take the states from the stamps. */
json_t *pl_setup_summary(const json_t *graph, const json_t *entry, const json_t *status);

#endif
