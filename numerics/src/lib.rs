//! # numerics — one path for each kind of numerics in mrtwin
//!
//! Pure computation, no I/O, one dependency (nalgebra, re-exported as [`nalgebra`]).
//!
//! * [`linalg`]: the small dense solves and inverses, through nalgebra's LU and Cholesky
//!   decompositions.
//! * [`least_squares`]: the Levenberg–Marquardt loop shared by every nonlinear fit.
//! * [`optimize`]: golden-section search in one dimension.
//! * [`parallel`]: independent jobs on a few scoped threads, results in index order.
//! * [`simd`]: whether the CPU has AVX2, for the hot loops compiled a second time with
//!   it (the same results, bit for bit).
//! * [`signal`]: stuck channels (runs of one exact value), on a record and on a stream.
//! * [`stats`]: quantiles and the median, the lag-1 autocorrelation and the AR(1)
//!   effective sample size, normal and χ² quantiles, the Wilson interval.

pub mod least_squares;
pub mod linalg;
pub mod optimize;
pub mod parallel;
pub mod signal;
pub mod simd;
pub mod stats;

pub use nalgebra;
