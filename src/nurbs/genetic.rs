//! The paper's improved genetic algorithm (§3.2) for knots and weights.
//!
//! Knots (§3.2.2): a binary chromosome over the `M − 1` candidate knots `j / M`
//! of a uniform grid (Fig. 2), exactly `n − p` ones. Weights (§3.2.3): `k` bits per
//! weight, decoded by eq. 22, `w = T1 + (Σ b_i 2^{i−1}) (T2 − T1)/(2^k − 1)` (resolution
//! eq. 21), chromosome length `(n + 1) k` (Fig. 5).
//!
//! Operators as in the paper: roulette-wheel selection (eq. 18), two-point
//! crossover with probability `Pc = 0.7`, bit mutation with `Pm` in 0.001–0.01;
//! knot chromosomes are repaired to keep exactly `n − p` ones (random extra ones
//! cleared / missing ones set). "Improved" = elitist: the next generation is the
//! best `N` distinct individuals of parents and children together, so the best
//! fitness never decreases. Fitness eq. 20: `Fit = 1 / (1 + c + λ f)`, with
//! `f = emax / ε` (ε the tolerance), `c = 0` and the penalty factor `λ = 1` when
//! the constraint `emax <= ε` holds and `λ = penalty` when it does not; an
//! infeasible knot vector (singular fit, folding curve) has fitness 0.
//! Termination: eq. 19 (the best fitness differs from the mean best fitness of
//! the last `window` generations by at most `η`, relative) or eq. 16 (the
//! generation cap). Randomness: ChaCha8 seeded from the fit's seed.
use std::collections::HashMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::knot_grid::{GridResult, random_indices};
use super::knot_placement::grid_knots;
use super::problem::FitProblem;

/// Settings of the genetic knot search (population, crossover, mutation, generations).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GaSettings {
    /// Population size N.
    pub population: usize,
    /// Crossover probability Pc (0.7).
    pub crossover: f64,
    /// Mutation probability Pm per gene (0.001–0.01).
    pub mutation: f64,
    /// Generation cap N_count (eq. 16).
    pub max_generations: usize,
    /// Window of eq. 19 (generations).
    pub window: usize,
    /// η of eq. 19 (relative, 1e-4 = 0.01 %).
    pub eta: f64,
    /// c of eq. 20.
    pub conservative: f64,
    /// λ of eq. 20 when the tolerance is missed.
    pub penalty: f64,
    /// Bits per weight, k (eq. 21).
    pub weight_bits: usize,
    /// Weight range [T1, T2].
    pub weight_range: (f64, f64),
}

impl Default for GaSettings {
    fn default() -> Self {
        GaSettings {
            population: 40,
            crossover: 0.7,
            mutation: 0.01,
            max_generations: 100,
            window: 10,
            eta: 1e-4,
            conservative: 0.0,
            penalty: 2.0,
            weight_bits: 8,
            weight_range: (0.5, 2.0),
        }
    }
}

/// Weights found by the weight GA.
#[derive(Clone, Debug)]
pub struct WeightResult {
    pub weights: Vec<f64>,
    pub evaluations: u64,
}

/// Eq. 20 with the penalty of the module doc.
pub fn fitness(emax: f64, tolerance: f64, settings: &GaSettings) -> f64 {
    if !emax.is_finite() {
        return 0.0;
    }
    let f = emax / tolerance.max(1e-12);
    let lambda = if emax <= tolerance {
        1.0
    } else {
        settings.penalty
    };
    1.0 / (1.0 + settings.conservative + lambda * f)
}

/// Roulette wheel (eq. 18): index drawn with probability Fit_i / Σ Fit.
fn roulette(rng: &mut ChaCha8Rng, fit: &[f64]) -> usize {
    let total: f64 = fit.iter().sum();
    if !(total > 0.0) {
        return rng.random_range(0..fit.len());
    }
    let mut r = rng.random::<f64>() * total;
    for (i, f) in fit.iter().enumerate() {
        r -= f;
        if r <= 0.0 {
            return i;
        }
    }
    fit.len() - 1
}

fn two_point_crossover(rng: &mut ChaCha8Rng, a: &mut [bool], b: &mut [bool]) {
    let len = a.len();
    if len < 2 {
        return;
    }
    let mut i = rng.random_range(0..len);
    let mut j = rng.random_range(0..len);
    if i > j {
        std::mem::swap(&mut i, &mut j);
    }
    for t in i..=j {
        std::mem::swap(&mut a[t], &mut b[t]);
    }
}

