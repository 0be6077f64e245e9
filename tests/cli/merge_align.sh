#!/usr/bin/env bash
# setlight merge --align end to end: a small textured PNG bracket whose
# brightest frame was taken 3 px right and 2 px up; the shift is found,
# reported in --json and the EXR, and bad alignment options are refused.
. "$(dirname "$0")/lib.bash"

# gen DIR: frames k=0..2 (2 stops apart) of a blob texture; frame 2 moved by (3, -2).
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
moves = [(0, 0), (0, 0), (3, -2)]
for k in range(3):
    dx, dy = moves[k]
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
            lin = 2 ** (l2 + 2 * (k - 1))
            z = min(1.0, lin) ** (1 / 2.2)
            vals += [int(round(z * 255))] * 3
        rows.append(bytes(vals))
    png("%s/al_%d.png" % (d, k), rows)
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
# without --align there is no alignment in the JSON
expect 0 "$SETLIGHT" merge --json -o "$T/plain.exr" --times $TIMES "${F[@]}"
json_eval "$T/out" '"align" not in d["frames"][2]'

finish
