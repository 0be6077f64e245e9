/* SPDX-License-Identifier: BSD-3-Clause */
/* Atomic output: write beside the target under a temporary name, fsync,
 * rename. A failed or interrupted run leaves the old file (or nothing). */
#include "setlight/core.h"

#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int temp_counter;

sl_result sl_atomic_begin(sl_atomic_file *f, const char *final_path, sl_error *err)
{
    memset(f, 0, sizeof *f);
    if (!final_path || !*final_path)
        return sl_error_set(err, SL_ERR_USAGE, "empty output path");
    if (strlen(final_path) >= sizeof f->final_path - 64)
        return sl_error_set(err, SL_ERR_USAGE, "%s: output path too long", final_path);
    struct stat st;
    if (stat(final_path, &st) == 0 && S_ISDIR(st.st_mode))
        return sl_error_set(err, SL_ERR_USAGE, "%s: output is a directory", final_path);
    strcpy(f->final_path, final_path);
    const char *slash = strrchr(final_path, '/');
    const char *base = slash ? slash + 1 : final_path;
    size_t dir_len = slash ? (size_t)(slash - final_path + 1) : 0;
    const char *dot = strrchr(base, '.');
    const char *ext = dot && dot != base ? dot : "";
    size_t stem_len = strlen(base) - strlen(ext);
    int n = __atomic_add_fetch(&temp_counter, 1, __ATOMIC_RELAXED);
    snprintf(f->temp_path, sizeof f->temp_path, "%.*s.%.*s.sl-tmp-%d-%d%s", (int)dir_len,
             final_path, (int)stem_len, base, (int)getpid(), n, ext);
    /* Check the folder is writable now, so the error names the output. */
    int fd = open(f->temp_path, O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd < 0) {
        int e = errno;
        f->temp_path[0] = 0;
        return sl_error_set(err, e == ENOENT ? SL_ERR_USAGE : SL_ERR_IO,
                            "%s: cannot write: %s", final_path, strerror(e));
    }
    close(fd);
    return SL_OK;
}

sl_result sl_atomic_commit(sl_atomic_file *f, sl_error *err)
{
    int fd = open(f->temp_path, O_RDONLY);
    if (fd >= 0) {
        fsync(fd);
        close(fd);
    }
    if (rename(f->temp_path, f->final_path) != 0) {
        int e = errno;
        sl_atomic_abort(f);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot rename into place: %s", f->final_path,
                            strerror(e));
    }
    f->temp_path[0] = 0;
    return SL_OK;
}

void sl_atomic_abort(sl_atomic_file *f)
{
    if (f->temp_path[0])
        unlink(f->temp_path);
    f->temp_path[0] = 0;
}

sl_result sl_write_file_atomic(const char *path, const void *data, size_t size, sl_error *err)
{
    sl_atomic_file f;
    sl_result r = sl_atomic_begin(&f, path, err);
    if (r)
        return r;
    FILE *fp = fopen(f.temp_path, "wb");
    if (!fp) {
        int e = errno;
        sl_atomic_abort(&f);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot write: %s", path, strerror(e));
    }
    size_t wrote = size ? fwrite(data, 1, size, fp) : 0;
    int close_failed = fclose(fp);
    if (wrote != size || close_failed) {
        int e = errno;
        sl_atomic_abort(&f);
        return sl_error_set(err, SL_ERR_IO, "%s: write failed: %s", path, strerror(e));
    }
    return sl_atomic_commit(&f, err);
}

sl_result sl_check_input_file(const char *path, sl_error *err)
{
    struct stat st;
    if (!path || !*path)
        return sl_error_set(err, SL_ERR_USAGE, "empty input path");
    if (stat(path, &st) != 0)
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: no such file", path);
    if (S_ISDIR(st.st_mode))
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: is a directory, not a file", path);
    if (!S_ISREG(st.st_mode))
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: not a regular file", path);
    if (access(path, R_OK) != 0)
        return sl_error_set(err, SL_ERR_IO, "%s: not readable: %s", path, strerror(errno));
    if (st.st_size == 0)
        return sl_error_set(err, SL_ERR_INPUT, "%s: empty file (0 bytes)", path);
    return SL_OK;
}

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st;
    (void)flag;
    (void)ftw;
    return remove(path);
}

void sl_remove_tree(const char *path)
{
    nftw(path, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}
