#!/bin/bash
# setlight process at the scale of a shoot day: 50 simulated setups
# (exterior, stage and night; 3 fisheye views x 7 frames and the three probes
# each, --size small), two jobs at a time. The whole day is processed, its
# peak memory (the runner's accounting: the running jobs' peak RSS summed,
# plus the runner's) stays within --memory-mb, and the run keeps its slots
# busy: its wall time is within 1.15x the jobs' CPU time divided by the
# slots, the CPU the machine's other work took from the jobs added to it
# (their run-queue wait; 0 on an idle machine, docs/process.md "Cost of a
# run"). The graph --emit-jobs writes validates against
# docs/jobs.schema.json, and the validator rejects broken graphs.
#
# About 11 minutes of CPU (docs/process.md): run by the release pass of
# .ci/run only, skipped under the sanitizers (SETLIGHT_SANITIZED).
# SETLIGHT_SCALE_SETUPS=N and SETLIGHT_SCALE_SIZE=tiny run a smaller day (for
# development); SETLIGHT_SCALE_SCENES another cycle of scenes.
. "$(dirname "$0")/lib.bash"
. "$(dirname "$0")/day.bash"
S="$SETLIGHT"
SRC="${SETLIGHT_SOURCE_DIR:-$(cd "$(dirname "$0")/../.." && pwd)}"
if [ -n "${SETLIGHT_SANITIZED:-}" ]; then
  skip "the 50-setup day runs in the release pass only (about 11 CPU-minutes; x10 under ASan)"
  finish
  exit
fi
if ! python3 -c 'import jsonschema' 2>/dev/null; then
  bad "python3-jsonschema is not installed (scripts/install-deps.sh)"
  finish
  exit
fi
printf 'leak:cv::fastMalloc\n' >"$T/lsan.supp"
export LSAN_OPTIONS="suppressions=$T/lsan.supp"
N=${SETLIGHT_SCALE_SETUPS:-50}
SIZE=${SETLIGHT_SCALE_SIZE:-small}
BUDGET=1024
P=(--probe-view 180,0)

# The day: 10 distinct captures (exterior, stage and night in turn: seeds
# 1-4, 1-3 and 1-3), each setup a copy of one of them.
if ! simulate_day "$S" "$N" "$SIZE" "$T/day" 10 "${SETLIGHT_SCALE_SCENES:-exterior stage night}"; then
  bad "simulating the day failed"
  finish
  exit
fi
SETUPS=("$T"/day/setup_*)
if [ "${#SETUPS[@]}" -eq "$N" ]; then ok; else bad "the day has ${#SETUPS[@]} setups, not $N"; fi

# 1. The graph alone: it validates against its schema and holds together.
expect 0 "$S" process "${SETUPS[@]}" -o "$T/processed" "${P[@]}" --emit-jobs "$T/jobs.json" --json -q
json_eval "$T/out" 'len(d["setups"]) == '"$N"' and all(s["status"] == "planned" for s in d["setups"])'
json_eval "$T/jobs.json" 'len(d["jobs"]) == 16 * '"$N"' + 1'
if python3 "$SRC/tests/cli/check_jobs.py" "$SRC/docs/jobs.schema.json" "$T/jobs.json" 2>"$T/check.err"; then ok; else
  bad "the emitted graph does not validate: $(head -3 "$T/check.err")"
fi
# ... and a broken graph does not.
python3 - "$T/jobs.json" "$T/broken" <<'PY'
import copy, json, sys
doc = json.load(open(sys.argv[1]))
def broken(name, change):
    d = copy.deepcopy(doc)
    change(d)
    json.dump(d, open("%s_%s.json" % (sys.argv[2], name), "w"))
