//! Fuzzing every parser of mrtwin on stable Rust (issue 15): seeded generators and
//! mutators, a campaign runner that catches panics and watches for hangs, and the list of
//! parsers.
//!
//! Each [`Parser`] has a generator (structure-aware: a valid input of the format, built from
//! random content, then, most of the time, [`mutate`]d at the byte or line level) and a
//! check that runs the parser's public entry point on it. The check returns what the
//! parser did ([`Verdict`]) or the property that failed: an input the generator made valid
//! was rejected, a round trip (write → read, encode → decode) changed the data, or an
//! error did not name its file. A panic is caught with [`std::panic::catch_unwind`]; a
//! parser that runs longer than [`CampaignOptions::hang_limit`] on one input is a hang.
//! Either way the input is saved (one directory per input, one file per part) for a
//! regression test.
//!
//! Inputs are reproducible one by one: input `i` of parser `p` in a campaign of seed `s`
//! is drawn from [`rng::input_seed`]`(s, p, i)`.
//!
//! The driver is `src/bin/fuzz-parsers.rs` (1 M inputs per parser); `tests/fuzz_parsers.rs`
//! runs a fast slice of the same generators in `cargo test`.

pub mod bags;
pub mod cdr;
pub mod config;
pub mod mutate;
pub mod recordings;
pub mod rng;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, Once};
use std::time::{Duration, Instant};

use rng::{input_seed, Rng};

/// One generated input: named parts (one text, or the files of a bag directory).
#[derive(Debug, Clone, Default)]
pub struct FuzzInput {
    /// `(file name, content)`, in the order the check uses them.
    pub parts: Vec<(String, Vec<u8>)>,
    /// The generator left the valid input untouched: the parser must accept it.
    pub valid: bool,
}

impl FuzzInput {
    /// An input of one part.
    pub fn single(name: &str, data: Vec<u8>, valid: bool) -> Self {
        Self {
            parts: vec![(name.to_owned(), data)],
            valid,
        }
    }

    /// The content of the part named `name` (empty when there is none).
    pub fn part(&self, name: &str) -> &[u8] {
        self.parts
            .iter()
            .find(|(n, _)| n == name)
            .map_or(&[][..], |(_, d)| d.as_slice())
    }

    /// Total bytes of all parts.
    pub fn len(&self) -> usize {
        self.parts.iter().map(|(_, d)| d.len()).sum()
    }

    /// `true` when every part is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Write every part into `dir` (created), as the regression test will read it.
    pub fn save(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        for (name, data) in &self.parts {
            std::fs::write(dir.join(name), data)?;
        }
        Ok(())
    }
}

/// What a parser did with an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// It returned a value (and every property held).
    Accepted,
    /// It returned an error.
    Rejected,
}

/// An error must name the file it is about (`file`: its path, or the name the parser was
/// given for it): then the input was rejected as it should be.
pub(crate) fn names_file(message: &str, file: &str) -> Result<Verdict, String> {
    if message.contains(file) {
        Ok(Verdict::Rejected)
    } else {
        Err(format!(
            "the error does not name the file {file}: {message}"
        ))
    }
}

