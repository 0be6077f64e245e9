#!/usr/bin/env bash
# setlight merge and setlight response end to end: a synthetic PNG bracket
# (no EXIF, so --times), the exposure check, response files, and every bad
# input the merge issue names (exit code, message naming the frame, no output).
. "$(dirname "$0")/lib.bash"

# gen DIR PREFIX W H STOPS N BITS [VALUE [WELL]]: PNG frames of a smooth scene
# through a 1/2.2 gamma curve (or a flat VALUE; "-" for none), exposure doubling
# STOPS per frame; with WELL, a sensor's noise (WELL electrons at white, 3 of
# read noise, seeded).
gen() {
  python3 - "$@" <<'PY'
import math, struct, sys, zlib
d, prefix, w, h, stops, n, bits = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]), int(sys.argv[6]), int(sys.argv[7])
flat = float(sys.argv[8]) if len(sys.argv) > 8 and sys.argv[8] != "-" else None
well = float(sys.argv[9]) if len(sys.argv) > 9 else None
import random
rng = random.Random(7)
top = (1 << bits) - 1
def png(path, rows):
    def chunk(t, data):
        c = struct.pack(">I", len(data)) + t + data
        return c + struct.pack(">I", zlib.crc32(t + data) & 0xffffffff)
    raw = b"".join(b"\0" + r for r in rows)
    hdr = struct.pack(">IIBBBBB", w, h, bits, 2, 0, 0, 0)
    open(path, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", hdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
for k in range(n):
    gain = 2 ** (stops * (k - (n - 1) / 2))
    rows = []
    for y in range(h):
        vals = []
        for x in range(w):
            u, v = (x + 0.5) / w, (y + 0.5) / h
            lin = 2 ** (-6 + 10 * (0.6 * u + 0.4 * v))
            for c in range(3):
                e = lin * gain * (1 + 0.1 * c)
                if well:
                    e += rng.gauss(0, math.sqrt(e / well + (3 / well) ** 2))
                z = flat if flat is not None else min(1.0, max(e, 0.0)) ** (1 / 2.2)
                vals.append(int(round(z * top)))
        rows.append(struct.pack(">%d%s" % (len(vals), "B" if bits == 8 else "H"), *vals))
    png("%s/%s_%d.png" % (d, prefix, k), rows)
PY
}

gen "$T" br 64 32 2 3 8 || bad "fixture"
F=("$T/br_0.png" "$T/br_1.png" "$T/br_2.png")
TIMES=1/16,1/4,1

# --- help and usage
expect 0 "$SETLIGHT" merge --help; out_has "usage: setlight merge"
expect 0 "$SETLIGHT" response --help; out_has "usage: setlight response"
expect 2 "$SETLIGHT" merge "${F[@]}"; err_has "-o"; err_one_line
expect 2 "$SETLIGHT" merge -o "$T/x.exr" --times 1,2 "${F[@]}"; err_has "2 times for 3 frames"
expect 2 "$SETLIGHT" merge -o "$T/x.exr" --times 1,x,2 "${F[@]}"; err_has "--times"
expect 2 "$SETLIGHT" merge -o "$T/x.exr" --exposures maybe --times $TIMES "${F[@]}"; err_has "exif or data"
expect 2 "$SETLIGHT" response -o "$T/x.json" --mask m.exr "${F[@]}"; err_has "--mask"
absent "$T/x.exr"; absent "$T/x.json"

