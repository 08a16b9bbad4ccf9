#!/usr/bin/env python3
"""Proving-ground study of `mrtwin diagnose`: generate scenarios (generate.py), run the
diagnosis with each selector, compare the reported effects with the hidden ones.

    .venv/bin/python scripts/proving_ground/study.py --seeds 0:40 --jobs 2 \
        --out /tmp/pg --markdown /tmp/pg/study.md
    .venv/bin/python scripts/proving_ground/study.py --quick          # 8 fixed seeds

Scoring (per record and selector):
  found    = accepted findings + every effect of an `undecided` group
  detected = hidden effect in `found`
  exact    = findings == hidden set and no `undecided` group at all
  false    = accepted findings that are not hidden (undecided groups never count as false)
  improved = the record has >= 1 finding and final.holdout_rmse_n <= 0.9 baseline.holdout_rmse_n
"""
import argparse
import hashlib
import json
import multiprocessing as mp
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import generate  # noqa: E402
from pgstats import (  # noqa: E402
    IDENTIFIABLE_U, NULL_BASELINE_WITHIN, null_baseline_ratio, score, wilson)

EFFECTS = generate.EFFECTS
# null, each effect alone, and a three-effect record (see plan() in generate.py)
QUICK_SEEDS = [18, 3, 26, 15, 23, 8, 5, 0]


def fmt_rate(k, n):
    if n == 0:
        return "–"
    p, lo, hi = wilson(k, n)
    return f"{100 * p:.0f} % ({100 * lo:.0f}–{100 * hi:.0f}) [{k}/{n}]"


def probe_selector(binary, sel):
    """True if the binary accepts `--selector sel` (clap parses options before the file
    is opened, so a missing input shows whether the option itself is accepted)."""
    r = subprocess.run([binary, "diagnose", "/nonexistent/probe.csv", "--selector", sel],
                       capture_output=True, text=True, timeout=60)
    err = r.stderr.lower()
    if r.returncode == 2 and ("unexpected argument" in err or "invalid value" in err
                              or "possible values" in err):
        return False, r.stderr.strip().splitlines()[0] if r.stderr.strip() else ""
    return True, ""


def _rmse(block):
    """holdout_rmse_n / holdout_rmse_N (the key's case has varied)."""
    for k, v in (block or {}).items():
        if k.lower() == "holdout_rmse_n":
            return v
    return None


def file_sha256(path):
    """sha256 of a file's bytes (hex)."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def run_one(task):
    """Worker: generate seed's scenario (cached in out dir) and diagnose it per selector."""
    seed, out, binary, selectors, timeout, use_flag, bin_sha, resume, extra_args = task
    csv = os.path.join(out, f"seed{seed:04d}.csv")
    meta_path = os.path.join(out, f"seed{seed:04d}.meta.json")
    t0 = time.process_time()
    gen_cpu = None  # None: scenario files reused from --out
    if not (os.path.exists(csv) and os.path.exists(meta_path)):
        meta, rec = generate.scenario(seed)
        generate.write_csv(csv + ".tmp", rec)
        os.replace(csv + ".tmp", csv)
        with open(meta_path, "w") as f:
            json.dump(generate._jsonable(meta), f, indent=1)
        gen_cpu = time.process_time() - t0
    with open(meta_path) as f:
        meta = json.load(f)
    # The scenario file's hash: a study on another machine can tell whether its files or
    # only its decisions differ (numba and numpy dispatch on the CPU; glibc's libm too).
    csv_sha = file_sha256(csv)
    res = []
    for sel in selectors:
        js = os.path.join(out, f"seed{seed:04d}.{sel}.json")
        side = os.path.join(out, f"seed{seed:04d}.{sel}.run.json")
        if resume and os.path.exists(side):
            with open(side) as f:
                old = json.load(f)
            if old.get("binary_sha256") == bin_sha and old.get("diagnose_args", []) == extra_args:
                old["reused"] = True
                res.append(old)
                continue
        cmd = [binary, "diagnose", csv, "--json", js, "--report", os.devnull] + extra_args
        if use_flag:
            cmd += ["--selector", sel]
        t1 = time.perf_counter()
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
            rc, err = r.returncode, r.stderr[-2000:]
        except subprocess.TimeoutExpired:
            rc, err = "timeout", ""
        wall = time.perf_counter() - t1
        entry = dict(seed=seed, selector=sel, rc=rc, wall_s=wall, hidden=meta["hidden"],
                     u=[round(e["u_achieved"], 2) for e in meta["effects"]],
                     u_unabsorbed=[round(e.get("u_unabsorbed", float("nan")), 2)
                                   for e in meta["effects"]],
                     sigma_F=meta.get("sigma_F_N"), csv_sha256=csv_sha)
        if rc == 0 and os.path.exists(js):
            with open(js) as f:
                d = json.load(f)
            entry["findings"] = [x["effect"] for x in d.get("findings", [])]
            entry["undecided"] = [list(x.get("effects", [])) for x in d.get("undecided", [])]
            entry["baseline_rmse"] = _rmse(d.get("baseline"))
            entry["final_rmse"] = _rmse(d.get("final"))
            entry["reported_selector"] = d.get("selector")
        else:
            entry["error"] = err.strip().splitlines()[-1] if err.strip() else str(rc)
        entry["binary_sha256"] = bin_sha
        entry["diagnose_args"] = extra_args
        with open(side, "w") as f:
            json.dump(entry, f)
        res.append(entry)
    return dict(seed=seed, gen_cpu_s=gen_cpu, runs=res)


