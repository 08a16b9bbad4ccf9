//! The shared-memory services behind [`Iceoryx2Transport`], [`ControlServer`] and
//! [`ControlClient`] (feature `iceoryx2`).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use iceoryx2::node::NodeBuilder;
use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::client::Client;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::server::Server;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::{
    ipc, ipc_threadsafe, Node, NodeName, PortFactory, ServiceName, SignalHandlingMode,
};
use iceoryx2::service::port_factory::request_response::PortFactory as RequestResponseFactory;
use msgs::shm::{ShmPrediction, ShmRequest, ShmSample};
use msgs::{DamperSample, Header, Time, TwinOutput, YieldEstimate};

use super::wakeup::{WakeListener, WakeNotifier};
use super::{Iceoryx2Config, NAME};
use crate::transport::{Message, Topic, Transport, TransportError};
use crate::wake::Doorbell;

/// The iceoryx2 service variant of the publish–subscribe transport: inter-process, ports
/// `Send` (the node's loop may run in any thread).
pub(super) type Svc = ipc_threadsafe::Service;

/// The service variant of the control service's request–response ports: inter-process,
/// single-threaded (no mutex per port operation). A [`ControlServer`] or [`ControlClient`]
/// is therefore not `Send`: create it in the thread that serves or asks. The mutex-protected
/// variant cost about 0.25 µs per round trip and 0.4 µs at its p99 (BENCHMARKS.md,
/// "iceoryx2 control service"). Both variants share every shared-memory resource, so
/// either side may use either.
pub(super) type CtlSvc = ipc::Service;

type PubSubFactory<T> = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>;

fn err(context: impl Into<String>, reason: impl ToString) -> TransportError {
    TransportError::new(NAME, context, reason)
}

pub(super) fn dbg_err(context: impl Into<String>, reason: impl std::fmt::Debug) -> TransportError {
    TransportError::new(NAME, context, format!("{reason:?}"))
}

pub(super) fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(|e| dbg_err(format!("service name `{name}`"), e))
}

/// A node with signal handling off, after removing what dead nodes left behind.
fn make_node<S: iceoryx2::service::Service>(role: &str) -> Result<Node<S>, TransportError> {
    let name = NodeName::new(role).map_err(|e| dbg_err(format!("node name `{role}`"), e))?;
    let node = NodeBuilder::new()
        .name(&name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<S>()
        .map_err(|e| dbg_err(format!("create node `{role}`"), e))?;
    // Dead nodes (crashed processes) still hold ports; free them so a restarted peer fits
    // in the port limits. Nodes that cannot be cleaned now are skipped, not fatal.
    let _ = node.try_cleanup_dead_nodes();
    Ok(node)
}

/// The control service with the configured limits (same call on both sides).
fn control_service(
    node: &Node<CtlSvc>,
    cfg: &Iceoryx2Config,
) -> Result<RequestResponseFactory<CtlSvc, ShmRequest, (), ShmPrediction, ()>, TransportError> {
    cfg.validate()?;
    let name = cfg.control_service();
    node.service_builder(&service_name(&name)?)
        .request_response::<ShmRequest, ShmPrediction>()
        // One twin answers; a second server would double every reply.
        .max_servers(1)
        .max_clients(cfg.max_clients)
        .max_active_requests_per_client(cfg.max_in_flight)
        // One reply per request; room for a second in case a reply to an abandoned
        // request is still in the channel when it is reused.
        .max_response_buffer_size(2)
        .max_nodes(cfg.max_clients + 4)
        .open_or_create()
        .map_err(|e| dbg_err(format!("open or create service `{name}`"), e))
}

/// A publish–subscribe service of plain-data `T` with the configured limits.
fn pubsub_service<T>(
    node: &Node<Svc>,
    cfg: &Iceoryx2Config,
    name: &str,
) -> Result<PubSubFactory<T>, TransportError>
where
    T: std::fmt::Debug + iceoryx2::prelude::ZeroCopySend + 'static,
{
    node.service_builder(&service_name(name)?)
        .publish_subscribe::<T>()
        .subscriber_max_buffer_size(cfg.subscriber_buffer)
        .max_publishers(cfg.max_publishers)
        .max_subscribers(cfg.max_subscribers)
        .max_nodes(cfg.max_publishers + cfg.max_subscribers + 4)
        // Best effort, keep last: a slow subscriber loses the oldest samples, the
        // publisher never blocks the sensor loop.
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| dbg_err(format!("open or create service `{name}`"), e))
}

