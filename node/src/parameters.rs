//! A node's settings as ROS 2 parameters (`ros2 param list|get|set|describe`, rclpy's
//! `AsyncParameterClient`), served by the ROS 2 adapter ([`bridge::params::ParamService`]):
//! the twin's ([`TwinParameters`]) and the stand's ([`crate::stand::StandParameters`]), by
//! one path.
//!
//! - **Names** are the parameter file's keys, dotted: `health.residual_warn_sigma`,
//!   `estimator.settings.forgetting_factor`, `two_chamber.bulk_modulus_pa`,
//!   `two_chamber.fluid.yield_stress_pa`, `model`, `effects`, `currents_a`,
//!   `faults.drop_probability`, … Every key that can change while the node runs is
//!   declared. The restart-only keys ([`ServedSettings::RESTART_ONLY`]: the damper, the
//!   transports, the middleware settings, …) are not.
//! - **Types:** numbers are `double` (counts are `integer`), lists of numbers
//!   `double_array`, names `string`, switches `bool`. A set of another type is refused by
//!   the parameter store.
//! - **A set** builds the whole parameter set with the new value and checks it as a
//!   reloaded parameter file is checked ([`ServedSettings::check`]: validation, the model
//!   and its effects built), plus: a number must be finite. A bad value is refused with
//!   the reason and nothing changes. An accepted one is taken by the node's loop before
//!   it steps its next sample (the twin: [`crate::core::TwinCore::reload`], the estimator
//!   keeps its state when its settings are unchanged, and `/diagnostics` then shows the
//!   new parameter version; the stand: [`crate::stand::StandPlayer::retune`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use bridge::params::{ParamService, ParamValue};
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_norway::{Number, Value};

use crate::config::TwinNodeParams;
use crate::pipeline::TwinPipeline;

/// A node's parameter set as served: its restart-only keys, and the check a whole set
/// passes before it is taken.
pub trait ServedSettings: Serialize + DeserializeOwned + Clone + PartialEq + Send {
    /// Top-level keys that take effect only at a restart: not served.
    const RESTART_ONLY: &'static [&'static str];
    /// Would the node take this parameter set? `Err`: why not.
    fn check(&self) -> Result<(), String>;
}

impl ServedSettings for TwinNodeParams {
    const RESTART_ONLY: &'static [&'static str] = &[
        "damper",
        "transports",
        "input",
        "control_service",
        "low_latency",
        "zenoh",
        "ros2",
        "iceoryx2",
    ];

    /// Validated, and its pipeline (model, effects, estimator) built.
    fn check(&self) -> Result<(), String> {
        let cfg = self.pipeline_config().map_err(|e| e.to_string())?;
        TwinPipeline::new(cfg).map_err(|e| e.to_string())?;
        Ok(())
    }
}

/// The twin node's served parameters (the stand's: [`crate::stand::StandParameters`]).
pub type TwinParameters = Served<TwinNodeParams>;

/// A node's parameters, shared by the ROS 2 adapter (which checks and sets) and the
/// node's loop (which takes what was set).
pub struct Served<P> {
    /// The parameter set with every accepted value.
    current: Mutex<P>,
    /// Set since the loop last took it.
    pending: AtomicBool,
}

impl<P: ServedSettings> Served<P> {
    /// Serve `params`.
    pub fn new(params: &P) -> Arc<Self> {
        Arc::new(Self {
            current: Mutex::new(params.clone()),
            pending: AtomicBool::new(false),
        })
    }

    fn lock(&self) -> MutexGuard<'_, P> {
        self.current.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The parameter set after a set the loop has not taken yet (one atomic load when
    /// there is none).
    pub fn take_pending(&self) -> Option<P> {
        (self.pending.load(Ordering::Acquire) && self.pending.swap(false, Ordering::AcqRel))
            .then(|| self.lock().clone())
    }

    /// The node took parameters from elsewhere (a reloaded file): later sets start from
    /// them.
    pub fn taken(&self, params: &P) {
        *self.lock() = params.clone();
    }
}

impl<P: ServedSettings> ParamService for Served<P> {
    fn declared(&self) -> Vec<(String, ParamValue)> {
        declared(&*self.lock())
    }

    fn check(&self, name: &str, value: &ParamValue) -> Result<(), String> {
        with_value(&*self.lock(), name, value).map(|_| ())
    }

