#!/usr/bin/env bash
# setlight info and convert, end to end: good files, real HDRIs, and every bad
# input the foundation issue names (exit code, one-line message naming the
# file, no output left behind).
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" nan "$T/nan.pfm" 64 32 || bad "fixture"
"$MAKE_FIXTURE" wide "$T/wide.exr" 96 || bad "fixture"
"$MAKE_FIXTURE" wideenv "$T/wideenv.exr" 96 || bad "fixture"
"$MAKE_FIXTURE" conf "$T/conf.exr" 48 || bad "fixture"
"$MAKE_FIXTURE" png "$T/png_named.exr" 64 32 || bad "fixture"

# --- global behaviour
expect 0 "$SETLIGHT" --version; out_has "setlight "
expect 0 "$SETLIGHT" --help; out_has "convert"
expect 2 "$SETLIGHT" nosuchcommand; err_has "unknown command"
expect 0 "$SETLIGHT" info --help; out_has "usage: setlight info"
expect 0 "$SETLIGHT" convert --help; out_has "usage: setlight convert"
expect 2 "$SETLIGHT" info --bogus "$T/env.exr"; err_has "--bogus"; err_one_line
expect 2 "$SETLIGHT" info
expect 2 "$SETLIGHT" convert --threads x "$T/env.exr" "$T/o.exr"

# --- info on a good file, text and JSON
expect 0 "$SETLIGHT" info "$T/env.exr"; out_has "64 x 32"; out_has "latlong"
expect 0 "$SETLIGHT" info --json "$T/env.exr"
json_ok "$T/out"
json_eval "$T/out" 'd["files"][0]["width"] == 64 and d["files"][0]["envmap"] == "latlong" and d["files"][0]["nan_count"] == 0'
json_eval "$T/out" 'abs(d["files"][0]["channel_stats"][0]["mean"] - 0.6) < 1e-3'

# --- info reports NaN/Inf and does not fail on them
expect 0 "$SETLIGHT" info --json "$T/nan.pfm"
json_eval "$T/out" 'd["files"][0]["nan_count"] == 1 and d["files"][0]["inf_count"] == 2'

# --- bad inputs to info: exit 3, one line naming the file
mkdir -p "$T/adir"
: >"$T/empty.exr"
head -c 300 "$T/env.exr" >"$T/truncated.exr"
for f in "$T/missing.exr" "$T/adir" "$T/empty.exr" "$T/truncated.exr"; do
  expect 3 "$SETLIGHT" info "$f"; err_has "$f"; err_one_line
done
# a PNG renamed to .exr is read for what it is
expect 0 "$SETLIGHT" info --json "$T/png_named.exr"
json_eval "$T/out" 'd["files"][0]["format"] == "png"'
err_has "png_named.exr: the file is png"; err_one_line
# several files: every one is examined, exit code of the first failure
expect 3 "$SETLIGHT" info "$T/env.exr" "$T/missing.exr" "$T/nan.pfm"
out_has "env.exr"; out_has "nan.pfm"; err_has "missing.exr"

# --- convert: round trips through every projection keep the mean
for p in mirrorball angular cubemap; do
  expect 0 "$SETLIGHT" convert --to "$p" "$T/env.exr" "$T/env_$p.exr"; present "$T/env_$p.exr"
  expect 0 "$SETLIGHT" convert --json --from "$p" --width 64 "$T/env_$p.exr" "$T/back_$p.exr"
  json_eval "$T/out" 'd["width"] == 64 and d["height"] == 32'
done
expect 0 "$SETLIGHT" info --json "$T/back_cubemap.exr"
json_eval "$T/out" 'abs(d["files"][0]["channel_stats"][0]["mean"] - 0.6) < 0.01'
expect 0 "$SETLIGHT" info --json "$T/env_cubemap.exr"
json_eval "$T/out" 'd["files"][0]["envmap"] == "cube" and d["files"][0]["height"] == 6 * d["files"][0]["width"]'
# GNU order: options after the file names
expect 0 "$SETLIGHT" convert "$T/env.exr" "$T/late_mb.exr" --to mirrorball --json
expect 0 "$SETLIGHT" info --json "$T/late_mb.exr"
json_eval "$T/out" 'd["files"][0]["width"] == 32 and d["files"][0]["height"] == 32'
expect 0 "$SETLIGHT" info "$T/env.exr" --json; json_ok "$T/out"
# rotation and colour space
expect 0 "$SETLIGHT" convert --rotate 90 --colorspace acescg "$T/env.exr" "$T/rot.exr"
expect 0 "$SETLIGHT" info --json "$T/rot.exr"
json_eval "$T/out" 'd["files"][0]["colorspace"] == "acescg"'
# LDR preview
expect 0 "$SETLIGHT" convert --to mirrorball "$T/env.exr" "$T/ball.png"; present "$T/ball.png"
expect 0 "$SETLIGHT" info --json "$T/ball.png"
json_eval "$T/out" 'd["files"][0]["channels"] == 3 and d["files"][0]["bits_per_sample"] == 8'

