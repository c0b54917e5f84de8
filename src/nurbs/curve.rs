//! Planar NURBS curves (the paper's eq. 1): `C(u) = Σ w_i P_i N_{i,p}(u) / Σ w_i N_{i,p}(u)`.
//!
//! Invariants: `knots` is a valid clamped vector for `degree` (see
//! [`knot_vector::is_valid_clamped`]), `weights.len() == points.len() ==
//! knots.len() - degree - 1`, every weight is finite and positive (so the
//! denominator never vanishes), `degree <= MAX_DEGREE`.
use serde::{Deserialize, Serialize};

use super::basis::{MAX_DEGREE, basis_funs, ders_basis_funs, find_span};
use super::knot_vector;

/// A planar NURBS curve `u ↦ (x, y)`, `u` in the knot range (for SMEM curves x is the axis position, y the error value).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NurbsCurve {
    /// Polynomial degree p (1..=`MAX_DEGREE`).
    pub degree: usize,
    /// Clamped knot vector, non-decreasing, `points.len() + degree + 1` knots.
    pub knots: Vec<f64>,
    /// Weight of each control point, finite and positive.
    pub weights: Vec<f64>,
    /// Control points `[x, y]`.
    pub points: Vec<[f64; 2]>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CurveError {
    #[error("degree {0} is outside 1..={MAX_DEGREE}")]
    Degree(usize),
    #[error("the knot vector is not a valid clamped vector for degree {0}")]
    Knots(usize),
    #[error(
        "{points} control points and {weights} weights do not match {knots} knots of degree {degree}"
    )]
    Counts {
        points: usize,
        weights: usize,
        knots: usize,
        degree: usize,
    },
    #[error("weights must be finite and positive")]
    Weights,
    #[error("control points must be finite")]
    Points,
}

impl NurbsCurve {
    /// A validated curve.
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        weights: Vec<f64>,
        points: Vec<[f64; 2]>,
    ) -> Result<Self, CurveError> {
        if degree == 0 || degree > MAX_DEGREE {
            return Err(CurveError::Degree(degree));
        }
        if !knot_vector::is_valid_clamped(&knots, degree) {
            return Err(CurveError::Knots(degree));
        }
        let count = knots.len() - degree - 1;
        if points.len() != count || weights.len() != count {
            return Err(CurveError::Counts {
                points: points.len(),
                weights: weights.len(),
                knots: knots.len(),
                degree,
            });
        }
        if weights.iter().any(|w| !w.is_finite() || *w <= 0.0) {
            return Err(CurveError::Weights);
        }
        if points.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CurveError::Points);
        }
        Ok(NurbsCurve {
            degree,
            knots,
            weights,
            points,
        })
    }

    /// Parameter domain `[u_p, u_{n+1}]`.
    pub fn domain(&self) -> (f64, f64) {
        (self.knots[0], self.knots[self.knots.len() - 1])
    }

    fn n(&self) -> usize {
        self.points.len() - 1
    }

    /// The point `C(u)`; `u` is clamped to the domain.
    pub fn eval(&self, u: f64) -> [f64; 2] {
        let p = self.degree;
        let span = find_span(self.n(), p, u, &self.knots);
        let mut basis = [0.0; MAX_DEGREE + 1];
        basis_funs(span, u, p, &self.knots, &mut basis);
        let (mut x, mut y, mut w) = (0.0, 0.0, 0.0);
        for j in 0..=p {
            let i = span - p + j;
            let bw = basis[j] * self.weights[i];
            x += bw * self.points[i][0];
            y += bw * self.points[i][1];
            w += bw;
        }
        [x / w, y / w]
    }

    /// `C(u)` and its derivatives up to order `nd` (Piegl & Tiller A4.2, the
    /// rational quotient rule applied to the homogeneous derivatives).
    pub fn derivatives(&self, u: f64, nd: usize) -> Vec<[f64; 2]> {
        let p = self.degree;
        let span = find_span(self.n(), p, u, &self.knots);
        let ders = ders_basis_funs(span, u, p, nd, &self.knots);
        // Homogeneous derivatives A^(k) (weighted point) and w^(k).
        let mut a = vec![[0.0; 2]; nd + 1];
        let mut w = vec![0.0; nd + 1];
        for k in 0..=nd {
            for j in 0..=p {
                let i = span - p + j;
                let bw = ders[k][j] * self.weights[i];
                a[k][0] += bw * self.points[i][0];
                a[k][1] += bw * self.points[i][1];
                w[k] += bw;
            }
        }
        let mut out: Vec<[f64; 2]> = vec![[0.0; 2]; nd + 1];
        for k in 0..=nd {
            let mut v = a[k];
            for i in 1..=k {
                let c = binomial(k, i) * w[i];
                v[0] -= c * out[k - i][0];
                v[1] -= c * out[k - i][1];
            }
            out[k] = [v[0] / w[0], v[1] / w[0]];
        }
        out
    }
}

/// Binomial coefficient as f64 (small arguments).
pub fn binomial(n: usize, k: usize) -> f64 {
    if k > n {
        return 0.0;
    }
    let mut r = 1.0;
    for i in 0..k.min(n - k) {
        r = r * (n - i) as f64 / (i + 1) as f64;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quarter_circle() -> NurbsCurve {
        // Exact quarter circle: degree 2, middle weight sqrt(2)/2.
        NurbsCurve::new(
            2,
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            vec![1.0, std::f64::consts::FRAC_1_SQRT_2, 1.0],
            vec![[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        )
        .unwrap()
    }

    #[test]
    fn rational_curve_is_exact_circle() {
        let c = quarter_circle();
        for k in 0..=20 {
            let [x, y] = c.eval(k as f64 / 20.0);
            assert!((x * x + y * y - 1.0).abs() < 1e-14);
        }
        assert_eq!(c.eval(0.0), [1.0, 0.0]);
        assert_eq!(c.eval(1.0), [0.0, 1.0]);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let c = quarter_circle();
        let u = 0.37;
        let h = 1e-5;
        let d = c.derivatives(u, 2);
        let (p, m) = (c.eval(u + h), c.eval(u - h));
        let z = c.eval(u);
        for k in 0..2 {
            assert!((d[0][k] - z[k]).abs() < 1e-14);
            assert!((d[1][k] - (p[k] - m[k]) / (2.0 * h)).abs() < 1e-7);
            assert!((d[2][k] - (p[k] - 2.0 * z[k] + m[k]) / (h * h)).abs() < 1e-3);
        }
        // On a circle the velocity is tangent.
        assert!((d[0][0] * d[1][0] + d[0][1] * d[1][1]).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_curves() {
        assert_eq!(
            NurbsCurve::new(
                2,
                vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
                vec![1.0, -1.0, 1.0],
                vec![[0.0; 2]; 3]
            ),
            Err(CurveError::Weights)
        );
        assert!(matches!(
            NurbsCurve::new(
                2,
                vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
                vec![1.0; 2],
                vec![[0.0; 2]; 3]
            ),
            Err(CurveError::Counts { .. })
        ));
    }
}
