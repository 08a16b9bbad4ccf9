//! The ROS 2 adapter: the twin's [`Topic`]s over DDS, in pure Rust (ros2-client on RustDDS,
//! no ROS installation), visible to and interoperable with rclcpp/rclpy nodes.
//!
//! * One DDS participant (`ROS_DOMAIN_ID` = [`Ros2Config::domain_id`]) with one ROS node
//!   `<namespace>/<node_name>`, announced on `ros_discovery_info` like rmw does, so
//!   `ros2 node list` shows it. rosout and the parameter services are off.
//! * Topic names: relative names ([`Topic::ros_name`], e.g. `twin/predicted_force`)
//!   resolve under the namespace (`/damper1/twin/predicted_force`); `/diagnostics` and
//!   `/clock` are absolute. DDS names follow the ROS 2 mapping (`rt/…`,
//!   `pkg::msg::dds_::Type_`).
//! * QoS (see [`Ros2Config::qos`] to override): sensor samples best effort, keep last
//!   1000; outputs (`twin/output`, `twin/predicted_force`, `twin/yield_estimate`, `/clock`)
//!   reliable, keep last 1000 so that 10 kHz bursts between two polls are not dropped;
//!   `/diagnostics` reliable, keep last 100. Volatile durability everywhere.
//! * The node's spinner (ros2-client's background task for ROS graph events) runs on a
//!   thread of the adapter under `futures::executor::block_on`; the adapter collects the
//!   nodes other participants announce, for [`Ros2Transport::graph`].
//!
//! [`Transport::publish`] is bounded: on a reliable topic with a full send window it waits
//! at most 100 ms (ros2-client's `WhenFull::DEFAULT`) and then reports an error.
//! [`Transport::poll`] takes whatever is in the readers' caches, without waiting.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use msgs::{
    Clock, DamperSample, DiagnosticArray, Float64, Float64MultiArray, RosMessage, TwinOutput,
    YieldEstimate,
};
use ros2_client::dds::{Context, ContextOptions, Node, NodeEvent, Publisher, Subscription};
use ros2_client::qos::{Durability, History, Reliability as QosReliability, WhenFull};
use ros2_client::{MessageTypeName, Name, NodeName, NodeOptions, QosProfile};
use serde::{Deserialize, Serialize};

use crate::transport::{Message, Topic, Transport, TransportError};

const NAME: &str = "ros2";

/// The delivery guarantee the QoS settings choose (the same type as the bags' QoS).
pub use crate::qos::Reliability;

/// QoS override of one topic (unset fields keep the default of the topic).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QosOverride {
    /// Reliability.
    pub reliability: Option<Reliability>,
    /// History depth (keep last N), at least 1.
    pub depth: Option<usize>,
}

/// Configuration of the ROS 2 adapter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2Config {
    /// DDS domain (`ROS_DOMAIN_ID`), 0..=232.
    pub domain_id: u16,
    /// Node namespace (`__ns:=`), absolute: `/` or `/damper1`.
    pub namespace: String,
    /// Node name (`__node:=`).
    pub node_name: String,
    /// Per-topic QoS overrides, keyed by topic ([`Topic::key`] or [`Topic::ros_name`],
    /// e.g. `sensor/sample`, `/diagnostics`).
    pub qos: BTreeMap<String, QosOverride>,
}

impl Default for Ros2Config {
    fn default() -> Self {
        Self {
            domain_id: 0,
            namespace: "/".into(),
            node_name: "mrtwin_twin".into(),
            qos: BTreeMap::new(),
        }
    }
}

