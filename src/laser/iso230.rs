//! ISO 230-2 (2014) evaluation of bidirectional positioning runs: per target
//! position the unidirectional means x̄↑ x̄↓, the reversal value B_i, the
//! estimators of the standard uncertainty s↑ s↓ and the repeatabilities; per
//! axis the figures A, B, E, M, R and their unidirectional forms.
//!
//! Units are the deviations' (µm or µrad). A standard deviation needs two runs
//! in that direction; with one run the figures that use it are `None`.

/// The statistics of one target position.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TargetStats {
    /// mm or degrees.
    pub target: f64,
    /// Number of readings approaching in the positive direction.
    pub n_up: usize,
    /// Number of readings approaching in the negative direction.
    pub n_down: usize,
    /// x̄_i↑, x̄_i↓: mean unidirectional positional deviations.
    pub mean_up: f64,
    /// x̄_i↓ (see `mean_up`).
    pub mean_down: f64,
    /// x̄_i = (x̄_i↑ + x̄_i↓)/2: mean bidirectional positional deviation (the table's value).
    pub mean: f64,
    /// B_i = x̄_i↑ − x̄_i↓: reversal value (the table's REVERSAL).
    pub reversal: f64,
    /// The standard uncertainty of x̄_i, `½ √(s_i↑²/n↑ + s_i↓²/n↓)` (the
    /// table's `u_<parameter>`); `None` without two runs in each direction.
    #[serde(rename = "u")]
    pub uncertainty: Option<f64>,
    /// s_i↑, s_i↓ (n − 1 in the denominator).
    pub s_up: Option<f64>,
    /// s_i↓ (see `s_up`).
    pub s_down: Option<f64>,
    /// R_i↑ = 4 s_i↑, R_i↓ = 4 s_i↓.
    #[serde(rename = "R_up")]
    pub repeatability_up: Option<f64>,
    /// R_i↓ (see `repeatability_up`).
    #[serde(rename = "R_down")]
    pub repeatability_down: Option<f64>,
    /// R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓).
    #[serde(rename = "R")]
    pub repeatability: Option<f64>,
}

/// The figures of an axis (ISO 230-2 §2.11-2.22).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AxisFigures {
    /// A: accuracy (bidirectional).
    #[serde(rename = "A")]
    pub accuracy: Option<f64>,
    /// B = max |B_i|: reversal value of the axis.
    #[serde(rename = "B")]
    pub reversal: f64,
    /// B̄: mean reversal value (signed mean of B_i).
    #[serde(rename = "B_mean")]
    pub mean_reversal: f64,
    /// E: bidirectional systematic positional deviation.
    #[serde(rename = "E")]
    pub systematic: f64,
    /// M: range of the mean bidirectional positional deviation.
    #[serde(rename = "M")]
    pub mean_range: f64,
    /// R: bidirectional repeatability (max R_i).
    #[serde(rename = "R")]
    pub repeatability: Option<f64>,
    /// A↑: unidirectional accuracy, positive direction.
    #[serde(rename = "A_up")]
    pub accuracy_up: Option<f64>,
    /// A↓: unidirectional accuracy, negative direction.
    #[serde(rename = "A_down")]
    pub accuracy_down: Option<f64>,
    /// E↑: unidirectional systematic positional deviation, positive direction.
    #[serde(rename = "E_up")]
    pub systematic_up: f64,
    /// E↓: unidirectional systematic positional deviation, negative direction.
    #[serde(rename = "E_down")]
    pub systematic_down: f64,
    /// R↑: unidirectional repeatability, positive direction (max R_i↑).
    #[serde(rename = "R_up")]
    pub repeatability_up: Option<f64>,
    /// R↓: unidirectional repeatability, negative direction (max R_i↓).
    #[serde(rename = "R_down")]
    pub repeatability_down: Option<f64>,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Sample standard deviation (n − 1); `None` below two values.
