//! Linear least squares `y ≈ X β` with an honest covariance.
//!
//! Solved by Householder QR of the column-scaled `X` (nalgebra), then an SVD of the small
//! triangular factor `R`: the singular values give the condition number, and
//! `(XᵀX)⁻¹ = V Σ⁻² Vᵀ` without forming `XᵀX`.
//!
//! Covariance: residuals of a servo log are not white (the loop, the encoder and
//! unmodelled dynamics correlate them over milliseconds), so the classical
//! `σ² (XᵀX)⁻¹` is too optimistic. The covariance returned is the larger (in each
//! diagonal element, by taking the larger matrix of the two) of the classical one and the
//! cluster-robust ("sandwich") one: rows are grouped in consecutive blocks much longer than
//! the residual's correlation time, and `Cov = (XᵀX)⁻¹ (Σ_b s_b s_bᵀ) (XᵀX)⁻¹ · B/(B−1)` with
//! `s_b = Σ_{i∈b} x_i e_i`. It covers noise and jitter, not a bias of the model itself.
//!
//! Cost: `O(n p²)` for `n` rows and `p` columns (QR) plus `O(n p)` (scores).

use nalgebra::{DMatrix, DVector};

/// A design matrix stored by rows, with block labels for the robust covariance.
#[derive(Clone, Debug, Default)]
pub struct Design {
    /// Number of columns.
    pub p: usize,
    /// Row-major regressors, `n × p`.
    pub x: Vec<f64>,
    /// Observations, length `n`.
    pub y: Vec<f64>,
    /// Block index of each row (non-decreasing within a log; any labels are fine).
    pub block: Vec<u32>,
}

impl Design {
    /// An empty design with `p` columns.
    pub fn new(p: usize) -> Self {
        Design { p, ..Design::default() }
    }

    /// Appends one row.
    #[inline]
    pub fn push(&mut self, row: &[f64], y: f64, block: u32) {
        debug_assert_eq!(row.len(), self.p);
        self.x.extend_from_slice(row);
        self.y.push(y);
        self.block.push(block);
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.y.len()
    }
}

/// The least-squares solution.
#[derive(Clone, Debug)]
pub struct Solution {
    /// Coefficients `β`.
    pub beta: Vec<f64>,
    /// Covariance of `β` (see the module documentation), `p × p`.
    pub cov: DMatrix<f64>,
    /// Residuals `y − Xβ`.
    pub residual: Vec<f64>,
    /// RMS of the residuals.
    pub residual_rms: f64,
    /// Condition number of the column-scaled `X` (largest / smallest singular value).
    pub condition: f64,
    /// Variance inflation of each coefficient: `diag((XᵀX)⁻¹)·diag(XᵀX)` on the scaled
    /// columns (1 = orthogonal to the others; ≫ 1 = confounded with them).
    pub inflation: Vec<f64>,
}

/// Why a fit failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LsqError {
    /// Fewer rows than columns (plus one).
    #[error("{rows} samples for {cols} unknowns")]
    TooFewRows {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
    },
    /// A column is all zeros or the columns are linearly dependent.
    #[error("the regressors are linearly dependent (condition number {0:.3e})")]
    Singular(f64),
    /// An observation, a coefficient, the residual or the covariance is not finite
    /// (values too large to square in f64, or NaN in the data).
    #[error("{0} is not finite (values in the data out of range, e.g. a current of 1e200 A?)")]
    NonFinite(&'static str),
}

/// Solves the least-squares problem.
pub fn solve(d: &Design) -> Result<Solution, LsqError> {
    let (n, p) = (d.rows(), d.p);
    if n <= p {
        return Err(LsqError::TooFewRows { rows: n, cols: p });
    }
    if d.y.iter().any(|v| !v.is_finite()) {
        return Err(LsqError::NonFinite("an observation"));
    }
    let scale = column_scales(d)?;
    let Scaled { beta_s, inv, condition } = solve_scaled(d, &scale)?;
    let beta: Vec<f64> = (0..p).map(|j| beta_s[j] / scale[j]).collect();
    let (residual, rss) = residuals(d, &beta);
    if !rss.is_finite() || beta.iter().any(|b| !b.is_finite()) {
        return Err(LsqError::NonFinite(if rss.is_finite() { "a coefficient" } else { "the residual sum of squares" }));
    }
    let sigma2 = rss / (n - p) as f64;
    let cov = covariance(d, &scale, &residual, &inv, sigma2)?;
    let inflation = (0..p).map(|j| inv[(j, j)] * n as f64).collect();
    Ok(Solution { beta, cov, residual_rms: (rss / n as f64).sqrt(), residual, condition, inflation })
}

