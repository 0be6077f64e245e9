#!/usr/bin/env python3
"""Can a bracket's noise tell a curve from the other members of its equal-step class?

With every step s in ln exposure, g -> g + p(g), p periodic of period s, fits noise-free
frames as well as the true curve (docs/merge.md "Real camera curves"). What is left to
choose the member is the noise: a member stretches each code's scatter by 1 + p'. This
scores the frames' log-likelihood under members g + a sin(2 pi g / s + phi) of the true
curve and says whether the true curve is the maximum.

The frames come from the bench, which keeps one bracket with exact steps:

  BENCH_KEEP=/tmp/k ./build/bench/bench_merge_crf --width 256 --curves 121 --alt-stops 3
  /usr/bin/python3 bench/crf_class_likelihood.py /tmp/k Ektachrome-64CDRed [--mode M]

The noise model is the camera's own (bench writes it: raw Poisson and read noise through
white balance and colour matrix). With --noise member (the default) each member's frames
carry the variance of a grey pixel at the member's own linear value, A mu + B, with a
factor on it fitted from --gains: a member moves each pixel's linear value by exp(p),
and the sensor's noise does not follow (the information bench/crf_class_floor.py
counts); --noise fixed gives every member the true curve's variance, pixel by pixel.
Codes are exact 8-bit bins, top codes censored. For each phase the peak of a parabola
through the scores says where the likelihood puts the curve along that member. Modes,
for each pixel's unknown radiance E (per channel):
  profile  E at its maximum (what a fit does; biased with few frames a pixel)
  flat     E integrated out under a flat prior in ln E of the member's own radiance
  density  E integrated out under the scene's density of ln E, estimated from the
           member's own radiance (a kernel estimate, leave-one-out): the default
A member changes the scene's radiance (E -> E exp(p)), so its flat prior is a different
prior on the scene; the density mode lets each member carry the scene it implies.
numpy and OpenCV (cv2) only; about 5 minutes a curve at --sub 8 (member noise).
"""
import argparse
import os
import sys

import cv2
import numpy as np

from crf_class_pairs import load_dorf  # the script's own folder is on the path


def ndtr(x):
    """Standard normal CDF (Abramowitz-Stegun erfc, 1.2e-7), vectorised, no scipy."""
    x = np.nan_to_num(x, posinf=40, neginf=-40) / np.sqrt(2)
    z = np.abs(x)
    t = 1 / (1 + 0.5 * z)
    poly = -z * z - 1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (
            -0.82215223 + t * 0.17087277))))))))
    erfc = t * np.exp(poly)
    return 0.5 * np.where(x <= 0, erfc, 2 - erfc)


