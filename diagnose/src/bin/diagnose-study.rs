//! The concealed-effect study: every scenario of `diagnose::study` × seeds, diagnosed by
//! `diagnose` and by the SINDy-style sparse regression, with detection and false-alarm
//! rates side by side.
//!
//! `cargo run --release -p diagnose --bin diagnose-study -- [SEEDS] [--verbose] [--only TEXT]`

use std::time::Instant;

use diagnose::study::{generate, Scenario};
use diagnose::{diagnose, sindy};
use twin::Effect;

fn ids(v: &[Effect]) -> String {
    if v.is_empty() {
        "—".into()
    } else {
        v.iter().map(|e| e.id()).collect::<Vec<_>>().join(", ")
    }
}

/// CPU time of this process (all threads) in seconds, from /proc/self/stat (Linux; clock
/// ticks of 10 ms); `None` elsewhere.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

#[derive(Default, Clone, Copy)]
struct Tally {
    runs: usize,
    exact: usize,
    detected: usize,
    false_alarm: usize,
}

impl Tally {
    /// Count one record: the effects `found` against the `hidden` ones.
    fn count(&mut self, found: &[Effect], hidden: &[Effect]) {
        let mut hidden = hidden.to_vec();
        hidden.sort();
        self.runs += 1;
        self.exact += usize::from(found == hidden.as_slice());
        self.detected += usize::from(hidden.iter().all(|h| found.contains(h)));
        self.false_alarm += usize::from(found.iter().any(|e| !hidden.contains(e)));
    }

    fn add(&mut self, x: Tally) {
        self.runs += x.runs;
        self.exact += x.exact;
        self.detected += x.detected;
        self.false_alarm += x.false_alarm;
    }
}

/// `--verbose`: one record's verdicts and every trial, on stderr.
fn print_trials(
    scn: &Scenario,
    seed: u64,
    rise: f64,
    dg: &diagnose::Diagnosis,
    found: &[Effect],
    sf: &[Effect],
) {
    eprintln!(
        "{} seed {seed}: ΔT {rise:.1} K; diagnose [{}] undecided {:?}; sindy [{}]; holdout {:.2} → {:.2} N",
        scn.name,
        ids(found),
        dg.report.undecided.iter().map(|u| u.effects.join("/")).collect::<Vec<_>>(),
        ids(sf),
        dg.report.baseline.holdout_rmse_n,
        dg.report.final_model.holdout_rmse_n
    );
    for t in &dg.report.trials {
        eprintln!(
            "    r{} {:<22} pass {:?} dBIC {:>10.1} hold {:.3}→{:.3} z {:>6.1} struct {:.2} ({}) {:?}",
            t.round,
            t.effect,
            t.passed,
            t.evidence.delta_bic,
            t.evidence.holdout_rmse_before_n,
            t.evidence.holdout_rmse_after_n,
            t.evidence.holdout_z,
            t.evidence.structure_drop,
            t.evidence.structure_region,
            t.parameters.values().map(|p| (p.value, p.ci95)).collect::<Vec<_>>()
        );
    }
}

