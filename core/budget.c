/* SPDX-License-Identifier: BSD-3-Clause */
/* The memory budget every reader consults before it allocates what a file's
 * header claims (docs/conventions.md). The default is half the memory the
 * process may use: the machine's RAM, or a smaller cgroup limit. */
#include "setlight/core.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

static uint64_t budget_bytes; /* 0: the default */

/* cgroup v2's memory.max for this process, UINT64_MAX when unlimited or
 * unreadable. */
static uint64_t cgroup_limit(void)
{
    FILE *f = fopen("/sys/fs/cgroup/memory.max", "r");
    if (!f)
        return UINT64_MAX;
    char line[64] = "";
    uint64_t v = UINT64_MAX;
    if (fgets(line, sizeof line, f)) {
        char *end;
        unsigned long long n = strtoull(line, &end, 10);
        if (end != line && n > 0)
            v = (uint64_t)n;
    }
    fclose(f);
    return v;
}

uint64_t sl_memory_budget_default(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    uint64_t ram = pages > 0 && page > 0 ? (uint64_t)pages * (uint64_t)page : (uint64_t)8 << 30;
    uint64_t cg = cgroup_limit();
    if (cg < ram)
        ram = cg;
    return ram / 2;
}

void sl_memory_budget_set(uint64_t bytes) { budget_bytes = bytes; }

uint64_t sl_memory_budget(void)
{
    return budget_bytes ? budget_bytes : sl_memory_budget_default();
}

static double megabytes(uint64_t bytes) { return (double)bytes / (1024.0 * 1024.0); }

sl_result sl_memory_check(uint64_t bytes, const char *path, const char *what, sl_error *err)
{
    uint64_t budget = sl_memory_budget();
    if (bytes <= budget)
        return SL_OK;
    return sl_error_set(err, SL_ERR_INPUT,
                        "%s: %s needs %.0f MB, over the memory budget of %.0f MB "
                        "(--max-memory-mb, SETLIGHT_MAX_MEMORY_MB)",
                        path ? path : "(input)", what, megabytes(bytes), megabytes(budget));
}

sl_result sl_check_input_size(const char *path, uint64_t max_bytes, const char *what,
                              sl_error *err)
{
    sl_result r = sl_check_input_file(path, err);
    struct stat st;
    if (r || stat(path, &st))
        return r;
    if ((uint64_t)st.st_size <= max_bytes)
        return SL_OK;
    return sl_error_set(err, SL_ERR_INPUT, "%s: %.0f MB, larger than a %s may be (%.0f MB)", path,
                        megabytes((uint64_t)st.st_size), what, megabytes(max_bytes));
}
