//! `mrtwin demo`: the whole system on one machine, no hardware, no ROS install, no
//! server. The test stand plays the simulator as a live 1 kHz sensor stream on ROS 2,
//! zenoh and iceoryx2; the twin node takes the samples from one of them (zenoh by
//! default), steps its model in lockstep and publishes on all three; a monitor counts
//! what arrives on each transport; a local controller asks the twin what-if questions
//! over the iceoryx2 request–response service. One live line per second, then a summary.

use std::net::TcpListener;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use bridge::transport::{Message, Topic};
use clap::Args;
use msgs::shm::{ShmRequest, ShmSample};
use node::config::TwinNodeParams;
use node::runner::{LiveStats, StopWhen, TwinNode};
use node::stand::{StandNode, StandParams};
use node::transports::{open, ControlClient, TransportKind, TransportSettings};

/// Arguments of `mrtwin demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// How long to run [s].
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub duration: f64,
    /// Transport the twin takes the samples from.
    #[arg(long, value_name = "ros2|zenoh|iceoryx2", default_value = "zenoh")]
    pub input: TransportKind,
    /// ROS domain id.
    #[arg(long, value_name = "ID", default_value_t = 0)]
    pub domain_id: u16,
    /// Sample rate of the stand [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 1000.0)]
    pub rate: f64,
    /// First element of every zenoh key (tests give their own; users keep `mrtwin`).
    #[arg(long, value_name = "PREFIX", default_value = "mrtwin")]
    pub key_prefix: String,
    /// Serve the twin's Foxglove live view on `[HOST:]PORT` (a bare port is loopback).
    #[arg(long, value_name = "[HOST:]PORT")]
    pub foxglove: Option<String>,
}

/// One line per second.
pub fn live_line(s: &LiveStats) -> String {
    let tau = s.estimate.map_or("τ0 —".to_string(), |e| {
        format!("τ0 {:.1} ± {:.1} kPa", e.tau0_pa / 1e3, e.tau0_std_pa / 1e3)
    });
    format!(
        "t={:>5.1} s  {:>6.0} samples/s  I {:>4.2} A  F meas {:>8.1} N  pred {:>8.1} N  rms residual {:>6.1} N  {}  health {}",
        s.elapsed_s,
        s.rate_hz,
        s.current_a,
        s.measured_force_n,
        s.predicted_force_n,
        s.residual_rms_n,
        tau,
        s.level.name()
    )
}

/// A free loopback TCP port (for a zenoh listener).
pub(crate) fn free_port() -> Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")
        .context("find a free loopback port for zenoh")?
        .local_addr()?
        .port())
}

/// The demo's twin and stand, as a user finds them: the twin listens on a loopback port
/// that the stand and the monitor connect to (so the demo runs without multicast too),
/// and both answer zenoh's multicast scouting like any `mrtwin node`, so a stock zenoh
/// peer on this machine in its default configuration finds them; ROS 2 on the domain
/// asked for (0 by default). Every listener stays on loopback.
fn configure(args: &DemoArgs, damper: &str, port: u16) -> (TwinNodeParams, StandParams) {
    let all = TransportKind::ALL.to_vec();
    let mut twin = TwinNodeParams {
        damper: damper.to_string(),
        transports: all.clone(),
        input: args.input,
        ..Default::default()
    };
    twin.zenoh.listen = vec![format!("tcp/127.0.0.1:{port}")];
    twin.zenoh.key_prefix.clone_from(&args.key_prefix);
    twin.ros2.domain_id = args.domain_id;
    let mut stand = StandParams {
        damper: damper.to_string(),
        transports: all,
        rate_hz: args.rate,
        // One stroke frequency, three currents of 3 s each: the default 10 s shows the
        // estimate at every current.
        frequencies_hz: vec![2.0],
        currents_a: vec![0.5, 1.0, 2.0],
        segment_duration_s: 3.0,
        ..Default::default()
    };
    stand.zenoh.connect = vec![format!("tcp/127.0.0.1:{port}")];
    stand.zenoh.key_prefix.clone_from(&args.key_prefix);
    stand.ros2.domain_id = args.domain_id;
    stand.ros2.node_name = "mrtwin_stand".into();
    (twin, stand)
}

