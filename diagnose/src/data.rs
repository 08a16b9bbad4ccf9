//! The recording as diagnose sees it: signals, derived acceleration and dissipated energy,
//! current levels, strokes (cycles), segments, stroke phases and the fitting / held-out split.

use serde::Serialize;

/// The signals of a recording (SI units, PHYSICS.md conventions).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Signals {
    /// Time \[s\], strictly increasing.
    pub time_s: Vec<f64>,
    /// Displacement x \[m\], positive in extension.
    pub displacement_m: Vec<f64>,
    /// Velocity v \[m/s\].
    pub velocity_m_s: Vec<f64>,
    /// Measured rod force \[N\].
    pub force_n: Vec<f64>,
    /// Coil current \[A\].
    pub current_a: Vec<f64>,
}

/// Why a recording cannot be diagnosed.
#[derive(Debug, Clone, PartialEq)]
pub struct DataError(pub String);

impl std::fmt::Display for DataError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DataError {}

/// Stroke phase of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// |v| below a quarter of the stroke's peak speed.
    NearReversal,
    /// Speed rising (v·a > 0).
    Accelerating,
    /// Speed falling.
    Decelerating,
}

impl Phase {
    /// All phases, in report order.
    pub const ALL: [Phase; 3] = [
        Phase::NearReversal,
        Phase::Accelerating,
        Phase::Decelerating,
    ];
    /// Name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Phase::NearReversal => "near reversal",
            Phase::Accelerating => "accelerating",
            Phase::Decelerating => "decelerating",
        }
    }
}

/// A recording prepared for fitting.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Time \[s\].
    pub t: Vec<f64>,
    /// Displacement \[m\].
    pub x: Vec<f64>,
    /// Velocity \[m/s\].
    pub v: Vec<f64>,
    /// Acceleration \[m/s²\], central difference of v over about ±2 ms.
    pub a: Vec<f64>,
    /// Current \[A\].
    pub i: Vec<f64>,
    /// Measured force \[N\].
    pub f: Vec<f64>,
    /// Cumulative dissipated energy ∫ F v dt from the measurement \[kJ\].
    pub energy_kj: Vec<f64>,
    /// Step to the previous sample \[s\] (0 at the start and after a time gap).
    pub h: Vec<f64>,
    /// Current knots (the distinct current levels, or a grid when there are many).
    pub knots: Vec<f64>,
    /// Stroke (cycle) index of each sample.
    pub cycle: Vec<usize>,
    /// Number of strokes.
    pub cycles: usize,
    /// Segment index of each sample (new segment at a current step or a change of stroke).
    pub segment: Vec<usize>,
    /// Number of segments.
    pub segments: usize,
    /// Stroke phase of each sample.
    pub phase: Vec<Phase>,
    /// Peak speed of each sample's stroke \[m/s\].
    pub stroke_speed: Vec<f64>,
    /// `true` for held-out samples.
    pub holdout: Vec<bool>,
    /// Velocity scale of the friction smoothing \[m/s\] (1 % of the peak speed).
    pub friction_velocity: f64,
    /// How the data were split.
    pub split_method: String,
}

