#!/bin/bash
# setlight render end to end: a small render, its stats, and every bad input
# giving one message, the documented exit code and no output file.
set -u
S="$SETLIGHT"
T="$SETLIGHT_TEST_TMP/cli_render"
rm -rf "$T" && mkdir -p "$T"
fail=0
check() { # name expected-rc actual-rc
    if [ "$2" != "$3" ]; then echo "FAIL $1: exit $3, expected $2"; fail=1; else echo "ok   $1"; fi
}
noout() { # name file
    if [ -e "$2" ] || ls "$T"/.*sl-tmp* >/dev/null 2>&1; then echo "FAIL $1: output left behind"; fail=1; fi
}
# A valid environment: write one with the renderer itself is not possible, so
# build a tiny Radiance HDR by hand (32x16, uniform).
python3 - "$T/env.hdr" <<'PY'
import sys
w, h = 32, 16
with open(sys.argv[1], "wb") as f:
    f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w))
    f.write(bytes([128, 128, 128, 129]) * (w * h))  # 1.0 everywhere
PY

"$S" render --env "$T/env.hdr" --scene grey --width 16 --spp 4 -o "$T/grey.exr" --stats "$T/grey.json" --quiet
check "grey render" 0 $?
[ -s "$T/grey.exr" ] || { echo "FAIL no grey.exr"; fail=1; }
grep -q '"passes"' "$T/grey.json" || { echo "FAIL stats without passes"; fail=1; }
"$S" render --env "$T/env.hdr" --scene grey --width 16 --spp 4 --reference "$T/grey.exr" -o "$T/grey2.exr" --json --quiet > "$T/out.json"
check "render with reference" 0 $?
grep -q '"ref_rel_rmse": 0,' "$T/out.json" || grep -q '"ref_rel_rmse": 0\b' "$T/out.json" || { echo "FAIL same seed should match its reference exactly: $(cat "$T/out.json")"; fail=1; }
# Adaptive sampling: under a uniform dome the background (21% of the image)
# has no variance and stops at once; the stats count what was saved.
"$S" render --env "$T/env.hdr" --scene grey --width 16 --target-error 0.001 -o "$T/ad.exr" --stats "$T/ad.json" --quiet
check "adaptive render" 0 $?
python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); sys.exit(0 if d["pixels_stopped_early"] >= 50 and 0 < d["samples"] < d["spp"] * 256 and d["passes"][-1]["est_rel_rmse"] <= 0.001 else 1)' "$T/ad.json" || { echo "FAIL adaptive stats: $(head -c 400 "$T/ad.json")"; fail=1; }
"$S" render --help > "$T/help.txt"
check "help" 0 $?
for o in --env --scene --material --width --view --background --pixel-centers --spp --time --target-error --bounces --strategy --sampler --closed-form --seed --reference --stats --output; do
    grep -q -- "$o" "$T/help.txt" || { echo "FAIL --help lacks $o"; fail=1; }
done

"$S" render --env "$T/env.hdr" --scene chrome --material plastic:0.5,0.1,0.1:0.3 --view 30,20 --width 12 --spp 2 -o "$T/mat.exr" --quiet
check "material and view" 0 $?
printf '{"version": 1, "lights": [{"type": "sphere", "direction": [0, 0.894, -0.447], "solid_angle": 0.05,
  "radiance": [20, 20, 20], "integral": [1, 1, 1], "position": [0, 4, -2], "size": [1, 1], "texture": null},
  {"type": "distant", "direction": [0, 0.707, -0.707], "solid_angle": 0.0003, "radiance": [3000, 3000, 3000],
  "integral": [0.9, 0.9, 0.9], "position": null, "size": null, "texture": null}],
  "dome": {"file": "env.hdr", "integral": [1, 1, 1]}}' > "$T/rig.json"
"$S" render --rig "$T/rig.json" --scene shadow --width 16 --spp 4 -o "$T/rig.exr" --stats "$T/rig_stats.json" --quiet
check "rig render" 0 $?
grep -q '"shadow_rays": [1-9]' "$T/rig_stats.json" || { echo "FAIL rig render traced no shadow rays"; fail=1; }

# Pixel centres: a mirror ball's pixels are then exact after one sample pair,
# so 2 and 8 samples per pixel give the same image (error 0 against each other).
"$S" render --env "$T/env.hdr" --scene chrome --material conductor:1,1,1:0 --pixel-centers --width 12 --spp 2 -o "$T/c2.exr" --quiet
check "pixel centres" 0 $?
"$S" render --env "$T/env.hdr" --scene chrome --material conductor:1,1,1:0 --pixel-centers --width 12 --spp 8 --seed 5 \
    --reference "$T/c2.exr" -o "$T/c8.exr" --json --quiet > "$T/c8.json"
