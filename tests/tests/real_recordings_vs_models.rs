//! The damper models against the real UTFSM recordings (`../shared/data/real/`), which no
//! simulator of ours produced.
//!
//! * The Bingham baseline (`twin::models::BinghamDamper`), fitted by linear least squares
//!   per recording, explains most of the force, and its Coulomb level rises with current
//!   in every test programme.
//! * The real F–v loops open near v = 0 (the z-shape of the second paper) far more than
//!   the fitted incompressible Bingham model does on the same kinematics: the real damper
//!   has the compliance the two-chamber model adds.

use std::collections::BTreeMap;
use std::path::PathBuf;

use bridge::utfsm::{parse_test_name, read_preprocessed};
use twin::metrics::zero_force_velocity_gap;
use twin::models::{BinghamDamper, BinghamParams};
use twin::{DamperInput, DamperModel};

fn data_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/maurel-utfsm/preprocessed");
    assert!(
        dir.is_dir(),
        "real recordings not found at {}",
        dir.display()
    );
    dir
}

/// Least squares for F ≈ fc sgn v + c0 v + f0 (normal equations, 3×3 Gauss).
fn fit_bingham(v: &[f64], f: &[f64]) -> [f64; 3] {
    let mut a = [[0.0; 3]; 3];
    let mut b = [0.0; 3];
    for (&v, &f) in v.iter().zip(f) {
        let row = [
            if v > 0.0 {
                1.0
            } else if v < 0.0 {
                -1.0
            } else {
                0.0
            },
            v,
            1.0,
        ];
        for i in 0..3 {
            b[i] += row[i] * f;
            for j in 0..3 {
                a[i][j] += row[i] * row[j];
            }
        }
    }
    for c in 0..3 {
        let p = (c..3)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..3 {
            let k = a[r][c] / a[c][c];
            let pivot_row = a[c];
            for (x, p) in a[r].iter_mut().zip(pivot_row).skip(c) {
                *x -= k * p;
            }
            b[r] -= k * b[c];
        }
    }
    let mut x = [0.0; 3];
    for c in (0..3).rev() {
        x[c] = (b[c] - (c + 1..3).map(|j| a[c][j] * x[j]).sum::<f64>()) / a[c][c];
    }
    x
}

struct Fit {
    current_a: f64,
    coulomb_n: f64,
    r2: f64,
    real_gap: f64,
    model_gap: f64,
}

fn fit_file(path: &std::path::Path) -> Fit {
    let rec = read_preprocessed(path).unwrap_or_else(|e| panic!("{e}"));
    let v: Vec<f64> = rec.samples.iter().map(|s| s.velocity_m_s).collect();
    let f: Vec<f64> = rec.samples.iter().map(|s| s.force_n).collect();
    let [fc, c0, f0] = fit_bingham(&v, &f);
    let current_a = rec.samples[0].current_a;
    // Drive the twin's Bingham model with the fitted parameters through the real kinematics.
    let mut model = BinghamDamper::new(BinghamParams {
        friction_force_n: [fc, 0.0, 0.0],
        damping_n_s_m: [c0, 0.0, 0.0],
        offset_n: f0,
    });
    let predicted: Vec<f64> = rec
        .samples
        .windows(2)
        .map(|w| {
            let input = DamperInput {
                displacement_m: w[1].displacement_m,
                velocity_m_s: w[1].velocity_m_s,
                current_a,
                ..Default::default()
            };
            model.step(&input, w[1].time_s - w[0].time_s).force_n
        })
        .collect();
    let measured = &f[1..];
    let mean = measured.iter().sum::<f64>() / measured.len() as f64;
    let ss_tot: f64 = measured.iter().map(|f| (f - mean).powi(2)).sum();
    let ss_res: f64 = measured
        .iter()
        .zip(&predicted)
        .map(|(m, p)| (m - p).powi(2))
        .sum();
    Fit {
        current_a,
        coulomb_n: fc,
        r2: 1.0 - ss_res / ss_tot,
        real_gap: zero_force_velocity_gap(&v[1..], measured),
        model_gap: zero_force_velocity_gap(&v[1..], &predicted),
    }
}

#[test]
fn bingham_baseline_fits_the_real_damper_and_its_yield_force_rises_with_current() {
    let mut groups: BTreeMap<String, Vec<Fit>> = BTreeMap::new();
    let mut report = String::new();
    for entry in std::fs::read_dir(data_dir()).unwrap() {
        let path = entry.unwrap().path();
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let name = parse_test_name(&stem).unwrap_or_else(|| panic!("bad name {stem}"));
        let fit = fit_file(&path);
        report.push_str(&format!(
            "{stem}: fc {:.0} N, R² {:.3}, zero-force velocity gap real {:.3} model {:.3}\n",
            fit.coulomb_n, fit.r2, fit.real_gap, fit.model_gap
        ));
        let key = format!("{}mm {}Hz", name.amplitude_m * 1e3, name.frequency_hz);
        groups.entry(key).or_default().push(fit);
    }
    eprintln!("{report}");
    assert_eq!(groups.values().map(Vec::len).sum::<usize>(), 30, "{report}");
    for (key, fits) in &mut groups {
        fits.sort_by(|a, b| a.current_a.total_cmp(&b.current_a));
        for fit in fits.iter() {
            assert!(
                fit.r2 > 0.8,
                "{key} {} A: R² {}\n{report}",
                fit.current_a,
                fit.r2
            );
            assert!(
                fit.coulomb_n > 0.0,
                "{key}: negative Coulomb level\n{report}"
            );
        }
        // At 2 mm the stroke hardly exceeds the damper's pre-yield compliance: the force
        // there is set by the compliance (the largest loop opening of all tests, below)
        // and the Coulomb level saturates above 0.5 A, so only larger strokes are
        // required to show a monotone yield force.
        let monotone_from = if key.starts_with("2mm") {
            fits.len() - 2
        } else {
            fits.len()
        };
        for w in fits[..monotone_from].windows(2) {
            assert!(
                w[1].coulomb_n > w[0].coulomb_n,
                "{key}: Coulomb level does not rise from {} A to {} A\n{report}",
                w[0].current_a,
                w[1].current_a
            );
        }
        // At 1 A the real loop opens near v = 0 much more than the incompressible model's.
        let one_amp = fits.last().unwrap();
        assert!(
            one_amp.real_gap > 2.0 * one_amp.model_gap.max(0.005),
            "{key} 1 A: real gap {} vs model {}\n{report}",
            one_amp.real_gap,
            one_amp.model_gap
        );
    }
    let gap_at_1a = |k: &str| groups[k].last().unwrap().real_gap;
    let small = gap_at_1a("2mm 5Hz");
    for key in groups.keys().filter(|k| !k.starts_with("2mm")) {
        assert!(
            small > gap_at_1a(key),
            "2 mm opening {small} not above {key}\n{report}"
        );
    }
}
