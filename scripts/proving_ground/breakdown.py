#!/usr/bin/env python3
"""Where `mrtwin diagnose` can be trusted: a proving-ground study's records split by what
kind of record they are (stroke, current, fluid law, velocity channel, sample rate, number
of hidden effects) and by what diagnose reported (how many effects), each class with its
exact-set rate, its false findings and its null baselines, and each effect's detection
alone and beside others, with Wilson 95 % intervals.

    .venv/bin/python scripts/proving_ground/breakdown.py DIR [DIR ...] \
        [--selector calibrated] [--markdown OUT.md] [--json OUT.json]

Each DIR is a `study.py --out` directory (several are pooled): its results.json and the
seedNNNN.meta.json files beside it (the hidden truth and every drawn setting). Records are
scored as study.py scores them (`pgstats.score`); this script only groups them.
"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pgstats import NULL_BASELINE_WITHIN, null_baseline_ratio, score, wilson  # noqa: E402


def fs_band(fs):
    """The sample rate in three bands (the generator draws 200, 500, 1000, 2000, 2500 or
    5000 Hz)."""
    if fs <= 500:
        return "200–500 Hz"
    if fs <= 2000:
        return "1–2 kHz"
    return "2.5–5 kHz"


def reported(run):
    """What diagnose reported: the number of accepted findings, or "undecided" when it
    left a group of effects undecided."""
    if run.get("undecided"):
        return "undecided group"
    return f"{len(run['findings'])} reported"


def stroke(meta):
    return meta["excitation"]["kind"]


def current(meta):
    return meta["excitation"]["current"]["mode"]


def stroke_and_current(run, meta):
    return f"{stroke(meta)}, {current(meta)}"


# (name, what a record's run and meta say about it)
GROUPINGS = [
    ("stroke", lambda r, m: stroke(m)),
    ("current", lambda r, m: current(m)),
    ("stroke × current", stroke_and_current),
    ("fluid law", lambda r, m: m["fluid"]["law"]),
    ("velocity channel", lambda r, m: m["measurement"]["velocity"]),
    ("sample rate", lambda r, m: fs_band(m["excitation"]["fs_hz"])),
    ("hidden effects", lambda r, m: str(len(m["hidden"]))),
    # Read the other way round: how often the set is right when diagnose reports k effects
    # (what a user of one record can lean on).
    ("effects reported", lambda r, m: reported(r)),
]


def load(dirname, selector):
    """(run, meta, score) of every diagnosed record of `selector` in a study directory."""
    with open(os.path.join(dirname, "results.json")) as f:
        results = json.load(f)
    out = []
    for rec in results["records"]:
        for run in rec["runs"]:
            if run["selector"] != selector or "findings" not in run:
                continue
            with open(os.path.join(dirname, f"seed{rec['seed']:04d}.meta.json")) as f:
                meta = json.load(f)
            out.append((run, meta, score(run)))
    return out


def load_all(dirnames, selector):
    """[`load`] over several study directories; a seed found twice is an error (the same
    scenario would count twice)."""
    rows, seen = [], set()
    for d in dirnames:
        for row in load(d, selector):
            seed = row[0]["seed"]
            if seed in seen:
                sys.exit(f"{d}: seed {seed} is also in an earlier directory")
            seen.add(seed)
            rows.append(row)
    return rows


def tally(rows):
    """Counts of one class: records, exact, exact with the < 0.5 σ_F effects optional,
    nulls with a false finding, records with hidden effects and one beside them, and null
    baselines within 15 % of σ_F."""
    nulls = [(r, s) for r, _, s in rows if not r["hidden"]]
    pos = [(r, s) for r, _, s in rows if r["hidden"]]
    base = [x for x in (null_baseline_ratio(r) for r, _ in nulls) if x is not None]
    return dict(
        records=len(rows),
        exact=sum(s["exact"] for _, _, s in rows),
        exact_identifiable=sum(s["exact_identifiable"] for _, _, s in rows),
        nulls=len(nulls),
        false_on_nulls=sum(s["n_false"] > 0 for _, s in nulls),
        with_effects=len(pos),
        false_beside=sum(s["n_false"] > 0 for _, s in pos),
        null_baselines=len(base),
        null_baseline_within=sum(x <= NULL_BASELINE_WITHIN for x in base),
    )


def rate(k, n):
    if n == 0:
        return "—"
    p, lo, hi = wilson(k, n)
    return f"{k}/{n}, {100 * p:.0f} % ({100 * lo:.0f}–{100 * hi:.0f})"


def breakdown(rows):
    """{grouping: {class: tally}} plus the whole set under "all"."""
    table = {"all": {"all records": tally(rows)}}
    for name, key in GROUPINGS:
        classes = {}
        for row in rows:
            classes.setdefault(key(row[0], row[1]), []).append(row)
        table[name] = {c: tally(classes[c]) for c in sorted(classes)}
    return table


def detection_by_count(rows):
    """{effect: {hidden count: [detected, records]}}: how each effect fares alone and beside
    one or two others."""
    det = {}
    for run, _, s in rows:
        n = str(len(run["hidden"]))
        for e, ok in s["detected"].items():
            k = det.setdefault(e, {}).setdefault(n, [0, 0])
            k[0] += ok
            k[1] += 1
    return {e: det[e] for e in sorted(det)}


def markdown(table, missed_by, detection):
    lines = ["| grouping | class | records | exact set | exact, < 0.5 σ_F effects optional "
             "| ≥ 1 false finding, nulls | ≥ 1 false finding beside true effects "
             "| null baseline within 15 % of σ_F |",
             "|---|---|---|---|---|---|---|---|"]
    for name, classes in table.items():
        for c, t in classes.items():
            lines.append(
                f"| {name} | {c} | {t['records']} | {rate(t['exact'], t['records'])} "
                f"| {rate(t['exact_identifiable'], t['records'])} "
                f"| {rate(t['false_on_nulls'], t['nulls'])} "
                f"| {rate(t['false_beside'], t['with_effects'])} "
                f"| {rate(t['null_baseline_within'], t['null_baselines'])} |")
    lines.append("")
    counts = sorted({n for d in detection.values() for n in d})
    lines.append("| effect | " + " | ".join(f"detected, {n} hidden" for n in counts) + " |")
    lines.append("|---|" + "---|" * len(counts))
    for e, d in detection.items():
        lines.append(f"| `{e}` | " + " | ".join(rate(*d.get(n, [0, 0])) for n in counts) + " |")
    lines.append("")
    listed = "; ".join(f"{c}: {', '.join(map(str, s))}" for c, s in sorted(missed_by.items()))
    lines.append(f"Records not exactly right, by stroke × current: {listed or 'none'}.")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+", help="study.py --out directories (their records pooled)")
    ap.add_argument("--selector", default="calibrated")
    ap.add_argument("--markdown", help="write the table here (printed either way)")
    ap.add_argument("--json", help="write the counts as JSON here")
    args = ap.parse_args()
    rows = load_all(args.dirs, args.selector)
    if not rows:
        sys.exit(f"{', '.join(args.dirs)}: no diagnosed record of selector {args.selector!r} in results.json")
    table = breakdown(rows)
    missed = {}
    for run, meta, s in sorted(rows, key=lambda r: r[0]["seed"]):
        if not s["exact"]:
            missed.setdefault(stroke_and_current(run, meta), []).append(run["seed"])
    detection = detection_by_count(rows)
    md = markdown(table, missed, detection)
    print(md)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(md)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(selector=args.selector, table=table, detection_by_hidden_count=detection,
                           missed_by_stroke_and_current=missed), f, indent=1)


if __name__ == "__main__":
    main()
