/* SPDX-License-Identifier: BSD-3-Clause */
/* The job graph read back (docs/process.md, "The job graph"): a user or
 * another queue may have edited it, so it is parsed from memory and checked
 * whole (fields, sizes, ids, dependencies) before `setlight job`, the
 * report or the index acts on any of it. The parser writes nothing; the
 * graph is written here too (pl_graph_write), checked as it is written, so
 * that a job may read its own job alone while the file is unchanged. */
#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "pipeline_private.h"
#include "setlight/capture.h" /* sl_sha256_hex */

/* "setup": a whole setup as one job, as the Slurm runner submits a grouped setup. */
static const char *const stages[] = {"merge",  "stitch", "unwrap", "calibrate", "rig",
                                     "render", "report", "index",  "setup",     NULL};

/* "NAME: job 'ID': what", or "NAME: job N: what" (1-based) before its id
 * is known to be good. */
static sl_result bad_job(const char *name, size_t i, const char *id, sl_error *err,
                         const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static sl_result bad_job(const char *name, size_t i, const char *id, sl_error *err,
                         const char *fmt, ...)
{
    char what[640];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    if (id)
        return sl_error_set(err, SL_ERR_INPUT, "%s: job '%s': %s", name, id, what);
    return sl_error_set(err, SL_ERR_INPUT, "%s: job %zu: %s", name, i + 1, what);
}

/* An id names its stamp, OUT/<id>.stamp.json: a relative path with no
 * empty, "." or ".." part (nothing written outside OUT), printable. */
static bool valid_id(const char *id)
{
    size_t n = strlen(id);
    if (!n || n > SL_PIPELINE_MAX_ID)
        return false;
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)id[i] < 0x20 || id[i] == 0x7f)
            return false;
    for (const char *p = id;;) {
        const char *slash = strchr(p, '/');
        size_t len = slash ? (size_t)(slash - p) : strlen(p);
        if (!len || (len == 1 && p[0] == '.') || (len == 2 && p[0] == '.' && p[1] == '.'))
            return false;
        if (!slash)
            return true;
        p = slash + 1;
    }
}

/* What is wrong with a path the runner opens or creates, or NULL. */
static const char *path_problem(const json_t *v)
{
    const char *s = json_string_value(v);
    if (!s)
        return "is not a string";
    if (s[0] != '/')
        return "is not an absolute path";
    if (strlen(s) >= PATH_MAX)
        return "is longer than PATH_MAX";
    return NULL;
}

/* A job's list field: at most SL_PIPELINE_MAX_LIST strings, absolute paths
 * when `paths`, at least one when `nonempty`. */
static sl_result check_list(const char *name, size_t i, const char *id, const json_t *job,
                            const char *key, bool paths, bool nonempty, sl_error *err)
{
    const json_t *list = json_object_get(job, key);
    if (!json_is_array(list))
        return bad_job(name, i, id, err, "\"%s\" is not a list", key);
    size_t n = json_array_size(list);
    if (nonempty && !n)
        return bad_job(name, i, id, err, "\"%s\" is empty", key);
    if (n > SL_PIPELINE_MAX_LIST)
        return bad_job(name, i, id, err, "\"%s\" has %zu entries, more than %d", key, n,
                       SL_PIPELINE_MAX_LIST);
    for (size_t k = 0; k < n; k++) {
        const json_t *x = json_array_get(list, k);
        const char *problem = paths ? path_problem(x) : json_is_string(x) ? NULL
                                                                           : "is not a string";
        if (problem)
            return bad_job(name, i, id, err, "\"%s\" entry %zu %s", key, k + 1, problem);
    }
    return SL_OK;
}

static bool string_or_null(const json_t *v)
{
    return !v || json_is_null(v) || json_is_string(v);
}