impl Prepared {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Check and prepare the signals.
// Several per-sample arrays are read and written with one index: range loops are clearer.
#[allow(clippy::needless_range_loop)]
pub fn prepare(s: &Signals) -> Result<Prepared, DataError> {
    let n = s.time_s.len();
    for (name, len) in [
        ("displacement_m", s.displacement_m.len()),
        ("velocity_m_s", s.velocity_m_s.len()),
        ("force_N", s.force_n.len()),
        ("current_A", s.current_a.len()),
    ] {
        if len != n {
            return Err(DataError(format!(
                "column {name} has {len} samples, time_s has {n}"
            )));
        }
    }
    if n < 200 {
        return Err(DataError(format!(
            "only {n} samples: diagnose needs at least 200 (several strokes)"
        )));
    }
    for k in 0..n {
        let row = [
            s.time_s[k],
            s.displacement_m[k],
            s.velocity_m_s[k],
            s.force_n[k],
            s.current_a[k],
        ];
        if row.iter().any(|x| !x.is_finite()) {
            return Err(DataError(format!("sample {k} holds a non-finite value")));
        }
        if k > 0 && s.time_s[k] <= s.time_s[k - 1] {
            return Err(DataError(format!("time does not increase at sample {k}")));
        }
    }
    let t = s.time_s.clone();
    let x = s.displacement_m.clone();
    let v = s.velocity_m_s.clone();
    let f = s.force_n.clone();
    let i = s.current_a.clone();
    let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let dt = dts[dts.len() / 2];
    let mut h = vec![0.0; n];
    for k in 1..n {
        let d = t[k] - t[k - 1];
        h[k] = if d > 5.0 * dt { 0.0 } else { d };
    }
    let vpeak = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if vpeak <= 0.0 {
        return Err(DataError(
            "the piston does not move (velocity is zero throughout)".into(),
        ));
    }
    // Acceleration: central difference over ±k samples (about ±2 ms), within runs.
    let kk = ((0.002 / dt).round() as usize).max(1);
    let mut a = vec![0.0; n];
    for j in 0..n {
        let lo = j.saturating_sub(kk);
        let hi = (j + kk).min(n - 1);
        if hi > lo {
            a[j] = (v[hi] - v[lo]) / (t[hi] - t[lo]);
        }
    }
    let mut energy_kj = vec![0.0; n];
    for k in 1..n {
        let p = 0.5 * (f[k] * v[k] + f[k - 1] * v[k - 1]);
        energy_kj[k] = energy_kj[k - 1] + h[k] * p.max(0.0) * 1e-3;
    }
    // Current knots.
    let imax = i.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let tol = (0.02 * imax).max(1e-3);
    let mut levels: Vec<f64> = Vec::new();
    for &c in &i {
        if !levels.iter().any(|l| (l - c).abs() <= tol) {
            levels.push(c);
            if levels.len() > 12 {
                break;
            }
        }
    }
    let knots = if levels.len() <= 12 {
        // Snap each level to the mean of the samples near it.
        let mut k: Vec<f64> = levels
            .iter()
            .map(|l| {
                let near: Vec<f64> = i.iter().copied().filter(|c| (c - l).abs() <= tol).collect();
                near.iter().sum::<f64>() / near.len() as f64
            })
            .collect();
        k.sort_by(f64::total_cmp);
        k
    } else {
        let lo = i.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = i.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (0..8).map(|j| lo + (hi - lo) * j as f64 / 7.0).collect()
    };
    // Strokes: a new cycle where v turns from negative to positive (hysteresis 5 % of peak).
    let thr = 0.05 * vpeak;
    let mut cycle = vec![0usize; n];
    let mut c = 0usize;
    let mut state = 0i8;
    let mut start = 0usize;
    for k in 0..n {
        if h[k] == 0.0 && k > 0 {
            c += 1;
            start = k;
            state = 0;
        }
        if v[k] < -thr {
            state = -1;
        } else if v[k] > thr && state == -1 {
            state = 1;
            if k - start > 4 {
                c += 1;
                start = k;
            }
        }
        cycle[k] = c;
    }
    let cycles = c + 1;
    let mut stroke_speed = vec![0.0f64; cycles];
    for k in 0..n {
        stroke_speed[cycle[k]] = stroke_speed[cycle[k]].max(v[k].abs());
    }
    let stroke_speed: Vec<f64> = cycle.iter().map(|&c| stroke_speed[c]).collect();
    let phase = (0..n)
        .map(|k| {
            if v[k].abs() < 0.25 * stroke_speed[k] {
                Phase::NearReversal
            } else if v[k] * a[k] > 0.0 {
                Phase::Accelerating
            } else {
                Phase::Decelerating
            }
        })
        .collect();
    // Segments: a new one at a current step or where the stroke period changes by > 20 %.
    let mut segment = vec![0usize; n];
    let mut seg = 0usize;
    let mut period_prev: Option<f64> = None;
    let mut cycle_start = vec![0usize; cycles];
    let mut cycle_end = vec![0usize; cycles];
    for k in (0..n).rev() {
        cycle_start[cycle[k]] = k;
    }
    for k in 0..n {
        cycle_end[cycle[k]] = k;
    }
    for k in 0..n {
        let mut new = k > 0 && (h[k] == 0.0 || (i[k] - i[k - 1]).abs() > tol);
        if k > 0 && cycle[k] != cycle[k - 1] {
            let cc = cycle[k];
            let period = t[cycle_end[cc]] - t[cycle_start[cc]];
            let complete = cc + 1 < cycles;
            if let (Some(p), true) = (period_prev, complete) {
                if (period / p - 1.0).abs() > 0.2 {
                    new = true;
                }
            }
            if complete {
                period_prev = Some(period);
            }
        }
        if new {
            seg += 1;
        }
        segment[k] = seg;
    }
    let segments = seg + 1;
    // Split: alternate strokes; short records (< 6 strokes) alternate 0.25 s blocks.
    let (holdout, split_method) = if cycles >= 6 {
        (
            cycle.iter().map(|c| c % 2 == 1).collect(),
            "alternate strokes: strokes are counted from one negative-to-positive velocity \
             crossing to the next; even strokes fit, odd strokes are held out, so both parts \
             cover every segment, current and time of the recording"
                .to_string(),
        )
    } else {
        (
            t.iter()
                .map(|tt| (((tt - t[0]) / 0.25) as usize) % 2 == 1)
                .collect(),
            "alternate 0.25 s blocks (fewer than 6 strokes): even blocks fit, odd blocks are held out"
                .to_string(),
        )
    };
    let friction_velocity = 0.01 * vpeak;
    Ok(Prepared {
        t,
        x,
        v,
        a,
        i,
        f,
        energy_kj,
        h,
        knots,
        cycle,
        cycles,
        segment,
        segments,
        phase,
        stroke_speed,
        holdout,
        friction_velocity,
        split_method,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(n: usize) -> Signals {
        let mut s = Signals::default();
        for k in 0..n {
            let t = k as f64 * 0.001;
            let w = 2.0 * std::f64::consts::PI * 3.0;
            s.time_s.push(t);
            s.displacement_m.push(0.01 * (w * t).sin());
            s.velocity_m_s.push(0.01 * w * (w * t).cos());
            s.force_n.push(100.0 * (w * t).cos());
            s.current_a.push(if t < 1.0 { 0.0 } else { 1.0 });
        }
        s
    }

    #[test]
    fn split_covers_every_current_and_phases_are_sane() {
        let d = prepare(&sine(2000)).unwrap();
        assert_eq!(d.knots, vec![0.0, 1.0]);
        assert!(d.cycles >= 6);
        for level in [0.0, 1.0] {
            let (mut tr, mut ho) = (0, 0);
            for j in 0..d.len() {
                if d.i[j] == level {
                    if d.holdout[j] {
                        ho += 1;
                    } else {
                        tr += 1;
                    }
                }
            }
            assert!(
                tr > 300 && ho > 300,
                "level {level}: {tr} fitting, {ho} held out"
            );
        }
        let near = d
            .phase
            .iter()
            .filter(|p| **p == Phase::NearReversal)
            .count();
        let share = near as f64 / d.len() as f64;
        // |cos| < 0.25 holds for 2 asin(0.25)/π ≈ 16 % of a sine.
        assert!((0.12..0.2).contains(&share), "near-reversal share {share}");
        assert!(d.segments >= 2);
    }

    #[test]
    fn bad_input_is_named() {
        let e = prepare(&sine(100)).unwrap_err();
        assert!(e.0.contains("only 100 samples"), "{e}");
        let mut s = sine(1000);
        s.force_n[500] = f64::NAN;
        assert!(prepare(&s).unwrap_err().0.contains("sample 500"));
        let mut s = sine(1000);
        s.velocity_m_s.iter_mut().for_each(|v| *v = 0.0);
        assert!(prepare(&s).unwrap_err().0.contains("does not move"));
        let mut s = sine(1000);
        s.current_a.pop();
        assert!(prepare(&s).unwrap_err().0.contains("current_A"));
    }
}
