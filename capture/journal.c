/* SPDX-License-Identifier: BSD-3-Clause */
/* The session journal: DIR/journal.jsonl, append-only, one JSON object per
 * line, each line on disk (fsync) before the call returns. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "capture_private.h"

sl_result sl_capture_path(char *buf, size_t size, const char *dir, const char *name, sl_error *err)
{
    int n = snprintf(buf, size, "%s/%s", dir, name);
    if (n < 0 || (size_t)n >= size)
        return sl_error_set(err, SL_ERR_USAGE, "%s: path too long", dir);
    return SL_OK;
}

sl_result sl_journal_append(const char *dir, const char *json_line, sl_error *err)
{
    char path[4096];
    sl_result r = sl_capture_path(path, sizeof path, dir, SL_JOURNAL_NAME, err);
    if (r)
        return r;
    if (strchr(json_line, '\n'))
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: journal line with a newline", path);
    struct stat st;
    bool created = stat(path, &st) != 0;
    int fd = open(path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot open the journal: %s", path,
                            strerror(errno));
    size_t n = strlen(json_line);
    char *line = malloc(n + 2);
    if (!line) {
        close(fd);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    memcpy(line, json_line, n);
    line[n] = '\n';
    /* One write per line: a crash leaves whole lines or a torn last line,
     * which resume refuses rather than guesses about. */
    ssize_t w = write(fd, line, n + 1);
    int werr = errno;
    free(line);
    if (w != (ssize_t)(n + 1)) {
        if (w > 0 && ftruncate(fd, st.st_size >= 0 && !created ? st.st_size : 0) != 0)
            werr = errno;
        close(fd);
        return sl_error_set(err, SL_ERR_IO, "%s: journal write failed: %s", path,
                            strerror(w < 0 ? werr : ENOSPC));
    }
    if (fsync(fd) != 0) {
        werr = errno;
        close(fd);
        return sl_error_set(err, SL_ERR_IO, "%s: fsync failed: %s", path, strerror(werr));
    }
    close(fd);
    if (created) {
        int dfd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (dfd >= 0) {
            fsync(dfd);
            close(dfd);
        }
    }
    return SL_OK;
}

sl_result sl_journal_event(const char *dir, json_t *event, sl_error *err)
{
    time_t now = time(NULL);
    struct tm tm;
    char stamp[32];
    gmtime_r(&now, &tm);
    strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &tm);
    json_object_set_new(event, "time", json_string(stamp));
    char *text = json_dumps(event, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(10));
    if (!text)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: journal event: out of memory", dir);
    sl_result r = sl_journal_append(dir, text, err);
    free(text);
    return r;
}

sl_result sl_journal_read(const char *dir, json_t **events, sl_error *err)
{
    *events = NULL;
    char path[4096];
    sl_result r = sl_capture_path(path, sizeof path, dir, SL_JOURNAL_NAME, err);
    if (r)
        return r;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: not a capture session (no %s)", dir,
                            SL_JOURNAL_NAME);
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && (uint64_t)st.st_size > SL_JOURNAL_MAX_BYTES) {
        fclose(f);
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: %lld bytes, larger than a journal may be (%llu MB)", path,
                            (long long)st.st_size,
                            (unsigned long long)(SL_JOURNAL_MAX_BYTES >> 20));
    }
    json_t *all = json_array();
    char *line = NULL;
    size_t cap = 0;
    ssize_t len;
    int number = 0;
    while ((len = getline(&line, &cap, f)) >= 0) {
        number++;
        bool whole = len > 0 && line[len - 1] == '\n';
        json_error_t je;
        json_t *e = whole ? json_loadb(line, (size_t)len - 1, 0, &je) : NULL;
        if (!e || !json_is_object(e) || !json_is_string(json_object_get(e, "event"))) {
            json_decref(e);
            r = sl_error_set(err, SL_ERR_INPUT, "%s: corrupt journal at line %d%s", path, number,
                             whole ? "" : " (torn last line)");
            break;
        }
        if (number == 1 &&
            (strcmp(json_string_value(json_object_get(e, "event")), "session_start") != 0 ||
             json_integer_value(json_object_get(e, "version")) != 1)) {
            json_decref(e);
            r = sl_error_set(err, SL_ERR_INPUT, "%s: line 1 is not a version 1 session start",
                             path);
            break;
        }
        json_array_append_new(all, e);
    }
    free(line);
    fclose(f);
    if (!r && number == 0)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: empty journal", path);
    if (r) {
        json_decref(all);
        return r;
    }
    *events = all;
    return SL_OK;
}
