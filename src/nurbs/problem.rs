//! One curve-fitting problem: the data points of an error parameter, normalised
//! and parameterised once, and the evaluation of a candidate (interior knots,
//! weights) into a fitted curve and its errors. Every knot method and optimiser
//! scores candidates through [`FitProblem::evaluate`], so they are compared on the
//! same objective.
//!
//! Units and scaling: positions (mm or deg) and values (µm or µrad) have unrelated
//! units, and the chord-based parameterisations depend on the scale. Both
//! coordinates are mapped affinely to `[0, 1]` (position by its range, value by its
//! range, or 1 when constant) before parameterising and fitting; NURBS are
//! affine-invariant, so the control points are mapped back to table units exactly.
//!
//! Error measure (what the paper evaluates in Fig. 8): for each data point the
//! curve is inverted at its position (`x(u) = x_k`) and the vertical error
//! `|y(u) − y_k|` (table units) is taken; `emax` is the largest, `erms` the RMS.
//! A candidate whose least-squares system is singular, whose control polygon does
//! not advance in position, or whose `x(u)` folds back is infeasible (`None`).
use super::curve::NurbsCurve;
use super::knot_vector;
use super::least_squares::fit_control_points;
use super::lookup::CurveLookup;
use super::parameterization::{Parameterization, parameterize};
use std::sync::atomic::{AtomicU64, Ordering};

/// Least advance of consecutive control points in normalised position, as a
/// fraction of the uniform spacing `1 / (n − 1)` (the table's range is 1): a
/// fold-free curve whose slope stays bounded between the data points, as a
/// machine's error function does.
pub const MIN_CONTROL_ADVANCE: f64 = 0.2;

/// One table column prepared for fitting: the data, normalised to the unit square, and its parameters.
#[derive(Clone, Debug)]
pub struct FitProblem {
    /// Degree of the curves to fit.
    pub degree: usize,
    /// Raw data, table units.
    pub positions: Vec<f64>,
    /// Values at `positions`, table units (µm or µrad).
    pub values: Vec<f64>,
    /// Normalised points (row-major pairs) and their parameters.
    normalised: Vec<f64>,
    /// Parameter `ū_k` of each data point (in [0, 1], from the normalised points).
    pub params: Vec<f64>,
    origin: [f64; 2],
    scale: [f64; 2],
    /// Least advance of consecutive control points (fraction of the uniform
    /// spacing): 0 for the fixed knot placements, [`MIN_CONTROL_ADVANCE`] for the
    /// searches ([`FitProblem::regular`]).
    min_control_advance: f64,
    /// Work of the least-squares fits so far and its limit
    /// ([`FitProblem::with_work_limit`]).
    work: Work,
}

/// Work done by a problem's fits, in samples × control points per fit (a
/// fit costs about that much), against a limit. Shared by the threads of a
/// search through `&FitProblem`.
#[derive(Debug)]
struct Work {
    done: AtomicU64,
    limit: u64,
}

impl Clone for Work {
    fn clone(&self) -> Self {
        Work {
            done: AtomicU64::new(self.done.load(Ordering::Relaxed)),
            limit: self.limit,
        }
    }
}

/// A fitted candidate and its errors at the data points (table units).
#[derive(Clone, Debug)]
pub struct Candidate {
    pub curve: NurbsCurve,
    pub lookup: CurveLookup,
    pub emax: f64,
    pub erms: f64,
    /// Vertical errors at the data points (table units, signed: curve − data).
    pub residuals: Vec<f64>,
}

impl Candidate {
    /// `(mean |e|^q)^(1/q)`: a smooth stand-in for `emax` (q → ∞).
    pub fn lp_norm(&self, q: f64) -> f64 {
        if self.emax == 0.0 {
            return 0.0;
        }
        let mean = self
            .residuals
            .iter()
            .map(|e| (e.abs() / self.emax).powf(q))
            .sum::<f64>()
            / self.residuals.len() as f64;
        self.emax * mean.powf(1.0 / q)
    }
}

impl FitProblem {
    /// `positions` strictly increasing and finite, `values` finite, same length,
    /// at least `degree + 2` points (checked by the caller, `smem::fit_parameter`).
    pub fn new(
        positions: &[f64],
        values: &[f64],
        degree: usize,
        parameterization: Parameterization,
    ) -> FitProblem {
        let m = positions.len();
        let x0 = positions[0];
        let sx = positions[m - 1] - x0;
        let (ymin, ymax) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let sy = if ymax > ymin { ymax - ymin } else { 1.0 };
        let pts: Vec<[f64; 2]> = positions
            .iter()
            .zip(values)
            .map(|(&x, &y)| [(x - x0) / sx, (y - ymin) / sy])
            .collect();
        let params = parameterize(&pts, parameterization);
        FitProblem {
            degree,
            positions: positions.to_vec(),
            values: values.to_vec(),
            normalised: pts.iter().flatten().copied().collect(),
            params,
            origin: [x0, ymin],
            scale: [sx, sy],
            min_control_advance: 0.0,
            work: Work {
                done: AtomicU64::new(0),
                limit: u64::MAX,
            },
        }
    }

