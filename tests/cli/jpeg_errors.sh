#!/usr/bin/env bash
# A cut or damaged JPEG through info, convert and merge: exit 3 and one line
# naming the file, from setlight (libjpeg's default handlers would print a
# warning and pad the image with grey, or exit the process), and no output
# left behind.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" png "$T/src.png" 64 48 || bad "fixture"
"$SETLIGHT" convert "$T/src.png" "$T/plain.jpg" 2>/dev/null || bad "fixture"
python3 - "$T" <<'PY' || bad "fixture"
import sys
out = sys.argv[1]
d = open(out + '/plain.jpg', 'rb').read()
sos = d.find(b'\xff\xda')
open(out + '/cut_header.jpg', 'wb').write(d[:sos - 20])          # inside the tables
open(out + '/cut_scan.jpg', 'wb').write(d[:sos + (len(d) - sos) // 2])  # half the scan
b = bytearray(d)
mid = sos + (len(d) - sos) // 2
b[mid:mid + 2] = b'\xff\xc8'                                   # a stray marker in the scan
open(out + '/stray_marker.jpg', 'wb').write(bytes(b))
open(out + '/soi_only.jpg', 'wb').write(b'\xff\xd8\xff')
PY

expect 0 "$SETLIGHT" info --json "$T/plain.jpg"
json_eval "$T/out" 'd["files"][0]["width"] == 64 and d["files"][0]["height"] == 48'

for f in cut_header cut_scan stray_marker soi_only; do
  p="$T/$f.jpg"
  expect 3 "$SETLIGHT" info "$p"; err_has "setlight info: $p: "; err_one_line
  expect 3 "$SETLIGHT" convert "$p" "$T/$f.exr"; err_has "setlight convert: $p: "; err_one_line
  absent "$T/$f.exr"
  expect 3 "$SETLIGHT" merge --times 1/30,1/120 -o "$T/${f}_m.exr" "$T/plain.jpg" "$p"
  err_has "setlight merge: $p: "; err_one_line
  absent "$T/${f}_m.exr"
  if grep -qi 'premature\|corrupt jpeg data' "$T/err" && ! grep -q "setlight" "$T/err"; then
    bad "$f: libjpeg's own message on stderr"
  else ok; fi
done
no_temp "$T"

finish