impl Ros2Config {
    /// Reliability and depth of `topic`: the defaults of the module doc, then the override.
    pub fn qos_of(&self, topic: Topic) -> (Reliability, usize) {
        let (mut reliability, mut depth) = match topic {
            Topic::Sample => (Reliability::BestEffort, 1000),
            Topic::Diagnostics => (Reliability::Reliable, 100),
            Topic::Output | Topic::PredictedForce | Topic::YieldEstimate | Topic::Clock => {
                (Reliability::Reliable, 1000)
            }
        };
        if let Some(o) = self
            .qos
            .iter()
            .find(|(k, _)| Topic::parse(k) == Some(topic))
            .map(|(_, o)| o)
        {
            reliability = o.reliability.unwrap_or(reliability);
            depth = o.depth.unwrap_or(depth);
        }
        (reliability, depth)
    }

    /// The namespace in canonical form (leading `/`, no trailing `/` except for the root),
    /// or why it is not a valid ROS namespace.
    pub fn canonical_namespace(&self) -> Result<String, String> {
        let ns = self.namespace.trim();
        let ns = if ns.starts_with('/') {
            ns.to_string()
        } else {
            format!("/{ns}")
        };
        let ns = if ns.len() > 1 {
            ns.trim_end_matches('/').to_string()
        } else {
            ns
        };
        if ns == "/" {
            return Ok(ns);
        }
        for token in ns[1..].split('/') {
            let ok = !token.is_empty()
                && token.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
                && token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                && !token.contains("__");
            if !ok {
                return Err(format!(
                    "namespace {:?}: token {token:?} must be non-empty, start with a letter or \
                     '_', and hold only letters, digits and single '_'",
                    self.namespace
                ));
            }
        }
        Ok(ns)
    }

    /// Check everything [`Ros2Transport::new`] would reject, with the field named.
    pub fn validate(&self) -> Result<(), TransportError> {
        let err = |field: &str, reason: String| {
            TransportError::new(NAME, format!("configuration field `{field}`"), reason)
        };
        if self.domain_id > 232 {
            return Err(err(
                "domain_id",
                format!("{} is out of range 0..=232", self.domain_id),
            ));
        }
        let ns = self
            .canonical_namespace()
            .map_err(|e| err("namespace", e))?;
        NodeName::new(&ns, &self.node_name)
            .map_err(|e| err("node_name", format!("{:?}: {e}", self.node_name)))?;
        for (key, o) in &self.qos {
            if Topic::parse(key).is_none() {
                let known: Vec<&str> = Topic::ALL.iter().map(|t| t.key()).collect();
                return Err(err(
                    &format!("qos.{key}"),
                    format!("unknown topic; known: {}", known.join(", ")),
                ));
            }
            if o.depth == Some(0) {
                return Err(err(
                    &format!("qos.{key}.depth"),
                    "must be at least 1".into(),
                ));
            }
        }
        Ok(())
    }

    /// Fully-qualified ROS name of `topic` under this namespace.
    pub fn resolve(&self, topic: Topic) -> String {
        let name = topic.ros_name();
        if name.starts_with('/') {
            return name.to_string();
        }
        match self.canonical_namespace() {
            Ok(ns) if ns != "/" => format!("{ns}/{name}"),
            _ => format!("/{name}"),
        }
    }
}

/// What the adapter sees of the ROS graph.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RosGraph {
    /// `(namespace, name)` of every node announced on `ros_discovery_info`, ours included.
    pub nodes: Vec<(String, String)>,
    /// `(topic, type)` in ROS form (`/damper1/twin/output`, `mrtwin_msgs/msg/TwinOutput`)
    /// of every ROS topic discovered over DDS, ours included.
    pub topics: Vec<(String, String)>,
}

/// DDS topic name `rt/a/b` → ROS `/a/b` (other DDS topics: `None`).
fn ros_topic_name(dds: &str) -> Option<String> {
    dds.strip_prefix("rt/").map(|rest| format!("/{rest}"))
}

/// DDS type name `pkg::msg::dds_::Type_` → ROS `pkg/msg/Type`.
fn ros_type_name(dds: &str) -> String {
    let parts: Vec<&str> = dds.split("::").collect();
    match parts.as_slice() {
        [pkg, kind, "dds_", ty] => format!("{pkg}/{kind}/{}", ty.strip_suffix('_').unwrap_or(ty)),
        _ => dds.to_string(),
    }
}

