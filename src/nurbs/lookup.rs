//! Fast exact lookup `position → value` on a planar NURBS curve `(x(u), y(u))`:
//! solve `x(u) = position`, return `y(u)` (the paper's Fig. 9 uses a binary
//! search on `u`; this is the same inversion, faster).
//!
//! Each non-empty knot span is converted once to polynomials in the local
//! parameter `s ∈ [0, 1]`: `X(s) = Σ w_i x_i N_i`, `Y(s)`, `W(s) = Σ w_i N_i`, so
//! `x = X/W`, `y = Y/W`. A lookup finds the span by binary search on the span-end
//! positions, then solves the polynomial equation `X(s) − x₀ W(s) = 0` by Newton's
//! method safeguarded by bisection (the bracket always holds the root).
//!
//! Invariant (checked at construction, [`LookupError::NotMonotonic`]): `x(u)` is
//! strictly increasing — the numerator of `x'(u)`, `X'W − XW'`, is shown positive
//! on every span through its Bernstein coefficients (with subdivision), so the
//! inverse exists and is unique.
use serde::{Deserialize, Serialize};

use super::basis::{MAX_DEGREE, ders_basis_funs};
use super::curve::{NurbsCurve, binomial};

const COEFS: usize = MAX_DEGREE + 1;

#[derive(Clone, Debug, Serialize, Deserialize)]
struct SpanPolynomials {
    /// Parameter at the span start and span length.
    u0: f64,
    h: f64,
    /// Power-basis coefficients in `s`, lowest first.
    x: [f64; COEFS],
    y: [f64; COEFS],
    w: [f64; COEFS],
    /// Positions at the span ends.
    x_start: f64,
    x_end: f64,
    /// `Δx · ds/dx` at both span ends: the cubic Hermite model of the inverse
    /// `s(x)` that gives Newton its starting point.
    slope_start: f64,
    slope_end: f64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LookupError {
    #[error("the fitted curve folds back: x(u) is not strictly increasing near u = {u:.6}")]
    NotMonotonic { u: f64 },
}

/// Precomputed inversion table of one curve. See the module doc.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CurveLookup {
    degree: usize,
    spans: Vec<SpanPolynomials>,
    /// `x_end` of every span but the last, for the binary search.
    ends: Vec<f64>,
}

#[inline]
fn horner(c: &[f64; COEFS], degree: usize, s: f64) -> f64 {
    if degree == 3 {
        // The SMEM's cubic, unrolled.
        return ((c[3] * s + c[2]) * s + c[1]) * s + c[0];
    }
    let mut v = c[degree];
    for k in (0..degree).rev() {
        v = v * s + c[k];
    }
    v
}

#[inline]
fn horner_derivative(c: &[f64; COEFS], degree: usize, s: f64) -> f64 {
    if degree == 3 {
        return (3.0 * c[3] * s + 2.0 * c[2]) * s + c[1];
    }
    let mut v = c[degree] * degree as f64;
    for k in (1..degree).rev() {
        v = v * s + c[k] * k as f64;
    }
    v
}

/// Is the polynomial with power coefficients `a` (lowest first) positive on
/// `[0, 1]`? Conservative: `false` when positivity cannot be shown after a
/// bounded subdivision.
fn positive_on_unit_interval(a: &[f64]) -> bool {
    let d = a.len() - 1;
    // Power → Bernstein: b_i = Σ_{k<=i} C(i,k)/C(d,k) a_k.
    let b: Vec<f64> = (0..=d)
        .map(|i| {
            (0..=i)
                .map(|k| binomial(i, k) / binomial(d, k) * a[k])
                .sum()
        })
        .collect();
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(scale > 0.0) {
        return false;
    }
    bernstein_positive(&b, 0, 1e-13 * scale)
}

fn bernstein_positive(b: &[f64], depth: usize, eps: f64) -> bool {
    if b[0] <= eps || b[b.len() - 1] <= eps {
        return false;
    }
    if b.iter().all(|&v| v > 0.0) {
        return true;
    }
    if depth >= 24 {
        return false;
    }
    // de Casteljau split at 1/2.
    let d = b.len() - 1;
    let mut work = b.to_vec();
    let mut left = Vec::with_capacity(d + 1);
    let mut right = vec![0.0; d + 1];
    left.push(work[0]);
    right[d] = work[d];
    for r in 1..=d {
        for i in 0..=d - r {
            work[i] = 0.5 * (work[i] + work[i + 1]);
        }
        left.push(work[0]);
        right[d - r] = work[d - r];
    }
    bernstein_positive(&left, depth + 1, eps) && bernstein_positive(&right, depth + 1, eps)
}

