//! The twin core: one sensor sample in, the messages to publish out. It knows no clock
//! and no transport, so the live node, replay, record, the demo and any fleet are thin
//! loops around it, and a replay of a live run's samples publishes the same bytes.
//!
//! Everything published because of a sample — `twin/output`, `twin/predicted_force`,
//! `twin/yield_estimate` at its period and `/diagnostics` at its period or when the
//! level changes — is scheduled on the **sample stamps**, never on the caller's clock.
//! The caller's clock (`now`, monotonic seconds) serves one purpose: noticing that the
//! samples stopped ([`TwinCore::on_idle`] announces STALE), which by its nature only a
//! live run can see.

use bridge::transport::Message;
use estimation::health::Level;
use msgs::{DiagnosticArray, Float64, Header, TwinOutput};

use crate::conditioning::{SensorSample, StreamCounters};
use crate::config::{InvalidParam, TwinNodeParams};
use crate::diagnostics::{diagnostic_array, level_byte, worst, StreamState};
use crate::pipeline::{Processed, TwinPipeline, TwinStep};

/// Shortest sample time between two diagnostics published because the level changed \[s\]
/// (≤ 10 Hz, so a flickering check cannot flood `/diagnostics`).
pub const LEVEL_CHANGE_MIN_INTERVAL_S: f64 = 0.1;

/// Who the core speaks as, and its publishing periods.
#[derive(Debug, Clone, PartialEq)]
pub struct CoreConfig {
    /// Fully qualified node name (`/ns/name`): names the diagnostic statuses.
    pub node_name: String,
    /// Damper name: frame_id of the outputs, hardware_id of the statuses.
    pub damper: String,
    /// Period of `twin/yield_estimate` in sample time \[s\].
    pub yield_estimate_period_s: f64,
    /// Period of `/diagnostics` \[s\] (sample time while samples flow, the caller's
    /// clock while they do not).
    pub diagnostics_period_s: f64,
    /// Silence after which the sensor stream is STALE \[s\] (caller's clock), and the
    /// stamp gap after which the stream counts as resumed (sample time).
    pub stale_after_s: f64,
}

impl CoreConfig {
    /// The core settings of a twin node's parameters, speaking as `node_name`.
    pub fn of(params: &TwinNodeParams, node_name: &str) -> Self {
        Self {
            node_name: node_name.to_string(),
            damper: params.damper.clone(),
            yield_estimate_period_s: params.yield_estimate_period_s,
            diagnostics_period_s: params.diagnostics_period_s,
            stale_after_s: params.stale_after_s,
        }
    }
}

/// What one sample produced: the pipeline's verdict and the messages to publish.
#[derive(Debug, Clone, PartialEq)]
pub struct Outputs {
    /// The pipeline's verdict on the sample.
    pub processed: Processed,
    /// `twin/output` (when the model stepped).
    pub output: Option<TwinOutput>,
    /// `twin/predicted_force` (when the model stepped).
    pub force: Option<Float64>,
    /// `twin/yield_estimate` (at its period).
    pub yield_estimate: Option<msgs::YieldEstimate>,
    /// `/diagnostics` (at its period, and at once when the level changes).
    pub diagnostics: Option<DiagnosticArray>,
}

impl Outputs {
    /// The messages in publishing order: output, force, yield estimate, diagnostics.
    pub fn into_messages(self) -> impl Iterator<Item = Message> {
        self.output
            .map(Message::Output)
            .into_iter()
            .chain(self.force.map(Message::PredictedForce))
            .chain(self.yield_estimate.map(Message::YieldEstimate))
            .chain(self.diagnostics.map(Message::Diagnostics))
    }
}

/// Where the sample-driven diagnostics schedule stands (sample time).
#[derive(Debug, Clone, Copy)]
struct SampleSchedule {
    next_yield_s: Option<f64>,
    next_diag_s: Option<f64>,
    last_diag_s: f64,
    last_sample_s: Option<f64>,
    level: Level,
    previous: StreamCounters,
}

/// Where the idle (clock-driven) STALE announcements stand.
#[derive(Debug, Clone, Copy, Default)]
struct IdleSchedule {
    last_arrival: Option<f64>,
    last_announced: Option<f64>,
}

/// The twin core. See the module documentation.
pub struct TwinCore {
    cfg: CoreConfig,
    pipeline: TwinPipeline,
    schedule: SampleSchedule,
    idle: IdleSchedule,
    transport_errors: u64,
    transport_errors_reported: u64,
}

