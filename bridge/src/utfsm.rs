//! Readers for the real MR damper recordings from the UTFSM test press
//! (`shared/data/real/maurel-utfsm`, see its README).
//!
//! # Preprocessed files (`preprocessed/*.txt`)
//! Whitespace-separated, no header, four columns: time (s), displacement (mm),
//! velocity (mm/s), force (N). The coil current is only in the file name
//! (`25mm0x5Hz1A.txt`: 25 mm, 0.5 Hz, 1 A; `x` is the decimal point).
//! [`read_preprocessed`] converts to SI. What the 30 files actually contain
//! (checked on every file): CRLF line endings and one trailing line break, time
//! starting at exactly 0 with a constant step (1 ms for the 1 and 3 Hz tests,
//! 5 ms otherwise), no repeated timestamps, no NaN, mean-free displacement, and
//! a velocity column equal to the backward difference of the displacement. The
//! reader still checks every row and rejects NaN/infinite values and
//! non-increasing time with the line number.
//!
//! # Raw logger files (`raw/ME*.txt`)
//! The data logger's text export: a header (`Header Size: 7`, `Sampling
//! Interval`, `Sample Count`, …) whose last line is
//! `Sample Number, Date/Time, CHANNEL0, CHANNEL1, Events`, then one row per
//! sample in volts. Each file holds the five current levels (0, 0.25, 0.5,
//! 0.75, 1 A) one after another. The README says the levels are separated by
//! rows of NaN; the files themselves have no NaN: the logger marks the breaks
//! with `DAQ Pause` (last sample of a level) and `DAQ Resume` (first sample of
//! the next) in the Events column, while the sample number keeps counting (the
//! NaN rows are most likely what the original MATLAB import made of those
//! event rows). [`parse_raw`] splits on both: a `DAQ Pause`/`DAQ Resume` event,
//! a row with a NaN channel or a row whose sample number is NaN ends a segment.
//!
//! Scaling: force = V × 980.665 N, displacement = V × 10 mm. Channel order
//! depends on the test frequency ([`ChannelLayout::for_frequency`]). The raw
//! signals keep what the preprocessing removed: the displacement sensor's
//! offset (the piston rests near −30 mm, so raw displacement oscillates around
//! about −0.03 m, not 0), a force offset of a few tens of N, the sharp corners,
//! and idle stretches before and after the motion in each segment.

use std::fs;
use std::path::Path;

use crate::csv::{derive_velocity, parse_finite, Recording, RecordingError, Sample};

/// Force scaling of the raw files: N per volt.
pub const FORCE_N_PER_VOLT: f64 = 980.665;
/// Displacement scaling of the raw files: m per volt (10 mm/V).
pub const DISPLACEMENT_M_PER_VOLT: f64 = 0.01;
/// The coil currents of the five segments of a raw file, in file order (A).
pub const CURRENT_LEVELS_A: [f64; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];

const PREPROCESSED_NAME: &str =
    "<amplitude>mm<frequency>Hz<current>A with `x` as decimal point, e.g. 25mm0x5Hz1A.txt";
const RAW_NAME: &str =
    "ME<amplitude>mm<frequency>Hz with `x` as decimal point, e.g. ME25mm0x5Hz.txt";
const RAW_COLUMNS: [&str; 5] = [
    "Sample Number",
    "Date/Time",
    "CHANNEL0",
    "CHANNEL1",
    "Events",
];
const PREPROCESSED_COLUMNS: [&str; 4] = [
    "1 (time s)",
    "2 (displacement mm)",
    "3 (velocity mm/s)",
    "4 (force N)",
];

/// Test parameters encoded in a preprocessed file name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TestName {
    /// Nominal sinusoid amplitude in m.
    pub amplitude_m: f64,
    /// Sinusoid frequency in Hz.
    pub frequency_hz: f64,
    /// Coil current in A.
    pub current_a: f64,
}

/// Test parameters encoded in a raw file name (`ME25mm0x5Hz`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawTestName {
    /// Nominal sinusoid amplitude in m.
    pub amplitude_m: f64,
    /// Sinusoid frequency in Hz.
    pub frequency_hz: f64,
}

/// One current level of a raw file.
#[derive(Debug, Clone, PartialEq)]
pub struct RawSegment {
    /// Coil current in A.
    pub current_a: f64,
    /// The samples, in SI, time from 0 at the segment's first sample, velocity
    /// derived by central differences.
    pub recording: Recording,
}

