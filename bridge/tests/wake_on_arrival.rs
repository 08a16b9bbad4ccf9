//! Every adapter rings its doorbell when a message arrives, so a loop that sleeps on it
//! (the twin node, `mrtwin record`) wakes for the message instead of at its deadline; the
//! control service rings the server's doorbell when a client sends a request.
//!
//! Each round publishes one sample and sleeps up to [`WAIT`] on the receiver's doorbell.
//! Before discovery a round's sample may be lost (the sleep then runs out); once one
//! arrives, the sleep that delivered it must have ended well before [`WAIT`]: without a
//! ring it would last the whole of it. Own ROS domain id, zenoh port and key prefix, and
//! iceoryx2 service prefix.

#![cfg(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2"))]

use std::time::{Duration, Instant};

use bridge::iceoryx2::{ControlClient, ControlServer, Iceoryx2Config, Iceoryx2Transport};
use bridge::ros2::{QosOverride, Reliability, Ros2Config, Ros2Transport};
use bridge::transport::{Message, Topic, Transport};
use bridge::wake::wait_until;
use bridge::zenoh::{ZenohConfig, ZenohTransport};
use msgs::shm::{ShmRequest, ShmSample};
use msgs::{DamperSample, Header};

const DOMAIN: u16 = 44;
const WAIT: Duration = Duration::from_secs(4);
const ROUNDS: usize = 8;

fn sample(k: usize) -> Message {
    Message::Sample(DamperSample {
        header: Header::at(k as f64 * 1e-3, "wake"),
        displacement: 1e-3,
        velocity: 0.0,
        force: 10.0,
        current: 1.0,
        temperature: f64::NAN,
    })
}

/// Publish on `tx` until a sample reaches `rx`; the sleep that delivered it must have
/// been cut short by the ring. Returns how long that sleep lasted.
fn woken_by_arrival(tx: &mut dyn Transport, rx: &mut dyn Transport) -> Duration {
    let bell = rx.doorbell().expect("the adapter rings");
    bell.bind_current_thread();
    let mut got = Vec::new();
    for k in 0..ROUNDS {
        got.clear();
        rx.poll(&mut got).unwrap();
        tx.publish(&sample(k)).unwrap();
        let t0 = Instant::now();
        wait_until(t0 + WAIT);
        let slept = t0.elapsed();
        rx.poll(&mut got).unwrap();
        if got.iter().any(|m| matches!(m, Message::Sample(_))) {
            return slept;
        }
    }
    panic!(
        "{}: nothing arrived in {ROUNDS} rounds of {WAIT:?}",
        rx.name()
    );
}

fn assert_rung(name: &str, slept: Duration) {
    assert!(
        slept < WAIT / 2,
        "{name}: the delivering sleep lasted {slept:?}: the doorbell did not ring"
    );
}

#[test]
fn zenoh_rings_on_arrival() {
    let port = mrtwin_tests::free_port();
    let listen = ZenohConfig {
        listen: vec![format!("tcp/127.0.0.1:{port}")],
        multicast_scouting: false,
        key_prefix: "mrtwin_it_wake".into(),
        ..Default::default()
    };
    let connect = ZenohConfig {
        listen: Vec::new(),
        connect: vec![format!("tcp/127.0.0.1:{port}")],
        ..listen.clone()
    };
    let mut rx = ZenohTransport::new(&listen, "w", &[], &[Topic::Sample]).unwrap();
    let mut tx = ZenohTransport::new(&connect, "w", &[Topic::Sample], &[]).unwrap();
    assert_rung("zenoh", woken_by_arrival(&mut tx, &mut rx));
}