impl TwinCore {
    /// The core of a twin node with `params`, speaking as `node_name`.
    pub fn new(params: &TwinNodeParams, node_name: &str) -> Result<Self, CoreError> {
        params.validate()?;
        let pipeline = TwinPipeline::new(params.pipeline_config()?)?;
        Ok(Self::with_pipeline(
            CoreConfig::of(params, node_name),
            pipeline,
        ))
    }

    /// The core around an existing pipeline.
    pub fn with_pipeline(cfg: CoreConfig, pipeline: TwinPipeline) -> Self {
        Self {
            cfg,
            schedule: SampleSchedule {
                next_yield_s: None,
                next_diag_s: None,
                last_diag_s: f64::NEG_INFINITY,
                last_sample_s: None,
                level: Level::Stale,
                previous: pipeline.counters(),
            },
            pipeline,
            idle: IdleSchedule::default(),
            transport_errors: 0,
            transport_errors_reported: 0,
        }
    }

    /// The pipeline (estimates, counters, checks).
    pub fn pipeline(&self) -> &TwinPipeline {
        &self.pipeline
    }

    /// The settings.
    pub fn config(&self) -> &CoreConfig {
        &self.cfg
    }

    /// Count one failed publish or poll; it shows in the next `/diagnostics`.
    pub fn count_transport_error(&mut self) {
        self.transport_errors += 1;
    }

    /// Transport errors counted so far.
    pub fn transport_errors(&self) -> u64 {
        self.transport_errors
    }

    /// Take one sample that arrived at `now` (caller's clock, seconds): step the twin and
    /// return what to publish. The messages depend on the samples alone, not on `now`.
    pub fn on_sample(&mut self, sample: &SensorSample, now: f64) -> Outputs {
        self.idle = IdleSchedule {
            last_arrival: Some(now),
            last_announced: None,
        };
        let processed = self.pipeline.process(sample);
        let t = sample.time_s;
        let mut out = Outputs {
            processed,
            output: None,
            force: None,
            yield_estimate: None,
            diagnostics: None,
        };
        if let Processed::Stepped(step) = &processed {
            out.output = Some(twin_output(
                step,
                &self.cfg.damper,
                self.pipeline.model_id(),
            ));
            out.force = Some(Float64 {
                data: step.output.force_n,
            });
            if self.schedule.next_yield_s.is_none_or(|next| t >= next) {
                self.schedule.next_yield_s = Some(t + self.cfg.yield_estimate_period_s);
                out.yield_estimate = Some(yield_msg(&self.pipeline, step, &self.cfg.damper));
            }
        }
        if t.is_finite() {
            out.diagnostics = self.sample_diagnostics(t);
            self.schedule.last_sample_s = Some(match self.schedule.last_sample_s {
                Some(last) => last.max(t),
                None => t,
            });
        }
        out
    }

    /// `/diagnostics` due at sample time `t`: the first sample, every period, when the
    /// stream resumes after a stamp gap longer than the stale time, and at once (≤ 10 Hz)
    /// when the level changes.
    fn sample_diagnostics(&mut self, t: f64) -> Option<DiagnosticArray> {
        let s = self.schedule;
        let counters = self.pipeline.counters();
        let stream = StreamState {
            silence_s: Some(0.0),
            stale_after_s: self.cfg.stale_after_s,
            counters,
            previous: s.previous,
            rate_hz: rate(counters.received - s.previous.received, t - s.last_diag_s),
            transport_errors: self.transport_errors - self.transport_errors_reported,
        };
        let level = worst([stream.level(), self.pipeline.health_level()]);
        let periodic = s.next_diag_s.is_none_or(|next| t >= next);
        let resumed = s
            .last_sample_s
            .is_some_and(|last| t - last > self.cfg.stale_after_s);
        let changed = level != s.level && t - s.last_diag_s >= LEVEL_CHANGE_MIN_INTERVAL_S;
        if !(periodic || resumed || changed) {
            return None;
        }
        let msg = self.diagnostics(t, stream);
        self.schedule.level = level;
        if periodic || resumed {
            self.schedule.next_diag_s = Some(t + self.cfg.diagnostics_period_s);
            self.schedule.previous = counters;
            self.schedule.last_diag_s = t;
            self.transport_errors_reported = self.transport_errors;
        }
        Some(msg)
    }

