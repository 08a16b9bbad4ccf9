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
use estimation::health::{Check, Level};
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

/// Which model and parameters the core runs, for `/diagnostics` (`twin model`).
#[derive(Debug, Clone, PartialEq)]
struct ModelState {
    /// `fnv1a64` of the resolved parameters, 16 hex digits.
    params_version: String,
    /// Effects as configured (`""`: the model's own).
    effects: String,
    /// Parameter sets taken in flight.
    reloads: u64,
    /// Why the last offered parameters were refused, if they were.
    refused: Option<String>,
    /// A reload was taken or refused since the last `/diagnostics`: say so at once.
    announce: bool,
}

/// The version of a parameter set: `fnv1a64` of its resolved values, 16 hex digits (the
/// same for a live node and a replay given the same parameters, whatever the file layout).
pub fn params_version(params: &TwinNodeParams) -> String {
    let text = format!("{params:?}");
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// What [`TwinCore::reload`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reloaded {
    /// The yield-stress estimator kept its state (same settings and scale).
    pub estimator_kept: bool,
}

/// Why offered parameters were not taken in flight.
#[derive(Debug, thiserror::Error)]
pub enum ReloadError {
    /// They do not make a valid twin.
    #[error(transparent)]
    Invalid(#[from] CoreError),
    /// They change what only a restart can (the damper name, transports, periods).
    #[error("'{0}' changed: it takes a restart, not a reload")]
    NeedsRestart(&'static str),
}

/// The twin core. See the module documentation.
pub struct TwinCore {
    cfg: CoreConfig,
    params: TwinNodeParams,
    model_state: ModelState,
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
        Ok(Self {
            cfg: CoreConfig::of(params, node_name),
            model_state: ModelState {
                params_version: params_version(params),
                effects: params.effects.to_string(),
                reloads: 0,
                refused: None,
                announce: false,
            },
            params: params.clone(),
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
        })
    }

    /// Take new parameters in flight (a parameter-file reload): the model, its parameters
    /// and effects switch at the next sample, the stream and health carry on, and the
    /// estimator keeps its state unless its settings or scale changed. Parameters that
    /// only a restart can change, or that do not make a valid twin, are refused: the core
    /// runs on as it was and `/diagnostics` (`twin model`) says why.
    pub fn reload(&mut self, params: &TwinNodeParams) -> Result<Reloaded, ReloadError> {
        let result = self.try_reload(params);
        self.model_state.refused = result.as_ref().err().map(|e| e.to_string());
        self.model_state.announce = true;
        result
    }

    /// Note offered parameters that could not even be read (file, key and line in
    /// `reason`): shown on `/diagnostics` until parameters are taken.
    pub fn refuse_reload(&mut self, reason: String) {
        self.model_state.refused = Some(reason);
        self.model_state.announce = true;
    }

    fn try_reload(&mut self, params: &TwinNodeParams) -> Result<Reloaded, ReloadError> {
        let old = &self.params;
        let restart = [
            ("damper", params.damper != old.damper),
            ("transports", params.transports != old.transports),
            ("input", params.input != old.input),
            ("zenoh", params.zenoh != old.zenoh),
            ("ros2", params.ros2 != old.ros2),
            ("iceoryx2", params.iceoryx2 != old.iceoryx2),
            (
                "control_service",
                params.control_service != old.control_service,
            ),
        ];
        if let Some((key, _)) = restart.iter().find(|(_, changed)| *changed) {
            return Err(ReloadError::NeedsRestart(key));
        }
        params.validate().map_err(CoreError::from)?;
        let cfg = params.pipeline_config().map_err(CoreError::from)?;
        let estimator_kept = self.pipeline.replace_model(cfg).map_err(CoreError::from)?;
        let node_name = std::mem::take(&mut self.cfg.node_name);
        self.cfg = CoreConfig::of(params, &node_name);
        self.params = params.clone();
        self.model_state.params_version = params_version(params);
        self.model_state.effects = params.effects.to_string();
        self.model_state.reloads += 1;
        Ok(Reloaded { estimator_kept })
    }

    /// Samples since the report with counters `previous` on which the model's solver
    /// failed.
    fn new_solver_failures(&self, previous: &StreamCounters) -> u64 {
        self.pipeline.counters().solver_failures - previous.solver_failures
    }

    /// The `twin model` check's level alone: WARN while offered parameters are refused or
    /// when the model's solver failed since the report with counters `previous`.
    fn model_level(&self, previous: &StreamCounters) -> Level {
        if self.model_state.refused.is_some() || self.new_solver_failures(previous) > 0 {
            Level::Warn
        } else {
            Level::Ok
        }
    }

    /// The `twin model` check: model, effects, parameter version, reloads, and the samples
    /// on which the model's implicit solver failed (since the report with counters
    /// `previous`, and in all).
    fn model_check(&self, previous: &StreamCounters) -> Check {
        let m = &self.model_state;
        let model = self.pipeline.model_id();
        let effects = if m.effects.is_empty() {
            "model default"
        } else {
            &m.effects
        };
        let failures = self.new_solver_failures(previous);
        let (level, message) = match &m.refused {
            None if failures > 0 => (
                Level::Warn,
                format!(
                    "{model} ({effects}): the implicit solver did not converge on {failures} \
                     samples since the last report (state held)"
                ),
            ),
            None => (
                Level::Ok,
                format!("{model} ({effects}), parameters {}", m.params_version),
            ),
            Some(why) => (
                Level::Warn,
                format!(
                    "{model}, parameters {}; new parameters refused: {why}",
                    m.params_version
                ),
            ),
        };
        Check {
            name: "twin model".into(),
            level,
            message,
            values: vec![
                ("model".into(), model.to_string()),
                ("effects".into(), m.effects.clone()),
                ("params_version".into(), m.params_version.clone()),
                ("reloads".into(), m.reloads.to_string()),
                ("refused".into(), m.refused.clone().unwrap_or_default()),
                (
                    "solver_failures".into(),
                    self.pipeline.counters().solver_failures.to_string(),
                ),
            ],
        }
    }

    /// The pipeline (estimates, counters, checks).
    pub fn pipeline(&self) -> &TwinPipeline {
        &self.pipeline
    }

    /// The version of the parameters it runs ([`params_version`]).
    pub fn params_version(&self) -> &str {
        &self.model_state.params_version
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
        let level = worst([
            stream.level(),
            self.pipeline.health_level(),
            self.model_level(&s.previous),
        ]);
        let periodic = s.next_diag_s.is_none_or(|next| t >= next);
        let resumed = s
            .last_sample_s
            .is_some_and(|last| t - last > self.cfg.stale_after_s);
        let changed = (level != s.level || self.model_state.announce)
            && t - s.last_diag_s >= LEVEL_CHANGE_MIN_INTERVAL_S;
        if !(periodic || resumed || changed) {
            return None;
        }
        self.model_state.announce = false;
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

    /// The node time at which [`TwinCore::on_idle`] will next have something to say
    /// (the stream going STALE, or the next announcement while it is): the loop may sleep
    /// until then. `now` when it is due already.
    pub fn next_idle_due(&self, now: f64) -> f64 {
        let stale_at = self
            .idle
            .last_arrival
            .map(|t| t + self.cfg.stale_after_s)
            .filter(|&t| t >= now);
        match (stale_at, self.idle.last_announced) {
            // Just past the threshold: `on_idle` wants silence > stale_after_s.
            (Some(t), _) => t + 1e-4,
            (None, Some(a)) => (a + self.cfg.diagnostics_period_s).max(now),
            (None, None) => now,
        }
    }

    /// The DiagnosticArray of the stream check and the pipeline's checks at `stamp_s`.
    fn diagnostics(&self, stamp_s: f64, stream: StreamState) -> DiagnosticArray {
        let mut checks = vec![stream.check()];
        checks.extend(self.pipeline.checks());
        checks.push(self.model_check(&stream.previous));
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
            worst([
                self.schedule.level,
                self.pipeline.health_level(),
                self.model_level(&self.schedule.previous),
            ])
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
    use twin::EffectSet;

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

    /// The loop sleeps until `next_idle_due`: at that time (and not before) `on_idle` must
    /// have its announcement, so a sleeping node reports STALE on time.
    #[test]
    fn next_idle_due_is_when_on_idle_next_speaks() {
        let p = TwinNodeParams::default();
        let mut core = TwinCore::new(&p, "/ns/twin").unwrap();
        assert_eq!(
            core.next_idle_due(0.0),
            0.0,
            "due at once before any sample"
        );
        assert!(core.on_idle(0.0).is_some());
        let due = core.next_idle_due(0.1);
        assert!((due - p.diagnostics_period_s).abs() < 1e-9, "{due}");
        assert!(core.on_idle(due - 1e-3).is_none());
        assert!(core.on_idle(due).is_some());
        // A sample at 10 s: nothing to say until the stream has been silent for
        // stale_after_s; then STALE, then one period later again.
        core.on_sample(&samples(1, 1000.0)[0], 10.0);
        let due = core.next_idle_due(10.0);
        assert!(due > 10.0 + p.stale_after_s && due < 10.0 + p.stale_after_s + 1e-3);
        assert!(core.on_idle(due - 2e-3).is_none());
        let d = core.on_idle(due).expect("STALE at the due time");
        assert_eq!(d.status[0].level, msgs::DiagnosticStatus::STALE);
        let next = core.next_idle_due(due);
        assert!(
            (next - (due + p.diagnostics_period_s)).abs() < 1e-9,
            "{next}"
        );
        assert!(core.on_idle(next - 1e-3).is_none());
        assert!(core.on_idle(next).is_some());
    }

    #[test]
    fn a_reload_switches_the_effects_in_flight_and_a_bad_one_is_refused() {
        let p = TwinNodeParams {
            effects: twin::EffectsChoice::List(EffectSet::NONE),
            ..Default::default()
        };
        let mut core = TwinCore::new(&p, "/twin").unwrap();
        // The damper's record: the estimator has τ0 after the first strokes.
        let prog = twin::stand::Programme::grid(0.01, &[2.0], &[1.0], 4.0, 1000.0);
        let mut truth =
            twin::models::build(p.model, &p.model_params(), p.model.effects(p.effects)).unwrap();
        let input: Vec<SensorSample> = twin::stand::run(truth.as_mut(), &prog, None)
            .iter()
            .map(SensorSample::from)
            .collect();
        assert_eq!(input.len(), 4000);
        let model_of = |o: &Outputs| o.output.as_ref().map(|m| m.model_id.clone());
        let status = |d: &DiagnosticArray, key: &str| -> String {
            let s = d
                .status
                .iter()
                .find(|s| s.name == "/twin: twin model")
                .unwrap();
            s.values
                .iter()
                .find(|kv| kv.key == key)
                .unwrap()
                .value
                .clone()
        };
        let first = core.on_sample(&input[0], 0.0);
        assert_eq!(model_of(&first).as_deref(), Some("two-chamber"));
        assert_eq!(
            status(first.diagnostics.as_ref().unwrap(), "effects"),
            "none"
        );
        let v0 = status(first.diagnostics.as_ref().unwrap(), "params_version");
        for s in &input[1..3000] {
            core.on_sample(s, s.time_s);
        }
        let tau_before = core.pipeline().curve();
        assert!(!tau_before.is_empty(), "an estimate before the reload");
        // Same geometry, the paper's effects switched on: the estimator keeps its state.
        let upgraded = TwinNodeParams {
            effects: twin::EffectsChoice::Paper,
            ..p.clone()
        };
        let r = core.reload(&upgraded).unwrap();
        assert!(r.estimator_kept);
        assert_eq!(core.pipeline().curve(), tau_before);
        let mut diag = None;
        for s in &input[3000..] {
            let out = core.on_sample(s, s.time_s);
            assert_eq!(model_of(&out).as_deref(), Some("two-chamber"));
            diag = out.diagnostics.or(diag);
        }
        let d = diag.expect("diagnostics after the reload");
        assert_eq!(status(&d, "reloads"), "1");
        assert_eq!(status(&d, "effects"), "paper");
        assert_ne!(status(&d, "params_version"), v0);
        assert_eq!(status(&d, "params_version"), params_version(&upgraded));
        // What only a restart can change is refused, and the twin runs on.
        let moved = TwinNodeParams {
            damper: "other".into(),
            ..upgraded.clone()
        };
        let e = core.reload(&moved).unwrap_err();
        assert!(e.to_string().contains("'damper'"), "{e}");
        let t = input[3999].time_s + 0.001;
        let out = core.on_sample(
            &SensorSample {
                time_s: t,
                ..input[3999]
            },
            2.0,
        );
        assert_eq!(model_of(&out).as_deref(), Some("two-chamber"));
        let d = out.diagnostics.expect("the refusal is reported at once");
        let st = d
            .status
            .iter()
            .find(|s| s.name == "/twin: twin model")
            .unwrap();
        assert_eq!(st.level, msgs::DiagnosticStatus::WARN);
        assert!(st.message.contains("restart"), "{}", st.message);
    }

    #[test]
    fn a_solver_failure_is_counted_on_diagnostics_and_clears_a_period_later() {
        let p = TwinNodeParams::default();
        let mut core = TwinCore::new(&p, "/twin").unwrap();
        let mut input = samples(3000, 1000.0);
        // A finite but absurd rod speed passes the conditioning; the chamber solver cannot
        // take the step (nor the next, which starts from it).
        input[500].velocity_m_s = 1e150;
        let model = |d: &DiagnosticArray| {
            let s = d
                .status
                .iter()
                .find(|s| s.name == "/twin: twin model")
                .expect("a twin model check")
                .clone();
            let n = s
                .values
                .iter()
                .find(|kv| kv.key == "solver_failures")
                .expect("solver_failures")
                .value
                .clone();
            (s.level, s.message, n)
        };
        let mut seen = Vec::new();
        for s in &input {
            if let Some(d) = core.on_sample(s, s.time_s).diagnostics {
                seen.push((s.time_s, model(&d)));
            }
        }
        assert_eq!(core.pipeline().counters().solver_failures, 2);
        let before: Vec<_> = seen.iter().filter(|(t, _)| *t < 0.5).collect();
        assert!(before
            .iter()
            .all(|(_, (l, _, n))| *l == msgs::DiagnosticStatus::OK && n == "0"));
        // Reported in the next diagnostics (at once only when it changes the node's worst
        // level; here the residual check of this unfitted twin is worse already).
        let (_, (level, message, n)) = seen
            .iter()
            .find(|(t, _)| *t >= 0.5)
            .expect("diagnostics after the failure");
        assert_eq!(*level, msgs::DiagnosticStatus::WARN);
        assert!(
            message.contains("did not converge on 2 samples"),
            "{message}"
        );
        assert_eq!(n, "2");
        // A period after the last failure the check is OK again; the total stays.
        let (_, (level, _, n)) = seen.last().unwrap();
        assert_eq!(*level, msgs::DiagnosticStatus::OK);
        assert_eq!(n, "2");
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
