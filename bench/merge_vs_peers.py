#!/usr/bin/python3
"""setlight merge vs the peers (OpenCV Debevec and Robertson, pfstools, Luminance HDR) on the
same simulated brackets, same machine, one run: wall, CPU, peak memory, accuracy vs ground truth,
and setlight's ratios to each peer (medians over --repeats runs).

  /usr/bin/python3 bench/merge_vs_peers.py                  # 2048x1024, stacks 7x3 and 5x2, 3 runs
  /usr/bin/python3 bench/merge_vs_peers.py --big            # 6000x4000 7x3 (TIFF and JPEG), 1 run

The scene, camera model, timing (measure.py: /usr/bin/time -v plus /proc polling) and scoring
(evaluate.py: luminance error after one fitted scale over the mid-tones) are the peers' own
scripts in ../shared/peers/merge (see its RESULTS.md); they are copied into --work with the
generated data, so nothing is written beside them. Peers come from scripts/install-peers.sh.
"""
import argparse
import glob
import json
import math
import os
import shutil
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PY = "/usr/bin/python3"


def peers_configs(stack, out, times, big):
    """name -> shell command run from the work folder (self-calibrated responses only: what a
    user gets from the bracket alone)."""
    n = len(times)
    imgs = " ".join("img_%02d.tif" % i for i in range(n))
    evs = ",".join("%g" % math.log2(t) for t in times)
    up = os.path.relpath(".", stack)
    o = lambda name: os.path.join(up, out, name + ".exr")
    lum = "QT_QPA_PLATFORM=offscreen luminance-hdr-cli"
    c = {}
    c["opencv_debevec"] = "%s run_opencv.py --stack %s --mode debevec_calib --out %s/opencv_debevec.exr" % (PY, stack, out)
    # CalibrateRobertson takes minutes at 24 MP (341 s in RESULTS.md): at that size its merge
    # with the true curve stands in for the time.
    rmode = "robertson_true" if big else "robertson_calib"
    c["opencv_robertson"] = "%s run_opencv.py --stack %s --mode %s --out %s/opencv_robertson.exr" % (PY, stack, rmode, out)
    c["pfstools"] = "cd %s && pfsinhdrgen stack.hdrgen | pfshdrcalibrate | pfsoutexr %s" % (stack, o("pfstools"))
    c["luminance_hdr"] = "cd %s && %s -e %s -s %s %s" % (stack, lum, evs, o("luminance_hdr"), imgs)
    return c


def run(work, name, cmd, log):
    subprocess.run([PY, "measure.py", "--name", name, "--cwd", ".", "--out", log, "--", cmd],
                   cwd=work, check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(work, log)) as f:
        return json.loads(f.readlines()[-1])


