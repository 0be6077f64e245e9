/* SPDX-License-Identifier: BSD-3-Clause */
/* Atomic output: write beside the target under a temporary name, fsync,
 * rename. A failed or interrupted run leaves the old file (or nothing).
 *
 * Every temporary file or folder is registered in a fixed table while it
 * exists, so the SIGINT/SIGTERM/SIGHUP handler can remove them all with
 * async-signal-safe calls only. The steps that create or rename a
 * temporary (the critical sections) run with those signals blocked in
 * their thread and are counted: the handler, in whatever thread it runs,
 * first stops new ones (`dying`), waits for the running ones to end, then
 * removes what is registered. So a temporary is either renamed whole into
 * place or removed, and an output set's renames finish together. */
#include "setlight/core.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

/* ------------------------------------------------------------------ */
/* The registry of live temporaries                                    */
/* ------------------------------------------------------------------ */

enum { SLOT_FREE = 0, SLOT_CLAIMED, SLOT_FILE, SLOT_DIR };

#define TEMP_SLOTS 256

typedef struct temp_slot {
    int state; /* __atomic */
    char path[4096];
} temp_slot;

static temp_slot slots[TEMP_SLOTS];
static int temp_counter;
static int busy;  /* threads inside a critical section */
static int dying; /* the signal being handled, 0 before */

typedef struct critical {
    sigset_t old;
} critical;

/* Blocks the interrupt signals in this thread and counts it in; false
 * (and nothing held) once an interrupt is being handled. */
static bool critical_enter(critical *c)
{
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &set, &c->old);
    __atomic_add_fetch(&busy, 1, __ATOMIC_SEQ_CST);
    if (__atomic_load_n(&dying, __ATOMIC_SEQ_CST)) {
        __atomic_sub_fetch(&busy, 1, __ATOMIC_SEQ_CST);
        pthread_sigmask(SIG_SETMASK, &c->old, NULL);
        return false;
    }
    return true;
}

static void critical_leave(critical *c)
{
    __atomic_sub_fetch(&busy, 1, __ATOMIC_SEQ_CST);
    pthread_sigmask(SIG_SETMASK, &c->old, NULL);
}

/* Inside a critical section. -1 when the table is full: the temporary
 * still works but an interrupt would leave it. */
static int slot_claim(const char *path, int kind)
{
    for (int i = 0; i < TEMP_SLOTS; i++) {
        int expect = SLOT_FREE;
        if (__atomic_compare_exchange_n(&slots[i].state, &expect, SLOT_CLAIMED, false,
                                        __ATOMIC_ACQUIRE, __ATOMIC_RELAXED)) {
            snprintf(slots[i].path, sizeof slots[i].path, "%s", path);
            __atomic_store_n(&slots[i].state, kind, __ATOMIC_RELEASE);
            return i;
        }
    }
    return -1;
}

static void slot_release(int i)
{
    if (i >= 0 && i < TEMP_SLOTS)
        __atomic_store_n(&slots[i].state, SLOT_FREE, __ATOMIC_RELEASE);
}

/* Async-signal-safe removal of a folder and what is in it (a few levels:
 * temporary folders are shallow). */
static void remove_tree_now(int parent, const char *name, int depth)
{
    if (unlinkat(parent, name, 0) == 0 || errno == ENOENT)
        return;
    int fd = openat(parent, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0)
        return;
    char buf[4096];
    for (int pass = 0; pass < 64; pass++) {
        long n = syscall(SYS_getdents64, fd, buf, sizeof buf);
        if (n <= 0)
            break;
        for (long off = 0; off < n;) {
            struct {
                uint64_t ino;
                int64_t off;
                unsigned short reclen;
                unsigned char type;
                char name[];
            } *d = (void *)(buf + off);
            off += d->reclen;
            if (!strcmp(d->name, ".") || !strcmp(d->name, ".."))
                continue;
            if (depth < 8)
                remove_tree_now(fd, d->name, depth + 1);
            else
                unlinkat(fd, d->name, 0);
        }
    }
    close(fd);
    unlinkat(parent, name, AT_REMOVEDIR);
}