/// Which logger channel carries which signal in a raw file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChannelLayout {
    /// CHANNEL0 is force, CHANNEL1 displacement.
    ForceOnChannel0,
    /// CHANNEL0 is displacement, CHANNEL1 force.
    DisplacementOnChannel0,
}

impl ChannelLayout {
    /// The layout used for a test frequency, per the README (from the original
    /// script): force on CHANNEL0 at 5, 0.5, 0.25 and 0.1 Hz, displacement on
    /// CHANNEL0 at 1 and 3 Hz. `None` for any other frequency, since nothing
    /// says which layout it would have used.
    pub fn for_frequency(frequency_hz: f64) -> Option<Self> {
        let is = |f: f64| (frequency_hz - f).abs() < 1e-9;
        if [5.0, 0.5, 0.25, 0.1].into_iter().any(is) {
            Some(Self::ForceOnChannel0)
        } else if [1.0, 3.0].into_iter().any(is) {
            Some(Self::DisplacementOnChannel0)
        } else {
            None
        }
    }
}

/// Parses a number written with `x` as decimal point (`0x25` = 0.25):
/// digits, optionally followed by `x` and more digits.
fn parse_x_decimal(text: &str) -> Option<f64> {
    let (int, frac) = match text.split_once('x') {
        Some((i, f)) => (i, Some(f)),
        None => (text, None),
    };
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(int) || !frac.is_none_or(digits) {
        return None;
    }
    let value: f64 = match frac {
        Some(f) => format!("{int}.{f}").parse().ok()?,
        None => int.parse().ok()?,
    };
    value.is_finite().then_some(value)
}

/// Parses `<amplitude>mm<frequency>Hz` into (amplitude m, frequency Hz).
fn parse_amplitude_frequency(text: &str) -> Option<(f64, f64)> {
    let (amplitude, frequency) = text.split_once("mm")?;
    let amplitude_mm = parse_x_decimal(amplitude)?;
    let frequency_hz = parse_x_decimal(frequency.strip_suffix("Hz")?)?;
    (amplitude_mm > 0.0 && frequency_hz > 0.0).then_some((amplitude_mm / 1000.0, frequency_hz))
}

/// Parses a preprocessed file stem such as `25mm0x5Hz1A` (25 mm, 0.5 Hz,
/// 1 A; `x` is the decimal point). `None` if the stem does not follow that
/// scheme or the amplitude or frequency is zero.
pub fn parse_test_name(file_stem: &str) -> Option<TestName> {
    let (head, current) = file_stem.strip_suffix('A')?.rsplit_once("Hz")?;
    let (amplitude_m, frequency_hz) = parse_amplitude_frequency(&format!("{head}Hz"))?;
    Some(TestName {
        amplitude_m,
        frequency_hz,
        current_a: parse_x_decimal(current)?,
    })
}

/// Parses a raw file stem such as `ME5mm3Hz` (5 mm, 3 Hz).
pub fn parse_raw_test_name(file_stem: &str) -> Option<RawTestName> {
    let (amplitude_m, frequency_hz) = parse_amplitude_frequency(file_stem.strip_prefix("ME")?)?;
    Some(RawTestName {
        amplitude_m,
        frequency_hz,
    })
}

/// Reads a whole file, naming the path on failure.
fn read_text(path: &Path) -> Result<String, RecordingError> {
    fs::read_to_string(path).map_err(|error| RecordingError::Io {
        path: path.to_owned(),
        action: "read",
        error,
    })
}

/// The file stem of `path` as text, or a [`RecordingError::BadFileName`].
fn stem<'a>(path: &'a Path, expected: &'static str) -> Result<&'a str, RecordingError> {
    path.file_stem()
        .and_then(|s| s.to_str())
        .ok_or_else(|| RecordingError::BadFileName {
            file: path.display().to_string(),
            expected,
        })
}

/// Reads a preprocessed file, converting to SI; the current comes from the
/// file name ([`parse_test_name`]).
///
/// The velocity is the file's own (backward difference of the smoothed
/// displacement, so `velocity_derived` is false); there is no temperature.
pub fn read_preprocessed(path: &Path) -> Result<Recording, RecordingError> {
    let name = parse_test_name(stem(path, PREPROCESSED_NAME)?).ok_or_else(|| {
        RecordingError::BadFileName {
            file: path.display().to_string(),
            expected: PREPROCESSED_NAME,
        }
    })?;
    parse_preprocessed(
        &read_text(path)?,
        &path.display().to_string(),
        name.current_a,
    )
}

