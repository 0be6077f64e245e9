#!/bin/bash
# setlight demo at the tiny size: the virtual stage simulated, processed by
# `setlight process`, every stage scored against the truth. The numbers come
# from `demo --json`; the bounds are what the pipeline gives now at tiny with
# a margin (docs/virtual-set.md "The demo"), so a stage that gets worse fails.
. "$(dirname "$0")/lib.bash"
S="$SETLIGHT"

expect 0 "$S" demo --help
for o in --size --seed --force --check --json; do out_has "$o"; done

# The chart detector (OpenCV mcc) leaks inside OpenCV, as in calibrate.sh.
printf 'leak:cv::fastMalloc\n' >"$T/lsan.supp"
export LSAN_OPTIONS="suppressions=$T/lsan.supp"

expect 0 "$S" demo "$T/demo" --size tiny --json --quiet
json_ok "$T/out"
cp "$T/out" "$T/score.json"
present "$T/demo/report.html"
present "$T/demo/process/capture/report.html"
present "$T/demo/process/capture/rig/rig.usda"
present "$T/demo/capture/truth/latlong.exr"
json_eval "$T/score.json" 'd == json.load(open(sys.argv[1].replace("/score.json", "/demo/score.json")))'
no_temp "$T/demo"
# calibrate records the white it balanced to: the chart's light
json_eval "$T/demo/process/capture/calibrate/calibrate.result.json" 'd["white"] == "chart"'
json_eval "$T/score.json" '[s["name"] for s in d["stages"]] == ["simulate", "merge", "stitch", "unwrap", "calibrate", "rig", "render"]'

if python3 - "$T/score.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
st = {s["name"]: s for s in d["stages"]}
n = {k: s["numbers"] for k, s in st.items()}
def near(x, target, off):
    return abs(x - target) <= off
checks = {
    # every view's and probe's merge against the radiance its frames saw (1.3% at tiny)
    "merge median": n["merge"]["merges"] == 5 and n["merge"]["worst_median_rel_error"] < 0.03,
    # the fisheye views' merges disagree in scale (1.45x at tiny): not worse
    "merge spread": 1 <= n["merge"]["view_scale_spread"] < 2.0,
    # the lat-longs within 60 deg of the horizon (2.9% / 47% / 1.02 at tiny: no pair
    # solved, the poses planned, the focal from the image circle; docs/virtual-set.md)
    "stitch": n["stitch"]["median_rel_error"] < 0.05 and n["stitch"]["p95_rel_error"] < 0.65
              and near(n["stitch"]["power_ratio"], 1, 0.08),
    # against the truth with the chart's light made white, as the chart fit balances:
    # balance 0.994 1.003 0.986 at tiny (0.84 1.04 1.19 against the radiance itself)
    "calibrate": n["calibrate"]["median_rel_error"] < 0.05 and n["calibrate"]["p95_rel_error"] < 0.65
                 and near(n["calibrate"]["power_ratio"], 1, 0.08)
                 and n["calibrate"]["white"] == "chart"
                 and all(near(b, 1, 0.05) for b in n["calibrate"]["channel_balance"])
                 # the stage's light on the chart is warm (kinos, bulbs at 2700-3200 K)
                 and n["calibrate"]["chart_light"][0] > 1.05 > 0.95 > n["calibrate"]["chart_light"][2]
                 and n["calibrate"]["vs_radiance"]["channel_balance"][2] > 1.1
                 # the map against the grey ball's photo read through the same plate matrix:
                 # 0.960 at tiny, the stitch's planned poses (0.9995 at small, solved)
                 and near(n["calibrate"]["exposure_vs_grey"], 1, 0.06)
                 and n["calibrate"]["units"] in ("relative", "cd/m2"),
    # the chrome ball's half of the set (6.4%), and against the stitch (12.7%)
    "unwrap": n["unwrap"]["median_rel_error"] < 0.12 and n["unwrap"]["vs_stitch"]["median_rel_error"] < 0.25,
    # 5 of the 7 lamps (the others are within a few degrees of each other), 2.0 deg;
    # power 1.023 in the chart's white, the rig's map's white (1.033 of the physical lamps)
    "rig": n["rig"]["matched"] >= 4 and n["rig"]["truth_lights"] == 7
           and n["rig"]["direction_worst_deg"] < 4 and near(n["rig"]["power_median"], 1, 0.12)
           and n["rig"]["white"] == "chart"
           and n["rig"]["power_median"] != n["rig"]["vs_radiance"]["power_median"],
    # the six renders against the scenes under the truth in the calibration's white
    # (4.9% grey/chart, 30.0% chrome at tiny; 17.6% and 37.8% in the truth's own white)
    "render": n["render"]["renders"] == 6 and n["render"]["worst_rel_rmse"] < 0.10
              and n["render"]["worst_chrome_rel_rmse"] < 0.45,
}
# each verdict is the stage's numbers against its stated tolerances
t = {k: s["tolerances"] for k, s in st.items()}
m, ll = n["merge"], n["stitch"]
verdicts = {
    "merge": m["worst_median_rel_error"] <= t["merge"]["median_rel_error"]
             and m["view_scale_spread"] <= t["merge"]["view_scale_spread"],
    "stitch": ll["median_rel_error"] <= t["stitch"]["median_rel_error"]
              and ll["p95_rel_error"] <= t["stitch"]["p95_rel_error"]
              and abs(ll["power_ratio"] - 1) <= t["stitch"]["power_ratio_off"],
    "unwrap": n["unwrap"]["median_rel_error"] <= t["unwrap"]["median_rel_error"],
    "calibrate": n["calibrate"]["median_rel_error"] <= t["calibrate"]["median_rel_error"]
                 and n["calibrate"]["p95_rel_error"] <= t["calibrate"]["p95_rel_error"]
                 and abs(n["calibrate"]["power_ratio"] - 1) <= t["calibrate"]["power_ratio_off"]
                 and all(abs(b - 1) <= t["calibrate"]["channel_balance_off"]
                         for b in n["calibrate"]["channel_balance"])
                 and abs(n["calibrate"]["exposure_vs_grey"] - 1) <= t["calibrate"]["exposure_vs_grey_off"]
                 and (n["calibrate"]["units"] == "relative"
                      or abs(n["calibrate"]["scale"] - 1) <= t["calibrate"]["absolute_scale_off"]),
    "render": all(i["rel_rmse"] <= (t["render"]["chrome_rel_rmse"] if i["scene"] == "chrome"
                                    else t["render"]["rel_rmse"]) for i in n["render"]["images"]),
}
checks["verdicts"] = all(st[k]["pass"] == v for k, v in verdicts.items())
checks["passed"] = d["passed"] == all(s["pass"] for s in d["stages"]) and \
    d["stages_failed"] == sum(not s["pass"] for s in d["stages"])
