#!/usr/bin/env bash
# setlight merge --align end to end: a small textured PNG bracket whose
# brightest frame was taken 3 px right and 2 px up; the shift is found,
# reported in --json and the EXR, and bad alignment options are refused.
. "$(dirname "$0")/lib.bash"

# frames k=0..2 (2 stops apart) of a blob texture: al_* with frame 2 moved by
# (3, -2), st_* not moved.
python3 - "$T" <<'PY' || bad "fixture"
import math, random, struct, sys, zlib
d = sys.argv[1]
w, h = 128, 96
rnd = random.Random(3)
blobs = [(rnd.uniform(-10, w + 10), rnd.uniform(-10, h + 10), rnd.uniform(2.5, 12), rnd.uniform(-2.5, 3))
         for _ in range(40)]
def png(path, rows):
    def chunk(t, data):
        c = struct.pack(">I", len(data)) + t + data
        return c + struct.pack(">I", zlib.crc32(t + data) & 0xffffffff)
    raw = b"".join(b"\0" + r for r in rows)
    hdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    open(path, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", hdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
sets = {"al": [(0, 0), (0, 0), (3, -2)], "st": [(0, 0)] * 3, "dk": [(0, 0)]}
for name, moves in sets.items():
  for k in range(len(moves)):
    dx, dy = moves[k]
    step = -5 if name == "dk" else k  # dk: 12 stops under al_1, black
    rows = []
    for y in range(h):
        vals = []
        for x in range(w):
            px, py = x + 0.5 - dx, y + 0.5 - dy
            l2 = -5 + 2 * px / w
            for bx, by, s, a in blobs:
                d2 = (px - bx) ** 2 + (py - by) ** 2
                if d2 < 16 * s * s:
                    l2 += a * math.exp(-d2 / (2 * s * s))
            lin = 2 ** (l2 + 2 * (step - 1))
            z = min(1.0, lin) ** (1 / 2.2)
            vals += [int(round(z * 255))] * 3
        rows.append(bytes(vals))
    png("%s/%s_%d.png" % (d, name, k), rows)
PY
F=("$T/al_0.png" "$T/al_1.png" "$T/al_2.png")
TIMES=1/16,1/4,1

# --- bad alignment options: usage errors, no output
expect 2 "$SETLIGHT" merge --align-max-shift -3 -o "$T/x.exr" --times $TIMES "${F[@]}"; err_has "--align-max-shift"; err_one_line
expect 2 "$SETLIGHT" merge --align-max-shift many -o "$T/x.exr" --times $TIMES "${F[@]}"; err_has "'many'"
expect 2 "$SETLIGHT" merge --align-max-angle 30 -o "$T/x.exr" --times $TIMES "${F[@]}"; err_has "at most 10"
expect 2 "$SETLIGHT" response --align=never -o "$T/x.json" --times $TIMES "${F[@]}"; err_has "--align is auto, on or off"; err_one_line
absent "$T/x.exr"; absent "$T/x.json"

# --- the shift is found and reported
expect 0 "$SETLIGHT" merge --align --json -o "$T/out.exr" --times $TIMES "${F[@]}"
json_ok "$T/out"
json_eval "$T/out" 'd["frames"][1]["align"]["note"] == "reference"'
json_eval "$T/out" 'abs(d["frames"][2]["align"]["dx"] - 3) < 0.25 and abs(d["frames"][2]["align"]["dy"] + 2) < 0.25'
json_eval "$T/out" 'd["frames"][2]["align"]["applied"] and abs(d["frames"][2]["align"]["angle_deg"]) < 0.1'
json_eval "$T/out" 'abs(d["frames"][0]["align"]["dx"]) < 0.25 and abs(d["frames"][0]["align"]["dy"]) < 0.25'
err_has "al_2.png: shift +3."
present "$T/out.exr"; no_temp "$T"
expect 0 "$SETLIGHT" info --json "$T/out.exr"
out_has "setlight:merge:align"
out_has "al_2.png dx=3."
# --align off (or =off): nothing measured, merged as shot; "off" is no frame
for off in "--align off" "--align=off"; do
  expect 0 "$SETLIGHT" merge --json -o "$T/plain.exr" $off --times $TIMES "${F[@]}"
  json_eval "$T/out" '"align" not in d["frames"][2] and len(d["frames"]) == 3'
  json_eval "$T/out" 'd["align"]["mode"] == "off" and not d["align"]["aligned"] and d["align"]["misalignment_px"] is None'
  err_has "shifts (px) not measured (merged as shot)"
done

# --- auto (the default): the moved frame is measured, registered and said so
expect 0 "$SETLIGHT" merge --json -o "$T/auto.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["align"]["mode"] == "auto" and d["align"]["aligned"] and abs(d["align"]["misalignment_px"] - 3.6) < 0.3'
json_eval "$T/out" 'd["frames"][2]["align"]["applied"] and abs(d["frames"][2]["align"]["dx"] - 3) < 0.25 and abs(d["frames"][2]["align"]["dy"] + 2) < 0.25'
json_eval "$T/out" '0 <= d["align"]["measure_cpu_seconds"] <= d["align"]["cpu_seconds"] and d["timing"]["align"]["cpu"] > 0'
err_has "frames registered before merging: auto: al_2.png moved 3."
err_has "--align=off merges them as shot"
err_has " ref +3."; err_has "shifts (px) "
err_has "(aligned)"
expect 0 "$SETLIGHT" info --json "$T/auto.exr"
out_has "auto: al_2.png moved 3."
out_has "al_2.png dx=3."
# --align auto (space) is the same; --align=auto too
expect 0 "$SETLIGHT" merge --json -o "$T/auto2.exr" --align auto --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["align"]["mode"] == "auto" and d["align"]["aligned"] and len(d["frames"]) == 3'

# --- auto on frames that did not move: measured, not registered, no warning
S=("$T/st_0.png" "$T/st_1.png" "$T/st_2.png")
expect 0 "$SETLIGHT" merge --json --align=auto -o "$T/still.exr" --times $TIMES "${S[@]}"
json_eval "$T/out" 'not d["align"]["aligned"] and 0 <= d["align"]["misalignment_px"] < 0.5'
json_eval "$T/out" 'all(not f["align"]["applied"] and abs(f["align"]["dx"]) < 0.25 and abs(f["align"]["dy"]) < 0.25 for f in d["frames"])'
err_has "(merged as shot)"
if grep -q warning "$T/err"; then bad "warning on still frames: $(cat "$T/err")"; else ok; fi
expect 0 "$SETLIGHT" info --json "$T/still.exr"
out_has "auto: frames within 0."

# --- a black frame cannot be measured: said so, and where it was put
expect 0 "$SETLIGHT" merge --json --align=on -o "$T/dark.exr" --times 1/1024,$TIMES "$T/dk_0.png" "${F[@]}"
json_eval "$T/out" 'd["frames"][0]["align"]["refused"] and "too few" in d["frames"][0]["align"]["note"]'
json_eval "$T/out" 'd["frames"][0]["align"]["dx"] == d["frames"][1]["align"]["dx"]'
err_has "warning: $T/dk_0.png: 0 pixels well exposed in both frames (too few): not aligned; left where its neighbour in exposure is (shift +0."

# --- a mode that is none: usage error, one line, no output
expect 2 "$SETLIGHT" merge --align=sometimes -o "$T/bad.exr" --times $TIMES "${F[@]}"
err_has "--align is auto, on or off, not 'sometimes'"; err_one_line
absent "$T/bad.exr"; no_temp "$T"
# the response command measures too
expect 0 "$SETLIGHT" response --json --align=off -o "$T/crf.json" --times $TIMES "${F[@]}"
json_eval "$T/out" 'd["align"]["mode"] == "off"'

finish
