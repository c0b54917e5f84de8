//! B-spline basis functions (the paper's eq. 2, Cox–de Boor recursion).
//!
//! Knot vectors are non-decreasing; a basis of degree `p` over `n + 1` control
//! points uses `n + p + 2` knots. Spans are half-open `[u_i, u_{i+1})` except the
//! last non-empty one, which also owns the right end `u = u_{n+1}` (the usual
//! right-end handling, so a clamped curve reaches its last control point).

/// Highest degree supported by the fixed-size work arrays (the SMEM uses 3).
pub const MAX_DEGREE: usize = 7;

/// Index `i` of the knot span with `knots[i] <= u < knots[i + 1]`, `p <= i <= n`,
/// for a basis of `n + 1` functions (Piegl & Tiller A2.1). `u` is clamped to the
/// domain `[knots[p], knots[n + 1]]`; the right end maps to the last non-empty span.
pub fn find_span(n: usize, p: usize, u: f64, knots: &[f64]) -> usize {
    if u >= knots[n + 1] {
        // Last non-empty span (skip repeated end knots).
        let mut i = n;
        while i > p && knots[i] >= knots[n + 1] {
            i -= 1;
        }
        return i;
    }
    if u <= knots[p] {
        let mut i = p;
        while i < n && knots[i + 1] <= knots[p] {
            i += 1;
        }
        return i;
    }
    // Binary search in knots[p..=n+1].
    let (mut low, mut high) = (p, n + 1);
    while high - low > 1 {
        let mid = (low + high) / 2;
        if u < knots[mid] {
            high = mid;
        } else {
            low = mid;
        }
    }
    low
}

