//! Damper recordings in the project's CSV format (PHYSICS.md, "Recording
//! format (CSV)").
//!
//! A recording is one header row, then one row per sample, comma separated:
//!
//! | column           | unit | required                                   |
//! | ---------------- | ---- | ------------------------------------------ |
//! | `time_s`         | s    | yes                                        |
//! | `displacement_m` | m    | yes                                        |
//! | `velocity_m_s`   | m/s  | no (derived from displacement when absent) |
//! | `force_N`        | N    | yes                                        |
//! | `current_A`      | A    | yes                                        |
//! | `temperature_C`  | °C   | no                                         |
//!
//! Columns may come in any order, other columns are ignored, fields are
//! trimmed of surrounding whitespace, and blank lines are allowed at the end of
//! the file (not in the middle). Time must strictly increase; the sampling may
//! be uneven. Sign conventions are those of PHYSICS.md: displacement positive
//! in extension, force positive when the damper resists extension.
//!
//! Every reading error names the file and, where it applies, the line (1-based,
//! the header is line 1) and the column.

use std::fmt;
use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Name of the time column (s).
pub const COL_TIME: &str = "time_s";
/// Name of the displacement column (m).
pub const COL_DISPLACEMENT: &str = "displacement_m";
/// Name of the optional velocity column (m/s).
pub const COL_VELOCITY: &str = "velocity_m_s";
/// Name of the force column (N).
pub const COL_FORCE: &str = "force_N";
/// Name of the coil current column (A).
pub const COL_CURRENT: &str = "current_A";
/// Name of the optional temperature column (°C).
pub const COL_TEMPERATURE: &str = "temperature_C";

/// Largest plausible |displacement| in metres. A larger peak almost certainly
/// means the column was written in millimetres.
pub const MAX_DISPLACEMENT_M: f64 = 1.0;

/// One sample of a recording, in SI units (temperature in °C).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time in s.
    pub time_s: f64,
    /// Piston displacement in m, positive in extension.
    pub displacement_m: f64,
    /// Piston velocity in m/s (`dx/dt`).
    pub velocity_m_s: f64,
    /// Rod force in N, positive when the damper resists extension.
    pub force_n: f64,
    /// Coil current in A.
    pub current_a: f64,
    /// Fluid/body temperature in °C, when recorded.
    pub temperature_c: Option<f64>,
}

/// A time series of [`Sample`]s with strictly increasing time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// The samples, in time order.
    pub samples: Vec<Sample>,
    /// `true` when the velocity was computed from the displacement (see
    /// [`derive_velocity`]) rather than read from the source.
    pub velocity_derived: bool,
    /// `true` when the source had a temperature column.
    pub has_temperature: bool,
    /// Where the recording came from: a file path or a short description.
    pub source: String,
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// `true` when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

