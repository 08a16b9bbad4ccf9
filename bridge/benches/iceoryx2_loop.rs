//! Round trip of the twin's iceoryx2 control service next to iceoryx2's own raw round trip
//! for the same payload, in the same run.
//!
//! * raw: iceoryx2's request–response API directly (`ipc::Service`), a server thread that
//!   echoes the request's sample into a `ShmPrediction`.
//! * twin: `bridge::iceoryx2::{ControlServer, ControlClient}` with a real twin model (the
//!   paper's two-chamber damper, compressibility + gas spring) stepped once per request
//!   on a 1 kHz stroke timeline.
//!
//! Server in a thread of this process, client in the main thread; both busy poll. The
//! cases alternate in rounds (only the active case's server polls; the others park) so
//! all see the same machine load. Beside the round trips: the model's own time per
//! request inside the server thread, and the model alone without transport. Run:
//!
//! ```text
//! cargo bench -p bridge --features iceoryx2 --bench iceoryx2_loop [-- REQUESTS ROUNDS]
//! ```
//! (default 100 000 requests per case in 100 alternating rounds of 1 000).

#[path = "../tests/support/twin_handler.rs"]
mod twin_handler;

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::thread::Thread;
use std::time::{Duration, Instant};

use bridge::iceoryx2::controller::quantile;
use bridge::iceoryx2::{ControlClient, ControlServer, Iceoryx2Config};
use iceoryx2::prelude::*;
use msgs::shm::{ShmPrediction, ShmRequest, ShmSample};
use twin_handler::TwinHandler;

const IDLE: u8 = 0;
const RAW: u8 = 1;
const TWIN: u8 = 2;
const WRAP: u8 = 3;
const STOP: u8 = 4;

fn request(i: u64) -> ShmRequest {
    let t = i as f64 * 1e-3;
    let w = 2.0 * std::f64::consts::PI * 2.0;
    ShmRequest {
        kind: ShmRequest::SAMPLE,
        reserved: 0,
        sample: ShmSample {
            seq: i,
            time_ns: i as i64 * 1_000_000,
            displacement_m: 0.01 * (w * t).sin(),
            velocity_m_s: 0.01 * w * (w * t).cos(),
            force_n: f64::NAN,
            current_a: 1.0,
            temperature_c: f64::NAN,
        },
    }
}

fn echo(r: &ShmRequest) -> ShmPrediction {
    ShmPrediction {
        seq: r.sample.seq,
        time_ns: r.sample.time_ns,
        predicted_force_n: r.sample.force_n,
        ..ShmPrediction::default()
    }
}

/// Wait while `state` is none of `mine`, parked (another case is measured meanwhile);
/// returns the case to serve, `None` at the end. [`switch_to`] unparks the servers.
///
/// Parked, not sleeping in a loop: a server that slept 200 µs per look woke every
/// ≈ 265 µs (timer slack) and took a core from the two busy-polling threads of the case
/// being measured, a ≈ 20 µs stall every 265 µs. That stall hit about one request in
/// 55 of the twin case (longer requests) against one in 90 of raw, so it set the twin's
/// p99 and not raw's (BENCHMARKS.md, "iceoryx2 control service").
fn parked(state: &AtomicU8, mine: &[u8]) -> Option<u8> {
    loop {
        match state.load(Ordering::Acquire) {
            STOP => return None,
            s if mine.contains(&s) => return Some(s),
            // Bounded: a lost unpark costs at most this, never a hang.
            _ => std::thread::park_timeout(Duration::from_millis(100)),
        }
    }
}

