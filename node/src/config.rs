//! The nodes' parameters, in the ROS 2 `ros__parameters` convention (read with the
//! `launch-config` crate: unknown keys and wrong types are errors naming file, key and line).
//!
//! ```yaml
//! mrtwin_twin:
//!   ros__parameters:
//!     damper: damper            # names the hardware: zenoh keys, frame_id, hardware_id
//!     model: two-chamber
//!     effects: fluid_compressibility,gas_spring
//!     transports: [ros2, zenoh, iceoryx2]
//!     input: zenoh              # the transport the sensor samples come in on
//!     two_chamber: { bulk_modulus_pa: 5.0e8 }
//!     estimator: { memory_s: 1.0 }
//!     health: { residual: { warn: 0.05, error: 0.15 } }
//!     zenoh: { multicast_scouting: true }
//! ```

use serde::{Deserialize, Serialize};
use twin::models::{
    BinghamParams, DirectShearParams, FluidParams, ModelKind, ModelParams, SpencerParams,
    TwoChamberParams, MAX_CURRENT_COEFFS,
};
use twin::EffectsChoice;

use crate::conditioning::ConditioningConfig;
use crate::transports::TransportKind;

/// Default node name of the twin.
pub const TWIN_NODE: &str = "mrtwin_twin";
/// Default node name of the stand.
pub const STAND_NODE: &str = "mrtwin_stand";

/// Parameters of the twin node (`mrtwin node`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TwinNodeParams {
    /// Damper name.
    pub damper: String,
    /// Model: bingham, spencer, direct-shear, two-chamber.
    pub model: ModelKind,
    /// Effects of the two-chamber model, comma separated ids, `paper`, `all` or `none`;
    /// empty: the model's defaults.
    pub effects: EffectsChoice,
    /// Ambient temperature when samples carry none \[°C\].
    pub ambient_temperature_c: f64,
    /// Transports to publish on.
    pub transports: Vec<TransportKind>,
    /// Transport the samples arrive on.
    pub input: TransportKind,
    /// Period of `/diagnostics` \[s\].
    pub diagnostics_period_s: f64,
    /// Period of the yield-estimate topic \[s\].
    pub yield_estimate_period_s: f64,
    /// Sensor silence after which health goes STALE \[s\] (wall clock).
    pub stale_after_s: f64,
    /// Serve the iceoryx2 request–response control service.
    pub control_service: bool,
    /// Poll the transports without sleeping while samples flow (yielding the core between
    /// polls; after 2 ms of quiet the loop sleeps as without it): the lowest latency, one
    /// core busy while samples flow. Off (default): the loop sleeps until a transport's
    /// wake-up or its next deadline. Read at start.
    pub low_latency: bool,
    /// Sample conditioning.
    pub conditioning: ConditioningConfig,
    /// Estimator; `enabled: false` switches it off.
    pub estimator: EstimatorSection,
    /// Health thresholds.
    pub health: estimation::health::HealthConfig,
    /// `bingham` parameters.
    pub bingham: BinghamParams,
    /// `spencer` parameters.
    pub spencer: SpencerParams,
    /// `direct-shear` parameters.
    pub direct_shear: DirectShearParams,
    /// `two-chamber` parameters.
    pub two_chamber: TwoChamberParams,
    /// Transport settings.
    pub zenoh: bridge::zenoh::ZenohConfig,
    /// ROS 2 settings.
    pub ros2: bridge::ros2::Ros2Config,
    /// iceoryx2 settings.
    pub iceoryx2: bridge::iceoryx2::Iceoryx2Config,
}

/// The estimator section: on/off plus the estimator's own settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorSection {
    /// Estimate τ0(I) online.
    pub enabled: bool,
    /// Settings.
    pub settings: estimation::online::EstimatorConfig,
}

impl Default for EstimatorSection {
    fn default() -> Self {
        Self {
            enabled: true,
            settings: Default::default(),
        }
    }
}