/// [`DamperSample`] → [`ShmSample`].
pub fn sample_to_shm(seq: u64, s: &DamperSample) -> ShmSample {
    ShmSample {
        seq,
        time_ns: s.header.stamp.as_nanos(),
        displacement_m: s.displacement,
        velocity_m_s: s.velocity,
        force_n: s.force,
        current_a: s.current,
        temperature_c: s.temperature,
    }
}

/// [`ShmSample`] → [`DamperSample`] (`frame_id` = the damper name).
pub fn sample_from_shm(s: &ShmSample, frame_id: &str) -> DamperSample {
    DamperSample {
        header: Header {
            stamp: Time::from_nanos(s.time_ns),
            frame_id: frame_id.to_string(),
        },
        displacement: s.displacement_m,
        velocity: s.velocity_m_s,
        force: s.force_n,
        current: s.current_a,
        temperature: s.temperature_c,
    }
}

/// [`TwinOutput`] → [`ShmPrediction`]; τ0 from the last yield estimate (NaN when none).
pub fn output_to_shm(seq: u64, o: &TwinOutput, tau0: (f64, f64)) -> ShmPrediction {
    ShmPrediction {
        seq,
        time_ns: o.header.stamp.as_nanos(),
        predicted_force_n: o.predicted_force,
        residual_n: o.residual,
        tau0_pa: tau0.0,
        tau0_std_pa: tau0.1,
        health_level: o.health_level,
        rejected: 0,
        server_sleeps: 0,
        reserved: [0; 5],
    }
}

/// [`ShmPrediction`] → [`TwinOutput`]. What the plain layout does not carry is NaN
/// (measured force = predicted + residual when both are finite, dissipated power and
/// fluid temperature) or empty (model id).
pub fn output_from_shm(p: &ShmPrediction, frame_id: &str) -> TwinOutput {
    TwinOutput {
        header: Header {
            stamp: Time::from_nanos(p.time_ns),
            frame_id: frame_id.to_string(),
        },
        predicted_force: p.predicted_force_n,
        measured_force: p.predicted_force_n + p.residual_n,
        residual: p.residual_n,
        dissipated_power: f64::NAN,
        fluid_temperature: f64::NAN,
        model_id: String::new(),
        health_level: p.health_level,
    }
}

/// Counts samples lost between a publisher and a subscriber from the sequence numbers.
#[derive(Debug, Default, Clone, Copy)]
struct GapCounter {
    last: Option<u64>,
    missed: u64,
}

impl GapCounter {
    fn see(&mut self, seq: u64) {
        if let Some(last) = self.last {
            // A lower or equal number is a restarted publisher: a new stream, no loss.
            if seq > last + 1 {
                self.missed += seq - last - 1;
            }
        }
        self.last = Some(seq);
    }
}

/// Publish–subscribe adapter: publishes [`Topic::Output`] as [`ShmPrediction`] (and
/// [`Topic::Sample`] as [`ShmSample`], for the stand), subscribes [`Topic::Sample`]
/// ([`ShmSample`] → [`DamperSample`]) and [`Topic::Output`].
///
/// A [`Topic::YieldEstimate`] is not sent by itself: its τ0 and σ ride in the τ0 fields of
/// the predictions published after it; a subscriber of [`Topic::YieldEstimate`] gets an
/// estimate (τ0 and σ only: current NaN, no curve) each time those fields change.
///
/// Other topics are ignored: iceoryx2 carries only the plain-data local loop; diagnostics,
/// the full yield curve and the clock go over ROS 2 or zenoh. Publishing a message whose
/// topic was not given to [`Iceoryx2Transport::new`] is an error.
pub struct Iceoryx2Transport {
    frame_id: String,
    publish: Vec<Topic>,
    sample_pub: Option<Publisher<Svc, ShmSample, ()>>,
    output_pub: Option<Publisher<Svc, ShmPrediction, ()>>,
    sample_sub: Option<(Subscriber<Svc, ShmSample, ()>, GapCounter)>,
    output_sub: Option<(Subscriber<Svc, ShmPrediction, ()>, GapCounter)>,
    emit_outputs: bool,
    /// `Some(last τ0 bits seen)` when subscribed to yield estimates.
    emit_yield: Option<(u64, u64)>,
    sample_svc: Option<PubSubFactory<ShmSample>>,
    output_svc: Option<PubSubFactory<ShmPrediction>>,
    sample_seq: u64,
    output_seq: u64,
    tau0: (f64, f64),
    /// Notify `<service>/wake` after each send (per published service).
    sample_wake: Option<WakeNotifier>,
    output_wake: Option<WakeNotifier>,
    /// Ring `doorbell` when a subscribed service's sender notifies.
    doorbell: Doorbell,
    _listeners: Vec<WakeListener>,
    // Dropped last: the ports above belong to it.
    _node: Node<Svc>,
}

