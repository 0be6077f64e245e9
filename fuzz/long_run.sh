#!/usr/bin/env bash
# The long fuzz run (docs/fuzzing.md): targets one after another in two
# lanes, each for its wall-clock share, at the lowest priority, with the
# CPU time each really got measured by /usr/bin/time (libFuzzer's fork mode
# runs the inputs in child processes: their time is counted too).
#   fuzz/long_run.sh BUILD_DIR WORK_DIR [SCALE]
# BUILD_DIR: a -DSETLIGHT_FUZZ=ON build; WORK_DIR gets per target its
# growing corpus (seeded from fuzz/corpus), crash artifacts and log.
# SCALE multiplies every target's minutes (default 1: 60 minutes a lane).
set -euo pipefail
B=$(realpath "${1:?usage: fuzz/long_run.sh BUILD_DIR WORK_DIR [SCALE]}")
W=$(realpath -m "${2:?usage: fuzz/long_run.sh BUILD_DIR WORK_DIR [SCALE]}")
SCALE=${3:-1}
SRC=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$W"
export TMPDIR=${TMPDIR:-/dev/shm}

# target minutes max_len; the newest target first, so a crash it finds is
# known while the run goes on
lane_a="job_graph:10:16384 exr:16:16384 photo:16:16384 hdr:9:8192 rig_json:9:8192"
lane_b="ingest:9:16384 journal:8:8192 scene_json:8:4096 vset_scene:7:4096
        response_json:7:16384 response_text:7:4096 chart_reference:7:4096
        lens_profile:7:4096"

run_target() {
  local t=$1 minutes=$2 max_len=$3 secs
  secs=$(python3 -c "print(int($minutes * 60 * $SCALE))")
  mkdir -p "$W/$t/corpus" "$W/$t/artifacts"
  cp -n "$SRC/corpus/$t"/* "$W/$t/corpus/" 2>/dev/null || true
  local dict=()
  [ -f "$SRC/dict/$t.dict" ] && dict=(-dict="$SRC/dict/$t.dict")
  (cd "$W/$t" && /usr/bin/time -f "cpu_user %U cpu_sys %S wall %e maxrss_kb %M" -o time.txt \
     nice -n 19 "$B/fuzz/fuzz_$t" "${dict[@]}" -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
       -max_total_time="$secs" -max_len="$max_len" -timeout=20 -rss_limit_mb=2048 \
       -artifact_prefix="$W/$t/artifacts/" -print_final_stats=1 corpus > log.txt 2>&1) || true
}

lane() {
  for spec in $1; do
    IFS=: read -r t m l <<< "$spec"
    run_target "$t" "$m" "$l"
  done
}

lane "$lane_a" & a=$!
lane "$lane_b" & b=$!
wait $a $b
"$SRC/long_run_summary.sh" "$W"
