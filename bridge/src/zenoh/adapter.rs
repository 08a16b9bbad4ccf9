//! The zenoh session behind [`ZenohTransport`] (feature `zenoh`).

use std::collections::HashMap;

use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use super::ZenohConfig;
use crate::transport::{Message, Topic, Transport, TransportError};

const NAME: &str = "zenoh";

/// zenoh's own configuration for `cfg`.
fn session_config(cfg: &ZenohConfig) -> Result<zenoh::Config, TransportError> {
    let err = |what: &str, e: Box<dyn std::error::Error + Send + Sync>| {
        TransportError::new(NAME, format!("configuration: {what}"), e)
    };
    // zenoh is built with its TCP link only (bridge/Cargo.toml): say so, rather than
    // zenoh's "not supported" at open.
    for (what, endpoints) in [("connect", &cfg.connect), ("listen", &cfg.listen)] {
        if let Some(e) = endpoints.iter().find(|e| !e.starts_with("tcp/")) {
            return Err(TransportError::new(
                NAME,
                format!("configuration: {what}"),
                format!(
                    "endpoint '{e}': this build's zenoh has the TCP link only (tcp/<host>:<port>)"
                ),
            ));
        }
    }
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", &format!("\"{}\"", cfg.mode))
        .map_err(|e| err("mode", e))?;
    c.insert_json5("connect/endpoints", &json_list(&cfg.connect))
        .map_err(|e| err("connect", e))?;
    if !cfg.listen.is_empty() {
        c.insert_json5("listen/endpoints", &json_list(&cfg.listen))
            .map_err(|e| err("listen", e))?;
    }
    c.insert_json5(
        "scouting/multicast/enabled",
        if cfg.multicast_scouting {
            "true"
        } else {
            "false"
        },
    )
    .map_err(|e| err("multicast_scouting", e))?;
    Ok(c)
}

fn json_list(v: &[String]) -> String {
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
        let session = zenoh::open(session_config(cfg)?)
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
                    Err(e) => {
                        tracing::warn!(key = %sample.key_expr(), error = %e, "undecodable payload dropped");
                        self.undecodable += 1;
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_of_links_not_built_in_are_named() {
        let mut cfg = ZenohConfig {
            listen: vec!["tcp/127.0.0.1:0".into()],
            ..Default::default()
        };
        session_config(&cfg).unwrap();
        cfg.connect = vec!["udp/127.0.0.1:7447".into()];
        let e = session_config(&cfg).unwrap_err().to_string();
        assert!(
            e.contains("connect") && e.contains("udp/127.0.0.1:7447") && e.contains("TCP"),
            "{e}"
        );
    }
}
