/* SPDX-License-Identifier: BSD-3-Clause */
/* The capture fault matrix (issue 22): each fault a real shoot meets - the
 * link dropping, the camera answering busy, a shutter change acknowledged
 * but not applied, the disk filling - injected at every one of the 21
 * frames of a 3 x 7 plan in turn. A fault the capture absorbs (busy,
 * ignored setting) leaves a whole session; one that stops it (drop, disk
 * full) leaves every frame before it journalled and on disk, and --resume
 * completes the session: 0 frames lost, 0 duplicated, every file on disk
 * with its checksum, no temporary file left. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "capture_check.h"
#include "setlight/vset.h"
#include "testing.h"

#define VIEWS 3
#define COUNT 7
#define FRAMES (VIEWS * COUNT)

typedef enum { FAULT_DROP, FAULT_BUSY, FAULT_IGNORED, FAULT_DISK_FULL, FAULT_KINDS } fault_kind;
static const char *const fault_names[FAULT_KINDS] = {"drop", "busy", "ignored", "diskfull"};

/* Files whose name says they are a writer's temporary. */
static int temp_files(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += strstr(e->d_name, "sl-tmp") != NULL;
    if (d)
        closedir(d);
    return n;
}

/* Accepted frame events, and those at (view, index). */
static int accepted(const char *dir, int view, int index, int *at)
{
    json_t *j = cap_journal(dir), *acc = cap_events(j, "frame", 1), *e;
    size_t i;
    *at = 0;
    json_array_foreach(acc, i, e)*at +=
        cap_ival(e, "view") == view && cap_ival(e, "index") == index;
    int n = (int)json_array_size(acc);
    json_decref(acc);
    json_decref(j);
    return n;
}

/* Where the 84 sessions go: a capture fsyncs every frame and journal line
 * (6000 in all, a minute on a disk), which is not what is tested here, so
 * a memory file system when there is one. */
static char base[4096];

static void choose_base(void)
{
    snprintf(base, sizeof base, "/dev/shm/setlight_faults_XXXXXX");
    if (!mkdtemp(base))
        snprintf(base, sizeof base, "%s", sl_test_path("faults"));
}

/* 96 x 64 frames (smaller leave too few mid-tones to measure a ratio on). */
static void small_camera(sl_virtual_camera_opts *vo)
{
    cap_vopts(vo);
    vo->width = 96;
    vo->height = 64;
}

/* A working camera of that size (NULL after a failed CHECK). */
static sl_camera *open_small(void)
{
    sl_virtual_camera_opts vo;
    small_camera(&vo);
    return cap_open_virtual(&vo);
}

/* Frame q (0-based in shooting order) meets the fault; the capture either
 * absorbs it or stops and is resumed with a camera that works. */
