#!/usr/bin/env bash
# A failing write at every write call in turn (tests/fault/fault_inject.c,
# preloaded: write, pwrite, writev, fwrite, fsync or rename fails with ENOSPC
# or EIO): exit 1, one line on stderr naming the output, no temporary left,
# and the earlier outputs intact, all of them (rig's four files and merge's
# two are one set each). Writers: the EXR writer (convert), the strip writer
# (merge, unwrap), JSON/USD text and the PNG preview (rig).
. "$(dirname "$0")/lib.bash"

if [ -z "${FAULT_INJECT:-}" ] || [ ! -e "$FAULT_INJECT" ]; then
  skip "no fault injector (FAULT_INJECT)"; finish; exit $?
fi
# ASan checks that its runtime comes first; the injector must come before libc.
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"

checksums() { for f in "$@"; do if [ -e "$f" ]; then md5sum <"$f" | cut -c1-32; else echo -; fi; done; }

# Under AddressSanitizer a run costs ten times more: fewer calls there.
if ldd "$SETLIGHT" 2>/dev/null | grep -q libasan; then FIRST=2 LAST=12 STRIDE=40 ALL=no
else FIRST=8 LAST=16 STRIDE=12 ALL=yes; fi

# faults NAME EVERY DIR OUTPUTS -- CMD...: OUTPUTS (in DIR) hold the earlier
# results; the command would write different ones. Every counted call fails
# in turn (EVERY=all, not under ASan), or the first 8, the last 16 (where
# files are finished, fsynced and renamed) and every 12th between (the same
# chunk writes).
faults() {
  local name=$1 every=$2 dir=$3 outs=() cmd=()
  shift 3
  while [ "$1" != "--" ]; do outs+=("$dir/$1"); shift; done
  shift
  cmd=("$@")
  local old n i rc runs=0
  old=$(checksums "${outs[@]}")
  # count the calls of a good run, made in a copy of the folder
  rm -rf "$dir.count" && cp -r "$dir" "$dir.count"
  local counted=("${cmd[@]//$dir\//$dir.count/}")
  SL_FAULT_COUNT="$T/count" LD_PRELOAD="$FAULT_INJECT" "${counted[@]}" >/dev/null 2>&1 || bad "$name: the good run failed"
  [ "$old" != "$(checksums "${outs[@]//$dir\//$dir.count/}")" ] && ok || bad "$name: new outputs equal the old"
  n=$(cat "$T/count")
  [ "$n" -gt 3 ] && ok || bad "$name: only $n write calls counted"
  for ((i = 1; i <= n; i++)); do
    if { [ "$every" != all ] || [ "$ALL" != yes ]; } && [ "$i" -gt "$FIRST" ] && [ "$i" -le $((n - LAST)) ] &&
       [ $((i % STRIDE)) -ne 0 ]; then continue; fi
    local e=ENOSPC msg="No space left on device"
    if [ $((i % 2)) -eq 0 ]; then e=EIO; msg="Input/output error"; fi
    SL_FAULT_AT=$i SL_FAULT_ERRNO=$e LD_PRELOAD="$FAULT_INJECT" "${cmd[@]}" >/dev/null 2>"$T/err"
    rc=$?
    runs=$((runs + 1))
    if [ "$rc" -eq 1 ]; then ok; else bad "$name: write call $i of $n failing ($e): exit $rc: $(head -c 300 "$T/err")"; fi
    err_one_line
    err_has "$msg"
    err_has "setlight "
    no_temp "$dir"
    [ "$(checksums "${outs[@]}")" = "$old" ] && ok || bad "$name: write call $i of $n failing ($e): earlier outputs changed"
  done
  echo "$name: $runs of $n write calls failed in turn"
}

# --- rig: usda, json, residual EXR, PNG preview (one set)
"$MAKE_FIXTURE" sun "$T/sun.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/smooth.exr" 64 32 || bad "fixture"
mkdir -p "$T/rig"
"$SETLIGHT" rig -q "$T/smooth.exr" -o "$T/rig/r.usda" --json "$T/rig/r.json" --preview "$T/rig/r.png" \
  >/dev/null 2>&1 || bad "rig: the old set"
faults rig all "$T/rig" r.usda r.json r_residual.exr r.png -- \
  "$SETLIGHT" rig -q "$T/sun.exr" -o "$T/rig/r.usda" --json "$T/rig/r.json" --preview "$T/rig/r.png"

# --- convert: the whole-image EXR writer
mkdir -p "$T/convert"
"$SETLIGHT" convert -q "$T/smooth.exr" "$T/convert/c.exr" || bad "convert: the old file"
faults convert some "$T/convert" c.exr -- "$SETLIGHT" convert -q "$T/sun.exr" "$T/convert/c.exr"

# --- merge: the strip writer, radiance and clipped mask (one set)
png_bracket "$T" 64 32 || bad "fixture"
mkdir -p "$T/merge"
"$SETLIGHT" merge -q --align=off --times 1/8,1/2,2 -o "$T/merge/m.exr" "$T"/br_{0,1,2}.png \
  >/dev/null 2>&1 || bad "merge: the old set"
faults merge some "$T/merge" m.exr m_clipped.exr -- \
  "$SETLIGHT" merge -q --align=off --times 1/16,1/4,1 -o "$T/merge/m.exr" "$T"/br_0.png "$T"/br_1.png "$T"/br_2.png

# --- unwrap: the strip writer
"$MAKE_FIXTURE" ball "$T/ball.exr" || bad "fixture"
mkdir -p "$T/unwrap"
"$SETLIGHT" unwrap -q --focal-mm 18 --sensor-mm 20 --width 128 -o "$T/unwrap/u.exr" "$T/ball.exr" \
  >/dev/null 2>&1 || bad "unwrap: the old file"
faults unwrap some "$T/unwrap" u.exr -- \
  "$SETLIGHT" unwrap -q --focal-mm 18 --sensor-mm 20 --width 256 -o "$T/unwrap/u.exr" "$T/ball.exr"

finish
