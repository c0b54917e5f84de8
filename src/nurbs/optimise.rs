//! volcomp's own knot optimiser (method `best`), beyond the paper's GA:
//!
//! 1. **Grid local search** on the same grid of `M` segments as the GA: starting
//!    from UKM, EPM and LAM snapped to the grid and a few seeded random starts, move
//!    one knot at a time to any free grid candidate, taking the best move, until no
//!    move lowers `(emax, erms)` (lexicographic, so plateaus of the max norm are
//!    left through the RMS). Each pass costs `(n − p)(M − 1 − n + p)` fits and every
//!    pass strictly improves, so it stops; fits are memoised.
//! 2. **Continuous free-knot refinement**: a compass (pattern) search on the knot
//!    positions themselves, off the grid, keeping them ordered with a minimum gap;
//!    steps halve when no knot moves, down to `1e-6`; first on a smooth surrogate
//!    of the max norm (the L8 mean of the errors), then on `(emax, erms)`. Only
//!    improvements are accepted, so the result is never worse than its start (the
//!    grid optima found in 1; the 2 best are refined).
//! 3. Weights (when the tolerance is still missed): the same compass search on
//!    `ln w_i`, within the GA's weight range.
use std::collections::HashMap;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::knot_placement::{self, grid_knots};
use super::problem::FitProblem;

/// The best knot set found on a grid: sorted candidate indices in `1..M`.
#[derive(Clone, Debug, PartialEq)]
pub struct GridResult {
    pub indices: Vec<usize>,
    pub emax: f64,
    pub erms: f64,
    /// Least-squares fits evaluated.
    pub evaluations: u64,
}

/// Result of a continuous refinement.
#[derive(Clone, Debug)]
pub struct Refined {
    pub interior: Vec<f64>,
    pub weights: Vec<f64>,
    pub emax: f64,
    pub erms: f64,
    pub evaluations: u64,
}

/// Random restarts of the grid local search besides UKM, EPM and LAM.
const RANDOM_STARTS: usize = 4;

struct Memo<'a> {
    problem: &'a FitProblem,
    segments: usize,
    weights: Vec<f64>,
    cache: HashMap<Vec<usize>, (f64, f64)>,
    evaluations: u64,
}

impl Memo<'_> {
    fn score(&mut self, indices: &[usize]) -> (f64, f64) {
        if let Some(&v) = self.cache.get(indices) {
            return v;
        }
        self.evaluations += 1;
        let v = self
            .problem
            .evaluate(&grid_knots(indices, self.segments), &self.weights)
            .map_or((f64::INFINITY, f64::INFINITY), |c| (c.emax, c.erms));
        self.cache.insert(indices.to_vec(), v);
        v
    }
}

/// Snap knots in (0, 1) to distinct sorted grid indices in `1..segments`.
fn snap(knots: &[f64], segments: usize) -> Vec<usize> {
    let k = knots.len();
    let mut idx: Vec<usize> = knots
        .iter()
        .map(|&u| ((u * segments as f64).round() as usize).clamp(1, segments - 1))
        .collect();
    // Make strictly increasing within 1..=segments-1 (k <= segments - 1).
    for j in 0..k {
        let min = if j == 0 { 1 } else { idx[j - 1] + 1 };
        idx[j] = idx[j].max(min);
    }
    for j in (0..k).rev() {
        let max = if j + 1 == k {
            segments - 1
        } else {
            idx[j + 1] - 1
        };
        idx[j] = idx[j].min(max);
    }
    idx
}

/// Grids with at most this many knot combinations are searched exhaustively.
pub const EXACT_SEARCH_LIMIT: u64 = 2_000;

/// Perturbation rounds of the iterated local search.
const KICKS: usize = 12;

