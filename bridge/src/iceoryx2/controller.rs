//! A local controller's request loop over the control service, paced in real time: the
//! body of `examples/iceoryx2_controller.rs`, here as a library so tests can run it in a
//! child process and check its summary.
//!
//! Each cycle sends a measured sample of a sinusoidal stroke
//! x(t) = A sin(2π f t), v(t) = 2π f A cos(2π f t) ([`ShmRequest::SAMPLE`]); every
//! `what_if_every` cycles it also asks what the damper would do at the same state with a
//! planned current ([`ShmRequest::PLANNED_CURRENT`]). Every reply is awaited with a bounded
//! timeout and checked against its request's sequence number.

use std::time::{Duration, Instant};

use msgs::shm::{ShmRequest, ShmSample};

use super::{ControlClient, Iceoryx2Config};
use crate::transport::TransportError;

/// How the controller runs.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerOptions {
    /// Cycle rate \[Hz\] (default 1000).
    pub rate_hz: f64,
    /// Run time \[s\] (default 10): `round(rate × seconds)` samples are sent.
    pub seconds: f64,
    /// Longest wait for one reply (default 200 ms).
    pub reply_timeout: Duration,
    /// Longest wait for the twin to appear before the loop starts (default 5 s).
    pub server_timeout: Duration,
    /// A planned-current what-if after every this many samples (0: never; default 10).
    pub what_if_every: u64,
    /// Stroke amplitude \[m\] (default 10 mm).
    pub amplitude_m: f64,
    /// Stroke frequency \[Hz\] (default 2).
    pub frequency_hz: f64,
    /// Coil current of the samples \[A\] (default 1).
    pub current_a: f64,
    /// Current of the what-ifs \[A\] (default 2).
    pub planned_current_a: f64,
}

impl Default for ControllerOptions {
    fn default() -> Self {
        Self {
            rate_hz: 1000.0,
            seconds: 10.0,
            reply_timeout: Duration::from_millis(200),
            server_timeout: Duration::from_secs(5),
            what_if_every: 10,
            amplitude_m: 0.01,
            frequency_hz: 2.0,
            current_a: 1.0,
            planned_current_a: 2.0,
        }
    }
}

/// What a run did (printed as one JSON line by the example).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ControllerSummary {
    /// Cycle rate \[Hz\].
    pub rate_hz: f64,
    /// Requests sent (samples + what-ifs).
    pub sent: u64,
    /// Measured-sample requests among them.
    pub samples: u64,
    /// Planned-current requests among them.
    pub what_ifs: u64,
    /// Replies received with the right sequence number.
    pub replied: u64,
    /// Requests without a correct reply (`sent − replied`).
    pub lost: u64,
    /// Requests whose reply did not come within the timeout.
    pub timeouts: u64,
    /// Replies carrying another sequence number than their request.
    pub mismatched: u64,
    /// Replies marked rejected by the twin.
    pub rejected: u64,
    /// Cycles that started more than one period late.
    pub overruns: u64,
    /// Whether the loop stopped early because the server went away.
    pub server_gone: bool,
    /// Median round trip \[µs\].
    pub latency_p50_us: f64,
    /// 99th percentile round trip \[µs\].
    pub latency_p99_us: f64,
    /// Longest round trip \[µs\].
    pub latency_max_us: f64,
    /// Wall time of the loop \[s\].
    pub elapsed_s: f64,
}

/// The `q`-quantile (0 ≤ q ≤ 1) of sorted values by nearest rank
/// ([`numerics::stats::quantile`]); NaN when empty.
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    numerics::stats::quantile(sorted, q).unwrap_or(f64::NAN)
}

/// Sleep until `target`, then spin the last stretch (the OS sleep overshoots by
/// ≈ 50–100 µs, so it is only trusted up to 200 µs before the deadline).
pub fn spin_sleep_until(target: Instant) {
    const SPIN: Duration = Duration::from_micros(200);
    loop {
        let now = Instant::now();
        if now >= target {
            return;
        }
        let left = target - now;
        if left > SPIN {
            std::thread::sleep(left - SPIN);
        } else {
            std::hint::spin_loop();
        }
    }
}

/// The stroke sample at `t` \[s\] into the run, stamped `origin_ns` + t.
fn stroke(opts: &ControllerOptions, seq: u64, origin_ns: i64, t: f64) -> ShmSample {
    let w = 2.0 * std::f64::consts::PI * opts.frequency_hz;
    ShmSample {
        seq,
        time_ns: origin_ns + (t * 1e9).round() as i64,
        displacement_m: opts.amplitude_m * (w * t).sin(),
        velocity_m_s: opts.amplitude_m * w * (w * t).cos(),
        // This controller has no load cell: no measured force, so no residual.
        force_n: f64::NAN,
        current_a: opts.current_a,
        temperature_c: f64::NAN,
    }
}

