#!/usr/bin/env python3
"""How precisely do a bracket's frames pin its curve's equal-step class? (Cramer-Rao)

With every step s in ln exposure, g -> g + p(g), p periodic of period s, fits noise-free
frames as well as the true curve (docs/merge.md "Real camera curves"). The noise is what
is left to tell the members apart: a member stretches each code's bin by 1 + p' and moves
each pixel's linear value by exp(p), which the sensor's noise (variance A mu + B in the
linear value mu) does not follow. This computes the Fisher information of the frames on
the class coordinates theta (p = sum theta_j b_j, the first H harmonics of the step) with
each pixel's radiance a free parameter (taken out per pixel, Schur complement) and, unless
--noise-known, each channel's A and B free too; one curve for the three channels. Codes
are exact 8-bit bins, codes from --censor up read "at least". The bound Cov >= I^-1 gives
the class's radiance error (rms over the scene's pixels, after a free scale) that no
unbiased estimator of the curve can beat from these frames; set against the ideal
estimator's median error (Gaussian: 1.1x allows a systematic rms of 0.458 sigma).

The scene, the exposures and the camera's noise come from one bracket the bench keeps
(any curve; each curve's bins come from DoRF):

  BENCH_KEEP=/tmp/k ./build/bench/bench_merge_crf --width 256 --curves 7
  ./build/bench/bench_merge_crf --width 256 > /tmp/all.txt   # optional: ideal errors
  /usr/bin/python3 bench/crf_class_floor.py /tmp/k [--ideal /tmp/all.txt] [--equal]

The noise: raw Poisson and read noise through white balance and the colour matrix, taken
at a grey pixel (A_c = gain sum_j M_cj^2 r_j, B_c = floor sum_j M_cj^2); white-balanced
clips are not modelled. --pixels scales the kept scene's histogram to a frame size
(default 1024x512, the issue's). numpy and OpenCV only; under a second a curve.
"""
import argparse
import os
import sys

import cv2
import numpy as np

from crf_class_pairs import load_dorf  # the script's own folder is on the path
from crf_class_likelihood import ndtr


def npdf(x):
    x = np.nan_to_num(x, posinf=40, neginf=-40)
    return np.exp(-0.5 * x * x) / np.sqrt(2 * np.pi)


def harmonics(v, count, step):
    return np.stack([f(2 * np.pi * h * v / step) for h in range(1, count + 1)
                     for f in (np.cos, np.sin)], -1)


