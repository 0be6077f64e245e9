#!/usr/bin/env bash
# Builds the fuzz targets' seed corpora from what the project makes itself:
# small images written by oiiotool and by setlight, setlight's own JSON
# outputs (rig, response, capture journal), and the formats' examples from
# the docs and tests. Nothing from ../shared/data.
#   fuzz/seed.sh SETLIGHT [OUT]     (OUT: fuzz/corpus)
# Every seed stays under 20 KB: libFuzzer mutates small inputs fastest.
set -euo pipefail
S=${1:?usage: fuzz/seed.sh path/to/setlight [OUT]}
S=$(realpath "$S")
cd "$(dirname "$0")"
OUT=$(realpath -m "${2:-corpus}")
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
for t in exr hdr photo ingest scene_json vset_scene rig_json journal response_json response_text \
         chart_reference job_graph; do
  rm -rf "${OUT:?}/$t"
  mkdir -p "$OUT/$t"
done

# --- images: a small gradient with HDR values above 1
oiiotool --pattern fill:topleft=0.02,0.05,0.1:topright=4,2,1:bottomleft=0.5,0.4,0.3:bottomright=20,10,5 \
  16x8 3 -d float -o "$T/grad.exr"
oiiotool "$T/grad.exr" --ch R,G,B,A=1.0 -d float -o "$T/grad4.exr"
e="$OUT/exr"
# setlight's own writer: ZIP, RLE, PIZ, uncompressed (half and float) through convert
"$S" convert --quiet "$T/grad.exr" "$e/setlight_zip_half.exr"
for c in none rle zip zips piz pxr24 b44 b44a dwaa; do
  oiiotool "$T/grad.exr" -d half --compression "$c" -o "$e/rgb_${c}_half.exr"
done
for c in none zip piz; do
  oiiotool "$T/grad.exr" -d float --compression "$c" -o "$e/rgb_${c}_float.exr"
  oiiotool "$T/grad4.exr" -d half --compression "$c" -o "$e/rgba_${c}_half.exr"
done
oiiotool "$T/grad.exr" -d half --tile 8 8 --compression zip -o "$e/rgb_tiled_zip.exr"
oiiotool "$T/grad.exr" -d half --tile 8 8 --compression piz -o "$e/rgb_tiled_piz.exr"
oiiotool "$T/grad.exr" --ch Y=G -d half --compression zip -o "$e/y_zip.exr"
oiiotool "$T/grad.exr" --ch diffuse.R=R,diffuse.G=G,diffuse.B=B -d half --compression zip \
  -o "$e/layer_zip.exr"
oiiotool "$T/grad.exr" --attrib envmap latlong --attrib "setlight:inputs" "seed" -d half \
  --compression zip -o "$e/latlong_attrs.exr"
# data window inside a larger display window
oiiotool "$T/grad.exr" --fullsize 32x16+0+0 --origin +4+2 -d half -o "$e/datawindow.exr"
# a channel setlight does not pick (a render's depth): OpenEXR 3.1's
# unpackers once wrote through the NULL pointer core/exr.c gave it
for c in zip piz rle; do
  oiiotool "$T/grad.exr" --ch R,G,B,Z=G -d half --compression "$c" -o "$e/rgbz_${c}_half.exr"
done

h="$OUT/hdr"
oiiotool "$T/grad.exr" -o "$h/grad_16x8.hdr"    # run-length rows (8 <= width)
oiiotool "$T/grad.exr" --resize 4x2 -o "$h/flat_4x2.hdr"
oiiotool "$T/grad.exr" --resize 32x16 -o "$h/latlong_32x16.hdr"

p="$OUT/photo"
oiiotool "$T/grad.exr" --resize 16x16 --colorconvert linear sRGB -d uint8 \
  --attrib Exif:ExposureTime 0.01 --attrib Exif:FNumber 8 --attrib Exif:PhotographicSensitivity 100 \
  --attrib Make setlight --attrib Model seed -o "$p/exif.jpg"
