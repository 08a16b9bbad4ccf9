//! The sub-sample grid the model is evaluated on behind the rig's anti-alias filter.
//!
//! The recorded force is the continuous-time force low-pass filtered, then sampled. At a
//! stroke reversal the force of an MR damper turns over by 2 F_y within a small part of one
//! sample interval; where in the interval that happens moves the filtered, sampled force by
//! a large part of the jump. A model evaluated only at the samples cannot say where, so it
//! leaves several σ_F at every reversal: on the proving ground's nulls, the *true* law at
//! the noise-free filtered velocity, evaluated on the samples and filtered, is still 2–6 σ_F
//! off, and 1.05–1.15 σ_F once evaluated on an 8× finer grid
//! (`scripts/proving_ground/measurement_floor.py`).
//!
//! So, inside every sample interval where the rod reverses (or comes within two intervals'
//! velocity change of it), the model is also evaluated at [`OVERSAMPLING`] − 1 points
//! between the samples, on the velocity rebuilt there by cubic Hermite interpolation
//! (values and accelerations at both ends); displacement, current, dissipated energy and
//! velocity error are interpolated linearly. Elsewhere the force is smooth on the scale of
//! an interval and the filter sees it interpolated linearly between the samples
//! ([`crate::antialias::AntiAlias::resample`]). The model's states (field lag, chamber
//! compliance) are integrated over the sub-steps.
//!
//! An interval where the current steps ([`crate::current`]) is refined too: its inserted
//! points take the level before or after the step, and the one point whose sub-interval
//! holds the step takes the blend of the two that puts the piecewise-linear current's
//! transition where the step is (equal area: the filter sees the step at its time to
//! second order, not rounded to an eighth of a sample).

/// Sub-intervals per refined sample interval (and the rate, in samples, of the filter
/// that runs behind the model).
pub const OVERSAMPLING: usize = 8;

/// Model inputs on the sub-sample grid: the record's samples, with the points inside each
/// refined interval inserted before the sample that ends it.
#[derive(Debug, Clone, Default)]
pub struct SubGrid {
    /// Sub-intervals per sample interval.
    pub m: usize,
    /// Per sample j: the interval (j − 1, j] carries the m − 1 inserted points.
    pub refined: Vec<bool>,
    /// Per sample j: its index on the grid.
    pub pos: Vec<usize>,
    /// Step to the previous grid point \[s\] (0 where the record's step is 0).
    pub h: Vec<f64>,
    /// Velocity \[m/s\].
    pub v: Vec<f64>,
    /// Acceleration \[m/s²\].
    pub a: Vec<f64>,
    /// Displacement \[m\].
    pub x: Vec<f64>,
    /// Current \[A\].
    pub i: Vec<f64>,
    /// Cumulative dissipated energy \[kJ\].
    pub energy_kj: Vec<f64>,
    /// Standard deviation of the velocity's error \[m/s\].
    pub v_sigma: Vec<f64>,
}

/// The model's per-point inputs: the record's samples (a grid is built from them) or the
/// points of a sub-sample grid.
pub struct Channels<'a> {
    /// Step to the previous point \[s\] (0 at the start and after a gap).
    pub h: &'a [f64],
    /// Velocity \[m/s\].
    pub v: &'a [f64],
    /// Acceleration \[m/s²\].
    pub a: &'a [f64],
    /// Displacement \[m\].
    pub x: &'a [f64],
    /// Current \[A\].
    pub i: &'a [f64],
    /// Cumulative dissipated energy \[kJ\].
    pub energy_kj: &'a [f64],
    /// Velocity error \[m/s\].
    pub v_sigma: &'a [f64],
}