/* Every field of one job but its dependencies. */
static sl_result check_job(const char *name, size_t i, const json_t *job, sl_error *err)
{
    if (!json_is_object(job))
        return bad_job(name, i, NULL, err, "not an object");
    const char *id = json_string_value(json_object_get(job, "id"));
    if (!id)
        return bad_job(name, i, NULL, err, "\"id\" is missing or not a string");
    if (!valid_id(id))
        return bad_job(name, i, NULL, err,
                       "\"id\" is not a relative path of at most %d printable bytes with no "
                       "empty, '.' or '..' part",
                       SL_PIPELINE_MAX_ID);
    const char *stage = json_string_value(json_object_get(job, "stage"));
    size_t s = 0;
    while (stage && stages[s] && strcmp(stages[s], stage))
        s++;
    if (!stage || !stages[s])
        return bad_job(name, i, id, err,
                       "\"stage\" is not one of merge, stitch, unwrap, calibrate, rig, render, "
                       "report, index, setup");
    if (!string_or_null(json_object_get(job, "setup")))
        return bad_job(name, i, id, err, "\"setup\" is neither a string nor null");
    sl_result r;
    if ((r = check_list(name, i, id, job, "argv", false, true, err)) ||
        (r = check_list(name, i, id, job, "command", false, true, err)) ||
        (r = check_list(name, i, id, job, "inputs", true, false, err)) ||
        (r = check_list(name, i, id, job, "outputs", true, false, err)) ||
        (r = check_list(name, i, id, job, "deps", false, false, err)))
        return r;
    const char *problem = path_problem(json_object_get(job, "log"));
    if (problem)
        return bad_job(name, i, id, err, "\"log\" %s", problem);
    if (!string_or_null(json_object_get(job, "array")))
        return bad_job(name, i, id, err, "\"array\" is neither a string nor null");
    if (!string_or_null(json_object_get(job, "key")))
        return bad_job(name, i, id, err, "\"key\" is neither a string nor null");
    const json_t *mem = json_object_get(job, "memory_mb"), *cpus = json_object_get(job, "cpus");
    if (!json_is_integer(mem) || json_integer_value(mem) < 0 || json_integer_value(mem) > INT_MAX)
        return bad_job(name, i, id, err, "\"memory_mb\" is not a whole number >= 0");
    if (!json_is_integer(cpus) || json_integer_value(cpus) < 1 ||
        json_integer_value(cpus) > INT_MAX)
        return bad_job(name, i, id, err, "\"cpus\" is not a whole number >= 1");
    /* Optional: other queues' graphs need not estimate. */
    const json_t *cpu_s = json_object_get(job, "cpu_seconds");
    if (cpu_s && !(json_is_number(cpu_s) && json_number_value(cpu_s) >= 0))
        return bad_job(name, i, id, err, "\"cpu_seconds\" is not a number >= 0");
    if (!json_is_boolean(json_object_get(job, "up_to_date")))
        return bad_job(name, i, id, err, "\"up_to_date\" is not true or false");
    return SL_OK;
}

static const char *job_id(const sl_pipeline_graph *g, size_t i)
{
    return json_string_value(json_object_get(json_array_get(g->jobs, i), "id"));
}

/* Every dependency a job of the graph, then Kahn's order over them; a job
 * left over waits on a cycle, which is followed back to name it. */
static sl_result order_jobs(const char *name, sl_pipeline_graph *g, sl_error *err)
{
    size_t n = (size_t)g->count, edges = 0;
    for (size_t i = 0; i < n; i++)
        edges += json_array_size(json_object_get(json_array_get(g->jobs, i), "deps"));
    /* dep[e]: the job edge e waits for; first[i]..first[i+1]: job i's edges. */
    size_t *first = calloc(n + 1, sizeof *first), *dep = calloc(edges + 1, sizeof *dep);
    size_t *left = calloc(n + 1, sizeof *left), *users = calloc(n + 1, sizeof *users);
    size_t *user = calloc(edges + 1, sizeof *user), *fill = calloc(n + 1, sizeof *fill);
    g->order = calloc(n + 1, sizeof *g->order);
    sl_result r = SL_OK;
    if (!first || !dep || !left || !users || !user || !fill || !g->order) {
        r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for %zu jobs", name, n);
        goto done;
    }
    size_t e = 0;
    for (size_t i = 0; i < n && !r; i++) {
        const json_t *job = json_array_get(g->jobs, i);
        const char *id = job_id(g, i);
        first[i] = e;
        size_t k;
        json_t *d;
        json_array_foreach(json_object_get(job, "deps"), k, d) {
            const json_t *at = json_object_get(g->ids, json_string_value(d));
            if (!at) {
                r = bad_job(name, i, id, err, "dependency '%s' is not a job of the graph",
                            json_string_value(d));
                break;
            }
            if ((size_t)json_integer_value(at) == i) {
                r = bad_job(name, i, id, err, "depends on itself");
                break;
            }
            dep[e++] = (size_t)json_integer_value(at);
            users[dep[e - 1]]++;
        }
        left[i] = e - first[i];
    }
    first[n] = e;
    if (r)
        goto done;
    /* users[j]..users[j+1]: the edges waiting for job j (a running sum). */
    size_t sum = 0;
    for (size_t j = 0; j < n; j++) {
        size_t c = users[j];
        users[j] = sum;
        sum += c;
    }
    users[n] = sum;
    for (size_t i = 0; i < n; i++)
        for (size_t k = first[i]; k < first[i + 1]; k++)
            user[users[dep[k]] + fill[dep[k]]++] = i;
    size_t done_count = 0;
    for (size_t i = 0; i < n; i++)
        if (!left[i])
            g->order[done_count++] = (int)i;
    for (size_t k = 0; k < done_count; k++) {
        size_t j = (size_t)g->order[k];
        for (size_t u = users[j]; u < users[j + 1]; u++)
            if (--left[user[u]] == 0)
                g->order[done_count++] = (int)user[u];
    }
    if (done_count < n) {
        /* Every job left waits on another left (fill[i]: its first such
         * dependency): n steps along them land on a cycle. */
        size_t at = n;
        for (size_t i = 0; i < n; i++) {
            if (!left[i])
                continue;
            size_t k = first[i];
            while (!left[dep[k]])
                k++;
            fill[i] = dep[k];
            if (at == n)
                at = i;
        }
        for (size_t step = 0; step < n; step++)
            at = fill[at];
        /* Named from its job listed first. */
        size_t start = at;
        for (size_t j = fill[at]; j != at; j = fill[j])
            if (j < start)
                start = j;
        char path[512] = "";
        size_t len = 0, j = start;
        do {
            if (len < sizeof path)
                len += (size_t)snprintf(path + len, sizeof path - len, "%s -> ", job_id(g, j));
            j = fill[j];
        } while (j != start);
        if (len < sizeof path)
            snprintf(path + len, sizeof path - len, "%s", job_id(g, start));
        r = bad_job(name, start, job_id(g, start), err, "its dependencies form a cycle (%s)", path);
    }
done:
    free(first);
    free(dep);
    free(left);
    free(users);
    free(user);
    free(fill);
    return r;
}

