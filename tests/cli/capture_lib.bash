# Shared by the capture CLI tests (sourced after lib.bash, not run).

# check_session DIR VIEWS COUNT: frames on disk (with their siblings),
# journal complete, checksums, EXIF exposures as planned, session.json
# grouping.
check_session() {
  local dir=$1 views=$2 count=$3
  local files
  files=$(python3 -c '
import json,sys
d=json.load(open(sys.argv[1]+"/session.json"))
print(" ".join(sys.argv[1]+"/"+f["file"] for v in d["views"] for b in v["brackets"] for f in b["frames"]))' "$dir")
  # shellcheck disable=SC2086
  "$SETLIGHT" info --json $files >"$T/info.json" 2>"$T/info.err" || bad "info on the frames failed"
  if python3 - "$dir" "$views" "$count" "$T/info.json" <<'EOF'
import hashlib, json, math, os, sys
d, views, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
info = {os.path.basename(f["file"]): f for f in json.load(open(sys.argv[4]))["files"]}
lines = [json.loads(l) for l in open(d + "/journal.jsonl")]
assert lines[0]["event"] == "session_start" and lines[0]["version"] == 1
plan = lines[0]["plan"]["times"]
assert len(plan) == count and lines[0]["plan"]["views"] == views
acc = [e for e in lines if e["event"] == "frame" and e["accepted"]]
keys = [(e["view"], e["index"]) for e in acc]
assert len(keys) == views * count, ("accepted frames", len(keys))
assert len(set(keys)) == len(keys), "a frame was accepted twice"
assert any(e["event"] == "session_end" for e in lines), "no session_end"
# a frame's files: its own and its siblings' (RAW+JPEG), each checksummed
def files(e):
    return [e] + e.get("siblings", [])
for e in [e for e in lines if e["event"] == "frame"]:
    for f in files(e):
        data = open(d + "/" + f["file"], "rb").read()
        assert hashlib.sha256(data).hexdigest() == f["sha256"], f["file"]
for e in acc:
    exif = info[e["file"]]["exif"]["exposure_time"]
    assert abs(math.log2(exif / plan[e["index"]])) < 1 / 6, (e["file"], exif, plan[e["index"]])
s = json.load(open(d + "/session.json"))
assert s["version"] == 1 and len(s["views"]) == views
for v, view in enumerate(s["views"]):
    assert view["view"] == v and len(view["brackets"]) == 1
    fr = view["brackets"][0]["frames"]
    assert len(fr) == count
    assert all(f["file"].startswith("v%02d_" % v) for f in fr)
    t = [f["exposure_time"] for f in fr]
    assert t == sorted(t)
    for f, p in zip(fr, plan):
        assert abs(math.log2(f["exposure_time"] / p)) < 1 / 6
    assert all(len(f["sha256"]) == 64 for f in fr)
    # ratios between neighbours: every frame after the first was measured
    assert all(f["measured_ratio"] for f in fr[1:])
# every file on disk is in the journal, none is a leftover temporary
named = {f["file"] for e in lines if e["event"] == "frame" for f in files(e)}
for name in os.listdir(d):
    if name not in ("journal.jsonl", "session.json"):
        assert name in named, ("stray file", name)
EOF
  then ok; else bad "session check of $dir"; fi
}