oiiotool "$T/grad.exr" --colorconvert linear sRGB -d uint8 -o "$p/rgb8.png"
oiiotool "$T/grad.exr" --colorconvert linear sRGB -d uint16 -o "$p/rgb16.png"
oiiotool "$T/grad4.exr" -d uint8 -o "$p/rgba8.png"
oiiotool "$T/grad.exr" --ch G -d uint8 -o "$p/grey8.png"
oiiotool "$T/grad.exr" --colorconvert linear sRGB -d uint8 -o "$p/rgb8.tif"
oiiotool "$T/grad.exr" -d uint16 --compression lzw -o "$p/rgb16_lzw.tif"
oiiotool "$T/grad.exr" -d float -o "$p/float.tif"
oiiotool "$T/grad.exr" --ch G -d uint8 -o "$p/grey8.jpg"
# --- render scene files (docs/render.md)
cat > "$OUT/scene_json/full.json" <<'J'
{
  "preset": "grey",
  "materials": {
    "red":   {"type": "lambert", "color": [0.5, 0.05, 0.05]},
    "gold":  {"type": "conductor", "reflectance": [1.0, 0.78, 0.34], "edge_tint": [1, 1, 1], "roughness": 0.2},
    "ball":  {"type": "chrome"},
    "toy":   {"type": "plastic", "color": [0.1, 0.2, 0.6], "ior": 1.5, "roughness": 0.3}
  },
  "objects": [
    {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "red"},
    {"type": "rect", "center": [0, -1, 0], "u": [0, 0, 4], "v": [4, 0, 0], "material": "red"},
    {"type": "disk", "center": [0, 2, 0], "normal": [0, -1, 0], "radius": 0.5, "material": "gold"}
  ],
  "camera": {"type": "perspective", "position": [0, 1, -6], "look_at": [0, 0, 0], "up": [0, 1, 0],
             "fov": 40, "aspect": 0.75},
  "background": "env"
}
J
cat > "$OUT/scene_json/fisheye.json" <<'J'
{"objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": "m"}],
 "materials": {"m": {"type": "lambert", "color": [0.18, 0.18, 0.18]}},
 "camera": {"type": "fisheye", "position": [0, 0, -3], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 180}}
J
cat > "$OUT/scene_json/ortho.json" <<'J'
{"preset": "chart", "camera": {"type": "orthographic", "position": [0, 0, -5], "look_at": [0, 0, 0],
 "up": [0, 1, 0], "width": 3, "aspect": 1}}
J

# --- virtual-set scenes (docs/virtual-set.md)
cat > "$OUT/vset_scene/alley.json" <<'J'
{
  "name": "alley",
  "background": "dark",
  "dark_luminance": 0.01,
  "lights": [
    {"type": "disk", "name": "lamp", "azimuth": 10, "elevation": 20,
     "diameter": 0.5, "kelvin": 2700, "luminance": 1e5},
    {"type": "rect", "azimuth": -30, "elevation": 5, "width": 4, "height": 2,
     "roll": 15, "rgb": [1, 0.2, 0.1], "luminance": 500},
    {"type": "window", "azimuth": 90, "elevation": 0, "width": 20, "height": 30,
     "transmission": 0.8},
    {"type": "sun", "azimuth": 60, "elevation": 35}
  ]
}
J
cat > "$OUT/vset_scene/sky.json" <<'J'
{"name": "field", "background": "sky", "turbidity": 3, "ground_albedo": 0.2,
 "sun_azimuth": 40, "sun_elevation": 30, "lights": [{"type": "sun", "azimuth": 40, "elevation": 30, "diameter": 0.53}]}
J
cat > "$OUT/vset_scene/room.json" <<'J'
{"background": "room", "room_illuminance": 300, "lights": [
 {"type": "window", "azimuth": 0, "elevation": 10, "width": 30, "height": 20, "roll": 5}]}
J

# --- a rig from setlight rig (version 2) on a small lat-long with a sun
oiiotool --pattern constant:color=5000,4800,4500 2x2 3 \
  --pattern constant:color=0.3,0.35,0.4 64x32 3 --paste +40+8 \
  -d half --attrib envmap latlong -o "$T/env.exr"
