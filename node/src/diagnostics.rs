//! Health as `diagnostic_msgs/DiagnosticArray`: one `DiagnosticStatus` per check, named
//! `"<node>: <check>"`, `hardware_id` = the damper, levels OK/WARN/ERROR/STALE, so
//! rqt_robot_monitor and diagnostic_aggregator understand it.

use estimation::health::{Check, Level};
use msgs::{DiagnosticArray, DiagnosticStatus, Header, KeyValue};

use crate::conditioning::StreamCounters;

/// The sensor-stream check: staleness and what the conditioning dropped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamState {
    /// Seconds since the last sample arrived (wall clock); none before the first.
    pub silence_s: Option<f64>,
    /// STALE after this much silence \[s\].
    pub stale_after_s: f64,
    /// Counters now.
    pub counters: StreamCounters,
    /// Counters at the previous report (what changed since is judged).
    pub previous: StreamCounters,
    /// Samples per second (wall clock) over the last report period.
    pub rate_hz: f64,
    /// Transport errors since the previous report.
    pub transport_errors: u64,
}

impl StreamState {
    /// Samples dropped since the previous report.
    fn dropped(&self) -> u64 {
        let (c, p) = (self.counters, self.previous);
        (c.non_finite - p.non_finite)
            + (c.duplicates - p.duplicates)
            + (c.out_of_order - p.out_of_order)
    }

    /// The check's level alone (the node asks every loop turn; no strings built).
    pub fn level(&self) -> Level {
        match self.silence_s {
            None => Level::Stale,
            Some(s) if s > self.stale_after_s => Level::Stale,
            Some(_) if self.transport_errors > 0 || self.dropped() > 0 => Level::Warn,
            Some(_) => Level::Ok,
        }
    }

    /// The check.
    pub fn check(&self) -> Check {
        let c = self.counters;
        let dropped = self.dropped();
        let (level, message) = match self.silence_s {
            None => (Level::Stale, "no sensor sample yet".to_string()),
            Some(s) if s > self.stale_after_s => {
                (Level::Stale, format!("no sensor sample for {s:.1} s"))
            }
            Some(_) if self.transport_errors > 0 => (
                Level::Warn,
                format!("{} transport errors", self.transport_errors),
            ),
            Some(_) if dropped > 0 => (
                Level::Warn,
                format!("{dropped} samples dropped (NaN, duplicate or out of order)"),
            ),
            Some(_) => (Level::Ok, format!("{:.0} samples/s", self.rate_hz)),
        };
        Check {
            name: "sensor stream".into(),
            level,
            message,
            values: vec![
                ("rate_hz".into(), format!("{:.1}", self.rate_hz)),
                (
                    "silence_s".into(),
                    self.silence_s.map_or("inf".into(), |s| format!("{s:.3}")),
                ),
                ("received".into(), c.received.to_string()),
                ("accepted".into(), c.accepted.to_string()),
                ("non_finite".into(), c.non_finite.to_string()),
                ("duplicates".into(), c.duplicates.to_string()),
                ("out_of_order".into(), c.out_of_order.to_string()),
                ("gaps".into(), c.gaps.to_string()),
                ("transport_errors".into(), self.transport_errors.to_string()),
            ],
        }
    }
}

/// ROS level byte of a [`Level`].
pub fn level_byte(l: Level) -> u8 {
    match l {
        Level::Ok => DiagnosticStatus::OK,
        Level::Warn => DiagnosticStatus::WARN,
        Level::Error => DiagnosticStatus::ERROR,
        Level::Stale => DiagnosticStatus::STALE,
    }
}

/// Worst level, with STALE above ERROR (as the ROS aggregator ranks it for display).
pub fn worst(levels: impl IntoIterator<Item = Level>) -> Level {
    levels
        .into_iter()
        .max_by_key(|l| level_byte(*l))
        .unwrap_or(Level::Ok)
}

/// The DiagnosticArray of `checks` at `stamp_s`.
pub fn diagnostic_array(
    node: &str,
    damper: &str,
    stamp_s: f64,
    checks: &[Check],
) -> DiagnosticArray {
    DiagnosticArray {
        header: Header::at(stamp_s, ""),
        status: checks
            .iter()
            .map(|c| DiagnosticStatus {
                level: level_byte(c.level),
                name: format!("{node}: {}", c.name),
                message: c.message.clone(),
                hardware_id: damper.to_string(),
                values: c
                    .values
                    .iter()
                    .map(|(k, v)| KeyValue::new(k.clone(), v.clone()))
                    .collect(),
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn silence_goes_stale_and_back() {
        let mut s = StreamState {
            silence_s: None,
            stale_after_s: 0.5,
            counters: StreamCounters::default(),
            previous: StreamCounters::default(),
            rate_hz: 0.0,
            transport_errors: 0,
        };
        assert_eq!(s.check().level, Level::Stale);
        assert_eq!(s.level(), s.check().level);
        s.silence_s = Some(0.1);
        assert_eq!(s.check().level, Level::Ok);
        assert_eq!(s.level(), s.check().level);
        s.counters.duplicates = 3;
        assert_eq!(s.check().level, Level::Warn);
        assert_eq!(s.level(), s.check().level);
        s.silence_s = Some(0.6);
        assert_eq!(s.check().level, Level::Stale);
        assert_eq!(s.level(), s.check().level);
        let a = diagnostic_array("/ns/twin", "d1", 1.0, &[s.check()]);
        assert_eq!(a.status[0].name, "/ns/twin: sensor stream");
        assert_eq!(a.status[0].level, DiagnosticStatus::STALE);
        assert_eq!(a.status[0].hardware_id, "d1");
    }
}
