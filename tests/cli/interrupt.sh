#!/usr/bin/env bash
# SIGINT and SIGTERM at several moments of `rig` (four outputs, one set),
# `merge` (radiance and clipped mask, one set) and `unwrap` (one large
# streamed EXR): the run ends by the signal (status 130 / 143), leaves no
# temporary file, and its outputs are either all as before or all new.
. "$(dirname "$0")/lib.bash"

# Background jobs of a script ignore SIGINT; give the command the default back.
if env --default-signal=INT true 2>/dev/null; then RUN=(env --default-signal=INT)
else RUN=(); fi

now() { date +%s.%N; }
# checksums FILE... : one line per file ("-" when missing)
checksums() { for f in "$@"; do if [ -e "$f" ]; then md5sum <"$f" | cut -c1-32; else echo -; fi; done; }

# interrupts NAME DIR OUTPUTS -- CMD...: the command's outputs (names in
# DIR) before each run are OLD (made by the caller); NEW is what an
# uninterrupted run writes. Signals at 5..95% of a full run's time.
interrupts() {
  local name=$1 dir=$2 outs=() cmd=() i
  shift 2
  while [ "$1" != "--" ]; do outs+=("$dir/$1"); shift; done
  shift
  cmd=("$@")
  mkdir -p "$T/$name.old"
  for i in "${outs[@]}"; do [ -e "$i" ] && cp "$i" "$T/$name.old/"; done
  local old new t0 full
  old=$(checksums "${outs[@]}")
  t0=$(now)
  "${cmd[@]}" >/dev/null 2>&1 || bad "$name: the uninterrupted run failed"
  full=$(echo "$(now) - $t0" | bc)
  new=$(checksums "${outs[@]}")
  [ "$old" != "$new" ] && ok || bad "$name: the new outputs equal the old ones (the test would prove nothing)"
  local interrupted=0 k sig want delay rc now_sums try
  for k in 1 2 3 4 5 6 7 8; do
    if [ $((k % 2)) -eq 1 ] && [ ${#RUN[@]} -gt 0 ]; then sig=INT; want=130; else sig=TERM; want=143; fi
    delay=$(echo "$full * (0.05 + 0.9 * ($k - 1) / 7)" | bc -l)
    # A run that finished before its signal (the machine got faster than
    # during the timed run) is tried again with half the delay, so that a
    # busy CI machine cannot leave too few runs interrupted.
    for try in 1 2 3 4; do
      for i in "${outs[@]}"; do rm -f "$i"; [ -e "$T/$name.old/$(basename "$i")" ] && cp "$T/$name.old/$(basename "$i")" "$i"; done
      "${RUN[@]}" "${cmd[@]}" >/dev/null 2>"$T/err" &
      local pid=$!
      sleep "$delay"
      kill -"$sig" "$pid" 2>/dev/null
      wait "$pid"
      rc=$?
      now_sums=$(checksums "${outs[@]}")
      if [ "$rc" -eq "$want" ]; then
        interrupted=$((interrupted + 1)); ok
        [ ! -s "$T/err" ] && ok || bad "$name SIG$sig: printed $(head -c 200 "$T/err")"
      elif [ "$rc" -eq 0 ]; then ok  # finished before the signal
      else bad "$name SIG$sig after ${delay}s: exit $rc (want $want): $(head -c 300 "$T/err")"; fi
      no_temp "$dir"
      if [ "$now_sums" = "$old" ] || [ "$now_sums" = "$new" ]; then ok
      else bad "$name SIG$sig after ${delay}s (exit $rc): a mixed set of outputs: $(echo $now_sums)"; fi
      [ "$rc" -eq 0 ] || break
      delay=$(echo "$delay / 2" | bc -l)
    done
  done
  [ "$interrupted" -ge 4 ] && ok || bad "$name: only $interrupted of 8 runs were interrupted"
}

# --- rig: usda, json, residual, preview
"$MAKE_FIXTURE" sun "$T/sun.exr" 1024 512 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/smooth.exr" 1024 512 || bad "fixture"
mkdir -p "$T/rig"
"$SETLIGHT" rig -q "$T/smooth.exr" -o "$T/rig/r.usda" --json "$T/rig/r.json" --preview "$T/rig/r.png" \
  >/dev/null 2>&1 || bad "rig: the old set"
interrupts rig "$T/rig" r.usda r.json r_residual.exr r.png -- \
  "$SETLIGHT" rig -q "$T/sun.exr" -o "$T/rig/r.usda" --json "$T/rig/r.json" --preview "$T/rig/r.png"

# --- merge: radiance and its clipped mask
png_bracket "$T" 1024 512 || bad "fixture"
mkdir -p "$T/merge"
"$SETLIGHT" merge -q --align off --times 1/8,1/2,2 -o "$T/merge/m.exr" "$T/br_0.png" "$T/br_1.png" "$T/br_2.png" \
  >/dev/null 2>&1 || bad "merge: the old set"
interrupts merge "$T/merge" m.exr m_clipped.exr -- \
  "$SETLIGHT" merge -q --align off --times 1/16,1/4,1 -o "$T/merge/m.exr" "$T/br_0.png" "$T/br_1.png" "$T/br_2.png"

# --- unwrap: one streamed lat-long
"$MAKE_FIXTURE" ball "$T/ball.exr" || bad "fixture"
mkdir -p "$T/unwrap"
"$SETLIGHT" unwrap -q --focal-mm 18 --sensor-mm 20 --width 512 -o "$T/unwrap/u.exr" "$T/ball.exr" \
  >/dev/null 2>&1 || bad "unwrap: the old output"
interrupts unwrap "$T/unwrap" u.exr -- \
  "$SETLIGHT" unwrap -q --focal-mm 18 --sensor-mm 20 --width 2048 -o "$T/unwrap/u.exr" "$T/ball.exr"

finish
