#!/usr/bin/env bash
# setlight unwrap end to end: a ray-traced perspective chrome ball (detected,
# unwrapped with the lens, reflectance divided out), provenance and JSON, and
# every bad input the issue names: no ball, two balls, a ball cut by the frame,
# an 8-bit JPEG (warned and linearised), a circle outside the image.
. "$(dirname "$0")/lib.bash"

for k in ball ball90 balltwo ballclip ballnone ballfisheye ballfill; do
  "$MAKE_FIXTURE" "$k" "$T/$k.exr" || bad "fixture $k"
done
"$MAKE_FIXTURE" balljpg "$T/ball.jpg" || bad "fixture balljpg"

expect 0 "$SETLIGHT" unwrap --help; out_has "usage: setlight unwrap"
expect 0 "$SETLIGHT" --help; out_has "unwrap"

# --- a good ball: found, lens model from focal length and sensor width
expect 0 "$SETLIGHT" unwrap --json --focal-mm 18 --sensor-mm 20 --reflectance chrome \
  -o "$T/env.exr" "$T/ball.exr"
json_ok "$T/out"
json_eval "$T/out" 'd["circle"]["detected"] and abs(d["circle"]["cx"] - 104.3) < 0.5 and abs(d["circle"]["r"] - 46.5) < 0.5'
json_eval "$T/out" 'd["camera"] == "perspective" and abs(d["distance_radii"] - 4.0) < 0.05'
json_eval "$T/out" '0 < d["circle"]["uncertainty"] < 0.25'
# --- a tight crop: the ball's outline touches the four sides of the frame
expect 0 "$SETLIGHT" unwrap --json -o "$T/fill.exr" "$T/ballfill.exr"
json_eval "$T/out" 'abs(d["circle"]["cx"] - 128) < 0.3 and abs(d["circle"]["cy"] - 128) < 0.3 and abs(d["circle"]["r"] - 128) < 0.3'
json_eval "$T/out" 'd["width"] == 2 * d["height"] and d["width"] % 4 == 0'
present "$T/env.exr"; no_temp "$T"
expect 0 "$SETLIGHT" info --json "$T/env.exr"
json_eval "$T/out" 'd["files"][0]["envmap"] == "latlong" and d["files"][0]["channels"] == 4'
expect 0 "$SETLIGHT" info "$T/env.exr"
out_has "setlight:ball_circle"; out_has "setlight:ball_camera perspective"
out_has "setlight:ball_reflectance conductor"

# --- given circle, orthographic model, fixed width, RGB only
expect 0 "$SETLIGHT" unwrap --json --circle 104.33,86.37,46.47 --camera ortho --width 64 \
  --no-confidence -o "$T/ortho.exr" "$T/ball.exr"
json_eval "$T/out" 'not d["circle"]["detected"] and d["camera"] == "orthographic" and d["width"] == 64'
json_eval "$T/out" 'd["encoding"] == {"pixel": "half", "compression": "zip"}'
expect 0 "$SETLIGHT" info --json "$T/ortho.exr"
json_eval "$T/out" 'd["files"][0]["channels"] == 3'
cp "$T/out" "$T/ortho_info.json"
# GNU order: the same unwrap with the options after the photo
expect 0 "$SETLIGHT" unwrap -o "$T/ortho_late.exr" "$T/ball.exr" --circle 104.33,86.37,46.47 \
  --camera ortho --width 64 --no-confidence --json
json_eval "$T/out" 'd["camera"] == "orthographic" and d["width"] == 64'
if cmp -s "$T/ortho.exr" "$T/ortho_late.exr"; then ok; else bad "options after the photo changed the unwrap"; fi
# the other lossless compressions: the same pixels, a different file
for comp in piz rle none; do
  expect 0 "$SETLIGHT" unwrap --json --circle 104.33,86.37,46.47 --camera ortho --width 64 \
    --no-confidence --compression $comp -o "$T/ortho_$comp.exr" "$T/ball.exr"
  json_eval "$T/out" "d['encoding']['compression'] == '$comp'"
  expect 0 "$SETLIGHT" info --json "$T/ortho_$comp.exr"
  if python3 -c 'import json,sys; a,b=(json.load(open(p))["files"][0]["channel_stats"] for p in sys.argv[1:]); sys.exit(a != b)' \
    "$T/ortho_info.json" "$T/out"; then ok; else bad "--compression $comp changed the pixels"; fi
done
cmp -s "$T/ortho.exr" "$T/ortho_none.exr" && bad "--compression none wrote the ZIP file" || ok
expect 2 "$SETLIGHT" unwrap --circle 104.33,86.37,46.47 --compression zips -o "$T/zips.exr" "$T/ball.exr"
err_has "--compression"; err_one_line; absent "$T/zips.exr"

# --- camera orientation and field of view options are accepted and recorded
expect 0 "$SETLIGHT" unwrap --fov 58.07 --camera-azimuth 30 --camera-elevation 10 \
  --camera-roll 2 -o "$T/turned.exr" "$T/ball.exr"
