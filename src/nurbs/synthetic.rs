//! A seeded synthetic error curve resembling the paper's Fig. 3 (40 points over
//! 0–200 mm, roughly −10…20 µm, nonlinear, with measurement noise): the common
//! input of the tests and of `benches/smem.rs` that reproduce Tables 3 and 4.
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// `(positions mm, values µm)`: 40 points, 0 to 200 mm in steps of 200/39 mm,
/// smooth shape plus N(0, 0.5 µm) noise drawn from ChaCha8(`seed`).
pub fn paper_like_curve(seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.5).expect("valid normal");
    let positions: Vec<f64> = (0..40).map(|i| 200.0 * i as f64 / 39.0).collect();
    let values = positions
        .iter()
        .map(|&x| paper_like_truth(x) + noise.sample(&mut rng))
        .collect();
    (positions, values)
}

/// The noise-free curve behind [`paper_like_curve`] (µm at `x` mm): the truth
/// a fit is judged against.
pub fn paper_like_truth(x: f64) -> f64 {
    let t = x / 200.0;
    4.0 + 12.0 * (2.0 * std::f64::consts::PI * (1.3 * t + 0.1)).sin() * (1.0 - 0.4 * t)
        + 6.0 * (-((t - 0.62) / 0.05).powi(2)).exp()
        + 5.0 * t * t
}
