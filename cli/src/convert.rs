//! `mrtwin convert IN OUT`: a recording from CSV (PHYSICS.md format) to a rosbag2 MCAP
//! bag or back, chosen by the paths: a directory, a `.mcap` file or a file starting with
//! the MCAP magic is a bag; OUT ending in `.csv` is CSV, in `.mcap` a bare MCAP file,
//! anything else a bag directory. Bag to bag copies every message (unknown topics too)
//! into a finished bag: the way to give a crashed recording its summary back.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use bridge::bag::{self, BagWriter, BagWriterOptions, RawMessages};
use bridge::qos::Reliability;
use bridge::Recording;
use clap::Args;

/// Arguments of `mrtwin convert`.
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Input: CSV recording, bag directory or .mcap file.
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// Output: FILE.csv, FILE.mcap, or a bag directory (must not exist or be empty).
    #[arg(value_name = "OUT")]
    pub output: PathBuf,
    /// Damper name for a bag: namespace of `/<name>/sensor/sample` and the frame_id.
    #[arg(long, value_name = "NAME", default_value = "damper")]
    pub name: String,
}

/// What an output path is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    /// `.csv`.
    Csv,
    /// `.mcap`.
    Mcap,
    /// A rosbag2 directory.
    BagDir,
}

/// The kind of an output path, by its extension.
pub fn output_kind(path: &Path) -> OutputKind {
    match path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
    {
        Some(e) if e == "csv" => OutputKind::Csv,
        Some(e) if e == "mcap" => OutputKind::Mcap,
        _ => OutputKind::BagDir,
    }
}

/// Write a recording to `path` as [`output_kind`] says (CSV through `write_csv`, else a
/// bag with `/<name>/sensor/sample`); returns a description of what was written.
pub fn write_output(path: &Path, rec: &Recording, name: &str) -> Result<&'static str> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create directory {}", dir.display()))?;
    }
    Ok(match output_kind(path) {
        OutputKind::Csv => {
            bridge::write_csv(path, rec)?;
            "CSV recording"
        }
        OutputKind::Mcap => {
            bag::write_recording_mcap(path, rec, name)?;
            "MCAP file"
        }
        OutputKind::BagDir => {
            bag::write_recording(path, rec, name)?;
            "rosbag2 bag (MCAP storage)"
        }
    })
}

/// Run the subcommand.
pub fn run(args: &ConvertArgs) -> Result<()> {
    let in_bag = bridge::is_bag_path(&args.input);
    let out_kind = output_kind(&args.output);
    if !in_bag && out_kind == OutputKind::Csv {
        bail!(
            "{} and {} are both CSV: convert turns CSV into a bag or a bag into CSV",
            args.input.display(),
            args.output.display()
        );
    }
    if in_bag && out_kind != OutputKind::Csv {
        let n = copy_bag(&args.input, &args.output)?;
        eprintln!(
            "convert: copied {n} messages from {} to {}",
            args.input.display(),
            args.output.display()
        );
        return Ok(());
    }
    let rec = if in_bag {
        let contents = bag::read_bag(&args.input)?;
        report_contents(&contents);
        bag::recording_from_contents(&contents)?
    } else {
        bridge::read_csv(&args.input)?
    };
    let what = write_output(&args.output, &rec, &args.name)?;
    eprintln!(
        "convert: {} samples from {} to {what} {}",
        rec.samples.len(),
        args.input.display(),
        args.output.display()
    );
    Ok(())
}

/// Tell on stderr what a bag read skipped or recovered.
pub fn report_contents(c: &bag::BagContents) {
    for s in &c.skipped {
        eprintln!(
            "note: skipped topic {} ({}): {} messages, {}",
            s.name, s.type_name, s.count, s.reason
        );
    }
    for n in &c.notes {
        eprintln!("note: {n}");
    }
}

/// Copy every message of a bag into a new, finished bag.
fn copy_bag(input: &Path, output: &Path) -> Result<u64> {
    let mut raw = RawMessages::open(input)?;
    let options = BagWriterOptions::default();
    let mut w = match output_kind(output) {
        OutputKind::Mcap => BagWriter::create_mcap(output, options)?,
        _ => BagWriter::create(output, options)?,
    };
    let mut n = 0;
    for m in raw.by_ref() {
        let m = m?;
        let ch = &m.channel;
        let reliability = match &ch.qos {
            Some(q) if q.contains("reliability: 2") || q.contains("best_effort") => {
                Reliability::BestEffort
            }
            _ => Reliability::Reliable,
        };
        w.write(
            &ch.topic,
            &ch.type_name,
            &ch.definition,
            reliability,
            m.log_time_ns,
            m.publish_time_ns,
            &m.data,
        )?;
        n += 1;
    }
    for note in raw.notes() {
        eprintln!("note: {note}");
    }
    w.finish()?;
    Ok(n)
}