/// Parses the text of a preprocessed file (see the module docs); `source`
/// names it in errors (line numbers are 1-based, there is no header) and
/// `current_a` is the coil current for every sample.
pub fn parse_preprocessed(
    text: &str,
    source: &str,
    current_a: f64,
) -> Result<Recording, RecordingError> {
    if text.trim().is_empty() {
        return Err(RecordingError::Empty {
            file: source.to_owned(),
        });
    }
    let mut samples: Vec<Sample> = Vec::new();
    let mut previous_line = 0;
    let mut blank_line = None;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        if raw.trim().is_empty() {
            blank_line.get_or_insert(line);
            continue;
        }
        if let Some(blank) = blank_line {
            return Err(RecordingError::BlankLine {
                file: source.to_owned(),
                line: blank,
            });
        }
        let fields: Vec<&str> = raw.split_whitespace().collect();
        if fields.len() != PREPROCESSED_COLUMNS.len() {
            return Err(RecordingError::FieldCount {
                file: source.to_owned(),
                line,
                expected: PREPROCESSED_COLUMNS.len(),
                found: fields.len(),
            });
        }
        let mut values = [0.0; 4];
        for ((value, field), column) in values.iter_mut().zip(&fields).zip(PREPROCESSED_COLUMNS) {
            *value = parse_finite(field, source, line, column)?;
        }
        let [time_s, displacement_mm, velocity_mm_s, force_n] = values;
        if let Some(previous) = samples.last() {
            if time_s <= previous.time_s {
                return Err(RecordingError::TimeNotIncreasing {
                    file: source.to_owned(),
                    line,
                    time_s,
                    previous_line,
                    previous_s: previous.time_s,
                });
            }
        }
        samples.push(Sample {
            time_s,
            displacement_m: displacement_mm / 1000.0,
            velocity_m_s: velocity_mm_s / 1000.0,
            force_n,
            current_a,
            temperature_c: None,
        });
        previous_line = line;
    }
    Ok(Recording {
        samples,
        velocity_derived: false,
        has_temperature: false,
        source: source.to_owned(),
    })
}

/// Reads a raw logger file: frequency (hence channel layout) from the file
/// name ([`parse_raw_test_name`]), then [`parse_raw`].
pub fn read_raw(path: &Path) -> Result<Vec<RawSegment>, RecordingError> {
    let file = path.display().to_string();
    let name =
        parse_raw_test_name(stem(path, RAW_NAME)?).ok_or_else(|| RecordingError::BadFileName {
            file: file.clone(),
            expected: RAW_NAME,
        })?;
    let layout = ChannelLayout::for_frequency(name.frequency_hz).ok_or_else(|| {
        RecordingError::BadFileName {
            file: file.clone(),
            expected: "a test frequency with a known channel layout (0.1, 0.25, 0.5, 1, 3 or 5 Hz)",
        }
    })?;
    parse_raw(&read_text(path)?, &file, layout)
}

/// Builds a [`RecordingError::Format`].
fn format_err(file: &str, line: usize, message: String) -> RecordingError {
    RecordingError::Format {
        file: file.to_owned(),
        line,
        message,
    }
}

/// The parsed header of a raw file.
struct RawHeader {
    /// Number of header lines (data start on the next line).
    size: usize,
    /// Seconds between samples.
    interval_s: f64,
    /// Declared sample count and the line declaring it.
    count: Option<(usize, usize)>,
}