/// Everything that can go wrong reading or writing a recording.
///
/// `file` is the path or source description given to the reader; `line` is
/// 1-based and counts the header as line 1.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be read, written or renamed.
    #[error("{}: cannot {action}: {error}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What was being attempted, e.g. "read", "write temporary file".
        action: &'static str,
        /// The underlying error.
        #[source]
        error: io::Error,
    },
    /// The file has no content at all (not even a header).
    #[error("{file}: file is empty")]
    Empty {
        /// File or source description.
        file: String,
    },
    /// The file has a header but no data rows.
    #[error("{file}: no data rows after the header")]
    NoData {
        /// File or source description.
        file: String,
    },
    /// A required column is not in the header.
    #[error(
        "{file} line 1: missing required column {column}; columns found: {}",
        ColumnList(found)
    )]
    MissingColumn {
        /// File or source description.
        file: String,
        /// The missing column.
        column: &'static str,
        /// The header's column names, in order.
        found: Vec<String>,
    },
    /// A known column appears twice in the header.
    #[error("{file} line 1: column {column} appears twice (fields {first} and {second})")]
    DuplicateColumn {
        /// File or source description.
        file: String,
        /// The repeated column.
        column: String,
        /// 1-based position of the first occurrence.
        first: usize,
        /// 1-based position of the second occurrence.
        second: usize,
    },
    /// A row does not have as many fields as the header.
    #[error("{file} line {line}: expected {expected} fields, found {found}")]
    FieldCount {
        /// File or source description.
        file: String,
        /// Line of the row.
        line: usize,
        /// Number of fields expected.
        expected: usize,
        /// Number of fields found.
        found: usize,
    },
    /// A blank line is followed by more data.
    #[error(
        "{file} line {line}: blank line inside the data (blank lines are only allowed at the end)"
    )]
    BlankLine {
        /// File or source description.
        file: String,
        /// Line of the blank line.
        line: usize,
    },
    /// A field does not parse as a number.
    #[error("{file} line {line}, column {column}: value {value:?} is not a number")]
    NotANumber {
        /// File or source description.
        file: String,
        /// Line of the row.
        line: usize,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
    },
    /// A field is NaN or infinite.
    #[error("{file} line {line}, column {column}: value {value:?} is not a finite number")]
    NotFinite {
        /// File or source description.
        file: String,
        /// Line of the row.
        line: usize,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
    },
    /// Time does not strictly increase.
    #[error("{file} line {line}: time {time_s} s is not after {previous_s} s on line {previous_line}; time must strictly increase")]
    TimeNotIncreasing {
        /// File or source description.
        file: String,
        /// Line of the offending row.
        line: usize,
        /// Time on that line.
        time_s: f64,
        /// Line of the previous row.
        previous_line: usize,
        /// Time on the previous row.
        previous_s: f64,
    },
    /// The displacement column looks like millimetres.
    #[error("{file} line {line}, column displacement_m: |displacement| reaches {peak} (> 1 m); displacement_m must be in metres (this looks like millimetres)")]
    DisplacementUnits {
        /// File or source description.
        file: String,
        /// Line where the peak occurs.
        line: usize,
        /// The peak |displacement| found.
        peak: f64,
    },
    /// A file name does not follow the expected naming scheme.
    #[error("{file}: file name does not match {expected}")]
    BadFileName {
        /// The file.
        file: String,
        /// The expected scheme, with an example.
        expected: &'static str,
    },
    /// A format-specific structural problem at a given line.
    #[error("{file} line {line}: {message}")]
    Format {
        /// File or source description.
        file: String,
        /// Line concerned.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A file holds a different number of segments than expected.
    #[error("{file}: expected {expected} segments, found {found}")]
    SegmentCount {
        /// File or source description.
        file: String,
        /// Segments expected.
        expected: usize,
        /// Segments found.
        found: usize,
    },
}

/// Formats a header's column list for error messages.
struct ColumnList<'a>(&'a [String]);

impl fmt::Display for ColumnList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.iter().all(|c| c.is_empty()) {
            return f.write_str("(none)");
        }
        for (i, c) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{c:?}")?;
        }
        Ok(())
    }
}

/// Parses `text` as a finite `f64`, reporting `file`, `line` and `column` on
/// failure.
pub(crate) fn parse_finite(
    text: &str,
    file: &str,
    line: usize,
    column: &str,
) -> Result<f64, RecordingError> {
    let value: f64 = text.parse().map_err(|_| RecordingError::NotANumber {
        file: file.to_owned(),
        line,
        column: column.to_owned(),
        value: text.to_owned(),
    })?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(RecordingError::NotFinite {
            file: file.to_owned(),
            line,
            column: column.to_owned(),
            value: text.to_owned(),
        })
    }
}