def summarise(records, selectors, label_of):
    """Markdown section and a machine-readable summary."""
    lines, summary = [], {}
    for sel in selectors:
        runs = [r for rec in records for r in rec["runs"] if r["selector"] == sel]
        ok = [r for r in runs if "findings" in r]
        failed = [r for r in runs if "findings" not in r]
        sc = [(r, score(r)) for r in ok]
        nulls = [(r, s) for r, s in sc if not r["hidden"]]
        pos = [(r, s) for r, s in sc if r["hidden"]]
        withf = [(r, s) for r, s in sc if s["has_finding"]]
        walls = [r["wall_s"] for r in runs if r["rc"] != "timeout"]
        S = dict(records=len(runs), ok=len(ok), failed=len(failed))
        lines.append(f"### selector `{label_of[sel]}`\n")
        lines.append(f"{len(ok)} of {len(runs)} records diagnosed"
                     + (f" ({len(failed)} failed or timed out)" if failed else "")
                     + (f"; wall time per record: mean {statistics.mean(walls):.2f} s, "
                        f"median {statistics.median(walls):.2f} s, max {max(walls):.2f} s" if walls else "") + ".\n")
        lines.append("| effect | detection rate (Wilson 95 %) | of those ≥ 1 σ_F unabsorbed | of those < 1 σ_F |")
        lines.append("|---|---|---|---|")
        for e in EFFECTS:
            k = sum(s["detected"][e] for r, s in sc if e in s["detected"])
            n = sum(1 for r, s in sc if e in s["detected"])
            S[f"detect_{e}"] = [k, n]
            # Size after the generator's least-squares projection onto what the null
            # model absorbs (per-level Coulomb step and viscous term, offset): a Coulomb
            # friction is mostly a different field-off yield (generate.absorbable_basis).
            by = {True: [0, 0], False: [0, 0]}
            for r, s_ in sc:
                for h, ua in zip(r["hidden"], r.get("u_unabsorbed", [])):
                    if h == e and ua == ua:
                        by[ua >= 1.0][0] += s_["detected"][e]
                        by[ua >= 1.0][1] += 1
            lines.append(f"| `{e}` | {fmt_rate(k, n)} | {by[True][0]}/{by[True][1]} | {by[False][0]}/{by[False][1]} |")
        lines.append("")
        rows = [
            ("exact set (all records)", sum(s["exact"] for _, s in sc), len(sc)),
            ("exact set, nulls (nothing reported)", sum(s["exact"] for _, s in nulls), len(nulls)),
            ("exact set, records with hidden effects", sum(s["exact"] for _, s in pos), len(pos)),
            (f"exact set, an effect leaving < {IDENTIFIABLE_U} σ_F unabsorbed optional",
             sum(s["exact_identifiable"] for _, s in sc), len(sc)),
            ("≥ 1 false finding, nulls", sum(s["n_false"] > 0 for _, s in nulls), len(nulls)),
            ("≥ 1 false finding, records with hidden effects", sum(s["n_false"] > 0 for _, s in pos), len(pos)),
            ("held-out RMSE fell ≥ 10 %, records with a finding", sum(s["improved"] for _, s in withf), len(withf)),
            ("held-out RMSE above σ_F fell ≥ 10 %, records with a finding",
             sum(s["improved_excess"] for _, s in withf), len(withf)),
        ]
        lines.append("| measure | rate (Wilson 95 %) |")
        lines.append("|---|---|")
        for name, k, n in rows:
            S[name] = [k, n]
            lines.append(f"| {name} | {fmt_rate(k, n)} |")
        # The measurement-aware baseline on nulls: its held-out RMS over the true force noise.
        ratios = sorted(x for x in (null_baseline_ratio(r) for r, _ in nulls) if x is not None)
        if ratios:
            k15 = sum(x <= NULL_BASELINE_WITHIN for x in ratios)
            S["null_baseline_over_sigma_median"] = statistics.median(ratios)
            S["null baseline within 15 % of σ_F"] = [k15, len(ratios)]
            lines.append(f"| null baseline held-out RMS within 15 % of σ_F | {fmt_rate(k15, len(ratios))} |")
            lines.append(f"| null baseline held-out RMS / σ_F, median | {statistics.median(ratios):.2f} |")
        n_opt = sum(s["n_optional"] for _, s in sc)
        lines.append(f"| hidden effects leaving < {IDENTIFIABLE_U} σ_F unabsorbed (optional above) | "
                     f"{n_opt} of {sum(len(r['hidden']) for r, _ in sc)} |")
        mf = statistics.mean([s["n_false"] for _, s in sc]) if sc else float("nan")
        S["mean_false_per_record"] = mf
        S["mean_wall_s"] = statistics.mean(walls) if walls else None
        lines.append(f"| mean false findings per record | {mf:.2f} |")
        lines.append("")
        fails = [(r, s) for r, s in sc if not s["exact"]]
        if fails or failed:
            lines.append(f"Records not exactly right ({len(fails)}"
                         + (f", plus {len(failed)} failed runs" if failed else "") + "; first 40 by seed):\n")
            lines.append("| seed | hidden (u) | findings | undecided | false |")
            lines.append("|---|---|---|---|---|")
            for r, s in sorted(fails, key=lambda t: t[0]["seed"])[:40]:
                hid = ", ".join(f"{h} ({u})" for h, u in zip(r["hidden"], r["u"])) or "—"
                und = "; ".join("{" + ", ".join(g) + "}" for g in r["undecided"]) or "—"
                lines.append(f"| {r['seed']} | {hid} | {', '.join(r['findings']) or '—'} | {und} | "
                             f"{', '.join(s['false']) or '—'} |")
            for r in failed[:10]:
                lines.append(f"| {r['seed']} | {', '.join(r['hidden']) or '—'} | run failed: {r['rc']} "
                             f"{r.get('error', '')[:80]} | | |")
            lines.append("")
        summary[label_of[sel]] = S
    return "\n".join(lines), summary


