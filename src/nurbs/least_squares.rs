//! Least-squares control points (the paper's eq. 5–10), solved stably.
//!
//! The paper writes the normal equations `RᵀR P = RᵀQ` and `P = (RᵀR)⁻¹RᵀQ`;
//! forming `RᵀR` squares the condition number, so this module solves the same
//! least-squares problem `min ‖Q − RP‖₂` by a Householder QR of `R` (nalgebra),
//! never an explicit inverse. As usual for clamped fits (Piegl & Tiller §9.4.1)
//! the first and last control points interpolate the first and last data points;
//! only the interior control points are unknowns.
//!
//! Invariants: the data are `m + 1 >= n + 1` rows of `dim` values, parameters
//! sorted in `[a, b]` of the knot vector; a rank-deficient system (empty knot spans,
//! Schoenberg–Whitney violated) is an error, never a silent garbage solution.
use nalgebra::DMatrix;

use super::basis::{MAX_DEGREE, basis_funs, find_span};

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LeastSquaresError {
    #[error("{data} data points cannot determine {control} control points")]
    TooFewData { data: usize, control: usize },
    #[error("the least-squares system is rank deficient (knot spans without data)")]
    Singular,
}

/// Rational basis row `R_{i,p}(u)` for all `i` (dense, length `n + 1`).
pub fn rational_row(u: f64, p: usize, knots: &[f64], weights: &[f64], row: &mut [f64]) {
    let n = weights.len() - 1;
    row.iter_mut().for_each(|v| *v = 0.0);
    let span = find_span(n, p, u, knots);
    let mut basis = [0.0; MAX_DEGREE + 1];
    basis_funs(span, u, p, knots, &mut basis);
    let mut denom = 0.0;
    for j in 0..=p {
        denom += basis[j] * weights[span - p + j];
    }
    for j in 0..=p {
        let i = span - p + j;
        row[i] = basis[j] * weights[i] / denom;
    }
}

/// Control values (`weights.len()` rows of `dim`, row-major) of the least-squares
/// fit of `data` (`params.len()` rows of `dim`, row-major) at `params`, with the
/// end control points equal to the end data.
pub fn fit_control_points(
    params: &[f64],
    data: &[f64],
    dim: usize,
    p: usize,
    knots: &[f64],
    weights: &[f64],
) -> Result<Vec<f64>, LeastSquaresError> {
    let rows = params.len();
    let count = weights.len();
    if rows < count || count < 2 {
        return Err(LeastSquaresError::TooFewData {
            data: rows,
            control: count,
        });
    }
    let n = count - 1;
    let mut out = vec![0.0; count * dim];
    out[..dim].copy_from_slice(&data[..dim]);
    out[n * dim..].copy_from_slice(&data[(rows - 1) * dim..]);
    if count == 2 {
        return Ok(out);
    }
    let unknowns = count - 2;
    let eq = rows - 2;
    let mut a = DMatrix::<f64>::zeros(eq, unknowns);
    let mut b = DMatrix::<f64>::zeros(eq, dim);
    let mut row = vec![0.0; count];
    for k in 1..rows - 1 {
        rational_row(params[k], p, knots, weights, &mut row);
        for i in 1..n {
            a[(k - 1, i - 1)] = row[i];
        }
        for d in 0..dim {
            b[(k - 1, d)] =
                data[k * dim + d] - row[0] * data[d] - row[n] * data[(rows - 1) * dim + d];
        }
    }
    let qr = a.qr();
    qr.q_tr_mul(&mut b);
    let r = qr.r();
    let diag_max = (0..unknowns).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
    if !(diag_max > 0.0) || (0..unknowns).any(|i| r[(i, i)].abs() <= 1e-12 * diag_max) {
        return Err(LeastSquaresError::Singular);
    }
    let top = b.rows(0, unknowns).into_owned();
    let x = r
        .solve_upper_triangular(&top)
        .ok_or(LeastSquaresError::Singular)?;
    for i in 1..n {
        for d in 0..dim {
            let v = x[(i - 1, d)];
            if !v.is_finite() {
                return Err(LeastSquaresError::Singular);
            }
            out[i * dim + d] = v;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nurbs::knot_vector::clamped;

    #[test]
    fn reproduces_a_polynomial_exactly() {
        // A cubic polynomial is in every cubic spline space: the fit is exact.
        let knots = clamped(3, &[0.3, 0.6], 0.0, 1.0);
        let weights = vec![1.0; 6];
        let params: Vec<f64> = (0..=20).map(|i| i as f64 / 20.0).collect();
        let f = |u: f64| 1.0 - 2.0 * u + 3.0 * u * u * u;
        let data: Vec<f64> = params.iter().map(|&u| f(u)).collect();
        let ctrl = fit_control_points(&params, &data, 1, 3, &knots, &weights).unwrap();
        let mut row = vec![0.0; 6];
        for &u in &[0.05, 0.5, 0.77] {
            rational_row(u, 3, &knots, &weights, &mut row);
            let v: f64 = row.iter().zip(&ctrl).map(|(r, c)| r * c).sum();
            assert!((v - f(u)).abs() < 1e-12);
        }
    }

    #[test]
    fn singular_when_spans_are_empty() {
        // Four basis functions live on (0.4, 1] but only three data points do.
        let knots = clamped(3, &[0.4, 0.5, 0.6, 0.7], 0.0, 1.0);
        let params = [0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.9, 0.95, 1.0];
        let data = params.to_vec();
        assert_eq!(
            fit_control_points(&params, &data, 1, 3, &knots, &[1.0; 8]),
            Err(LeastSquaresError::Singular)
        );
    }
}
