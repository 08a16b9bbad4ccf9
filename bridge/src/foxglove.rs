//! A live view for Foxglove: a Foxglove WebSocket server (the `foxglove` crate's, protocol
//! `foxglove.sdk.v1`) that carries one twin's messages to the Foxglove app or any client
//! of that protocol.
//!
//! Channels, named like the ROS 2 topics under the node's namespace:
//!
//! | channel | encoding | schema |
//! |---|---|---|
//! | `sensor/sample` | `cdr` | `mrtwin_msgs/msg/DamperSample` (`ros2msg`) |
//! | `twin/output` | `cdr` | `mrtwin_msgs/msg/TwinOutput`: measured and predicted force |
//! | `twin/predicted_force` | `cdr` | `std_msgs/msg/Float64` |
//! | `twin/yield_estimate` | `cdr` | `mrtwin_msgs/msg/YieldEstimate` |
//! | `/diagnostics` | `cdr` | `diagnostic_msgs/msg/DiagnosticArray` |
//! | `twin/fv_loop` | `json` | [`FV_LOOP_SCHEMA`]: one point of the force–velocity loop |
//!
//! The CDR payloads are the bytes the node sends over DDS and zenoh, with the full
//! `ros2msg` definitions the bags carry, so Foxglove's ROS panels (Plot, Diagnostics, Raw
//! Messages) decode them as they would a ROS 2 connection. `twin/fv_loop` pairs each sample
//! with the twin's output for it: in a Plot panel, X axis `/twin/fv_loop.velocity_m_s`,
//! series `.measured_force_n` and `.predicted_force_n`, is the F–v loop.
//!
//! The server listens where it is told (the command line's default is loopback) and serves
//! any number of clients; a message goes only to the clients subscribed to its channel, and
//! costs nothing when none is.

use std::collections::HashMap;
use std::sync::Arc;

use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use msgs::DamperSample;

use crate::transport::{Message, Topic, Transport, TransportError};

/// The topics a twin shows on Foxglove (besides `twin/fv_loop`).
pub const TOPICS: [Topic; 5] = [
    Topic::Sample,
    Topic::Output,
    Topic::PredictedForce,
    Topic::YieldEstimate,
    Topic::Diagnostics,
];

/// Name of the force–velocity loop channel, relative to the node's namespace.
pub const FV_LOOP: &str = "twin/fv_loop";

/// JSON schema of one `twin/fv_loop` message.
pub const FV_LOOP_SCHEMA: &str = r#"{"title":"mrtwin.FvLoopPoint","description":"One sample of the damper and the twin's prediction for it (SI units, PHYSICS.md signs)","type":"object","properties":{"time_s":{"type":"number","description":"sample stamp [s]"},"displacement_m":{"type":"number"},"velocity_m_s":{"type":"number"},"current_a":{"type":"number"},"measured_force_n":{"type":"number"},"predicted_force_n":{"type":"number"},"residual_n":{"type":"number"}},"required":["time_s","displacement_m","velocity_m_s","current_a","measured_force_n","predicted_force_n","residual_n"]}"#;

/// Where the server listens and what it calls its channels.
#[derive(Debug, Clone)]
pub struct FoxgloveConfig {
    /// Interface to bind (`127.0.0.1` unless the user names another).
    pub host: String,
    /// Port; 0 picks a free one ([`FoxgloveServer::port`] says which).
    pub port: u16,
    /// Node namespace the channel names sit under (`/` for the root).
    pub namespace: String,
    /// Server name shown by clients.
    pub name: String,
}

/// The running server and its channels. Dropping it stops the server.
pub struct FoxgloveServer {
    /// The channels' context: the server holds it weakly, so it lives here.
    _context: Arc<Context>,
    handle: Option<foxglove::WebSocketServerHandle>,
    port: u16,
    channels: HashMap<Topic, Arc<RawChannel>>,
    fv_loop: Arc<RawChannel>,
    /// The last sample seen, waiting for the output with its stamp.
    last_sample: Option<DamperSample>,
    /// Stamp of the last message that had one \[ns\] (for those that do not).
    last_stamp_ns: Option<u64>,
}

impl std::fmt::Debug for FoxgloveServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FoxgloveServer")
            .field("port", &self.port)
            .finish_non_exhaustive()
    }
}

fn error(context: &str, e: impl ToString) -> TransportError {
    TransportError::new("foxglove", context, e)
}

/// `ns` + `name` as an absolute channel name (`/diagnostics` stays global).
pub fn channel_name(namespace: &str, name: &str) -> String {
    if name.starts_with('/') {
        return name.to_string();
    }
    let ns = namespace.trim_end_matches('/');
    if ns.is_empty() {
        format!("/{name}")
    } else if ns.starts_with('/') {
        format!("{ns}/{name}")
    } else {
        format!("/{ns}/{name}")
    }
}

