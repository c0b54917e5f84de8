//! Clamped (open, non-periodic) knot vectors, the paper's eq. 3:
//! `U = {a,…,a, u_{p+1},…,u_n, b,…,b}` with `p + 1` copies of each end.
//!
//! Invariant of every vector built here: non-decreasing, ends repeated `p + 1`
//! times, interior knots strictly inside `(a, b)`, length `n + p + 2` for `n + 1`
//! control points.

/// A clamped knot vector on `[a, b]` from its interior knots (sorted, strictly
/// inside `(a, b)`; not checked here, see `is_valid_clamped`).
pub fn clamped(p: usize, interior: &[f64], a: f64, b: f64) -> Vec<f64> {
    let mut knots = Vec::with_capacity(interior.len() + 2 * (p + 1));
    knots.extend(std::iter::repeat_n(a, p + 1));
    knots.extend_from_slice(interior);
    knots.extend(std::iter::repeat_n(b, p + 1));
    knots
}

/// The interior knots `u_{p+1} … u_n` of a clamped vector.
pub fn interior(knots: &[f64], p: usize) -> &[f64] {
    &knots[p + 1..knots.len() - p - 1]
}

/// Number of control points a clamped vector of degree `p` carries.
pub fn control_point_count(knots: &[f64], p: usize) -> usize {
    knots.len() - p - 1
}

/// Does `knots` satisfy the invariant above for degree `p`, with interior knots
/// of multiplicity at most `p` (so the curve stays continuous)?
pub fn is_valid_clamped(knots: &[f64], p: usize) -> bool {
    if knots.len() < 2 * (p + 1) || knots.iter().any(|k| !k.is_finite()) {
        return false;
    }
    let a = knots[0];
    let b = knots[knots.len() - 1];
    if a >= b
        || knots[..=p].iter().any(|&k| k != a)
        || knots[knots.len() - p - 1..].iter().any(|&k| k != b)
    {
        return false;
    }
    if knots.windows(2).any(|w| w[1] < w[0]) {
        return false;
    }
    let inner = interior(knots, p);
    if inner.iter().any(|&k| k <= a || k >= b) {
        return false;
    }
    let mut run = 1;
    for w in inner.windows(2) {
        run = if w[0] == w[1] { run + 1 } else { 1 };
        if run > p {
            return false;
        }
    }
    true
}

/// The Greville abscissae `(u_{i+1} + … + u_{i+p}) / p` of each control point.
pub fn greville(knots: &[f64], p: usize) -> Vec<f64> {
    let count = control_point_count(knots, p);
    (0..count)
        .map(|i| {
            if p == 0 {
                knots[i]
            } else {
                knots[i + 1..=i + p].iter().sum::<f64>() / p as f64
            }
        })
        .collect()
}

/// Schoenberg–Whitney condition for a least-squares fit with both ends
/// interpolated: each basis function `N_i` (`0 <= i <= n`) can be matched to a
/// distinct data parameter inside its support (greedy matching is exact because
/// the supports are ordered at both ends). `params` sorted, in `[a, b]`.
/// Without it the normal matrix is singular.
pub fn schoenberg_whitney(knots: &[f64], p: usize, params: &[f64]) -> bool {
    let count = control_point_count(knots, p);
    if params.len() < count {
        return false;
    }
    let a = knots[0];
    let b = knots[knots.len() - 1];
    let mut k = 0;
    for i in 0..count {
        let lo = knots[i];
        let hi = knots[i + p + 1];
        loop {
            if k >= params.len() {
                return false;
            }
            let t = params[k];
            let inside_lo = t > lo || (i == 0 && t == a);
            let inside_hi = t < hi || (i + 1 == count && t == b);
            if inside_lo && inside_hi {
                k += 1;
                break;
            }
            if !inside_hi {
                return false;
            }
            k += 1;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_and_validates() {
        let k = clamped(3, &[0.25, 0.5], 0.0, 1.0);
        assert_eq!(k.len(), 2 + 8);
        assert!(is_valid_clamped(&k, 3));
        assert_eq!(control_point_count(&k, 3), 6);
        assert!(!is_valid_clamped(&clamped(3, &[0.5, 0.25], 0.0, 1.0), 3));
        assert!(!is_valid_clamped(
            &clamped(3, &[0.5, 0.5, 0.5, 0.5], 0.0, 1.0),
            3
        ));
        assert!(!is_valid_clamped(&clamped(3, &[1.0], 0.0, 1.0), 3));
    }

    #[test]
    fn schoenberg_whitney_detects_empty_spans() {
        let params: Vec<f64> = (0..=10).map(|i| i as f64 / 10.0).collect();
        assert!(schoenberg_whitney(
            &clamped(3, &[0.5], 0.0, 1.0),
            3,
            &params
        ));
        // Three knots in a gap between data: N_i needs a datum inside its support.
        let few = [0.0, 0.1, 0.2, 0.9, 1.0];
        assert!(!schoenberg_whitney(
            &clamped(3, &[0.4, 0.5, 0.6], 0.0, 1.0),
            3,
            &few
        ));
    }
}
