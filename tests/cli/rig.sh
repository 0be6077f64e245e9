#!/usr/bin/env bash
# setlight rig end to end: outputs, --json summary and rig.json, median cut,
# and every bad input the lightrig issue names (exit code, one-line message
# naming the file, no output left behind).
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" sun "$T/sun.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/smooth.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" nan "$T/nan.pfm" 64 32 || bad "fixture"
"$MAKE_FIXTURE" wide "$T/wide.exr" 96 || bad "fixture"
# A black map and a stage with two panels, written as PFM (no envmap attribute).
python3 - "$T" <<'PY'
import math, struct, sys
t = sys.argv[1]
def pfm(path, w, h, f):
    with open(path, "wb") as o:
        o.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        for y in range(h - 1, -1, -1):
            row = []
            for x in range(w):
                row += f(x, y, w, h)
            o.write(struct.pack("<%df" % len(row), *row))
pfm(t + "/black.pfm", 64, 32, lambda x, y, w, h: [0.0, 0.0, 0.0])
def stage(x, y, w, h):
    if 100 <= x < 120 and 60 <= y < 70: return [50.0, 50.0, 50.0]
    if 300 <= x < 310 and 40 <= y < 50: return [80.0, 60.0, 40.0]
    return [0.5, 0.5, 0.5]
pfm(t + "/stage.pfm", 512, 256, stage)
# a panel graded 10..100 left to right (a window): variation about 0.45
def graded(x, y, w, h):
    if 100 <= x < 140 and 60 <= y < 80: v = 10 + 90 * (x - 100) / 39.0; return [v, v, v]
    return [0.5, 0.5, 0.5]
pfm(t + "/graded.pfm", 512, 256, graded)
PY
"$SETLIGHT" convert --float "$T/stage.pfm" "$T/stage.exr" || bad "convert stage"
"$SETLIGHT" convert --float "$T/graded.pfm" "$T/graded.exr" || bad "convert graded"

# --- help and a good run
expect 0 "$SETLIGHT" rig --help; out_has "usage: setlight rig"; out_has "--max-lights"
expect 0 "$SETLIGHT" --help; out_has "rig"
mkdir -p "$T/o" "$T/bad"
expect 0 "$SETLIGHT" rig --json "$T/stage.exr" -o "$T/o/stage.usda" --json "$T/o/stage.json" \
  --preview "$T/o/stage.png" --energy 1
present "$T/o/stage.usda"; present "$T/o/stage_residual.exr"; present "$T/o/stage.json"
present "$T/o/stage.png"; no_temp "$T/o"
json_ok "$T/out"
json_eval "$T/out" 'd["lights"] == 2 and d["relative_error"] < 1e-3 and d["rig"]["version"] == 2'
json_eval "$T/o/stage.json" 'd["version"] == 2 and len(d["lights"]) == 2 and d["ledger"]["relative_error"] < 1e-3'
json_eval "$T/o/stage.json" 'set(d) == {"version", "lights", "dome", "ledger", "skipped"} and d["dome"]["file"] == "stage_residual.exr"'
json_eval "$T/o/stage.json" 'all(set(l) == {"type","direction","solid_angle","radiance","integral","position","size","texture","textured","texture_variation","texture_reason","axis_u","angular_size","share","share_glossy"} for l in d["lights"])'
# uniform panels: no texture by default, and the reason says why
json_eval "$T/o/stage.json" 'all(not l["textured"] and l["texture"] is None and l["texture_variation"] < 0.05 and l["texture_reason"].startswith("uniform") for l in d["lights"])'
[ -z "$(ls "$T/o" | grep _light_)" ] && ok || bad "uniform panels got textures: $(ls "$T/o")"
json_eval "$T/o/stage.json" 'all(abs(sum(v*v for v in l["direction"]) - 1) < 1e-9 and l["position"] is None for l in d["lights"])'
# ledger: lights + dome = original per channel
json_eval "$T/o/stage.json" 'all(abs(d["ledger"]["lights"][c] + d["ledger"]["dome"][c] - d["ledger"]["original"][c]) <= 1e-3 * d["ledger"]["original"][c] for c in range(3))'
if grep -q 'def DomeLight "dome"' "$T/o/stage.usda" && grep -q '@stage_residual.exr@' "$T/o/stage.usda" &&
  [ "$(grep -c 'def RectLight\|def DistantLight' "$T/o/stage.usda")" -eq 2 ]; then ok; else bad "usda content"; fi
