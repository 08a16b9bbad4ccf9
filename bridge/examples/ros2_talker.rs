//! Publish a predicted damper force on ROS 2, so stock tools can see it.
//!
//! ```sh
//! cargo run --release -p bridge --features ros2 --example ros2_talker -- --ns /damper1 --seconds 30
//! # in a ROS 2 shell (any RMW that speaks DDS, e.g. rmw_fastrtps_cpp or rmw_cyclonedds_cpp),
//! # same ROS_DOMAIN_ID:
//! ros2 topic echo /damper1/twin/predicted_force      # std_msgs/msg/Float64, 100 Hz
//! ros2 topic echo /diagnostics                       # diagnostic_msgs/msg/DiagnosticArray, 1 Hz
//! ros2 node list                                     # /damper1/mrtwin_talker
//! ```
//!
//! The force is a Bingham-like square-ish wave `F = 400 N · tanh(v / 0.02 m/s) + 2000 N·s/m · v`
//! over a 2 Hz, 10 mm sinusoidal stroke: something that looks like a damper, not a model run
//! (use the twin node for that). The domain comes from `ROS_DOMAIN_ID` (default 0).

use std::time::{Duration, Instant};

use bridge::ros2::{Ros2Config, Ros2Transport};
use bridge::transport::{Message, Topic, Transport};
use msgs::{DiagnosticArray, DiagnosticStatus, Float64, Header, KeyValue};

fn main() {
    let mut cfg = Ros2Config {
        node_name: "mrtwin_talker".into(),
        ..Default::default()
    };
    let mut seconds = 10.0f64;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let value = args.get(i + 1).cloned();
        match (args[i].as_str(), value) {
            ("--ns", Some(v)) => {
                cfg.namespace = v.parse().unwrap_or_else(|e| exit(&format!("--ns {v}: {e}")))
            }
            ("--node", Some(v)) => cfg.node_name = v,
            ("--seconds", Some(v)) => {
                seconds = v.parse().unwrap_or_else(|_| exit(&format!("--seconds {v}: not a number")))
            }
            (a, _) => exit(&format!(
                "unknown or incomplete argument {a:?}; usage: ros2_talker [--ns NS] [--node NAME] [--seconds S]"
            )),
        }
        i += 2;
    }
    if let Ok(d) = std::env::var("ROS_DOMAIN_ID") {
        cfg.domain_id = d
            .parse()
            .unwrap_or_else(|_| exit(&format!("ROS_DOMAIN_ID={d}: not a number")));
    }
    let mut tr = Ros2Transport::new(&cfg, &[Topic::PredictedForce, Topic::Diagnostics], &[])
        .unwrap_or_else(|e| exit(&e.to_string()));
    println!(
        "{} publishing {} (std_msgs/msg/Float64) on domain {} for {seconds} s",
        tr.node_fqn(),
        cfg.resolve(Topic::PredictedForce),
        cfg.domain_id
    );
    let start = Instant::now();
    let period = Duration::from_millis(10);
    let mut k = 0u64;
    while start.elapsed().as_secs_f64() < seconds {
        let t = k as f64 * period.as_secs_f64();
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let v = 0.010 * w * (w * t).cos();
        let force = 400.0 * (v / 0.02).tanh() + 2000.0 * v;
        tr.publish(&Message::PredictedForce(Float64 { data: force }))
            .unwrap_or_else(|e| eprintln!("{e}"));
        if k % 100 == 0 {
            let d = DiagnosticArray {
                header: Header::at(t, ""),
                status: vec![DiagnosticStatus {
                    level: DiagnosticStatus::OK,
                    name: format!("{}: talker", cfg.node_name),
                    message: "publishing a demo force".into(),
                    hardware_id: "demo".into(),
                    values: vec![KeyValue::new("samples", k.to_string())],
                }],
            };
            tr.publish(&Message::Diagnostics(d))
                .unwrap_or_else(|e| eprintln!("{e}"));
        }
        k += 1;
        let next = start + period * k as u32;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    tr.shutdown();
}

fn exit(msg: &str) -> ! {
    eprintln!("ros2_talker: {msg}");
    std::process::exit(2)
}
