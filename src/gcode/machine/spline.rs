//! The curves of LinuxCNC's spline codes, and their straight pieces.
//!
//! LinuxCNC's interpreter turns G5 (cubic), G5.1 (quadratic) and the NURBS of
//! G5.2 … G5.3 into one canonical call, `NURBS_FEED(control points, order k)`
//! (`interp_convert.cc`, `convert_spline` and `convert_nurbs`): control points
//! X Y with weights W, in the XY plane, in program coordinates. The curve is
//! the NURBS of order k (degree k − 1) over LinuxCNC's knot vector
//! (`knot_vector_creator`): k zeros, then 1, 2, …, n − k + 1, then k times
//! n − k + 2, for control points 0 … n; the parameter runs from 0 to
//! n − k + 2. G5 is the cubic Bézier curve through the start, start + (I, J),
//! end + (P, Q) and the end (k = 4, weights 1), G5.1 the quadratic one
//! through the start, start + (I, J) and the end (k = 3).
//!
//! LinuxCNC's motion planner follows the curve with biarcs through
//! 4 × (n + 1) points of it (`emccanon.cc`); volcomp follows the curve itself,
//! with straight pieces that stay within a given distance of it
//! ([`chords`]). Pure geometry: no I/O, no machine.

/// A control point: X Y (program coordinates, mm) and its weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlPoint {
    pub x: f64,
    pub y: f64,
    pub w: f64,
}

/// A NURBS curve in the XY plane as LinuxCNC's `NURBS_FEED` receives it.
#[derive(Clone, Debug, PartialEq)]
pub struct Nurbs {
    pub points: Vec<ControlPoint>,
    /// Order k (degree k − 1), 2 ≤ k ≤ number of points.
    pub order: usize,
}

/// Why a curve cannot be followed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SplineError {
    #[error("the curve is not finite (a weight of 0 or less makes its denominator vanish)")]
    NonFinite,
    #[error("the curve needs more than {0} straight pieces to stay within the tolerance of it")]
    TooManyPieces(usize),
}

impl Nurbs {
    /// LinuxCNC's knot vector for `points.len()` points and order `k`.
    fn knots(&self) -> Vec<f64> {
        let n = self.points.len() - 1;
        let k = self.order;
        (0..=n + k)
            .map(|i| {
                if i < k {
                    0.0
                } else if i <= n {
                    (i - k + 1) as f64
                } else {
                    (n - k + 2) as f64
                }
            })
            .collect()
    }

    /// The end of the parameter range (n − k + 2).
    pub fn u_max(&self) -> f64 {
        (self.points.len() + 1 - self.order) as f64
    }

    /// The point at parameter `u` ∈ [0, [`Nurbs::u_max`]] (de Boor on the
    /// weighted points).
    #[cfg(test)]
    pub fn point(&self, u: f64) -> [f64; 2] {
        let knots = self.knots();
        self.point_with(&knots, u)
    }

    fn point_with(&self, knots: &[f64], u: f64) -> [f64; 2] {
        let u = u.clamp(0.0, self.u_max());
        de_boor(
            |i| {
                let c = self.points[i];
                ([c.x, c.y], c.w)
            },
            self.points.len(),
            self.order - 1,
            knots,
            u,
        )
    }
}

/// A rational B-spline (NURBS) curve in `D` dimensions: control points,
/// their weights, the degree and a clamped knot vector of
/// `points.len() + degree + 1` knots; the parameter runs from
/// `knots[degree]` to `knots[points.len()]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RationalCurve<const D: usize> {
    pub points: Vec<[f64; D]>,
    pub weights: Vec<f64>,
    pub degree: usize,
    pub knots: Vec<f64>,
}

impl<const D: usize> RationalCurve<D> {
    /// The point at parameter `u` (clamped to the curve's range).
    pub fn point(&self, u: f64) -> [f64; D] {
        let n = self.points.len();
        let u = u.clamp(self.knots[self.degree], self.knots[n]);
        de_boor(
            |i| (self.points[i], self.weights[i]),
            n,
            self.degree,
            &self.knots,
            u,
        )
    }
}

