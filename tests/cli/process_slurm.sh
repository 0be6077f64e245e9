#!/bin/bash
# setlight process --farm slurm on a real single-node Slurm cluster
# (tests/slurm/cluster.sh; skipped with its reason where the daemons cannot
# start): the same stage outputs as the local run, byte for byte, a Slurm
# job per job and a setup as one Slurm job; a job made to fail (a corrupt
# frame) fails with its dependants cancelled or not run, no good output is
# replaced, the index says so, and the rerun runs it and what follows it,
# nothing else; the default (--farm-group auto) groups the tiny setup, whose
# 16 jobs of well under a second would cost Slurm more than their work.
. "$(dirname "$0")/lib.bash"
S="$SETLIGHT"
# The calibrate jobs' chart detector (OpenCV mcc) leaks inside OpenCV, as in
# calibrate.sh and demo.sh: suppressed for every job (Slurm passes the
# environment on).
printf 'leak:cv::fastMalloc\n' >"$T/lsan.supp"
export LSAN_OPTIONS="suppressions=$T/lsan.supp"
CLUSTER_SH="$(cd "$(dirname "$0")/.." && pwd)/slurm/cluster.sh"

# munged's socket path must fit a sockaddr_un: the cluster lives in /tmp.
C=$(mktemp -d /tmp/sl-process-slurm-XXXXXX)
chmod 755 "$C"
stop_cluster() { bash "$CLUSTER_SH" stop "$C" >/dev/null 2>&1; rm -rf "$C"; }
if ! bash "$CLUSTER_SH" start "$C" >/dev/null 2>"$T/cluster.err"; then
  skip "Slurm: the cluster did not start: $(head -1 "$T/cluster.err")"
  rm -rf "$C"
  finish
  exit
fi
trap stop_cluster EXIT
export SLURM_CONF="$C/slurm.conf"

"$S" simulate --scene exterior --size tiny -o "$T/ext" -q
P=(--probe-view 180,0)

# 1. Local and farm runs of the same setup into the same folder (outputs
# carry their command lines): the same bytes.
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" -q
mv "$T/farm" "$T/local"
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --farm-group job --json -q
cp "$T/out" "$T/farm1.json"
json_eval "$T/farm1.json" 'd["jobs"]["failed"] == 0 and d["jobs"]["ran"] == d["jobs"]["total"] and d["setups"][0]["status"] == "ok"'
present "$T/farm/index.html"
present "$T/farm/ext/report.html"
stage_outputs() { (cd "$1" && find ext \( -name '*.exr' -o -name '*.usda' -o -name '*.png' \) -not -path '*/ingest/*' | sort | xargs sha256sum); }
stage_outputs "$T/local" >"$T/sums_local"
stage_outputs "$T/farm" >"$T/sums_farm"
if [ "$(wc -l <"$T/sums_local")" -ge 10 ] && cmp -s "$T/sums_local" "$T/sums_farm"; then ok; else
  bad "farm outputs differ from the local run's: $(diff "$T/sums_local" "$T/sums_farm" | head -5)"
fi
# Every job ran on the cluster: its log is Slurm's output file.
json_eval "$T/farm/jobs.json" 'all(__import__("os").path.exists(j["log"]) for j in d["jobs"] if j["stage"] != "index")'

# 2. A frame of view 1's ingested copy goes corrupt: that merge fails, what
# depends on it is cancelled (not left pending), the setup fails with exit 3.
G="$T/farm/ext/ingest/hdri/v01_b00_f03.tif"
cp "$G" "$T/frame.good"
head -c 3000 "$T/frame.good" >"$G"
rm -f "$T/farm/ext/merge/1.exr" "$T/farm/ext/merge/1.stamp.json" "$T/farm/ext/stitch.stamp.json"
expect 3 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --farm-group job --json -q
err_one_line
err_has "ext/merge/1"
json_eval "$T/out" '{j["id"]: j["status"] for j in d["setups"][0]["jobs"]}["ext/merge/1"] == "failed" and {j["id"]: j["status"] for j in d["setups"][0]["jobs"]}["ext/stitch"] == "not run"'
present "$T/farm/index.html"

# 3. The frame repaired: the rerun submits the failed merge and what follows
# it; the other merges and the chrome-ball unwrap stay as they are.
cp "$T/frame.good" "$G"
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --farm-group job --json -q
json_eval "$T/out" '{j["id"]: j["status"] for j in d["setups"][0]["jobs"]}["ext/merge/1"] == "ran" and all(j["status"] == "skipped" for j in d["setups"][0]["jobs"] if j["id"] in ("ext/merge/0", "ext/merge/2", "ext/unwrap"))'
stage_outputs "$T/farm" >"$T/sums_farm2"
if cmp -s "$T/sums_local" "$T/sums_farm2"; then ok; else
  bad "rerun outputs differ from the local run's: $(diff "$T/sums_local" "$T/sums_farm2" | head -5)"
fi