def score(work, scene, stack, est, name):
    p = subprocess.run([PY, "evaluate.py", "--scene", os.path.join("work", "data", scene),
                        "--stack", stack, "--est", est, "--name", name],
                       cwd=work, check=True, capture_output=True, text=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--big", action="store_true", help="6000x4000 x 7 instead of 2048x1024")
    ap.add_argument("--repeats", type=int, default=None, help="runs per tool (default 3, 1 with --big)")
    ap.add_argument("--peers", default=os.environ.get("SETLIGHT_PEERS", os.path.join(HERE, "..", "..", "shared", "peers", "merge")))
    ap.add_argument("--work", default="/tmp/setlight-bench-merge")
    ap.add_argument("--setlight", default=os.path.join(HERE, "..", "build", "setlight"))
    ap.add_argument("--only", default=None, help="comma list of tool names")
    a = ap.parse_args()
    repeats = a.repeats or (1 if a.big else 3)
    work = os.path.abspath(a.work)
    os.makedirs(work, exist_ok=True)
    for f in glob.glob(os.path.join(a.peers, "*.py")):
        shutil.copy(f, work)
    scene = "synth6k" if a.big else "synth2k"
    stacks = ["7x3"] if a.big else ["7x3", "5x2"]
    if not os.path.exists(os.path.join(work, "work", "data", scene, stacks[0], "times.txt")):
        subprocess.run([PY, "make_data.py"] + (["--only-big"] if a.big else []), cwd=work, check=True)
    sl = os.path.abspath(a.setlight)
    rows = []
    for st in stacks:
        stack = os.path.join("work", "data", scene, st)
        out = os.path.join("work", "out", "%s_%s" % (scene, st))
        os.makedirs(os.path.join(work, out), exist_ok=True)
        times = [float(x) for x in open(os.path.join(work, stack, "times.txt")) if x.strip()]
        tl = ",".join("%.10g" % t for t in times)
        frames = " ".join(os.path.join(stack, "img_%02d.tif" % i) for i in range(len(times)))
        cfg = {"setlight": "%s merge --times %s -o %s/setlight.exr %s" % (sl, tl, out, frames)}
        if a.big:
            # The case: the same bracket as 8-bit JPEGs (quality 95).
            jdir = os.path.join(work, stack, "jpg")
            if not os.path.isdir(jdir):
                os.makedirs(jdir)
                for i in range(len(times)):
                    subprocess.run([PY, "-c", "import cv2,sys; cv2.imwrite(sys.argv[2], cv2.imread(sys.argv[1]), [cv2.IMWRITE_JPEG_QUALITY, 95])",
                                    os.path.join(work, stack, "img_%02d.tif" % i), os.path.join(jdir, "img_%02d.jpg" % i)], check=True)
            jframes = " ".join(os.path.join(stack, "jpg", "img_%02d.jpg" % i) for i in range(len(times)))
            cfg["setlight_jpeg"] = "%s merge --times %s -o %s/setlight_jpeg.exr %s" % (sl, tl, out, jframes)
        cfg.update(peers_configs(stack, out, times, a.big))
        if a.only:
            keep = a.only.split(",")
            cfg = {k: v for k, v in cfg.items() if k in keep}
        for name, cmd in cfg.items():
            recs = []
            for r in range(repeats):
                est = os.path.join(out, name + ".exr")
                if os.path.exists(os.path.join(work, est)):
                    os.unlink(os.path.join(work, est))
                t = run(work, "%s/%s/%s#%d" % (scene, st, name, r), cmd, "bench_runs.jsonl")
                acc = score(work, scene, st, est, name) if t["rc"] == 0 else {"failure": "exit %d" % t["rc"]}
                recs.append((t, acc))
            med = lambda k: statistics.median(t.get(k, float("nan")) for t, _ in recs)
            acc = recs[-1][1]
            get = lambda reg, k: acc.get(reg, {}).get(k, float("nan")) if isinstance(acc.get(reg), dict) else float("nan")
            rows.append({"stack": st, "tool": name, "wall": med("wall_s"), "cpu": med("cpu_s"),
                         "peak_mb": max(med("gnu_maxrss_mb"), med("tree_peak_mb")),
                         "mid_med": get("mid", "median"), "all_p99": get("all", "p99"),
                         "sun_energy": acc.get("sun_energy_ratio", float("nan")),
                         "bad": sum(acc.get(k, 0) for k in ("n_nan", "n_inf", "n_neg")),
                         "failure": acc.get("failure", "")})
            print("%-6s %-18s wall %6.2f s  cpu %6.2f s  peak %6.0f MB  mid %.2f%%  p99 %.1f%%  sun %.2f %s"
                  % (st, name, rows[-1]["wall"], rows[-1]["cpu"], rows[-1]["peak_mb"],
                     100 * rows[-1]["mid_med"], 100 * rows[-1]["all_p99"], rows[-1]["sun_energy"],
                     rows[-1]["failure"]), flush=True)
    size = "6000x4000" if a.big else "2048x1024"
    print("\n%s, median of %d run(s); ratio = peer / setlight (above 1: setlight better)" % (size, repeats))
    print("| stack | tool | wall s | CPU s | peak MB | mid-tone median err | p99 err (all) | sun energy | wall ratio | CPU ratio | memory ratio | error ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        # Ratios against setlight's own row (its JPEG run when --only leaves the TIFF one out).
        base = next((x for x in rows if x["stack"] == row["stack"] and x["tool"] == "setlight"),
                    next(x for x in rows if x["stack"] == row["stack"]))
        print("| %s | %s | %.2f | %.2f | %.0f | %.2f %% | %.1f %% | %.2f | %.1f | %.1f | %.1f | %.1f |" % (
            row["stack"], row["tool"], row["wall"], row["cpu"], row["peak_mb"], 100 * row["mid_med"],
            100 * row["all_p99"], row["sun_energy"], row["wall"] / base["wall"],
            row["cpu"] / base["cpu"], row["peak_mb"] / base["peak_mb"],
            row["mid_med"] / base["mid_med"]))


if __name__ == "__main__":
    main()
