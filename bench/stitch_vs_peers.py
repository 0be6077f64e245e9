#!/usr/bin/python3
"""Fisheye stitch: setlight stitch vs Hugin and OpenCV's stitching module, same views, one run.

  /usr/bin/python3 bench/stitch_vs_peers.py [--full] [--tools setlight,hugin,opencv]
                                            [--setlight build/setlight] [--work DIR]

Inputs (made once under --work, default /tmp/setlight-bench/stitch[-full]): `setlight simulate
--scene exterior` (3 views of an 8 mm equisolid fisheye on a nodal head, 120 deg apart, each a
7 x 3-stop bracket; --size small: 720x480 frames, a 1024x512 truth) and each view's bracket
merged by `setlight merge` (JPEG frames) to a radiance EXR. --full: `--size full` (3000x2000)
views upsampled 2x to 6000x4000 (24 MP, the nominal focal length in pixels doubles with them)
and 8192x4096 outputs. Every tool gets the same views and only the nominal lens: 8 mm on a
36 mm wide sensor, equisolid; the views' yaws are not given to the peers (a user's pto_gen
and cv2.Stitcher have no such input), setlight takes its default (evenly spaced).

Runs, each timed with GNU time (wall, CPU = user + sys, peak RSS):
  setlight  setlight stitch --json --projection equisolid --focal-mm 8 --sensor-mm 36,24
  hugin     (and hugin-ldr: the control points found and optimised on 8-bit log-encoded
            copies, nona and enblend then on the HDR views) pto_gen (circular fisheye, f2, HFOV from the nominal focal length, cropped to the
            nominal image circle, as the Hugin manual asks for circular fisheyes), cpfind
            --multirow, cpclean, autooptimiser -a -l -s, pano_modify (equirectangular
            360x180), nona (float TIFF layers), enblend; the time is the sum of the steps,
            the memory the largest step's
  opencv    cv2.Stitcher (PANORAMA mode, spherical warper) on 8-bit log-encoded copies of
            the views (its blenders take 8/16-bit integers)
Error against the truth: the output area-averaged to the truth's size, luminance relative
error over the texels the tool covered within latitudes +-75 deg, median and p95, after the
one global scale that best fits (median log ratio; merge's radiance is relative). The peers'
outputs are also turned about the vertical (whole-texel yaw search, and a mirror) to their
best fit, as their frame is their own; setlight's is scored as written and also so. Coverage
is the share of the +-75 deg band with finite, positive output. Reprojection error: what each
tool reports (setlight's --json, autooptimiser's control-point distances); OpenCV reports none.
"""
import argparse
import glob
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PY = "/usr/bin/python3"
PEERS = "/work/shared/peers/merge"


def run_timed(cmd, cwd, check=True):
    with tempfile.NamedTemporaryFile("r", suffix=".time") as tf:
        p = subprocess.run(["/usr/bin/time", "-f", "%e %U %S %M", "-o", tf.name, "bash", "-c", cmd],
                           cwd=cwd, capture_output=True, text=True)
        fields = tf.read().split()[-4:]
    if check and p.returncode:
        sys.exit("failed (%d): %s\n%s" % (p.returncode, cmd, p.stderr[-2000:]))
    wall, user, sys_, rss = fields if len(fields) == 4 else (0, 0, 0, 0)
    return {"wall": float(wall), "cpu": float(user) + float(sys_), "rss_mb": int(rss) / 1024.0,
            "stdout": p.stdout, "stderr": p.stderr, "rc": p.returncode}


def make_inputs(a, setlight):
    """Simulated capture and merged views; returns (views, truth path, width, height)."""
    cap = os.path.join(a.work, "capture")
    if not os.path.exists(os.path.join(cap, "capture.json")):
        os.makedirs(a.work, exist_ok=True)
        run_timed("'%s' simulate --scene exterior --size %s --out '%s' --force" %
                  (setlight, "full" if a.full else "small", cap), a.work)
    info = json.load(open(os.path.join(cap, "capture.json")))
    views = []
    for v in range(info["views"]):
        out = os.path.join(a.work, "view%d.exr" % v)
        if not os.path.exists(out):
            frames = " ".join("'%s'" % os.path.join(cap, "hdri", f["name"] + ".jpg")
                              for f in info["frames"] if f["view"] == v)
            run_timed("'%s' merge --quiet -o '%s' %s" % (setlight, out, frames), a.work)
        views.append(out)
    if a.full:
        from common import read_hdr, write_exr
        big = []
        for v in views:
            out = v.replace(".exr", "_24mp.exr")
            if not os.path.exists(out):
                import cv2
                img = read_hdr(v)
                write_exr(out, cv2.resize(img, (2 * img.shape[1], 2 * img.shape[0]),
                                          interpolation=cv2.INTER_LINEAR))
            big.append(out)
        views = big
    from common import read_hdr
    h, w = read_hdr(views[0]).shape[:2]
    return views, os.path.join(cap, "truth", "latlong.exr"), w, h


