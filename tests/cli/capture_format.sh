#!/usr/bin/env bash
# setlight capture --format through the real libgphoto2 and the PTP/IP
# emulator (CompressionSetting 0x5004, labelled by ptp2 as a Nikon body's
# "imagequality"): raw+jpeg shots with both files and siblings, a body left
# in raw+jpeg (keep), raw alone,
# a format change the camera ignores, a format it does not offer, a drop
# between a shot's JPEG and raw then --resume, another --format on resume.
. "$(dirname "$0")/lib.bash"
. "$(dirname "$0")/capture_lib.bash"
. "$(dirname "$0")/capture_ptpip.bash"

# check_pairs DIR COUNT LABEL: every accepted frame is a DNG with its JPEG
# sibling; session.json lists the siblings and the camera's label.
check_pairs() {
  if python3 - "$@" <<'PY'
import json, sys
d, count, label = sys.argv[1], int(sys.argv[2]), sys.argv[3]
l = [json.loads(x) for x in open(d + "/journal.jsonl")]
acc = [e for e in l if e["event"] == "frame" and e["accepted"]]
assert len(acc) == count, len(acc)
for e in acc:
    assert e["file"].endswith(".dng") and e["source"].endswith(".DNG"), e["file"]
    sib = e["siblings"]
    assert len(sib) == 1 and sib[0]["file"] == e["file"][:-4] + ".jpg", sib
    assert e["verified_on"] == sib[0]["file"] and e["pixels_ok"] in (True, None)
s = json.load(open(d + "/session.json"))
assert s["camera"]["format"] == "raw+jpeg" and s["camera"]["format_label"] == label, s["camera"]
fr = [f for v in s["views"] for b in v["brackets"] for f in b["frames"]]
assert len(fr) == count and all(len(f["siblings"]) == 1 for f in fr)
PY
  then ok; else bad "raw+jpeg pairs in $1"; fi
}

# --- raw+jpeg, 3 views x 7: 21 shots, 42 files, against jpeg alone
start_cam
t0=$(date +%s.%N)
expect 0 cap --json --camera "ptpip:127.0.0.1:$PORT" --format raw+jpeg --bracket 7x3 --center 1/30 --views 3 --no-prompt -o "$T/pair"
t1=$(date +%s.%N)
check_session "$T/pair" 3 7
check_pairs "$T/pair" 21 "NEF+Fine"
json_eval "$T/out" 'd["format"] == "raw+jpeg" and d["format_label"] == "NEF+Fine" and d["frames"] == 21'
n=$(ls "$T/pair" | wc -l)
if [ "$n" -eq 44 ]; then ok; else bad "$n files in the raw+jpeg session, want 42 + 2"; fi
t2=$(date +%s.%N)
expect 0 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --format jpeg --bracket 7x3 --center 1/30 --views 3 --no-prompt -o "$T/jpeg"
t3=$(date +%s.%N)
check_session "$T/jpeg" 3 7
python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); f=[f for v in s["views"] for b in v["brackets"] for f in b["frames"]]; sys.exit(0 if s["camera"]["format_label"]=="JPEG Fine" and all(x["file"].endswith(".jpg") and "siblings" not in x for x in f) else 1)' \
  "$T/jpeg/session.json" && ok || bad "jpeg session"
awk -v a="$t0" -v b="$t1" -v c="$t2" -v d="$t3" 'BEGIN { printf "3x7 over PTP/IP: raw+jpeg %.2f s (%.0f ms a shot), jpeg %.2f s (%.0f ms a shot)\n", b - a, (b - a) * 1000 / 21, d - c, (d - c) * 1000 / 21 }'

# --- --format left out (keep) on a body already set to NEF+Fine: both files
# of each trigger are taken, the session records the camera's label
start_cam --quality 7
expect 0 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/keep"
check_session "$T/keep" 1 7
python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); f=[f for v in s["views"] for b in v["brackets"] for f in b["frames"]]; sys.exit(0 if s["camera"]["format"]=="keep" and s["camera"]["format_label"]=="NEF+Fine" and all(x["file"].endswith(".dng") and len(x["siblings"])==1 for x in f) else 1)' \
  "$T/keep/session.json" && ok || bad "keep on a raw+jpeg body"
