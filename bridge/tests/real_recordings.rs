//! Reads every real UTFSM recording (`shared/data/real/maurel-utfsm`) and
//! checks that what comes out is physically plausible. Fails, rather than
//! skipping, when the data directory is missing.

use std::path::{Path, PathBuf};

use bridge::utfsm::{self, RawSegment, CURRENT_LEVELS_A};
use bridge::Recording;

/// The tests in the preprocessed folder: (amplitude mm, frequency Hz, file
/// stem prefix, sample interval s).
const TESTS: [(f64, f64, &str, f64); 6] = [
    (2.0, 5.0, "2mm5Hz", 0.005),
    (5.0, 3.0, "5mm3Hz", 0.001),
    (10.0, 1.0, "10mm1Hz", 0.001),
    (25.0, 0.1, "25mm0x1Hz", 0.005),
    (25.0, 0.25, "25mm0x25Hz", 0.005),
    (25.0, 0.5, "25mm0x5Hz", 0.005),
];
const CURRENT_SUFFIXES: [&str; 5] = ["0A", "0x25A", "0x5A", "0x75A", "1A"];

fn data_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real/maurel-utfsm");
    assert!(
        dir.is_dir(),
        "real-data directory {} is missing: these tests need the UTFSM recordings \
         (shared/data/real/maurel-utfsm, with preprocessed/ and raw/)",
        dir.display()
    );
    dir
}

fn max_by(rec: &Recording, f: impl Fn(&bridge::Sample) -> f64) -> f64 {
    rec.samples.iter().map(f).fold(f64::NEG_INFINITY, f64::max)
}

fn min_by(rec: &Recording, f: impl Fn(&bridge::Sample) -> f64) -> f64 {
    rec.samples.iter().map(f).fold(f64::INFINITY, f64::min)
}

/// Half the peak-to-peak value: an amplitude that ignores any offset.
fn half_range(rec: &Recording, f: impl Fn(&bridge::Sample) -> f64 + Copy) -> f64 {
    (max_by(rec, f) - min_by(rec, f)) / 2.0
}

/// Correlation sign check of the PHYSICS.md convention: force and velocity
/// have the same sign most of the time for a damper (F ≈ c v).
fn force_follows_velocity(rec: &Recording) -> bool {
    let mean_f = rec.samples.iter().map(|s| s.force_n).sum::<f64>() / rec.len() as f64;
    rec.samples
        .iter()
        .map(|s| (s.force_n - mean_f) * s.velocity_m_s)
        .sum::<f64>()
        > 0.0
}

fn check_peak_force(what: &str, current_a: f64, peak_n: f64) {
    if current_a == 0.0 {
        assert!(
            (100.0..300.0).contains(&peak_n),
            "{what}: peak force {peak_n:.0} N at 0 A, README says about 190 N"
        );
    }
    if current_a == 1.0 {
        assert!(
            (1000.0..1800.0).contains(&peak_n),
            "{what}: peak force {peak_n:.0} N at 1 A, README says up to about 1.5 kN"
        );
    }
}