def find_numbers(obj, words, path=""):
    """Every number in a JSON tree whose key path contains all of `words`."""
    out = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.update(find_numbers(v, words, path + "/" + k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out.update(find_numbers(v, words, path + "[%d]" % i))
    elif isinstance(obj, (int, float)) and all(w in path.lower() for w in words):
        out[path] = obj
    return out


def run_setlight(a, setlight, views, w, out_w):
    d = os.path.join(a.work, "setlight")
    os.makedirs(d, exist_ok=True)
    out = os.path.join(d, "stitch.exr")
    r = run_timed("'%s' stitch --json --projection equisolid --focal-mm 8 --sensor-mm 36,24 %s "
                  "-o '%s' %s" % (setlight, a.setlight_args, out, " ".join(views)), d, check=False)
    r["out"] = out if r["rc"] == 0 else None
    try:
        j = json.loads(r["stdout"])
        r["reproj"] = {k: v for k, v in find_numbers(j, ["rms"]).items() if "px" in k or "reproj" in k}
        r["pairs"] = [(os.path.basename(p.get("a", "")), os.path.basename(p.get("b", "")),
                       p.get("matches"), p.get("inliers"), p.get("status"))
                      for p in j.get("pairs", []) if isinstance(p, dict)]
    except ValueError:
        r["reproj"] = {}
    if r["rc"]:
        r["note"] = "exit %d: %s" % (r["rc"], r["stderr"].strip()[-300:])
    return r


def log_encode(src, dst):
    """An 8-bit copy of a radiance view, log-encoded between its 0.5th and 99.5th percentiles."""
    import cv2
    from common import read_hdr, luminance
    rgb = read_hdr(src)
    y = luminance(rgb)
    lo, hi = np.percentile(y[y > 0], 0.5), np.percentile(y[y > 0], 99.5)
    enc = np.clip(np.log(np.maximum(rgb, lo) / lo) / np.log(hi / lo), 0, 1)
    cv2.imwrite(dst, np.ascontiguousarray((enc[..., ::-1] * 255 + 0.5).astype(np.uint8)))


def run_hugin(a, views, w, h, out_w, ldr=False):
    """Hugin on the HDR views; ldr: control points and optimisation on 8-bit log-encoded
    copies (what a user does when cpfind finds nothing on HDR), nona and enblend on the HDR
    views."""
    d = os.path.join(a.work, "hugin-ldr" if ldr else "hugin")
    os.makedirs(d, exist_ok=True)
    inputs = views
    if ldr:
        inputs = [os.path.join(d, "ldr%d.tif" % i) for i in range(len(views))]
        for v, l in zip(views, inputs):
            log_encode(v, l)
    f_px = 8.0 * w / 36.0
    # Hugin's circular fisheye (f2) is equidistant: HFOV = width / f radians.
    hfov = np.degrees(w / f_px)
    r90 = f_px * np.sqrt(2.0)  # the equisolid circle, 90 deg off-axis
    crop = "%d,%d,%d,%d" % (max(0, w / 2 - r90), min(w, w / 2 + r90), max(0, h / 2 - r90),
                            min(h, h / 2 + r90))
    steps = [
        "pto_gen -p 2 -f %.4f -c %s -o p0.pto %s" % (hfov, crop, " ".join(inputs)),
        "cpfind --multirow -o p1.pto p0.pto",
        "cpclean -o p2.pto p1.pto",
        "autooptimiser -a -l -s -o p3.pto p2.pto",
        "pano_modify --projection=2 --fov=360x180 --canvas=%dx%d -o p4.pto p3.pto" % (out_w, out_w // 2)
        + "".join(" && sed -i 's|%s|%s|' p4.pto" % (l, v) for l, v in zip(inputs, views) if l != v),
        "nona -m TIFF_m -o layer_ p4.pto",
        "enblend -o hugin.tif layer_*.tif",
    ]
    total = {"wall": 0.0, "cpu": 0.0, "rss_mb": 0.0, "steps": []}
    for s in steps:
        r = run_timed(s, d, check=False)
        total["wall"] += r["wall"]
        total["cpu"] += r["cpu"]
        total["rss_mb"] = max(total["rss_mb"], r["rss_mb"])
        total["steps"].append((s.split()[0], r["wall"], r["rss_mb"]))
        if s.startswith("cpfind"):
            m = re.findall(r"Found (\d+) matches", r["stdout"] + r["stderr"])
            total["cpfind_matches"] = [int(x) for x in m]
        if s.startswith("autooptimiser"):
            rms = re.findall(r"iteration\(s\):\s+([-\d.e]+) units", r["stdout"] + r["stderr"])
            if rms:
                total["reproj"] = {"autooptimiser control-point rms px (last)": float(rms[-1])}
        if r["rc"]:
            total["note"] = "%s failed (exit %d): %s" % (s.split()[0], r["rc"], r["stderr"].strip()[-300:])
            total["out"] = None
            return total
    cps = open(os.path.join(d, "p3.pto")).read().count("\nc ")
    total["control_points"] = cps
    poses = []
    for line in open(os.path.join(d, "p3.pto")):
        if line.startswith("i "):
            f = {t[0]: t[1:] for t in line.split() if t[0] in "ypr" and len(t) > 1}
            poses.append(tuple(round(float(f[k]), 2) for k in "ypr"))
    total["poses"] = poses
    total["out"] = os.path.join(d, "hugin.tif")
    return total


OPENCV_CHILD = r"""
import sys, cv2
views, out = sys.argv[1:-1], sys.argv[-1]
imgs = [cv2.imread(v) for v in views]
st = cv2.Stitcher_create(cv2.Stitcher_PANORAMA)
status, pano = st.stitch(imgs)
print("status", status)
if status == 0:
    cv2.imwrite(out, pano)
    print("size", pano.shape[1], pano.shape[0])
"""


def run_opencv(a, views):
    d = os.path.join(a.work, "opencv")
    os.makedirs(d, exist_ok=True)
    child = os.path.join(d, "stitch_child.py")
    open(child, "w").write(OPENCV_CHILD)
    ldr = [os.path.join(d, "ldr%d.png" % i) for i in range(len(views))]
    for v, l in zip(views, ldr):
        log_encode(v, l)
    out = os.path.join(d, "opencv.png")
    r = run_timed("%s %s %s %s" % (PY, child, " ".join(ldr), out), d, check=False)
    m = re.search(r"status (-?\d+)", r["stdout"])
    status = int(m.group(1)) if m else None
    names = {0: "OK", 1: "ERR_NEED_MORE_IMGS", 2: "ERR_HOMOGRAPHY_EST_FAIL",
             3: "ERR_CAMERA_PARAMS_ADJUST_FAIL"}
    r["note"] = "cv2.Stitcher status %s (%s)%s" % (status, names.get(status, "crashed"),
                                                   "; 8-bit log-encoded panorama in its own "
                                                   "spherical frame, no radiance to score"
                                                   if status == 0 else "")
    r["out"] = None
    r["reproj"] = {}
    return r


def score(path, truth, align):
    """Median and p95 relative luminance error vs the truth within +-75 deg, coverage, yaw shift."""
    import cv2
    from common import read_hdr, luminance
    img = read_hdr(path)
    th, tw = truth.shape[:2]
    img = cv2.resize(img, (tw, th), interpolation=cv2.INTER_AREA)
    yt, yo = luminance(truth), luminance(img)
    lat = 90.0 - (np.arange(th) + 0.5) * 180.0 / th
    band = np.repeat((np.abs(lat) <= 75.0)[:, None], tw, axis=1)

    def err(yo_):
        m = band & np.isfinite(yo_) & (yo_ > 0) & (yt > 0)
        if m.sum() < 100:
            return None
        s = float(np.exp(np.median(np.log(yt[m]) - np.log(yo_[m]))))
        rel = np.abs(s * yo_[m] - yt[m]) / yt[m]
        return {"median": float(np.median(rel)), "p95": float(np.percentile(rel, 95)),
                "coverage": float(m.sum() / band.sum()), "scale": s}

    best = err(yo)
    if best is not None:
        best["shift_deg"] = 0.0
        best["mirrored"] = False
    if align:
        coarse = max(1, tw // 256)
        for mirror in (False, True):
            base = yo[:, ::-1] if mirror else yo
            for dx in range(0, tw, coarse):
                e = err(np.roll(base, dx, axis=1))
                if e and (best is None or e["median"] < best["median"]):
                    e["shift_deg"] = dx * 360.0 / tw
                    e["mirrored"] = mirror
                    best = e
    bad = int(np.sum(~np.isfinite(img)) + np.sum(img < 0))
    if best is not None:
        best["nonfinite_or_negative"] = bad
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--full", action="store_true", help="3 x 24 MP views to 8192x4096")
    ap.add_argument("--tools", default="setlight,hugin,hugin-ldr,opencv")
    ap.add_argument("--setlight", default=os.path.join(ROOT, "build", "setlight"))
    ap.add_argument("--setlight-args", default="", help="extra options for setlight stitch")
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    a.work = a.work or ("/tmp/setlight-bench/stitch" + ("-full" if a.full else ""))
    sys.path.insert(0, PEERS)
    from common import read_hdr
    setlight = os.path.abspath(a.setlight)
    views, truth_path, w, h = make_inputs(a, setlight)
    truth = read_hdr(truth_path)
    out_w = 8192 if a.full else truth.shape[1]
    print("views: %d x %dx%d (%s), truth %dx%d, output %dx%d; nominal lens 8 mm equisolid on 36 mm"
          % (len(views), w, h, os.path.dirname(views[0]), truth.shape[1], truth.shape[0], out_w,
             out_w // 2))
    results = {}
    tools = a.tools.split(",")
    if "setlight" in tools:
        results["setlight"] = run_setlight(a, setlight, views, w, out_w)
    if "hugin" in tools:
        results["hugin"] = run_hugin(a, views, w, h, out_w)
    if "hugin-ldr" in tools:
        results["hugin-ldr"] = run_hugin(a, views, w, h, out_w, ldr=True)
    if "opencv" in tools:
        results["opencv"] = run_opencv(a, views)
    print("\n%-9s %8s %8s %9s  %-28s %s" % ("tool", "wall s", "CPU s", "peak MB",
                                            "error vs truth (+-75 deg)", "notes"))
    for name, r in results.items():
        s = score(r["out"], truth, align=True) if r.get("out") else None
        r["score"] = s
        if s:
            e = "med %.4f p95 %.4f cov %.2f" % (s["median"], s["p95"], s["coverage"])
            if s["shift_deg"] or s["mirrored"]:
                e += " (turned %.1f deg%s)" % (s["shift_deg"], ", mirrored" if s["mirrored"] else "")
        else:
            e = "-"
        print("%-9s %8.2f %8.2f %9.1f  %-28s %s" % (name, r["wall"], r["cpu"], r["rss_mb"], e,
                                                    r.get("note", "")))
        if r.get("reproj"):
            print("          reprojection: %s" % r["reproj"])
        if name.startswith("hugin"):
            print("          steps (tool, wall s, peak MB): %s" % r.get("steps"))
            print("          cpfind matches per pair: %s, control points kept: %s" %
                  (r.get("cpfind_matches"), r.get("control_points")))
            print("          solved poses (yaw, pitch, roll deg): %s" % r.get("poses"))
        if r.get("pairs"):
            print("          pairs (a, b, matches, inliers, status): %s" % r["pairs"])
        if name == "setlight" and s:
            s0 = score(r["out"], truth, align=False)
            print("          as written (no turn): med %.4f p95 %.4f cov %.2f; NaN/Inf/negative "
                  "samples %d" % (s0["median"], s0["p95"], s0["coverage"], s0["nonfinite_or_negative"]))
    sl = results.get("setlight")
    for name in ("hugin", "hugin-ldr", "opencv"):
        p = results.get(name)
        if sl and p and sl["wall"] > 0 and sl.get("out"):
            print("setlight / %s: wall %.3f, CPU %.3f, peak memory %.3f" %
                  (name, sl["wall"] / max(p["wall"], 1e-9), sl["cpu"] / max(p["cpu"], 1e-9),
                   sl["rss_mb"] / max(p["rss_mb"], 1e-9)))
    json.dump({k: {kk: vv for kk, vv in v.items() if kk not in ("stdout", "stderr")}
               for k, v in results.items()}, open(os.path.join(a.work, "results.json"), "w"),
              indent=1, default=str)


if __name__ == "__main__":
    main()
