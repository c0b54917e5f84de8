//! volcomp's own knot optimiser (method `best`), beyond the paper's GA. Its aim
//! is the least Emax over knots anywhere in (0, 1), whatever grid it starts on.
//!
//! 1. **Grid search with double knots** on a grid of `M` segments (default
//!    `3 (n − p) + 1`, finer than the paper's `2 (n − p) + 1`): a knot set is a
//!    multiset of grid indices, each at most twice ([`MAX_MULTIPLICITY`]; a double
//!    knot is a C¹ join). The better optima of Emax pair knots close together at
//!    sharp features, which a grid of distinct knots cannot reach.
//!    - When the grid holds at most [`EXACT_SEARCH_LIMIT`] multisets, all are
//!      scored (in parallel).
//!    - Otherwise an iterated local search: from UKM, EPM and LAM snapped to the
//!      grid and [`RANDOM_STARTS`] seeded random starts, move one knot at a time
//!      to any grid index (doubling one is a move), taking the best move, until
//!      no move lowers `(emax, erms)` (lexicographic, so plateaus of the max norm
//!      are left through the RMS); then [`KICKS`] times, move two knots of the
//!      incumbent at random and descend again. Descents run in parallel (the
//!      starts, then the kicks in rounds), each with its memo of fits; every
//!      pass strictly improves, so each descent stops.
//! 2. **Continuous refinement** of the best [`POLISHED`] grid optima, one per
//!    basin (a knot set within one grid step of a better one is skipped), off
//!    the grid by two local methods whose better result is kept:
//!    - [`minimax_knots`]: Levenberg–Marquardt steps on linearised Chebyshev
//!      problems (finite-difference Jacobian of the residuals in the knots);
//!    - [`refine_knots`]: a compass search, first on a smooth surrogate of the
//!      max norm, then on `(emax, erms)`.
//!
//!    Both accept only improvements, so the result is never worse than the best
//!    grid knot set.
//! 3. Weights (when the tolerance is still missed): the compass search on
//!    `ln w_i`, within the GA's weight range.
//!
//! How close this comes to the optimum over the continuum is measured by
//! `cargo run --release --example knot_search` (docs/fidelity.md).
use std::collections::HashMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::knot_grid::{
    GridResult, MAX_MULTIPLICITY, multiset_count, multisets, random_multiset, snap,
    within_multiplicity,
};
use super::knot_placement::{self, grid_knots};
use super::problem::FitProblem;

/// Result of a continuous refinement.
#[derive(Clone, Debug)]
pub struct Refined {
    pub interior: Vec<f64>,
    pub weights: Vec<f64>,
    pub emax: f64,
    pub erms: f64,
    pub evaluations: u64,
}

/// Random starts of the grid local search besides UKM, EPM and LAM.
pub const RANDOM_STARTS: usize = 8;

/// Perturbations of the iterated local search ...
pub const KICKS: usize = 24;

/// ... descended in parallel this many at a time, from the incumbent of the
/// round before.
const KICKS_PER_ROUND: usize = 4;

/// Grid optima (one per basin) refined off the grid by [`minimax_knots`] ...
pub const POLISHED: usize = 8;

/// ... and the best of them, also by [`refine_knots`].
const COMPASS_POLISHED: usize = 2;

/// Grids with at most this many knot multisets are searched exhaustively.
pub const EXACT_SEARCH_LIMIT: u64 = 2_000;

/// The default grid of `best` for `k` interior knots.
pub fn default_segments(k: usize) -> usize {
    3 * k + 1
}

type Score = (f64, f64);

/// `(emax, erms)` of a valid knot multiset (`+∞` when infeasible).
fn score_of(problem: &FitProblem, indices: &[usize], segments: usize, weights: &[f64]) -> Score {
    problem
        .evaluate(&grid_knots(indices, segments), weights)
        .map_or((f64::INFINITY, f64::INFINITY), |c| (c.emax, c.erms))
}

struct Memo<'a> {
    problem: &'a FitProblem,
    segments: usize,
    weights: Vec<f64>,
    cache: HashMap<Vec<usize>, Score>,
    evaluations: u64,
}

impl Memo<'_> {
    fn score(&mut self, indices: &[usize]) -> Score {
        if let Some(&v) = self.cache.get(indices) {
            return v;
        }
        self.evaluations += 1;
        let v = score_of(self.problem, indices, self.segments, &self.weights);
        self.cache.insert(indices.to_vec(), v);
        v
    }
}

