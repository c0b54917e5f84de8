//! The SMEM of one error parameter (the paper's §3, Fig. 8): a cubic NURBS curve
//! through the measured `(position, value)` points, with knots (and weights)
//! optimised and the number of control points grown until the largest error at
//! the data points is within tolerance.
//!
//! Adaptive loop (Fig. 8): for `n + 1 = p + 1, p + 2, …` control points (or the
//! fixed count of [`FitOptions::control_points`]): place the knots with the chosen
//! [`KnotMethod`], fit by least squares, and if the tolerance is not met and
//! weights are optimised, optimise the weights; stop at the first count that
//! meets the tolerance, or at the cap. Missing the tolerance is never silent:
//! [`FitStats::met`] is false and the best curve found is returned.
//!
//! Default tolerances (used when [`FitOptions::tolerance`] is `None`): 0.5 µm for
//! lengths and 1.0 µrad for angles — about the repeatability of laser-interferometer
//! and autocollimator measurements of these errors, so the curve follows the
//! measured shape without chasing the measurement noise of each point.
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::curve::NurbsCurve;
use super::exhaustive;
pub use super::fit_error::FitError;
use super::genetic::{self, GaSettings};
use super::knot_placement;
use super::lookup::CurveLookup;
use super::optimise;
use super::parameterization::Parameterization;
use super::problem::{Candidate, FitProblem};

/// How the interior knots are chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KnotMethod {
    /// Uniform knots, eq. 13.
    Ukm,
    /// Equal partition (Piegl & Tiller averaging), eq. 14.
    Epm,
    /// Local average (Yeh & Su), eq. 15.
    Lam,
    /// The paper's improved genetic algorithm over a grid of M segments (§3.2).
    Ga,
    /// Every combination of the grid (the paper's "combination global search").
    Exhaustive,
    /// Grid local search from several starts, then continuous free-knot refinement.
    #[default]
    Best,
}

impl KnotMethod {
    pub const ALL: [KnotMethod; 6] = [
        KnotMethod::Ukm,
        KnotMethod::Epm,
        KnotMethod::Lam,
        KnotMethod::Ga,
        KnotMethod::Exhaustive,
        KnotMethod::Best,
    ];

    pub fn name(self) -> &'static str {
        match self {
            KnotMethod::Ukm => "ukm",
            KnotMethod::Epm => "epm",
            KnotMethod::Lam => "lam",
            KnotMethod::Ga => "ga",
            KnotMethod::Exhaustive => "exhaustive",
            KnotMethod::Best => "best",
        }
    }
}

impl std::fmt::Display for KnotMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for KnotMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        KnotMethod::ALL
            .into_iter()
            .find(|m| m.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                format!(
                    "unknown knot method `{s}` (expected ukm, epm, lam, ga, exhaustive or best)"
                )
            })
    }
}

/// What an error parameter measures; selects the default tolerance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ParameterKind {
    /// Positioning and straightness errors, µm.
    Length,
    /// Angular errors (pitch, yaw, roll), µrad.
    Angle,
}

impl ParameterKind {
    /// 0.5 µm for lengths, 1.0 µrad for angles (see the module doc).
    pub fn default_tolerance(self) -> f64 {
        match self {
            ParameterKind::Length => 0.5,
            ParameterKind::Angle => 1.0,
        }
    }

    pub fn unit(self) -> &'static str {
        match self {
            ParameterKind::Length => "um",
            ParameterKind::Angle => "urad",
        }
    }
}