# the cost: every stage's wall and CPU time, each process job's
checks["cost"] = all(s["seconds"] > 0 and s["cpu_seconds"] > 0 for s in d["stages"] if s["name"] != "unwrap") \
    and len(d["cost"]["process_jobs"]) == 16 and d["cost"]["process_job_counts"]["total"] == 17 \
    and d["cost"]["simulate_seconds"] > 0 \
    and all(s["jobs_ran"] >= 1 for s in d["stages"] if s["name"] != "simulate")
bad = [k for k, v in checks.items() if not v]
if bad:
    print("off:", bad, json.dumps(n)[:3000])
sys.exit(1 if bad else 0)
PY
then ok; else bad "demo --json numbers off"; fi

# the human output: one line per stage with its verdict, then the report's path;
# --check: exit 1 and one line on stderr when a stage is outside its tolerances, else 0
want=0
python3 -c 'import json,sys; sys.exit(0 if json.load(open(sys.argv[1]))["passed"] else 1)' "$T/score.json" || want=1
expect $want "$S" demo "$T/demo" --size tiny --force --check
[ "$(grep -cE '^(simulate|merge|stitch|unwrap|calibrate|rig|render) +(pass|FAIL) ' "$T/out")" = 7 ] && ok || bad "summary: $(head -c 600 "$T/out")"
out_has "report: $T/demo/report.html"
if [ $want = 1 ]; then err_one_line; err_has "stages outside their tolerances"; fi
browser_check "$T/demo/report.html" 1

before=$(md5sum "$T/demo/report.html")
expect 2 "$S" demo "$T/demo" --size tiny
err_has "--force"
err_one_line
[ "$before" = "$(md5sum "$T/demo/report.html")" ] && ok || bad "report changed without --force"

mkdir -p "$T/busy" && echo mine > "$T/busy/notes.txt"
expect 2 "$S" demo "$T/busy" --size tiny
err_has "busy"
[ "$(ls "$T/busy")" = "notes.txt" ] && ok || bad "busy folder was touched"
expect 2 "$S" demo "$T/x" --size full
err_has "full"
absent "$T/x"
expect 1 "$S" demo /proc/setlight-nope --size tiny
err_has "/proc/setlight-nope"

finish