/// De Boor's algorithm on the weighted points (homogeneous coordinates):
/// the point at `u` of the rational B-spline of `count` control points
/// (`point(i)`: the point and its weight), `degree` and `knots`.
fn de_boor<const D: usize>(
    point: impl Fn(usize) -> ([f64; D], f64),
    count: usize,
    degree: usize,
    knots: &[f64],
    u: f64,
) -> [f64; D] {
    let n = count - 1;
    let p = degree;
    // The span: knots[s] <= u < knots[s + 1], s in p ..= n.
    let mut s = p;
    while s < n && u >= knots[s + 1] {
        s += 1;
    }
    let mut d: Vec<([f64; D], f64)> = (0..=p)
        .map(|j| {
            let (c, w) = point(s - p + j);
            (c.map(|v| v * w), w)
        })
        .collect();
    for r in 1..=p {
        for j in (r..=p).rev() {
            let i = s - p + j;
            let denom = knots[i + p + 1 - r] - knots[i];
            let a = if denom == 0.0 {
                0.0
            } else {
                (u - knots[i]) / denom
            };
            for c in 0..D {
                d[j].0[c] = (1.0 - a) * d[j - 1].0[c] + a * d[j].0[c];
            }
            d[j].1 = (1.0 - a) * d[j - 1].1 + a * d[j].1;
        }
    }
    let (x, w) = d[p];
    x.map(|v| v / w)
}

/// Straight pieces that follow `curve` within `tolerance_mm`: the ends of the
/// pieces (the curve's points, its last point included, its first not), at
/// most `max_pieces`. Every piece is checked at three points inside it.
pub fn chords(
    curve: &Nurbs,
    tolerance_mm: f64,
    max_pieces: usize,
) -> Result<Vec<[f64; 2]>, SplineError> {
    let knots = curve.knots();
    let at = |u: f64| curve.point_with(&knots, u);
    // Start from four pieces per control point (LinuxCNC's own division).
    let mut out = chords_over(
        &at,
        (0.0, curve.u_max()),
        4 * curve.points.len(),
        tolerance_mm,
        max_pieces,
    )?;
    // The last point is the last control point exactly (clamped knots).
    if let (Some(last), Some(end)) = (out.last_mut(), curve.points.last()) {
        *last = [end.x, end.y];
    }
    Ok(out)
}

/// Straight pieces that follow the curve `at` from parameter `u0` to `u1`
/// within `tolerance_mm`: the ends of the pieces (the curve's points at
/// increasing parameters, `at(u1)` last, `at(u0)` not), at most
/// `max_pieces`. It starts from `first` equal pieces and halves a piece
/// while one of three points inside it (a quarter, half, three quarters)
/// is farther from it than the tolerance.
pub fn chords_over<const D: usize>(
    at: &dyn Fn(f64) -> [f64; D],
    (u0, u1): (f64, f64),
    first: usize,
    tolerance_mm: f64,
    max_pieces: usize,
) -> Result<Vec<[f64; D]>, SplineError> {
    let span = u1 - u0;
    let first = first.max(1);
    let mut out = Vec::new();
    let tol = tolerance_mm.max(1e-9);
    let finite = |p: &[f64; D]| p.iter().all(|v| v.is_finite());
    // (from, to, the curve's point at each end when known).
    type Piece<const D: usize> = (f64, f64, Option<[f64; D]>, Option<[f64; D]>);
    let mut stack: Vec<Piece<D>> = Vec::new();
    let mut a = at(u0);
    if !finite(&a) {
        return Err(SplineError::NonFinite);
    }
    for i in (1..=first).rev() {
        let (v0, v1) = (
            u0 + span * (i - 1) as f64 / first as f64,
            u0 + span * i as f64 / first as f64,
        );
        stack.push((v0, v1, None, None));
    }
    while let Some((v0, v1, p0, p1)) = stack.pop() {
        let p0 = p0.unwrap_or(a);
        let p1 = p1.unwrap_or_else(|| at(v1));
        if !finite(&p1) {
            return Err(SplineError::NonFinite);
        }
        let mut worst = 0.0f64;
        for f in [0.25, 0.5, 0.75] {
            let q = at(v0 + f * (v1 - v0));
            if !finite(&q) {
                return Err(SplineError::NonFinite);
            }
            worst = worst.max(distance_to_segment(q, p0, p1));
        }
        // A piece shorter than a nanometre in parameter is not split again.
        if worst > tol && (v1 - v0) > 1e-12 * span.max(1.0) {
            let vm = 0.5 * (v0 + v1);
            let pm = at(vm);
            stack.push((vm, v1, Some(pm), Some(p1)));
            stack.push((v0, vm, Some(p0), Some(pm)));
            if out.len() + stack.len() > max_pieces {
                return Err(SplineError::TooManyPieces(max_pieces));
            }
            continue;
        }
        out.push(p1);
        a = p1;
        if out.len() > max_pieces {
            return Err(SplineError::TooManyPieces(max_pieces));
        }
    }
    Ok(out)
}

