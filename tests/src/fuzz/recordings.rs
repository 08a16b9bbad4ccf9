//! Generators and checks of the recording parsers: the CSV format
//! (`bridge::csv::parse_csv` / `read_csv`) and the UTFSM text files
//! (`bridge::utfsm::parse_preprocessed` / `parse_raw`, their file-name parsers and the
//! path readers).

use bridge::csv::{parse_csv, read_csv, to_csv_string, Recording, Sample};
use bridge::utfsm::{
    parse_preprocessed, parse_raw, parse_raw_test_name, parse_test_name, read_preprocessed,
    read_raw, ChannelLayout,
};

use super::mutate::mutate;
use super::rng::Rng;
use super::{names_file, FuzzInput, Parser, Scratch, Verdict};

/// Largest generated text.
const MAX_TEXT: usize = 2048;

/// The recording parsers.
pub fn parsers() -> Vec<Parser> {
    vec![
        Parser {
            name: "csv",
            entry: "bridge::csv::parse_csv, read_csv (1 in 32); accepted → to_csv_string → parse_csv round trip",
            generate: generate_csv,
            check: check_csv,
        },
        Parser {
            name: "utfsm-preprocessed",
            entry: "bridge::utfsm::parse_preprocessed, parse_test_name, read_preprocessed (1 in 32)",
            generate: generate_preprocessed,
            check: check_preprocessed,
        },
        Parser {
            name: "utfsm-raw",
            entry: "bridge::utfsm::parse_raw, parse_raw_test_name, read_raw (1 in 32)",
            generate: generate_raw,
            check: check_raw,
        },
    ]
}

/// A number as text in one of the ways people write them.
fn number_text(rng: &mut Rng, v: f64) -> String {
    match rng.below(6) {
        0 => format!("{v:e}"),
        1 => format!("{v:.3}"),
        2 if v.is_sign_positive() => format!("+{v}"),
        3 => format!("{v:E}"),
        _ => format!("{v}"),
    }
}

/// Random samples with strictly increasing times and |displacement| ≤ 1 m.
fn random_samples(rng: &mut Rng, n: usize, temperature: bool) -> Vec<Sample> {
    let mut t = if rng.one_in(3) { 0.0 } else { rng.plain_f64() };
    let step = 10f64.powi(rng.range(0, 6) as i32 - 5);
    (0..n)
        .map(|_| {
            t += step * rng.uniform(0.5, 1.5);
            Sample {
                time_s: t,
                displacement_m: rng.uniform(-1.0, 1.0) * 10f64.powi(-(rng.below(4) as i32)),
                velocity_m_s: rng.plain_f64(),
                force_n: rng.plain_f64(),
                current_a: rng.plain_f64(),
                temperature_c: (temperature && !rng.one_in(5)).then(|| rng.plain_f64()),
            }
        })
        .collect()
}

const CSV_DICTIONARY: &[&[u8]] = &[
    b"time_s",
    b"displacement_m",
    b"velocity_m_s",
    b"force_N",
    b"current_A",
    b"temperature_C",
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"1e308",
    b"1e309",
    b"-0",
    b"5e-324",
    b",",
    b",,",
    b"\r\n",
    b"\n\n",
    b"\xef\xbb\xbf",
    b"99999999999999999999",
    b"0x10",
    b"1_000",
];

