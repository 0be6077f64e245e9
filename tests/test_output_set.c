/* SPDX-License-Identifier: BSD-3-Clause */
/* Output sets and interrupts (core/atomic.c): a set's files are all new or
 * all as before, after a commit, an abort, a failed rename (rolled back) or
 * a signal; nothing temporary is ever left. */
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testing.h"

static const char *in_dir(const char *dir, const char *name)
{
    static char buf[16][8600];
    static int k;
    k = (k + 1) % 16;
    snprintf(buf[k], sizeof buf[k], "%s/%s", dir, name);
    return buf[k];
}

static const char *fresh_dir(const char *name)
{
    const char *d = sl_test_path(name);
    sl_remove_tree(d);
    mkdir(d, 0777);
    return d;
}

/* The text of a file ("" when missing). */
static bool has_text(const char *path, const char *text)
{
    char *s = sl_test_read_file(path, NULL);
    bool same = s ? !strcmp(s, text) : !*text;
    free(s);
    return same;
}

static int temps_in(const char *dir)
{
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "ls -a '%s' | grep -q sl-tmp", dir);
    return system(cmd) == 0;
}

static void write_text(const char *path, const char *text)
{
    sl_error err;
    CHECK_OK(sl_write_file_atomic(path, text, strlen(text), &err), &err);
}

/* Folder `name` with OLD's files ("old a", ...), and a set of a.txt,
 * b.txt and c.txt begun and written ("new a", ...), not committed. */
static const char *set_of_three(const char *name, const char *old, const char *m[3])
{
    const char *d = fresh_dir(name);
    static const char *const names[3] = {"a.txt", "b.txt", "c.txt"};
    char text[16];
    for (int i = 0; i < 3; i++) {
        m[i] = in_dir(d, names[i]);
        snprintf(text, sizeof text, "old %c", 'a' + i);
        if (strchr(old, 'a' + i))
            write_text(m[i], text);
    }
    sl_error err;
    CHECK_OK(sl_output_set_begin(m, 3, &err), &err);
    for (int i = 0; i < 3; i++) {
        snprintf(text, sizeof text, "new %c", 'a' + i);
        write_text(m[i], text);
    }
    return d;
}

static void test_commit_and_abort(void)
{
    const char *members[3];
    const char *d = set_of_three("set1", "ab", members);
    const char *a = members[0], *b = members[1], *c = members[2];
    sl_error err;
    /* nothing moved yet; the new content is readable at its temporary */
    CHECK(has_text(a, "old a") && has_text(b, "old b") && !sl_test_file_exists(c));
    const char *pending = sl_output_set_pending(b);
    CHECK(pending && strstr(pending, ".sl-tmp-") && has_text(pending, "new b"));
    /* a file outside the set commits at once */
    write_text(in_dir(d, "other.txt"), "other");
    CHECK(has_text(in_dir(d, "other.txt"), "other"));
    CHECK_OK(sl_output_set_commit(&err), &err);
    CHECK(has_text(a, "new a") && has_text(b, "new b") && has_text(c, "new c"));
    CHECK(!temps_in(d));
    CHECK(sl_output_set_pending(a) == NULL);

    /* abort: every old file stays, no temporary */
    CHECK_OK(sl_output_set_begin(members, 3, &err), &err);
    write_text(a, "newer a");
    write_text(c, "newer c");
    sl_output_set_abort();
    CHECK(has_text(a, "new a") && has_text(c, "new c"));
    CHECK(!temps_in(d));
    /* after the set, commits are immediate again */
    write_text(a, "plain");
    CHECK(has_text(a, "plain"));
}

static void test_prefix_and_nesting(void)
{
    const char *d = fresh_dir("set2");
    const char *usd = in_dir(d, "r.usda");
    char glob[4200];
    snprintf(glob, sizeof glob, "%s/r_light_*", d);
    sl_error err;
    const char *outer[2] = {usd, glob};
    CHECK_OK(sl_output_set_begin(outer, 2, &err), &err);
    write_text(in_dir(d, "r_light_01.exr"), "tex");
    CHECK(!sl_test_file_exists(in_dir(d, "r_light_01.exr")));
    /* a library's own set inside the command's joins it */
    const char *inner[1] = {in_dir(d, "mask.exr")};
    CHECK_OK(sl_output_set_begin(inner, 1, &err), &err);
    write_text(in_dir(d, "mask.exr"), "mask");
    CHECK_OK(sl_output_set_commit(&err), &err);
    CHECK(!sl_test_file_exists(in_dir(d, "mask.exr")));
    write_text(usd, "usd");
    CHECK_OK(sl_output_set_commit(&err), &err);
    CHECK(has_text(in_dir(d, "mask.exr"), "mask") && has_text(usd, "usd") &&
          has_text(in_dir(d, "r_light_01.exr"), "tex"));
    CHECK(!temps_in(d));
}

