//! The least squares behind [`super::identify_ripple`]: a grid over the head's three
//! nonlinear unknowns with the ripple phasors solved in closed form at each node (variable
//! projection), then Levenberg–Marquardt on all unknowns together, and the covariance
//! `σ²·(JᵀWJ)⁻¹` with `σ²` from the weighted residuals (the delta method's input).

use crate::complex::Complex;
use crate::head::belt_transfer;

/// One block's measurement, ready to fit.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    /// The (order, direction) group whose ripple phasor drives it.
    pub group: usize,
    /// The harmonic's angular frequency (rad/s, signed).
    pub w: f64,
    /// `e^{i·k·λ}`: the rotor's steady lag `λ` (electrical rad) turned to the harmonic `k`.
    pub lag: Complex,
    /// The stiffness `K·cos λ` (N·m/rad) at this block's speed.
    pub stiffness: f64,
    /// A known torque (N·m, phasor against the commanded angle) added to the ripple: an
    /// `M973` trial's shift `U` (rad) on the stiffness, `K·U/Nr`; 0 otherwise.
    pub known: Complex,
    /// The measured response (m/s²).
    pub y: Complex,
    /// The weight (the block's samples).
    pub weight: f64,
}

/// The fixed parts of the model.
#[derive(Debug, Clone, Copy)]
pub(super) struct Fixed {
    pub radius_m: f64,
    /// The base profile's viscous damping (N·m·s/rad), the fit's start.
    pub viscous: f64,
}

/// The nonlinear unknowns: `ln J_t`, `ln ω_b`, `ln ζ`, `ln c`, and the delay `τ` of the
/// commanded angle's shift (in [`DELAY_UNIT_S`]).
pub(super) const NL: usize = 5;
/// The unit of the delay unknown `x[4]` (s).
pub(super) const DELAY_UNIT_S: f64 = 1e-4;

/// The fitted unknowns: `[ln J_t, ln ω_b, ln ζ, ln c, τ]`, then `Re T, Im T` per group.
pub(super) struct Solution {
    pub x: Vec<f64>,
    /// `σ²·(JᵀWJ)⁻¹`.
    pub covariance: Vec<Vec<f64>>,
    /// `Σ w·|y − ŷ|²` and `Σ w·|y|²`, per group and in all.
    pub residual: Vec<f64>,
    pub total: Vec<f64>,
    /// Whether any block has a known torque (a trial): without one the delay `τ` is not
    /// fitted (held at 0, its variance meaningless).
    pub delay_fitted: bool,
}

/// The head's response per torque against the commanded angle:
/// `AxisModel::acceleration_per_torque` written on the fitted unknowns.
fn gain(f: &Fixed, p: &Point, nl: &[f64]) -> Complex {
    gain_linear(f, p, [nl[0].exp(), nl[1].exp(), nl[2].exp(), nl[3].exp()])
}

/// [`gain`] at `[J_t, ω_b, ζ, c]` themselves.
fn gain_linear(f: &Fixed, p: &Point, [j, wb, z, c]: [f64; 4]) -> Complex {
    let rotor = Complex::new(-p.w * p.w, 0.0) / Complex::new(p.stiffness - j * p.w * p.w, c * p.w);
    belt_transfer(f.radius_m, wb, z, p.w) * rotor
}

/// The prediction `G·(e^{ikλ}·T + known·e^{−iwτ})`: the drive applies the commanded
/// angle's shift `τ` (s) late (its computation and current loop), the ripple acts at once.
fn predict(g: Complex, p: &Point, t: Complex, delay_s: f64) -> Complex {
    g * (p.lag * t + p.known * Complex::from_polar(1.0, -p.w * delay_s))
}

