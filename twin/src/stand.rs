//! The test stand: a programme of sinusoidal strokes at fixed currents, driven through a
//! model sample by sample, with optional measurement noise. Pure computation; writing
//! the recording is the `bridge` crate's job.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::model::{DamperInput, DamperModel, DamperOutput};

/// One segment of the programme: x = A sin(2π f (t − t_start)) at a constant current.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Stroke amplitude A \[m\].
    pub amplitude_m: f64,
    /// Frequency f \[Hz\].
    pub frequency_hz: f64,
    /// Coil current \[A\].
    pub current_a: f64,
    /// Duration \[s\].
    pub duration_s: f64,
}

/// A test programme: consecutive segments sampled at a fixed rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Programme {
    /// Segments, one after another.
    pub segments: Vec<Segment>,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Ambient temperature \[°C\].
    pub ambient_temperature_c: f64,
}

impl Programme {
    /// Every combination of `currents` (outer) and `frequencies` (inner), one segment each.
    pub fn grid(
        amplitude_m: f64,
        frequencies_hz: &[f64],
        currents_a: &[f64],
        duration_s: f64,
        rate_hz: f64,
    ) -> Self {
        let segments = currents_a
            .iter()
            .flat_map(|&current_a| {
                frequencies_hz.iter().map(move |&frequency_hz| Segment {
                    amplitude_m,
                    frequency_hz,
                    current_a,
                    duration_s,
                })
            })
            .collect();
        Self {
            segments,
            rate_hz,
            ambient_temperature_c: 25.0,
        }
    }

    /// The programme of Skalski & Zalewski: A = 10 mm; 1.66, 3.33, 5 Hz; 0.5, 1, 2 A;
    /// 5 s each at 400 Hz.
    pub fn skalski_zalewski() -> Self {
        Self::grid(0.010, &[1.66, 3.33, 5.0], &[0.5, 1.0, 2.0], 5.0, 400.0)
    }

    /// Total duration \[s\].
    pub fn duration_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// Number of samples (one at t = 0 and one every 1/rate up to the end, excluded).
    pub fn sample_count(&self) -> usize {
        (self.duration_s() * self.rate_hz).round() as usize
    }

    /// The segment index and the input at sample `k` (t = k / rate).
    pub fn input_at(&self, k: usize) -> (usize, f64, DamperInput) {
        let t = k as f64 / self.rate_hz;
        let mut start = 0.0;
        let last = self.segments.len().saturating_sub(1);
        for (i, s) in self.segments.iter().enumerate() {
            // Sample times are compared in whole samples to avoid rounding at boundaries.
            let end_k = ((start + s.duration_s) * self.rate_hz).round() as usize;
            if k < end_k || i == last {
                let tau = t - start;
                let w = 2.0 * std::f64::consts::PI * s.frequency_hz;
                let (sn, cs) = (w * tau).sin_cos();
                let input = DamperInput {
                    displacement_m: s.amplitude_m * sn,
                    velocity_m_s: s.amplitude_m * w * cs,
                    acceleration_m_s2: -s.amplitude_m * w * w * sn,
                    current_a: s.current_a,
                    ambient_temperature_c: self.ambient_temperature_c,
                };
                return (i, t, input);
            }
            start += s.duration_s;
        }
        (0, t, DamperInput::default())
    }
}

/// One simulated sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedSample {
    /// Time \[s\].
    pub time_s: f64,
    /// Segment index in the programme.
    pub segment: usize,
    /// What drove the model.
    pub input: DamperInput,
    /// What the model returned (noise-free).
    pub output: DamperOutput,
    /// The force as a sensor would read it (with noise, if any) \[N\].
    pub measured_force_n: f64,
}

/// Gaussian force-sensor noise: standard deviation `fraction` × peak |F| of the record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Noise standard deviation as a fraction of the peak force.
    pub fraction: f64,
    /// Seed of the random generator (same seed, same record).
    pub seed: u64,
}

/// Drive `model` through the programme, reset at the first sample.
pub fn run(
    model: &mut dyn DamperModel,
    programme: &Programme,
    noise: Option<Noise>,
) -> Vec<SimulatedSample> {
    let n = programme.sample_count();
    let dt = 1.0 / programme.rate_hz;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let (segment, time_s, input) = programme.input_at(k);
        let output = if k == 0 {
            model.reset(&input);
            model.step(&input, 0.0)
        } else {
            model.step(&input, dt)
        };
        out.push(SimulatedSample {
            time_s,
            segment,
            input,
            output,
            measured_force_n: output.force_n,
        });
    }
    if let Some(noise) = noise.filter(|n| n.fraction > 0.0) {
        let peak = out
            .iter()
            .map(|s| s.output.force_n.abs())
            .fold(0.0, f64::max);
        let sigma = noise.fraction * peak;
        if let Ok(normal) = Normal::new(0.0, sigma) {
            let mut rng = rand::rngs::StdRng::seed_from_u64(noise.seed);
            for s in &mut out {
                s.measured_force_n = s.output.force_n + normal.sample(&mut rng);
            }
        }
    }
    out
}
