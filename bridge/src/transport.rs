//! The small interface every middleware adapter implements, so the twin node, the test
//! stand and the recorder never see DDS, zenoh or iceoryx2 types.
//!
//! Topic names are relative to the node's namespace, except `/diagnostics` and `/clock`,
//! which are global by ROS convention. Adapters map them to their own naming:
//! ROS 2 topics as below; zenoh key expressions `mrtwin/<damper>/<topic>`; iceoryx2
//! service names `mrtwin/<damper>/<topic>`.

use msgs::{Clock, DamperSample, DiagnosticArray, Float64, TwinOutput, YieldEstimate};
use serde::{Deserialize, Serialize};

/// The topics of an mrtwin system. In parameter files by [`Topic::key`] or
/// [`Topic::ros_name`] (`sensor/sample`, `/diagnostics`); an unknown name is an error
/// listing the known ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Topic {
    /// Sensor samples in (`sensor/sample`, `mrtwin_msgs/msg/DamperSample`, best effort).
    Sample,
    /// The twin's output per sample (`twin/output`, `mrtwin_msgs/msg/TwinOutput`, reliable).
    Output,
    /// Predicted force as a standard type (`twin/predicted_force`, `std_msgs/msg/Float64`).
    PredictedForce,
    /// Yield-stress estimate (`twin/yield_estimate`, `mrtwin_msgs/msg/YieldEstimate`).
    YieldEstimate,
    /// Health (`/diagnostics`, `diagnostic_msgs/msg/DiagnosticArray`, 1 Hz).
    Diagnostics,
    /// Simulated time during replay (`/clock`, `rosgraph_msgs/msg/Clock`).
    Clock,
}

impl Topic {
    /// Every topic.
    pub const ALL: [Topic; 6] = [
        Topic::Sample,
        Topic::Output,
        Topic::PredictedForce,
        Topic::YieldEstimate,
        Topic::Diagnostics,
        Topic::Clock,
    ];

    /// ROS 2 topic name: relative (`sensor/sample`) or absolute (`/diagnostics`).
    pub fn ros_name(self) -> &'static str {
        match self {
            Topic::Sample => "sensor/sample",
            Topic::Output => "twin/output",
            Topic::PredictedForce => "twin/predicted_force",
            Topic::YieldEstimate => "twin/yield_estimate",
            Topic::Diagnostics => "/diagnostics",
            Topic::Clock => "/clock",
        }
    }

    /// The name without a leading slash, for zenoh keys and iceoryx2 services.
    pub fn key(self) -> &'static str {
        self.ros_name().trim_start_matches('/')
    }

    /// ROS type name.
    pub fn type_name(self) -> &'static str {
        use msgs::RosMessage;
        match self {
            Topic::Sample => DamperSample::TYPE_NAME,
            Topic::Output => TwinOutput::TYPE_NAME,
            Topic::PredictedForce => Float64::TYPE_NAME,
            Topic::YieldEstimate => YieldEstimate::TYPE_NAME,
            Topic::Diagnostics => DiagnosticArray::TYPE_NAME,
            Topic::Clock => Clock::TYPE_NAME,
        }
    }

    /// `true` for sensor data (best-effort QoS, keep last); outputs are reliable.
    pub fn is_sensor_data(self) -> bool {
        self == Topic::Sample
    }

    /// From [`Topic::ros_name`] or [`Topic::key`].
    pub fn parse(name: &str) -> Option<Topic> {
        Topic::ALL
            .into_iter()
            .find(|t| t.ros_name() == name || t.key() == name)
    }
}

/// A name that is not one of the [`Topic`]s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown topic '{0}'; known: {known}", known = Topic::ALL.map(Topic::key).join(", "))]
pub struct UnknownTopic(pub String);

impl std::str::FromStr for Topic {
    type Err = UnknownTopic;
    fn from_str(name: &str) -> Result<Self, UnknownTopic> {
        Topic::parse(name.trim()).ok_or_else(|| UnknownTopic(name.trim().to_string()))
    }
}

impl TryFrom<String> for Topic {
    type Error = UnknownTopic;
    fn try_from(name: String) -> Result<Self, UnknownTopic> {
        name.parse()
    }
}

impl From<Topic> for String {
    fn from(t: Topic) -> Self {
        t.key().to_string()
    }
}