impl Default for TwinNodeParams {
    fn default() -> Self {
        Self {
            damper: "damper".into(),
            model: ModelKind::TwoChamber,
            effects: EffectsChoice::ModelDefault,
            ambient_temperature_c: 25.0,
            transports: vec![
                TransportKind::Ros2,
                TransportKind::Zenoh,
                TransportKind::Iceoryx2,
            ],
            input: TransportKind::Zenoh,
            diagnostics_period_s: 1.0,
            yield_estimate_period_s: 0.1,
            stale_after_s: 0.5,
            control_service: true,
            low_latency: false,
            conditioning: Default::default(),
            estimator: Default::default(),
            health: Default::default(),
            bingham: Default::default(),
            spencer: Default::default(),
            direct_shear: Default::default(),
            two_chamber: Default::default(),
            zenoh: Default::default(),
            ros2: Default::default(),
            iceoryx2: Default::default(),
        }
    }
}

/// A parameter that parsed but makes no sense.
#[derive(Debug, thiserror::Error)]
#[error("parameter '{key}': {reason}")]
pub struct InvalidParam {
    /// Dotted key.
    pub key: &'static str,
    /// Why.
    pub reason: String,
}

/// The two-chamber fluid's laws in current (`yield_stress_pa`, `viscosity_pa_s`): 1 to
/// [`MAX_CURRENT_COEFFS`] finite coefficients each. Checked for the twin and the stand.
pub(crate) fn check_laws_in_current(fluid: &FluidParams) -> Result<(), InvalidParam> {
    for (key, c) in [
        ("two_chamber.fluid.yield_stress_pa", &fluid.yield_stress_pa),
        ("two_chamber.fluid.viscosity_pa_s", &fluid.viscosity_pa_s),
    ] {
        if c.is_empty() || c.len() > MAX_CURRENT_COEFFS || !c.iter().all(|v| v.is_finite()) {
            return Err(InvalidParam {
                key,
                reason: format!(
                    "must be 1 to {MAX_CURRENT_COEFFS} finite coefficients \
                     (c0 + c1 |I| + c2 I² + …), got {c:?}"
                ),
            });
        }
    }
    Ok(())
}

impl TwinNodeParams {
    /// The transport settings of node `node_fqn` (the twin, or a tool speaking for it:
    /// replay, record) with these parameters.
    pub fn transport_settings(&self, node_fqn: &str) -> crate::transports::TransportSettings {
        crate::transports::TransportSettings::new(
            &self.damper,
            node_fqn,
            &self.ros2,
            &self.zenoh,
            &self.iceoryx2,
        )
    }

    /// The model parameters of the four sections.
    pub fn model_params(&self) -> ModelParams {
        ModelParams {
            bingham: self.bingham.clone(),
            spencer: self.spencer.clone(),
            direct_shear: self.direct_shear.clone(),
            two_chamber: self.two_chamber.clone(),
        }
    }

    /// The pipeline these parameters describe (model, effects, conditioning, estimator,
    /// health): the same for the live node and for replay. Checks the parameters first
    /// ([`TwinNodeParams::validate`]).
    pub fn pipeline_config(&self) -> Result<crate::pipeline::PipelineConfig, InvalidParam> {
        self.validate()?;
        Ok(crate::pipeline::PipelineConfig {
            model: self.model,
            params: self.model_params(),
            effects: self.model.effects(self.effects),
            ambient_temperature_c: self.ambient_temperature_c,
            conditioning: self.conditioning.clone(),
            estimator: self
                .estimator
                .enabled
                .then(|| self.estimator.settings.clone()),
            health: self.health.clone(),
        })
    }