# --- convert: an image that is no environment (not 2:1, no envmap, no --from)
expect 0 "$SETLIGHT" convert --json "$T/wide.exr" "$T/wide_copy.exr"
json_eval "$T/out" 'd["from"] == "image" and d["width"] == 96 and d["height"] == 32'
expect 0 "$SETLIGHT" info --json "$T/wide_copy.exr"
json_eval "$T/out" 'd["files"][0]["envmap"] == "none" and d["files"][0]["width"] == 96 and abs(d["files"][0]["channel_stats"][0]["mean"] - 0.6) < 1e-3'
# preview: the median (3.7) to mid grey through the sRGB view, the confidence
# channel dropped (no alpha): every pixel 118 = round(255 * srgb(0.18))
expect 0 "$SETLIGHT" convert --json "$T/conf.exr" "$T/conf.png"
json_eval "$T/out" 'abs(d["preview"]["exposure_stops"] - (-4.36148)) < 1e-4 and d["preview"]["view"] == "sRGB/Standard" and d["width"] == 48 and d["height"] == 32'
expect 0 "$SETLIGHT" info --json "$T/conf.png"
json_eval "$T/out" 'd["files"][0]["channels"] == 3 and d["files"][0]["bits_per_sample"] == 8 and all(abs(s["min"] - 118/255) < 1e-6 and abs(s["max"] - 118/255) < 1e-6 for s in d["files"][0]["channel_stats"])'
# a given exposure and the Raw view: 3.7 * 2^-4 = 0.23125 -> 59 of 255
expect 0 "$SETLIGHT" convert "$T/conf.exr" --exposure -4 --view Raw "$T/conf_raw.jpg"
expect 0 "$SETLIGHT" info --json "$T/conf_raw.jpg"
json_eval "$T/out" 'd["files"][0]["channels"] == 3 and all(abs(s["mean"] - 59/255) < 1.5/255 for s in d["files"][0]["channel_stats"])'
# --width keeps the aspect; EXR out is a plain copy that keeps the confidence
expect 0 "$SETLIGHT" convert --json --width 24 "$T/conf.exr" "$T/conf_small.png"
json_eval "$T/out" 'd["width"] == 24 and d["height"] == 16'
expect 0 "$SETLIGHT" convert "$T/conf.exr" "$T/conf_copy.exr"
expect 0 "$SETLIGHT" info --json "$T/conf_copy.exr"
json_eval "$T/out" 'd["files"][0]["channels"] == 4 and abs(d["files"][0]["channel_stats"][3]["max"] - 1) < 1e-3'
# what a preview cannot do, or an image cannot be: refused, nothing written
mkdir -p "$T/pv"
expect 2 "$SETLIGHT" convert --view Filmic "$T/conf.exr" "$T/pv/a.png"; err_has "Filmic"; err_has "Standard, Raw"; err_one_line
expect 2 "$SETLIGHT" convert --exposure bright "$T/conf.exr" "$T/pv/a.png"; err_has "--exposure"; err_one_line
expect 2 "$SETLIGHT" convert --exposure 1 "$T/conf.exr" "$T/pv/a.exr"; err_has "a.exr"; err_one_line
expect 2 "$SETLIGHT" convert --colorspace acescg "$T/conf.exr" "$T/pv/a.png"; err_has "--view"; err_one_line
expect 3 "$SETLIGHT" convert --to mirrorball "$T/wide.exr" "$T/pv/a.png"; err_has "wide.exr: not a lat-long"; err_has "2:1"; err_one_line
expect 3 "$SETLIGHT" convert --rotate 30 "$T/conf.exr" "$T/pv/a.exr"; err_has "conf.exr"; err_one_line
absent "$T/pv/a.png"; absent "$T/pv/a.exr"; no_temp "$T/pv"

# --- convert: NaN input is counted, reported and replaced; --strict refuses
expect 0 "$SETLIGHT" convert --json "$T/nan.pfm" "$T/nan_out.exr"
json_eval "$T/out" 'd["nonfinite_replaced"] == 3'
err_has "nan.pfm"
expect 0 "$SETLIGHT" info --json "$T/nan_out.exr"
json_eval "$T/out" 'd["files"][0]["nan_count"] == 0 and d["files"][0]["inf_count"] == 0'
expect 3 "$SETLIGHT" convert --strict "$T/nan.pfm" "$T/strict_out.exr"; err_has "nan.pfm"; absent "$T/strict_out.exr"