static void remove_slot_now(int i)
{
    int state = __atomic_load_n(&slots[i].state, __ATOMIC_ACQUIRE);
    if (state == SLOT_FILE)
        unlink(slots[i].path);
    else if (state == SLOT_DIR)
        remove_tree_now(AT_FDCWD, slots[i].path, 0);
}

static void on_interrupt(int sig)
{
    int saved = errno;
    __atomic_store_n(&dying, sig, __ATOMIC_SEQ_CST);
    /* Critical sections block the signal in their own thread, so this
     * thread is in none: wait (bounded) for the others' to end. */
    struct timespec ms = {0, 1000000};
    for (int k = 0; k < 5000 && __atomic_load_n(&busy, __ATOMIC_SEQ_CST); k++)
        nanosleep(&ms, NULL);
    for (int i = 0; i < TEMP_SLOTS; i++)
        remove_slot_now(i);
    /* End by the signal itself, so a calling shell sees 128 + sig and a
     * script's loop stops too. */
    signal(sig, SIG_DFL);
    raise(sig);
    errno = saved;
}

void sl_interrupt_install(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_interrupt;
    sigemptyset(&sa.sa_mask);
    sigaddset(&sa.sa_mask, SIGINT);
    sigaddset(&sa.sa_mask, SIGTERM);
    sigaddset(&sa.sa_mask, SIGHUP);
    int sigs[3] = {SIGINT, SIGTERM, SIGHUP};
    for (int k = 0; k < 3; k++) {
        struct sigaction old;
        /* an ignored signal (nohup, a background job) stays ignored */
        if (sigaction(sigs[k], NULL, &old) == 0 && old.sa_handler == SIG_IGN)
            continue;
        sigaction(sigs[k], &sa, NULL);
    }
}

int sl_temp_dir_create(char *template_path)
{
    critical c;
    if (!critical_enter(&c)) {
        errno = EINTR;
        return -1;
    }
    int slot = -1;
    if (mkdtemp(template_path)) {
        slot = slot_claim(template_path, SLOT_DIR);
        if (slot < 0)
            slot = TEMP_SLOTS; /* untracked, still removable */
    }
    critical_leave(&c);
    return slot;
}

void sl_temp_dir_remove(const char *path, int handle)
{
    sl_remove_tree(path);
    if (handle < TEMP_SLOTS)
        slot_release(handle);
}

/* ------------------------------------------------------------------ */
/* Output sets                                                         */
/* ------------------------------------------------------------------ */

typedef struct pending_file {
    char final_path[4096];
    char temp_path[4096];
    /* During the commit: a hard link to the old file, or the old folder
     * moved aside (a folder cannot be linked, nor renamed over a full one). */
    char backup_path[4096];
    int slot;     /* -1: adopted, the caller's temporary */
    bool folder;  /* an adopted folder */
    bool aside;   /* the old folder is at backup_path */
} pending_file;

static struct {
    int open; /* depth: a set begun inside another joins it */
    char **members; /* exact paths, or prefixes ending in '*' */
    int member_count;
    pending_file *pending;
    int pending_count;
} set;
static pthread_mutex_t set_lock = PTHREAD_MUTEX_INITIALIZER;

static bool set_has_member(const char *path)
{
    for (int i = 0; i < set.member_count; i++) {
        size_t n = strlen(set.members[i]);
        if (n && set.members[i][n - 1] == '*' ? !strncmp(path, set.members[i], n - 1)
                                              : !strcmp(path, set.members[i]))
            return true;
    }
    return false;
}

static void set_clear(void)
{
    for (int i = 0; i < set.member_count; i++)
        free(set.members[i]);
    free(set.members);
    free(set.pending);
    memset(&set, 0, sizeof set);
}

sl_result sl_output_set_begin(const char *const *members, int count, sl_error *err)
{
    pthread_mutex_lock(&set_lock);
    sl_result r = SL_OK;
    char **grown = realloc(set.members, (size_t)(set.member_count + (count > 0 ? count : 0) + 1) *
                                            sizeof *set.members);
    if (!grown)
        r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
    else
        set.members = grown;
    for (int i = 0; !r && i < count; i++) {
        if (!members[i] || !*members[i])
            continue;
        if (!(set.members[set.member_count] = strdup(members[i])))
            r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
        else
            set.member_count++;
    }
    if (!r)
        set.open++;
    else if (!set.open)
        set_clear();
    pthread_mutex_unlock(&set_lock);
    return r;
}

