//! `mrtwin info`: what a recording holds — samples, duration, sample rate, gaps, current
//! levels (or, for a continuously varying current, its range, percentiles and histogram),
//! force range, and stretches where a channel is stuck at one value — after the strict checks of the CSV reader (NaN, unsorted time,
//! missing columns and millimetres for metres are errors naming the line or column).
//!
//! For a bag (directory or `.mcap`): its files and metadata, then per topic the type,
//! message count, duration, median rate, largest gap between log times and the number of
//! gaps longer than twice the median period; topics mrtwin skips; recovery notes
//! (truncated or unfinished files); and the recording summary of `sensor/sample`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;

/// Arguments of `mrtwin info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// A CSV recording in the format of PHYSICS.md, a rosbag2 bag directory or a .mcap file.
    #[arg(value_name = "FILE.csv|BAG")]
    pub input: PathBuf,
}

/// Print a summary of a recording.
pub fn run(args: &InfoArgs) -> Result<()> {
    if bridge::is_bag_path(&args.input) {
        return bag_info(&args.input);
    }
    let rec = bridge::csv::read_csv(&args.input)
        .with_context(|| format!("cannot use {} as a recording", args.input.display()))?;
    print_recording(&rec, &args.input);
    Ok(())
}

/// Largest gap and the number of gaps > 2× the median period of sorted times \[ns\];
/// with the median period. `None` with fewer than 2 times.
pub fn gap_stats(times_ns: &[u64]) -> Option<(f64, f64, usize)> {
    if times_ns.len() < 2 {
        return None;
    }
    let mut t = times_ns.to_vec();
    t.sort_unstable();
    let d: Vec<u64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = d.clone();
    sorted.sort_unstable();
    let median = sorted[sorted.len() / 2];
    let largest = *sorted.last().unwrap_or(&0);
    let long = d.iter().filter(|&&x| x > 2 * median).count();
    Some((median as f64 * 1e-9, largest as f64 * 1e-9, long))
}

fn bag_info(path: &Path) -> Result<()> {
    let c = bridge::bag::read_bag(path)
        .with_context(|| format!("cannot use {} as a bag", path.display()))?;
    println!("bag           {}", path.display());
    for f in &c.files {
        let size = std::fs::metadata(f).map(|m| m.len()).unwrap_or(0);
        println!("file          {} ({size} bytes)", f.display());
    }
    match &c.metadata {
        Some(m) => println!(
            "metadata      rosbag2 version {}, storage {}, {} messages, distro {}",
            m.version,
            m.storage_identifier,
            m.message_count,
            if m.ros_distro.is_empty() {
                "?"
            } else {
                &m.ros_distro
            }
        ),
        None => println!("metadata      none (bare MCAP)"),
    }
    let all: Vec<u64> = c
        .topics
        .iter()
        .flat_map(|t| t.log_times_ns.iter().copied())
        .collect();
    let (first, last) = (all.iter().min(), all.iter().max());
    println!("messages      {}", c.message_count());
    if let (Some(a), Some(b)) = (first, last) {
        println!(
            "time          {:.6} s to {:.6} s ({:.3} s)",
            *a as f64 * 1e-9,
            *b as f64 * 1e-9,
            (b - a) as f64 * 1e-9
        );
    }
    println!("topics        {}", c.topics.len());
    for t in &c.topics {
        let mut line = format!("  {}  {}  {} msgs", t.name, t.type_name, t.count);
        if let Some((median, largest, long)) = gap_stats(&t.log_times_ns) {
            let (a, b) = (
                t.log_times_ns.iter().min().unwrap(),
                t.log_times_ns.iter().max().unwrap(),
            );
            line.push_str(&format!(
                ", {:.3} s, {:.1} Hz, largest gap {:.3} ms, {long} gaps > 2x median",
                (b - a) as f64 * 1e-9,
                if median > 0.0 {
                    1.0 / median
                } else {
                    f64::INFINITY
                },
                largest * 1e3
            ));
        }
        if t.known.is_none() {
            line.push_str("  [skipped]");
        }
        println!("{line}");
    }
    for s in &c.skipped {
        println!(
            "skipped       {} ({}): {} messages, {}",
            s.name, s.type_name, s.count, s.reason
        );
    }
    for n in &c.notes {
        println!("note          {n}");
    }
    if c.topics
        .iter()
        .any(|t| t.known == Some(bridge::transport::Topic::Sample))
    {
        match bridge::bag::recording_from_contents(&c) {
            Ok(rec) => {
                println!("-- sensor/sample as a recording --");
                print_recording(&rec, path);
            }
            Err(e) => println!("note          not usable as a recording: {e}"),
        }
    }
    Ok(())
}