/// The totals table: diagnose and the SINDy-style reference, records with hidden effects
/// and nulls.
fn print_totals(td: Tally, null_d: Tally, ts: Tally, null_s: Tally) {
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    println!();
    println!("| method | detection rate (all hidden found) | exactly right | false-alarm rate with hidden effects | false-alarm rate on nulls |");
    println!("| --- | --- | --- | --- | --- |");
    for (name, t, nl) in [("diagnose", td, null_d), ("SINDy-style STLSQ", ts, null_s)] {
        println!(
            "| {name} | {:.0} % ({}/{}) | {:.0} % ({}/{}) | {:.0} % ({}/{}) | {:.0} % ({}/{}) |",
            pct(t.detected, t.runs),
            t.detected,
            t.runs,
            pct(t.exact + nl.exact, t.runs + nl.runs),
            t.exact + nl.exact,
            t.runs + nl.runs,
            pct(t.false_alarm, t.runs),
            t.false_alarm,
            t.runs,
            pct(nl.false_alarm, nl.runs),
            nl.false_alarm,
            nl.runs
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: u64 = args.iter().find_map(|a| a.parse().ok()).unwrap_or(5);
    let verbose = args.iter().any(|a| a == "--verbose");
    let th = diagnose::Options::default();
    let only = args
        .iter()
        .position(|a| a == "--only")
        .and_then(|k| args.get(k + 1))
        .cloned();
    let scenarios: Vec<Scenario> = Scenario::all()
        .into_iter()
        .filter(|s| only.as_ref().is_none_or(|o| s.name.contains(o.as_str())))
        .collect();
    println!(
        "| scenario | hidden | diagnose: exact / hidden found / false alarm | SINDy-style: exact / hidden found / false alarm | diagnose held-out RMSE baseline → final (N, mean) |"
    );
    println!("| --- | --- | --- | --- | --- |");
    let (mut td, mut ts) = (Tally::default(), Tally::default());
    let (mut null_d, mut null_s) = (Tally::default(), Tally::default());
    let mut time_total = 0.0;
    let mut cpu_total = 0.0;
    let mut cpu_sindy = 0.0;
    let mut nrun = 0usize;
    for scn in &scenarios {
        let (mut d, mut s) = (Tally::default(), Tally::default());
        let (mut hb, mut hf) = (0.0, 0.0);
        for seed in 0..seeds {
            let (sig, rise) = generate(scn, 1000 + seed);
            let t0 = Instant::now();
            let c0 = cpu_seconds();
            let dg = diagnose(&sig, &scn.name, &th).expect("study data are valid");
            time_total += t0.elapsed().as_secs_f64();
            if let (Some(a), Some(b)) = (c0, cpu_seconds()) {
                cpu_total += b - a;
            }
            nrun += 1;
            let mut found: Vec<Effect> = dg
                .report
                .findings
                .iter()
                .map(|f| f.effect.parse().expect("known id"))
                .collect();
            found.sort();
            let c1 = cpu_seconds();
            let sf = sindy::sindy_effects(&sig).expect("study data are valid");
            if let (Some(a), Some(b)) = (c1, cpu_seconds()) {
                cpu_sindy += b - a;
            }
            hb += dg.report.baseline.holdout_rmse_n;
            hf += dg.report.final_model.holdout_rmse_n;
            d.count(&found, &scn.hidden);
            s.count(&sf, &scn.hidden);
            if verbose {
                print_trials(scn, seed, rise, &dg, &found, &sf);
            }
        }
        println!(
            "| {} | {} | {}/{} / {}/{} / {}/{} | {}/{} / {}/{} / {}/{} | {:.2} → {:.2} |",
            scn.name,
            ids(&scn.hidden),
            d.exact,
            d.runs,
            d.detected,
            d.runs,
            d.false_alarm,
            d.runs,
            s.exact,
            s.runs,
            s.detected,
            s.runs,
            s.false_alarm,
            s.runs,
            hb / seeds as f64,
            hf / seeds as f64
        );
        let (a, b) = if scn.hidden.is_empty() {
            (&mut null_d, &mut null_s)
        } else {
            (&mut td, &mut ts)
        };
        a.add(d);
        b.add(s);
    }
    print_totals(td, null_d, ts, null_s);
    println!();
    println!(
        "diagnose: {nrun} recordings of 30 000 samples (60 s at 500 Hz): mean wall time {:.2} s, \
         mean CPU time (all threads) {:.2} s per diagnosis; reference in the same run, the \
         SINDy-style selection (one baseline fit + thresholded least squares): {:.2} s CPU",
        time_total / nrun.max(1) as f64,
        cpu_total / nrun.max(1) as f64,
        cpu_sindy / nrun.max(1) as f64
    );
}
