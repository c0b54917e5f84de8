//! Knot sets on a uniform grid of `M` segments (the candidates `j / M`,
//! `1 ≤ j < M`): the search space shared by the paper's GA, the exhaustive
//! search and `best`'s first stage, in its own file so that none of them imports
//! another for it.
//!
//! A knot set is a sorted list of grid indices. The GA and the exhaustive search
//! use distinct indices (the paper's binary chromosome); `best` also admits a
//! double knot (an index taken twice, at most [`MAX_MULTIPLICITY`] times): a C¹
//! join, which a sharp feature of the data can need.
use rand::Rng;
use rand::seq::SliceRandom;

/// The best knot set found on a grid: sorted candidate indices in `1..M`.
#[derive(Clone, Debug, PartialEq)]
pub struct GridResult {
    pub indices: Vec<usize>,
    pub emax: f64,
    pub erms: f64,
    /// Least-squares fits evaluated.
    pub evaluations: u64,
}

/// `C(n, k)`, saturating at `u64::MAX`.
pub fn combinations(n: usize, k: usize) -> u64 {
    if k > n {
        return 0;
    }
    let k = k.min(n - k);
    let mut r: u128 = 1;
    for i in 0..k {
        r = r * (n - i) as u128 / (i + 1) as u128;
        if r > u64::MAX as u128 {
            return u64::MAX;
        }
    }
    r as u64
}

/// Most times one grid index may appear in a knot set of `best` (a cubic stays
/// C¹ across a double knot).
pub const MAX_MULTIPLICITY: usize = 2;

/// A random k-subset of `1..segments`, sorted (distinct indices).
pub fn random_indices(rng: &mut impl Rng, segments: usize, k: usize) -> Vec<usize> {
    sorted_sample(rng, (1..segments).collect(), k)
}

/// A random sorted multiset of `k` indices in `1..segments`, each at most
/// [`MAX_MULTIPLICITY`] times: distinct when the grid holds `k` of them.
pub fn random_multiset(rng: &mut impl Rng, segments: usize, k: usize) -> Vec<usize> {
    if k < segments {
        return random_indices(rng, segments, k);
    }
    let pool = (1..segments)
        .flat_map(|t| std::iter::repeat_n(t, MAX_MULTIPLICITY))
        .collect();
    sorted_sample(rng, pool, k)
}

/// `k` of `pool`, drawn at random, sorted.
fn sorted_sample(rng: &mut impl Rng, mut pool: Vec<usize>, k: usize) -> Vec<usize> {
    pool.shuffle(rng);
    pool.truncate(k);
    pool.sort_unstable();
    pool
}

/// Snap knots in (0, 1) to distinct sorted grid indices in `1..segments`
/// (`knots.len() < segments`).
pub fn snap(knots: &[f64], segments: usize) -> Vec<usize> {
    let k = knots.len();
    let mut idx: Vec<usize> = knots
        .iter()
        .map(|&u| ((u * segments as f64).round() as usize).clamp(1, segments - 1))
        .collect();
    idx.sort_unstable();
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

/// Is a sorted index list a valid multiset (no index more than
/// [`MAX_MULTIPLICITY`] times)?
pub fn within_multiplicity(indices: &[usize]) -> bool {
    indices
        .windows(MAX_MULTIPLICITY + 1)
        .all(|w| w[0] != w[MAX_MULTIPLICITY])
}

/// The number of sorted multisets of `k` indices out of `candidates`, each index
/// at most twice, saturating at `u64::MAX`.
pub fn multiset_count(candidates: usize, k: usize) -> u64 {
    // d doubles and k − 2d singles among the remaining candidates.
    (0..=k / 2)
        .map(|d| {
            combinations(candidates, d)
                .saturating_mul(combinations(candidates - d.min(candidates), k - 2 * d))
        })
        .fold(0u64, u64::saturating_add)
}

/// Every sorted multiset of `k` indices in `1..segments`, each at most twice.
pub fn multisets(segments: usize, k: usize) -> Vec<Vec<usize>> {
    fn extend(
        current: &mut Vec<usize>,
        from: usize,
        segments: usize,
        k: usize,
        out: &mut Vec<Vec<usize>>,
    ) {
        if current.len() == k {
            out.push(current.clone());
            return;
        }
        for t in from..segments {
            for times in 1..=MAX_MULTIPLICITY.min(k - current.len()) {
                current.extend(std::iter::repeat_n(t, times));
                extend(current, t + 1, segments, k, out);
                current.truncate(current.len() - times);
            }
        }
    }
    let mut out = Vec::new();
    extend(&mut Vec::with_capacity(k), 1, segments, k, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multisets_are_counted_and_listed_alike() {
        for (segments, k) in [(6, 0), (6, 1), (6, 2), (8, 3), (10, 4), (5, 6)] {
            let all = multisets(segments, k);
            assert_eq!(
                all.len() as u64,
                multiset_count(segments - 1, k),
                "{segments} {k}"
            );
            assert!(all.iter().all(|s| s.len() == k && within_multiplicity(s)));
            assert!(all.iter().all(|s| s.windows(2).all(|w| w[0] <= w[1])));
        }
        // 4 candidates, 2 knots: C(4, 2) pairs and 4 doubles.
        assert_eq!(multiset_count(4, 2), 10);
        assert!(!within_multiplicity(&[2, 3, 3, 3]));
    }

    #[test]
    fn snapped_indices_are_distinct_and_on_the_grid() {
        assert_eq!(snap(&[0.01, 0.02, 0.03], 10), vec![1, 2, 3]);
        assert_eq!(snap(&[0.97, 0.98, 0.99], 10), vec![7, 8, 9]);
        assert_eq!(snap(&[0.25, 0.5], 4), vec![1, 2]);
    }
}
