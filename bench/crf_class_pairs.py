#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Do DoRF's camera curves hide one another under a bracket of equal steps?

With every step s in ln exposure, curve b's frames of a scene E are curve a's
frames of the scene Psi(E), bit for bit when noise-free, wherever
g_b = g_a + p(g_a) + c with p periodic of period s (g = ln f^-1) and
v + p(v) rising (Psi must be a scene: monotone). No merge can tell such a
pair apart, so it must be wrong on one of them by about half of p. This
fits p (12 harmonics) to every ordered pair over the codes a merge weighs
and counts the pairs that match within a residual, differ by more than a
given periodic part, and have a rising Psi (docs/merge.md, "Real camera
curves").

usage: bench/crf_class_pairs.py [DORF_TXT] [--codes LO,HI] [--step STOPS]
       [--residual R] [--periodic A]
"""
import argparse
import numpy as np


def load_dorf(path):
    lines = open(path).read().split('\n')
    curves, i = [], 0
    while i < len(lines):
        if lines[i].strip() == 'I =':  # I: irradiance (a uniform grid), B: brightness
            irradiance = np.array(lines[i + 1].split(), float)
            brightness = np.array(lines[i + 3].split(), float)
            curves.append((lines[i - 2].strip(), irradiance, brightness))
            i += 4
        else:
            i += 1
    return curves


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('dorf', nargs='?', default='../shared/data/crf/dorfCurves.txt')
    ap.add_argument('--codes', default='0.01,0.98')
    ap.add_argument('--step', type=float, default=2.979, help='stops (the bench: 2.979 mean)')
    ap.add_argument('--residual', type=float, default=0.002, help='rms in ln exposure')
    ap.add_argument('--periodic', type=float, default=0.03, help='rms of p')
    args = ap.parse_args()
    lo, hi = (float(v) for v in args.codes.split(','))
    curves = load_dorf(args.dorf)
    z = np.linspace(lo, hi, 300)
    g = []
    for _, irradiance, brightness in curves:
        codes, first = np.unique(brightness, return_index=True)
        g.append(np.log(np.maximum(np.interp(z, codes, irradiance[first]), 1e-9)))
    g = np.array(g)
    period, harmonics = args.step * np.log(2), 12

    def basis(v):
        cols = [np.ones_like(v)]
        for h in range(1, harmonics + 1):
            cols += [np.cos(2 * np.pi * h * v / period), np.sin(2 * np.pi * h * v / period)]
        return np.stack(cols, 1)

    phase = np.linspace(0, period, 512, endpoint=False)
    phase_basis = basis(phase)[:, 1:]
    n = len(g)
    span = (g[:, -1] - g[:, 0]) / period
    matched = rising = 0
    partnered, sizes = set(), []
    for a in range(n):
        # Every curve b against a at once: one pseudo-inverse of a's design.
        diff = g - g[a]
        coef = diff @ np.linalg.pinv(basis(g[a])).T
        residual = np.sqrt(np.mean((diff - coef @ basis(g[a]).T) ** 2, axis=1))
        p = coef[:, 1:] @ phase_basis.T
        size = np.std(p, axis=1)
        for b in np.flatnonzero((residual < args.residual) & (size > args.periodic)):
            if b == a:
                continue
            matched += 1
            if (1 + np.gradient(p[b], phase)).min() > 0:
                rising += 1
                partnered.add(b)
                sizes.append(size[b])
    print('%d curves; codes %g-%g span %.2f periods of %.3f stops (median; %.2f-%.2f)'
          % (n, lo, hi, np.median(span), args.step, span.min(), span.max()))
    print('ordered pairs within %.2f%% rms of g_a + p(g_a) + c, p over %.0f%% rms: %d; '
          'with a rising Psi: %d' % (100 * args.residual, 100 * args.periodic, matched, rising))
    if partnered:
        names = sorted(curves[b][0] for b in partnered)
        print('curves with such a partner: %d (p rms median %.3f): %s'
              % (len(partnered), np.median(sizes), ', '.join(names)))


if __name__ == '__main__':
    main()