fn mutate(rng: &mut ChaCha8Rng, genes: &mut [bool], pm: f64) {
    for g in genes.iter_mut() {
        if rng.random::<f64>() < pm {
            *g = !*g;
        }
    }
}

/// Restore exactly `k` ones by clearing or setting random genes.
fn repair(rng: &mut ChaCha8Rng, genes: &mut [bool], k: usize) {
    let mut ones: Vec<usize> = (0..genes.len()).filter(|&i| genes[i]).collect();
    while ones.len() > k {
        let t = rng.random_range(0..ones.len());
        genes[ones.swap_remove(t)] = false;
    }
    let mut zeros: Vec<usize> = (0..genes.len()).filter(|&i| !genes[i]).collect();
    while ones.len() < k {
        let t = rng.random_range(0..zeros.len());
        let g = zeros.swap_remove(t);
        genes[g] = true;
        ones.push(g);
    }
}

/// Eq. 19: relative change of the best fitness against the mean of the window.
fn converged(history: &[f64], window: usize, eta: f64) -> bool {
    if window == 0 || history.len() <= window {
        return false;
    }
    let last = history[history.len() - 1];
    let prev = &history[history.len() - 1 - window..history.len() - 1];
    let mean = prev.iter().sum::<f64>() / window as f64;
    mean > 0.0 && ((last - mean) / mean).abs() <= eta
}

/// The elitist generation loop shared by knots and weights: `score` maps a
/// chromosome to `(fitness, emax)`, `fix` repairs a chromosome after crossover and
/// mutation. Returns the best chromosome, its emax and the generations run.
fn evolve(
    rng: &mut ChaCha8Rng,
    settings: &GaSettings,
    mut population: Vec<Vec<bool>>,
    mut score: impl FnMut(&[bool]) -> (f64, f64),
    mut fix: impl FnMut(&mut ChaCha8Rng, &mut Vec<bool>),
) -> (Vec<bool>, f64, usize) {
    let size = settings.population.max(2);
    let mut scored: Vec<(Vec<bool>, f64, f64)> = population
        .drain(..)
        .map(|c| {
            let (f, e) = score(&c);
            (c, f, e)
        })
        .collect();
    let mut history = Vec::new();
    let mut generations = 0;
    loop {
        scored.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
        history.push(scored[0].1);
        if generations >= settings.max_generations
            || converged(&history, settings.window, settings.eta)
        {
            break;
        }
        generations += 1;
        let fit: Vec<f64> = scored.iter().map(|s| s.1).collect();
        let mut children: Vec<Vec<bool>> = Vec::with_capacity(size);
        while children.len() < size {
            let mut a = scored[roulette(rng, &fit)].0.clone();
            let mut b = scored[roulette(rng, &fit)].0.clone();
            if rng.random::<f64>() < settings.crossover {
                two_point_crossover(rng, &mut a, &mut b);
            }
            for c in [&mut a, &mut b] {
                mutate(rng, c, settings.mutation);
                fix(rng, c);
            }
            children.push(a);
            children.push(b);
        }
        for c in children {
            if scored.iter().any(|s| s.0 == c) {
                continue;
            }
            let (f, e) = score(&c);
            scored.push((c, f, e));
        }
        scored.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
        scored.truncate(size);
    }
    let best = scored.swap_remove(0);
    (best.0, best.2, generations)
}

/// Knot GA (§3.2.2): `n − p` interior knots among the `segments − 1` grid candidates.
pub fn optimise_knots(
    problem: &FitProblem,
    n: usize,
    segments: usize,
    settings: &GaSettings,
    tolerance: f64,
    seed: u64,
) -> GridResult {
    let k = n - problem.degree;
    let len = segments - 1;
    let weights = vec![1.0; n + 1];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cache: HashMap<Vec<bool>, (f64, f64, f64)> = HashMap::new();
    let mut evaluations = 0u64;
    let decode = |genes: &[bool]| -> Vec<usize> {
        (0..genes.len())
            .filter(|&i| genes[i])
            .map(|i| i + 1)
            .collect()
    };
    let mut score_full = |genes: &[bool]| -> (f64, f64, f64) {
        if let Some(&v) = cache.get(genes) {
            return v;
        }
        evaluations += 1;
        let (emax, erms) = problem
            .evaluate(&grid_knots(&decode(genes), segments), &weights)
            .map_or((f64::INFINITY, f64::INFINITY), |c| (c.emax, c.erms));
        let v = (fitness(emax, tolerance, settings), emax, erms);
        cache.insert(genes.to_vec(), v);
        v
    };
    if k == 0 {
        let (_, emax, erms) = score_full(&vec![false; len]);
        return GridResult {
            indices: Vec::new(),
            emax,
            erms,
            evaluations,
        };
    }
    let population: Vec<Vec<bool>> = (0..settings.population.max(2))
        .map(|_| {
            let mut g = vec![false; len];
            for i in random_indices(&mut rng, segments, k) {
                g[i - 1] = true;
            }
            g
        })
        .collect();
    let (best, _, _) = evolve(
        &mut rng,
        settings,
        population,
        |g| {
            let (f, e, _) = score_full(g);
            (f, e)
        },
        |rng, g| repair(rng, g, k),
    );
    let (_, emax, erms) = score_full(&best);
    GridResult {
        indices: decode(&best),
        emax,
        erms,
        evaluations,
    }
}