const char *sl_output_set_pending(const char *final_path)
{
    const char *temp = NULL;
    pthread_mutex_lock(&set_lock);
    for (int i = 0; set.open && i < set.pending_count; i++)
        if (!strcmp(set.pending[i].final_path, final_path))
            temp = set.pending[i].temp_path;
    pthread_mutex_unlock(&set_lock);
    return temp;
}

/* Takes over a complete temporary of a member (sl_atomic_commit while the
 * set is open); a member written twice keeps the later file. */
static sl_result set_defer(sl_atomic_file *f, sl_error *err)
{
    pthread_mutex_lock(&set_lock);
    pending_file *p = NULL;
    for (int i = 0; i < set.pending_count; i++)
        if (!strcmp(set.pending[i].final_path, f->final_path)) {
            p = &set.pending[i];
            unlink(p->temp_path);
            slot_release(p->slot);
        }
    if (!p) {
        pending_file *grown = realloc(set.pending, (size_t)(set.pending_count + 1) * sizeof *grown);
        if (!grown) {
            pthread_mutex_unlock(&set_lock);
            sl_atomic_abort(f);
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", f->final_path);
        }
        set.pending = grown;
        p = &set.pending[set.pending_count++];
    }
    snprintf(p->final_path, sizeof p->final_path, "%s", f->final_path);
    snprintf(p->temp_path, sizeof p->temp_path, "%s", f->temp_path);
    p->backup_path[0] = 0;
    p->slot = f->slot;
    p->folder = false;
    f->temp_path[0] = 0;
    f->slot = -1;
    pthread_mutex_unlock(&set_lock);
    return SL_OK;
}

sl_result sl_output_set_adopt(const char *final_path, const char *temp_path, sl_error *err)
{
    struct stat st;
    if (lstat(temp_path, &st) != 0)
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: no temporary %s", final_path, temp_path);
    pthread_mutex_lock(&set_lock);
    pending_file *grown = set.open ? realloc(set.pending, (size_t)(set.pending_count + 1) *
                                                              sizeof *grown)
                                   : NULL;
    if (!grown) {
        pthread_mutex_unlock(&set_lock);
        return sl_error_set(err, set.open ? SL_ERR_NOMEM : SL_ERR_INTERNAL,
                            "%s: %s", final_path, set.open ? "out of memory" : "no output set");
    }
    set.pending = grown;
    pending_file *p = &set.pending[set.pending_count++];
    snprintf(p->final_path, sizeof p->final_path, "%s", final_path);
    snprintf(p->temp_path, sizeof p->temp_path, "%s", temp_path);
    p->backup_path[0] = 0;
    p->slot = -1;
    p->folder = S_ISDIR(st.st_mode);
    pthread_mutex_unlock(&set_lock);
    return SL_OK;
}

/* Keeps what is at a member's final path: a hard link to a file, or a
 * folder moved aside. Inside the commit's critical section. */
static sl_result keep_old(pending_file *p, sl_error *err)
{
    struct stat st;
    p->backup_path[0] = 0;
    p->aside = false;
    if (lstat(p->final_path, &st) != 0 || !(p->folder ? S_ISDIR(st.st_mode) : S_ISREG(st.st_mode)))
        return SL_OK;
    const char *slash = strrchr(p->final_path, '/');
    int dir_len = slash ? (int)(slash - p->final_path + 1) : 0;
    int n = __atomic_add_fetch(&temp_counter, 1, __ATOMIC_RELAXED);
    int len = snprintf(p->backup_path, sizeof p->backup_path, "%.*s.%s.sl-tmp-%d-%d.old", dir_len,
                       p->final_path, p->final_path + dir_len, (int)getpid(), n);
    if (len >= (int)sizeof p->backup_path) {
        p->backup_path[0] = 0;
        return p->folder ? sl_error_set(err, SL_ERR_IO, "%s: path too long", p->final_path)
                         : SL_OK;
    }
    if (!p->folder) {
        if (link(p->final_path, p->backup_path) != 0)
            p->backup_path[0] = 0; /* no hard links here: no way back for this one */
        return SL_OK;
    }
    if (rename(p->final_path, p->backup_path) != 0) {
        int e = errno;
        p->backup_path[0] = 0;
        return sl_error_set(err, SL_ERR_IO, "%s: cannot move the earlier one aside: %s",
                            p->final_path, strerror(e));
    }
    p->aside = true;
    return SL_OK;
}