/// Derives velocity from displacement by finite differences.
///
/// Interior points use the three-point central difference for uneven
/// sampling, `v_i = (h₊·s₋ + h₋·s₊) / (h₋ + h₊)`, where `s₋`, `s₊` are the
/// slopes to the previous and next sample and `h₋`, `h₊` the two time steps;
/// it is the derivative of the parabola through the three points (second-order
/// accurate) and reduces to `(x_{i+1} − x_{i−1}) / (2h)` for even sampling.
/// The first and last points use one-sided (first-order) differences.
///
/// `time_s` must strictly increase and have the same length as
/// `displacement_m`; a single sample gets velocity 0, and an empty input gives
/// an empty output.
pub fn derive_velocity(time_s: &[f64], displacement_m: &[f64]) -> Vec<f64> {
    let n = time_s.len().min(displacement_m.len());
    match n {
        0 => return Vec::new(),
        1 => return vec![0.0],
        _ => {}
    }
    let slope =
        |i: usize| (displacement_m[i + 1] - displacement_m[i]) / (time_s[i + 1] - time_s[i]);
    let mut v = Vec::with_capacity(n);
    v.push(slope(0));
    for i in 1..n - 1 {
        let h_prev = time_s[i] - time_s[i - 1];
        let h_next = time_s[i + 1] - time_s[i];
        v.push((h_next * slope(i - 1) + h_prev * slope(i)) / (h_prev + h_next));
    }
    v.push(slope(n - 2));
    v
}

/// Column positions of a parsed header.
struct Columns {
    count: usize,
    time: usize,
    displacement: usize,
    velocity: Option<usize>,
    force: usize,
    current: usize,
    temperature: Option<usize>,
}

impl Columns {
    /// Locates the known columns in the header `names`.
    fn locate(names: &[String], file: &str) -> Result<Self, RecordingError> {
        let find = |column: &str| -> Result<Option<usize>, RecordingError> {
            let mut hits = names
                .iter()
                .enumerate()
                .filter(|(_, n)| n.as_str() == column);
            let first = hits.next().map(|(i, _)| i);
            if let (Some(first), Some((second, _))) = (first, hits.next()) {
                return Err(RecordingError::DuplicateColumn {
                    file: file.to_owned(),
                    column: column.to_owned(),
                    first: first + 1,
                    second: second + 1,
                });
            }
            Ok(first)
        };
        let require = |column: &'static str| -> Result<usize, RecordingError> {
            find(column)?.ok_or_else(|| RecordingError::MissingColumn {
                file: file.to_owned(),
                column,
                found: names.to_vec(),
            })
        };
        Ok(Self {
            count: names.len(),
            time: require(COL_TIME)?,
            displacement: require(COL_DISPLACEMENT)?,
            velocity: find(COL_VELOCITY)?,
            force: require(COL_FORCE)?,
            current: require(COL_CURRENT)?,
            temperature: find(COL_TEMPERATURE)?,
        })
    }
}

/// Reads a recording from a CSV file; see the module docs for the format.
///
/// The path (as displayed) becomes [`Recording::source`] and prefixes every
/// error message.
pub fn read_csv(path: &Path) -> Result<Recording, RecordingError> {
    let text = fs::read_to_string(path).map_err(|error| RecordingError::Io {
        path: path.to_owned(),
        action: "read",
        error,
    })?;
    parse_csv(&text, &path.display().to_string())
}

