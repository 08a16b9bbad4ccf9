//! Quality of service, as ROS 2 names it, shared by the ROS 2 adapter (what it offers and
//! requests per topic) and the bags (the `offered_qos_profiles` rosbag2 records).

use serde::{Deserialize, Serialize};

/// Delivery guarantee of a topic (ROS 2 QoS reliability; parameter files spell it
/// `best_effort` / `reliable`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reliability {
    /// Samples may be lost; a best-effort reader matches any writer (rmw value 2; sensor
    /// data).
    BestEffort,
    /// Lost samples are re-sent; a reliable reader only matches reliable writers (rmw
    /// value 1).
    Reliable,
}