/// Step 1 of the module doc: the best grid knot sets found (best first, at most
/// `keep`, distinct local optima), by exact enumeration when the grid has at most
/// [`EXACT_SEARCH_LIMIT`] combinations, else by iterated local search.
pub fn grid_search_top(
    problem: &FitProblem,
    n: usize,
    segments: usize,
    seed: u64,
    keep: usize,
) -> Vec<GridResult> {
    let p = problem.degree;
    let k = n - p;
    let mut memo = Memo {
        problem,
        segments,
        weights: vec![1.0; n + 1],
        cache: HashMap::new(),
        evaluations: 0,
    };
    if k == 0 || segments < k + 1 {
        let (emax, erms) = memo.score(&[]);
        return vec![GridResult {
            indices: Vec::new(),
            emax,
            erms,
            evaluations: memo.evaluations,
        }];
    }
    if super::exhaustive::combinations(segments - 1, k) <= EXACT_SEARCH_LIMIT {
        if let Ok(r) = super::exhaustive::search(problem, n, segments, EXACT_SEARCH_LIMIT) {
            return vec![r];
        }
    }
    let mut starts = vec![
        snap(&knot_placement::uniform(n, p), segments),
        snap(
            &knot_placement::equal_partition(&problem.params, n, p),
            segments,
        ),
        snap(
            &knot_placement::local_average(&problem.params, n, p),
            segments,
        ),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..RANDOM_STARTS {
        starts.push(random_indices(&mut rng, segments, k));
    }
    starts.dedup();
    let mut optima: Vec<(Vec<usize>, (f64, f64))> = Vec::new();
    for start in starts {
        optima.push(local_search(&mut memo, start, segments));
    }
    let order = |a: &(Vec<usize>, (f64, f64)), b: &(Vec<usize>, (f64, f64))| {
        a.1.0
            .total_cmp(&b.1.0)
            .then(a.1.1.total_cmp(&b.1.1))
            .then_with(|| a.0.cmp(&b.0))
    };
    optima.sort_by(order);
    // Iterated local search: kick the incumbent (move two knots at random), descend.
    for _ in 0..KICKS {
        let mut kicked = optima[0].0.clone();
        for _ in 0..2.min(k) {
            let j = rng.random_range(0..k);
            let free: Vec<usize> = (1..segments)
                .filter(|t| kicked.binary_search(t).is_err())
                .collect();
            if free.is_empty() {
                break;
            }
            kicked[j] = free[rng.random_range(0..free.len())];
            kicked.sort_unstable();
        }
        optima.push(local_search(&mut memo, kicked, segments));
        optima.sort_by(order);
    }
    optima.dedup_by(|a, b| a.0 == b.0);
    let evaluations = memo.evaluations;
    optima
        .into_iter()
        .take(keep.max(1))
        .map(|(indices, (emax, erms))| GridResult {
            indices,
            emax,
            erms,
            evaluations,
        })
        .collect()
}

/// The best grid knot set of [`grid_search_top`].
pub fn grid_search(problem: &FitProblem, n: usize, segments: usize, seed: u64) -> GridResult {
    grid_search_top(problem, n, segments, seed, 1).swap_remove(0)
}

/// Steps 1 and 2: refine the best few grid optima off the grid and keep the best.
/// Never worse than the best grid knot set found.
pub fn best_knots(problem: &FitProblem, n: usize, segments: usize, seed: u64) -> Refined {
    let top = grid_search_top(problem, n, segments, seed, 2);
    let mut evaluations = top[0].evaluations;
    let weights = vec![1.0; n + 1];
    let mut best: Option<Refined> = None;
    for g in &top {
        let r = refine_knots(problem, &grid_knots(&g.indices, segments), &weights);
        evaluations += r.evaluations;
        if best
            .as_ref()
            .is_none_or(|b| (r.emax, r.erms) < (b.emax, b.erms))
        {
            best = Some(r);
        }
    }
    let mut best = best.unwrap_or_else(|| refine_knots(problem, &[], &weights));
    best.evaluations = evaluations;
    best
}

fn local_search(
    memo: &mut Memo<'_>,
    mut current: Vec<usize>,
    segments: usize,
) -> (Vec<usize>, (f64, f64)) {
    let mut score = memo.score(&current);
    loop {
        let mut best_move: Option<(Vec<usize>, (f64, f64))> = None;
        for j in 0..current.len() {
            for target in 1..segments {
                if current.binary_search(&target).is_ok() {
                    continue;
                }
                let mut cand = current.clone();
                cand[j] = target;
                cand.sort_unstable();
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
    const MIN_GAP: f64 = 1e-4;
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

/// A random k-subset of `1..segments`, sorted (shared with the GA's initialisation).
pub fn random_indices(rng: &mut impl Rng, segments: usize, k: usize) -> Vec<usize> {
    let mut all: Vec<usize> = (1..segments).collect();
    all.shuffle(rng);
    let mut s = all[..k].to_vec();
    s.sort_unstable();
    s
}
