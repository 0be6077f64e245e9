#!/usr/bin/env bash
# setlight calibrate end to end on rendered fixtures: grey sphere alone,
# chart by corners plus grey sphere, no chart found, and the bad inputs.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"
# The grey-sphere "photo": the true light is the fixture at twice its level.
"$SETLIGHT" render --env "$T/env.exr" --intensity 2 --scene grey --width 48 --spp 256 \
    --seed 9 -o "$T/grey.exr" 2>/dev/null || bad "grey fixture"
# The chart "photo" sampled, with a photo's noise: the closed form would make
# every patch exactly flat, and a flat white patch at the image's maximum is
# what a saturated sensor writes (calibrate takes it as clipped).
"$SETLIGHT" render --env "$T/env.exr" --scene chart --width 240 --spp 16 --closed-form off \
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
# Default (--hdri-in chart): the HDRI goes through the plate matrix, then the gains.
json_eval "$T/out" 'd["hdri_in"] == "chart" and all(abs(d["matrix"][i][j] - d["grey"]["gain"][i] * d["plate_matrix"][i][j]) < 1e-6 * abs(d["matrix"][i][i]) for i in range(3) for j in range(3))'
# --hdri-in working: the HDRI is already in the working space, only the gains.
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --grey "$T/grey.exr" --grey-circle 24,24,24 --spp 64 --hdri-in working \
    -o "$T/cal2w.exr"
json_eval "$T/out" 'd["matrix"][0][1] == 0 and d["matrix"][2][0] == 0 and "plate_matrix" in d'
json_eval "$T/out" 'd["hdri_in"] == "working" and abs(d["scale"] / 2 - 1) < 0.01'
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" --hdri-in raw -o "$T/keep.exr"
err_has "--hdri-in"

# --- the grey photo's camera (unwrap's options): the orthographic fixture is a
# pinhole 2000 radii away, so the perspective fit gives the same exposure.
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --spp 64 --distance 50000 --ball-diameter 50 -o "$T/cal_far.exr"
json_eval "$T/out" 'd["grey"]["camera"]["model"] == "perspective" and d["grey"]["camera"]["distance_radii"] == 2000 and abs(d["scale"] / 2 - 1) < 0.01'
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --spp 64 --fov 0.1 -o "$T/cal_fov.exr"
json_eval "$T/out" 'd["grey"]["camera"]["focal_px"] > 27000 and abs(d["scale"] / 2 - 1) < 0.01'
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --spp 64 --camera ortho --fov 0.1 -o "$T/cal_ortho.exr"
json_eval "$T/out" 'd["grey"]["camera"]["model"] == "orthographic"'
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" --distance 2000 \
    -o "$T/keep.exr"; err_has "--ball-diameter"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" --distance 20 \
    --ball-diameter 50 -o "$T/keep.exr"; err_has "inside"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" --focal-mm 50 \
    -o "$T/keep.exr"; err_has "--sensor-mm"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" --grey-circle 24,24,24 \
    --camera perspective -o "$T/keep.exr"; err_has "grey.exr"; err_one_line

# --- a reference file: X-Rite's published Lab (D50), as a CSV with a name column
{
  echo "# ColorChecker Classic, X-Rite after November 2014, CIELAB D50"
  echo "patch,L,a,b"
  echo "dark skin,37.54,14.37,14.92"; echo "light skin,64.66,19.27,17.50"
  echo "blue sky,49.32,-3.82,-22.54"; echo "foliage,43.46,-12.74,22.72"
  echo "blue flower,54.94,9.61,-24.79"; echo "bluish green,70.48,-32.26,-0.37"
  echo "orange,62.73,35.83,56.50"; echo "purplish blue,39.43,10.75,-45.17"
  echo "moderate red,50.57,48.64,16.67"; echo "purple,30.10,22.54,-20.87"
  echo "yellow green,71.77,-24.13,58.19"; echo "orange yellow,71.51,18.24,67.37"
  echo "blue,28.37,15.42,-49.80"; echo "green,54.38,-39.72,32.27"
  echo "red,42.43,51.05,28.62"; echo "yellow,81.80,2.67,80.41"
  echo "magenta,50.63,51.28,-14.12"; echo "cyan,49.57,-29.71,-28.32"
  echo "white 9.5,95.19,-1.03,2.93"; echo "neutral 8,81.29,-0.57,0.44"
  echo "neutral 6.5,66.89,-0.75,-0.06"; echo "neutral 5,50.76,-0.13,0.14"
  echo "neutral 3.5,35.63,-0.46,-0.48"; echo "black 2,20.64,0.07,-0.46"
} >"$T/ref_lab.csv"
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --chart-reference "$T/ref_lab.csv" -o "$T/cal_ref.exr"
json_eval "$T/out" 'd["chart"]["reference"].endswith("ref_lab.csv") and d["chart"]["delta_e_after_mean"] < 1.0'
head -n 10 "$T/ref_lab.csv" >"$T/ref_short.csv"
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --chart-reference "$T/ref_short.csv" -o "$T/keep_ref.exr"
err_has "ref_short.csv"; err_has "24"; err_one_line; absent "$T/keep_ref.exr"
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --chart-reference "$T/nope.csv" -o "$T/keep_ref.exr"
err_has "nope.csv"; absent "$T/keep_ref.exr"

