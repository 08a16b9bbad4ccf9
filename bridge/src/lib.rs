//! mrtwin I/O.
//!
//! - [`recording`]: recordings in the project's CSV format (PHYSICS.md,
//!   "Recording format (CSV)"), read and written loss-free.
//! - [`utfsm`]: readers for the real MR damper recordings from the UTFSM test
//!   press (`shared/data/real/maurel-utfsm`).

pub mod recording;
pub mod utfsm;

pub use recording::{
    derive_velocity, parse_csv, read_csv, to_csv_string, write_csv, Recording, RecordingError,
    Sample,
};