# --- convert: bad inputs leave no output and no temporary
mkdir -p "$T/outdir"
expect 3 "$SETLIGHT" convert "$T/missing.exr" "$T/outdir/a.exr"; err_has "missing.exr"; err_one_line
expect 3 "$SETLIGHT" convert "$T/adir" "$T/outdir/a.exr"; err_has "adir"
expect 3 "$SETLIGHT" convert "$T/empty.exr" "$T/outdir/a.exr"; err_has "empty.exr"
expect 3 "$SETLIGHT" convert "$T/truncated.exr" "$T/outdir/a.exr"; err_has "truncated.exr"
expect 3 "$SETLIGHT" convert "$T/wideenv.exr" "$T/outdir/a.exr"; err_has "wideenv.exr"; err_has "2:1"; err_one_line
expect 2 "$SETLIGHT" convert --colorspace nosuchspace "$T/env.exr" "$T/outdir/a.exr"; err_has "nosuchspace"; err_one_line
expect 2 "$SETLIGHT" convert --to nosuchproj "$T/env.exr" "$T/outdir/a.exr"; err_has "nosuchproj"
expect 2 "$SETLIGHT" convert --width -3 "$T/env.exr" "$T/outdir/a.exr"
expect 2 "$SETLIGHT" convert --unknown-option "$T/env.exr" "$T/outdir/a.exr"; err_has "--unknown-option"
expect 2 "$SETLIGHT" convert "$T/env.exr"
expect 2 "$SETLIGHT" convert "$T/env.exr" "$T/no/such/dir/a.exr"; err_has "a.exr"
expect 2 "$SETLIGHT" convert "$T/env.exr" "$T/outdir/a.xyz"; err_has "a.xyz"
absent "$T/outdir/a.exr"; no_temp "$T/outdir"; no_temp "$T"
# an existing output is untouched when a run fails
cp "$T/env.exr" "$T/outdir/keep.exr"
expect 3 "$SETLIGHT" convert "$T/truncated.exr" "$T/outdir/keep.exr"
if cmp -s "$T/env.exr" "$T/outdir/keep.exr"; then ok; else bad "existing output changed by a failed run"; fi

# --- real HDRIs (skipped when shared data is absent)
hdri="${SETLIGHT_SHARED_DATA:-}/hdri"
if [ -d "$hdri" ]; then
  files=()
  for f in "$hdri"/*.hdr "$hdri"/*/*.exr "$hdri"/small/*.hdr; do [ -e "$f" ] && files+=("$f"); done
  expect 0 "$SETLIGHT" info --json "${files[@]}"; json_ok "$T/out"
  json_eval "$T/out" 'len(d["files"]) == '"${#files[@]}"' and all("error" not in f and f["nan_count"] == 0 and f["width"] > 0 for f in d["files"])'
  n=${#files[@]}
  for f in "$hdri"/venice_sunset_1k.hdr "$hdri"/Grace_Cathedral_500x250.hdr; do
    [ -e "$f" ] || continue
    expect 0 "$SETLIGHT" convert --width 256 "$f" "$T/real.exr"
    expect 0 "$SETLIGHT" convert --to cubemap --width 256 "$f" "$T/real_cube.exr"
  done
  # a real angular light probe unwraps to a lat-long
  probe="${SETLIGHT_SHARED_DATA:-}/probes/grace_probe_angular.hdr"
  [ -e "$probe" ] && { expect 0 "$SETLIGHT" convert --from angular --width 256 "$probe" "$T/grace.exr"; present "$T/grace.exr"; }
  # a merged view (not 2:1) previewed: same size, RGB, 8-bit
  mem="${SETLIGHT_SHARED_DATA:-}/brackets/memorial/memorial.exr"
  if [ -e "$mem" ]; then
    expect 0 "$SETLIGHT" convert --json "$mem" "$T/memorial.jpg"
    json_eval "$T/out" 'd["from"] == "image" and d["width"] == 512 and d["height"] == 768 and d["preview"]["median_luminance"] > 0'
    expect 0 "$SETLIGHT" info --json "$T/memorial.jpg"
    json_eval "$T/out" 'd["files"][0]["channels"] == 3 and d["files"][0]["width"] == 512'
  fi
  echo "read $n real HDRIs"
else
  skip "shared HDRIs absent"
fi

finish
