//! Which middleware a node uses, and opening the adapters (all behind
//! [`bridge::transport::Transport`]).

use std::fmt;

use bridge::transport::{Topic, Transport, TransportError};
use serde::{Deserialize, Serialize};

/// A middleware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TransportKind {
    /// ROS 2 over DDS (ros2-client).
    Ros2,
    /// zenoh, peer mode.
    Zenoh,
    /// iceoryx2 shared memory (local only).
    Iceoryx2,
}

impl TransportKind {
    /// Every kind.
    pub const ALL: [TransportKind; 3] = [
        TransportKind::Ros2,
        TransportKind::Zenoh,
        TransportKind::Iceoryx2,
    ];

    /// Name as in parameter files.
    pub fn name(self) -> &'static str {
        match self {
            TransportKind::Ros2 => "ros2",
            TransportKind::Zenoh => "zenoh",
            TransportKind::Iceoryx2 => "iceoryx2",
        }
    }
}

impl fmt::Display for TransportKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for TransportKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        TransportKind::ALL
            .into_iter()
            .find(|k| k.name() == s.trim())
            .ok_or_else(|| format!("unknown transport '{s}' (ros2, zenoh, iceoryx2)"))
    }
}

/// Settings of all transports, and the identity of the node on them.
#[derive(Debug, Clone)]
pub struct TransportSettings {
    /// Damper name (zenoh keys, iceoryx2 services).
    pub damper: String,
    /// Node name (ROS 2).
    pub node_name: String,
    /// Namespace (ROS 2), `/` for the root.
    pub namespace: String,
    /// ROS 2.
    pub ros2: bridge::ros2::Ros2Config,
    /// zenoh.
    pub zenoh: bridge::zenoh::ZenohConfig,
    /// iceoryx2.
    pub iceoryx2: bridge::iceoryx2::Iceoryx2Config,
}

impl TransportSettings {
    /// The settings of node `node_fqn` (`/ns/name`) for `damper`.
    pub fn new(
        damper: &str,
        node_fqn: &str,
        ros2: &bridge::ros2::Ros2Config,
        zenoh: &bridge::zenoh::ZenohConfig,
        iceoryx2: &bridge::iceoryx2::Iceoryx2Config,
    ) -> Self {
        let (namespace, name) = crate::runner::split_name(node_fqn);
        Self {
            damper: damper.to_string(),
            node_name: name.to_string(),
            namespace: namespace.to_string(),
            ros2: ros2.clone(),
            zenoh: zenoh.clone(),
            iceoryx2: iceoryx2.clone(),
        }
    }

    /// The iceoryx2 settings with the damper's default service prefix filled in.
    pub fn iceoryx2_config(&self) -> bridge::iceoryx2::Iceoryx2Config {
        let mut c = self.iceoryx2.clone();
        if c.service_prefix == bridge::iceoryx2::Iceoryx2Config::default().service_prefix {
            c.service_prefix = format!("mrtwin/{}", self.damper);
        }
        c
    }
}

/// Open one adapter.
pub fn open(
    kind: TransportKind,
    s: &TransportSettings,
    publish: &[Topic],
    subscribe: &[Topic],
) -> Result<Box<dyn Transport>, TransportError> {
    Ok(match kind {
        TransportKind::Ros2 => {
            let mut c = s.ros2.clone();
            c.node_name = s.node_name.clone();
            c.namespace = s.namespace.clone();
            Box::new(bridge::ros2::Ros2Transport::new(&c, publish, subscribe)?)
        }
        TransportKind::Zenoh => Box::new(bridge::zenoh::ZenohTransport::new(
            &s.zenoh, &s.damper, publish, subscribe,
        )?),
        TransportKind::Iceoryx2 => Box::new(bridge::iceoryx2::Iceoryx2Transport::new(
            &s.iceoryx2_config(),
            publish,
            subscribe,
        )?),
    })
}
