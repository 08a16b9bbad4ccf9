//! A control-service handler around a real twin model, shared by the iceoryx2 loop test
//! and benchmark (the node crate has the production one).
//!
//! * SAMPLE: step the model to the sample's instant (dt from the previous sample,
//!   acceleration by finite difference) and answer its force; residual = measured −
//!   predicted (NaN when the sample carries no force).
//! * PLANNED_CURRENT: step a copy of the model (`DamperModel::clone_box`) with the planned
//!   current over one sample period past the last sample (or up to the request time if
//!   later) and answer that force; the twin itself does not advance.
//! * Non-finite kinematics or current, or time going back: rejected.

#![allow(dead_code)]

use msgs::shm::{ShmPrediction, ShmRequest, ShmSample};
use twin::effects::EffectSet;
use twin::model::{DamperInput, DamperModel};
use twin::models::{build, ModelKind, ModelParams};

/// Ambient temperature when a sample has none \[°C\].
const AMBIENT_C: f64 = 20.0;

pub struct TwinHandler {
    model: Box<dyn DamperModel>,
    last: Option<(i64, DamperInput)>,
    period_s: f64,
    pub steps: u64,
    pub what_ifs: u64,
}

impl TwinHandler {
    /// The paper's two-chamber model (compressibility + gas spring), default parameters.
    pub fn paper() -> Self {
        let model = build(
            ModelKind::TwoChamber,
            &ModelParams::default(),
            EffectSet::paper(),
        )
        .expect("two-chamber takes the paper's effects");
        Self {
            model,
            last: None,
            period_s: 1e-3,
            steps: 0,
            what_ifs: 0,
        }
    }

    fn input(s: &ShmSample, accel: f64) -> DamperInput {
        DamperInput {
            displacement_m: s.displacement_m,
            velocity_m_s: s.velocity_m_s,
            acceleration_m_s2: accel,
            current_a: s.current_a,
            ambient_temperature_c: if s.temperature_c.is_finite() {
                s.temperature_c
            } else {
                AMBIENT_C
            },
        }
    }

    pub fn handle(&mut self, req: &ShmRequest) -> ShmPrediction {
        let s = &req.sample;
        let finite =
            s.displacement_m.is_finite() && s.velocity_m_s.is_finite() && s.current_a.is_finite();
        let back_in_time = self.last.is_some_and(|(t, _)| {
            if req.kind == ShmRequest::SAMPLE {
                s.time_ns <= t
            } else {
                s.time_ns < t
            }
        });
        if !finite || back_in_time || req.kind > ShmRequest::PLANNED_CURRENT {
            return bridge::iceoryx2::rejected_reply(req);
        }
        let force = if req.kind == ShmRequest::SAMPLE {
            let (dt, accel) = match self.last {
                Some((t, prev)) => {
                    let dt = (s.time_ns - t) as f64 * 1e-9;
                    (dt, (s.velocity_m_s - prev.velocity_m_s) / dt)
                }
                None => (0.0, 0.0),
            };
            let input = Self::input(s, accel);
            let out = self.model.step(&input, dt);
            if dt > 0.0 {
                self.period_s = dt;
            }
            self.last = Some((s.time_ns, input));
            self.steps += 1;
            out.force_n
        } else {
            let mut copy = self.model.clone_box();
            let dt = match self.last {
                Some((t, _)) => ((s.time_ns - t) as f64 * 1e-9).max(self.period_s),
                None => 0.0,
            };
            self.what_ifs += 1;
            copy.step(&Self::input(s, 0.0), dt).force_n
        };
        ShmPrediction {
            seq: s.seq,
            time_ns: s.time_ns,
            predicted_force_n: force,
            residual_n: if req.kind == ShmRequest::SAMPLE {
                s.force_n - force
            } else {
                f64::NAN
            },
            tau0_pa: f64::NAN,
            tau0_std_pa: f64::NAN,
            health_level: 0,
            rejected: 0,
            server_sleeps: 0,
            reserved: [0; 5],
        }
    }
}