sl_result sl_pipeline_graph_parse(const char *name, const char *text, size_t size,
                                  sl_pipeline_graph **out, sl_error *err)
{
    *out = NULL;
    if (size > SL_MAX_JSON_BYTES)
        return sl_error_set(err, SL_ERR_INPUT, "%s: a job graph of %zu bytes, more than %llu",
                            name, size, (unsigned long long)SL_MAX_JSON_BYTES);
    sl_pipeline_graph *g = calloc(1, sizeof *g);
    if (!g)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", name);
    json_error_t je;
    sl_result r = SL_OK;
    g->root = json_loadb(text, size, JSON_REJECT_DUPLICATES, &je);
    const json_t *version = json_object_get(g->root, "version");
    const char *format = json_string_value(json_object_get(g->root, "format"));
    if (!g->root)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: not a job graph: line %d: %s", name, je.line,
                         je.text);
    else if (!format || strcmp(format, "setlight-jobs"))
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: not a job graph (format is not \"setlight-jobs\")", name);
    else if (!json_is_integer(version) || json_integer_value(version) != 1)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: job graph version is not 1", name);
    else if (path_problem(json_object_get(g->root, "out")))
        r = sl_error_set(err, SL_ERR_INPUT, "%s: \"out\" %s", name,
                         path_problem(json_object_get(g->root, "out")));
    else if (!json_is_array(g->jobs = json_object_get(g->root, "jobs")))
        r = sl_error_set(err, SL_ERR_INPUT, "%s: \"jobs\" is not a list", name);
    else if (json_array_size(g->jobs) > SL_PIPELINE_MAX_JOBS)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: %zu jobs, more than %d", name,
                         json_array_size(g->jobs), SL_PIPELINE_MAX_JOBS);
    if (r) {
        sl_pipeline_graph_free(g);
        return r;
    }
    g->out = json_string_value(json_object_get(g->root, "out"));
    g->count = (int)json_array_size(g->jobs);
    g->ids = json_object();
    for (size_t i = 0; i < (size_t)g->count && !r; i++) {
        const json_t *job = json_array_get(g->jobs, i);
        if ((r = check_job(name, i, job, err)))
            break;
        const char *id = json_string_value(json_object_get(job, "id"));
        if (json_object_get(g->ids, id))
            r = bad_job(name, i, id, err, "two jobs have this id");
        else if (json_object_set_new(g->ids, id, json_integer((json_int_t)i)))
            r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", name);
    }
    if (!r)
        r = order_jobs(name, g, err);
    if (r) {
        sl_pipeline_graph_free(g);
        return r;
    }
    *out = g;
    return SL_OK;
}

int sl_pipeline_graph_job_count(const sl_pipeline_graph *g)
{
    return g ? g->count : 0;
}