impl SubGrid {
    /// The grid with `m` sub-intervals in each interval where the velocity changes sign or
    /// comes within twice its change over the interval of zero, or where the current steps
    /// (`step_at[j]`: the step's position as a fraction of the interval (j − 1, j]).
    pub fn build(c: &Channels, m: usize, step_at: &[Option<f64>]) -> Self {
        let n = c.h.len();
        let m = m.max(1);
        let mut g = SubGrid {
            m,
            refined: vec![false; n],
            pos: Vec::with_capacity(n),
            ..SubGrid::default()
        };
        for j in 0..n {
            let step = step_at.get(j).copied().flatten().filter(|_| j > 0);
            let reversal = m > 1 && j > 0 && c.h[j] > 0.0 && {
                let (v0, v1) = (c.v[j - 1], c.v[j]);
                let sweep = 2.0 * c.a[j - 1].abs().max(c.a[j].abs()) * c.h[j];
                v0 * v1 <= 0.0 || v0.abs().min(v1.abs()) < sweep
            };
            let refine = reversal || (m > 1 && j > 0 && c.h[j] > 0.0 && step.is_some());
            if refine {
                g.refined[j] = true;
                let h = c.h[j];
                for s in 1..m {
                    let w = s as f64 / m as f64;
                    let lerp = |y: &[f64]| (1.0 - w) * y[j - 1] + w * y[j];
                    // Cubic through a reversal; linear where only the current steps (as
                    // the unrefined intervals are seen, and safe where records are joined).
                    let (v, a) = if reversal {
                        hermite(c.v[j - 1], c.a[j - 1], c.v[j], c.a[j], h, w)
                    } else {
                        (lerp(c.v), lerp(c.a))
                    };
                    let i = match step {
                        Some(at) => stepped_current(c.i[j - 1], c.i[j], at, s, m),
                        None => lerp(c.i),
                    };
                    g.push(h / m as f64, v, a, lerp(c.x), i, lerp(c.energy_kj));
                    g.v_sigma.push(lerp(c.v_sigma));
                }
            }
            g.pos.push(g.h.len());
            let h = if g.refined[j] {
                c.h[j] / m as f64
            } else {
                c.h[j]
            };
            g.push(h, c.v[j], c.a[j], c.x[j], c.i[j], c.energy_kj[j]);
            g.v_sigma.push(c.v_sigma[j]);
        }
        g
    }

    fn push(&mut self, h: f64, v: f64, a: f64, x: f64, i: f64, e: f64) {
        self.h.push(h);
        self.v.push(v);
        self.a.push(a);
        self.x.push(x);
        self.i.push(i);
        self.energy_kj.push(e);
    }

    /// The grid's points as model inputs.
    pub fn channels(&self) -> Channels<'_> {
        Channels {
            h: &self.h,
            v: &self.v,
            a: &self.a,
            x: &self.x,
            i: &self.i,
            energy_kj: &self.energy_kj,
            v_sigma: &self.v_sigma,
        }
    }

    /// Number of grid points.
    pub fn len(&self) -> usize {
        self.h.len()
    }

    /// No grid points.
    pub fn is_empty(&self) -> bool {
        self.h.is_empty()
    }
}

/// The current at inserted point `s` of `m` in an interval where it steps from `from` to
/// `to` at the fraction `at`: `from` before the step's sub-interval, `to` after it. Between
/// the sub-interval's two points the model's output is taken as linear, a ramp centred on
/// the sub-interval's middle; to centre it on the step, one of them takes a blend: with the
/// step at ψ ∈ \[0, 1) of its sub-interval, the point before it carries `to` with weight
/// ½ − ψ (ψ < ½), or the point after it `from` with weight ψ − ½, which gives the ramp the
/// step's area. A blend that would fall on a sample is left out (the step then rounds to
/// the sub-interval's middle).
fn stepped_current(from: f64, to: f64, at: f64, s: usize, m: usize) -> f64 {
    let pos = at * m as f64;
    let lo = (pos.floor() as usize).min(m - 1);
    let psi = pos - lo as f64;
    if s <= lo {
        if s == lo && psi < 0.5 {
            from + (0.5 - psi) * (to - from)
        } else {
            from
        }
    } else if s == lo + 1 && psi > 0.5 {
        to - (psi - 0.5) * (to - from)
    } else {
        to
    }
}