/// Parses a recording from CSV text; `source` names it in errors and becomes
/// [`Recording::source`].
///
/// When the `velocity_m_s` column is absent the velocity is computed with
/// [`derive_velocity`] and [`Recording::velocity_derived`] is set. An empty
/// `temperature_C` field reads as `None` (that is what [`to_csv_string`]
/// writes for a sample without temperature).
pub fn parse_csv(text: &str, source: &str) -> Result<Recording, RecordingError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.trim().is_empty() {
        return Err(RecordingError::Empty {
            file: source.to_owned(),
        });
    }
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    let names: Vec<String> = header.split(',').map(|s| s.trim().to_owned()).collect();
    let cols = Columns::locate(&names, source)?;

    let mut samples: Vec<Sample> = Vec::new();
    // Line of each sample, for error messages after the row loop.
    let mut sample_lines: Vec<usize> = Vec::new();
    let mut blank_line = None;
    for (index, raw) in lines.enumerate() {
        let line = index + 2;
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
        let fields: Vec<&str> = raw.split(',').map(str::trim).collect();
        if fields.len() != cols.count {
            return Err(RecordingError::FieldCount {
                file: source.to_owned(),
                line,
                expected: cols.count,
                found: fields.len(),
            });
        }
        let get = |i: usize| parse_finite(fields[i], source, line, &names[i]);
        let time_s = get(cols.time)?;
        let displacement_m = get(cols.displacement)?;
        let velocity_m_s = cols.velocity.map(get).transpose()?.unwrap_or(0.0);
        let force_n = get(cols.force)?;
        let current_a = get(cols.current)?;
        let temperature_c = match cols.temperature {
            Some(i) if !fields[i].is_empty() => Some(get(i)?),
            _ => None,
        };
        if let (Some(previous), Some(&previous_line)) = (samples.last(), sample_lines.last()) {
            let previous_s = previous.time_s;
            if time_s <= previous_s {
                return Err(RecordingError::TimeNotIncreasing {
                    file: source.to_owned(),
                    line,
                    time_s,
                    previous_line,
                    previous_s,
                });
            }
        }
        samples.push(Sample {
            time_s,
            displacement_m,
            velocity_m_s,
            force_n,
            current_a,
            temperature_c,
        });
        sample_lines.push(line);
    }
    if samples.is_empty() {
        return Err(RecordingError::NoData {
            file: source.to_owned(),
        });
    }

    let (peak_index, peak) = samples
        .iter()
        .map(|s| s.displacement_m.abs())
        .enumerate()
        .fold(
            (0, 0.0_f64),
            |best, (i, a)| if a > best.1 { (i, a) } else { best },
        );
    if peak > MAX_DISPLACEMENT_M {
        return Err(RecordingError::DisplacementUnits {
            file: source.to_owned(),
            line: sample_lines[peak_index],
            peak,
        });
    }

    let velocity_derived = cols.velocity.is_none();
    if velocity_derived {
        let t: Vec<f64> = samples.iter().map(|s| s.time_s).collect();
        let x: Vec<f64> = samples.iter().map(|s| s.displacement_m).collect();
        for ((s, v), &line) in samples
            .iter_mut()
            .zip(derive_velocity(&t, &x))
            .zip(&sample_lines)
        {
            // Time steps that are all but zero, or near f64::MAX, overflow the difference
            // quotient: a recording with an infinite velocity would not even write back.
            if !v.is_finite() {
                return Err(RecordingError::Format {
                    file: source.to_owned(),
                    line,
                    message: format!(
                        "the velocity derived from {COL_TIME} and {COL_DISPLACEMENT} is {v} \
                         (the time steps around this line are too small or too large); fix \
                         {COL_TIME} or give a {COL_VELOCITY} column"
                    ),
                });
            }
            s.velocity_m_s = v;
        }
    }

    Ok(Recording {
        samples,
        velocity_derived,
        has_temperature: cols.temperature.is_some(),
        source: source.to_owned(),
    })
}

/// Formats `value` so that parsing the text gives back the identical `f64`.
///
/// Both `{}` and `{:e}` print the shortest round-trip digits; `{:e}` is used
/// for very small or large magnitudes to keep the text short.
fn fmt_f64(out: &mut String, value: f64) {
    use fmt::Write as _;
    let a = value.abs();
    // Writing into a String cannot fail.
    let _ = if a == 0.0 || (1e-5..1e16).contains(&a) || !a.is_finite() {
        write!(out, "{value}")
    } else {
        write!(out, "{value:e}")
    };
}

