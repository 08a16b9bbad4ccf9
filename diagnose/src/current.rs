//! The current channel's measurement model.
//!
//! A rig holds the coil current at a level and steps it between levels; the recorded
//! channel is that current through the data-acquisition front end: white noise of a few
//! mA on every sample, and each step smeared by the anti-alias filter over a few samples.
//! Taken as it is, the channel moves the model's yield force with its noise (near 0 A,
//! where F_y(I) is steep, a 5 mA sample moved the predicted force of proving-ground null
//! seed 41 by 2–3 σ_F), and at a step the model sees the *filtered* current and then
//! filters its force again: the step smeared twice (null seed 18, 200 Hz, 0.9 s dwells: two
//! thirds of the baseline's systematic misfit sat in the 1–3 samples after each step).
//!
//! So the channel is conditioned before any fit:
//! * **Plateaus.** Where the current holds (every 5-sample window spans at most
//!   [`STABLE_RANGE_PER_SIGMA`] times the channel's white noise, over at least
//!   [`MIN_PLATEAU_SAMPLES`], with no drift beyond [`MAX_DRIFT_PER_SIGMA`] σ end to end)
//!   the samples take the plateau's median. The noise σ_I comes from second differences
//!   (robust to the few steps, blind to slow trends).
//! * **Steps.** Between two plateaus at most [`MAX_TRANSITION_SAMPLES`] apart that differ
//!   by more than [`MIN_STEP_PER_SIGMA`] σ_I, the current is a step, placed in the
//!   measured channels' time frame: at the time the filtered step crosses its midpoint
//!   when no filter is known, and, under the fitted anti-alias filter
//!   ([`crate::antialias`]), at the true step time fitted to the transition samples with
//!   the filter's step response, plus the filter's group delay (the frame the other
//!   channels are in). The sub-sample grid carries the step inside its interval
//!   ([`crate::subsample`]), so the model's force steps there and is filtered once.
//! * **The front end's cut-off.** The steps are the anti-alias filter's step response,
//!   sampled: their shape gives its cut-off ([`ConditionedCurrent::cutoff_from_steps`]),
//!   independently of any force model, and the force is filtered under it
//!   ([`ConditionedCurrent::front_end_cutoff_hz`] says when it is clear enough).
//! * Anything else (a continuously varying current, a coil current rising over tens of
//!   samples) is left as recorded.

use std::ops::Range;

use serde::Serialize;

/// Largest span of a 5-sample window on a plateau, in σ_I (the span of 5 Gaussian samples
/// exceeds 6 σ about once in 10⁴ windows).
pub const STABLE_RANGE_PER_SIGMA: f64 = 6.0;
/// Fewest samples of a plateau.
pub const MIN_PLATEAU_SAMPLES: usize = 8;
/// Largest drift over a plateau (first five against last five samples), in σ_I.
pub const MAX_DRIFT_PER_SIGMA: f64 = 4.0;
/// Most samples between two plateaus for the change to be a (filtered) step.
pub const MAX_TRANSITION_SAMPLES: usize = 16;
/// Smallest step, in σ_I.
pub const MIN_STEP_PER_SIGMA: f64 = 8.0;

/// Smallest step that enters the cut-off fit ([`ConditionedCurrent::cutoff_from_steps`]), in
/// σ_I.
pub const MIN_CUTOFF_STEP_PER_SIGMA: f64 = 30.0;
/// Largest relative standard error of a cut-off read from the steps that is taken.
pub const MAX_CUTOFF_SE_REL: f64 = 0.1;
/// Largest RMS misfit of the steps' Butterworth responses, in σ_I, for their cut-off to be
/// taken as the front end's.
pub const MAX_STEP_MISFIT_PER_SIGMA: f64 = 2.0;
/// Range of the cut-off searched from the steps, as fractions of the sample rate.
pub const CUTOFF_SEARCH_PER_FS: (f64, f64) = (0.05, 0.5);

/// The anti-alias cut-off read from the current channel's steps.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CutoffFromSteps {
    /// Cut-off \[Hz\].
    pub cutoff_hz: f64,
    /// Its standard error \[Hz\] (from the misfit's curvature).
    pub se_hz: f64,
    /// Steps it was read from.
    pub steps: usize,
    /// RMS misfit of the step responses \[A\].
    pub residual_rms_a: f64,
}