/* After a failure: members [0, done) were renamed into place. Puts every
 * old file or folder back, and takes away new ones that had none. */
static void set_roll_back(int done)
{
    for (int i = 0; i < set.pending_count; i++) {
        pending_file *p = &set.pending[i];
        if (i < done) {
            if (p->folder)
                rename(p->final_path, p->temp_path); /* the caller's, removed with it */
            else if (!p->backup_path[0])
                unlink(p->final_path);
        } else if (!p->aside) {
            continue;
        }
        if (p->backup_path[0] && rename(p->backup_path, p->final_path) == 0)
            p->backup_path[0] = 0;
    }
}

sl_result sl_output_set_commit(sl_error *err)
{
    pthread_mutex_lock(&set_lock);
    sl_result r = SL_OK;
    if (set.open > 1) { /* the outer set commits */
        set.open--;
        pthread_mutex_unlock(&set_lock);
        return SL_OK;
    }
    critical c;
    if (!critical_enter(&c)) {
        pthread_mutex_unlock(&set_lock);
        sl_output_set_abort();
        return sl_error_set(err, SL_ERR_CANCELLED, "interrupted");
    }
    /* Every temporary is complete and fsynced; the old ones are kept until
     * every rename succeeded. */
    int done = 0;
    for (int i = 0; i < set.pending_count && !r; i++)
        r = keep_old(&set.pending[i], err);
    for (; !r && done < set.pending_count; done++) {
        pending_file *p = &set.pending[done];
        if (rename(p->temp_path, p->final_path) != 0) {
            int e = errno;
            r = sl_error_set(err, SL_ERR_IO, "%s: cannot rename into place: %s", p->final_path,
                             strerror(e));
            break;
        }
    }
    if (r)
        set_roll_back(done);
    for (int i = 0; i < set.pending_count; i++) {
        pending_file *p = &set.pending[i];
        if (i >= done && p->slot >= 0)
            unlink(p->temp_path);
        if (p->backup_path[0] && p->folder)
            sl_remove_tree(p->backup_path);
        else if (p->backup_path[0])
            unlink(p->backup_path);
        slot_release(p->slot);
    }
    set.pending_count = 0;
    critical_leave(&c);
    set_clear();
    pthread_mutex_unlock(&set_lock);
    return r;
}

void sl_output_set_abort(void)
{
    pthread_mutex_lock(&set_lock);
    /* a failed part fails the whole set, also from inside a nested one */
    for (int i = 0; i < set.pending_count; i++) {
        if (set.pending[i].slot >= 0) /* an adopted one is the caller's */
            unlink(set.pending[i].temp_path);
        slot_release(set.pending[i].slot);
    }
    set.pending_count = 0;
    if (set.open > 1)
        set.open--;
    else
        set_clear();
    pthread_mutex_unlock(&set_lock);
}

/* ------------------------------------------------------------------ */
/* Single files                                                        */
/* ------------------------------------------------------------------ */

