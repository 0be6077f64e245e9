#!/usr/bin/env python3
"""The Cramer-Rao bound of each stitch-solve inlier's position (docs/stitch.md,
"The noise floor of the point matches").

  /usr/bin/python3 bench/stitch_match_bound.py DUMP VIEWDIR CLEANDIR [--drop-list FILE PX]
                                                [--noisy-gradients]

DUMP: the solve's stderr with bench/stitch_match_dump.patch applied and
SL_DUMP_RES=1 (a "STEP" line, then per inlier "RES a b pa pb edge normal e1 e2
true_pa solved_pa", in the solve's pixels). VIEWDIR: view{0,1,2}_24mp.exr of
`bench/stitch_vs_peers.py --full`; CLEANDIR: clean{0,1,2}.exr of
build/bench/bench_stitch_truth_views (the same views without the camera).

The noise is the merged view's log luminance minus the clean view's, both
taken the way the solve sees them (2x bilinear up as the bench does, 2x2 box
down as the stitch does). Its autocorrelation (every lag up to 16 px) comes
from the averaged periodograms of 64 x 64 windows at the matches. Per match,
with J the clean patch's gradients (the refinement's 15 x 15 patch, step and
half-pixel differences) and its three gain terms as nuisance parameters, and C
the two views' noise covariance over the patch (b's taken on a's grid):
Cov >= (J^T C^-1 J)^-1. A point's bound is sqrt(var_x + var_y), an edge's
the variance across the edge; both compare with |refined - true|.
--drop-list writes the matches whose bound exceeds PX (a b pb per line), for
the patch's SL_DROP. --noisy-gradients takes J from the merged view instead
(what the solve itself has).
"""
import sys

import numpy as np

sys.path.insert(0, "/work/shared/peers/merge")
from common import read_hdr  # noqa: E402

HALF = 7          # the refinement's patch: (2 HALF + 1)^2 samples
P = 64            # noise windows
LAGS = 16         # autocorrelation lags used


def log_lum(img):
    return np.log(np.maximum(0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2],
                             1e-30))


def reduce2(img):
    return 0.25 * (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2])


def bilinear(img, x, y):
    u, v = x - 0.5, y - 0.5
    x0, y0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fx, fy = u - x0, v - y0
    return ((1 - fy) * ((1 - fx) * img[y0, x0] + fx * img[y0, x0 + 1]) +
            fy * ((1 - fx) * img[y0 + 1, x0] + fx * img[y0 + 1, x0 + 1]))


def remove_plane(n):
    yy, xx = np.mgrid[0:n.shape[0], 0:n.shape[1]]
    a = np.stack([np.ones(n.size), xx.ravel(), yy.ravel()], 1)
    return n - (a @ np.linalg.lstsq(a, n.ravel(), rcond=None)[0]).reshape(n.shape)


