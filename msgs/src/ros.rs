//! `builtin_interfaces/msg/Time` and `std_msgs/msg/Header`.

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the epoch (or since the
/// start of a recording, for simulated time).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0..1e9.
    pub nanosec: u32,
}

impl Time {
    /// .msg text.
    pub const MSG: &'static str = "int32 sec\nuint32 nanosec\n";

    /// From seconds as f64 (rounded to the nearest nanosecond).
    pub fn from_secs_f64(t: f64) -> Self {
        Self::from_nanos((t * 1e9).round() as i64)
    }

    /// From nanoseconds.
    pub fn from_nanos(ns: i64) -> Self {
        Self {
            sec: ns.div_euclid(1_000_000_000) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }

    /// As nanoseconds.
    pub fn as_nanos(&self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }

    /// As seconds.
    pub fn as_secs_f64(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Frame the data is in (for a damper: its name).
    pub frame_id: String,
}

impl Header {
    /// .msg text.
    pub const MSG: &'static str = "builtin_interfaces/Time stamp\nstring frame_id\n";

    /// A header at `t` seconds.
    pub fn at(t: f64, frame_id: &str) -> Self {
        Self {
            stamp: Time::from_secs_f64(t),
            frame_id: frame_id.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_round_trips_and_handles_negative() {
        let t = Time::from_secs_f64(12.000_000_5);
        assert_eq!(t.sec, 12);
        assert_eq!(t.nanosec, 500);
        assert_eq!(Time::from_nanos(t.as_nanos()), t);
        let n = Time::from_secs_f64(-0.25);
        assert_eq!((n.sec, n.nanosec), (-1, 750_000_000));
        assert!((n.as_secs_f64() + 0.25).abs() < 1e-12);
    }
}
