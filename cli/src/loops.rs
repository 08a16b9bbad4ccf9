//! Slicing a simulated programme into its segments and cycles, and the numbers that
//! characterise each segment's loop.

use std::ops::Range;

use serde::Serialize;
use twin::metrics::{loop_work, zero_force_velocity_gap};
use twin::stand::{Programme, SimulatedSample};

/// The numbers of one programme segment. Cycle numbers are NaN (`null` in JSON) when the
/// segment is shorter than one full cycle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SegmentMetrics {
    /// Coil current \[A\].
    #[serde(rename = "current_A")]
    pub current_a: f64,
    /// Stroke frequency \[Hz\].
    #[serde(rename = "frequency_Hz")]
    pub frequency_hz: f64,
    /// Largest |F| over the whole segment \[N\].
    #[serde(rename = "peak_force_N")]
    pub peak_force_n: f64,
    /// ∮F dx over the last full cycle: energy dissipated per cycle \[J\].
    #[serde(rename = "energy_per_cycle_J")]
    pub energy_per_cycle_j: f64,
    /// Opening of the F–v loop near v = 0 over the last full cycle, as a fraction of the
    /// peak-to-peak velocity (`twin::metrics::zero_force_velocity_gap`).
    pub z_opening: f64,
}

/// The sample ranges of each segment of `programme`, in order (empty for a segment
/// without samples).
pub fn segment_ranges(samples: &[SimulatedSample], programme: &Programme) -> Vec<Range<usize>> {
    (0..programme.segments.len())
        .map(|seg| {
            let start = samples.partition_point(|s| s.segment < seg);
            let end = samples.partition_point(|s| s.segment <= seg);
            start..end
        })
        .collect()
}

/// The last full cycle of a segment of `range` at `frequency_hz`: its last
/// round(rate / f) + 1 samples, a closed loop up to a fraction of a sample. `None` if the
/// segment is shorter than that.
pub fn last_full_cycle(
    range: &Range<usize>,
    rate_hz: f64,
    frequency_hz: f64,
) -> Option<Range<usize>> {
    let period = (rate_hz / frequency_hz).round() as usize;
    if period < 2 || range.len() < period + 1 {
        return None;
    }
    Some(range.end - period - 1..range.end)
}

/// The metrics of every segment (the force is the measured one).
pub fn segment_metrics(samples: &[SimulatedSample], programme: &Programme) -> Vec<SegmentMetrics> {
    segment_ranges(samples, programme)
        .iter()
        .zip(&programme.segments)
        .map(|(range, seg)| {
            let part = &samples[range.clone()];
            let peak_force_n = part
                .iter()
                .map(|s| s.measured_force_n.abs())
                .fold(0.0, f64::max);
            let (energy_per_cycle_j, z_opening) =
                match last_full_cycle(range, programme.rate_hz, seg.frequency_hz) {
                    Some(cycle) => {
                        let c = &samples[cycle];
                        let x: Vec<f64> = c.iter().map(|s| s.input.displacement_m).collect();
                        let v: Vec<f64> = c.iter().map(|s| s.input.velocity_m_s).collect();
                        let f: Vec<f64> = c.iter().map(|s| s.measured_force_n).collect();
                        (loop_work(&x, &f), zero_force_velocity_gap(&v, &f))
                    }
                    None => (f64::NAN, f64::NAN),
                };
            SegmentMetrics {
                current_a: seg.current_a,
                frequency_hz: seg.frequency_hz,
                peak_force_n,
                energy_per_cycle_j,
                z_opening,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn last_cycle_is_one_period_long() {
        assert_eq!(last_full_cycle(&(0..2000), 400.0, 1.66), Some(1758..2000));
        assert_eq!(last_full_cycle(&(0..200), 400.0, 1.66), None);
    }

    #[test]
    fn dashpot_metrics() {
        let programme = Programme::grid(0.01, &[2.0], &[1.0], 1.0, 1000.0);
        let c = 1000.0;
        let samples: Vec<SimulatedSample> = (0..programme.sample_count())
            .map(|k| {
                let (segment, time_s, input) = programme.input_at(k);
                let output = twin::DamperOutput {
                    force_n: c * input.velocity_m_s,
                    ..Default::default()
                };
                SimulatedSample {
                    time_s,
                    segment,
                    input,
                    output,
                    measured_force_n: output.force_n,
                }
            })
            .collect();
        let m = segment_metrics(&samples, &programme);
        assert_eq!(m.len(), 1);
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let expected = std::f64::consts::PI * c * w * 0.01 * 0.01;
        assert!((m[0].energy_per_cycle_j / expected - 1.0).abs() < 1e-3);
        assert!(m[0].z_opening.abs() < 1e-6);
        assert!((m[0].peak_force_n / (c * w * 0.01) - 1.0).abs() < 1e-6);
    }
}
