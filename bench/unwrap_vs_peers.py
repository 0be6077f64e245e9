#!/usr/bin/python3
"""Chrome-ball unwrap: setlight vs pfspanoramic and Hugin nona, same inputs, one run.

  /usr/bin/python3 bench/unwrap_vs_peers.py [--big] [--repeats N] [--setlight build/setlight]
  /usr/bin/python3 bench/unwrap_vs_peers.py --small [--env LATLONG]

Inputs (made once under --work, default /tmp/setlight-bench/unwrap): the synthetic 2048x1024
ground-truth lat-long of ../shared/peers/merge (make_scene, seed 1: sky, sun, lamps) and ideal
orthographic mirror balls of it rendered by that folder's render_ball.py (1024 px, 8x8
supersampled; with --big also 4096 px, 2x2). Camera on +Z looking down -Z, image right +X: for
setlight that is --camera ortho --camera-azimuth 180 with the circle filling the frame.

Runs, each timed with GNU time (wall, CPU = user + sys, peak RSS), median of --repeats:
  setlight unwrap (--no-confidence, half EXR; its own --json timing of the unwrap stage too)
  pfspanoramic mirrorball+polar -i (bilinear; pfsin | ... | pfsout)
  nona, ball as a 360-degree equisolid fisheye, bilinear (m i5) and cubic (m i0, Hugin's default)
Error: ../shared/peers/merge/evaluate_unwrap.py's score(): median relative luminance error per
region by angle from +Z (front < 90, side 90-150, back > 150 deg); peers' mirrored outputs are
flipped back (the lower front error wins, as there). 8192x4096 outputs are area-averaged 4x4 to
the 2048x1024 ground truth first. Ratios are setlight / peer.

--small: the small-ball case instead (docs/unwrap.md, "Small balls"): ideal orthographic balls
256, 512 and 1024 px across filling the frame (render_ball.py, 8x8 supersampled) of --env (a
lat-long; default the ground truth above), each unwrapped by setlight to N x N/2 and by a plain
bicubic remap (ref_unwrap.py's maps, one cv2.remap INTER_CUBIC lookup per texel centre); median
relative luminance error within 110 deg of +Z (the direction back at the camera) against two
references: the texel means of the environment the balls were rendered from (its bilinear
surface, 8x8 solid-angle-weighted samples per output texel), and the lat-long's own texels
averaged k x k to the output's size (k = env width / N; for k = 1 or 2 these are point values of
that surface at the output's texel centres, not texel means).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PY = "/usr/bin/python3"


def run_timed(cmd, cwd):
    with tempfile.NamedTemporaryFile("r", suffix=".time") as tf:
        p = subprocess.run(["/usr/bin/time", "-f", "%e %U %S %M", "-o", tf.name, "bash", "-c", cmd],
                           cwd=cwd, capture_output=True, text=True)
        if p.returncode:
            sys.exit("failed (%d): %s\n%s" % (p.returncode, cmd, p.stderr[-2000:]))
        wall, user, sys_, rss = tf.read().split()[-4:]
    return {"wall": float(wall), "cpu": float(user) + float(sys_), "rss_mb": int(rss) / 1024.0,
            "stdout": p.stdout}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--big", action="store_true", help="also 4096 px -> 8192x4096")
    ap.add_argument("--only-big", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--setlight", default=os.path.join(ROOT, "build", "setlight"))
    ap.add_argument("--peers", default=os.path.normpath(os.path.join(ROOT, "..", "..", "shared",
                                                                     "peers", "merge")))
    ap.add_argument("--work", default="/tmp/setlight-bench/unwrap")
    ap.add_argument("--tools", default="setlight,pfspanoramic,nona_bilinear,nona_cubic",
                    help="comma-separated subset to run")
    ap.add_argument("--small", action="store_true",
                    help="256/512/1024 px balls to N x N/2 against a bicubic remap instead")
    ap.add_argument("--env", default=None, help="--small: the lat-long to render (default gt.exr)")
    a = ap.parse_args()
    if not os.path.isdir(a.peers):
        a.peers = "/work/shared/peers/merge"
    sys.path.insert(0, a.peers)
    from common import make_scene, write_exr, read_hdr, cv2  # noqa: E402
    import render_ball  # noqa: E402
    import make_pto  # noqa: E402
    from evaluate_unwrap import score, area_down  # noqa: E402

    setlight = os.path.abspath(a.setlight)
    os.makedirs(a.work, exist_ok=True)
    w = a.work
    gt_path = os.path.join(w, "gt.exr")
    if not os.path.exists(gt_path):
        gt, lab = make_scene(2048, 1024, seed=1)
        write_exr(gt_path, gt)
        cv2.imwrite(os.path.join(w, "labels.png"), lab)
    gt = read_hdr(gt_path)
    lab = cv2.imread(os.path.join(w, "labels.png"), cv2.IMREAD_UNCHANGED)
    if a.small:
        small(a, setlight, read_hdr(a.env) if a.env else gt, render_ball, write_exr, read_hdr, cv2)
        return
    cases = [] if a.only_big else [(1024, 2048, 8)]
    if a.big or a.only_big:
        cases.append((4096, 8192, 2))
    results = []
    for n, width, ss in cases:
        ball = os.path.join(w, "ball%d.exr" % n)
        if not os.path.exists(ball):
            write_exr(ball, render_ball.render_ball(gt, n, ss))
        h = width // 2
        out = os.path.join(w, "out%d" % n)
        os.makedirs(out, exist_ok=True)
        pto = os.path.join(out, "p%d.pto")
        tools = {
            "setlight": "%s unwrap --json --circle %g,%g,%g --camera ortho --camera-azimuth 180 "
                        "--width %d --no-confidence -o %s/setlight.exr %s"
                        % (setlight, n / 2, n / 2, n / 2, width, out, ball),
            "pfspanoramic": "pfsin %s | pfspanoramic mirrorball+polar -w %d -h %d -i | pfsout "
                            "%s/pfspanoramic.exr" % (ball, width, h, out),
            "nona_bilinear": "nona -m EXR -o %s/nona_bilinear %s" % (out, pto % 5),
            "nona_cubic": "nona -m EXR -o %s/nona_cubic %s" % (out, pto % 0),
        }
        for code in (0, 5):
            make_pto.ball_pto(ball, pto % code, width, h, code)
        for name, cmd in tools.items():
            if name not in a.tools.split(","):
                continue
            runs = []
            for _ in range(a.repeats):
                runs.append(run_timed(cmd, w))
            rec = {"case": "%d->%dx%d" % (n, width, h), "tool": name,
                   "wall": statistics.median(r["wall"] for r in runs),
                   "cpu": statistics.median(r["cpu"] for r in runs),
                   "rss_mb": max(r["rss_mb"] for r in runs), "runs": len(runs)}
            if name == "setlight":
                timing = [json.loads(r["stdout"])["timing"] for r in runs]
                rec["unwrap_stage"] = statistics.median(t["unwrap"] for t in timing)
                rec["unwrap_stage_cpu"] = statistics.median(t["unwrap_cpu"] for t in timing)
            est = read_hdr(os.path.join(out, name + ".exr"))
            if est.shape[0] != gt.shape[0]:
                k = est.shape[0] // gt.shape[0]
                est = area_down(est.astype(np.float64), k).astype(np.float32)
            r0, r1 = score(gt, est, lab), score(gt, est[:, ::-1].copy(), lab)
            best = r1 if r1["front"]["median"] < r0["front"]["median"] else r0
            for region in ("front", "side", "back"):
                rec[region] = best[region]["median"]
            rec["flop"] = best is r1
            rec["sun_energy"] = best.get("sun_energy_ratio")
            results.append(rec)
            print(json.dumps(rec), flush=True)
    print()
    print("| case | tool | wall s | CPU s | peak MB | front | side | back | sun energy |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results:
        extra = (" (unwrap stage %.2f s, %.2f s CPU)" % (r["unwrap_stage"], r["unwrap_stage_cpu"])
                 if "unwrap_stage" in r else "")
        print("| %s | %s | %.2f%s | %.2f | %.0f | %.3f%% | %.3f%% | %.3f%% | %.3f |"
              % (r["case"], r["tool"], r["wall"], extra, r["cpu"], r["rss_mb"], 100 * r["front"],
                 100 * r["side"], 100 * r["back"], r["sun_energy"] or 0))
    print()
    for case in sorted({r["case"] for r in results}):
        mine = [r for r in results if r["case"] == case and r["tool"] == "setlight"]
        if not mine:
            continue
        mine = mine[0]
        for r in results:
            if r["case"] != case or r["tool"] == "setlight":
                continue
            print("%s setlight/%s: wall %.3f, CPU %.3f, error front %.2f side %.2f back %.2f"
                  % (case, r["tool"], mine["wall"] / r["wall"], mine["cpu"] / r["cpu"],
                     mine["front"] / r["front"], mine["side"] / r["side"], mine["back"] / r["back"]))


def texel_means(env, n, sub=8):
    """Solid-angle-weighted means over each texel of an n x n/2 lat-long of env's bilinear surface
    (the surface render_ball.py reflects)."""
    from common import sample_latlong_bilinear
    h0, w0 = env.shape[:2]
    h = n // 2
    acc = np.zeros((h, n, 3))
    wsum = np.zeros((h, 1, 1))
    for j in range(sub):
        v = (np.arange(h) + (j + 0.5) / sub) / h
        wt = np.cos(np.pi * (0.5 - v))[:, None, None]
        for i in range(sub):
            u = (np.arange(n) + (i + 0.5) / sub) / n
            px = np.broadcast_to((u * w0 - 0.5)[None, :], (h, n))
            py = np.broadcast_to((v * h0 - 0.5)[:, None], (h, n))
            acc += wt * sample_latlong_bilinear(env, px, py)
            wsum += wt
    return acc / wsum


def small(a, setlight, env, render_ball, write_exr, read_hdr, cv2):
    from common import latlong_dirs, luminance
    from evaluate_unwrap import area_down
    from ref_unwrap import maps
    w0 = env.shape[1]
    tag = os.path.splitext(os.path.basename(a.env or "gt"))[0]
    print("| ball | output | reference | setlight | bicubic remap | ratio |")
    print("|---|---|---|---|---|---|")
    for n in (256, 512, 1024):
        ball = os.path.join(a.work, "small_%s_%d.exr" % (tag, n))
        if not os.path.exists(ball):
            write_exr(ball, render_ball.render_ball(env, n, 8))
        photo = read_hdr(ball)
        out = os.path.join(a.work, "small_%s_%d_setlight.exr" % (tag, n))
        subprocess.run([setlight, "unwrap", "--circle", "%g,%g,%g" % (n / 2, n / 2, n / 2),
                        "--camera", "ortho", "--camera-azimuth", "180", "--width", str(n),
                        "--no-confidence", "--float", "-o", out, ball], check=True)
        est = read_hdr(out)
        (mx, my), = maps(n, n, n // 2, 1)
        cubic = cv2.remap(photo, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
        d = latlong_dirs(n, n // 2)
        front = np.degrees(np.arccos(np.clip(d[..., 2], -1, 1))) < 110
        k = w0 // n
        sa = np.cos(np.pi * (0.5 - (np.arange(env.shape[0]) + 0.5) / env.shape[0]))
        sa = np.broadcast_to(sa[:, None, None], env.shape[:2] + (1,))
        refs = (("texel means", texel_means(env, n)),
                ("texels %dx%d" % (k, k), area_down(env * sa, k) / area_down(sa, k)))
        for name, ref in refs:
            y = luminance(ref).astype(np.float64)

            def err(e):
                return float(np.median((np.abs(luminance(e) - y) / y)[front]))
            es, eb = err(est), err(cubic)
            print("| %d | %dx%d | %s | %.3f%% | %.3f%% | %.3f |"
                  % (n, n, n // 2, name, 100 * es, 100 * eb, es / eb), flush=True)


if __name__ == "__main__":
    main()