def class_information(edge, ln_e, counts, times, a_c, b_c, count, step, censor):
    """Fisher information on (theta, A, B) of one channel, each pixel's ln E taken out.

    edge: linear exposure at the half codes (k + 0.5) / 255 through the curve; ln_e,
    counts: the scene's histogram of ln E; a_c, b_c: the noise's variance law."""
    lo = np.concatenate([[-np.inf], edge])[:censor + 1]  # code 0: that code or less
    hi = np.concatenate([edge, [np.inf]])[:censor + 1].copy()
    hi[censor] = np.inf  # code `censor`: that code or more
    finite_hi = np.where(np.isfinite(hi), hi, 0)
    finite_lo = np.where(np.isfinite(lo), lo, 0)
    b_lo = harmonics(np.log(np.maximum(finite_lo, 1e-30)), count, step) * (lo > 0)[:, None]
    b_hi = harmonics(np.log(np.where(np.isfinite(hi), hi, 1)), count, step) * \
        np.isfinite(hi)[:, None]
    n = 1 + 2 * count + 2
    info = np.zeros((len(ln_e), n, n))
    for t in times:
        mu = np.exp(ln_e)[:, None] * t
        sd = np.sqrt(a_c * mu + b_c)
        a, b = (hi[None] - mu) / sd, (lo[None] - mu) / sd
        p = np.where(b > 0, ndtr(-b) - ndtr(-a), ndtr(a) - ndtr(b))  # no cancellation
        ok = p > 1e-14
        p = np.where(ok, p, 1.0)
        pa, pb = npdf(a), npdf(b)
        d_mu = -(pa - pb) / sd
        d_sd = -(np.where(np.isfinite(a), a, 0) * pa - np.where(np.isfinite(b), b, 0) * pb) / sd
        scores = [mu * (d_mu + d_sd * a_c / (2 * sd))]  # ln E: mu and the noise move
        for j in range(2 * count):  # theta_j scales each edge by exp(b_j(ln edge))
            scores.append((pa * finite_hi[None] * b_hi[None, :, j] -
                           pb * finite_lo[None] * b_lo[None, :, j]) / sd)
        scores += [d_sd * mu / (2 * sd), d_sd / (2 * sd)]  # A, B
        s = np.stack(scores, -1)
        info += np.einsum('bzp,bzq,bz->bpq', s, s, ok / p)
    per_pixel = info[:, 1:, 1:] - info[:, 1:, :1] * info[:, :1, 1:] / \
        np.maximum(info[:, :1, :1], 1e-300)
    return (per_pixel * counts[:, None, None]).sum(0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('dir', help='a bracket the bench kept (BENCH_KEEP)')
    ap.add_argument('--curves', default='all', help='DoRF indices, comma-separated')
    ap.add_argument('--harmonics', type=int, default=2, help='of the step (2)')
    ap.add_argument('--censor', type=int, default=250, help='codes from here: "at least"')
    ap.add_argument('--equal', action='store_true', help='steps exactly the mean step')
    ap.add_argument('--noise-known', action='store_true', help='A and B given, not fitted')
    ap.add_argument('--pixels', type=float, default=1024 * 512, help='frame size to scale to')
    ap.add_argument('--show-information', action='store_true',
                    help='also print the information on each coordinate alone (cos, sin)')
    ap.add_argument('--ideal', help='the bench\'s output for the same curves (ideal median)')
    ap.add_argument('--dorf', default=os.path.join(os.path.dirname(__file__), '..', '..',
                                                    'shared', 'data', 'crf', 'dorfCurves.txt'))
    o = ap.parse_args()
    need = [os.path.join(o.dir, n) for n in ('times.txt', 'camera.txt', 'truth.txt')]
    missing = [os.path.basename(n) for n in need if not os.path.exists(n)]
    if missing:
        sys.exit('%s: not a kept bracket (no %s); keep one with BENCH_KEEP=DIR '
                 'bench_merge_crf' % (o.dir, ', '.join(missing)))
    rows = [l.split() for l in open(need[0])]
    times = np.array([float(r[1]) for r in rows])
    frames = [cv2.imread(r[0], cv2.IMREAD_UNCHANGED) for r in rows]
    if any(f is None or f.dtype != np.uint8 for f in frames):
        sys.exit('%s: frames must be 8-bit' % o.dir)
    z = np.stack([f[..., ::-1] for f in frames]).reshape(len(rows), -1, 3).astype(int)
    cam = [l.split() for l in open(need[1])]
    gain, floor = float(cam[0][0]), float(cam[0][1])
    to_out = np.array([[float(v) for v in r[:3]] for r in cam[1:]]) * \
        np.array([float(r[3]) for r in cam[1:]])[None, :]
    a_law = gain * (to_out ** 2) @ (np.linalg.inv(to_out) @ np.ones(3))
    b_law = floor * (to_out ** 2).sum(1)
    step = np.log(times[1:] / times[:-1]).mean()
    if o.equal:
        times = times[0] * np.exp(step * np.arange(len(times)))
    # the scene: each pixel's radiance through the kept curve, best-exposed frame
    truth = np.array([float(l) for l in open(need[2])])
    best = np.abs(z - 128).argmin(0)
    scene = np.take_along_axis(truth[z] / times[:, None, None], best[None], 0)[0]
    scale = o.pixels / z.shape[1]
    curves = load_dorf(o.dorf)
    try:
        pick = range(len(curves)) if o.curves == 'all' else \
            [int(v) for v in o.curves.split(',')]
    except ValueError:
        sys.exit('--curves: indices 0-%d separated by commas, not %s' % (len(curves) - 1,
                                                                         o.curves))
    if any(not 0 <= ci < len(curves) for ci in pick):
        sys.exit('--curves: %s: %s holds curves 0-%d' % (o.curves, o.dorf, len(curves) - 1))
    ideal = {}
    if o.ideal:
        for fields in (l.split() for l in open(o.ideal)):
            if len(fields) > 10 and fields[0].isdigit():
                ideal[int(fields[0])] = float(fields[8])  # ideal median %, per pixel
    count, bin_w = o.harmonics, 0.02
    print('# %s, %d harmonics of %.3f, %s steps, noise %s, %.0f pixels: class rms %% (the '
          'bound, free scale)%s' % (o.dir, count, step, 'equal' if o.equal else 'kept',
                                    'known' if o.noise_known else 'A, B fitted per channel',
                                    o.pixels, '; ideal median %, floor ratio of the median'
                                    if o.ideal else ''))
    worst = (0, None)
    for ci in pick:
        name, irradiance, brightness = curves[ci]
        codes, first = np.unique(brightness, return_index=True)
        edge = np.interp((np.arange(255) + 0.5) / 255, codes, irradiance[first])
        edge = np.maximum.accumulate(np.maximum(edge, 1e-12))
        theta_info = np.zeros((2 * count, 2 * count))
        spread, mean, total = 0, 0, 0
        for c in range(3):
            cells, counts = np.unique(np.floor(np.log(np.maximum(scene[:, c], 1e-12)) /
                                               bin_w).astype(int), return_counts=True)
            ln_e = (cells + 0.5) * bin_w
            f = class_information(edge, ln_e, counts, times, a_law[c], b_law[c], count,
                                  step, o.censor) * scale
            t = slice(0, 2 * count)
            if o.noise_known:
                theta_info += f[t, t]
            else:
                cross = f[t, 2 * count:]
                theta_info += f[t, t] - cross @ np.linalg.pinv(f[2 * count:, 2 * count:]) @ cross.T
            # a member's radiance error: p at the pixel's frame nearest mid-grey
            frame = np.abs(np.log(np.exp(ln_e)[:, None] * times[None] / 0.18)).argmin(1)
            b = harmonics(ln_e + np.log(times[frame]), count, step)
            spread = spread + np.einsum('bj,bk,b->jk', b, b, counts)
            mean, total = mean + (b * counts[:, None]).sum(0), total + counts.sum()
        m = spread / total - np.outer(mean / total, mean / total)
        rms = 100 * np.sqrt(max(np.trace(np.linalg.pinv(theta_info) @ m), 0))
        line = '%3d %-32s %.4f' % (ci, name, rms)
        if o.show_information:
            line += '  information ' + ' '.join('%.4g' % v for v in np.diag(theta_info))
        if ci in ideal:
            sigma = ideal[ci] / 0.6745
            ratio = np.sqrt(1 + (rms / sigma) ** 2)
            line += '  %.2f  %.5f' % (ideal[ci], ratio)
            worst = max(worst, (ratio, name))
        print(line, flush=True)
    if worst[1]:
        print('# worst floor ratio %.5f (%s); the goal is 1.1' % worst)


if __name__ == '__main__':
    main()
