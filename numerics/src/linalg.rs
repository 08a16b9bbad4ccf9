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

/// Solve `a x = b` for a square N×N system by LU decomposition with partial pivoting
/// (2×2 systems by Cramer's rule, which is forward stable at that size and a quarter of
/// the cost: the stiff integrator's Newton iterations solve one per iteration, and were a
/// quarter of the two-chamber model's time in LU). `None` if `a` is singular or `x` is not
/// finite.
pub fn solve<const N: usize>(a: &SMatrix<f64, N, N>, b: &SVector<f64, N>) -> Option<SVector<f64, N>>
where
    Const<N>: LuDim,
{
    let x = if N == 2 {
        let det = a[(0, 0)] * a[(1, 1)] - a[(0, 1)] * a[(1, 0)];
        if det == 0.0 {
            return None;
        }
        let x0 = (b[0] * a[(1, 1)] - a[(0, 1)] * b[1]) / det;
        let x1 = (a[(0, 0)] * b[1] - a[(1, 0)] * b[0]) / det;
        SVector::<f64, N>::from_fn(|i, _| if i == 0 { x0 } else { x1 })
    } else {
        a.lu().solve(b)?
    };
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

/// The solution of a symmetric positive definite block-tridiagonal system, with the
/// blocks of its inverse on and next to the diagonal ([`solve_block_tridiagonal`]).
#[derive(Debug, Clone, Default)]
pub struct BlockTridiagonalSolution<const N: usize> {
    /// x_j, one block per diagonal block.
    pub x: Vec<SVector<f64, N>>,
    /// (A⁻¹)_jj.
    pub inv_diag: Vec<SMatrix<f64, N, N>>,
    /// (A⁻¹)_(j,j+1); one fewer than the diagonal blocks.
    pub inv_upper: Vec<SMatrix<f64, N, N>>,
    /// Work space: the inverses of the forward Schur complements and the forward right-hand
    /// sides.
    schur_inv: Vec<SMatrix<f64, N, N>>,
    y: Vec<SVector<f64, N>>,
}

/// Solve `A x = b` for a symmetric positive definite block-tridiagonal `A` — diagonal
/// blocks `diag[j]` = A_jj, blocks `upper[j]` = A_(j,j+1) (A_(j+1,j) = upper\[j\]ᵀ) — by
/// block Cholesky elimination (the block Thomas algorithm), and compute the blocks of A⁻¹
/// on and next to the diagonal by the backward recursion of selected inversion:
/// Σ_(n−1) = S_(n−1)⁻¹, Σ_(j,j+1) = −S_j⁻¹ U_j Σ_(j+1), Σ_j = S_j⁻¹ − Σ_(j,j+1) U_jᵀ S_j⁻¹,
/// S_j the forward Schur complements. O(n N³); `out` is reused (no allocation once it has
/// grown). `false` (and `out` unspecified) when a Schur complement is not positive
/// definite or a result is not finite.
pub fn solve_block_tridiagonal<const N: usize>(
    diag: &[SMatrix<f64, N, N>],
    upper: &[SMatrix<f64, N, N>],
    rhs: &[SVector<f64, N>],
    out: &mut BlockTridiagonalSolution<N>,
) -> bool {
    let n = diag.len();
    assert!(
        rhs.len() == n && upper.len() + 1 == n.max(1),
        "block shapes"
    );
    out.schur_inv.clear();
    out.y.clear();
    for j in 0..n {
        let (s, y) = if j == 0 {
            (diag[0], rhs[0])
        } else {
            let l = upper[j - 1].transpose() * out.schur_inv[j - 1];
            (diag[j] - l * upper[j - 1], rhs[j] - l * out.y[j - 1])
        };
        let Some(chol) = s.cholesky() else {
            return false;
        };
        out.schur_inv.push(chol.inverse());
        out.y.push(y);
    }
    out.x.clear();
    out.x.resize(n, SVector::zeros());
    out.inv_diag.clear();
    out.inv_diag.resize(n, SMatrix::zeros());
    out.inv_upper.clear();
    out.inv_upper.resize(n.saturating_sub(1), SMatrix::zeros());
    for j in (0..n).rev() {
        let si = out.schur_inv[j];
        if j + 1 == n {
            out.x[j] = si * out.y[j];
            out.inv_diag[j] = si;
        } else {
            out.x[j] = si * (out.y[j] - upper[j] * out.x[j + 1]);
            let off = -(si * upper[j]) * out.inv_diag[j + 1];
            let d = si - off * upper[j].transpose() * si;
            out.inv_upper[j] = off;
            out.inv_diag[j] = 0.5 * (d + d.transpose());
        }
    }
    out.x.iter().all(|x| all_finite(x.as_slice()))
        && out.inv_diag.iter().all(|m| all_finite(m.as_slice()))
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
    fn block_tridiagonal_solve_and_inverse_blocks_match_the_dense_ones() {
        use nalgebra::{Matrix2, Vector2};
        // Four 2×2 blocks: a diagonally dominant SPD matrix assembled densely as well.
        let diag: Vec<Matrix2<f64>> = (0..4)
            .map(|j| Matrix2::new(6.0 + j as f64, 0.5, 0.5, 5.0 + 0.3 * j as f64))
            .collect();
        let upper: Vec<Matrix2<f64>> = (0..3)
            .map(|j| Matrix2::new(-1.0, 0.4 * j as f64, 0.2, -0.7))
            .collect();
        let rhs: Vec<Vector2<f64>> = (0..4)
            .map(|j| Vector2::new(1.0 + j as f64, -2.0 + 0.5 * j as f64))
            .collect();
        let mut a = DMatrix::zeros(8, 8);
        let mut b = DVector::zeros(8);
        for j in 0..4 {
            a.view_mut((2 * j, 2 * j), (2, 2)).copy_from(&diag[j]);
            b.rows_mut(2 * j, 2).copy_from(&rhs[j]);
            if j < 3 {
                a.view_mut((2 * j, 2 * j + 2), (2, 2)).copy_from(&upper[j]);
                a.view_mut((2 * j + 2, 2 * j), (2, 2))
                    .copy_from(&upper[j].transpose());
            }
        }
        let inv = a.clone().try_inverse().unwrap();
        let x = &inv * &b;
        let mut out = BlockTridiagonalSolution::default();
        assert!(solve_block_tridiagonal(&diag, &upper, &rhs, &mut out));
        for j in 0..4 {
            assert!((out.x[j] - x.rows(2 * j, 2)).norm() < 1e-12);
            assert!((out.inv_diag[j] - inv.view((2 * j, 2 * j), (2, 2))).norm() < 1e-12);
            if j < 3 {
                let dense = inv.view((2 * j, 2 * j + 2), (2, 2));
                assert!((out.inv_upper[j] - dense).norm() < 1e-12);
            }
        }
        // One block: the plain inverse; an indefinite block is refused.
        assert!(solve_block_tridiagonal(
            &diag[..1],
            &[],
            &rhs[..1],
            &mut out
        ));
        assert!((out.inv_diag[0] - diag[0].try_inverse().unwrap()).norm() < 1e-12);
        let bad = [Matrix2::new(1.0, 2.0, 2.0, 1.0)];
        assert!(!solve_block_tridiagonal(&bad, &[], &rhs[..1], &mut out));
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
