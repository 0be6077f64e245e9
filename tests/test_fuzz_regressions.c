/* SPDX-License-Identifier: BSD-3-Clause */
/* Every input the fuzzers kept, replayed through its target without
 * libFuzzer: the crashes found (tests/fuzz_regressions/<target>/, each
 * fixed) and the seed corpora (fuzz/corpus/<target>/, files the parsers
 * must take). A regression shows as a crash here, or as a sanitizer report
 * in CI's AddressSanitizer pass. */
#include <dirent.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz.h"
#include "testing.h"

static int cmp_names(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Runs every file of dir through target, in name order; how many. */
static int replay_dir(const sl_fuzz_target *target, const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    char *names[4096];
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < 4096)
        if (e->d_name[0] != '.')
            names[n++] = strdup(e->d_name);
    closedir(d);
    qsort(names, (size_t)n, sizeof *names, cmp_names);
    int done = 0;
    for (int i = 0; i < n; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        size_t size = 0;
        char *data = sl_test_read_file(path, &size);
        CHECK_MSG(data != NULL, "%s: cannot be read", path);
        if (data) {
            printf("  %s %s\n", target->name, names[i]);
            fflush(stdout); /* the last name printed is the one that crashed */
            CHECK(target->run((const uint8_t *)data, size) == 0);
            done++;
        }
        free(data);
        free(names[i]);
    }
    return done;
}

static void test_replay(void)
{
    int targets = 0;
    for (const sl_fuzz_target *t = sl_fuzz_targets; t->name; t++, targets++) {
        char dir[4096];
        snprintf(dir, sizeof dir, "%s/fuzz/corpus/%s", SETLIGHT_SOURCE_DIR, t->name);
        int seeds = replay_dir(t, dir);
        /* every target has seeds (fuzz/seed.sh): a missing corpus is a mistake */
        CHECK_MSG(seeds >= 2, "%s: %d seeds in %s", t->name, seeds, dir);
        snprintf(dir, sizeof dir, "%s/tests/fuzz_regressions/%s", SETLIGHT_SOURCE_DIR, t->name);
        replay_dir(t, dir);
    }
    CHECK(targets == 13);
}

int main(void)
{
    sl_fuzz_init();
    RUN(test_replay);
    return sl_test_finish();
}