/// `pkg/msg/Type` → ros2-client's type name.
fn message_type_name(ros_type: &str) -> MessageTypeName {
    let mut it = ros_type.split('/');
    let pkg = it.next().unwrap_or_default();
    let ty = it.next_back().unwrap_or_default();
    MessageTypeName::new(pkg, ty)
}

fn qos_profile(reliability: Reliability, depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability(match reliability {
            Reliability::BestEffort => QosReliability::BestEffort,
            Reliability::Reliable => QosReliability::Reliable {
                when_full: WhenFull::DEFAULT,
            },
        })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// One publisher per topic type.
enum Pub {
    Sample(Publisher<DamperSample>),
    Output(Publisher<TwinOutput>),
    PredictedForce(Publisher<Float64>),
    YieldEstimate(Publisher<YieldEstimate>),
    Diagnostics(Publisher<DiagnosticArray>),
    Clock(Publisher<Clock>),
}

/// One subscription per topic type.
enum Sub {
    Sample(Subscription<DamperSample>),
    Output(Subscription<TwinOutput>),
    PredictedForce(Subscription<Float64>),
    YieldEstimate(Subscription<YieldEstimate>),
    Diagnostics(Subscription<DiagnosticArray>),
    Clock(Subscription<Clock>),
    /// Samples in their standard-type form (`sensor/sample_array`), converted to
    /// [`Message::Sample`] with this frame id; malformed ones are counted.
    SampleArray(Subscription<Float64MultiArray>, String),
}

impl Sub {
    /// Take everything pending; the first read error ends the take.
    fn take_all(&self, out: &mut Vec<Message>) -> Result<(), String> {
        fn drain<M: 'static + serde::de::DeserializeOwned>(
            s: &Subscription<M>,
            out: &mut Vec<Message>,
            wrap: fn(M) -> Message,
        ) -> Result<(), String> {
            loop {
                match s.take() {
                    Ok(Some((m, _info))) => out.push(wrap(m)),
                    Ok(None) => return Ok(()),
                    Err(e) => return Err(e.to_string()),
                }
            }
        }
        match self {
            Sub::Sample(s) => drain(s, out, Message::Sample),
            Sub::Output(s) => drain(s, out, Message::Output),
            Sub::PredictedForce(s) => drain(s, out, Message::PredictedForce),
            Sub::YieldEstimate(s) => drain(s, out, Message::YieldEstimate),
            Sub::Diagnostics(s) => drain(s, out, Message::Diagnostics),
            Sub::Clock(s) => drain(s, out, Message::Clock),
            Sub::SampleArray(s, frame) => loop {
                match s.take() {
                    Ok(Some((m, _info))) => match m.to_damper_sample(frame) {
                        Ok(d) => out.push(Message::Sample(d)),
                        Err(e) => return Err(format!("sensor/sample_array: {e}")),
                    },
                    Ok(None) => return Ok(()),
                    Err(e) => return Err(e.to_string()),
                }
            },
        }
    }
}

type NodeMap = Arc<Mutex<BTreeMap<String, Vec<(String, String)>>>>;

/// The ROS 2 adapter: one DDS participant with one ROS node, publishing and subscribing
/// the [`Topic`]s given at creation. Leaves the ROS graph on [`Ros2Transport::shutdown`]
/// or drop.
pub struct Ros2Transport {
    // Field order = drop order: endpoints first, then the node (which stops the spinner
    // and withdraws itself from ros_discovery_info), then the context.
    publishers: BTreeMap<Topic, Pub>,
    subscriptions: Vec<(Topic, Sub)>,
    node: Option<Node>,
    spinner: Option<JoinHandle<()>>,
    remote_nodes: NodeMap,
    context: Option<Context>,
    fully_qualified_name: String,
}