# --- clipped sun: the merge left the sun at 100 (true 1e5) and named its mask
"$MAKE_FIXTURE" sun "$T/sun_true.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" sunclip "$T/sunclip.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" sunmask "$T/sunmask.exr" 64 32 || bad "fixture"
"$SETLIGHT" render --env "$T/sun_true.exr" --scene grey --width 48 --spp 256 --seed 9 \
    --view 180,0 -o "$T/grey_sun.exr" 2>/dev/null || bad "grey sun fixture"
# Without the repair the grey sphere cannot be matched ...
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/sunclip.exr" --grey "$T/grey_sun.exr" \
    --grey-circle 24,24,24 --spp 64 --grey-view 180,0 --no-sun-repair -o "$T/cal_nosun.exr"
json_eval "$T/out" '"sun_repair" not in d and d["grey"]["rel_rmse_after"] > 0.05'
# ... with it (mask found beside the HDRI through its setlight:merge:clipped_mask):
# the sun's energy (1e5 x the texel's 7.14e-3 sr = 714) is back, the sphere matches.
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/sunclip.exr" --grey "$T/grey_sun.exr" \
    --grey-circle 24,24,24 --spp 64 --grey-view 180,0 -o "$T/cal_sun.exr"
err_has "clipped source at azimuth"
json_eval "$T/out" 'd["sun_repair"]["clipped_texels"] == 1 and abs(d["sun_repair"]["energy_added"][1] / (714.0 - 0.714) - 1) < 0.05'
json_eval "$T/out" 'd["sun_repair"]["rel_rmse_before"] > 0.2 and d["grey"]["rel_rmse_after"] < 0.03 and abs(d["scale"] - 1) < 0.03'
json_eval "$T/out" '0 < d["sun_repair"]["radiance_sigma"][1] < 0.1 * d["sun_repair"]["radiance"][1]'
expect 0 "$SETLIGHT" info --json "$T/cal_sun.exr"; out_has "setlight:sun_repair"
# An explicit mask that does not exist: exit 3, nothing written.
expect 3 "$SETLIGHT" calibrate --hdri "$T/sunclip.exr" --grey "$T/grey_sun.exr" \
    --grey-circle 24,24,24 --spp 64 --clipped-mask "$T/nomask.exr" -o "$T/keep_sun.exr"
err_has "nomask.exr"; absent "$T/keep_sun.exr"

# --- absolute: EXIF exposure on the grey photo puts the HDRI in cd/m^2
# (L = 78 N^2 / (0.65 S t) per unit: 1920 at 1/100 s, f/4, ISO 100).
"$MAKE_FIXTURE" exif "$T/grey_exif.exr" "$T/grey.exr" 0.01 4 100 || bad "fixture"
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey_exif.exr" \
    --grey-circle 24,24,24 --spp 64 -o "$T/cal_abs.exr"
json_eval "$T/out" 'd["units"] == "cd/m^2" and abs(d["absolute"]["cd_m2_per_unit"] / 1920 - 1) < 1e-6'
json_eval "$T/out" 'abs(d["matrix"][1][1] / (2 * 1920) - 1) < 0.01'
expect 0 "$SETLIGHT" info --json "$T/cal_abs.exr"; out_has "cd/m^2"; out_has "setlight:absolute_scale"
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey_exif.exr" \
    --grey-circle 24,24,24 --spp 64 --no-absolute -o "$T/cal_rel.exr"