/// Parses the `key: value` header of a raw file.
fn parse_raw_header(lines: &[&str], file: &str) -> Result<RawHeader, RecordingError> {
    let key_value = |line: usize| -> Option<(&str, &str)> {
        let (k, v) = lines.get(line - 1)?.split_once(':')?;
        Some((k.trim(), v.trim()))
    };
    let size = match key_value(1) {
        Some(("Header Size", v)) => v.parse::<usize>().ok().filter(|&n| n >= 2),
        _ => None,
    }
    .ok_or_else(|| {
        format_err(
            file,
            1,
            "expected `Header Size: <n>` (n ≥ 2) as the first line of a data-logger export".into(),
        )
    })?;
    let columns_line = lines.get(size - 1).ok_or_else(|| {
        format_err(
            file,
            lines.len(),
            format!("file ends inside the {size}-line header"),
        )
    })?;
    let columns: Vec<&str> = columns_line.split(',').map(str::trim).collect();
    if columns != RAW_COLUMNS {
        return Err(format_err(
            file,
            size,
            format!(
                "expected the column header `{}`, found `{}`",
                RAW_COLUMNS.join(", "),
                columns_line.trim()
            ),
        ));
    }
    let mut interval_s = None;
    let mut count = None;
    for line in 2..size {
        match key_value(line) {
            Some(("Sampling Interval", v)) => {
                let dt = v
                    .parse::<f64>()
                    .ok()
                    .filter(|dt| dt.is_finite() && *dt > 0.0);
                interval_s = Some(dt.ok_or_else(|| {
                    format_err(
                        file,
                        line,
                        format!("Sampling Interval {v:?} is not a positive number of seconds"),
                    )
                })?);
            }
            Some(("Sample Count", v)) => {
                let n = v.parse::<usize>().map_err(|_| {
                    format_err(
                        file,
                        line,
                        format!("Sample Count {v:?} is not a whole number"),
                    )
                })?;
                count = Some((n, line));
            }
            _ => {}
        }
    }
    let interval_s = interval_s.ok_or_else(|| {
        format_err(
            file,
            size,
            format!("the header (lines 1 to {size}) has no `Sampling Interval`"),
        )
    })?;
    Ok(RawHeader {
        size,
        interval_s,
        count,
    })
}

/// Parses the text of a raw logger file into its five current levels (see
/// the module docs); `source` names it in errors.
///
/// Time is `(sample number − first sample number of the segment) × Sampling
/// Interval`, so each segment starts at 0 and a gap in the sample numbers
/// shows as uneven sampling. Errors: malformed header, wrong field count, a
/// channel that is not a number (NaN is a segment separator, infinity is
/// rejected), a sample number that does not increase, a `Sample Count` that
/// disagrees with the number of rows, or a segment count other than five.
pub fn parse_raw(
    text: &str,
    source: &str,
    layout: ChannelLayout,
) -> Result<Vec<RawSegment>, RecordingError> {
    let lines: Vec<&str> = text.lines().collect();
    if text.trim().is_empty() {
        return Err(RecordingError::Empty {
            file: source.to_owned(),
        });
    }
    let header = parse_raw_header(&lines, source)?;

    // Each segment: (sample number, CHANNEL0 V, CHANNEL1 V, line) rows.
    let mut segments: Vec<Vec<(u64, f64, f64, usize)>> = vec![Vec::new()];
    let mut previous: Option<(u64, usize)> = None;
    let mut rows = 0;
    let mut blank_line = None;
    for (index, raw) in lines.iter().enumerate().skip(header.size) {
        let line = index + 1;
        if raw.trim().is_empty() {
            blank_line.get_or_insert(line);
            continue;
        }
        if let Some(blank) = blank_line {
            return Err(RecordingError::BlankLine {
                file: source.to_owned(),
                line: blank,
            });
        }
        rows += 1;
        let fields: Vec<&str> = raw.split(',').map(str::trim).collect();
        if !(4..=5).contains(&fields.len()) {
            return Err(RecordingError::FieldCount {
                file: source.to_owned(),
                line,
                expected: RAW_COLUMNS.len(),
                found: fields.len(),
            });
        }
        if fields[0].eq_ignore_ascii_case("nan") {
            // A separator row without even a sample number.
            if segments.last().is_some_and(|s| !s.is_empty()) {
                segments.push(Vec::new());
            }
            continue;
        }
        let number: u64 = fields[0].parse().map_err(|_| RecordingError::NotANumber {
            file: source.to_owned(),
            line,
            column: RAW_COLUMNS[0].to_owned(),
            value: fields[0].to_owned(),
        })?;
        if let Some((prev, prev_line)) = previous {
            if number <= prev {
                return Err(format_err(
                    source,
                    line,
                    format!("sample number {number} is not after {prev} on line {prev_line}"),
                ));
            }
        }
        previous = Some((number, line));
        let channel = |i: usize| -> Result<f64, RecordingError> {
            let text = fields[i];
            match text.parse::<f64>() {
                Ok(v) if v.is_nan() => Ok(v),
                _ => parse_finite(text, source, line, RAW_COLUMNS[i]),
            }
        };
        let (ch0, ch1) = (channel(2)?, channel(3)?);
        let event = fields.get(4).copied().unwrap_or("");
        let open = segments.last().is_some_and(|s| !s.is_empty());
        if open && (ch0.is_nan() || ch1.is_nan() || event == "DAQ Resume") {
            segments.push(Vec::new());
        }
        if ch0.is_nan() || ch1.is_nan() {
            continue;
        }
        if let Some(segment) = segments.last_mut() {
            segment.push((number, ch0, ch1, line));
        }
        if event == "DAQ Pause" {
            segments.push(Vec::new());
        }
    }
    if let Some((count, count_line)) = header.count {
        if count != rows {
            return Err(format_err(
                source,
                count_line,
                format!("the header says Sample Count {count} but the file has {rows} data rows"),
            ));
        }
    }
    segments.retain(|s| !s.is_empty());
    if segments.len() != CURRENT_LEVELS_A.len() {
        return Err(RecordingError::SegmentCount {
            file: source.to_owned(),
            expected: CURRENT_LEVELS_A.len(),
            found: segments.len(),
        });
    }

    segments
        .iter()
        .zip(CURRENT_LEVELS_A)
        .enumerate()
        .map(|(k, (rows, current_a))| {
            Ok(RawSegment {
                current_a,
                recording: build_segment(
                    rows,
                    current_a,
                    header.interval_s,
                    layout,
                    source,
                    &format!(
                        "{source} segment {} of {} ({current_a} A)",
                        k + 1,
                        CURRENT_LEVELS_A.len()
                    ),
                )?,
            })
        })
        .collect()
}

