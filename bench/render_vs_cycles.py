#!/usr/bin/python3
"""setlight render vs Blender Cycles: relative RMSE at equal wall time.

    /usr/bin/python3 bench/render_vs_cycles.py [--runs 3] [--cycles-spp 16]
        [--ref-spp 1024] [--cases grey,shadow,chrome,metal0.3,metal0.8,plastic0.4]
        [--quad-stride 16]
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

Per case: a setlight reference (the sampler alone, --closed-form off: two halves of
--ref-spp samples, seeds 1001/1002,
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
    # the grey ball on an 8 x 8 grey ground 1 below its centre (setlight's `shadow`
    # preset's ball and ground; Cycles z = -1), direct light only in both (Cycles
    # max_bounces 0, setlight --bounces 0): the ground hides the lower sky from the ball
    "shadow": (dict(mat="diffuse"), "lambert:0.18,0.18,0.18"),
    "chrome": (dict(mat="mirror"), "conductor:1,1,1:0"),
    "metal0.3": (dict(mat="metal", rough=0.3), "conductor:0.9,0.9,0.9:0.3"),
    "metal0.8": (dict(mat="metal", rough=0.8), "conductor:0.9,0.9,0.9:0.8"),
    "plastic0.4": (dict(mat="plastic", rough=0.4), "plastic:0.5,0.5,0.5:0.4"),
}
# cases whose reference is the quadrature below (setlight computes them in closed form,
# so a setlight reference would only compare setlight with itself)
QUADRATURE_CASES = ("grey", "shadow")
SHADOW_SCENE = {"preset": "shadow", "camera": SCENE["camera"]}

# Blender script for the shadow case: the peers' cycles_scene.py, its build() followed by
# the ground (the same material) and direct lighting only.
GROUND_WRAPPER = r'''
import os, sys
import bpy
path = os.path.join(os.environ.get("SETLIGHT_PEERS", "/work/shared/peers/render"), "cycles_scene.py")
src = open(path).read().rstrip()
assert src.endswith("main()"), "cycles_scene.py no longer ends with main()"
ns = {"__name__": "cycles_scene", "__file__": path}
exec(compile(src[:-len("main()")], path, "exec"), ns)
peers_build = ns["build"]


def build(a):
    sc = peers_build(a)
    me = bpy.data.meshes.new("Ground")
    me.from_pydata([(-4, -4, -1), (4, -4, -1), (4, 4, -1), (-4, 4, -1)], [], [(0, 1, 2, 3)])
    me.materials.append(bpy.data.materials["M"])
    ob = bpy.data.objects.new("Ground", me)
    sc.collection.objects.link(ob)
    sc.cycles.max_bounces = 0
    return sc


ns["build"] = build
ns["main"]()
'''


def setlight_render(a, material, out, seed, spp=None, seconds=None, scene=None, extra=()):
    cmd = [a.setlight, "render", "--quiet", "--env", a.env, "--scene", scene or a.scene, "--material", material,
           "--width", str(RES), "--pixel-centers", "--seed", str(seed), "--stats", out + ".json",
           "-o", out] + list(extra)
    cmd += ["--spp", str(spp)] if spp else ["--time", "%.4f" % seconds]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t0
    st = json.load(open(out + ".json"))
    cf = st.get("closed_form", {})
    return dict(wall=wall, render_s=st["seconds"], spp=st["spp"],
                sps=st["samples_per_second"], cpu_s=st["cpu_seconds"],
                cf_exact=cf.get("exact_pixels", 0), cf_control=cf.get("control_variate_pixels", 0),
                cf_cut=cf.get("cut_by_time", False))


def rel_rmse(img, ref, ref_var, mask):
    d = (img - ref)[mask]
    mse = float(np.mean(d * d)) - float(np.mean(ref_var[mask]))
    return max(mse, 0.0) ** 0.5 / float(np.mean(ref[mask]))


def latlong_cells(env, down, bright_frac):
    """Lat-long cells of down x down texels as vector irradiance sums (per channel:
    sum of L w dOmega over the texels, exact for n.w linear, i.e. wherever the cell
    is wholly above the horizon), except the brightest texels (bright_frac of the
    power: the sun), which stay single texels. setlight's lat-long convention:
    u -> longitude pi (1 - 2u), v -> latitude pi (0.5 - v), w = (sin lon cos lat,
    sin lat, cos lon cos lat)."""
    h, w = env.shape[:2]
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    lat = np.pi * (0.5 - v)[:, None]
    lon = np.pi * (1.0 - 2.0 * u)[None, :]
    dirs = np.stack([np.sin(lon) * np.cos(lat), np.sin(lat) * np.ones_like(lon), np.cos(lon) * np.cos(lat)], -1)
    om = ((np.cos(np.pi * np.arange(h) / h) - np.cos(np.pi * (np.arange(h) + 1) / h)) * 2 * np.pi / w)[:, None]
    power = env * om[..., None]                      # L dOmega per texel and channel
    lumw = power @ np.array([0.2126, 0.7152, 0.0722])
    order = np.argsort(lumw, axis=None)[::-1]
    cum = np.cumsum(lumw.ravel()[order])
    nb = int(np.searchsorted(cum, bright_frac * cum[-1])) + 1
    bright = np.zeros(h * w, bool)
    bright[order[:nb]] = True
    bright = bright.reshape(h, w)
    rest = np.where(bright[..., None], 0.0, power)
    # vector sums: V[c, k] = sum over the cell of L_c dOmega w_k
    vec = rest[..., :, None] * dirs[..., None, :]    # h, w, 3 (c), 3 (k)
    vec = vec.reshape(h // down, down, w // down, down, 3, 3).sum(axis=(1, 3)).reshape(-1, 3, 3)
    bvec = (power[bright][:, :, None] * dirs[bright][:, None, :])
    return np.concatenate([vec, bvec]), nb


def quadrature(a, name, mask, stride):
    """Reference of the Lambert cases, independent of setlight's code: per pixel centre
    (every stride-th pixel of the mask), E = sum over cells of max(0, n.V_c), with the
    ground's visibility (shadow case) taken at each cell's mean direction. Cells of 4x4
    texels (8x8 with the ground), the brightest texels holding 60% of the power alone.
    Its own accuracy: the same at twice the cell size, printed."""
    env = load_exr(a.env)
    sel = np.zeros_like(mask)
    sel[stride // 2::stride, stride // 2::stride] = True
    sel &= mask
    iy, ix = np.nonzero(sel)
    c = (np.arange(RES) + 0.5) / RES - 0.5
    # setlight camera: at (-10, 0, 0) looking +X, +Y up, image right = +Z, width 2.5
    Z = (c * 2.5)[ix]
    Y = (-c * 2.5)[iy]
    X = -np.sqrt(np.clip(1 - Y * Y - Z * Z, 0, 1))
    P = np.stack([X, Y, Z], -1)                      # on the unit sphere: p = n

    def run(down):
        V, nb = latlong_cells(env, down, 0.6)
        Vl = np.einsum("nck,c->nk", V, np.array([0.2126, 0.7152, 0.0722]))  # mean direction
        D = Vl / np.maximum(np.linalg.norm(Vl, axis=1, keepdims=True), 1e-300)
        out = np.zeros((len(P), 3))
        for i0 in range(0, len(P), 256):
            n = P[i0:i0 + 256]
            vis = np.ones((len(n), len(V)))
            if name == "shadow":                      # ground: y = -1, |x|, |z| <= 4
                wy = np.minimum(D[None, :, 1], -1e-12)
                t = (-1.0 - n[:, 1:2]) / wy
                gx = n[:, 0:1] + t * D[None, :, 0]
                gz = n[:, 2:3] + t * D[None, :, 2]
                vis = ~((D[None, :, 1] < 0) & (np.abs(gx) <= 4) & (np.abs(gz) <= 4))
            for ch in range(3):
                out[i0:i0 + 256, ch] = (np.maximum(n @ V[:, ch, :].T, 0.0) * vis).sum(1)
        return out * 0.18 / np.pi, nb

    e1, nb = run(4 if name == "grey" else 8)
    e2, _ = run(8 if name == "grey" else 16)
    acc = float(np.sqrt(np.mean((e1 - e2) ** 2)) / np.mean(e1))
    ref = np.zeros((RES, RES, 3))
    ref[iy, ix] = e1
    print("  reference: quadrature over %d pixels (every %dth), %d sun texels alone; "
          "difference at twice the cell size %.4f%%" % (len(P), stride, nb, 100 * acc), flush=True)
    return ref, np.zeros_like(ref), sel, acc


def reference(a, name, material):
    halves = []
    for s in (1001, 1002):
        p = os.path.join(a.work, "ref_sampled_%s_%d_s%d.exr" % (name, a.ref_spp, s))
        if not os.path.exists(p):
            # the sampler alone: a reference independent of the glossy closed form
            r = setlight_render(a, material, p, s, spp=a.ref_spp, extra=("--closed-form", "off"))
            print("  reference half seed %d: %d spp in %.1f s" % (s, r["spp"], r["wall"]), flush=True)
        halves.append(load_exr(p))
    return 0.5 * (halves[0] + halves[1]), (halves[0] - halves[1]) ** 2 / 4.0


def closed_form_reference(a, name, material):
    """setlight's glossy closed form at a tight tolerance (--target-error 0.002): a
    sampled reference of a few hundred spp cannot resolve errors under about 1%
    (metal 0.3: 0.95%), so the --time 1 goal of 0.5% is also scored against this;
    its own distance to the sampled reference is printed beside it."""
    p = os.path.join(a.work, "ref_closed_form_%s.exr" % name)
    if not os.path.exists(p):
        r = setlight_render(a, material, p, 1, spp=1, extra=("--target-error", "0.002"))
        print("  tight closed form: %.1f s" % r["wall"], flush=True)
    return load_exr(p)


def cycles_render(a, name, opts, seed):
    p = os.path.join(a.work, "cy_%s_%dspp_s%d.exr" % (name, a.cycles_spp, seed))
    here = driver.HERE
    if name == "shadow":
        # driver runs HERE/cycles_scene.py: point it at the ground wrapper
        d = os.path.join(a.work, "cycles_ground")
        os.makedirs(d, exist_ok=True)
        open(os.path.join(d, "cycles_scene.py"), "w").write(GROUND_WRAPPER)
        os.environ["SETLIGHT_PEERS"] = PEERS
        driver.HERE = d
    try:
        r = driver.render(p, log=p + ".log", env=a.env, res=RES, spp=a.cycles_spp, seed=seed, threads=2, **opts)
    finally:
        driver.HERE = here
    json.dump(r, open(p + ".json", "w"))
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cycles-spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=1024, help="setlight reference, per half")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--work", default="/tmp/setlight-bench/render")
    ap.add_argument("--setlight", default=os.path.join(HERE, "..", "build", "setlight"))
    ap.add_argument("--time1-only", action="store_true",
                    help="only the --time 1 runs (no Cycles): the issue's 0.5%%-in-one-second goal")
    ap.add_argument("--quad-stride", type=int, default=16,
                    help="quadrature reference: every Nth pixel in x and y (grey, shadow)")
    a = ap.parse_args()
    print("render_vs_cycles %s, load average at start: %s" % (
        time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), open("/proc/loadavg").read().split()[:3]),
        flush=True)
    os.makedirs(a.work, exist_ok=True)
    a.env = os.path.join(a.work, "env_test.exr")
    if not os.path.exists(a.env):
        subprocess.run(["/usr/bin/python3", os.path.join(PEERS, "envgen.py"), a.work], check=True)
    a.scene = os.path.join(a.work, "scene_cycles_camera.json")
    json.dump(SCENE, open(a.scene, "w"))
    a.shadow_scene = os.path.join(a.work, "scene_cycles_camera_shadow.json")
    json.dump(SHADOW_SCENE, open(a.shadow_scene, "w"))
    mask = sphere_mask(RES)
    rows = []
    for name in a.cases.split(","):
        opts, material = CASES[name]
        scene = a.shadow_scene if name == "shadow" else a.scene
        print("%s:" % name, flush=True)
        if name in QUADRATURE_CASES:
            ref, ref_var, emask, ref_acc = quadrature(a, name, mask, a.quad_stride)
            ref_kind = "quadrature (%.3f%%)" % (100 * ref_acc)
        else:
            ref, ref_var = reference(a, name, material)
            emask = mask
            ref_kind = "setlight sampled %d spp" % (2 * a.ref_spp)
        mask_all, mask = mask, emask
        mref = float(np.mean(ref[mask]))
        cf_ref = None if name in QUADRATURE_CASES or name == "chrome" else closed_form_reference(a, name, material)
        if a.time1_only:
            for seed in range(1, a.runs + 1):
                p1 = os.path.join(a.work, "sl_%s_time1_s%d.exr" % (name, seed))
                t1 = setlight_render(a, material, p1, seed, seconds=1.0, scene=scene)
                img = load_exr(p1)
                e_cf = "" if cf_ref is None else ", %.3f%% vs the tight closed form" % (
                    100 * rel_rmse(img, cf_ref, np.zeros_like(cf_ref), mask))
                rows.append(dict(case=name, err=rel_rmse(img, ref, ref_var, mask)))
                print("  --time 1 seed %d (load %s): %.3f%% vs %s%s; %.2f s wall (%.2f CPU s), %d spp%s" % (
                    seed, open("/proc/loadavg").read().split()[0], 100 * rows[-1]["err"], ref_kind, e_cf,
                    t1["wall"], t1["cpu_s"], t1["spp"], ", plan cut" if t1["cf_cut"] else ""), flush=True)
            if cf_ref is not None:
                print("  the tight closed form vs %s: %.3f%%" % (ref_kind, 100 * rel_rmse(cf_ref, ref, ref_var, mask)),
                      flush=True)
            mask = mask_all
            continue
        # setlight's fixed cost (read, build, write) from a short run, so the whole
        # process fits the budget
        probe = setlight_render(a, material, os.path.join(a.work, "sl_probe.exr"), 99, spp=2, scene=scene)
        overhead = probe["wall"] - probe["render_s"]
        # each Cycles run is followed at once by a setlight run given the same time,
        # so both see the same load from other jobs on the machine
        cy, cy_img, cy_err, sl, sl_err = [], [], [], [], []
        for seed in range(1, a.runs + 1):
            r = cycles_render(a, name, opts, seed)
            cy.append(r)
            cy_img.append(load_exr(r["out"]))
            cy_err.append(rel_rmse(cy_img[-1], ref, ref_var, mask))
            p = os.path.join(a.work, "sl_%s_s%d.exr" % (name, seed))
            q = setlight_render(a, material, p, seed, seconds=max(0.02, r["cycles_time_s"] - overhead),
                                scene=scene)
            q["cycles_s"] = r["cycles_time_s"]
            sl.append(q)
            sl_err.append(rel_rmse(load_exr(p), ref, ref_var, mask))
            print("  seed %d: Cycles %.2f s (other load %.2f cores) %.4f | setlight %.2f s, %d spp %.4f" % (
                seed, r["cycles_time_s"], r["others_cores"], cy_err[-1], q["wall"], q["spp"], sl_err[-1]),
                flush=True)
        # the second goal: within 0.5% of the reference with --time 1
        p1 = os.path.join(a.work, "sl_%s_time1.exr" % name)
        t1 = setlight_render(a, material, p1, 1, seconds=1.0, scene=scene)
        t1_img = load_exr(p1)
        t1_err = rel_rmse(t1_img, ref, ref_var, mask)
        t1_cf = rel_rmse(t1_img, cf_ref, np.zeros_like(cf_ref), mask) if cf_ref is not None else -1.0
        print("  setlight --time 1: %.4f (%.2f s wall, %.2f s render, %d spp, closed form: %d exact, "
              "%d control variate px%s)" % (t1_err, t1["wall"], t1["render_s"], t1["spp"], t1["cf_exact"],
                                             t1["cf_control"], ", cut by --time" if t1["cf_cut"] else ""),
              flush=True)
        budget = statistics.median(r["cycles_time_s"] for r in cy)
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
                   cycles_errs=cy_err, setlight_errs=sl_err, reference=ref_kind,
                   time1_err=t1_err, time1_wall_s=t1["wall"], time1_render_s=t1["render_s"],
                   time1_spp=t1["spp"], time1_cut=t1["cf_cut"], time1_err_cf=t1_cf)
        # Cycles' noise against setlight's error, so model differences between the two
        # BSDFs do not count against Cycles: per run, its error with the systematic
        # part removed (median: robust to a run with a firefly), and the spread of its
        # runs (for chrome, where the systematic part is Cycles' bilinear filtering of
        # the sun and swamps the per-run estimate)
        row["cycles_noise_run"] = statistics.median(max(x * x - row["agree_sys"] ** 2, 0.0) ** 0.5
                                                    for x in cy_err)
        e_sl = row["setlight_err"]
        row["ratio_run"] = row["cycles_noise_run"] / e_sl if e_sl > 0 else float("inf")
        row["ratio"] = row["cycles_noise"] / e_sl if e_sl > 0 else float("inf")
        # the same at equal CPU time (error ~ 1/sqrt(time)), less sensitive to other load
        row["ratio_cpu"] = row["ratio"] * (cy_cpu / sl_cpu) ** -0.5 if e_sl > 0 else float("inf")
        rows.append(row)
        mask = mask_all
        print("  Cycles %d spp %.2f s: noise %.4f (vs reference %.4f) | setlight %d spp %.2f s: %.4f | "
              "ratio %.2f | Cycles vs reference: systematic %.4f, bias %+.4f, median px %.4f" % (
                  a.cycles_spp, budget, row["cycles_noise"], row["cycles_err"], row["setlight_spp"],
                  row["setlight_wall_s"], row["setlight_err"], row["ratio"], row["agree_sys"],
                  row["agree_bias"], row["agree_median_px"]), flush=True)
    if a.time1_only:
        return
    json.dump(rows, open(os.path.join(a.work, "results_%dspp_%s.json" % (a.cycles_spp, a.cases.replace(",", "_"))), "w"), indent=1)
    print("\nColumns: Cycles' error is its noise (the systematic difference to the reference taken out, "
          "per run; and the spread of its runs), setlight's is its whole error against the reference; "
          "ratio = Cycles' / setlight's at equal wall time (CPU: rescaled to equal CPU seconds); "
          "'--time 1' is setlight given one second (goal: <= 0.5%); reference: quadrature (grey, shadow: "
          "independent of setlight, its own accuracy in brackets) or setlight at high spp.")
    print("\n| case | reference | setlight --time 1: rel RMSE (wall s, spp) | Cycles spp | Cycles render s (process wall; CPU s) | Cycles rel RMSE: per run; "
          "spread (vs ref) | setlight spp | setlight wall s (CPU s) | setlight rel RMSE | ratio Cycles/setlight "
          "at equal wall: per run; spread (CPU) | Cycles vs ref: systematic, bias, median px |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| %s | %s | %.3f%%%s (%.2f, %d%s) | %d | %.1f (%.1f; %.1f) | %.1f%%; %.1f%% (%.1f%%) | %d | %.1f (%.1f) | %.2f%% | %.2f; %.2f (%.2f) "
              "| %.2f%%, %+.2f%%, %.2f%% |" % (
                  r["case"], r["reference"], 100 * r["time1_err"],
                  " (%.3f%% vs the tight closed form)" % (100 * r["time1_err_cf"]) if r["time1_err_cf"] >= 0 else "",
                  r["time1_wall_s"], r["time1_spp"],
                  ", plan cut" if r["time1_cut"] else "", r["cycles_spp"], r["cycles_render_s"], r["cycles_wall_s"], r["cycles_cpu_s"],
                  100 * r["cycles_noise_run"], 100 * r["cycles_noise"], 100 * r["cycles_err"], r["setlight_spp"],
                  r["setlight_wall_s"], r["setlight_cpu_s"], 100 * r["setlight_err"], r["ratio_run"], r["ratio"],
                  r["ratio_cpu"], 100 * r["agree_sys"], 100 * r["agree_bias"], 100 * r["agree_median_px"]))
    print("medians of %d runs; Cycles other load (cores): %s; load average at the end: %s" % (
        a.runs, ", ".join("%.2f" % r["cycles_other_load"] for r in rows), open("/proc/loadavg").read().split()[:3]))


if __name__ == "__main__":
    main()