#[test]
fn all_preprocessed_files_read_and_are_plausible() {
    let dir = data_dir().join("preprocessed");
    let mut found: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| {
            e.unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|n| n.ends_with(".txt"))
        .collect();
    found.sort();
    let mut expected: Vec<String> = TESTS
        .iter()
        .flat_map(|(_, _, stem, _)| CURRENT_SUFFIXES.map(|c| format!("{stem}{c}.txt")))
        .collect();
    expected.sort();
    assert_eq!(found, expected, "unexpected file set in {}", dir.display());
    assert_eq!(found.len(), 30);

    for (amplitude_mm, frequency_hz, stem, dt) in TESTS {
        let mut peaks = Vec::new();
        for (suffix, current_a) in CURRENT_SUFFIXES.iter().zip(CURRENT_LEVELS_A) {
            let name = format!("{stem}{suffix}");
            let path = dir.join(format!("{name}.txt"));
            let rec = utfsm::read_preprocessed(&path).unwrap_or_else(|e| panic!("{e}"));

            let test = utfsm::parse_test_name(&name).expect("name parses");
            assert!(
                (test.amplitude_m - amplitude_mm / 1000.0).abs() < 1e-12,
                "{name}"
            );
            assert!((test.frequency_hz - frequency_hz).abs() < 1e-12, "{name}");
            assert_eq!(test.current_a, current_a, "{name}");

            assert!(rec.len() > 400, "{name}: only {} samples", rec.len());
            assert!(!rec.velocity_derived && !rec.has_temperature, "{name}");
            assert!(
                rec.samples.iter().all(|s| s.current_a == current_a),
                "{name}"
            );
            assert_eq!(rec.samples[0].time_s, 0.0, "{name}");
            for pair in rec.samples.windows(2) {
                let step = pair[1].time_s - pair[0].time_s;
                assert!((step - dt).abs() < 1e-6, "{name}: step {step} s");
            }
            // The whole record covers at least one period.
            let duration = rec.samples[rec.len() - 1].time_s;
            assert!(duration * frequency_hz >= 1.0, "{name}: {duration} s");

            // Displacement: mean removed, amplitude near nominal (the press
            // reaches about 81 % of it at 2 mm / 5 Hz).
            let amplitude = max_by(&rec, |s| s.displacement_m.abs()) * 1000.0;
            assert!(
                (0.75 * amplitude_mm..1.05 * amplitude_mm).contains(&amplitude),
                "{name}: displacement amplitude {amplitude:.2} mm, nominal {amplitude_mm} mm"
            );
            // Velocity amplitude near A ω of the achieved amplitude.
            let v_peak = max_by(&rec, |s| s.velocity_m_s.abs()) * 1000.0;
            let v_expected = amplitude * 2.0 * std::f64::consts::PI * frequency_hz;
            assert!(
                (v_peak / v_expected - 1.0).abs() < 0.15,
                "{name}: peak velocity {v_peak:.1} mm/s, expected about {v_expected:.1}"
            );

            let peak_force = max_by(&rec, |s| s.force_n.abs());
            check_peak_force(&name, current_a, peak_force);
            assert!(
                force_follows_velocity(&rec),
                "{name}: force opposes velocity"
            );
            peaks.push(peak_force);
        }
        assert!(
            peaks.windows(2).all(|p| p[1] > p[0]),
            "{stem}: peak force does not increase with current: {peaks:?}"
        );
    }
}

#[test]
fn all_raw_files_read_and_are_plausible() {
    let dir = data_dir().join("raw");
    for (stem, amplitude_mm, frequency_hz, dt) in [
        ("ME2mm5Hz", 2.0, 5.0, 0.005),
        ("ME5mm3Hz", 5.0, 3.0, 0.001),
        ("ME25mm0x5Hz", 25.0, 0.5, 0.005),
    ] {
        let name = utfsm::parse_raw_test_name(stem).expect("name parses");
        assert_eq!(name.frequency_hz, frequency_hz);
        let path = dir.join(format!("{stem}.txt"));
        let segments: Vec<RawSegment> = utfsm::read_raw(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(segments.len(), 5, "{stem}");

        let mut peaks = Vec::new();
        for (seg, current_a) in segments.iter().zip(CURRENT_LEVELS_A) {
            let what = format!("{stem} at {current_a} A");
            let rec = &seg.recording;
            assert_eq!(seg.current_a, current_a, "{what}");
            assert!(
                rec.samples.iter().all(|s| s.current_a == current_a),
                "{what}"
            );
            assert!(rec.velocity_derived, "{what}");
            assert!(rec.len() > 1000, "{what}: only {} samples", rec.len());
            assert_eq!(rec.samples[0].time_s, 0.0, "{what}");
            for pair in rec.samples.windows(2) {
                let step = pair[1].time_s - pair[0].time_s;
                assert!((step - dt).abs() < 1e-9, "{what}: step {step} s");
            }

            // Raw displacement keeps the sensor offset (about -30 mm), so
            // judge the amplitude from the peak-to-peak range.
            let amplitude = half_range(rec, |s| s.displacement_m) * 1000.0;
            assert!(
                (0.75 * amplitude_mm..1.05 * amplitude_mm).contains(&amplitude),
                "{what}: displacement amplitude {amplitude:.2} mm, nominal {amplitude_mm} mm"
            );
            let mid = (max_by(rec, |s| s.displacement_m) + min_by(rec, |s| s.displacement_m)) / 2.0;
            assert!(
                (-0.032..-0.028).contains(&mid),
                "{what}: displacement centre {mid} m, expected the ~-30 mm sensor offset"
            );

            // Half peak-to-peak ignores the force offset of a few tens of N.
            let peak_force = half_range(rec, |s| s.force_n);
            check_peak_force(&what, current_a, peak_force);
            assert!(
                force_follows_velocity(rec),
                "{what}: force opposes velocity"
            );
            peaks.push(peak_force);
        }
        assert!(
            peaks.windows(2).all(|p| p[1] > p[0]),
            "{stem}: peak force does not increase with current: {peaks:?}"
        );
    }
}
