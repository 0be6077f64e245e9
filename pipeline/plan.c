/* SPDX-License-Identifier: BSD-3-Clause */
/* The planner: each SETUP folder to its session(s) (ingested first when it
 * is a plain folder or a virtual-set capture), then to its jobs. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "pipeline_private.h"
#include "setlight/capture.h"

/* --- Jobs --- */

static json_t *strs(const char *first, ...)
{
    json_t *a = json_array();
    va_list ap;
    va_start(ap, first);
    for (const char *s = first; s; s = va_arg(ap, const char *))
        json_array_append_new(a, json_string(s));
    va_end(ap);
    return a;
}

/* Appends b's items to a and drops b. */
static void extend_new(json_t *a, json_t *b)
{
    json_array_extend(a, b);
    json_decref(b);
}

static void push(json_t *a, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void push(json_t *a, const char *fmt, ...)
{
    char buf[2 * PATH_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    json_array_append_new(a, json_string(buf));
}

static double file_mb(const char *p)
{
    struct stat st;
    return stat(p, &st) ? 0 : (double)st.st_size / (1 << 20);
}

/* A frame's megapixels from its header (no pixels read); a file whose
 * header does not read (the merge will say why) counts 3 bytes a pixel. */
static double frame_mp(const char *path)
{
    sl_meta meta;
    sl_error err;
    int w = 0, h = 0, c = 0;
    sl_meta_init(&meta);
    sl_result r = sl_photo_read_meta(path, &meta, &w, &h, &c, &err);
    sl_meta_free(&meta);
    return r || w <= 0 || h <= 0 ? file_mb(path) * (1 << 20) / 3e6 : (double)w * h / 1e6;
}

/* A job's CPU estimate (one thread): a stage's fixed part (start-up,
 * libraries, fixed-size work such as the 128 px renders) plus seconds per
 * megapixel of the pixels it works on. Fitted to the jobs' stamps at the
 * virtual set's tiny (192x128) and small (720x480) sizes, within about 30%
 * of a setup's total there (docs/process.md, "The graph"); beyond, the
 * per-pixel part is extrapolated. */
typedef struct cpu_model {
    double fixed_s, per_mp_s;
} cpu_model;
static const cpu_model cpu_merge = {0.025, 0.05};     /* per MP of the bracket's frames */
static const cpu_model cpu_stitch = {0.06, 0.71};     /* per MP of the fisheye views */
static const cpu_model cpu_unwrap = {0.03, 0.3};      /* per MP of the chrome ball's view */
static const cpu_model cpu_calibrate = {0.45, 0.27};  /* per MP of the fisheye views */
static const cpu_model cpu_rig = {0.15, 0.3};         /* per MP of the fisheye views */
static const cpu_model cpu_render = {0.25, 0};        /* 128 px, 32 spp */
static const cpu_model cpu_report = {0.27, 0.073};    /* per MP of the fisheye views */
static const cpu_model cpu_index = {0.02, 0};

static double cpu_estimate(cpu_model m, double mp)
{
    return round((m.fixed_s + m.per_mp_s * mp) * 100) / 100;
}

/* Adds a job. command, inputs, outputs, deps: new references taken. The
 * memory estimate: the stage's base (start-up, libraries) plus a multiple of
 * its input files' size (decoded pixels are 2-12x their files); cpu_s: its
 * CPU estimate (cpu_estimate). */
static json_t *add_job(json_t *jobs, const char *out, const char *jobs_path, const char *setup,
                       const char *stage, int n, const char *array, json_t *command,
                       json_t *inputs, json_t *outputs, json_t *deps, int base_mb, double per_mb,
                       double cpu_s)
{
    char id[512], log[2 * PATH_MAX];
    if (n >= 0)
        snprintf(id, sizeof id, "%s/%s/%d", setup, stage, n);
    else if (setup)
        snprintf(id, sizeof id, "%s/%s", setup, stage);
    else
        snprintf(id, sizeof id, "%s", stage);
    char flat[512];
    snprintf(flat, sizeof flat, "%s", id);
    for (char *p = flat; *p; p++)
        if (*p == '/')
            *p = '_';
    snprintf(log, sizeof log, "%s/logs/%s.log", out, flat);
    double in_mb = 0;
    size_t i;
    json_t *x;
    json_array_foreach(inputs, i, x)
        in_mb += file_mb(json_string_value(x));
    json_t *job = json_object();
    json_object_set_new(job, "id", json_string(id));
    json_object_set_new(job, "setup", setup ? json_string(setup) : json_null());
    json_object_set_new(job, "stage", json_string(stage));
    json_object_set_new(job, "argv", strs(json_string_value(json_array_get(command, 0)), "job",
                                          jobs_path, id, NULL));
    json_object_set_new(job, "command", command);
    json_object_set_new(job, "inputs", inputs);
    json_object_set_new(job, "outputs", outputs);
    json_object_set_new(job, "deps", deps);
    json_object_set_new(job, "array", array ? json_string(array) : json_null());
    json_object_set_new(job, "memory_mb", json_integer(base_mb + (int)(per_mb * in_mb + 0.5)));
    json_object_set_new(job, "cpus", json_integer(1));
    json_object_set_new(job, "cpu_seconds", json_real(cpu_s));
    json_object_set_new(job, "log", json_string(log));
    json_object_set_new(job, "key", json_null());
    json_object_set_new(job, "up_to_date", json_false());
    json_array_append_new(jobs, job);
    return job;
}

static const char *id_of(const json_t *job)
{
    return json_string_value(json_object_get(job, "id"));
}

/* The report follows the job and reads its output number `result`. */
static void report_on(json_t *report_deps, json_t *report_in, const json_t *job, size_t result)
{
    json_array_append_new(report_deps, json_string(id_of(job)));
    json_array_append(report_in, json_array_get(json_object_get(job, "outputs"), result));
}

/* A stage job whose outputs are its image and its result
 * (DIR/STAGE/STAGE.result.json, what --json prints); the report reads the
 * result. cmd, inputs, deps: new references taken. */
static json_t *add_stage_job(const setup_plan *sp, json_t *jobs, const char *out,
                             const char *jobs_path, json_t *report_deps, json_t *report_in,
                             const char *stage, const char *image, json_t *cmd, json_t *inputs,
                             json_t *deps, int base_mb, double cpu_s)
{
    extend_new(cmd, strs("--json", "--threads", "1", NULL));
    json_t *outs = strs(image, NULL);
    push(outs, "%s/%s/%s.result.json", sp->dir, stage, stage);
    json_t *job = add_job(jobs, out, jobs_path, sp->name, stage, -1, NULL, cmd, inputs, outs,
                          deps, base_mb, 8, cpu_s);
    report_on(report_deps, report_in, job, 1);
    return job;
}

/* The setup's graph. Every command runs single-threaded (--threads 1): the
 * parallelism is across jobs, and the keys do not depend on the machine. */
static void plan_jobs(setup_plan *sp, json_t *jobs, const char *out, const char *jobs_path)
{
    const sl_pipeline_options *o = sp->o;
    const char *exe = o->exe, *s = sp->name, *d = sp->dir;
    /* The fisheye views: the widest lens of the views that are not probes. */
    double wide = 0;
    for (int i = 0; i < sp->view_count; i++)
        if (!sp->views[i].probe && sp->views[i].focal_mm > 0 &&
            (!wide || sp->views[i].focal_mm < wide))
            wide = sp->views[i].focal_mm;
    /* Megapixels of a frame of each view, and of the fisheye views together. */
    double view_mp[sizeof sp->views / sizeof sp->views[0]] = {0}, fisheye_mp = 0;
    for (int i = 0; i < sp->view_count; i++) {
        view *v = &sp->views[i];
        if (v->probe == PROBE_CHART || (!v->probe && wide && v->focal_mm != wide))
            continue;
        view_mp[i] = frame_mp(json_string_value(json_array_get(v->frames, 0)));
        if (!v->probe)
            fisheye_mp += view_mp[i];
    }
    char arr[600];
    snprintf(arr, sizeof arr, "%s/merge", s);
    json_t *view_deps = json_array(), *stitch_in = json_array(), *report_in = json_array(),
           *report_deps = json_array();
    int n = 0, chrome = -1, grey = -1, chart = -1;
    double chrome_mp = 0;
    for (int i = 0; i < sp->view_count; i++) {
        view *v = &sp->views[i];
        if (v->probe == PROBE_CHART) {
            chart = i;
            continue;
        }
        if (!v->probe && wide && v->focal_mm != wide)
            continue; /* neither a fisheye view nor a known probe */
        json_t *cmd = strs(exe, "merge", "-o", NULL), *out_files = json_array();
        push(cmd, "%s/merge/%d.exr", d, n);
        json_array_extend(cmd, v->frames);
        extend_new(cmd, strs("--json", "--threads", "1", NULL));
        push(out_files, "%s/merge/%d.exr", d, n);
        push(out_files, "%s/merge/%d_clipped.exr", d, n);
        push(out_files, "%s/merge/%d.result.json", d, n);
        json_t *job = add_job(jobs, out, jobs_path, s, "merge", n, arr, cmd,
                              json_deep_copy(v->frames), out_files, json_array(), 160, 6,
                              cpu_estimate(cpu_merge, view_mp[i] * (double)json_array_size(v->frames)));
        report_on(report_deps, report_in, job, 2);
        if (v->probe == PROBE_CHROME)
            chrome = n, chrome_mp = view_mp[i];
        else if (v->probe == PROBE_GREY)
            grey = n;
        else {
            json_array_append_new(view_deps, json_string(id_of(job)));
            push(stitch_in, "%s/merge/%d.exr", d, n);
            push(stitch_in, "%s/merge/%d_clipped.exr", d, n);
        }
        n++;
    }
    char hdri[2 * PATH_MAX], env[2 * PATH_MAX], az[64], el[64], view_arg[128], focal[64],
        sensor[64];
    snprintf(hdri, sizeof hdri, "%s/stitch/hdri.exr", d);
    snprintf(az, sizeof az, "%g", o->probe_azimuth_deg);
    snprintf(el, sizeof el, "%g", o->probe_elevation_deg);
    snprintf(view_arg, sizeof view_arg, "%s,%s", az, el);
    double probe_focal = 0;
    for (int i = 0; i < sp->view_count; i++)
        if (sp->views[i].probe && sp->views[i].focal_mm > 0)
            probe_focal = sp->views[i].focal_mm;
    snprintf(focal, sizeof focal, "%g", probe_focal);
    snprintf(sensor, sizeof sensor, "%g", o->probe_sensor_mm > 0 ? o->probe_sensor_mm : sp->sensor_mm);
    bool lens = probe_focal > 0 && (o->probe_sensor_mm > 0 || sp->sensor_mm > 0);

    json_t *cmd = strs(exe, "stitch", "-o", hdri, NULL), *in = json_array();
    for (size_t i = 0; i < json_array_size(stitch_in); i += 2)
        json_array_append(cmd, json_array_get(stitch_in, i));
    json_array_extend(in, stitch_in);
    json_t *stitch = add_stage_job(sp, jobs, out, jobs_path, report_deps, report_in, "stitch",
                                   hdri, cmd, in, view_deps, 200,
                                   cpu_estimate(cpu_stitch, fisheye_mp));
    json_decref(stitch_in);

    if (chrome >= 0) {
        char unwrapped[2 * PATH_MAX], dep[600];
        snprintf(unwrapped, sizeof unwrapped, "%s/unwrap/chrome.exr", d);
        cmd = strs(exe, "unwrap", "-o", unwrapped, NULL);
        push(cmd, "%s/merge/%d.exr", d, chrome);
        extend_new(cmd, strs("--camera-azimuth", az, "--camera-elevation", el, NULL));
        if (lens)
            extend_new(cmd, strs("--focal-mm", focal, "--sensor-mm", sensor, NULL));
        in = json_array();
        push(in, "%s/merge/%d.exr", d, chrome);
        snprintf(dep, sizeof dep, "%s/merge/%d", s, chrome);
        add_stage_job(sp, jobs, out, jobs_path, report_deps, report_in, "unwrap", unwrapped, cmd,
                      in, strs(dep, NULL), 160, cpu_estimate(cpu_unwrap, chrome_mp));
    }

    snprintf(env, sizeof env, "%s", hdri);
    json_t *env_dep = json_string(id_of(stitch));
    if (grey >= 0 || chart >= 0) {
        snprintf(env, sizeof env, "%s/calibrate/hdri.exr", d);
        cmd = strs(exe, "calibrate", "--hdri", hdri, "-o", env, NULL);
        in = strs(hdri, NULL);
        json_t *deps = strs(id_of(stitch), NULL);
        if (chart >= 0) {
            /* The chart's middle exposure, metered for it, alone: a merge
             * would mix frames the camera clipped per channel. */
            json_t *fr = sp->views[chart].frames;
            json_t *mid = json_array_get(fr, json_array_size(fr) / 2);
            extend_new(cmd, strs("--chart", json_string_value(mid), NULL));
            json_array_append(in, mid);
        }
        if (grey >= 0) {
            json_array_append_new(cmd, json_string("--grey"));
            push(cmd, "%s/merge/%d.exr", d, grey);
            push(in, "%s/merge/%d.exr", d, grey);
            extend_new(cmd, strs("--grey-view", view_arg, NULL));
            if (lens)
                extend_new(cmd, strs("--focal-mm", focal, "--sensor-mm", sensor, NULL));
            char dep[600];
            snprintf(dep, sizeof dep, "%s/merge/%d", s, grey);
            json_array_append_new(deps, json_string(dep));
        }
        json_t *job = add_stage_job(sp, jobs, out, jobs_path, report_deps, report_in,
                                    "calibrate", env, cmd, in, deps, 220,
                                    cpu_estimate(cpu_calibrate, fisheye_mp));
        json_decref(env_dep);
        env_dep = json_string(id_of(job));
    }

    char rig[2 * PATH_MAX], rig_json[2 * PATH_MAX], residual[2 * PATH_MAX];
    snprintf(rig, sizeof rig, "%s/rig/rig.usda", d);
    snprintf(rig_json, sizeof rig_json, "%s/rig/rig.json", d);
    snprintf(residual, sizeof residual, "%s/rig/rig_residual.exr", d);
    cmd = strs(exe, "rig", env, "-o", rig, "--json", rig_json, NULL);
    push(cmd, "--preview");
    push(cmd, "%s/rig/preview.png", d);
    extend_new(cmd, strs("--threads", "1", NULL));
    json_t *outs = strs(rig, rig_json, residual, NULL);
    push(outs, "%s/rig/preview.png", d);
    push(outs, "%s/rig/rig.result.json", d);
    json_t *rig_job = add_job(jobs, out, jobs_path, s, "rig", -1, NULL, cmd, strs(env, NULL),
                              outs, json_array(), 160, 8, cpu_estimate(cpu_rig, fisheye_mp));
    json_array_append(json_object_get(rig_job, "deps"), env_dep);
    report_on(report_deps, report_in, rig_job, 4);

    static const char *const scenes[] = {"grey", "chrome", "chart"};
    snprintf(arr, sizeof arr, "%s/render", s);
    for (int k = 0; k < 6; k++) {
        bool by_rig = k >= 3;
        char file[2 * PATH_MAX];
        snprintf(file, sizeof file, "%s/render/%s_%s.exr", d, by_rig ? "rig" : "env", scenes[k % 3]);
        cmd = strs(exe, "render", by_rig ? "--rig" : "--env", by_rig ? rig_json : env, "--scene",
                   scenes[k % 3], "--width", "128", "--spp", "32", "-o", file, "--threads", "1",
                   NULL);
        in = by_rig ? strs(rig_json, residual, NULL) : strs(env, NULL);
        json_t *deps = json_array();
        json_array_append(deps, env_dep);
        json_array_append_new(deps, json_string(id_of(rig_job)));
        json_t *job = add_job(jobs, out, jobs_path, s, "render", k, arr, cmd, in,
                              strs(file, NULL), deps, 80, 8, cpu_estimate(cpu_render, 0));
        report_on(report_deps, report_in, job, 0);
    }
    json_decref(env_dep);

    json_array_append_new(report_in, json_string(env));
    outs = json_array();
    push(outs, "%s/report.html", d);
    push(outs, "%s/report.json", d);
    for (int k = 0; k < PL_REPORT_PICTURES; k++)
        push(outs, "%s/%s", d, pl_report_pictures[k]);
    add_job(jobs, out, jobs_path, s, "report", -1, NULL,
            strs(exe, "process-report", jobs_path, s, NULL), report_in, outs, report_deps, 120, 4,
            cpu_estimate(cpu_report, fisheye_mp));
}

static bool valid_name(const char *name)
{
    return *name && strcmp(name, ".") && strcmp(name, "..") && strcmp(name, "logs") &&
           !strchr(name, '/');
}

/* The setup's name: its folder's last component. */
static void setup_name(const char *path, char *name, size_t size)
{
    char buf[PATH_MAX];
    snprintf(buf, sizeof buf, "%s", path);
    size_t n = strlen(buf);
    while (n > 1 && buf[n - 1] == '/')
        buf[--n] = 0;
    const char *b = strrchr(buf, '/');
    snprintf(name, size, "%s", b && b[1] ? b + 1 : buf);
}

/* sp (zeroed) for setup i, named `name`, of OUT: its source's real path in
 * src, its folder made, its views loaded (ingested first when needed,
 * pl_load_setup). */
static sl_result setup_load(setup_plan *sp, const sl_pipeline_options *o, const char *out, int i,
                            const char *name, char src[PATH_MAX], sl_error *err)
{
    sp->o = o;
    sp->name = name;
    sp->warnings = json_array();
    snprintf(sp->dir, sizeof sp->dir, "%s/%s", out, name);
    if (!realpath(o->setups[i], src))
        snprintf(src, PATH_MAX, "%s", o->setups[i]);
    sl_error_clear(err);
    sl_result r = pl_mkdirs(sp->dir, err);
    return r ? r : pl_load_setup(sp, src, err);
}

/* The ingest (every frame copied into OUT and hashed) is the runner's work
 * before the first job starts, while the slots idle. It waits on the disk
 * more than it computes (a frame's atomic write ends in an fsync: 12 tiny
 * setups, 0.6 s of CPU in 2-4 s), and concurrent fsyncs are committed
 * together: 12 tiny setups ingest in 4.1 s in one process, 3.0 s in two,
 * 2.0 s in four, no less in eight. */
enum { INGEST_PROCESSES = 4 };

/* So the setups are loaded first in INGEST_PROCESSES processes, whatever
 * --jobs, each setup i by process i mod N; the plan then loads each
 * again, in order, and finds its ingest up to date (ingest_cached). A setup
 * a process could not load is left to the plan, which says why. The
 * processes' CPU and their waits for a CPU go to cost's runner figures. */
static void ingest_ahead(const sl_pipeline_options *o, const char *out, char names[][256],
                         sl_pipeline_result *cost)
{
    int n = INGEST_PROCESSES;
    if (n > o->setup_count)
        n = o->setup_count;
    if (n < 2 || n > 64)
        return;
    pid_t pids[64];
    int started = 0;
    fflush(NULL); /* nothing buffered is written twice */
    for (int c = 0; c < n; c++) {
        pid_t pid = fork();
        if (pid == 0) {
            for (int i = c; i < o->setup_count; i += n) {
                setup_plan *sp = calloc(1, sizeof *sp);
                char src[PATH_MAX];
                sl_error ignored;
                if (sp)
                    setup_load(sp, o, out, i, names[i], src, &ignored);
                /* freed by _exit */
            }
            _exit(0);
        }
        if (pid > 0)
            pids[started++] = pid;
    }
    /* The waits stand for slot time the machine's other work took; more
     * processes than slots also wait for each other, so theirs count for
     * the slots only: slots / n of their sum. */
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    int slots = o->jobs > 0 && (cores < 1 || o->jobs < cores) ? o->jobs : (int)cores;
    double share = slots > 0 && slots < n ? (double)slots / n : 1;
    for (int c = 0; c < started; c++) {
        struct rusage ru;
        double cpu_wait;
        pl_reap(pids[c], &ru, &cpu_wait);
        cost->runner_cpu_seconds += pl_cpu_seconds(&ru);
        cost->runner_cpu_wait_seconds += cpu_wait * share;
    }
}

sl_result pl_plan(const sl_pipeline_options *o, char *jobs_path, size_t jobs_path_size,
                  json_t **graph, json_t **setups, sl_pipeline_result *cost, sl_error *err)
{
    *graph = NULL;
    *setups = NULL;
    /* Refused before anything is written: two setups of one name, an OUT
     * that is a file. */
    char names[256][256];
    if (o->setup_count < 1 || o->setup_count > 256)
        return sl_error_set(err, SL_ERR_USAGE, "between 1 and 256 setups, not %d", o->setup_count);
    for (int i = 0; i < o->setup_count; i++) {
        setup_name(o->setups[i], names[i], sizeof names[i]);
        if (!valid_name(names[i]))
            return sl_error_set(err, SL_ERR_USAGE, "%s: a setup's folder name cannot be '%s'",
                                o->setups[i], names[i]);
        for (int j = 0; j < i; j++)
            if (!strcmp(names[i], names[j]))
                return sl_error_set(err, SL_ERR_USAGE,
                                    "%s and %s: two setups named '%s' (their outputs would mix)",
                                    o->setups[j], o->setups[i], names[i]);
    }
    struct stat st;
    if (!stat(o->out, &st) && !S_ISDIR(st.st_mode))
        return sl_error_set(err, SL_ERR_USAGE, "%s: the output is a file, not a folder", o->out);
    sl_result r = pl_mkdirs(o->out, err);
    char out[PATH_MAX], logs[PATH_MAX + 8];
    if (r)
        return r;
    if (!realpath(o->out, out))
        return sl_error_set(err, SL_ERR_IO, "%s: %s", o->out, strerror(errno));
    if (!jobs_path[0])
        snprintf(jobs_path, jobs_path_size, "%s/jobs.json", out);
    snprintf(logs, sizeof logs, "%s/logs", out);
    if ((r = pl_mkdirs(logs, err)))
        return r;

    ingest_ahead(o, out, names, cost);
    json_t *jobs = json_array(), *list = json_array();
    json_t *index_deps = json_array();
    for (int i = 0; i < o->setup_count; i++) {
        setup_plan *sp = calloc(1, sizeof *sp);
        if (!sp) {
            r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
            break;
        }
        char src[PATH_MAX];
        sl_error se;
        sl_result sr = setup_load(sp, o, out, i, names[i], src, &se);
        int fisheye = 0;
        for (int v = 0; v < sp->view_count; v++)
            fisheye += !sp->views[v].probe;
        if (!sr && !fisheye)
            sr = sl_error_set(&se, SL_ERR_INPUT, "%s: no bracket of frames to merge", src);
        json_t *entry = json_pack("{s:s,s:s,s:s}", "name", names[i], "source", src, "status",
                                  sr ? "failed" : "ok");
        if (sr) {
            json_object_set_new(entry, "reason", json_string(se.message));
            json_object_set_new(entry, "exit", json_integer(sl_result_exit_code(sr)));
        } else {
            size_t before = json_array_size(jobs);
            plan_jobs(sp, jobs, out, jobs_path);
            json_array_append_new(index_deps,
                                  json_string(id_of(json_array_get(jobs, json_array_size(jobs) - 1))));
            json_object_set_new(entry, "jobs", json_integer((json_int_t)(json_array_size(jobs) - before)));
        }
        json_object_set_new(entry, "warnings", sp->warnings);
        json_array_append_new(list, entry);
        for (int v = 0; v < sp->view_count; v++)
            json_decref(sp->views[v].frames);
        free(sp);
    }
    if (r) {
        json_decref(jobs);
        json_decref(list);
        json_decref(index_deps);
        return r;
    }
    char setups_path[2 * PATH_MAX];
    snprintf(setups_path, sizeof setups_path, "%s/setups.json", out);
    json_t *setups_doc = json_pack("{s:s,s:i,s:O}", "format", "setlight-setups", "version", 1,
                                   "setups", list);
    sl_atomic_sweep(setups_path); /* what a runner killed while writing it left */
    r = pl_json_write(setups_path, setups_doc, err);
    json_decref(setups_doc);
    json_t *in = json_array(), *outs = json_array();
    push(in, "%s", setups_path);
    push(in, "%s/status.json", out);
    push(outs, "%s/index.html", out);
    push(outs, "%s/index.json", out);
    add_job(jobs, out, jobs_path, NULL, "index", -1, NULL,
            strs(o->exe, "process-index", jobs_path, NULL), in, outs, index_deps, 120, 4,
            cpu_estimate(cpu_index, 0));
    *graph = json_pack("{s:s,s:i,s:s,s:s,s:o}", "format", "setlight-jobs", "version", 1,
                       "setlight", sl_version(), "out", out, "jobs", jobs);
    /* Keys where the inputs exist, and whether the stamp matches. */
    size_t k;
    json_t *job;
    json_array_foreach(jobs, k, job) {
        char key[65];
        if (pl_job_key(job, key)) {
            json_object_set_new(job, "key", json_string(key));
            json_object_set_new(job, "up_to_date", json_boolean(pl_stamp_current(*graph, job, key)));
        }
    }
    *setups = list;
    if (r) {
        json_decref(*graph);
        json_decref(list);
        *graph = *setups = NULL;
    }
    return r;
}