/// Copy-paste commands that look at the running demo from other tools on this machine.
fn look_commands(args: &DemoArgs, twin: &TwinNodeParams, port: u16) -> String {
    let keys = format!("{}/{}/**", twin.zenoh.key_prefix, twin.damper);
    let domain = if args.domain_id == 0 {
        String::new()
    } else {
        format!("ROS_DOMAIN_ID={} ", args.domain_id)
    };
    let ros = |topic: Topic| twin.ros2.resolve(topic);
    [
        "look at it while it runs (copy-paste into another terminal):".to_string(),
        format!(
            "  zenoh, a stock peer in its default configuration (pip install eclipse-zenoh); \
             messages per key in 3 s:\n    python3 -c 'import collections, time, zenoh; \
             n = collections.Counter(); s = zenoh.open(zenoh.Config()); \
             sub = s.declare_subscriber(\"{keys}\", lambda x: n.update([str(x.key_expr)])); \
             time.sleep(3); s.close(); print(dict(n))'"
        ),
        format!("  zenoh, connecting to the twin directly: z_sub -k '{keys}' -e tcp/127.0.0.1:{port}"),
        format!(
            "  ROS 2 (domain {}): {domain}ros2 topic echo {}   ·   {domain}ros2 topic echo {}",
            args.domain_id,
            ros(Topic::PredictedForce),
            ros(Topic::Diagnostics)
        ),
        format!(
            "  rclpy without a ROS install: python3 examples/rclpy-listener/listener.py --domain-id {}",
            args.domain_id
        ),
    ]
    .join("\n")
}

/// Twin outputs received per transport (in [`TransportKind::ALL`] order).
type Counts = Arc<[AtomicU64; 3]>;

