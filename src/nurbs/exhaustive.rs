//! The paper's "combination global search" (Table 4): every choice of `n − p`
//! interior knots among the `M − 1` candidates `j / M` of a uniform grid. The
//! reference optimum on the grid for tests and benchmarks; cost `C(M − 1, n − p)`
//! least-squares fits (run in parallel with rayon).
//!
//! Ties are broken deterministically: smallest `emax`, then smallest `erms`, then
//! the lexicographically smallest index set, whatever the thread schedule.
use rayon::prelude::*;

use super::fit_error::FitError;
use super::knot_grid::{GridResult, combinations};
use super::knot_placement::grid_knots;
use super::problem::FitProblem;

/// Advance `idx` (sorted, values in `lo..=hi`) to the next combination; false at the end.
fn next_combination(idx: &mut [usize], hi: usize) -> bool {
    let k = idx.len();
    for j in (0..k).rev() {
        if idx[j] < hi - (k - 1 - j) {
            idx[j] += 1;
            for t in j + 1..k {
                idx[t] = idx[t - 1] + 1;
            }
            return true;
        }
    }
    false
}

/// Candidate ordering: (emax, erms, indices) ascending.
fn better(a: &GridResult, b: &GridResult) -> bool {
    (a.emax, a.erms) < (b.emax, b.erms)
        || ((a.emax, a.erms) == (b.emax, b.erms) && a.indices < b.indices)
}

/// Best `n − p` grid knots of `segments` segments by enumeration. Errors when the
/// count exceeds `limit`.
pub fn search(
    problem: &FitProblem,
    n: usize,
    segments: usize,
    limit: u64,
) -> Result<GridResult, FitError> {
    let p = problem.degree;
    let k = n - p;
    let candidates = segments.saturating_sub(1);
    let count = combinations(candidates, k);
    if count > limit {
        return Err(FitError::TooManyCombinations {
            candidates,
            choose: k,
            count,
            limit,
        });
    }
    let weights = vec![1.0; n + 1];
    let score = |indices: &[usize]| -> GridResult {
        let interior = grid_knots(indices, segments);
        let (emax, erms) = problem
            .evaluate(&interior, &weights)
            .map_or((f64::INFINITY, f64::INFINITY), |c| (c.emax, c.erms));
        GridResult {
            indices: indices.to_vec(),
            emax,
            erms,
            evaluations: 1,
        }
    };
    if k == 0 {
        return Ok(score(&[]));
    }
    if candidates < k {
        return Err(FitError::NoFeasibleFit);
    }
    // Parallel over the first index; each task enumerates the rest.
    let best = (1..=candidates - k + 1)
        .into_par_iter()
        .map(|first| {
            let mut idx: Vec<usize> = (0..k).map(|j| first + j).collect();
            let mut best = score(&idx);
            let mut evaluations = 1;
            while next_combination(&mut idx[1..], candidates) {
                let r = score(&idx);
                evaluations += 1;
                if better(&r, &best) {
                    best = r;
                }
            }
            best.evaluations = evaluations;
            best
        })
        .reduce_with(|a, b| {
            let evaluations = a.evaluations + b.evaluations;
            let mut r = if better(&b, &a) { b } else { a };
            r.evaluations = evaluations;
            r
        })
        .ok_or(FitError::NoFeasibleFit)?;
    if !best.emax.is_finite() {
        return Err(FitError::NoFeasibleFit);
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enumerates_all_combinations() {
        assert_eq!(combinations(32, 6), 906_192);
        assert_eq!(combinations(12, 6), 924);
        let mut idx = vec![2, 3];
        let mut seen = 1;
        while next_combination(&mut idx, 5) {
            seen += 1;
        }
        // first index fixed at 1: pairs from 2..=5.
        assert_eq!(seen, combinations(4, 2));
    }
}
