//! Parameters `ū_k` of the data points (the paper's eq. 11–12):
//! `ū_0 = 0, ū_m = 1, ū_i = ū_{i-1} + λ_i |Q_i − Q_{i−1}|^k / Σ_j λ_j |Q_j − Q_{j−1}|^k`.
//!
//! * uniform: λ = 1, k = 0; chord length: λ = 1, k = 1; centripetal: λ = 1, k = 1/2;
//! * corrected centripetal: k = 1/2 with the angle correction of Fang, Wang & Hung
//!   (2013): `λ_i = 1 + 3/2 (θ̂_{i−1} d_{i−1} / (d_{i−1} + d_i) + θ̂_i d_{i+1} / (d_i + d_{i+1}))`,
//!   `d_i = |Q_i − Q_{i−1}|`, `θ̂_i = min(π − θ_i, π/2)` with `θ_i` the angle at `Q_i`
//!   between `Q_{i−1}` and `Q_{i+1}`. (The extracted paper prints k = 1 for this case; a
//!   centripetal correction has k = 1/2, which is what is implemented.)
//!
//! The SMEM feeds points that were normalised to the unit square first (see
//! `smem.rs`), because positions (mm, deg) and errors (µm, µrad) have different units.
//!
//! Invariant of the result: `ū_0 = 0`, `ū_m = 1`, strictly increasing whenever the
//! points are pairwise distinct.
use serde::{Deserialize, Serialize};

/// How the data points get their curve parameters `ū_k` (the paper's eq. 11–12).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Parameterization {
    /// Equally spaced parameters (λ = 1, k = 0).
    Uniform,
    /// Proportional to chord length (λ = 1, k = 1).
    ChordLength,
    /// Proportional to the square root of chord length (λ = 1, k = 1/2); the default.
    #[default]
    Centripetal,
    /// Centripetal with the angle correction of Fang, Wang & Hung (2013).
    CorrectedCentripetal,
}

impl Parameterization {
    /// The name as the command line and files write it (`"chord-length"`, …).
    pub fn name(self) -> &'static str {
        match self {
            Parameterization::Uniform => "uniform",
            Parameterization::ChordLength => "chord-length",
            Parameterization::Centripetal => "centripetal",
            Parameterization::CorrectedCentripetal => "corrected-centripetal",
        }
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt()
}

/// Parameters of `points` (at least two) in `[0, 1]`. Coincident neighbours get
/// a zero step; callers reject repeated positions before this.
pub fn parameterize(points: &[[f64; 2]], method: Parameterization) -> Vec<f64> {
    let m = points.len();
    if m < 2 {
        return vec![0.0; m];
    }
    let d: Vec<f64> = points.windows(2).map(|w| dist(w[0], w[1])).collect();
    let steps: Vec<f64> = match method {
        Parameterization::Uniform => vec![1.0; m - 1],
        Parameterization::ChordLength => d.clone(),
        Parameterization::Centripetal => d.iter().map(|v| v.sqrt()).collect(),
        Parameterization::CorrectedCentripetal => {
            // θ̂ at every interior point (0 at the ends).
            let theta_hat: Vec<f64> = (0..m)
                .map(|i| {
                    if i == 0 || i + 1 == m {
                        return 0.0;
                    }
                    let a = [
                        points[i - 1][0] - points[i][0],
                        points[i - 1][1] - points[i][1],
                    ];
                    let b = [
                        points[i + 1][0] - points[i][0],
                        points[i + 1][1] - points[i][1],
                    ];
                    let na = (a[0] * a[0] + a[1] * a[1]).sqrt();
                    let nb = (b[0] * b[0] + b[1] * b[1]).sqrt();
                    if na == 0.0 || nb == 0.0 {
                        return 0.0;
                    }
                    let cos = ((a[0] * b[0] + a[1] * b[1]) / (na * nb)).clamp(-1.0, 1.0);
                    let theta = cos.acos();
                    (std::f64::consts::PI - theta).min(std::f64::consts::FRAC_PI_2)
                })
                .collect();
            // Step i (between points i and i+1) uses d[i] and its neighbours.
            (0..m - 1)
                .map(|i| {
                    let di = d[i];
                    let mut lambda = 1.0;
                    if i > 0 && d[i - 1] + di > 0.0 {
                        lambda += 1.5 * theta_hat[i] * d[i - 1] / (d[i - 1] + di);
                    }
                    if i + 1 < m - 1 && di + d[i + 1] > 0.0 {
                        lambda += 1.5 * theta_hat[i + 1] * d[i + 1] / (di + d[i + 1]);
                    }
                    lambda * di.sqrt()
                })
                .collect()
        }
    };
    let total: f64 = steps.iter().sum();
    let mut out = Vec::with_capacity(m);
    out.push(0.0);
    if total <= 0.0 || !total.is_finite() {
        out.extend((1..m).map(|i| i as f64 / (m - 1) as f64));
        return out;
    }
    let mut acc = 0.0;
    for s in &steps[..m - 2] {
        acc += s;
        out.push(acc / total);
    }
    out.push(1.0);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_on_a_hand_checked_case() {
        // Steps of length 1, 4 (x only): chord 1/5, centripetal 1/3, uniform 1/2.
        let pts = [[0.0, 0.0], [1.0, 0.0], [5.0, 0.0]];
        assert_eq!(
            parameterize(&pts, Parameterization::Uniform),
            vec![0.0, 0.5, 1.0]
        );
        assert_eq!(
            parameterize(&pts, Parameterization::ChordLength),
            vec![0.0, 0.2, 1.0]
        );
        let c = parameterize(&pts, Parameterization::Centripetal);
        assert!((c[1] - 1.0 / 3.0).abs() < 1e-15);
        // Collinear points: no turning, the correction vanishes.
        let cc = parameterize(&pts, Parameterization::CorrectedCentripetal);
        assert!((cc[1] - 1.0 / 3.0).abs() < 1e-15);
        // A right-angle turn lengthens the steps next to it equally here.
        let turn = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [2.0, 1.0]];
        let t = parameterize(&turn, Parameterization::CorrectedCentripetal);
        assert!((t[1] - (1.0 - t[2])).abs() < 1e-15);
    }
}
