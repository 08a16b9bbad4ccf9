//! The DDS participant behind [`Ros2Transport`] (feature `ros2`).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::task::{Context as TaskContext, Poll, Waker};
use std::thread::JoinHandle;

use futures::Stream;

use msgs::{
    Clock, DamperSample, DiagnosticArray, Float64, Float64MultiArray, RosMessage, TwinOutput,
    YieldEstimate,
};
use ros2_client::dds::{Context, ContextOptions, Node, NodeEvent, Publisher, Subscription};
use ros2_client::qos::{Durability, History, Reliability as QosReliability, WhenFull};
use ros2_client::{MessageTypeName, Name, NodeName, NodeOptions, ParameterValue, QosProfile};

use super::{Reliability, Ros2Config, NAME};
use crate::params::{ParamService, ParamValue};
use crate::transport::{Message, Topic, Transport, TransportError};
use crate::wake::Doorbell;

/// What the adapter sees of the ROS graph.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RosGraph {
    /// `(namespace, name)` of every node announced on `ros_discovery_info`, ours included.
    pub nodes: Vec<(String, String)>,
    /// `(topic, type)` in ROS form (`/damper1/twin/output`, `mrtwin_msgs/msg/TwinOutput`)
    /// of every ROS topic discovered over DDS, ours included.
    pub topics: Vec<(String, String)>,
}

/// The node's options: no rosout; the parameter services when there are parameters.
fn node_options(params: Option<Arc<dyn ParamService>>) -> NodeOptions {
    let options = NodeOptions::new().enable_rosout(false);
    let Some(params) = params else {
        return options.start_parameter_services(false);
    };
    let mut options = options.start_parameter_services(true);
    for (name, value) in params.declared() {
        options = options.declare_parameter(&name, to_ros(value));
    }
    let check = Arc::clone(&params);
    options
        .parameter_validator(Box::new(move |name, value| {
            check.check(name, &from_ros(name, value)?)
        }))
        .parameter_set_action(Box::new(move |name, value| {
            params.set(name, &from_ros(name, value)?)
        }))
}

fn to_ros(v: ParamValue) -> ParameterValue {
    match v {
        ParamValue::Bool(b) => ParameterValue::Boolean(b),
        ParamValue::Integer(i) => ParameterValue::Integer(i),
        ParamValue::Double(x) => ParameterValue::Double(x),
        ParamValue::Text(s) => ParameterValue::String(s),
        ParamValue::Doubles(x) => ParameterValue::DoubleArray(x),
        ParamValue::Texts(s) => ParameterValue::StringArray(s),
    }
}

