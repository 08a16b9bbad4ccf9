//! Generators and checks of CDR decoding (`msgs::cdr::decode`) for every message type of
//! `msgs`: random messages, encoded (a valid input: decode must give them back), then
//! mostly mutated. Every accepted input must re-encode to bytes that decode again to the
//! same encoding.

use msgs::cdr::{decode, encode};
use msgs::{
    Clock, DamperSample, DiagnosticArray, DiagnosticStatus, Float64, Float64MultiArray, Header,
    KeyValue, MultiArrayDimension, MultiArrayLayout, RosMessage, Time, TwinOutput, YieldEstimate,
};

use super::mutate::mutate;
use super::rng::Rng;
use super::{FuzzInput, Parser, Scratch, Verdict};

/// Largest generated message.
const MAX_BYTES: usize = 1024;

/// One CDR parser per message type.
pub fn parsers() -> Vec<Parser> {
    vec![
        cdr_parser::<DamperSample>("cdr-damper-sample"),
        cdr_parser::<TwinOutput>("cdr-twin-output"),
        cdr_parser::<YieldEstimate>("cdr-yield-estimate"),
        cdr_parser::<Float64>("cdr-float64"),
        cdr_parser::<Clock>("cdr-clock"),
        cdr_parser::<DiagnosticArray>("cdr-diagnostic-array"),
        cdr_parser::<Float64MultiArray>("cdr-float64-multi-array"),
    ]
}

fn cdr_parser<T: RandomMessage>(name: &'static str) -> Parser {
    Parser {
        name,
        entry: "msgs::cdr::decode::<T>; accepted → encode → decode round trip",
        generate: generate::<T>,
        check: check::<T>,
    }
}

/// A message type the generator can fill with random content.
pub trait RandomMessage: RosMessage {
    /// A random message.
    fn random(rng: &mut Rng) -> Self;
    /// What runs after a successful decode (conversions that read the fields).
    fn after_decode(&self) {}
}

/// A random string: empty, ASCII, a name, or with multi-byte characters.
fn random_string(rng: &mut Rng) -> String {
    match rng.below(6) {
        0 => String::new(),
        1 => "d1".into(),
        2 => "µ-Ω damper ✓".into(),
        3 => {
            let n = rng.range(1, 24);
            (0..n)
                .map(|_| (b' ' + rng.below(95) as u8) as char)
                .collect()
        }
        4 => "mrtwin: residual".into(),
        _ => format!("damper_{}", rng.below(1000)),
    }
}

fn random_time(rng: &mut Rng) -> Time {
    Time {
        sec: rng.next_u64() as i32,
        nanosec: if rng.one_in(8) {
            rng.next_u64() as u32
        } else {
            rng.below(1_000_000_000) as u32
        },
    }
}

fn random_header(rng: &mut Rng) -> Header {
    Header {
        stamp: random_time(rng),
        frame_id: random_string(rng),
    }
}

fn random_vec<T>(rng: &mut Rng, max: usize, f: impl Fn(&mut Rng) -> T) -> Vec<T> {
    let n = rng.below(max + 1);
    (0..n).map(|_| f(rng)).collect()
}

impl RandomMessage for DamperSample {
    fn random(rng: &mut Rng) -> Self {
        Self {
            header: random_header(rng),
            displacement: rng.any_f64(),
            velocity: rng.any_f64(),
            force: rng.any_f64(),
            current: rng.any_f64(),
            temperature: rng.any_f64(),
        }
    }
}

impl RandomMessage for TwinOutput {
    fn random(rng: &mut Rng) -> Self {
        Self {
            header: random_header(rng),
            predicted_force: rng.any_f64(),
            measured_force: rng.any_f64(),
            residual: rng.any_f64(),
            dissipated_power: rng.any_f64(),
            fluid_temperature: rng.any_f64(),
            model_id: random_string(rng),
            health_level: rng.next_u64() as u8,
        }
    }
}

