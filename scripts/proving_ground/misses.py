"""Why each hidden effect of a proving-ground study was missed, as read from the diagnosis
JSON of each record (its last trial of the effect: the round it was last tried in).

    python3 scripts/proving_ground/misses.py DIR [--selector calibrated]

DIR is a study's --out directory (results.json and seedNNNN.<selector>.json). Standard
library only. The causes, in the order they are tested:

  absorbed        its statistic T is below the screen (not bootstrapped): the baseline and
                  the effects already in leave nothing for it to explain
  below null      T is below its calibrated (bootstrap) threshold
  no presliding   a seal friction whose step the interval rule rejects (the fluid's shape,
                  or no presliding displacement to tell it from the fluid: docs/diagnose.md)
  held-out worse  T passes but the held-out RMS rises by more than 10 % (the fit went to
                  another basin, or predicts the held-out blocks worse)
  no gain         T passes, the held-out RMS does not fall at all
  interval        T passes, the 95 % interval is not clear of the no-effect value
  structure       T passes, the held-out structure does not fall enough
  other           none of the above: the record's report says why (another candidate
                  won, a held-out fall the rules' held-out test does not count, ...)

These read the trial's flags (held-out, criterion, interval, structure) and its
calibrated evidence; they are a summary, not the selection's own reasoning, which is in
the record's Markdown report.

A second table reads the *leads* the last round leaves: the candidates of each record's
last round (the one that accepted nothing) whose statistic T is at least R times its
threshold and that were not accepted, for R in --lead-ratios. For each R: how many such
lead effects there are, how many of them are hidden in their record (true) or not
(false), on how many nulls one appears, and how many missed effects a lead names. It
measures how much a "fits far better but is not confirmed" note would tell a user.

A third table sorts the records by how far the final model stays from the noise, its
held-out RMS over σ_F (results.json's `final_rmse` and `sigma_F`): how many records in
each band, how many are not exact with the effects leaving < 0.5 σ_F unabsorbed optional
(`pgstats.score`'s `exact_identifiable`, as study.py scores), how many have a false finding, and how many of the
band's records have random strokes (the scenario's `excitation.kind`).

A fourth table reads each missed effect's last trial's `holdout_harm` (docs/diagnose.md
§5): per cause, how many of those trials make a held-out block at least HARM_LISTED times
worse in mean square, and in how many of them at least half the other candidates of that
round harm the same block at the same current knot that much (the harm is then the
refit's, not the effect's: the knot's fluid law moved away from where the current model
stopped).
"""
import argparse
import collections
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pgstats import score  # noqa: E402


def cause(effect, trial):
    ev = trial["evidence"]
    cal = ev.get("calibration") or {}
    t, thr = cal.get("statistic", 0.0), cal.get("threshold", 0.0)
    held, _criterion, interval, structure = trial["passed"]
    before, after = ev["holdout_rmse_before_N"], ev["holdout_rmse_after_N"]
    if t < thr and cal.get("replicates", 0) == 0:
        return "absorbed"
    if t < thr:
        return "below null"
    if effect == "seal_friction" and not interval:
        return "no presliding"
    if after > 1.1 * before:
        return "held-out worse"
    if not held and after >= before:
        return "no gain"
    if not interval:
        return "interval"
    if not structure:
        return "structure"
    return "other"


def last_round_leads(diagnosis, ratio):
    """Effects of the last round's unaccepted candidates whose statistic is at least
    `ratio` times its threshold (a pair's two effects), less the record's findings."""
    trials = diagnosis["trials"]
    if not trials:
        return set()
    last = max(t["round"] for t in trials)
    found = {f["effect"] for f in diagnosis["findings"]}
    leads = set()
    for t in trials:
        if t["round"] != last or t.get("accepted"):
            continue
        cal = t["evidence"].get("calibration") or {}
        if cal.get("statistic", 0.0) >= ratio * cal.get("threshold", float("inf")):
            leads |= set(t["effect"].split("+"))
    return leads - found


def diagnosed_run(rec, selector):
    """The record's run by `selector` when it diagnosed it (exit 0), else None."""
    run = next((r for r in rec["runs"] if r["selector"] == selector), None)
    return run if run is not None and run["rc"] == 0 else None


def diagnosed(dirpath, records, selector):
    """(seed, hidden effects, missed effects, diagnosis JSON) of each record the selector
    diagnosed; missed: hidden and neither found nor in an undecided group, in the order
    the record hides them."""
    out = []
    for rec in records:
        run = diagnosed_run(rec, selector)
        if run is None:
            continue
        missed = [h for h in run["hidden"] if h not in run["findings"]
                  and not any(h in g for g in run.get("undecided", []))]
        path = os.path.join(dirpath, "seed%04d.%s.json" % (rec["seed"], selector))
        with open(path) as f:
            out.append((rec["seed"], run["hidden"], missed, json.load(f)))
    return out


def leads_table(diagnoses, ratios):
    """The leads table of `diagnoses` ([`diagnosed`]), one row per ratio."""
    print("| T / threshold at least | lead effects | hidden (true) | not hidden (false) "
          "| nulls with a lead | missed effects a lead names |")
    print("|---|---|---|---|---|---|")
    nulls = sum(1 for _, h, _, _ in diagnoses if not h)
    missed = sum(len(m) for _, _, m, _ in diagnoses)
    for ratio in ratios:
        n = true = null_leads = named = 0
        for _, hidden, miss, d in diagnoses:
            leads = last_round_leads(d, ratio)
            n += len(leads)
            true += len(leads & set(hidden))
            null_leads += bool(leads) and not hidden
            named += len(leads & set(miss))
        print(f"| {ratio:g} | {n} | {true} | {n - true} | {null_leads} of {nulls} "
              f"| {named} of {missed} |")


