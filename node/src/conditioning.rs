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

use serde::{Deserialize, Serialize};

/// Conditioning settings (parameter-file section `conditioning`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConditioningConfig {
    /// Gap after which the model is re-seated instead of integrated across \[s\].
    pub max_gap_s: f64,
}

impl Default for ConditioningConfig {
    fn default() -> Self {
        Self { max_gap_s: 0.1 }
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

/// What to do with an accepted sample.
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
}

/// The conditioning state machine.
#[derive(Debug, Clone, Default)]
pub struct Conditioner {
    cfg: ConditioningConfig,
    last_time_s: Option<f64>,
    counters: StreamCounters,
}

impl Conditioner {
    /// With these settings.
    pub fn new(cfg: ConditioningConfig) -> Self {
        Self {
            cfg,
            last_time_s: None,
            counters: StreamCounters::default(),
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

    /// Judge one sample.
    pub fn admit(&mut self, s: &SensorSample) -> Result<Accepted, Dropped> {
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
        Ok(verdict)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t: f64) -> SensorSample {
        SensorSample {
            time_s: t,
            temperature_c: f64::NAN,
            ..Default::default()
        }
    }

    #[test]
    fn stream_faults_are_sorted_and_counted() {
        let mut c = Conditioner::new(ConditioningConfig { max_gap_s: 0.1 });
        assert_eq!(c.admit(&at(0.0)), Ok(Accepted::Seat));
        assert_eq!(c.admit(&at(0.001)), Ok(Accepted::Step { dt: 0.001 }));
        assert_eq!(c.admit(&at(0.001)), Err(Dropped::Duplicate));
        assert_eq!(c.admit(&at(0.0005)), Err(Dropped::OutOfOrder));
        let mut nan = at(0.002);
        nan.velocity_m_s = f64::NAN;
        assert_eq!(c.admit(&nan), Err(Dropped::NonFinite("velocity_m_s")));
        assert_eq!(c.admit(&at(0.5)), Ok(Accepted::Seat));
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
}