/// A step of the current between two plateaus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentStep {
    /// Last sample of the plateau before.
    pub before: usize,
    /// First sample of the plateau after.
    pub after: usize,
    /// Level before \[A\].
    pub from_a: f64,
    /// Level after \[A\].
    pub to_a: f64,
    /// When the recorded (filtered) step crosses its midpoint \[s\].
    pub midpoint_s: f64,
}

impl CurrentStep {
    /// The samples a step's response is fitted to: its transition and two samples either
    /// side (of a record of `n` samples).
    fn fitted_samples(&self, n: usize) -> std::ops::RangeInclusive<usize> {
        self.before.saturating_sub(2)..=(self.after + 2).min(n - 1)
    }
}

/// The current channel as conditioned.
#[derive(Debug, Clone, Default)]
pub struct ConditionedCurrent {
    /// The recorded current \[A\].
    pub raw: Vec<f64>,
    /// White-noise σ of the channel \[A\].
    pub noise_a: f64,
    /// Plateaus (sample ranges) and their levels \[A\].
    pub plateaus: Vec<(Range<usize>, f64)>,
    /// Steps between plateaus.
    pub steps: Vec<CurrentStep>,
    /// The anti-alias cut-off the steps show ([`ConditionedCurrent::cutoff_from_steps`]).
    pub cutoff: Option<CutoffFromSteps>,
}

/// What the conditioning did, for the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CurrentSummary {
    /// White-noise σ of the current channel \[A\].
    pub noise_a: f64,
    /// Number of plateaus (held stretches) set to their median.
    pub plateaus: usize,
    /// Share of the samples on a plateau.
    pub plateau_share: f64,
    /// Number of steps modelled as sharp steps.
    pub steps: usize,
    /// The anti-alias cut-off read from the steps (`null`: no step high enough, or the
    /// fit ends at the edge of its range).
    pub cutoff_from_steps: Option<CutoffFromSteps>,
}

/// The current at the samples and, per sample j, where in the interval (j − 1, j] the
/// current steps (a fraction in (0, 1]; `None`: no step in it).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlacedCurrent {
    /// Current at the samples \[A\].
    pub i: Vec<f64>,
    /// Step position inside each sample's preceding interval.
    pub step_at: Vec<Option<f64>>,
}

/// Robust white-noise σ from second differences: `e_k − (e_{k−1} + e_{k+1})/2` has variance
/// 1.5 σ² for white noise and cancels any linear trend.
fn noise_sigma(i: &[f64], h: &[f64]) -> f64 {
    let mut d: Vec<f64> = (1..i.len().saturating_sub(1))
        .filter(|&k| h[k] > 0.0 && h[k + 1] > 0.0)
        .map(|k| (i[k] - 0.5 * (i[k - 1] + i[k + 1])).abs())
        .collect();
    numerics::stats::median(&mut d).map_or(0.0, |m| 1.4826 * m / 1.5f64.sqrt())
}

