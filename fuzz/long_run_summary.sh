#!/usr/bin/env bash
# One line per target of a long run's WORK_DIR (fuzz/long_run.sh): CPU time,
# executions, coverage (cov, ft: libFuzzer's last stats line), corpus size,
# crash/oom/timeout counts and the artifacts kept.
set -euo pipefail
W=${1:?usage: fuzz/long_run_summary.sh WORK_DIR}
printf '| target | CPU s | wall s | executions | cov | ft | corpus | oom/timeout/crash | artifacts |\n'
printf '|---|---|---|---|---|---|---|---|---|\n'
total=0
for d in "$W"/*/; do
  t=$(basename "$d")
  [ -f "$d/log.txt" ] || continue
  cpu=$(awk '/^cpu_user/ {printf "%.0f", $2 + $4}' "$d/time.txt" 2>/dev/null || echo "?")
  wall=$(awk '/^cpu_user/ {printf "%.0f", $6}' "$d/time.txt" 2>/dev/null || echo "?")
  # fork mode: "#EXECS: cov: N ft: N corp: N exec/s: N oom/timeout/crash: a/b/c time: ..."
  last=$(grep -E '^#[0-9]+: cov:' "$d/log.txt" | tail -1 || true)
  execs=$(sed -E 's/^#([0-9]+):.*/\1/' <<< "$last")
  cov=$(sed -E 's/.* cov: ([0-9]+).*/\1/' <<< "$last")
  ft=$(sed -E 's/.* ft: ([0-9]+).*/\1/' <<< "$last")
  corp=$(sed -E 's/.* corp: ([0-9]+).*/\1/' <<< "$last")
  oct=$(sed -E 's|.* oom/timeout/crash: ([0-9/]+).*|\1|' <<< "$last")
  arts=$(ls "$d/artifacts" 2>/dev/null | wc -l)
  printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$t" "$cpu" "$wall" "$execs" "$cov" \
    "$ft" "$corp" "$oct" "$arts"
  [[ $cpu =~ ^[0-9]+$ ]] && total=$((total + cpu))
done
echo
echo "CPU time in all: $total s ($(python3 -c "print(round($total / 3600, 2))") CPU-hours)"
