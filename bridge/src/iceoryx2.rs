//! iceoryx2 (shared memory, zero copy) adapter: the local, plain-data loop of the twin.
//!
//! Three ipc services under one prefix ([`Iceoryx2Config::service_prefix`], default
//! `mrtwin/damper`):
//!
//! | service | pattern | payload |
//! |---|---|---|
//! | `<prefix>/sensor/sample` | publish–subscribe | [`ShmSample`] |
//! | `<prefix>/twin/prediction` | publish–subscribe | [`ShmPrediction`] |
//! | `<prefix>/twin/control` | request–response | [`ShmRequest`] → [`ShmPrediction`] |
//!
//! [`ShmSample`]: msgs::shm::ShmSample
//! [`ShmPrediction`]: msgs::shm::ShmPrediction
//! [`ShmRequest`]: msgs::shm::ShmRequest
//!
//! * [`Iceoryx2Transport`] implements [`Transport`](crate::transport::Transport) for the
//!   publish–subscribe pair. It carries [`Topic::Sample`](crate::transport::Topic::Sample)
//!   and [`Topic::Output`](crate::transport::Topic::Output), and
//!   [`Topic::YieldEstimate`](crate::transport::Topic::YieldEstimate) reduced to τ0 ± σ
//!   inside the predictions; the other topics have no plain-data layout and are ignored on
//!   publish and subscribe (see [`Iceoryx2Transport::carries`]).
//! * [`ControlServer`] answers a local controller's requests: a measured sample (the twin
//!   steps) or a planned current (a what-if on a copy of the twin's state).
//! * [`ControlClient`] is the controller's side: blocking [`ControlClient::request`] with a
//!   bounded timeout, or pipelined [`ControlClient::send`] + [`ControlClient::receive`].
//! * [`controller`]: the paced request loop of the example controller, as a library.
//!
//! Every node is created with signal handling off (the application owns SIGINT/SIGTERM)
//! and first removes the stale resources of dead nodes (processes that crashed), so a
//! restarted client or publisher can take the place of the dead one.
//!
//! Service settings (buffer sizes, in-flight requests, port counts) come from
//! [`Iceoryx2Config`] and must be equal on both sides: iceoryx2 refuses to open a service
//! created with smaller limits than the opener asks for.
//!
//! The settings ([`Iceoryx2Config`]) are compiled in every build, so one parameter file
//! reads everywhere; the adapter only with the `iceoryx2` feature.

#[cfg(feature = "iceoryx2")]
mod adapter;
#[cfg(feature = "iceoryx2")]
pub mod controller;
#[cfg(feature = "iceoryx2")]
mod wakeup;

#[cfg(feature = "iceoryx2")]
pub use adapter::{
    output_from_shm, output_to_shm, quiet_logs, rejected_reply, sample_from_shm, sample_to_shm,
    Backoff, ControlClient, ControlServer, Iceoryx2Transport, POLLING_SERVER_STAYS_HOT,
};

use crate::transport::TransportError;

const NAME: &str = "iceoryx2";

/// Settings of the iceoryx2 adapter (the `iceoryx2:` section of a launch configuration).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Iceoryx2Config {
    /// Prefix of the service names: `<prefix>/sensor/sample`, `<prefix>/twin/prediction`,
    /// `<prefix>/twin/control`. Its last segment is the damper name (`frame_id` of the
    /// samples received).
    pub service_prefix: String,
    /// Whether the twin node offers the request–response control service
    /// (read by the node; [`ControlServer::new`] itself does not look at it).
    pub request_response: bool,
    /// Samples a subscriber keeps between two polls (default 1024: one second at 1 kHz).
    /// When it overflows, the oldest sample is dropped and counted by
    /// [`Iceoryx2Transport::missed_samples`].
    pub subscriber_buffer: usize,
    /// Requests one client may have in flight (pipelining depth; default 16).
    pub max_in_flight: usize,
    /// Clients of the control service (default 4).
    pub max_clients: usize,
    /// Publishers per publish–subscribe service (default 4).
    pub max_publishers: usize,
    /// Subscribers per publish–subscribe service (default 8).
    pub max_subscribers: usize,
}

impl Default for Iceoryx2Config {
    fn default() -> Self {
        Self {
            service_prefix: "mrtwin/damper".to_string(),
            request_response: true,
            subscriber_buffer: 1024,
            max_in_flight: 16,
            max_clients: 4,
            max_publishers: 4,
            max_subscribers: 8,
        }
    }
}

impl Iceoryx2Config {
    /// The same settings with another prefix (tests give each run its own).
    pub fn with_prefix(&self, prefix: impl Into<String>) -> Self {
        Self {
            service_prefix: prefix.into(),
            ..self.clone()
        }
    }

    /// Service name of the sensor samples.
    pub fn sample_service(&self) -> String {
        format!("{}/sensor/sample", self.service_prefix)
    }

    /// Service name of the twin's predictions.
    pub fn prediction_service(&self) -> String {
        format!("{}/twin/prediction", self.service_prefix)
    }

    /// Service name of the request–response control service.
    pub fn control_service(&self) -> String {
        format!("{}/twin/control", self.service_prefix)
    }

    /// The damper name: the prefix's last segment.
    pub fn damper_name(&self) -> &str {
        self.service_prefix
            .rsplit('/')
            .find(|s| !s.is_empty())
            .unwrap_or("damper")
    }

    /// Check the numbers and the names before any shared memory is touched.
    pub fn validate(&self) -> Result<(), TransportError> {
        let positive = [
            ("subscriber_buffer", self.subscriber_buffer),
            ("max_in_flight", self.max_in_flight),
            ("max_clients", self.max_clients),
            ("max_publishers", self.max_publishers),
            ("max_subscribers", self.max_subscribers),
        ];
        for (field, v) in positive {
            if v == 0 {
                return Err(TransportError::new(
                    NAME,
                    format!("config field `{field}`"),
                    "must be at least 1",
                ));
            }
        }
        let p = &self.service_prefix;
        if p.is_empty() || p.starts_with('/') || p.ends_with('/') || p.contains("//") {
            return Err(TransportError::new(
                NAME,
                format!("config field `service_prefix` = {p:?}"),
                "must be non-empty segments joined by `/` (e.g. `mrtwin/damper`)",
            ));
        }
        #[cfg(feature = "iceoryx2")]
        for name in [
            self.sample_service(),
            self.prediction_service(),
            self.control_service(),
        ] {
            adapter::service_name(&name)?;
        }
        Ok(())
    }
}
