//! `simulate`: the measurement a real machine would give (effects.md
//! "volcomp simulate"): nominal points moved by the geometric volumetric error of
//! the true machine, plus every effect, plus Gaussian probing noise along `n`.
//!
//! Invariant: deterministic for a given seed (ChaCha8); uncut points are measured
//! too (they exist on the part), with the same formula.
use super::DiagnoseError;
use super::effects::Effect;
use crate::inspection::{MeasuredPoint, Measurement, PlanPoint};
use crate::toolpath::PointContext;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Settings of [`simulate`].
#[derive(Clone, Debug, PartialEq)]
pub struct SimulateOptions {
    /// Standard deviation of the probing noise along the normal, µm (≥ 0).
    pub noise_um: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for SimulateOptions {
    fn default() -> Self {
        SimulateOptions {
            noise_um: 0.3,
            seed: 1,
        }
    }
}

/// Gaussian probing noise along the normal (µm), seeded.
struct ProbingNoise {
    normal: Normal<f64>,
    rng: ChaCha8Rng,
    on: bool,
}

impl ProbingNoise {
    fn new(options: &SimulateOptions) -> Result<ProbingNoise, DiagnoseError> {
        if !(options.noise_um.is_finite() && options.noise_um >= 0.0) {
            return Err(DiagnoseError::BadOption(format!(
                "noise must be a finite number ≥ 0 µm, found {}",
                options.noise_um
            )));
        }
        Ok(ProbingNoise {
            normal: Normal::new(0.0, options.noise_um)
                .map_err(|e| DiagnoseError::BadOption(format!("noise: {e}")))?,
            rng: ChaCha8Rng::seed_from_u64(options.seed),
            on: options.noise_um > 0.0,
        })
    }

    fn draw(&mut self) -> f64 {
        if self.on {
            self.normal.sample(&mut self.rng)
        } else {
            0.0
        }
    }
}

/// `m = p + (e_true + ΣΔ)/1000 + noise·n/1000` (mm) for every context, where
/// `truth_um[i]` is the true volumetric error `e` (µm, part coordinates) of
/// context `i`.
pub fn simulate(
    contexts: &[PointContext],
    truth_um: &[[f64; 3]],
    effects: &[Effect],
    options: &SimulateOptions,
) -> Result<Measurement, DiagnoseError> {
    if contexts.len() != truth_um.len() {
        return Err(DiagnoseError::LengthMismatch {
            what: "true volumetric errors",
            expected: contexts.len(),
            found: truth_um.len(),
        });
    }
    let mut noise = ProbingNoise::new(options)?;
    let mut points = Vec::with_capacity(contexts.len());
    for (ctx, e) in contexts.iter().zip(truth_um) {
        super::check_context(ctx)?;
        if !e.iter().all(|v| v.is_finite()) {
            return Err(DiagnoseError::NonFinite {
                what: "true volumetric error",
                id: ctx.id.clone(),
            });
        }
        let mut total = *e;
        for effect in effects {
            let d = effect.displacement(ctx);
            for k in 0..3 {
                total[k] += d[k];
            }
        }
        let noise = noise.draw();
        let measured =
            [0, 1, 2].map(|k| ctx.point[k] + total[k] / 1000.0 + noise * ctx.normal[k] / 1000.0);
        if !measured.iter().all(|v| v.is_finite()) {
            // An effect's parameters so large that the displacement overflows.
            return Err(DiagnoseError::NonFinite {
                what: "the simulated measured point (the effects' displacement overflows: check their parameters)",
                id: ctx.id.clone(),
            });
        }
        points.push(MeasuredPoint {
            plan: PlanPoint {
                id: ctx.id.clone(),
                point: ctx.point,
                normal: ctx.normal,
            },
            measured,
        });
    }
    Ok(Measurement { points })
}

/// Readings of follow-up probes on the machine (docs/diagnose.md "Follow-up"),
/// µm: `truth_reading_um[i]` (the true machine's `n·(e_cut − e_probe)`), plus
/// `n·(Δ_cut − Δ_probe)` of every effect (the probe moved only by the effects
/// that act on it), plus Gaussian probing noise.
pub fn simulate_followup(
    contexts: &[PointContext],
    probes: &[super::followup::Probe],
    truth_reading_um: &[f64],
    effects: &[Effect],
    options: &SimulateOptions,
) -> Result<Vec<f64>, DiagnoseError> {
    if probes.len() != truth_reading_um.len() {
        return Err(DiagnoseError::LengthMismatch {
            what: "true follow-up readings",
            expected: probes.len(),
            found: truth_reading_um.len(),
        });
    }
    let mut noise = ProbingNoise::new(options)?;
    probes
        .iter()
        .zip(truth_reading_um)
        .map(|(probe, truth)| {
            if !truth.is_finite() {
                return Err(DiagnoseError::NonFinite {
                    what: "true follow-up reading",
                    id: probe.id.clone(),
                });
            }
            let row = super::followup::probe_row(contexts, probe)?;
            let mut value = *truth;
            for effect in effects {
                value += effect.deviation_um(row.cut);
                if let Some(p) = row.probe.filter(|_| effect.kind.acts_on_probe()) {
                    value -= effect.deviation_um(p);
                }
            }
            let value = value + noise.draw();
            if !value.is_finite() {
                return Err(DiagnoseError::NonFinite {
                    what: "the simulated reading (the effects' displacement overflows: check their parameters)",
                    id: probe.id.clone(),
                });
            }
            Ok(value)
        })
        .collect()
}
