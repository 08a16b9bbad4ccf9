//! The live twin node: a thin loop around [`TwinCore`]. It takes samples from the input
//! transport and iceoryx2 control requests, hands each to the core with the wall clock,
//! publishes what the core returns on every transport, lets the core announce sensor
//! silence (STALE), and reports live statistics once a second.
//!
//! One thread owns the core: no locks on the sample path. Between turns the loop sleeps
//! until a transport rings its [`Doorbell`](bridge::wake::Doorbell) (a sample or a
//! control request arrived) or the next deadline of its own comes (the stream going
//! STALE, the once-a-second statistics, the parameter poll), so an idle twin costs
//! almost no CPU and a sample is stepped and published as soon as its transport hands
//! it over. With [`TwinNodeParams::low_latency`] the loop instead polls without
//! sleeping while samples flow (yielding the core) and sleeps like the default after
//! 2 ms of quiet: a core busy while samples flow, for the shortest wake-up.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use bridge::params::ParamService;
use bridge::transport::{Message, Topic, Transport, TransportError};
use estimation::health::{Check, Level};
use estimation::online::Tau0Estimate;

use crate::conditioning::{SensorSample, StreamCounters};
use crate::config::{InvalidParam, TwinNodeParams};
use crate::core::{CoreError, TwinCore};
use crate::parameters::TwinParameters;
use crate::pipeline::{Processed, TwinPipeline, TwinStep};
use crate::transports::{open_serving, TransportKind};

/// Why a node could not start.
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

impl From<CoreError> for NodeError {
    fn from(e: CoreError) -> Self {
        match e {
            CoreError::Param(p) => NodeError::Param(p),
            CoreError::Effects(x) => NodeError::Effects(x),
        }
    }
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

impl StopWhen<'_> {
    /// Whether the flag is set or the deadline has passed at `now`.
    pub fn reached(&self, now: Instant) -> bool {
        self.flag.is_some_and(|f| f.load(Ordering::Relaxed))
            || self.deadline.is_some_and(|d| now >= d)
    }
}

/// New parameters offered to a running node: `None` when nothing changed, `Err` with the
/// reason (file, key, line) when they could not be read. Polled twice a second.
pub type ParamsSource = Box<dyn FnMut() -> Option<Result<TwinNodeParams, String>> + Send>;

/// How often a running node asks its [`ParamsSource`] \[s\].
pub const PARAMS_POLL_S: f64 = 0.5;

/// The twin node.
///
/// With the `iceoryx2` feature it is not `Send`: its control server's ports are
/// single-threaded (`bridge::iceoryx2::ControlServer`), so create it in the thread that
/// runs it.
pub struct TwinNode {
    core: TwinCore,
    params_source: Option<ParamsSource>,
    /// The parameters served to the middleware's tools (ROS 2 parameters); a set is
    /// taken before the next sample.
    served: Arc<TwinParameters>,
    /// What the input transport delivered this loop turn (kept to reuse its buffer).
    inbox: Vec<Message>,
    transports: Vec<(TransportKind, Box<dyn Transport>)>,
    input: usize,
    /// Watch-only adapters (the Foxglove live view): every message published, and every
    /// sample taken, just before the outputs for it.
    viewers: Vec<Box<dyn Transport>>,
    #[cfg(feature = "iceoryx2")]
    control: Option<bridge::iceoryx2::ControlServer>,
    low_latency: bool,
}

/// Longest sleep between turns when nothing rings: how soon a stop flag is seen.
const MAX_SLEEP: Duration = Duration::from_millis(50);

/// Sleep between polls of a source that cannot ring.
const POLL_SLEEP: Duration = Duration::from_micros(100);

/// With `low_latency`: how long after the last sample or request the loop keeps polling
/// hot before it sleeps on its doorbells like the default loop (what the control service
/// promises its clients when it says it polls).
#[cfg(feature = "iceoryx2")]
const HOT_AFTER_ACTIVITY: Duration = bridge::iceoryx2::POLLING_SERVER_STAYS_HOT;
#[cfg(not(feature = "iceoryx2"))]
const HOT_AFTER_ACTIVITY: Duration = Duration::from_millis(2);

