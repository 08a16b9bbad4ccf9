//! A local controller talking to the twin over iceoryx2 shared memory.
//!
//! It connects to the twin's request–response service `<service>/twin/control`, then,
//! at a fixed rate (real-time paced: sleep, then spin the last 200 µs), sends the measured
//! sample of a sinusoidal stroke and waits for the twin's predicted force; every
//! `--what-if-every` cycles it also asks what the force would be with a planned current
//! (a what-if the twin answers without advancing). Every wait is bounded by `--timeout-ms`.
//! At the end it prints one JSON line: requests sent, replied, lost, timeouts and the
//! round-trip latency p50/p99/max in µs.
//!
//! Run the twin first (it serves `<service>/twin/control`), then:
//!
//! ```text
//! cargo run --release -p bridge --features iceoryx2 --example iceoryx2_controller -- \
//!     --service mrtwin/damper --rate 1000 --seconds 10
//! ```
//!
//! Options (defaults in brackets): `--service PREFIX` [mrtwin/damper], `--rate HZ` [1000],
//! `--seconds S` [10], `--timeout-ms MS` [200], `--what-if-every N` [10, 0 = never],
//! `--current A` [1], `--planned-current A` [2], `--amplitude M` [0.01],
//! `--frequency HZ` [2], `--wait-server-s S` [5].

use std::process::ExitCode;
use std::time::Duration;

use bridge::iceoryx2::controller::{run_controller, ControllerOptions};
use bridge::iceoryx2::Iceoryx2Config;

fn parse_args() -> Result<(Iceoryx2Config, ControllerOptions), String> {
    let mut cfg = Iceoryx2Config::default();
    let mut opts = ControllerOptions::default();
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        if flag == "--help" || flag == "-h" {
            return Err(String::new());
        }
        let value = args
            .next()
            .ok_or_else(|| format!("option {flag} needs a value"))?;
        let num = |what: &str| -> Result<f64, String> {
            value
                .parse::<f64>()
                .map_err(|_| format!("option {flag}: `{value}` is not a number ({what})"))
        };
        match flag.as_str() {
            "--service" => cfg.service_prefix = value.clone(),
            "--rate" => opts.rate_hz = num("Hz")?,
            "--seconds" => opts.seconds = num("s")?,
            "--timeout-ms" => opts.reply_timeout = duration(num("ms")? / 1e3, &flag)?,
            "--wait-server-s" => opts.server_timeout = duration(num("s")?, &flag)?,
            "--what-if-every" => {
                opts.what_if_every = value
                    .parse()
                    .map_err(|_| format!("option {flag}: `{value}` is not a whole number"))?
            }
            "--current" => opts.current_a = num("A")?,
            "--planned-current" => opts.planned_current_a = num("A")?,
            "--amplitude" => opts.amplitude_m = num("m")?,
            "--frequency" => opts.frequency_hz = num("Hz")?,
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok((cfg, opts))
}

fn duration(secs: f64, flag: &str) -> Result<Duration, String> {
    Duration::try_from_secs_f64(secs).map_err(|_| format!("option {flag}: must be a positive time"))
}

fn main() -> ExitCode {
    // iceoryx2 warns once that no config file was found and defaults are used: expected.
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
    let (cfg, opts) = match parse_args() {
        Ok(v) => v,
        Err(e) => {
            if !e.is_empty() {
                eprintln!("error: {e}");
            }
            eprintln!("usage: iceoryx2_controller [--service PREFIX] [--rate HZ] [--seconds S] [--timeout-ms MS] [--what-if-every N] [--current A] [--planned-current A] [--amplitude M] [--frequency HZ] [--wait-server-s S]");
            return ExitCode::from(2);
        }
    };
    match run_controller(&cfg, &opts) {
        Ok(summary) => {
            println!(
                "{}",
                serde_json::to_string(&summary).expect("summary is plain data")
            );
            if summary.lost == 0 {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