json_eval "$T/out" 'd["units"] == "relative" and abs(d["scale"] / 2 - 1) < 0.01'
# The HDRI's own exposure agrees (the photo is 2x the HDRI: 1/200 s) ...
"$MAKE_FIXTURE" exif "$T/env_ok.exr" "$T/env.exr" 0.005 4 100 || bad "fixture"
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env_ok.exr" --grey "$T/grey_exif.exr" \
    --grey-circle 24,24,24 --spp 64 -o "$T/cal_ok.exr"
json_eval "$T/out" 'abs(d["exposure_check"]["disagreement_stops"]) < 0.05'
# ... or contradicts it by 3.3 stops: exit 3, nothing written.
"$MAKE_FIXTURE" exif "$T/env_bad.exr" "$T/env.exr" 0.05 4 100 || bad "fixture"
expect 3 "$SETLIGHT" calibrate --hdri "$T/env_bad.exr" --grey "$T/grey_exif.exr" \
    --grey-circle 24,24,24 --spp 64 -o "$T/keep_abs.exr"
err_has "grey_exif.exr: exposure metadata"; err_has "contradicts"; err_one_line
absent "$T/keep_abs.exr"
expect 0 "$SETLIGHT" calibrate --hdri "$T/env_bad.exr" --grey "$T/grey_exif.exr" \
    --grey-circle 24,24,24 --spp 64 --exposure-tolerance 4 -o "$T/cal_tol.exr"
# A chart alone: the HDRI gets the plate matrix itself.
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS -o "$T/cal6.exr"
json_eval "$T/out" 'd["matrix"] == d["plate_matrix"] and d["scale"] == 1'

# --- the report: HTML with the patch table and the grey sphere images, JSON
expect 0 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chart.exr" \
    --chart-corners $CORNERS --grey "$T/grey.exr" --grey-circle 24,24,24 --spp 64 -o "$T/cal5.exr" \
    --report "$T/rep"
present "$T/rep/calibrate.html"; present "$T/rep/grey_error.png"; present "$T/rep/grey_render.png"
grep -q "bluish green" "$T/rep/calibrate.html" && ok || bad "report lacks the patch table"
grep -q '<img src="delta_e.svg">' "$T/rep/calibrate.html" && ok || bad "report lacks the dE bars"
browser_check "$T/rep/calibrate.html" 4
json_ok "$T/rep/calibrate.json"
json_eval "$T/rep/calibrate.json" 'abs(d["scale"] / 2 - 1) < 0.01'

# --- no chart in the chart photo: said, and the grey sphere carries on
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/grey.exr" \
    --grey "$T/grey.exr" --grey-circle 24,24,24 --spp 64 -o "$T/cal3.exr"
err_has "no chart found"
json_eval "$T/out" 'd["chart"]["located"] == "not found" and "grey" in d'
# ... and without a grey sphere it is an input error, nothing written.
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/grey.exr" -o "$T/cal4.exr"
err_has "grey.exr: no chart found"; err_one_line; absent "$T/cal4.exr"; no_temp "$T"

# --- things that are not a ColorChecker (make_fixture chart*): the detector
# takes the JPEG wall, squares and shuffled board for charts; the fit is
# judged and refused with its reasons, nothing written. As EXR the wall is
# not even an outline.
printf 'leak:cv::fastMalloc\n' >"$T/lsan_mcc.supp"
mcc() { env LSAN_OPTIONS="suppressions=$T/lsan_mcc.supp" "$@"; }
for k in chartwall chartsquares chartshuffled chartok chartclipped charttiny chartcut; do
  "$MAKE_FIXTURE" $k "$T/$k.jpg" && "$MAKE_FIXTURE" $k "$T/$k.exr" || bad "fixture $k"
done
for f in chartwall.jpg chartsquares.jpg chartshuffled.jpg charttiny.jpg chartcut.jpg \
         chartwall.exr chartsquares.exr chartshuffled.exr charttiny.exr chartcut.exr; do
  expect 3 mcc "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/$f" -o "$T/nochart.exr"
  err_has "setlight calibrate: $T/$f: "; err_one_line; absent "$T/nochart.exr"
done
no_temp "$T"
expect 3 mcc "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chartwall.jpg" -o "$T/nochart.exr"
err_has "not a usable ColorChecker: only"; err_has "patches fit one colour matrix"
err_has "CIEDE2000 from the chart after the best matrix"
expect 3 mcc "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chartshuffled.exr" -o "$T/nochart.exr"
err_has "not a usable ColorChecker"
# Corners given by hand on the wall: judged the same.
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --chart "$T/chartwall.jpg" \
    --chart-corners 220,180,420,180,420,300,220,300 -o "$T/nochart.exr"