grep -q '"ref_rel_rmse": 0,' "$T/c8.json" || { echo "FAIL pixel centres: 8 spp differ from 2: $(cat "$T/c8.json")"; fail=1; }
"$S" render --env "$T/env.hdr" --scene chrome --material conductor:1,1,1:0 --width 12 --spp 8 --seed 5 \
    --reference "$T/c2.exr" -o "$T/c8b.exr" --json --quiet > "$T/c8b.json"
grep -q '"ref_rel_rmse": 0,' "$T/c8b.json" && { echo "FAIL box-filtered pixels should differ from pixel centres"; fail=1; }

run_bad() { # name expected-rc message-pattern args...
    local name=$1 want=$2 pat=$3; shift 3
    "$S" render "$@" -o "$T/bad.exr" 2> "$T/err.txt"
    local rc=$?
    check "$name" "$want" "$rc"
    [ "$(wc -l < "$T/err.txt")" -eq 1 ] || { echo "FAIL $name: not one line: $(cat "$T/err.txt")"; fail=1; }
    grep -q -- "$pat" "$T/err.txt" || { echo "FAIL $name: message lacks '$pat': $(cat "$T/err.txt")"; fail=1; }
    noout "$name" "$T/bad.exr"
}
run_bad "missing env" 3 "nope.exr" --env "$T/nope.exr"
printf 'this is not an image' > "$T/corrupt.exr"
run_bad "corrupt env" 3 "corrupt.exr" --env "$T/corrupt.exr"
run_bad "unknown preset" 2 "teapot" --env "$T/env.hdr" --scene teapot
run_bad "zero width" 2 "width" --env "$T/env.hdr" --width 0
python3 - "$T/square.hdr" <<'PY'
import sys
with open(sys.argv[1], "wb") as f:
    f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16 +X 16\n" + bytes([128, 128, 128, 129]) * 256)
PY
run_bad "env not a lat-long" 3 "square.hdr.*lat-long" --env "$T/square.hdr"
run_bad "no env" 2 "env" --scene grey
printf '{"materials": {"m": {"type": "lambert"}}, "objects": [{"type": "sphere", "radius": -1, "material": "m"}]}' > "$T/neg.json"
run_bad "negative radius" 3 "neg.json: objects\[0\].radius" --env "$T/env.hdr" --scene "$T/neg.json"
printf '{"materials": {"m": {"type": "lambert", "color": [0.5, NaN, 0.1]}}, "objects": []}' > "$T/nan.json"
run_bad "NaN in scene" 3 "nan.json" --env "$T/env.hdr" --scene "$T/nan.json"
printf '{"materials": {"m": {"type": "lambert", "color": [0.5, -0.2, 0.1]}}, "objects": [{"type": "sphere", "material": "m"}]}' > "$T/negc.json"
run_bad "negative colour" 3 "negc.json: materials.m.color" --env "$T/env.hdr" --scene "$T/negc.json"
run_bad "missing scene file" 3 "absent.json" --env "$T/env.hdr" --scene "$T/absent.json"
run_bad "bad strategy" 2 "strategy" --env "$T/env.hdr" --strategy magic
run_bad "bad material" 2 "material" --env "$T/env.hdr" --material gold
run_bad "env and rig" 2 "exactly one" --env "$T/env.hdr" --rig "$T/rig.json"
L='"direction": [0, 1, 0], "solid_angle": 0.1, "integral": [1, 1, 1]'
printf '{"version": 1, "dome": {"file": null}, "lights": [{"type": "rect", %s, "radiance": [1, 1, 1],
  "position": [0, 3, 0], "size": [1, 1], "texture": "missing_softbox.exr"}]}' "$L" > "$T/rig_tex.json"
run_bad "rig with missing texture" 3 "rig_tex.json: lights\[0\].texture.*missing_softbox.exr" --rig "$T/rig_tex.json"
printf '{"version": 1, "dome": {"file": null}, "lights": [{"type": "disk", %s, "radiance": [1, -1, 1],
  "position": null, "size": null, "texture": null}]}' "$L" > "$T/rig_neg.json"
