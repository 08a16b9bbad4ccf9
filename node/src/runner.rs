//! The twin node's loop: take samples from the input transport, step the pipeline,
//! publish the output on every transport, the yield estimate at its period and
//! `/diagnostics` at 1 Hz (and at once when the health level changes), answer the
//! iceoryx2 control service, and notice sensor silence (STALE) by the wall clock.
//!
//! One thread owns the pipeline: no locks on the sample path. While samples flow the
//! loop polls without sleeping (yielding the core); after 2 ms of quiet it sleeps
//! 100 µs between polls.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use bridge::transport::{Message, Topic, Transport, TransportError};
use estimation::health::{Check, Level};
use estimation::online::Tau0Estimate;
use msgs::shm::{ShmPrediction, ShmRequest};
use msgs::{Float64, Header, TwinOutput};

use crate::conditioning::{SensorSample, StreamCounters};
use crate::config::{InvalidParam, TwinNodeParams};
use crate::diagnostics::{diagnostic_array, level_byte, worst, StreamState};
use crate::pipeline::{Processed, TwinPipeline, TwinStep};
use crate::transports::{open, TransportKind, TransportSettings};

/// Why the node could not start.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// A parameter makes no sense.
    #[error(transparent)]
    Param(#[from] InvalidParam),
    /// The model cannot take the effects.
    #[error(transparent)]
    Effects(#[from] twin::models::UnsupportedEffects),
    /// A transport failed to open.
    #[error(transparent)]
    Transport(#[from] TransportError),
}

/// What the node reports once per second (for the demo's live line).
#[derive(Debug, Clone, PartialEq)]
pub struct LiveStats {
    /// Wall seconds since start.
    pub elapsed_s: f64,
    /// Samples per second over the last second.
    pub rate_hz: f64,
    /// Stream counters.
    pub counters: StreamCounters,
    /// Last measured force \[N\].
    pub measured_force_n: f64,
    /// Last predicted force \[N\].
    pub predicted_force_n: f64,
    /// RMS residual over the last second \[N\].
    pub residual_rms_n: f64,
    /// Last current \[A\].
    pub current_a: f64,
    /// Yield estimate at the last current.
    pub estimate: Option<Tau0Estimate>,
    /// Worst health level.
    pub level: Level,
    /// The checks.
    pub checks: Vec<Check>,
    /// Control requests answered.
    pub control_requests: u64,
}

/// When to stop.
#[derive(Debug, Default)]
pub struct StopWhen<'a> {
    /// Set from a signal handler.
    pub flag: Option<&'a AtomicBool>,
    /// Wall-clock deadline.
    pub deadline: Option<Instant>,
}

/// The twin node.
pub struct TwinNode {
    params: TwinNodeParams,
    node_name: String,
    pipeline: TwinPipeline,
    transports: Vec<(TransportKind, Box<dyn Transport>)>,
    input: usize,
    control: Option<bridge::iceoryx2::ControlServer>,
}

impl TwinNode {
    /// Build the pipeline and open the transports. `node_name` is fully qualified
    /// (`/ns/name`); the namespace is its parent.
    pub fn new(params: TwinNodeParams, node_name: &str) -> Result<Self, NodeError> {
        params.validate()?;
        let pipeline = TwinPipeline::new(params.pipeline_config()?)?;
        let settings = TransportSettings::new(
            &params.damper,
            node_name,
            &params.ros2,
            &params.zenoh,
            &params.iceoryx2,
        );
        let outputs = [
            Topic::Output,
            Topic::PredictedForce,
            Topic::YieldEstimate,
            Topic::Diagnostics,
        ];
        let mut transports = Vec::new();
        let mut input = 0;
        for &kind in &params.transports {
            let subscribe: &[Topic] = if kind == params.input {
                &[Topic::Sample]
            } else {
                &[]
            };
            if kind == params.input {
                input = transports.len();
            }
            transports.push((kind, open(kind, &settings, &outputs, subscribe)?));
        }
        let control =
            if params.control_service && params.transports.contains(&TransportKind::Iceoryx2) {
                Some(bridge::iceoryx2::ControlServer::new(
                    &settings.iceoryx2_config(),
                )?)
            } else {
                None
            };
        Ok(Self {
            node_name: node_name.to_string(),
            params,
            pipeline,
            transports,
            input,
            control,
        })
    }

    /// The pipeline (for tests and summaries).
    pub fn pipeline(&self) -> &TwinPipeline {
        &self.pipeline
    }

    /// Run until `stop`; `on_second` gets the live stats once per second.
    pub fn run(&mut self, stop: StopWhen<'_>, on_second: &mut dyn FnMut(&LiveStats)) -> LiveStats {
        let start = Instant::now();
        let period = Duration::from_secs_f64(self.params.diagnostics_period_s);
        let yield_period = Duration::from_secs_f64(self.params.yield_estimate_period_s);
        let mut next_diag = start;
        let mut next_yield = start + yield_period;
        let mut next_live = start + Duration::from_secs(1);
        let mut last_activity = start;
        let mut last_sample_at: Option<Instant> = None;
        let mut inbox = Vec::new();
        let mut steps: Vec<TwinStep> = Vec::new();
        let mut previous = self.pipeline.counters();
        let mut live_previous = previous;
        let mut last_level = Level::Stale;
        let mut transport_errors = 0u64;
        let mut transport_errors_reported = 0u64;
        let mut control_requests = 0u64;
        let mut last_step: Option<TwinStep> = None;
        let mut sum_r2 = 0.0;
        let mut n_r = 0u64;
        let mut last_diag_at = start;
        loop {
            let now = Instant::now();
            if stop.flag.is_some_and(|f| f.load(Ordering::Relaxed))
                || stop.deadline.is_some_and(|d| now >= d)
            {
                break;
            }
            let mut busy = false;
            // Samples in.
            inbox.clear();
            if let Err(_e) = self.transports[self.input].1.poll(&mut inbox) {
                transport_errors += 1;
            }
            for m in inbox.drain(..) {
                if let Message::Sample(s) = m {
                    busy = true;
                    last_sample_at = Some(now);
                    if let Processed::Stepped(step) =
                        self.pipeline.process(&SensorSample::from_msg(&s))
                    {
                        steps.push(step);
                    }
                }
            }
            // Control service.
            if let Some(ctrl) = self.control.as_mut() {
                let pipeline = &mut self.pipeline;
                let mut handler =
                    |req: &ShmRequest| -> ShmPrediction { answer(pipeline, req, &mut steps) };
                match ctrl.serve_pending(&mut handler) {
                    Ok(n) if n > 0 => {
                        busy = true;
                        control_requests += n as u64;
                        last_sample_at = Some(now);
                    }
                    Ok(_) => {}
                    Err(_) => transport_errors += 1,
                }
            }
            // Outputs.
            for step in steps.drain(..) {
                sum_r2 += step.residual_n * step.residual_n;
                n_r += 1;
                let out = Message::Output(twin_output(
                    &step,
                    &self.params.damper,
                    self.pipeline.model_id(),
                ));
                let force = Message::PredictedForce(Float64 {
                    data: step.output.force_n,
                });
                for (_, t) in &mut self.transports {
                    if t.publish(&out).is_err() || t.publish(&force).is_err() {
                        transport_errors += 1;
                    }
                }
                last_step = Some(step);
            }
            let now = Instant::now();
            if now >= next_yield {
                next_yield = now + yield_period;
                if let Some(step) = &last_step {
                    let msg = Message::YieldEstimate(yield_msg(
                        &self.pipeline,
                        step,
                        &self.params.damper,
                    ));
                    for (_, t) in &mut self.transports {
                        if t.publish(&msg).is_err() {
                            transport_errors += 1;
                        }
                    }
                }
            }
            // Health: periodic, and at once (≤ 10 Hz) when the level changes.
            let counters = self.pipeline.counters();
            let stream = StreamState {
                silence_s: last_sample_at.map(|t| now.duration_since(t).as_secs_f64()),
                stale_after_s: self.params.stale_after_s,
                counters,
                previous,
                rate_hz: (counters.received - previous.received) as f64
                    / now.duration_since(last_diag_at).as_secs_f64().max(1e-3),
                transport_errors: transport_errors - transport_errors_reported,
            };
            let stream_level = stream.level();
            let level = worst([stream_level, self.pipeline.health_level()]);
            let level_changed = level != last_level
                && now.duration_since(last_diag_at) >= Duration::from_millis(100);
            if now >= next_diag || level_changed {
                let mut checks = vec![stream.check()];
                checks.extend(self.pipeline.checks());
                let stamp = last_step.map_or(0.0, |s| s.sample.time_s);
                let msg = Message::Diagnostics(diagnostic_array(
                    &self.node_name,
                    &self.params.damper,
                    stamp,
                    &checks,
                ));
                for (_, t) in &mut self.transports {
                    if t.publish(&msg).is_err() {
                        transport_errors += 1;
                    }
                }
                if now >= next_diag {
                    next_diag = now + period;
                    previous = counters;
                    transport_errors_reported = transport_errors;
                    last_diag_at = now;
                }
                last_level = level;
            }
            if now >= next_live {
                let stats = self.live(
                    start,
                    now,
                    live_previous,
                    last_step,
                    sum_r2,
                    n_r,
                    level,
                    control_requests,
                );
                on_second(&stats);
                live_previous = counters;
                sum_r2 = 0.0;
                n_r = 0;
                next_live += Duration::from_secs(1);
            }
            if busy {
                last_activity = now;
            } else if now.duration_since(last_activity) < Duration::from_millis(2) {
                std::thread::yield_now();
            } else {
                std::thread::sleep(Duration::from_micros(100));
            }
        }
        let now = Instant::now();
        let level = self.pipeline.health_level();
        self.live(
            start,
            now,
            live_previous,
            last_step,
            sum_r2,
            n_r,
            level,
            control_requests,
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn live(
        &self,
        start: Instant,
        now: Instant,
        previous: StreamCounters,
        last: Option<TwinStep>,
        sum_r2: f64,
        n_r: u64,
        level: Level,
        control_requests: u64,
    ) -> LiveStats {
        let counters = self.pipeline.counters();
        LiveStats {
            elapsed_s: now.duration_since(start).as_secs_f64(),
            rate_hz: (counters.received - previous.received) as f64,
            counters,
            measured_force_n: last.map_or(f64::NAN, |s| s.sample.force_n),
            predicted_force_n: last.map_or(f64::NAN, |s| s.output.force_n),
            residual_rms_n: if n_r > 0 {
                (sum_r2 / n_r as f64).sqrt()
            } else {
                f64::NAN
            },
            current_a: last.map_or(f64::NAN, |s| s.sample.current_a),
            estimate: last.and_then(|s| self.pipeline.estimate_at(s.sample.current_a)),
            level,
            checks: self.pipeline.checks(),
            control_requests,
        }
    }
}

/// Answer one control request on the pipeline.
fn answer(
    pipeline: &mut TwinPipeline,
    req: &ShmRequest,
    steps: &mut Vec<TwinStep>,
) -> ShmPrediction {
    let s = &req.sample;
    let sample = SensorSample {
        time_s: s.time_ns as f64 * 1e-9,
        displacement_m: s.displacement_m,
        velocity_m_s: s.velocity_m_s,
        force_n: s.force_n,
        current_a: s.current_a,
        temperature_c: s.temperature_c,
    };
    let mut reply = ShmPrediction {
        seq: s.seq,
        time_ns: s.time_ns,
        predicted_force_n: f64::NAN,
        residual_n: f64::NAN,
        tau0_pa: f64::NAN,
        tau0_std_pa: f64::NAN,
        health_level: level_byte(pipeline.health_level()),
        rejected: 1,
        reserved: [0; 6],
    };
    if req.kind == ShmRequest::PLANNED_CURRENT {
        let f = pipeline.predict_with_current(&sample, s.current_a);
        if f.is_finite() {
            reply.predicted_force_n = f;
            reply.rejected = 0;
        }
    } else if let Processed::Stepped(step) = pipeline.process(&sample) {
        reply.predicted_force_n = step.output.force_n;
        reply.residual_n = step.residual_n;
        reply.rejected = 0;
        reply.health_level = level_byte(step.health);
        steps.push(step);
    }
    if let Some(e) = pipeline.estimate_at(s.current_a) {
        reply.tau0_pa = e.tau0_pa;
        reply.tau0_std_pa = e.tau0_std_pa;
    }
    reply
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

/// The YieldEstimate message after a step.
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

/// `/ns/name` → (`/ns`, `name`); `name` → (`/`, `name`).
pub fn split_name(fqn: &str) -> (&str, &str) {
    match fqn.rfind('/') {
        Some(0) => ("/", &fqn[1..]),
        Some(i) => (&fqn[..i], &fqn[i + 1..]),
        None => ("/", fqn),
    }
}