impl std::fmt::Debug for Iceoryx2Transport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Iceoryx2Transport")
            .field("frame_id", &self.frame_id)
            .field("publish", &self.publish)
            .finish_non_exhaustive()
    }
}

impl Iceoryx2Transport {
    /// Whether iceoryx2 carries `topic`: [`Topic::Sample`], [`Topic::Output`] and (τ0 ± σ
    /// only, inside the predictions) [`Topic::YieldEstimate`].
    pub fn carries(topic: Topic) -> bool {
        matches!(topic, Topic::Sample | Topic::Output | Topic::YieldEstimate)
    }

    /// Open (or create) the services of the carried topics among `publish` and `subscribe`.
    pub fn new(
        cfg: &Iceoryx2Config,
        publish: &[Topic],
        subscribe: &[Topic],
    ) -> Result<Self, TransportError> {
        cfg.validate()?;
        let node = make_node("mrtwin-pubsub")?;
        let mut t = Self {
            frame_id: cfg.damper_name().to_string(),
            publish: publish.to_vec(),
            sample_pub: None,
            output_pub: None,
            sample_sub: None,
            output_sub: None,
            emit_outputs: subscribe.contains(&Topic::Output),
            emit_yield: subscribe
                .contains(&Topic::YieldEstimate)
                .then_some((f64::NAN.to_bits(), f64::NAN.to_bits())),
            sample_svc: None,
            output_svc: None,
            sample_seq: 0,
            output_seq: 0,
            tau0: (f64::NAN, f64::NAN),
            sample_wake: None,
            output_wake: None,
            doorbell: Doorbell::new(),
            _listeners: Vec::new(),
            _node: node,
        };
        let (senders, receivers) = (cfg.max_publishers, cfg.max_subscribers);
        let node = &t._node;
        if publish.contains(&Topic::Sample) || subscribe.contains(&Topic::Sample) {
            let name = cfg.sample_service();
            let svc = pubsub_service::<ShmSample>(node, cfg, &name)?;
            if publish.contains(&Topic::Sample) {
                t.sample_pub = Some(
                    svc.publisher_builder()
                        .create()
                        .map_err(|e| dbg_err(format!("publisher on `{name}`"), e))?,
                );
                t.sample_wake = Some(WakeNotifier::new(node, &name, senders, receivers)?);
            }
            if subscribe.contains(&Topic::Sample) {
                let sub = svc
                    .subscriber_builder()
                    .buffer_size(cfg.subscriber_buffer)
                    .create()
                    .map_err(|e| dbg_err(format!("subscriber on `{name}`"), e))?;
                t.sample_sub = Some((sub, GapCounter::default()));
                let bell = t.doorbell.clone();
                let l = WakeListener::spawn(node, &name, senders, receivers, bell)?;
                t._listeners.push(l);
            }
            t.sample_svc = Some(svc);
        }
        let sub_outputs =
            subscribe.contains(&Topic::Output) || subscribe.contains(&Topic::YieldEstimate);
        if publish.contains(&Topic::Output) || sub_outputs {
            let name = cfg.prediction_service();
            let svc = pubsub_service::<ShmPrediction>(node, cfg, &name)?;
            if publish.contains(&Topic::Output) {
                t.output_pub = Some(
                    svc.publisher_builder()
                        .create()
                        .map_err(|e| dbg_err(format!("publisher on `{name}`"), e))?,
                );
                t.output_wake = Some(WakeNotifier::new(node, &name, senders, receivers)?);
            }
            if sub_outputs {
                let sub = svc
                    .subscriber_builder()
                    .buffer_size(cfg.subscriber_buffer)
                    .create()
                    .map_err(|e| dbg_err(format!("subscriber on `{name}`"), e))?;
                t.output_sub = Some((sub, GapCounter::default()));
                let bell = t.doorbell.clone();
                let l = WakeListener::spawn(node, &name, senders, receivers, bell)?;
                t._listeners.push(l);
            }
            t.output_svc = Some(svc);
        }
        Ok(t)
    }