/// A directory of one worker for parsers that read paths; reused for every input.
#[derive(Debug)]
pub struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    /// A fresh, empty directory under the system temp dir.
    pub fn new(label: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("mrtwin-fuzz-{}-{label}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create the fuzz scratch directory");
        Self { dir }
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A parser under test: its generator and its check.
pub struct Parser {
    /// Short name (`--parser NAME`).
    pub name: &'static str,
    /// The entry points it drives.
    pub entry: &'static str,
    /// Draws one input.
    pub generate: fn(&mut Rng) -> FuzzInput,
    /// Runs the parser on an input; `Err` names the property that failed.
    pub check: fn(&FuzzInput, &Scratch) -> Result<Verdict, String>,
}

/// Every parser, in the order of the report.
pub fn parsers() -> Vec<Parser> {
    let mut all = Vec::new();
    all.extend(recordings::parsers());
    all.extend(bags::parsers());
    all.extend(cdr::parsers());
    all.extend(config::parsers());
    all
}

/// Settings of a campaign.
#[derive(Debug, Clone)]
pub struct CampaignOptions {
    /// Inputs per parser.
    pub inputs: u64,
    /// Campaign seed.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
    /// One input running longer than this is a hang: the input is saved and the process
    /// exits with status 3 (a stuck thread cannot be stopped).
    pub hang_limit: Duration,
    /// Where failing inputs are saved (`<dir>/<parser>-<seed>-<index>/`); `None`: not saved.
    pub failures_dir: Option<PathBuf>,
}

/// A failing input.
#[derive(Debug, Clone)]
pub struct Failure {
    /// Index of the input in the campaign.
    pub index: u64,
    /// `true` for a panic, `false` for a failed property.
    pub panic: bool,
    /// The panic message with its location, or the property that failed.
    pub message: String,
    /// Where the input was saved.
    pub saved: Option<PathBuf>,
}

/// What a campaign found for one parser.
#[derive(Debug, Clone)]
pub struct ParserReport {
    /// Parser name.
    pub name: &'static str,
    /// Inputs run.
    pub inputs: u64,
    /// Inputs the parser accepted.
    pub accepted: u64,
    /// Inputs the parser rejected with an error.
    pub rejected: u64,
    /// Panics.
    pub panics: u64,
    /// Failed properties (valid input rejected, round trip broken, error without its file).
    pub violations: u64,
    /// The longest time one input took, and its index.
    pub slowest: (Duration, u64),
    /// Wall time of the parser's campaign.
    pub wall: Duration,
    /// The first failures (at most 20 are kept).
    pub failures: Vec<Failure>,
}

thread_local! {
    /// The panic message of the input running on this thread (set by the hook).
    static PANIC_MESSAGE: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
    /// This thread runs fuzz inputs: its panics are recorded, not printed.
    static FUZZING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Install (once) a panic hook that records the message and location of panics on fuzz
/// threads instead of printing them; other threads keep the previous hook.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if FUZZING.with(|f| f.get()) {
                let payload = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| (*s).to_owned())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(non-text panic payload)".to_owned());
                let at = info
                    .location()
                    .map(|l| format!(" at {}:{}", l.file(), l.line()))
                    .unwrap_or_default();
                PANIC_MESSAGE.with(|m| *m.borrow_mut() = Some(format!("{payload}{at}")));
            } else {
                previous(info);
            }
        }));
    });
}

/// Run `parser` on the input of seed `seed` once, catching a panic: `Ok(verdict)`, or
/// `Err((panicked, message))`.
pub fn run_one(
    parser: &Parser,
    input: &FuzzInput,
    scratch: &Scratch,
) -> Result<Verdict, (bool, String)> {
    install_panic_hook();
    FUZZING.with(|f| f.set(true));
    let result = catch_unwind(AssertUnwindSafe(|| (parser.check)(input, scratch)));
    FUZZING.with(|f| f.set(false));
    match result {
        Ok(Ok(verdict)) => Ok(verdict),
        Ok(Err(property)) => Err((false, property)),
        Err(_) => {
            let message = PANIC_MESSAGE
                .with(|m| m.borrow_mut().take())
                .unwrap_or_else(|| "panic".to_owned());
            Err((true, message))
        }
    }
}

/// Input `index` of `parser` in a campaign of seed `seed`.
pub fn input(parser: &Parser, seed: u64, index: u64) -> FuzzInput {
    (parser.generate)(&mut Rng::new(input_seed(seed, parser.name, index)))
}

/// The directory a failing input is saved in.
fn failure_dir(opts: &CampaignOptions, parser: &Parser, index: u64) -> Option<PathBuf> {
    opts.failures_dir
        .as_ref()
        .map(|d| d.join(format!("{}-{}-{index}", parser.name, opts.seed)))
}

/// Per-worker progress the watchdog reads: index + 1 of the running input (0 when idle)
/// and its start, in µs since the campaign started.
struct Progress {
    running: AtomicU64,
    started_us: AtomicU64,
}

