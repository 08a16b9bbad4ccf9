//! Sensor samples through the ROS 2 adapter (DDS, reliable QoS, keep last 1000) between two
//! [`Ros2Transport`]s in one process, next to the same traffic over a `std::sync::mpsc`
//! channel (the floor of this measurement: same messages, same polling receiver thread).
//!
//! Two loads per case:
//! * `max`: the publisher sends N `DamperSample`s as fast as `publish` returns;
//! * `10 kHz`: paced at 100 µs per sample for S seconds (the twin's highest sensor rate).
//!
//! Each sample's header stamp is the wall clock at publish; the receiver thread polls
//! (sleeping 50 µs when nothing is pending, as a node loop would) and records
//! receive − stamp. "offered" is the rate at which `publish` accepted samples, "rate" the
//! rate at which they arrived (first publish to last receive). Losses = sent − received
//! after a drain of up to 3 s. Run:
//!
//! ```text
//! cargo bench -p bridge --features ros2 --bench ros2_throughput [-- N SECONDS]
//! ```
//! (default N = 50 000, SECONDS = 3). Uses ROS_DOMAIN_ID 78 (the test range 40–79).

use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bridge::ros2::{QosOverride, Reliability, Ros2Config, Ros2Transport};
use bridge::transport::{Message, Topic, Transport};
use msgs::{DamperSample, Header, Time};

const DOMAIN: u16 = 78;

fn now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .expect("clock after 1970")
        .as_nanos() as i64
}

fn sample(k: u64) -> DamperSample {
    let t = k as f64 * 1e-4;
    let w = 2.0 * std::f64::consts::PI * 2.0;
    DamperSample {
        header: Header {
            stamp: Time::from_nanos(now_ns()),
            frame_id: "damper1".into(),
        },
        displacement: 0.01 * (w * t).sin(),
        velocity: 0.01 * w * (w * t).cos(),
        force: 500.0 * (w * t).cos(),
        current: 1.0,
        temperature: f64::NAN,
    }
}

/// The two ends of a case, behind one interface.
trait Sender {
    fn send(&mut self, s: DamperSample) -> bool;
}
trait Receiver: Send {
    fn recv_all(&mut self, out: &mut Vec<DamperSample>);
}

impl Sender for Ros2Transport {
    fn send(&mut self, s: DamperSample) -> bool {
        self.publish(&Message::Sample(s)).is_ok()
    }
}
impl Receiver for Ros2Transport {
    fn recv_all(&mut self, out: &mut Vec<DamperSample>) {
        let mut msgs = Vec::new();
        self.poll(&mut msgs).expect("poll");
        out.extend(msgs.into_iter().filter_map(|m| match m {
            Message::Sample(s) => Some(s),
            _ => None,
        }));
    }
}
impl Sender for mpsc::Sender<DamperSample> {
    fn send(&mut self, s: DamperSample) -> bool {
        mpsc::Sender::send(self, s).is_ok()
    }
}
struct MpscRx(mpsc::Receiver<DamperSample>);
impl Receiver for MpscRx {
    fn recv_all(&mut self, out: &mut Vec<DamperSample>) {
        out.extend(self.0.try_iter());
    }
}

struct Run {
    sent: u64,
    send_seconds: f64,
    send_errors: u64,
    received: u64,
    seconds: f64,
    latencies_us: Vec<f64>,
}

/// Send `n` samples (paced every `period` if given) and collect them on a receiver thread.
fn run<R: Receiver + 'static>(
    tx: &mut dyn Sender,
    mut rx: R,
    n: u64,
    period: Option<Duration>,
) -> (Run, R) {
    let (done_tx, done_rx) = mpsc::channel::<u64>();
    let receiver = std::thread::spawn(move || {
        let mut lat = Vec::with_capacity(n as usize);
        let mut buf = Vec::new();
        let mut expected: Option<u64> = None;
        let mut last_progress = Instant::now();
        let mut received = 0u64;
        let mut last_rx = Instant::now();
        loop {
            buf.clear();
            rx.recv_all(&mut buf);
            let t = now_ns();
            if !buf.is_empty() {
                last_progress = Instant::now();
                last_rx = last_progress;
                received += buf.len() as u64;
                lat.extend(
                    buf.iter()
                        .map(|s| (t - s.header.stamp.as_nanos()) as f64 / 1e3),
                );
            } else {
                std::thread::sleep(Duration::from_micros(50));
            }
            if expected.is_none() {
                expected = done_rx.try_recv().ok();
            }
            if let Some(e) = expected {
                if received >= e || last_progress.elapsed() > Duration::from_secs(3) {
                    return (received, lat, last_rx, rx);
                }
            }
        }
    });
    let start = Instant::now();
    let mut send_errors = 0;
    for k in 0..n {
        if let Some(p) = period {
            let target = start + p * k as u32;
            loop {
                let now = Instant::now();
                if now >= target {
                    break;
                }
                let left = target - now;
                if left > Duration::from_micros(120) {
                    std::thread::sleep(left - Duration::from_micros(80));
                } else {
                    std::thread::yield_now();
                }
            }
        }
        if !tx.send(sample(k)) {
            send_errors += 1;
        }
    }
    let send_seconds = start.elapsed().as_secs_f64();
    done_tx.send(n - send_errors).unwrap();
    let (received, latencies_us, last_rx, rx) = receiver.join().unwrap();
    (
        Run {
            sent: n,
            send_seconds,
            send_errors,
            received,
            seconds: (last_rx - start).as_secs_f64(),
            latencies_us,
        },
        rx,
    )
}