/// The RMS of each column of `d`; an error when one is zero or not finite.
fn column_scales(d: &Design) -> Result<Vec<f64>, LsqError> {
    let (n, p) = (d.rows(), d.p);
    let mut scale = vec![0.0; p];
    for row in d.x.chunks_exact(p) {
        for (s, v) in scale.iter_mut().zip(row) {
            *s += v * v;
        }
    }
    for s in &mut scale {
        *s = (*s / n as f64).sqrt();
    }
    if scale.iter().any(|&s| !(s > 0.0 && s.is_finite())) {
        return Err(LsqError::Singular(f64::INFINITY));
    }
    Ok(scale)
}

/// The solution in the units of the column-scaled `X` (each column divided by its scale).
struct Scaled {
    /// `β` of the scaled columns.
    beta_s: DVector<f64>,
    /// `(XsᵀXs)⁻¹`.
    inv: DMatrix<f64>,
    /// Condition number of `Xs`.
    condition: f64,
}

/// QR of the scaled `X`, then the SVD of `R`: `β_s = V Σ⁻¹ Uᵀ Qᵀy` and
/// `(XsᵀXs)⁻¹ = V Σ⁻² Vᵀ`; an error when the condition number reaches 1e10.
fn solve_scaled(d: &Design, scale: &[f64]) -> Result<Scaled, LsqError> {
    let (n, p) = (d.rows(), d.p);
    let xs = DMatrix::from_fn(n, p, |i, j| d.x[i * p + j] / scale[j]);
    let qr = xs.qr();
    let r = qr.r();
    let mut qty = DVector::from_column_slice(&d.y);
    qr.q_tr_mul(&mut qty);
    let qty = qty.rows(0, p).into_owned();
    let svd = r.clone().svd(true, true);
    let sv = &svd.singular_values;
    let smax = sv.max();
    let smin = sv.min();
    let condition = if smin > 0.0 { smax / smin } else { f64::INFINITY };
    if condition.is_nan() || condition >= 1e10 {
        return Err(LsqError::Singular(condition));
    }
    let (u, vt) = (svd.u.as_ref().expect("computed"), svd.v_t.as_ref().expect("computed"));
    let uty = u.transpose() * &qty;
    let mut beta_s = DVector::zeros(p);
    let mut inv = DMatrix::zeros(p, p);
    for k in 0..p {
        let vk = vt.row(k).transpose();
        beta_s += &vk * (uty[k] / sv[k]);
        inv += &vk * vk.transpose() / (sv[k] * sv[k]);
    }
    Ok(Scaled { beta_s, inv, condition })
}

/// The residuals `y − Xβ` and their sum of squares.
fn residuals(d: &Design, beta: &[f64]) -> (Vec<f64>, f64) {
    let mut residual = Vec::with_capacity(d.rows());
    let mut rss = 0.0;
    for (row, &y) in d.x.chunks_exact(d.p).zip(&d.y) {
        let e = y - row.iter().zip(beta).map(|(a, b)| a * b).sum::<f64>();
        rss += e * e;
        residual.push(e);
    }
    (residual, rss)
}