sl_result sl_atomic_begin(sl_atomic_file *f, const char *final_path, sl_error *err)
{
    memset(f, 0, sizeof *f);
    f->slot = -1;
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
    critical c;
    if (!critical_enter(&c)) {
        f->temp_path[0] = 0;
        return sl_error_set(err, SL_ERR_CANCELLED, "%s: interrupted", final_path);
    }
    /* Registered before it exists, so an interrupt never misses it. */
    f->slot = slot_claim(f->temp_path, SLOT_FILE);
    /* Check the folder is writable now, so the error names the output. */
    int fd = open(f->temp_path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    int e = errno;
    if (fd < 0) {
        slot_release(f->slot);
        f->slot = -1;
    }
    critical_leave(&c);
    if (fd < 0) {
        f->temp_path[0] = 0;
        return sl_error_set(err, e == ENOENT ? SL_ERR_USAGE : SL_ERR_IO,
                            "%s: cannot write: %s", final_path, strerror(e));
    }
    close(fd);
    return SL_OK;
}

sl_result sl_atomic_commit(sl_atomic_file *f, sl_error *err)
{
    int fd = open(f->temp_path, O_RDONLY | O_CLOEXEC);
    if (fd >= 0) {
        int failed = fsync(fd);
        int e = errno;
        close(fd);
        if (failed && e != EINVAL && e != EROFS) {
            sl_atomic_abort(f);
            return sl_error_set(err, SL_ERR_IO, "%s: write failed: %s", f->final_path,
                                strerror(e));
        }
    }
    pthread_mutex_lock(&set_lock);
    bool deferred = set.open && set_has_member(f->final_path);
    pthread_mutex_unlock(&set_lock);
    if (deferred)
        return set_defer(f, err);
    critical c;
    if (!critical_enter(&c)) {
        sl_atomic_abort(f);
        return sl_error_set(err, SL_ERR_CANCELLED, "%s: interrupted", f->final_path);
    }
    int failed = rename(f->temp_path, f->final_path);
    int e = errno;
    if (!failed) {
        slot_release(f->slot);
        f->slot = -1;
        f->temp_path[0] = 0;
    }
    critical_leave(&c);
    if (failed) {
        sl_atomic_abort(f);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot rename into place: %s", f->final_path,
                            strerror(e));
    }
    return SL_OK;
}

void sl_atomic_abort(sl_atomic_file *f)
{
    if (f->temp_path[0])
        unlink(f->temp_path);
    f->temp_path[0] = 0;
    slot_release(f->slot);
    f->slot = -1;
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
    int e = errno;
    int close_failed = fclose(fp);
    if (close_failed)
        e = errno;
    if (wrote != size || close_failed) {
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

/* Whether a temporary's name `.NAME.sl-tmp-PID-N...` starts with prefix
 * and names a process that no longer exists on this machine. */
static bool temp_of_dead_process(const char *entry, const char *prefix, size_t prefix_len)
{
    if (strncmp(entry, prefix, prefix_len) != 0)
        return false;
    char *end;
    long pid = strtol(entry + prefix_len, &end, 10);
    if (end == entry + prefix_len || *end != '-' || pid <= 0 || pid > INT32_MAX)
        return false;
    return kill((pid_t)pid, 0) != 0 && errno == ESRCH;
}

int sl_atomic_sweep(const char *final_path)
{
    const char *slash = strrchr(final_path, '/');
    const char *base = slash ? slash + 1 : final_path;
    char dir[4096]; /* the folder, with its slash ("." for a bare name) */
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - final_path + 1) : 1,
             slash ? final_path : ".");
    const char *dot = strrchr(base, '.');
    size_t stem_len = dot && dot != base ? (size_t)(dot - base) : strlen(base);
    /* `.stem.sl-tmp-PID-N.ext` (a file being written) and
     * `.name.sl-tmp-PID-N.old` (an output set's old file set aside) */
    char temp_prefix[600], old_prefix[600];
    snprintf(temp_prefix, sizeof temp_prefix, ".%.*s.sl-tmp-", (int)stem_len, base);
    snprintf(old_prefix, sizeof old_prefix, ".%s.sl-tmp-", base);
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    int removed = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!temp_of_dead_process(e->d_name, temp_prefix, strlen(temp_prefix)) &&
            !temp_of_dead_process(e->d_name, old_prefix, strlen(old_prefix)))
            continue;
        char path[8192];
        snprintf(path, sizeof path, "%s%s%s", dir, slash ? "" : "/", e->d_name);
        struct stat st;
        if (lstat(path, &st) == 0 && S_ISREG(st.st_mode) && unlink(path) == 0)
            removed++;
    }
    closedir(d);
    return removed;
}