/// Renders a recording as CSV text: header
/// `time_s,displacement_m,velocity_m_s,force_N,current_A` plus `,temperature_C`
/// when [`Recording::has_temperature`] is set, then one row per sample.
///
/// Numbers are written in shortest round-trip form, so [`parse_csv`] gives
/// back bit-identical values. A sample without temperature in a recording that
/// has a temperature column gets an empty field; temperatures are dropped when
/// `has_temperature` is false. Non-finite values are written as `NaN`/`inf`,
/// and a recording without samples as a header alone; the reader rejects
/// both.
pub fn to_csv_string(rec: &Recording) -> String {
    let mut out = String::with_capacity(64 + rec.samples.len() * 80);
    out.push_str("time_s,displacement_m,velocity_m_s,force_N,current_A");
    if rec.has_temperature {
        out.push_str(",temperature_C");
    }
    out.push('\n');
    for s in &rec.samples {
        for (i, v) in [
            s.time_s,
            s.displacement_m,
            s.velocity_m_s,
            s.force_n,
            s.current_a,
        ]
        .into_iter()
        .enumerate()
        {
            if i > 0 {
                out.push(',');
            }
            fmt_f64(&mut out, v);
        }
        if rec.has_temperature {
            out.push(',');
            if let Some(t) = s.temperature_c {
                fmt_f64(&mut out, t);
            }
        }
        out.push('\n');
    }
    out
}

