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
//!    steps halve when no knot moves, down to `1e-6`. It only accepts improvements,
//!    so the result is never worse than its start (the grid optimum found in 1).
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
const RANDOM_STARTS: usize = 3;

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

/// Step 1 of the module doc: the best grid knot set found by local search.
pub fn grid_search(problem: &FitProblem, n: usize, segments: usize, seed: u64) -> GridResult {
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
        return GridResult {
            indices: Vec::new(),
            emax,
            erms,
            evaluations: memo.evaluations,
        };
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
    let mut all: Vec<usize> = (1..segments).collect();
    for _ in 0..RANDOM_STARTS {
        all.shuffle(&mut rng);
        let mut s = all[..k].to_vec();
        s.sort_unstable();
        starts.push(s);
    }
    starts.dedup();
    let mut best: Option<(Vec<usize>, (f64, f64))> = None;
    for start in starts {
        let (idx, score) = local_search(&mut memo, start, segments);
        if best
            .as_ref()
            .is_none_or(|(bi, bs)| score < *bs || (score == *bs && idx < *bi))
        {
            best = Some((idx, score));
        }
    }
    let (indices, (emax, erms)) = best.unwrap_or_default();
    GridResult {
        indices,
        emax,
        erms,
        evaluations: memo.evaluations,
    }
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

/// Step 2 of the module doc: compass search on the knot positions.
pub fn refine_knots(problem: &FitProblem, start: &[f64], weights: &[f64]) -> Refined {
    let mut interior = start.to_vec();
    let mut evaluations = 1;
    let eval = |knots: &[f64]| {
        problem
            .evaluate(knots, weights)
            .map_or((f64::INFINITY, f64::INFINITY), |c| (c.emax, c.erms))
    };
    let mut score = eval(&interior);
    let min_gap = 1e-4;
    let mut step = 0.5 / (interior.len() + 1) as f64 / 4.0;
    const MAX_EVALUATIONS: u64 = 4000;
    while step >= 1e-6 && evaluations < MAX_EVALUATIONS {
        let mut moved = false;
        for j in 0..interior.len() {
            let lo = if j == 0 { 0.0 } else { interior[j - 1] } + min_gap;
            let hi = if j + 1 == interior.len() {
                1.0
            } else {
                interior[j + 1]
            } - min_gap;
            for dir in [1.0, -1.0] {
                let u = interior[j] + dir * step;
                if u < lo || u > hi {
                    continue;
                }
                let mut cand = interior.clone();
                cand[j] = u;
                evaluations += 1;
                let s = eval(&cand);
                if s < score {
                    interior = cand;
                    score = s;
                    moved = true;
                    break;
                }
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    Refined {
        interior,
        weights: weights.to_vec(),
        emax: score.0,
        erms: score.1,
        evaluations,
    }
}

/// Step 3 of the module doc: compass search on `ln w` within `range`.
pub fn refine_weights(
    problem: &FitProblem,
    interior: &[f64],
    start: &[f64],
    range: (f64, f64),
) -> Refined {
    let (lo, hi) = (range.0.max(1e-6).ln(), range.1.max(range.0.max(1e-6)).ln());
    let mut logw: Vec<f64> = start.iter().map(|w| w.ln().clamp(lo, hi)).collect();
    let eval = |lw: &[f64]| {
        let w: Vec<f64> = lw.iter().map(|v| v.exp()).collect();
        problem
            .evaluate(interior, &w)
            .map_or((f64::INFINITY, f64::INFINITY), |c| (c.emax, c.erms))
    };
    let mut evaluations = 1;
    let mut score = eval(&logw);
    let mut step = 0.25;
    const MAX_EVALUATIONS: u64 = 3000;
    while step >= 1e-3 && evaluations < MAX_EVALUATIONS {
        let mut moved = false;
        for j in 0..logw.len() {
            for dir in [1.0, -1.0] {
                let v = logw[j] + dir * step;
                if v < lo || v > hi {
                    continue;
                }
                let mut cand = logw.clone();
                cand[j] = v;
                evaluations += 1;
                let s = eval(&cand);
                if s < score {
                    logw = cand;
                    score = s;
                    moved = true;
                    break;
                }
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    let weights = logw.iter().map(|v| v.exp()).collect();
    Refined {
        interior: interior.to_vec(),
        weights,
        emax: score.0,
        erms: score.1,
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
