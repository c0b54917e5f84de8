//! The noise floor: the scatter of residuals that no smooth effect can explain.
//!
//! Estimator (a robust Gasser–Sroka–Jennen-Steinmetz difference estimator along
//! the cut): points in cutting order; for every triple of consecutive points with
//! the same direction of travel σ and gaps ≤ 3× the median gap, the pseudo-residual
//! `e = r_i − (w r_{i−1} + (1−w) r_{i+1})` (linear interpolation by distance along
//! the part) has variance `σ²(1 + w² + (1−w)²)` for smooth signal plus white
//! noise. With `z² = e²/(1 + w² + (1−w)²)` ~ σ²χ²₁, `σ̂² = mean(z² ≤ its 90 %
//! quantile) / 0.6230` (the mean of χ²₁ below its 90 % quantile): a trimmed mean,
//! so the few triples that straddle a step (a reversal, a block edge) do not
//! inflate it, with far less scatter than a median.
//!
//! Invariant: linear trends along the cut cancel exactly; the estimate is ≥ 0 and finite.
use crate::toolpath::PointContext;

/// Mean of χ²₁ restricted to values below its 90 % quantile (2.7055):
/// P(χ²₃ ≤ 2.7055) / 0.9.
const CHI2_1_TRIMMED_MEAN: f64 = 0.623_015_484_134_681_9;
/// Fraction of the pseudo-residuals kept.
const KEEP: f64 = 0.9;

fn distance(a: &PointContext, b: &PointContext) -> f64 {
    (0..3)
        .map(|k| (a.point[k] - b.point[k]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Estimate the noise floor (µm, one standard deviation) of residuals `r`
/// at `contexts` (same order).
pub fn estimate_noise_floor(contexts: &[&PointContext], r: &[f64]) -> f64 {
    let n = contexts.len();
    if n < 3 {
        return rms(r);
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        contexts[a]
            .time_min
            .total_cmp(&contexts[b].time_min)
            .then(contexts[a].block.cmp(&contexts[b].block))
            .then(a.cmp(&b))
    });
    let mut gaps: Vec<f64> = order
        .windows(2)
        .map(|w| distance(contexts[w[0]], contexts[w[1]]))
        .collect();
    gaps.sort_by(f64::total_cmp);
    let limit = 3.0 * gaps[gaps.len() / 2].max(1e-9);
    let collect = |strict: bool| -> Vec<f64> {
        order
            .windows(3)
            .filter_map(|w| {
                let (a, b, c) = (contexts[w[0]], contexts[w[1]], contexts[w[2]]);
                let (d1, d2) = (distance(a, b), distance(b, c));
                if strict && (a.sigma != b.sigma || b.sigma != c.sigma || d1 > limit || d2 > limit)
                {
                    return None;
                }
                let w_prev = if d1 + d2 > 1e-12 { d2 / (d1 + d2) } else { 0.5 };
                let e = r[w[1]] - (w_prev * r[w[0]] + (1.0 - w_prev) * r[w[2]]);
                let c2 = 1.0 + w_prev * w_prev + (1.0 - w_prev).powi(2);
                Some(e * e / c2)
            })
            .collect()
    };
    let mut z = collect(true);
    if z.len() < 5 {
        z = collect(false);
    }
    if z.is_empty() {
        return rms(r);
    }
    z.sort_by(f64::total_cmp);
    let keep = ((z.len() as f64 * KEEP).round() as usize).clamp(1, z.len());
    let mean = z[..keep].iter().sum::<f64>() / keep as f64;
    (mean / CHI2_1_TRIMMED_MEAN).sqrt()
}

pub use crate::inspection::rms;
