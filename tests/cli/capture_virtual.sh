#!/usr/bin/env bash
# setlight capture with the virtual set's camera (--camera virtual[:SCENE]):
# the whole capture path without hardware, its frames merged, ingested back
# from shuffled names, the progress display on a terminal, and its bad input.
. "$(dirname "$0")/lib.bash"
. "$(dirname "$0")/capture_lib.bash"

# --- a full 3 x 7 capture of the stage scene
t0=$(date +%s.%N)
expect 0 timeout 120 "$SETLIGHT" capture --camera virtual:stage --bracket 7x3 --center 1/30 --views 3 \
  --no-prompt --json -o "$T/full"
t1=$(date +%s.%N)
echo "full 3x7 capture with the virtual camera: $(python3 -c "print(round($t1 - $t0, 2))") s"
json_ok "$T/out"
json_eval "$T/out" 'd["ok"] and d["frames"] == 21 and d["camera"]["backend"] == "virtual" and d["camera"]["port"] == "virtual:stage"'
json_eval "$T/out" 'len(d["plan"]) == 7 and abs(d["plan"][0]["moved_stops"]) > 0.5'
err_has "view 3/3 frame 7/7"
err_has "snapped to 1/8000 s"
check_session "$T/full" 3 7
json_eval "$T/full/session.json" 'd["camera"]["backend"] == "virtual" and d["problems"] == []'
no_temp "$T/full"

# --- its brackets merge: EXIF and the fitted exposures agree, nothing clipped
for v in 0 1 2; do
  expect 0 "$SETLIGHT" merge --json -o "$T/merged_$v.exr" "$T/full/v0${v}_f0"?.jpg
  json_eval "$T/out" 'len(d["frames"]) == 7 and d["disagreeing_frames"] == 0 and d["clipped_pixels"] == 0'
done

# --- ingest: the session's frames under shuffled names on a "card"; the
# virtual clock turns the head for 15 s between views
mkdir -p "$T/card/DCIM/100VSET"
i=0
for f in $(ls "$T/full"/v*.jpg | sort -R); do
  i=$((i + 1))
  cp "$f" "$T/card/DCIM/100VSET/IMG_$(printf %04d $((RANDOM % 9000 + 1000)))_$i.JPG"
done
echo "lens cap" >"$T/card/DCIM/100VSET/notes.txt"
expect 0 "$SETLIGHT" ingest --json "$T/card" -o "$T/ingested"
json_eval "$T/out" 'd["frames"] == 21 and d["views"] == 3'
if python3 - "$T/full" "$T/ingested" <<'EOF'
import json, sys
cap = json.load(open(sys.argv[1] + "/session.json"))
ing = json.load(open(sys.argv[2] + "/session.json"))
want = [[f["sha256"] for f in v["brackets"][0]["frames"]] for v in cap["views"]]
got = [[f["sha256"] for f in v["brackets"][0]["frames"]] for v in ing["views"]]
assert [len(v["brackets"]) for v in ing["views"]] == [1, 1, 1]
assert got == want, "ingest grouped the frames differently from the capture"
assert len(ing["problems"]) == 1 and "notes.txt" in ing["problems"][0]
EOF
then ok; else bad "ingest of the virtual capture"; fi

# --- ingest of a virtual-set capture folder: every shot is a JPEG, a 16-bit
# TIFF and a linear TIFF (as RAW+JPEG on a card), renumbered at random but
# alike for a shot's files: 21 frames, the linear TIFF (by its ICC profile) the frame's file, the other
# two its siblings, ISO (which TIFF EXIF loses) taken from the JPEG
expect 0 "$SETLIGHT" simulate --scene stage --size tiny --out "$T/sim"
mkdir -p "$T/simcard/DCIM/100VSET"
python3 - "$T/sim" "$T/simcard/DCIM/100VSET" <<'EOF'
import json, random, shutil, sys
cap = json.load(open(sys.argv[1] + "/capture.json"))
numbers = random.Random(7).sample(range(1000, 9999), len(cap["frames"]))
for f, n in zip(cap["frames"], numbers):
    for suffix in (".jpg", ".tif", "_linear.tif"):
        shutil.copy(f"{sys.argv[1]}/hdri/{f['name']}{suffix}", f"{sys.argv[2]}/DSC_{n}{suffix}")