impl RandomMessage for YieldEstimate {
    fn random(rng: &mut Rng) -> Self {
        Self {
            header: random_header(rng),
            current: rng.any_f64(),
            tau0: rng.any_f64(),
            tau0_std: rng.any_f64(),
            curve_current: random_vec(rng, 6, Rng::any_f64),
            curve_tau0: random_vec(rng, 6, Rng::any_f64),
            curve_tau0_std: random_vec(rng, 6, Rng::any_f64),
        }
    }
}

impl RandomMessage for Float64 {
    fn random(rng: &mut Rng) -> Self {
        Self {
            data: rng.any_f64(),
        }
    }
}

impl RandomMessage for Clock {
    fn random(rng: &mut Rng) -> Self {
        Self {
            clock: random_time(rng),
        }
    }
}

impl RandomMessage for DiagnosticArray {
    fn random(rng: &mut Rng) -> Self {
        Self {
            header: random_header(rng),
            status: random_vec(rng, 3, |rng| DiagnosticStatus {
                level: rng.below(5) as u8,
                name: random_string(rng),
                message: random_string(rng),
                hardware_id: random_string(rng),
                values: random_vec(rng, 3, |rng| {
                    KeyValue::new(random_string(rng), random_string(rng))
                }),
            }),
        }
    }
}

impl RandomMessage for Float64MultiArray {
    fn random(rng: &mut Rng) -> Self {
        let sample = rng.one_in(2);
        Self {
            layout: MultiArrayLayout {
                dim: random_vec(rng, 2, |rng| MultiArrayDimension {
                    label: if sample {
                        msgs::SAMPLE_ARRAY_LABEL.into()
                    } else {
                        random_string(rng)
                    },
                    size: rng.below(8) as u32,
                    stride: rng.below(8) as u32,
                }),
                data_offset: if rng.one_in(4) {
                    rng.next_u64() as u32
                } else {
                    rng.below(3) as u32
                },
            },
            data: random_vec(rng, 9, Rng::any_f64),
        }
    }

    fn after_decode(&self) {
        // The Float64MultiArray form of a damper sample (the ROS 2 adapter's input).
        let _ = self.to_damper_sample("d1");
    }
}

/// Bytes that matter to CDR: encapsulation headers, lengths, NUL, UTF-8 starts.
const CDR_DICTIONARY: &[&[u8]] = &[
    &[0, 1, 0, 0],
    &[0, 0, 0, 0],
    &[0, 2, 0, 0],
    &[0, 3, 0, 0],
    &[0xff, 0xff, 0xff, 0xff],
    &[0, 0, 0, 0x80],
    &[0x80, 0, 0, 0],
    &[1, 0, 0, 0],
    &[0],
    &[0xc3, 0x28],
    &[0xf0, 0x9f, 0x98],
];

fn generate<T: RandomMessage>(rng: &mut Rng) -> FuzzInput {
    let mut data = encode(&T::random(rng));
    let mut valid = true;
    if !rng.one_in(4) {
        mutate(rng, &mut data, CDR_DICTIONARY, MAX_BYTES);
        valid = false;
    }
    FuzzInput::single("message.cdr", data, valid)
}

fn check<T: RandomMessage>(input: &FuzzInput, _: &Scratch) -> Result<Verdict, String> {
    let bytes = input.part("message.cdr");
    let message: T = match decode(bytes) {
        Ok(m) => m,
        Err(e) if input.valid => return Err(format!("valid {} rejected: {e}", T::TYPE_NAME)),
        Err(_) => return Ok(Verdict::Rejected),
    };
    message.after_decode();
    let encoded = encode(&message);
    if input.valid && encoded != bytes {
        return Err(format!("{}: encode(decode(x)) != x", T::TYPE_NAME));
    }
    let again: T = decode(&encoded).map_err(|e| {
        format!(
            "{}: a re-encoded message does not decode: {e}",
            T::TYPE_NAME
        )
    })?;
    if encode(&again) != encoded {
        return Err(format!(
            "{}: encode → decode → encode changes the bytes",
            T::TYPE_NAME
        ));
    }
    Ok(Verdict::Accepted)
}
