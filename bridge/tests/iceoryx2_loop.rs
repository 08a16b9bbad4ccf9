//! The iceoryx2 local loop across processes: a controller process against the twin's
//! control service, samples over publish–subscribe, and a crashed client replaced by a
//! new one. The child processes are this test binary itself, re-executed with
//! `MRTWIN_ICE_CHILD` set, which makes `child_process_entry` run the child's part.
//! Every test has its own service prefix (process id + test name), so they run in parallel.

#![cfg(feature = "iceoryx2")]

#[path = "support/twin_handler.rs"]
mod twin_handler;

use std::io::Read;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use bridge::iceoryx2::controller::{run_with_client, ControllerOptions, ControllerSummary};
use bridge::iceoryx2::{Backoff, ControlClient, ControlServer, Iceoryx2Config, Iceoryx2Transport};
use bridge::transport::{Message, Topic, Transport};
use msgs::shm::{ShmPrediction, ShmRequest, ShmSample};
use msgs::{DamperSample, Header, Time, TwinOutput, YieldEstimate};
use twin_handler::TwinHandler;

const CHILD_ENV: &str = "MRTWIN_ICE_CHILD";
const CONFIG_ENV: &str = "MRTWIN_ICE_CONFIG";
const CYCLES_ENV: &str = "MRTWIN_ICE_CYCLES";
const RESULT_TAG: &str = "CHILD-RESULT ";

fn config(test: &str) -> Iceoryx2Config {
    Iceoryx2Config::default().with_prefix(format!("mrtwin/test-{}-{test}", std::process::id()))
}

/// What the server thread saw.
#[derive(Debug, Default)]
struct ServerReport {
    answered: u64,
    undelivered: u64,
    steps: u64,
    what_ifs: u64,
    /// ∑ F v over the sample requests (∝ the energy the damper dissipated).
    power_sum: f64,
    non_finite_forces: u64,
}

struct ServerThread {
    stop: Arc<AtomicBool>,
    handle: JoinHandle<Result<ServerReport, String>>,
}

impl ServerThread {
    /// A control server with a real twin model, polled with a backoff, in a thread.
    fn start(cfg: &Iceoryx2Config) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        // Created in its serving thread (single-threaded ports); started before return.
        let (created_tx, created_rx) = std::sync::mpsc::sync_channel(1);
        let cfg = cfg.clone();
        let handle = std::thread::spawn(move || {
            let mut server = ControlServer::new(&cfg).expect("control server");
            created_tx.send(()).expect("test waits for the server");
            let mut twin = TwinHandler::paper();
            let mut report = ServerReport::default();
            let mut backoff = Backoff::new(Duration::from_micros(200), Duration::from_micros(50));
            while !flag.load(Ordering::Relaxed) {
                let n = server
                    .serve_pending(&mut |req: &ShmRequest| {
                        let reply = twin.handle(req);
                        if !reply.predicted_force_n.is_finite() {
                            report.non_finite_forces += 1;
                        } else if req.kind == ShmRequest::SAMPLE {
                            report.power_sum += reply.predicted_force_n * req.sample.velocity_m_s;
                        }
                        reply
                    })
                    .map_err(|e| e.to_string())?;
                if n > 0 {
                    backoff.activity();
                } else {
                    backoff.idle();
                }
            }
            report.answered = server.answered();
            report.undelivered = server.undelivered();
            report.steps = twin.steps;
            report.what_ifs = twin.what_ifs;
            Ok(report)
        });
        created_rx
            .recv_timeout(Duration::from_secs(10))
            .expect("control server created within 10 s");
        Self { stop, handle }
    }

    fn finish(self) -> ServerReport {
        self.stop.store(true, Ordering::Relaxed);
        self.handle
            .join()
            .expect("server thread panicked")
            .expect("server failed")
    }
}

