#!/usr/bin/env python3
"""Do diagnose's detection limits predict what it finds? Over a proving-ground study.

    python3 scripts/proving_ground/limits.py STUDY_DIR [--null-twins DIR]

STUDY_DIR is a `study.py --out` directory (results.json, seedNNNN.meta.json,
seedNNNN.calibrated.json). Each diagnosis states, for every library effect its final
model lacks, the smallest size the record could have shown (`detection_limits`: the
effect's force RMS at the limit, for diagnose's own shape of the effect).

* Missed effects (from STUDY_DIR alone): the hidden effect's force RMS (the generator's
  `rms_effect_N`, noise-free, through the measurement chain) over the limit the record's
  own diagnosis states for it. Below 1: the miss is one the report owns up to.
* With --null-twins DIR (a directory of `generate.py --null-twin` records of the same
  seeds, diagnosed into seedNNNN.calibrated.json: the same damper, excitation and noise
  with nothing hidden): the limit is read off the null twin, so found effects can be
  scored too. Each hidden effect is *predicted* found when its force RMS exceeds the
  twin's limit, and the prediction is set against what the study's diagnosis found (a
  finding, or a member of an undecided group). Also counted: the records whose every
  hidden effect is above its twin's limit (the nulls with them), and on how many of them
  diagnose names the exact set.

A seal friction is read against the limit of the shape the generator gave it: a
Stribeck map has no presliding, so its row is the step's (never reported); Dahl and
LuGre against the Dahl friction with presliding. The generator's formulations differ from
diagnose's candidates (polytropic gas, two chambers, heat balance, ...), so the
comparison in force RMS holds only as far as the shapes are alike. Standard library only.
"""
import argparse
import collections
import json
import os

EFFECTS = ["fluid_compressibility", "gas_spring", "seal_friction", "thermal_softening",
           "field_lag", "fluid_inertia"]


def load(path):
    with open(path) as f:
        return json.load(f)


def limit_row(diag, effect, meta_effect):
    """The detection-limit row of `effect` that matches the hidden effect's shape."""
    rows = [r for r in diag.get("detection_limits", []) if r["effect"] == effect]
    if not rows:
        return None
    if effect == "seal_friction":
        kind = meta_effect["parameters"].get("kind")
        want_step = kind == "stribeck"
        for r in rows:
            if (r["limit"] is None and "without presliding" in r["shape"]) == want_step:
                return r
    return rows[0]


def ratio(meta_effect, row):
    """Hidden force RMS over the limit's (inf where the limit is none: not separable)."""
    if row is None:
        return None
    if row["effect_rms_N"] is None:
        return 0.0
    return meta_effect["rms_effect_N"] / row["effect_rms_N"]


def detected(run, effect):
    return effect in run.get("findings", []) or any(effect in g for g in run.get("undecided", []))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir")
    ap.add_argument("--null-twins")
    ap.add_argument("--selector", default="calibrated")
    a = ap.parse_args()
    res = load(os.path.join(a.dir, "results.json"))
    missed = collections.defaultdict(list)
    table = collections.defaultdict(collections.Counter)
    # Records whose every hidden effect is above its null twin's limit (nulls too): how
    # many there are, and on how many diagnose names the exact set (study.py's reading:
    # the findings are the hidden set and no group is undecided).
    reachable = collections.Counter()
    for rec in res["records"]:
        seed = rec["seed"]
        run = next((r for r in rec["runs"] if r["selector"] == a.selector), None)
        if run is None or run["rc"] != 0:
            continue
        exact = set(run["findings"]) == set(run["hidden"]) and not run.get("undecided")
        if not run["hidden"]:
            reachable["records"] += 1
            reachable["exact"] += exact
            continue
        all_above = True
        meta = load(os.path.join(a.dir, "seed%04d.meta.json" % seed))
        diag = load(os.path.join(a.dir, "seed%04d.%s.json" % (seed, a.selector)))
        twin = None
        if a.null_twins:
            p = os.path.join(a.null_twins, "seed%04d.%s.json" % (seed, a.selector))
            twin = load(p) if os.path.exists(p) else None
        for me in meta["effects"]:
            e = me["effect"]
            hit = detected(run, e)
            if not hit:
                q = ratio(me, limit_row(diag, e, me))
                missed[e].append((seed, q))
            if twin is not None:
                q = ratio(me, limit_row(twin, e, me))
                all_above = all_above and q is not None and q > 1.0
                if q is None:
                    continue
                table[e][("above" if q > 1.0 else "below", "found" if hit else "missed")] += 1
        if twin is not None and all_above:
            reachable["records"] += 1
            reachable["exact"] += exact

    print("Missed hidden effects against the limit their own record states "
          "(hidden force RMS / the limit's):\n")
    print("| missed effect | missed | below its limit (< 1) | 1–2 × | above 2 × | no row |")
    print("|---|---:|---:|---:|---:|---:|")
    tot = collections.Counter()
    for e in EFFECTS:
        qs = missed.get(e, [])
        c = collections.Counter()
        for _, q in qs:
            c["none" if q is None else "below" if q < 1 else "1-2" if q < 2 else "above"] += 1
        tot.update(c)
        tot["n"] += len(qs)
        print(f"| `{e}` | {len(qs)} | {c['below']} | {c['1-2']} | {c['above']} | {c['none']} |")
    print(f"| all | {tot['n']} | {tot['below']} | {tot['1-2']} | {tot['above']} | {tot['none']} |")
    above = sorted((s, e, round(q, 2)) for e, qs in missed.items() for s, q in qs
                   if q is not None and q >= 2)
    if above:
        print("\nMissed at 2 × their limit or more (seed, effect, ratio):", above)
    if a.null_twins:
        print("\nEvery hidden effect against its null twin's limit (predicted found when its "
              "force RMS is above the limit):\n")
        print("| effect | above, found | above, missed | below, found | below, missed | "
              "prediction right |")
        print("|---|---:|---:|---:|---:|---:|")
        allc = collections.Counter()
        for e in EFFECTS:
            c = table.get(e, collections.Counter())
            allc.update(c)
            n = sum(c.values())
            right = c[("above", "found")] + c[("below", "missed")]
            print(f"| `{e}` | {c[('above', 'found')]} | {c[('above', 'missed')]} | "
                  f"{c[('below', 'found')]} | {c[('below', 'missed')]} | {right}/{n} |")
        n = sum(allc.values())
        right = allc[("above", "found")] + allc[("below", "missed")]
        print(f"| all | {allc[('above', 'found')]} | {allc[('above', 'missed')]} | "
              f"{allc[('below', 'found')]} | {allc[('below', 'missed')]} | {right}/{n} |")
        print(f"\nRecords with every hidden effect above its null twin's limit (nulls included): "
              f"{reachable['records']}; the exact set on {reachable['exact']} of them.")


if __name__ == "__main__":
    main()