impl Ros2Transport {
    /// Join the ROS graph as node `cfg.namespace/cfg.node_name` on domain `cfg.domain_id`,
    /// with publishers for `publish` and subscriptions for `subscribe`.
    pub fn new(
        cfg: &Ros2Config,
        publish: &[Topic],
        subscribe: &[Topic],
    ) -> Result<Self, TransportError> {
        cfg.validate()?;
        let ns = cfg.canonical_namespace().expect("validated");
        let node_name = NodeName::new(&ns, &cfg.node_name).expect("validated");
        let fqn = node_name.fully_qualified_name();
        let context = Context::with_options(ContextOptions::new().domain_id(cfg.domain_id))
            .map_err(|e| {
                TransportError::new(
                    NAME,
                    format!("create DDS participant on domain {}", cfg.domain_id),
                    e,
                )
            })?;
        let mut node = context
            .new_node(
                node_name,
                NodeOptions::new()
                    .enable_rosout(false)
                    .start_parameter_services(false),
            )
            .map_err(|e| TransportError::new(NAME, format!("create node {fqn}"), e))?;

        let mut publishers = BTreeMap::new();
        for &topic in publish {
            if publishers.contains_key(&topic) {
                continue;
            }
            let p = Self::make_pub(&mut node, cfg, topic)?;
            publishers.insert(topic, p);
        }
        let mut subscriptions = Vec::new();
        for &topic in subscribe {
            if subscriptions.iter().any(|(t, _)| *t == topic) {
                continue;
            }
            let s = Self::make_sub(&mut node, cfg, topic)?;
            subscriptions.push((topic, s));
            if topic == Topic::Sample {
                subscriptions.push((topic, Self::make_sample_array_sub(&mut node, cfg)?));
            }
        }

        // The spinner, plus a collector of the nodes announced by other participants.
        let spinner = node
            .spinner()
            .map_err(|e| TransportError::new(NAME, "create the node's spinner", e))?;
        let events = node
            .status_receiver()
            .ok_or_else(|| TransportError::new(NAME, "graph events", "no spinner"))?;
        let remote_nodes: NodeMap = Arc::default();
        let collector_nodes = Arc::clone(&remote_nodes);
        let thread = std::thread::Builder::new()
            .name(format!("ros2-spin{fqn}").replace('/', "-"))
            .spawn(move || {
                use futures::StreamExt;
                let collect = events.for_each(move |ev| {
                    if let NodeEvent::ParticipantEntities(info) = ev {
                        let nodes = info
                            .nodes()
                            .iter()
                            .map(|n| (n.namespace().to_string(), n.name().to_string()))
                            .collect();
                        collector_nodes
                            .lock()
                            .unwrap_or_else(|p| p.into_inner())
                            .insert(format!("{:?}", info.gid()), nodes);
                    }
                    futures::future::ready(())
                });
                // The spinner ends when the node is dropped or stopped; the event stream
                // ends then too (its sender lives in the node).
                let spin = spinner.spin();
                futures::executor::block_on(async {
                    futures::pin_mut!(spin);
                    futures::pin_mut!(collect);
                    futures::future::select(spin, collect).await;
                });
            })
            .map_err(|e| TransportError::new(NAME, "start the spinner thread", e))?;

        Ok(Self {
            publishers,
            subscriptions,
            node: Some(node),
            spinner: Some(thread),
            remote_nodes,
            context: Some(context),
            fully_qualified_name: fqn,
        })
    }

    fn make_topic(
        node: &Node,
        cfg: &Ros2Config,
        topic: Topic,
    ) -> Result<(ros2_client::dds::rustdds::Topic, QosProfile), TransportError> {
        let full = cfg.resolve(topic);
        let (reliability, depth) = cfg.qos_of(topic);
        let qos = qos_profile(reliability, depth);
        let name = Name::parse(&full)
            .map_err(|e| TransportError::new(NAME, format!("topic name {full}"), e))?;
        let t = node
            .create_topic(&name, message_type_name(topic.type_name()), &qos)
            .map_err(|e| TransportError::new(NAME, format!("create topic {full}"), e))?;
        Ok((t, qos))
    }

