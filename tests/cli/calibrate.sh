#!/usr/bin/env bash
# setlight calibrate end to end on rendered fixtures: grey sphere alone,
# chart by corners plus grey sphere, no chart found, and the bad inputs.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"
# The grey-sphere "photo": the true light is the fixture at twice its level.
"$SETLIGHT" render --env "$T/env.exr" --intensity 2 --scene grey --width 48 --spp 256 \
    --seed 9 -o "$T/grey.exr" 2>/dev/null || bad "grey fixture"
"$SETLIGHT" render --env "$T/env.exr" --scene chart --width 240 --spp 16 \
    -o "$T/chart.exr" 2>/dev/null || bad "chart fixture"
CORNERS=24,24,216,24,216,139.2,24,139.2

expect 0 "$SETLIGHT" calibrate --help; out_has "usage: setlight calibrate"

# --- grey sphere alone: exposure 2 recovered
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 -o "$T/cal.exr"
json_ok "$T/out"
json_eval "$T/out" 'abs(d["scale"] / 2 - 1) < 0.01 and d["grey"]["rel_rmse_after"] < 0.02'
present "$T/cal.exr"
expect 0 "$SETLIGHT" info --json "$T/cal.exr"
out_has "setlight:calibration_matrix"

# --- chart by corners, then the grey sphere
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --grey "$T/grey.exr" --grey-circle 24,24,24 -o "$T/cal2.exr"
json_eval "$T/out" 'd["chart"]["patches_used"] == 24 and d["chart"]["delta_e_after_mean"] < 1.0'
json_eval "$T/out" 'len(d["chart"]["patches"]) == 24 and d["chart"]["patches"][0]["pixels"] > 0'
json_eval "$T/out" 'd["grey"]["rel_rmse_after"] < 0.02'
# The grey photo went through the plate matrix: the HDRI gets only diagonal gains.
json_eval "$T/out" 'd["matrix"][0][1] == 0 and d["matrix"][2][0] == 0 and "plate_matrix" in d'
# A chart alone: the HDRI gets the plate matrix itself.
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS -o "$T/cal6.exr"
json_eval "$T/out" 'd["matrix"] == d["plate_matrix"] and d["scale"] == 1'

# --- the report: HTML with the patch table and the grey sphere images, JSON
expect 0 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --grey "$T/grey.exr" --grey-circle 24,24,24 -o "$T/cal5.exr" \
    --report "$T/rep"
present "$T/rep/calibrate.html"; present "$T/rep/grey_error.png"; present "$T/rep/grey_render.png"
grep -q "bluish green" "$T/rep/calibrate.html" && ok || bad "report lacks the patch table"
json_ok "$T/rep/calibrate.json"
json_eval "$T/rep/calibrate.json" 'abs(d["scale"] / 2 - 1) < 0.01'

# --- no chart in the chart photo: said, and the grey sphere carries on
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/grey.exr" \
    --grey "$T/grey.exr" --grey-circle 24,24,24 -o "$T/cal3.exr"
err_has "no chart found"
json_eval "$T/out" 'd["chart"]["located"] == "not found" and "grey" in d'
# ... and without a grey sphere it is an input error, nothing written.
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/grey.exr" -o "$T/cal4.exr"
err_has "grey.exr: no chart found"; err_one_line; absent "$T/cal4.exr"; no_temp "$T"

# --- colour spaces: ACEScg out (recorded), an sRGB PNG chart in; unknown names refused
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --colorspace acescg -o "$T/cal_aces.exr"
expect 0 "$SETLIGHT" info --json "$T/cal_aces.exr"; out_has '"colorspace": "acescg"'
# A real sRGB JPEG chart photo, found by the detector (when the shared data is there).
JPG="${SETLIGHT_SHARED_DATA:-/nonexistent}/colorchecker/arcu/color_checker_1.jpg"
if [ -f "$JPG" ]; then
  # OpenCV 4.6's mcc leaks from its own allocator when it finds a chart.
  printf 'leak:cv::fastMalloc\n' >"$T/lsan.supp"
  expect 0 env LSAN_OPTIONS="suppressions=$T/lsan.supp" "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$JPG" -o "$T/cal_jpg.exr"
  json_eval "$T/out" 'd["chart"]["located"] == "detected" and d["chart"]["patches_used"] >= 20'
  json_eval "$T/out" 'd["chart"]["delta_e_after_mean"] < d["chart"]["delta_e_before_mean"]'
else
  skip "shared chart photo"
fi
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --colorspace nosuchspace -o "$T/keep.exr"; err_has "nosuchspace"

# --- NaN/Inf in the HDRI: counted, replaced, none in the output
"$MAKE_FIXTURE" nan "$T/nan.exr" 64 32 || bad "fixture"
expect 0 "$SETLIGHT" calibrate --hdri "$T/nan.exr" --grey "$T/grey.exr" --grey-circle 24,24,24 \
    -o "$T/cal_nan.exr"
err_has "replaced by 0"
expect 0 "$SETLIGHT" info --json "$T/cal_nan.exr"
json_eval "$T/out" 'd["files"][0]["nan_count"] == 0 and d["files"][0]["inf_count"] == 0'

# --- bad inputs: usage (2), missing or bad files (3), nothing overwritten
cp "$T/cal.exr" "$T/keep.exr"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" -o "$T/keep.exr"; err_has "--chart, --grey"
# No circle given and no whole sphere in the photo (it fills the frame): exit 3.
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" -o "$T/keep.exr"
err_has "grey.exr: no grey sphere found"; err_one_line
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" --grey-circle 1,2 \
    -o "$T/keep.exr"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" --chart-corners 1,2,3 \
    -o "$T/keep.exr"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-reference nosuch -o "$T/keep.exr"; err_has "nosuch"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners 0,0,1,1,2,2,3,3 -o "$T/keep.exr"; err_has "chart corners"
expect 3 "$SETLIGHT" calibrate --hdri "$T/missing.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 -o "$T/keep.exr"; err_has "missing.exr"; err_one_line
expect 3 "$SETLIGHT" calibrate --hdri "$T/grey.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 -o "$T/keep.exr"; err_has "not an RGB lat-long"
# A circle on empty background: no sphere there.
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/chart.exr" \
    --grey-circle 120,150,10 -o "$T/keep.exr"; err_has "chart.exr"; err_one_line
cmp -s "$T/cal.exr" "$T/keep.exr" && ok || bad "keep.exr was overwritten"
no_temp "$T"

finish
