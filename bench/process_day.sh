#!/usr/bin/env bash
# A simulated shoot day through setlight process (docs/process.md, "Cost of
# a run"): N setups (default 50, --size small, exterior, stage and night in
# turn: 3 fisheye views x 7 frames and the three probes each), processed
# locally with --jobs 1 and --jobs 2, and through Slurm on a single-node test
# cluster (tests/slurm/cluster.sh, 2 CPUs): a Slurm job per job (slurm,
# --farm-group job), per setup (slurm-setup, --farm-group setup), and as
# the default chooses per setup (slurm-auto, --farm-group auto: the choices
# are printed). Per mode, medians of RUNS runs (default 1), each from an empty OUT: wall, the commands' CPU, their wait
# for a CPU (the machine's other load), peak memory (the runner's
# accounting), jobs per minute, and the overhead per job, (wall x cores -
# CPU) / jobs, with its share of the CPU; the same less the wait.
#   bench/process_day.sh BUILD_DIR [N [SIZE [RUNS [MODES]]]]
# MODES: any of "jobs1 jobs2 slurm slurm-setup slurm-auto" (default all five).
# SETLIGHT_BENCH_SCENES: the scenes the day cycles (default "exterior stage
# night"). Work files in SETLIGHT_BENCH_WORK (default
# /tmp/setlight-bench/day); the simulated day is kept there and reused.
set -u
here=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:?usage: process_day.sh BUILD_DIR [N [SIZE [RUNS [MODES]]]]}" && pwd)
n=${2:-50}
size=${3:-small}
runs=${4:-1}
modes=${5:-jobs1 jobs2 slurm slurm-setup slurm-auto}
work=${SETLIGHT_BENCH_WORK:-/tmp/setlight-bench/day}
exe="$build/setlight"
mkdir -p "$work"
. "$here/tests/cli/day.bash"
printf 'leak:cv::fastMalloc\n' >"$work/lsan.supp"
export LSAN_OPTIONS="suppressions=$work/lsan.supp"

t0=$(date +%s.%N)
simulate_day "$exe" "$n" "$size" "$work/sets" 10 "${SETLIGHT_BENCH_SCENES:-exterior stage night}" || { echo "simulating the day failed" >&2; exit 1; }
echo "day: $n setups, --size $size ($(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.0f", b-a}') s to simulate or reuse)"
setups=("$work"/sets/setup_*)

cluster=""
stop_cluster() { [ -n "$cluster" ] && bash "$here/tests/slurm/cluster.sh" stop "$cluster" >/dev/null 2>&1; [ -n "$cluster" ] && rm -rf "$cluster"; }
trap stop_cluster EXIT

results="$work/results.jsonl"
: >"$results"
for mode in $modes; do
  args=(--jobs 2)
  cores=2
  case $mode in
  jobs1) args=(--jobs 1) cores=1 ;;
  jobs2) ;;
  slurm | slurm-setup | slurm-auto)
    cluster=$(mktemp -d /tmp/sl-day-bench.XXXXXX)
    chmod 755 "$cluster"
    if ! bash "$here/tests/slurm/cluster.sh" start "$cluster" >/dev/null 2>"$work/cluster.err"; then
      echo "slurm: skipped, the cluster did not start: $(head -1 "$work/cluster.err")"
      rm -rf "$cluster"
      cluster=""
      continue
    fi
    export SLURM_CONF="$cluster/slurm.conf"
    args=(--farm slurm --farm-group "$(case $mode in slurm) echo job ;; slurm-setup) echo setup ;; *) echo auto ;; esac)")
    ;;
  *) echo "unknown mode $mode" >&2; exit 2 ;;
  esac
  for ((r = 1; r <= runs; r++)); do
    rm -rf "$work/out"
    load0=$(cut -d' ' -f1 /proc/loadavg)
    /usr/bin/time -v -o "$work/time.txt" "$exe" process "${setups[@]}" -o "$work/out" --probe-view 180,0 \
      "${args[@]}" --json -q >"$work/run.json" 2>"$work/run.err"
    rc=$?
    load1=$(cut -d' ' -f1 /proc/loadavg)
    python3 - "$work/run.json" "$work/time.txt" "$mode" "$cores" "$rc" "$load0" "$load1" "$work/out" >>"$results" <<'PY'
import glob, json, re, sys
path, timef, mode, cores, rc, l0, l1, out = sys.argv[1:]
# From the jobs' stamps (each job's own clock: started when `setlight job`
# began, ended when its stamp was made, seconds the command's wall): from
# the first job's start to the last one's end, the slot time no job held
# (scheduling passes, process start-up between jobs, the tail) and the
# wrapper's own time inside each job (graph, input hashes, stamp).
st, index = [], None
for f in glob.glob(out + "/**/*.stamp.json", recursive=True):
    try:
        s = json.load(open(f))
        st.append((s["started"], s["ended"], s["seconds"]))
        if s.get("id") == "index":
            index = s["started"]
    except (ValueError, KeyError):
        pass
