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
use super::smoothing;

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
    /// Every method, in the order of their names.
    pub const ALL: [KnotMethod; 6] = [
        KnotMethod::Ukm,
        KnotMethod::Epm,
        KnotMethod::Lam,
        KnotMethod::Ga,
        KnotMethod::Exhaustive,
        KnotMethod::Best,
    ];

    /// The name as the command line and files write it (`"ukm"`, …).
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

    /// `"um"` for lengths, `"urad"` for angles (the table units).
    pub fn unit(self) -> &'static str {
        match self {
            ParameterKind::Length => "um",
            ParameterKind::Angle => "urad",
        }
    }
}

/// How the complexity of a curve is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Selection {
    /// Noise-aware (the default): a penalised cubic B-spline whose control
    /// points and smoothness minimise generalised cross-validation
    /// (`nurbs::smoothing`); periodic over a full C turn.
    #[default]
    Cv,
    /// The paper's: the fewest control points whose largest error at the data
    /// points is within the tolerance (knots by [`KnotMethod`], weights optimised).
    Emax,
}

impl Selection {
    /// The name as the command line and files write it (`"cv"`, `"emax"`).
    pub fn name(self) -> &'static str {
        match self {
            Selection::Cv => "cv",
            Selection::Emax => "emax",
        }
    }
}

impl std::fmt::Display for Selection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Selection {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "cv" => Ok(Selection::Cv),
            "emax" => Ok(Selection::Emax),
            _ => Err(format!("unknown selection `{s}` (expected cv or emax)")),
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
    /// How knots are placed (Emax selection).
    pub method: KnotMethod,
    /// How the data points get their curve parameters.
    pub parameterization: Parameterization,
    /// Fixed number of control points (no adaptive loop).
    pub control_points: Option<usize>,
    /// Cap of the adaptive loop; `None` = samples − 1.
    pub max_control_points: Option<usize>,
    /// Optimise the weights when knots alone miss the tolerance (§3.2.3).
    pub optimise_weights: bool,
    /// Segments `M` of the candidate-knot grid for ga, exhaustive and best; `None` =
    /// `2 (n − p) + 1` for ga and exhaustive (the paper's M = 13 for n = 9) and
    /// `3 (n − p) + 1` for best, which also admits double knots and refines off
    /// the grid.
    pub grid_segments: Option<usize>,
    /// Largest number of combinations the exhaustive method may enumerate.
    pub exhaustive_limit: u64,
    /// Seed of every random choice (GA, local-search restarts): fits are reproducible.
    pub seed: u64,
    /// Settings of the genetic search (`method = ga`).
    pub ga: GaSettings,
    /// How the complexity is chosen (cross-validation, or the paper's Emax).
    #[serde(default)]
    pub select: Selection,
    /// The table is one revolution of a rotary axis (0…360°): the curve's value
    /// and first two derivatives agree at both ends (`Selection::Cv` only; the
    /// paper's fits are not periodic).
    #[serde(default)]
    pub periodic: bool,
    /// Most work the `Selection::Emax` search may do for one parameter, in
    /// samples × control points summed over its least-squares fits (about
    /// 80 ns each on one core); beyond it the fit fails with
    /// [`FitError::WorkLimit`] instead of searching on for minutes. `None`:
    /// [`default_work_limit`] for the adaptive loop, no limit for a fixed
    /// count of control points (its search is bounded by its method).
    #[serde(default)]
    pub work_limit: Option<u64>,
}

/// The work limit of an Emax search with this tolerance on a table with this
/// noise (difference-based, `smoothing::estimate_noise`):
/// [`WORK_LIMIT_BELOW_NOISE`] when the tolerance is below `BELOW_NOISE` (0.5) of
/// the noise, else [`WORK_LIMIT`].
///
/// A tolerance below half the noise asks the curve to pass nearer every point
/// than the measurement scatters: only near-interpolants meet it, after a
/// search through all the counts that costs minutes per parameter, so it gets
/// about 8 s. Above, the limit is beyond what realistic tables need: of the
/// fidelity bench's 1 200 Emax fits (noise up to the tolerance, methods best
/// and ga), the hardest needed 1.7e9 and 61 more than 1e8; ref-trt's 30
/// tables at most 2.7e7.
pub fn default_work_limit(tolerance: f64, noise: f64) -> u64 {
    if tolerance < BELOW_NOISE * noise {
        WORK_LIMIT_BELOW_NOISE
    } else {
        WORK_LIMIT
    }
}