fn from_ros(name: &str, v: &ParameterValue) -> Result<ParamValue, String> {
    Ok(match v {
        ParameterValue::Boolean(b) => ParamValue::Bool(*b),
        ParameterValue::Integer(i) => ParamValue::Integer(*i),
        ParameterValue::Double(x) => ParamValue::Double(*x),
        ParameterValue::String(s) => ParamValue::Text(s.clone()),
        ParameterValue::DoubleArray(x) => ParamValue::Doubles(x.clone()),
        ParameterValue::StringArray(s) => ParamValue::Texts(s.clone()),
        other => {
            return Err(format!(
                "parameter '{name}': {:?} values are not used by mrtwin",
                other.to_parameter_type()
            ))
        }
    })
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
    /// Take everything pending, then leave `waker` with the reader so that RustDDS wakes
    /// it on the next arrival; the first read error ends the take.
    fn take_all(&self, out: &mut Vec<Message>, waker: &Waker) -> Result<(), String> {
        fn drain<M: 'static + serde::de::DeserializeOwned>(
            s: &Subscription<M>,
            out: &mut Vec<Message>,
            waker: &Waker,
            wrap: impl Fn(M) -> Result<Message, String>,
        ) -> Result<(), String> {
            loop {
                match s.take() {
                    Ok(Some((m, _info))) => out.push(wrap(m)?),
                    Ok(None) => break,
                    Err(e) => return Err(e.to_string()),
                }
            }
            // The reader's stream stores the waker when it finds nothing (and takes what
            // arrived in between), so no arrival after the take above goes unrung.
            let stream = s.async_stream();
            futures::pin_mut!(stream);
            let mut cx = TaskContext::from_waker(waker);
            loop {
                match stream.as_mut().poll_next(&mut cx) {
                    Poll::Ready(Some(Ok((m, _info)))) => out.push(wrap(m)?),
                    Poll::Ready(Some(Err(e))) => return Err(e.to_string()),
                    Poll::Ready(None) | Poll::Pending => return Ok(()),
                }
            }
        }
        match self {
            Sub::Sample(s) => drain(s, out, waker, |m| Ok(Message::Sample(m))),
            Sub::Output(s) => drain(s, out, waker, |m| Ok(Message::Output(m))),
            Sub::PredictedForce(s) => drain(s, out, waker, |m| Ok(Message::PredictedForce(m))),
            Sub::YieldEstimate(s) => drain(s, out, waker, |m| Ok(Message::YieldEstimate(m))),
            Sub::Diagnostics(s) => drain(s, out, waker, |m| Ok(Message::Diagnostics(m))),
            Sub::Clock(s) => drain(s, out, waker, |m| Ok(Message::Clock(m))),
            Sub::SampleArray(s, frame) => drain(s, out, waker, |m| {
                m.to_damper_sample(frame)
                    .map(Message::Sample)
                    .map_err(|e| format!("sensor/sample_array: {e}"))
            }),
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
    /// Rung by the readers' wakers when a message arrives.
    doorbell: Doorbell,
    waker: Waker,
}

impl Ros2Transport {
    /// Join the ROS graph as node `cfg.namespace/cfg.node_name` on domain `cfg.domain_id`,
    /// with publishers for `publish` and subscriptions for `subscribe`.
    pub fn new(
        cfg: &Ros2Config,
        publish: &[Topic],
        subscribe: &[Topic],
    ) -> Result<Self, TransportError> {
        Self::with_parameters(cfg, publish, subscribe, None)
    }

    /// [`Self::new`], serving `params` as the node's ROS 2 parameters (the standard
    /// parameter services; a set is checked by the service, refused with its reason, and
    /// otherwise handed to it). Without `params` the node serves none.
    pub fn with_parameters(
        cfg: &Ros2Config,
        publish: &[Topic],
        subscribe: &[Topic],
        params: Option<Arc<dyn ParamService>>,
    ) -> Result<Self, TransportError> {
        cfg.validate()?;
        let node_name = NodeName::new(cfg.namespace.as_str(), &cfg.node_name).map_err(|e| {
            TransportError::new(
                NAME,
                format!("node name {}/{}", cfg.namespace, cfg.node_name),
                e,
            )
        })?;
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
            .new_node(node_name, node_options(params))
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

        let doorbell = Doorbell::new();
        Ok(Self {
            publishers,
            subscriptions,
            node: Some(node),
            spinner: Some(thread),
            remote_nodes,
            context: Some(context),
            fully_qualified_name: fqn,
            waker: doorbell.waker(),
            doorbell,
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
        let frame = cfg.namespace.as_str().trim_start_matches('/').to_string();
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
            // Dropping the node signals its spinner to stop (once; an explicit
            // `stop_spinner()` before it made the drop's second signal fail and log an
            // error at every exit) and removes the node from ros_discovery_info.
            drop(node);
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
            s.take_all(out, &self.waker).map_err(|e| {
                TransportError::new(NAME, format!("take from {}", topic.ros_name()), e)
            })?;
        }
        Ok(())
    }

    fn doorbell(&self) -> Option<Doorbell> {
        Some(self.doorbell.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dds_names_map_to_ros_names() {
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
}
