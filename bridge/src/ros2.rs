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
//! [`Transport::publish`](crate::transport::Transport::publish) is bounded: on a reliable topic with a full send window it waits
//! at most 100 ms (ros2-client's `WhenFull::DEFAULT`) and then reports an error.
//! [`Transport::poll`](crate::transport::Transport::poll) takes whatever is in the readers' caches, without waiting.
//!
//! The settings ([`Ros2Config`], with the namespace and the QoS keys parsed when the file
//! is read) are compiled in every build, so one parameter file reads everywhere; the
//! adapter ([`Ros2Transport`]) only with the `ros2` feature.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::transport::{Topic, TransportError};

#[cfg(feature = "ros2")]
mod adapter;
#[cfg(feature = "ros2")]
pub use adapter::{Ros2Transport, RosGraph};

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

/// A ROS namespace in canonical form: absolute, no trailing `/` except for the root
/// (`/`, `/damper1`, `/lab/rig_a`). Parsed from any spelling ROS accepts (`damper1/` is
/// `/damper1`); a malformed one is an error naming the bad token.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Namespace(String);

impl Namespace {
    /// `/`.
    pub fn root() -> Self {
        Namespace("/".into())
    }

    /// The canonical text.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// `true` for `/`.
    pub fn is_root(&self) -> bool {
        self.0 == "/"
    }
}

impl Default for Namespace {
    fn default() -> Self {
        Self::root()
    }
}

/// A malformed ROS name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidName(String);

impl FromStr for Namespace {
    type Err = InvalidName;
    fn from_str(text: &str) -> Result<Self, InvalidName> {
        let ns = text.trim();
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
            return Ok(Namespace(ns));
        }
        for token in ns[1..].split('/') {
            let ok = !token.is_empty()
                && token.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
                && token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                && !token.contains("__");
            if !ok {
                return Err(InvalidName(format!(
                    "namespace {text:?}: token {token:?} must be non-empty, start with a letter \
                     or '_', and hold only letters, digits and single '_'"
                )));
            }
        }
        Ok(Namespace(ns))
    }
}

impl TryFrom<String> for Namespace {
    type Error = InvalidName;
    fn try_from(s: String) -> Result<Self, InvalidName> {
        s.parse()
    }
}

impl From<Namespace> for String {
    fn from(ns: Namespace) -> Self {
        ns.0
    }
}

impl fmt::Display for Namespace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Why `name` is not a ROS node name (`None`: it is one): non-empty, a letter or `_`
/// first, then letters, digits and `_`.
fn node_name_error(name: &str) -> Option<String> {
    let ok = name.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    (!ok).then(|| {
        format!(
            "{name:?} must be non-empty, start with a letter or '_', and hold only letters, \
             digits and '_'"
        )
    })
}

/// Configuration of the ROS 2 adapter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2Config {
    /// DDS domain (`ROS_DOMAIN_ID`), 0..=232.
    pub domain_id: u16,
    /// Node namespace (`__ns:=`).
    pub namespace: Namespace,
    /// Node name (`__node:=`).
    pub node_name: String,
    /// Per-topic QoS overrides, keyed by topic ([`Topic::key`] or [`Topic::ros_name`],
    /// e.g. `sensor/sample`, `/diagnostics`; an unknown topic is an error listing the
    /// known ones).
    pub qos: BTreeMap<Topic, QosOverride>,
}

impl Default for Ros2Config {
    fn default() -> Self {
        Self {
            domain_id: 0,
            namespace: Namespace::root(),
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
        if let Some(o) = self.qos.get(&topic) {
            reliability = o.reliability.unwrap_or(reliability);
            depth = o.depth.unwrap_or(depth);
        }
        (reliability, depth)
    }

    /// Check the ranges and the node name (everything [`Ros2Transport::new`] would
    /// reject that the types do not rule out), with the field named.
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
        if let Some(reason) = node_name_error(&self.node_name) {
            return Err(err("node_name", reason));
        }
        for (topic, o) in &self.qos {
            if o.depth == Some(0) {
                return Err(err(
                    &format!("qos.{}.depth", topic.key()),
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
            name.to_string()
        } else if self.namespace.is_root() {
            format!("/{name}")
        } else {
            format!("{}/{name}", self.namespace)
        }
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
        cfg.namespace = "damper1/".parse().unwrap();
        assert_eq!(cfg.namespace.as_str(), "/damper1");
        assert_eq!(cfg.resolve(Topic::Sample), "/damper1/sensor/sample");
        assert_eq!(cfg.resolve(Topic::Clock), "/clock");
    }

    #[test]
    fn bad_configuration_names_the_field() {
        let parse = |json: &str| serde_json::from_str::<Ros2Config>(json);
        let e = parse(r#"{"namespace": "/a b"}"#).unwrap_err().to_string();
        assert!(e.contains("namespace") && e.contains("\"a b\""), "{e}");
        let mut cfg: Ros2Config = parse(r#"{"namespace": "/ok"}"#).unwrap();
        cfg.node_name = "9lives".into();
        let e = cfg.validate().unwrap_err().to_string();
        assert!(e.contains("`node_name`"), "{e}");
        cfg.node_name = "twin".into();
        let e = parse(r#"{"qos": {"twin/nothing": {}}}"#)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("twin/nothing") && e.contains("sensor/sample"),
            "{e}"
        );
        cfg.qos = parse(r#"{"qos": {"/diagnostics": {"reliability": "best_effort", "depth": 0}}}"#)
            .unwrap()
            .qos;
        assert!(cfg.validate().unwrap_err().to_string().contains("depth"));
        cfg.qos.get_mut(&Topic::Diagnostics).unwrap().depth = Some(5);
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
