//! `mrtwin record --out DIR`: record sensor samples and twin outputs from the live system
//! into a rosbag2 MCAP bag. The writer closes a chunk and flushes it (with fsync) at least
//! once a second, and rewrites `metadata.yaml` at every flush, so a Ctrl-C loses nothing
//! and a `kill -9` loses at most the messages since the last flush (≤ 1 s).
//!
//! A write that fails (a full disk, a file-size limit) stops the recording with an error
//! naming the bag file and the cause, and saying how many messages the bag keeps: those of
//! the last completed flush, readable as after a `kill -9`.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use bridge::bag::{BagError, BagWriter, BagWriterOptions};
use bridge::transport::Topic;
use clap::Args;
use launch_config::{load_node_params, parse_ros_args};
use node::config::TwinNodeParams;
use node::transports::{open, TransportKind};

/// Default node name of the recorder.
pub const RECORD_NODE: &str = "mrtwin_record";

/// Arguments of `mrtwin record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Bag directory to create.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Topics (default: sensor/sample, twin/output, twin/yield_estimate, /diagnostics).
    #[arg(long, value_name = "TOPIC[,TOPIC…]", value_delimiter = ',')]
    pub topics: Vec<String>,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Transport to record from.
    #[arg(long, value_name = "ros2|zenoh|iceoryx2", default_value = "zenoh")]
    pub transport: TransportKind,
    /// Longest time between flushes [s].
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub flush_period: f64,
    /// ROS 2 arguments; parameters are read as for the twin node (damper, transports).
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "--ros-args …"
    )]
    pub ros_args: Vec<String>,
}

/// `mrtwin record`.
pub fn run(args: &RecordArgs) -> Result<()> {
    let ros = parse_ros_args(&args.ros_args)?;
    let params: TwinNodeParams = load_node_params(&ros, RECORD_NODE)?;
    let name = ros.fully_qualified_name(RECORD_NODE);
    let topics: Vec<Topic> = if args.topics.is_empty() {
        vec![
            Topic::Sample,
            Topic::Output,
            Topic::YieldEstimate,
            Topic::Diagnostics,
        ]
    } else {
        args.topics
            .iter()
            .map(|t| {
                Topic::parse(t.trim()).with_context(|| format!("--topics: unknown topic '{t}'"))
            })
            .collect::<Result<_>>()?
    };
    if !(args.flush_period.is_finite() && args.flush_period > 0.0) {
        bail!("--flush-period must be positive, got {}", args.flush_period);
    }
    ignore_file_size_signal();
    let settings = params.transport_settings(&name);
    let mut transport = open(args.transport, &settings, &[], &topics)?;
    let mut writer = BagWriter::create(
        &args.out,
        BagWriterOptions {
            flush_period: Duration::from_secs_f64(args.flush_period),
            ..Default::default()
        },
    )
    .with_context(|| format!("create bag {}", args.out.display()))?;
    let stop = crate::stop::stop_flag()?;
    let deadline = args
        .duration
        .map(|d| Instant::now() + Duration::from_secs_f64(d.max(0.0)));
    tracing::info!(
        node = %name,
        topics = ?topics.iter().map(|t| t.ros_name()).collect::<Vec<_>>(),
        transport = %args.transport,
        out = %args.out.display(),
        "recording (Ctrl-C stops)"
    );
    let mut inbox = Vec::new();
    let mut errors = 0u64;
    // Idle, sleep until the transport rings (or 20 ms, for the flush period and Ctrl-C); a
    // transport that cannot ring is polled every 500 µs.
    let doorbell = transport.doorbell();
    if let Some(b) = &doorbell {
        b.bind_current_thread();
    }
    const GATHER: Duration = Duration::from_micros(500);
    const LINGER: Duration = Duration::from_millis(20);
    let mut last_message = Instant::now();
    let idle_wait = if doorbell.is_some() {
        Duration::from_millis(20)
    } else {
        GATHER
    };
    loop {
        if stop.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        inbox.clear();
        if let Err(e) = transport.poll(&mut inbox) {
            tracing::warn!(transport = %args.transport, error = %e, "poll failed");
            errors += 1;
        }
        let now_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        let written = inbox
            .iter()
            .try_for_each(|m| writer.write_message(&params.damper, m, now_ns))
            .and_then(|()| writer.tick());
        if let Err(e) = written {
            return Err(stopped(e, writer, &args.out));
        }
        // While messages flow (and for 20 ms after the last), poll every 500 µs: a burst
        // (a sample, its output, its force) is taken in one wake-up, and the recorder
        // sleeps through the messages' rings instead of waking for each (a recorder needs
        // no low latency; the queues hold far more than 500 µs: zenoh 65 536 per topic,
        // DDS history 1000, iceoryx2 1024). Quiet longer: sleep until a message rings.
        let now = Instant::now();
        if !inbox.is_empty() {
            last_message = now;
        }
        let quiet = now.duration_since(last_message) >= LINGER;
        let t = now + if quiet { idle_wait } else { GATHER };
        let until = deadline.map_or(t, |d| d.min(t));
        if quiet {
            bridge::wake::wait_until(until);
        } else {
            std::thread::sleep(until.saturating_duration_since(Instant::now()));
        }
    }
    let summary = writer.finish()?;
    println!(
        "{name}: {} messages in {} ({} transport errors)",
        summary.message_count,
        args.out.display(),
        errors
    );
    for (topic, ty, n) in &summary.topics {
        println!("  {topic} [{ty}]: {n}");
    }
    Ok(())
}

/// Past a file-size limit (`ulimit -f`, `RLIMIT_FSIZE`) the kernel sends SIGXFSZ, whose
/// default action kills the recorder without a word; ignored, the write fails with EFBIG
/// instead and the recorder stops saying why, as on a full disk (ENOSPC).
fn ignore_file_size_signal() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN installs no handler code.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// The error of a recording that cannot go on (the bag's file cannot be written): the
/// cause, and what the bag keeps. The bag is finished if it still can be (then it holds
/// every message); otherwise it stays as of its last flush.
fn stopped(e: BagError, writer: BagWriter, out: &Path) -> anyhow::Error {
    let (written, flushed) = (writer.message_count(), writer.flushed_message_count());
    let kept = match writer.finish() {
        Ok(summary) => format!(
            "the bag was finished with all {} messages",
            summary.message_count
        ),
        Err(_) => format!(
            "the bag keeps the {flushed} messages of its last flush, the {} written since are lost",
            written - flushed
        ),
    };
    // The bag error's text already holds its cause: as a chain it would print twice.
    anyhow::anyhow!("{e}").context(format!("recording into {} stopped ({kept})", out.display()))
}
