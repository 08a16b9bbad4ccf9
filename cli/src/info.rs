//! `mrtwin info`: what a recording holds — samples, duration, sample rate, gaps, current
//! levels, force range — after the strict checks of the CSV reader (NaN, unsorted time,
//! missing columns and millimetres for metres are errors naming the line or column).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

/// Arguments of `mrtwin info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// A CSV recording in the format of PHYSICS.md.
    #[arg(value_name = "FILE.csv")]
    pub input: PathBuf,
}

/// Print a summary of a recording.
pub fn run(args: &InfoArgs) -> Result<()> {
    let rec = bridge::recording::read_csv(&args.input)
        .with_context(|| format!("cannot use {} as a recording", args.input.display()))?;
    let s = &rec.samples;
    let n = s.len();
    let duration = s[n - 1].time_s - s[0].time_s;
    let mut dts: Vec<f64> = s.windows(2).map(|w| w[1].time_s - w[0].time_s).collect();
    dts.sort_by(f64::total_cmp);
    let median_dt = dts.get(dts.len() / 2).copied().unwrap_or(0.0);
    let gaps: Vec<(f64, f64)> = s
        .windows(2)
        .filter(|w| median_dt > 0.0 && w[1].time_s - w[0].time_s > 1.5 * median_dt)
        .map(|w| (w[0].time_s, w[1].time_s - w[0].time_s))
        .collect();
    let mut currents: Vec<f64> = Vec::new();
    for smp in s {
        let level = (smp.current_a * 1000.0).round() / 1000.0;
        if !currents.contains(&level) {
            currents.push(level);
        }
    }
    let (fmin, fmax) = s
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x.force_n), b.max(x.force_n))
        });
    let (xmin, xmax) = s
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x.displacement_m), b.max(x.displacement_m))
        });
    println!("recording     {}", args.input.display());
    println!("samples       {n}");
    println!(
        "time          {:.6} s to {:.6} s ({duration:.3} s)",
        s[0].time_s,
        s[n - 1].time_s
    );
    if median_dt > 0.0 {
        println!(
            "sample rate   {:.1} Hz (median step {:.3} ms)",
            1.0 / median_dt,
            median_dt * 1e3
        );
    }
    println!(
        "gaps          {}{}",
        gaps.len(),
        gaps.first()
            .map(|(t, d)| format!(" (first at {t:.4} s, {:.2} ms)", d * 1e3))
            .unwrap_or_default()
    );
    let levels: Vec<String> = currents.iter().map(|c| format!("{c}")).collect();
    println!("currents      {} A", levels.join(", "));
    println!("displacement  {:.3} to {:.3} mm", xmin * 1e3, xmax * 1e3);
    println!("force         {fmin:.1} to {fmax:.1} N");
    println!(
        "velocity      {}",
        if rec.velocity_derived {
            "derived from displacement"
        } else {
            "recorded"
        }
    );
    println!(
        "temperature   {}",
        if rec.has_temperature {
            "recorded"
        } else {
            "absent"
        }
    );
    Ok(())
}