# --- a good merge, with JSON, the mask beside it, and clean values
expect 0 "$SETLIGHT" merge --json -o "$T/out.exr" --times $TIMES "${F[@]}"
json_ok "$T/out"
json_eval "$T/out" 'd["width"] == 64 and d["height"] == 32 and len(d["frames"]) == 3 and d["response"] == "debevec-malik"'
json_eval "$T/out" 'd["disagreeing_frames"] == 0 and d["mask"].endswith("out_clipped.exr")'
present "$T/out.exr"; present "$T/out_clipped.exr"; no_temp "$T"
# lossless PNG codes: only the clip code is saturated (JPEG: 0.95, below)
json_eval "$T/out" 'd["units"] == "relative" and d["weights"]["saturation"] == 1 and d["weights"]["noise_gain"] == 2e-5'
# the default saturation chosen from the frames still leaves room above --black
expect 2 "$SETLIGHT" merge -o "$T/x.exr" --black 0.9 --times $TIMES "${F[@]}"; err_has "too close to the saturation code 1"
absent "$T/x.exr"
# GNU order: options after and among the frames give the same merge; '--' ends options
expect 0 "$SETLIGHT" merge -o "$T/late.exr" "${F[@]}" --times $TIMES --json
json_eval "$T/out" 'len(d["frames"]) == 3 and d["disagreeing_frames"] == 0'; present "$T/late.exr"
expect 0 "$SETLIGHT" merge "${F[0]}" --times $TIMES "${F[1]}" -o "$T/among.exr" -- "${F[2]}"
present "$T/among.exr"
expect 0 "$SETLIGHT" merge --json --response robertson -o "$T/rob.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["response"] == "robertson" and d["disagreeing_frames"] == 0'
# The curve-shape prior: opt-in, named in the result; a wrong value is a usage error.
expect 0 "$SETLIGHT" merge --json --response-prior dorf -o "$T/prior.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["response"].startswith("debevec-malik, prior dorf")'
expect 2 "$SETLIGHT" merge --response-prior emor -o "$T/x.exr" --times $TIMES "${F[@]}"
err_has "--response-prior"; err_one_line; absent "$T/x.exr"
# Absolute units need EXIF f-number and ISO on every frame (PNG has none).
expect 3 "$SETLIGHT" merge --absolute -o "$T/abs.exr" --times $TIMES "${F[@]}"; err_has "br_0.png"; err_has "f-number"; err_one_line
absent "$T/abs.exr"
expect 2 "$SETLIGHT" response --absolute -o "$T/x.json" --times $TIMES "${F[@]}"; err_has "--absolute"
expect 0 "$SETLIGHT" info --json "$T/out.exr"
json_eval "$T/out" 'd["files"][0]["nan_count"] == 0 and d["files"][0]["inf_count"] == 0 and d["files"][0]["negative_count"] == 0'
json_eval "$T/out" 'd["files"][0]["envmap"] == "latlong"'