/// A monitor thread that counts the twin's outputs on every transport until `done`.
fn spawn_monitor(
    settings: &TransportSettings,
    counts: Counts,
    done: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>> {
    let mut monitors = Vec::new();
    for (i, &k) in TransportKind::ALL.iter().enumerate() {
        monitors.push((
            i,
            open(k, settings, &[], &[Topic::Output])
                .with_context(|| format!("open the {k} monitor"))?,
        ));
    }
    Ok(std::thread::spawn(move || {
        let mut inbox = Vec::new();
        while !done.load(Ordering::Relaxed) {
            for (i, t) in &mut monitors {
                inbox.clear();
                if let Err(e) = t.poll(&mut inbox) {
                    tracing::warn!(transport = t.name(), error = %e, "monitor poll failed");
                }
                let n = inbox
                    .iter()
                    .filter(|m| matches!(m, Message::Output(_)))
                    .count();
                counts[*i].fetch_add(n as u64, Ordering::Relaxed);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }))
}

/// What-if answers: `[answered, rejected]`.
type WhatIf = Arc<[AtomicU64; 2]>;

/// A local controller asking "what force with 2 A now?" at 100 Hz over iceoryx2.
fn spawn_controller(
    cfg: bridge::iceoryx2::Iceoryx2Config,
    whatif: WhatIf,
    done: Arc<AtomicBool>,
) -> std::thread::JoinHandle<Result<()>> {
    std::thread::spawn(move || -> Result<()> {
        let mut client = ControlClient::new(&cfg)?;
        client.wait_for_server(Duration::from_secs(5))?;
        let mut seq = 0;
        while !done.load(Ordering::Relaxed) {
            seq += 1;
            let now = SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos() as i64);
            let req = ShmRequest {
                kind: ShmRequest::PLANNED_CURRENT,
                reserved: 0,
                sample: ShmSample {
                    seq,
                    time_ns: now,
                    current_a: 2.0,
                    temperature_c: f64::NAN,
                    ..Default::default()
                },
            };
            if let Ok(r) = client.request(&req, Duration::from_millis(100)) {
                whatif[usize::from(r.rejected != 0)].fetch_add(1, Ordering::Relaxed);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(())
    })
}

/// `mrtwin demo`.
pub fn run(args: &DemoArgs) -> Result<()> {
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0) {
        bail!("--duration must be in (0, 86400] s, got {}", args.duration);
    }
    if !(args.rate.is_finite() && args.rate > 0.0 && args.rate <= 20_000.0) {
        bail!("--rate must be in (0, 20000] Hz, got {}", args.rate);
    }
    let stop = crate::stop::stop_flag()?;
    let port = free_port()?;
    let damper = format!("demo{}", std::process::id());
    let (twin, stand) = configure(args, &damper, port);
    println!(
        "mrtwin demo: stand ({} Hz, {} model, currents {:?} A, frequencies {:?} Hz) → twin ({} in; ROS 2 domain {}, zenoh tcp/127.0.0.1:{port}, iceoryx2 mrtwin/{damper}) for {} s",
        args.rate, stand.model, stand.currents_a, stand.frequencies_hz, args.input, args.domain_id, args.duration
    );
    println!("{}", look_commands(args, &twin, port));
    let mut node = TwinNode::new(twin.clone(), "/mrtwin_twin").context("start the twin node")?;
    if let Some(spec) = &args.foxglove {
        crate::foxglove::attach(&mut node, spec, "/mrtwin_twin")?;
    }
    let mut stand_node =
        StandNode::new(stand.clone(), "/mrtwin_stand").context("start the stand node")?;
    let settings = TransportSettings::new(
        &damper,
        "/mrtwin_monitor",
        &stand.ros2,
        &stand.zenoh,
        &twin.iceoryx2,
    );
    let counts: Counts = Arc::new(Default::default());
    let whatif: WhatIf = Arc::new(Default::default());
    let done = Arc::new(AtomicBool::new(false));
    let monitor = spawn_monitor(&settings, counts.clone(), done.clone())?;
    let controller = spawn_controller(settings.iceoryx2_config(), whatif.clone(), done.clone());
    let duration = Duration::from_secs_f64(args.duration);
    let stand_stop = done.clone();
    let stand_thread =
        std::thread::spawn(move || stand_node.run(Some(&stand_stop), Some(duration)));
    let deadline = Instant::now() + duration + Duration::from_millis(300);
    let mut prev = [0u64; 3];
    let summary = node.run(
        StopWhen {
            flag: Some(&stop),
            deadline: Some(deadline),
        },
        &mut |s| {
            let now: Vec<u64> = counts.iter().map(|c| c.load(Ordering::Relaxed)).collect();
            println!(
                "{}  | out/s ros2 {} zenoh {} iceoryx2 {}  what-if {}",
                live_line(s),
                now[0] - prev[0],
                now[1] - prev[1],
                now[2] - prev[2],
                whatif[0].load(Ordering::Relaxed)
            );
            prev = [now[0], now[1], now[2]];
        },
    );
    done.store(true, Ordering::Relaxed);
    let stand_summary = stand_thread
        .join()
        .map_err(|_| anyhow::anyhow!("stand thread panicked"))??;
    std::thread::sleep(Duration::from_millis(200));
    let _ = monitor.join();
    let ctrl = controller
        .join()
        .map_err(|_| anyhow::anyhow!("controller thread panicked"))?;
    println!("\nsummary");
    println!("  stand: {} samples generated, {} messages published on {} transports, max lateness {:.2} ms",
        stand_summary.generated, stand_summary.published, stand.transports.len(), stand_summary.max_lateness_s * 1e3);
    print_twin_summary(args, &node, &summary, &counts, &whatif, ctrl);
    Ok(())
}

/// The twin's part of the summary: stream, outputs per transport, what-ifs, τ0, health.
fn print_twin_summary(
    args: &DemoArgs,
    node: &TwinNode,
    summary: &LiveStats,
    counts: &Counts,
    whatif: &WhatIf,
    controller: Result<()>,
) {
    let c = summary.counters;
    println!(
        "  twin:  {} samples received on {}, {} stepped, {} dropped, {} gaps",
        c.received,
        args.input,
        c.accepted,
        c.non_finite + c.duplicates + c.out_of_order,
        c.gaps
    );
    println!(
        "  outputs received: ros2 {}  zenoh {}  iceoryx2 {}",
        counts[0].load(Ordering::Relaxed),
        counts[1].load(Ordering::Relaxed),
        counts[2].load(Ordering::Relaxed)
    );
    println!(
        "  what-if requests over iceoryx2: {} answered, {} rejected{}",
        whatif[0].load(Ordering::Relaxed),
        whatif[1].load(Ordering::Relaxed),
        match controller {
            Ok(()) => String::new(),
            Err(e) => format!(" (controller: {e:#})"),
        }
    );
    let curve = node.pipeline().curve();
    if curve.is_empty() {
        println!(
            "  yield stress: no estimate yet (needs post-yield strokes both ways at a current)"
        );
    }
    for e in curve {
        println!(
            "  yield stress at {:.2} A: {:.1} ± {:.1} kPa",
            e.current_a,
            e.tau0_pa / 1e3,
            e.tau0_std_pa / 1e3
        );
    }
    for ch in &summary.checks {
        println!(
            "  health {:<24} {:<5} {}",
            ch.name,
            ch.level.name(),
            ch.message
        );
    }
}
