/* SPDX-License-Identifier: BSD-3-Clause */
/* What every target shares: setup once and the input written as a file
 * (the parsers take paths, as the commands give them). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz.h"

static char fuzz_dir[4096];

static void remove_fuzz_dir(void)
{
    if (fuzz_dir[0])
        sl_remove_tree(fuzz_dir);
}

void sl_fuzz_init(void)
{
    if (fuzz_dir[0])
        return;
    sl_log_set_quiet(true);
    sl_log_set_level(SL_LOG_ERROR);
    sl_threads_set(1);
    /* Under libFuzzer's 2 GB RSS limit: a legal claim within the default
     * budget (half the RAM) would otherwise show as an out-of-memory. */
    sl_memory_budget_set((uint64_t)1 << 30);
    const char *tmp = getenv("TMPDIR");
    snprintf(fuzz_dir, sizeof fuzz_dir, "%s/setlight-fuzz-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(fuzz_dir)) {
        perror(fuzz_dir);
        abort(); /* no folder: every input would be a false "not found" */
    }
    atexit(remove_fuzz_dir);
}

const char *sl_fuzz_dir(void)
{
    return fuzz_dir;
}

const char *sl_fuzz_file(const char *name, const uint8_t *data, size_t size)
{
    static char path[4096 + 64];
    snprintf(path, sizeof path, "%s/%s", fuzz_dir, name);
    FILE *f = fopen(path, "wb");
    if (!f)
        return NULL;
    bool ok = fwrite(data, 1, size, f) == size;
    ok = fclose(f) == 0 && ok;
    return ok ? path : NULL;
}

void sl_fuzz_image(const char *name, const uint8_t *data, size_t size, sl_fuzz_image_reader read)
{
    const char *path = sl_fuzz_file(name, data, size);
    if (!path)
        return;
    sl_image img = {0};
    sl_meta meta;
    sl_meta_init(&meta);
    sl_error err = {0};
    read(path, &img, &meta, &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
}