mkdir -p "$T/h1" "$T/h0"
# --- output encoding: half ZIP by default for 8-bit frames (values bounded
# by the shortest frame's white), --float / --half / --compression forced,
# recorded in --json and the EXR; the same pixels within half's rounding
expect 0 "$SETLIGHT" merge --json --response linear -o "$T/enc.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["encoding"]["pixels"] == "half" and d["encoding"]["compression"] == "zip" and abs(d["encoding"]["max_value"] - 4) < 1e-9'
expect 0 "$SETLIGHT" info --json "$T/enc.exr"
json_eval "$T/out" 'd["files"][0]["attributes"]["setlight:merge:encoding"].startswith("half, ZIP compression (half: values up to 4;")'
# a noise model too fine for half's rounding: float
expect 0 "$SETLIGHT" merge --json --noise 1e-9,1e-12 -o "$T/encn.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["encoding"]["pixels"] == "float" and "above a quarter" in d["encoding"]["why"]'
expect 0 "$SETLIGHT" merge --json --float --compression piz -o "$T/encf.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["encoding"]["pixels"] == "float" and d["encoding"]["compression"] == "piz" and d["encoding"]["why"] == "float as asked"'
expect 0 "$SETLIGHT" merge --json -o "$T/h1/enc.exr" --times $TIMES "${F[@]}"
expect 0 "$SETLIGHT" merge --json --half --compression rle -o "$T/ench.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["encoding"]["pixels"] == "half" and d["encoding"]["compression"] == "rle"'
json_eval "$T/out" 'd["frames_decoded_once"] == 3'
# where the time went: phases that add up to the merge's wall and CPU
json_eval "$T/out" '(lambda t, ph: abs(sum(t[p]["cpu"] for p in ph) - t["total"]["cpu"]) < 1e-6 and abs(sum(t[p]["wall"] for p in ph) - t["total"]["wall"]) < 1e-6 and t["write"]["cpu"] > 0 and t["process_cpu"] >= t["total"]["cpu"])(d["timing"], ["decode", "sample", "fit", "merge", "write", "align", "other"])'
expect 0 "$SETLIGHT" merge --json --hold-mb 0 -o "$T/h0/enc.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["frames_decoded_once"] == 0'
# frames held or decoded twice: the same file but for the mask path's h0/h1
[ "$(cmp -l "$T/h0/enc.exr" "$T/h1/enc.exr" | wc -l)" -le 1 ] && ok || bad "held and decoded-twice merges differ"
expect 2 "$SETLIGHT" merge --hold-mb -1 -o "$T/x.exr" --times $TIMES "${F[@]}"; err_has "--hold-mb"
expect 2 "$SETLIGHT" merge --compression lzw -o "$T/x.exr" --times $TIMES "${F[@]}"; err_has "piz, zip, rle or none"; err_one_line
absent "$T/x.exr"; no_temp "$T"

# --- linear response, no mask; frames in any order give the same answer
expect 0 "$SETLIGHT" merge --json --response linear --no-mask -o "$T/lin.exr" --times 1,1/16,1/4 "${F[2]}" "${F[0]}" "${F[1]}"
json_eval "$T/out" 'd["response"] == "linear" and d["mask"] is None and [f["rank"] for f in d["frames"]] == [2, 0, 1]'
absent "$T/lin_clipped.exr"

# --- deghost on a static bracket: a ghost mask with nothing in it
expect 0 "$SETLIGHT" merge --json --deghost -o "$T/dg.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["ghost_mask"].endswith("dg_ghost.exr") and d["ghost_pixels"] == 0'
present "$T/dg_ghost.exr"
expect 0 "$SETLIGHT" info --json "$T/dg_ghost.exr"
json_eval "$T/out" 'd["files"][0]["channel_stats"][0]["max"] == 0'
expect 2 "$SETLIGHT" response --deghost -o "$T/x.json" --times $TIMES "${F[@]}"; err_has "--deghost"

# --- the curve refined under the noise: setlight response by default, merge when asked
gen "$T" rf 256 128 2 5 8 - 4000 || bad "fixture"
R=("$T/rf_0.png" "$T/rf_1.png" "$T/rf_2.png" "$T/rf_3.png" "$T/rf_4.png")
RT=1/16,1/4,1,4,16
expect 0 "$SETLIGHT" response --json -o "$T/rf.json" --times $RT "${R[@]}"
json_eval "$T/out" 'd["response_refine"]["refined"] and d["source"] == "debevec-malik, refined"'
json_eval "$T/out" 'abs(d["linear_at_half"][1] / 0.5 ** 2.2 - 1) < 0.05 and d["response_refine"]["noise_gain"][0] == 0'
# the noise law it fitted: the fixture's 4000 electrons at white (gain 2.5e-4)
json_eval "$T/out" 'abs(d["response_refine"]["noise_gain"][1] / 2.5e-4 - 1) < 0.15'
expect 0 "$SETLIGHT" response --json --response-refine off -o "$T/rf_off.json" --times $RT "${R[@]}"
json_eval "$T/out" 'not d["response_refine"]["refined"] and d["response_refine"]["note"] == "not refined (not asked)"'
expect 0 "$SETLIGHT" merge --json -o "$T/rf.exr" --times $RT "${R[@]}"
json_eval "$T/out" 'not d["response_refine"]["refined"] and d["response"] == "debevec-malik"'
expect 0 "$SETLIGHT" merge --json --response-refine on -o "$T/rf_on.exr" --times $RT "${R[@]}"
json_eval "$T/out" 'd["response_refine"]["refined"] and d["response_refine"]["series"] >= 300'
expect 2 "$SETLIGHT" merge --response-refine maybe -o "$T/x.exr" --times $RT "${R[@]}"
err_has "--response-refine"; err_one_line; absent "$T/x.exr"
# too small a bracket to refine: the curve stands and the note says why
gen "$T" few 8 8 2 3 8 || bad "fixture"
expect 0 "$SETLIGHT" response --json -o "$T/small.json" --times $TIMES "$T/few_0.png" "$T/few_1.png" "$T/few_2.png"
json_eval "$T/out" 'not d["response_refine"]["refined"] and "too few" in d["response_refine"]["note"]'

