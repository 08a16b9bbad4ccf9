//! The zenoh session behind [`ZenohTransport`] (feature `zenoh`).

use std::collections::HashMap;

use zenoh::handlers::{FifoChannel, FifoChannelHandler, IntoHandler};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use super::ZenohConfig;
use crate::transport::{Message, Topic, Transport, TransportError};
use crate::wake::Doorbell;

const NAME: &str = "zenoh";

/// Where a peer listens when its configuration names no endpoint: loopback, any free port.
pub const LOOPBACK_LISTEN: &str = "tcp/127.0.0.1:0";

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
    // Security default: a peer listens on loopback unless told otherwise (zenoh's own
    // default is every interface, `tcp/[::]:0`). Peers on this host still find it by
    // scouting; a peer elsewhere needs `listen` set to an address it can reach.
    let listen = match (cfg.listen.is_empty(), cfg.mode) {
        (true, super::ZenohMode::Peer) => vec![LOOPBACK_LISTEN.to_string()],
        _ => cfg.listen.clone(),
    };
    if !listen.is_empty() {
        c.insert_json5("listen/endpoints", &json_list(&listen))
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
    /// Per subscribed topic: zenoh's subscriber (its callback queues the sample in a FIFO
    /// channel, as zenoh's default handler does, and rings the doorbell) and the queue.
    subscribers: Vec<(Topic, Subscriber<()>, FifoChannelHandler<Sample>)>,
    doorbell: Doorbell,
}

/// Samples queued per subscription before zenoh's receiving thread waits for the reader.
const QUEUE: usize = 65_536;

/// A subscriber to `key` whose callback queues each sample in a FIFO channel, as zenoh's
/// default handler does, and rings `doorbell`. Queueing blocks zenoh's receiving thread
/// while the queue is full.
fn queued_subscriber(
    session: &Session,
    key: String,
    doorbell: &Doorbell,
) -> Result<(Subscriber<()>, FifoChannelHandler<Sample>), TransportError> {
    let (queue, rx) = FifoChannel::new(QUEUE).into_handler();
    let bell = doorbell.clone();
    let s = session
        .declare_subscriber(key.clone())
        .callback(move |sample| {
            queue.call(sample);
            bell.ring();
        })
        .wait()
        .map_err(|e| TransportError::new(NAME, format!("declare subscriber {key}"), e))?;
    Ok((s, rx))
}

/// One zenoh session shared by many dampers' adapters (a fleet in one process: one
/// session, one set of links, N dampers' key expressions). Dropping the last adapter and
/// this handle closes it.
#[derive(Clone)]
pub struct ZenohSession {
    session: Session,
    cfg: ZenohConfig,
}

impl std::fmt::Debug for ZenohSession {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohSession")
            .field("zid", &self.session.zid())
            .finish_non_exhaustive()
    }
}

impl ZenohSession {
    /// Open a session with `cfg`.
    pub fn open(cfg: &ZenohConfig) -> Result<Self, TransportError> {
        let session = zenoh::open(session_config(cfg)?)
            .wait()
            .map_err(|e| TransportError::new(NAME, "open session", e))?;
        Ok(Self {
            session,
            cfg: cfg.clone(),
        })
    }

    /// An adapter for `damper` on this session: its publishers and subscribers, keyed
    /// `<key_prefix>/<damper>/<topic>` as [`ZenohTransport::new`]'s.
    pub fn transport(
        &self,
        damper: &str,
        publish: &[Topic],
        subscribe: &[Topic],
    ) -> Result<ZenohTransport, TransportError> {
        ZenohTransport::declare(self.session.clone(), &self.cfg, damper, publish, subscribe)
    }

    /// Every damper's `topic` under this session's key prefix
    /// (`<key_prefix>/**/<topic>`): what a central monitor subscribes to, whatever the
    /// sites and dampers behind the routers.
    pub fn watch(&self, topic: Topic) -> Result<TopicWatch, TransportError> {
        let key = format!("{}/**/{}", self.cfg.key_prefix, topic.key());
        let doorbell = Doorbell::new();
        let (subscriber, rx) = queued_subscriber(&self.session, key, &doorbell)?;
        Ok(TopicWatch {
            topic,
            prefix: format!("{}/", self.cfg.key_prefix),
            suffix: format!("/{}", topic.key()),
            _subscriber: subscriber,
            queue: rx,
            doorbell,
        })
    }
}

/// One topic of every damper under a key prefix ([`ZenohSession::watch`]).
pub struct TopicWatch {
    topic: Topic,
    prefix: String,
    suffix: String,
    _subscriber: Subscriber<()>,
    queue: FifoChannelHandler<Sample>,
    doorbell: Doorbell,
}

impl TopicWatch {
    /// Append what arrived, each with the damper's key between the prefix and the topic
    /// (`siteA/d001` for `mrtwin/siteA/d001/twin/output`). A payload that does not
    /// decode is an error naming its key (what came before it is kept).
    pub fn poll(&mut self, out: &mut Vec<(String, Message)>) -> Result<(), TransportError> {
        while let Some(sample) = self
            .queue
            .try_recv()
            .map_err(|e| TransportError::new(NAME, format!("receive {}", self.suffix), e))?
        {
            let key = sample.key_expr().as_str();
            let damper = key
                .strip_prefix(&self.prefix)
                .and_then(|k| k.strip_suffix(&self.suffix))
                .unwrap_or(key)
                .to_string();
            let m = Message::from_cdr(self.topic, &sample.payload().to_bytes())
                .map_err(|e| TransportError::new(NAME, format!("decode {key}"), e))?;
            out.push((damper, m));
        }
        Ok(())
    }