expect 0 "$SETLIGHT" info "$T/turned.exr"; out_has "azimuth 30, elevation 10, roll 2"

# --- two views a quarter turn apart, view 2's azimuth given 6 degrees off and found again
expect 0 "$SETLIGHT" unwrap --json --focal-mm 18 --sensor-mm 20 --reflectance chrome \
  --camera2-azimuth 84 -o "$T/two.exr" "$T/ball.exr" "$T/ball90.exr"
json_eval "$T/out" 'abs(d["view2"]["azimuth_deg"] - 90) < 0.5 and d["view2"]["azimuth_given_deg"] == 84'
json_eval "$T/out" 'd["view2"]["residual"] < d["view2"]["residual_given"] and d["view2"]["circle"]["detected"]'
err_has "view 2 azimuth"
expect 0 "$SETLIGHT" info "$T/two.exr"; out_has "setlight:source2"; out_has "setlight:two_views"
expect 0 "$SETLIGHT" unwrap --json --focal-mm 18 --sensor-mm 20 --search 0 -o "$T/two0.exr" \
  "$T/ball.exr" "$T/ball90.exr"
json_eval "$T/out" 'd["view2"]["azimuth_deg"] == 90 and d["view2"]["residual"] is None'

# --- reflectance from a patch of known radiance (in front of the ball: azimuth 180):
# the ball's mean there over the radiance; halving the radiance doubles it
expect 0 "$SETLIGHT" unwrap --json --focal-mm 18 --sensor-mm 20 --reflectance-patch 180,10,12,1 \
  -o "$T/patch1.exr" "$T/ball.exr"
json_eval "$T/out" '0.01 < d["reflectance_patch"]["reflectance"][1] < 10'
M=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["reflectance_patch"]["reflectance"][1])' "$T/out")
expect 0 "$SETLIGHT" unwrap --json --focal-mm 18 --sensor-mm 20 --reflectance-patch "180,10,12,$M,$M,$M" \
  -o "$T/patch2.exr" "$T/ball.exr"
json_eval "$T/out" 'abs(d["reflectance_patch"]["reflectance"][1] - 1) < 1e-6'
expect 0 "$SETLIGHT" info "$T/patch2.exr"; out_has "from a patch at 180,10, 12 deg"

# --- an 8-bit JPEG: warned, linearised, still unwrapped
expect 0 "$SETLIGHT" unwrap --json -o "$T/jpg.exr" "$T/ball.jpg"
err_has "not HDR"; err_has "ball.jpg"
json_eval "$T/out" 'd["ldr_linearised"] == True'

# --- bad inputs: exit code, one line naming the file, no output left behind
mkdir -p "$T/outdir"
expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/ballnone.exr"
err_has "ballnone.exr"; err_has "no chrome ball"; err_one_line; absent "$T/outdir/a.exr"
expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/balltwo.exr"
err_has "balltwo.exr"; err_has "2 balls"; err_one_line; absent "$T/outdir/a.exr"
expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/ballclip.exr"
err_has "ballclip.exr"; err_has "cut by the frame edge"; err_one_line; absent "$T/outdir/a.exr"
expect 2 "$SETLIGHT" unwrap --circle 180,80,40 -o "$T/outdir/a.exr" "$T/ball.exr"
err_has "not inside"; err_has "ball.exr"; err_one_line; absent "$T/outdir/a.exr"
expect 2 "$SETLIGHT" unwrap --circle 1,2 -o "$T/outdir/a.exr" "$T/ball.exr"; err_has "--circle"
expect 2 "$SETLIGHT" unwrap --camera fisheye -o "$T/outdir/a.exr" "$T/ball.exr"; err_has "fisheye"
expect 2 "$SETLIGHT" unwrap --reflectance 2 -o "$T/outdir/a.exr" "$T/ball.exr"
expect 2 "$SETLIGHT" unwrap --width 33 -o "$T/outdir/a.exr" "$T/ball.exr"
expect 2 "$SETLIGHT" unwrap --focal-mm 18 -o "$T/outdir/a.exr" "$T/ball.exr"; err_has "--sensor-mm"
expect 2 "$SETLIGHT" unwrap --distance 300 -o "$T/outdir/a.exr" "$T/ball.exr"; err_has "--ball-diameter"
expect 2 "$SETLIGHT" unwrap "$T/ball.exr"; err_has "-o"
expect 2 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/ball.exr" "$T/ball.exr" "$T/ball.exr"
err_has "one or two ball photos"
expect 2 "$SETLIGHT" unwrap --circle2 50,50,20 -o "$T/outdir/a.exr" "$T/ball.exr"; err_has "second ball photo"
expect 2 "$SETLIGHT" unwrap --search 100 -o "$T/outdir/a.exr" "$T/ball.exr" "$T/ball90.exr"; err_has "--search"
expect 2 "$SETLIGHT" unwrap --reflectance 0.5 --reflectance-patch 0,0,5,1 -o "$T/outdir/a.exr" "$T/ball.exr"
err_has "not both"
expect 2 "$SETLIGHT" unwrap --reflectance-patch 0,0,5 -o "$T/outdir/a.exr" "$T/ball.exr"; err_has "--reflectance-patch"
# a patch behind the ball (the camera looks along +Z: azimuth 0 is behind it) is not seen
expect 3 "$SETLIGHT" unwrap --focal-mm 18 --sensor-mm 20 --reflectance-patch 0,0,5,1 -o "$T/outdir/a.exr" "$T/ball.exr"
err_has "ball.exr"; err_has "reflectance patch"; err_one_line
expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/ball.exr" "$T/balltwo.exr"; err_has "balltwo.exr"; err_has "2 balls"
expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/missing.exr"; err_has "missing.exr"; err_one_line
no_temp "$T/outdir"
if [ "$(ls -A "$T/outdir")" = "" ]; then ok; else bad "outdir not empty: $(ls "$T/outdir")"; fi