impl ConditionedCurrent {
    /// Find the plateaus and steps of the recorded current `i` (`h[j]` the step to the
    /// previous sample, 0 at a time gap), and the cut-off they show at the record's sample
    /// interval `dt` ([`ConditionedCurrent::cutoff_from_steps`]).
    pub fn condition(t: &[f64], h: &[f64], i: &[f64], dt: f64) -> Self {
        let n = i.len();
        let scale = i.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        // A quantised or noise-free channel: a floor of 1e-6 of the range (and 1 µA).
        let noise = noise_sigma(i, h).max(1e-6 * scale).max(1e-6);
        let span = STABLE_RANGE_PER_SIGMA * noise;
        // Stable samples: the 5-sample window around them, within one run, spans little.
        let stable: Vec<bool> = (0..n)
            .map(|k| {
                if k < 2 || k + 2 >= n || (k - 1..=k + 2).any(|q| h[q] <= 0.0) {
                    return false;
                }
                let w = &i[k - 2..=k + 2];
                let lo = w.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                hi - lo <= span
            })
            .collect();
        let mut plateaus = Vec::new();
        let mut k = 0;
        while k < n {
            if !stable[k] {
                k += 1;
                continue;
            }
            let start = k;
            while k < n && stable[k] && (k == start || h[k] > 0.0) {
                k += 1;
            }
            let r = start..k;
            if r.len() < MIN_PLATEAU_SAMPLES {
                continue;
            }
            let head = i[r.start..r.start + 5].iter().sum::<f64>() / 5.0;
            let tail = i[r.end - 5..r.end].iter().sum::<f64>() / 5.0;
            if (tail - head).abs() > MAX_DRIFT_PER_SIGMA * noise {
                continue;
            }
            let level = crate::stats::median(i[r.clone()].to_vec());
            plateaus.push((r, level));
        }
        // The 5-sample window leaves two samples at each end of a plateau out: grow it
        // back over neighbours within half a window span of its level (an unfiltered jump
        // then has its plateaus meet).
        for q in 0..plateaus.len() {
            let lo_limit = if q == 0 { 0 } else { plateaus[q - 1].0.end };
            let hi_limit = plateaus.get(q + 1).map_or(n, |p| p.0.start);
            let (r, level) = &mut plateaus[q];
            while r.start > lo_limit
                && h[r.start] > 0.0
                && (i[r.start - 1] - *level).abs() <= 0.5 * span
            {
                r.start -= 1;
            }
            while r.end < hi_limit && h[r.end] > 0.0 && (i[r.end] - *level).abs() <= 0.5 * span {
                r.end += 1;
            }
        }
        let mut steps = Vec::new();
        for w in plateaus.windows(2) {
            let ((ra, la), (rb, lb)) = (&w[0], &w[1]);
            let (a, b) = (ra.end - 1, rb.start);
            let gap = (a + 1..=b).any(|q| h[q] <= 0.0);
            // A jump with no sample between the plateaus went through no filter (records
            // joined end to end, a current set between samples): nothing says where in its
            // interval it happened, and the current stays linear across it, as recorded.
            if gap
                || b == a + 1
                || b - a - 1 > MAX_TRANSITION_SAMPLES
                || (lb - la).abs() < MIN_STEP_PER_SIGMA * noise
            {
                continue;
            }
            // Midpoint crossing of the recorded transition (linear between samples).
            let mid = 0.5 * (la + lb);
            let up = lb > la;
            let cross = (a + 1..=b).find(|&q| (i[q] >= mid) == up).unwrap_or(b);
            let (y0, y1) = (i[cross - 1], i[cross]);
            let frac = if (y1 - y0).abs() > 0.0 {
                ((mid - y0) / (y1 - y0)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            steps.push(CurrentStep {
                before: a,
                after: b,
                from_a: *la,
                to_a: *lb,
                midpoint_s: t[cross - 1] + frac * h[cross],
            });
        }
        let mut channel = Self {
            raw: i.to_vec(),
            noise_a: noise,
            plateaus,
            steps,
            cutoff: None,
        };
        channel.cutoff = channel.cutoff_from_steps(t, dt);
        channel
    }

    /// The summary for the report.
    pub fn summary(&self) -> CurrentSummary {
        let on: usize = self.plateaus.iter().map(|(r, _)| r.len()).sum();
        CurrentSummary {
            noise_a: self.noise_a,
            plateaus: self.plateaus.len(),
            plateau_share: on as f64 / self.raw.len().max(1) as f64,
            steps: self.steps.len(),
            cutoff_from_steps: self.cutoff,
        }
    }

    /// The current the model sees: plateaus at their level, each step sharp at its time in
    /// the measured channels' frame. `filter`: the anti-alias cut-off \[Hz\] and group delay
    /// \[s\], under which each step's true time is fitted to its transition samples; without
    /// it the step sits at the recorded midpoint crossing.
    pub fn place(&self, t: &[f64], h: &[f64], filter: Option<(f64, f64)>) -> PlacedCurrent {
        let n = self.raw.len();
        let mut i = self.raw.clone();
        for (r, level) in &self.plateaus {
            i[r.clone()].fill(*level);
        }
        let mut step_at = vec![None; n];
        for s in &self.steps {
            let ts = match filter {
                Some((fc, delay)) => self.fitted_step_time(s, t, fc) + delay,
                None => s.midpoint_s,
            };
            // Inside the transition: after the plateau's last sample, at or before the next
            // plateau's first.
            let ts = ts.clamp(t[s.before] + 1e-9 * h[s.before + 1], t[s.after]);
            for q in s.before + 1..=s.after {
                if t[q] < ts {
                    i[q] = s.from_a;
                } else {
                    if t[q - 1] < ts && step_at[q].is_none() {
                        step_at[q] = Some(((ts - t[q - 1]) / h[q]).clamp(1e-9, 1.0));
                    }
                    i[q] = s.to_a;
                }
            }
        }
        PlacedCurrent { i, step_at }
    }

    /// The front end's anti-alias cut-off as the current channel shows it: the cut-off
    /// \[Hz\] whose analog second-order Butterworth step response, each step at its own
    /// fitted time, best fits the transitions of the steps at least
    /// [`MIN_CUTOFF_STEP_PER_SIGMA`] σ_I high (least squares in log fc, golden section over
    /// [`CUTOFF_SEARCH_PER_FS`] of the sample rate `1/dt`). `None` without such a step, or
    /// when the best cut-off lies at an end of the range (the transitions say no more than
    /// "faster" or "slower" than it can tell). The force, displacement and velocity go
    /// through the same front end ([`crate::antialias`]); a coil that rises over tens of
    /// samples is no step ([`MAX_TRANSITION_SAMPLES`]) and does not enter.
    pub fn cutoff_from_steps(&self, t: &[f64], dt: f64) -> Option<CutoffFromSteps> {
        let steps: Vec<&CurrentStep> = self
            .steps
            .iter()
            .filter(|s| (s.to_a - s.from_a).abs() >= MIN_CUTOFF_STEP_PER_SIGMA * self.noise_a)
            .collect();
        if steps.is_empty() {
            return None;
        }
        let sse = |fc: f64| -> f64 {
            steps
                .iter()
                .map(|s| {
                    let ts = self.fitted_step_time(s, t, fc);
                    self.step_sse(s, t, fc, ts)
                })
                .sum()
        };
        let (lo, hi) = (
            (CUTOFF_SEARCH_PER_FS.0 / dt).ln(),
            (CUTOFF_SEARCH_PER_FS.1 / dt).ln(),
        );
        let (a, b) = numerics::optimize::golden_section(|u| sse(u.exp()), lo, hi, 50);
        let u = 0.5 * (a + b);
        let margin = 0.02 * (hi - lo);
        if u - lo < margin || hi - u < margin {
            return None;
        }
        let fc = u.exp();
        let best = sse(fc);
        let dof = steps
            .iter()
            .map(|s| s.fitted_samples(t.len()).count())
            .sum::<usize>()
            .saturating_sub(steps.len() + 1)
            .max(1);
        // Curvature of the SSE in fc, scaled by the residual variance: its standard error.
        let step = 0.01 * fc;
        let curv = (sse(fc + step) - 2.0 * best + sse(fc - step)) / (step * step);
        let var = best / dof as f64;
        let se_hz = if curv > 0.0 {
            (2.0 * var / curv).sqrt()
        } else {
            f64::INFINITY
        };
        Some(CutoffFromSteps {
            cutoff_hz: fc,
            se_hz,
            steps: steps.len(),
            residual_rms_a: var.sqrt(),
        })
    }

    /// The front end's cut-off \[Hz\] as the steps show it, when they show it clearly:
    /// to within [`MAX_CUTOFF_SE_REL`] of itself, with the step responses fitting to within
    /// [`MAX_STEP_MISFIT_PER_SIGMA`] of the channel's noise (a coil's first-order rise, or
    /// an amplifier's overshoot, is not the anti-alias filter's response).
    pub fn front_end_cutoff_hz(&self) -> Option<f64> {
        self.cutoff
            .filter(|c| {
                c.se_hz <= MAX_CUTOFF_SE_REL * c.cutoff_hz
                    && c.residual_rms_a <= MAX_STEP_MISFIT_PER_SIGMA * self.noise_a
            })
            .map(|c| c.cutoff_hz)
    }

    /// Squared misfit of step `s` at time `ts` under a Butterworth of cut-off `fc` over its
    /// transition and two samples either side.
    fn step_sse(&self, s: &CurrentStep, t: &[f64], fc: f64, ts: f64) -> f64 {
        s.fitted_samples(t.len())
            .map(|q| {
                let y = s.from_a + (s.to_a - s.from_a) * butterworth2_step(t[q] - ts, fc);
                (self.raw[q] - y).powi(2)
            })
            .sum()
    }

    /// The true time of step `s` under a second-order Butterworth of cut-off `fc` \[Hz\]:
    /// the time whose analog step response best fits the recorded transition (least
    /// squares over the transition and two samples either side, golden section).
    fn fitted_step_time(&self, s: &CurrentStep, t: &[f64], fc: f64) -> f64 {
        let (a, b) = numerics::optimize::golden_section(
            |ts| self.step_sse(s, t, fc, ts),
            t[s.before] - 3.0 / fc,
            t[s.after],
            60,
        );
        0.5 * (a + b)
    }
}

/// Unit step response of the analog second-order Butterworth low-pass of cut-off `fc` \[Hz\]
/// at time `t` \[s\] after the step (0 before it).
pub fn butterworth2_step(t: f64, fc: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let wn = 2.0 * std::f64::consts::PI * fc;
    let zeta = std::f64::consts::FRAC_1_SQRT_2;
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let e = (-zeta * wn * t).exp();
    1.0 - e * ((wd * t).cos() + zeta / (1.0 - zeta * zeta).sqrt() * (wd * t).sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// Time, step to the previous sample, current, and the steps (time, from, to).
    type Record = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<(f64, f64, f64)>);

    /// A 1 kHz record of held levels with steps at known sub-sample times, through an
    /// analog 2nd-order Butterworth at 300 Hz, plus 3 mA of white noise.
    fn record(noise: f64) -> Record {
        let steps = [(0.3004, 0.0, 1.2), (0.7637, 1.2, 0.4), (1.1291, 0.4, 0.9)];
        let fc = 300.0;
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let nz = Normal::new(0.0, noise.max(1e-300)).unwrap();
        let n = 1500;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let h: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { 1e-3 }).collect();
        let i: Vec<f64> = t
            .iter()
            .map(|&tk| {
                let mut y = steps[0].1;
                for &(ts, a, b) in &steps {
                    y += (b - a) * butterworth2_step(tk - ts, fc);
                }
                y + if noise > 0.0 {
                    nz.sample(&mut rng)
                } else {
                    0.0
                }
            })
            .collect();
        (t, h, i, steps.to_vec())
    }

    #[test]
    fn plateaus_take_their_level_and_steps_their_true_time() {
        let (t, h, i, truth) = record(3e-3);
        let c = ConditionedCurrent::condition(&t, &h, &i, 1e-3);
        assert!((c.noise_a / 3e-3 - 1.0).abs() < 0.1, "σ_I {}", c.noise_a);
        assert_eq!(c.steps.len(), 3, "{:?}", c.steps);
        assert_eq!(c.plateaus.len(), 4);
        // Under the true filter, each step's time is recovered to a small part of a sample
        // (the midpoint crossing alone lies about one group delay after it).
        let fc = 300.0;
        for (s, &(ts, a, b)) in c.steps.iter().zip(&truth) {
            assert!((s.from_a - a).abs() < 3e-3 && (s.to_a - b).abs() < 3e-3);
            let fitted = c.fitted_step_time(s, &t, fc);
            assert!((fitted - ts).abs() < 0.02e-3, "{fitted} vs {ts}");
            assert!(
                s.midpoint_s - ts > 0.4e-3,
                "midpoint {} vs {ts}",
                s.midpoint_s
            );
        }
        // Placed with a delay of 0.5 ms: the step falls in the interval holding ts + 0.5 ms,
        // at its fraction, and the plateaus are flat.
        let p = c.place(&t, &h, Some((fc, 0.5e-3)));
        for &(ts, a, b) in &truth {
            let tm = ts + 0.5e-3;
            let q = t.iter().position(|&x| x >= tm).unwrap();
            let frac = p.step_at[q].expect("a step in this interval");
            assert!(((t[q - 1] + frac * 1e-3) - tm).abs() < 0.03e-3);
            assert!((p.i[q - 1] - a).abs() < 3e-3 && (p.i[q] - b).abs() < 3e-3);
        }
        assert_eq!(p.step_at.iter().filter(|s| s.is_some()).count(), 3);
        let flat = &p.i[500..700];
        assert!(flat.iter().all(|x| *x == flat[0]));
    }

    #[test]
    fn the_steps_show_the_front_ends_cut_off() {
        // Three steps of 0.5–1.2 A through 300 Hz (0.3 f_s) with 3 mA of noise: the
        // cut-off comes back within 2 % and within three of its standard errors.
        let (t, h, i, _) = record(3e-3);
        let c = ConditionedCurrent::condition(&t, &h, &i, 1e-3);
        let est = c.cutoff.expect("three steps of 170-400 σ_I");
        assert_eq!(est.steps, 3);
        assert!(
            (est.cutoff_hz / 300.0 - 1.0).abs() < 0.02,
            "{} Hz",
            est.cutoff_hz
        );
        assert!(
            (est.cutoff_hz - 300.0).abs() < 3.0 * est.se_hz && est.se_hz < 6.0,
            "{est:?}"
        );
        assert!((est.residual_rms_a / 3e-3 - 1.0).abs() < 0.3, "{est:?}");
        assert_eq!(c.summary().cutoff_from_steps, Some(est));
        // A first-order rise of the same speed (a coil, not the front end) is still a
        // step, but no Butterworth fits it to the channel's noise: its misfit says so.
        let tau = 1.0 / (2.0 * std::f64::consts::PI * 300.0);
        let coil: Vec<f64> = t
            .iter()
            .map(|&tk| {
                if tk < 0.5 {
                    0.2
                } else {
                    0.2 + 0.8 * (1.0 - (-(tk - 0.5) / tau).exp())
                }
            })
            .collect();
        let c = ConditionedCurrent::condition(&t, &h, &coil, 1e-3);
        assert_eq!(c.steps.len(), 1);
        assert_eq!(c.front_end_cutoff_hz(), None, "{:?}", c.cutoff);
        // The Butterworth record's is taken.
        let c = ConditionedCurrent::condition(&t, &h, &i, 1e-3);
        assert_eq!(c.front_end_cutoff_hz(), Some(c.cutoff.unwrap().cutoff_hz));
    }

    #[test]
    fn records_joined_end_to_end_keep_their_jump_as_recorded() {
        // 0.25 A, then 0.5 A from the next sample on (two files joined, no filter).
        let n = 400;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 5e-3).collect();
        let h: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { 5e-3 }).collect();
        let i: Vec<f64> = (0..n).map(|k| if k < 200 { 0.25 } else { 0.5 }).collect();
        let c = ConditionedCurrent::condition(&t, &h, &i, 5e-3);
        assert_eq!(c.plateaus.len(), 2);
        assert_eq!((c.plateaus[0].0.end, c.plateaus[1].0.start), (200, 200));
        assert!(c.steps.is_empty());
        let p = c.place(&t, &h, Some((40.0, 5e-3)));
        assert_eq!(p.i, i);
        assert!(p.step_at.iter().all(|s| s.is_none()));
    }

    #[test]
    fn a_continuously_varying_current_is_left_as_recorded() {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let h: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { 1e-3 }).collect();
        let i: Vec<f64> = t.iter().map(|x| 1.0 + 0.5 * (6.0 * x).sin()).collect();
        let c = ConditionedCurrent::condition(&t, &h, &i, 1e-3);
        let p = c.place(&t, &h, None);
        // A smooth sweep is "stable" sample to sample but drifts: no plateau keeps it.
        assert!(c.plateaus.is_empty(), "{:?}", c.plateaus.len());
        assert_eq!(p.i, i);
        assert!(p.step_at.iter().all(|s| s.is_none()));
    }
}