/// The distance of `q` from the segment `a`–`b`.
pub fn distance_to_segment<const D: usize>(q: [f64; D], a: [f64; D], b: [f64; D]) -> f64 {
    let mut len2 = 0.0;
    let mut along = 0.0;
    for k in 0..D {
        let d = b[k] - a[k];
        len2 += d * d;
        along += (q[k] - a[k]) * d;
    }
    let t = if len2 > 0.0 {
        (along / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let e: [f64; D] = std::array::from_fn(|k| q[k] - a[k] - t * (b[k] - a[k]));
    if D == 2 {
        e[0].hypot(e[1])
    } else {
        e.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cp(x: f64, y: f64) -> ControlPoint {
        ControlPoint { x, y, w: 1.0 }
    }

    #[test]
    fn g5_is_the_cubic_bezier_curve() {
        let c = Nurbs {
            points: vec![cp(0.0, 0.0), cp(5.0, 0.0), cp(15.0, 10.0), cp(20.0, 10.0)],
            order: 4,
        };
        assert_eq!(c.u_max(), 1.0);
        for t in [0.0, 0.1, 0.37, 0.5, 0.9, 1.0] {
            let b = |p0: f64, p1: f64, p2: f64, p3: f64| {
                let s = 1.0 - t;
                s * s * s * p0 + 3.0 * s * s * t * p1 + 3.0 * s * t * t * p2 + t * t * t * p3
            };
            let p = c.point(t);
            assert!((p[0] - b(0.0, 5.0, 15.0, 20.0)).abs() < 1e-12);
            assert!((p[1] - b(0.0, 0.0, 10.0, 10.0)).abs() < 1e-12);
        }
    }

    #[test]
    fn a_quadratic_with_weights_is_a_circle() {
        // The quarter circle as a rational quadratic: weights 1, √2/2, 1.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let c = Nurbs {
            points: vec![
                cp(10.0, 0.0),
                ControlPoint {
                    x: 10.0,
                    y: 10.0,
                    w: h,
                },
                cp(0.0, 10.0),
            ],
            order: 3,
        };
        for i in 0..=20 {
            let p = c.point(i as f64 / 20.0);
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-12, "{p:?}");
        }
        // Its pieces stay within the tolerance of the circle.
        let pieces = chords(&c, 1e-4, 10_000).unwrap();
        let mut from = [10.0, 0.0];
        for p in &pieces {
            let mid = [(from[0] + p[0]) / 2.0, (from[1] + p[1]) / 2.0];
            assert!(10.0 - mid[0].hypot(mid[1]) <= 1.0001e-4);
            from = *p;
        }
        assert_eq!(*pieces.last().unwrap(), [0.0, 10.0]);
    }

    #[test]
    fn knots_are_linuxcncs() {
        let c = Nurbs {
            points: (0..6).map(|i| cp(i as f64, 0.0)).collect(),
            order: 3,
        };
        assert_eq!(c.knots(), vec![0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 4.0]);
        assert_eq!(c.u_max(), 4.0);
        // Clamped: the ends are the end points.
        assert_eq!(c.point(0.0), [0.0, 0.0]);
        assert_eq!(c.point(4.0), [5.0, 0.0]);
    }

    #[test]
    fn too_many_pieces_is_an_error() {
        let c = Nurbs {
            points: vec![cp(0.0, 0.0), cp(50.0, 100.0), cp(100.0, 0.0)],
            order: 3,
        };
        assert_eq!(chords(&c, 1e-9, 100), Err(SplineError::TooManyPieces(100)));
    }
}