impl CurveLookup {
    /// Precompute the span polynomials of `curve` and prove `x(u)` increasing.
    pub fn new(curve: &NurbsCurve) -> Result<CurveLookup, LookupError> {
        let p = curve.degree;
        let n = curve.points.len() - 1;
        let knots = &curve.knots;
        let mut spans = Vec::new();
        for i in p..=n {
            let h = knots[i + 1] - knots[i];
            if h <= 0.0 {
                continue;
            }
            let ders = ders_basis_funs(i, knots[i], p, p, knots);
            let mut x = [0.0; COEFS];
            let mut y = [0.0; COEFS];
            let mut w = [0.0; COEFS];
            let mut factor = 1.0; // h^k / k!
            for k in 0..=p {
                for j in 0..=p {
                    let idx = i - p + j;
                    let bw = ders[k][j] * curve.weights[idx] * factor;
                    x[k] += bw * curve.points[idx][0];
                    y[k] += bw * curve.points[idx][1];
                    w[k] += bw;
                }
                factor *= h / (k + 1) as f64;
            }
            // x' numerator in s: X'W − XW' (degree 2p − 1, top term cancels).
            let mut num = vec![0.0; 2 * p];
            for a in 1..=p {
                for b in 0..=p {
                    num[a - 1 + b] += a as f64 * (x[a] * w[b] - w[a] * x[b]);
                }
            }
            if !positive_on_unit_interval(&num) {
                return Err(LookupError::NotMonotonic { u: knots[i] });
            }
            let x_start = x[0] / w[0];
            let x_end = horner(&x, p, 1.0) / horner(&w, p, 1.0);
            spans.push(SpanPolynomials {
                u0: knots[i],
                h,
                x,
                y,
                w,
                x_start,
                x_end,
                slope_start: 0.0,
                slope_end: 0.0,
            });
        }
        // The clamped ends interpolate the end control points: exact domain.
        if let Some(first) = spans.first_mut() {
            first.x_start = curve.points[0][0];
        }
        if let Some(last) = spans.last_mut() {
            last.x_end = curve.points[n][0];
        }
        // Interior span ends by de Boor evaluation (shared by neighbouring spans).
        for j in 1..spans.len() {
            let x = curve.eval(spans[j].u0)[0];
            spans[j - 1].x_end = x;
            spans[j].x_start = x;
        }
        for sp in &mut spans {
            // dx/ds = (X'W − XW')/W² at s = 0 and 1.
            let dxds = |s: f64| {
                let w = horner(&sp.w, p, s);
                (horner_derivative(&sp.x, p, s) * w
                    - horner(&sp.x, p, s) * horner_derivative(&sp.w, p, s))
                    / (w * w)
            };
            let dx = sp.x_end - sp.x_start;
            sp.slope_start = dx / dxds(0.0);
            sp.slope_end = dx / dxds(1.0);
        }
        let ends = spans[..spans.len() - 1].iter().map(|s| s.x_end).collect();
        Ok(CurveLookup {
            degree: p,
            spans,
            ends,
        })
    }

    /// `(x(a), x(b))`: the positions the curve covers.
    pub fn domain(&self) -> (f64, f64) {
        (
            self.spans[0].x_start,
            self.spans[self.spans.len() - 1].x_end,
        )
    }

    /// The curve parameter `u` with `x(u) = position` (clamped to the domain).
    pub fn parameter_at(&self, position: f64) -> f64 {
        let (span, s) = self.solve(position);
        let sp = &self.spans[span];
        sp.u0 + s * sp.h
    }

    /// `y(u)` where `x(u) = position`; `position` is clamped to [`Self::domain`].
    #[inline]
    pub fn value_at(&self, position: f64) -> f64 {
        let (span, s) = self.solve(position);
        let sp = &self.spans[span];
        horner(&sp.y, self.degree, s) / horner(&sp.w, self.degree, s)
    }

    /// Span index and local parameter `s` solving `x = position` to round-off.
    #[inline]
    fn solve(&self, position: f64) -> (usize, f64) {
        let i = self.ends.partition_point(|&e| e < position);
        let sp = &self.spans[i];
        let p = self.degree;
        if position <= sp.x_start {
            return (i, 0.0);
        }
        if position >= sp.x_end {
            return (i, 1.0);
        }
        // f(s) = X(s) − x0 W(s): f(0) < 0 < f(1), single root (x increasing, W > 0).
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        // Cubic Hermite model of s(x) on the span: a start within ~1e-4 or better.
        let t = (position - sp.x_start) / (sp.x_end - sp.x_start);
        let (t2, t3) = (t * t, t * t * t);
        let mut s = (t3 - 2.0 * t2 + t) * sp.slope_start
            + (-2.0 * t3 + 3.0 * t2)
            + (t3 - t2) * sp.slope_end;
        if !(s > 0.0 && s < 1.0) {
            s = t;
        }
        for _ in 0..60 {
            let f = horner(&sp.x, p, s) - position * horner(&sp.w, p, s);
            if f == 0.0 {
                return (i, s);
            }
            if f < 0.0 {
                lo = s;
            } else {
                hi = s;
            }
            let df = horner_derivative(&sp.x, p, s) - position * horner_derivative(&sp.w, p, s);
            let mut next = s - f / df;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            // Converged to round-off: a Newton step of 1e-12 leaves an error far below
            // it. (Stopping earlier, at 1e-8, made value_at noisy at the 1e-12 level,
            // which finite-difference slopes of callers amplify.)
            if (next - s).abs() <= 1e-12 || hi - lo <= 1e-15 {
                return (i, next);
            }
            s = next;
        }
        (i, s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverts_a_curve() {
        let curve = NurbsCurve::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.4, 1.0, 1.0, 1.0, 1.0],
            vec![1.0, 1.3, 0.7, 1.0, 1.1],
            vec![
                [0.0, 1.0],
                [10.0, -3.0],
                [30.0, 4.0],
                [45.0, 0.0],
                [50.0, 2.0],
            ],
        )
        .unwrap();
        let lookup = CurveLookup::new(&curve).unwrap();
        for k in 0..=200 {
            let u = k as f64 / 200.0;
            let [x, y] = curve.eval(u);
            assert!((lookup.value_at(x) - y).abs() < 1e-9);
            assert!((lookup.parameter_at(x) - u).abs() < 1e-9);
        }
        assert_eq!(lookup.domain(), (0.0, 50.0));
    }

    #[test]
    fn refuses_a_folding_curve() {
        let curve = NurbsCurve::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
            vec![1.0; 4],
            vec![[0.0, 0.0], [30.0, 1.0], [5.0, 2.0], [20.0, 3.0]],
        )
        .unwrap();
        assert!(matches!(
            CurveLookup::new(&curve),
            Err(LookupError::NotMonotonic { .. })
        ));
    }
}
