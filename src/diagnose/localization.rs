//! Where the gap lies: worst points and blocks, residual RMS by time band, by
//! region of the part, by A and C range, and by direction of travel.
//!
//! Invariant: every group lists its point count; empty groups are left out.
use super::noise::rms;
use super::report::{
    AngleBand, BlockResidual, DirectionGroup, Localization, Region, TimeBand, WorstPoint,
};
use crate::axes::Axis;
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
    // Bands of the machine's own rotary axes (A and C, B and C, …), each
    // under its letter.
    let rotary = contexts.first().map_or([Axis::A, Axis::C], |c| c.rotary);
    let bands_of = |letter: Axis| {
        if rotary.contains(&letter) {
            angle_bands(contexts.iter().map(|c| c.joints.get(letter)).collect())
        } else {
            Vec::new()
        }
    };
    let (by_a, by_b, by_c) = (bands_of(Axis::A), bands_of(Axis::B), bands_of(Axis::C));
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
        by_b,
        by_c,
        by_direction,
    }
}

/// Neighbourhood radius of the local-anomaly scan, mm.
pub const ANOMALY_RADIUS_MM: f64 = 10.0;
/// A neighbourhood mean at least this many standard deviations from zero is
/// anomalous.
pub const ANOMALY_SIGMA: f64 = 6.0;
/// Fewest points in a neighbourhood for its mean to count.
const ANOMALY_MIN_POINTS: usize = 4;

/// Significant local clusters of the residual `r` (µm, after the selected
/// effects) at `contexts` (docs/diagnose.md "Local anomalies"). Each point's
/// neighbourhood (points within [`ANOMALY_RADIUS_MM`]) has a mean residual
/// `m`; against white noise σ and a smooth model error of standard
/// uncertainty u (the same at neighbouring points), its standard deviation is
/// `√(σ²/k + u²)`. Points whose `|z| = |m|/√(σ²/k + u²)` reaches
/// [`ANOMALY_SIGMA`] are joined (neighbours, same sign) into clusters, largest
/// `|z|` first (at most three).
pub fn local_anomalies(
    contexts: &[&PointContext],
    r: &[f64],
    noise_um: f64,
    model_u_um: f64,
) -> Vec<super::report::LocalAnomaly> {
    let n = contexts.len().min(r.len());
    let r2 = ANOMALY_RADIUS_MM * ANOMALY_RADIUS_MM;
    let dist2 = |a: usize, b: usize| -> f64 {
        (0..3)
            .map(|k| (contexts[a].point[k] - contexts[b].point[k]).powi(2))
            .sum()
    };
    // Neighbours by a grid of cells of the radius (plan x, y).
    let mut cells: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
    let cell = |i: usize| {
        (
            (contexts[i].point[0] / ANOMALY_RADIUS_MM).floor() as i64,
            (contexts[i].point[1] / ANOMALY_RADIUS_MM).floor() as i64,
        )
    };
    for i in 0..n {
        cells.entry(cell(i)).or_default().push(i);
    }
    let neighbours: Vec<Vec<usize>> = (0..n)
        .map(|i| {
            let (cx, cy) = cell(i);
            let mut v = Vec::new();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    if let Some(list) = cells.get(&(cx + dx, cy + dy)) {
                        v.extend(list.iter().copied().filter(|&j| dist2(i, j) <= r2));
                    }
                }
            }
            v
        })
        .collect();
    let s2 = noise_um.max(1e-6).powi(2);
    let u2 = model_u_um.powi(2);
    let z: Vec<f64> = (0..n)
        .map(|i| {
            let k = neighbours[i].len();
            if k < ANOMALY_MIN_POINTS {
                return 0.0;
            }
            let m = neighbours[i].iter().map(|&j| r[j]).sum::<f64>() / k as f64;
            m / (s2 / k as f64 + u2).sqrt()
        })
        .collect();
    let mut label = vec![usize::MAX; n];
    let mut clusters: Vec<Vec<usize>> = Vec::new();
    for i in 0..n {
        if z[i].abs() < ANOMALY_SIGMA || label[i] != usize::MAX {
            continue;
        }
        let id = clusters.len();
        let mut members = vec![i];
        label[i] = id;
        let mut at = 0;
        while at < members.len() {
            let a = members[at];
            at += 1;
            for &b in &neighbours[a] {
                if label[b] == usize::MAX
                    && z[b].abs() >= ANOMALY_SIGMA
                    && z[b].signum() == z[i].signum()
                {
                    label[b] = id;
                    members.push(b);
                }
            }
        }
        clusters.push(members);
    }
    let mut out: Vec<(f64, super::report::LocalAnomaly)> = clusters
        .into_iter()
        .map(|mut members| {
            members.sort_by(|&a, &b| r[b].abs().total_cmp(&r[a].abs()).then(a.cmp(&b)));
            let sigma = members.iter().map(|&i| z[i].abs()).fold(0.0f64, f64::max);
            let k = members.len() as f64;
            let centre =
                [0, 1, 2].map(|c| members.iter().map(|&i| contexts[i].point[c]).sum::<f64>() / k);
            let extent = members
                .iter()
                .map(|&i| {
                    (0..3)
                        .map(|c| (contexts[i].point[c] - centre[c]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(0.0f64, f64::max)
                + ANOMALY_RADIUS_MM;
            let mut lines: Vec<usize> = members.iter().map(|&i| contexts[i].line).collect();
            lines.sort_unstable();
            lines.dedup();
            lines.truncate(12);
            let vals: Vec<f64> = members.iter().map(|&i| r[i]).collect();
            (
                sigma,
                super::report::LocalAnomaly {
                    points: members.len(),
                    ids: members
                        .iter()
                        .take(20)
                        .map(|&i| contexts[i].id.clone())
                        .collect(),
                    centre,
                    radius_mm: extent,
                    lines,
                    peak_um: vals.first().copied().unwrap_or(0.0),
                    mean_um: mean(&vals),
                    sigma,
                    time_min: [
                        members
                            .iter()
                            .map(|&i| contexts[i].time_min)
                            .fold(f64::INFINITY, f64::min),
                        members
                            .iter()
                            .map(|&i| contexts[i].time_min)
                            .fold(0.0f64, f64::max),
                    ],
                },
            )
        })
        .collect();
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out.into_iter().take(3).map(|(_, a)| a).collect()
}
