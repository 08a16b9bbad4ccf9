//! Sample conditioning: the twin steps only on samples that make sense, and counts the
//! rest, so health can say what the stream did.
//!
//! Rules (in order):
//! 1. a non-finite time, displacement, velocity or current → rejected (`non_finite`):
//!    the model cannot step on it. A NaN force means "not measured" (a controller asking
//!    for a prediction) or a sensor fault: the model still steps on the kinematics, the
//!    estimator rejects and counts the sample, and health says so. A NaN temperature
//!    means "not measured";
//! 2. a stamp equal to the previous accepted one → dropped (`duplicates`);
//! 3. a stamp before the previous accepted one → dropped (`out_of_order`): the model has
//!    already integrated past it, and stepping back in time is not physics;
//! 4. a gap longer than `max_gap_s` → accepted, but the model is re-seated at the new
//!    sample (`gaps`): integrating a stroke across a hole would invent a motion.
//!
//! An accepted sample is then *conditioned*:
//! * **stuck channels**: when the displacement, velocity or force has repeated one exact
//!   value for `stuck_samples` samples covering 20 ms ([`numerics::signal::StuckDetector`]:
//!   a clipped amplifier, a saturated ADC, a dead sensor), the sample is marked stuck
//!   (`stuck`). The model still steps on the kinematics; the estimator and the residual
//!   checks leave the sample out, and health says which channel;
//! * **the current channel**: when the recording's current column is the driver's command
//!   voltage (`current_channel: command_voltage`, e.g. the Dyke record), the coil current is
//!   `I = g · max(u, 0)` through a first-order lag `τ dI/dt = g max(u, 0) − I` (exact
//!   discrete step; `driver_gain_a_per_v` g, `driver_lag_s` τ). A unipolar current driver
//!   does not follow a negative command. The model, the estimator and health all see this
//!   coil current.

use numerics::signal::{StuckDetector, MIN_STUCK_SAMPLES};
use serde::{Deserialize, Serialize};

/// What the recording's current column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CurrentChannel {
    /// The coil current in A (default).
    #[default]
    CoilCurrent,
    /// The current driver's command voltage in V.
    CommandVoltage,
}

/// Conditioning settings (parameter-file section `conditioning`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConditioningConfig {
    /// Gap after which the model is re-seated instead of integrated across \[s\].
    pub max_gap_s: f64,
    /// What the current column holds: `coil_current` (default) or `command_voltage`.
    pub current_channel: CurrentChannel,
    /// Coil current per volt of command, with `command_voltage` \[A/V\]. Default 1.
    pub driver_gain_a_per_v: f64,
    /// Time constant of the driver and coil, with `command_voltage` \[s\]. Default 0.
    pub driver_lag_s: f64,
    /// A channel that repeats one value for this many samples (and 20 ms) is stuck.
    /// Default 20.
    pub stuck_samples: usize,
    /// The rod acceleration the model takes (its fluid inertia) is the slope of the
    /// least-squares line through the measured velocity over this last stretch of time,
    /// the new sample included ([`AccelerationEstimator`]) \[s\]. 0: the difference of
    /// the last two samples. Default 5 ms.
    pub acceleration_window_s: f64,
}

impl Default for ConditioningConfig {
    fn default() -> Self {
        Self {
            max_gap_s: 0.1,
            current_channel: CurrentChannel::CoilCurrent,
            driver_gain_a_per_v: 1.0,
            driver_lag_s: 0.0,
            stuck_samples: MIN_STUCK_SAMPLES,
            acceleration_window_s: ACCELERATION_WINDOW_S,
        }
    }
}

/// Default of [`ConditioningConfig::acceleration_window_s`]: 5 ms, 25 samples at 5 kHz
/// and 5 at 1 kHz; at 200 Hz the previous sample alone.
pub const ACCELERATION_WINDOW_S: f64 = 5e-3;

/// Most velocity samples [`AccelerationEstimator`] keeps, whatever the window.
const ACCELERATION_MAX_SAMPLES: usize = 256;

