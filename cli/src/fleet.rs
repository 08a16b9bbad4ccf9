//! `mrtwin fleet`: N simulated stands and N twins in one process over zenoh, each damper
//! on its own key expressions (`<key_prefix>/<damper>/…`) and under its own ROS 2
//! namespace (`/fleet/<damper>/mrtwin_twin`, the name its diagnostics carry; `__ns:=`
//! moves `/fleet`), with the
//! stand's and the twin's code of the single nodes ([`node::fleet`]). A central monitor,
//! a third zenoh session, counts every damper's outputs and how late they arrive.
//!
//! Three sessions on loopback: the twins' listens on a free port, the stands' and the
//! monitor's connect to it (multicast scouting off: the fleet is self-contained; another
//! peer connects to the printed endpoint).

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use bridge::transport::{Message, Topic, Transport};
use bridge::zenoh::{ZenohConfig, ZenohSession};
use clap::Args;
use node::config::TwinNodeParams;
use node::fleet::{FleetStands, FleetTwins, StandCounts, TwinCounts};
use node::runner::StopWhen;
use node::stand::{StandParams, StandSummary};
use numerics::stats::quantile;
use serde_json::json;

/// Arguments of `mrtwin fleet`.
#[derive(Debug, Args)]
pub struct FleetArgs {
    /// Number of dampers (stand + twin each).
    #[arg(long, value_name = "N", default_value_t = 4)]
    pub dampers: usize,
    /// Sample rate of every stand [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 1000.0)]
    pub rate: f64,
    /// How long the stands play [s].
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub duration: f64,
    /// Write the per-damper counts and the CPU use as JSON.
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// First element(s) of every zenoh key (tests give their own; a site behind a router
    /// gives its own, e.g. `mrtwin/siteA`).
    #[arg(long, value_name = "PREFIX", default_value = "mrtwin")]
    pub key_prefix: String,
    /// A zenoh router the twins' session connects to as well (e.g. the site's router,
    /// `tcp/127.0.0.1:7447`), so that their outputs and diagnostics reach a central
    /// monitor (`mrtwin monitor`) through it. Repeat for several.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// What a launch file passes (`exec: fleet`): `--ros-args -r __ns:=NS` puts the twins
    /// under `NS/<damper>/mrtwin_twin` (default `/fleet`); `__node` is the launch label.
    /// Parameter files, `-p` and other remappings are refused: the fleet is configured by
    /// its flags.
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "--ros-args …"
    )]
    pub ros_args: Vec<String>,
}

/// How long the twins keep serving after the stands stopped: the samples in flight.
const DRAIN: Duration = Duration::from_millis(300);

/// The damper names: `d001`, `d002`, …
fn damper_name(i: usize) -> String {
    format!("d{:03}", i + 1)
}

/// Process CPU time so far (user + system) \[s\].
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage writes the struct it is given and nothing else.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `ru` is a valid, writable rusage.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut ru) } != 0 {
        return f64::NAN;
    }
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    tv(ru.ru_utime) + tv(ru.ru_stime)
}

/// What the monitor saw of one damper: outputs received and their delays (sample stamp to
/// arrival, wall clock) \[s\].
#[derive(Default)]
struct Seen {
    received: u64,
    delays: Vec<f64>,
}