/// The covariance of `β` (see the module documentation): the classical `σ²(XsᵀXs)⁻¹`, or,
/// with enough blocks, the robust one raised to the classical variance where it is smaller,
/// then unscaled to the units of `β`.
fn covariance(
    d: &Design,
    scale: &[f64],
    residual: &[f64],
    inv: &DMatrix<f64>,
    sigma2: f64,
) -> Result<DMatrix<f64>, LsqError> {
    let p = d.p;
    let (meat, blocks) = block_scores(d, scale, residual);
    let classical = inv * sigma2;
    let mut cov_s = if blocks >= 2 * p.max(2) {
        let robust = inv * meat * inv * (blocks as f64 / (blocks - 1) as f64);
        at_least_classical(robust, &classical)
    } else {
        classical
    };
    // Unscale.
    for j in 0..p {
        for k in 0..p {
            cov_s[(j, k)] /= scale[j] * scale[k];
        }
    }
    if cov_s.iter().any(|c| !c.is_finite()) {
        return Err(LsqError::NonFinite("the covariance"));
    }
    Ok(cov_s)
}

/// The sandwich's meat in scaled units, `Σ_b s_b s_bᵀ` with `s_b = Σ_{i∈b} x_i e_i` over
/// runs of equal block labels, and the number of blocks.
fn block_scores(d: &Design, scale: &[f64], residual: &[f64]) -> (DMatrix<f64>, usize) {
    let p = d.p;
    let mut meat = DMatrix::<f64>::zeros(p, p);
    let mut blocks = 0usize;
    let mut s = DVector::<f64>::zeros(p);
    let mut current: Option<u32> = None;
    for (i, row) in d.x.chunks_exact(p).enumerate() {
        if current != Some(d.block[i]) {
            if current.is_some() {
                meat += &s * s.transpose();
                blocks += 1;
            }
            s.fill(0.0);
            current = Some(d.block[i]);
        }
        for j in 0..p {
            s[j] += row[j] / scale[j] * residual[i];
        }
    }
    meat += &s * s.transpose();
    blocks += 1;
    (meat, blocks)
}

/// `robust` with each variance raised to at least the classical one: row and column `j`
/// scaled by `√(classical_jj / robust_jj)` where the robust variance is smaller.
fn at_least_classical(mut c: DMatrix<f64>, classical: &DMatrix<f64>) -> DMatrix<f64> {
    let p = c.nrows();
    for j in 0..p {
        if c[(j, j)] < classical[(j, j)] {
            let f = (classical[(j, j)] / c[(j, j)].max(f64::MIN_POSITIVE)).sqrt();
            for k in 0..p {
                c[(j, k)] *= f;
                c[(k, j)] *= f;
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn recovers_known_coefficients_and_covers_them_with_the_interval() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut d = Design::new(3);
        for i in 0..20_000 {
            let x = [1.0, (i as f64 * 0.01).sin(), i as f64 * 1e-4];
            let e: f64 = rng.random_range(-1.0..1.0);
            d.push(&x, 2.0 - 3.0 * x[1] + 0.5 * x[2] + 0.1 * e, (i / 200) as u32);
        }
        let s = solve(&d).unwrap();
        for (b, want) in s.beta.iter().zip([2.0, -3.0, 0.5]) {
            assert!((b - want).abs() < 0.01, "{:?}", s.beta);
        }
        for j in 0..3 {
            let sd = s.cov[(j, j)].sqrt();
            assert!(sd > 0.0 && (s.beta[j] - [2.0, -3.0, 0.5][j]).abs() < 4.0 * sd, "{j}: sd {sd}");
        }
        assert!((s.residual_rms - 0.1 / 3f64.sqrt()).abs() < 0.003);
    }

    #[test]
    fn dependent_columns_are_reported() {
        let mut d = Design::new(2);
        for i in 0..100 {
            d.push(&[i as f64, 2.0 * i as f64], 1.0, 0);
        }
        assert!(matches!(solve(&d), Err(LsqError::Singular(_))));
    }

    #[test]
    fn observations_too_large_to_square_are_an_error_not_an_infinite_fit() {
        let mut d = Design::new(2);
        for i in 0..100 {
            let x = i as f64 * 0.1;
            d.push(&[1.0, x.sin()], 1e200 * (1.0 + x.cos()), 0);
        }
        assert_eq!(solve(&d).unwrap_err(), LsqError::NonFinite("the residual sum of squares"));
        d.y[3] = f64::NAN;
        assert_eq!(solve(&d).unwrap_err(), LsqError::NonFinite("an observation"));
    }
}