/// Scales one segment's raw rows (with their lines in `file`) to SI and derives the
/// velocity; a value that is not finite once scaled (volts near f64::MAX, a huge sampling
/// interval) is an error naming its line.
fn build_segment(
    rows: &[(u64, f64, f64, usize)],
    current_a: f64,
    interval_s: f64,
    layout: ChannelLayout,
    file: &str,
    source: &str,
) -> Result<Recording, RecordingError> {
    let first = rows.first().map_or(0, |r| r.0);
    let mut samples: Vec<Sample> = rows
        .iter()
        .map(|&(number, ch0, ch1, _)| {
            let (force_v, displacement_v) = match layout {
                ChannelLayout::ForceOnChannel0 => (ch0, ch1),
                ChannelLayout::DisplacementOnChannel0 => (ch1, ch0),
            };
            Sample {
                time_s: (number - first) as f64 * interval_s,
                displacement_m: displacement_v * DISPLACEMENT_M_PER_VOLT,
                velocity_m_s: 0.0,
                force_n: force_v * FORCE_N_PER_VOLT,
                current_a,
                temperature_c: None,
            }
        })
        .collect();
    let t: Vec<f64> = samples.iter().map(|s| s.time_s).collect();
    let x: Vec<f64> = samples.iter().map(|s| s.displacement_m).collect();
    for ((s, v), row) in samples.iter_mut().zip(derive_velocity(&t, &x)).zip(rows) {
        s.velocity_m_s = v;
        let scaled = [
            ("time", s.time_s, "s"),
            ("displacement", s.displacement_m, "m"),
            ("velocity", s.velocity_m_s, "m/s"),
            ("force", s.force_n, "N"),
        ];
        if let Some((name, value, unit)) = scaled.into_iter().find(|(_, v, _)| !v.is_finite()) {
            return Err(format_err(
                file,
                row.3,
                format!(
                    "sample {}: the {name} is {value} {unit} once scaled (CHANNEL0 {:e} V, \
                     CHANNEL1 {:e} V, Sampling Interval {interval_s:e} s); the values are out \
                     of range",
                    row.0, row.1, row.2
                ),
            ));
        }
    }
    Ok(Recording {
        samples,
        velocity_derived: true,
        has_temperature: false,
        source: source.to_owned(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn test_names_parse() {
        assert_eq!(
            parse_test_name("25mm0x5Hz1A"),
            Some(TestName {
                amplitude_m: 0.025,
                frequency_hz: 0.5,
                current_a: 1.0
            })
        );
        assert_eq!(
            parse_test_name("2mm5Hz0x25A"),
            Some(TestName {
                amplitude_m: 0.002,
                frequency_hz: 5.0,
                current_a: 0.25
            })
        );
        let t = parse_test_name("25mm0x1Hz0A").expect("valid");
        assert_eq!((t.frequency_hz, t.current_a), (0.1, 0.0));
        for bad in [
            "",
            "25mm0x5Hz",
            "25mm0x5Hz1",
            "mm0x5Hz1A",
            "25mm0x5HzA",
            "25mmHz1A",
            "25mm0x5x1Hz1A",
            "25mmx5Hz1A",
            "25mm5xHz1A",
            "0mm1Hz1A",
            "25mm0Hz1A",
            "ME25mm0x5Hz",
            "25 mm1Hz1A",
            "25mm1Hz1A.txt",
            "-2mm1Hz1A",
        ] {
            assert_eq!(parse_test_name(bad), None, "{bad:?}");
        }
        assert_eq!(
            parse_raw_test_name("ME5mm3Hz"),
            Some(RawTestName {
                amplitude_m: 0.005,
                frequency_hz: 3.0
            })
        );
        assert_eq!(
            parse_raw_test_name("ME25mm0x5Hz").map(|n| n.frequency_hz),
            Some(0.5)
        );
        assert_eq!(parse_raw_test_name("25mm0x5Hz"), None);
        assert_eq!(parse_raw_test_name("ME25mm0x5Hz1A"), None);
    }

    #[test]
    fn channel_layout_follows_readme() {
        use ChannelLayout::*;
        for (f, layout) in [
            (5.0, Some(ForceOnChannel0)),
            (0.5, Some(ForceOnChannel0)),
            (0.25, Some(ForceOnChannel0)),
            (0.1, Some(ForceOnChannel0)),
            (1.0, Some(DisplacementOnChannel0)),
            (3.0, Some(DisplacementOnChannel0)),
            (2.0, None),
        ] {
            assert_eq!(ChannelLayout::for_frequency(f), layout, "{f} Hz");
        }
    }

    fn pre_err(text: &str) -> String {
        parse_preprocessed(text, "10mm1Hz1A.txt", 1.0)
            .expect_err("expected an error")
            .to_string()
    }

    #[test]
    fn preprocessed_converts_to_si() {
        let text = "   0.0000000e+00  -2.4899864e-02  -1.1900000e+00  -1.9281989e+02\r\n   \
                    5.0000000e-03  -3.1899864e-02  -1.4000000e+00  -2.1691237e+02\r\n";
        let rec = parse_preprocessed(text, "f", 0.75).expect("valid");
        assert_eq!(rec.len(), 2);
        assert!(!rec.velocity_derived && !rec.has_temperature);
        let s = rec.samples[1];
        assert_eq!(s.time_s, 0.005);
        assert!((s.displacement_m + 3.1899864e-5).abs() < 1e-18);
        assert!((s.velocity_m_s + 1.4e-3).abs() < 1e-15);
        assert_eq!(s.force_n, -216.91237);
        assert_eq!(s.current_a, 0.75);
    }

    #[test]
    fn preprocessed_errors_name_line_and_column() {
        let msg = pre_err("0 1 2 3\n0.001 1 NaN 3\n");
        assert_eq!(
            msg,
            r#"10mm1Hz1A.txt line 2, column 3 (velocity mm/s): value "NaN" is not a finite number"#
        );
        let msg = pre_err("0 1 2 3\n0.001 1 2 x3\n");
        assert!(
            msg.contains("line 2, column 4 (force N): value \"x3\" is not a number"),
            "{msg}"
        );
        let msg = pre_err("0 1 2 3\n0.001 1 2\n");
        assert!(msg.contains("line 2: expected 4 fields, found 3"), "{msg}");
        let msg = pre_err("0 1 2 3\n0.001 1 2 3\n0.001 1 2 3\n");
        assert!(
            msg.contains("line 3: time 0.001 s is not after 0.001 s on line 2"),
            "{msg}"
        );
        let msg = pre_err("0 1 2 3\n\n0.001 1 2 3\n");
        assert!(msg.contains("line 2: blank line"), "{msg}");
        assert!(pre_err("\r\n").contains("10mm1Hz1A.txt: file is empty"));
    }

    #[test]
    fn read_errors_name_the_path() {
        let msg = read_preprocessed(Path::new("/no/such/dir/25mm0x5Hz1A.txt"))
            .expect_err("missing")
            .to_string();
        assert!(
            msg.starts_with("/no/such/dir/25mm0x5Hz1A.txt: cannot read"),
            "{msg}"
        );
        let msg = read_preprocessed(Path::new("/no/such/dir/foo.txt"))
            .expect_err("bad name")
            .to_string();
        assert!(msg.contains("foo.txt: file name does not match"), "{msg}");
        let msg = read_raw(Path::new("/no/such/ME2mm2Hz.txt"))
            .expect_err("unknown layout")
            .to_string();
        assert!(
            msg.contains("ME2mm2Hz.txt") && msg.contains("channel layout"),
            "{msg}"
        );
        let msg = read_raw(Path::new("/no/such/ME2mm5Hz.txt"))
            .expect_err("missing")
            .to_string();
        assert!(
            msg.starts_with("/no/such/ME2mm5Hz.txt: cannot read"),
            "{msg}"
        );
    }

    const RAW_HEADER: &str = "Header Size:  7\r\nVersion:  2\r\nSampling Interval:  0.005\r\n\
        Sampling Rate:  200\r\nSample Count:  COUNT\r\nDevice Serial Number:  0\r\n\
        Sample Number, Date/Time, CHANNEL0, CHANNEL1, Events\r\n";

    /// A raw file with `per` samples per level, levels split by Pause/Resume
    /// events (or NaN rows when `nan_rows`: with a sample number before
    /// levels 1 and 3, all NaN before levels 2 and 4), force growing with the
    /// level.
    fn raw_text(per: usize, nan_rows: bool) -> String {
        let mut body = String::new();
        let (mut n, mut rows) = (0, 0);
        for level in 0..5 {
            if nan_rows && level > 0 {
                rows += 1;
                if level % 2 == 1 {
                    n += 1;
                    body.push_str(&format!("{n:>10},   date, NaN, NaN\r\n"));
                } else {
                    body.push_str("NaN, NaN, NaN, NaN\r\n");
                }
            }
            for i in 0..per {
                n += 1;
                rows += 1;
                let force_v = 0.3 * (level + 1) as f64 * (i as f64).sin();
                let disp_v = -3.0 + 0.1 * i as f64;
                let event = match (i, nan_rows) {
                    (0, _) if n == 1 => ", DAQ Start",
                    (0, false) => ", DAQ Resume",
                    (i, false) if i + 1 == per => ", DAQ Pause",
                    _ => "",
                };
                body.push_str(&format!(
                    "{n:>10},   date, {force_v:.4}, {disp_v:.4}{event}\r\n"
                ));
            }
        }
        RAW_HEADER.replace("COUNT", &rows.to_string()) + &body
    }

    #[test]
    fn raw_splits_into_five_levels() {
        for nan_rows in [false, true] {
            let segs = parse_raw(
                &raw_text(4, nan_rows),
                "ME2mm5Hz.txt",
                ChannelLayout::ForceOnChannel0,
            )
            .expect("valid");
            assert_eq!(segs.len(), 5);
            for (seg, current) in segs.iter().zip(CURRENT_LEVELS_A) {
                assert_eq!(seg.current_a, current);
                let rec = &seg.recording;
                assert_eq!(rec.len(), 4);
                assert!(rec.velocity_derived);
                assert_eq!(rec.samples[0].time_s, 0.0);
                assert_eq!(rec.samples[3].time_s, 3.0 * 0.005);
                assert!((rec.samples[0].displacement_m + 0.03).abs() < 1e-12);
                // 0.1 V per 5 ms = 1 mm per 5 ms = 0.2 m/s.
                assert!(rec
                    .samples
                    .iter()
                    .all(|s| (s.velocity_m_s - 0.2).abs() < 1e-9));
                assert!(rec.samples.iter().all(|s| s.current_a == current));
            }
            let seg = &segs[4].recording.samples[1];
            assert!((seg.force_n - 1.5 * 1f64.sin() * FORCE_N_PER_VOLT).abs() < 0.1);
        }
        // The other layout swaps the channels.
        let segs = parse_raw(
            &raw_text(4, false),
            "x",
            ChannelLayout::DisplacementOnChannel0,
        )
        .expect("valid");
        assert!((segs[0].recording.samples[0].force_n + 3.0 * FORCE_N_PER_VOLT).abs() < 1e-9);
    }

    fn raw_err(text: &str) -> String {
        parse_raw(text, "ME2mm5Hz.txt", ChannelLayout::ForceOnChannel0)
            .expect_err("expected an error")
            .to_string()
    }

    /// Found by the fuzzer (issue 15, `fuzz-parsers --parser utfsm-raw --seed 2`, input
    /// 99211): 1e308 V on CHANNEL0 is finite, the force it scales to (× 980.665 N/V) is
    /// not; the file was accepted with an infinite force.
    #[test]
    fn a_value_that_overflows_once_scaled_is_an_error_naming_its_line() {
        let fuzzed = "Header Size: 7\r\nSampling Interval: 1e-3\r\nSample Count: 9\r\n\
            Start: 11/07/2019\r\nChannels: 2\r\nUnits: V\r\n\
            Sample Number, Date/Time, CHANNEL0, CHANNEL1, Events\r\n\
            0, 11/07/2019 10:00:00.295, -5.198290120629975e0, -8.936789837498162, \r\n\
            1, 11/07/2019 10:00:00.826, 8.740145170347269, -4.703160700509419e0, DAQ Resume\r\n\
            2, x, NaN, NaN, \r\n\
            3, 11/07/2019 10:00:00.241, 1e308, 8.015, \r\n\
            4, 11/07/2019 10:00:00.219, 2.9645720250974996, 5.266452600499143e-1, \r\n\
            NaN, NaN, NaN, NaN\r\n\
            5, 11/07/2019 10:00:00.044, 9.782265570873218, -4.890543281403579E0, \r\n\
            7, x, NaN, NaN, \r\n\
            8, 11/07/2019 10:00:00.671, 2.020210300007113, 2.381433167553027e0, \r\n";
        assert_eq!(
            parse_raw(fuzzed, "ME25mm0x5Hz.txt", ChannelLayout::ForceOnChannel0)
                .expect_err("an infinite force")
                .to_string(),
            "ME25mm0x5Hz.txt line 11: sample 3: the force is inf N once scaled (CHANNEL0 1e308 \
             V, CHANNEL1 8.015e0 V, Sampling Interval 1e-3 s); the values are out of range"
        );
    }

    #[test]
    fn raw_errors_name_line_and_column() {
        let good = raw_text(3, false);
        // Data lines start at line 8; line 9 is the second sample.
        let with_line9 = |replacement: &str| {
            let mut lines: Vec<String> = good.lines().map(str::to_owned).collect();
            lines[8] = replacement.to_owned();
            lines.join("\n")
        };
        let msg = raw_err(&with_line9("2, date, 0.1, abc"));
        assert_eq!(
            msg,
            r#"ME2mm5Hz.txt line 9, column CHANNEL1: value "abc" is not a number"#
        );
        let msg = raw_err(&with_line9("2, date, inf, 0"));
        assert!(
            msg.contains("line 9, column CHANNEL0: value \"inf\" is not a finite"),
            "{msg}"
        );
        let msg = raw_err(&with_line9("two, date, 0, 0"));
        assert!(msg.contains("line 9, column Sample Number"), "{msg}");
        let msg = raw_err(&with_line9("1, date, 0, 0"));
        assert!(
            msg.contains("line 9: sample number 1 is not after 1 on line 8"),
            "{msg}"
        );
        let msg = raw_err(&with_line9("2, date, 0"));
        assert!(msg.contains("line 9: expected 5 fields, found 3"), "{msg}");
        // A stray NaN inside a level splits it: six segments.
        let msg = raw_err(&with_line9("2, date, NaN, NaN"));
        assert_eq!(msg, "ME2mm5Hz.txt: expected 5 segments, found 6");
        // Truncated file.
        let truncated: Vec<&str> = good.lines().collect();
        let msg = raw_err(&truncated[..truncated.len() - 1].join("\n"));
        assert!(
            msg.contains("line 5: the header says Sample Count 15 but the file has 14"),
            "{msg}"
        );
        // Header problems.
        let msg = raw_err(&good.replace("Header Size", "Size"));
        assert!(
            msg.contains("ME2mm5Hz.txt line 1: expected `Header Size"),
            "{msg}"
        );
        let msg = raw_err(&good.replace("Sampling Interval:  0.005", "Sampling Interval: -1"));
        assert!(msg.contains("line 3: Sampling Interval \"-1\""), "{msg}");
        let msg = raw_err(&good.replace("CHANNEL1", "CH1"));
        assert!(msg.contains("line 7: expected the column header"), "{msg}");
        let msg = raw_err("Header Size: 7\nVersion: 2\n");
        assert!(
            msg.contains("line 2: file ends inside the 7-line header"),
            "{msg}"
        );
        assert_eq!(raw_err(""), "ME2mm5Hz.txt: file is empty");
    }
}