# 3b. The default, --farm-group auto: the tiny setup's 16 jobs (CPU
# estimates well under a second each) would cost Slurm more than their work,
# so the setup goes as one Slurm job running its jobs in turn, into the same
# folder (outputs carry their command lines): the same bytes; the choice and
# its reason in --json.
mv "$T/farm" "$T/farm_by_job"
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --json -q
json_eval "$T/out" 'd["jobs"]["failed"] == 0 and d["jobs"]["ran"] == d["jobs"]["total"] and d["setups"][0]["status"] == "ok"'
json_eval "$T/out" '(lambda f: f["group"] == "setup" and f["jobs"] == 16 and f["slurm_seconds"] == 12.4 and 0 < f["cpu_seconds"] < 12.4 and f["reason"].startswith("grouped: 16 jobs of ~") and f["reason"].endswith("(grouped above 2%)"))(d["setups"][0]["farm"])'
json_eval "$T/farm/jobs.json.slurm.json" '[j["id"] for j in d["jobs"]] == ["ext"] and d["jobs"][0]["argv"][:2] == ["/bin/sh", "-c"]'
# The estimate is the jobs' CPU within a factor of 3 (docs/process.md); a
# sanitized build runs the same jobs several times slower than the estimate
# (a release build's), so there only its being positive is checked.
if [ -z "${SETLIGHT_SANITIZED:-}" ]; then
  json_eval "$T/out" '(lambda s: 1 / 3 < s["farm"]["cpu_seconds"] / s["cost"]["cpu_seconds"] < 3)(d["setups"][0])'
else
  json_eval "$T/out" 'd["setups"][0]["farm"]["cpu_seconds"] > 0'
fi
present "$T/farm/logs/ext_merge_0.log"
stage_outputs "$T/farm" >"$T/sums_grouped"
if cmp -s "$T/sums_local" "$T/sums_grouped"; then ok; else
  bad "grouped farm outputs differ from the local run's: $(diff "$T/sums_local" "$T/sums_grouped" | head -5)"
fi
# A corrupt frame in the grouped setup: that merge fails, what needs it does
# not run, the unwrap (which does not) runs, exit 3; no good output is
# replaced (the failed merge's own among them) and the index says which job
# failed.
good_sums() { (cd "$T/farm/ext" && sha256sum merge/1.exr stitch/hdri.exr calibrate/hdri.exr rig/rig.usda render/env_grey.exr report.html); }
good_sums >"$T/sums_good"
head -c 3000 "$T/frame.good" >"$T/farm/ext/ingest/hdri/v01_b00_f03.tif"
rm -f "$T/farm/ext/unwrap.stamp.json"
expect 3 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --json -q
err_one_line
err_has "ext/merge/1"
json_eval "$T/out" '(lambda s: s["ext/merge/1"] == "failed" and s["ext/stitch"] == "not run" and s["ext/report"] == "not run" and s["ext/unwrap"] == "ran" and s["ext/merge/0"] == "skipped")({j["id"]: j["status"] for j in d["setups"][0]["jobs"]})'
json_eval "$T/out" 'd["setups"][0]["farm"]["group"] == "setup"'
if good_sums | cmp -s - "$T/sums_good"; then ok; else bad "a failed grouped job replaced a good output: $(good_sums | diff "$T/sums_good" - | head -4)"; fi
json_eval "$T/farm/index.json" 'd["setups_failed"] == 1 and d["setups"][0]["status"] == "failed" and "ext/merge/1" in d["setups"][0]["reason"]'
# Repaired, the rerun submits the failed merge and the 10 jobs after it
# (stitch, calibrate, rig, 6 renders, report), not the other merges nor the
# unwrap, which stay as they are. The merge reproduces the bytes it had
# kept, so the stitch finds its key unchanged and skips itself; it ends with
# the local run's bytes.
cp "$T/frame.good" "$T/farm/ext/ingest/hdri/v01_b00_f03.tif"
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --json -q
json_eval "$T/out" '(lambda s: s["ext/merge/1"] == "ran" and s["ext/stitch"] == "skipped" and all(s[i] == "skipped" for i in ("ext/merge/0", "ext/merge/2", "ext/merge/3", "ext/merge/4", "ext/unwrap")))({j["id"]: j["status"] for j in d["setups"][0]["jobs"]})'
json_eval "$T/out" 'd["setups"][0]["farm"]["jobs"] == 11 and d["setups"][0]["farm"]["group"] == "setup"'
json_eval "$T/farm/index.json" 'd["setups_failed"] == 0 and d["setups"][0]["status"] == "ok"'
stage_outputs "$T/farm" >"$T/sums_grouped2"
if cmp -s "$T/sums_local" "$T/sums_grouped2"; then ok; else
  bad "grouped rerun outputs differ from the local run's: $(diff "$T/sums_local" "$T/sums_grouped2" | head -5)"
fi
rm -rf "$T/farm"