    /// Messages lost on the subscribed topics so far (gaps in the publishers' sequence
    /// numbers: subscriber buffer overflow).
    pub fn missed_samples(&self) -> u64 {
        self.sample_sub.as_ref().map_or(0, |s| s.1.missed)
            + self.output_sub.as_ref().map_or(0, |s| s.1.missed)
    }

    /// Subscribers currently registered on the service of `topic` (0 for a topic this
    /// adapter neither publishes nor subscribes). A publisher can wait for its peer with it.
    pub fn subscriber_count(&self, topic: Topic) -> usize {
        match topic {
            Topic::Sample => self
                .sample_svc
                .as_ref()
                .map_or(0, |s| s.dynamic_config().number_of_subscribers()),
            Topic::Output => self
                .output_svc
                .as_ref()
                .map_or(0, |s| s.dynamic_config().number_of_subscribers()),
            _ => 0,
        }
    }
}

impl Transport for Iceoryx2Transport {
    fn name(&self) -> &'static str {
        NAME
    }

    fn publish(&mut self, msg: &Message) -> Result<(), TransportError> {
        let topic = msg.topic();
        if !self.publish.contains(&topic) {
            return Err(err(
                format!("publish on {}", topic.key()),
                "topic not among this adapter's publications",
            ));
        }
        match msg {
            Message::Sample(s) => {
                if let Some(p) = &self.sample_pub {
                    p.send_copy(sample_to_shm(self.sample_seq, s))
                        .map_err(|e| dbg_err("publish on sensor/sample", e))?;
                    self.sample_seq += 1;
                    if let Some(w) = &self.sample_wake {
                        w.notify()?;
                    }
                }
            }
            Message::Output(o) => {
                if let Some(p) = &self.output_pub {
                    p.send_copy(output_to_shm(self.output_seq, o, self.tau0))
                        .map_err(|e| dbg_err("publish on twin/prediction", e))?;
                    self.output_seq += 1;
                    if let Some(w) = &self.output_wake {
                        w.notify()?;
                    }
                }
            }
            Message::YieldEstimate(y) => self.tau0 = (y.tau0, y.tau0_std),
            // Not carried: no plain-data layout on shared memory.
            Message::PredictedForce(_) | Message::Diagnostics(_) | Message::Clock(_) => {}
        }
        Ok(())
    }

    fn poll(&mut self, out: &mut Vec<Message>) -> Result<(), TransportError> {
        if let Some((sub, gaps)) = &mut self.sample_sub {
            while let Some(s) = sub
                .receive()
                .map_err(|e| dbg_err("receive on sensor/sample", e))?
            {
                gaps.see(s.seq);
                out.push(Message::Sample(sample_from_shm(&s, &self.frame_id)));
            }
        }
        if let Some((sub, gaps)) = &mut self.output_sub {
            while let Some(p) = sub
                .receive()
                .map_err(|e| dbg_err("receive on twin/prediction", e))?
            {
                gaps.see(p.seq);
                if let Some(last) = &mut self.emit_yield {
                    let now = (p.tau0_pa.to_bits(), p.tau0_std_pa.to_bits());
                    if now != *last {
                        *last = now;
                        out.push(Message::YieldEstimate(YieldEstimate {
                            header: Header {
                                stamp: Time::from_nanos(p.time_ns),
                                frame_id: self.frame_id.clone(),
                            },
                            current: f64::NAN,
                            tau0: p.tau0_pa,
                            tau0_std: p.tau0_std_pa,
                            curve_current: Vec::new(),
                            curve_tau0: Vec::new(),
                            curve_tau0_std: Vec::new(),
                        }));
                    }
                }
                if self.emit_outputs {
                    out.push(Message::Output(output_from_shm(&p, &self.frame_id)));
                }
            }
        }
        Ok(())
    }

    fn doorbell(&self) -> Option<Doorbell> {
        Some(self.doorbell.clone())
    }
}

