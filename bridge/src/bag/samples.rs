//! A [`Recording`] as the `sensor/sample` topic of a bag (`mrtwin_msgs/msg/DamperSample`)
//! and back.
//!
//! Time: a sample's `time_s` becomes its header stamp (rounded to the nanosecond), which
//! is also the message's log and publish time; reading takes `time_s` from the stamp.
//! So times round-trip to within 1 ns, every other field bit for bit. A temperature the
//! recording lacks travels as NaN (the .msg convention) and comes back as `None`.

use std::path::Path;

use msgs::{DamperSample, Header};

use crate::csv::{Recording, Sample};
use crate::transport::{Message, Topic};

use super::reader::{read_bag, BagContents};
use super::writer::{BagSummary, BagWriter, BagWriterOptions};
use super::BagError;

/// Read the samples of the bag's `sensor/sample` topic (any namespace) as a recording.
/// Other topics are ignored; truncated files give what they hold (see
/// [`recording_from_contents`] to see the notes too).
pub fn read_recording(path: &Path) -> Result<Recording, BagError> {
    recording_from_contents(&read_bag(path)?)
}

/// The recording of the `sensor/sample` messages of `contents`: one sample topic only,
/// sorted by stamp, strictly increasing, finite values.
pub fn recording_from_contents(contents: &BagContents) -> Result<Recording, BagError> {
    let path = &contents.path;
    let no_data = |reason: String| BagError::NoData {
        path: path.clone(),
        reason,
    };
    let names: Vec<&str> = contents
        .topics
        .iter()
        .filter(|t| t.known == Some(Topic::Sample))
        .map(|t| t.name.as_str())
        .collect();
    match names.len() {
        0 => {
            let seen: Vec<String> = contents
                .topics
                .iter()
                .map(|t| format!("{} ({}, {})", t.name, t.type_name, t.count))
                .collect();
            let mut reason = format!(
                "no sensor/sample messages of type {} (topics: {})",
                Topic::Sample.type_name(),
                if seen.is_empty() {
                    "none".to_string()
                } else {
                    seen.join(", ")
                }
            );
            if !contents.notes.is_empty() {
                reason.push_str("; ");
                reason.push_str(&contents.notes.join("; "));
            }
            return Err(no_data(reason));
        }
        1 => {}
        _ => {
            return Err(no_data(format!(
                "several sample topics ({}); a recording holds one damper",
                names.join(", ")
            )))
        }
    }
    let mut samples: Vec<(i64, usize, &DamperSample)> = contents
        .messages
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match &m.message {
            Message::Sample(s) => Some((s.header.stamp.as_nanos(), i, s)),
            _ => None,
        })
        .collect();
    samples.sort_by_key(|(t, i, _)| (*t, *i));
    for w in samples.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(no_data(format!(
                "samples {} and {} have the same stamp {} s; time must strictly increase",
                w[0].1,
                w[1].1,
                w[0].2.header.stamp.as_secs_f64()
            )));
        }
    }
    let mut out = Recording {
        samples: Vec::with_capacity(samples.len()),
        velocity_derived: false,
        has_temperature: false,
        source: path.display().to_string(),
    };
    for (_, i, s) in samples {
        for (field, v) in [
            ("displacement", s.displacement),
            ("velocity", s.velocity),
            ("force", s.force),
            ("current", s.current),
        ] {
            if !v.is_finite() {
                return Err(no_data(format!(
                    "message {i} on {}: {field} is {v}, not a finite number",
                    names[0]
                )));
            }
        }
        let temperature_c = s.temperature.is_finite().then_some(s.temperature);
        out.has_temperature |= temperature_c.is_some();
        out.samples.push(Sample {
            time_s: s.header.stamp.as_secs_f64(),
            displacement_m: s.displacement,
            velocity_m_s: s.velocity,
            force_n: s.force,
            current_a: s.current,
            temperature_c,
        });
    }
    Ok(out)
}

/// Write `rec` as a bag directory `dir` holding `/<damper_name>/sensor/sample`
/// (frame_id = `damper_name`).
pub fn write_recording(
    dir: &Path,
    rec: &Recording,
    damper_name: &str,
) -> Result<BagSummary, BagError> {
    check_times(dir, rec)?;
    let w = BagWriter::create(dir, BagWriterOptions::default())?;
    write_samples(w, rec, damper_name)
}

/// Like [`write_recording`], into a bare `.mcap` file.
pub fn write_recording_mcap(
    path: &Path,
    rec: &Recording,
    damper_name: &str,
) -> Result<BagSummary, BagError> {
    check_times(path, rec)?;
    let w = BagWriter::create_mcap(path, BagWriterOptions::default())?;
    write_samples(w, rec, damper_name)
}

fn check_times(path: &Path, rec: &Recording) -> Result<(), BagError> {
    if let Some(s) = rec
        .samples
        .iter()
        .find(|s| !s.time_s.is_finite() || s.time_s < 0.0)
    {
        return Err(BagError::write(
            path,
            format!(
                "sample time {} s is negative or not finite; bag times start at 0",
                s.time_s
            ),
        ));
    }
    Ok(())
}

fn write_samples(
    mut w: BagWriter,
    rec: &Recording,
    damper_name: &str,
) -> Result<BagSummary, BagError> {
    for s in &rec.samples {
        let msg = DamperSample {
            header: Header::at(s.time_s, damper_name),
            displacement: s.displacement_m,
            velocity: s.velocity_m_s,
            force: s.force_n,
            current: s.current_a,
            temperature: s.temperature_c.unwrap_or(f64::NAN),
        };
        let t = msg.header.stamp.as_nanos() as u64;
        w.write_message(damper_name, &Message::Sample(msg), t)?;
    }
    w.finish()
}