/// See [`default_work_limit`]: 1e8, about 8 s of one core here.
pub const WORK_LIMIT_BELOW_NOISE: u64 = 100_000_000;

/// See [`default_work_limit`]: 4e9, about 5 minutes of one core here.
pub const WORK_LIMIT: u64 = 4_000_000_000;

/// See [`default_work_limit`].
pub const BELOW_NOISE: f64 = 0.5;

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
            select: Selection::Cv,
            periodic: false,
            work_limit: None,
        }
    }
}

/// Statistics of a fit (errors at the data points, table units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitStats {
    /// Number of data points fitted.
    pub samples: usize,
    /// Number of control points of the curve.
    pub control_points: usize,
    /// Knot method used.
    pub method: KnotMethod,
    /// Largest absolute error at the data points, table units.
    pub emax: f64,
    /// Root-mean-square error at the data points, table units.
    pub erms: f64,
    /// The tolerance asked for (or the default of the parameter kind), table units.
    pub tolerance: f64,
    /// `emax <= tolerance`.
    pub met: bool,
    /// Grid segments `M` used by the last knot search (None for ukm/epm/lam).
    pub grid_segments: Option<usize>,
    /// Least-squares fits evaluated.
    pub evaluations: u64,
    /// Wall-clock time of the fit, seconds.
    pub seconds: f64,
    /// How the complexity was chosen.
    #[serde(default = "emax_selection")]
    pub select: Selection,
    /// Noise of the table estimated from the data alone (difference-based),
    /// table units.
    #[serde(default)]
    pub noise: f64,
    /// Effective number of parameters of the curve (trace of the smoother;
    /// control points + free interior knots for the paper's fits).
    #[serde(default)]
    pub dof: f64,
    /// Cross-validated error `√GCV`: the expected RMS error at a new
    /// measurement of the table, table units.
    #[serde(default)]
    pub cv_error: f64,
    /// Periodic over one revolution.
    #[serde(default)]
    pub periodic: bool,
}

fn emax_selection() -> Selection {
    Selection::Emax
}

/// A fitted SMEM curve: the NURBS `(x(u), y(u))` in table units, its lookup table
/// and fit statistics. Invariant: `x(u)` strictly increasing over the domain.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(into = "SmemCurveData", try_from = "SmemCurveData")]
pub struct SmemCurve {
    curve: NurbsCurve,
    lookup: CurveLookup,
    stats: FitStats,
    /// `(position, standard uncertainty)` at the fitted samples, increasing.
    uncertainty: Vec<[f64; 2]>,
}

/// The serialised form of [`SmemCurve`]; the lookup is rebuilt (and the curve
/// re-validated) when read back.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SmemCurveData {
    /// Degree of the curve.
    pub degree: usize,
    /// Clamped knot vector.
    pub knots: Vec<f64>,
    /// Weight of each control point.
    pub weights: Vec<f64>,
    /// Control points `(position, value)`, table units.
    pub control_points: Vec<[f64; 2]>,
    /// The fit statistics.
    pub stats: FitStats,
    /// `(position, standard uncertainty)` of the curve at the fitted samples
    /// (empty in files written before uncertainties were reported).
    #[serde(default)]
    pub uncertainty: Vec<[f64; 2]>,
}

impl From<SmemCurve> for SmemCurveData {
    fn from(c: SmemCurve) -> Self {
        SmemCurveData {
            degree: c.curve.degree,
            knots: c.curve.knots,
            weights: c.curve.weights,
            control_points: c.curve.points,
            stats: c.stats,
            uncertainty: c.uncertainty,
        }
    }
}

