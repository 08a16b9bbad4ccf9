//! The offline pipeline of Skalski & Zalewski on recordings simulated with the paper's own
//! law: the direct-shear Bodner–Partom model with n, R0 from (5.5) (twin::models::DirectShear),
//! 10 mm stroke at 1.66 / 3.33 / 5 Hz and 0.5 / 1 / 2 A, each test starting from rest.

use estimation::identify::{identify, TestRecord};
use twin::fluid::BodnerPartom;
use twin::models::{DirectShear, DirectShearParams};
use twin::stand::{run, Noise, Programme};

const RATE_HZ: f64 = 20_000.0;

fn simulate(current_a: f64, frequency_hz: f64, noise: Option<Noise>) -> TestRecord {
    let mut model = DirectShear::new(DirectShearParams::default());
    let prog = Programme::grid(0.010, &[frequency_hz], &[current_a], 0.03, RATE_HZ);
    let out = run(&mut model, &prog, noise);
    TestRecord {
        source: format!("{current_a} A {frequency_hz} Hz"),
        current_a,
        temperature_c: Some(25.0),
        time_s: out.iter().map(|s| s.time_s).collect(),
        displacement_m: out.iter().map(|s| s.input.displacement_m).collect(),
        force_n: out.iter().map(|s| s.measured_force_n).collect(),
    }
}

#[test]
fn pipeline_gives_back_n_and_r0_of_the_paper_within_two_percent() {
    let params = DirectShearParams::default();
    let (h, area) = (params.gap_height_m, params.shear_area_m2());
    let currents = [0.5, 1.0, 2.0];
    let mut tests = Vec::new();
    for (k, &i) in currents.iter().enumerate() {
        for (j, &f) in [1.66, 3.33, 5.0].iter().enumerate() {
            // 0.1 % force noise, as a good load cell.
            tests.push(simulate(
                i,
                f,
                Some(Noise {
                    fraction: 1e-3,
                    seed: (10 * k + j) as u64,
                }),
            ));
        }
    }
    let id = identify(&tests, h, area).unwrap_or_else(|e| panic!("{e}"));
    let mut report = String::new();
    for t in &id.tests {
        report.push_str(&format!(
            "{}: rate {:.1} 1/s, tau0 {:.1} kPa, G {:.3} MPa\n",
            t.source,
            t.shear_rate_per_s,
            t.tau0_pa / 1e3,
            t.shear_modulus_pa / 1e6
        ));
    }
    assert_eq!(id.laws.len(), 3);
    for law in &id.laws {
        let truth = BodnerPartom::from_paper(law.current_a, 25.0, h);
        report.push_str(&format!(
            "{} A: n {:.4} ± {:.4} (truth {:.4}), R0 {:.0} ± {:.0} kPa (truth {:.0}), rms {:.2} kPa\n",
            law.current_a,
            law.n,
            law.n_se,
            truth.n,
            law.r0_pa / 1e3,
            law.r0_se_pa / 1e3,
            truth.r0_pa / 1e3,
            law.rms_pa / 1e3
        ));
    }
    eprintln!("{report}");
    for law in &id.laws {
        let truth = BodnerPartom::from_paper(law.current_a, 25.0, h);
        assert!(
            (law.n / truth.n - 1.0).abs() < 0.02,
            "n at {} A\n{report}",
            law.current_a
        );
        assert!(
            (law.r0_pa / truth.r0_pa - 1.0).abs() < 0.02,
            "R0 at {} A\n{report}",
            law.current_a
        );
        assert!(law.n_se.is_finite() && law.r0_se_pa.is_finite());
    }
    // (5.5): n = 0.18 + 0.10 i − 0.0001 t and R0 h = 6.8 − 0.07 i − 0.01 t at t = 25 °C.
    let dep = id
        .dependence
        .expect("three currents give a current dependence");
    assert!(!dep.with_temperature);
    let n0 = 0.18 - 0.0001 * 25.0;
    let r0 = 6.8 - 0.01 * 25.0;
    assert!((dep.n[0].value - n0).abs() < 0.02 * n0, "{dep:?}");
    assert!((dep.n[1].value - 0.10).abs() < 0.01, "{dep:?}");
    assert!((dep.r0_h_kpa_m[0].value - r0).abs() < 0.02 * r0, "{dep:?}");
}