stamps = None
if st:
    span = max(e for _, e, _ in st) - min(b for b, _, _ in st)
    busy = sum(e - b for b, e, _ in st)
    # The day's tail: the slot time left idle after the last moment every
    # slot held a job (a setup's serial chain running alone), and the wait
    # from the last other job's end to the index's start.
    work = [(b, e) for b, e, _ in st if b != index]
    events = sorted([(b, 1) for b, _ in work] + [(e, -1) for _, e in work])
    at, full = 0, min(b for b, _ in work) if work else 0
    for t, d in events:
        if at >= int(cores) and at + d < int(cores):
            full = t
        at += d
    others = [e for _, e in work]
    tail = sum(max(0.0, e - max(b, full)) for b, e in work)
    stamps = {"jobs": len(st), "span": span, "busy": busy,
              "slot_gaps": int(cores) * span - busy, "wrapper": sum(e - b - w for b, e, w in st),
              "command": sum(w for _, _, w in st),
              "tail_idle": int(cores) * (max(others) - full) - tail if others else 0,
              "index_wait": index - max(others) if index is not None and others else None}
try:
    d = json.load(open(path))
except ValueError:
    d = {"run": {}, "jobs": {}}
t = open(timef).read()
rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", t)
print(json.dumps({"mode": mode, "cores": int(cores), "exit": int(rc), "load": [float(l0), float(l1)],
                  "largest_process_mb": int(rss.group(1)) / 1024 if rss else None,
                  "jobs": d.get("jobs"), "run": d.get("run"), "stamps": stamps,
                  "farm": [s["farm"]["group"] for s in d.get("setups", []) if s.get("farm")],
                  "farm_reason": next((s["farm"]["reason"] for s in d.get("setups", []) if s.get("farm")), None)}))
PY
    echo "$mode run $r: exit $rc, load $load0 -> $load1"
  done
  if [ "$mode" != "${mode#slurm}" ]; then stop_cluster; cluster=""; unset SLURM_CONF; fi
done

python3 - "$results" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print()
print("jobs failed (a setup failed on its input): %s" % {r["mode"]: r["jobs"]["failed"] for r in rows if r["jobs"]})
for r in rows:
    if r.get("farm"):
        print("%s: setups grouped %d of %d (first: %s)" % (r["mode"], r["farm"].count("setup"), len(r["farm"]), r["farm_reason"]))
print("| mode | runs | wall s | CPU s | CPU wait s | peak memory MB (largest process) | jobs/min | overhead s/job | share of the CPU | s/job less the wait | load |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for mode in dict.fromkeys(r["mode"] for r in rows):
    # exit 3: a setup failed on its input (reported); its jobs not run are not counted
    rs = [r for r in rows if r["mode"] == mode and r["exit"] in (0, 3) and r["run"]]
    if not rs:
        print("| %s | 0 | (failed: exit %s) |" % (mode, [r["exit"] for r in rows if r["mode"] == mode]))
        continue
    med = lambda f: statistics.median(f(r) for r in rs)
    cores = rs[0]["cores"]
    jobs = med(lambda r: r["run"]["jobs_ran"])
    wall = med(lambda r: r["run"]["wall_seconds"])
    cpu = med(lambda r: r["run"]["cpu_seconds"])
    wait = med(lambda r: r["run"]["cpu_wait_seconds"] + r["run"]["runner_cpu_wait_seconds"])
    over = med(lambda r: (r["run"]["wall_seconds"] * cores - r["run"]["cpu_seconds"]) / r["run"]["jobs_ran"])
    share = med(lambda r: (r["run"]["wall_seconds"] * cores - r["run"]["cpu_seconds"]) / r["run"]["cpu_seconds"])
    less = med(lambda r: (r["run"]["wall_seconds"] * cores - r["run"]["cpu_seconds"] - r["run"]["cpu_wait_seconds"]
                          - r["run"]["runner_cpu_wait_seconds"]) / r["run"]["jobs_ran"])
    print("| %s (%d cores) | %d | %.0f | %.0f | %.0f | %.0f (%.0f) | %.1f | %.2f | %.0f%% | %.2f (%.1f%%) | %.1f-%.1f |" % (
        mode, cores, len(rs), wall, cpu, wait, med(lambda r: r["run"]["peak_memory_mb"]),
        med(lambda r: r["largest_process_mb"] or 0), med(lambda r: 60 * r["run"]["jobs_ran"] / r["run"]["wall_seconds"]),
        over, 100 * share, less, 100 * less * jobs / cpu,
        min(min(r["load"]) for r in rs), max(max(r["load"]) for r in rs)))
print()
print("From the jobs' stamps (first start to last end): per job, the slot time no job held and the")
print("wrapper's own time (graph, input hashes, stamp), against the commands' own wall time:")
print("(tail: slot time idle after the last moment every slot was busy; index: its start after the")
print("last other job's end)")
print("| mode | jobs | span s | commands s/job | slot gaps s/job | wrapper s/job | gaps + wrapper, share of the commands | tail s | index s |")
print("|---|---|---|---|---|---|---|---|---|")
for mode in dict.fromkeys(r["mode"] for r in rows):
    rs = [r for r in rows if r["mode"] == mode and r.get("stamps")]
    if not rs:
        continue
    med = lambda f: statistics.median(f(r["stamps"]) for r in rs)
    print("| %s | %d | %.0f | %.3f | %.3f | %.3f | %.1f%% | %.1f | %s |" % (
        mode, med(lambda s: s["jobs"]), med(lambda s: s["span"]), med(lambda s: s["command"] / s["jobs"]),
        med(lambda s: s["slot_gaps"] / s["jobs"]), med(lambda s: s["wrapper"] / s["jobs"]),
        med(lambda s: 100 * (s["slot_gaps"] + s["wrapper"]) / s["command"]), med(lambda s: s["tail_idle"]),
        "%.1f" % med(lambda s: s["index_wait"]) if all(r["stamps"]["index_wait"] is not None for r in rs) else "-"))
PY
