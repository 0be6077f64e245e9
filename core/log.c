/* SPDX-License-Identifier: BSD-3-Clause */
/* Logging, progress and clocks. Everything goes to stderr: stdout belongs to
 * --json results and command output. */
#include "setlight/core.h"

#include <pthread.h>
#include <stdarg.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static sl_log_level min_level = SL_LOG_INFO;
static bool quiet;
static pthread_mutex_t log_lock = PTHREAD_MUTEX_INITIALIZER;
/* The bar on screen, if any: log lines clear it, print, and draw it again. */
static sl_progress *active_bar;
static void progress_draw(sl_progress *p, bool final);

void sl_log_set_level(sl_log_level level) { min_level = level; }
void sl_log_set_quiet(bool q) { quiet = q; }
bool sl_log_is_quiet(void) { return quiet; }

static bool shown(sl_log_level level)
{
    return level >= min_level && !(quiet && level < SL_LOG_WARN);
}

/* One line; the caller holds log_lock. */
static void write_line(sl_log_level level, const char *text)
{
    static const char *const prefix[] = {"debug: ", "", "warning: ", "error: "};
    if (active_bar)
        fputs("\r\033[K", stderr);
    fprintf(stderr, "setlight: %s%s\n", prefix[level], text);
    if (active_bar) {
        active_bar->last_draw_seconds = 0;
        progress_draw(active_bar, false);
    }
}

/* Notes held for the end of a run: a refusal stays one line. */
#define NOTES_MAX 32
#define LINE_MAX_CHARS 2048
static bool notes_held;
static int note_count;
static struct {
    sl_log_level level;
    char text[LINE_MAX_CHARS];
} notes[NOTES_MAX];

void sl_log_hold_notes(bool hold) { notes_held = hold; }

static void log_line(sl_log_level level, bool note, const char *fmt, va_list ap)
{
    if (!shown(level))
        return;
    char text[LINE_MAX_CHARS];
    vsnprintf(text, sizeof text, fmt, ap);
    pthread_mutex_lock(&log_lock);
    if (!note || !notes_held) {
        write_line(level, text);
    } else {
        bool seen = false;
        for (int i = 0; i < note_count && !seen; i++)
            seen = strcmp(notes[i].text, text) == 0;
        if (!seen && note_count < NOTES_MAX) {
            notes[note_count].level = level;
            memcpy(notes[note_count++].text, text, sizeof text);
        }
    }
    pthread_mutex_unlock(&log_lock);
}

void sl_log(sl_log_level level, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    log_line(level, false, fmt, ap);
    va_end(ap);
}

void sl_log_note(sl_log_level level, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    log_line(level, true, fmt, ap);
    va_end(ap);
}

void sl_log_release_notes(bool print)
{
    pthread_mutex_lock(&log_lock);
    for (int i = 0; print && i < note_count; i++)
        write_line(notes[i].level, notes[i].text);
    note_count = 0;
    pthread_mutex_unlock(&log_lock);
}

static double clock_seconds(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double sl_seconds(void) { return clock_seconds(CLOCK_MONOTONIC); }
double sl_cpu_seconds(void) { return clock_seconds(CLOCK_PROCESS_CPUTIME_ID); }
double sl_thread_cpu_seconds(void) { return clock_seconds(CLOCK_THREAD_CPUTIME_ID); }

static void progress_draw(sl_progress *p, bool final)
{
    double now = sl_seconds();
    if (!final && now - p->last_draw_seconds < 0.1)
        return;
    p->last_draw_seconds = now;
    double frac = p->total > 0 ? (double)p->done / (double)p->total : 0.0;
    if (frac > 1)
        frac = 1;
    int bar = (int)(frac * 30 + 0.5);
    char line[128];
    int n = 0;
    for (int i = 0; i < 30; i++)
        line[n++] = i < bar ? '#' : '.';
    line[n] = 0;
    fprintf(stderr, "\r%-16.16s [%s] %5.1f%% %6.1fs%s", p->label ? p->label : "", line,
            100.0 * frac, now - p->start_seconds, final ? "\n" : "");
    fflush(stderr);
}

void sl_progress_begin(sl_progress *p, const char *label, int64_t total)
{
    p->label = label;
    p->total = total;
    p->done = 0;
    p->start_seconds = sl_seconds();
    p->last_draw_seconds = 0;
    p->enabled = !quiet && isatty(STDERR_FILENO);
    if (p->enabled) {
        pthread_mutex_lock(&log_lock);
        active_bar = p;
        progress_draw(p, false);
        pthread_mutex_unlock(&log_lock);
    }
}

void sl_progress_add(sl_progress *p, int64_t amount)
{
    if (!p)
        return;
    int64_t done = __atomic_add_fetch(&p->done, amount, __ATOMIC_RELAXED);
    (void)done;
    if (p->enabled && pthread_mutex_trylock(&log_lock) == 0) {
        progress_draw(p, false);
        pthread_mutex_unlock(&log_lock);
    }
}

void sl_progress_end(sl_progress *p)
{
    if (p && p->enabled) {
        pthread_mutex_lock(&log_lock);
        p->done = p->total;
        progress_draw(p, true);
        if (active_bar == p)
            active_bar = NULL;
        pthread_mutex_unlock(&log_lock);
    }
}
