//! Classic interior-knot placements on the parameter domain `[0, 1]`, for `n + 1`
//! control points of degree `p` and data parameters `ū_0 … ū_m` (m + 1 points).
//! Each returns the `n − p` interior knots, sorted.
//!
//! * UKM (eq. 13): `u_{j+p} = j / (n − p + 1)`.
//! * EPM (eq. 14, Piegl & Tiller eq. 9.69): `d = (m + 1)/(n − p + 1)`,
//!   `i = ⌊j d⌋`, `α = j d − i`, `u_{j+p} = (1 − α) ū_{i−1} + α ū_i`.
//! * LAM (eq. 15, averaging over windows of `m − n + p` parameters):
//!   `u_{j+p} = (1/(m − n + p)) Σ_{i=j}^{m−n+p+j−1} ū_i`; for `m = n` this is de
//!   Boor's averaging (Piegl & Tiller eq. 9.8).
//! * grid knots: the `M − 1` candidates `j / M` of a uniform grid of `M` segments
//!   (the search space of §3.2.2).

/// UKM, eq. 13.
pub fn uniform(n: usize, p: usize) -> Vec<f64> {
    let k = n - p;
    (1..=k).map(|j| j as f64 / (k + 1) as f64).collect()
}

/// EPM, eq. 14. `params.len() = m + 1 >= n + 1`.
pub fn equal_partition(params: &[f64], n: usize, p: usize) -> Vec<f64> {
    let k = n - p;
    let d = params.len() as f64 / (k + 1) as f64;
    (1..=k)
        .map(|j| {
            let jd = j as f64 * d;
            let i = (jd.floor() as usize).clamp(1, params.len() - 1);
            let alpha = jd - i as f64;
            (1.0 - alpha) * params[i - 1] + alpha * params[i]
        })
        .collect()
}

/// LAM, eq. 15. `params.len() = m + 1 >= n + 1`.
pub fn local_average(params: &[f64], n: usize, p: usize) -> Vec<f64> {
    let m = params.len() - 1;
    let k = n - p;
    let window = m - n + p;
    (1..=k)
        .map(|j| params[j..j + window].iter().sum::<f64>() / window as f64)
        .collect()
}

/// The candidate knot `index` (1..M) of a uniform grid of `segments` segments.
pub fn grid_knot(index: usize, segments: usize) -> f64 {
    index as f64 / segments as f64
}

/// Interior knots from sorted grid indices.
pub fn grid_knots(indices: &[usize], segments: usize) -> Vec<f64> {
    indices.iter().map(|&i| grid_knot(i, segments)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_checked_knots() {
        // n = 5, p = 3: two interior knots.
        assert_eq!(uniform(5, 3), vec![1.0 / 3.0, 2.0 / 3.0]);
        let params: Vec<f64> = (0..=8).map(|i| i as f64 / 8.0).collect();
        // d = 9/3 = 3: j = 1 -> i = 3, α = 0 -> ū_2 = 0.25; j = 2 -> ū_5 = 0.625.
        assert_eq!(equal_partition(&params, 5, 3), vec![0.25, 0.625]);
        // m = 8, window = 8 - 5 + 3 = 6: mean(ū_1..ū_6) = 3.5/8, mean(ū_2..ū_7) = 4.5/8.
        let lam = local_average(&params, 5, 3);
        assert!((lam[0] - 3.5 / 8.0).abs() < 1e-15 && (lam[1] - 4.5 / 8.0).abs() < 1e-15);
        assert_eq!(grid_knots(&[4, 6], 13), vec![4.0 / 13.0, 6.0 / 13.0]);
    }
}
