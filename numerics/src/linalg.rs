//! Small dense linear algebra through nalgebra's decompositions.
//!
//! Every solve returns `None` when the matrix is singular or the result is not finite
//! (an overflowing or NaN solution is as useless to the callers as a singular matrix), so
//! a caller has one failure to handle.

use nalgebra::{Const, DMatrix, DVector, DimMin, SMatrix, SVector};

/// A square dimension nalgebra's LU decomposition accepts: `Const<N>` for every N the
/// callers use (nalgebra implements it up to 127). Generic code over `const N: usize`
/// states `Const<N>: LuDim` to call [`solve`] or [`inverse`].
pub trait LuDim: DimMin<Self, Output = Self> {}

impl<D: DimMin<D, Output = D>> LuDim for D {}

/// Solve `a x = b` for a square N×N system by LU decomposition with partial pivoting.
/// `None` if `a` is singular or `x` is not finite.
pub fn solve<const N: usize>(a: &SMatrix<f64, N, N>, b: &SVector<f64, N>) -> Option<SVector<f64, N>>
where
    Const<N>: LuDim,
{
    let x = a.lu().solve(b)?;
    all_finite(x.as_slice()).then_some(x)
}

/// The inverse of a square N×N matrix by LU decomposition with partial pivoting.
/// `None` if `a` is singular or the inverse is not finite.
pub fn inverse<const N: usize>(a: &SMatrix<f64, N, N>) -> Option<SMatrix<f64, N, N>>
where
    Const<N>: LuDim,
{
    let inv = a.lu().try_inverse()?;
    all_finite(inv.as_slice()).then_some(inv)
}

/// Solve `a x = b` for a symmetric positive definite `a` (of any size) by Cholesky
/// decomposition. `None` if `a` is not numerically positive definite or `x` is not finite.
pub fn solve_spd(a: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    let x = a.cholesky()?.solve(b);
    all_finite(x.as_slice()).then_some(x)
}

/// The N×N matrix whose rows are `rows` (the row-major array form the callers build).
pub fn from_rows<const N: usize>(rows: &[[f64; N]; N]) -> SMatrix<f64, N, N> {
    SMatrix::from_fn(|i, j| rows[i][j])
}

/// The rows of an N×N matrix, the inverse of [`from_rows`].
pub fn to_rows<const N: usize>(m: &SMatrix<f64, N, N>) -> [[f64; N]; N] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn solve_recovers_a_known_solution() {
        // A row swap is needed (zero leading entry).
        let a = Matrix3::new(0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 2.0);
        let x = Vector3::new(1.0, -2.0, 0.5);
        let got = solve(&a, &(a * x)).unwrap();
        assert!((got - x).amax() < 1e-14, "{got}");
    }

    #[test]
    fn singular_and_non_finite_systems_are_refused() {
        let singular = Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 1.0, 1.0);
        assert!(solve(&singular, &Vector3::new(1.0, 2.0, 3.0)).is_none());
        assert!(inverse(&singular).is_none());
        let nan = Matrix3::new(f64::NAN, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(solve(&nan, &Vector3::new(1.0, 1.0, 1.0)).is_none());
        let overflow = Matrix3::identity() * 1e-300;
        assert!(solve(&overflow, &Vector3::new(1e300, 0.0, 0.0)).is_none());
    }

    #[test]
    fn inverse_of_a_5x5_times_the_matrix_is_the_identity() {
        let m = SMatrix::<f64, 5, 5>::from_fn(|i, j| {
            1.0 / (i + j + 1) as f64 + if i == j { 1.0 } else { 0.0 }
        });
        let inv = inverse(&m).unwrap();
        assert!((inv * m - SMatrix::<f64, 5, 5>::identity()).amax() < 1e-13);
        // The rows round-trip through the array form.
        assert_eq!(from_rows(&to_rows(&m)), m);
        assert_eq!(to_rows(&m)[1][3], 1.0 / 5.0);
    }

    #[test]
    fn spd_solve_by_cholesky() {
        let a = DMatrix::from_row_slice(2, 2, &[4.0, 2.0, 2.0, 3.0]);
        let x = solve_spd(a.clone(), &DVector::from_vec(vec![2.0, 5.0])).unwrap();
        // 4x + 2y = 2, 2x + 3y = 5 → x = −0.5, y = 2.
        assert!(
            (x[0] + 0.5).abs() < 1e-14 && (x[1] - 2.0).abs() < 1e-14,
            "{x}"
        );
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        assert!(solve_spd(indefinite, &DVector::from_vec(vec![1.0, 1.0])).is_none());
    }
}