/// Make `case` the polling server, unpark the servers, and wait (at most 10 s) until it
/// polls. `ready` is cleared first: a server that was descheduled through the other
/// case's whole round (loaded machine) is still in its polling loop and re-announces
/// itself from there.
fn switch_to(
    state: &AtomicU8,
    ready: &AtomicU8,
    servers: &[&Thread],
    case: u8,
) -> Result<(), String> {
    ready.store(IDLE, Ordering::Release);
    state.store(case, Ordering::Release);
    for server in servers {
        server.unpark();
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while ready.load(Ordering::Acquire) != case {
        if Instant::now() > deadline {
            return Err(format!("server {case} did not start polling within 10 s"));
        }
        std::thread::yield_now();
    }
    Ok(())
}

/// (p50, p90, p99, p99.9, max, mean).
fn stats(mut v: Vec<f64>) -> [f64; 6] {
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    [
        quantile(&v, 0.5),
        quantile(&v, 0.9),
        quantile(&v, 0.99),
        quantile(&v, 0.999),
        *v.last().unwrap(),
        mean,
    ]
}

/// Samples per stroke of [`request`]'s 2 Hz stroke at 1 kHz.
const STROKE: u64 = 500;

/// Is request `seq` within 25 samples of a stroke reversal (v = 0 at a quarter and three
/// quarters of the stroke), where the chamber flow blocks and opens again?
fn near_reversal(seq: u64) -> bool {
    let phase = seq % STROKE;
    [STROKE / 4, 3 * STROKE / 4]
        .iter()
        .any(|&r| phase.abs_diff(r) <= 25)
}

/// Of the requests slower than the p99 of `lat` (request `i` has sequence number
/// `seq0 + i`), the share within 25 samples of a reversal (10 % of all requests are).
fn slow_share_near_reversal(lat: &[f64], seq0: u64) -> f64 {
    let mut sorted = lat.to_vec();
    sorted.sort_by(f64::total_cmp);
    let p99 = quantile(&sorted, 0.99);
    let slow: Vec<u64> = (0..lat.len() as u64)
        .filter(|&i| lat[i as usize] > p99)
        .collect();
    let near = slow.iter().filter(|&&i| near_reversal(seq0 + i)).count();
    near as f64 / slow.len().max(1) as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    set_log_level(LogLevel::Error);
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let total: u64 = args.first().map_or(Ok(100_000), |s| s.parse())?;
    let rounds: u64 = args.get(1).map_or(Ok(100), |s| s.parse())?;
    let per_round = total / rounds;
    let prefix = format!("mrtwin/bench-{}", std::process::id());
    let cfg = Iceoryx2Config::default().with_prefix(format!("{prefix}/twin"));
    let raw_name = format!("{prefix}/raw/control");
    let state = Arc::new(AtomicU8::new(IDLE));
    let ready = Arc::new(AtomicU8::new(IDLE));

    // Raw iceoryx2 echo server.
    let raw_server = {
        let (state, ready) = (state.clone(), ready.clone());
        let name = raw_name.clone();
        std::thread::spawn(move || -> Result<(), String> {
            let node = NodeBuilder::new()
                .create::<ipc::Service>()
                .map_err(|e| format!("{e:?}"))?;
            let service = node
                .service_builder(&ServiceName::new(&name).map_err(|e| format!("{e:?}"))?)
                .request_response::<ShmRequest, ShmPrediction>()
                .open_or_create()
                .map_err(|e| format!("{e:?}"))?;
            let server = service
                .server_builder()
                .create()
                .map_err(|e| format!("{e:?}"))?;
            while parked(&state, &[RAW]).is_some() {
                while state.load(Ordering::Relaxed) == RAW {
                    ready.store(RAW, Ordering::Relaxed);
                    if let Some(active) = server.receive().map_err(|e| format!("{e:?}"))? {
                        let reply = echo(active.payload());
                        active.send_copy(reply).map_err(|e| format!("{e:?}"))?;
                    }
                }
            }
            Ok(())
        })
    };
    // The twin's control server: echo (wrapper overhead) or a real model step.
    // Created in its serving thread (single-threaded ports); the thread says whether it
    // could.
    let (created_tx, created_rx) = std::sync::mpsc::sync_channel::<Result<(), String>>(1);
    let twin_server = {
        let (state, ready) = (state.clone(), ready.clone());
        let cfg = cfg.clone();
        std::thread::spawn(move || -> Result<(u64, Vec<f64>), String> {
            let mut server = match ControlServer::new(&cfg) {
                Ok(server) => server,
                Err(e) => {
                    let _ = created_tx.send(Err(e.to_string()));
                    return Err(e.to_string());
                }
            };
            // This server busy polls: its clients need not notify it.
            server.set_sleeps(false);
            let _ = created_tx.send(Ok(()));
            let mut twin = TwinHandler::paper();
            // The model's own time inside the server thread, per request (µs).
            let mut served = Vec::with_capacity(2 * total as usize);
            let mut model = |r: &ShmRequest| {
                let t0 = Instant::now();
                let reply = twin.handle(r);
                served.push(t0.elapsed().as_secs_f64() * 1e6);
                reply
            };
            let mut echo = echo;
            while let Some(case) = parked(&state, &[TWIN, WRAP]) {
                let handler: &mut dyn FnMut(&ShmRequest) -> ShmPrediction =
                    if case == TWIN { &mut model } else { &mut echo };
                while state.load(Ordering::Relaxed) == case {
                    ready.store(case, Ordering::Relaxed);
                    server.serve_pending(handler).map_err(|e| e.to_string())?;
                }
            }
            let answered = server.answered();
            Ok((answered, served))
        })
    };

    // Clients.
    let node = NodeBuilder::new().create::<ipc::Service>()?;
    let raw_service = node
        .service_builder(&ServiceName::new(&raw_name)?)
        .request_response::<ShmRequest, ShmPrediction>()
        .open_or_create()?;
    let raw_client = raw_service.client_builder().create()?;
    created_rx.recv_timeout(Duration::from_secs(10))??;
    let mut twin_client = ControlClient::new(&cfg)?;
    let deadline = Instant::now() + Duration::from_secs(10);
    while raw_service.dynamic_config().number_of_servers() == 0 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(1));
    }
    twin_client.wait_for_server(Duration::from_secs(10))?;

    let timeout = Duration::from_secs(1);
    let servers = [raw_server.thread(), twin_server.thread()];
    let mut raw_lat = Vec::with_capacity(total as usize);
    let mut twin_lat = Vec::with_capacity(total as usize);
    let mut wrap_lat = Vec::with_capacity(total as usize);
    let mut twin_seq = 0u64;
    let mut wrap_seq = 0u64;
    let mut force_sum = 0.0;
    for round in 0..=rounds {
        // Round 0 is the warm-up (1 000 requests each, not recorded).
        let n = if round == 0 { 1000 } else { per_round };
        switch_to(&state, &ready, &servers, RAW)?;
        for i in 0..n {
            let t0 = Instant::now();
            let pending = raw_client.send_copy(request(i))?;
            let reply = loop {
                if let Some(r) = pending.receive()? {
                    break *r.payload();
                }
                if t0.elapsed() > timeout {
                    return Err(format!("raw: no reply to {i} within {timeout:?}").into());
                }
            };
            let dt = t0.elapsed().as_secs_f64() * 1e6;
            assert_eq!(reply.seq, i);
            if round > 0 {
                raw_lat.push(dt);
            }
        }
        switch_to(&state, &ready, &servers, WRAP)?;
        for _ in 0..n {
            let req = request(wrap_seq);
            wrap_seq += 1;
            let t0 = Instant::now();
            let reply = twin_client.request(&req, timeout)?;
            let dt = t0.elapsed().as_secs_f64() * 1e6;
            assert_eq!(reply.seq, req.sample.seq);
            if round > 0 {
                wrap_lat.push(dt);
            }
        }
        switch_to(&state, &ready, &servers, TWIN)?;
        for _ in 0..n {
            let req = request(twin_seq);
            twin_seq += 1;
            let t0 = Instant::now();
            let reply = twin_client.request(&req, timeout)?;
            let dt = t0.elapsed().as_secs_f64() * 1e6;
            assert_eq!(reply.seq, req.sample.seq);
            assert!(reply.predicted_force_n.is_finite() && reply.rejected == 0);
            force_sum += reply.predicted_force_n * req.sample.velocity_m_s;
            if round > 0 {
                twin_lat.push(dt);
            }
        }
    }
    state.store(STOP, Ordering::Release);
    for server in servers {
        server.unpark();
    }
    raw_server.join().expect("raw server")?;
    let (answered, served) = twin_server.join().expect("twin server")?;
    // The warm-up round's model steps are not recorded on the client either.
    let served = served[served.len().saturating_sub(twin_lat.len())..].to_vec();
    assert_eq!(answered, twin_seq + wrap_seq);
    assert!(
        force_sum > 0.0,
        "the damper must dissipate over whole strokes"
    );

    // The model alone on the same requests (no transport), for the breakdown.
    let mut alone = TwinHandler::paper();
    let mut model_lat = Vec::with_capacity(twin_seq as usize);
    for i in 0..twin_seq {
        let req = request(i);
        let t0 = Instant::now();
        let reply = alone.handle(&req);
        model_lat.push(t0.elapsed().as_secs_f64() * 1e6);
        assert!(reply.predicted_force_n.is_finite());
    }

    println!("iceoryx2 request-response round trip, 64 B request / 56 B reply; server in a thread of this process, client in the main thread, both busy polling; {} requests per case in {rounds} alternating rounds", raw_lat.len());
    // The twin's recorded requests are its sequence numbers 1000.. (after the warm-up).
    let twin_near = slow_share_near_reversal(&twin_lat, 1000);
    let model_near = slow_share_near_reversal(&model_lat, 0);
    println!("| case | p50 µs | p90 µs | p99 µs | p99.9 µs | max µs | mean µs |");
    println!("|---|---|---|---|---|---|---|");
    let rows = [
        ("raw iceoryx2 echo (reference)", raw_lat),
        ("ControlServer/ControlClient, echo handler", wrap_lat),
        (
            "ControlServer/ControlClient, two-chamber paper model step",
            twin_lat,
        ),
        ("(model step inside the server thread)", served),
        ("(model step alone, no transport)", model_lat),
    ];
    let mut p99 = Vec::new();
    for (name, lat) in rows {
        let [a, b, c, d, e, f] = stats(lat);
        println!("| {name} | {a:.2} | {b:.2} | {c:.2} | {d:.2} | {e:.1} | {f:.2} |");
        p99.push(c);
    }
    println!(
        "p99 / raw p99: echo wrapper {:.2}, twin {:.2} (target ≤ 3)",
        p99[1] / p99[0],
        p99[2] / p99[0]
    );
    println!(
        "slowest 1 %: {:.0} % of the twin's round trips and {:.0} % of the model steps alone lie within 25 samples of a stroke reversal (10 % of all requests do)",
        100.0 * twin_near,
        100.0 * model_near
    );
    Ok(())
}