# --- a response saved once and reused
expect 0 "$SETLIGHT" response --json -o "$T/crf.json" --times $TIMES "${F[@]}"
json_ok "$T/crf.json"
json_eval "$T/crf.json" 'd["format"] == "setlight-response" and len(d["inverse"]) == 3 and len(d["inverse"][0]) == d["nodes"]'
json_eval "$T/crf.json" 'all(b >= a for c in d["inverse"] for a, b in zip(c, c[1:])) and abs(d["inverse"][1][-1] - 1) < 1e-9'
# the gamma 2.2 curve: mid-grey code 0.5 is about 0.5^2.2 = 0.218 of white
json_eval "$T/out" 'abs(d["linear_at_half"][1] / 0.5 ** 2.2 - 1) < 0.05'
expect 0 "$SETLIGHT" merge --json --response "$T/crf.json" -o "$T/reuse.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["response"] == "crf.json"'
echo '{"format": "nope"}' >"$T/bad.json"
expect 3 "$SETLIGHT" merge --response "$T/bad.json" -o "$T/r2.exr" --times $TIMES "${F[@]}"
err_has "bad.json"; err_one_line; absent "$T/r2.exr"

# --- a time one stop off: named by the check; --exposures data fixes it
expect 0 "$SETLIGHT" merge --json -o "$T/lie.exr" --times 1/16,1/2,1 "${F[@]}"
json_eval "$T/out" 'd["disagreeing_frames"] == 1 and d["frames"][1]["disagrees"] and abs(d["frames"][1]["disagreement_stops"] + 1) < 0.15'
err_has "br_1.png"
expect 0 "$SETLIGHT" merge --json --exposures data -o "$T/lie2.exr" --times 1/16,1/2,1 "${F[@]}"
json_eval "$T/out" 'd["exposures"] == "data" and abs(d["frames"][1]["exposure"] / d["frames"][1]["exif_exposure"] - 0.5) < 0.05'