/// The `p + 1` non-zero basis functions `N_{span-p..=span, p}(u)` into `out[..=p]`
/// (Piegl & Tiller A2.2). `out.len() > p`, `p <= MAX_DEGREE`.
pub fn basis_funs(span: usize, u: f64, p: usize, knots: &[f64], out: &mut [f64]) {
    let mut left = [0.0; MAX_DEGREE + 1];
    let mut right = [0.0; MAX_DEGREE + 1];
    out[0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            let denom = right[r + 1] + left[j - r];
            let temp = if denom != 0.0 { out[r] / denom } else { 0.0 };
            out[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        out[j] = saved;
    }
}

/// Basis functions and their derivatives up to order `nd` at `u` (Piegl & Tiller
/// A2.3): `ders[k][j]` is the k-th derivative of `N_{span-p+j, p}(u)`; orders above
/// `p` are zero.
pub fn ders_basis_funs(span: usize, u: f64, p: usize, nd: usize, knots: &[f64]) -> Vec<Vec<f64>> {
    let mut out = [[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1];
    ders_basis_funs_into(span, u, p, nd.min(MAX_DEGREE), knots, &mut out);
    (0..=nd)
        .map(|k| {
            if k <= MAX_DEGREE {
                out[k][..=p].to_vec()
            } else {
                vec![0.0; p + 1]
            }
        })
        .collect()
}

/// [`ders_basis_funs`] without allocating: `ders[k][j]` for `k <= nd`, `j <= p`
/// (`nd, p <= MAX_DEGREE`); the rest of `ders` is left as it was.
pub fn ders_basis_funs_into(
    span: usize,
    u: f64,
    p: usize,
    nd: usize,
    knots: &[f64],
    ders: &mut [[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1],
) {
    let mut ndu = [[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1];
    let mut left = [0.0; MAX_DEGREE + 1];
    let mut right = [0.0; MAX_DEGREE + 1];
    ndu[0][0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            ndu[j][r] = right[r + 1] + left[j - r];
            let temp = if ndu[j][r] != 0.0 {
                ndu[r][j - 1] / ndu[j][r]
            } else {
                0.0
            };
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    for row in ders.iter_mut().take(nd + 1) {
        row[..=p].iter_mut().for_each(|v| *v = 0.0);
    }
    for j in 0..=p {
        ders[0][j] = ndu[j][p];
    }
    let mut a = [[0.0; MAX_DEGREE + 1]; 2];
    for r in 0..=p {
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0][0] = 1.0;
        for k in 1..=nd.min(p) {
            let mut d = 0.0;
            let rk = r as isize - k as isize;
            let pk = p - k;
            if r >= k {
                let denom = ndu[pk + 1][rk as usize];
                a[s2][0] = if denom != 0.0 { a[s1][0] / denom } else { 0.0 };
                d = a[s2][0] * ndu[rk as usize][pk];
            }
            let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
            let j2 = if r as isize - 1 <= pk as isize {
                k - 1
            } else {
                p - r
            };
            for j in j1..=j2 {
                let idx = (rk + j as isize) as usize;
                let denom = ndu[pk + 1][idx];
                a[s2][j] = if denom != 0.0 {
                    (a[s1][j] - a[s1][j - 1]) / denom
                } else {
                    0.0
                };
                d += a[s2][j] * ndu[idx][pk];
            }
            if r as isize <= pk as isize {
                let denom = ndu[pk + 1][r];
                a[s2][k] = if denom != 0.0 {
                    -a[s1][k - 1] / denom
                } else {
                    0.0
                };
                d += a[s2][k] * ndu[r][pk];
            }
            ders[k][r] = d;
            std::mem::swap(&mut s1, &mut s2);
        }
    }
    let mut factor = p as f64;
    for k in 1..=nd.min(p) {
        for j in 0..=p {
            ders[k][j] *= factor;
        }
        factor *= (p - k) as f64;
    }
}

/// One basis function `N_{i,p}(u)` by the plain Cox–de Boor recursion (eq. 2), with
/// the right-end convention of [`find_span`]. Slow; the reference for tests.
#[cfg(test)]
pub fn basis_function(i: usize, p: usize, u: f64, knots: &[f64]) -> f64 {
    let last = knots.len() - 1;
    if p == 0 {
        let (a, b) = (knots[i], knots[i + 1]);
        if a <= u && u < b {
            return 1.0;
        }
        // Right end: the last non-empty span is closed.
        if u == knots[last] && b == knots[last] && a < b {
            return 1.0;
        }
        return 0.0;
    }
    let mut value = 0.0;
    let d1 = knots[i + p] - knots[i];
    if d1 != 0.0 {
        value += (u - knots[i]) / d1 * basis_function(i, p - 1, u, knots);
    }
    let d2 = knots[i + p + 1] - knots[i + 1];
    if d2 != 0.0 {
        value += (knots[i + p + 1] - u) / d2 * basis_function(i + 1, p - 1, u, knots);
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn algorithms_agree_with_recursion() {
        let knots = [0.0, 0.0, 0.0, 0.0, 0.2, 0.5, 0.5, 0.8, 1.0, 1.0, 1.0, 1.0];
        let p = 3;
        let n = knots.len() - p - 2;
        for k in 0..=100 {
            let u = k as f64 / 100.0;
            let span = find_span(n, p, u, &knots);
            let mut out = [0.0; 4];
            basis_funs(span, u, p, &knots, &mut out);
            let ders = ders_basis_funs(span, u, p, 2, &knots);
            for j in 0..=p {
                let r = basis_function(span - p + j, p, u, &knots);
                assert!((out[j] - r).abs() < 1e-12, "u={u} j={j}");
                assert!((ders[0][j] - r).abs() < 1e-12);
            }
            assert!((out.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            // Derivatives of a partition of unity sum to zero.
            assert!(ders[1].iter().sum::<f64>().abs() < 1e-9);
        }
    }

    #[test]
    fn derivative_matches_finite_difference() {
        let knots = [0.0, 0.0, 0.0, 0.0, 0.3, 0.6, 1.0, 1.0, 1.0, 1.0];
        let p = 3;
        let n = knots.len() - p - 2;
        let u = 0.41;
        let h = 1e-6;
        let span = find_span(n, p, u, &knots);
        let ders = ders_basis_funs(span, u, p, 1, &knots);
        for j in 0..=p {
            let i = span - p + j;
            let fd = (basis_function(i, p, u + h, &knots) - basis_function(i, p, u - h, &knots))
                / (2.0 * h);
            assert!((ders[1][j] - fd).abs() < 1e-5);
        }
    }
}