/// The ripple phasors that fit best at `[J_t, ω_b, ζ]`, and the residual.
fn project(f: &Fixed, pts: &[Point], groups: usize, linear: [f64; 4]) -> (Vec<Complex>, f64) {
    let mut num = vec![Complex::default(); groups];
    let mut den = vec![0.0; groups];
    let mut yy = 0.0;
    for p in pts {
        let g0 = gain_linear(f, p, linear);
        let (g, y) = (g0 * p.lag, p.y - g0 * p.known);
        num[p.group] = num[p.group] + (g.conj() * y).scale(p.weight);
        den[p.group] += p.weight * g.norm_sqr();
        yy += p.weight * y.norm_sqr();
    }
    let t: Vec<Complex> = num.iter().zip(&den).map(|(n, d)| n.scale(1.0 / d)).collect();
    let explained: f64 = num.iter().zip(&den).map(|(n, d)| n.norm_sqr() / d).sum();
    (t, yy - explained)
}

/// The best node of a grid over `J_t` in `j_range` (kg·m²), `ω_b` over 40–2000 Hz and `ζ`,
/// with `c` the base profile's.
fn grid_start(f: &Fixed, pts: &[Point], groups: usize, j_range: (f64, f64)) -> [f64; 4] {
    let logspace = |a: f64, b: f64, n: usize| -> Vec<f64> {
        (0..n).map(|i| (a.ln() + (b.ln() - a.ln()) * i as f64 / (n - 1) as f64).exp()).collect()
    };
    let tau = std::f64::consts::TAU;
    let mut best = (f64::INFINITY, [0.0; 4]);
    for &j in &logspace(j_range.0, j_range.1, 24) {
        for &wb in &logspace(tau * 40.0, tau * 2000.0, 48) {
            for &z in &logspace(0.02, 0.5, 6) {
                let s = project(f, pts, groups, [j, wb, z, f.viscous]).1;
                if s < best.0 {
                    best = (s, [j, wb, z, f.viscous]);
                }
            }
        }
    }
    best.1
}

/// The weighted residuals `√w·(y − ŷ)` (re, im per point) at `x`.
fn residuals(f: &Fixed, pts: &[Point], x: &[f64]) -> Vec<f64> {
    let nl = &x[..NL];
    let mut r = Vec::with_capacity(2 * pts.len());
    for p in pts {
        let t = Complex::new(x[NL + 2 * p.group], x[NL + 1 + 2 * p.group]);
        let e = (p.y - predict(gain(f, p, nl), p, t, nl[4] * DELAY_UNIT_S)).scale(p.weight.sqrt());
        r.extend([e.re, e.im]);
    }
    r
}

/// The Jacobian of [`residuals`] (rows: residuals; columns: unknowns).
fn jacobian(f: &Fixed, pts: &[Point], x: &[f64]) -> Vec<Vec<f64>> {
    let n = x.len();
    let mut jac = vec![vec![0.0; n]; 2 * pts.len()];
    for k in 0..NL {
        let h = 1e-6;
        let (mut up, mut down) = (x.to_vec(), x.to_vec());
        up[k] += h;
        down[k] -= h;
        let (a, b) = (residuals(f, pts, &up), residuals(f, pts, &down));
        for (row, (ra, rb)) in jac.iter_mut().zip(a.iter().zip(&b)) {
            row[k] = (ra - rb) / (2.0 * h);
        }
    }
    let nl = &x[..NL];
    for (i, p) in pts.iter().enumerate() {
        let g = (gain(f, p, nl) * p.lag).scale(-p.weight.sqrt());
        let c = NL + 2 * p.group;
        // d(−g·T)/d Re T = −g, d/d Im T = −i·g.
        jac[2 * i][c] = g.re;
        jac[2 * i + 1][c] = g.im;
        jac[2 * i][c + 1] = -g.im;
        jac[2 * i + 1][c + 1] = g.re;
    }
    jac
}

/// `JᵀJ` and `Jᵀr`.
fn normal(jac: &[Vec<f64>], r: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
    let n = jac.first().map_or(0, Vec::len);
    let mut a = vec![vec![0.0; n]; n];
    let mut g = vec![0.0; n];
    for (row, &ri) in jac.iter().zip(r) {
        for i in 0..n {
            if row[i] == 0.0 {
                continue;
            }
            g[i] += row[i] * ri;
            for j in 0..n {
                a[i][j] += row[i] * row[j];
            }
        }
    }
    // Without a known torque (no trial) the delay's column is zero: it stays at its start, 0.
    if n > DELAY && a[DELAY][DELAY] == 0.0 {
        a[DELAY][DELAY] = 1.0;
    }
    (a, g)
}