/// The rod acceleration from the measured velocity: the slope of the least-squares line
/// through the velocity samples of the last `window_s` seconds and the new one (at least
/// the previous sample: with a window of 0, the difference of the two). Causal, so the
/// live twin and its replay agree. A rig's velocity channel carries noise that the
/// difference of two samples divides by the sample interval: on proving-ground seed 433
/// (5 kHz, a velocity sensor with 1.5 % noise, a 78 kg moving mass) the difference made
/// the twin's m a mostly noise and its fitted inertia 1.5 kg; the slope over the last 4 ms
/// (20 samples) fits 76.5 kg and the residual falls 81.6 → 41.4 N, over 8 ms 77.9 kg. The
/// line lags the acceleration by half the window (1/4 rad of a 16 Hz stroke at 5 ms).
#[derive(Debug, Clone, Default)]
pub struct AccelerationEstimator {
    window_s: f64,
    /// (time \[s\], velocity \[m/s\]) of the samples kept, oldest first.
    recent: std::collections::VecDeque<(f64, f64)>,
}

impl AccelerationEstimator {
    /// Over the last `window_s` seconds.
    pub fn new(window_s: f64) -> Self {
        Self {
            window_s,
            recent: std::collections::VecDeque::new(),
        }
    }

    /// Forget the samples kept (the model is re-seated: a gap or a reset).
    pub fn reset(&mut self) {
        self.recent.clear();
    }

    /// The acceleration at the new sample (`t`, `v`) \[m/s²\], without keeping it; 0 with
    /// no sample kept.
    pub fn at(&self, t: f64, v: f64) -> f64 {
        let used = self
            .recent
            .iter()
            .rev()
            .enumerate()
            .take_while(|(k, (tk, _))| *k == 0 || t - tk <= self.window_s)
            .count();
        match used {
            0 => 0.0,
            // The difference, exactly.
            1 => {
                let (t0, v0) = self.recent[self.recent.len() - 1];
                (v - v0) / (t - t0)
            }
            _ => {
                let pts = || {
                    self.recent
                        .iter()
                        .skip(self.recent.len() - used)
                        .copied()
                        .chain(std::iter::once((t, v)))
                };
                let n = (used + 1) as f64;
                let (tm, vm) = pts().fold((0.0, 0.0), |(a, b), (tk, vk)| (a + tk, b + vk));
                let (tm, vm) = (tm / n, vm / n);
                let (sxy, sxx) = pts().fold((0.0, 0.0), |(a, b), (tk, vk)| {
                    (a + (tk - tm) * (vk - vm), b + (tk - tm) * (tk - tm))
                });
                if sxx > 0.0 {
                    sxy / sxx
                } else {
                    0.0
                }
            }
        }
    }

    /// Keep the sample (`t`, `v`), after [`AccelerationEstimator::at`] has given its
    /// acceleration.
    pub fn push(&mut self, t: f64, v: f64) {
        self.recent.push_back((t, v));
        while self.recent.len() > ACCELERATION_MAX_SAMPLES
            || self
                .recent
                .front()
                .is_some_and(|(t0, _)| t - t0 > self.window_s && self.recent.len() > 1)
        {
            self.recent.pop_front();
        }
    }
}

/// One sensor sample as the node sees it (SI units, time in s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorSample {
    /// Measurement time \[s\].
    pub time_s: f64,
    /// Displacement \[m\].
    pub displacement_m: f64,
    /// Velocity \[m/s\].
    pub velocity_m_s: f64,
    /// Measured force \[N\].
    pub force_n: f64,
    /// Coil current \[A\].
    pub current_a: f64,
    /// Temperature \[°C\], NaN when not measured.
    pub temperature_c: f64,
}

impl From<&twin::stand::SimulatedSample> for SensorSample {
    /// A simulated test-stand sample as the sensors read it: the measured (noisy) force,
    /// no temperature channel.
    fn from(s: &twin::stand::SimulatedSample) -> Self {
        SensorSample {
            time_s: s.time_s,
            displacement_m: s.input.displacement_m,
            velocity_m_s: s.input.velocity_m_s,
            force_n: s.measured_force_n,
            current_a: s.input.current_a,
            temperature_c: f64::NAN,
        }
    }
}

impl SensorSample {
    /// From the ROS message.
    pub fn from_msg(m: &msgs::DamperSample) -> Self {
        Self {
            time_s: m.header.stamp.as_secs_f64(),
            displacement_m: m.displacement,
            velocity_m_s: m.velocity,
            force_n: m.force,
            current_a: m.current,
            temperature_c: m.temperature,
        }
    }