static void run_fault(fault_kind kind, int q, const double *times)
{
    char name[64], dir[4200];
    snprintf(name, sizeof name, "%s_%02d", fault_names[kind], q);
    snprintf(dir, sizeof dir, "%s/%s", base, name);
    sl_virtual_camera_opts vo;
    small_camera(&vo);
    sl_capture_options o = cap_options(dir, times, COUNT, VIEWS);
    o.reconnect_seconds = -1; /* a dropped link stops the run at once */
    sl_result want = SL_OK;
    switch (kind) {
    case FAULT_DROP:
        vo.drop_at = q + 1;
        vo.down_attempts = -1;
        want = SL_ERR_CAMERA;
        break;
    case FAULT_BUSY:
        vo.busy = 3; /* within the 10 retries: absorbed */
        vo.busy_at = q + 1;
        break;
    case FAULT_IGNORED:
        vo.ignore_shutter = q + 1; /* every frame changes the speed */
        break;
    case FAULT_DISK_FULL:
        o.disk_full_at = q + 1;
        want = SL_ERR_IO;
        break;
    default:
        break;
    }
    sl_camera *cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    sl_error err;
    sl_result r = sl_capture_run(cam, &o, &err);
    sl_camera_close(cam);
    CHECK_MSG(r == want, "%s: %s (want %s): %s", name, sl_result_name(r), sl_result_name(want),
              r ? err.message : "");
    int at, n = accepted(dir, q / COUNT, q % COUNT, &at);
    if (want != SL_OK) {
        /* stopped at frame q: the frames before it kept, it not taken */
        CHECK_MSG(n == q && at == 0, "%s: %d frames accepted before the fault", name, n);
        CHECK(!strchr(err.message, '\n'));
        if (!(cam = open_small()))
            return;
        char jp[4300];
        snprintf(jp, sizeof jp, "%s/journal.jsonl", dir);
        size_t before_size;
        char *before = sl_test_read_file(jp, &before_size);
        sl_capture_options ro;
        memset(&ro, 0, sizeof ro);
        ro.reconnect_seconds = -1;
        CHECK_OK(sl_capture_resume(cam, &ro, dir, &err), &err);
        sl_camera_close(cam);
        /* append-only: the journal before the resume is a prefix of it after */
        char *after = sl_test_read_file(jp, NULL);
        CHECK_MSG(before && after && !strncmp(before, after, before_size),
                  "%s: the resume rewrote the journal", name);
        free(before);
        free(after);
    }
    if (kind == FAULT_IGNORED) {
        /* the wrong frame is rejected and shot again */
        json_t *j = cap_journal(dir), *rej = cap_events(j, "frame", 0);
        CHECK_MSG(json_array_size(rej) == 1 &&
                      cap_ival(json_array_get(rej, 0), "view") == q / COUNT &&
                      cap_ival(json_array_get(rej, 0), "index") == q % COUNT,
                  "%s: %zu frames rejected", name, json_array_size(rej));
        json_decref(rej);
        json_decref(j);
    }
    if (kind == FAULT_BUSY) {
        json_t *j = cap_journal(dir), *acc = cap_events(j, "frame", 1);
        json_t *e = json_array_get(acc, (size_t)q);
        CHECK_MSG(cap_ival(e, "busy_retries") == 3 && cap_ival(e, "view") == q / COUNT &&
                      cap_ival(e, "index") == q % COUNT,
                  "%s: busy retries not at the frame", name);
        json_decref(acc);
        json_decref(j);
    }
    /* 0 lost, 0 duplicated; every file on disk with its checksum */
    cap_check_session(dir, VIEWS, COUNT, times);
    CHECK_MSG(temp_files(dir) == 0, "%s: temporary files left", name);
    /* the frames, the journal and session.json; rejected shots keep theirs */
    int rejected = kind == FAULT_IGNORED;
    CHECK_MSG(sl_test_count_files(dir) == FRAMES + rejected + 2, "%s: %d files", name,
              sl_test_count_files(dir));
}

static void test_fault_matrix(void)
{
    sl_camera *cam = open_small();
    if (!cam)
        return;
    double *times;
    int n = cap_plan_of(cam, "7x2", 1.0 / 125, &times);
    sl_camera_close(cam);
    CHECK(n == COUNT);
    choose_base();
    double t0 = sl_seconds();
    for (int k = 0; k < FAULT_KINDS && n == COUNT; k++)
        for (int q = 0; q < FRAMES; q++)
            run_fault((fault_kind)k, q, times);
    printf("%d faults x %d frames, each resumed or absorbed: %.1f s in %s\n", FAULT_KINDS, FRAMES,
           sl_seconds() - t0, base);
    free(times);
    if (sl_test_failed == 0)
        sl_remove_tree(base);
}

/* A journal's plan over the bracket limit, or a journal over its size
 * limit: refused before anything is allocated for it or shot. */
static void test_journal_caps(void)
{
    sl_camera *cam = open_small();
    if (!cam)
        return;
    const char *dir = sl_test_path("bigplan");
    mkdir(dir, 0755);
    char jp[4300], line[4096];
    snprintf(jp, sizeof jp, "%s/journal.jsonl", dir);
    int n = snprintf(line, sizeof line,
                     "{\"event\": \"session_start\", \"version\": 1, \"plan\": {\"views\": 1, "
                     "\"times\": [");
    for (int i = 0; i < 65; i++)
        n += snprintf(line + n, sizeof line - (size_t)n, "%s0.01", i ? ", " : "");
    snprintf(line + n, sizeof line - (size_t)n, "]}}\n");
    FILE *f = fopen(jp, "w");
    if (f) {
        fputs(line, f);
        fclose(f);
    }
    sl_capture_options ro;
    memset(&ro, 0, sizeof ro);
    sl_error err;
    CHECK_RESULT(sl_capture_resume(cam, &ro, dir, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, "65 frames a bracket") && strstr(err.message, "at most 64"),
              "%s", err.message);
    CHECK(sl_test_count_files(dir) == 1);
    /* 300 MB (a sparse file): refused unread */
    CHECK(truncate(jp, (off_t)300 << 20) == 0);
    CHECK_RESULT(sl_capture_resume(cam, &ro, dir, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, "larger than a journal may be (256 MB)"), "%s", err.message);
    sl_camera_close(cam);
}

int main(void)
{
    sl_log_set_quiet(true);
    test_journal_caps();
    test_fault_matrix();
    return sl_test_finish();
}
