#!/usr/bin/env bash
# EXRs as renders write them, end to end through info and convert: RGB + a
# depth channel setlight does not read, in PIZ (killed info, convert, rig,
# render --env, unwrap and calibrate --hdri with SIGSEGV before), tiled RGBA
# + Z, and float B44 (wrong pixels before): same pixels as the plain file.
# tests/test_exr_layouts.c checks every compression and layout.
. "$(dirname "$0")/lib.bash"

if ! command -v oiiotool >/dev/null; then
  skip "EXR layouts (no oiiotool: scripts/install-deps.sh installs openimageio-tools)"
  finish
  exit
fi

"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"
oiiotool "$T/env.exr" -d half --ch R,G,B,Z=G --compression piz -o "$T/rgbz_piz.exr" || bad "oiiotool piz"
oiiotool "$T/env.exr" -d half --ch R,G,B,A=1.0,Z=R --tile 16 16 --compression rle -o "$T/tiled.exr" ||
  bad "oiiotool tiled"
oiiotool "$T/env.exr" -d float --ch R,G,B,Z=B --compression b44 -o "$T/b44_float.exr" ||
  bad "oiiotool b44"
oiiotool "$T/env.exr" -d half -o "$T/env_half.exr" || bad "oiiotool half"

# The means of the plain file in the same pixel type, for each.
expect 0 "$SETLIGHT" info --json "$T/env.exr"
for f in b44_float b44_float_out; do cp "$T/out" "$T/$f.want"; done
expect 0 "$SETLIGHT" info --json "$T/env_half.exr"
for f in rgbz_piz rgbz_piz_out tiled tiled_out; do cp "$T/out" "$T/$f.want"; done
# same_means NAME: the last info's channel means are NAME's.
same_means() {
  python3 - "$T/$1.want" "$T/out" <<'EOF'
import json, sys
a = json.load(open(sys.argv[1]))["files"][0]["channel_stats"]
b = json.load(open(sys.argv[2]))["files"][0]["channel_stats"]
sys.exit(0 if all(abs(a[c]["mean"] - b[c]["mean"]) <= 1e-6 * abs(a[c]["mean"]) for c in range(3)) else 1)
EOF
}
for f in rgbz_piz tiled b44_float; do
  expect 0 "$SETLIGHT" info --json "$T/$f.exr"
  json_eval "$T/out" 'd["files"][0]["width"] == 64 and d["files"][0]["height"] == 32'
  if same_means "$f"; then ok; else bad "$f.exr: means differ from the plain file's"; fi
  expect 0 "$SETLIGHT" convert --float "$T/$f.exr" "$T/${f}_out.exr"; present "$T/${f}_out.exr"
  expect 0 "$SETLIGHT" info --json "$T/${f}_out.exr"
  if same_means "${f}_out"; then ok; else bad "${f}_out.exr: means differ from the plain file's"; fi
done
expect 0 "$SETLIGHT" convert "$T/rgbz_piz.exr" "$T/preview.png"; present "$T/preview.png"
expect 0 "$SETLIGHT" info --json "$T/tiled.exr"
json_eval "$T/out" 'd["files"][0]["channels"] == 4 and abs(d["files"][0]["channel_stats"][3]["mean"] - 1) < 1e-6'
expect 0 "$SETLIGHT" info --json "$T/rgbz_piz.exr"
json_eval "$T/out" 'd["files"][0]["channels"] == 3'
no_temp "$T"

finish