/// The topics the twin node publishes.
const OUTPUTS: [Topic; 4] = [
    Topic::Output,
    Topic::PredictedForce,
    Topic::YieldEstimate,
    Topic::Diagnostics,
];

impl TwinNode {
    /// Build the core and open the transports. `node_name` is fully qualified
    /// (`/ns/name`); the namespace is its parent.
    pub fn new(params: TwinNodeParams, node_name: &str) -> Result<Self, NodeError> {
        let core = TwinCore::new(&params, node_name)?;
        let settings = params.transport_settings(node_name);
        let served = TwinParameters::new(&params);
        let mut transports = Vec::new();
        let mut input = 0;
        for &kind in &params.transports {
            let subscribe: &[Topic] = if kind == params.input {
                input = transports.len();
                &[Topic::Sample]
            } else {
                &[]
            };
            let serve: Arc<dyn ParamService> = served.clone();
            transports.push((
                kind,
                open_serving(kind, &settings, &OUTPUTS, subscribe, Some(serve))?,
            ));
        }
        #[cfg(feature = "iceoryx2")]
        let control =
            if params.control_service && params.transports.contains(&TransportKind::Iceoryx2) {
                let mut c = bridge::iceoryx2::ControlServer::new(&settings.iceoryx2_config())?;
                c.set_sleeps(!params.low_latency);
                Some(c)
            } else {
                None
            };
        Ok(Self {
            core,
            params_source: None,
            served,
            inbox: Vec::new(),
            transports,
            input,
            viewers: Vec::new(),
            #[cfg(feature = "iceoryx2")]
            control,
            low_latency: params.low_latency,
        })
    }

    /// Bind the doorbells of the sources the loop reads (input transport, control
    /// service) to the calling thread; `false` when the input transport cannot ring (the
    /// control service always can), so the loop must poll it on a timer.
    fn bind_doorbells(&self) -> bool {
        #[cfg(feature = "iceoryx2")]
        if let Some(c) = &self.control {
            c.doorbell().bind_current_thread();
        }
        let input = self.transports[self.input].1.doorbell();
        if let Some(b) = &input {
            b.bind_current_thread();
        }
        input.is_some()
    }

    /// Take new parameters in flight from `source` (e.g. the parameter file, re-read when
    /// it changes): see [`TwinCore::reload`].
    pub fn watch_params(&mut self, source: ParamsSource) {
        self.params_source = Some(source);
    }

    /// Ask the parameter source; take what it offers, or say why not.
    fn poll_params(&mut self) {
        let Some(offer) = self.params_source.as_mut().and_then(|f| f()) else {
            return;
        };
        match offer.map_err(|e| e.to_string()) {
            Ok(params) => {
                if self.take_params(&params, "parameter file") {
                    self.served.taken(&params);
                }
            }
            Err(e) => {
                tracing::warn!(error = %e, "new parameters refused");
                self.core.refuse_reload(e);
            }
        }
    }

    /// Take `params` (from `source`); `false` when the core refused them.
    fn take_params(&mut self, params: &TwinNodeParams, source: &str) -> bool {
        match self.core.reload(params) {
            Ok(r) => {
                tracing::info!(
                    source,
                    model = self.core.pipeline().model_id(),
                    effects = %params.effects,
                    params_version = self.core.params_version(),
                    estimator_kept = r.estimator_kept,
                    "parameters reloaded"
                );
                true
            }
            Err(e) => {
                tracing::warn!(source, error = %e, "new parameters refused");
                false
            }
        }
    }

    /// The core (estimates, counters, checks).
    pub fn core(&self) -> &TwinCore {
        &self.core
    }

    /// The pipeline (for tests and summaries).
    pub fn pipeline(&self) -> &TwinPipeline {
        self.core.pipeline()
    }

    /// Add a watch-only adapter: it is given every message the node publishes and every
    /// sample it takes (the samples go to no other transport). Its failures are logged and
    /// counted like a transport's.
    pub fn attach_viewer(&mut self, viewer: Box<dyn Transport>) {
        self.viewers.push(viewer);
    }

