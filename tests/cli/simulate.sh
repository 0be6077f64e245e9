#!/bin/bash
# setlight simulate end to end: a small capture, its layout and JSON summary,
# and every bad input giving one message, the documented exit code and
# nothing written or overwritten.
. "$(dirname "$0")/lib.bash"
S="$SETLIGHT"

expect 0 "$S" simulate --help
for o in --scene --out --seed --size --zenith --response --curve --raw-bits --jitter --ghost --force; do out_has "$o"; done

# A real run: the night set at the tiny size (the small one runs in the demo).
expect 0 "$S" simulate --scene night --out "$T/night" --seed 3 --size tiny --json --quiet
json_ok "$T/out"
cp "$T/out" "$T/summary.json"
json_eval "$T/summary.json" 'd["frames"] == 21 and d["views"] == 3 and d["scene"] == "night" and d["probe_frames"] == 13'
for f in IMG_0022.jpg IMG_0028_linear.tif IMG_0034.tif; do present "$T/night/probes/$f"; done
present "$T/night/truth/probes.json"
for k in chrome grey chart; do present "$T/night/truth/probe_$k.exr"; done
json_eval "$T/night/truth/probes.json" '[p["kind"] for p in d["probes"]] == ["chrome", "grey", "chart"] and len(d["probes"][2]["chart"]["corners"]) == 4 and d["probes"][0]["ball"]["r_px"] > 10'
present "$T/night/capture.json"
# a folder named like a scene (an earlier run's --out, here the current directory's)
# does not hide the built-in scene
(cd "$T" && expect 0 "$S" simulate --scene night --out night2 --seed 3 --size tiny --quiet)
present "$T/night2/capture.json"
present "$T/night/truth/latlong.exr"
present "$T/night/truth/lights.json"
present "$T/night/truth/camera.json"
for f in IMG_0001.jpg IMG_0001.tif IMG_0001_linear.tif IMG_0021.jpg; do present "$T/night/hdri/$f"; done
json_eval "$T/night/truth/lights.json" 'len(d["lights"]) == 4 and all(l["integral_rgb"][1] > 0 for l in d["lights"])'
json_eval "$T/night/capture.json" 'len(d["frames"]) == 21 and d["frames"][0]["exposure_time_s"] < d["frames"][6]["exposure_time_s"]'
no_temp "$T"

# A measured film curve from the DoRF database, 12-bit raw.
if [ -f "$SETLIGHT_SHARED_DATA/crf/dorfCurves.txt" ]; then
    expect 0 "$S" simulate --scene exterior --out "$T/film" --size tiny --raw-bits 12 \
        --response "$SETLIGHT_SHARED_DATA/crf/dorfCurves.txt" --curve agfacolor-futura-100CDBlue
    json_eval "$T/film/truth/camera.json" 'd["response"]["name"] == "agfacolor-futura-100CDBlue" and d["raw_bits"] == 12'
    expect 3 "$S" simulate --scene exterior --out "$T/film2" --size tiny \
        --response "$SETLIGHT_SHARED_DATA/crf/dorfCurves.txt" --curve no-such-film
    err_has "no-such-film"
    absent "$T/film2"
else
    skip "DoRF curves absent"
fi
expect 2 "$S" simulate --scene exterior --out "$T/resp" --size tiny --response velvia
err_has "velvia"
absent "$T/resp"

# Refuses to overwrite a capture without --force; nothing changes.
before=$(md5sum "$T/night/capture.json" "$T/night/hdri/IMG_0001.jpg")
expect 2 "$S" simulate --scene night --out "$T/night" --seed 4 --size tiny
err_has "already holds a capture"
err_has "--force"
err_one_line
after=$(md5sum "$T/night/capture.json" "$T/night/hdri/IMG_0001.jpg")
if [ "$before" = "$after" ]; then ok; else bad "capture changed without --force"; fi
no_temp "$T"

# A folder holding other files is never used, even with --force.
mkdir -p "$T/photos" && echo mine > "$T/photos/keep.txt"
expect 2 "$S" simulate --scene stage --out "$T/photos" --force
err_has "photos"
[ "$(ls "$T/photos")" = "keep.txt" ] && ok || bad "photos folder was touched"

# Output folder that cannot be created: runtime failure, exit 1.
expect 1 "$S" simulate --scene stage --out /proc/setlight-nope/cap --size tiny
err_has "/proc/setlight-nope/cap"
err_one_line

# Usage errors.
expect 2 "$S" simulate --scene studio --out "$T/x1"
err_has "studio"
err_one_line
absent "$T/x1"
expect 2 "$S" simulate --out "$T/x2"
err_has "--scene"
expect 2 "$S" simulate --scene stage
err_has "--out"
expect 2 "$S" simulate --scene stage --out "$T/x3" --size huge
err_has "huge"
expect 2 "$S" simulate --scene stage --out "$T/x4" --seed -5
err_has "--seed"
expect 2 "$S" simulate --scene stage --out "$T/x5" --frobnicate
err_has "frobnicate"
expect 2 "$S" simulate --scene stage --out "$T/x6" --jitter 40
err_has "--jitter"
for d in x2 x3 x4 x5 x6; do absent "$T/$d"; done

# Malformed scene files: exit 3, the file and the problem named, no output.
printf '{"background": "dark", "lights": [}\n' > "$T/syntax.json"
printf '{"background": "dark", "lights": [{"type": "disk", "azimuth": "north", "elevation": 1, "diameter": 1, "kelvin": 3000, "luminance": 10}]}\n' > "$T/type.json"
printf '{"background": "dark", "lights": [{"type": "disk", "azimuth": 0, "elevation": 1, "diameter": -2, "kelvin": 3000, "luminance": 10}]}\n' > "$T/negative.json"
printf '{"background": "dark", "lights": [{"type": "disk", "azimuth": 0, "elevation": 1, "diameter": 1, "kelvin": 3000}]}\n' > "$T/missing.json"
for case in "syntax:JSON syntax error" "type:expected a number" "negative:diameter -2" "missing:missing field \"luminance\""; do
    f=${case%%:*}
    msg=${case#*:}
    expect 3 "$S" simulate --scene "$T/$f.json" --out "$T/out_$f"
    err_has "$f.json"
    err_has "$msg"
    err_one_line
    absent "$T/out_$f"
done
expect 3 "$S" simulate --scene "$T/absent.json" --out "$T/out_absent"
err_has "absent.json"
absent "$T/out_absent"
no_temp "$T"

finish
