//! Numbers that characterise a force–displacement / force–velocity loop.

/// The work ∮F dx over a closed loop (trapezoid rule over consecutive samples) \[J\]:
/// the energy the damper dissipates per cycle.
pub fn loop_work(displacement_m: &[f64], force_n: &[f64]) -> f64 {
    displacement_m
        .windows(2)
        .zip(force_n.windows(2))
        .map(|(x, f)| 0.5 * (f[0] + f[1]) * (x[1] - x[0]))
        .sum()
}

/// The opening of the F–v loop near v = 0 ("z-shape"), as a fraction of the peak-to-peak
/// velocity: the velocity at which the force crosses its mid-level (½(max + min)) while
/// rising, minus the velocity at which it crosses it while falling, over (v_max − v_min).
///
/// A damper whose force follows velocity at once (incompressible Bingham) crosses at
/// v = 0 both ways: 0. Compressibility with flow blocking delays the force after each
/// reversal, so the rising crossing comes at v > 0 and the falling one at v < 0: the
/// number grows with the delay. Give it one or more whole cycles; crossings are averaged.
pub fn zero_force_velocity_gap(velocity_m_s: &[f64], force_n: &[f64]) -> f64 {
    let fmax = force_n.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let fmin = force_n.iter().cloned().fold(f64::INFINITY, f64::min);
    let vmax = velocity_m_s
        .iter()
        .cloned()
        .fold(f64::NEG_INFINITY, f64::max);
    let vmin = velocity_m_s.iter().cloned().fold(f64::INFINITY, f64::min);
    let mid = 0.5 * (fmax + fmin);
    let (mut rise, mut nr, mut fall, mut nf) = (0.0, 0, 0.0, 0);
    for i in 1..force_n.len() {
        let (a, b) = (force_n[i - 1] - mid, force_n[i] - mid);
        if a == b || (a < 0.0) == (b < 0.0) {
            continue;
        }
        let w = a / (a - b);
        let v = velocity_m_s[i - 1] + w * (velocity_m_s[i] - velocity_m_s[i - 1]);
        if b > a {
            rise += v;
            nr += 1;
        } else {
            fall += v;
            nf += 1;
        }
    }
    if nr == 0 || nf == 0 || vmax <= vmin {
        return f64::NAN;
    }
    (rise / nr as f64 - fall / nf as f64) / (vmax - vmin)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dashpot_loop_work_is_pi_c_omega_a_squared() {
        let (c, a, w) = (1000.0, 0.01, 2.0 * std::f64::consts::PI * 2.0);
        let n = 4000;
        let t: Vec<f64> = (0..=n).map(|k| k as f64 / n as f64 * 0.5).collect();
        let x: Vec<f64> = t.iter().map(|t| a * (w * t).sin()).collect();
        let f: Vec<f64> = t.iter().map(|t| c * a * w * (w * t).cos()).collect();
        let expected = std::f64::consts::PI * c * w * a * a;
        assert!((loop_work(&x, &f) / expected - 1.0).abs() < 1e-5);
        assert!(
            zero_force_velocity_gap(&f.iter().map(|f| f / c).collect::<Vec<_>>(), &f).abs() < 1e-9
        );
    }
}
