//! `mrtwin monitor`: the central view of a fleet behind zenoh routers. A zenoh client of
//! the central router subscribes to every damper's outputs and diagnostics under the key
//! prefix (`<prefix>/**/twin/output`, `<prefix>/**/diagnostics`), prints one line per
//! change of a damper's level (STALE when its outputs stop for `--stale-after`, its twin's
//! own level otherwise) and writes the counts and changes as JSON at the end.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use bridge::transport::{Message, Topic};
use bridge::zenoh::{ZenohConfig, ZenohMode, ZenohSession};
use clap::Args;
use node::monitor::{level_name, Change, FleetMonitor};
use node::runner::StopWhen;
use serde_json::json;

/// Arguments of `mrtwin monitor`.
#[derive(Debug, Args)]
pub struct MonitorArgs {
    /// The router to connect to, e.g. `tcp/10.0.0.1:7447` (repeat for several).
    #[arg(long, value_name = "ENDPOINT", required = true)]
    pub connect: Vec<String>,
    /// First element(s) of the keys watched: every damper under it.
    #[arg(long, value_name = "PREFIX", default_value = "mrtwin")]
    pub key_prefix: String,
    /// A damper whose outputs stop this long is STALE [s].
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub stale_after: f64,
    /// Stop after this long [s] (default: Ctrl-C).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Write every damper's counts and level changes as JSON when stopping.
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
}

fn print_change(c: &Change) {
    println!(
        "[{:8.3} s] {}: {} ({})",
        c.at_s,
        c.damper,
        level_name(c.level),
        c.reason
    );
}

/// `mrtwin monitor`.
pub fn run(args: &MonitorArgs) -> Result<()> {
    if !(args.stale_after.is_finite() && args.stale_after > 0.0) {
        bail!(
            "--stale-after must be a positive number of seconds, got {}",
            args.stale_after
        );
    }
    let duration = crate::nodes::duration(args.duration)?;
    let stop = crate::stop::stop_flag()?;
    let session = ZenohSession::open(&ZenohConfig {
        mode: ZenohMode::Client,
        connect: args.connect.clone(),
        multicast_scouting: false,
        key_prefix: args.key_prefix.clone(),
        ..Default::default()
    })
    .with_context(|| format!("connect to the router at {}", args.connect.join(", ")))?;
    let mut outputs = session.watch(Topic::Output)?;
    let mut diagnostics = session.watch(Topic::Diagnostics)?;
    outputs.doorbell().bind_current_thread();
    diagnostics.doorbell().bind_current_thread();
    println!(
        "mrtwin monitor: watching {}/** through {} (STALE after {} s without an output)",
        args.key_prefix,
        args.connect.join(", "),
        args.stale_after
    );
    let start = Instant::now();
    let until = StopWhen {
        flag: Some(&stop),
        deadline: duration.map(|d| start + d),
    };
    let mut monitor = FleetMonitor::new(args.stale_after);
    let mut inbox = Vec::new();
    loop {
        let now = Instant::now();
        if until.reached(now) {
            break;
        }
        let t = now.duration_since(start).as_secs_f64();
        inbox.clear();
        for (what, r) in [
            ("outputs", outputs.poll(&mut inbox)),
            ("diagnostics", diagnostics.poll(&mut inbox)),
        ] {
            if let Err(e) = r {
                tracing::warn!(error = %e, "monitor: receiving {what} failed");
            }
        }
        for (damper, m) in &inbox {
            let change = match m {
                Message::Output(_) => monitor.on_output(damper, t),
                Message::Diagnostics(d) => monitor.on_diagnostics(damper, d, t),
                _ => None,
            };
            change.iter().for_each(print_change);
        }
        monitor.tick(t).iter().for_each(print_change);
        bridge::wake::wait_until(now + Duration::from_millis(50));
    }
    let elapsed = start.elapsed().as_secs_f64();
    let dampers: Vec<_> = monitor
        .dampers()
        .iter()
        .map(|(damper, w)| {
            json!({
                "damper": damper,
                "outputs": w.outputs,
                "diagnostics": w.diagnostics,
                "level": level_name(w.level),
                "stale_s": w.stale_s,
                "changes": w.changes.iter().map(|c| json!({
                    "at_s": c.at_s, "level": level_name(c.level), "reason": c.reason,
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    println!(
        "mrtwin monitor: stopped after {elapsed:.1} s: {} dampers seen",
        dampers.len()
    );
    if let Some(path) = &args.json {
        let v =
            json!({ "elapsed_s": elapsed, "stale_after_s": args.stale_after, "dampers": dampers });
        std::fs::write(path, serde_json::to_string_pretty(&v)? + "\n")
            .with_context(|| format!("write {}", path.display()))?;
    }
    Ok(())
}
