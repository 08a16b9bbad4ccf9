//! The twin node's network path: samples published at a fixed rate on ROS 2 (reliable
//! QoS) or zenoh, stepped by a twin node (two-chamber model, estimator and health on)
//! running in a thread, outputs received by a subscriber. Reports what arrived (loss) and
//! the stamp-to-receive latency p50/p99 (the sample stamp is the wall-clock send time, so
//! this bounds stamp-to-publish from above). Reference in the same run: the same
//! publisher → subscriber path on the same transport without the twin.
//!
//! `cargo bench -p node --bench node_path [-- SECONDS RATE_HZ…]` (defaults: 3 s at 10 and
//! 20 kHz).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bridge::transport::{Message, Topic, Transport};
use node::config::TwinNodeParams;
use node::runner::{StopWhen, TwinNode};
use node::transports::{open, TransportKind, TransportSettings};

fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

struct Row {
    received: u64,
    sent: u64,
    p50_us: f64,
    p99_us: f64,
}

/// Nearest-rank quantile ([`numerics::stats::quantile_unsorted`]); NaN when empty.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    numerics::stats::quantile_unsorted(v, q).unwrap_or(f64::NAN)
}

fn run(kind: TransportKind, with_twin: bool, rate: f64, seconds: f64, case: u16) -> Row {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let damper = format!("bench{}x{case}", std::process::id());
    let mut params = TwinNodeParams {
        damper: damper.clone(),
        transports: vec![kind],
        input: kind,
        control_service: false,
        ..Default::default()
    };
    params.zenoh.multicast_scouting = false;
    params.zenoh.listen = vec![format!("tcp/127.0.0.1:{port}")];
    params.ros2.domain_id = 80 + case % 20;
    let mut client_params = params.clone();
    client_params.zenoh.listen.clear();
    client_params.zenoh.connect = vec![format!("tcp/127.0.0.1:{port}")];
    let settings = |p: &TwinNodeParams, name: &str| {
        TransportSettings::new(&damper, name, &p.ros2, &p.zenoh, &p.iceoryx2)
    };
    let stop = Arc::new(AtomicBool::new(false));
    let (twin_thread, mut source, sink_topic, mut sink): (
        _,
        Box<dyn Transport>,
        Topic,
        Box<dyn Transport>,
    ) = if with_twin {
        let mut node = TwinNode::new(params.clone(), "/bench_twin").expect("twin node");
        let stop2 = stop.clone();
        let t = std::thread::spawn(move || {
            node.run(
                StopWhen {
                    flag: Some(&stop2),
                    deadline: None,
                },
                &mut |_| {},
            );
        });
        let src = open(
            kind,
            &settings(&client_params, "bench_source"),
            &[Topic::Sample],
            &[],
        )
        .unwrap();
        let sink = open(
            kind,
            &settings(&client_params, "bench_sink"),
            &[],
            &[Topic::Output],
        )
        .unwrap();
        (Some(t), src, Topic::Output, sink)
    } else {
        let src = open(
            kind,
            &settings(&params, "bench_source"),
            &[Topic::Sample],
            &[],
        )
        .unwrap();
        let sink = open(
            kind,
            &settings(&client_params, "bench_sink"),
            &[],
            &[Topic::Sample],
        )
        .unwrap();
        (None, src, Topic::Sample, sink)
    };
    // Discovery / connection.
    std::thread::sleep(Duration::from_secs(3));
    let n = (rate * seconds) as u64;
    let sink_done = Arc::new(AtomicBool::new(false));
    let sink_thread = {
        let done = sink_done.clone();
        std::thread::spawn(move || {
            let mut lat = Vec::with_capacity(n as usize);
            let mut inbox = Vec::new();
            let idle_deadline = Duration::from_secs(2);
            let mut last = Instant::now();
            loop {
                inbox.clear();
                let _ = sink.poll(&mut inbox);
                let t = now_s();
                for m in &inbox {
                    let stamp = match (m, sink_topic) {
                        (Message::Output(o), Topic::Output) => o.header.stamp.as_secs_f64(),
                        (Message::Sample(s), Topic::Sample) => s.header.stamp.as_secs_f64(),
                        _ => continue,
                    };
                    lat.push((t - stamp) * 1e6);
                }
                if !inbox.is_empty() {
                    last = Instant::now();
                } else if done.load(Ordering::Relaxed) && last.elapsed() > idle_deadline {
                    break;
                } else {
                    std::thread::yield_now();
                }
            }
            lat
        })
    };
    let start = Instant::now();
    let w = 2.0 * std::f64::consts::PI * 2.0;
    for k in 0..n {
        let due = start + Duration::from_secs_f64(k as f64 / rate);
        while Instant::now() < due {
            std::hint::spin_loop();
        }
        let t = k as f64 / rate;
        let s = msgs::DamperSample {
            header: msgs::Header::at(now_s(), &damper),
            displacement: 0.01 * (w * t).sin(),
            velocity: 0.01 * w * (w * t).cos(),
            force: 500.0 * (w * t).cos(),
            current: 1.0,
            temperature: f64::NAN,
        };
        let _ = source.publish(&Message::Sample(s));
    }
    sink_done.store(true, Ordering::Relaxed);
    let mut lat = sink_thread.join().unwrap();
    stop.store(true, Ordering::Relaxed);
    if let Some(t) = twin_thread {
        t.join().unwrap();
    }
    Row {
        received: lat.len() as u64,
        sent: n,
        p50_us: quantile(&mut lat, 0.5),
        p99_us: quantile(&mut lat, 0.99),
    }
}

fn main() {
    bridge::iceoryx2::quiet_logs();
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let seconds: f64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(3.0);
    let rates: Vec<f64> = if args.len() > 1 {
        args[1..].iter().filter_map(|s| s.parse().ok()).collect()
    } else {
        vec![10_000.0, 20_000.0]
    };
    println!(
        "| transport | path | rate (samples/s) | sent | received | lost | p50 (µs) | p99 (µs) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut case = 0;
    for kind in [TransportKind::Zenoh, TransportKind::Ros2] {
        for &rate in &rates {
            for with_twin in [false, true] {
                case += 1;
                let r = run(kind, with_twin, rate, seconds, case);
                println!(
                    "| {} | {} | {:.0} | {} | {} | {} | {:.0} | {:.0} |",
                    kind,
                    if with_twin {
                        "sample → twin → output"
                    } else {
                        "sample → subscriber (reference)"
                    },
                    rate,
                    r.sent,
                    r.received,
                    r.sent.saturating_sub(r.received),
                    r.p50_us,
                    r.p99_us
                );
            }
        }
    }
}
