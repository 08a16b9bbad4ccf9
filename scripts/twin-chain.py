#!/usr/bin/env python3
"""The closed loop of issue 12 on simulated and real records, as quoted in BENCHMARKS.md:
`mrtwin fit` → `mrtwin diagnose --params --write-params` → `mrtwin replay` of both twins.

    python3 scripts/twin-chain.py [--bin target/release/mrtwin] [--only NAME]

Per record: samples; the fitted twin's replay RMS; what diagnose found; the upgraded twin's
replay RMS and its ratio, against the ratio predicted by taking the variance diagnose's
findings explained (held-out, unweighted) off the twin's residual, and diagnose's own ratio;
diagnose's final held-out RMS; the wall time of fit, diagnose (with the upgrade) and the
two replays; and, over the same samples (every sample of the record, from diagnose's
`--residuals` and the replay), the upgraded twin's RMS residual against diagnose's final
model's. Records: two simulated two-chamber records (`mrtwin simulate`, nothing hidden
and gas spring + seal friction hidden), the four UTFSM tests (five currents each, as in
scripts/diagnose-real.py) and Dyke's ransim_u. Standard library only.
"""
import argparse
import csv
import importlib.util
import json
import math
import os
import subprocess
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REAL = os.path.join(ROOT, "..", "shared", "data", "real")


def _real():
    spec = importlib.util.spec_from_file_location(
        "diagnose_real", os.path.join(ROOT, "scripts", "diagnose-real.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run(cmd):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t


def replay_rms(binary, rec, params, out):
    dt = run([binary, "replay", rec, "--params", params, "--out", out])
    with open(out) as f:
        e = [float(r["residual_N"]) for r in csv.DictReader(f)]
    e = [x for x in e if math.isfinite(x)]
    return math.sqrt(sum(x * x for x in e) / len(e)), dt


def same_samples_rms(residuals_csv, replay_csv):
    """(diagnose's final model, the replayed twin) RMS residual over the same samples: every
    row of the record where both are finite (diagnose's `--residuals` and the replay's CSV
    have one row per sample, in order; their times are checked)."""
    with open(residuals_csv) as f:
        dg = list(csv.DictReader(f))
    with open(replay_csv) as f:
        rp = list(csv.DictReader(f))
    assert len(dg) == len(rp), (len(dg), len(rp))
    a = b = n = 0.0
    for x, y in zip(dg, rp):
        assert abs(float(x["time_s"]) - float(y["time_s"])) < 1e-9, (x["time_s"], y["time_s"])
        e1 = float(x["force_N"]) - float(x["final_N"])
        e2 = float(y["residual_N"])
        if math.isfinite(e1) and math.isfinite(e2):
            a, b, n = a + e1 * e1, b + e2 * e2, n + 1
    return math.sqrt(a / n), math.sqrt(b / n)


def chain(name, rec, binary, tmp):
    twin, up = os.path.join(tmp, "twin.yaml"), os.path.join(tmp, "up.yaml")
    dj, res = os.path.join(tmp, "d.json"), os.path.join(tmp, "res.csv")
    t_fit = run([binary, "fit", rec, "--out", twin])
    t_dg = run([binary, "diagnose", rec, "--params", twin, "--write-params", up,
                "--json", dj, "--report", os.devnull, "--residuals", res])
    with open(dj) as f:
        d = json.load(f)
    r_twin, t1 = replay_rms(binary, rec, twin, os.path.join(tmp, "r0.csv"))
    r_up, t2 = replay_rms(binary, rec, up, os.path.join(tmp, "r1.csv"))
    claim = d["twin"]["predicted_replay_ratio"]
    raw = d["twin"]["diagnose_holdout_ratio"]
    found = ", ".join(x["effect"] for x in d["findings"]) or "—"
    dg_same, up_same = same_samples_rms(res, os.path.join(tmp, "r1.csv"))
    return ("| %s | %d | %.1f | %s | %.1f | %.3f | %.3f | %.3f | %.1f | %.2f vs %.2f | "
            "%.1f + %.1f + %.1f s |") % (
        name, d["samples"], r_twin, found, r_up, r_up / r_twin, claim, raw,
        d["final"]["holdout_rmse_unweighted_N"], up_same, dg_same, t_fit, t_dg, t1 + t2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "mrtwin"))
    ap.add_argument("--only", default=None, help="run only records whose name contains this")
    args = ap.parse_args()
    real = _real()
    print("| record | samples | fitted twin: replay RMS (N) | found | upgraded: replay RMS (N) "
          "| replay ratio | predicted ratio | diagnose's own ratio | diagnose final held-out (N) "
          "| same samples: upgraded twin vs diagnose final (N) | fit + diagnose + replays |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        records = []
        for name, effects, extra, seed in [
                ("simulated, nothing hidden", "none", [], 3),
                ("simulated, gas_spring + seal_friction", "gas_spring,seal_friction",
                 ["--seal-friction", "120"], 4)]:
            path = os.path.join(tmp, "sim%d.csv" % seed)
            run([args.bin, "simulate", "--model", "two-chamber", "--effects", effects,
                 "--noise", "0.005", "--seed", str(seed), "--out", path] + extra)
            records.append((name, path))
        for stem in ["5mm3Hz", "2mm5Hz", "10mm1Hz", "25mm0x5Hz"]:
            path = os.path.join(tmp, stem + ".csv")
            real.utfsm_csv(stem, path)
            records.append(("UTFSM %s (5 currents)" % stem, path))
        records.append(("Dyke ransim_u", os.path.join(REAL, "dyke-nees", "ransim_u.csv")))
        for name, path in records:
            if args.only and args.only not in name:
                continue
            print(chain(name, path, args.bin, tmp), flush=True)


if __name__ == "__main__":
    main()