broken("unknown_dep", lambda d: d["jobs"][5]["deps"].append("setup_001/merge/99"))
broken("cycle", lambda d: d["jobs"][0]["deps"].append(d["jobs"][20]["id"]))
broken("two_ids", lambda d: d["jobs"][1].update(id=d["jobs"][0]["id"], argv=d["jobs"][0]["argv"]))
broken("no_argv", lambda d: d["jobs"][3].pop("argv"))
broken("memory", lambda d: d["jobs"][3].update(memory_mb=0))
broken("relative", lambda d: d["jobs"][3]["inputs"].append("frames/a.tif"))
broken("stage", lambda d: d["jobs"][3].update(stage="denoise"))
broken("format", lambda d: d.update(version=2))
broken("argv_other_job", lambda d: d["jobs"][2]["argv"].__setitem__(3, d["jobs"][1]["id"]))
broken("array_deps", lambda d: [j["deps"].append(d["jobs"][0]["id"]) for j in d["jobs"] if j["id"] == "setup_002/merge/1"])
PY
for f in "$T"/broken_*.json; do
  if python3 "$SRC/tests/cli/check_jobs.py" "$SRC/docs/jobs.schema.json" "$f" 2>"$T/check.err"; then
    bad "$(basename "$f"): a broken graph validates"
  elif [ "$(wc -l <"$T/check.err")" -ge 1 ]; then ok; else bad "$(basename "$f"): rejected without a reason"; fi
done

# 2. The day, two jobs at a time within the budget; /usr/bin/time -v gives
# the largest single process (a job or the runner), the runner's --json the
# sum over jobs running at once.
TIME=(/usr/bin/time -v -o "$T/time.txt")
[ -x /usr/bin/time ] || TIME=()
echo "load before the run: $(uptime)"
expect 0 "${TIME[@]}" "$S" process "${SETUPS[@]}" -o "$T/processed" "${P[@]}" --jobs 2 --memory-mb "$BUDGET" --json -q
cp "$T/out" "$T/run.json"
echo "load after the run: $(uptime)"
json_eval "$T/run.json" 'all(s["status"] == "ok" for s in d["setups"]) and d["jobs"]["ran"] == d["jobs"]["total"] == 16 * '"$N"' + 1 and d["jobs"]["failed"] == 0'
present "$T/processed/index.html"
python3 - "$T/run.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))["run"]
print("run: %.0f s wall, %d jobs, %d slots, CPU %.0f s (job processes %.0f s, runner %.1f s), "
      "CPU wait %.0f s (runner %.1f s), peak memory %.0f MB of %d MB, %.1f jobs/min, "
      "overhead %.2f s/job (%.1f%% of the CPU), %.2f s/job less the wait"
      % (r["wall_seconds"], r["jobs_ran"], r["slots"], r["cpu_seconds"], r["job_process_cpu_seconds"],
         r["runner_cpu_seconds"], r["cpu_wait_seconds"], r["runner_cpu_wait_seconds"], r["peak_memory_mb"],
         r["memory_budget_mb"], r["jobs_per_minute"], r["overhead_seconds_per_job"],
         100 * r["overhead_share"], r["overhead_seconds_per_job_less_wait"]))
PY
json_eval "$T/run.json" 'd["run"]["memory_budget_mb"] == '"$BUDGET"' and 0 < d["run"]["peak_memory_mb"] <= '"$BUDGET"' and d["run"]["most_jobs_at_once"] == 2'
if [ ${#TIME[@]} -gt 0 ]; then
  max_kb=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$T/time.txt")
  if [ -n "$max_kb" ] && [ "$max_kb" -le $((BUDGET * 1024)) ]; then ok; else bad "a process of the run peaked at $max_kb kB"; fi
fi
# Wall time against the jobs' CPU over the slots (the issue's 1.15x), their
# wait for a CPU added: on a shared machine the others' load stretches the
# wall time, not the runner.
json_eval "$T/run.json" 'd["run"]["wall_seconds"] <= 1.15 * (d["run"]["cpu_seconds"] + d["run"]["cpu_wait_seconds"] + d["run"]["runner_cpu_wait_seconds"]) / d["run"]["slots"]'
finish
