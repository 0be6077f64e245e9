#!/usr/bin/env bash
# setlight ingest of a card mixing the real bracket sets stack_room (Canon
# T2i, 640x427, 7 frames), stack_ghost (Canon T2i, another body and lens,
# 900x600, 3 frames) and memorial (PNG, no EXIF, 16 frames): each set is its
# own view, one warning line per two sets kept apart says why, and the
# session and --json say the same. Skips without the shared data.
. "$(dirname "$0")/lib.bash"

D="${SETLIGHT_SHARED_DATA:-/nonexistent}/brackets"
if [ ! -d "$D/stack_room" ] || [ ! -d "$D/stack_ghost" ] || [ ! -d "$D/memorial" ]; then
  skip "shared data brackets/ absent"
  finish
  exit
fi
mkdir -p "$T/card/DCIM/100CANON" "$T/card/scans"
cp "$D"/stack_room/*.jpg "$D"/stack_ghost/*.JPG "$T/card/DCIM/100CANON/"
cp "$D"/memorial/*.png "$T/card/scans/"

expect 0 "$SETLIGHT" ingest "$T/card" -o "$T/ing" --gap 1e9
err_has "warning: $T/card: scans/memorial0061.png..scans/memorial0076.png (16 frames) and DCIM/100CANON/IMG_0959.JPG..DCIM/100CANON/IMG_0961.JPG (3 frames) not grouped together: camera none vs 'Canon EOS REBEL T2i'"
err_has "(7 frames) not grouped together: body serial 1823918851 vs none; lens 'EF-S18-55mm f/3.5-5.6 IS' vs none; focal length 18 vs 36 mm; image size 900x600 vs 640x427"
err_has "$T/ing: 26 frames in 3 views; 1 problem listed in $T/ing/session.json"
if [ "$(grep -c 'not grouped together' "$T/err")" -eq 2 ]; then ok; else bad "want 2 split lines: $(cat "$T/err")"; fi
S="$T/ing/session.json"
json_eval "$S" '[sum(len(b["frames"]) for b in v["brackets"]) for v in d["views"]] == [16, 3, 7]'
json_eval "$S" '[len(v["brackets"]) for v in d["views"]] == [1, 1, 1]'
json_eval "$S" '[(v["camera"]["width"], v["camera"]["height"]) for v in d["views"]] == [(512, 768), (900, 600), (640, 427)]'
json_eval "$S" 'd["views"][1]["camera"]["serial"] == "1823918851" and d["views"][2]["camera"]["serial"] is None'
json_eval "$S" 'len(d["splits"]) == 2'
json_eval "$S" 'len(d["problems"]) == 1 and "16 of 16 frames" in d["problems"][0] and "--times" in d["problems"][0]'
present "$T/ing/v00_b00_f15.png"
present "$T/ing/v02_b00_f06.jpg"

# --json: the same splits and problems on stdout
expect 0 "$SETLIGHT" ingest --json --gap 1e9 "$T/card" -o "$T/ing2"
json_ok "$T/out"
json_eval "$T/out" 'd["frames"] == 26 and d["views"] == 3 and len(d["splits"]) == 2 and len(d["problems"]) == 1'
json_eval "$T/out" 'd["splits"] == json.load(open(sys.argv[1].replace("/out", "/ing2/session.json")))["splits"]'

# a folder that already holds a file the ingest would write: exit 2 when it
# gets there, one line, and the frames copied before it are taken back
mkdir -p "$T/ing4"; echo mine >"$T/ing4/v01_b00_f01.jpg"
expect 2 "$SETLIGHT" ingest --quiet --gap 1e9 "$T/card" -o "$T/ing4"
err_has "setlight ingest: $T/ing4/v01_b00_f01.jpg: exists; never overwritten"
err_one_line
if [ "$(ls "$T/ing4")" = "v01_b00_f01.jpg" ]; then ok; else bad "left in ing4: $(ls "$T/ing4" | head)"; fi
no_temp "$T/ing4"

# with the default gap the stack_room frames, shot 15 to 22 s apart, are
# views of one frame each: each is a problem, not a silent bracket
expect 0 "$SETLIGHT" ingest --json "$T/card" -o "$T/ing3"
json_eval "$T/out" 'd["views"] == 9 and sum("one frame" in p for p in d["problems"]) == 7'

finish
