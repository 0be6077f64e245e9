#!/bin/bash
# setlight demo on the small size (tiny under the sanitizers), as CI runs it:
# the report lists every stage with its numbers against the truth, and an
# earlier demo is not replaced without --force.
. "$(dirname "$0")/lib.bash"
S="$SETLIGHT"

expect 0 "$S" demo --help
for o in --size --seed --force; do out_has "$o"; done

# The chart detector (OpenCV mcc) leaks inside OpenCV, as in calibrate.sh.
printf 'leak:cv::fastMalloc\n' >"$T/lsan.supp"
export LSAN_OPTIONS="suppressions=$T/lsan.supp"

# Under the sanitizers (several times slower) the first run is tiny too; the
# checks below hold at both sizes.
size=small
[ -n "${SETLIGHT_SANITIZED:-}" ] && size=tiny
expect 0 "$S" demo "$T/demo" --size $size --json --quiet
json_ok "$T/out"
cp "$T/out" "$T/summary.json"
json_eval "$T/summary.json" '[s["name"] for s in d["stages"]] == ["simulate", "truth", "frames", "ingest", "merge", "unwrap", "calibrate", "rig", "render"]'
present "$T/demo/report.html"
present "$T/demo/truth.png"
present "$T/demo/capture/capture.json"
present "$T/demo/render_refs.png"
present "$T/demo/unwrap_chrome.exr"
present "$T/demo/unwrap_chrome.png"
present "$T/demo/rig.json"
present "$T/demo/capture/truth/probes.json"
for f in IMG_0022.jpg IMG_0034_linear.tif; do present "$T/demo/capture/probes/$f"; done
# each new stage's numbers against the truth, within what the virtual set allows
if python3 - "$T/demo/report.html" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
u = re.search(r"front hemisphere \(toward the camera\), both averaged to 128x64: energy ([+-][0-9.]+)%", t)
c = re.search(r"CIEDE2000 mean ([0-9.]+) \(max [0-9.]+\) before, ([0-9.]+) \(max", t)
g = re.search(r"exposure scale [0-9.]+ \(([+-][0-9.]+)%", t)
r = re.search(r"7 of 7 truth lights matched|Each truth light", t)
ok = u and abs(float(u.group(1))) < 5 and c and float(c.group(2)) < 1 and g and abs(float(g.group(1))) < 1 and r
sys.exit(0 if ok else 1)
PY
then ok; else bad "unwrap, calibrate or rig numbers missing or off"; fi
# the renderer agrees with a brute-force irradiance sum at the grey ball's centre
if python3 - "$T/demo/report.html" <<'PY'
import re, sys
m = re.search(r"brute-force irradiance sum [0-9.e+-]+ cd/m\^2 \(([+-][0-9.]+)%", open(sys.argv[1]).read())
sys.exit(0 if m and abs(float(m.group(1))) < 1.0 else 1)
PY
then ok; else bad "grey-ball check missing or above 1%"; fi
for stage in simulate truth frames ingest merge unwrap calibrate rig render; do
    if grep -q "<td>$stage</td>" "$T/demo/report.html"; then ok; else bad "report lacks stage $stage"; fi
done
if grep -q "EXIF read back through OpenImageIO matches the plan for 21 of 21 frames" "$T/demo/report.html"; then ok; else bad "EXIF check missing from the report"; fi
if grep -q "21 frames in 3 views grouped from EXIF time and exposure alone; 21 of 21 planned frames in the right view, bracket and place; 42 sibling files" "$T/demo/report.html"; then ok; else bad "ingest check missing from the report"; fi
present "$T/demo/capture/session/session.json"
no_temp "$T/demo"

before=$(md5sum "$T/demo/report.html")
expect 2 "$S" demo "$T/demo" --size tiny
err_has "--force"
err_one_line
[ "$before" = "$(md5sum "$T/demo/report.html")" ] && ok || bad "report changed without --force"
expect 0 "$S" demo "$T/demo" --size tiny --force --quiet
present "$T/demo/report.html"

mkdir -p "$T/busy" && echo mine > "$T/busy/notes.txt"
expect 2 "$S" demo "$T/busy" --size tiny
err_has "busy"
[ "$(ls "$T/busy")" = "notes.txt" ] && ok || bad "busy folder was touched"
expect 2 "$S" demo "$T/x" --size full
err_has "full"
absent "$T/x"
expect 1 "$S" demo /proc/setlight-nope --size tiny
err_has "/proc/setlight-nope"

finish