/// Settings of a fit. `Default` is the SMEM as used by `volcomp fit`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FitOptions {
    /// Degree `p` (3).
    pub degree: usize,
    /// Largest allowed error at the data points (table units); `None` = the default
    /// of the parameter kind.
    pub tolerance: Option<f64>,
    pub method: KnotMethod,
    pub parameterization: Parameterization,
    /// Fixed number of control points (no adaptive loop).
    pub control_points: Option<usize>,
    /// Cap of the adaptive loop; `None` = samples − 1.
    pub max_control_points: Option<usize>,
    /// Optimise the weights when knots alone miss the tolerance (§3.2.3).
    pub optimise_weights: bool,
    /// Segments `M` of the candidate-knot grid for ga, exhaustive and best; `None` =
    /// `2 (n − p) + 1` (the paper's M = 13 for n = 9; best refines off the grid).
    pub grid_segments: Option<usize>,
    /// Largest number of combinations the exhaustive method may enumerate.
    pub exhaustive_limit: u64,
    /// Seed of every random choice (GA, local-search restarts): fits are reproducible.
    pub seed: u64,
    pub ga: GaSettings,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            degree: 3,
            tolerance: None,
            method: KnotMethod::Best,
            parameterization: Parameterization::Centripetal,
            control_points: None,
            max_control_points: None,
            optimise_weights: true,
            grid_segments: None,
            exhaustive_limit: 5_000_000,
            seed: 2016,
            ga: GaSettings::default(),
        }
    }
}

/// Statistics of a fit (errors at the data points, table units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitStats {
    pub samples: usize,
    pub control_points: usize,
    pub method: KnotMethod,
    pub emax: f64,
    pub erms: f64,
    pub tolerance: f64,
    /// `emax <= tolerance`.
    pub met: bool,
    /// Grid segments `M` used by the last knot search (None for ukm/epm/lam).
    pub grid_segments: Option<usize>,
    /// Least-squares fits evaluated.
    pub evaluations: u64,
    pub seconds: f64,
}

/// A fitted SMEM curve: the NURBS `(x(u), y(u))` in table units, its lookup table
/// and fit statistics. Invariant: `x(u)` strictly increasing over the domain.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(into = "SmemCurveData", try_from = "SmemCurveData")]
pub struct SmemCurve {
    curve: NurbsCurve,
    lookup: CurveLookup,
    stats: FitStats,
}

/// The serialised form of [`SmemCurve`]; the lookup is rebuilt (and the curve
/// re-validated) when read back.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SmemCurveData {
    pub degree: usize,
    pub knots: Vec<f64>,
    pub weights: Vec<f64>,
    pub control_points: Vec<[f64; 2]>,
    pub stats: FitStats,
}

impl From<SmemCurve> for SmemCurveData {
    fn from(c: SmemCurve) -> Self {
        SmemCurveData {
            degree: c.curve.degree,
            knots: c.curve.knots,
            weights: c.curve.weights,
            control_points: c.curve.points,
            stats: c.stats,
        }
    }
}

impl TryFrom<SmemCurveData> for SmemCurve {
    type Error = String;
    fn try_from(d: SmemCurveData) -> Result<Self, String> {
        let curve = NurbsCurve::new(d.degree, d.knots, d.weights, d.control_points)
            .map_err(|e| e.to_string())?;
        SmemCurve::from_curve(curve, d.stats).map_err(|e| e.to_string())
    }
}

impl SmemCurve {
    /// Wrap a curve (checks that `x(u)` is strictly increasing).
    pub fn from_curve(
        curve: NurbsCurve,
        stats: FitStats,
    ) -> Result<SmemCurve, super::lookup::LookupError> {
        let lookup = CurveLookup::new(&curve)?;
        Ok(SmemCurve {
            curve,
            lookup,
            stats,
        })
    }

    /// The fitted error at `position` (table units): `y(u)` with `x(u) = position`,
    /// solved to round-off. `position` must lie in [`Self::domain`]; outside it the
    /// end value is returned (wrap-around and out-of-range policy belong to the
    /// caller). A NaN position is a caller bug (checked at the boundary); it yields
    /// some value of the curve, never a panic.
    #[inline]
    pub fn value_at(&self, position: f64) -> f64 {
        self.lookup.value_at(position)
    }

    /// First and last measured positions.
    pub fn domain(&self) -> (f64, f64) {
        self.lookup.domain()
    }