    /// A value equal to the present one changes nothing (the parameter store sets every
    /// declared value once when the node starts).
    fn set(&self, name: &str, value: &ParamValue) -> Result<(), String> {
        let mut current = self.lock();
        let new = with_value(&*current, name, value)?;
        if new != *current {
            *current = new;
            self.pending.store(true, Ordering::Release);
        }
        Ok(())
    }
}

/// Every parameter of `params` that can change while the node runs, with its value.
pub fn declared<P: ServedSettings>(params: &P) -> Vec<(String, ParamValue)> {
    let mut out = Vec::new();
    if let Ok(Value::Mapping(m)) = serde_norway::to_value(params) {
        for (k, v) in &m {
            match k.as_str() {
                Some(k) if !P::RESTART_ONLY.contains(&k) => flatten(k, v, &mut out),
                _ => {}
            }
        }
    }
    out
}

fn flatten(name: &str, v: &Value, out: &mut Vec<(String, ParamValue)>) {
    match v {
        Value::Mapping(m) => {
            for (k, v) in m {
                if let Some(k) = k.as_str() {
                    flatten(&format!("{name}.{k}"), v, out);
                }
            }
        }
        other => {
            if let Some(p) = leaf(other) {
                out.push((name.to_string(), p));
            }
        }
    }
}

/// A leaf value as a parameter (empty lists and lists of records are not served: their
/// element type is unknown or not a parameter type).
fn leaf(v: &Value) -> Option<ParamValue> {
    Some(match v {
        Value::Bool(b) => ParamValue::Bool(*b),
        Value::Number(n) if n.is_f64() => ParamValue::Double(n.as_f64()?),
        Value::Number(n) => ParamValue::Integer(n.as_i64()?),
        Value::String(s) => ParamValue::Text(s.clone()),
        Value::Sequence(items) if !items.is_empty() => {
            if let Some(x) = items.iter().map(|i| i.as_f64()).collect::<Option<Vec<_>>>() {
                ParamValue::Doubles(x)
            } else {
                ParamValue::Texts(
                    items
                        .iter()
                        .map(|i| i.as_str().map(str::to_string))
                        .collect::<Option<Vec<_>>>()?,
                )
            }
        }
        _ => return None,
    })
}

fn to_yaml(v: &ParamValue) -> Result<Value, String> {
    let number = |x: f64| {
        if x.is_finite() {
            Ok(Value::Number(Number::from(x)))
        } else {
            Err(format!("must be a finite number, got {x}"))
        }
    };
    Ok(match v {
        ParamValue::Bool(b) => Value::Bool(*b),
        ParamValue::Integer(i) => Value::Number(Number::from(*i)),
        ParamValue::Double(x) => number(*x)?,
        ParamValue::Text(s) => Value::String(s.clone()),
        ParamValue::Doubles(x) => {
            Value::Sequence(x.iter().map(|x| number(*x)).collect::<Result<_, _>>()?)
        }
        ParamValue::Texts(s) => Value::Sequence(s.iter().cloned().map(Value::String).collect()),
    })
}

/// `params` with parameter `name` set to `value`, checked as a reloaded file is; `Err`:
/// the reason, naming the parameter.
pub fn with_value<P: ServedSettings>(
    params: &P,
    name: &str,
    value: &ParamValue,
) -> Result<P, String> {
    let reason = |e: String| {
        if e.contains(&format!("'{name}'")) {
            e
        } else {
            format!("parameter '{name}': {e}")
        }
    };
    let top = name.split('.').next().unwrap_or_default();
    if P::RESTART_ONLY.contains(&top) {
        return Err(reason("takes effect only at a restart".into()));
    }
    let mut tree = serde_norway::to_value(params).map_err(|e| reason(e.to_string()))?;
    let mut at = &mut tree;
    for key in name.split('.') {
        at = match at {
            Value::Mapping(m) => m
                .get_mut(key)
                .ok_or_else(|| reason("no such parameter".into()))?,
            _ => return Err(reason("no such parameter".into())),
        };
    }
    if matches!(at, Value::Mapping(_)) {
        return Err(reason("is a section, not a parameter".into()));
    }
    *at = to_yaml(value).map_err(reason)?;
    let new: P = serde_norway::from_value(tree).map_err(|e| reason(e.to_string()))?;
    new.check().map_err(reason)?;
    Ok(new)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stand::{StandParameters, StandParams};

    fn find<'a>(d: &'a [(String, ParamValue)], name: &str) -> Option<&'a ParamValue> {
        d.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    #[test]
    fn the_runtime_keys_are_declared_with_their_types_and_the_restart_only_ones_are_not() {
        let p = TwinNodeParams::default();
        let d = declared(&p);
        assert_eq!(
            find(&d, "two_chamber.bulk_modulus_pa"),
            Some(&ParamValue::Double(p.two_chamber.bulk_modulus_pa))
        );
        assert_eq!(
            find(&d, "two_chamber.fluid.yield_stress_pa"),
            Some(&ParamValue::Doubles(
                p.two_chamber.fluid.yield_stress_pa.to_vec()
            ))
        );
        assert_eq!(
            find(&d, "model"),
            Some(&ParamValue::Text("two-chamber".into()))
        );
        assert!(matches!(
            find(&d, "estimator.enabled"),
            Some(ParamValue::Bool(true))
        ));
        assert!(d.iter().any(|(n, _)| n.starts_with("health.")));
        assert!(d.iter().any(|(n, _)| n.starts_with("estimator.settings.")));
        for (n, _) in &d {
            let top = n.split('.').next().unwrap();
            assert!(
                !TwinNodeParams::RESTART_ONLY.contains(&top),
                "{n} is restart-only"
            );
        }
    }

