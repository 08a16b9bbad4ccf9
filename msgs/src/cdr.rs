//! CDR encoding as ROS 2 carries it on DDS and in rosbag2: a 4-byte encapsulation header
//! (`00 01 00 00` = CDR little-endian, `00 00 00 00` = big-endian) then the plain CDR body.

use byteorder::{BigEndian, LittleEndian};

/// Encapsulation header of little-endian plain CDR.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
/// Encapsulation header of big-endian plain CDR.
pub const CDR_BE_HEADER: [u8; 4] = [0x00, 0x00, 0x00, 0x00];

/// Why a message could not be decoded or encoded.
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    /// Fewer than 4 bytes: no encapsulation header.
    #[error("CDR message of {0} bytes is too short for the 4-byte encapsulation header")]
    TooShort(usize),
    /// An encapsulation kind other than plain CDR.
    #[error("unsupported CDR encapsulation {0:02x} {1:02x} (only plain CDR, 00 00 / 00 01)")]
    Encapsulation(u8, u8),
    /// The body does not decode as the expected type.
    #[error("CDR body does not decode as {type_name}: {reason}")]
    Body {
        /// The expected ROS type.
        type_name: &'static str,
        /// What went wrong.
        reason: String,
    },
}

/// Encode a message: encapsulation header (CDR little-endian) + body.
pub fn encode<T: crate::RosMessage>(msg: &T) -> Vec<u8> {
    let mut out = CDR_LE_HEADER.to_vec();
    cdr_encoding::to_writer::<T, LittleEndian, _>(&mut out, msg)
        .expect("serde types of this crate always encode");
    out
}

/// Decode a message with its encapsulation header (either byte order).
pub fn decode<T: crate::RosMessage>(bytes: &[u8]) -> Result<T, CdrError> {
    if bytes.len() < 4 {
        return Err(CdrError::TooShort(bytes.len()));
    }
    let body = &bytes[4..];
    let result = match (bytes[0], bytes[1]) {
        (0x00, 0x01) => cdr_encoding::from_bytes::<T, LittleEndian>(body),
        (0x00, 0x00) => cdr_encoding::from_bytes::<T, BigEndian>(body),
        (a, b) => return Err(CdrError::Encapsulation(a, b)),
    };
    result.map(|(m, _)| m).map_err(|e| CdrError::Body {
        type_name: T::TYPE_NAME,
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DamperSample, DiagnosticArray, DiagnosticStatus, Float64, Header, KeyValue};

    #[test]
    fn float64_is_header_plus_eight_bytes() {
        let b = encode(&Float64 { data: 1.5 });
        assert_eq!(&b[..4], &CDR_LE_HEADER);
        assert_eq!(&b[4..], &1.5f64.to_le_bytes());
    }

    #[test]
    fn round_trips_and_aligns_doubles() {
        let s = DamperSample {
            header: Header::at(1.25, "d1"),
            displacement: 0.01,
            velocity: -0.2,
            force: 350.0,
            current: 1.0,
            temperature: f64::NAN,
        };
        let b = encode(&s);
        // header: sec(4) nanosec(4) strlen(4) "d1\0"(3) -> 15, pad to 16, then 5 doubles.
        assert_eq!(b.len(), 4 + 16 + 5 * 8);
        let back: DamperSample = decode(&b).unwrap();
        assert_eq!(back.header, s.header);
        assert_eq!(back.force, 350.0);
        assert!(back.temperature.is_nan());
        let d = DiagnosticArray {
            header: Header::at(2.0, ""),
            status: vec![DiagnosticStatus {
                level: DiagnosticStatus::WARN,
                name: "mrtwin: residual".into(),
                message: "high".into(),
                hardware_id: "d1".into(),
                values: vec![KeyValue::new("rms_N", "12.5")],
            }],
        };
        assert_eq!(decode::<DiagnosticArray>(&encode(&d)).unwrap(), d);
    }

    #[test]
    fn bad_bytes_are_errors_not_panics() {
        assert!(matches!(
            decode::<Float64>(&[0, 1]),
            Err(CdrError::TooShort(2))
        ));
        assert!(matches!(
            decode::<Float64>(&[0, 7, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8]),
            Err(CdrError::Encapsulation(0, 7))
        ));
        assert!(decode::<DamperSample>(&[0, 1, 0, 0, 1, 0]).is_err());
    }
}