def dorf_inverse_at_half_codes(path, name):
    """Linear exposure at codes (k + 0.5) / 255 through the DoRF curve `name`."""
    curve = [c for c in load_dorf(path) if c[0] == name]
    if not curve:
        sys.exit('%s: no curve named %s' % (path, name))
    _, irradiance, brightness = curve[0]
    return np.interp((np.arange(255) + 0.5) / 255, brightness, irradiance)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('dir', help='the bench\'s kept bracket (BENCH_KEEP)')
    ap.add_argument('curve', help='the DoRF curve\'s name, as the bench printed it')
    ap.add_argument('--mode', choices=('profile', 'flat', 'density'), default='density')
    ap.add_argument('--sub', type=int, default=4, help='every N-th pixel (4)')
    ap.add_argument('--amp', type=float, default=0.05, help='member amplitude a at s = 1, ln')
    ap.add_argument('--noise', choices=('member', 'fixed'), default='member',
                    help='variance in each member\'s own linear value (member) or the '
                         'true curve\'s, the same for every member (fixed)')
    ap.add_argument('--gains', default='0.9,1,1.1',
                    help='member noise: factors on the variance, the best kept')
    ap.add_argument('--bandwidth', type=float, default=0.05, help='density kernel, ln E')
    ap.add_argument('--dorf', default=os.path.join(os.path.dirname(__file__), '..', '..',
                                                    'shared', 'data', 'crf', 'dorfCurves.txt'))
    o = ap.parse_args()

    need = [os.path.join(o.dir, n) for n in ('times.txt', 'camera.txt', 'truth.txt')]
    missing = [n for n in need if not os.path.exists(n)]
    if missing:
        sys.exit('%s: not a kept bracket (no %s); keep one with BENCH_KEEP=DIR '
                 'bench_merge_crf' % (o.dir, ', '.join(os.path.basename(n) for n in missing)))
    rows = [l.split() for l in open(need[0])]
    times = np.array([float(r[1]) for r in rows])
    frames = [cv2.imread(r[0], cv2.IMREAD_UNCHANGED) for r in rows]
    if any(f is None or f.dtype != np.uint8 for f in frames):
        sys.exit('%s: frames must be 8-bit' % o.dir)
    z = np.stack([f[..., ::-1] for f in frames]).reshape(len(rows), -1, 3)[:, ::o.sub, :]
    z = z.astype(int)
    cam = [l.split() for l in open(os.path.join(o.dir, 'camera.txt'))]
    gain, floor = float(cam[0][0]), float(cam[0][1])  # raw variance: gain x + floor
    ccm = np.array([[float(v) for v in r[:3]] for r in cam[1:]])
    wb = np.array([float(r[3]) for r in cam[1:]])
    to_out = ccm * wb[None, :]
    to_raw = np.linalg.inv(to_out)
    step = np.log(times[1:] / times[:-1]).mean()
    half = dorf_inverse_at_half_codes(o.dorf, o.curve)
    censored = 242  # codes at or above: only "at least this" (the clip)

    # Each pixel's radiance through the true curve (best-exposed frame): the noise's
    # variance per frame and channel, raw Poisson + read noise mixed by the matrix.
    truth = np.array([float(l) for l in open(os.path.join(o.dir, 'truth.txt'))])
    x = truth[z] / times[:, None, None]
    best = np.abs(z - 128).argmin(0)
    e0 = np.take_along_axis(x, best[None], 0)[0]
    raw = np.einsum('ij,knj->kni', to_raw, e0[None] * times[:, None, None]).clip(0, 1)
    var = np.einsum('ij,knj->kni', to_out ** 2, gain * raw + floor)

    # A grey pixel's variance law in the linear value: A mu + B (the noise a member
    # carries follows its own linear value, which is what the member gets wrong)
    a_law = gain * (to_out ** 2) @ (to_raw @ np.ones(3))
    b_law = floor * (to_out ** 2).sum(1)
    noise_factor = [1.0]

    def loglik(inv_half):
        lo = np.concatenate([[-np.inf], inv_half])
        hi = np.concatenate([inv_half, [np.inf]])
        hi[censored - 1:] = np.inf
        lo[censored:] = inv_half[censored - 1]
        total = 0.0
        for c in range(3):
            zc = z[:, :, c]
            L, H, sd_true = lo[zc], hi[zc], np.sqrt(var[:, :, c])
            use = ((zc > 0) & (zc < censored)).sum(0) >= 2

            def frames_ll(ln_e):
                mu = np.exp(ln_e)[None, :] * times[:, None]
                sd = sd_true if o.noise == 'fixed' else \
                    np.sqrt(noise_factor[0] * (a_law[c] * mu + b_law[c]))
                p = ndtr((H - mu) / sd) - ndtr((L - mu) / sd)
                return np.log(np.maximum(p, 1e-300)).sum(0)
            ln_e = np.log(np.maximum(e0[:, c], 1e-12))
            for width in (0.3, 0.03, 0.003):
                offs = np.linspace(-width, width, 21)
                vals = np.stack([frames_ll(ln_e + d) for d in offs])
                ln_e = ln_e + offs[vals.argmax(0)]
            if o.mode == 'profile':
                total += frames_ll(ln_e)[use].sum()
                continue
            offs = np.linspace(-0.4, 0.4, 161)
            vals = np.stack([frames_ll(ln_e + d) for d in offs])
            top = vals.max(0)
            total += (top + np.log(np.exp(vals - top).sum(0) * (offs[1] - offs[0])))[use].sum()
            if o.mode == 'density':
                xs, bw = ln_e[use], o.bandwidth
                bin_w = bw / 10
                origin = xs.min() - 5 * bw
                idx = ((xs - origin) / bin_w).astype(int)
                counts = np.bincount(idx, minlength=int((xs.max() + 5 * bw - origin) / bin_w) + 1)
                kx = np.arange(-50, 51) * bin_w
                kernel = np.exp(-0.5 * (kx / bw) ** 2) / (np.sqrt(2 * np.pi) * bw)
                dens = np.convolve(counts.astype(float), kernel, mode='same')
                leave_one_out = (dens[idx] - kernel[50]) / (len(xs) - 1)
                total += np.log(np.maximum(leave_one_out, 1e-300)).sum()
        return total

    def best_over_scale(inv_half):
        """The maximum over the variance's factors (member noise) and the scale."""
        best = -np.inf
        for factor in [float(v) for v in o.gains.split(',')] if o.noise == 'member' else [1]:
            noise_factor[0] = factor
            best = max(best, best_over_scale_only(inv_half))
        return best

    def best_over_scale_only(inv_half):
        """The likelihood's maximum over a free scale (a curve is known up to one)."""
        best, at = -np.inf, 0.0
        for ls in np.linspace(-0.1, 0.1, 11):
            v = loglik(inv_half * np.exp(ls))
            best, at = (v, ls) if v > best else (best, at)
        for ls in at + np.linspace(-0.02, 0.02, 9):
            v = loglik(inv_half * np.exp(ls))
            best, at = (v, ls) if v > best else (best, at)
        return best

    base = best_over_scale(half)
    print('# %s, %s, mode %s, noise %s: log-likelihood of members g + s %.3g '
          'sin(2 pi g / %.3f + phi) less the true curve\'s (%.1f)' %
          (o.dir, o.curve, o.mode, o.noise, o.amp, step, base))
    worst = -np.inf
    gh = np.log(np.maximum(half, 1e-12))
    for phi in (0, np.pi / 2):
        cells, grid, vals = [], (-1, -0.5, 0.5, 1), [0.0]
        for s in grid:
            v = best_over_scale(half * np.exp(s * o.amp * np.sin(2 * np.pi * gh / step + phi)))
            worst = max(worst, v - base)
            cells.append('s %+.1f: %+8.1f' % (s, v - base))
            vals.append(v - base)
        # where the likelihood peaks along this phase: a parabola through s = 0 and the grid
        curve2, slope, _ = np.polyfit((0,) + grid, vals, 2)
        peak = -slope / (2 * curve2) if curve2 < 0 else float('nan')
        print('phi %.2f  %s  peak at s %+.2f (%.2f%% in ln)' % (
            phi, '  '.join(cells), peak, 100 * peak * o.amp), flush=True)
    print('true curve is the maximum: %s (best member %+.1f nats)' %
          ('yes' if worst < 0 else 'no', worst))


if __name__ == '__main__':
    main()