    #[test]
    fn a_good_value_changes_only_its_key_and_a_bad_one_is_refused_with_its_reason() {
        let p = TwinNodeParams::default();
        let q = with_value(&p, "two_chamber.bulk_modulus_pa", &ParamValue::Double(7e8)).unwrap();
        assert_eq!(q.two_chamber.bulk_modulus_pa, 7e8);
        assert_eq!(
            TwinNodeParams {
                two_chamber: p.two_chamber.clone(),
                ..q.clone()
            },
            p
        );
        for (name, value, says) in [
            ("stale_after_s", ParamValue::Double(-1.0), "positive"),
            ("stale_after_s", ParamValue::Double(f64::NAN), "finite"),
            (
                "effects",
                ParamValue::Text("warp_drive".into()),
                "warp_drive",
            ),
            ("model", ParamValue::Text("magic".into()), "magic"),
            ("damper", ParamValue::Text("other".into()), "restart"),
            (
                "two_chamber.no_such_key",
                ParamValue::Double(1.0),
                "no such parameter",
            ),
            ("two_chamber.fluid", ParamValue::Double(1.0), "section"),
        ] {
            let e = with_value(&p, name, &value).unwrap_err();
            assert!(e.contains(name) && e.contains(says), "{name}: {e}");
        }
    }

    #[test]
    fn a_set_is_pending_once_and_a_refused_one_changes_nothing() {
        let p = TwinNodeParams::default();
        let s = TwinParameters::new(&p);
        s.set("stale_after_s", &ParamValue::Double(p.stale_after_s))
            .unwrap();
        assert!(s.take_pending().is_none(), "the same value is no change");
        assert!(s.set("stale_after_s", &ParamValue::Double(-2.0)).is_err());
        assert!(s.take_pending().is_none());
        s.set("stale_after_s", &ParamValue::Double(2.0)).unwrap();
        assert_eq!(s.take_pending().map(|q| q.stale_after_s), Some(2.0));
        assert!(s.take_pending().is_none());
        assert_eq!(
            find(&s.declared(), "stale_after_s"),
            Some(&ParamValue::Double(2.0))
        );
    }

    #[test]
    fn the_stand_serves_its_programme_model_and_faults_but_not_its_pacing() {
        let p = StandParams::default();
        let d = declared(&p);
        assert_eq!(
            find(&d, "currents_a"),
            Some(&ParamValue::Doubles(p.currents_a.clone()))
        );
        assert!(find(&d, "faults.drop_probability").is_some());
        assert!(find(&d, "two_chamber.bulk_modulus_pa").is_some());
        for restart_only in ["rate_hz", "seed", "damper", "transports"] {
            assert!(find(&d, restart_only).is_none(), "{restart_only} served");
            assert!(with_value(&p, restart_only, &ParamValue::Double(1.0))
                .unwrap_err()
                .contains("restart"));
        }
        let e = with_value(&p, "noise_n", &ParamValue::Double(-1.0)).unwrap_err();
        assert!(e.contains("noise_n") && e.contains("≥ 0"), "{e}");
        let e = with_value(&p, "model", &ParamValue::Text("magic".into())).unwrap_err();
        assert!(e.contains("magic"), "{e}");
        let s = StandParameters::new(&p);
        s.set("currents_a", &ParamValue::Doubles(vec![1.75]))
            .unwrap();
        assert_eq!(s.take_pending().map(|q| q.currents_a), Some(vec![1.75]));
    }
}
