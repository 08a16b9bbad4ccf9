//! The twin node's path, next to the bare transport, on ROS 2 (reliable QoS), zenoh
//! (peer to peer over loopback TCP) and iceoryx2 (publish–subscribe).
//!
//! A source publishes `DamperSample`s at a fixed rate, paced by the OS sleep (as a sensor
//! node driven by its hardware would be, not a spinning thread) and stamped with the wall
//! clock at send. In the twin rows a twin node (the default two-chamber model, estimator
//! and health on, `node::runner`) runs in a thread, steps on every sample and publishes
//! `TwinOutput`; a subscriber in a third endpoint, which sleeps on its transport's
//! doorbell, measures stamp → receive. The twin path is two hops (source → twin →
//! subscriber); the reference row is the bare one-hop source → subscriber path of the
//! same transport in the same run. Each twin path runs twice: the default loop (sleeps
//! until a transport's wake-up) and `low_latency` (polls while samples flow).
//!
//! CPU: `twin cpu` is the twin loop's own thread, `process cpu` every thread of this
//! process (source, subscriber, middleware threads), both in % of one core over the
//! measured stretch. The idle rows open a twin on all three transports with no input for
//! the same stretch and report the same two figures.
//!
//! `cargo bench -p node --bench node_path [-- SECONDS RATE_HZ… [--stress] [--only=KIND]]`
//! (defaults: 2 s at 1, 10 and 20 kHz). `--stress` runs a busy-loop process beside the
//! bench (the other core loaded); `--only=zenoh` (ros2, iceoryx2) runs one transport.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bridge::transport::{Message, Topic};
use node::config::TwinNodeParams;
use node::runner::{StopWhen, TwinNode};
use node::transports::{open, TransportKind, TransportSettings};

fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// The CPU-time clock of another thread of this process.
fn thread_clock<T>(h: &std::thread::JoinHandle<T>) -> libc::clockid_t {
    use std::os::unix::thread::JoinHandleExt;
    let mut id: libc::clockid_t = 0;
    // SAFETY: the thread is alive (joined later), `id` is writable.
    let rc = unsafe { libc::pthread_getcpuclockid(h.as_pthread_t(), &mut id) };
    assert_eq!(rc, 0, "pthread_getcpuclockid");
    id
}

/// CPU seconds of `clock` (`CLOCK_PROCESS_CPUTIME_ID`, or a thread's clock).
fn cpu_s(clock: libc::clockid_t) -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock ids are the POSIX constants.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

struct Row {
    /// Samples the twin received and stepped (twin rows).
    twin_received: Option<u64>,
    twin_stepped: Option<u64>,
    received: u64,
    sent: u64,
    p50_us: f64,
    p99_us: f64,
    p999_us: f64,
    twin_cpu_pct: f64,
    process_cpu_pct: f64,
}

/// Nearest-rank quantile ([`numerics::stats::quantile_unsorted`]); NaN when empty.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    numerics::stats::quantile_unsorted(v, q).unwrap_or(f64::NAN)
}

#[derive(Clone, Copy, PartialEq)]
enum Path {
    Bare,
    Twin { low_latency: bool },
}

struct Case {
    kind: TransportKind,
    case: u16,
}

impl Case {
    fn params(&self, low_latency: bool) -> (TwinNodeParams, TwinNodeParams) {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let mut params = TwinNodeParams {
            damper: format!("bench{}x{}", std::process::id(), self.case),
            transports: vec![self.kind],
            input: self.kind,
            control_service: false,
            low_latency,
            ..Default::default()
        };
        params.zenoh.multicast_scouting = false;
        params.zenoh.listen = vec![format!("tcp/127.0.0.1:{port}")];
        params.ros2.domain_id = 80 + self.case % 20;
        let mut client = params.clone();
        client.zenoh.listen.clear();
        client.zenoh.connect = vec![format!("tcp/127.0.0.1:{port}")];
        (params, client)
    }
}

fn settings(p: &TwinNodeParams, name: &str) -> TransportSettings {
    TransportSettings::new(&p.damper, name, &p.ros2, &p.zenoh, &p.iceoryx2)
}