    /// To the ROS message.
    pub fn to_msg(&self, frame_id: &str) -> msgs::DamperSample {
        msgs::DamperSample {
            header: msgs::Header::at(self.time_s, frame_id),
            displacement: self.displacement_m,
            velocity: self.velocity_m_s,
            force: self.force_n,
            current: self.current_a,
            temperature: self.temperature_c,
        }
    }

    /// From a recording sample.
    pub fn from_recording(s: &bridge::csv::Sample) -> Self {
        Self {
            time_s: s.time_s,
            displacement_m: s.displacement_m,
            velocity_m_s: s.velocity_m_s,
            force_n: s.force_n,
            current_a: s.current_a,
            temperature_c: s.temperature_c.unwrap_or(f64::NAN),
        }
    }
}

/// Why a sample was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dropped {
    /// A required field is NaN or infinite (its name).
    NonFinite(&'static str),
    /// Same stamp as the previous sample.
    Duplicate,
    /// Stamp before the previous sample.
    OutOfOrder,
}

/// What to do with an accepted sample, and the sample as conditioned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Admitted {
    /// Seat or step.
    pub verdict: Accepted,
    /// The sample with the coil current in `current_a`.
    pub sample: SensorSample,
    /// The first stuck channel (CSV column name), if any.
    pub stuck: Option<&'static str>,
}

/// Seat or step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Accepted {
    /// The first sample, or the first after a gap: seat the model here.
    Seat,
    /// Integrate over `dt` seconds.
    Step {
        /// Time since the previous accepted sample \[s\].
        dt: f64,
    },
}

/// Counters of what the stream did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StreamCounters {
    /// Samples seen.
    pub received: u64,
    /// Samples the model stepped on.
    pub accepted: u64,
    /// Rejected for NaN/∞.
    pub non_finite: u64,
    /// Dropped as duplicates.
    pub duplicates: u64,
    /// Dropped as out of order.
    pub out_of_order: u64,
    /// Gaps longer than `max_gap_s` (model re-seated).
    pub gaps: u64,
    /// Accepted samples with a stuck channel.
    pub stuck: u64,
    /// Stepped samples on which the model's implicit solver did not converge (its state
    /// was held; [`twin::DamperOutput::solver_failed`]). Counted by the pipeline.
    pub solver_failures: u64,
}

/// The conditioning state machine.
#[derive(Debug, Clone)]
pub struct Conditioner {
    cfg: ConditioningConfig,
    last_time_s: Option<f64>,
    counters: StreamCounters,
    /// Displacement, velocity and force.
    stuck: [StuckDetector; 3],
    /// Coil current behind the driver's lag \[A\] (command-voltage channel).
    coil_current_a: f64,
}

impl Conditioner {
    /// With these settings.
    pub fn new(cfg: ConditioningConfig) -> Self {
        let detector = StuckDetector::new(cfg.stuck_samples);
        Self {
            cfg,
            last_time_s: None,
            counters: StreamCounters::default(),
            stuck: [detector.clone(), detector.clone(), detector],
            coil_current_a: 0.0,
        }
    }

    /// The coil current for the current column's value `u`, after `dt` (None: seat).
    fn coil_current(&mut self, u: f64, dt: Option<f64>) -> f64 {
        match self.cfg.current_channel {
            CurrentChannel::CoilCurrent => u,
            CurrentChannel::CommandVoltage => {
                let target = self.cfg.driver_gain_a_per_v * u.max(0.0);
                self.coil_current_a = match dt {
                    Some(dt) if self.cfg.driver_lag_s > 0.0 => {
                        let a = (-dt / self.cfg.driver_lag_s).exp();
                        a * self.coil_current_a + (1.0 - a) * target
                    }
                    _ => target,
                };
                self.coil_current_a
            }
        }
    }

    /// Counters so far.
    pub fn counters(&self) -> StreamCounters {
        self.counters
    }

    /// Time of the last accepted sample.
    pub fn last_time_s(&self) -> Option<f64> {
        self.last_time_s
    }