# --- a circular fisheye photo is no ball (nor an angular or mirror-ball map): refused by
# unwrap (with or without --circle) and by convert --from angular/mirrorball, naming stitch
expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$T/ballfisheye.exr"
err_has "ballfisheye.exr"; err_has "circular fisheye"; err_has "'setlight stitch'"; err_one_line
absent "$T/outdir/a.exr"
expect 3 "$SETLIGHT" unwrap --circle 150,100,90 -o "$T/outdir/a.exr" "$T/ballfisheye.exr"
err_has "circular fisheye"; err_one_line; absent "$T/outdir/a.exr"
for p in angular mirrorball; do
  expect 3 "$SETLIGHT" convert --from $p "$T/ballfisheye.exr" "$T/outdir/c.exr"
  err_has "ballfisheye.exr"; err_has "'setlight stitch'"; err_one_line; absent "$T/outdir/c.exr"
done
# the angular and mirror-ball maps of a ball's unwrap still convert
expect 0 "$SETLIGHT" convert --to angular --width 256 "$T/env.exr" "$T/env_angular.exr"
expect 0 "$SETLIGHT" convert --from angular "$T/env_angular.exr" "$T/env_back.exr"
expect 0 "$SETLIGHT" convert --to mirrorball --width 256 "$T/env.exr" "$T/env_ball.exr"
expect 0 "$SETLIGHT" convert --from mirrorball "$T/env_ball.exr" "$T/env_back2.exr"
no_temp "$T/outdir"
# --- those maps are no photos of a ball: unwrap refuses them, naming convert, unless
# --circle says the disc is a ball
for m in env_angular env_ball; do
  expect 3 "$SETLIGHT" unwrap -o "$T/outdir/m.exr" "$T/$m.exr"
  err_has "$m.exr: a disc filling its frame on pure black is a light-probe map"
  err_has "'setlight convert --from angular'"; err_has "--circle"; err_one_line
  absent "$T/outdir/m.exr"
done
no_temp "$T/outdir"
expect 0 "$SETLIGHT" unwrap --circle 64,64,64 -o "$T/forced.exr" "$T/env_ball.exr"
present "$T/forced.exr"
F="${SETLIGHT_SHARED_DATA:-}/fisheye/sigma8mm_canon6d/IMG_2843.JPG"
G="${SETLIGHT_SHARED_DATA:-}/probes/grace_probe_angular.hdr"
if [ -f "$F" ] && [ -f "$G" ]; then
  expect 3 "$SETLIGHT" unwrap -o "$T/outdir/a.exr" "$F"
  err_has "IMG_2843.JPG: looks like a circular fisheye image"; err_has "'setlight stitch'"
  err_one_line; absent "$T/outdir/a.exr"
  expect 3 "$SETLIGHT" convert --from angular "$F" "$T/outdir/c.exr"
  err_has "circular fisheye"; err_one_line; absent "$T/outdir/c.exr"
  expect 0 "$SETLIGHT" convert --from angular "$G" "$T/grace.exr"; present "$T/grace.exr"
  expect 3 "$SETLIGHT" unwrap -o "$T/outdir/g.exr" "$G"
  err_has "grace_probe_angular.hdr: a disc filling its frame on pure black is a light-probe map"
  err_has "'setlight convert --from angular'"; err_one_line; absent "$T/outdir/g.exr"
else
  skip "real fisheye and angular probe"
fi

# --- the real iPhone probes (when present): this one is whole and unwraps
P="${SETLIGHT_SHARED_DATA:-}/probes/chromeball_iphone7/160.JPG"
if [ -f "$P" ]; then
  expect 0 "$SETLIGHT" unwrap --json -o "$T/iphone.exr" "$P"
  json_eval "$T/out" 'd["circle"]["detected"] and 225 < d["circle"]["r"] < 240'
else
  skip "real probe photo"
fi

finish
