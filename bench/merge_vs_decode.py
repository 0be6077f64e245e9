#!/usr/bin/python3
"""The merge against only decoding its frames (issue 5: "the merge itself within 1.2x of the
time it takes only to decode the frames"), on the 6000x4000x7 JPEG bracket.

  /usr/bin/python3 bench/merge_vs_decode.py [--runs 5] [--frames DIR] [--setlight BIN]...

Runs `setlight merge --json` (default options: half PIZ radiance and mask) and
`build/bench/bench_decode` (the same reader, every frame once, the same threads) in turn,
--runs times, and prints medians (with --setlight given more than once, e.g. the build
before a change and after, each build in turn in every round, a column each; the ratios
are the last build's): the merge's phases (its --json "timing": wall and CPU of
every thread per phase), both commands as processes (CPU = user + sys from wait4, peak RSS),
and the ratios:
  (a) the whole merge command against the whole decode-only command (both start the process
      and load OpenImageIO), with and without the merge's writing;
  (b) the merge's own arithmetic (phase "merge") against decoding (the merge's own "decode"
      phase, and bench_decode's decoding).
DIR holds times.txt and jpg/img_*.jpg (bench/merge_vs_peers.py --big makes them).
"""
import argparse
import glob
import json
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PHASES = ["decode", "sample", "fit", "merge", "write", "align", "other"]


def run(cmd, out):
    """Runs cmd with stdout to the file out; returns wall, CPU (user + sys) and peak MB."""
    t0 = time.monotonic()
    with open(out, "w") as f:
        p = subprocess.Popen(cmd, stdout=f, stderr=subprocess.DEVNULL)
        _, status, ru = os.wait4(p.pid, 0)
    wall = time.monotonic() - t0
    if status != 0:
        sys.exit("failed (%d): %s" % (status, " ".join(cmd)))
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--frames", default="/tmp/setlight-bench-merge/work/data/synth6k/7x3")
    ap.add_argument("--setlight", action="append", default=None)
    ap.add_argument("--decode", default=os.path.join(HERE, "..", "build", "bench", "bench_decode"))
    ap.add_argument("--work", default="/tmp/setlight-bench-merge-decode")
    a = ap.parse_args()
    builds = a.setlight or [os.path.join(HERE, "..", "build", "setlight")]
    frames = sorted(glob.glob(os.path.join(a.frames, "jpg", "img_*.jpg")))
    if not frames:
        sys.exit("%s: no jpg/img_*.jpg (run bench/merge_vs_peers.py --big first)" % a.frames)
    times = ",".join(x.strip() for x in open(os.path.join(a.frames, "times.txt")) if x.strip())
    os.makedirs(a.work, exist_ok=True)
    out, js, dec = os.path.join(a.work, "out.exr"), os.path.join(a.work, "merge.json"), os.path.join(a.work, "decode.txt")
    decode_cmd = [a.decode] + frames
    runs, d = [[] for _ in builds], []
    for _ in range(a.runs):
        for b, build in enumerate(builds):
            wall, cpu, mb = run([build, "merge", "--json", "--times", times, "-o", out] + frames, js)
            t = json.load(open(js))["timing"]
            runs[b].append({"wall": wall, "cpu": cpu, "mb": mb, "t": t})
        wall, cpu, mb = run(decode_cmd, dec)
        words = open(dec).read().split()
        # "module load: wall W s, CPU C s" then "decode only: N frames, wall W s, CPU C s".
        nums = [float(w) for w in words if w.replace(".", "", 1).isdigit() and "." in w]
        d.append({"wall": wall, "cpu": cpu, "mb": mb, "load_wall": nums[0], "load_cpu": nums[1],
                  "dec_wall": nums[2], "dec_cpu": nums[3]})
    med = lambda rows, f: statistics.median(f(r) for r in rows)
    print("6000x4000x7 JPEG, %d runs each (interleaved), medians; CPU = all threads" % a.runs)
    print("| merge phase, CPU / wall s | %s |" % " | ".join(builds))
    print("|---|%s" % ("---|" * len(builds)))
    for ph in PHASES + ["total"]:
        print("| %s | %s |" % (ph, " | ".join("%.2f / %.2f" % (med(m, lambda r: r["t"][ph]["cpu"]), med(m, lambda r: r["t"][ph]["wall"]))
                                             for m in runs)))
    print("| process | %s |" % " | ".join("%.2f / %.2f, %.0f MB" % (med(m, lambda r: r["cpu"]), med(m, lambda r: r["wall"]), med(m, lambda r: r["mb"]))
                                        for m in runs))
    m = runs[-1]
    mc, mw, mm = med(m, lambda r: r["cpu"]), med(m, lambda r: r["wall"]), med(m, lambda r: r["mb"])
    mc_nw = med(m, lambda r: r["cpu"] - r["t"]["write"]["cpu"])
    mw_nw = med(m, lambda r: r["wall"] - r["t"]["write"]["wall"])
    dc, dw, dm = med(d, lambda r: r["cpu"]), med(d, lambda r: r["wall"]), med(d, lambda r: r["mb"])
    print("\n| command | CPU s | wall s | peak MB |")
    print("|---|---|---|---|")
    print("| setlight merge (process) | %.2f | %.2f | %.0f |" % (mc, mw, mm))
    print("| setlight merge without its writing | %.2f | %.2f | |" % (mc_nw, mw_nw))
    print("| bench_decode (process) | %.2f | %.2f | %.0f |" % (dc, dw, dm))
    print("| bench_decode: module load | %.2f | %.2f | |" % (med(d, lambda r: r["load_cpu"]), med(d, lambda r: r["load_wall"])))
    print("| bench_decode: decoding | %.2f | %.2f | |" % (med(d, lambda r: r["dec_cpu"]), med(d, lambda r: r["dec_wall"])))
    pix, mdec = med(m, lambda r: r["t"]["merge"]["cpu"]), med(m, lambda r: r["t"]["decode"]["cpu"])
    pixw, mdecw = med(m, lambda r: r["t"]["merge"]["wall"]), med(m, lambda r: r["t"]["decode"]["wall"])
    ddec, ddecw = med(d, lambda r: r["dec_cpu"]), med(d, lambda r: r["dec_wall"])
    print("\n| ratio (goal 1.2) | CPU | wall |")
    print("|---|---|---|")
    print("| (a) merge command / decode-only command | %.2f | %.2f |" % (mc / dc, mw / dw))
    print("| (a) merge command without writing / decode-only command | %.2f | %.2f |" % (mc_nw / dc, mw_nw / dw))
    print("| (b) merge arithmetic / the merge's decoding | %.2f | %.2f |" % (pix / mdec, pixw / mdecw))
    print("| (b) merge arithmetic / bench_decode's decoding | %.2f | %.2f |" % (pix / ddec, pixw / ddecw))


if __name__ == "__main__":
    main()