# 3b'. The grouped setup's Slurm job killed mid-way (as a time or memory
# limit would): what it ran stays done, the first job it had not run is the
# failed one, what follows is not run, the setup fails (exit 1: not its
# input); the rerun runs the rest only and ends with the local run's bytes
# (into the same folder: outputs carry their command lines).
"$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --json -q >"$T/killed.json" 2>"$T/killed.err" &
runner=$!
for _ in $(seq 1200); do [ -e "$T/farm/ext/stitch.stamp.json" ] && break; sleep 0.1; done
scancel --name=ext
wait "$runner"
rc=$?
if [ "$rc" = 1 ] && [ "$(wc -l <"$T/killed.err")" = 1 ] && grep -q "^setlight process: ext: ext/.*: failed (the setup's Slurm job ended CANCELLED before it ran)$" "$T/killed.err"; then ok; else
  bad "killed setup: exit $rc, stderr $(head -c 300 "$T/killed.err")"
fi
json_eval "$T/killed.json" 'd["setups"][0]["farm"]["slurm_state"] == "CANCELLED"'
json_eval "$T/killed.json" '(lambda s: list(s.values()).count("failed") == 1 and all(s["ext/merge/%d" % k] == "ran" for k in range(5)) and s["ext/stitch"] == "ran" and s["ext/report"] == "not run")({j["id"]: j["status"] for j in d["setups"][0]["jobs"]}) and d["setups"][0]["status"] == "failed"'
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --json -q
json_eval "$T/out" '(lambda s: all(s["ext/merge/%d" % k] == "skipped" for k in range(5)) and s["ext/stitch"] == "skipped" and s["ext/report"] == "ran")({j["id"]: j["status"] for j in d["setups"][0]["jobs"]})'
stage_outputs "$T/farm" >"$T/sums_killed"
if cmp -s "$T/sums_local" "$T/sums_killed"; then ok; else
  bad "outputs after the killed setup's rerun differ from the local run's: $(diff "$T/sums_local" "$T/sums_killed" | head -5)"
fi
rm -rf "$T/farm"

# 3c. Three setups (hard-linked copies of ext) grouped on the 2 CPUs: the
# Slurm job that ends its setup first goes on with the third setup at once
# (no wait for Slurm's next pass), so the third setup's own Slurm job finds
# it taken and ends; the other, its setup done while the third still has
# jobs nobody took, helps it (its log says so) instead of ending; every job
# ran (its stamp written this run), all ok, with its outputs; the setups'
# scripts and claims are removed. (That each job runs once, whichever Slurm
# job took it, is tests/test_pipeline_share.c's.)
cp -al "$T/ext" "$T/s1" && cp -al "$T/ext" "$T/s2" && cp -al "$T/ext" "$T/s3"
expect 0 "$S" process "$T/s1" "$T/s2" "$T/s3" -o "$T/three" "${P[@]}" --farm slurm --farm-group setup --json -q
json_eval "$T/out" 'd["jobs"]["failed"] == 0 and d["jobs"]["ran"] == d["jobs"]["total"] and all(s["status"] == "ok" for s in d["setups"])'
ran_by=$(cd "$T/three/logs" && grep -H '^setlight: setup ' s?.slurm.log | sed 's/\.slurm\.log:setlight: setup / /' | sort)
if [ "$(echo "$ran_by" | awk '{print $2}' | sort | tr '\n' ' ')" = "s1 s2 s3 " ] &&
  [ -n "$(echo "$ran_by" | awk '$1 != $2')" ]; then ok; else
  bad "each setup once, one by another setup's Slurm job: $(echo "$ran_by" | tr '\n' ';')"
fi
if grep -q "^setlight: helping setup s" "$T/three/logs"/s?.slurm.log; then ok; else
  bad "no Slurm job helped the last setup: $(cat "$T/three/logs"/s?.slurm.log | tr '\n' ';')"
fi
if ls -d "$T/three/logs"/farm-* >/dev/null 2>&1; then bad "the grouped setups' scripts were left"; else ok; fi
for s in s1 s2 s3; do present "$T/three/$s/stitch/hdri.exr"; present "$T/three/$s/rig/rig.usda"; done
rm -rf "$T/three"
mv "$T/farm_by_job" "$T/farm"

# 4. Everything up to date: nothing to submit, so no Slurm needed. Then the
# cluster down with a job to run (the rig's stamp gone): one line, exit 1,
# nothing written over.
stop_cluster
trap - EXIT
expect 0 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --json -q
json_eval "$T/out" 'all(j["status"] == "skipped" for j in d["setups"][0]["jobs"])'
sha_before=$(sha256sum <"$T/farm/ext/rig/rig.usda")
rm "$T/farm/ext/rig.stamp.json"
expect 1 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm -q
err_one_line
if [ "$(sha256sum <"$T/farm/ext/rig/rig.usda")" = "$sha_before" ]; then ok; else bad "a failed farm run changed an output"; fi
# The same grouped by setup: the setups' scripts are not left behind.
expect 1 "$S" process "$T/ext" -o "$T/farm" "${P[@]}" --farm slurm --farm-group setup -q
err_one_line
if ls -d "$T/farm/logs"/farm-* >/dev/null 2>&1; then bad "the grouped setups' scripts were left"; else ok; fi
finish