    fn make_pub(node: &mut Node, cfg: &Ros2Config, topic: Topic) -> Result<Pub, TransportError> {
        let (t, qos) = Self::make_topic(node, cfg, topic)?;
        let ctx = || format!("create publisher on {}", cfg.resolve(topic));
        let e = |e: ros2_client::CreateError| TransportError::new(NAME, ctx(), e);
        let q = Some(qos);
        Ok(match topic {
            Topic::Sample => Pub::Sample(node.create_publisher(&t, q).map_err(e)?),
            Topic::Output => Pub::Output(node.create_publisher(&t, q).map_err(e)?),
            Topic::PredictedForce => Pub::PredictedForce(node.create_publisher(&t, q).map_err(e)?),
            Topic::YieldEstimate => Pub::YieldEstimate(node.create_publisher(&t, q).map_err(e)?),
            Topic::Diagnostics => Pub::Diagnostics(node.create_publisher(&t, q).map_err(e)?),
            Topic::Clock => Pub::Clock(node.create_publisher(&t, q).map_err(e)?),
        })
    }

    /// `sensor/sample_array` (`std_msgs/msg/Float64MultiArray`, labelled
    /// [`msgs::SAMPLE_ARRAY_LABEL`]): damper samples from publishers without our message
    /// package, e.g. plain rclpy or `ros2 topic pub`. Same QoS as `sensor/sample`.
    fn make_sample_array_sub(node: &mut Node, cfg: &Ros2Config) -> Result<Sub, TransportError> {
        let full = format!("{}_array", cfg.resolve(Topic::Sample));
        let (reliability, depth) = cfg.qos_of(Topic::Sample);
        let qos = qos_profile(reliability, depth);
        let name = Name::parse(&full)
            .map_err(|e| TransportError::new(NAME, format!("topic name {full}"), e))?;
        let t = node
            .create_topic(&name, message_type_name(Float64MultiArray::TYPE_NAME), &qos)
            .map_err(|e| TransportError::new(NAME, format!("create topic {full}"), e))?;
        let sub = node
            .create_subscription(&t, Some(qos))
            .map_err(|e| TransportError::new(NAME, format!("create subscription on {full}"), e))?;
        let frame = cfg
            .canonical_namespace()
            .unwrap_or_default()
            .trim_start_matches('/')
            .to_string();
        Ok(Sub::SampleArray(sub, frame))
    }

    fn make_sub(node: &mut Node, cfg: &Ros2Config, topic: Topic) -> Result<Sub, TransportError> {
        let (t, qos) = Self::make_topic(node, cfg, topic)?;
        let ctx = || format!("create subscription on {}", cfg.resolve(topic));
        let e = |e: ros2_client::CreateError| TransportError::new(NAME, ctx(), e);
        let q = Some(qos);
        Ok(match topic {
            Topic::Sample => Sub::Sample(node.create_subscription(&t, q).map_err(e)?),
            Topic::Output => Sub::Output(node.create_subscription(&t, q).map_err(e)?),
            Topic::PredictedForce => {
                Sub::PredictedForce(node.create_subscription(&t, q).map_err(e)?)
            }
            Topic::YieldEstimate => Sub::YieldEstimate(node.create_subscription(&t, q).map_err(e)?),
            Topic::Diagnostics => Sub::Diagnostics(node.create_subscription(&t, q).map_err(e)?),
            Topic::Clock => Sub::Clock(node.create_subscription(&t, q).map_err(e)?),
        })
    }

    /// Fully-qualified name of our node (`/damper1/mrtwin_twin`).
    pub fn node_fqn(&self) -> &str {
        &self.fully_qualified_name
    }