/// Validate the options (clear message naming the field).
fn check(opts: &ControllerOptions) -> Result<(), TransportError> {
    let bad = |field: &str, why: &str| {
        TransportError::new("iceoryx2", "controller options", format!("`{field}` {why}"))
    };
    if !(opts.rate_hz.is_finite() && opts.rate_hz > 0.0 && opts.rate_hz <= 100_000.0) {
        return Err(bad("rate", "must be in (0, 100000] Hz"));
    }
    if !(opts.seconds.is_finite() && opts.seconds >= 0.0 && opts.seconds <= 86_400.0) {
        return Err(bad("seconds", "must be in [0, 86400]"));
    }
    for (f, v) in [
        ("amplitude", opts.amplitude_m),
        ("frequency", opts.frequency_hz),
        ("current", opts.current_a),
        ("planned current", opts.planned_current_a),
    ] {
        if !v.is_finite() {
            return Err(bad(f, "must be finite"));
        }
    }
    Ok(())
}

/// Connect to the twin's control service and run the paced loop; returns its summary.
pub fn run_controller(
    cfg: &Iceoryx2Config,
    opts: &ControllerOptions,
) -> Result<ControllerSummary, TransportError> {
    check(opts)?;
    let mut client = ControlClient::new(cfg)?;
    client.wait_for_server(opts.server_timeout)?;
    run_with_client(&mut client, opts)
}

/// [`run_controller`] with a client already connected.
pub fn run_with_client(
    client: &mut ControlClient,
    opts: &ControllerOptions,
) -> Result<ControllerSummary, TransportError> {
    check(opts)?;
    let n = (opts.rate_hz * opts.seconds).round() as u64;
    let period = Duration::from_secs_f64(1.0 / opts.rate_hz);
    let mut s = ControllerSummary {
        rate_hz: opts.rate_hz,
        sent: 0,
        samples: 0,
        what_ifs: 0,
        replied: 0,
        lost: 0,
        timeouts: 0,
        mismatched: 0,
        rejected: 0,
        overruns: 0,
        server_gone: false,
        latency_p50_us: f64::NAN,
        latency_p99_us: f64::NAN,
        latency_max_us: f64::NAN,
        elapsed_s: 0.0,
    };
    let mut latencies = Vec::with_capacity(n as usize + n as usize / 4);
    let mut seq = 0u64;
    // Samples are stamped with wall-clock time (as a real controller's would be), so a
    // restarted controller continues the twin's timeline instead of going back.
    let origin_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64);
    let start = Instant::now();
    'cycles: for i in 0..n {
        let target = start + period.mul_f64(i as f64);
        if Instant::now() > target + period {
            s.overruns += 1;
        }
        spin_sleep_until(target);
        let t = i as f64 / opts.rate_hz;
        let mut reqs = vec![ShmRequest {
            kind: ShmRequest::SAMPLE,
            reserved: 0,
            sample: stroke(opts, seq, origin_ns, t),
        }];
        if opts.what_if_every > 0 && (i + 1) % opts.what_if_every == 0 {
            let mut plan = stroke(opts, seq + 1, origin_ns, t);
            plan.current_a = opts.planned_current_a;
            reqs.push(ShmRequest {
                kind: ShmRequest::PLANNED_CURRENT,
                reserved: 0,
                sample: plan,
            });
        }
        for req in &reqs {
            seq += 1;
            s.sent += 1;
            if req.kind == ShmRequest::SAMPLE {
                s.samples += 1;
            } else {
                s.what_ifs += 1;
            }
            let sent_at = Instant::now();
            let reply = match client.request_within(req, opts.reply_timeout) {
                Ok(r) => r,
                Err(_) if !client.server_present() => {
                    // The twin went away mid-run: stop, the rest would fail too.
                    s.server_gone = true;
                    break 'cycles;
                }
                Err(e) => return Err(e),
            };
            match reply {
                Some(reply) => {
                    latencies.push(sent_at.elapsed().as_secs_f64() * 1e6);
                    if reply.seq != req.sample.seq {
                        s.mismatched += 1;
                    } else {
                        s.replied += 1;
                    }
                    if reply.rejected != 0 {
                        s.rejected += 1;
                    }
                }
                None => {
                    s.timeouts += 1;
                    if !client.server_present() {
                        s.server_gone = true;
                        break 'cycles;
                    }
                }
            }
        }
    }
    s.elapsed_s = start.elapsed().as_secs_f64();
    s.lost = s.sent - s.replied;
    latencies.sort_by(f64::total_cmp);
    s.latency_p50_us = quantile(&latencies, 0.5);
    s.latency_p99_us = quantile(&latencies, 0.99);
    s.latency_max_us = latencies.last().copied().unwrap_or(f64::NAN);
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.5), 50.0);
        assert_eq!(quantile(&v, 0.99), 99.0);
        assert_eq!(quantile(&v, 1.0), 100.0);
        assert_eq!(quantile(&v, 0.0), 1.0);
        assert!(quantile(&[], 0.5).is_nan());
    }

    #[test]
    fn bad_options_are_refused_before_connecting() {
        let cfg = Iceoryx2Config::default()
            .with_prefix(format!("mrtwin/test-opts-{}", std::process::id()));
        let opts = ControllerOptions {
            rate_hz: 0.0,
            ..ControllerOptions::default()
        };
        let e = run_controller(&cfg, &opts).unwrap_err();
        assert!(e.to_string().contains("`rate`"), "{e}");
    }
}
