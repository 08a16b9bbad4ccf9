#!/usr/bin/env python3
"""`mrtwin diagnose` on the real recordings of ../shared/data/real, as quoted in BENCHMARKS.md.

UTFSM: the five currents (0, 0.25, 0.5, 0.75, 1 A) of one test concatenated into one
recording, time made continuous, mm and mm/s turned into m and m/s (the same concatenation
as diagnose/tests/real_recordings.rs). Dyke: ransim_u.csv as it is.

    python3 scripts/diagnose-real.py [--bin target/release/mrtwin] [--selector calibrated]

Prints a Markdown table: samples, held-out RMS baseline → final, findings with their
parameters, the number of unexplained entries, withdrawn effects, and the current knots the
record does not identify. Standard library only.
"""
import argparse
import json
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REAL = os.path.join(ROOT, "..", "shared", "data", "real")
CURRENTS = [("0A", 0.0), ("0x25A", 0.25), ("0x5A", 0.5), ("0x75A", 0.75), ("1A", 1.0)]


def utfsm_csv(stem, out):
    """Concatenate the five currents of UTFSM test `stem` (e.g. 5mm3Hz) into `out`."""
    rows, t_end = [], 0.0
    for tag, amps in CURRENTS:
        path = os.path.join(REAL, "maurel-utfsm", "preprocessed", f"{stem}{tag}.txt")
        with open(path) as f:
            data = [list(map(float, line.split())) for line in f if line.strip()]
        t0, dt = data[0][0], data[1][0] - data[0][0]
        rows += [(t_end + r[0] - t0, r[1] * 1e-3, r[2] * 1e-3, r[3], amps) for r in data]
        t_end = rows[-1][0] + dt
    with open(out, "w") as f:
        f.write("time_s,displacement_m,velocity_m_s,force_N,current_A\n")
        for r in rows:
            f.write("%.6f,%.9g,%.9g,%.6g,%g\n" % r)


def row(name, path, binary, selector, tmp):
    js = os.path.join(tmp, "d.json")
    subprocess.run([binary, "diagnose", path, "--selector", selector, "--json", js,
                    "--report", os.devnull], check=True, capture_output=True)
    with open(js) as f:
        d = json.load(f)
    finds = ", ".join(
        "%s (%s)" % (x["effect"], ", ".join("%s %.3g %s" % (k, p["value"], p["unit"])
                                            for k, p in x["parameters"].items()))
        for x in d["findings"]) or "—"
    withdrawn = ", ".join(w.split(":")[0] for w in d.get("withdrawn", [])) or "—"
    undecided = "; ".join(" or ".join(u["effects"]) for u in d.get("undecided", [])) or "—"
    knots = ", ".join("%.2f A" % k["current_a"] for k in d.get("unidentified_knots", [])) or "—"
    return "| %s | %d | %.1f → %.1f | %s | %s | %d | %s | %s |" % (
        name, d["samples"], d["baseline"]["holdout_rmse_N"], d["final"]["holdout_rmse_N"],
        finds, undecided, len(d["unexplained"]), withdrawn, knots)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "mrtwin"))
    ap.add_argument("--selector", default="calibrated")
    args = ap.parse_args()
    print("| record | samples | held-out RMS (N), baseline → final | findings | undecided | "
          "unexplained | withdrawn | knots not identified |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for stem in ["5mm3Hz", "2mm5Hz", "10mm1Hz", "25mm0x5Hz"]:
            csv = os.path.join(tmp, stem + ".csv")
            utfsm_csv(stem, csv)
            print(row(f"UTFSM {stem} (5 currents)", csv, args.bin, args.selector, tmp), flush=True)
        dyke = os.path.join(REAL, "dyke-nees", "ransim_u.csv")
        print(row("Dyke ransim_u", dyke, args.bin, args.selector, tmp))


if __name__ == "__main__":
    main()