"$S" rig --quiet "$T/env.exr" -o "$T/r.usda" --json "$OUT/rig_json/rig_v2.json" >/dev/null
cat > "$OUT/rig_json/distant.json" <<'J'
{"version": 2, "lights": [{"type": "distant", "direction": [0.3, 0.8, 0.5], "angle_deg": 0.53,
 "color": [1, 0.95, 0.9], "intensity": 1000, "exposure": 0, "normalize": true}], "dome": null}
J

# --- a capture journal from the virtual camera (2 views x 3 frames)
"$S" capture --quiet --camera virtual:stage --bracket 3x2 --center 1/30 --views 2 --no-prompt -o "$T/cap"
cp "$T/cap/journal.jsonl" "$OUT/journal/virtual_2x3.jsonl"
# ingest: the virtual camera's JPEGs (setlight's camera-style EXIF, sub-seconds) and oiiotool's
for f in "$T"/cap/*.jpg; do
  [ "$(stat -c %s "$f")" -lt 20000 ] && cp "$f" "$OUT/ingest/virtual_$(basename "$f")" && break
done
cp "$OUT/photo/exif.jpg" "$OUT/photo/rgb8.tif" "$OUT/ingest/"
head -n 3 "$T/cap/journal.jsonl" > "$OUT/journal/interrupted.jsonl"

# --- response curves
"$S" simulate --scene stage --out "$T/sim" --seed 1 --size tiny --quiet
"$S" response --quiet -o "$OUT/response_json/sim.json" "$T"/sim/hdri/IMG_000[1-7].jpg 2>/dev/null
python3 - "$OUT/response_json/gamma.json" <<'P'
import json, sys
n = 16
inv = [[(k / (n - 1)) ** 2.2 for k in range(n)] for c in range(3)]
json.dump({"format": "setlight-response", "version": 1, "source": "seed", "nodes": n,
           "inverse": inv}, open(sys.argv[1], "w"))
P
python3 - "$OUT/response_text" <<'P'
import sys
out = sys.argv[1]
xs = [k / 32 for k in range(33)]
ys = [x ** (1 / 2.2) for x in xs]
f = lambda v: "  ".join("%.6f" % x for x in v)
with open(out + "/dorf.txt", "w") as o:
    for name, g in (("seedA", 2.2), ("seedB", 1.8)):
        o.write("%s\ngraph\nI =\n%s\nB =\n%s\n" % (name, f(xs), f(x ** (1 / g) for x in xs)))
with open(out + "/ib.txt", "w") as o:
    o.write("# I B\n" + "".join("%.6f %.6f\n" % (x, y) for x, y in zip(xs, ys)))
P

# --- ColorChecker references (docs/calibrate.md): CSV Lab with names, CSV RGB, JSON XYZ
c="$OUT/chart_reference"
lab="37.54,14.37,14.92 64.66,19.27,17.50 49.32,-3.82,-22.54 43.46,-12.74,22.72
54.94,9.61,-24.79 70.48,-32.26,-0.37 62.73,35.83,56.50 39.43,10.75,-45.17
50.57,48.64,16.67 30.10,22.54,-20.87 71.77,-24.13,58.19 71.51,18.24,67.37
28.37,15.42,-49.80 54.38,-39.72,32.27 42.43,51.05,28.62 81.80,2.67,80.41
50.63,51.28,-14.12 49.57,-29.71,-28.32 95.19,-1.03,2.93 81.29,-0.57,0.44
66.89,-0.75,-0.06 50.76,-0.13,0.14 35.63,-0.46,-0.48 20.64,0.07,-0.46"
{ echo "# ColorChecker Classic, CIELAB D50"; echo "patch,L,a,b"
  i=1; for v in $lab; do echo "p$i,$v"; i=$((i + 1)); done; } > "$c/lab.csv"
{ echo "R,G,B"; for v in $lab; do echo "0.2,0.3,0.4"; done; } > "$c/rgb.csv"
python3 - "$c/xyz.json" <<'P'
import json, sys
json.dump({"space": "xyz_d50", "patches": [[20 + i, 21 + i, 18 + i] for i in range(24)]},
          open(sys.argv[1], "w"))
P

# --- job graphs (docs/process.md): process --emit-jobs on two tiny simulated
# setups, one graph each, written compact and with the temporary folder's
# path shortened to /t (under the 16 KB max_len of the fuzz runs); then
# hand-made edge cases, good and bad
g="$OUT/job_graph"
"$S" simulate --scene exterior --size tiny -o "$T/ext" -q
"$S" simulate --scene stage --size tiny -o "$T/stage" -q
for s in ext stage; do
  "$S" process "$T/$s" -o "$T/day" --probe-view 180,0 --emit-jobs "$T/jobs_$s.json" -q
  python3 -c 'import json, sys; json.dump(json.loads(open(sys.argv[1]).read().replace(sys.argv[3], "/t")),
                                          open(sys.argv[2], "w"), separators=(",", ":"))' \
    "$T/jobs_$s.json" "$g/emitted_$s.json" "$T"
done
python3 - "$g" <<'P'
import json, sys
out = sys.argv[1]
def job(id, deps=(), stage="merge", setup="s", **kw):
    j = {"id": id, "setup": setup, "stage": stage, "argv": ["/usr/bin/setlight", "job", "/d/jobs.json", id],
         "command": ["/usr/bin/setlight", stage, "-o", "/d/%s.exr" % id], "inputs": ["/d/in.tif"],
         "outputs": ["/d/%s.exr" % id, "/d/%s.result.json" % id], "deps": list(deps), "array": None,
         "memory_mb": 100, "cpus": 1, "log": "/d/logs/%s.log" % id.replace("/", "_"), "key": None,
         "up_to_date": False}
    j.update(kw)
    return j
def graph(jobs, **kw):
    g = {"format": "setlight-jobs", "version": 1, "setlight": "0.1.0", "out": "/d", "jobs": jobs}
    g.update(kw)
    return g
cases = {
    "one_job": graph([job("s/merge/0")]),
    "index_only": graph([job("index", stage="index", setup=None)]),
    "no_jobs": graph([]),
    # listed against dependency order: a diamond, then the index
    "diamond_reordered": graph([job("s/report", ["s/render/0", "s/render/1"], "report"),
                                job("s/render/1", ["s/rig"], "render", array="s/render"),
                                job("s/render/0", ["s/rig"], "render", array="s/render"),
                                job("s/rig", ["s/merge/0", "s/merge/0"], "rig"),
                                job("s/merge/0", key="ab" * 32, up_to_date=True),
                                job("index", ["s/report"], "index", setup=None)]),
    "cycle": graph([job("a", ["c"]), job("b", ["a"]), job("c", ["b"]), job("d", ["a"])]),
    "self_dependency": graph([job("a", ["a"])]),
    "unknown_dependency": graph([job("a", ["nowhere"])]),
    "duplicate_id": graph([job("a"), job("a")]),
    "id_escapes_out": graph([job("../../etc/a")]),
    "relative_out": graph([job("a")], out="day"),
    "relative_input": graph([job("a", inputs=["in.tif"])]),
    "unknown_stage": graph([job("a", stage="paint")]),
    "empty_command": graph([job("a", command=[])]),
    "number_in_argv": graph([job("a", argv=["/usr/bin/setlight", 1])]),
    "cpus_zero": graph([job("a", cpus=0)]),
    "version_2": graph([job("a")], version=2),
    "other_format": {"format": "setlight-rig", "version": 1, "jobs": []},
}
for name, doc in cases.items():
    with open("%s/%s.json" % (out, name), "w") as f:
        json.dump(doc, f, separators=(",", ":"))
with open(out + "/duplicate_key.json", "w") as f:
    f.write('{"format":"setlight-jobs","version":1,"out":"/d","out":"/e","jobs":[]}')
P

find "$OUT" -type f -size +20k -print -delete | sed 's/^/dropped (over 20 KB): /'
du -sh "$OUT"
for t in "$OUT"/*; do echo "$(basename "$t"): $(ls "$t" | wc -l) seeds"; done