impl TryFrom<SmemCurveData> for SmemCurve {
    type Error = String;
    fn try_from(d: SmemCurveData) -> Result<Self, String> {
        let curve = NurbsCurve::new(d.degree, d.knots, d.weights, d.control_points)
            .map_err(|e| e.to_string())?;
        let mut c = SmemCurve::from_curve(curve, d.stats).map_err(|e| e.to_string())?;
        c.set_uncertainty(d.uncertainty)?;
        Ok(c)
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
            uncertainty: Vec::new(),
        })
    }

    /// Attach the standard uncertainty of the curve at increasing positions
    /// (finite, ≥ 0).
    pub fn set_uncertainty(&mut self, pairs: Vec<[f64; 2]>) -> Result<(), String> {
        if pairs
            .iter()
            .any(|[x, u]| !x.is_finite() || !u.is_finite() || *u < 0.0)
            || pairs.windows(2).any(|w| w[1][0] <= w[0][0])
        {
            return Err("uncertainties must be finite, >= 0, at increasing positions".into());
        }
        self.uncertainty = pairs;
        Ok(())
    }

    /// Standard uncertainty of the fitted error at `position` (table units),
    /// interpolated linearly between the fitted samples and held beyond them;
    /// `None` when the curve carries none (older model files).
    pub fn uncertainty_at(&self, position: f64) -> Option<f64> {
        let u = &self.uncertainty;
        let first = u.first()?;
        let last = u[u.len() - 1];
        if !(position > first[0]) {
            return Some(first[1]);
        }
        if position >= last[0] {
            return Some(last[1]);
        }
        let k = u.partition_point(|p| p[0] <= position);
        let ([x0, u0], [x1, u1]) = (u[k - 1], u[k]);
        Some(u0 + (u1 - u0) * (position - x0) / (x1 - x0))
    }

    /// The `(position, uncertainty)` pairs the curve carries.
    pub fn uncertainty(&self) -> &[[f64; 2]] {
        &self.uncertainty
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

    /// The fit statistics.
    pub fn stats(&self) -> &FitStats {
        &self.stats
    }

    /// The clamped knot vector.
    pub fn knots(&self) -> &[f64] {
        &self.curve.knots
    }

    /// Weight of each control point.
    pub fn weights(&self) -> &[f64] {
        &self.curve.weights
    }

    /// Control points `(position, value)`, table units.
    pub fn control_points(&self) -> &[[f64; 2]] {
        &self.curve.points
    }

    /// Degree of the curve.
    pub fn degree(&self) -> usize {
        self.curve.degree
    }

    /// The underlying NURBS curve.
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
    let _ = samples;
    match method {
        KnotMethod::Best => optimise::default_segments(n - p),
        _ => 2 * (n - p) + 1,
    }
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
    fit_parameter_with_uncertainty(positions, values, None, kind, options)
}

