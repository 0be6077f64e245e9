/* SPDX-License-Identifier: BSD-3-Clause */
/* Fault injection for file output, loaded with LD_PRELOAD by the tests
 * (never linked into setlight): counts the calls that write to a regular
 * file or move one into place (write, pwrite, writev, fwrite, fsync,
 * rename) and makes the Nth fail.
 *   SL_FAULT_AT=N        fail the Nth counted call (unset or 0: only count)
 *   SL_FAULT_ERRNO=E     ENOSPC (default) or EIO
 *   SL_FAULT_COUNT=FILE  at a normal exit, write the number of counted calls there
 * Calls on stdin/stdout/stderr, pipes and terminals are not counted. */

#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

static long fail_at;
static int fail_errno = ENOSPC;
static long calls;
static const char *count_file;

__attribute__((constructor)) static void fault_init(void)
{
    const char *at = getenv("SL_FAULT_AT");
    fail_at = at ? atol(at) : 0;
    const char *e = getenv("SL_FAULT_ERRNO");
    fail_errno = e && !strcmp(e, "EIO") ? EIO : ENOSPC;
    count_file = getenv("SL_FAULT_COUNT");
}

static ssize_t (*real_write)(int, const void *, size_t);

__attribute__((destructor)) static void fault_report(void)
{
    if (!count_file)
        return;
    int fd = open(count_file, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0)
        return;
    char buf[32];
    int n = snprintf(buf, sizeof buf, "%ld\n", __atomic_load_n(&calls, __ATOMIC_SEQ_CST));
    if (!real_write)
        real_write = (ssize_t(*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
    if (real_write(fd, buf, (size_t)n) != n)
        n = -1;
    close(fd);
}

static int regular_fd(int fd)
{
    struct stat st;
    return fd > 2 && fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
}

/* true: this call fails */
static int counted(void)
{
    long n = __atomic_add_fetch(&calls, 1, __ATOMIC_SEQ_CST);
    if (fail_at > 0 && n == fail_at) {
        errno = fail_errno;
        return 1;
    }
    return 0;
}

#define REAL(name) \
    static __typeof__(&name) real_##name##_fn; \
    if (!real_##name##_fn) \
        real_##name##_fn = (__typeof__(&name))dlsym(RTLD_NEXT, #name)

ssize_t write(int fd, const void *buf, size_t n)
{
    if (!real_write)
        real_write = (ssize_t(*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
    if (regular_fd(fd) && counted())
        return -1;
    return real_write(fd, buf, n);
}

ssize_t pwrite(int fd, const void *buf, size_t n, off_t off)
{
    REAL(pwrite);
    if (regular_fd(fd) && counted())
        return -1;
    return real_pwrite_fn(fd, buf, n, off);
}

ssize_t pwrite64(int fd, const void *buf, size_t n, off_t off)
{
    REAL(pwrite64);
    if (regular_fd(fd) && counted())
        return -1;
    return real_pwrite64_fn(fd, buf, n, off);
}

ssize_t writev(int fd, const struct iovec *iov, int count)
{
    REAL(writev);
    if (regular_fd(fd) && counted())
        return -1;
    return real_writev_fn(fd, iov, count);
}

size_t fwrite(const void *buf, size_t size, size_t n, FILE *fp)
{
    REAL(fwrite);
    if (regular_fd(fileno(fp)) && counted()) {
        return 0;
    }
    return real_fwrite_fn(buf, size, n, fp);
}

int fsync(int fd)
{
    REAL(fsync);
    if (regular_fd(fd) && counted())
        return -1;
    return real_fsync_fn(fd);
}

int rename(const char *from, const char *to)
{
    REAL(rename);
    if (counted())
        return -1;
    return real_rename_fn(from, to);
}