    /// Nodes (from `ros_discovery_info`, ours included) and ROS topics with their types
    /// (from DDS discovery) seen so far.
    pub fn graph(&self) -> RosGraph {
        let mut nodes: Vec<(String, String)> = self
            .remote_nodes
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .values()
            .flatten()
            .cloned()
            .collect();
        let mut topics = Vec::new();
        if let Some(ctx) = &self.context {
            for n in ctx.participant_entities_info().nodes() {
                nodes.push((n.namespace().to_string(), n.name().to_string()));
            }
            for t in ctx.discovered_topics() {
                if let Some(name) = ros_topic_name(&t.name) {
                    topics.push((name, ros_type_name(&t.type_name)));
                }
            }
        }
        nodes.sort();
        nodes.dedup();
        topics.sort();
        topics.dedup();
        RosGraph { nodes, topics }
    }

    /// Number of matched remote subscriptions of our publisher on `topic` (0 when we do
    /// not publish it).
    pub fn matched_subscriptions(&self, topic: Topic) -> usize {
        let Some(node) = &self.node else { return 0 };
        match self.publishers.get(&topic) {
            Some(Pub::Sample(p)) => p.get_subscription_count(node),
            Some(Pub::Output(p)) => p.get_subscription_count(node),
            Some(Pub::PredictedForce(p)) => p.get_subscription_count(node),
            Some(Pub::YieldEstimate(p)) => p.get_subscription_count(node),
            Some(Pub::Diagnostics(p)) => p.get_subscription_count(node),
            Some(Pub::Clock(p)) => p.get_subscription_count(node),
            None => 0,
        }
    }

    /// Number of matched remote publishers of our subscription on `topic`.
    pub fn matched_publishers(&self, topic: Topic) -> usize {
        let Some(node) = &self.node else { return 0 };
        let sum = |f: &dyn Fn(&Sub) -> usize| -> usize {
            self.subscriptions
                .iter()
                .filter(|(t, _)| *t == topic)
                .map(|(_, s)| f(s))
                .sum()
        };
        sum(&|s| match s {
            Sub::Sample(s) => s.get_publisher_count(node),
            Sub::SampleArray(s, _) => s.get_publisher_count(node),
            Sub::Output(s) => s.get_publisher_count(node),
            Sub::PredictedForce(s) => s.get_publisher_count(node),
            Sub::YieldEstimate(s) => s.get_publisher_count(node),
            Sub::Diagnostics(s) => s.get_publisher_count(node),
            Sub::Clock(s) => s.get_publisher_count(node),
        })
    }

    /// Leave the ROS graph cleanly: close the endpoints, withdraw the node from
    /// `ros_discovery_info`, stop the spinner, and drop the DDS participant (which tells
    /// its peers it is gone). Drop does the same.
    pub fn shutdown(mut self) {
        self.close();
    }

    fn close(&mut self) {
        self.publishers.clear();
        self.subscriptions.clear();
        if let Some(node) = self.node.take() {
            node.stop_spinner();
            drop(node); // removes the node from ros_discovery_info (broadcast)
        }
        if let Some(t) = self.spinner.take() {
            let _ = t.join();
        }
        self.context.take(); // last handle: the participant is disposed
    }
}

impl Drop for Ros2Transport {
    fn drop(&mut self) {
        self.close();
    }
}