/* A rename that fails half way puts every replaced file back. */
static void test_rollback(void)
{
    const char *members[3];
    const char *d = set_of_three("set3", "ac", members);
    const char *a = members[0], *b = members[1], *c = members[2];
    sl_error err;
    /* c becomes a folder: its rename, the last, fails */
    unlink(c);
    mkdir(c, 0777);
    write_text(in_dir(c, "inside"), "x");
    CHECK_RESULT(sl_output_set_commit(&err), SL_ERR_IO, &err);
    CHECK(strstr(err.message, "c.txt") != NULL);
    CHECK(has_text(a, "old a")); /* put back from its hard link */
    CHECK(!sl_test_file_exists(b)); /* there was none */
    CHECK(has_text(in_dir(c, "inside"), "x"));
    CHECK(!temps_in(d));
}

/* A report folder built in a temporary folder and adopted: it replaces the
 * earlier folder at the commit, and a failed commit puts the earlier back. */
static void test_adopted_folder(void)
{
    const char *members[3];
    const char *d = set_of_three("set5", "c", members);
    const char *report = in_dir(d, "report");
    mkdir(report, 0777);
    write_text(in_dir(report, "old.png"), "old");
    sl_error err;
    for (int fail = 0; fail < 2; fail++) {
        char tmp[4200];
        snprintf(tmp, sizeof tmp, "%s/.report.sl-tmp-XXXXXX", d);
        int handle = sl_temp_dir_create(tmp);
        CHECK(handle >= 0);
        char built[4300];
        snprintf(built, sizeof built, "%s/report", tmp);
        mkdir(built, 0777);
        write_text(in_dir(built, "new.png"), "new");
        CHECK_OK(sl_output_set_adopt(report, built, &err), &err);
        if (fail) { /* c.txt becomes a folder: the last rename fails */
            unlink(members[2]);
            mkdir(members[2], 0777);
            write_text(in_dir(members[2], "inside"), "x");
            CHECK_RESULT(sl_output_set_commit(&err), SL_ERR_IO, &err);
            CHECK(has_text(in_dir(report, "old.png"), "old"));
            CHECK(!sl_test_file_exists(in_dir(report, "new.png")));
            CHECK(!sl_test_file_exists(members[0]) && !sl_test_file_exists(members[1]));
            sl_temp_dir_remove(tmp, handle);
            CHECK(!temps_in(d));
        } else {
            CHECK_OK(sl_output_set_commit(&err), &err);
            sl_temp_dir_remove(tmp, handle);
            CHECK(!temps_in(d));
            CHECK(has_text(in_dir(report, "new.png"), "new"));
            CHECK(!sl_test_file_exists(in_dir(report, "old.png")));
            CHECK(has_text(members[0], "new a") && has_text(members[2], "new c"));
            /* the earlier report again, for the failing round */
            sl_remove_tree(report);
            mkdir(report, 0777);
            write_text(in_dir(report, "old.png"), "old");
            const char *again[3] = {members[0], members[1], members[2]};
            for (int i = 0; i < 3; i++)
                unlink(again[i]);
            write_text(members[2], "old c");
            CHECK_OK(sl_output_set_begin(again, 3, &err), &err);
            write_text(members[0], "new a");
            write_text(members[1], "new b");
            write_text(members[2], "new c");
        }
    }
}

/* A signal in the middle of a set: the child dies by it, the old files
 * stay, every temporary (files, a pending member, a folder) is removed. */
static void interrupted_child(const char *d, int sig)
{
    sl_interrupt_install();
    sl_error err;
    const char *a = in_dir(d, "a.txt"), *b = in_dir(d, "b.txt");
    const char *members[2] = {a, b};
    if (sl_output_set_begin(members, 2, &err))
        _exit(90);
    write_text(a, "new a"); /* pending */
    sl_atomic_file f;       /* being written */
    if (sl_atomic_begin(&f, b, &err))
        _exit(91);
    char tmpl[4200];
    snprintf(tmpl, sizeof tmpl, "%s/.report.sl-tmp-XXXXXX", d);
    if (sl_temp_dir_create(tmpl) < 0)
        _exit(92);
    char inner[4300];
    snprintf(inner, sizeof inner, "%s/sub", tmpl);
    mkdir(inner, 0777);
    write_text(in_dir(inner, "page.html"), "page");
    raise(sig);
    _exit(93); /* not reached: the handler ends the process by the signal */
}

static void test_interrupt(void)
{
    int sigs[3] = {SIGINT, SIGTERM, SIGHUP};
    for (int k = 0; k < 3; k++) {
        const char *d = fresh_dir("set4");
        write_text(in_dir(d, "a.txt"), "old a");
        write_text(in_dir(d, "b.txt"), "old b");
        fflush(stdout);
        pid_t pid = fork();
        if (pid == 0)
            interrupted_child(d, sigs[k]);
        int status = 0;
        waitpid(pid, &status, 0);
        CHECK_MSG(WIFSIGNALED(status) && WTERMSIG(status) == sigs[k],
                  "signal %d: the child ended with status 0x%x", sigs[k], status);
        CHECK(has_text(in_dir(d, "a.txt"), "old a") && has_text(in_dir(d, "b.txt"), "old b"));
        CHECK_MSG(!temps_in(d), "signal %d: temporaries left", sigs[k]);
        CHECK(sl_test_count_files(d) == 2);
    }
}

int main(void)
{
    RUN(test_commit_and_abort);
    RUN(test_prefix_and_nesting);
    RUN(test_rollback);
    RUN(test_adopted_folder);
    RUN(test_interrupt);
    return sl_test_finish();
}
