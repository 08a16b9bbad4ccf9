//! `mrtwin`: the command line of the MR damper digital twin.
//!
//! * `simulate`: drive a damper model through a test-stand programme, write a CSV recording.
//! * `yield-stress`: τ0 of the Bodner–Partom law of Skalski & Zalewski, eqs. (5.3), (5.5).
//! * `demo`: the Skalski–Zalewski programme through two models: recordings, plots, summary.
//! * `info`: what a CSV recording holds, after strict input checks.
//!
//! Errors are printed as `error: …` with their causes, and the exit code is 1.

mod demo;
mod info;
mod loops;
mod numbers;
mod plot;
mod simulate;
mod yield_stress;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Digital twin of a magnetorheological (MR) damper.
#[derive(Debug, Parser)]
#[command(name = "mrtwin", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Simulate a test-stand programme with a damper model and write the recording as CSV.
    Simulate(Box<simulate::SimulateArgs>),
    /// Yield stress τ0 of the Bodner–Partom law (Skalski & Zalewski, eqs. 5.3 and 5.5).
    YieldStress(yield_stress::YieldStressArgs),
    /// Run the Skalski–Zalewski programme on two models: CSVs, SVG plots and a summary.
    Demo(demo::DemoArgs),
    /// Check a CSV recording and summarise it: samples, rate, gaps, currents, force range.
    Info(info::InfoArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Simulate(args) => simulate::run(args),
        Command::YieldStress(args) => yield_stress::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Info(args) => info::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
