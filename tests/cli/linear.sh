#!/usr/bin/env bash
# Every command reads an image as scene-linear radiance the same way
# (core/image_linear.c, docs/color.md): an 8-bit sRGB lat-long is linearised
# through OpenColorIO, a 2:1 image without envmap attribute is a lat-long,
# each said in one line worded the same by every command; what is not a
# lat-long is refused in one line with nothing written.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" code128 "$T/c128.png" 64 32 || bad "fixture png"
"$MAKE_FIXTURE" code128 "$T/c128.jpg" 64 32 || bad "fixture jpg"
"$MAKE_FIXTURE" plain "$T/plain.exr" 64 32 || bad "fixture plain"
"$MAKE_FIXTURE" wide "$T/wide.exr" 96 || bad "fixture wide"
"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture env"
"$MAKE_FIXTURE" balljpg "$T/ball.jpg" || bad "fixture balljpg"
"$SETLIGHT" convert --to cubemap "$T/env.exr" "$T/cube.exr" 2>/dev/null || bad "fixture cube"
"$SETLIGHT" render --env "$T/env.exr" --scene grey --width 48 --spp 64 -o "$T/grey.exr" \
    2>/dev/null || bad "fixture grey"

LIN_NOTE="c128.png: 8-bit png in srgb, converted to scene-linear lin_rec709 through OpenColorIO; not HDR: clipped highlights make bright sources too dark"
LL_NOTE="c128.png: no envmap attribute; 64x32 is 2:1, taken as a lat-long"

# max_near FILE VALUE TOL: the image's largest R is VALUE within TOL.
max_near() {
  "$SETLIGHT" info --json "$1" >"$T/info" 2>/dev/null
  json_eval "$T/info" "abs(d['files'][0]['channel_stats'][0]['max'] - $2) < $3"
}
# notes FILE CMD: the last run's notes on reading FILE, in $T/notes.CMD.
notes() {
  grep -F "$1:" "$T/err" | grep -E "converted to scene-linear|taken as a lat-long" |
    sed 's/^setlight: \(warning: \)\{0,1\}//' >"$T/notes.$2"
}

# --- render --env: a code-128 sRGB map is radiance 0.2159, not 0.502. Under a
# uniform dome of radiance L a Lambert sphere of albedo 0.18 is 0.18 L
# everywhere: 0.03885 (0.0904 read as codes). Cosine sampling is exact here.
# (-i: the warning may follow another line; the note only on success.)
G=0.038854890020501867
for f in c128.png c128.jpg; do
  expect 0 "$SETLIGHT" render --env "$T/$f" --scene grey --width 32 --spp 16 --strategy cosine \
      -o "$T/grey_$f.exr"
  max_near "$T/grey_$f.exr" $G 2e-4
done
"$SETLIGHT" render --env "$T/c128.png" --scene grey --width 32 --spp 16 --strategy cosine \
    -o "$T/grey_again.exr" >"$T/out" 2>"$T/err"
err_has "$LIN_NOTE"; err_has "$LL_NOTE"
notes c128.png render
if [ "$(wc -l <"$T/notes.render")" -eq 2 ]; then ok; else bad "render notes: $(cat "$T/notes.render")"; fi
# the default strategy (MIS) agrees within its noise
expect 0 "$SETLIGHT" render --env "$T/c128.png" --scene grey --width 32 --spp 64 -o "$T/grey_mis.exr"
"$SETLIGHT" info --json "$T/grey_mis.exr" >"$T/info" 2>/dev/null
json_eval "$T/info" "abs(d['files'][0]['channel_stats'][0]['mean'] / ($G * 3.14159265 / 4) - 1) < 0.05"

# --input-colorspace overrides what the file says: codes taken as linear light
# light the ball at 0.18 x 128/255, with no linearising note
expect 0 "$SETLIGHT" render --env "$T/c128.png" --input-colorspace lin_rec709 --scene grey \
    --width 32 --spp 16 --strategy cosine -o "$T/grey_lin.exr"
if grep -qF "converted to scene-linear" "$T/err"; then bad "override still linearised"; else ok; fi
max_near "$T/grey_lin.exr" 0.090352941 2e-4
for cmd in "render --env" rig unwrap; do
  expect 2 "$SETLIGHT" $cmd "$T/c128.png" --input-colorspace nosuch -o "$T/bad_cs.exr"
  err_has "unknown colour space 'nosuch'"; err_one_line
done
absent "$T/bad_cs.exr"