/// The index of the delay unknown `τ` in `x`.
const DELAY: usize = 4;

/// The inverse of a symmetric positive definite `a` by Gauss–Jordan with partial pivoting;
/// `None` if it is singular to working precision.
pub(super) fn invert(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let scale = a.iter().enumerate().map(|(i, r)| r[i].abs()).fold(0.0, f64::max);
    let mut m: Vec<Vec<f64>> = a.to_vec();
    let mut inv: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect()).collect();
    for col in 0..n {
        let piv = (col..n).max_by(|&p, &q| m[p][col].abs().total_cmp(&m[q][col].abs()))?;
        if m[piv][col].abs().is_nan() || m[piv][col].abs() <= 1e-13 * scale {
            return None;
        }
        m.swap(col, piv);
        inv.swap(col, piv);
        let d = m[col][col];
        for j in 0..n {
            m[col][j] /= d;
            inv[col][j] /= d;
        }
        for i in (0..n).filter(|&i| i != col) {
            let k = m[i][col];
            if k != 0.0 {
                for j in 0..n {
                    m[i][j] -= k * m[col][j];
                    inv[i][j] -= k * inv[col][j];
                }
            }
        }
    }
    Some(inv)
}

/// Fits every unknown; `None` when the normal equations are singular (the captures do not
/// determine the unknowns).
pub(super) fn solve(f: &Fixed, pts: &[Point], groups: usize, j_range: (f64, f64)) -> Option<Solution> {
    let start = grid_start(f, pts, groups, j_range);
    let (t, _) = project(f, pts, groups, start);
    let mut x: Vec<f64> = start.map(f64::ln).to_vec();
    x.push(0.0);
    x.extend(t.iter().flat_map(|c| [c.re, c.im]));
    let sum = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut s = sum(&residuals(f, pts, &x));
    let mut mu = 1e-3;
    for _ in 0..200 {
        let r = residuals(f, pts, &x);
        let (a, g) = normal(&jacobian(f, pts, &x), &r);
        let mut damped = a.clone();
        for (i, row) in damped.iter_mut().enumerate() {
            row[i] += mu * a[i][i].max(1e-300);
        }
        let inv = invert(&damped)?;
        let step: Vec<f64> = inv.iter().map(|row| -row.iter().zip(&g).map(|(a, b)| a * b).sum::<f64>()).collect();
        let trial: Vec<f64> = x.iter().zip(&step).map(|(a, b)| a + b).collect();
        let st = sum(&residuals(f, pts, &trial));
        if st.is_finite() && st <= s {
            let done = s - st <= 1e-12 * s;
            (x, s, mu) = (trial, st, (mu / 3.0).max(1e-12));
            if done {
                break;
            }
        } else {
            mu *= 4.0;
            if mu > 1e12 {
                break;
            }
        }
    }
    let r = residuals(f, pts, &x);
    let (a, _) = normal(&jacobian(f, pts, &x), &r);
    let dof = (r.len() as f64 - x.len() as f64).max(1.0);
    let sigma2 = sum(&r) / dof;
    let covariance = invert(&a)?.into_iter().map(|row| row.into_iter().map(|v| v * sigma2).collect()).collect();
    let mut residual = vec![0.0; groups];
    let mut total = vec![0.0; groups];
    for (i, p) in pts.iter().enumerate() {
        residual[p.group] += r[2 * i] * r[2 * i] + r[2 * i + 1] * r[2 * i + 1];
        total[p.group] += p.weight * p.y.norm_sqr();
    }
    let delay_fitted = pts.iter().any(|p| p.known != Complex::default());
    Some(Solution { x, covariance, residual, total, delay_fitted })
}