/// A prediction that rejects `req` (bad numbers, time going back): force NaN, `rejected` 1.
pub fn rejected_reply(req: &ShmRequest) -> ShmPrediction {
    ShmPrediction {
        seq: req.sample.seq,
        time_ns: req.sample.time_ns,
        predicted_force_n: f64::NAN,
        residual_n: f64::NAN,
        tau0_pa: f64::NAN,
        tau0_std_pa: f64::NAN,
        health_level: 2,
        rejected: 1,
        server_sleeps: 0,
        reserved: [0; 5],
    }
}

/// Request–response server for a local controller: a controller sends a [`ShmRequest`]
/// (a measured sample, or a planned current as a what-if) and gets a [`ShmPrediction`]
/// back. The service admits one server: a second twin on the same prefix is refused.
///
/// Polling: [`ControlServer::serve_pending`] never blocks; the caller's loop decides how
/// to wait between calls (busy poll for the lowest latency, or a [`Backoff`]).
pub struct ControlServer {
    server: Server<CtlSvc, ShmRequest, (), ShmPrediction, ()>,
    service: RequestResponseFactory<CtlSvc, ShmRequest, (), ShmPrediction, ()>,
    budget: usize,
    answered: u64,
    undelivered: u64,
    /// Rung when a client notifies `<control>/wake` after a request.
    doorbell: Doorbell,
    /// Told to clients in every reply ([`ShmPrediction::server_sleeps`]).
    sleeps: bool,
    _listener: WakeListener,
    // Dropped last: the ports above belong to them (the wake-up listener's thread needs
    // `Send` ports, hence its own node).
    _node: Node<CtlSvc>,
    _listener_node: Node<Svc>,
}

impl std::fmt::Debug for ControlServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControlServer")
            .field("answered", &self.answered)
            .field("undelivered", &self.undelivered)
            .finish_non_exhaustive()
    }
}

impl ControlServer {
    /// Open (or create) `<prefix>/twin/control` and become its server.
    pub fn new(cfg: &Iceoryx2Config) -> Result<Self, TransportError> {
        let node = make_node::<CtlSvc>("mrtwin-control-server")?;
        let service = control_service(&node, cfg)?;
        let server = service.server_builder().create().map_err(|e| {
            dbg_err(
                format!(
                    "server on `{}` (is another twin serving this prefix?)",
                    cfg.control_service()
                ),
                e,
            )
        })?;
        let doorbell = Doorbell::new();
        let name = cfg.control_service();
        let listener_node = make_node::<Svc>("mrtwin-control-wake")?;
        let listener =
            WakeListener::spawn(&listener_node, &name, cfg.max_clients, 1, doorbell.clone())?;
        Ok(Self {
            server,
            service,
            budget: cfg.max_clients * cfg.max_in_flight,
            answered: 0,
            undelivered: 0,
            doorbell,
            sleeps: true,
            _listener: listener,
            _node: node,
            _listener_node: listener_node,
        })
    }

    /// Answer every pending request with `handler`; never blocks; returns how many were
    /// answered. At most one full set of in-flight requests (clients × in-flight) per
    /// call, so a flooding client cannot hold the caller's loop.
    ///
    /// A reply the client no longer waits for (it timed out and dropped the request) is
    /// counted by [`ControlServer::undelivered`], not an error: the twin has still stepped.
    pub fn serve_pending(
        &mut self,
        handler: &mut dyn FnMut(&ShmRequest) -> ShmPrediction,
    ) -> Result<usize, TransportError> {
        let mut n = 0;
        while n < self.budget {
            let Some(active) = self
                .server
                .receive()
                .map_err(|e| dbg_err("receive a control request", e))?
            else {
                break;
            };
            let mut reply = handler(active.payload());
            reply.server_sleeps = u8::from(self.sleeps);
            if active.is_connected() && active.send_copy(reply).is_ok() {
                self.answered += 1;
            } else {
                self.undelivered += 1;
            }
            n += 1;
        }
        Ok(n)
    }

    /// The doorbell rung when a client sends a request (bind it to the serving thread).
    pub fn doorbell(&self) -> Doorbell {
        self.doorbell.clone()
    }

    /// Whether the serving loop sleeps between requests (default) and so needs clients to
    /// notify it, or busy polls (`false`: clients then skip the notification, a syscall
    /// per request). Said to clients in every reply. A loop that says it polls must keep
    /// polling for at least [`POLLING_SERVER_STAYS_HOT`] after each request.
    pub fn set_sleeps(&mut self, sleeps: bool) {
        self.sleeps = sleeps;
    }

    /// Replies delivered since creation.
    pub fn answered(&self) -> u64 {
        self.answered
    }