/// The central monitor: one adapter per damper on its own session, polled until `done`.
fn spawn_monitor(
    session: &ZenohSession,
    n: usize,
    seen: Arc<Mutex<Vec<Seen>>>,
    done: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>> {
    let mut subs = Vec::with_capacity(n);
    for i in 0..n {
        subs.push(
            session
                .transport(&damper_name(i), &[], &[Topic::Output])
                .context("declare the monitor's subscriber")?,
        );
    }
    Ok(std::thread::spawn(move || {
        let mut inbox = Vec::new();
        for s in &subs {
            if let Some(b) = s.doorbell() {
                b.bind_current_thread();
            }
        }
        loop {
            let finished = done.load(Ordering::Relaxed);
            let mut got = false;
            for (i, s) in subs.iter_mut().enumerate() {
                inbox.clear();
                if let Err(e) = s.poll(&mut inbox) {
                    tracing::warn!(error = %e, "fleet monitor: poll failed");
                }
                if inbox.is_empty() {
                    continue;
                }
                got = true;
                let now = node::stand::wall_clock_s();
                let mut seen = seen.lock().unwrap_or_else(|p| p.into_inner());
                for m in &inbox {
                    if let Message::Output(o) = m {
                        seen[i].received += 1;
                        seen[i]
                            .delays
                            .push(now - o.header.stamp.as_nanos() as f64 * 1e-9);
                    }
                }
            }
            if finished && !got {
                break;
            }
            bridge::wake::wait_until(Instant::now() + Duration::from_millis(5));
        }
    }))
}

/// Check the arguments of `mrtwin fleet`; returns the twins' namespace (`/fleet`, or the
/// `__ns:=` of its ROS arguments, without a trailing `/`).
fn checked_namespace(args: &FleetArgs) -> Result<String> {
    let n = args.dampers;
    if !(1..=1000).contains(&n) {
        bail!("--dampers must be in 1..=1000, got {n}");
    }
    if !(args.rate.is_finite() && args.rate > 0.0 && args.rate <= 20_000.0) {
        bail!("--rate must be in (0, 20000] Hz, got {}", args.rate);
    }
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0) {
        bail!("--duration must be in (0, 86400] s, got {}", args.duration);
    }
    let ros = launch_config::parse_ros_args(&args.ros_args)?;
    if !ros.params_files.is_empty() || !ros.params.is_empty() || !ros.remaps.is_empty() {
        bail!(
            "fleet takes no parameter files, -p overrides or remappings (its dampers are set by \
             --dampers and --rate); got {:?}",
            args.ros_args
        );
    }
    Ok(ros
        .namespace
        .as_deref()
        .unwrap_or("/fleet")
        .trim_end_matches('/')
        .to_string())
}

/// What a fleet run counted: per damper, the samples its stand sent and its twin stepped;
/// the stands' lateness; the process's wall and CPU time \[s\].
struct Outcome {
    sent: Vec<StandCounts>,
    counts: Vec<TwinCounts>,
    stand_summary: StandSummary,
    wall: f64,
    cpu: f64,
    cores: usize,
}

impl Outcome {
    /// Print the one-line summary and return the JSON one (`--json`): per damper what was
    /// sent, stepped and received centrally, the dampers without loss, the CPU use and the
    /// sample-to-monitor latency.
    fn report(&self, args: &FleetArgs, namespace: &str, seen: &[Seen]) -> serde_json::Value {
        let (sent, counts, stand_summary) = (&self.sent, &self.counts, &self.stand_summary);
        let (wall, cpu, cores) = (self.wall, self.cpu, self.cores);
        let n = sent.len();
        let mut all_delays: Vec<f64> = seen.iter().flat_map(|s| s.delays.iter().copied()).collect();
        all_delays.sort_by(f64::total_cmp);
        let entries: Vec<_> = (0..n)
            .map(|i| {
                json!({
                    "damper": damper_name(i),
                    "node": format!("{namespace}/{}/mrtwin_twin", damper_name(i)),
                    "sent": sent[i].sent,
                    "stepped": counts[i].stepped,
                    "received": seen[i].received,
                    "twin_received": counts[i].received,
                    "errors": sent[i].errors + counts[i].errors,
                })
            })
            .collect();
        let lossless = (0..n)
            .filter(|&i| sent[i].sent == counts[i].stepped && counts[i].stepped == seen[i].received)
            .count();
        let total = |f: &dyn Fn(usize) -> u64| (0..n).map(f).sum::<u64>();
        let summary = json!({
            "dampers": entries,
            "rate_hz": args.rate,
            "duration_s": args.duration,
            "wall_s": wall,
            "cpu_s": cpu,
            "cores": cores,
            "cpu_percent": 100.0 * cpu / (wall * cores as f64),
            "dampers_without_loss": lossless,
            "stand_max_lateness_ms": stand_summary.max_lateness_s * 1e3,
            "latency_ms": {
                "p50": quantile(&all_delays, 0.5).map_or(f64::NAN, |d| d * 1e3),
                "p99": quantile(&all_delays, 0.99).map_or(f64::NAN, |d| d * 1e3),
                "max": all_delays.last().map_or(f64::NAN, |d| d * 1e3),
            },
        });
        println!(
            "sent {}, stepped {}, received centrally {}; {lossless} of {n} dampers without loss; \
             CPU {:.0} % of {cores} cores; sample-to-monitor latency p50 {:.2} ms, p99 {:.2} ms; \
             stand lateness max {:.2} ms",
            total(&|i| sent[i].sent),
            total(&|i| counts[i].stepped),
            total(&|i| seen[i].received),
            summary["cpu_percent"].as_f64().unwrap_or(f64::NAN),
            summary["latency_ms"]["p50"].as_f64().unwrap_or(f64::NAN),
            summary["latency_ms"]["p99"].as_f64().unwrap_or(f64::NAN),
            stand_summary.max_lateness_s * 1e3,
        );
        summary
    }
}