expect 0 "$SETLIGHT" info --json "$T/o/stage_residual.exr"
json_eval "$T/out" 'd["files"][0]["envmap"] == "latlong" and d["files"][0]["nan_count"] == 0'
# the dome no longer holds the panels
json_eval "$T/out" 'd["files"][0]["channel_stats"][0]["max"] < 5'

# --- validation renders (the two panels are uniform rects: the rig is close to the map)
mkdir -p "$T/v"
expect 0 "$SETLIGHT" rig --json "$T/stage.exr" -o "$T/v/stage.usda" --energy 1 --validate=16
cp "$T/out" "$T/v.json"
json_eval "$T/v.json" 'd["validation"]["spp"] == 16 and d["validation"]["width"] == 96 and all(0 <= d["validation"][k] < 0.2 for k in ("grey", "chrome", "shadow"))'
json_eval "$T/v.json" 'd["validation"]["report"].endswith("/v/stage.validate.html") and all(d["validation"]["render_seconds"][k]["map"] > 0 and d["validation"]["render_seconds"][k]["rig"] > 0 for k in ("grey", "chrome", "shadow"))'
err_has "validation report: $T/v/stage.validate.html"
# the temporary rig.json for the renderer is gone; the report is the page and its folder
if [ "$(ls -A "$T/v" | tr '\n' ' ')" = "stage.usda stage.validate stage.validate.html stage_residual.exr " ]; then ok
else bad "validate left files: $(ls -A "$T/v")"; fi
# check_report DIR NAME SPP JSON: every image of the page exists and is a whole PNG of the
# right size (renders 96x96, shadow 96x72, the preview the map's 512x256, enlarged to
# >= 256 px wide); the numbers in
# the page are those in the --json summary; the renders are kept as EXR.
check_report() {
  python3 - "$@" <<'PY'
import json, re, struct, sys, zlib
d, name, spp, summary = sys.argv[1], sys.argv[2], int(sys.argv[3]), json.load(open(sys.argv[4]))
page = open(f"{d}/{name}.html").read()
def png_size(path):
    b = open(path, "rb").read()
    assert b[:8] == b"\x89PNG\r\n\x1a\n", path
    i, idat, size = 8, b"", None
    while i < len(b):
        n, kind = struct.unpack(">I4s", b[i:i + 8])
        body = b[i + 8:i + 8 + n]
        assert zlib.crc32(kind + body) == struct.unpack(">I", b[i + 8 + n:i + 12 + n])[0], path
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
            depth, colour = body[8], body[9]
        elif kind == b"IDAT":
            idat += body
        i += 12 + n
        if kind == b"IEND":
            break
    assert kind == b"IEND" and i == len(b), path
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    w, h = size
    assert len(zlib.decompress(idat)) == h * (1 + w * channels * depth // 8), path
    return size
want = {"diff_scale": (256, 16), "preview": (512, 256)}
for s in ("grey", "chrome", "shadow"):
    for k in ("map", "rig", "diff"):
        want[f"{s}_{k}"] = (96, 72) if s == "shadow" else (96, 96)
srcs = re.findall(r'<img src="([^"]+)"', page)
assert sorted(srcs) == sorted(f"{name}/{k}.png" for k in want), srcs
# the report enlarges images under 256 px wide by whole pixels to >= 256
want = {k: (w * -(-256 // w), h * -(-256 // w)) for k, (w, h) in want.items()}
for k, size in want.items():
    assert png_size(f"{d}/{name}/{k}.png") == size, (k, png_size(f"{d}/{name}/{k}.png"))
v = summary["validation"]
for s in ("grey", "chrome", "shadow"):
    m = re.search(rf"<tr><td>{s}</td><td>([0-9.]+)</td><td>([0-9]+)</td><td>(\d+)x(\d+)</td>", page)
    assert m and abs(float(m.group(1)) - 100 * v[s]) <= 0.0005 + 1e-9, (s, m and m.group(1), v[s])
    assert int(m.group(2)) == spp == v["spp"], s
    assert f"relative RMSE {m.group(1)}%" in page, s
    n = re.search(rf"<tr><td>{s}</td>(?:<td>[^<]*</td>){{5}}<td>([0-9.]+)</td><td>([0-9.]+)</td></tr>", page)
    assert n and abs(float(n.group(1)) - 100 * v["noise"][s]) <= 0.0005 + 1e-9, s
    assert abs(float(n.group(2)) - 100 * v["beyond_noise"][s]) <= 0.0005 + 1e-9, s
    assert 0 < v["noise"][s] and v["beyond_noise"][s] <= v[s], s
for s in ("grey", "chrome", "shadow"):
    for k in ("map", "rig"):
        assert open(f"{d}/{name}/{s}_{k}.exr", "rb").read(4) == b"\x76\x2f\x31\x01", (s, k)
PY
}
if check_report "$T/v" stage.validate 16 "$T/v.json"; then ok; else bad "validation report"; fi
expect 0 "$SETLIGHT" info --json "$T/v/stage.validate/shadow_rig.exr"
json_eval "$T/out" 'd["files"][0]["width"] == 96 and d["files"][0]["height"] == 72 and d["files"][0]["nan_count"] == 0'
# a second run replaces the report whole (its old folder and page gone, nothing temporary)
touch "$T/v/stage.validate/stale.png"
expect 0 "$SETLIGHT" rig --json "$T/stage.exr" -o "$T/v/stage.usda" --energy 1 --validate=8
cp "$T/out" "$T/v.json"
if check_report "$T/v" stage.validate 8 "$T/v.json"; then ok; else bad "replaced validation report"; fi
absent "$T/v/stage.validate/stale.png"; no_temp "$T/v"
if [ "$(ls -A "$T/v" | tr '\n' ' ')" = "stage.usda stage.validate stage.validate.html stage_residual.exr " ]; then ok
else bad "second validate left files: $(ls -A "$T/v")"; fi
expect 2 "$SETLIGHT" rig "$T/stage.exr" -o "$T/v/x.usda" --validate=0
[ ! -e "$T/v/x.usda" ] && ok || bad "--validate=0 wrote output"
# the report cannot replace a file named like its folder (or a folder named like its
# page): exit 2 before anything is written
mkdir -p "$T/vb" "$T/vc/r.validate.html"
echo keep >"$T/vb/r.validate"
expect 2 "$SETLIGHT" rig "$T/stage.exr" -o "$T/vb/r.usda" --validate=8; err_has "r.validate"; err_one_line
[ "$(ls -A "$T/vb")" = "r.validate" ] && ok || bad "blocked report left files: $(ls -A "$T/vb")"
expect 2 "$SETLIGHT" rig "$T/stage.exr" -o "$T/vc/r.usda" --validate=8; err_has "r.validate.html"
[ "$(ls -A "$T/vc")" = "r.validate.html" ] && ok || bad "blocked report left files: $(ls -A "$T/vc")"

# --- positions in a room; median cut
expect 0 "$SETLIGHT" rig --json "$T/stage.exr" -o "$T/o/room.usda" --json "$T/o/room.json" \
  --room 8,6,4 --capture-height 1.5 --energy 1
json_eval "$T/o/room.json" 'all(l["position"] is not None and l["size"] is not None for l in d["lights"])'
expect 0 "$SETLIGHT" rig "$T/stage.exr" -o "$T/o/tex.usda" --json "$T/o/tex.json" \
  --distance 4 --energy 1 --textures
present "$T/o/tex_light_01.exr"
json_eval "$T/o/tex.json" 'd["lights"][0]["texture"] == "tex_light_01.exr"'
if grep -q '@tex_light_01.exr@' "$T/o/tex.usda"; then ok; else bad "usda lacks the texture"; fi
json_eval "$T/o/tex.json" 'all(l["textured"] and l["texture_reason"].startswith("textures forced") for l in d["lights"])'
if grep -q 'def RectLight' "$T/o/room.usda"; then ok; else bad "room rig has no RectLight"; fi

# --- automatic textures: the graded panel gets one, --no-textures turns that off
mkdir -p "$T/g"
expect 0 "$SETLIGHT" rig "$T/graded.exr" -o "$T/g/auto.usda" --json "$T/g/auto.json" --energy 1
err_has "light 1 (rect): textured, graded"
present "$T/g/auto_light_01.exr"
json_eval "$T/g/auto.json" 'len(d["lights"]) == 1 and d["lights"][0]["textured"] and d["lights"][0]["texture"] == "auto_light_01.exr" and 0.3 < d["lights"][0]["texture_variation"] < 0.7'
if grep -q '@auto_light_01.exr@' "$T/g/auto.usda"; then ok; else bad "usda lacks the texture"; fi
expect 0 "$SETLIGHT" rig "$T/graded.exr" -o "$T/g/off.usda" --json "$T/g/off.json" --energy 1 --no-textures
json_eval "$T/g/off.json" 'not d["lights"][0]["textured"] and d["lights"][0]["texture_reason"].startswith("textures off")'
[ ! -e "$T/g/off_light_01.exr" ] && ok || bad "--no-textures wrote a texture"
expect 2 "$SETLIGHT" rig "$T/graded.exr" -o "$T/g/x.usda" --textures --no-textures
err_has "--no-textures"; err_one_line
[ ! -e "$T/g/x.usda" ] && ok || bad "conflicting options wrote output"
expect 0 "$SETLIGHT" rig --json --method mediancut --max-lights 8 "$T/stage.exr" -o "$T/o/mc.usda"
json_eval "$T/out" 'd["lights"] == 8 and d["method"] == "mediancut" and d["relative_error"] < 1e-6'

# --- artist tags: the panel around column 305, row 45 of 512x256 is at latitude 58, longitude -35
expect 0 "$SETLIGHT" rig --json "$T/stage.exr" -o "$T/o/tags.usda" --energy 1 --exclude 58,-35
json_eval "$T/out" 'd["lights"] == 1 and d["skipped"] == 1 and "--exclude" in d["rig"]["skipped"][0]["reason"]'
expect 2 "$SETLIGHT" rig --include 100,0 "$T/stage.exr" -o "$T/bad/a.usda"; err_has "--include"; err_one_line
expect 2 "$SETLIGHT" rig --exclude 10 "$T/stage.exr" -o "$T/bad/a.usda"; err_has "--exclude"

# --- a sun (one texel at 1e5): a distant light
expect 0 "$SETLIGHT" rig --json "$T/sun.exr" -o "$T/o/sun.usda"
json_eval "$T/out" 'd["lights"] == 1 and d["rig"]["lights"][0]["type"] == "distant"'

# --- black map: empty rig, clear message, exit 0 (a PFM has no envmap attribute:
# 2:1, taken as a lat-long with a note)
expect 0 "$SETLIGHT" rig --json "$T/black.pfm" -o "$T/o/black.usda"
err_has "black.pfm: no envmap attribute; 64x32 is 2:1, taken as a lat-long"
err_has "black"; json_eval "$T/out" 'd["lights"] == 0 and d["black"]'
present "$T/o/black.usda"

# --- NaN/Inf: counted, excluded, reported (--assume-latlong: accepted, no effect)
expect 0 "$SETLIGHT" rig --json --assume-latlong "$T/nan.pfm" -o "$T/o/nan.usda"
err_has "nan.pfm"; err_has "3 NaN/Inf"; json_eval "$T/out" 'd["nonfinite"] == 3'

# --- bad inputs: exit code, one line naming the file or option, no output
mkdir -p "$T/bad"
expect 3 "$SETLIGHT" rig "$T/missing.exr" -o "$T/bad/a.usda"; err_has "missing.exr"; err_one_line
expect 3 "$SETLIGHT" rig "$T/wide.exr" -o "$T/bad/a.usda"; err_has "wide.exr"; err_has "2:1"; err_one_line
expect 2 "$SETLIGHT" rig --max-lights 0 "$T/stage.exr" -o "$T/bad/a.usda"; err_has "--max-lights"; err_one_line
expect 2 "$SETLIGHT" rig --room 8,6,2 --capture-height 2.5 "$T/stage.exr" -o "$T/bad/a.usda"
err_has "does not contain the capture point"; err_one_line
expect 2 "$SETLIGHT" rig --room 8,6,4 "$T/stage.exr" -o "$T/bad/a.usda"; err_has "--capture-height"
expect 2 "$SETLIGHT" rig --energy 1.5 "$T/stage.exr" -o "$T/bad/a.usda"; err_has "--energy"
expect 2 "$SETLIGHT" rig --method mediancut "$T/stage.exr" -o "$T/bad/a.usda"; err_has "--max-lights"
expect 2 "$SETLIGHT" rig "$T/stage.exr" -o "$T/bad/a.usd"; err_has ".usda"
expect 2 "$SETLIGHT" rig "$T/stage.exr"; err_has "-o"
expect 2 "$SETLIGHT" rig "$T/stage.exr" -o "$T/nosuchdir/a.usda"; err_has "nosuchdir"
# a missing folder for the last output: nothing written, not even the first
expect 2 "$SETLIGHT" rig "$T/stage.exr" -o "$T/bad/a.usda" --preview "$T/nosuchdir/p.png"
err_has "nosuchdir"; err_one_line
if [ "$(ls -A "$T/bad")" = "" ]; then ok; else bad "output left in $T/bad: $(ls -A "$T/bad")"; fi

finish