    /// No sample now (caller's clock, seconds): `/diagnostics` with a STALE sensor stream
    /// when the samples have stopped for longer than the stale time (or never came),
    /// at once and then every period. Nothing while samples flow.
    pub fn on_idle(&mut self, now: f64) -> Option<DiagnosticArray> {
        let silence_s = self.idle.last_arrival.map(|t| (now - t).max(0.0));
        if silence_s.is_some_and(|s| s <= self.cfg.stale_after_s) {
            return None;
        }
        if self
            .idle
            .last_announced
            .is_some_and(|t| now - t < self.cfg.diagnostics_period_s)
        {
            return None;
        }
        self.idle.last_announced = Some(now);
        let counters = self.pipeline.counters();
        let stream = StreamState {
            silence_s,
            stale_after_s: self.cfg.stale_after_s,
            counters,
            previous: self.schedule.previous,
            rate_hz: 0.0,
            transport_errors: self.transport_errors - self.transport_errors_reported,
        };
        let stamp = self.schedule.last_sample_s.unwrap_or(0.0);
        let msg = self.diagnostics(stamp, stream);
        self.schedule.previous = counters;
        self.transport_errors_reported = self.transport_errors;
        Some(msg)
    }

    /// The DiagnosticArray of the stream check and the pipeline's checks at `stamp_s`.
    fn diagnostics(&self, stamp_s: f64, stream: StreamState) -> DiagnosticArray {
        let mut checks = vec![stream.check()];
        checks.extend(self.pipeline.checks());
        diagnostic_array(&self.cfg.node_name, &self.cfg.damper, stamp_s, &checks)
    }

    /// The worst level now, the stream's silence at `now` included.
    pub fn level(&self, now: f64) -> Level {
        let stale = self
            .idle
            .last_arrival
            .is_none_or(|t| now - t > self.cfg.stale_after_s);
        if stale {
            Level::Stale
        } else {
            worst([self.schedule.level, self.pipeline.health_level()])
        }
    }

    /// What-if: the force at `sample` with `planned_current_a`, the twin not advanced.
    pub fn predict_with_current(&self, sample: &SensorSample, planned_current_a: f64) -> f64 {
        self.pipeline
            .predict_with_current(sample, planned_current_a)
    }
}

/// Samples per second: `n` over `dt` seconds (0 when `dt` is not positive and finite).
fn rate(n: u64, dt: f64) -> f64 {
    if dt.is_finite() && dt > 0.0 {
        n as f64 / dt
    } else {
        0.0
    }
}