    /// Run until `stop`; `on_second` gets the live stats once per second.
    pub fn run(&mut self, stop: StopWhen<'_>, on_second: &mut dyn FnMut(&LiveStats)) -> LiveStats {
        let start = Instant::now();
        let clock = |t: Instant| t.duration_since(start).as_secs_f64();
        let mut window = LiveWindow::new(self.core.pipeline().counters());
        let mut outbox = Vec::new();
        let mut last_activity = start;
        let mut next_params_poll = PARAMS_POLL_S;
        let rings = self.bind_doorbells();
        loop {
            let now = Instant::now();
            if stop.reached(now) {
                break;
            }
            self.take_parameter_set();
            let mut busy = self.take_samples(clock(now), &mut window, &mut outbox);
            busy |= self.serve_control(clock(now), &mut window, &mut outbox);
            if let Some(d) = self.core.on_idle(clock(now)) {
                outbox.push(Message::Diagnostics(d));
            }
            self.publish(&mut outbox);
            if clock(now) >= next_params_poll {
                next_params_poll = clock(now) + PARAMS_POLL_S;
                self.poll_params();
            }
            if clock(now) >= window.next_report_s {
                on_second(&window.report(&self.core, clock(now)));
            }
            if busy {
                last_activity = now;
            }
            // low_latency: poll hot while samples flow (yield the core between polls).
            if self.low_latency && now.duration_since(last_activity) < HOT_AFTER_ACTIVITY {
                if !busy {
                    std::thread::yield_now();
                }
                continue;
            }
            // Sleep until a ring or the next thing due (a ring during this turn returns
            // at once: nothing that arrived after the poll waits for a deadline).
            let due_s = window
                .next_report_s
                .min(next_params_poll)
                .min(self.core.next_idle_due(clock(now)));
            let mut wake_at = now + Duration::from_secs_f64((due_s - clock(now)).max(0.0));
            wake_at = wake_at.min(now + if rings { MAX_SLEEP } else { POLL_SLEEP });
            if let Some(d) = stop.deadline {
                wake_at = wake_at.min(d);
            }
            bridge::wake::wait_until(wake_at);
        }
        window.report(&self.core, clock(Instant::now()))
    }

    /// Hand every sample that arrived on the input transport to the core.
    fn take_samples(
        &mut self,
        now: f64,
        window: &mut LiveWindow,
        outbox: &mut Vec<Message>,
    ) -> bool {
        let (kind, input) = &mut self.transports[self.input];
        if let Err(e) = input.poll(&mut self.inbox) {
            tracing::warn!(transport = %kind, error = %e, "poll for samples failed");
            self.core.count_transport_error();
        }
        let mut busy = false;
        let mut inbox = std::mem::take(&mut self.inbox);
        for m in inbox.drain(..) {
            if let Message::Sample(s) = m {
                busy = true;
                // A set answered while this batch waited applies from this sample on.
                self.take_parameter_set();
                let out = self.core.on_sample(&SensorSample::from_msg(&s), now);
                window.observe(&out.processed);
                if !self.viewers.is_empty() {
                    outbox.push(Message::Sample(s));
                }
                outbox.extend(out.into_messages());
            }
        }
        self.inbox = inbox;
        busy
    }

    /// Take a ROS 2 parameter set if one was answered since the last look (an atomic
    /// load when none was): every sample stepped after the answer sees it.
    fn take_parameter_set(&mut self) {
        if let Some(params) = self.served.take_pending() {
            self.take_params(&params, "ROS 2 parameter set");
        }
    }

    /// Answer pending iceoryx2 control requests; a stepped sample publishes like any other.
    #[cfg(feature = "iceoryx2")]
    fn serve_control(
        &mut self,
        now: f64,
        window: &mut LiveWindow,
        outbox: &mut Vec<Message>,
    ) -> bool {
        let Some(ctrl) = self.control.as_mut() else {
            return false;
        };
        let core = &mut self.core;
        let mut handler =
            |req: &msgs::shm::ShmRequest| control::answer(core, req, now, window, outbox);
        match ctrl.serve_pending(&mut handler) {
            Ok(n) => {
                window.control_requests += n as u64;
                n > 0
            }
            Err(e) => {
                tracing::warn!(transport = "iceoryx2", error = %e, "control service failed");
                self.core.count_transport_error();
                false
            }
        }
    }

    #[cfg(not(feature = "iceoryx2"))]
    fn serve_control(&mut self, _: f64, _: &mut LiveWindow, _: &mut Vec<Message>) -> bool {
        false
    }

