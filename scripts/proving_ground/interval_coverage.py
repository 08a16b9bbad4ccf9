#!/usr/bin/env python3
"""How often diagnose's 95 % parameter intervals hold the generator's true value (issue 13,
last item), over a study directory of `study.py` (seedNNNN.calibrated.json beside
seedNNNN.meta.json).

    python3 scripts/proving_ground/interval_coverage.py DIR

Only parameters with a clean counterpart in the generator are scored:
- field_lag, first-order lag: the time constant (ms);
- fluid_inertia: the fluid mass (kg) against the generator's moving mass plus its gap
  fluid's mass;
- thermal_softening, linear law: the softening per dissipated energy (1/kJ) against
  β_τ / C (the yield stress's temperature coefficient over the heat capacity), and, where
  diagnose freed it from the yield force's (no `tied_to`), the viscous softening against
  β_μ / C;
- gas_spring: the stiffness (N/mm) against the least-squares line through the polytropic
  gas's force −(p0 (Vg0/(Vg0 + Ar x))^κ − p_atm) Ar over the record's own displacement
  samples: diagnose fits a line, and the gas's stiffness varies over the stroke. The gas's
  stiffness at x = 0 (the score before session 55) is reported beside it.
Standard library only.
"""
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pgstats import wilson  # noqa: E402


def truths_of(effect, meta):
    """[(row label, parameter name, true value in diagnose's unit)], empty when the
    generator's effect has no clean counterpart."""
    eff = {e["effect"]: e for e in meta["effects"]}.get(effect)
    if eff is None:
        return []
    p = eff["parameters"]
    if effect == "field_lag" and p.get("kind") == "first_order":
        return [(effect, "field_time_constant", p["effective_tau_s"] * 1e3)]
    if effect == "fluid_inertia":
        return [(effect, "fluid_mass", p["moving_mass_kg"] + p["gap_fluid_mass_kg"])]
    if effect == "thermal_softening" and p.get("law") == "linear":
        per_kj = 1e3 / meta["thermal"]["C_J_K"]
        return [(effect, "softening_per_energy", p["beta_tau_per_K"] * per_kj),
                ("thermal_softening (viscous, freed)", "viscous_softening_per_energy",
                 p["beta_mu_per_K"] * per_kj)]
    if effect == "gas_spring":
        return [(effect, "stiffness", p["stiffness_at_0_N_m"] / 1e3)]
    return []


def gas_line_stiffness(meta, csv_path):
    """The slope (N/mm) of the least-squares line through the generator's polytropic gas
    force over the record's displacement column: what a linear spring fitted to that
    record estimates. The gas force is −(p_g − p_atm) Ar; the constant p_atm Ar does not
    move a slope, so only −p_g Ar is formed."""
    p = {e["effect"]: e for e in meta["effects"]}["gas_spring"]["parameters"]
    ar = meta["geometry"]["Ar"]
    xs = []
    with open(csv_path) as f:
        col = next(f).strip().split(",").index("displacement_m")
        for line in f:
            xs.append(float(line.split(",")[col]))
    fs = [-p["p0_abs_Pa"] * (p["Vg0_m3"] / (p["Vg0_m3"] + ar * x)) ** p["kappa"] * ar for x in xs]
    mx, mf = sum(xs) / len(xs), sum(fs) / len(fs)
    sxy = sum((x - mx) * (g - mf) for x, g in zip(xs, fs))
    sxx = sum((x - mx) ** 2 for x in xs)
    return sxy / sxx / 1e3


def main(argv):
    d = argv[1]
    rows = {}
    for name in sorted(os.listdir(d)):
        if not name.endswith(".calibrated.json"):
            continue
        seed = int(name[4:8])
        with open(os.path.join(d, name)) as f:
            dg = json.load(f)
        with open(os.path.join(d, f"seed{seed:04d}.meta.json")) as f:
            meta = json.load(f)
        for fnd in dg.get("findings", []):
            for row, pname, truth in truths_of(fnd["effect"], meta):
                par = fnd["parameters"].get(pname)
                # A parameter held equal to another is that one's value, not a measurement.
                if par is None or par.get("tied_to"):
                    continue
                lo, hi = par["ci95"]
                se = (hi - lo) / 3.92
                truths = [(row, truth)]
                if fnd["effect"] == "gas_spring":
                    line = gas_line_stiffness(meta, os.path.join(d, f"seed{seed:04d}.csv"))
                    truths = [("gas_spring (line over the record)", line),
                              ("gas_spring (stiffness at x = 0)", truth)]
                for label, tv in truths:
                    z = (par["value"] - tv) / se if se > 0 else float("inf")
                    rows.setdefault(label, []).append(
                        dict(seed=seed, truth=tv, value=par["value"], lo=lo, hi=hi, z=z,
                             rel=(par["value"] - tv) / tv if tv else float("nan")))
    print("| effect (parameter) | found with a clean truth | 95 % interval holds it | "
          "Wilson 95 % | median \\|z\\| | median \\|error\\| / truth | interval factor for 95 % |")
    print("|---|---:|---:|---|---:|---:|---:|")
    for e, r in sorted(rows.items()):
        k = sum(1 for x in r if x["lo"] <= x["truth"] <= x["hi"])
        _, lo, hi = wilson(k, len(r))
        az = sorted(abs(x["z"]) for x in r)
        rel = sorted(abs(x["rel"]) for x in r)
        q95 = az[min(len(az) - 1, int(math.ceil(0.95 * len(az))) - 1)]
        print(f"| {e} | {len(r)} | {k} | {100 * lo:.0f}–{100 * hi:.0f} % | "
              f"{az[len(az) // 2]:.1f} | {100 * rel[len(rel) // 2]:.1f} % | {q95 / 1.96:.1f} |")
    with open(os.path.join(d, "interval_coverage.json"), "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main(sys.argv)