impl Transport for Ros2Transport {
    fn name(&self) -> &'static str {
        NAME
    }

    fn publish(&mut self, msg: &Message) -> Result<(), TransportError> {
        let topic = msg.topic();
        let err = |reason: String| {
            TransportError::new(NAME, format!("publish on {}", topic.ros_name()), reason)
        };
        let p = self
            .publishers
            .get(&topic)
            .ok_or_else(|| err("not among this adapter's publications".into()))?;
        let r = match (p, msg) {
            (Pub::Sample(p), Message::Sample(m)) => p.publish(m.clone()).map_err(|e| e.to_string()),
            (Pub::Output(p), Message::Output(m)) => p.publish(m.clone()).map_err(|e| e.to_string()),
            (Pub::PredictedForce(p), Message::PredictedForce(m)) => {
                p.publish(*m).map_err(|e| e.to_string())
            }
            (Pub::YieldEstimate(p), Message::YieldEstimate(m)) => {
                p.publish(m.clone()).map_err(|e| e.to_string())
            }
            (Pub::Diagnostics(p), Message::Diagnostics(m)) => {
                p.publish(m.clone()).map_err(|e| e.to_string())
            }
            (Pub::Clock(p), Message::Clock(m)) => p.publish(*m).map_err(|e| e.to_string()),
            _ => Err("publisher of another type (internal error)".into()),
        };
        r.map_err(err)
    }

    fn poll(&mut self, out: &mut Vec<Message>) -> Result<(), TransportError> {
        for (topic, s) in &self.subscriptions {
            s.take_all(out).map_err(|e| {
                TransportError::new(NAME, format!("take from {}", topic.ros_name()), e)
            })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_under_the_namespace() {
        let mut cfg = Ros2Config::default();
        assert_eq!(cfg.resolve(Topic::Output), "/twin/output");
        assert_eq!(cfg.resolve(Topic::Diagnostics), "/diagnostics");
        cfg.namespace = "damper1/".into();
        assert_eq!(cfg.canonical_namespace().unwrap(), "/damper1");
        assert_eq!(cfg.resolve(Topic::Sample), "/damper1/sensor/sample");
        assert_eq!(cfg.resolve(Topic::Clock), "/clock");
        assert_eq!(
            ros_type_name("mrtwin_msgs::msg::dds_::TwinOutput_"),
            "mrtwin_msgs/msg/TwinOutput"
        );
        assert_eq!(ros_topic_name("rt/a/b").as_deref(), Some("/a/b"));
        assert_eq!(ros_topic_name("ros_discovery_info"), None);
        assert_eq!(
            message_type_name(Topic::Diagnostics.type_name()).dds_msg_type(),
            "diagnostic_msgs::msg::dds_::DiagnosticArray_"
        );
    }

    #[test]
    fn bad_configuration_names_the_field() {
        let mut cfg = Ros2Config {
            namespace: "/a b".into(),
            ..Default::default()
        };
        let e = cfg.validate().unwrap_err().to_string();
        assert!(e.contains("`namespace`"), "{e}");
        cfg.namespace = "/ok".into();
        cfg.node_name = "9lives".into();
        let e = cfg.validate().unwrap_err().to_string();
        assert!(e.contains("`node_name`"), "{e}");
        cfg.node_name = "twin".into();
        cfg.qos
            .insert("twin/nothing".into(), QosOverride::default());
        let e = cfg.validate().unwrap_err().to_string();
        assert!(
            e.contains("qos.twin/nothing") && e.contains("sensor/sample"),
            "{e}"
        );
        cfg.qos.clear();
        cfg.qos.insert(
            "/diagnostics".into(),
            QosOverride {
                reliability: Some(Reliability::BestEffort),
                depth: Some(0),
            },
        );
        assert!(cfg.validate().unwrap_err().to_string().contains("depth"));
        cfg.qos.get_mut("/diagnostics").unwrap().depth = Some(5);
        cfg.validate().unwrap();
        assert_eq!(cfg.qos_of(Topic::Diagnostics), (Reliability::BestEffort, 5));
        assert_eq!(cfg.qos_of(Topic::Sample), (Reliability::BestEffort, 1000));
        cfg.domain_id = 300;
        assert!(cfg
            .validate()
            .unwrap_err()
            .to_string()
            .contains("domain_id"));
        let parsed: Result<Ros2Config, _> =
            serde_json::from_str(r#"{"domain_id": 3, "namspace": "/x"}"#);
        assert!(parsed.is_err());
    }
}