    /// Rings when something arrived.
    pub fn doorbell(&self) -> Doorbell {
        self.doorbell.clone()
    }
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
        Self::declare(session, cfg, damper, publish, subscribe)
    }

    /// Declare the publishers and subscribers of `damper` on `session`.
    fn declare(
        session: Session,
        cfg: &ZenohConfig,
        damper: &str,
        publish: &[Topic],
        subscribe: &[Topic],
    ) -> Result<Self, TransportError> {
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
        let doorbell = Doorbell::new();
        for &t in subscribe {
            let (s, rx) = queued_subscriber(&session, cfg.key(damper, t), &doorbell)?;
            subscribers.push((t, s, rx));
        }
        Ok(Self {
            session,
            publishers,
            subscribers,
            doorbell,
        })
    }

    /// Close the session (also done on drop of its last handle; on a [`ZenohSession`]'s
    /// adapter this closes the session for every adapter on it).
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}

impl Transport for ZenohTransport {
    fn name(&self) -> &'static str {
        NAME
    }

    /// As the ROS 2 and iceoryx2 adapters: a topic not among the adapter's publications is
    /// an error.
    fn publish(&mut self, msg: &Message) -> Result<(), TransportError> {
        let topic = msg.topic();
        let context = || format!("publish on {}", topic.key());
        let p = self.publishers.get(&topic).ok_or_else(|| {
            TransportError::new(
                NAME,
                context(),
                "topic not among this adapter's publications",
            )
        })?;
        p.put(msg.to_cdr())
            .wait()
            .map_err(|e| TransportError::new(NAME, context(), e))
    }

    /// As the ROS 2 adapter: what arrived before a failure is appended, the failure is
    /// returned (a payload that does not decode is dropped with it; a closed channel is
    /// an error), and the rest waits for the next call.
    fn poll(&mut self, out: &mut Vec<Message>) -> Result<(), TransportError> {
        for (topic, sub, queue) in &self.subscribers {
            let context = || format!("receive on {}", sub.key_expr());
            while let Some(sample) = queue
                .try_recv()
                .map_err(|e| TransportError::new(NAME, context(), e))?
            {
                let bytes = sample.payload().to_bytes();
                let m = Message::from_cdr(*topic, &bytes).map_err(|e| {
                    TransportError::new(
                        NAME,
                        format!("decode {} from {}", topic.key(), sample.key_expr()),
                        e,
                    )
                })?;
                out.push(m);
            }
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

    /// The same contract as the ROS 2 and iceoryx2 adapters: wrong use and bad payloads are
    /// errors that name the topic, and what arrived before them is kept.
    #[test]
    fn undeclared_topics_and_undecodable_payloads_are_errors() {
        let cfg = ZenohConfig {
            listen: vec!["tcp/127.0.0.1:0".into()],
            multicast_scouting: false,
            key_prefix: "mrtwin_it_adapter_errors".into(),
            ..Default::default()
        };
        let mut t = ZenohTransport::new(
            &cfg,
            "d1",
            &[Topic::PredictedForce],
            &[Topic::PredictedForce],
        )
        .unwrap();
        let e = t
            .publish(&Message::Clock(msgs::Clock::default()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("clock") && e.contains("not among"), "{e}");
        // A good message, then a payload that is not CDR of a Float64 (the session
        // delivers its own publications to its own subscribers).
        t.publish(&Message::PredictedForce(msgs::Float64 { data: 2.5 }))
            .unwrap();
        let key = cfg.key("d1", Topic::PredictedForce);
        t.session.put(key.clone(), vec![1u8, 2]).wait().unwrap();
        let mut out = Vec::new();
        let mut err = None;
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while err.is_none() && std::time::Instant::now() < deadline {
            if let Err(e) = t.poll(&mut out) {
                err = Some(e.to_string());
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let e = err.expect("the bad payload is reported within 10 s");
        assert!(e.contains("decode") && e.contains(&key), "{e}");
        assert_eq!(
            out,
            vec![Message::PredictedForce(msgs::Float64 { data: 2.5 })]
        );
        t.close();
    }

    #[test]
    fn a_peer_listens_on_loopback_unless_told_otherwise() {
        let listen = |cfg: &ZenohConfig| {
            session_config(cfg)
                .unwrap()
                .get_json("listen/endpoints")
                .unwrap()
        };
        let peer = ZenohConfig::default();
        assert!(
            listen(&peer).contains("tcp/127.0.0.1:0"),
            "{}",
            listen(&peer)
        );
        let told = ZenohConfig {
            listen: vec!["tcp/0.0.0.0:7447".into()],
            ..Default::default()
        };
        let l = listen(&told);
        assert!(
            l.contains("tcp/0.0.0.0:7447") && !l.contains("127.0.0.1"),
            "{l}"
        );
        // A client does not listen: nothing is added.
        let client = ZenohConfig {
            mode: crate::zenoh::ZenohMode::Client,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            ..Default::default()
        };
        assert!(
            !listen(&client).contains("127.0.0.1:0"),
            "{}",
            listen(&client)
        );
    }

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