    /// Judge one sample and condition it.
    pub fn admit(&mut self, s: &SensorSample) -> Result<Admitted, Dropped> {
        self.counters.received += 1;
        let fields = [
            ("time_s", s.time_s),
            ("displacement_m", s.displacement_m),
            ("velocity_m_s", s.velocity_m_s),
            ("current_A", s.current_a),
        ];
        if let Some((name, _)) = fields.iter().find(|(_, v)| !v.is_finite()) {
            self.counters.non_finite += 1;
            return Err(Dropped::NonFinite(name));
        }
        let verdict = match self.last_time_s {
            None => Accepted::Seat,
            Some(t0) if s.time_s == t0 => {
                self.counters.duplicates += 1;
                return Err(Dropped::Duplicate);
            }
            Some(t0) if s.time_s < t0 => {
                self.counters.out_of_order += 1;
                return Err(Dropped::OutOfOrder);
            }
            Some(t0) if s.time_s - t0 > self.cfg.max_gap_s => {
                self.counters.gaps += 1;
                Accepted::Seat
            }
            Some(t0) => Accepted::Step { dt: s.time_s - t0 },
        };
        self.last_time_s = Some(s.time_s);
        self.counters.accepted += 1;
        let dt = match verdict {
            Accepted::Seat => {
                for d in &mut self.stuck {
                    d.reset();
                }
                None
            }
            Accepted::Step { dt } => Some(dt),
        };
        let channels = [
            ("displacement_m", s.displacement_m),
            ("velocity_m_s", s.velocity_m_s),
            ("force_N", s.force_n),
        ];
        let mut stuck = None;
        // Every detector sees its channel (each keeps its own run); a NaN force (not
        // measured) never equals itself, so it never makes a run.
        for (d, (name, y)) in self.stuck.iter_mut().zip(channels) {
            if d.push(s.time_s, y) && stuck.is_none() {
                stuck = Some(name);
            }
        }
        self.counters.stuck += u64::from(stuck.is_some());
        let sample = SensorSample {
            current_a: self.coil_current(s.current_a, dt),
            ..*s
        };
        Ok(Admitted {
            verdict,
            sample,
            stuck,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// The acceleration at (`t`, `v`), then the sample kept, as the pipeline does per sample.
    fn step(a: &mut AccelerationEstimator, t: f64, v: f64) -> f64 {
        let at = a.at(t, v);
        a.push(t, v);
        at
    }

    /// With a window of 0 the estimate is the difference of the last two samples, bit for
    /// bit; a reset forgets the samples kept.
    #[test]
    fn a_zero_acceleration_window_is_the_difference_of_two_samples() {
        let mut a = AccelerationEstimator::new(0.0);
        assert_eq!(step(&mut a, 0.0, 0.3), 0.0, "no sample kept yet");
        let v = [0.3, 0.31, 0.335, 0.33];
        for k in 1..v.len() {
            let (t0, t1) = ((k - 1) as f64 * 1e-3, k as f64 * 1e-3);
            assert_eq!(step(&mut a, t1, v[k]), (v[k] - v[k - 1]) / (t1 - t0));
        }
        a.reset();
        assert_eq!(a.at(1.0, 0.5), 0.0);
    }

    /// Over a window the estimate is exact on a velocity ramp (a constant acceleration), and
    /// on a noisy velocity its noise is the line's slope error, far below the difference's:
    /// at 5 kHz and 5 ms (26 samples) σ_v √(12 / (n (n² − 1))) / Δt against σ_v √2 / Δt.
    #[test]
    fn the_windowed_acceleration_is_exact_on_a_ramp_and_averages_the_noise() {
        let (dt, accel) = (2e-4, 3.0);
        let mut ramp = AccelerationEstimator::new(ACCELERATION_WINDOW_S);
        let mut last = 0.0;
        for k in 0..200 {
            let t = k as f64 * dt;
            last = step(&mut ramp, t, 0.1 + accel * t);
        }
        assert!((last / accel - 1.0).abs() < 1e-9, "{last}");
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let noise = Normal::new(0.0, 1e-3).unwrap();
        let (mut windowed, mut difference) = (
            AccelerationEstimator::new(ACCELERATION_WINDOW_S),
            AccelerationEstimator::new(0.0),
        );
        let (mut sw, mut sd, mut n) = (0.0, 0.0, 0.0);
        for k in 0..20_000 {
            let t = k as f64 * dt;
            let v = 0.1 + accel * t + noise.sample(&mut rng);
            let (w, d) = (step(&mut windowed, t, v), step(&mut difference, t, v));
            if k >= 100 {
                sw += (w - accel).powi(2);
                sd += (d - accel).powi(2);
                n += 1.0;
            }
        }
        let (sw, sd) = ((sw / n).sqrt(), (sd / n).sqrt());
        let m = 26.0f64;
        let expected = 1e-3 * (12.0 / (m * (m * m - 1.0))).sqrt() / dt;
        assert!(
            (sd / (1e-3 * 2f64.sqrt() / dt) - 1.0).abs() < 0.05,
            "difference {sd}"
        );
        assert!(
            (sw / expected - 1.0).abs() < 0.1,
            "windowed {sw} against {expected}"
        );
    }

    fn at(t: f64) -> SensorSample {
        SensorSample {
            time_s: t,
            temperature_c: f64::NAN,
            ..Default::default()
        }
    }

    #[test]
    fn stream_faults_are_sorted_and_counted() {
        let mut c = Conditioner::new(ConditioningConfig::default());
        let verdict = |r: Result<Admitted, Dropped>| r.map(|a| a.verdict);
        assert_eq!(verdict(c.admit(&at(0.0))), Ok(Accepted::Seat));
        assert_eq!(
            verdict(c.admit(&at(0.001))),
            Ok(Accepted::Step { dt: 0.001 })
        );
        assert_eq!(c.admit(&at(0.001)), Err(Dropped::Duplicate));
        assert_eq!(c.admit(&at(0.0005)), Err(Dropped::OutOfOrder));
        let mut nan = at(0.002);
        nan.velocity_m_s = f64::NAN;
        assert_eq!(c.admit(&nan), Err(Dropped::NonFinite("velocity_m_s")));
        assert_eq!(verdict(c.admit(&at(0.5))), Ok(Accepted::Seat));
        let k = c.counters();
        assert_eq!(
            (
                k.received,
                k.accepted,
                k.duplicates,
                k.out_of_order,
                k.non_finite,
                k.gaps
            ),
            (6, 3, 1, 1, 1, 1)
        );
    }

    #[test]
    fn a_clipped_force_is_stuck_from_its_twentieth_sample_and_a_gap_restarts_the_count() {
        let mut c = Conditioner::new(ConditioningConfig::default());
        let mut stuck = Vec::new();
        for k in 0..100 {
            let s = SensorSample {
                time_s: k as f64 * 1e-3,
                displacement_m: 1e-3 * (k as f64 * 0.1).sin(),
                velocity_m_s: 0.1 * (k as f64 * 0.1).cos(),
                force_n: if k >= 50 { 4545.4545 } else { k as f64 },
                ..at(0.0)
            };
            if c.admit(&s).unwrap().stuck.is_some() {
                stuck.push(k);
            }
        }
        assert_eq!(stuck, (69..100).collect::<Vec<_>>());
        assert_eq!(c.counters().stuck, 31);
        // After a gap the run starts again.
        let s = SensorSample {
            time_s: 1.0,
            force_n: 4545.4545,
            ..at(0.0)
        };
        assert_eq!(c.admit(&s).unwrap().stuck, None);
    }

    #[test]
    fn a_command_voltage_becomes_a_lagging_coil_current_that_ignores_negative_commands() {
        let mut c = Conditioner::new(ConditioningConfig {
            current_channel: CurrentChannel::CommandVoltage,
            driver_gain_a_per_v: 0.5,
            driver_lag_s: 0.01,
            ..Default::default()
        });
        let mut coil = |t: f64, u: f64| {
            let s = SensorSample {
                time_s: t,
                current_a: u,
                force_n: t,
                ..at(0.0)
            };
            c.admit(&s).unwrap().sample.current_a
        };
        // Seated at the command's current, a negative command drives no current.
        assert_eq!(coil(0.0, -0.4), 0.0);
        // A 2 V step: 1 A after the lag, 1 − e⁻¹ of the way after one time constant.
        let mut i = 0.0;
        for k in 1..=10 {
            i = coil(k as f64 * 1e-3, 2.0);
        }
        assert!((i - (1.0 - (-1.0f64).exp())).abs() < 1e-12, "{i}");
        for k in 11..=200 {
            i = coil(k as f64 * 1e-3, 2.0);
        }
        assert!((i - 1.0).abs() < 1e-6, "{i}");
    }
}
