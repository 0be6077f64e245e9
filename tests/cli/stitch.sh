#!/usr/bin/env bash
# setlight stitch end to end: three fisheye views of the virtual stage to one
# lat-long (RGB + confidence, envmap, provenance, JSON report), a nadir mask,
# one view (partial, coverage reported), a featureless pair (fallback reported),
# a saved lens profile reused, and every bad input the issue names.
. "$(dirname "$0")/lib.bash"

for y in 0 120 240; do "$MAKE_FIXTURE" fisheye "$T/f$y.exr" 480 360 "$y" || bad "fixture f$y"; done
"$MAKE_FIXTURE" fisheye "$T/flat0.exr" 480 360 0 0 flat || bad "fixture flat0"
"$MAKE_FIXTURE" fisheye "$T/flat90.exr" 480 360 90 0 flat || bad "fixture flat90"
"$MAKE_FIXTURE" fisheye "$T/small.exr" 240 180 120 || bad "fixture small"
"$MAKE_FIXTURE" fisheye "$T/other.exr" 480 320 120 || bad "fixture other"
"$MAKE_FIXTURE" latlong "$T/ll.exr" 480 360 || bad "fixture latlong"
"$MAKE_FIXTURE" nan "$T/nan.pfm" 480 360 || bad "fixture nan"
LENS=(--focal-mm 8 --sensor-mm 36)

expect 0 "$SETLIGHT" stitch --help; out_has "usage: setlight stitch"
expect 0 "$SETLIGHT" --help; out_has "stitch"

# --- three views: a lat-long with confidence, envmap and provenance
expect 0 "$SETLIGHT" stitch --json "${LENS[@]}" -o "$T/st.exr" "$T/f0.exr" "$T/f120.exr" "$T/f240.exr"
json_ok "$T/out"
json_eval "$T/out" 'd["width"] == 2 * d["height"] and d["width"] >= 600'
json_eval "$T/out" 'abs(d["coverage"]["seen_sr"] - 12.566) < 0.01 and d["coverage"]["filled_sr"] < 0.01'
json_eval "$T/out" 'len(d["pairs"]) == 3 and len(d["views"]) == 3 and d["circle"]["radius"] > 100'
json_eval "$T/out" 'abs(d["views"][1]["nominal_ypr_deg"][0] - 120) < 1e-9'
present "$T/st.exr"; no_temp "$T"
expect 0 "$SETLIGHT" info --json "$T/st.exr"
json_eval "$T/out" 'd["files"][0]["envmap"] == "latlong" and d["files"][0]["channels"] == 4'
json_eval "$T/out" 'd["files"][0]["nan_count"] == 0 and d["files"][0]["inf_count"] == 0'
# options among the file names, as every command takes them
expect 0 "$SETLIGHT" stitch "$T/f0.exr" --no-solve "$T/f120.exr" "${LENS[@]}" "$T/f240.exr" -o "$T/st2.exr" --width 256
present "$T/st2.exr"

# --- a masked nadir: filled and reported
expect 0 "$SETLIGHT" stitch --json --no-solve --nadir-mask 25 "${LENS[@]}" -o "$T/nadir.exr" "$T/f0.exr" "$T/f120.exr" "$T/f240.exr"
json_eval "$T/out" 'abs(d["coverage"]["masked_sr"] - 2*3.14159265*(1-0.906307787)) < 0.02'
json_eval "$T/out" 'abs(d["coverage"]["filled_percent"] - 100*(1-0.906307787)/2) < 0.2'

# --- one view: a partial lat-long, half of it filled and flagged
expect 0 "$SETLIGHT" stitch --json "${LENS[@]}" -o "$T/one.exr" "$T/f0.exr"
json_eval "$T/out" 'abs(d["coverage"]["filled_percent"] - 50) < 1 and not d["solved"]'
err_has "filled"

# --- a featureless pair falls back to the nominal rotation, and says so
expect 0 "$SETLIGHT" stitch --json "${LENS[@]}" --yaw 0,90 -o "$T/flat.exr" "$T/flat0.exr" "$T/flat90.exr"
json_eval "$T/out" 'd["pairs"][0]["fallback"] and d["pairs"][0]["status"] == "too few matches"'
err_has "nominal rotation kept"

# --- a lens profile saved by one stitch stitches the next the same way
expect 0 "$SETLIGHT" stitch --no-solve "${LENS[@]}" --save-lens "$T/lens.json" -o "$T/a.exr" "$T/f0.exr" "$T/f120.exr" "$T/f240.exr"
present "$T/lens.json"
expect 0 "$SETLIGHT" stitch --no-solve --lens-profile "$T/lens.json" -o "$T/b.exr" "$T/f0.exr" "$T/f120.exr" "$T/f240.exr"
expect 0 "$SETLIGHT" info --json "$T/a.exr"; cp "$T/out" "$T/info_a.json"
expect 0 "$SETLIGHT" info --json "$T/b.exr"
json_eval "$T/out" 'd["files"][0]["channel_stats"] == json.load(open("'"$T/info_a.json"'"))["files"][0]["channel_stats"]'