EOF
expect 0 "$SETLIGHT" ingest --json "$T/simcard" -o "$T/simingest"
json_eval "$T/out" 'd["frames"] == 21 and d["views"] == 3'
if python3 - "$T/sim" "$T/simingest" <<'EOF'
import hashlib, json, sys
cap = json.load(open(sys.argv[1] + "/capture.json"))
ing = json.load(open(sys.argv[2] + "/session.json"))
sha = lambda p: hashlib.sha256(open(p, "rb").read()).hexdigest()
want = {}
for f in cap["frames"]:
    want.setdefault(f["view"], []).append(sha(f"{sys.argv[1]}/hdri/{f['name']}_linear.tif"))
assert [len(v["brackets"]) for v in ing["views"]] == [1, 1, 1]
got = {v["view"]: [f["sha256"] for f in v["brackets"][0]["frames"]] for v in ing["views"]}
assert got == want, "frames grouped differently from the plan"
for v in ing["views"]:
    for f in v["brackets"][0]["frames"]:
        # The linear TIFF (its ICC profile says so) is the frame's file.
        assert f["file"].endswith(".tif") and f["source"].endswith("_linear.tif") and f["iso"] == 100.0, f
        assert f["content"].startswith("scene-linear"), f
        sib = f["siblings"]
        assert len(sib) == 2 and sib[0]["content"].startswith("display-referred: 16-bit"), sib
        assert sib[1]["file"].endswith("_2.jpg"), sib
        assert sha(sys.argv[2] + "/" + sib[1]["file"]) == sib[1]["sha256"]
assert ing["problems"] == []
EOF
then ok; else bad "ingest of a virtual-set folder (JPEG, TIFF and linear TIFF per shot)"; fi

# --- progress for people: a bar on a terminal, nothing with --quiet
if script -qec "true" /dev/null >/dev/null 2>&1; then
  script -qec "'$SETLIGHT' capture --camera virtual:stage --bracket 1/250,1/30,1/4 --views 2 --no-prompt -o '$T/tty'" \
    /dev/null >"$T/tty.txt" 2>&1
  if grep -q "capture .*\[#*\.*\] *100.0%" "$T/tty.txt" && grep -q "view 2/2 frame 3/3" "$T/tty.txt"; then ok
  else bad "no progress bar on a terminal: $(head -c 600 "$T/tty.txt")"; fi
else
  skip "progress bar (no script(1) for a terminal)"
fi
expect 0 "$SETLIGHT" capture --quiet --camera virtual:stage --bracket 1/250,1/30 --no-prompt -o "$T/quiet"
if [ ! -s "$T/err" ]; then ok; else bad "--quiet printed: $(head -c 300 "$T/err")"; fi

# --- a plan the camera cannot do, and a scene it does not know
expect 2 "$SETLIGHT" capture --camera virtual --bracket 7x3 --center 8 --no-prompt -o "$T/bad1"
err_has "out of the camera's range (1/8000 to 30 s)"; err_one_line; absent "$T/bad1"
expect 2 "$SETLIGHT" capture --camera virtual:moon --no-prompt -o "$T/bad2"
err_has "unknown virtual scene 'moon'"; err_one_line; absent "$T/bad2"
expect 3 "$SETLIGHT" capture --camera virtual:"$T/absent.json" --no-prompt -o "$T/bad3"
err_has "$T/absent.json"; absent "$T/bad3"
expect 2 "$SETLIGHT" capture --camera virtual --views 0 -o "$T/bad4"; err_has "--views"; absent "$T/bad4"
expect 2 "$SETLIGHT" capture --camera virtual --reconnect -1 -o "$T/bad5"; err_has "--reconnect"

finish
