#!/usr/bin/env bash
# setlight capture's faults end to end through the real libgphoto2 and the
# PTP/IP emulator: a refused setting, a disconnect (reconnected, or not and
# then --resume), a drop while a setting is sent, and a full disk. Split from
# capture.sh so that each stays well inside the test timeout under sanitizers.
. "$(dirname "$0")/lib.bash"
. "$(dirname "$0")/capture_lib.bash"
. "$(dirname "$0")/capture_ptpip.bash"

# --- a setting the camera refuses (Invalid Device Prop Value for the 4th
# shutter speed): clear message, journal consistent, no reconnection tried
start_cam --refuse-shutter 4
expect 1 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/refused"
err_has "ptpip:127.0.0.1:$PORT: setting shutterspeed to 0.0323 failed"; err_one_line
if python3 - "$T/refused" <<'EOF'
import hashlib, json, sys
d = sys.argv[1]
l = [json.loads(x) for x in open(d + "/journal.jsonl")]
acc = [e for e in l if e["event"] == "frame" and e["accepted"]]
err = [e for e in l if e["event"] == "error"]
assert [e["index"] for e in acc] == [0, 1, 2], acc
assert len(err) == 1 and err[0]["index"] == 3 and "shutterspeed" in err[0]["message"]
assert not [e for e in l if e["event"] == "reconnect"]
for e in acc:
    assert hashlib.sha256(open(d + "/" + e["file"], "rb").read()).hexdigest() == e["sha256"]
s = json.load(open(d + "/session.json"))
assert len(s["views"][0]["brackets"][0]["frames"]) == 3 and len(s["problems"]) == 1
EOF
then ok; else bad "refused setting: journal"; fi
# a camera that takes the speed finishes the session
start_cam
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --no-prompt --resume "$T/refused"
check_session "$T/refused" 1 7

# --- disconnect after frame 10, reconnection within the run: 21 frames in
# one go, the journal shows the error and the reconnection
start_cam --drop-after 10
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --views 3 --no-prompt -o "$T/reconnect"
check_session "$T/reconnect" 3 7
python3 -c 'import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; k=[(e["event"],e.get("view"),e.get("index"),e.get("ok")) for e in l if e["event"] in ("error","reconnect")]; sys.exit(0 if k==[("error",1,3,None),("reconnect",1,3,True)] else print(k) or 1)' \
  "$T/reconnect/journal.jsonl" && ok || bad "reconnect not journalled"

# --- the connection drops while the shutter speed is being set (4th change):
# a lost connection, not a refusal: reconnection, 7 frames, journalled
start_cam --drop-at-set 4
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/dropset"
check_session "$T/dropset" 1 7
python3 -c 'import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; k=[(e["event"],e.get("index"),e.get("ok")) for e in l if e["event"] in ("error","reconnect")]; sys.exit(0 if len(k)==2 and k[0][0]=="error" and k[1]==("reconnect",k[0][1],True) and "shutterspeed" in [e for e in l if e["event"]=="error"][0]["message"] else print(k) or 1)' \
  "$T/dropset/journal.jsonl" && ok || bad "drop while setting: not reconnected"
grep -q "dropping the connection at exposure-time change 4" "$T/cam.log" && ok || bad "emulator did not drop: $(tail -3 "$T/cam.log")"

# --- disconnect after frame 10 with no reconnection, then --resume: 21
# frames, none lost or twice
start_cam --drop-after 10
expect 1 cap --quiet --reconnect 0 --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --views 3 --no-prompt -o "$T/drop"
err_has "ptpip:127.0.0.1:$PORT"; err_has "--resume"; err_one_line
n=$(ls "$T/drop"/v*.jpg | wc -l)
if [ "$n" -eq 10 ]; then ok; else bad "after the drop: $n frames, want 10"; fi
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --no-prompt --resume "$T/drop"
check_session "$T/drop" 3 7
if python3 - "$T/drop" <<'EOF'
import json, sys
l = [json.loads(x) for x in open(sys.argv[1] + "/journal.jsonl")]
kinds = [e["event"] for e in l]
err = kinds.index("error"); res = kinds.index("resume")
assert err < res and l[err]["view"] == 1 and l[err]["index"] == 3
assert l[res]["frames_done"] == 10 and (l[res]["next_view"], l[res]["next_index"]) == (1, 3)
assert l[res]["after_error"]
# the first frame after the resume is measured against the last one before it
first = [e for e in l[res:] if e["event"] == "frame"][0]
assert (first["view"], first["index"]) == (1, 3) and first["measured_ratio"]
# the camera card numbering continues: every source is distinct
src = [e["source"] for e in l if e["event"] == "frame"]
assert len(src) == len(set(src))
EOF
then ok; else bad "journal does not show the gap and the resume"; fi
# resuming a complete session shoots nothing and journals nothing
lines=$(wc -l <"$T/drop/journal.jsonl")
# (the same command line as the first run: its plan options are not used, and it says so)
expect 0 cap --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --views 3 --no-prompt --resume "$T/drop"
err_has "is not used with --resume"
if [ "$(wc -l <"$T/drop/journal.jsonl")" -eq "$lines" ]; then ok; else bad "complete session journalled again"; fi

# --- disk full: a 48 KiB tmpfs in a private mount namespace
if unshare -rm true 2>/dev/null; then
  start_cam
  mkdir -p "$T/small" "$T/full_disk"
  unshare -rm bash -c '
    mount -t tmpfs -o size=48k tmpfs "$1" || exit 99
    timeout 60 "$2" capture --camera "ptpip:127.0.0.1:$3" --bracket 7x3 --center 1/30 --views 3 \
      --no-prompt -o "$1/s" 2>"$4/err"
    echo $? >"$4/rc"
    cp -r "$1/s/." "$4/"' _ "$T/small" "$SETLIGHT" "$PORT" "$T/full_disk"
  rc=$(cat "$T/full_disk/rc" 2>/dev/null)
  if [ "$rc" = 1 ]; then ok; else bad "disk full: exit $rc: $(cat "$T/full_disk/err" 2>/dev/null)"; fi
  if grep -q "No space left" "$T/full_disk/err"; then ok; else bad "disk full message: $(cat "$T/full_disk/err")"; fi
  if python3 - "$T/full_disk" <<'EOF'
import hashlib, json, os, sys
d = sys.argv[1]
l = [json.loads(x) for x in open(d + "/journal.jsonl")]
err = [e for e in l if e["event"] == "error"]
assert len(err) == 1 and "No space" in err[0]["message"], err
acc = [e for e in l if e["event"] == "frame" and e["accepted"]]
assert 0 < len(acc) < 21
# the failed frame is the one after the last accepted one
last = acc[-1]
assert (err[0]["view"] * 7 + err[0]["index"]) == last["view"] * 7 + last["index"] + 1
for e in acc:
    assert hashlib.sha256(open(d + "/" + e["file"], "rb").read()).hexdigest() == e["sha256"]
assert not [n for n in os.listdir(d) if "sl-tmp" in n]
EOF
  then ok; else bad "disk full: journal or frames"; fi
else
  skip "disk full (no unshare -rm for a private tmpfs)"
fi


finish