    /// Publish every message of `outbox` on every transport and viewer (samples on the
    /// viewers only); a failure is logged with its transport and topic, counted, and does
    /// not stop the other publications.
    fn publish(&mut self, outbox: &mut Vec<Message>) {
        for m in outbox.drain(..) {
            let is_output = m.topic() != Topic::Sample;
            let transports = self.transports.iter_mut().filter(|_| is_output);
            for t in transports.map(|(_, t)| t).chain(&mut self.viewers) {
                if let Err(e) = t.publish(&m) {
                    tracing::warn!(transport = t.name(), topic = m.topic().ros_name(), error = %e, "publish failed");
                    self.core.count_transport_error();
                }
            }
        }
    }
}

/// The live statistics of the current second.
struct LiveWindow {
    previous: StreamCounters,
    last_step: Option<TwinStep>,
    sum_r2: f64,
    n_r: u64,
    control_requests: u64,
    next_report_s: f64,
}

impl LiveWindow {
    fn new(counters: StreamCounters) -> Self {
        Self {
            previous: counters,
            last_step: None,
            sum_r2: 0.0,
            n_r: 0,
            control_requests: 0,
            next_report_s: 1.0,
        }
    }

    fn observe(&mut self, p: &Processed) {
        if let Processed::Stepped(step) = p {
            self.sum_r2 += step.residual_n * step.residual_n;
            self.n_r += 1;
            self.last_step = Some(*step);
        }
    }

    /// The stats at `now` (node seconds); starts the next second.
    fn report(&mut self, core: &TwinCore, now: f64) -> LiveStats {
        let pipeline = core.pipeline();
        let counters = pipeline.counters();
        let last = self.last_step;
        let stats = LiveStats {
            elapsed_s: now,
            rate_hz: (counters.received - self.previous.received) as f64,
            counters,
            measured_force_n: last.map_or(f64::NAN, |s| s.sample.force_n),
            predicted_force_n: last.map_or(f64::NAN, |s| s.output.force_n),
            residual_rms_n: if self.n_r > 0 {
                (self.sum_r2 / self.n_r as f64).sqrt()
            } else {
                f64::NAN
            },
            current_a: last.map_or(f64::NAN, |s| s.sample.current_a),
            estimate: last.and_then(|s| pipeline.estimate_at(s.sample.current_a)),
            level: core.level(now),
            checks: pipeline.checks(),
            control_requests: self.control_requests,
        };
        self.previous = counters;
        self.sum_r2 = 0.0;
        self.n_r = 0;
        self.next_report_s += 1.0;
        stats
    }
}

/// The iceoryx2 control service's answers.
#[cfg(feature = "iceoryx2")]
mod control {
    use bridge::transport::Message;
    use msgs::shm::{ShmPrediction, ShmRequest};

    use super::LiveWindow;
    use crate::conditioning::SensorSample;
    use crate::core::TwinCore;
    use crate::diagnostics::level_byte;
    use crate::pipeline::Processed;

    /// Answer one request: a what-if on a copy of the model, or a sample that steps the
    /// twin (and publishes like any sample from the input transport).
    pub(super) fn answer(
        core: &mut TwinCore,
        req: &ShmRequest,
        now: f64,
        window: &mut LiveWindow,
        outbox: &mut Vec<Message>,
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
            health_level: level_byte(core.pipeline().health_level()),
            rejected: 1,
            server_sleeps: 0,
            reserved: [0; 5],
        };
        if req.kind == ShmRequest::PLANNED_CURRENT {
            let f = core.predict_with_current(&sample, s.current_a);
            if f.is_finite() {
                reply.predicted_force_n = f;
                reply.rejected = 0;
            }
        } else {
            let out = core.on_sample(&sample, now);
            window.observe(&out.processed);
            if let Processed::Stepped(step) = out.processed {
                reply.predicted_force_n = step.output.force_n;
                reply.residual_n = step.residual_n;
                reply.rejected = 0;
                reply.health_level = level_byte(step.health);
            }
            outbox.extend(out.into_messages());
        }
        if let Some(e) = core.pipeline().estimate_at(s.current_a) {
            reply.tau0_pa = e.tau0_pa;
            reply.tau0_std_pa = e.tau0_std_pa;
        }
        reply
    }
}