run_bad "rig with negative radiance" 3 "rig_neg.json: lights\[0\].radiance" --rig "$T/rig_neg.json"
printf '{"version": 1, "lights": [], "dome": {"file": "gone.exr"}}' > "$T/rig_dome.json"
run_bad "rig with missing dome" 3 "rig_dome.json: dome.file.*gone.exr" --rig "$T/rig_dome.json"
printf '{"lights": [], "dome": {"file": "env.hdr"}}' > "$T/rig_old.json"
run_bad "rig without version 1" 3 "rig_old.json: version" --rig "$T/rig_old.json"
# The closed form: a grey ball under a uniform dome is exact inside (no
# samples there), --json and --stats say so; the shadow scene samples only the
# shadowed part; a chrome ball, a rig or --closed-form off are sampled.
"$S" render --env "$T/env.hdr" --scene grey --width 16 --spp 4 --json --stats "$T/cf.json" -o "$T/cf.exr" --quiet > "$T/cf_out.json"
check "closed form render" 0 $?
python3 - "$T/cf_out.json" "$T/cf.json" <<'PY' || { echo "FAIL closed form not reported: $(cat "$T/cf_out.json")"; fail=1; }
import json, sys
out, st = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
cf = out["closed_form"]
assert cf["used"] and cf["exact_pixels"] > 100 and cf["control_variate_pixels"] == 0, cf
assert cf["exact_pixels"] + cf["sampled_pixels"] == 256, cf
assert 0 < cf["max_rel_bound"] <= 0.02 and cf["tolerance"] == 0.01, cf
s = st["closed_form"]
assert s["used"] and s["objects"] == [0] and s["exact_pixels"] == cf["exact_pixels"], s
assert s["evaluations"] >= s["exact_pixels"] and s["cells"] > 0 and s["top_level"] >= s["finest_level"], s
assert st["camera_rays"] == 4 * s["sampled_pixels"], st
PY
"$S" render --env "$T/env.hdr" --scene shadow --width 16 --spp 4 --bounces 1 --json -o "$T/cfs.exr" --quiet > "$T/cfs.json"
check "closed form as control variate" 0 $?
python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["closed_form"]; sys.exit(0 if c["control_variate_pixels"] > 0 else 1)' "$T/cfs.json" || { echo "FAIL shadow: no control variate: $(cat "$T/cfs.json")"; fail=1; }
# no bounces: the shadowed part is computed, the shadowed pixels exact
"$S" render --env "$T/env.hdr" --scene shadow --width 16 --spp 4 --json -o "$T/cfs0.exr" --quiet > "$T/cfs0.json"
check "closed form with the shadowed part computed" 0 $?
python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["closed_form"]; sys.exit(0 if c["control_variate_pixels"] == 0 and c["exact_pixels"] > 100 else 1)' "$T/cfs0.json" || { echo "FAIL shadow: not exact: $(cat "$T/cfs0.json")"; fail=1; }
for args in "--scene chrome" "--scene grey --closed-form off"; do
    "$S" render --env "$T/env.hdr" $args --width 8 --spp 2 --json -o "$T/cfn.exr" --quiet > "$T/cfn.json"
    check "sampled: $args" 0 $?
    python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["closed_form"]; sys.exit(0 if not c["used"] and c["exact_pixels"] == 0 else 1)' "$T/cfn.json" || { echo "FAIL $args: closed form used: $(cat "$T/cfn.json")"; fail=1; }
done
# A rig's lights are in the closed form too: rig.json's sphere and distant light
# exact, the dome they may hide from the ball sampled (control variate).
"$S" render --rig "$T/rig.json" --scene grey --width 16 --spp 4 --json -o "$T/cfr.exr" --quiet > "$T/cfr.json"
check "rig closed form" 0 $?
python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["closed_form"]; sys.exit(0 if c["used"] and c["lights_exact"] == 2 and c["lights_sampled"] == 0 and c["control_variate_pixels"] > 0 else 1)' "$T/cfr.json" || { echo "FAIL rig closed form: $(cat "$T/cfr.json")"; fail=1; }
# The log says in words which dome cells the closed form used.
"$S" render --env "$T/env.hdr" --scene grey --width 16 --spp 4 -o "$T/cfl.exr" 2> "$T/cfl.log"
check "closed form log" 0 $?
grep "closed form:" "$T/cfl.log" | grep -q "dome cells of .*texel" && ! grep -q "mip levels" "$T/cfl.log" || { echo "FAIL closed form log: $(cat "$T/cfl.log")"; fail=1; }
"$S" render --env "$T/env.hdr" --closed-form maybe -o "$T/cfbad.exr" --quiet 2> "$T/cfbad.err"
check "bad --closed-form" 2 $?
[ "$(wc -l < "$T/cfbad.err")" = 1 ] && grep -q "closed-form" "$T/cfbad.err" || { echo "FAIL bad --closed-form message: $(cat "$T/cfbad.err")"; fail=1; }
noout "bad --closed-form" "$T/cfbad.exr"
exit $fail
