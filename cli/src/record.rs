//! `mrtwin record --out DIR`: record sensor samples and twin outputs from the live system
//! into a rosbag2 MCAP bag. The writer closes a chunk and flushes it (with fsync) at least
//! once a second, and rewrites `metadata.yaml` at every flush, so a Ctrl-C loses nothing
//! and a `kill -9` loses at most the messages since the last flush (≤ 1 s).

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use bridge::bag::{BagWriter, BagWriterOptions};
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
        for m in &inbox {
            writer.write_message(&params.damper, m, now_ns)?;
        }
        writer.tick()?;
        if inbox.is_empty() {
            std::thread::sleep(Duration::from_micros(500));
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
