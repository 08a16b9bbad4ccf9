//! Plain-data payloads for iceoryx2 shared memory: `#[repr(C)]`, no pointers, fixed size,
//! so a local controller reads them in place (zero copy). With the `iceoryx2` feature they
//! derive `ZeroCopySend` with a stable type name, which iceoryx2 checks on both sides.

#[cfg(feature = "iceoryx2")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "iceoryx2")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// A sensor sample (publish–subscribe input of the twin).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(
    feature = "iceoryx2",
    derive(ZeroCopySend),
    type_name("mrtwin::ShmSample")
)]
pub struct ShmSample {
    /// Sequence number given by the sender.
    pub seq: u64,
    /// Measurement time \[ns\].
    pub time_ns: i64,
    /// Displacement \[m\].
    pub displacement_m: f64,
    /// Velocity \[m/s\].
    pub velocity_m_s: f64,
    /// Measured force \[N\].
    pub force_n: f64,
    /// Coil current \[A\].
    pub current_a: f64,
    /// Temperature \[°C\] (NaN when not measured).
    pub temperature_c: f64,
}

/// The twin's output for one sample (publish–subscribe output, and the reply of the
/// request–response service).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(
    feature = "iceoryx2",
    derive(ZeroCopySend),
    type_name("mrtwin::ShmPrediction")
)]
pub struct ShmPrediction {
    /// Sequence number of the request or sample this answers.
    pub seq: u64,
    /// Time of the sample \[ns\].
    pub time_ns: i64,
    /// Predicted force \[N\].
    pub predicted_force_n: f64,
    /// Measured − predicted \[N\] (NaN for a planned-current query).
    pub residual_n: f64,
    /// Yield stress estimate at the present current \[Pa\] (NaN when none yet).
    pub tau0_pa: f64,
    /// Its standard deviation \[Pa\].
    pub tau0_std_pa: f64,
    /// 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    pub health_level: u8,
    /// 1 when the request was rejected (bad numbers, time going back); the force is NaN.
    pub rejected: u8,
    /// In a control reply: 1 when the twin's loop sleeps between requests, so a client
    /// must notify the control service's wake-up event after each request (mrtwin's
    /// `ControlClient` does); 0 when it polls (`low_latency`). 0 on the prediction topic.
    pub server_sleeps: u8,
    /// Padding, zero.
    pub reserved: [u8; 5],
}

/// What a controller asks the twin over the request–response service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(
    feature = "iceoryx2",
    derive(ZeroCopySend),
    type_name("mrtwin::ShmRequest")
)]
pub struct ShmRequest {
    /// [`ShmRequest::SAMPLE`] or [`ShmRequest::PLANNED_CURRENT`].
    pub kind: u32,
    /// Padding, zero.
    pub reserved: u32,
    /// The sample (for a planned current, `current_a` is the plan and `force_n` is ignored).
    pub sample: ShmSample,
}

impl ShmRequest {
    /// A measured sample: the twin steps its state with it and answers the prediction.
    pub const SAMPLE: u32 = 0;
    /// A what-if: the force the damper would give at this state with the planned current,
    /// computed on a copy of the twin's state (the twin itself does not advance).
    pub const PLANNED_CURRENT: u32 = 1;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_are_plain_fixed_size() {
        assert_eq!(std::mem::size_of::<ShmSample>(), 56);
        assert_eq!(std::mem::size_of::<ShmPrediction>(), 56);
        assert_eq!(std::mem::size_of::<ShmRequest>(), 64);
        assert_eq!(std::mem::align_of::<ShmRequest>(), 8);
    }
}