# --- bad input: one line naming the file, exit code, nothing left
expect 3 "$SETLIGHT" stitch "${LENS[@]}" -o "$T/bad.exr" "$T/f0.exr" "$T/small.exr"
err_has "small.exr"; err_has "240x180"; err_one_line; absent "$T/bad.exr"; no_temp "$T"
expect 3 "$SETLIGHT" stitch "${LENS[@]}" --yaw 0,180 -o "$T/bad.exr" "$T/f0.exr" "$T/f120.exr"
err_has "do not overlap"; err_has "f120.exr"; err_one_line; absent "$T/bad.exr"
expect 3 "$SETLIGHT" stitch "${LENS[@]}" -o "$T/bad.exr" "$T/ll.exr"
err_has "ll.exr"; err_has "no image circle"; err_one_line; absent "$T/bad.exr"
expect 3 "$SETLIGHT" stitch -o "$T/bad.exr" "$T/f0.exr" "$T/f120.exr"
err_has "f0.exr"; err_has "--focal-mm"; err_one_line; absent "$T/bad.exr"
expect 3 "$SETLIGHT" stitch "${LENS[@]}" -o "$T/bad.exr" "$T/nan.pfm"
err_has "nan.pfm"; err_has "NaN"; err_one_line; absent "$T/bad.exr"; no_temp "$T"
expect 3 "$SETLIGHT" stitch --lens-profile "$T/lens.json" -o "$T/bad.exr" "$T/other.exr"
err_has "lens.json"; err_one_line; absent "$T/bad.exr"
expect 3 "$SETLIGHT" stitch "${LENS[@]}" -o "$T/bad.exr" "$T/missing.exr"
err_one_line; absent "$T/bad.exr"
expect 2 "$SETLIGHT" stitch "${LENS[@]}" "$T/f0.exr"
err_has "-o OUT.exr"
expect 2 "$SETLIGHT" stitch "${LENS[@]}" --yaw 0,x -o "$T/bad.exr" "$T/f0.exr"
expect 2 "$SETLIGHT" stitch "${LENS[@]}" --yaw 0,120,240 -o "$T/bad.exr" "$T/f0.exr"
expect 2 "$SETLIGHT" stitch --projection fishy -o "$T/bad.exr" "$T/f0.exr"
expect 2 "$SETLIGHT" stitch --lens-profile "$T/lens.json" --focal-mm 8 -o "$T/bad.exr" "$T/f0.exr"
expect 2 "$SETLIGHT" stitch "${LENS[@]}" --width 15 -o "$T/bad.exr" "$T/f0.exr"
absent "$T/bad.exr"; no_temp "$T"

# --- the report: summary on top, the confidence map, the views with their circles
mkdir -p "$T/rep"
expect 0 "$SETLIGHT" stitch "${LENS[@]}" --nadir-mask 30 --report "$T/rep/stitch.html" -o "$T/rep.exr" \
  "$T/f0.exr" "$T/f120.exr" "$T/f240.exr"
present "$T/rep.exr"; present "$T/rep/stitch.html"
for f in confidence latlong view1 view2 view3; do present "$T/rep/stitch_$f.png"; done
grep -q "Lens (equisolid, 8 mm" "$T/rep/stitch.html" && ok || bad "report lacks the lens"
grep -q "Coverage: seen .* filled .*masked" "$T/rep/stitch.html" && ok || bad "report lacks the coverage"
grep -q "<th>inliers</th>" "$T/rep/stitch.html" && ok || bad "report lacks the pair table"
grep -q "its image circle in red" "$T/rep/stitch.html" && ok || bad "report lacks the circles"
if ! /usr/bin/python3 -c "import cv2" 2>/dev/null; then skip "confidence map pixels (no python3-opencv)"
else /usr/bin/python3 - "$T/rep/stitch_confidence.png" <<'PY' && ok || bad "confidence map under 256 px or without the filled nadir"
import sys, cv2
m = cv2.imread(sys.argv[1])
h, w = m.shape[:2]
nadir = m[int(0.95 * h), w // 2]  # BGR: filled texels are red
sys.exit(0 if w >= 256 and nadir[2] > 200 and nadir[1] < 50 else 1)
PY
fi
browser_check "$T/rep/stitch.html" 5
# a report in a folder that is not there: refused, nothing left
expect 2 "$SETLIGHT" stitch "${LENS[@]}" --no-solve --report "$T/nodir/stitch.html" -o "$T/bad.exr" "$T/f0.exr"
err_one_line; err_has "nodir"; absent "$T/bad.exr"; no_temp "$T"

finish
