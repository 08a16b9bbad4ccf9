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

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use crate::transport::{Message, Topic, Transport, TransportError};

const NAME: &str = "zenoh";

/// zenoh settings (parameter-file section `zenoh`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohConfig {
    /// `peer` (default, no router needed) or `client` (through a router in `connect`).
    pub mode: String,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447`.
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:0`.
    pub listen: Vec<String>,
    /// Find peers by UDP multicast scouting (off for isolated tests).
    pub multicast_scouting: bool,
    /// First element of every key expression.
    pub key_prefix: String,
}

impl Default for ZenohConfig {
    fn default() -> Self {
        Self {
            mode: "peer".into(),
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

    fn to_zenoh(&self) -> Result<zenoh::Config, TransportError> {
        let err = |what: &str, e: Box<dyn std::error::Error + Send + Sync>| {
            TransportError::new(NAME, format!("configuration: {what}"), e)
        };
        if self.mode != "peer" && self.mode != "client" {
            return Err(TransportError::new(
                NAME,
                "configuration: mode",
                format!("'{}' is not peer or client", self.mode),
            ));
        }
        let mut c = zenoh::Config::default();
        c.insert_json5("mode", &format!("\"{}\"", self.mode))
            .map_err(|e| err("mode", e))?;
        let list = |v: &[String]| serde_json_list(v);
        c.insert_json5("connect/endpoints", &list(&self.connect))
            .map_err(|e| err("connect", e))?;
        if !self.listen.is_empty() {
            c.insert_json5("listen/endpoints", &list(&self.listen))
                .map_err(|e| err("listen", e))?;
        }
        c.insert_json5(
            "scouting/multicast/enabled",
            if self.multicast_scouting {
                "true"
            } else {
                "false"
            },
        )
        .map_err(|e| err("multicast_scouting", e))?;
        Ok(c)
    }
}

fn serde_json_list(v: &[String]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|s| format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\"")))
        .collect();
    format!("[{}]", items.join(","))
}

/// The zenoh adapter.
pub struct ZenohTransport {
    session: Session,
    publishers: HashMap<Topic, Publisher<'static>>,
    subscribers: Vec<(Topic, Subscriber<FifoChannelHandler<Sample>>)>,
    /// Messages that arrived but did not decode (counted, not fatal).
    pub undecodable: u64,
}

impl ZenohTransport {
    /// Open a session and declare the publishers and subscribers of `damper`.
    pub fn new(
        cfg: &ZenohConfig,
        damper: &str,
        publish: &[Topic],
        subscribe: &[Topic],
    ) -> Result<Self, TransportError> {
        let session = zenoh::open(cfg.to_zenoh()?)
            .wait()
            .map_err(|e| TransportError::new(NAME, "open session", e))?;
        let mut publishers = HashMap::new();
        for &t in publish {
            let key = cfg.key(damper, t);
            let congestion = zenoh::qos::CongestionControl::Block;
            let p = session
                .declare_publisher(key.clone())
                .encoding(zenoh::bytes::Encoding::APPLICATION_CDR)
                .congestion_control(congestion)
                .wait()
                .map_err(|e| TransportError::new(NAME, format!("declare publisher {key}"), e))?;
            publishers.insert(t, p);
        }
        let mut subscribers = Vec::new();
        for &t in subscribe {
            let key = cfg.key(damper, t);
            let s = session
                .declare_subscriber(key.clone())
                .with(zenoh::handlers::FifoChannel::new(65_536))
                .wait()
                .map_err(|e| TransportError::new(NAME, format!("declare subscriber {key}"), e))?;
            subscribers.push((t, s));
        }
        Ok(Self {
            session,
            publishers,
            subscribers,
            undecodable: 0,
        })
    }

    /// Close the session (also done on drop).
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}

impl Transport for ZenohTransport {
    fn name(&self) -> &'static str {
        NAME
    }

    fn publish(&mut self, msg: &Message) -> Result<(), TransportError> {
        let topic = msg.topic();
        let Some(p) = self.publishers.get(&topic) else {
            return Ok(());
        };
        p.put(msg.to_cdr())
            .wait()
            .map_err(|e| TransportError::new(NAME, format!("publish on {}", topic.key()), e))
    }

    fn poll(&mut self, out: &mut Vec<Message>) -> Result<(), TransportError> {
        for (topic, sub) in &self.subscribers {
            while let Ok(Some(sample)) = sub.try_recv() {
                let bytes = sample.payload().to_bytes();
                match Message::from_cdr(*topic, &bytes) {
                    Ok(m) => out.push(m),
                    Err(_) => self.undecodable += 1,
                }
            }
        }
        Ok(())
    }
}
