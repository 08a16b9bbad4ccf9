//! zenoh adapter: every topic is a key expression `<key_prefix>/<damper>/<topic>`
//! (e.g. `mrtwin/damper/twin/output`), the payload is the message's CDR bytes with the
//! encapsulation header (encoding `application/cdr`), the same bytes DDS and rosbag2 carry,
//! so a zenoh-bridge-ros2dds user and a plain zenoh subscriber read the same thing.
//!
//! QoS: every topic is published with congestion control `Block` (reliable), so neither
//! samples nor outputs are lost when the link is busy; a publisher waits instead.
//!
//! Peer mode by default: no router is needed; peers find each other by multicast
//! scouting, or by the `connect`/`listen` endpoints given in the configuration.
//! zenoh is built with its TCP link only: endpoints are `tcp/<host>:<port>` (multicast
//! scouting is part of zenoh's core and needs no link).
//!
//! The settings ([`ZenohConfig`]) are compiled in every build, so one parameter file
//! reads everywhere; the adapter ([`ZenohTransport`]) only with the `zenoh` feature.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::transport::Topic;

#[cfg(feature = "zenoh")]
mod adapter;
#[cfg(feature = "zenoh")]
pub use adapter::{TopicWatch, ZenohSession, ZenohTransport};

/// How a zenoh session joins the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ZenohMode {
    /// `peer`: talks to other peers directly, no router needed.
    #[default]
    Peer,
    /// `client`: talks through the router(s) in `connect`.
    Client,
}

impl ZenohMode {
    /// The name in parameter files and in zenoh's own configuration.
    pub fn name(self) -> &'static str {
        match self {
            ZenohMode::Peer => "peer",
            ZenohMode::Client => "client",
        }
    }
}

impl fmt::Display for ZenohMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// zenoh settings (parameter-file section `zenoh`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohConfig {
    /// `peer` (default, no router needed) or `client` (through a router in `connect`).
    pub mode: ZenohMode,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447`.
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/0.0.0.0:7447`. Empty (the default): a peer
    /// listens on loopback only, `tcp/127.0.0.1:0` (any free port).
    pub listen: Vec<String>,
    /// Find peers by UDP multicast scouting (off for isolated tests).
    pub multicast_scouting: bool,
    /// First element of every key expression.
    pub key_prefix: String,
}

impl Default for ZenohConfig {
    fn default() -> Self {
        Self {
            mode: ZenohMode::Peer,
            connect: Vec::new(),
            listen: Vec::new(),
            multicast_scouting: true,
            key_prefix: "mrtwin".into(),
        }
    }
}

impl ZenohConfig {
    /// The key expression of `topic` for `damper`.
    pub fn key(&self, damper: &str, topic: Topic) -> String {
        format!("{}/{}/{}", self.key_prefix, damper, topic.key())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_parses_by_name_and_unknown_modes_are_listed() {
        let c: ZenohConfig = serde_json::from_str(r#"{"mode": "client"}"#).unwrap();
        assert_eq!(c.mode, ZenohMode::Client);
        assert_eq!(c.mode.to_string(), "client");
        let e = serde_json::from_str::<ZenohConfig>(r#"{"mode": "router"}"#)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("router") && e.contains("peer") && e.contains("client"),
            "{e}"
        );
        assert_eq!(
            ZenohConfig::default().key("d1", Topic::Diagnostics),
            "mrtwin/d1/diagnostics"
        );
    }
}