# ... and in a raw+JPEG mode whose label ptp2 cannot name ("Unknown value
# 0003"): one file expected, the second taken before the capture complete,
# never mistaken for the next trigger's
start_cam --qualities 0,1,2,3 --quality 3
expect 0 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --bracket 7x3 --center 1/30 --no-prompt -o "$T/unnamed"
check_session "$T/unnamed" 1 7
python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); f=[f for v in s["views"] for b in v["brackets"] for f in b["frames"]]; sys.exit(0 if s["camera"]["format_label"]=="Unknown value 0003" and all(x["file"].endswith(".dng") and x["source"][-8:-4]==x["siblings"][0]["source"][-8:-4] for x in f) else 1)' \
  "$T/unnamed/session.json" && ok || bad "unnamed raw+jpeg mode: files mixed up between triggers"
start_cam

# --- raw alone: DNGs only, verified on their own pixels (OpenImageIO reads them)
expect 0 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --format raw --bracket 7x3 --center 1/30 --no-prompt -o "$T/raw"
check_session "$T/raw" 1 7
python3 -c 'import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; a=[e for e in l if e["event"]=="frame" and e["accepted"]]; sys.exit(0 if all(e["file"].endswith(".dng") and "siblings" not in e for e in a) and sum(e["pixels_ok"] is True for e in a)==6 else 1)' \
  "$T/raw/journal.jsonl" && ok || bad "raw alone"

# --- --resume with another --format: refused, nothing written
cp "$T/raw/journal.jsonl" "$T/raw.before"
expect 2 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --format raw+jpeg --no-prompt --resume "$T/raw"
err_has "$T/raw: the session is shot as raw; --format raw+jpeg would mix formats"; err_one_line
cmp -s "$T/raw.before" "$T/raw/journal.jsonl" && ok || bad "journal changed by a refused resume"

# --- the camera ignores the first format change: the read-back catches it,
# the format is set again, the session is complete
start_cam --ignore-format 1
expect 0 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --format raw+jpeg --bracket 7x3 --center 1/30 --no-prompt -o "$T/ignored"
check_session "$T/ignored" 1 7
check_pairs "$T/ignored" 7 "NEF+Fine"
python3 -c 'import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; f=[(e["attempt"],e["ok"]) for e in l if e["event"]=="format"]; m=[e.get("message","") for e in l if e["event"]=="format"][0]; sys.exit(0 if f==[(1,False),(2,True)] and "reads '"'"'JPEG Fine'"'"' after being set to '"'"'NEF+Fine'"'"'" in m else print(f, m) or 1)' \
  "$T/ignored/journal.jsonl" && ok || bad "ignored format change not journalled"
grep -q "ignoring image quality change 1" "$T/cam.log" && ok || bad "emulator did not ignore the change"

# --- a format the camera does not offer (a body without raw): usage error
# before anything is written, the camera's choices in the message
start_cam --qualities 0,1,2
expect 2 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --format raw --bracket 7x3 --center 1/30 --no-prompt -o "$T/noraw"
err_has "ptpip:127.0.0.1:$PORT: the camera offers no raw image format (its choices: 'JPEG Basic', 'JPEG Normal', 'JPEG Fine')"
err_one_line
absent "$T/noraw"

# --- the link drops after frame 3's JPEG, before its raw: the JPEG is kept
# and journalled incomplete; --resume shoots frame 3 again under new names
start_cam --drop-before-raw 3
expect 1 cap --quiet --reconnect 0 --camera "ptpip:127.0.0.1:$PORT" --format raw+jpeg --bracket 7x3 --center 1/30 --no-prompt -o "$T/drop"
err_has "IMG_0003.DNG"; err_has "--resume"; err_one_line
landed=$(sha256sum "$T/drop/v00_f02.jpg" | cut -d' ' -f1)
absent "$T/drop/v00_f02.dng"
expect 0 cap --quiet --camera "ptpip:127.0.0.1:$PORT" --no-prompt --resume "$T/drop"
check_session "$T/drop" 1 7
check_pairs "$T/drop" 7 "NEF+Fine"
if python3 - "$T/drop" "$landed" <<'PY'
import hashlib, json, sys
d, landed = sys.argv[1], sys.argv[2]
l = [json.loads(x) for x in open(d + "/journal.jsonl")]
inc = [e for e in l if e["event"] == "frame" and e.get("incomplete")]
assert len(inc) == 1 and inc[0]["index"] == 2 and inc[0]["file"] == "v00_f02.jpg", inc
assert inc[0]["sha256"] == landed and "1 of 2 files" in inc[0]["reason"]
acc = {e["index"]: e for e in l if e["event"] == "frame" and e["accepted"]}
assert acc[2]["file"] == "v00_f02_r2.dng" and acc[2]["siblings"][0]["file"] == "v00_f02_r2.jpg"
assert hashlib.sha256(open(d + "/v00_f02.jpg", "rb").read()).hexdigest() == landed
PY
then ok; else bad "drop between JPEG and raw"; fi

finish
