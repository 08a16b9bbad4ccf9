//! A local controller on the mrtwin twin node's iceoryx2 control service
//! (`<service>/twin/control`, request–response over shared memory).
//!
//! Every cycle, at a fixed rate, it sends the measured sample of a 10 mm, 2 Hz stroke (the
//! twin steps its model on it) and then asks what the force would be one cycle later with
//! a planned current (a what-if on a copy of the twin's state; the twin does not advance).
//! It prints both forces, the twin's health and the round-trip latency. Run the twin with
//! `input: iceoryx2` first (see README.md).

use std::f64::consts::PI;
use std::process::ExitCode;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bridge::iceoryx2::controller::{quantile, spin_sleep_until};
use bridge::iceoryx2::{quiet_logs, ControlClient, Iceoryx2Config};
use clap::Parser;
use msgs::shm::{ShmRequest, ShmSample};

/// Send stroke samples and planned-current what-ifs to the twin over iceoryx2.
#[derive(Parser)]
struct Args {
    /// Service prefix of the twin (`mrtwin/<damper>`).
    #[arg(long, default_value = "mrtwin/rig1")]
    service: String,
    /// Cycles per second (one sample and one what-if each).
    #[arg(long, default_value_t = 100.0)]
    rate: f64,
    /// Run time [s].
    #[arg(long, default_value_t = 5.0)]
    seconds: f64,
    /// Coil current of the measured samples [A].
    #[arg(long, default_value_t = 1.0)]
    current: f64,
    /// Current of the what-if [A].
    #[arg(long, default_value_t = 2.0)]
    planned_current: f64,
    /// Print every this many cycles.
    #[arg(long, default_value_t = 15)]
    print_every: u64,
}

const HEALTH: [&str; 4] = ["OK", "WARN", "ERROR", "STALE"];

fn main() -> Result<ExitCode, Box<dyn std::error::Error>> {
    let args = Args::parse();
    if !(args.rate > 0.0 && args.seconds >= 0.0 && args.print_every > 0) {
        return Err("--rate and --print-every must be positive, --seconds not negative".into());
    }
    quiet_logs();
    let cfg = Iceoryx2Config::default().with_prefix(&args.service);
    let mut client = ControlClient::new(&cfg)?;
    client.wait_for_server(Duration::from_secs(10))?;
    println!("connected to {}", cfg.control_service());

    // Samples carry wall-clock stamps, as a real controller's would. No load cell here:
    // no measured force (so no residual), no temperature.
    let origin_ns = SystemTime::now().duration_since(UNIX_EPOCH)?.as_nanos() as i64;
    let w = 2.0 * PI * 2.0;
    let stroke = |t: f64, current_a: f64| ShmSample {
        time_ns: origin_ns + (t * 1e9).round() as i64,
        displacement_m: 0.01 * (w * t).sin(),
        velocity_m_s: 0.01 * w * (w * t).cos(),
        force_n: f64::NAN,
        current_a,
        temperature_c: f64::NAN,
        seq: 0,
    };
    let period = Duration::from_secs_f64(1.0 / args.rate);
    let (mut seq, mut lost, mut latencies_us) = (0u64, 0u64, Vec::new());
    let start = Instant::now();
    for i in 0..(args.rate * args.seconds).round() as u64 {
        spin_sleep_until(start + period.mul_f64(i as f64));
        let t = i as f64 / args.rate;
        let requests = [
            (ShmRequest::SAMPLE, stroke(t, args.current)),
            (
                ShmRequest::PLANNED_CURRENT,
                stroke(t + 1.0 / args.rate, args.planned_current),
            ),
        ];
        let (mut forces, mut health) = ([f64::NAN; 2], 0);
        for (k, (kind, sample)) in requests.into_iter().enumerate() {
            seq += 1;
            let request = ShmRequest {
                kind,
                reserved: 0,
                sample: ShmSample { seq, ..sample },
            };
            let sent = Instant::now();
            match client.request_within(&request, Duration::from_millis(200))? {
                Some(reply) if reply.seq == seq && reply.rejected == 0 => {
                    latencies_us.push(sent.elapsed().as_secs_f64() * 1e6);
                    forces[k] = reply.predicted_force_n;
                    health = reply.health_level;
                }
                _ => lost += 1, // timed out, rejected or not ours
            }
        }
        if i % args.print_every == 0 {
            println!(
                "t={t:6.3} s  x={:+6.2} mm  force {:+8.1} N at {:.2} A, next step at {:.2} A {:+8.1} N  health {}  latency {:.1} µs",
                requests[0].1.displacement_m * 1e3,
                forces[0],
                args.current,
                args.planned_current,
                forces[1],
                HEALTH.get(usize::from(health)).unwrap_or(&"?"),
                latencies_us.last().copied().unwrap_or(f64::NAN),
            );
        }
    }
    latencies_us.sort_by(f64::total_cmp);
    println!(
        "summary: sent {seq} replied {} lost {lost} latency p50 {:.1} µs p99 {:.1} µs max {:.1} µs",
        latencies_us.len(),
        quantile(&latencies_us, 0.5),
        quantile(&latencies_us, 0.99),
        latencies_us.last().copied().unwrap_or(f64::NAN),
    );
    Ok(if lost == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
