#!/usr/bin/env bash
# CI's short fuzz pass: every target of a -DSETLIGHT_FUZZ=ON build for
# SECONDS (default 25) from a copy of its seeds (fuzz/corpus stays as it is).
# A crash, a sanitizer report, a leak, an input over 20 s or an allocation
# over 2 GB stops that target; all targets run, then the exit status is 1
# if any stopped, with each artifact's path and the command that replays it.
#   fuzz/ci_run.sh BUILD_DIR [SECONDS]
set -uo pipefail
B=$(realpath "${1:?usage: fuzz/ci_run.sh BUILD_DIR [SECONDS]}")
SECONDS_EACH=${2:-25}
SRC=$(cd "$(dirname "$0")" && pwd)
W="$B/fuzz-ci"
rm -rf "$W"
export TMPDIR=${TMPDIR:-/tmp}
failed=()
for bin in "$B"/fuzz/fuzz_*; do
  [ -x "$bin" ] || continue
  t=${bin##*/fuzz_}
  mkdir -p "$W/$t/corpus" "$W/$t/artifacts"
  cp "$SRC/corpus/$t"/* "$W/$t/corpus/"
  dict=()
  [ -f "$SRC/dict/$t.dict" ] && dict=(-dict="$SRC/dict/$t.dict")
  if "$bin" "${dict[@]}" -max_total_time="$SECONDS_EACH" -max_len=16384 -timeout=20 -rss_limit_mb=2048 \
       -artifact_prefix="$W/$t/artifacts/" -print_final_stats=1 "$W/$t/corpus" \
       > "$W/$t/log.txt" 2>&1; then
    echo "fuzz_$t: $(grep -E '^#[0-9]+.*DONE' "$W/$t/log.txt" | tail -1)"
  else
    echo "fuzz_$t: FAILED; the end of its log:"
    tail -40 "$W/$t/log.txt"
    for a in "$W/$t/artifacts"/*; do
      [ -e "$a" ] && echo "  replay: $bin $a   (keep it in tests/fuzz_regressions/$t/ once fixed)"
    done
    failed+=("$t")
  fi
done
if ((${#failed[@]})); then
  echo "fuzz: ${#failed[@]} target(s) failed: ${failed[*]}"
  exit 1
fi