/// A CSV recording: either exactly what `to_csv_string` writes (valid), or a hand-made
/// layout (columns in any order, extra columns, spaces, CRLF, BOM, number styles), then
/// mutated most of the time.
fn generate_csv(rng: &mut Rng) -> FuzzInput {
    let n = rng.range(0, 12);
    let temperature = rng.one_in(2);
    let samples = random_samples(rng, n, temperature);
    let written = rng.one_in(2);
    let text = if written {
        to_csv_string(&Recording {
            samples,
            velocity_derived: false,
            has_temperature: temperature,
            source: String::new(),
        })
    } else {
        let mut columns: Vec<&str> = vec![
            "time_s",
            "displacement_m",
            "velocity_m_s",
            "force_N",
            "current_A",
            "temperature_C",
            "note",
        ];
        if !rng.one_in(3) {
            columns.retain(|c| *c != "velocity_m_s");
        }
        if !temperature {
            columns.retain(|c| *c != "temperature_C");
        }
        if rng.one_in(2) {
            columns.retain(|c| *c != "note");
        }
        for i in (1..columns.len()).rev() {
            let j = rng.below(i + 1);
            columns.swap(i, j);
        }
        let eol = if rng.one_in(3) { "\r\n" } else { "\n" };
        let pad = |rng: &mut Rng, s: &str| {
            if rng.one_in(4) {
                format!(" {s} ")
            } else {
                s.to_owned()
            }
        };
        let mut text = String::new();
        if rng.one_in(8) {
            text.push('\u{feff}');
        }
        let header: Vec<String> = columns.iter().map(|c| pad(rng, c)).collect();
        text.push_str(&header.join(","));
        text.push_str(eol);
        for s in &samples {
            let fields: Vec<String> = columns
                .iter()
                .map(|c| {
                    let v = match *c {
                        "time_s" => format!("{}", s.time_s),
                        "displacement_m" => number_text(rng, s.displacement_m),
                        "velocity_m_s" => number_text(rng, s.velocity_m_s),
                        "force_N" => number_text(rng, s.force_n),
                        "current_A" => number_text(rng, s.current_a),
                        "temperature_C" => s
                            .temperature_c
                            .map_or(String::new(), |t| number_text(rng, t)),
                        _ => "x".to_owned(),
                    };
                    pad(rng, &v)
                })
                .collect();
            text.push_str(&fields.join(","));
            text.push_str(eol);
        }
        for _ in 0..rng.below(3) {
            text.push_str(eol);
        }
        text
    };
    let mut data = text.into_bytes();
    // Rounded numbers (`{:.3}`) may repeat a time or hide a displacement: only the plain
    // writer's output is known valid.
    let mut valid = n > 0 && written;
    if !rng.one_in(4) {
        mutate(rng, &mut data, CSV_DICTIONARY, MAX_TEXT);
        valid = false;
    }
    FuzzInput::single("recording.csv", data, valid)
}

/// Bits of every field of a sample, for exact comparisons (NaN included).
fn sample_bits(s: &Sample) -> [u64; 6] {
    [
        s.time_s.to_bits(),
        s.displacement_m.to_bits(),
        s.velocity_m_s.to_bits(),
        s.force_n.to_bits(),
        s.current_a.to_bits(),
        s.temperature_c.map_or(u64::MAX, f64::to_bits),
    ]
}