/// `mrtwin fleet`.
pub fn run(args: &FleetArgs) -> Result<()> {
    let n = args.dampers;
    let namespace = checked_namespace(args)?;
    let stop = crate::stop::stop_flag()?;
    let port = crate::live::free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let base = ZenohConfig {
        key_prefix: args.key_prefix.clone(),
        multicast_scouting: false,
        ..Default::default()
    };
    let twins_session = ZenohSession::open(&ZenohConfig {
        listen: vec![endpoint.clone()],
        connect: args.connect.clone(),
        ..base.clone()
    })
    .context("open the twins' zenoh session")?;
    let peer = ZenohConfig {
        connect: vec![endpoint.clone()],
        ..base
    };
    let stands_session = ZenohSession::open(&peer).context("open the stands' zenoh session")?;
    let monitor_session = ZenohSession::open(&peer).context("open the monitor's zenoh session")?;
    println!(
        "mrtwin fleet: {n} dampers at {} Hz for {} s over zenoh {endpoint} (keys {}/dNNN/…)",
        args.rate, args.duration, args.key_prefix
    );

    let mut twins = Vec::with_capacity(n);
    let mut stands = Vec::with_capacity(n);
    for i in 0..n {
        let damper = damper_name(i);
        let params = TwinNodeParams {
            damper: damper.clone(),
            ..Default::default()
        };
        let t: Box<dyn Transport> = Box::new(twins_session.transport(
            &damper,
            &[
                Topic::Output,
                Topic::PredictedForce,
                Topic::YieldEstimate,
                Topic::Diagnostics,
            ],
            &[Topic::Sample],
        )?);
        twins.push((params, format!("{namespace}/{damper}/mrtwin_twin"), t));
        // Each stand its own stroke frequency and noise seed; currents stepped as the
        // single stand's default.
        let stand = StandParams {
            damper: damper.clone(),
            rate_hz: args.rate,
            frequencies_hz: vec![1.0 + 0.25 * (i % 8) as f64],
            seed: 1 + i as u64,
            ..Default::default()
        };
        let s: Box<dyn Transport> =
            Box::new(stands_session.transport(&damper, &[Topic::Sample], &[])?);
        stands.push((stand, s));
    }
    let mut fleet = FleetTwins::new(twins).context("start the fleet's twins")?;
    let mut players = FleetStands::new(stands).context("start the fleet's stands")?;
    let seen = Arc::new(Mutex::new(
        (0..n).map(|_| Seen::default()).collect::<Vec<_>>(),
    ));
    let done = Arc::new(AtomicBool::new(false));
    let monitor = spawn_monitor(&monitor_session, n, seen.clone(), done.clone())?;
    // Let the subscriptions propagate before the first sample.
    std::thread::sleep(Duration::from_millis(500));

    let cpu0 = cpu_seconds();
    let t0 = Instant::now();
    let duration = Duration::from_secs_f64(args.duration);
    let stand_stop = stop.clone();
    // The twins run until the stands are done (their duration, or Ctrl-C) and their last
    // samples are through.
    let twins_stop = Arc::new(AtomicBool::new(false));
    let stands_done = twins_stop.clone();
    let stands_thread = std::thread::spawn(move || {
        let r = players.run(Some(&stand_stop), duration);
        std::thread::sleep(DRAIN);
        stands_done.store(true, Ordering::Relaxed);
        r
    });
    let counts = fleet.run(StopWhen {
        flag: Some(&twins_stop),
        deadline: Some(t0 + duration + DRAIN + Duration::from_secs(5)),
    });
    let (sent, stand_summary) = stands_thread
        .join()
        .map_err(|_| anyhow::anyhow!("the stands' thread panicked"))?;
    let wall = t0.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu0;
    done.store(true, Ordering::Relaxed);
    monitor
        .join()
        .map_err(|_| anyhow::anyhow!("the monitor thread panicked"))?;
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());

    let seen = seen.lock().unwrap_or_else(|p| p.into_inner());
    let outcome = Outcome {
        sent,
        counts,
        stand_summary,
        wall,
        cpu,
        cores,
    };
    let summary = outcome.report(args, &namespace, &seen);
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&summary)? + "\n")
            .with_context(|| format!("write {}", path.display()))?;
    }
    Ok(())
}
