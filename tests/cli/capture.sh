#!/usr/bin/env bash
# setlight capture / ingest / cameras end to end: the real libgphoto2 talks
# PTP/IP to tests/ptpip_camera on 127.0.0.1 (a free port it picks). Covers the
# full 3 x 7 capture, busy replies, an ignored shutter change, the exterior
# scene, ingest, and the bad inputs of the capture issue (the faults are in
# capture_faults.sh).
. "$(dirname "$0")/lib.bash"
. "$(dirname "$0")/capture_lib.bash"
. "$(dirname "$0")/capture_ptpip.bash"

# --- help and detection
expect 0 "$SETLIGHT" capture --help; out_has "usage: setlight capture"
expect 0 "$SETLIGHT" ingest --help; out_has "usage: setlight ingest"
expect 0 gp_leaks "$SETLIGHT" cameras --json; json_ok "$T/out"; json_eval "$T/out" 'isinstance(d["cameras"], list)'

start_cam || { finish; exit 1; }

# --- full 3 x 7 capture through libgphoto2 over PTP/IP
t0=$(date +%s.%N)
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --views 3 --no-prompt \
  --json -o "$T/full"
t1=$(date +%s.%N)
echo "full 3x7 capture: $(python3 -c "print(round($t1 - $t0, 2))") s"
json_ok "$T/out"
json_eval "$T/out" 'd["ok"] and len(d["plan"]) == 7 and abs(d["plan"][0]["moved_stops"]) > 0.5'
err_has "snapped to"
check_session "$T/full" 3 7
no_temp "$T/full"
# the same folder again is refused, nothing touched
cp "$T/full/journal.jsonl" "$T/journal.before"
expect 2 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 -o "$T/full"
err_has "already holds a session"
cmp -s "$T/journal.before" "$T/full/journal.jsonl" && ok || bad "journal changed"

# --- explicit list, step command between views
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 1/1000,1/125,1/15 --views 2 \
  --step-command "echo step \$SETLIGHT_VIEW >> '$T/steps.txt'" -o "$T/list"
check_session "$T/list" 2 3
if [ "$(cat "$T/steps.txt")" = "step 1" ]; then ok; else bad "step command: $(cat "$T/steps.txt")"; fi
python3 -c 'import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; sys.exit(0 if [e["view"] for e in l if e["event"]=="step"]==[1] else 1)' \
  "$T/list/journal.jsonl" && ok || bad "step not journalled"

# --- busy replies: retried with backoff, no frame lost
start_cam --busy 3 --busy-at 5
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/busy"
check_session "$T/busy" 1 7
if [ "$(grep -c 'busy reply' "$T/cam.log")" -eq 3 ]; then ok; else bad "emulator sent no busy replies"; fi
# the journal records them on the frame that waited (the 5th)
python3 -c 'import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; b=[(e["view"],e["index"],e.get("busy_retries")) for e in l if e["event"]=="frame" and e.get("busy_retries")]; sys.exit(0 if b==[(0,4,3)] else print(b) or 1)' \
  "$T/busy/journal.jsonl" && ok || bad "busy retries not journalled"

# --- the camera ignores one shutter change: caught (EXIF and pixels) and retried
start_cam --ignore-shutter 4
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/ignored"
check_session "$T/ignored" 1 7
err_has "REJECTED"
if python3 - "$T/ignored" <<'EOF'
import json, sys
l = [json.loads(x) for x in open(sys.argv[1] + "/journal.jsonl")]
rej = [e for e in l if e["event"] == "frame" and not e["accepted"]]
assert len(rej) == 1 and rej[0]["view"] == 0 and rej[0]["index"] == 3, rej
r = rej[0]
assert "ignored" in r["reason"]
assert abs(r["measured_ratio"] - 1.0) < 0.1          # the pixels did not change
assert r["exposure_time"] < r["planned"] / 4           # the EXIF shows the old speed
retry = [e for e in l if e["event"] == "frame" and e["accepted"] and (e["view"], e["index"]) == (0, 3)]
assert retry[0]["attempt"] == 2 and abs(retry[0]["measured_ratio"] / retry[0]["expected_ratio"] - 1) < 0.1
s = json.load(open(sys.argv[1] + "/session.json"))
assert any("rejected" in p for p in s["problems"])
EOF
then ok; else bad "ignored shutter not caught"; fi

# --- the emulator serving the virtual camera's photographs of the exterior:
# the verification measures real scene ratios and the bracket merges
start_cam --scene exterior
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 5x2 --center 1/125 --aperture 16 --no-prompt -o "$T/scene"
check_session "$T/scene" 1 5
expect 0 "$SETLIGHT" merge --json -o "$T/scene.exr" "$T/scene"/v00_f0?.jpg
json_eval "$T/out" 'len(d["frames"]) == 5 and d["disagreeing_frames"] == 0'