/// The twin node in a thread until `stop`; returns what it received and stepped.
fn spawn_twin(
    params: TwinNodeParams,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<node::conditioning::StreamCounters> {
    // Created in its own thread (the iceoryx2 control server's ports are single-threaded),
    // and up before the clients start.
    let (up_tx, up_rx) = std::sync::mpsc::sync_channel(1);
    let handle = std::thread::spawn(move || {
        let mut node = TwinNode::new(params, "/bench_twin").expect("twin node");
        up_tx.send(()).expect("bench waits for the twin");
        node.run(
            StopWhen {
                flag: Some(&stop),
                deadline: None,
            },
            &mut |_| {},
        )
        .counters
    });
    up_rx
        .recv_timeout(std::time::Duration::from_secs(30))
        .expect("twin node up within 30 s");
    handle
}

fn run(c: &Case, path: Path, rate: f64, seconds: f64) -> Row {
    let low_latency = matches!(path, Path::Twin { low_latency: true });
    let (params, client) = c.params(low_latency);
    let stop = Arc::new(AtomicBool::new(false));
    // Twin: source and sink are the twin's clients, the sink reads its outputs. Bare: the
    // source takes the twin's place (its settings), the sink reads the samples.
    let (twin, source_params, sink_topic) = match path {
        Path::Twin { .. } => (
            Some(spawn_twin(params.clone(), stop.clone())),
            &client,
            Topic::Output,
        ),
        Path::Bare => (None, &params, Topic::Sample),
    };
    let mut source = open(
        c.kind,
        &settings(source_params, "bench_source"),
        &[Topic::Sample],
        &[],
    )
    .unwrap();
    let mut sink = open(c.kind, &settings(&client, "bench_sink"), &[], &[sink_topic]).unwrap();
    // Discovery / connection.
    std::thread::sleep(Duration::from_secs(3));
    let n = (rate * seconds) as u64;
    let sink_done = Arc::new(AtomicBool::new(false));
    let sink_thread = {
        let done = sink_done.clone();
        std::thread::spawn(move || {
            let bell = sink.doorbell().expect("every adapter rings");
            bell.bind_current_thread();
            let mut lat = Vec::with_capacity(n as usize);
            let mut inbox = Vec::new();
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
                } else if done.load(Ordering::Relaxed) && last.elapsed() > Duration::from_secs(2) {
                    break;
                } else {
                    bridge::wake::wait_until(Instant::now() + Duration::from_millis(50));
                }
            }
            lat
        })
    };
    let twin_clock = twin.as_ref().map(thread_clock);
    let twin_cpu0 = twin_clock.map(cpu_s);
    let process_cpu0 = cpu_s(libc::CLOCK_PROCESS_CPUTIME_ID);
    let start = Instant::now();
    let w = 2.0 * std::f64::consts::PI * 2.0;
    let mut stamp = 0.0_f64;
    for k in 0..n {
        let due = start + Duration::from_secs_f64(k as f64 / rate);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let t = k as f64 / rate;
        // The send time, kept ≥ 1 µs after the previous stamp: after a late wake-up the
        // source sends a few samples back to back, and stamps closer than the f64 epoch
        // seconds resolve (0.24 µs) would reach the twin as duplicates and be dropped.
        stamp = now_s().max(stamp + 1e-6);
        let s = msgs::DamperSample {
            header: msgs::Header::at(stamp, &params.damper),
            displacement: 0.01 * (w * t).sin(),
            velocity: 0.01 * w * (w * t).cos(),
            force: 500.0 * (w * t).cos(),
            current: 1.0,
            temperature: f64::NAN,
        };
        let _ = source.publish(&Message::Sample(s));
    }
    let wall = start.elapsed().as_secs_f64();
    let process_cpu = cpu_s(libc::CLOCK_PROCESS_CPUTIME_ID) - process_cpu0;
    let twin_cpu = twin_clock.zip(twin_cpu0).map(|(c, c0)| cpu_s(c) - c0);
    sink_done.store(true, Ordering::Relaxed);
    let mut lat = sink_thread.join().unwrap();
    stop.store(true, Ordering::Relaxed);
    let twin_counters = twin.map(|t| t.join().unwrap());
    Row {
        twin_received: twin_counters.map(|c| c.received),
        twin_stepped: twin_counters.map(|c| c.accepted),
        received: lat.len() as u64,
        sent: n,
        p50_us: quantile(&mut lat, 0.5),
        p99_us: quantile(&mut lat, 0.99),
        p999_us: quantile(&mut lat, 0.999),
        twin_cpu_pct: twin_cpu.map_or(f64::NAN, |c| 100.0 * c / wall),
        process_cpu_pct: 100.0 * process_cpu / wall,
    }
}

