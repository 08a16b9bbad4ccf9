//! The first paper's numbers: Skalski & Zalewski (2014), eqs. (5.3) and (5.5), and the
//! shape of their Fig. 10 from the direct-shear model.

use twin::fluid::BodnerPartom;
use twin::models::{DirectShear, DirectShearParams};
use twin::{DamperInput, DamperModel};

const H: f64 = 0.7e-3;
const T: f64 = 25.0;

#[test]
fn n_and_r0_follow_eq_5_5() {
    // n = 0.18 + 0.10 i − 0.0001 t; R0 = (6.8 − 0.07 i − 0.01 t)/h  [kPa, h in m].
    for (i, n, r0_kpa) in [
        (0.5, 0.2275, 6.515 / H),
        (1.0, 0.2775, 6.480 / H),
        (2.0, 0.3775, 6.410 / H),
    ] {
        let bp = BodnerPartom::from_paper(i, T, H);
        assert!((bp.n - n).abs() < 1e-12, "n at {i} A: {}", bp.n);
        assert!(
            (bp.r0_pa / (r0_kpa * 1e3) - 1.0).abs() < 1e-12,
            "R0 at {i} A"
        );
        assert_eq!(bp.d0, 1.0e6);
    }
}

#[test]
fn yield_points_at_the_papers_shear_rates() {
    // Values worked out by hand from (5.3) with (5.5): 1 A, 73 1/s is the ≈364 kPa of
    // PHYSICS.md; 0.5 A and 2 A bracket it.
    for (i, rate, expected_kpa) in [(0.5, 73.0, 287.8), (1.0, 73.0, 364.6), (2.0, 73.0, 539.8)] {
        let tau0 = BodnerPartom::from_paper(i, T, H).yield_point(rate);
        assert!(
            (tau0 / (expected_kpa * 1e3) - 1.0).abs() < 5e-3,
            "{i} A, {rate} 1/s: {tau0} Pa"
        );
    }
    // τ0 rises with shear rate and with current (their Fig. 7).
    let rates = [73.0, 144.0, 217.0];
    let currents = [0.5, 1.0, 2.0];
    for &i in &currents {
        let bp = BodnerPartom::from_paper(i, T, H);
        let t: Vec<f64> = rates.iter().map(|&r| bp.yield_point(r)).collect();
        assert!(t[0] < t[1] && t[1] < t[2], "rate at {i} A: {t:?}");
    }
    for &r in &rates {
        let t: Vec<f64> = currents
            .iter()
            .map(|&i| BodnerPartom::from_paper(i, T, H).yield_point(r))
            .collect();
        assert!(t[0] < t[1] && t[1] < t[2], "current at {r} 1/s: {t:?}");
    }
}

/// Drive the direct-shear gap at a constant shear rate from rest: the first loading of
/// their Figs. 6 and 10.
fn first_loading(rate: f64, duration_s: f64) -> Vec<(f64, f64)> {
    let params = DirectShearParams::default();
    let area = params.shear_area_m2();
    let h = params.gap_height_m;
    let mut m = DirectShear::new(params);
    let dt = 1e-4;
    let n = (duration_s / dt) as usize;
    let mut out = Vec::with_capacity(n);
    for k in 0..=n {
        let t = k as f64 * dt;
        let input = DamperInput {
            displacement_m: rate * h * t,
            velocity_m_s: rate * h,
            current_a: 1.0,
            ambient_temperature_c: T,
            ..Default::default()
        };
        let out_k = if k == 0 {
            m.step(&input, 0.0)
        } else {
            m.step(&input, dt)
        };
        out.push((rate * t, out_k.force_n / area));
    }
    out
}

#[test]
fn direct_shear_first_loading_has_the_shape_of_fig_10() {
    let g = DirectShearParams::default().shear_modulus_pa;
    let mut plateaus = Vec::new();
    for rate in [73.0, 144.0, 217.0] {
        let curve = first_loading(rate, 0.05);
        // Elastic start: slope G.
        let (g1, t1) = curve[5];
        assert!(
            (t1 / g1 / g - 1.0).abs() < 0.02,
            "initial slope at {rate}: {}",
            t1 / g1
        );
        // Plastic plateau: the yield point (5.3) of that rate.
        let plateau = curve.last().unwrap().1;
        let tau0 = BodnerPartom::from_paper(1.0, T, H).yield_point(rate);
        assert!(
            (plateau / tau0 - 1.0).abs() < 5e-3,
            "plateau {plateau} vs τ0 {tau0}"
        );
        // Monotone rise, no overshoot.
        assert!(curve.windows(2).all(|w| w[1].1 >= w[0].1 - 1e-6 * tau0));
        plateaus.push(plateau);
    }
    assert!(plateaus[0] < plateaus[1] && plateaus[1] < plateaus[2]);
}