def scenario_hashes_matching(records):
    """(identical, compared): the records' scenario files against the recorded hashes."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenario_sha256.txt")
    if not os.path.exists(path):
        return 0, 0
    with open(path) as f:
        known = dict(line.split() for line in f if line.strip())
    pairs = [(known.get(str(r["seed"])), r["runs"][0].get("csv_sha256")) for r in records]
    pairs = [(k, h) for k, h in pairs if k and h]
    return sum(k == h for k, h in pairs), len(pairs)


def parse_seeds(s):
    """`A:B` (B exclusive), a single seed, or a comma-separated list of either."""
    out = []
    for part in s.split(","):
        if ":" in part:
            a, b = part.split(":")
            out.extend(range(int(a), int(b)))
        else:
            out.append(int(part))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-n", type=int, default=300, help="number of scenarios, seeds 0..N-1")
    ap.add_argument("--seeds", help="seed range A:B (B exclusive), or a comma-separated list of seeds and ranges; overrides -n")
    ap.add_argument("--quick", action="store_true", help=f"the 8-seed slice {QUICK_SEEDS}")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--bin", default="target/release/mrtwin")
    ap.add_argument("--selectors", default="calibrated,rules,sindy")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per diagnose run")
    ap.add_argument("--out", help="directory for CSVs, metas and diagnosis JSONs (default: a temp dir)")
    ap.add_argument("--markdown", help="write the Markdown section here")
    ap.add_argument("--diagnose-args", default="",
                    help="further arguments of every diagnose run, e.g. \"--yield-curve cubic\"")
    ap.add_argument("--resume", action="store_true",
                    help="reuse diagnosis runs already in --out made by the same binary (sha256)")
    args = ap.parse_args()

    seeds = QUICK_SEEDS if args.quick else (parse_seeds(args.seeds) if args.seeds else list(range(args.n)))
    out = args.out or tempfile.mkdtemp(prefix="proving_ground_")
    os.makedirs(out, exist_ok=True)
    if not os.path.exists(args.bin):
        sys.exit(f"no binary at {args.bin}: build it with `cargo build --release -p mrtwin`")
    # a private copy: a rebuild must not change the binary under a running study
    tmpdir = tempfile.mkdtemp(prefix="pg_bin_")
    binary = os.path.join(tmpdir, "mrtwin")
    shutil.copy2(args.bin, binary)

    selectors = [s for s in args.selectors.split(",") if s]
    supported = {}
    for sel in selectors:
        supported[sel] = probe_selector(binary, sel)
    if not any(v[0] for v in supported.values()):
        print("binary has no --selector option: running once with its default", file=sys.stderr)
        run_sels, use_flag, label_of = ["default"], False, {"default": "default"}
    else:
        run_sels = [s for s in selectors if supported[s][0]]
        for s in selectors:
            if not supported[s][0]:
                print(f"selector {s} rejected by the binary: {supported[s][1]}", file=sys.stderr)
        use_flag, label_of = True, {s: s for s in run_sels}

    bin_sha = file_sha256(binary)
    extra_args = shlex.split(args.diagnose_args)
    tasks = [(s, out, binary, run_sels, args.timeout, use_flag, bin_sha, args.resume, extra_args)
             for s in seeds]
    t0 = time.time()
    records = []
    with mp.get_context("fork").Pool(args.jobs) as pool:
        for i, rec in enumerate(pool.imap_unordered(run_one, tasks), 1):
            records.append(rec)
            brief = "; ".join(f"{r['selector']}: {','.join(r.get('findings', [])) or r.get('error', '-') or '-'}"
                              for r in rec["runs"])
            print(f"[{i}/{len(seeds)}] seed {rec['seed']} hidden {','.join(rec['runs'][0]['hidden']) or '-'} | {brief}",
                  flush=True)
    records.sort(key=lambda r: r["seed"])
    elapsed = time.time() - t0
    shutil.rmtree(tmpdir, ignore_errors=True)

    md_body, summary = summarise(records, run_sels, label_of)
    rng = f"{seeds[0]}–{seeds[-1]}" if not args.quick else ", ".join(map(str, seeds))
    cmd = "python scripts/proving_ground/study.py " + " ".join(sys.argv[1:])
    gens = [r["gen_cpu_s"] for r in records if r["gen_cpu_s"] is not None]
    n_reused = sum(1 for rec in records for r in rec["runs"] if r.get("reused"))
    n_runs = sum(len(rec["runs"]) for rec in records)
    nnull = sum(1 for r in records if not r["runs"][0]["hidden"])
    head = [f"## Proving ground: `mrtwin diagnose` on independent simulations\n",
            f"Command: `{cmd}` ({len(seeds)} scenarios, seeds {rng}; {nnull} nulls; "
            f"{args.jobs} parallel jobs, {elapsed / 60:.1f} min in all; binary sha256 {bin_sha[:12]}). "
            "Scenarios come from "
            "`scripts/proving_ground/generate.py`, a two-chamber simulator that shares no code "
            "with the twin (see its README); each hidden effect is sized to an RMS of 1–3 σ_F. "
            "Rates with Wilson 95 % intervals. A hidden effect named inside an `undecided` group "
            "counts as detected but not exact; undecided groups never count as false findings.\n"]
    if not use_flag:
        head.append("The binary has no `--selector` option: one run per record with its default decision method.\n")
    unsupported = [s for s in selectors if use_flag and not supported[s][0]]
    if unsupported:
        head.append(f"Selectors rejected by the binary and skipped: {', '.join(unsupported)}.\n")
    if gens:
        head.append(f"Generation: {statistics.mean(gens):.2f} s CPU per scenario (mean of {len(gens)}).\n")
    libs = generate.library_versions()
    head.append("Generator libraries (scenario files depend on them): "
                + ", ".join(f"{k} {v}" for k, v in libs.items()) + ".\n")
    same, recorded = scenario_hashes_matching(records)
    if recorded:
        head.append(f"Scenario files: {same} of {recorded} identical to the hashes recorded in "
                    "`scripts/proving_ground/scenario_sha256.txt` (seeds 0–299 session 67, OpenBLAS pinned; "
                    "the validation seeds 300–599 session 69, the fresh seeds 600–899 session 70); a "
                    "difference is the generator's numerics on this machine, not diagnose.\n")
    if n_reused:
        head.append(f"{n_reused} of {n_runs} diagnose runs were reused from earlier runs of the same binary "
                    "(`--resume`); their wall times are those measured then.\n")
    md = "\n".join(head) + "\n" + md_body
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(dict(seeds=seeds, records=records, summary=summary, generator_libraries=libs),
                  f, indent=1, default=str)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(md)
    print(md)
    print(f"per-record results: {os.path.join(out, 'results.json')}")
    n_failed = sum(1 for rec in records for r in rec["runs"] if "findings" not in r)
    # the quick slice is a smoke test: every run must produce a diagnosis
    if args.quick and n_failed:
        sys.exit(f"{n_failed} diagnose runs failed or timed out")
    sys.exit(1 if n_failed == len(records) * len(run_sels) else 0)


if __name__ == "__main__":
    main()