/// Run `opts.inputs` inputs of `parser` on `opts.threads` threads.
pub fn run_campaign(parser: &Parser, opts: &CampaignOptions) -> ParserReport {
    let threads = opts.threads.max(1);
    let start = Instant::now();
    let progress: Vec<Progress> = (0..threads)
        .map(|_| Progress {
            running: AtomicU64::new(0),
            started_us: AtomicU64::new(0),
        })
        .collect();
    let done = AtomicBool::new(false);
    let failures = Mutex::new(Vec::new());
    let report = std::thread::scope(|s| {
        s.spawn(|| watchdog(parser, opts, &progress, &done, start));
        let workers: Vec<_> = (0..threads)
            .map(|t| {
                let progress = &progress[t];
                let failures = &failures;
                s.spawn(move || {
                    let scratch = Scratch::new(&format!("{}-{t}", parser.name));
                    let mut counts = [0u64; 4];
                    let mut slowest = (Duration::ZERO, 0);
                    let mut index = t as u64;
                    while index < opts.inputs {
                        let input = input(parser, opts.seed, index);
                        let began = Instant::now();
                        progress.started_us.store(
                            began.duration_since(start).as_micros() as u64,
                            Ordering::Relaxed,
                        );
                        progress.running.store(index + 1, Ordering::Relaxed);
                        let result = run_one(parser, &input, &scratch);
                        progress.running.store(0, Ordering::Relaxed);
                        let took = began.elapsed();
                        if took > slowest.0 {
                            slowest = (took, index);
                        }
                        match result {
                            Ok(Verdict::Accepted) => counts[0] += 1,
                            Ok(Verdict::Rejected) => counts[1] += 1,
                            Err((panic, message)) => {
                                counts[if panic { 2 } else { 3 }] += 1;
                                let mut f = failures.lock().unwrap_or_else(|e| e.into_inner());
                                if f.len() < 20 {
                                    let saved = failure_dir(opts, parser, index)
                                        .filter(|dir| input.save(dir).is_ok());
                                    if let Some(dir) = &saved {
                                        let _ = std::fs::write(dir.join("failure.txt"), &message);
                                    }
                                    f.push(Failure {
                                        index,
                                        panic,
                                        message,
                                        saved,
                                    });
                                }
                            }
                        }
                        index += threads as u64;
                    }
                    (counts, slowest)
                })
            })
            .collect();
        let mut counts = [0u64; 4];
        let mut slowest = (Duration::ZERO, 0);
        for w in workers {
            let (c, s) = w.join().expect("fuzz workers catch every panic");
            for (total, add) in counts.iter_mut().zip(c) {
                *total += add;
            }
            if s.0 > slowest.0 {
                slowest = s;
            }
        }
        done.store(true, Ordering::Relaxed);
        (counts, slowest)
    });
    let ([accepted, rejected, panics, violations], slowest) = report;
    let mut failures = failures.into_inner().unwrap_or_else(|e| e.into_inner());
    failures.sort_by_key(|f| f.index);
    ParserReport {
        name: parser.name,
        inputs: accepted + rejected + panics + violations,
        accepted,
        rejected,
        panics,
        violations,
        slowest,
        wall: start.elapsed(),
        failures,
    }
}

/// Watch the workers; an input running past the hang limit is saved and reported, and the
/// process exits with status 3.
fn watchdog(
    parser: &Parser,
    opts: &CampaignOptions,
    progress: &[Progress],
    done: &AtomicBool,
    start: Instant,
) {
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
        let now_us = start.elapsed().as_micros() as u64;
        for p in progress {
            let running = p.running.load(Ordering::Relaxed);
            let started = p.started_us.load(Ordering::Relaxed);
            if running == 0 || now_us.saturating_sub(started) < opts.hang_limit.as_micros() as u64 {
                continue;
            }
            if p.running.load(Ordering::Relaxed) != running {
                continue;
            }
            let index = running - 1;
            let saved = failure_dir(opts, parser, index)
                .filter(|dir| input(parser, opts.seed, index).save(dir).is_ok());
            eprintln!(
                "HANG: parser {} ran input {index} (seed {}) for more than {:?}; input saved in {}",
                parser.name,
                opts.seed,
                opts.hang_limit,
                saved.map_or("(not saved)".to_owned(), |d| d.display().to_string())
            );
            std::process::exit(3);
        }
    }
}
