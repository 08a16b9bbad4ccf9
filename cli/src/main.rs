//! `mrtwin`: the command line of the MR damper digital twin.
//!
//! * `simulate`: drive a damper model through a test-stand programme, write a CSV recording.
//! * `yield-stress`: τ0 of the Bodner–Partom law of Skalski & Zalewski, eqs. (5.3), (5.5).
//! * `demo`: the live system (stand → twin over ROS 2, zenoh, iceoryx2) with a live line per second.
//! * `paper`: the Skalski–Zalewski programme through two models: recordings, plots, summary.
//! * `node`, `stand`, `launch`: the twin node, the test-stand node, a launch file of them.
//! * `info`: what a CSV recording holds, after strict input checks.
//! * `diagnose`: find the physics a model left out, add it, prove the held-out fit improves.
//! * `convert`: CSV recording ↔ rosbag2 MCAP bag.
//! * `fleet`: N stands and N twins in one process over zenoh, a central monitor (feature `zenoh`).
//! * `monitor`: the central view of a fleet behind zenoh routers: every damper's level,
//!   STALE when its outputs stop (feature `zenoh`).
//! * `identify`: the Skalski–Zalewski identification of n, R0 (5.3) and (5.5) from recordings.
//!
//! Errors are printed as `error: …` with their causes, and the exit code is 1.

mod convert;
mod diagnose;
mod fit;
#[cfg(feature = "zenoh")]
mod fleet;
mod foxglove;
mod html;
mod identify;
mod info;
mod live;
mod logging;
mod loops;
#[cfg(feature = "zenoh")]
mod monitor;
mod nodes;
mod numbers;
mod output;
mod paper;
mod plot;
mod record;
mod replay;
mod simulate;
mod stop;
mod upgrade;
mod yield_stress;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Digital twin of a magnetorheological (MR) damper.
#[derive(Debug, Parser)]
#[command(name = "mrtwin", version)]
struct Cli {
    /// Log level of mrtwin's messages on standard error (ROS 2 console format).
    #[arg(long, global = true, value_enum, default_value = "info")]
    log_level: logging::LogLevel,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Simulate a test-stand programme with a damper model; write the recording as CSV or a bag.
    Simulate(Box<simulate::SimulateArgs>),
    /// Yield stress τ0 of the Bodner–Partom law (Skalski & Zalewski, eqs. 5.3 and 5.5).
    YieldStress(yield_stress::YieldStressArgs),
    /// The live system: stand → twin over ROS 2, zenoh and iceoryx2, a live line per second.
    Demo(live::DemoArgs),
    /// Run the Skalski–Zalewski programme on two models: CSVs, SVG plots and a summary.
    Paper(paper::PaperArgs),
    /// The twin node: steps the model on live sensor samples, publishes prediction and health.
    Node(nodes::NodeArgs),
    /// The test-stand node: plays the simulator as a live sensor stream (real-time paced).
    Stand(nodes::NodeArgs),
    /// Start the nodes of a launch file (ROS 2 launch YAML style) and stop them on Ctrl-C.
    Launch(nodes::LaunchArgs),
    /// Replay a recording (bag or CSV) through the twin: outputs to CSV, a bag, or the transports.
    Replay(replay::ReplayArgs),
    /// Record sensor samples and twin outputs from the live system into a rosbag2 MCAP bag.
    Record(record::RecordArgs),
    /// Check a CSV recording and summarise it: samples, rate, gaps, currents, force range.
    Info(info::InfoArgs),
    /// Find the physics a baseline model leaves out, add it, and show the held-out fit improve.
    Diagnose(diagnose::DiagnoseArgs),
    /// Convert a recording between CSV and a rosbag2 MCAP bag (directory or .mcap).
    Convert(convert::ConvertArgs),
    /// Identify the Bodner–Partom law from recordings (Skalski & Zalewski: 5.3, 5.5).
    Identify(identify::IdentifyArgs),
    /// Calibrate the twin's own model to recordings; write it as a parameter file the nodes read.
    Fit(fit::FitArgs),
    /// N simulated stands and N twins in one process over zenoh, with a central monitor.
    #[cfg(feature = "zenoh")]
    Fleet(fleet::FleetArgs),
    /// The central view of a fleet behind zenoh routers: each damper's level, STALE when its outputs stop.
    #[cfg(feature = "zenoh")]
    Monitor(monitor::MonitorArgs),
}

impl Command {
    /// The logger name of the command's log lines (the node's default name for nodes).
    fn logger(&self) -> &'static str {
        match self {
            Command::Node(_) => "mrtwin_twin",
            Command::Stand(_) => "mrtwin_stand",
            Command::Record(_) => "mrtwin_record",
            Command::Demo(_) => "mrtwin_demo",
            Command::Launch(_) => "mrtwin_launch",
            Command::Replay(_) => "mrtwin_replay",
            #[cfg(feature = "zenoh")]
            Command::Fleet(_) => "mrtwin_fleet",
            #[cfg(feature = "zenoh")]
            Command::Monitor(_) => "mrtwin_monitor",
            _ => "mrtwin",
        }
    }
}

fn main() -> ExitCode {
    #[cfg(feature = "iceoryx2")]
    bridge::iceoryx2::quiet_logs();
    let cli = Cli::parse();
    logging::init(cli.log_level, cli.command.logger());
    let result = match &cli.command {
        Command::Simulate(args) => simulate::run(args),
        Command::YieldStress(args) => yield_stress::run(args),
        Command::Demo(args) => live::run(args),
        Command::Paper(args) => paper::run(args),
        Command::Node(args) => nodes::run_twin(args),
        Command::Stand(args) => nodes::run_stand(args),
        Command::Launch(args) => nodes::run_launch(args),
        Command::Replay(args) => replay::run(args),
        Command::Record(args) => record::run(args),
        Command::Info(args) => info::run(args),
        Command::Diagnose(args) => diagnose::run(args),
        Command::Convert(args) => convert::run(args),
        Command::Identify(args) => identify::run(args),
        Command::Fit(args) => fit::run(args),
        #[cfg(feature = "zenoh")]
        Command::Fleet(args) => fleet::run(args),
        #[cfg(feature = "zenoh")]
        Command::Monitor(args) => monitor::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