# --- bad inputs: exit code, message naming the frame, no output left
gen "$T" small 32 16 2 1 8 || bad "fixture"
gen "$T" deep 64 32 2 1 16 || bad "fixture"
gen "$T" tiny 1 1 2 2 8 || bad "fixture"
gen "$T" black 64 32 2 3 8 0 || bad "fixture"
gen "$T" white 64 32 2 3 8 1 || bad "fixture"
head -c 300 "${F[1]}" >"$T/cut.png"
check_bad() { # CODE NAMED ARGS...
  local code=$1 named=$2
  shift 2
  expect "$code" "$SETLIGHT" merge -o "$T/bad.exr" "$@"
  err_has "$named"; err_one_line; absent "$T/bad.exr"; absent "$T/bad_clipped.exr"; no_temp "$T"
}
check_bad 2 "br_0.png" --times 1 "${F[0]}"
check_bad 3 "small_0.png" --times $TIMES "${F[0]}" "$T/small_0.png" "${F[2]}"
check_bad 3 "br_2.png" --times 1,2,1 "${F[@]}"
check_bad 3 "br_0.png" "${F[@]}"
# A PNG cut short: libpng's own message goes into ours, on one line.
expect 3 "$SETLIGHT" merge -o "$T/bad.exr" --times $TIMES "${F[0]}" "$T/cut.png" "${F[2]}"
err_has "cut.png: truncated or corrupt"; err_one_line
absent "$T/bad.exr"; absent "$T/bad_clipped.exr"; no_temp "$T"
check_bad 3 "black_0.png" --times $TIMES "$T/black_0.png" "$T/black_1.png" "$T/black_2.png"
check_bad 3 "white_0.png" --times $TIMES "$T/white_0.png" "$T/white_1.png" "$T/white_2.png"
check_bad 3 "tiny_0.png" --times 1,2 "$T/tiny_0.png" "$T/tiny_1.png"
check_bad 3 "deep_0.png" --times $TIMES "${F[0]}" "${F[1]}" "$T/deep_0.png"
check_bad 3 "missing.png" --times 1,2 "${F[0]}" "$T/missing.png"
expect 3 "$SETLIGHT" response -o "$T/bad.json2" "${F[@]}"; err_has "br_0.png"; absent "$T/bad.json2"

# --- real brackets when present
M="${SETLIGHT_SHARED_DATA}/brackets/memorial"
if [ -d "$M" ]; then
  expect 0 "$SETLIGHT" merge --json -o "$T/memorial.exr" --times 1,1/2,1/4,1/8,1/16 \
    "$M/memorial0066.png" "$M/memorial0067.png" "$M/memorial0068.png" "$M/memorial0069.png" "$M/memorial0070.png"
  json_eval "$T/out" 'len(d["frames"]) == 5 and all(f["fitted_exposure"] > 0 for f in d["frames"])'
  expect 0 "$SETLIGHT" info --json "$T/memorial.exr"
  json_eval "$T/out" 'd["files"][0]["nan_count"] == 0 and d["files"][0]["negative_count"] == 0'
  # the whole scanned-film bracket: response refines by default, and where the
  # refinement cannot beat the first curve it says so and the first curve stands
  MT=32,16,8,4,2,1,1/2,1/4,1/8,1/16,1/32,1/64,1/128,1/256,1/512,1/1024
  expect 0 "$SETLIGHT" response --json -o "$T/mem.json" --times $MT "$M"/memorial00*.png
  json_eval "$T/out" '(d["source"] == "debevec-malik") == (not d["response_refine"]["refined"]) and d["response_refine"]["note"]'
  expect 0 "$SETLIGHT" response --json --response-refine off -o "$T/mem_off.json" --times $MT "$M"/memorial00*.png
  json_eval "$T/mem.json" 'd["source"].endswith("refined") or d["inverse"] == json.load(open("'"$T/mem_off.json"'"))["inverse"]'
else
  skip "brackets/memorial absent"
fi
R="${SETLIGHT_SHARED_DATA}/brackets/stack_room"
if [ -d "$R" ]; then
  expect 0 "$SETLIGHT" merge --json -o "$T/room.exr" "$R"/stack_room_exp_*.jpg
  json_eval "$T/out" 'len(d["frames"]) == 7 and d["frames"][0]["f_number"] == 4.5 and d["frames"][0]["iso"] == 200'
  json_eval "$T/out" 'd["weights"]["saturation"] == 0.95'
  # JPEG codes are not refined: asked for, the merge says so in a line
  expect 0 "$SETLIGHT" merge --json --response-refine on -o "$T/room_r.exr" "$R"/stack_room_exp_*.jpg
  err_has "not 8-bit lossless codes: not refined"
  json_eval "$T/out" 'not d["response_refine"]["refined"] and d["response"] == "debevec-malik"'
else
  skip "brackets/stack_room absent"
fi
finish