fn print_recording(rec: &bridge::Recording, input: &Path) {
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
    println!("recording     {}", input.display());
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
    let currents: Vec<f64> = s.iter().map(|x| x.current_a).collect();
    println!("currents      {}", current_summary(&currents));
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
    let stuck = stuck_stretches(rec, median_dt);
    if stuck.is_empty() {
        println!("stuck         none (no channel repeats one value for 20 samples and 20 ms)");
    }
    for line in stuck {
        println!("stuck         {line}");
    }
}

/// Most current levels listed one by one; more are summarised as a range.
const MAX_LISTED_LEVELS: usize = 12;

/// The current column in one line: its levels (to 1 mA, in order of appearance) when there
/// are few, else a continuously varying current as its range, percentiles and a histogram.
pub fn current_summary(currents: &[f64]) -> String {
    let mut levels: Vec<f64> = Vec::new();
    for c in currents {
        let level = (c * 1000.0).round() / 1000.0;
        if !levels.contains(&level) {
            levels.push(level);
            if levels.len() > MAX_LISTED_LEVELS {
                break;
            }
        }
    }
    if levels.len() <= MAX_LISTED_LEVELS {
        let listed: Vec<String> = levels.iter().map(|c| format!("{c}")).collect();
        return format!("{} A", listed.join(", "));
    }
    let mut sorted = currents.to_vec();
    sorted.sort_by(f64::total_cmp);
    let q = |p: f64| numerics::stats::quantile(&sorted, p).unwrap_or(f64::NAN);
    let (lo, hi) = (sorted[0], sorted[sorted.len() - 1]);
    const BINS: usize = 8;
    let mut counts = [0usize; BINS];
    for c in &sorted {
        let k = if hi > lo {
            (((c - lo) / (hi - lo)) * BINS as f64) as usize
        } else {
            0
        };
        counts[k.min(BINS - 1)] += 1;
    }
    let histogram: Vec<String> = counts
        .iter()
        .map(|k| format!("{:.0}", 100.0 * *k as f64 / sorted.len() as f64))
        .collect();
    format!(
        "continuous, {lo:.3} to {hi:.3} A; percentiles 5/25/50/75/95 %: {:.3} / {:.3} / {:.3} / {:.3} / {:.3} A; \
         % of samples in {BINS} equal bins: {}",
        q(0.05),
        q(0.25),
        q(0.5),
        q(0.75),
        q(0.95),
        histogram.join(" ")
    )
}

/// Stretches where the displacement, force or a recorded velocity repeats one value (a
/// clipped or dead channel; numerics::signal), one line each.
pub fn stuck_stretches(rec: &bridge::Recording, dt: f64) -> Vec<String> {
    let s = &rec.samples;
    let mut channels: Vec<(&str, Vec<f64>)> = vec![
        (
            "displacement_m",
            s.iter().map(|x| x.displacement_m).collect(),
        ),
        ("force_N", s.iter().map(|x| x.force_n).collect()),
    ];
    if !rec.velocity_derived {
        channels.push(("velocity_m_s", s.iter().map(|x| x.velocity_m_s).collect()));
    }
    let values: Vec<&[f64]> = channels.iter().map(|c| c.1.as_slice()).collect();
    numerics::signal::stuck_runs(dt, &values)
        .into_iter()
        .map(|(k, r)| {
            format!(
                "{} at {} from {:.4} s to {:.4} s ({} samples)",
                channels[k].0,
                values[k][r.start],
                s[r.start].time_s,
                s[r.end - 1].time_s,
                r.len()
            )
        })
        .collect()
}
