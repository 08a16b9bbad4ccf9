//! Fuzz driver of every mrtwin parser (issue 15): runs generated and mutated inputs through
//! each parser, catching panics and watching for hangs, and prints per parser the inputs
//! run, how many were accepted and rejected, the panics and failed properties, the slowest
//! input and the wall time. Failing inputs are saved, one directory each.
//!
//! ```text
//! cargo run --release -p mrtwin-tests --bin fuzz-parsers -- --inputs 1000000 \
//!     [--parser NAME] [--seed S] [--threads N] [--failures DIR] [--hang-limit-s T] \
//!     [--index I] [--list]
//! ```
//!
//! `--index I` runs input `I` alone (with `--parser` and `--seed`), prints it and what the
//! parser did: how to replay a failure. Exit status: 0 when no input panicked or failed a
//! property, 1 otherwise, 2 on bad arguments, 3 on a hang.

use std::path::PathBuf;
use std::time::Duration;

use mrtwin_tests::fuzz::{input, parsers, run_campaign, run_one, CampaignOptions, Scratch};

fn usage() -> ! {
    eprintln!(
        "usage: fuzz-parsers [--inputs N] [--parser NAME] [--seed S] [--threads N] \
         [--failures DIR] [--hang-limit-s T] [--index I] [--list]"
    );
    std::process::exit(2);
}

fn main() {
    let mut opts = CampaignOptions {
        inputs: 1_000_000,
        seed: 1,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        hang_limit: Duration::from_secs(10),
        failures_dir: Some(std::env::temp_dir().join("mrtwin-fuzz-failures")),
    };
    let mut only: Option<String> = None;
    let mut index: Option<u64> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| usage());
        let number = |v: String| v.parse::<u64>().unwrap_or_else(|_| usage());
        match a.as_str() {
            "--inputs" => opts.inputs = number(value()),
            "--seed" => opts.seed = number(value()),
            "--threads" => opts.threads = number(value()) as usize,
            "--parser" => only = Some(value()),
            "--failures" => opts.failures_dir = Some(PathBuf::from(value())),
            "--hang-limit-s" => opts.hang_limit = Duration::from_secs(number(value())),
            "--index" => index = Some(number(value())),
            "--list" => {
                for p in parsers() {
                    println!("{:<24} {}", p.name, p.entry);
                }
                return;
            }
            _ => usage(),
        }
    }
    let all = parsers();
    let selected: Vec<_> = all
        .iter()
        .filter(|p| only.as_deref().is_none_or(|n| n == p.name))
        .collect();
    if selected.is_empty() {
        eprintln!(
            "no parser named {}; --list shows them",
            only.unwrap_or_default()
        );
        std::process::exit(2);
    }

    if let Some(i) = index {
        let mut failed = false;
        for p in selected {
            let inp = input(p, opts.seed, i);
            for (name, data) in &inp.parts {
                println!(
                    "--- {name} ({} bytes)\n{}",
                    data.len(),
                    String::from_utf8_lossy(data)
                );
            }
            let scratch = Scratch::new(&format!("{}-replay", p.name));
            let result = run_one(p, &inp, &scratch);
            println!("{} input {i} (seed {}): {result:?}", p.name, opts.seed);
            failed |= result.is_err();
        }
        std::process::exit(i32::from(failed));
    }

    println!(
        "fuzz-parsers: {} inputs per parser, seed {}, {} threads, hang limit {:?}",
        opts.inputs, opts.seed, opts.threads, opts.hang_limit
    );
    println!(
        "| parser | inputs | accepted | rejected (error) | panics | failed properties | slowest input | wall time |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    let mut bad = 0;
    let mut total = Duration::ZERO;
    let mut failures = Vec::new();
    for p in selected {
        let r = run_campaign(p, &opts);
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.1} ms | {:.1} s |",
            r.name,
            r.inputs,
            r.accepted,
            r.rejected,
            r.panics,
            r.violations,
            r.slowest.0.as_secs_f64() * 1e3,
            r.wall.as_secs_f64()
        );
        total += r.wall;
        bad += r.panics + r.violations;
        failures.extend(r.failures.into_iter().map(|f| (r.name, f)));
    }
    println!("total wall time {:.1} s", total.as_secs_f64());
    for (name, f) in &failures {
        println!(
            "{} {name} input {}: {}{}",
            if f.panic { "PANIC" } else { "PROPERTY" },
            f.index,
            f.message,
            f.saved
                .as_ref()
                .map(|d| format!(" (saved in {})", d.display()))
                .unwrap_or_default()
        );
    }
    std::process::exit(i32::from(bad > 0));
}
