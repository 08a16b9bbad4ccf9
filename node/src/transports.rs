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
        let (namespace, name) = split_name(node_fqn);
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

/// Open one adapter. A transport this build does not hold (its cargo feature was off) is
/// an error naming the transport and the feature.
pub fn open(
    kind: TransportKind,
    s: &TransportSettings,
    publish: &[Topic],
    subscribe: &[Topic],
) -> Result<Box<dyn Transport>, TransportError> {
    open_serving(kind, s, publish, subscribe, None)
}

/// [`open`], with the node's parameters served where the middleware has a parameter
/// service of its own (ROS 2); the other transports ignore them.
pub fn open_serving(
    kind: TransportKind,
    s: &TransportSettings,
    publish: &[Topic],
    subscribe: &[Topic],
    params: Option<std::sync::Arc<dyn bridge::params::ParamService>>,
) -> Result<Box<dyn Transport>, TransportError> {
    #[cfg(not(feature = "ros2"))]
    let _ = params;
    match kind {
        #[cfg(feature = "ros2")]
        TransportKind::Ros2 => {
            let mut c = s.ros2.clone();
            c.node_name = s.node_name.clone();
            c.namespace = s
                .namespace
                .parse()
                .map_err(|e| TransportError::new("ros2", "node namespace", e))?;
            Ok(Box::new(bridge::ros2::Ros2Transport::with_parameters(
                &c, publish, subscribe, params,
            )?))
        }
        #[cfg(feature = "zenoh")]
        TransportKind::Zenoh => Ok(Box::new(bridge::zenoh::ZenohTransport::new(
            &s.zenoh, &s.damper, publish, subscribe,
        )?)),
        #[cfg(feature = "iceoryx2")]
        TransportKind::Iceoryx2 => Ok(Box::new(bridge::iceoryx2::Iceoryx2Transport::new(
            &s.iceoryx2_config(),
            publish,
            subscribe,
        )?)),
        #[cfg(not(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2")))]
        missing => {
            let _ = (s, publish, subscribe);
            Err(not_compiled(missing))
        }
    }
}

// `ControlClient`: the client of the iceoryx2 control service (a local controller's side),
// bridge's when the `iceoryx2` feature is on. Without it, a type with no values whose `new`
// reports that iceoryx2 is not compiled in, so callers need no feature gates of their own.
#[cfg(not(feature = "iceoryx2"))]
pub use absent::ControlClient;
#[cfg(feature = "iceoryx2")]
pub use bridge::iceoryx2::ControlClient;

#[cfg(not(feature = "iceoryx2"))]
mod absent {
    use std::time::Duration;

    use bridge::iceoryx2::Iceoryx2Config;
    use bridge::transport::TransportError;
    use msgs::shm::{ShmPrediction, ShmRequest};

    use super::{not_compiled, TransportKind};

    /// The control client of a build without iceoryx2: it cannot be created.
    #[derive(Debug)]
    pub enum ControlClient {}

    impl ControlClient {
        /// Always the error that iceoryx2 is not compiled in.
        pub fn new(_cfg: &Iceoryx2Config) -> Result<Self, TransportError> {
            Err(not_compiled(TransportKind::Iceoryx2))
        }

        /// Unreachable: there is no client.
        pub fn wait_for_server(&self, _timeout: Duration) -> Result<(), TransportError> {
            match *self {}
        }

        /// Unreachable: there is no client.
        pub fn request(
            &mut self,
            _req: &ShmRequest,
            _timeout: Duration,
        ) -> Result<ShmPrediction, TransportError> {
            match *self {}
        }
    }
}

/// The error of asking for a transport this build does not hold.
pub fn not_compiled(kind: TransportKind) -> TransportError {
    TransportError::new(
        kind.name(),
        "open",
        format!(
            "not compiled into this build; rebuild with the cargo feature `{kind}` \
             (e.g. cargo build --release -p mrtwin --features {kind})"
        ),
    )
}

/// `/ns/name` → (`/ns`, `name`); `name` → (`/`, `name`).
pub fn split_name(fqn: &str) -> (&str, &str) {
    match fqn.rfind('/') {
        Some(0) => ("/", &fqn[1..]),
        Some(i) => (&fqn[..i], &fqn[i + 1..]),
        None => ("/", fqn),
    }
}