# --- the same notes, worded the same, from rig, convert and calibrate
expect 0 "$SETLIGHT" rig "$T/c128.png" -o "$T/rig128.usda"
notes c128.png rig
expect 0 "$SETLIGHT" convert "$T/c128.png" "$T/conv128.exr"
notes c128.png convert
max_near "$T/conv128.exr" 0.21586050011389926 2e-4
expect 0 "$SETLIGHT" calibrate --hdri "$T/c128.png" --grey "$T/grey.exr" --grey-circle 24,24,24 \
    --spp 16 -o "$T/cal128.exr"
notes c128.png calibrate
for cmd in rig convert calibrate; do
  if cmp -s "$T/notes.render" "$T/notes.$cmd"; then ok
  else bad "$cmd notes differ from render's: $(cat "$T/notes.$cmd")"; fi
done
# unwrap words its photo's note the same way
expect 0 "$SETLIGHT" unwrap -o "$T/ball.exr" "$T/ball.jpg"
err_has "ball.jpg: 8-bit jpeg in srgb, converted to scene-linear lin_rec709 through OpenColorIO; not HDR: clipped highlights make bright sources too dark"
# --quiet keeps the warning, drops the note
expect 0 "$SETLIGHT" rig --quiet "$T/c128.png" -o "$T/rigq.usda"
err_has "$LIN_NOTE"
if grep -qF "$LL_NOTE" "$T/err"; then bad "--quiet printed the lat-long note"; else ok; fi

# --- a 2:1 EXR without envmap: a lat-long everywhere, with the note;
# --assume-latlong still accepted (no effect)
for opt in "" --assume-latlong; do
  expect 0 "$SETLIGHT" rig $opt --json "$T/plain.exr" -o "$T/plain$opt.usda"
  err_has "plain.exr: no envmap attribute; 64x32 is 2:1, taken as a lat-long"
  present "$T/plain$opt.usda"
done
expect 0 "$SETLIGHT" render --env "$T/plain.exr" --width 16 --spp 4 -o "$T/plain_r.exr"
err_has "plain.exr: no envmap attribute; 64x32 is 2:1, taken as a lat-long"

# --- published .hdr lat-longs (no envmap attribute): rig takes them
if [ -n "${SETLIGHT_SHARED_DATA:-}" ] && [ -d "$SETLIGHT_SHARED_DATA/hdri/small" ]; then
  for f in "$SETLIGHT_SHARED_DATA"/hdri/small/*.hdr "$SETLIGHT_SHARED_DATA/hdri/lebombo_1k.hdr"; do
    [ -f "$f" ] || continue
    b=$(basename "$f" .hdr)
    expect 0 "$SETLIGHT" rig --json "$f" -o "$T/$b.usda"
    err_has "$b.hdr: no envmap attribute; "; err_has "is 2:1, taken as a lat-long"
    json_eval "$T/out" 'd["lights"] >= 0'
    present "$T/$b.usda"
  done
else
  skip "shared data absent: real .hdr lat-longs"
fi

# --- not a lat-long: one line naming the file and the problem, exit 3, no output
mkdir -p "$T/bad"
expect 3 "$SETLIGHT" rig "$T/wide.exr" -o "$T/bad/a.usda"
err_has "wide.exr: not a lat-long: 96x32 is not 2:1"; err_one_line
if [ -f "${SETLIGHT_SHARED_DATA:-}/probes/grace_probe_angular.hdr" ]; then
  expect 3 "$SETLIGHT" rig "$SETLIGHT_SHARED_DATA/probes/grace_probe_angular.hdr" -o "$T/bad/a.usda"
  err_has "grace_probe_angular.hdr: not a lat-long: 1000x1000 is not 2:1 (a mirror ball or angular map?"
  err_one_line
else
  skip "shared data absent: angular probe"
fi
expect 3 "$SETLIGHT" rig "$T/cube.exr" -o "$T/bad/a.usda"
err_has "cube.exr: a cube map (envmap attribute), not a lat-long"; err_one_line
expect 3 "$SETLIGHT" render --env "$T/wide.exr" --width 16 -o "$T/bad/r.exr"
err_has "wide.exr: not a lat-long: 96x32 is not 2:1"; err_one_line
expect 3 "$SETLIGHT" render --env "$T/cube.exr" --width 16 -o "$T/bad/r.exr"
err_has "cube.exr: a cube map"; err_one_line
expect 3 "$SETLIGHT" calibrate --hdri "$T/wide.exr" --grey "$T/grey.exr" -o "$T/bad/c.exr"
err_has "wide.exr: not a lat-long"; err_one_line
# a refusal after a note is still one line: the notes are dropped
expect 3 "$SETLIGHT" calibrate --hdri "$T/c128.png" --grey "$T/missing.exr" -o "$T/bad/c.exr"
err_has "missing.exr"; err_one_line
if [ -z "$(ls -A "$T/bad")" ]; then ok; else bad "output left in $T/bad: $(ls -A "$T/bad")"; fi

finish