    pub fn stats(&self) -> &FitStats {
        &self.stats
    }

    pub fn knots(&self) -> &[f64] {
        &self.curve.knots
    }

    pub fn weights(&self) -> &[f64] {
        &self.curve.weights
    }

    pub fn control_points(&self) -> &[[f64; 2]] {
        &self.curve.points
    }

    pub fn degree(&self) -> usize {
        self.curve.degree
    }

    pub fn curve(&self) -> &NurbsCurve {
        &self.curve
    }

    /// The curve parameter `u` at `position` (for plots and tests).
    pub fn parameter_at(&self, position: f64) -> f64 {
        self.lookup.parameter_at(position)
    }

    /// Exact slope `dy/dx = y'(u) / x'(u)` at `position` (table units per mm or
    /// degree); `x'(u) > 0` everywhere by the fit's invariant.
    pub fn slope_at(&self, position: f64) -> f64 {
        let u = self.parameter_at(position);
        let d = self.curve.derivatives(u, 1);
        d[1][1] / d[1][0]
    }
}

/// Check the data at the boundary: same lengths, finite, strictly increasing.
fn validate(positions: &[f64], values: &[f64], degree: usize) -> Result<(), FitError> {
    if positions.len() != values.len() {
        return Err(FitError::LengthMismatch {
            positions: positions.len(),
            values: values.len(),
        });
    }
    if degree == 0 || degree > super::basis::MAX_DEGREE {
        return Err(FitError::Options(format!(
            "degree {degree} is outside 1..={}",
            super::basis::MAX_DEGREE
        )));
    }
    let need = degree + 2;
    if positions.len() < need {
        return Err(FitError::TooFewSamples {
            samples: positions.len(),
            degree,
            need,
        });
    }
    for (index, (&x, &y)) in positions.iter().zip(values).enumerate() {
        if !x.is_finite() {
            return Err(FitError::NotFinite {
                index,
                what: "position",
            });
        }
        if !y.is_finite() {
            return Err(FitError::NotFinite {
                index,
                what: "value",
            });
        }
        if index > 0 && x <= positions[index - 1] {
            return Err(FitError::NotIncreasing { index, position: x });
        }
    }
    Ok(())
}

/// The default grid `M` for `n + 1` control points (see [`FitOptions::grid_segments`]).
pub fn default_grid_segments(method: KnotMethod, n: usize, p: usize, samples: usize) -> usize {
    let _ = (method, samples);
    2 * (n - p) + 1
}

/// Knots (and weights) for `count` control points with the chosen method.
struct Placed {
    candidate: Candidate,
    grid: Option<usize>,
}