FIT_BANDS = [1.1, 1.3, 1.6, 2.0, 3.0, 5.0]


def fit_bands_table(dirpath, records, selector):
    """Records by final held-out RMS / σ_F (bands split at FIT_BANDS)."""
    edges = [0.0] + FIT_BANDS + [float("inf")]
    rows = [collections.Counter() for _ in range(len(edges) - 1)]
    for rec in records:
        run = diagnosed_run(rec, selector)
        if run is None:
            continue
        ratio = run["final_rmse"] / run["sigma_F"]
        band = next(i for i in range(len(rows)) if ratio < edges[i + 1])
        sc = score(run)
        with open(os.path.join(dirpath, "seed%04d.meta.json" % rec["seed"])) as f:
            random = json.load(f)["excitation"]["kind"] == "random"
        rows[band].update(records=1, not_exact=int(not sc["exact_identifiable"]),
                          false=int(sc["n_false"] > 0), random=int(random))
    print("| final held-out RMS / σ_F | records | not exact (optional effects optional) "
          "| with a false finding | random strokes |")
    print("|---|---|---|---|---|")
    for i, c in enumerate(rows):
        hi = "" if edges[i + 1] == float("inf") else f"{edges[i + 1]:g}"
        print(f"| {edges[i]:g}–{hi} | {c['records']} | {c['not_exact']} | {c['false']} "
              f"| {c['random']} |")


# report::HARM_LISTED: a held-out block this many times worse in mean square is listed.
HARM_LISTED = 2.0


def listed_harm(trial):
    """The trial's `holdout_harm` when it makes its block HARM_LISTED times worse, else
    None."""
    h = trial["evidence"].get("holdout_harm")
    if h and h["rmse_after_N"] ** 2 >= HARM_LISTED * h["rmse_before_N"] ** 2:
        return h
    return None


def shared_harm(diagnosis, trial):
    """Whether at least half the other candidates of `trial`'s round harm the same block at
    the same knot as `trial` does (listed_harm); False when `trial` harms none or is
    alone."""
    h = listed_harm(trial)
    others = [t for t in diagnosis["trials"] if t["round"] == trial["round"] and t is not trial]
    if h is None or not others:
        return False
    same = lambda o: o is not None and (o["start_s"], o["knot_a"]) == (h["start_s"], h["knot_a"])  # noqa: E731
    return 2 * sum(same(listed_harm(t)) for t in others) >= len(others)


def harm_table(missed_trials):
    """Per cause: missed effects, those whose last trial harms a block (listed_harm), and
    those whose round shares that harm (shared_harm). `missed_trials`: (seed,
    cause, trial, diagnosis) of each missed effect that was tried."""
    rows = collections.defaultdict(collections.Counter)
    shared_seeds = set()
    for seed, c, trial, d in missed_trials:
        harmed = listed_harm(trial) is not None
        shared = shared_harm(d, trial)
        rows[c].update(missed=1, harmed=int(harmed), shared=int(shared))
        if shared:
            shared_seeds.add(seed)
    print(f"| cause | missed effects | last trial makes a held-out block ≥ {HARM_LISTED:g}× worse "
          "| at least half the other candidates of that round make the same block worse at "
          "the same knot |")
    print("|---|---|---|---|")
    for c in CAUSES:
        if rows[c]["missed"]:
            r = rows[c]
            print(f"| {c} | {r['missed']} | {r['harmed']} | {r['shared']} |")
    if shared_seeds:
        print(f"\n- shared harm: seeds {', '.join(str(s) for s in sorted(shared_seeds))}")


CAUSES = ["absorbed", "below null", "no presliding", "held-out worse", "no gain",
          "interval", "structure", "other", "not tried"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir")
    ap.add_argument("--selector", default="calibrated")
    ap.add_argument("--lead-ratios", default="1,10,30,100,300",
                    help="comma-separated ratios T / threshold for the leads table")
    a = ap.parse_args()
    res = json.load(open(os.path.join(a.dir, "results.json")))
    table = collections.defaultdict(collections.Counter)
    seeds = collections.defaultdict(list)
    diagnoses = diagnosed(a.dir, res["records"], a.selector)
    missed_trials = []
    for seed, _, missed, d in diagnoses:
        last = {}
        for tr in d["trials"]:
            last[tr["effect"]] = tr
        for h in missed:
            c = cause(h, last[h]) if h in last else "not tried"
            table[h][c] += 1
            seeds[c].append(seed)
            if h in last:
                missed_trials.append((seed, c, last[h], d))
    effects = sorted(table)
    print("| missed effect | " + " | ".join(CAUSES) + " | all |")
    print("|---|" + "---|" * (len(CAUSES) + 1))
    for e in effects:
        row = [str(table[e][c]) if table[e][c] else "·" for c in CAUSES]
        print(f"| `{e}` | " + " | ".join(row) + f" | {sum(table[e].values())} |")
    tot = collections.Counter()
    for e in effects:
        tot.update(table[e])
    print("| all | " + " | ".join(str(tot[c]) if tot[c] else "·" for c in CAUSES)
          + f" | {sum(tot.values())} |")
    print()
    for c in CAUSES:
        if seeds[c]:
            print(f"- {c}: seeds {', '.join(str(s) for s in sorted(set(seeds[c])))}")
    print()
    leads_table(diagnoses, [float(x) for x in a.lead_ratios.split(",")])
    print()
    fit_bands_table(a.dir, res["records"], a.selector)
    print()
    harm_table(missed_trials)


if __name__ == "__main__":
    main()
