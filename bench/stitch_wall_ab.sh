#!/bin/bash
# The 24 MP stitch's wall time, two builds alternated (docs/stitch.md, "Wall time on 2 cores").
#
#   ./build/bench/bench_stitch_solve 6000 4000 stage write /tmp/v
#   bench/stitch_wall_ab.sh ROUNDS VIEWS_DIR SETLIGHT_A [SETLIGHT_B]
#
# Each run's output is deleted and the page cache written back (sync) before the next: a run that
# truncates the previous run's 0.5 GB file while the disk still writes it takes 0.3-0.5 s longer.
# "other" is the CPU time the rest of the machine used during the run (core-seconds): count a run
# as idle only when it is near 0.
set -e
R=$1; V=$2; shift 2
for i in $(seq "$R"); do
  for b in "$@"; do
    rm -f "$V/ab_out.exr"; sync; sleep 2
    s0=$(awk '/^cpu /{print $2+$3+$4+$7+$8}' /proc/stat)
    /usr/bin/time -f "%e %U %S %M" -o "$V/ab_time.txt" "$b" stitch --json --focal-mm 8 \
      --sensor-mm 36,24 -o "$V/ab_out.exr" "$V/view0.exr" "$V/view1.exr" "$V/view2.exr" \
      2>/dev/null > "$V/ab.json"
    s1=$(awk '/^cpu /{print $2+$3+$4+$7+$8}' /proc/stat)
    /usr/bin/python3 - "$b" "$V" "$s0" "$s1" <<'PY'
import json, sys
b, v, s0, s1 = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
t = json.load(open(v + "/ab.json"))["timing"]
w, u, s, m = open(v + "/ab_time.txt").read().split()
cpu = float(u) + float(s)
print("%-40s wall %s cpu %.2f other %.2f peak %.0f MB  read %.2f circle %.2f solve %.2f "
      "(features %.2f) blend %.2f" % (b[-40:], w, cpu, (s1 - s0) / 100.0 - cpu, int(m) / 1024,
      t["read"]["wall"], t["circle"]["wall"], t["solve"]["wall"],
      t["solve_stages"]["features"], t["blend"]["wall"]))
PY
  done
done
rm -f "$V/ab_out.exr" "$V/ab.json" "$V/ab_time.txt"