err_has "chartwall.jpg: "; err_one_line; absent "$T/nochart.exr"
# With a grey sphere: said, and the sphere alone calibrates; the report shows
# where the patches were looked for, each with its reason.
expect 0 mcc "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chartwall.jpg" \
    --grey "$T/grey.exr" --grey-circle 24,24,24 --spp 64 -o "$T/cal_wall.exr" --report "$T/rep_wall"
err_has "not a usable ColorChecker"; err_has "calibrating with the grey sphere alone"
json_eval "$T/out" 'd["chart"]["used"] is False and not d["chart"]["judgement"]["plausible"] and "plate_matrix" not in d'
json_eval "$T/out" 'd["matrix"][0][1] == 0 and abs(d["scale"] / 2 - 1) < 0.01'
present "$T/rep_wall/chart_patches.png"
grep -q "Chart refused, not used: only" "$T/rep_wall/calibrate.html" && ok || bad "report lacks the refusal"
png_width() { python3 -c 'import struct,sys; print(struct.unpack(">I", open(sys.argv[1],"rb").read()[16:20])[0])' "$1"; }
[ "$(png_width "$T/rep_wall/chart_patches.png")" -ge 256 ] && ok || bad "chart picture under 256 px"
# Real charts on the wall pass, with a one-line summary; clipped patches left out.
expect 0 mcc "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chartok.jpg" -o "$T/cal_ok.exr" \
    --report "$T/rep_ok"
err_has "chartok.jpg: ColorChecker, 24 of 24 patches used"; err_has "CIEDE2000 mean"
json_eval "$T/out" 'd["chart"]["used"] and d["chart"]["judgement"]["plausible"] and d["chart"]["delta_e_after_mean"] < 1'
[ "$(png_width "$T/rep_ok/chart_patches.png")" -ge 256 ] && ok || bad "chart picture under 256 px"
expect 0 mcc "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chartclipped.jpg" -o "$T/cal_clip.exr"
json_eval "$T/out" 'd["chart"]["used"] and d["chart"]["patches_invalid"] >= 4 and not d["chart"]["patches"][18]["used"]'
expect 0 "$SETLIGHT" info --json "$T/cal_clip.exr"
json_eval "$T/out" 'd["files"][0]["negative_count"] == 0'
# As a float file the clipped values are only seen pinned at the top: left out too.
expect 0 mcc "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --chart "$T/chartclipped.exr" -o "$T/cal_clip2.exr"
err_has "pixels pinned at the image's maximum"
json_eval "$T/out" 'd["chart"]["used"] and not d["chart"]["patches"][18]["used"] and d["chart"]["delta_e_after_mean"] < 0.5'

# --- colour spaces: ACEScg out (recorded), an sRGB PNG chart in; unknown names refused
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --spp 64 --colorspace acescg -o "$T/cal_aces.exr"
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
    --grey-circle 24,24,24 --spp 64 --colorspace nosuchspace -o "$T/keep.exr"; err_has "nosuchspace"
expect 2 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --spp 64 --grey-colorspace nosuchgrey -o "$T/keep.exr"; err_has "nosuchgrey"
# An HDRI in ACEScg (its metadata says so) comes into the working space first.
"$SETLIGHT" convert --colorspace acescg "$T/env.exr" "$T/env_aces.exr" 2>/dev/null || bad "acescg env"
expect 0 "$SETLIGHT" calibrate --json --hdri "$T/env_aces.exr" --grey "$T/grey.exr" \
    --grey-circle 24,24,24 --spp 64 -o "$T/cal_from_aces.exr"
json_eval "$T/out" 'abs(d["scale"] / 2 - 1) < 0.01 and max(d["grey"]["balance"]) - min(d["grey"]["balance"]) < 0.02' 

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
    --grey-circle 24,24,24 -o "$T/keep.exr"; err_has "grey.exr: not a lat-long: 48x48 is not 2:1"
# A circle on empty background: no sphere there.
expect 3 "$SETLIGHT" calibrate --hdri "$T/env.exr" --grey "$T/chart.exr" \
    --grey-circle 120,150,10 -o "$T/keep.exr"; err_has "chart.exr"; err_one_line
cmp -s "$T/cal.exr" "$T/keep.exr" && ok || bad "keep.exr was overwritten"
no_temp "$T"

finish