/// The properties of every accepted recording: finite values, strictly increasing time,
/// displacement in metres.
fn check_recording(rec: &Recording) -> Result<(), String> {
    for (i, s) in rec.samples.iter().enumerate() {
        let finite = [
            s.time_s,
            s.displacement_m,
            s.velocity_m_s,
            s.force_n,
            s.current_a,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite || s.temperature_c.is_some_and(|t| !t.is_finite()) {
            return Err(format!("accepted sample {i} has a non-finite value: {s:?}"));
        }
        if i > 0 && s.time_s <= rec.samples[i - 1].time_s {
            return Err(format!("accepted sample {i}: time does not increase"));
        }
    }
    Ok(())
}

/// 1 in 32 inputs also go through the path reader `read`, from the file `name` in the
/// worker's scratch directory; its error must name that path.
fn check_path_reader<T, E: std::fmt::Display>(
    input: &FuzzInput,
    scratch: &Scratch,
    name: &str,
    data: &[u8],
    read: impl Fn(&std::path::Path) -> Result<T, E>,
) -> Result<(), String> {
    if input.len() % 32 != 7 {
        return Ok(());
    }
    let path = scratch.dir().join(name);
    std::fs::write(&path, data).map_err(|e| format!("scratch write: {e}"))?;
    if let Err(e) = read(&path) {
        names_file(&e.to_string(), &path.display().to_string())?;
    }
    Ok(())
}

fn check_csv(input: &FuzzInput, scratch: &Scratch) -> Result<Verdict, String> {
    let data = input.part("recording.csv");
    let text = String::from_utf8_lossy(data);
    let source = "recording.csv";
    // Not UTF-8 is an I/O error of read_csv, which names the path.
    check_path_reader(input, scratch, source, data, read_csv)?;
    let rec = match parse_csv(&text, source) {
        Ok(rec) => rec,
        Err(e) if input.valid => return Err(format!("valid CSV rejected: {e}")),
        Err(e) => return names_file(&e.to_string(), source),
    };
    if rec.is_empty() {
        return Err("accepted a recording without samples".into());
    }
    check_recording(&rec)?;
    if rec
        .samples
        .iter()
        .any(|s| s.displacement_m.abs() > bridge::csv::MAX_DISPLACEMENT_M)
    {
        return Err("accepted a displacement above 1 m".into());
    }
    // Round trip: what was read, written and read again, is the same to the bit.
    let back = parse_csv(&to_csv_string(&rec), "round-trip.csv")
        .map_err(|e| format!("round trip: the written recording does not read back: {e}"))?;
    let same = back.samples.len() == rec.samples.len()
        && back
            .samples
            .iter()
            .zip(&rec.samples)
            .all(|(a, b)| sample_bits(a) == sample_bits(b))
        && back.has_temperature == rec.has_temperature;
    if !same {
        return Err("round trip: the recording read back differs".into());
    }
    if input.valid {
        // The generator's own text reads back as written: compare with a second write.
        if to_csv_string(&rec).as_bytes() != data {
            return Err("valid CSV: writing what was read gives other text".into());
        }
    }
    Ok(Verdict::Accepted)
}

const UTFSM_DICTIONARY: &[&[u8]] = &[
    b"Header Size: ",
    b"Sampling Interval: ",
    b"Sample Count: ",
    b"Sample Number, Date/Time, CHANNEL0, CHANNEL1, Events",
    b"DAQ Pause",
    b"DAQ Resume",
    b"NaN",
    b"nan",
    b"inf",
    b"1e308",
    b"18446744073709551615",
    b"18446744073709551616",
    b"0",
    b"-1",
    b"\t",
    b"\r\n",
    b"mm",
    b"Hz",
    b"x",
    b"A",
];

/// A test file name (`25mm0x5Hz1A` or `ME25mm0x5Hz`), sometimes mutated.
fn test_name(rng: &mut Rng, raw: bool) -> String {
    let amplitude = rng.pick(&["5", "10", "25", "0x5", "0"]);
    let frequency = rng.pick(&["0x1", "0x25", "0x5", "1", "3", "5", "7", "0"]);
    let mut name = if raw {
        format!("ME{amplitude}mm{frequency}Hz")
    } else {
        let current = rng.pick(&["0", "0x25", "0x5", "0x75", "1"]);
        format!("{amplitude}mm{frequency}Hz{current}A")
    };
    if rng.one_in(3) {
        let mut bytes = name.into_bytes();
        mutate(rng, &mut bytes, UTFSM_DICTIONARY, 64);
        name = String::from_utf8_lossy(&bytes).into_owned();
    }
    name
}

/// A preprocessed file: `time displacement_mm velocity_mm_s force_N` rows, CRLF.
fn generate_preprocessed(rng: &mut Rng) -> FuzzInput {
    let n = rng.range(1, 16);
    let samples = random_samples(rng, n, false);
    let eol = if rng.one_in(4) { "\n" } else { "\r\n" };
    let mut text = String::new();
    for s in &samples {
        let sep = if rng.one_in(4) { "\t" } else { " " };
        text.push_str(&format!(
            "{}{sep}{}{sep}{}{sep}{}{eol}",
            s.time_s,
            number_text(rng, s.displacement_m * 1000.0),
            number_text(rng, s.velocity_m_s),
            number_text(rng, s.force_n)
        ));
    }
    let mut data = text.into_bytes();
    let mut valid = true;
    if !rng.one_in(4) {
        mutate(rng, &mut data, UTFSM_DICTIONARY, MAX_TEXT);
        valid = false;
    }
    let name = test_name(rng, false);
    FuzzInput {
        parts: vec![
            ("name".into(), name.into_bytes()),
            ("test.txt".into(), data),
        ],
        valid,
    }
}

fn check_preprocessed(input: &FuzzInput, scratch: &Scratch) -> Result<Verdict, String> {
    let name = String::from_utf8_lossy(input.part("name"));
    let current_a = match parse_test_name(&name) {
        Some(t) if t.amplitude_m > 0.0 && t.frequency_hz > 0.0 && t.current_a.is_finite() => {
            t.current_a
        }
        Some(t) => return Err(format!("parse_test_name({name:?}) accepted {t:?}")),
        None => 0.5,
    };
    let data = input.part("test.txt");
    check_path_reader(input, scratch, "25mm0x5Hz1A.txt", data, read_preprocessed)?;
    let text = String::from_utf8_lossy(data);
    let source = "25mm0x5Hz1A.txt";
    match parse_preprocessed(&text, source, current_a) {
        Ok(rec) => {
            check_recording(&rec)?;
            let rows = text.lines().filter(|l| !l.trim().is_empty()).count();
            if rec.len() != rows {
                return Err(format!("{rows} rows but {} samples", rec.len()));
            }
            Ok(Verdict::Accepted)
        }
        Err(e) if input.valid => Err(format!("valid preprocessed file rejected: {e}")),
        Err(e) => names_file(&e.to_string(), source),
    }
}

/// A raw logger export: header, column line, five segments separated by `DAQ Pause` /
/// `DAQ Resume` events or NaN rows.
fn generate_raw(rng: &mut Rng) -> FuzzInput {
    let eol = if rng.one_in(4) { "\n" } else { "\r\n" };
    // How each of the four segment breaks is marked: `DAQ Pause` on the segment's last
    // row, `DAQ Resume` on the next one's first row, or a NaN row (with or without a
    // sample number).
    let breaks: Vec<usize> = (0..4).map(|_| rng.below(4)).collect();
    let mut rows = Vec::new();
    let mut number: u64 = rng.below(3) as u64;
    for segment in 0..5 {
        let n = rng.range(1, 5);
        for i in 0..n {
            let resume = segment > 0 && i == 0 && breaks[segment - 1] == 1;
            let pause = segment < 4 && i + 1 == n && breaks[segment] == 0;
            let event = match (resume, pause) {
                (true, true) => "DAQ Resume DAQ Pause",
                (true, false) => "DAQ Resume",
                (false, true) => "DAQ Pause",
                (false, false) => "",
            };
            if event.len() > 10 {
                // One row cannot carry both events: a NaN row marks the break instead.
                rows.push(format!("{number}, x, 1, 1, DAQ Resume"));
                number += 1;
                rows.push("NaN, NaN, NaN, NaN".into());
                continue;
            }
            let (ch0, ch1) = (rng.uniform(-10.0, 10.0), rng.uniform(-10.0, 10.0));
            rows.push(format!(
                "{number}, 11/07/2019 10:00:00.{:03}, {}, {}, {event}",
                rng.below(1000),
                number_text(rng, ch0),
                number_text(rng, ch1),
            ));
            number += 1 + rng.below(2) as u64;
        }
        if segment < 4 && breaks[segment] >= 2 {
            if breaks[segment] == 2 {
                rows.push(format!("{number}, x, NaN, NaN, "));
                number += 1;
            } else {
                rows.push("NaN, NaN, NaN, NaN".into());
            }
        }
    }
    let mut text = String::new();
    let size = 7;
    text.push_str(&format!("Header Size: {size}{eol}"));
    text.push_str(&format!(
        "Sampling Interval: {}{eol}",
        rng.pick(&["0.001", "0.005", "1e-3"])
    ));
    if rng.one_in(2) {
        text.push_str(&format!("Sample Count: {}{eol}", rows.len()));
    } else {
        text.push_str(&format!("Device: logger{eol}"));
    }
    text.push_str(&format!(
        "Start: 11/07/2019{eol}Channels: 2{eol}Units: V{eol}"
    ));
    text.push_str("Sample Number, Date/Time, CHANNEL0, CHANNEL1, Events");
    text.push_str(eol);
    for r in &rows {
        text.push_str(r);
        text.push_str(eol);
    }
    let mut data = text.into_bytes();
    let mut valid = true;
    if !rng.one_in(4) {
        mutate(rng, &mut data, UTFSM_DICTIONARY, MAX_TEXT);
        valid = false;
    }
    let name = test_name(rng, true);
    FuzzInput {
        parts: vec![("name".into(), name.into_bytes()), ("raw.txt".into(), data)],
        valid,
    }
}

fn check_raw(input: &FuzzInput, scratch: &Scratch) -> Result<Verdict, String> {
    let name = String::from_utf8_lossy(input.part("name"));
    let layout = parse_raw_test_name(&name)
        .and_then(|t| ChannelLayout::for_frequency(t.frequency_hz))
        .unwrap_or(if name.len() % 2 == 0 {
            ChannelLayout::ForceOnChannel0
        } else {
            ChannelLayout::DisplacementOnChannel0
        });
    let data = input.part("raw.txt");
    check_path_reader(input, scratch, "ME25mm0x5Hz.txt", data, read_raw)?;
    let text = String::from_utf8_lossy(data);
    let source = "ME25mm0x5Hz.txt";
    match parse_raw(&text, source, layout) {
        Ok(segments) => {
            if segments.len() != 5 {
                return Err(format!("accepted {} segments", segments.len()));
            }
            for s in &segments {
                if s.recording.is_empty() {
                    return Err("accepted an empty segment".into());
                }
                check_recording(&s.recording)?;
            }
            Ok(Verdict::Accepted)
        }
        Err(e) if input.valid => Err(format!("valid raw file rejected: {e}")),
        Err(e) => names_file(&e.to_string(), source),
    }
}
