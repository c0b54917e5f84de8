//! Where the gap lies: worst points and blocks, residual RMS by time band, by
//! region of the part, by A and C range, and by direction of travel.
//!
//! Invariant: every group lists its point count; empty groups are left out.
use super::noise::rms;
use super::report::{
    AngleBand, BlockResidual, DirectionGroup, Localization, Region, TimeBand, WorstPoint,
};
use crate::toolpath::PointContext;
use std::collections::BTreeMap;

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Equal-width bands of `key` over `[lo, hi]`: (from, to, residuals).
fn bands(keys: &[f64], r: &[f64], count: usize) -> Vec<(f64, f64, Vec<f64>)> {
    let lo = keys.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = keys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !lo.is_finite() {
        return Vec::new();
    }
    let count = if hi - lo < 1e-9 { 1 } else { count.max(1) };
    let width = ((hi - lo) / count as f64).max(1e-12);
    let mut out: Vec<(f64, f64, Vec<f64>)> = (0..count)
        .map(|b| {
            (
                lo + width * b as f64,
                lo + width * (b + 1) as f64,
                Vec::new(),
            )
        })
        .collect();
    if count == 1 {
        out[0].1 = hi;
    }
    for (k, v) in keys.iter().zip(r) {
        let b = (((k - lo) / width) as usize).min(count - 1);
        out[b].2.push(*v);
    }
    out.retain(|b| !b.2.is_empty());
    out
}

/// Localisation of residuals `r` (µm) at `contexts` (same order).
pub fn localize(contexts: &[&PointContext], r: &[f64]) -> Localization {
    let n = contexts.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| r[b].abs().total_cmp(&r[a].abs()).then(a.cmp(&b)));
    let worst: Vec<usize> = order.iter().copied().take(20.min(n)).collect();
    let worst_points_detail: Vec<WorstPoint> = worst
        .iter()
        .map(|&i| WorstPoint {
            id: contexts[i].id.clone(),
            residual_um: r[i],
            point: contexts[i].point,
            time_min: contexts[i].time_min,
            line: contexts[i].line,
        })
        .collect();
    let mut blocks: BTreeMap<usize, Vec<f64>> = BTreeMap::new();
    for (c, v) in contexts.iter().zip(r) {
        blocks.entry(c.line).or_default().push(*v);
    }
    let mut worst_blocks: Vec<BlockResidual> = blocks
        .into_iter()
        .map(|(line, v)| BlockResidual {
            line,
            residual_um: mean(&v),
            points: v.len(),
        })
        .collect();
    worst_blocks.sort_by(|a, b| {
        b.residual_um
            .abs()
            .total_cmp(&a.residual_um.abs())
            .then(a.line.cmp(&b.line))
    });
    worst_blocks.truncate(10);
    let times: Vec<f64> = contexts.iter().map(|c| c.time_min).collect();
    let by_time = bands(&times, r, 8)
        .into_iter()
        .map(|(from, to, v)| TimeBand {
            from_min: from,
            to_min: to,
            rms_um: rms(&v),
            mean_um: mean(&v),
            points: v.len(),
        })
        .collect();
    let centre = |axis: usize| {
        let lo = contexts
            .iter()
            .map(|c| c.point[axis])
            .fold(f64::INFINITY, f64::min);
        let hi = contexts
            .iter()
            .map(|c| c.point[axis])
            .fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    };
    let (cx, cy) = (centre(0), centre(1));
    let mut by_region = Vec::new();
    for (name, sx, sy) in [
        ("x-,y-", false, false),
        ("x+,y-", true, false),
        ("x-,y+", false, true),
        ("x+,y+", true, true),
    ] {
        let v: Vec<f64> = contexts
            .iter()
            .zip(r)
            .filter(|(c, _)| (c.point[0] >= cx) == sx && (c.point[1] >= cy) == sy)
            .map(|(_, v)| *v)
            .collect();
        if !v.is_empty() {
            by_region.push(Region {
                name: name.to_string(),
                rms_um: rms(&v),
                mean_um: mean(&v),
                points: v.len(),
            });
        }
    }
    let angle_bands = |keys: Vec<f64>| -> Vec<AngleBand> {
        bands(&keys, r, 6)
            .into_iter()
            .map(|(from, to, v)| AngleBand {
                from_deg: from,
                to_deg: to,
                rms_um: rms(&v),
                mean_um: mean(&v),
                points: v.len(),
            })
            .collect()
    };
    let by_a = angle_bands(contexts.iter().map(|c| c.joints.a).collect());
    let by_c = angle_bands(contexts.iter().map(|c| c.joints.c).collect());
    let mut by_direction = Vec::new();
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        for (sign, label) in [(-1.0, "-"), (0.0, "0"), (1.0, "+")] {
            let v: Vec<f64> = contexts
                .iter()
                .zip(r)
                .filter(|(c, _)| c.sigma[axis] == sign)
                .map(|(_, v)| *v)
                .collect();
            if !v.is_empty() {
                by_direction.push(DirectionGroup {
                    axis: name.to_string(),
                    sign: label.to_string(),
                    rms_um: rms(&v),
                    mean_um: mean(&v),
                    points: v.len(),
                });
            }
        }
    }
    Localization {
        worst_points: worst.iter().map(|&i| contexts[i].id.clone()).collect(),
        worst_points_detail,
        worst_blocks,
        by_time,
        by_region,
        by_a,
        by_c,
        by_direction,
    }
}