    /// Requests handled whose client had gone (timed out or exited) before the reply.
    pub fn undelivered(&self) -> u64 {
        self.undelivered
    }

    /// Clients currently registered on the control service.
    pub fn client_count(&self) -> usize {
        self.service.dynamic_config().number_of_clients()
    }
}

/// How long a control server that says it polls ([`ControlServer::set_sleeps`]`(false)`)
/// keeps polling after a request. A client whose previous request is older than half of
/// this notifies anyway, so a server that went to sleep meanwhile still wakes at once.
pub const POLLING_SERVER_STAYS_HOT: Duration = Duration::from_millis(2);

/// The client side of the control service, used by controllers (and tests, benches).
///
/// [`ControlClient::request`] sends one request and waits, busy polling, for its reply.
/// [`ControlClient::send`] and [`ControlClient::receive`] pipeline up to
/// [`Iceoryx2Config::max_in_flight`] requests.
pub struct ControlClient {
    client: Client<CtlSvc, ShmRequest, (), ShmPrediction, ()>,
    service: RequestResponseFactory<CtlSvc, ShmRequest, (), ShmPrediction, ()>,
    in_flight: VecDeque<PendingResponse<CtlSvc, ShmRequest, (), ShmPrediction, ()>>,
    /// Wakes the server after each request while it says it sleeps (the first request
    /// always notifies), and after a pause of half [`POLLING_SERVER_STAYS_HOT`].
    wake: WakeNotifier<CtlSvc>,
    notify: bool,
    last_send: Option<Instant>,
    // Dropped last: the ports above belong to it.
    _node: Node<CtlSvc>,
}

impl std::fmt::Debug for ControlClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControlClient")
            .field("in_flight", &self.in_flight.len())
            .finish_non_exhaustive()
    }
}

impl ControlClient {
    /// Open (or create) `<prefix>/twin/control` as a client. The server may come later:
    /// see [`ControlClient::wait_for_server`].
    pub fn new(cfg: &Iceoryx2Config) -> Result<Self, TransportError> {
        let node = make_node::<CtlSvc>("mrtwin-control-client")?;
        let service = control_service(&node, cfg)?;
        let client = service
            .client_builder()
            .create()
            .map_err(|e| dbg_err(format!("client on `{}`", cfg.control_service()), e))?;
        let wake = WakeNotifier::new(&node, &cfg.control_service(), cfg.max_clients, 1)?;
        Ok(Self {
            client,
            service,
            in_flight: VecDeque::new(),
            wake,
            notify: true,
            last_send: None,
            _node: node,
        })
    }

    /// Whether a twin serves the control service now.
    pub fn server_present(&self) -> bool {
        self.service.dynamic_config().number_of_servers() > 0
    }