const char *sl_pipeline_graph_job_id(const sl_pipeline_graph *g, int k)
{
    if (!g || k < 0 || k >= g->count)
        return NULL;
    return job_id(g, (size_t)g->order[k]);
}

void sl_pipeline_graph_free(sl_pipeline_graph *g)
{
    if (!g)
        return;
    json_decref(g->ids);
    json_decref(g->root);
    free(g->order);
    free(g);
}

json_t *pl_graph_job(const sl_pipeline_graph *g, const char *id)
{
    const json_t *at = json_object_get(g->ids, id);
    return at ? json_array_get(g->jobs, (size_t)json_integer_value(at)) : NULL;
}

/* The whole file, up to SL_MAX_JSON_BYTES, in *text (the caller's to free). */
static sl_result read_graph_text(const char *path, char **out, size_t *out_size, sl_error *err)
{
    *out = NULL;
    *out_size = 0;
    sl_result r = sl_check_input_size(path, SL_MAX_JSON_BYTES, "job graph", err);
    if (r)
        return r;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    char *text = NULL;
    size_t size = 0, cap = 0, limit = (size_t)SL_MAX_JSON_BYTES + 1;
    /* Read to the end, whatever stat said (the file may have grown since),
     * and never more than the cap and one byte. */
    while (!r) {
        if (size == cap) {
            if (cap == limit) {
                r = sl_error_set(err, SL_ERR_INPUT, "%s: a job graph over %llu bytes", path,
                                 (unsigned long long)SL_MAX_JSON_BYTES);
                break;
            }
            cap = cap ? (2 * cap < limit ? 2 * cap : limit) : 65536;
            char *grown = realloc(text, cap);
            if (!grown) {
                r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
                break;
            }
            text = grown;
        }
        size_t got = fread(text + size, 1, cap - size, f);
        size += got;
        if (got == 0) {
            if (ferror(f))
                r = sl_error_set(err, SL_ERR_IO, "%s: cannot read: %s", path, strerror(errno));
            break;
        }
    }
    fclose(f);
    if (r) {
        free(text);
        return r;
    }
    *out = text;
    *out_size = size;
    return SL_OK;
}

sl_result pl_graph_load(const char *path, sl_pipeline_graph **g, sl_error *err)
{
    *g = NULL;
    char *text = NULL;
    size_t size = 0;
    sl_result r = read_graph_text(path, &text, &size, err);
    if (!r)
        r = sl_pipeline_graph_parse(path, text, size, g, err);
    free(text);
    return r;
}

/* ------------------------------------------------------------------ */
/* Checked once: the graph as process writes it, and its sidecar       */
/* ------------------------------------------------------------------ */

#define CHECKED_FORMAT "setlight-jobs-checked"

static void checked_path(const char *path, char *buf, size_t size)
{
    snprintf(buf, size, "%s.checked", path);
}

sl_result pl_graph_write(const char *path, const json_t *graph, sl_error *err)
{
    /* The graph's own fields on the first line, then a job a line: each
     * job's bytes are where the sidecar says. */
    json_t *head = json_copy((json_t *)graph), *offsets = json_object();
    json_object_del(head, "jobs");
    char *head_text = json_dumps(head, JSON_COMPACT | JSON_PRESERVE_ORDER);
    json_decref(head);
    sl_text t = {0};
    if (head_text && strlen(head_text) > 2) {
        sl_text_add(&t, head_text, strlen(head_text) - 1); /* less its '}' */
        sl_text_add_str(&t, ",\"jobs\":[\n");
    } else
        t.failed = true;
    free(head_text);
    const json_t *jobs = json_object_get(graph, "jobs");
    size_t i;
    json_t *job;
    json_array_foreach(jobs, i, job) {
        char *one = json_dumps(job, JSON_COMPACT | JSON_PRESERVE_ORDER);
        const char *id = json_string_value(json_object_get(job, "id"));
        if (!one || !id) {
            free(one);
            t.failed = true;
            break;
        }
        json_object_set_new(offsets, id, json_pack("[I,I]", (json_int_t)t.len,
                                                   (json_int_t)strlen(one)));
        sl_text_add_str(&t, one);
        sl_text_add_str(&t, i + 1 < json_array_size(jobs) ? ",\n" : "\n");
        free(one);
    }
    sl_text_add_str(&t, "]}\n");
    sl_result r = SL_OK;
    if (t.failed || !t.s)
        r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    /* Checked whole here, by the parser every reader uses, so that a job
     * need not check it again while the file is unchanged. */
    sl_pipeline_graph *g = NULL;
    if (!r)
        r = sl_pipeline_graph_parse(path, t.s, t.len, &g, err);
    sl_pipeline_graph_free(g);
    char hex[65], side[PATH_MAX + 16];
    checked_path(path, side, sizeof side);
    if (!r) {
        unlink(side); /* never a sidecar beside a graph it does not describe */
        sl_atomic_sweep(path); /* what a runner killed while writing them left */
        sl_atomic_sweep(side);
        r = sl_write_file_atomic(path, t.s, t.len, err);
    }
    if (!r) {
        sl_sha256_hex(t.s, t.len, hex);
        json_t *doc = json_pack("{s:s,s:i,s:s,s:I,s:O}", "format", CHECKED_FORMAT, "version", 1,
                                "graph_sha256", hex, "graph_bytes", (json_int_t)t.len, "jobs",
                                offsets);
        char *text = doc ? json_dumps(doc, JSON_COMPACT) : NULL;
        r = text ? sl_write_file_atomic(side, text, strlen(text), err)
                 : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", side);
        free(text);
        json_decref(doc);
    }
    json_decref(offsets);
    sl_text_free(&t);
    return r;
}