    /// Check what serde cannot: ranges, and keys that must agree with each other (names,
    /// model and effects are parsed and checked when the file is read).
    pub fn validate(&self) -> Result<(), InvalidParam> {
        let positive = |key: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(InvalidParam {
                    key,
                    reason: format!("must be a positive number, got {v}"),
                })
            }
        };
        positive("diagnostics_period_s", self.diagnostics_period_s)?;
        positive("yield_estimate_period_s", self.yield_estimate_period_s)?;
        positive("stale_after_s", self.stale_after_s)?;
        positive("conditioning.max_gap_s", self.conditioning.max_gap_s)?;
        positive(
            "conditioning.driver_gain_a_per_v",
            self.conditioning.driver_gain_a_per_v,
        )?;
        if !(self.conditioning.driver_lag_s >= 0.0 && self.conditioning.driver_lag_s.is_finite()) {
            return Err(InvalidParam {
                key: "conditioning.driver_lag_s",
                reason: format!(
                    "must be a number >= 0, got {}",
                    self.conditioning.driver_lag_s
                ),
            });
        }
        let non_negative = |key: &'static str, v: f64| {
            if v >= 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(InvalidParam {
                    key,
                    reason: format!("must be a number >= 0, got {v}"),
                })
            }
        };
        let fluid = &self.two_chamber.fluid;
        check_laws_in_current(fluid)?;
        non_negative(
            "conditioning.acceleration_window_s",
            self.conditioning.acceleration_window_s,
        )?;
        non_negative("two_chamber.fluid.pre_yield_leak", fluid.pre_yield_leak)?;
        non_negative("two_chamber.fluid.current_range_a", fluid.current_range_a)?;
        non_negative("two_chamber.fluid.yield_step_share", fluid.yield_step_share)?;
        positive(
            "two_chamber.fluid.yield_step_velocity_m_s",
            fluid.yield_step_velocity_m_s,
        )?;
        non_negative(
            "estimator.settings.model_form_share",
            self.estimator.settings.model_form_share,
        )?;
        non_negative(
            "estimator.settings.common_offset_share",
            self.estimator.settings.common_offset_share,
        )?;
        if self.conditioning.stuck_samples < 2 {
            return Err(InvalidParam {
                key: "conditioning.stuck_samples",
                reason: format!(
                    "must be at least 2, got {}",
                    self.conditioning.stuck_samples
                ),
            });
        }
        if self.damper.is_empty() || self.damper.contains(['/', '*', '$', '?', '#', ' ']) {
            return Err(InvalidParam {
                key: "damper",
                reason: format!(
                    "'{}' must be a non-empty name without / * $ ? # or spaces",
                    self.damper
                ),
            });
        }
        if !self.transports.contains(&self.input) {
            return Err(InvalidParam {
                key: "input",
                reason: format!(
                    "'{}' is not among transports {:?}",
                    self.input, self.transports
                ),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(body: &str) -> Result<TwinNodeParams, launch_config::ConfigError> {
        launch_config::parse_params(
            &format!("{TWIN_NODE}:\n  ros__parameters:\n{body}"),
            "twin.yaml",
            TWIN_NODE,
        )
    }

    #[test]
    fn names_are_parsed_when_the_file_is_read() {
        let p = parse(
            "    model: bingham\n    effects: none\n    zenoh: {mode: client}\n    ros2:\n      namespace: rig/\n      qos: {/diagnostics: {depth: 5}}\n",
        )
        .unwrap();
        assert_eq!(p.model, ModelKind::Bingham);
        assert_eq!(p.effects, EffectsChoice::List(twin::EffectSet::NONE));
        assert_eq!(p.zenoh.mode, bridge::zenoh::ZenohMode::Client);
        assert_eq!(p.ros2.namespace.as_str(), "/rig");
        assert_eq!(p.ros2.qos_of(bridge::transport::Topic::Diagnostics).1, 5);
        let p = parse("    effects: all\n").unwrap();
        let cfg = p.pipeline_config().unwrap();
        assert_eq!(
            (cfg.model, cfg.effects),
            (ModelKind::TwoChamber, twin::EffectSet::all())
        );
        let cfg = TwinNodeParams::default().pipeline_config().unwrap();
        assert_eq!(cfg.effects, twin::EffectSet::paper());
    }

    #[test]
    fn a_bad_name_is_reported_with_file_key_line_and_the_valid_names() {
        for (body, at, wanted) in [
            (
                "    model: bouc-wen\n",
                "twin.yaml line 3, key model:",
                &["'bouc-wen'", "bingham", "two-chamber"][..],
            ),
            (
                "    effects: gas_spring,magic\n",
                "twin.yaml line 3, key effects:",
                &["'magic'", "seal_friction"],
            ),
            (
                "    zenoh:\n      mode: router\n",
                "twin.yaml line 4, key zenoh.mode:",
                &["router", "peer", "client"],
            ),
            (
                "    ros2:\n      qos:\n        twin/nothing: {depth: 1}\n",
                "twin.yaml line 5, key ros2.qos.twin/nothing:",
                &["sensor/sample", "diagnostics"],
            ),
            (
                "    ros2:\n      namespace: a b\n",
                "twin.yaml line 4, key ros2.namespace:",
                &["\"a b\""],
            ),
            (
                "    transports: [zenoh, dds]\n",
                "twin.yaml line 3, key transports[1]:",
                &["dds", "ros2", "iceoryx2"],
            ),
        ] {
            let e = parse(body).unwrap_err().to_string();
            assert!(e.starts_with(at), "{e}");
            for w in wanted {
                assert!(e.contains(w), "{w} not in: {e}");
            }
        }
    }

    #[test]
    fn a_negative_yield_step_or_a_zero_step_velocity_is_refused_by_its_key() {
        let p = parse("    two_chamber:\n      fluid:\n        yield_step_share: -0.1\n").unwrap();
        let e = p.validate().unwrap_err();
        assert_eq!(e.key, "two_chamber.fluid.yield_step_share");
        let p =
            parse("    two_chamber:\n      fluid:\n        yield_step_velocity_m_s: 0\n").unwrap();
        let e = p.validate().unwrap_err();
        assert_eq!(e.key, "two_chamber.fluid.yield_step_velocity_m_s");
        let p = parse("    two_chamber:\n      fluid:\n        yield_step_share: 0.2\n").unwrap();
        p.validate().unwrap();
        assert_eq!(p.two_chamber.fluid.yield_step_share, 0.2);
    }

    #[test]
    fn a_negative_or_nan_model_form_share_is_refused_by_its_key() {
        for bad in ["-0.5", ".nan"] {
            let p = parse(&format!(
                "    estimator:\n      settings:\n        model_form_share: {bad}\n"
            ))
            .unwrap();
            let e = p.validate().unwrap_err();
            assert_eq!(e.key, "estimator.settings.model_form_share");
        }
        let p = parse("    estimator:\n      settings:\n        model_form_share: 0.5\n").unwrap();
        p.validate().unwrap();
        assert_eq!(p.estimator.settings.model_form_share, 0.5);
    }

    #[test]
    fn laws_in_current_take_one_to_five_finite_coefficients_and_a_range_of_at_least_zero() {
        let fluid = |body: &str| parse(&format!("    two_chamber:\n      fluid:\n{body}")).unwrap();
        for (body, key) in [
            (
                "        yield_stress_pa: [1, 2, 3, 4, 5, 6]\n",
                "two_chamber.fluid.yield_stress_pa",
            ),
            (
                "        viscosity_pa_s: []\n",
                "two_chamber.fluid.viscosity_pa_s",
            ),
            (
                "        viscosity_pa_s: [0.1, .nan]\n",
                "two_chamber.fluid.viscosity_pa_s",
            ),
            (
                "        current_range_a: -1.0\n",
                "two_chamber.fluid.current_range_a",
            ),
        ] {
            let e = fluid(body).validate().unwrap_err();
            assert_eq!(e.key, key, "{body}");
        }
        let p = fluid("        yield_stress_pa: [1, 2, 3, 4, 5]\n        current_range_a: 1.0\n");
        p.validate().unwrap();
        assert_eq!(
            p.two_chamber.fluid.yield_stress_pa,
            [1.0, 2.0, 3.0, 4.0, 5.0]
        );
        fluid("        yield_stress_pa: [4000]\n")
            .validate()
            .unwrap();
    }

    #[test]
    fn a_negative_pre_yield_leak_is_refused_by_its_key() {
        let p = parse("    two_chamber:\n      fluid:\n        pre_yield_leak: -0.01\n").unwrap();
        let e = p.pipeline_config().unwrap_err();
        assert_eq!(e.key, "two_chamber.fluid.pre_yield_leak");
        assert!(e.reason.contains("-0.01"), "{}", e.reason);
        let p = parse("    two_chamber:\n      fluid:\n        pre_yield_leak: 0.05\n").unwrap();
        assert_eq!(
            p.pipeline_config()
                .unwrap()
                .params
                .two_chamber
                .fluid
                .pre_yield_leak,
            0.05
        );
    }
}