def noise_acf(noise, pts):
    """Autocorrelation (lags -LAGS..LAGS) of a view's noise from Hann-tapered
    windows at pts; windows reaching the circle's edge (variance over 3x the
    median) are left out. From a non-negative spectrum, so every patch
    covariance built from it is positive semi-definite."""
    hann = np.outer(np.hanning(P), np.hanning(P))
    wins = []
    for x, y in pts:
        xi, yi = int(x) - P // 2, int(y) - P // 2
        wins.append(remove_plane(noise[yi:yi + P, xi:xi + P]))
    var = np.array([np.var(w) for w in wins])
    kept = [w for w, v in zip(wins, var) if v < 3 * np.median(var)]
    psd = sum(np.abs(np.fft.fft2(w * hann)) ** 2 for w in kept)
    acf = np.fft.fftshift(np.real(np.fft.ifft2(psd)) / (len(kept) * np.sum(hann ** 2)))
    return acf[P // 2 - LAGS:P // 2 + LAGS + 1, P // 2 - LAGS:P // 2 + LAGS + 1], len(kept), len(wins)


GRID_I, GRID_J = [g.ravel() for g in np.meshgrid(np.arange(-HALF, HALF + 1), np.arange(-HALF, HALF + 1))]
DX = GRID_I[:, None] - GRID_I[None, :]
DY = GRID_J[:, None] - GRID_J[None, :]


def patch_cov(acf, fx, fy):
    """Covariance over the patch of the noise sampled bilinearly at the
    fraction (fx, fy) of a pixel (unit step)."""
    w = {(0, 0): (1 - fx) * (1 - fy), (1, 0): fx * (1 - fy), (0, 1): (1 - fx) * fy, (1, 1): fx * fy}
    c = np.zeros(DX.shape)
    for (a0, b0), wa in w.items():
        for (a1, b1), wb in w.items():
            c += wa * wb * acf[DY + b0 - b1 + LAGS, DX + a0 - a1 + LAGS]
    return c


def rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else float("nan")


def main():
    dump, vdir, cdir = sys.argv[1:4]
    lines = open(dump).read().splitlines()
    step = float([l.split()[1] for l in lines if l.startswith("STEP ")][-1])
    m = np.array([[float(x) for x in l.split()[1:]] for l in lines if l.startswith("RES ")])
    noisy, clean = [], []
    import cv2
    for v in range(3):
        noisy.append(log_lum(reduce2(read_hdr("%s/view%d_24mp.exr" % (vdir, v)).astype(np.float64))))
        c = read_hdr("%s/clean%d.exr" % (cdir, v)).astype(np.float32)
        c = cv2.resize(c, (2 * c.shape[1], 2 * c.shape[0]), interpolation=cv2.INTER_LINEAR)
        clean.append(log_lum(reduce2(c.astype(np.float64))))
    acfs = []
    for v in range(3):
        pts = [r[2:4] for r in m if int(r[0]) == v] + [r[4:6] for r in m if int(r[1]) == v]
        acf, kept, total = noise_acf(noisy[v] - clean[v], pts)
        acfs.append(acf)
        c0 = acf[LAGS, LAGS]
        print("view %d noise: std %.4f (%d of %d windows); correlation at 1, 2, 4, 8 px: x %s, y %s"
              % (v, np.sqrt(c0), kept, total,
                 " ".join("%.2f" % (acf[LAGS, LAGS + k] / c0) for k in (1, 2, 4, 8)),
                 " ".join("%.2f" % (acf[LAGS + k, LAGS] / c0) for k in (1, 2, 4, 8))))
    wgt = np.exp(-(GRID_I ** 2 + GRID_J ** 2) / (0.5 * HALF * HALF))
    rows = []
    for r in m:
        a, b = int(r[0]), int(r[1])
        pa, pb, edge, normal, pt = r[2:4], r[4:6], r[6] > 0, r[7:9], r[11:13]
        x, y = pa[0] + GRID_I * step, pa[1] + GRID_J * step
        cl = noisy[a] if "--noisy-gradients" in sys.argv else clean[a]
        gx = bilinear(cl, x + 0.5, y) - bilinear(cl, x - 0.5, y)
        gy = bilinear(cl, x, y + 0.5) - bilinear(cl, x, y - 0.5)
        jac = np.stack([gx, gy, np.ones_like(gx), GRID_I / HALF, GRID_J / HALF], 1)
        cov_n = (patch_cov(acfs[a], (pa[0] - 0.5) % 1, (pa[1] - 0.5) % 1) +
                 patch_cov(acfs[b], (pb[0] - 0.5) % 1, (pb[1] - 0.5) % 1))
        crb = np.linalg.inv(jac.T @ np.linalg.solve(cov_n, jac))[:2, :2]
        # the refinement's own estimator (Gaussian weights) under the same noise
        h = np.linalg.inv(jac.T @ (wgt[:, None] * jac))
        lk = (h @ (jac.T * wgt) @ cov_n @ (wgt[:, None] * jac) @ h)[:2, :2]
        if edge:
            bound, bound_lk, err = np.sqrt(normal @ crb @ normal), np.sqrt(normal @ lk @ normal), abs(normal @ (pa - pt))
        else:
            bound, bound_lk, err = np.sqrt(np.trace(crb)), np.sqrt(np.trace(lk)), np.hypot(*(pa - pt))
        reproj = np.sqrt(0.5 * (r[9] ** 2 + r[10] ** 2))
        rows.append((edge, bound, bound_lk, err, reproj, np.sqrt(crb[0, 0]), np.sqrt(crb[1, 1])))
    o = np.array(rows, dtype=float)
    print("step %.2f px; %d inliers, %d on edges; px of the solve's views" % (step, len(o), int(o[:, 0].sum())))
    print("%-7s %4s %16s %16s %9s %9s %8s" % ("", "n", "bound rms (med)", "LK est. rms (med)",
                                              "true err", "reproj", "err/bound"))
    for name, sel in (("all", o[:, 0] >= 0), ("points", o[:, 0] == 0), ("edges", o[:, 0] == 1)):
        s = o[sel]
        print("%-7s %4d %9.3f (%.3f) %9.3f (%.3f) %9.3f %9.3f %8.2f" %
              (name, len(s), rms(s[:, 1]), np.median(s[:, 1]), rms(s[:, 2]), np.median(s[:, 2]),
               rms(s[:, 3]), rms(s[:, 4]), rms(s[:, 3] / s[:, 1])))
    p = o[o[:, 0] == 0]
    print("points: bound along x %.3f, along y %.3f (rms); corr(bound, true err) %.2f"
          % (rms(p[:, 5]), rms(p[:, 6]), np.corrcoef(p[:, 1], p[:, 3])[0, 1]))
    for px in (0.3, 0.5):
        k = o[:, 1] <= px
        print("bound <= %.1f px: %d kept (%d points); their true err %.3f, reproj %.3f (before re-solving)"
              % (px, k.sum(), (k & (o[:, 0] == 0)).sum(), rms(o[k, 3]), rms(o[k, 4])))
    if "--drop-list" in sys.argv:
        i = sys.argv.index("--drop-list")
        path, px = sys.argv[i + 1], float(sys.argv[i + 2])
        with open(path, "w") as f:
            for r, s in zip(m, o):
                if s[1] > px:
                    f.write("%d %d %.4f %.4f\n" % (r[0], r[1], r[4], r[5]))


if __name__ == "__main__":
    main()
