"""How close can a model evaluated on the record's samples come to a proving-ground record?

For each seed (nulls are the useful ones), evaluate the generator's own law with its *true*
parameters (no hidden effect) and compare with the recorded force, in σ_F:

  noise            the recording against the true force through the fine-grid filter (≈ 1)
  coarse, no filter   true law at the filtered noise-free velocity, on the record's samples
  coarse, filtered    the same, then the true 2nd-order Butterworth (bilinear) and its
                      group delay advanced back — what diagnose's baseline does
  fine ×M, filtered   the law on an M× finer grid (linear interpolation), filtered there,
                      decimated: the floor of a sub-sample evaluation

    .venv/bin/python scripts/proving_ground/measurement_floor.py 20 21 22 41 57

With `--residuals DIR` (files DIR/NNNN.res.csv from `mrtwin diagnose --residuals`), also the
rebuilt velocity against the noise-free filtered one (RMS error over the stated σ near
reversal, |v| < 10 % of the peak) and the fine ×8 floor at the *rebuilt* velocity:

    .venv/bin/python scripts/proving_ground/measurement_floor.py --residuals /tmp/res 238 30 52

docs/diagnose.md (Limits) and BENCHMARKS.md (issue 10, session 59) quote its output.
"""
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pin_blas  # noqa: E402,F401  (before numpy: the same kernels on every machine)

import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

import generate as g  # noqa: E402
import physics



def coarse_filter(u, fc_per_fs):
    k = np.tan(np.pi * fc_per_fs)
    norm = 1 / (1 + np.sqrt(2) * k + k * k)
    b0 = k * k * norm
    a1, a2 = 2 * (k * k - 1) * norm, (1 - np.sqrt(2) * k + k * k) * norm
    b, a = [b0, 2 * b0, b0], [1, a1, a2]
    z = signal.lfilter(b, a, u, zi=signal.lfilter_zi(b, a) * u[0])[0]
    delay = 1 - (a1 + 2 * a2) / (1 + a1 + a2)
    return np.interp(np.arange(len(u)) + delay, np.arange(len(u)), z)


def fine_filtered(vf, xf, If, fs, fc, p, M):
    """The law on an M× finer grid (linear interpolation), filtered there, decimated."""
    n = len(vf)
    tf = np.arange((n - 1) * M + 1) / M
    vi, xi, Ii = (np.interp(tf, np.arange(n), y) for y in (vf, xf, If))
    ff = physics.simulate(xi, vi, np.gradient(vi, 1 / (fs * M)), Ii, 1 / (fs * M), p)[0]
    sos2 = signal.butter(2, fc, fs=fs * M, output="sos")
    z = signal.sosfilt(sos2, ff, zi=signal.sosfilt_zi(sos2) * ff[0])[0]
    d = np.sqrt(2) / (2 * np.pi * fc) * fs * M
    return np.interp(np.arange(len(z)) + d, np.arange(len(z)), z)[::M]


def main(seeds, residuals=None):
    for seed in seeds:
        meta, rec, fl, p, exc, t, x, v, a, icmd = g.base_law_rig(seed)  # the law alone
        meas = meta["measurement"]
        fs, m, fc = exc["fs_hz"], exc["oversampling"], meas["aa_cutoff_hz"]
        sig, off = meta["sigma_F_N"], meta["force_offset_N"]
        f_rec = rec["force_N"] - off
        rms = lambda y: float(np.sqrt(np.mean(y ** 2)) / sig)
        truth = g.aa_filter(physics.simulate(x, v, a, icmd, 1 / (fs * m), p)[0], fs * m, fc, m)
        sos = signal.butter(2, fc, fs=fs * m, output="sos")
        filt = lambda y: signal.sosfilt(sos, y, zi=signal.sosfilt_zi(sos) * y[0])[0][::m]
        vf, xf, If = filt(v), filt(x), filt(icmd)
        coarse = physics.simulate(xf, vf, np.gradient(vf, 1 / fs), If, 1 / fs, p)[0]
        line = (f"seed {seed} ({fl['law']}, {fs} Hz, hidden {meta['hidden']}): "
                f"noise {rms(f_rec - truth):.2f}, coarse no filter {rms(f_rec - coarse):.2f}, "
                f"coarse filtered {rms(f_rec - coarse_filter(coarse, fc / fs)):.2f}")
        for M in (2, 8):
            zz = fine_filtered(vf, xf, If, fs, fc, p, M)
            line += f", fine x{M} filtered {rms(f_rec[: len(zz)] - zz):.2f}"
        path = residuals and os.path.join(residuals, f"{seed:04d}.res.csv")
        if path and os.path.exists(path):
            with open(path) as f:
                rows = list(csv.DictReader(f))
            vh = np.array([float(r["velocity_m_s"]) for r in rows])
            sv = np.array([float(r["velocity_sigma_m_s"]) for r in rows])
            n = len(vh)
            near = np.abs(vf[:n]) < 0.1 * np.max(np.abs(vf[:n]))
            z = (vh - vf[:n])[near] / sv[near]
            zz = fine_filtered(vh, xf[:n], If[:n], fs, fc, p, 8)
            line += (f"; rebuilt velocity: error {np.sqrt(np.mean(z ** 2)):.2f} stated σ near "
                     f"reversal, fine x8 filtered {rms(f_rec[: len(zz)] - zz):.2f}")
        print(line)


if __name__ == "__main__":
    args = sys.argv[1:]
    res = None
    if args[:1] == ["--residuals"]:
        res, args = args[1], args[2:]
    main([int(s) for s in args] or [20, 21, 22, 41, 57], res)