#[test]
fn ros2_rings_on_arrival() {
    let mut cfg = Ros2Config {
        domain_id: DOMAIN,
        namespace: "/wake_it".parse().unwrap(),
        ..Default::default()
    };
    cfg.qos.insert(
        Topic::Sample,
        QosOverride {
            reliability: Some(Reliability::Reliable),
            depth: None,
        },
    );
    let tx_cfg = Ros2Config {
        node_name: "wake_tx".into(),
        ..cfg.clone()
    };
    let rx_cfg = Ros2Config {
        node_name: "wake_rx".into(),
        ..cfg
    };
    let mut rx = Ros2Transport::new(&rx_cfg, &[], &[Topic::Sample]).unwrap();
    let mut tx = Ros2Transport::new(&tx_cfg, &[Topic::Sample], &[]).unwrap();
    assert_rung("ros2", woken_by_arrival(&mut tx, &mut rx));
}

fn ice_config(test: &str) -> Iceoryx2Config {
    bridge::iceoryx2::quiet_logs();
    Iceoryx2Config::default().with_prefix(format!("mrtwin/wake-{}-{test}", std::process::id()))
}

#[test]
fn iceoryx2_rings_on_arrival() {
    let cfg = ice_config("pubsub");
    let mut rx = Iceoryx2Transport::new(&cfg, &[], &[Topic::Sample]).unwrap();
    let mut tx = Iceoryx2Transport::new(&cfg, &[Topic::Sample], &[]).unwrap();
    assert_rung("iceoryx2", woken_by_arrival(&mut tx, &mut rx));
}

/// The control service: a request rings the server while it says it sleeps; once it says
/// it busy polls, clients stop notifying (the server then wakes only at its deadline).
#[test]
fn a_control_request_rings_a_sleeping_server_and_not_a_polling_one() {
    let cfg = ice_config("control");
    let mut server = ControlServer::new(&cfg).unwrap();
    let mut client = ControlClient::new(&cfg).unwrap();
    server.doorbell().bind_current_thread();
    let request = |seq: u64| ShmRequest {
        kind: ShmRequest::SAMPLE,
        reserved: 0,
        sample: ShmSample {
            seq,
            time_ns: seq as i64 * 1_000_000,
            ..Default::default()
        },
    };
    let serve = |server: &mut ControlServer| {
        server
            .serve_pending(&mut |r: &ShmRequest| {
                let mut reply = bridge::iceoryx2::rejected_reply(r);
                reply.rejected = 0;
                reply
            })
            .unwrap()
    };
    // A request rings the sleeping server (any token left on this thread drained first);
    // returns when it was sent.
    let rings = |client: &mut ControlClient, server: &mut ControlServer, seq: u64, what: &str| {
        wait_until(Instant::now());
        client.send(&request(seq)).unwrap();
        let t0 = Instant::now();
        wait_until(t0 + WAIT);
        assert_rung(what, t0.elapsed());
        assert_eq!(serve(server), 1);
        t0
    };
    let t0 = rings(&mut client, &mut server, 1, "control");
    let reply = |client: &mut ControlClient, since: Instant| loop {
        if let Some(r) = client.receive().unwrap() {
            break r;
        }
        assert!(since.elapsed() < WAIT, "no reply");
    };
    assert_eq!(reply(&mut client, t0).server_sleeps, 1);
    // The server now busy polls: the next reply tells the client, which stops notifying
    // while it sends within half the server's hot window, and notifies after a pause.
    server.set_sleeps(false);
    let t_send2 = Instant::now();
    client.send(&request(2)).unwrap();
    wait_until(Instant::now() + WAIT);
    assert_eq!(serve(&mut server), 1);
    assert_eq!(reply(&mut client, t_send2).server_sleeps, 0);
    let gap = t_send2.elapsed();
    client.send(&request(3)).unwrap();
    if gap < bridge::iceoryx2::POLLING_SERVER_STAYS_HOT / 2 {
        let t0 = Instant::now();
        wait_until(t0 + Duration::from_millis(500));
        assert!(
            t0.elapsed() >= Duration::from_millis(400),
            "the client notified a polling server within its hot window"
        );
    } else {
        eprintln!("request 3 came {gap:?} after request 2: the hot window is not tested");
    }
    assert_eq!(serve(&mut server), 1);
    std::thread::sleep(bridge::iceoryx2::POLLING_SERVER_STAYS_HOT * 2);
    rings(&mut client, &mut server, 4, "control after a pause");
}
