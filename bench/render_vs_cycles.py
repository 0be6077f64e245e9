#!/usr/bin/python3
"""setlight render vs Blender Cycles: relative RMSE at equal wall time.

    /usr/bin/python3 bench/render_vs_cycles.py [--runs 3] [--cycles-spp 16]
        [--ref-spp 1024] [--cases grey,chrome,metal0.3,metal0.8,plastic0.4]
        [--work /tmp/setlight-bench/render] [--setlight build/setlight]

Same scene in both: a unit sphere at the origin, orthographic camera framing it at
80% of the width (the peers' cycles_scene.py camera), 512x512, lit by the peers'
sky-and-sun lat-long (envgen.py env_test.exr, 2048x1024, sun 5e4 = 58% of the
power in 42 texels). Cycles' world (+Z up, camera at -Y looking +Y) maps to
setlight's (+Y up) by (x, y, z)_setlight = (y, z, x)_cycles, so setlight's camera
sits at (-10, 0, 0) looking +X with +Y up; both then see the same lat-long texels
(checked below by the agreement of each case's Cycles renders with the reference).
Cycles' pixel filter is 0.01 px wide, so setlight samples pixel centres
(--pixel-centers) and both estimate the same pixel values.

Per case: a setlight reference (two halves of --ref-spp samples, seeds 1001/1002,
whose own noise (h1-h2)^2/4 is subtracted from every MSE); --runs Cycles renders of
--cycles-spp samples (seeds 1..runs, 2 threads, a fresh `blender -b` each); the
median Cycles render time T (sync + path tracing, Blender's start-up excluded) is
the budget; --runs setlight renders (seeds 1..runs, 2 threads) with --time chosen so
that setlight's whole process (reading the EXR, building the dome distribution,
rendering, writing) takes T. Errors: RMSE over the sphere pixels (1 px rim left
out) and RGB, divided by the reference's mean there (the peers' analyze_ibl.py
definition). Printed: medians over the runs and the ratio Cycles / setlight.

Agreement: the mean of the Cycles runs against the setlight reference, with the
noise of both removed (systematic rel. RMSE) and the mean bias; material models
differ slightly (Cycles' Principled BSDF vs setlight's conductor/plastic; see
docs/render.md), so the rough cases show a few % of model difference, the grey
and mirror cases none. Cycles renders and references are cached in --work.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

PEERS = os.environ.get("SETLIGHT_PEERS", "/work/shared/peers/render")
sys.path.insert(0, PEERS)
os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import numpy as np  # noqa: E402

import driver  # noqa: E402  (peers: runs cycles_scene.py in blender -b)
from common import load_exr, sphere_mask  # noqa: E402

RES = 512
HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = {"preset": "grey",
         "camera": {"type": "orthographic", "position": [-10, 0, 0], "look_at": [0, 0, 0],
                    "up": [0, 1, 0], "width": 2.5}}
# name -> (cycles_scene.py options, setlight --material)
CASES = {
    "grey": (dict(mat="diffuse"), "lambert:0.18,0.18,0.18"),
    "chrome": (dict(mat="mirror"), "conductor:1,1,1:0"),
    "metal0.3": (dict(mat="metal", rough=0.3), "conductor:0.9,0.9,0.9:0.3"),
    "metal0.8": (dict(mat="metal", rough=0.8), "conductor:0.9,0.9,0.9:0.8"),
    "plastic0.4": (dict(mat="plastic", rough=0.4), "plastic:0.5,0.5,0.5:0.4"),
}


def setlight_render(a, material, out, seed, spp=None, seconds=None):
    cmd = [a.setlight, "render", "--quiet", "--env", a.env, "--scene", a.scene, "--material", material,
           "--width", str(RES), "--pixel-centers", "--seed", str(seed), "--stats", out + ".json",
           "-o", out]
    cmd += ["--spp", str(spp)] if spp else ["--time", "%.4f" % seconds]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t0
    st = json.load(open(out + ".json"))
    return dict(wall=wall, render_s=st["seconds"], spp=st["spp"],
                sps=st["samples_per_second"], cpu_s=st["cpu_seconds"])


def rel_rmse(img, ref, ref_var, mask):
    d = (img - ref)[mask]
    mse = float(np.mean(d * d)) - float(np.mean(ref_var[mask]))
    return max(mse, 0.0) ** 0.5 / float(np.mean(ref[mask]))


def reference(a, name, material):
    halves = []
    for s in (1001, 1002):
        p = os.path.join(a.work, "ref_%s_%d_s%d.exr" % (name, a.ref_spp, s))
        if not os.path.exists(p):
            r = setlight_render(a, material, p, s, spp=a.ref_spp)
            print("  reference half seed %d: %d spp in %.1f s" % (s, r["spp"], r["wall"]), flush=True)
        halves.append(load_exr(p))
    return 0.5 * (halves[0] + halves[1]), (halves[0] - halves[1]) ** 2 / 4.0


def cycles_runs(a, name, opts):
    runs = []
    for seed in range(1, a.runs + 1):
        p = os.path.join(a.work, "cy_%s_%dspp_s%d.exr" % (name, a.cycles_spp, seed))
        meta = p + ".json"
        if not os.path.exists(meta):
            r = driver.render(p, log=p + ".log", env=a.env, res=RES, spp=a.cycles_spp, seed=seed,
                              threads=2, **opts)
            json.dump(r, open(meta, "w"))
        runs.append(json.load(open(meta)))
    return runs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cycles-spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=1024, help="setlight reference, per half")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--work", default="/tmp/setlight-bench/render")
    ap.add_argument("--cycles-only", action="store_true", help="only render (and cache) the Cycles runs")
    ap.add_argument("--setlight", default=os.path.join(HERE, "..", "build", "setlight"))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    a.env = os.path.join(a.work, "env_test.exr")
    if not os.path.exists(a.env):
        subprocess.run(["/usr/bin/python3", os.path.join(PEERS, "envgen.py"), a.work], check=True)
    a.scene = os.path.join(a.work, "scene_cycles_camera.json")
    json.dump(SCENE, open(a.scene, "w"))
    mask = sphere_mask(RES)
    rows = []
    for name in a.cases.split(","):
        opts, material = CASES[name]
        print("%s:" % name, flush=True)
        if a.cycles_only:
            for r in cycles_runs(a, name, opts):
                print("  Cycles seed %d: %.2f s, other load %.2f cores" % (r["seed"], r["cycles_time_s"], r["others_cores"]))
            continue
        ref, ref_var = reference(a, name, material)
        mref = float(np.mean(ref[mask]))
        cy = cycles_runs(a, name, opts)
        cy_img = [load_exr(r["out"]) for r in cy]
        cy_err = [rel_rmse(im, ref, ref_var, mask) for im in cy_img]
        budget = statistics.median(r["cycles_time_s"] for r in cy)
        # setlight's fixed cost (read, build, write) from a short run, so the whole
        # process fits the budget
        probe = setlight_render(a, material, os.path.join(a.work, "sl_probe.exr"), 99, spp=2)
        overhead = probe["wall"] - probe["render_s"]
        sl, sl_err = [], []
        for seed in range(1, a.runs + 1):
            p = os.path.join(a.work, "sl_%s_s%d.exr" % (name, seed))
            r = setlight_render(a, material, p, seed, seconds=max(0.02, budget - overhead))
            sl.append(r)
            sl_err.append(rel_rmse(load_exr(p), ref, ref_var, mask))
        # agreement of Cycles with the reference: error of the mean of the runs minus
        # its noise (spread of the runs / runs) and the reference's
        cm = np.mean(cy_img, axis=0)
        cvar = np.var(cy_img, axis=0, ddof=1) / len(cy_img) if len(cy_img) > 1 else np.zeros_like(cm)
        d = (cm - ref)[mask]
        sys_mse = float(np.mean(d * d) - np.mean(cvar[mask]) - np.mean(ref_var[mask]))
        cy_cpu = statistics.median(r["render_cpu_s"] for r in cy)
        sl_cpu = statistics.median(r["cpu_s"] for r in sl)
        row = dict(case=name, material=material, cycles=opts, ref_spp=2 * a.ref_spp,
                   ref_noise=float(np.sqrt(np.mean(ref_var[mask]))) / mref,
                   cycles_spp=a.cycles_spp, cycles_render_s=budget, cycles_cpu_s=cy_cpu,
                   cycles_wall_s=statistics.median(r["wall_total_s"] for r in cy),
                   cycles_other_load=statistics.median(r["others_cores"] for r in cy),
                   cycles_err=statistics.median(cy_err),
                   cycles_noise=float(np.sqrt(np.mean(cvar[mask]) * len(cy_img))) / mref,
                   setlight_wall_s=statistics.median(r["wall"] for r in sl), setlight_cpu_s=sl_cpu,
                   setlight_spp=statistics.median(r["spp"] for r in sl),
                   setlight_sps=statistics.median(r["sps"] for r in sl),
                   setlight_err=statistics.median(sl_err),
                   agree_sys=max(sys_mse, 0.0) ** 0.5 / mref,
                   agree_bias=float(np.mean(cm[mask])) / mref - 1.0,
                   agree_median_px=float(np.median(np.abs(cm - ref)[mask] / np.maximum(ref[mask], 1e-9))),
                   cycles_errs=cy_err, setlight_errs=sl_err)
        # Cycles' own noise (spread of its runs) against setlight's error: model
        # differences between the two BSDFs do not count against Cycles
        e_sl = row["setlight_err"]
        row["ratio"] = row["cycles_noise"] / e_sl if e_sl > 0 else float("inf")
        # the same at equal CPU time (error ~ 1/sqrt(time)), less sensitive to other load
        row["ratio_cpu"] = row["ratio"] * (cy_cpu / sl_cpu) ** -0.5 if e_sl > 0 else float("inf")
        rows.append(row)
        print("  Cycles %d spp %.2f s: noise %.4f (vs reference %.4f) | setlight %d spp %.2f s: %.4f | "
              "ratio %.2f | Cycles vs reference: systematic %.4f, bias %+.4f, median px %.4f" % (
                  a.cycles_spp, budget, row["cycles_noise"], row["cycles_err"], row["setlight_spp"],
                  row["setlight_wall_s"], row["setlight_err"], row["ratio"], row["agree_sys"],
                  row["agree_bias"], row["agree_median_px"]), flush=True)
    json.dump(rows, open(os.path.join(a.work, "results_%dspp.json" % a.cycles_spp), "w"), indent=1)
    print("\n| case | Cycles spp | Cycles render s (process wall; CPU s) | Cycles rel RMSE: noise (vs ref) "
          "| setlight spp | setlight wall s (CPU s) | setlight rel RMSE | ratio Cycles/setlight at equal "
          "wall (CPU) | Cycles vs ref: systematic, bias, median px |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| %s | %d | %.2f (%.2f; %.2f) | %.2f%% (%.2f%%) | %d | %.2f (%.2f) | %.3f%% | %.1f (%.1f) "
              "| %.2f%%, %+.2f%%, %.2f%% |" % (
                  r["case"], r["cycles_spp"], r["cycles_render_s"], r["cycles_wall_s"], r["cycles_cpu_s"],
                  100 * r["cycles_noise"], 100 * r["cycles_err"], r["setlight_spp"], r["setlight_wall_s"],
                  r["setlight_cpu_s"], 100 * r["setlight_err"], r["ratio"], r["ratio_cpu"],
                  100 * r["agree_sys"], 100 * r["agree_bias"], 100 * r["agree_median_px"]))
    print("medians of %d runs; reference: setlight, %d spp per case (pixel centres); Cycles other load "
          "(cores): %s" % (a.runs, 2 * a.ref_spp, ", ".join("%.2f" % r["cycles_other_load"] for r in rows)))


if __name__ == "__main__":
    main()
