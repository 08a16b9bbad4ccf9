#!/usr/bin/env python3
"""What a seal-friction bound on the yield-stress σ would do (issue 13, analysis only).

    .venv/bin/python scripts/proving_ground/friction_bound.py [--seeds 0:100] [--dir /tmp/pgcov] [--bin BIN]

Replays the estimator-coverage scenarios (estimator_coverage.py; generated into --dir when
missing) and, per κ, widens every published σ by κ × the running minimum of the record's
published τ0 in quadrature (a current-independent friction cannot exceed the smallest yield
force the record shows), then prints 2σ coverage and the median 2σ band (relative to the
true τ) per current range, and coverage on records with and without a hidden seal friction.
"""
import argparse
import multiprocessing as mp
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import pin_blas  # noqa: E402,F401  (before numpy: the same kernels on every machine)

import numpy as np  # noqa: E402

from estimator_coverage import _record_task, _seeds  # noqa: E402

RANGES = ((0.0, 0.25), (0.25, 0.5), (0.5, 1.0), (1.0, np.inf))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="0:100")
    ap.add_argument("--dir", default="/tmp/pgcov")
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "..", "target", "release", "mrtwin"))
    ap.add_argument("--kappas", default="0,0.25,0.35,0.5")
    a = ap.parse_args()
    os.makedirs(a.dir, exist_ok=True)
    tasks = [(s, a.dir, os.path.abspath(a.bin), (0.5,), 600.0, False) for s in _seeds(a.seeds)]
    with mp.Pool(2) as pool:
        recs = pool.map(_record_task, tasks)
    recs = [r for r in recs if "error" not in r and "0.5" in r.get("points", {})]
    print("| κ | " + " | ".join(f"{lo:g}–{hi:g} A" for lo, hi in RANGES) + " |")
    print("|---" * (len(RANGES) + 1) + "|")
    for kappa in (float(k) for k in a.kappas.split(",")):
        pts = []
        for r in recs:
            q = r["points"]["0.5"]
            fr = "seal_friction" in r["hidden"]
            low = np.minimum.accumulate(np.asarray(q["tau0"]))
            sd = np.hypot(np.asarray(q["sd"]), kappa * low)
            z = (np.asarray(q["tau0"]) - np.asarray(q["truth"])) / sd
            band = 2 * sd / np.asarray(q["truth"])
            pts += [(fr, i, zz, b) for i, zz, b in zip(q["i_field"], z, band)]
        cells = []
        for lo, hi in RANGES:
            sel = [p for p in pts if lo <= p[1] < hi]
            z = np.array([p[2] for p in sel])
            fr = np.array([p[0] for p in sel])
            b = np.array([p[3] for p in sel])
            cells.append(f"{100 * np.mean(abs(z) < 2):.0f} %, ±{100 * np.median(b):.0f} % "
                         f"(friction {100 * np.mean(abs(z[fr]) < 2):.0f} %, "
                         f"none {100 * np.mean(abs(z[~fr]) < 2):.0f} %)")
        print(f"| {kappa:g} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