fn std_dev(v: &[f64], m: f64) -> Option<f64> {
    (v.len() >= 2)
        .then(|| (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64).sqrt())
}

/// The statistics of one target from its deviations in each direction (both non-empty).
pub fn target_stats(target: f64, up: &[f64], down: &[f64]) -> TargetStats {
    let mean_up = mean(up);
    let mean_down = mean(down);
    let s_up = std_dev(up, mean_up);
    let s_down = std_dev(down, mean_down);
    let reversal = mean_up - mean_down;
    let repeatability = match (s_up, s_down) {
        (Some(su), Some(sd)) => Some(
            (2.0 * su + 2.0 * sd + reversal.abs())
                .max(4.0 * su)
                .max(4.0 * sd),
        ),
        _ => None,
    };
    TargetStats {
        target,
        n_up: up.len(),
        n_down: down.len(),
        mean_up,
        mean_down,
        mean: 0.5 * (mean_up + mean_down),
        reversal,
        uncertainty: match (s_up, s_down) {
            (Some(su), Some(sd)) => {
                Some(0.5 * (su * su / up.len() as f64 + sd * sd / down.len() as f64).sqrt())
            }
            _ => None,
        },
        s_up,
        s_down,
        repeatability_up: s_up.map(|s| 4.0 * s),
        repeatability_down: s_down.map(|s| 4.0 * s),
        repeatability,
    }
}

fn max_of(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(f64::NEG_INFINITY, f64::max)
}

fn min_of(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(f64::INFINITY, f64::min)
}

/// `Some` of every item, or `None` when one is missing.
fn all<T: Copy>(v: impl Iterator<Item = Option<T>>) -> Option<Vec<T>> {
    v.collect()
}

/// The axis figures over `targets` (not empty).
pub fn axis_figures(targets: &[TargetStats]) -> AxisFigures {
    let t = targets;
    let up = || t.iter().map(|s| s.mean_up);
    let down = || t.iter().map(|s| s.mean_down);
    let systematic_up = max_of(up()) - min_of(up());
    let systematic_down = max_of(down()) - min_of(down());
    let systematic = max_of(up().chain(down())) - min_of(up().chain(down()));
    let mean_range = max_of(t.iter().map(|s| s.mean)) - min_of(t.iter().map(|s| s.mean));
    let reversal = max_of(t.iter().map(|s| s.reversal.abs()));
    let mean_reversal = t.iter().map(|s| s.reversal).sum::<f64>() / t.len() as f64;
    let s_up = all(t.iter().map(|s| s.s_up));
    let s_down = all(t.iter().map(|s| s.s_down));
    let band = |s: &[f64], means: &mut dyn Iterator<Item = f64>| -> (f64, f64) {
        let (mut hi, mut lo) = (f64::NEG_INFINITY, f64::INFINITY);
        for (m, s) in means.zip(s) {
            hi = hi.max(m + 2.0 * s);
            lo = lo.min(m - 2.0 * s);
        }
        (hi, lo)
    };
    let band_up = s_up.as_ref().map(|s| band(s, &mut up()));
    let band_down = s_down.as_ref().map(|s| band(s, &mut down()));
    let accuracy = match (band_up, band_down) {
        (Some((hu, lu)), Some((hd, ld))) => Some(hu.max(hd) - lu.min(ld)),
        _ => None,
    };
    let max_opt = |v: Option<Vec<f64>>| v.map(|v| max_of(v.into_iter()));
    AxisFigures {
        accuracy,
        reversal,
        mean_reversal,
        systematic,
        mean_range,
        repeatability: max_opt(all(t.iter().map(|s| s.repeatability))),
        accuracy_up: band_up.map(|(h, l)| h - l),
        accuracy_down: band_down.map(|(h, l)| h - l),
        systematic_up,
        systematic_down,
        repeatability_up: max_opt(all(t.iter().map(|s| s.repeatability_up))),
        repeatability_down: max_opt(all(t.iter().map(|s| s.repeatability_down))),
    }
}