fn place(
    problem: &FitProblem,
    count: usize,
    options: &FitOptions,
    tolerance: f64,
    evaluations: &mut u64,
) -> Result<Option<Placed>, FitError> {
    let p = problem.degree;
    let n = count - 1;
    let ones = vec![1.0; count];
    let grid = options
        .grid_segments
        .unwrap_or_else(|| default_grid_segments(options.method, n, p, problem.samples()));
    if matches!(
        options.method,
        KnotMethod::Ga | KnotMethod::Exhaustive | KnotMethod::Best
    ) && grid < n - p + 1
    {
        return Err(FitError::Options(format!(
            "a grid of {grid} segments cannot hold {} interior knots",
            n - p
        )));
    }
    let seed = options.seed ^ (count as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let (interior, used_grid) = match options.method {
        KnotMethod::Ukm => (knot_placement::uniform(n, p), None),
        KnotMethod::Epm => (knot_placement::equal_partition(&problem.params, n, p), None),
        KnotMethod::Lam => (knot_placement::local_average(&problem.params, n, p), None),
        KnotMethod::Ga => {
            let r = genetic::optimise_knots(problem, n, grid, &options.ga, tolerance, seed);
            *evaluations += r.evaluations;
            (knot_placement::grid_knots(&r.indices, grid), Some(grid))
        }
        KnotMethod::Exhaustive => {
            let r = exhaustive::search(problem, n, grid, options.exhaustive_limit)?;
            *evaluations += r.evaluations;
            (knot_placement::grid_knots(&r.indices, grid), Some(grid))
        }
        KnotMethod::Best => {
            let refined = optimise::best_knots(problem, n, grid, seed);
            *evaluations += refined.evaluations;
            (refined.interior, Some(grid))
        }
    };
    *evaluations += 1;
    let Some(mut candidate) = problem.evaluate(&interior, &ones) else {
        return Ok(None);
    };
    if options.optimise_weights && candidate.emax > tolerance {
        let weights = match options.method {
            KnotMethod::Best => {
                let r =
                    optimise::refine_weights(problem, &interior, &ones, options.ga.weight_range);
                *evaluations += r.evaluations;
                r.weights
            }
            _ => {
                let r = genetic::optimise_weights(problem, &interior, &options.ga, tolerance, seed);
                *evaluations += r.evaluations;
                r.weights
            }
        };
        *evaluations += 1;
        if let Some(c) = problem.evaluate(&interior, &weights) {
            if c.emax < candidate.emax {
                candidate = c;
            }
        }
    }
    Ok(Some(Placed {
        candidate,
        grid: used_grid,
    }))
}

/// Fit the SMEM of one error parameter (see the module doc). `positions` strictly
/// increasing (mm or deg), `values` in µm or µrad, all finite.
pub fn fit_parameter(
    positions: &[f64],
    values: &[f64],
    kind: ParameterKind,
    options: &FitOptions,
) -> Result<SmemCurve, FitError> {
    let started = Instant::now();
    let p = options.degree;
    validate(positions, values, p)?;
    let tolerance = options.tolerance.unwrap_or(kind.default_tolerance());
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(FitError::Options(format!(
            "tolerance {tolerance} must be a finite number >= 0"
        )));
    }
    let samples = positions.len();
    let counts: Vec<usize> = match options.control_points {
        Some(c) => {
            if c < p + 1 || c > samples {
                return Err(FitError::Options(format!(
                    "{c} control points: need between {} and {samples} (the samples)",
                    p + 1
                )));
            }
            vec![c]
        }
        None => {
            let cap = options
                .max_control_points
                .unwrap_or(samples - 1)
                .min(samples);
            if cap < p + 1 {
                return Err(FitError::Options(format!(
                    "the cap of {cap} control points is below degree + 1 = {}",
                    p + 1
                )));
            }
            (p + 1..=cap).collect()
        }
    };
    let problem = FitProblem::new(positions, values, p, options.parameterization);
    let problem = match options.method {
        KnotMethod::Ukm | KnotMethod::Epm | KnotMethod::Lam => problem,
        KnotMethod::Ga | KnotMethod::Exhaustive | KnotMethod::Best => problem.regular(),
    };
    let mut evaluations = 0u64;
    let mut best: Option<Placed> = None;
    for count in counts {
        let Some(placed) = place(&problem, count, options, tolerance, &mut evaluations)? else {
            continue;
        };
        let met = placed.candidate.emax <= tolerance;
        if best
            .as_ref()
            .is_none_or(|b| placed.candidate.emax < b.candidate.emax)
            || met
        {
            best = Some(placed);
        }
        if met {
            break;
        }
    }
    let placed = best.ok_or(FitError::NoFeasibleFit)?;
    let c = placed.candidate;
    let stats = FitStats {
        samples,
        control_points: c.curve.points.len(),
        method: options.method,
        emax: c.emax,
        erms: c.erms,
        tolerance,
        met: c.emax <= tolerance,
        grid_segments: placed.grid,
        evaluations,
        seconds: started.elapsed().as_secs_f64(),
    };
    Ok(SmemCurve {
        curve: c.curve,
        lookup: c.lookup,
        stats,
    })
}