/* The job from the sidecar's offsets when the graph is byte for byte the
 * one it was written with (its SHA-256), or NULL: anything else (no
 * sidecar, another graph, an offset that does not hold the job) sends the
 * caller to the whole check. */
static json_t *checked_job(const char *path, const char *text, size_t size, const char *id)
{
    char side[PATH_MAX + 16], hex[65];
    checked_path(path, side, sizeof side);
    struct stat sb;
    if (stat(side, &sb) || (unsigned long long)sb.st_size > SL_MAX_JSON_BYTES)
        return NULL;
    json_error_t je;
    json_t *doc = json_load_file(side, 0, &je), *job = NULL;
    const char *format = json_string_value(json_object_get(doc, "format"));
    const char *sum = json_string_value(json_object_get(doc, "graph_sha256"));
    const json_t *at = json_object_get(json_object_get(doc, "jobs"), id);
    json_int_t off = json_integer_value(json_array_get(at, 0));
    json_int_t len = json_integer_value(json_array_get(at, 1));
    if (format && !strcmp(format, CHECKED_FORMAT) &&
        json_integer_value(json_object_get(doc, "version")) == 1 && sum &&
        json_integer_value(json_object_get(doc, "graph_bytes")) == (json_int_t)size && off > 0 &&
        len > 0 && (size_t)off + (size_t)len <= size) {
        sl_sha256_hex(text, size, hex);
        if (!strcmp(hex, sum))
            job = json_loadb(text + off, (size_t)len, JSON_REJECT_DUPLICATES, &je);
    }
    json_decref(doc);
    const char *jid = json_string_value(json_object_get(job, "id"));
    if (!json_is_object(job) || !jid || strcmp(jid, id)) {
        json_decref(job);
        return NULL;
    }
    return job;
}

sl_result pl_graph_load_job(const char *path, const char *id, json_t **graph, json_t **job,
                            bool *checked_whole, sl_error *err)
{
    *graph = *job = NULL;
    *checked_whole = false;
    char *text = NULL;
    size_t size = 0;
    sl_result r = read_graph_text(path, &text, &size, err);
    if (r)
        return r;
    json_t *one = checked_job(path, text, size, id);
    const char *stage = json_string_value(json_object_get(one, "stage"));
    if (one && stage && strcmp(stage, "index")) {
        /* The fields a job reads of the graph: its "out" (the stamps). */
        json_error_t je;
        const char *end = strstr(text, ",\"jobs\":[\n");
        json_t *head = NULL;
        if (end) {
            char *h = strndup(text, (size_t)(end - text) + 1);
            if (h) {
                h[end - text] = '}';
                head = json_loads(h, 0, &je);
                free(h);
            }
        }
        if (head && json_string_value(json_object_get(head, "out"))) {
            *graph = head;
            *job = one;
            free(text);
            return SL_OK;
        }
        json_decref(head);
    }
    json_decref(one);
    sl_pipeline_graph *g = NULL;
    r = sl_pipeline_graph_parse(path, text, size, &g, err);
    free(text);
    if (r)
        return r;
    *checked_whole = true;
    json_t *found = pl_graph_job(g, id);
    if (!found) {
        sl_pipeline_graph_free(g);
        return sl_error_set(err, SL_ERR_USAGE, "%s: no job '%s'", path, id);
    }
    *graph = json_incref(g->root);
    *job = json_incref(found);
    sl_pipeline_graph_free(g);
    return SL_OK;
}