/// `(score, indices)` ascending: the order of every result list here.
fn order(a: &(Vec<usize>, Score), b: &(Vec<usize>, Score)) -> std::cmp::Ordering {
    a.1.0
        .total_cmp(&b.1.0)
        .then(a.1.1.total_cmp(&b.1.1))
        .then_with(|| a.0.cmp(&b.0))
}

/// Step 1 of the module doc: the best grid knot sets found (best first, at most
/// `keep`, distinct).
pub fn grid_search_top(
    problem: &FitProblem,
    n: usize,
    segments: usize,
    seed: u64,
    keep: usize,
) -> Vec<GridResult> {
    let p = problem.degree;
    let k = n - p;
    let weights = vec![1.0; n + 1];
    let finish = |mut optima: Vec<(Vec<usize>, Score)>, evaluations: u64| {
        optima.sort_by(order);
        optima.dedup_by(|a, b| a.0 == b.0);
        // One per basin: a set within one grid step of a better one is skipped.
        let near = |a: &[usize], b: &[usize]| a.iter().zip(b).all(|(x, y)| x.abs_diff(*y) <= 1);
        let mut kept: Vec<(Vec<usize>, Score)> = Vec::new();
        for o in optima {
            if kept.len() == keep.max(1) {
                break;
            }
            if !kept.iter().any(|q| near(&q.0, &o.0)) {
                kept.push(o);
            }
        }
        kept.into_iter()
            .map(|(indices, (emax, erms))| GridResult {
                indices,
                emax,
                erms,
                evaluations,
            })
            .collect::<Vec<_>>()
    };
    if k == 0 || segments < 2 {
        return finish(
            vec![(Vec::new(), score_of(problem, &[], segments, &weights))],
            1,
        );
    }
    if multiset_count(segments - 1, k) <= EXACT_SEARCH_LIMIT {
        let all: Vec<(Vec<usize>, Score)> = multisets(segments, k)
            .into_par_iter()
            .map(|s| {
                let v = score_of(problem, &s, segments, &weights);
                (s, v)
            })
            .collect();
        let evaluations = all.len() as u64;
        return finish(all, evaluations);
    }
    let mut starts = Vec::new();
    if k < segments {
        starts.push(snap(&knot_placement::uniform(n, p), segments));
        starts.push(snap(
            &knot_placement::equal_partition(&problem.params, n, p),
            segments,
        ));
        starts.push(snap(
            &knot_placement::local_average(&problem.params, n, p),
            segments,
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..RANDOM_STARTS {
        starts.push(random_multiset(&mut rng, segments, k));
    }
    starts.dedup();
    let descend_all = |starts: Vec<Vec<usize>>| -> (Vec<(Vec<usize>, Score)>, u64) {
        let runs: Vec<((Vec<usize>, Score), u64)> = starts
            .into_par_iter()
            .map(|start| {
                let mut memo = Memo {
                    problem,
                    segments,
                    weights: weights.clone(),
                    cache: HashMap::new(),
                    evaluations: 0,
                };
                let r = local_search(&mut memo, start, segments);
                (r, memo.evaluations)
            })
            .collect();
        let evaluations = runs.iter().map(|r| r.1).sum();
        (runs.into_iter().map(|r| r.0).collect(), evaluations)
    };
    let (mut optima, mut evaluations) = descend_all(starts);
    optima.sort_by(order);
    // Kicks, in rounds descended in parallel: move two knots of the incumbent.
    for _ in 0..KICKS.div_ceil(KICKS_PER_ROUND) {
        let kicked: Vec<Vec<usize>> = (0..KICKS_PER_ROUND)
            .map(|_| {
                let mut kicked = optima[0].0.clone();
                for _ in 0..2.min(k) {
                    let j = rng.random_range(0..k);
                    kicked[j] = rng.random_range(1..segments);
                }
                kicked.sort_unstable();
                kicked
            })
            .filter(|s| within_multiplicity(s))
            .collect();
        let (found, e) = descend_all(kicked);
        evaluations += e;
        optima.extend(found);
        optima.sort_by(order);
    }
    finish(optima, evaluations)
}

/// Steps 1 and 2: refine the best few grid optima off the grid and keep the best.
/// Never worse than the best grid knot set found.
pub fn best_knots(problem: &FitProblem, n: usize, segments: usize, seed: u64) -> Refined {
    let top = grid_search_top(problem, n, segments, seed, POLISHED);
    let weights = vec![1.0; n + 1];
    let mut evaluations = top[0].evaluations;
    let mut best = Refined {
        interior: grid_knots(&top[0].indices, segments),
        weights: weights.clone(),
        emax: top[0].emax,
        erms: top[0].erms,
        evaluations: 0,
    };
    let refined: Vec<Refined> = top
        .par_iter()
        .enumerate()
        .flat_map_iter(|(rank, g)| {
            let start = grid_knots(&g.indices, segments);
            let mut r = vec![minimax_knots(problem, &start, &weights)];
            if rank < COMPASS_POLISHED {
                r.push(refine_knots(problem, &separated(&start), &weights));
            }
            r
        })
        .collect();
    for r in refined {
        evaluations += r.evaluations;
        if (r.emax, r.erms) < (best.emax, best.erms) {
            best = r;
        }
    }
    best.evaluations = evaluations;
    best
}

/// Knots pulled apart to at least [`MIN_GAP`] (a double knot becomes two close
/// ones), for the compass search whose moves keep that gap.
fn separated(knots: &[f64]) -> Vec<f64> {
    let mut x = knots.to_vec();
    for j in 1..x.len() {
        if x[j] < x[j - 1] + MIN_GAP {
            x[j] = x[j - 1] + MIN_GAP;
        }
    }
    x
}

/// Least gap between knots kept by the continuous refinements (a double knot of
/// the grid search is the one exception [`minimax_knots`] keeps).
const MIN_GAP: f64 = 1e-4;

fn local_search(
    memo: &mut Memo<'_>,
    mut current: Vec<usize>,
    segments: usize,
) -> (Vec<usize>, Score) {
    let mut score = memo.score(&current);
    loop {
        let mut best_move: Option<(Vec<usize>, Score)> = None;
        for j in 0..current.len() {
            for target in 1..segments {
                if target == current[j] {
                    continue;
                }
                let mut cand = current.clone();
                cand[j] = target;
                cand.sort_unstable();
                if !within_multiplicity(&cand) {
                    continue;
                }
                let s = memo.score(&cand);
                if s < score && best_move.as_ref().is_none_or(|(_, bs)| s < *bs) {
                    best_move = Some((cand, s));
                }
            }
        }
        match best_move {
            Some((cand, s)) => {
                current = cand;
                score = s;
            }
            None => return (current, score),
        }
    }
}

/// Exponent of the smooth surrogate `(mean |e|^q)^(1/q)` of the max norm used by
/// the first phase of the refinements: a compass search on the max norm alone
/// stalls on its ridges (improving needs several coordinates to move together).
const SURROGATE_EXPONENT: f64 = 8.0;

/// Compass (coordinate pattern) search minimising `score` from `start`: each
/// coordinate tries `±step` within `bounds(x, j)`; the first improving move is
/// taken; the step halves when no coordinate moves; stops below `min_step` or
/// after `budget` evaluations. Returns the point, its score, evaluations.
fn compass_search(
    start: Vec<f64>,
    mut step: f64,
    min_step: f64,
    budget: u64,
    bounds: impl Fn(&[f64], usize) -> (f64, f64),
    mut score: impl FnMut(&[f64]) -> (f64, f64),
) -> (Vec<f64>, (f64, f64), u64) {
    let mut x = start;
    let mut best = score(&x);
    let mut evaluations = 1;
    while step >= min_step && evaluations < budget {
        let mut moved = false;
        for j in 0..x.len() {
            let (lo, hi) = bounds(&x, j);
            for dir in [1.0, -1.0] {
                let v = x[j] + dir * step;
                if v < lo || v > hi {
                    continue;
                }
                let mut cand = x.clone();
                cand[j] = v;
                evaluations += 1;
                let s = score(&cand);
                if s < best {
                    x = cand;
                    best = s;
                    moved = true;
                    break;
                }
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    (x, best, evaluations)
}

/// Refinement over coordinates `x`: compass search on the surrogate then on
/// `(emax, erms)`, and directly on `(emax, erms)` from the start; the better of
/// the two by `(emax, erms)` — never worse than the start.
fn refine(
    start: Vec<f64>,
    step: f64,
    min_step: f64,
    bounds: impl Fn(&[f64], usize) -> (f64, f64) + Copy,
    evaluate: impl Fn(&[f64]) -> Option<(f64, f64, f64)>,
) -> (Vec<f64>, (f64, f64), u64) {
    const BUDGET: u64 = 2000;
    let primary =
        |x: &[f64]| evaluate(x).map_or((f64::INFINITY, f64::INFINITY), |(e, r, _)| (e, r));
    let surrogate =
        |x: &[f64]| evaluate(x).map_or((f64::INFINITY, f64::INFINITY), |(e, _, l)| (l, e));
    let (a, _, ea) = compass_search(start.clone(), step, min_step, BUDGET, bounds, surrogate);
    let (b, b_score, eb) = compass_search(a, step / 4.0, min_step, BUDGET, bounds, primary);
    let (c, c_score, ec) = compass_search(start, step, min_step, BUDGET, bounds, primary);
    let evaluations = ea + eb + ec;
    // `c` never ends worse than the start: compass search only accepts improvements.
    if b_score < c_score {
        (b, b_score, evaluations)
    } else {
        (c, c_score, evaluations)
    }
}

/// Step 2 of the module doc: refinement of the knot positions (ordered, gap ≥ 1e-4).
pub fn refine_knots(problem: &FitProblem, start: &[f64], weights: &[f64]) -> Refined {
    let bounds = |x: &[f64], j: usize| {
        let lo = if j == 0 { 0.0 } else { x[j - 1] } + MIN_GAP;
        let hi = if j + 1 == x.len() { 1.0 } else { x[j + 1] } - MIN_GAP;
        (lo, hi)
    };
    let step = 0.5 / (start.len() + 1) as f64 / 4.0;
    let (interior, (emax, erms), evaluations) = refine(start.to_vec(), step, 1e-6, bounds, |x| {
        problem
            .evaluate(x, weights)
            .map(|c| (c.emax, c.erms, c.lp_norm(SURROGATE_EXPONENT)))
    });
    Refined {
        interior,
        weights: weights.to_vec(),
        emax,
        erms,
        evaluations,
    }
}

/// Step 3 of the module doc: refinement of `ln w` within `range`.
pub fn refine_weights(
    problem: &FitProblem,
    interior: &[f64],
    start: &[f64],
    range: (f64, f64),
) -> Refined {
    let (lo, hi) = (range.0.max(1e-6).ln(), range.1.max(range.0.max(1e-6)).ln());
    let logw: Vec<f64> = start.iter().map(|w| w.ln().clamp(lo, hi)).collect();
    let (logw, (emax, erms), evaluations) = refine(
        logw,
        0.25,
        1e-3,
        |_, _| (lo, hi),
        |lw| {
            let w: Vec<f64> = lw.iter().map(|v| v.exp()).collect();
            problem
                .evaluate(interior, &w)
                .map(|c| (c.emax, c.erms, c.lp_norm(SURROGATE_EXPONENT)))
        },
    );
    let weights = logw.iter().map(|v| v.exp()).collect();
    Refined {
        interior: interior.to_vec(),
        weights,
        emax,
        erms,
        evaluations,
    }
}

/// Lawson iterations of the linearised Chebyshev subproblem.
const LAWSON_ITERATIONS: usize = 60;

/// `min_δ max_i |r_i + J_i δ|` (approximately, by Lawson's iteratively reweighted
/// least squares) with a Levenberg–Marquardt damping `μ ‖δ‖²`. `jac` is row-major
/// `r.len() × k`.
fn chebyshev_step(r: &[f64], jac: &[f64], k: usize, mu: f64) -> Option<Vec<f64>> {
    use nalgebra::{DMatrix, DVector};
    let m = r.len();
    let j = DMatrix::from_row_slice(m, k, jac);
    let r = DVector::from_column_slice(r);
    let mut w = DVector::from_element(m, 1.0 / m as f64);
    let mut delta = DVector::zeros(k);
    for _ in 0..LAWSON_ITERATIONS {
        // Normal equations of the weighted problem: (Jᵀ W J + μ I) δ = −Jᵀ W r.
        let scaled = DMatrix::from_fn(m, k, |i, c| j[(i, c)] * w[i].sqrt());
        let mut a = scaled.tr_mul(&scaled);
        for p in 0..k {
            a[(p, p)] += mu;
        }
        let b = -j.tr_mul(&r.component_mul(&w));
        delta = a.cholesky()?.solve(&b);
        let e = (&r + &j * &delta).abs();
        let total = w.dot(&e);
        if total.is_nan() || total <= 0.0 {
            break;
        }
        w = w.component_mul(&e) / total;
    }
    delta
        .iter()
        .all(|v| v.is_finite())
        .then(|| delta.as_slice().to_vec())
}

/// Minimax refinement of the knot positions off any grid: a Levenberg–Marquardt
/// sequence of linearised Chebyshev problems (finite-difference Jacobian of the
/// residuals with respect to the knots), accepting only steps that lower
/// `(emax, erms)`; a double knot may stay double or split. Never worse than the
/// start.
pub fn minimax_knots(problem: &FitProblem, start: &[f64], weights: &[f64]) -> Refined {
    const H: f64 = 1e-7;
    let k = start.len();
    let eval = |x: &[f64]| problem.evaluate(x, weights);
    let mut evaluations = 1;
    let Some(first) = eval(start) else {
        return Refined {
            interior: start.to_vec(),
            weights: weights.to_vec(),
            emax: f64::INFINITY,
            erms: f64::INFINITY,
            evaluations,
        };
    };
    let mut x = start.to_vec();
    let (mut emax, mut erms, mut r) = (first.emax, first.erms, first.residuals);
    if k == 0 {
        return Refined {
            interior: x,
            weights: weights.to_vec(),
            emax,
            erms,
            evaluations,
        };
    }
    // Sorted, inside (0, 1) by MIN_GAP, and at most a pair of knots closer
    // than MIN_GAP (a double knot).
    let ordered = |x: &[f64]| {
        x.windows(2).all(|w| w[0] <= w[1])
            && x.windows(MAX_MULTIPLICITY + 1)
                .all(|w| w[MAX_MULTIPLICITY] - w[0] >= MIN_GAP)
            && x[0] >= MIN_GAP
            && x[k - 1] <= 1.0 - MIN_GAP
    };
    let mut mu = 1e-2;
    let mut fresh = true;
    let mut jac = vec![0.0; r.len() * k];
    for _ in 0..80 {
        if fresh {
            for j in 0..k {
                let mut xp = x.clone();
                // One-sided, away from a neighbour too close (the other knot of a
                // double knot, or the end of the domain).
                let h = if x[j] + H <= x.get(j + 1).copied().unwrap_or(1.0 - MIN_GAP) {
                    H
                } else {
                    -H
                };
                xp[j] += h;
                evaluations += 1;
                match eval(&xp) {
                    Some(c) => {
                        for i in 0..r.len() {
                            jac[i * k + j] = (c.residuals[i] - r[i]) / h;
                        }
                    }
                    None => {
                        for i in 0..r.len() {
                            jac[i * k + j] = 0.0;
                        }
                    }
                }
            }
            fresh = false;
        }
        let scale = (0..k)
            .map(|j| (0..r.len()).map(|i| jac[i * k + j].powi(2)).sum::<f64>())
            .sum::<f64>()
            / (k * r.len()) as f64;
        let Some(delta) = chebyshev_step(&r, &jac, k, mu * scale.max(1e-300)) else {
            mu *= 4.0;
            continue;
        };
        let cand: Vec<f64> = x.iter().zip(&delta).map(|(a, d)| a + d).collect();
        let step = delta.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        let mut accepted = false;
        if ordered(&cand) {
            evaluations += 1;
            if let Some(c) = eval(&cand) {
                if (c.emax, c.erms) < (emax, erms) {
                    x = cand;
                    emax = c.emax;
                    erms = c.erms;
                    r = c.residuals;
                    accepted = true;
                }
            }
        }
        if accepted {
            mu = (mu / 3.0).max(1e-9);
            fresh = true;
        } else {
            mu *= 4.0;
        }
        if step < 1e-9 || mu > 1e9 {
            break;
        }
    }
    Refined {
        interior: x,
        weights: weights.to_vec(),
        emax,
        erms,
        evaluations,
    }
}