impl FoxgloveServer {
    /// Declare the channels and start listening. Must not be called from inside an async
    /// runtime (the server runs on a tokio runtime of its own).
    pub fn start(cfg: &FoxgloveConfig) -> Result<Self, TransportError> {
        let ctx = Context::new();
        let mut channels = HashMap::new();
        for topic in TOPICS {
            let ch = ChannelBuilder::new(channel_name(&cfg.namespace, topic.ros_name()))
                .message_encoding("cdr")
                .schema(Schema::new(
                    topic.type_name(),
                    "ros2msg",
                    crate::bag::writer::topic_definition(topic).into_bytes(),
                ))
                .context(&ctx)
                .build_raw()
                .map_err(|e| error(&format!("declare channel {}", topic.ros_name()), e))?;
            channels.insert(topic, ch);
        }
        let fv_loop = ChannelBuilder::new(channel_name(&cfg.namespace, FV_LOOP))
            .message_encoding("json")
            .schema(Schema::new(
                "mrtwin.FvLoopPoint",
                "jsonschema",
                FV_LOOP_SCHEMA.as_bytes(),
            ))
            .context(&ctx)
            .build_raw()
            .map_err(|e| error(&format!("declare channel {FV_LOOP}"), e))?;
        let handle = WebSocketServer::new()
            .name(cfg.name.clone())
            .bind(cfg.host.clone(), cfg.port)
            .context(&ctx)
            .start_blocking()
            .map_err(|e| error(&format!("listen on {}:{}", cfg.host, cfg.port), e))?;
        let port = handle.port();
        Ok(Self {
            _context: ctx,
            handle: Some(handle),
            port,
            channels,
            fv_loop,
            last_sample: None,
            last_stamp_ns: None,
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Clients connected now.
    pub fn client_count(&self) -> usize {
        self.handle.as_ref().map_or(0, |h| h.client_count())
    }

    fn metadata(&mut self, msg: &Message) -> PartialMetadata {
        let stamp = crate::bag::writer::message_stamp_ns(msg)
            .and_then(|ns| u64::try_from(ns).ok())
            .or(self.last_stamp_ns);
        if stamp.is_some() {
            self.last_stamp_ns = stamp;
        }
        PartialMetadata { log_time: stamp }
    }

    /// One `twin/fv_loop` point: `sample` and the output for it.
    fn log_fv_point(&self, sample: &DamperSample, out: &msgs::TwinOutput, meta: PartialMetadata) {
        let point = serde_json::json!({
            "time_s": sample.header.stamp.as_nanos() as f64 * 1e-9,
            "displacement_m": sample.displacement,
            "velocity_m_s": sample.velocity,
            "current_a": sample.current,
            "measured_force_n": out.measured_force,
            "predicted_force_n": out.predicted_force,
            "residual_n": out.residual,
        });
        self.fv_loop
            .log_with_meta(point.to_string().as_bytes(), meta);
    }
}

impl Transport for FoxgloveServer {
    fn name(&self) -> &'static str {
        "foxglove"
    }

    fn publish(&mut self, msg: &Message) -> Result<(), TransportError> {
        let topic = msg.topic();
        if !self.channels.contains_key(&topic) {
            return Ok(()); // `/clock`: not part of the live view
        }
        let meta = self.metadata(msg);
        let channel = &self.channels[&topic];
        if channel.has_sinks() {
            channel.log_with_meta(&msg.to_cdr(), meta);
        }
        match msg {
            Message::Sample(s) => self.last_sample = Some(s.clone()),
            Message::Output(out) => {
                if let Some(s) = self.last_sample.take() {
                    if s.header.stamp == out.header.stamp && self.fv_loop.has_sinks() {
                        self.log_fv_point(&s, out, meta);
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn poll(&mut self, _out: &mut Vec<Message>) -> Result<(), TransportError> {
        Ok(()) // clients only watch; nothing comes back
    }
}

impl Drop for FoxgloveServer {
    fn drop(&mut self) {
        if let Some(h) = self.handle.take() {
            h.stop().detach_all();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_names_follow_ros_resolution() {
        assert_eq!(channel_name("/", "twin/output"), "/twin/output");
        assert_eq!(channel_name("/rig1", "twin/output"), "/rig1/twin/output");
        assert_eq!(channel_name("/rig1/", "twin/fv_loop"), "/rig1/twin/fv_loop");
        assert_eq!(channel_name("/rig1", "/diagnostics"), "/diagnostics");
    }

    #[test]
    fn the_fv_loop_schema_is_json() {
        let v: serde_json::Value = serde_json::from_str(FV_LOOP_SCHEMA).unwrap();
        assert_eq!(v["required"].as_array().unwrap().len(), 7);
    }
}