/// Distinguishes temporary files of concurrent writes from one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes a recording as CSV (see [`to_csv_string`]) atomically.
///
/// The text goes through a `BufWriter` into a temporary file in the
/// destination's directory, which is flushed, synced and then renamed over
/// `path`; a crash or error never leaves a partial file at `path` (the
/// temporary file is removed on error).
pub fn write_csv(path: &Path, rec: &Recording) -> Result<(), RecordingError> {
    let io_err = |path: &Path, action: &'static str| {
        let path = path.to_owned();
        move |error| RecordingError::Io {
            path,
            action,
            error,
        }
    };
    let file_name = path.file_name().ok_or_else(|| RecordingError::Io {
        path: path.to_owned(),
        action: "write",
        error: io::Error::new(io::ErrorKind::InvalidInput, "path has no file name"),
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(file_name);
    temp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let temp = dir.join(temp_name);

    let write = || -> Result<(), RecordingError> {
        let file = fs::File::create(&temp).map_err(io_err(&temp, "create temporary file"))?;
        let mut writer = BufWriter::new(file);
        writer
            .write_all(to_csv_string(rec).as_bytes())
            .map_err(io_err(&temp, "write temporary file"))?;
        let file = writer
            .into_inner()
            .map_err(|e| io_err(&temp, "write temporary file")(e.into_error()))?;
        file.sync_all()
            .map_err(io_err(&temp, "sync temporary file"))?;
        drop(file);
        fs::rename(&temp, path).map_err(io_err(path, "move the finished temporary file into place"))
    };
    let result = write();
    if result.is_err() {
        // Best effort: the temporary file may not even exist.
        let _ = fs::remove_file(&temp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "time_s,displacement_m,force_N,current_A";

    fn err(text: &str) -> String {
        match parse_csv(text, "rec.csv") {
            Ok(r) => panic!("expected an error, got {} samples", r.len()),
            Err(e) => e.to_string(),
        }
    }

    /// A unique scratch directory under the system temp dir.
    fn scratch_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "bridge-recording-{}-{}-{}",
            name,
            std::process::id(),
            TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        fs::create_dir_all(&dir).expect("create scratch dir");
        dir
    }

    #[test]
    fn parses_columns_in_any_order_with_extras_and_whitespace() {
        let text = " current_A , note, force_N,time_s ,displacement_m,temperature_C\n\
                    0.5, a ,10,0,0.001,25\n\
                    0.5,b, -12.5 ,0.01,0.002,\n\
                    \n  \n";
        let rec = parse_csv(text, "x.csv").expect("valid");
        assert_eq!(rec.len(), 2);
        assert!(rec.velocity_derived);
        assert!(rec.has_temperature);
        assert_eq!(rec.source, "x.csv");
        let s = rec.samples[1];
        assert_eq!(s.time_s, 0.01);
        assert_eq!(s.displacement_m, 0.002);
        assert_eq!(s.force_n, -12.5);
        assert_eq!(s.current_a, 0.5);
        assert_eq!(rec.samples[0].temperature_c, Some(25.0));
        assert_eq!(s.temperature_c, None);
        // Two samples: both one-sided differences give the same slope.
        assert!((s.velocity_m_s - 0.1).abs() < 1e-12);
        assert!((rec.samples[0].velocity_m_s - 0.1).abs() < 1e-12);
    }

    #[test]
    fn reads_velocity_column_and_crlf() {
        let text =
            "time_s,displacement_m,velocity_m_s,force_N,current_A\r\n0,0,3,1,0\r\n1,0,4,1,0\r\n";
        let rec = parse_csv(text, "x.csv").expect("valid");
        assert!(!rec.velocity_derived);
        assert!(!rec.has_temperature);
        assert_eq!(rec.samples[0].velocity_m_s, 3.0);
        assert_eq!(rec.samples[1].velocity_m_s, 4.0);
    }

    #[test]
    fn missing_column_is_named_with_columns_found() {
        let msg = err("time_s,displacement_m,current_A\n0,0,0\n");
        assert!(msg.contains("rec.csv line 1"), "{msg}");
        assert!(msg.contains("missing required column force_N"), "{msg}");
        assert!(
            msg.contains(r#""time_s", "displacement_m", "current_A""#),
            "{msg}"
        );
    }

    #[test]
    fn duplicate_column_is_rejected() {
        let msg = err("time_s,force_N,displacement_m,current_A,force_N\n0,0,0,0,0\n");
        assert!(msg.contains("line 1"), "{msg}");
        assert!(
            msg.contains("force_N appears twice (fields 2 and 5)"),
            "{msg}"
        );
    }

    #[test]
    fn wrong_field_count_names_line() {
        let msg = err(&format!("{HEADER}\n0,0,0,0\n1,0,0\n"));
        assert!(msg.contains("rec.csv line 3"), "{msg}");
        assert!(msg.contains("expected 4 fields, found 3"), "{msg}");
    }

    #[test]
    fn unparsable_number_names_line_and_column() {
        let msg = err(&format!("{HEADER}\n0,0,0,0\n1,0,abc,0\n"));
        assert_eq!(
            msg,
            r#"rec.csv line 3, column force_N: value "abc" is not a number"#
        );
    }

    #[test]
    fn nan_and_infinity_name_line_and_column() {
        let mut text = format!("{HEADER}\n");
        for i in 0..16 {
            text.push_str(&format!("{i},0,0,0\n"));
        }
        text.push_str("16,0,nan,0\n");
        assert_eq!(
            err(&text),
            r#"rec.csv line 18, column force_N: value "nan" is not a finite number"#
        );
        let msg = err(&format!("{HEADER}\n0,inf,0,0\n"));
        assert!(
            msg.contains("line 2, column displacement_m: value \"inf\" is not a finite"),
            "{msg}"
        );
        let msg = err(&format!("{HEADER}\n0,0,0,-Infinity\n"));
        assert!(msg.contains("line 2, column current_A"), "{msg}");
    }

    #[test]
    fn time_not_increasing_names_line_and_both_times() {
        let msg = err(&format!("{HEADER}\n0,0,0,0\n0.5,0,0,0\n0.25,0,0,0\n"));
        assert!(msg.contains("rec.csv line 4"), "{msg}");
        assert!(
            msg.contains("time 0.25 s is not after 0.5 s on line 3"),
            "{msg}"
        );
        let msg = err(&format!("{HEADER}\n0,0,0,0\n0,0,0,0\n"));
        assert!(
            msg.contains("line 3: time 0 s is not after 0 s on line 2"),
            "{msg}"
        );
    }

    #[test]
    fn empty_file_and_header_only_are_rejected() {
        assert_eq!(err(""), "rec.csv: file is empty");
        assert!(err(" \n\n").contains("rec.csv: file is empty"));
        assert_eq!(
            err(&format!("{HEADER}\n\n")),
            "rec.csv: no data rows after the header"
        );
    }

    #[test]
    fn blank_line_inside_data_is_rejected() {
        let msg = err(&format!("{HEADER}\n0,0,0,0\n\n1,0,0,0\n"));
        assert!(msg.contains("rec.csv line 3: blank line"), "{msg}");
    }

    #[test]
    fn millimetre_displacement_is_rejected() {
        let msg = err(&format!("{HEADER}\n0,0.5,0,0\n1,-25,0,0\n2,3,0,0\n"));
        assert!(
            msg.contains("rec.csv line 3, column displacement_m"),
            "{msg}"
        );
        assert!(msg.contains("must be in metres"), "{msg}");
        assert!(msg.contains("millimetres"), "{msg}");
    }

    /// Found by the fuzzer (issue 15, `fuzz-parsers --parser csv --seed 1`, input
    /// 613356): a jump of the time to 6e307 s made the derived velocity infinite; the
    /// recording was accepted and did not read back once written.
    #[test]
    fn an_infinite_derived_velocity_is_an_error_naming_its_line() {
        let fuzzed = "   force_N,displacement_m,temperature_C,time_s,current_A\r\n \
            -3.2486469033610765e-1 ,0.002,-431191279,0.1269407616409118,-6.108939297149712E4\r\n\
            -6.078106174760445e5,0.0001963452625883595,-649.0499376730381,0.19712918673731378,\
            -0.008573099737098694\r\n+0, -0.30692458685406754 , 15291.788241528193 \
            ,0.2944254807099705, 0 \r\n     -866371201.4390119, -0.7792976828803588 ,-0e0,\
            0.3742079126389154,-6634000.08014297\r\n-0.00000000433592322399891,-0.007,  \
            ,0.4531090265207979,-4.0863244E7\r\n+0,0.088,, 0.598722078111e308,-6.374226790963";
        let msg = err(fuzzed);
        assert!(
            msg.starts_with(
                "rec.csv line 6: the velocity derived from time_s and displacement_m is inf"
            ),
            "{msg}"
        );
        // Subnormal time steps overflow the quotient too.
        let msg = err(&format!("{HEADER}\n0,0,0,0\n5e-324,0.5,0,0\n"));
        assert!(
            msg.starts_with("rec.csv line 2: the velocity derived"),
            "{msg}"
        );
    }

    #[test]
    fn io_error_names_path() {
        let path = Path::new("/nonexistent-dir-for-bridge-test/rec.csv");
        let msg = read_csv(path).expect_err("missing file").to_string();
        assert!(
            msg.starts_with("/nonexistent-dir-for-bridge-test/rec.csv: cannot read"),
            "{msg}"
        );
        let msg = write_csv(path, &Recording::default())
            .expect_err("missing dir")
            .to_string();
        assert!(msg.contains("/nonexistent-dir-for-bridge-test/"), "{msg}");
    }

    #[test]
    fn write_read_round_trip_is_bit_identical() {
        let awkward = [
            0.0,
            -0.0,
            1.0 / 3.0,
            -2.0 / 3.0,
            std::f64::consts::PI,
            1e-300,
            5e-324,
            -1.234_567_890_123_456_7e-7,
            0.1 + 0.2,
            123_456_789.012_345_68,
            1e22,
            f64::MAX,
            -f64::MIN_POSITIVE,
        ];
        let samples: Vec<Sample> = awkward
            .iter()
            .enumerate()
            .map(|(i, &a)| Sample {
                time_s: i as f64 * 0.001 + 1e-9 * a.signum(),
                displacement_m: (a / 1e300).clamp(-0.5, 0.5),
                velocity_m_s: a,
                force_n: -a,
                current_a: a.abs().sqrt(),
                temperature_c: if i % 3 == 0 { None } else { Some(a) },
            })
            .collect();
        let rec = Recording {
            samples,
            velocity_derived: false,
            has_temperature: true,
            source: "memory".into(),
        };
        let dir = scratch_dir("roundtrip");
        let path = dir.join("rec.csv");
        write_csv(&path, &rec).expect("write");
        let back = read_csv(&path).expect("read back");
        assert_eq!(back.samples.len(), rec.samples.len());
        for (a, b) in rec.samples.iter().zip(&back.samples) {
            let bits = |s: &Sample| {
                [
                    s.time_s,
                    s.displacement_m,
                    s.velocity_m_s,
                    s.force_n,
                    s.current_a,
                ]
                .map(f64::to_bits)
            };
            assert_eq!(bits(a), bits(b), "{a:?} vs {b:?}");
            assert_eq!(
                a.temperature_c.map(f64::to_bits),
                b.temperature_c.map(f64::to_bits)
            );
        }
        assert!(back.has_temperature);
        assert!(!back.velocity_derived);
        // Only the destination remains: no temporary files left behind.
        let names: Vec<_> = fs::read_dir(&dir)
            .expect("list")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("rec.csv")]);
        // Overwriting replaces the file.
        let short = Recording {
            samples: rec.samples[..2].to_vec(),
            has_temperature: false,
            ..rec.clone()
        };
        write_csv(&path, &short).expect("overwrite");
        let back = read_csv(&path).expect("read back");
        assert_eq!(back.len(), 2);
        assert!(!back.has_temperature);
        fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn header_without_temperature() {
        let rec = Recording {
            samples: vec![Sample {
                time_s: 0.5,
                displacement_m: 0.01,
                velocity_m_s: -0.2,
                force_n: 150.0,
                current_a: 1.0,
                temperature_c: Some(40.0),
            }],
            ..Recording::default()
        };
        assert_eq!(
            to_csv_string(&rec),
            "time_s,displacement_m,velocity_m_s,force_N,current_A\n0.5,0.01,-0.2,150,1\n"
        );
    }

    #[test]
    fn velocity_of_unevenly_sampled_sinusoid_matches_analytic() {
        let (amp, freq) = (0.025, 0.5);
        let w = 2.0 * std::f64::consts::PI * freq;
        // Nominal 5 ms steps with a deterministic ±40 % jitter.
        let mut t = vec![0.0];
        let mut state: u64 = 12345;
        while t.len() < 2000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let jitter = ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.8;
            let last = t[t.len() - 1];
            t.push(last + 0.005 * (1.0 + jitter));
        }
        let x: Vec<f64> = t.iter().map(|&t| amp * (w * t).sin()).collect();
        let v = derive_velocity(&t, &x);
        let peak = amp * w;
        let interior_err = t[1..t.len() - 1]
            .iter()
            .zip(&v[1..v.len() - 1])
            .map(|(&t, &v)| (v - peak * (w * t).cos()).abs())
            .fold(0.0, f64::max);
        // Second order: the truncation error is h₋·h₊/6 · |d³x/dt³|, at most
        // max(h₋·h₊)/6 · A ω³ (about 6e-6 m/s here, 1e-4 of the peak). The
        // plain (x₊ − x₋)/(t₊ − t₋) would be only first order on this grid,
        // with errors up to about (h₊ − h₋)/2 · A ω² ≈ 5e-4 m/s.
        let bound = t
            .windows(3)
            .map(|t3| (t3[1] - t3[0]) * (t3[2] - t3[1]))
            .fold(0.0, f64::max)
            / 6.0
            * amp
            * w.powi(3);
        assert!(
            interior_err < 1.05 * bound && bound < 2e-4 * peak,
            "interior error {interior_err}, bound {bound}"
        );
        // One-sided ends: first order, error ~ A ω² h / 2.
        let end_err = (v[0] - peak).abs();
        assert!(end_err < 1e-2 * peak, "end error {end_err}");
        assert_eq!(derive_velocity(&[1.0], &[2.0]), vec![0.0]);
        assert!(derive_velocity(&[], &[]).is_empty());
    }
}