/// Nearest-rank quantile of sorted values ([`numerics::stats::quantile`]); NaN when empty.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    numerics::stats::quantile(sorted, q).unwrap_or(f64::NAN)
}

fn row(case: &str, load: &str, r: &mut Run) {
    r.latencies_us.sort_by(|a, b| a.total_cmp(b));
    let l = &r.latencies_us;
    println!(
        "| {case:<19} | {load:<7} | {:>7} | {:>13.0} | {:>6} | {:>8} | {:>6} | {:>10.0} | {:>8.1} | {:>8.1} | {:>9.1} |",
        r.sent,
        r.sent as f64 / r.send_seconds,
        r.send_errors,
        r.received,
        r.sent - r.send_errors - r.received.min(r.sent - r.send_errors),
        r.received as f64 / r.seconds,
        quantile(l, 0.5),
        quantile(l, 0.99),
        l.last().copied().unwrap_or(f64::NAN),
    );
}

fn main() {
    // `cargo bench` passes `--bench`; take the first two numeric arguments.
    let nums: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let n = nums.first().copied().unwrap_or(50_000.0) as u64;
    let secs = nums.get(1).copied().unwrap_or(3.0);
    let period = Duration::from_micros(100);
    let paced_n = (secs / period.as_secs_f64()).round() as u64;

    let mut cfg = Ros2Config {
        domain_id: DOMAIN,
        namespace: "/bench".parse().expect("namespace"),
        ..Default::default()
    };
    cfg.qos.insert(
        Topic::Sample,
        QosOverride {
            reliability: Some(Reliability::Reliable),
            depth: Some(1000),
        },
    );
    let mut pub_cfg = cfg.clone();
    pub_cfg.node_name = "bench_pub".into();
    let mut sub_cfg = cfg;
    sub_cfg.node_name = "bench_sub".into();
    let mut tx = Ros2Transport::new(&pub_cfg, &[Topic::Sample], &[]).expect("publisher");
    let rx = Ros2Transport::new(&sub_cfg, &[], &[Topic::Sample]).expect("subscriber");
    let t0 = Instant::now();
    while tx.matched_subscriptions(Topic::Sample) == 0 || rx.matched_publishers(Topic::Sample) == 0
    {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the two adapters did not match within 20 s"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    println!(
        "matched after {:.2} s; N = {n} (max rate), {paced_n} at 10 kHz; DamperSample {} bytes CDR\n",
        t0.elapsed().as_secs_f64(),
        msgs::cdr::encode(&sample(0)).len()
    );
    println!("| case                | load    |    sent | offered [1/s] | errors | received |   lost | rate [1/s] | p50 [µs] | p99 [µs] |  max [µs] |");
    println!("|---------------------|---------|---------|---------------|--------|----------|--------|------------|----------|----------|-----------|");

    // Warm-up (not reported).
    let (_, rx) = run(&mut tx, rx, 2000, None);

    let (mut r, rx) = run(&mut tx, rx, paced_n, Some(period));
    row("ros2 (DDS reliable)", "10 kHz", &mut r);
    let (mut r, rx) = run(&mut tx, rx, n, None);
    row("ros2 (DDS reliable)", "max", &mut r);
    drop(rx);
    tx.shutdown();

    let (mut mtx, mrx) = mpsc::channel();
    let (mut r, mrx) = run(&mut mtx, MpscRx(mrx), paced_n, Some(period));
    row("std mpsc (ref.)", "10 kHz", &mut r);
    let (mut r, _) = run(&mut mtx, mrx, n, None);
    row("std mpsc (ref.)", "max", &mut r);
}
