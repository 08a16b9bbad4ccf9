//! A central view of many dampers: what a monitor behind the zenoh routers knows of each
//! damper from the outputs and diagnostics that reach it. A damper whose outputs stop
//! arriving for `stale_after_s` is STALE, whatever its own last diagnostics said (a
//! dropped link looks like that: the twin on the rig is fine, nothing reaches the
//! centre); when outputs arrive again it takes its twin's own level back. No I/O and no
//! clock: the caller passes `now`.

use std::collections::BTreeMap;

use msgs::{DiagnosticArray, DiagnosticStatus};

/// One change of a damper's central level.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    /// The damper's key (`siteA/d001`).
    pub damper: String,
    /// Its new level ([`DiagnosticStatus::OK`] … [`DiagnosticStatus::STALE`]).
    pub level: u8,
    /// When \[s, the caller's clock\].
    pub at_s: f64,
    /// Why, in words.
    pub reason: String,
}

/// What the centre knows of one damper.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Watched {
    /// Outputs received.
    pub outputs: u64,
    /// Diagnostics received.
    pub diagnostics: u64,
    /// When the last output arrived.
    pub last_output_s: Option<f64>,
    /// The worst level of the twin's own last diagnostics (OK before any).
    pub twin_level: u8,
    /// The central level: STALE when silent, else the twin's.
    pub level: u8,
    /// No output for longer than the monitor's `stale_after_s` (the twin's own STALE,
    /// e.g. its sensor stream stopped, is not this).
    pub silent: bool,
    /// Every change, oldest first.
    pub changes: Vec<Change>,
    /// Silence of the STALE periods that ended (last output before to first after) \[s\].
    pub stale_s: f64,
}

/// The central monitor's state of every damper seen.
#[derive(Debug, Clone)]
pub struct FleetMonitor {
    stale_after_s: f64,
    dampers: BTreeMap<String, Watched>,
}

/// `OK`, `WARN`, `ERROR` or `STALE`.
pub fn level_name(level: u8) -> &'static str {
    match level {
        DiagnosticStatus::OK => "OK",
        DiagnosticStatus::WARN => "WARN",
        DiagnosticStatus::ERROR => "ERROR",
        _ => "STALE",
    }
}

impl FleetMonitor {
    /// A damper is STALE after `stale_after_s` without an output.
    pub fn new(stale_after_s: f64) -> Self {
        Self {
            stale_after_s,
            dampers: BTreeMap::new(),
        }
    }

    /// Every damper seen, by key.
    pub fn dampers(&self) -> &BTreeMap<String, Watched> {
        &self.dampers
    }

    fn entry(&mut self, damper: &str) -> &mut Watched {
        self.dampers.entry(damper.to_string()).or_default()
    }

    /// An output of `damper` arrived at `now_s`: a change when it is the first, or ends a
    /// silence.
    pub fn on_output(&mut self, damper: &str, now_s: f64) -> Option<Change> {
        let w = self.entry(damper);
        w.outputs += 1;
        let reason = match w.last_output_s.replace(now_s) {
            None => "first output".to_string(),
            Some(last) if w.silent => {
                w.silent = false;
                w.stale_s += now_s - last;
                format!("outputs again after {:.1} s", now_s - last)
            }
            Some(_) => return None,
        };
        Some(set_level(damper, w, w.twin_level, now_s, reason))
    }

    /// Diagnostics of `damper` arrived: its twin's own level, taken unless the damper is
    /// silent.
    pub fn on_diagnostics(
        &mut self,
        damper: &str,
        array: &DiagnosticArray,
        now_s: f64,
    ) -> Option<Change> {
        let w = self.entry(damper);
        w.diagnostics += 1;
        let worst = array.status.iter().max_by_key(|s| s.level);
        w.twin_level = worst.map_or(DiagnosticStatus::OK, |s| s.level);
        if w.silent || w.level == w.twin_level {
            return None;
        }
        let reason = worst.map_or(String::new(), |s| format!("{}: {}", s.name, s.message));
        Some(set_level(damper, w, w.twin_level, now_s, reason))
    }

    /// The dampers that went STALE by `now_s`.
    pub fn tick(&mut self, now_s: f64) -> Vec<Change> {
        let after = self.stale_after_s;
        let mut changes = Vec::new();
        for (damper, w) in &mut self.dampers {
            let Some(last) = w.last_output_s else {
                continue;
            };
            if !w.silent && now_s - last > after {
                w.silent = true;
                let reason = format!("no output for {:.1} s", now_s - last);
                changes.push(set_level(damper, w, DiagnosticStatus::STALE, now_s, reason));
            }
        }
        changes
    }
}

fn set_level(damper: &str, w: &mut Watched, level: u8, at_s: f64, reason: String) -> Change {
    w.level = level;
    let c = Change {
        damper: damper.to_string(),
        level,
        at_s,
        reason,
    };
    w.changes.push(c.clone());
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diag(level: u8) -> DiagnosticArray {
        DiagnosticArray {
            status: vec![DiagnosticStatus {
                level,
                name: "/fleet/d001/mrtwin_twin: residual".into(),
                message: "high".into(),
                ..Default::default()
            }],
            ..Default::default()
        }
    }

    #[test]
    fn silence_is_stale_and_outputs_bring_back_the_twins_own_level() {
        let mut m = FleetMonitor::new(1.0);
        // The twin's own STALE (no sample yet) is its level, not a silence of its outputs.
        let own = m
            .on_diagnostics("siteA/d001", &diag(DiagnosticStatus::STALE), 0.0)
            .unwrap();
        assert_eq!(own.level, DiagnosticStatus::STALE);
        assert_eq!(
            m.on_diagnostics("siteA/d001", &diag(DiagnosticStatus::OK), 0.0)
                .map(|c| c.level),
            Some(DiagnosticStatus::OK)
        );
        let first = m.on_output("siteA/d001", 0.0).unwrap();
        assert_eq!((first.level, first.reason.as_str()), (0, "first output"));
        assert_eq!(m.on_output("siteA/d001", 0.5), None);
        let warn = m
            .on_diagnostics("siteA/d001", &diag(DiagnosticStatus::WARN), 0.6)
            .unwrap();
        assert_eq!(warn.level, DiagnosticStatus::WARN);
        assert!(m.tick(1.4).is_empty(), "0.9 s of silence is not stale");
        let stale = m.tick(1.6);
        assert_eq!(stale.len(), 1);
        assert_eq!(stale[0].level, DiagnosticStatus::STALE);
        assert!(stale[0].reason.contains("1.1 s"), "{}", stale[0].reason);
        assert!(m.tick(3.0).is_empty(), "reported once");
        // Diagnostics alone do not end a silence of the outputs.
        assert_eq!(
            m.on_diagnostics("siteA/d001", &diag(DiagnosticStatus::OK), 3.5),
            None
        );
        let back = m.on_output("siteA/d001", 4.0).unwrap();
        assert_eq!(back.level, DiagnosticStatus::OK, "the twin's last level");
        assert!(back.reason.contains("3.5 s"), "{}", back.reason);
        let w = &m.dampers()["siteA/d001"];
        assert_eq!((w.outputs, w.diagnostics, w.changes.len()), (3, 4, 6));
        assert!((w.stale_s - 3.5).abs() < 1e-12);
        assert_eq!(level_name(w.changes[4].level), "STALE");
        assert!(!w.silent);
    }
}