    /// Wait (sleeping 1 ms between looks) until a twin serves the control service.
    pub fn wait_for_server(&self, timeout: Duration) -> Result<(), TransportError> {
        let deadline = Instant::now() + timeout;
        while !self.server_present() {
            if Instant::now() >= deadline {
                return Err(err(
                    "wait for the control server",
                    format!("no server within {timeout:?}"),
                ));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(())
    }

    fn send_pending(
        &mut self,
        req: &ShmRequest,
    ) -> Result<PendingResponse<CtlSvc, ShmRequest, (), ShmPrediction, ()>, TransportError> {
        let pending = self
            .client
            .send_copy(*req)
            .map_err(|e| dbg_err(format!("send request {}", req.sample.seq), e))?;
        if pending.number_of_server_connections() == 0 {
            return Err(err(
                format!("send request {}", req.sample.seq),
                "no control server connected",
            ));
        }
        let now = Instant::now();
        let paused = self
            .last_send
            .is_none_or(|t| now.duration_since(t) > POLLING_SERVER_STAYS_HOT / 2);
        self.last_send = Some(now);
        if self.notify || paused {
            self.wake.notify()?;
        }
        Ok(pending)
    }

    /// Send `req` and wait for its reply, busy polling (spin, then yield) for at most
    /// `timeout`. On timeout the request is abandoned (a late reply is discarded) and an
    /// error naming the request is returned.
    pub fn request(
        &mut self,
        req: &ShmRequest,
        timeout: Duration,
    ) -> Result<ShmPrediction, TransportError> {
        self.request_within(req, timeout)?.ok_or_else(|| {
            err(
                format!("request {}", req.sample.seq),
                format!("no reply within {timeout:?}"),
            )
        })
    }

    /// [`ControlClient::request`] with a timeout as `Ok(None)` rather than an error.
    pub fn request_within(
        &mut self,
        req: &ShmRequest,
        timeout: Duration,
    ) -> Result<Option<ShmPrediction>, TransportError> {
        let deadline = Instant::now() + timeout;
        let pending = self.send_pending(req)?;
        let mut spins = 0u32;
        loop {
            if let Some(r) = pending
                .receive()
                .map_err(|e| dbg_err(format!("receive reply {}", req.sample.seq), e))?
            {
                self.notify = r.payload().server_sleeps != 0;
                return Ok(Some(*r.payload()));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            spin_or_yield(&mut spins);
        }
    }

    /// Send `req` without waiting (pipelined); its reply comes from
    /// [`ControlClient::receive`]. Fails when [`Iceoryx2Config::max_in_flight`] requests
    /// are already in flight or no server is connected.
    pub fn send(&mut self, req: &ShmRequest) -> Result<(), TransportError> {
        let pending = self.send_pending(req)?;
        self.in_flight.push_back(pending);
        Ok(())
    }

    /// A reply to one of the requests sent with [`ControlClient::send`], if one has
    /// arrived (the oldest request first); never blocks.
    pub fn receive(&mut self) -> Result<Option<ShmPrediction>, TransportError> {
        for i in 0..self.in_flight.len() {
            if let Some(r) = self.in_flight[i]
                .receive()
                .map_err(|e| dbg_err("receive a pipelined reply", e))?
            {
                let reply = *r.payload();
                self.notify = reply.server_sleeps != 0;
                drop(r);
                self.in_flight.remove(i);
                return Ok(Some(reply));
            }
        }
        Ok(None)
    }

    /// Requests sent with [`ControlClient::send`] still without a reply.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Give up the oldest request in flight (after a timeout); returns whether there was one.
    pub fn abandon_oldest(&mut self) -> bool {
        self.in_flight.pop_front().is_some()
    }
}

// The node's loop may own the transport in any thread; the control server and client
// (single-threaded ports, [`CtlSvc`]) stay in the thread that created them.
const _: fn() = || {
    fn send<T: Send>() {}
    send::<Iceoryx2Transport>();
};

/// Busy poll, then yield the core: a reply normally comes within a few µs, so the
/// first ~20 000 polls (≈ 1–2 ms) only spin; past that the server is evidently not running
/// (descheduled on a loaded machine) and the client yields to let it run.
///
/// No `spin_loop()` (PAUSE) hint between polls: on this project's virtual machines it made
/// the round trip's p99 ≈ 20 µs instead of ≈ 2 µs (pause-loop exits to the hypervisor are the
/// likely cause), measured with `benches/iceoryx2_loop.rs`.
fn spin_or_yield(spins: &mut u32) {
    const SPIN_POLLS: u32 = 20_000;
    if *spins < SPIN_POLLS {
        *spins += 1;
    } else {
        std::thread::yield_now();
    }
}

/// Idle strategy for a serving loop: busy poll for `spin` after the last activity (lowest
/// latency while traffic flows), then sleep `sleep` per idle round (a core is not burnt
/// while nobody asks). The reply latency of the first request after a quiet period is then
/// about `sleep` plus the OS timer slack (≈ 50–100 µs on Linux).
#[derive(Debug, Clone)]
pub struct Backoff {
    spin: Duration,
    sleep: Duration,
    last_activity: Instant,
}

impl Backoff {
    /// Busy poll for `spin` after activity, then sleep `sleep` per idle round.
    pub fn new(spin: Duration, sleep: Duration) -> Self {
        Self {
            spin,
            sleep,
            last_activity: Instant::now(),
        }
    }

    /// Something was done: poll hot again.
    pub fn activity(&mut self) {
        self.last_activity = Instant::now();
    }

    /// Nothing was done this round: spin, yield or sleep.
    pub fn idle(&mut self) {
        if self.last_activity.elapsed() < self.spin {
            std::thread::yield_now();
        } else {
            std::thread::sleep(self.sleep);
        }
    }
}

/// Keep iceoryx2's own logging to errors: it otherwise warns once per process that no
/// config file was found and defaults are used, which is the intended setup here.
pub fn quiet_logs() {
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
}