    /// The same problem with a limit on the work of its fits (samples ×
    /// control points, summed over [`FitProblem::evaluate`] calls): once it is
    /// spent, every candidate is infeasible, so any search ends quickly, and
    /// [`FitProblem::work_exhausted`] says why.
    pub fn with_work_limit(mut self, limit: u64) -> FitProblem {
        self.work.limit = limit;
        self
    }

    /// The work limit was reached: candidates after it were not evaluated.
    pub fn work_exhausted(&self) -> bool {
        self.work.done.load(Ordering::Relaxed) > self.work.limit
    }

    /// Work spent so far (samples × control points over all fits).
    pub fn work_done(&self) -> u64 {
        self.work.done.load(Ordering::Relaxed)
    }

    /// The same problem for a search over knots and weights: candidates whose
    /// control polygon advances by less than `MIN_CONTROL_ADVANCE` of the uniform
    /// spacing are infeasible. A search minimising Emax otherwise finds near-cusps
    /// that pass the data points and jump between them; a fixed knot placement
    /// cannot aim for them, so it only needs a polygon that advances at all.
    pub fn regular(mut self) -> FitProblem {
        self.min_control_advance = MIN_CONTROL_ADVANCE;
        self
    }

    /// Number of data points.
    pub fn samples(&self) -> usize {
        self.positions.len()
    }

    /// Fit with clamped knots on `[0, 1]` with these interior knots and weights
    /// (`weights.len() = interior.len() + degree + 1`).
    pub fn evaluate(&self, interior: &[f64], weights: &[f64]) -> Option<Candidate> {
        let p = self.degree;
        let cost = (self.positions.len() * weights.len()) as u64;
        let before = self.work.done.fetch_add(cost, Ordering::Relaxed);
        if before.saturating_add(cost) > self.work.limit {
            return None;
        }
        let knots = knot_vector::clamped(p, interior, 0.0, 1.0);
        if !knot_vector::is_valid_clamped(&knots, p)
            || !knot_vector::schoenberg_whitney(&knots, p, &self.params)
        {
            return None;
        }
        let ctrl =
            fit_control_points(&self.params, &self.normalised, 2, p, &knots, weights).ok()?;
        // The control polygon must advance in position, by at least a fraction of
        // the uniform spacing: with positive weights that makes x(u) monotone (the
        // variation-diminishing property), and it rules out near-cusps (a polygon
        // folding back, or crawling, around two close knots) that pass the data
        // points while jumping between them.
        let n_ctrl = ctrl.len() / 2;
        let min_advance = self.min_control_advance / (n_ctrl.max(2) - 1) as f64;
        if ctrl
            .chunks_exact(2)
            .zip(ctrl.chunks_exact(2).skip(1))
            .any(|(a, b)| !(b[0] - a[0] > min_advance))
        {
            return None;
        }
        let points: Vec<[f64; 2]> = ctrl
            .chunks_exact(2)
            .map(|c| {
                [
                    self.origin[0] + self.scale[0] * c[0],
                    self.origin[1] + self.scale[1] * c[1],
                ]
            })
            .collect();
        let curve = NurbsCurve::new(p, knots, weights.to_vec(), points).ok()?;
        let lookup = CurveLookup::new(&curve).ok()?;
        let residuals = self.residuals(&lookup);
        let emax = residuals.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        let erms = (residuals.iter().map(|e| e * e).sum::<f64>() / residuals.len() as f64).sqrt();
        Some(Candidate {
            curve,
            lookup,
            emax,
            erms,
            residuals,
        })
    }

    /// `emax` of a candidate, `+∞` when infeasible: the optimisers' objective.
    pub fn emax(&self, interior: &[f64], weights: &[f64]) -> f64 {
        self.evaluate(interior, weights)
            .map_or(f64::INFINITY, |c| c.emax)
    }

    /// Vertical errors `y(u) − y_k` at the data points through the exact inversion.
    pub fn residuals(&self, lookup: &CurveLookup) -> Vec<f64> {
        self.positions
            .iter()
            .zip(&self.values)
            .map(|(&x, &y)| lookup.value_at(x) - y)
            .collect()
    }
}