/// Re-execute this test binary as a child in `mode`.
fn spawn_child(mode: &str, cfg: &Iceoryx2Config, cycles: u64) -> Child {
    Command::new(std::env::current_exe().expect("test binary path"))
        .args([
            "--exact",
            "child_process_entry",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_ENV, mode)
        .env(CONFIG_ENV, serde_json::to_string(cfg).unwrap())
        .env(CYCLES_ENV, cycles.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn child")
}

/// Wait at most `timeout` for the child (killed after), and return its result line.
fn child_result(mut child: Child, timeout: Duration) -> String {
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out_t = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let err_t = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let deadline = Instant::now() + timeout;
    let status = loop {
        if let Some(st) = child.try_wait().expect("wait child") {
            break Some(st);
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let stdout = out_t.join().unwrap();
    let stderr = err_t.join().unwrap();
    let status = status.unwrap_or_else(|| {
        panic!("child did not finish within {timeout:?}\nstdout:\n{stdout}\nstderr:\n{stderr}")
    });
    assert!(
        status.success(),
        "child failed: {status}\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
    stdout
        .lines()
        .find_map(|l| {
            l.find(RESULT_TAG)
                .map(|i| l[i + RESULT_TAG.len()..].to_string())
        })
        .unwrap_or_else(|| panic!("no result line\nstdout:\n{stdout}\nstderr:\n{stderr}"))
}

/// The child's part when `MRTWIN_ICE_CHILD` is set; without it, nothing to do (this entry
/// only exists to be re-executed by the tests below).
#[test]
fn child_process_entry() {
    let Ok(mode) = std::env::var(CHILD_ENV) else {
        return;
    };
    let cfg: Iceoryx2Config = serde_json::from_str(&std::env::var(CONFIG_ENV).unwrap()).unwrap();
    let cycles: u64 = std::env::var(CYCLES_ENV).unwrap().parse().unwrap();
    let result = match mode.as_str() {
        // Controller at 1 kHz for `cycles` samples; a "crash" leaves without dropping
        // its client, as a killed process would.
        "controller" | "crash-controller" => {
            let mut client = ControlClient::new(&cfg).expect("client");
            client
                .wait_for_server(Duration::from_secs(10))
                .expect("server");
            let opts = ControllerOptions {
                seconds: cycles as f64 / 1000.0,
                reply_timeout: Duration::from_millis(500),
                ..ControllerOptions::default()
            };
            let summary = run_with_client(&mut client, &opts).expect("controller loop");
            let line = serde_json::to_string(&summary).unwrap();
            if mode == "crash-controller" {
                println!("{RESULT_TAG}{line}");
                std::mem::forget(client);
                std::process::exit(0);
            }
            line
        }
        // Publish `cycles` samples at 1 kHz, then wait for the parent's acknowledgement
        // (a prediction whose force is the number of samples it received).
        "publisher" => {
            let mut t = Iceoryx2Transport::new(&cfg, &[Topic::Sample], &[Topic::Output])
                .expect("transport");
            let deadline = Instant::now() + Duration::from_secs(10);
            while t.subscriber_count(Topic::Sample) == 0 && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(1));
            }
            let start = Instant::now();
            for i in 0..cycles {
                bridge::iceoryx2::controller::spin_sleep_until(
                    start + Duration::from_micros(1000 * i),
                );
                t.publish(&Message::Sample(stroke_sample(i)))
                    .expect("publish");
            }
            let mut ack = f64::NAN;
            let deadline = Instant::now() + Duration::from_secs(10);
            let mut got = Vec::new();
            while ack.is_nan() && Instant::now() < deadline {
                t.poll(&mut got).expect("poll");
                if let Some(Message::Output(o)) = got.last() {
                    ack = o.predicted_force;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            format!(
                "{{\"sent\":{cycles},\"ack\":{}}}",
                if ack.is_nan() { -1.0 } else { ack }
            )
        }
        other => panic!("unknown child mode {other}"),
    };
    println!("{RESULT_TAG}{result}");
}

/// Sample `i` of a 2 Hz, 10 mm stroke at 1 kHz.
fn stroke_sample(i: u64) -> DamperSample {
    let t = i as f64 * 1e-3;
    let w = 2.0 * std::f64::consts::PI * 2.0;
    DamperSample {
        header: Header {
            stamp: Time::from_nanos(i as i64 * 1_000_000),
            frame_id: "damper".into(),
        },
        displacement: 0.01 * (w * t).sin(),
        velocity: 0.01 * w * (w * t).cos(),
        force: i as f64,
        current: 1.0,
        temperature: f64::NAN,
    }
}

/// The issue's requirement: a separate iceoryx2 controller process runs the
/// request–response loop at 1 kHz for 10 s with no lost replies.
#[test]
fn controller_process_runs_1khz_for_10s_without_losing_a_reply() {
    let cfg = config("loop10s");
    let server = ServerThread::start(&cfg);
    let child = spawn_child("controller", &cfg, 10_000);
    let line = child_result(child, Duration::from_secs(60));
    let report = server.finish();
    let s: ControllerSummary = serde_json::from_str(&line).expect(&line);
    eprintln!("controller: {line}\nserver: {report:?}");

    assert_eq!(s.samples, 10_000, "{line}");
    assert_eq!(s.what_ifs, 1_000, "{line}");
    assert_eq!(s.sent, 11_000, "{line}");
    assert_eq!(s.lost, 0, "{line}");
    assert_eq!(s.timeouts, 0, "{line}");
    assert_eq!(s.mismatched, 0, "{line}");
    assert_eq!(s.rejected, 0, "{line}");
    assert!(!s.server_gone);
    assert_eq!(s.replied, 11_000);
    // The twin saw every request once: 10 000 steps, 1 000 what-ifs that did not step it.
    assert_eq!(report.steps, 10_000, "{report:?}");
    assert_eq!(report.what_ifs, 1_000, "{report:?}");
    assert_eq!(report.answered, 11_000, "{report:?}");
    assert_eq!(report.undelivered, 0);
    assert_eq!(report.non_finite_forces, 0);
    // A damper dissipates: the mean of F·v over whole strokes is positive.
    assert!(report.power_sum > 0.0, "{report:?}");
    assert!(s.latency_max_us >= s.latency_p99_us && s.latency_p99_us >= s.latency_p50_us);
}

/// Samples published by another process at 1 kHz for 1 s arrive complete and in order;
/// the acknowledgement travels back on the prediction service.
#[test]
fn samples_cross_processes_in_order_without_loss() {
    let cfg = config("pubsub");
    let mut twin = Iceoryx2Transport::new(&cfg, &[Topic::Output], &[Topic::Sample]).unwrap();
    let child = spawn_child("publisher", &cfg, 1000);
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while got.len() < 1000 && Instant::now() < deadline {
        twin.poll(&mut got).unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    let samples: Vec<DamperSample> = got
        .iter()
        .map(|m| match m {
            Message::Sample(s) => s.clone(),
            other => panic!("unexpected {other:?}"),
        })
        .collect();
    twin.publish(&Message::Output(TwinOutput {
        predicted_force: samples.len() as f64,
        ..TwinOutput::default()
    }))
    .unwrap();
    let line = child_result(child, Duration::from_secs(30));
    assert_eq!(samples.len(), 1000);
    assert_eq!(twin.missed_samples(), 0);
    for (i, s) in samples.iter().enumerate() {
        // Exactly the sample sent as number i (in order, nothing lost or repeated); the
        // damper name comes from the prefix, the unmeasured temperature stays NaN.
        let sent = stroke_sample(i as u64);
        assert!(s.temperature.is_nan(), "sample {i}");
        let s = DamperSample {
            temperature: sent.temperature,
            ..s.clone()
        };
        let sent = DamperSample {
            header: Header {
                frame_id: cfg.damper_name().into(),
                ..sent.header.clone()
            },
            ..sent.clone()
        };
        assert_eq!(
            s.header.frame_id,
            "test-{}-pubsub".replace("{}", &std::process::id().to_string())
        );
        assert_eq!(s.displacement, sent.displacement, "sample {i}");
        assert_eq!(
            (s.header, s.velocity, s.force, s.current),
            (sent.header, sent.velocity, sent.force, sent.current),
            "sample {i}"
        );
    }
    let v: serde_json::Value = serde_json::from_str(&line).unwrap();
    assert_eq!(v["ack"], 1000.0, "{line}");
}

/// A controller process that dies without cleaning up, then a new one: with room for a
/// single client, the newcomer only fits once the dead one's resources are removed; the
/// server keeps serving throughout.
#[test]
fn server_keeps_serving_after_a_client_crashes_and_another_starts() {
    let cfg = Iceoryx2Config {
        max_clients: 1,
        ..config("restart")
    };
    let server = ServerThread::start(&cfg);
    let first = child_result(
        spawn_child("crash-controller", &cfg, 300),
        Duration::from_secs(30),
    );
    let second = child_result(
        spawn_child("controller", &cfg, 300),
        Duration::from_secs(30),
    );
    let report = server.finish();
    let a: ControllerSummary = serde_json::from_str(&first).unwrap();
    let b: ControllerSummary = serde_json::from_str(&second).unwrap();
    for (s, line) in [(&a, &first), (&b, &second)] {
        assert_eq!(s.sent, 330, "{line}");
        assert_eq!(s.lost, 0, "{line}");
    }
    assert_eq!(report.answered, 660, "{report:?}");
    // Controllers stamp with wall-clock time, so the second one continues the twin's
    // timeline: every sample is accepted and steps the same twin.
    assert_eq!(a.rejected + b.rejected, 0);
    assert_eq!(report.steps, 600, "{report:?}");
    assert_eq!(report.what_ifs, 60, "{report:?}");
}

/// In one process: pipelined requests up to the in-flight limit, replies matched by
/// sequence number, a second twin on the same prefix refused, bad settings named.
#[test]
fn pipelined_requests_limits_and_bad_settings() {
    let cfg = Iceoryx2Config {
        max_in_flight: 4,
        ..config("pipeline")
    };
    let mut client = ControlClient::new(&cfg).unwrap();
    // No server yet: a request fails at once instead of waiting.
    let req = |seq: u64| ShmRequest {
        kind: ShmRequest::SAMPLE,
        reserved: 0,
        sample: ShmSample {
            seq,
            time_ns: 1_000_000 * (seq as i64 + 1),
            current_a: 0.5,
            ..ShmSample::default()
        },
    };
    let e = client.request(&req(0), Duration::from_secs(5)).unwrap_err();
    assert!(e.to_string().contains("no control server"), "{e}");

    let mut server = ControlServer::new(&cfg).unwrap();
    let e = ControlServer::new(&cfg).unwrap_err();
    assert!(e.to_string().contains("another twin"), "{e}");
    client.wait_for_server(Duration::from_secs(5)).unwrap();

    for seq in 0..4 {
        client.send(&req(seq)).unwrap();
    }
    let e = client.send(&req(4)).unwrap_err();
    assert!(e.to_string().contains("ExceedsMaxActiveRequests"), "{e}");
    assert_eq!(client.in_flight(), 4);
    // Echo the request's time as the force, to see which reply answers which request.
    let mut echo = |r: &ShmRequest| ShmPrediction {
        seq: r.sample.seq,
        time_ns: r.sample.time_ns,
        predicted_force_n: r.sample.time_ns as f64,
        ..ShmPrediction::default()
    };
    assert_eq!(server.serve_pending(&mut echo).unwrap(), 4);
    let mut seqs = Vec::new();
    while let Some(p) = client.receive().unwrap() {
        assert_eq!(p.predicted_force_n, p.time_ns as f64);
        seqs.push(p.seq);
    }
    assert_eq!(seqs, vec![0, 1, 2, 3]);
    assert_eq!(client.in_flight(), 0);
    assert_eq!(server.serve_pending(&mut echo).unwrap(), 0);

    // A request nobody answers times out within its bound, and the late reply to it is
    // not mistaken for the next request's.
    assert!(client
        .request_within(&req(10), Duration::from_millis(20))
        .unwrap()
        .is_none());
    assert_eq!(server.serve_pending(&mut echo).unwrap(), 1);
    assert_eq!(server.undelivered(), 1);
    // (Pipelined: server and client are single-threaded ports, so both stay in this
    // thread; `request` against a serving thread is the cross-process tests' part.)
    client.send(&req(11)).unwrap();
    assert_eq!(server.serve_pending(&mut echo).unwrap(), 1);
    let deadline = Instant::now() + Duration::from_secs(5);
    let p = loop {
        if let Some(p) = client.receive().unwrap() {
            break p;
        }
        assert!(
            Instant::now() < deadline,
            "no reply to request 11 within 5 s"
        );
        std::thread::yield_now();
    };
    assert_eq!(p.seq, 11);
    assert_eq!(server.answered(), 5);

    let bad = Iceoryx2Config {
        max_in_flight: 0,
        ..cfg.clone()
    };
    let e = ControlClient::new(&bad).unwrap_err();
    assert!(e.to_string().contains("`max_in_flight`"), "{e}");
    for prefix in ["", "/mrtwin", "mrtwin/", "a//b"] {
        let e = ControlServer::new(&cfg.with_prefix(prefix)).unwrap_err();
        assert!(e.to_string().contains("service_prefix"), "{prefix}: {e}");
    }
    let e = serde_json::from_str::<Iceoryx2Config>(r#"{"service_prefx": "a"}"#).unwrap_err();
    assert!(e.to_string().contains("service_prefx"), "{e}");
}

/// Twin outputs go out as plain predictions carrying the last yield estimate's τ0; topics
/// iceoryx2 does not carry are ignored, topics not declared are refused.
#[test]
fn outputs_carry_the_last_yield_estimate() {
    let cfg = config("outputs");
    let mut rx = Iceoryx2Transport::new(&cfg, &[], &[Topic::Output, Topic::YieldEstimate]).unwrap();
    let mut tx = Iceoryx2Transport::new(
        &cfg,
        &[Topic::Output, Topic::YieldEstimate, Topic::Diagnostics],
        &[],
    )
    .unwrap();
    assert_eq!(tx.subscriber_count(Topic::Output), 1);
    let out = |t: f64, f: f64| TwinOutput {
        header: Header::at(t, "damper"),
        predicted_force: f,
        measured_force: f + 2.0,
        residual: 2.0,
        health_level: 1,
        ..TwinOutput::default()
    };
    tx.publish(&Message::Output(out(0.001, 100.0))).unwrap();
    tx.publish(&Message::YieldEstimate(YieldEstimate {
        tau0: 25e3,
        tau0_std: 1e3,
        ..YieldEstimate::default()
    }))
    .unwrap();
    tx.publish(&Message::Diagnostics(Default::default()))
        .unwrap();
    tx.publish(&Message::Output(out(0.002, -50.0))).unwrap();
    tx.publish(&Message::Output(out(0.003, -60.0))).unwrap();
    let e = tx.publish(&Message::Sample(stroke_sample(0))).unwrap_err();
    assert!(e.to_string().contains("sensor/sample"), "{e}");

    let mut got = Vec::new();
    rx.poll(&mut got).unwrap();
    // The estimate shows up once, when τ0 changes, before the output that carries it.
    let kinds: Vec<Topic> = got.iter().map(Message::topic).collect();
    assert_eq!(
        kinds,
        [
            Topic::Output,
            Topic::YieldEstimate,
            Topic::Output,
            Topic::Output
        ]
    );
    let Message::YieldEstimate(y) = &got[1] else {
        unreachable!()
    };
    assert_eq!((y.tau0, y.tau0_std), (25e3, 1e3));
    assert_eq!(y.header.stamp.as_nanos(), 2_000_000);
    let outs: Vec<TwinOutput> = got
        .into_iter()
        .filter_map(|m| match m {
            Message::Output(o) => Some(o),
            _ => None,
        })
        .collect();
    assert_eq!(outs.len(), 3);
    assert_eq!(outs[0].predicted_force, 100.0);
    assert_eq!(outs[0].measured_force, 102.0);
    assert_eq!(outs[1].header.stamp.as_nanos(), 2_000_000);
    assert_eq!(outs[1].health_level, 1);
    assert_eq!(outs[1].header.frame_id, cfg.damper_name());
    assert_eq!(rx.missed_samples(), 0);
    assert!(!Iceoryx2Transport::carries(Topic::Diagnostics));
}