/// Why a core could not be built.
#[derive(Debug, thiserror::Error)]
pub enum CoreError {
    /// A parameter makes no sense.
    #[error(transparent)]
    Param(#[from] InvalidParam),
    /// The model cannot take the effects.
    #[error(transparent)]
    Effects(#[from] twin::models::UnsupportedEffects),
}

/// The TwinOutput message of a step.
pub fn twin_output(step: &TwinStep, damper: &str, model_id: &str) -> TwinOutput {
    TwinOutput {
        header: Header::at(step.sample.time_s, damper),
        predicted_force: step.output.force_n,
        measured_force: step.sample.force_n,
        residual: step.residual_n,
        dissipated_power: step.output.dissipated_power_w,
        fluid_temperature: step.output.fluid_temperature_c,
        model_id: model_id.to_string(),
        health_level: level_byte(step.health),
    }
}

/// The YieldEstimate message after a step: τ0 at the step's current and the whole curve.
pub fn yield_msg(p: &TwinPipeline, step: &TwinStep, damper: &str) -> msgs::YieldEstimate {
    let curve = p.curve();
    let e = p.estimate_at(step.sample.current_a);
    msgs::YieldEstimate {
        header: Header::at(step.sample.time_s, damper),
        current: step.sample.current_a,
        tau0: e.map_or(f64::NAN, |e| e.tau0_pa),
        tau0_std: e.map_or(f64::NAN, |e| e.tau0_std_pa),
        curve_current: curve.iter().map(|e| e.current_a).collect(),
        curve_tau0: curve.iter().map(|e| e.tau0_pa).collect(),
        curve_tau0_std: curve.iter().map(|e| e.tau0_std_pa).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bridge::transport::Topic;

    fn samples(n: usize, rate_hz: f64) -> Vec<SensorSample> {
        (0..n)
            .map(|k| {
                let t = k as f64 / rate_hz;
                let w = 2.0 * std::f64::consts::PI * 2.0;
                SensorSample {
                    time_s: t,
                    displacement_m: 0.01 * (w * t).sin(),
                    velocity_m_s: 0.01 * w * (w * t).cos(),
                    force_n: 500.0 * (w * t).cos().signum(),
                    current_a: 1.0,
                    temperature_c: f64::NAN,
                }
            })
            .collect()
    }

    fn topics(
        core: &mut TwinCore,
        input: &[SensorSample],
        clock: impl Fn(usize) -> f64,
    ) -> Vec<Topic> {
        input
            .iter()
            .enumerate()
            .flat_map(|(k, s)| core.on_sample(s, clock(k)).into_messages())
            .map(|m| m.topic())
            .collect()
    }

    #[test]
    fn messages_depend_on_the_samples_not_on_the_clock() {
        let p = TwinNodeParams::default();
        let input = samples(3000, 1000.0);
        let mut a = TwinCore::new(&p, "/mrtwin_twin").unwrap();
        let mut b = TwinCore::new(&p, "/mrtwin_twin").unwrap();
        let bytes = |core: &mut TwinCore, clock: &dyn Fn(usize) -> f64| -> Vec<Vec<u8>> {
            input
                .iter()
                .enumerate()
                .flat_map(|(k, s)| core.on_sample(s, clock(k)).into_messages())
                .map(|m| m.to_cdr())
                .collect()
        };
        let live = bytes(&mut a, &|k| 100.0 + k as f64 * 1.3e-3);
        let replay = bytes(&mut b, &|k| input[k].time_s);
        assert_eq!(live, replay);
        // 3 s at 1 kHz: an output and a force per sample, yield estimates every 0.1 s,
        // diagnostics every second (plus any level change).
        let mut c = TwinCore::new(&p, "/mrtwin_twin").unwrap();
        let t = topics(&mut c, &input, |k| k as f64);
        let count = |topic| t.iter().filter(|&&x| x == topic).count();
        assert_eq!(count(Topic::Output), 3000);
        assert_eq!(count(Topic::PredictedForce), 3000);
        assert_eq!(count(Topic::YieldEstimate), 30);
        assert!(
            (3..=12).contains(&count(Topic::Diagnostics)),
            "{}",
            count(Topic::Diagnostics)
        );
    }

    #[test]
    fn silence_is_announced_stale_once_per_period_and_the_resume_at_once() {
        let p = TwinNodeParams::default();
        let mut core = TwinCore::new(&p, "/ns/twin").unwrap();
        // Before any sample: STALE at once, then not again within the period.
        let d = core.on_idle(0.0).expect("STALE before the first sample");
        assert_eq!(d.status[0].level, msgs::DiagnosticStatus::STALE);
        assert_eq!(d.status[0].name, "/ns/twin: sensor stream");
        assert!(core.on_idle(0.5).is_none());
        let input = samples(1000, 1000.0);
        for (k, s) in input.iter().enumerate() {
            core.on_sample(s, 1.0 + s.time_s);
            assert!(core.on_idle(1.0 + s.time_s).is_none(), "sample {k}");
        }
        assert_ne!(core.level(2.0), Level::Stale);
        // Silence: STALE once past the stale time, again a period later.
        assert!(core.on_idle(2.0 + 0.4).is_none());
        let d = core
            .on_idle(2.0 + 0.6)
            .expect("STALE after 0.6 s of silence");
        assert_eq!(d.status[0].level, msgs::DiagnosticStatus::STALE);
        assert_eq!(core.level(2.6), Level::Stale);
        assert!(core.on_idle(3.0).is_none());
        assert!(core.on_idle(3.7).is_some());
        // The samples resume 3 s later in their own time: diagnostics at once.
        let mut s = input[999];
        s.time_s += 3.0;
        let out = core.on_sample(&s, 5.0);
        let d = out
            .diagnostics
            .expect("diagnostics when the stream resumes");
        assert_ne!(d.status[0].level, msgs::DiagnosticStatus::STALE);
    }

    #[test]
    fn transport_errors_show_in_the_next_diagnostics() {
        let p = TwinNodeParams::default();
        let mut core = TwinCore::new(&p, "/twin").unwrap();
        let input = samples(2500, 1000.0);
        let mut seen = Vec::new();
        for s in &input {
            if (s.time_s - 0.5).abs() < 1e-9 {
                core.count_transport_error();
            }
            if let Some(d) = core.on_sample(s, s.time_s).diagnostics {
                seen.push((s.time_s, d.status[0].level, d.status[0].message.clone()));
            }
        }
        let warn = seen
            .iter()
            .find(|(_, l, _)| *l == msgs::DiagnosticStatus::WARN)
            .expect("a WARN for the transport error");
        assert!(warn.2.contains("1 transport errors"), "{seen:?}");
        assert_eq!(core.transport_errors(), 1);
    }
}