/// Cubic Hermite interpolation of a velocity over an interval of length `h` at the
/// fraction `w`, from the values and slopes (accelerations) at its ends: `(v, dv/dt)`.
fn hermite(v0: f64, a0: f64, v1: f64, a1: f64, h: f64, w: f64) -> (f64, f64) {
    let (w2, w3) = (w * w, w * w * w);
    let v = (2.0 * w3 - 3.0 * w2 + 1.0) * v0
        + (w3 - 2.0 * w2 + w) * h * a0
        + (-2.0 * w3 + 3.0 * w2) * v1
        + (w3 - w2) * h * a1;
    let dv = ((6.0 * w2 - 6.0 * w) * v0
        + (3.0 * w2 - 4.0 * w + 1.0) * h * a0
        + (-6.0 * w2 + 6.0 * w) * v1
        + (3.0 * w2 - 2.0 * w) * h * a1)
        / h;
    (v, dv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reversals_are_refined_and_samples_keep_their_values() {
        // 2 Hz sine sampled at 100 Hz: refined intervals sit around the reversals only.
        let n = 200;
        let dt = 0.01;
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let x: Vec<f64> = t.iter().map(|t| 0.01 * (w * t).sin()).collect();
        let v: Vec<f64> = t.iter().map(|t| 0.01 * w * (w * t).cos()).collect();
        let a: Vec<f64> = t.iter().map(|t| -0.01 * w * w * (w * t).sin()).collect();
        let h: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { dt }).collect();
        let zeros = vec![0.0; n];
        let c = Channels {
            h: &h,
            v: &v,
            a: &a,
            x: &x,
            i: &zeros,
            energy_kj: &zeros,
            v_sigma: &zeros,
        };
        let g = SubGrid::build(&c, 8, &[]);
        for j in 0..n {
            assert_eq!(g.v[g.pos[j]], v[j]);
            if g.refined[j] {
                // Inserted points follow the true velocity closely (cubic interpolation).
                for s in 1..8 {
                    let tt = t[j - 1] + s as f64 / 8.0 * dt;
                    let err = (g.v[g.pos[j - 1] + s] - 0.01 * w * (w * tt).cos()).abs();
                    assert!(err < 1e-6, "{j} {s}: {err}");
                }
                assert_eq!(g.pos[j], g.pos[j - 1] + 8);
            } else if j > 0 {
                assert_eq!(g.pos[j], g.pos[j - 1] + 1);
            }
        }
        // Steps add up to the record's time.
        let total: f64 = g.h.iter().sum();
        assert!((total - t[n - 1]).abs() < 1e-9);
        // 8 reversals in 2 s, each refined over a few intervals, not more.
        let refined = g.refined.iter().filter(|r| **r).count();
        assert!((8..=8 * 6).contains(&refined), "{refined}");
    }

    #[test]
    fn a_current_step_is_refined_and_keeps_its_area() {
        // Still rod, current 0 → 1 A stepping 0.3 into the interval (4, 5].
        let n = 10;
        let h: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { 1.0 }).collect();
        let zeros = vec![0.0; n];
        let ones = vec![1.0; n];
        let i: Vec<f64> = (0..n).map(|k| if k < 5 { 0.0 } else { 1.0 }).collect();
        let c = Channels {
            h: &h,
            v: &ones,
            a: &zeros,
            x: &zeros,
            i: &i,
            energy_kj: &zeros,
            v_sigma: &zeros,
        };
        let mut steps = vec![None; n];
        for at in [0.3, 0.05, 0.52, 0.97] {
            steps[5] = Some(at);
            let g = SubGrid::build(&c, 8, &steps);
            assert!(g.refined[5] && !g.refined[4] && !g.refined[6]);
            // The piecewise-linear current over the interval has the step's area: 1 − at.
            let pts: Vec<f64> = (g.pos[4]..=g.pos[5]).map(|p| g.i[p]).collect();
            let area: f64 = pts.windows(2).map(|w| 0.5 * (w[0] + w[1]) / 8.0).sum();
            let rounding = if !(1.0 / 16.0..=15.0 / 16.0).contains(&at) {
                1.0 / 16.0
            } else {
                1e-12
            };
            assert!(
                (area - (1.0 - at)).abs() <= rounding,
                "at {at}: area {area}"
            );
            assert!(pts.iter().all(|x| (0.0..=1.0).contains(x)));
        }
    }
}