/// A twin on all three transports (as `mrtwin node` by default) with nothing arriving.
fn idle(case: u16, low_latency: bool, seconds: f64) -> (f64, f64) {
    let (mut params, _) = Case {
        kind: TransportKind::Zenoh,
        case,
    }
    .params(low_latency);
    params.transports = vec![
        TransportKind::Ros2,
        TransportKind::Zenoh,
        TransportKind::Iceoryx2,
    ];
    params.control_service = true;
    let stop = Arc::new(AtomicBool::new(false));
    let twin = spawn_twin(params, stop.clone());
    std::thread::sleep(Duration::from_secs(2));
    let clock = thread_clock(&twin);
    let (c0, p0) = (cpu_s(clock), cpu_s(libc::CLOCK_PROCESS_CPUTIME_ID));
    let t0 = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let (c, p) = (
        cpu_s(clock) - c0,
        cpu_s(libc::CLOCK_PROCESS_CPUTIME_ID) - p0,
    );
    let wall = t0.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    let _ = twin.join().unwrap();
    (100.0 * c / wall, 100.0 * p / wall)
}

fn main() {
    bridge::iceoryx2::quiet_logs();
    let raw: Vec<String> = std::env::args().skip(1).collect();
    let stress = raw.iter().any(|a| a == "--stress");
    // `--only=zenoh` (or ros2, iceoryx2): one transport's rows.
    let only: Option<TransportKind> = raw
        .iter()
        .find_map(|a| a.strip_prefix("--only="))
        .map(|k| k.parse().expect("--only=ros2|zenoh|iceoryx2"));
    let args: Vec<&String> = raw.iter().filter(|a| !a.starts_with("--")).collect();
    let seconds: f64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(2.0);
    let rates: Vec<f64> = if args.len() > 1 {
        args[1..].iter().filter_map(|s| s.parse().ok()).collect()
    } else {
        vec![1_000.0, 10_000.0, 20_000.0]
    };
    let mut busy = stress.then(|| {
        std::process::Command::new("sh")
            .args(["-c", "while :; do :; done"])
            .spawn()
            .expect("start the busy-loop process")
    });
    println!(
        "other core {}",
        if stress {
            "loaded (a busy-loop process)"
        } else {
            "idle"
        }
    );
    println!(
        "| transport | path | rate (samples/s) | sent | twin received / stepped | received | lost | p50 (µs) | p99 (µs) | p99.9 (µs) | twin cpu (%) | process cpu (%) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut case = 0;
    for kind in [
        TransportKind::Ros2,
        TransportKind::Zenoh,
        TransportKind::Iceoryx2,
    ] {
        if only.is_some_and(|o| o != kind) {
            continue;
        }
        for &rate in &rates {
            for path in [
                Path::Bare,
                Path::Twin { low_latency: false },
                Path::Twin { low_latency: true },
            ] {
                case += 1;
                let r = run(&Case { kind, case }, path, rate, seconds);
                println!(
                    "| {} | {} | {:.0} | {} | {} | {} | {} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} |",
                    kind,
                    match path {
                        Path::Bare => "sample → subscriber (reference)",
                        Path::Twin { low_latency: false } => "sample → twin → output",
                        Path::Twin { low_latency: true } => "… with low_latency",
                    },
                    rate,
                    r.sent,
                    r.twin_received
                        .zip(r.twin_stepped)
                        .map_or("—".to_string(), |(a, b)| format!("{a} / {b}")),
                    r.received,
                    r.sent.saturating_sub(r.received),
                    r.p50_us,
                    r.p99_us,
                    r.p999_us,
                    r.twin_cpu_pct,
                    r.process_cpu_pct,
                );
            }
        }
    }
    for low_latency in [false, true] {
        case += 1;
        let (twin, process) = idle(case, low_latency, seconds.max(5.0));
        println!(
            "| all three | idle{} | 0 | | | | | | | | {twin:.2} | {process:.2} |",
            if low_latency { ", low_latency" } else { "" }
        );
    }
    if let Some(b) = busy.as_mut() {
        let _ = b.kill();
        let _ = b.wait();
    }
}