/// One message on one of the [`Topic`]s.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// On [`Topic::Sample`].
    Sample(DamperSample),
    /// On [`Topic::Output`].
    Output(TwinOutput),
    /// On [`Topic::PredictedForce`].
    PredictedForce(Float64),
    /// On [`Topic::YieldEstimate`].
    YieldEstimate(YieldEstimate),
    /// On [`Topic::Diagnostics`].
    Diagnostics(DiagnosticArray),
    /// On [`Topic::Clock`].
    Clock(Clock),
}

impl Message {
    /// The topic it travels on.
    pub fn topic(&self) -> Topic {
        match self {
            Message::Sample(_) => Topic::Sample,
            Message::Output(_) => Topic::Output,
            Message::PredictedForce(_) => Topic::PredictedForce,
            Message::YieldEstimate(_) => Topic::YieldEstimate,
            Message::Diagnostics(_) => Topic::Diagnostics,
            Message::Clock(_) => Topic::Clock,
        }
    }

    /// CDR bytes with the encapsulation header (what DDS, zenoh and bags carry).
    pub fn to_cdr(&self) -> Vec<u8> {
        use msgs::cdr::encode;
        match self {
            Message::Sample(m) => encode(m),
            Message::Output(m) => encode(m),
            Message::PredictedForce(m) => encode(m),
            Message::YieldEstimate(m) => encode(m),
            Message::Diagnostics(m) => encode(m),
            Message::Clock(m) => encode(m),
        }
    }

    /// Decode CDR bytes of `topic`.
    pub fn from_cdr(topic: Topic, bytes: &[u8]) -> Result<Message, msgs::cdr::CdrError> {
        use msgs::cdr::decode;
        Ok(match topic {
            Topic::Sample => Message::Sample(decode(bytes)?),
            Topic::Output => Message::Output(decode(bytes)?),
            Topic::PredictedForce => Message::PredictedForce(decode(bytes)?),
            Topic::YieldEstimate => Message::YieldEstimate(decode(bytes)?),
            Topic::Diagnostics => Message::Diagnostics(decode(bytes)?),
            Topic::Clock => Message::Clock(decode(bytes)?),
        })
    }
}

/// A transport failure, with the adapter and what it was doing.
#[derive(Debug, thiserror::Error)]
#[error("{transport}: {context}: {reason}")]
pub struct TransportError {
    /// `ros2`, `zenoh`, `iceoryx2`.
    pub transport: &'static str,
    /// What it was doing (e.g. `publish on twin/output`).
    pub context: String,
    /// The underlying error, as text.
    pub reason: String,
}

impl TransportError {
    /// Build one.
    pub fn new(transport: &'static str, context: impl Into<String>, reason: impl ToString) -> Self {
        Self {
            transport,
            context: context.into(),
            reason: reason.to_string(),
        }
    }
}

/// A middleware adapter. Created with the topics it publishes and subscribes; used from
/// one thread (the node's loop), never blocking for long.
pub trait Transport: Send {
    /// `ros2`, `zenoh`, `iceoryx2`.
    fn name(&self) -> &'static str;
    /// Publish on the message's topic (which must be among the adapter's publications).
    fn publish(&mut self, msg: &Message) -> Result<(), TransportError>;
    /// Append whatever arrived on the subscribed topics since the last call; never blocks.
    fn poll(&mut self, out: &mut Vec<Message>) -> Result<(), TransportError>;
    /// The doorbell this adapter rings when something arrives on a subscribed topic
    /// (bind it to the thread that calls [`Transport::poll`]). `None`: the adapter cannot
    /// say, and its reader must poll on a timer.
    fn doorbell(&self) -> Option<crate::wake::Doorbell> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_parse_and_round_trip_cdr() {
        for t in Topic::ALL {
            assert_eq!(Topic::parse(t.ros_name()), Some(t));
            assert_eq!(Topic::parse(t.key()), Some(t));
        }
        let e = "twin/nothing".parse::<Topic>().unwrap_err().to_string();
        assert!(
            e.contains("'twin/nothing'") && e.contains("sensor/sample"),
            "{e}"
        );
        let m = Message::PredictedForce(Float64 { data: 3.0 });
        assert_eq!(Message::from_cdr(m.topic(), &m.to_cdr()).unwrap(), m);
    }
}