# --- bad input: clear message, documented exit code, nothing lost
expect 2 cap --camera nosuchport --no-prompt -o "$T/bad1"; err_has "nosuchport"; err_one_line
absent "$T/bad1"
expect 2 cap --camera "bogus:thing" --no-prompt -o "$T/bad1"; err_has "unknown camera port"; absent "$T/bad1"
expect 2 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 4 --no-prompt -o "$T/bad2"
err_has "out of the camera's range"; err_one_line; absent "$T/bad2"
expect 2 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 1/30,fast -o "$T/bad2"; err_has "fast"
expect 2 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 0x3 --center 1/30 -o "$T/bad2"
expect 2 cap --views 0 --camera "ptpip:127.0.0.1:$PORT" -o "$T/bad3"; err_has "--views"; absent "$T/bad3"
expect 2 cap --camera "ptpip:127.0.0.1:$PORT"; err_has "-o DIR"
mkdir -p "$T/notsession"; echo keep >"$T/notsession/a.txt"
expect 3 cap --camera "ptpip:127.0.0.1:$PORT" --no-prompt --resume "$T/notsession"
err_has "not a capture session"; err_one_line
if [ "$(ls "$T/notsession")" = "a.txt" ]; then ok; else bad "resume touched a non-session folder"; fi
# an aperture or ISO other than the session's on --resume: refused, nothing written
cp "$T/scene/journal.jsonl" "$T/scene.before"
expect 2 cap --camera "ptpip:127.0.0.1:$PORT" --aperture 8 --no-prompt --resume "$T/scene"
err_has "the session is shot at aperture 16; --aperture 8 would mix exposures"; err_one_line
expect 2 cap --camera "ptpip:127.0.0.1:$PORT" --iso 400 --no-prompt --resume "$T/scene"
err_has "left the iso to the camera; --iso 400"
cmp -s "$T/scene.before" "$T/scene/journal.jsonl" && ok || bad "journal changed by a refused resume"
cp -r "$T/full" "$T/corrupt"
printf '{"event": "frame", "view": 2, "ind\n' >>"$T/corrupt/journal.jsonl"
cp "$T/corrupt/journal.jsonl" "$T/corrupt.before"
expect 3 cap --camera "ptpip:127.0.0.1:$PORT" --no-prompt --resume "$T/corrupt"
err_has "corrupt journal"; err_has "line"
cmp -s "$T/corrupt.before" "$T/corrupt/journal.jsonl" && ok || bad "corrupt journal was changed"
cp -r "$T/full" "$T/tampered"
echo x >>"$T/tampered/v00_f02.jpg"
expect 3 cap --camera "ptpip:127.0.0.1:$PORT" --no-prompt --resume "$T/tampered"
err_has "v00_f02.jpg"
# a USB port where no camera is
expect 1 gp_leaks timeout 60 "$SETLIGHT" capture --camera usb:999,999 --bracket 7x3 --center 1/30 --no-prompt -o "$T/nousb"
err_has "usb:999,999"; err_has "no camera"; absent "$T/nousb"
stop_cam
# no camera listening on that port any more (libgphoto2 itself prints
# "connect cmd: Connection refused" before our line)
expect 1 gp_leaks timeout 60 "$SETLIGHT" capture --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/gone"
err_has "setlight capture: ptpip:127.0.0.1:$PORT: no camera answers"; absent "$T/gone"

# --- ingest: a card of shuffled names grouped by EXIF time and exposure. The
# emulator's clock runs one second per frame, so with no pause between views
# the 21 frames are one view of three 7-frame brackets (views split by time
# are tested with controlled clocks in test_capture).
mkdir -p "$T/card/DCIM/100TEST"
i=0
for name in $(ls "$T/full"/v*.jpg | sort -R); do
  i=$((i + 1))
  cp "$name" "$T/card/DCIM/100TEST/X$(printf %04d $((RANDOM % 9000 + 1000)))_$i.JPG"
done
echo "not a photo" >"$T/card/DCIM/100TEST/notes.txt"
: >"$T/card/empty.jpg"
expect 0 "$SETLIGHT" ingest --json "$T/card" -o "$T/ingested"
json_ok "$T/out"
json_eval "$T/out" 'd["frames"] == 21 and d["views"] == 1'
json_ok "$T/ingested/session.json"
json_eval "$T/ingested/session.json" 'len(d["problems"]) == 2 and any("notes.txt" in p for p in d["problems"])'
json_eval "$T/ingested/session.json" '[len(b["frames"]) for b in d["views"][0]["brackets"]] == [7, 7, 7]'
json_eval "$T/ingested/session.json" 'all([f["exposure_time"] for f in b["frames"]] == sorted(f["exposure_time"] for f in b["frames"]) for b in d["views"][0]["brackets"])'
expect 2 "$SETLIGHT" ingest "$T/card" -o "$T/ingested"; err_has "already holds a session"
mkdir -p "$T/nophotos"; echo x >"$T/nophotos/a.txt"
expect 3 "$SETLIGHT" ingest "$T/nophotos" -o "$T/ing2"; err_has "no photographs"; absent "$T/ing2/session.json"
expect 3 "$SETLIGHT" ingest "$T/missing" -o "$T/ing3"; err_has "$T/missing"

finish
