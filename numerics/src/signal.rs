//! Stuck channels: runs where a measured channel repeats exactly one value.
//!
//! A live sensor channel carries noise, so it never repeats one value for long; a run of
//! identical values is a clipped amplifier, a saturated ADC or a dead sensor (the Dyke
//! record's force is stuck at 4545.4545 N for its last 73 samples). The same rule is used
//! on a whole record ([`constant_runs`]: `info`, `fit`, `diagnose`) and sample by sample on
//! a stream ([`StuckDetector`]: the node, live and in replay).

/// Shortest run reported as stuck by default: 20 samples, and at least 20 ms.
pub const MIN_STUCK_SAMPLES: usize = 20;
/// Shortest stuck duration \[s\].
pub const MIN_STUCK_DURATION_S: f64 = 0.02;

/// The shortest stuck run at sample interval `dt` \[samples\]: `min_samples` and 20 ms.
pub fn min_stuck_len(dt: f64, min_samples: usize) -> usize {
    if dt > 0.0 && dt.is_finite() {
        ((MIN_STUCK_DURATION_S / dt).ceil() as usize).max(min_samples)
    } else {
        min_samples
    }
}

/// `true` when `b` is the same reading as `a` (equal to 1e-12 relative: a value written
/// to text and read back).
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + a.abs())
}

/// The runs of at least `min_len` identical values in `y`, as index ranges.
pub fn constant_runs(y: &[f64], min_len: usize) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let n = y.len();
    let mut a = 0;
    while a < n {
        let mut b = a + 1;
        while b < n && same(y[a], y[b]) {
            b += 1;
        }
        if b - a >= min_len.max(2) {
            out.push(a..b);
        }
        a = b;
    }
    out
}

/// The stuck runs of the channels of a record sampled every `dt`, channel by channel, as
/// (index into `channels`, range): runs of [`MIN_STUCK_SAMPLES`] samples and
/// [`MIN_STUCK_DURATION_S`].
pub fn stuck_runs(dt: f64, channels: &[&[f64]]) -> Vec<(usize, std::ops::Range<usize>)> {
    let min_len = min_stuck_len(dt, MIN_STUCK_SAMPLES);
    channels
        .iter()
        .enumerate()
        .flat_map(|(k, y)| constant_runs(y, min_len).into_iter().map(move |r| (k, r)))
        .collect()
}

/// Streaming form of [`constant_runs`] for one channel: a sample is stuck once the channel
/// has held its value for `min_len` samples covering 20 ms, this one included. The first
/// samples of a run cannot be told from a coincidence and pass.
#[derive(Debug, Clone)]
pub struct StuckDetector {
    min_len: usize,
    value: f64,
    run_len: usize,
    run_start_s: f64,
    last_t: f64,
}

impl StuckDetector {
    /// A detector that calls a run stuck from its `min_len`-th sample (and 20 ms).
    pub fn new(min_len: usize) -> Self {
        Self {
            min_len: min_len.max(2),
            value: f64::NAN,
            run_len: 0,
            run_start_s: f64::NAN,
            last_t: f64::NAN,
        }
    }

    /// Feed the channel's value at time `t`; `true` when it is stuck.
    pub fn push(&mut self, t: f64, y: f64) -> bool {
        let dt = if self.run_len > 0 {
            t - self.last_t
        } else {
            0.0
        };
        self.last_t = t;
        if self.run_len > 0 && same(self.value, y) {
            self.run_len += 1;
        } else {
            self.value = y;
            self.run_len = 1;
            self.run_start_s = t;
        }
        // The run covers its samples' intervals: n samples at dt span n·dt.
        let span = t - self.run_start_s + dt;
        self.run_len >= self.min_len && span >= MIN_STUCK_DURATION_S * (1.0 - 1e-9)
    }

    /// Forget the run (after a gap: the next value starts a new one).
    pub fn reset(&mut self) {
        self.run_len = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_one_value_are_found_on_a_record_and_on_a_stream_alike() {
        // Noise, then 30 samples clipped at 5.0, then noise, then 10 repeated (too short).
        let mut y: Vec<f64> = (0..50).map(|k| (k as f64 * 0.7).sin()).collect();
        y.extend(std::iter::repeat_n(5.0, 30));
        y.extend((0..20).map(|k| (k as f64 * 1.3).cos()));
        y.extend(std::iter::repeat_n(-1.0, 10));
        assert_eq!(constant_runs(&y, 20), vec![50..80]);
        // At 1 kHz the 20 ms rule and the 20-sample rule agree.
        assert_eq!(min_stuck_len(1e-3, 20), 20);
        assert_eq!(min_stuck_len(1e-4, 20), 200);
        let mut d = StuckDetector::new(20);
        let flags: Vec<bool> = y
            .iter()
            .enumerate()
            .map(|(k, &v)| d.push(k as f64 * 1e-3, v))
            .collect();
        // The stream knows the run from its 20th sample on.
        let stuck: Vec<usize> = (0..y.len()).filter(|&k| flags[k]).collect();
        assert_eq!(stuck, (69..80).collect::<Vec<_>>());
        // At 10 kHz 20 samples are 2 ms: not yet stuck.
        let mut fast = StuckDetector::new(20);
        let n_stuck = (0..100)
            .filter(|&k| fast.push(k as f64 * 1e-4, 1.0))
            .count();
        assert_eq!(n_stuck, 0);
        assert_eq!(
            (0..300)
                .filter(|&k| fast.push(0.01 + k as f64 * 1e-4, 2.0))
                .count(),
            101
        );
        d.reset();
        assert!(!d.push(1.0, 5.0));
        // A channel that is not measured (NaN) never makes a run.
        let nan = vec![f64::NAN; 100];
        assert!(constant_runs(&nan, 20).is_empty());
        let mut d = StuckDetector::new(20);
        assert!(!(0..100).any(|k| d.push(k as f64 * 1e-3, f64::NAN)));
        // Channel by channel.
        let flat = vec![2.0; 30];
        assert_eq!(
            stuck_runs(1e-3, &[&y, &flat]),
            vec![(0, 50..80), (1, 0..30)]
        );
    }
}
