#!/usr/bin/python3
"""A small bracket merged by a whole `setlight merge` process against a whole Python process
running OpenCV's Debevec calibrate + merge on the same frames (issue 20, item 12: process
start-up; goal: setlight at <= 0.2x OpenCV's time).

  /usr/bin/python3 bench/startup_vs_opencv.py [--runs 7] [--format png|jpg] [--setlight BIN]...
                                              [--work DIR]

Makes a 1024x512x7 8-bit PNG (or JPEG, quality 95, 4:2:0) bracket (a synthetic sky with a sun, 2 stops apart, through an
sRGB-like response with noise) in DIR, then, --runs times and interleaved, runs
  setlight merge --quiet --times T1,... -o DIR/setlight.exr FRAMES
  python3 -c '<imread the frames, cv2.createCalibrateDebevec().process,
              cv2.createMergeDebevec().process, cv2.imwrite DIR/opencv.exr>'
as processes and prints the medians of their wall time and CPU (user + sys, from wait4) and
the ratio setlight / OpenCV. With --setlight given more than once (a build before a change
and after), each build runs in every round; the ratio is the last build's. Both write a float
EXR (OpenCV with OPENCV_IO_ENABLE_OPENEXR=1). Needs Debian's python3-opencv and numpy.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
W, H, FRAMES = 1024, 512, 7

OPENCV_MERGE = r"""
import sys, cv2, numpy as np
out, times, frames = sys.argv[1], sys.argv[2], sys.argv[3:]
t = np.array([float(x) for x in times.split(",")], dtype=np.float32)
imgs = [cv2.imread(f) for f in frames]
crf = cv2.createCalibrateDebevec().process(imgs, t)
hdr = cv2.createMergeDebevec().process(imgs, t, crf)
if not cv2.imwrite(out, hdr):
    sys.exit("cannot write " + out)
"""


def make_bracket(work, ext):
    """Writes FRAMES PNGs or JPEGs (brightest last); returns their paths and exposure times."""
    rng = np.random.default_rng(20)
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    elev = 1.0 - y / H
    sky = 0.2 + 0.8 * elev
    radiance = np.stack([sky * 0.6, sky * 0.8, sky * 1.1], axis=-1)
    ground = y > H * 0.55
    texture = 0.05 + 0.1 * (0.5 + 0.5 * np.sin(x / 13.0) * np.cos(y / 7.0))
    radiance[ground] = np.stack([texture * 0.9, texture * 0.8, texture * 0.6], axis=-1)[ground]
    sun = (x - W * 0.7) ** 2 + (y - H * 0.25) ** 2 < 12 ** 2
    radiance[sun] = 400.0
    times = [1.0 / 4000 * 4 ** i for i in range(FRAMES)]
    paths = []
    for i, t in enumerate(times):
        v = radiance * t * 40.0
        v = v * (1 + 0.01 * rng.standard_normal(v.shape, dtype=np.float32))
        v = np.clip(v, 0, 1)
        code = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
        img = np.round(np.clip(code, 0, 1) * 255).astype(np.uint8)
        p = os.path.join(work, "frame_%d.%s" % (i, ext))
        cv2.imwrite(p, img[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])  # RGB -> BGR
        paths.append(p)
    return paths, times


def run(cmd, env=None):
    """Runs cmd; returns wall seconds and CPU seconds (user + sys of the process)."""
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.monotonic() - t0
    if status != 0:
        sys.exit("failed (%d): %s\n%s" % (status, " ".join(cmd), p.stderr.read().decode()))
    p.stderr.close()
    return wall, ru.ru_utime + ru.ru_stime


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--setlight", action="append", default=None)
    ap.add_argument("--format", choices=["png", "jpg"], default="png")
    ap.add_argument("--work", default="/tmp/setlight-bench-startup")
    a = ap.parse_args()
    builds = a.setlight or [os.path.join(HERE, "..", "build", "setlight")]
    os.makedirs(a.work, exist_ok=True)
    frames, times = make_bracket(a.work, a.format)
    tlist = ",".join("%.9g" % t for t in times)
    env = dict(os.environ, OPENCV_IO_ENABLE_OPENEXR="1")
    opencv = [sys.executable, "-c", OPENCV_MERGE, os.path.join(a.work, "opencv.exr"), tlist] + frames
    res = {b: [] for b in builds}
    ocv = []
    for _ in range(a.runs):
        for b in builds:
            out = os.path.join(a.work, "setlight.exr")
            res[b].append(run([b, "merge", "--quiet", "--times", tlist, "-o", out] + frames))
        ocv.append(run(opencv, env))
    med = lambda rows, i: statistics.median(r[i] for r in rows)
    print("%dx%dx%d 8-bit %s bracket, %d runs each (interleaved), medians, whole processes"
          % (W, H, FRAMES, a.format.upper(), a.runs))
    print("| command | wall s | CPU s |")
    print("|---|---|---|")
    for b in builds:
        print("| setlight merge (%s) | %.3f | %.3f |" % (b, med(res[b], 0), med(res[b], 1)))
    print("| OpenCV Debevec calibrate + merge (python3) | %.3f | %.3f |" % (med(ocv, 0), med(ocv, 1)))
    last = res[builds[-1]]
    print("ratio setlight / OpenCV: wall %.3f, CPU %.3f (goal <= 0.2)"
          % (med(last, 0) / med(ocv, 0), med(last, 1) / med(ocv, 1)))


if __name__ == "__main__":
    main()