/// [`fit_parameter`] with the standard uncertainty of every value when the
/// table gives it (`u_EXX`, formats extension in docs/extensions.md): the
/// cross-validated fit ([`Selection::Cv`]) is weighted by `1/u²` and takes
/// them as the noise instead of estimating it (its smoothness chosen by the
/// unbiased risk estimate, UBRE); the Emax fit takes their RMS as the noise
/// of its work limit. `None`: exactly [`fit_parameter`].
pub fn fit_parameter_with_uncertainty(
    positions: &[f64],
    values: &[f64],
    uncertainty: Option<&[f64]>,
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
    if options.select == Selection::Cv {
        return fit_cross_validated(positions, values, uncertainty, tolerance, options, started);
    }
    let noise = match uncertainty {
        Some(u) if !u.is_empty() => (u.iter().map(|s| s * s).sum::<f64>() / u.len() as f64).sqrt(),
        _ => smoothing::estimate_noise(positions, values),
    };
    // The adaptive loop is what grows without bound; a fixed count's search
    // is bounded by its method's own settings.
    let work_limit = match (options.work_limit, options.control_points) {
        (Some(limit), _) => limit,
        (None, None) => default_work_limit(tolerance, noise),
        (None, Some(_)) => u64::MAX,
    };
    let problem =
        FitProblem::new(positions, values, p, options.parameterization).with_work_limit(work_limit);
    let problem = match options.method {
        KnotMethod::Ukm | KnotMethod::Epm | KnotMethod::Lam => problem,
        KnotMethod::Ga | KnotMethod::Exhaustive | KnotMethod::Best => problem.regular(),
    };
    let mut evaluations = 0u64;
    let mut best: Option<Placed> = None;
    for count in counts {
        let placed = place(&problem, count, options, tolerance, &mut evaluations)?;
        if problem.work_exhausted() {
            // This count's search was cut short: only the complete ones count.
            return Err(FitError::WorkLimit {
                tolerance,
                noise,
                below_noise: tolerance < BELOW_NOISE * noise,
                limit: work_limit,
                best: best
                    .as_ref()
                    .map(|b| (b.candidate.emax, b.candidate.curve.points.len())),
            });
        }
        let Some(placed) = placed else {
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
    let count = c.curve.points.len();
    let free_knots = matches!(
        options.method,
        KnotMethod::Ga | KnotMethod::Exhaustive | KnotMethod::Best
    );
    let dof = (count + if free_knots { count - p - 1 } else { 0 }) as f64;
    let rss: f64 = c.residuals.iter().map(|r| r * r).sum();
    let n = samples as f64;
    let residual_sigma = (rss / (n - dof).max(1.0)).sqrt();
    let uncertainty = leverage_uncertainty(&problem, &c.curve, residual_sigma);
    let stats = FitStats {
        samples,
        control_points: count,
        method: options.method,
        emax: c.emax,
        erms: c.erms,
        tolerance,
        met: c.emax <= tolerance,
        grid_segments: placed.grid,
        evaluations,
        seconds: started.elapsed().as_secs_f64(),
        select: Selection::Emax,
        noise,
        dof,
        cv_error: if n - dof >= 1.0 {
            (n * rss / (n - dof).powi(2)).sqrt()
        } else {
            f64::INFINITY
        },
        periodic: false,
    };
    let mut curve = SmemCurve {
        curve: c.curve,
        lookup: c.lookup,
        stats,
        uncertainty: Vec::new(),
    };
    curve
        .set_uncertainty(
            positions
                .iter()
                .copied()
                .zip(uncertainty)
                .map(|(x, u)| [x, u])
                .collect(),
        )
        .map_err(FitError::Options)?;
    Ok(curve)
}

/// Standard uncertainty of a least-squares curve at its samples:
/// `σ̂ √h_kk`, `h` the hat matrix of the fit with its final knots and weights
/// (the knot search and the pinned end points are not counted).
fn leverage_uncertainty(problem: &FitProblem, curve: &NurbsCurve, sigma: f64) -> Vec<f64> {
    use nalgebra::DMatrix;
    let count = curve.points.len();
    let rows = problem.params.len();
    let mut a = DMatrix::<f64>::zeros(rows, count);
    let mut row = vec![0.0; count];
    for (k, &u) in problem.params.iter().enumerate() {
        super::least_squares::rational_row(u, curve.degree, &curve.knots, &curve.weights, &mut row);
        for (j, v) in row.iter().enumerate() {
            a[(k, j)] = *v;
        }
    }
    let gram = a.transpose() * &a;
    match gram.try_inverse() {
        Some(inv) => (0..rows)
            .map(|k| {
                let r = a.row(k);
                let h = (r * &inv * r.transpose())[(0, 0)].clamp(0.0, 1.0);
                sigma * h.sqrt()
            })
            .collect(),
        // A rank-deficient basis at the samples: every sample carries its noise.
        None => vec![sigma; rows],
    }
}

/// The noise-aware fit ([`Selection::Cv`]).
fn fit_cross_validated(
    positions: &[f64],
    values: &[f64],
    uncertainty: Option<&[f64]>,
    tolerance: f64,
    options: &FitOptions,
    started: Instant,
) -> Result<SmemCurve, FitError> {
    if let Some(u) = uncertainty
        && !options.periodic
        && options.control_points.is_none()
        && let Some(loo) = linear_predicts_better(positions, values, u, tolerance, options)?
    {
        return linear_interpolant(positions, values, u, tolerance, options, started, loo);
    }
    smoothing_curve(positions, values, uncertainty, tolerance, options, started)
}

/// Fewest targets a spline is fitted to a table of means from: the seed
/// paper's minimum of 8 rows (formats.md "Error table"); a shorter table (5 to
/// 7 targets, accepted when it carries its uncertainty) is joined by lines.
const MIN_CROSS_VALIDATED: usize = 8;

/// A table of means with their uncertainty (a laser run, issue 37): is linear
/// interpolation of the means the better predictor than the weighted spline?
/// Each interior target is left out in turn and predicted from the others by
/// both (the spline refitted without it, the straight line between its
/// neighbours). The spline, the more flexible of the two, is kept only when it
/// predicts significantly better: its mean squared prediction error plus one
/// standard error of the mean difference is still below the line's (the
/// one-standard-error rule, Breiman et al. 1984). `Some(the line's sum of
/// squared prediction errors)` when the line is kept, and always when the
/// table is shorter than the seed paper's 8 rows ([`MIN_CROSS_VALIDATED`]). Between targets farther apart than the
/// machine's features no curve knows more than the means, and a cubic through
/// them overshoots (docs/fidelity.md "Sparse laser tables").
fn linear_predicts_better(
    positions: &[f64],
    values: &[f64],
    u: &[f64],
    tolerance: f64,
    options: &FitOptions,
) -> Result<Option<f64>, FitError> {
    let n = positions.len();
    let line_error = |i: usize| {
        let w = (positions[i] - positions[i - 1]) / (positions[i + 1] - positions[i - 1]);
        values[i - 1] + w * (values[i + 1] - values[i - 1]) - values[i]
    };
    let line: f64 = (1..n.saturating_sub(1))
        .map(|i| line_error(i).powi(2))
        .sum();
    if n < MIN_CROSS_VALIDATED {
        return Ok(Some(line));
    }
    let mut differences = Vec::with_capacity(n - 2);
    for i in 1..n - 1 {
        let keep = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .enumerate()
                .filter(|(k, _)| *k != i)
                .map(|(_, x)| *x)
                .collect()
        };
        let (p, v, s) = (keep(positions), keep(values), keep(u));
        // A spline that cannot be fitted without one of its targets cannot be
        // cross-validated: the line is kept.
        let Ok(fit) = smoothing_curve(&p, &v, Some(&s), tolerance, options, Instant::now()) else {
            return Ok(Some(line));
        };
        let spline = (fit.value_at(positions[i]) - values[i]).powi(2);
        differences.push(spline - line_error(i).powi(2));
    }
    let m = differences.len() as f64;
    let mean = differences.iter().sum::<f64>() / m;
    let variance = differences.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (m - 1.0);
    let standard_error = (variance / m).sqrt();
    Ok((mean + standard_error >= 0.0).then_some(line))
}

/// The means joined by straight lines, as a degree-1 NURBS through them
/// (what [`linear_predicts_better`] chose); its uncertainty at each target is
/// the mean's own.
fn linear_interpolant(
    positions: &[f64],
    values: &[f64],
    u: &[f64],
    tolerance: f64,
    options: &FitOptions,
    started: Instant,
    loo: f64,
) -> Result<SmemCurve, FitError> {
    let n = positions.len();
    let (lo, hi) = (positions[0], positions[n - 1]);
    let mut knots = vec![0.0];
    knots.extend(positions.iter().map(|x| (x - lo) / (hi - lo)));
    knots.push(1.0);
    let points: Vec<[f64; 2]> = positions
        .iter()
        .zip(values)
        .map(|(&x, &y)| [x, y])
        .collect();
    let curve = NurbsCurve::new(1, knots, vec![1.0; n], points)
        .map_err(|e| FitError::Options(e.to_string()))?;
    let interior = n.saturating_sub(2).max(1) as f64;
    let stats = FitStats {
        samples: n,
        control_points: n,
        method: options.method,
        emax: 0.0,
        erms: 0.0,
        tolerance,
        met: true,
        grid_segments: None,
        evaluations: 0,
        seconds: started.elapsed().as_secs_f64(),
        select: Selection::Cv,
        noise: (u.iter().map(|s| s * s).sum::<f64>() / n as f64).sqrt(),
        dof: n as f64,
        cv_error: (loo / interior).sqrt(),
        periodic: false,
    };
    let mut curve = SmemCurve::from_curve(curve, stats).map_err(|_| FitError::NoFeasibleFit)?;
    curve
        .set_uncertainty(positions.iter().zip(u).map(|(&x, &s)| [x, s]).collect())
        .map_err(FitError::Options)?;
    Ok(curve)
}

/// The noise-aware smoothing spline (weighted by `uncertainty` when given).
fn smoothing_curve(
    positions: &[f64],
    values: &[f64],
    uncertainty: Option<&[f64]>,
    tolerance: f64,
    options: &FitOptions,
    started: Instant,
) -> Result<SmemCurve, FitError> {
    let fit = smoothing::fit_smoothing(
        positions,
        values,
        &smoothing::SmoothingOptions {
            degree: options.degree,
            periodic: options.periodic,
            max_control_points: options.max_control_points,
            control_points: options.control_points,
            sigma: uncertainty.map(<[f64]>::to_vec),
            ..smoothing::SmoothingOptions::default()
        },
    )?;
    let emax = fit.residuals.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let erms =
        (fit.residuals.iter().map(|e| e * e).sum::<f64>() / fit.residuals.len() as f64).sqrt();
    let stats = FitStats {
        samples: positions.len(),
        control_points: fit.curve.points.len(),
        method: options.method,
        emax,
        erms,
        tolerance,
        met: emax <= tolerance,
        grid_segments: None,
        evaluations: fit.evaluations,
        seconds: started.elapsed().as_secs_f64(),
        select: Selection::Cv,
        noise: fit.noise,
        dof: fit.dof,
        cv_error: fit.cv_error,
        periodic: options.periodic,
    };
    let mut curve = SmemCurve::from_curve(fit.curve, stats).map_err(|_| FitError::NoFeasibleFit)?;
    curve
        .set_uncertainty(
            positions
                .iter()
                .copied()
                .zip(fit.uncertainty)
                .map(|(x, u)| [x, u])
                .collect(),
        )
        .map_err(FitError::Options)?;
    Ok(curve)
}