/// Decode a weight chromosome (eq. 22), bits most significant first per weight.
pub fn decode_weights(genes: &[bool], bits: usize, range: (f64, f64)) -> Vec<f64> {
    let delta = (range.1 - range.0) / ((1u64 << bits) - 1) as f64;
    genes
        .chunks(bits)
        .map(|c| {
            let v = c.iter().fold(0u64, |acc, &b| (acc << 1) | b as u64);
            range.0 + v as f64 * delta
        })
        .collect()
}

fn encode_weight(w: f64, bits: usize, range: (f64, f64)) -> Vec<bool> {
    let max = (1u64 << bits) - 1;
    let v = (((w - range.0) / (range.1 - range.0)) * max as f64)
        .round()
        .clamp(0.0, max as f64) as u64;
    (0..bits).rev().map(|i| (v >> i) & 1 == 1).collect()
}

/// Weight GA (§3.2.3) for fixed interior knots. The initial population holds the
/// unit weights (so the result is never worse than the knots alone) and random
/// chromosomes.
pub fn optimise_weights(
    problem: &FitProblem,
    interior: &[f64],
    settings: &GaSettings,
    tolerance: f64,
    seed: u64,
) -> WeightResult {
    let count = interior.len() + problem.degree + 1;
    let bits = settings.weight_bits.clamp(1, 30);
    let range = settings.weight_range;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5745_4947_4854);
    let mut evaluations = 0u64;
    let mut cache: HashMap<Vec<bool>, (f64, f64)> = HashMap::new();
    let mut score = |genes: &[bool]| -> (f64, f64) {
        if let Some(&v) = cache.get(genes) {
            return v;
        }
        evaluations += 1;
        let emax = problem.emax(interior, &decode_weights(genes, bits, range));
        let v = (fitness(emax, tolerance, settings), emax);
        cache.insert(genes.to_vec(), v);
        v
    };
    let unit: Vec<bool> = (0..count)
        .flat_map(|_| encode_weight(1.0, bits, range))
        .collect();
    let mut population = vec![unit];
    while population.len() < settings.population.max(2) {
        population.push((0..count * bits).map(|_| rng.random::<bool>()).collect());
    }
    let (best, _, _) = evolve(&mut rng, settings, population, &mut score, |_, _| {});
    WeightResult {
        weights: decode_weights(&best, bits, range),
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weight_coding_follows_eq_22() {
        let range = (0.5, 2.0);
        // 8 bits: δ = 1.5 / 255; code 85 is exactly 1.0.
        let g = encode_weight(1.0, 8, range);
        assert_eq!(decode_weights(&g, 8, range), vec![1.0]);
        assert_eq!(decode_weights(&[false; 8], 8, range), vec![0.5]);
        assert_eq!(decode_weights(&[true; 8], 8, range), vec![2.0]);
    }

    #[test]
    fn repair_keeps_the_knot_count() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..100 {
            let mut g: Vec<bool> = (0..12).map(|_| rng.random::<bool>()).collect();
            repair(&mut rng, &mut g, 6);
            assert_eq!(g.iter().filter(|&&b| b).count(), 6);
        }
    }

    #[test]
    fn fitness_penalises_missed_tolerance() {
        let s = GaSettings::default();
        assert_eq!(fitness(0.0, 1.0, &s), 1.0);
        assert!(fitness(1.0, 1.0, &s) > fitness(1.0001, 1.0, &s) + 0.1);
        assert_eq!(fitness(f64::INFINITY, 1.0, &s), 0.0);
    }
}
