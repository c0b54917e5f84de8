//! The robustness generator of docs/diagnose.md "Robustness": seeded cases on
//! the synthetic saddle raster whose machine model is NOT the fitted one (the
//! model's prediction carries a smooth table-fit error of the RMS that its
//! declared uncertainty says), with single effects, localised servo lag,
//! pairs, wrong models (scaled tables with a thermal drift, tables noisier than
//! their uncertainty, a stale table), no effect, and local decoys; and the
//! scores of their diagnoses against the targets.
//!
//! Invariant: deterministic for given seeds; no I/O.
use super::effects::{Effect, EffectKind};
use super::followup::{self, FollowupDesign, FollowupOptions, FollowupOutcome, ProbeReading};
use super::report::DiagnoseReport;
use super::synthetic::{SyntheticOptions, SyntheticPart, random_effect, saddle_raster};
use super::{DiagnoseError, DiagnoseOptions, SimulateOptions};
use crate::toolpath::PointContext;
use crate::vec3::dot;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// RMS of the model's table-fit error, and its declared standard uncertainty, µm.
pub const MODEL_U_UM: f64 = 0.15;

/// What a case is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CaseClass {
    /// One effect (RMS 2–6 µm over the part).
    Single,
    /// Servo lag whose RMS over the part is 1.0–1.9 × the noise (a few large
    /// deviations at the raster's reversals).
    LocalisedServoLag,
    /// Two effects (RMS 2–6 µm each).
    Pair,
    /// The model's tables are 1.5 × the machine's, with a thermal drift.
    ScaledTables,
    /// The table-fit error is 4 × what the model's uncertainty says; no effect.
    NoisyTables,
    /// The Y table is another machine's (stale); no effect.
    StaleTable,
    /// No effect.
    NoEffect,
    /// A 4 µm bump 20 mm wide (FWHM) somewhere on the part, with or without
    /// one effect.
    Decoy,
    /// The decoy's case without the bump.
    Clean,
}

impl CaseClass {
    /// Whether the case's machine model is wrong (scaled, noisy or stale tables).
    pub fn wrong_model(self) -> bool {
        matches!(
            self,
            CaseClass::ScaledTables | CaseClass::NoisyTables | CaseClass::StaleTable
        )
    }
}

/// One generated case.
#[derive(Clone, Debug)]
pub struct Case {
    /// What kind of case.
    pub class: CaseClass,
    /// Probing noise of the measurement (one σ), µm.
    pub noise_um: f64,
    /// The seed of the case (effects, model error, noise).
    pub seed: u64,
    /// The effects injected (empty for no effect).
    pub injected: Vec<EffectKind>,
    /// The injected effects with their values (the kinds of `injected`).
    pub effects: Vec<Effect>,
    /// The bump's centre (part x, y, mm) when there is one.
    pub bump: Option<[f64; 2]>,
    /// Contexts with the (wrong) model's prediction.
    pub contexts: Vec<PointContext>,
    /// The simulated measured deviations, one per context, µm.
    pub measured_um: Vec<f64>,
}

/// The part every case is cut on.
pub fn part() -> SyntheticPart {
    saddle_raster(&SyntheticOptions {
        model_error_um: 0.0,
        ..SyntheticOptions::default()
    })
}

/// A smooth random field over the part with RMS `rms_um` at its points.
fn smooth_field(contexts: &[PointContext], rms_um: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let waves: Vec<[f64; 4]> = (0..4)
        .map(|_| {
            [
                rng.random_range(0.02..0.12),
                rng.random_range(0.0..6.3),
                rng.random_range(0.02..0.12),
                rng.random_range(0.0..6.3),
            ]
        })
        .collect();
    let raw: Vec<f64> = contexts
        .iter()
        .map(|c| {
            waves
                .iter()
                .map(|w| (w[0] * c.point[0] + w[1]).sin() * (w[2] * c.point[1] + w[3]).cos())
                .sum()
        })
        .collect();
    let r = super::noise::rms(&raw).max(1e-12);
    raw.iter().map(|v| v * rms_um / r).collect()
}

/// The decoy's bump centred at `centre` (part x, y, mm) at the part point
/// `point`: 4 µm high, 20 mm wide (FWHM), µm.
fn bump_um(centre: [f64; 2], point: [f64; 3]) -> f64 {
    let width = 20.0 / 2.355; // FWHM 20 mm
    let r2 = (point[0] - centre[0]).powi(2) + (point[1] - centre[1]).powi(2);
    4.0 * (-r2 / (2.0 * width * width)).exp()
}

/// Build one case: `effects` injected on `part`, probing noise `noise_um`.
pub fn case(
    part: &SyntheticPart,
    class: CaseClass,
    effects: &[Effect],
    noise_um: f64,
    seed: u64,
    with_bump: bool,
) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_0026);
    let table_error = if class == CaseClass::NoisyTables {
        4.0 * MODEL_U_UM
    } else {
        MODEL_U_UM
    };
    let field = smooth_field(&part.contexts, table_error, &mut rng);
    let stale = smooth_field(&part.contexts, 1.5, &mut rng);
    let mut contexts = part.contexts.clone();
    let mut truth = Vec::with_capacity(contexts.len());
    for (i, c) in contexts.iter_mut().enumerate() {
        let machine = dot(c.normal, part.truth_um[i]);
        truth.push(machine);
        let mut axis = c.axis_deviation_um;
        let mut predicted = machine;
        match class {
            CaseClass::ScaledTables => {
                for a in axis.iter_mut() {
                    *a *= 1.5;
                }
                predicted *= 1.5;
            }
            CaseClass::StaleTable => {
                // The Y table of another machine.
                predicted += stale[i] - axis[1];
                axis[1] = stale[i];
            }
            _ => {}
        }
        c.axis_deviation_um = axis;
        c.predicted_um = predicted + field[i];
        c.model_u_um = MODEL_U_UM;
    }
    let bump = with_bump.then(|| [rng.random_range(-30.0..30.0), rng.random_range(-22.0..22.0)]);
    let normal = Normal::new(0.0, noise_um.max(0.0)).unwrap_or(Normal::new(0.0, 0.0).unwrap());
    let measured_um = contexts
        .iter()
        .zip(&truth)
        .map(|(c, t)| {
            let mut d = *t + effects.iter().map(|e| e.deviation_um(c)).sum::<f64>();
            if let Some(centre) = bump {
                d += bump_um(centre, c.point);
            }
            d + normal.sample(&mut rng)
        })
        .collect();
    Case {
        class,
        noise_um,
        seed,
        injected: effects.iter().map(|e| e.kind).collect(),
        effects: effects.to_vec(),
        bump,
        contexts,
        measured_um,
    }
}

/// How many cases of each kind [`cases`] makes.
#[derive(Clone, Copy, Debug)]
pub struct RobustnessOptions {
    /// Seeds per effect and noise level for the single effects (4: 36 runs per level).
    pub seeds_per_effect: u64,
    /// Probing noise levels (one σ, µm); every kind of case is made at each.
    pub noise_levels: &'static [f64],
    /// Localised servo-lag runs per noise level.
    pub servo_runs: u64,
    /// Pair runs per noise level.
    pub pair_runs: u64,
    /// Wrong-model runs: scaled tables, noisy tables, stale table.
    pub wrong_model_runs: [u64; 3],
    /// No-effect runs per noise level.
    pub none_runs: u64,
    /// Decoy runs (and as many clean ones).
    pub decoy_runs: u64,
}

impl Default for RobustnessOptions {
    fn default() -> Self {
        RobustnessOptions {
            seeds_per_effect: 4,
            noise_levels: &[0.1, 0.3, 0.6, 1.0],
            servo_runs: 10,
            pair_runs: 20,
            wrong_model_runs: [5, 4, 4],
            none_runs: 3,
            decoy_runs: 12,
        }
    }
}

impl RobustnessOptions {
    /// No case at all: set the counts wanted (`..RobustnessOptions::none()`).
    pub fn none() -> Self {
        RobustnessOptions {
            seeds_per_effect: 0,
            noise_levels: &[],
            servo_runs: 0,
            pair_runs: 0,
            wrong_model_runs: [0, 0, 0],
            none_runs: 0,
            decoy_runs: 0,
        }
    }
}

/// Every case of the table, in a fixed order.
pub fn cases(part: &SyntheticPart, options: &RobustnessOptions) -> Vec<Case> {
    let ctx = &part.contexts;
    let mut out = Vec::new();
    let effect_rng = |seed: u64| ChaCha8Rng::seed_from_u64(seed.wrapping_mul(7919) + 13);
    for (li, &noise) in options.noise_levels.iter().enumerate() {
        for (ki, kind) in EffectKind::ALL.iter().enumerate() {
            for s in 0..options.seeds_per_effect {
                let seed = 1000 * li as u64 + 10 * ki as u64 + s;
                let e = random_effect(*kind, ctx, (2.0, 6.0), &mut effect_rng(seed));
                out.push(case(part, CaseClass::Single, &[e], noise, seed, false));
            }
        }
        if noise >= 0.3 {
            for s in 0..options.servo_runs {
                let seed = 50_000 + 100 * li as u64 + s;
                let e = random_effect(
                    EffectKind::ServoLag,
                    ctx,
                    (1.0 * noise, 1.9 * noise),
                    &mut effect_rng(seed),
                );
                out.push(case(
                    part,
                    CaseClass::LocalisedServoLag,
                    &[e],
                    noise,
                    seed,
                    false,
                ));
            }
        }
        for s in 0..options.none_runs {
            let seed = 60_000 + 100 * li as u64 + s;
            out.push(case(part, CaseClass::NoEffect, &[], noise, seed, false));
        }
    }
    let kinds = EffectKind::ALL;
    let pairs: Vec<(EffectKind, EffectKind)> = (0..kinds.len())
        .flat_map(|i| (i + 1..kinds.len()).map(move |j| (kinds[i], kinds[j])))
        .collect();
    for s in 0..options.pair_runs {
        let seed = 70_000 + s;
        let (a, b) = pairs[(s as usize * 11) % pairs.len()];
        let mut rng = effect_rng(seed);
        let ea = random_effect(a, ctx, (2.0, 6.0), &mut rng);
        let eb = random_effect(b, ctx, (2.0, 6.0), &mut rng);
        out.push(case(part, CaseClass::Pair, &[ea, eb], 0.3, seed, false));
    }
    let [scaled, noisy, stale] = options.wrong_model_runs;
    for s in 0..scaled {
        let seed = 80_000 + s;
        let e = random_effect(
            EffectKind::ThermalDrift,
            ctx,
            (2.0, 6.0),
            &mut effect_rng(seed),
        );
        out.push(case(part, CaseClass::ScaledTables, &[e], 0.3, seed, false));
    }
    for s in 0..noisy {
        let seed = 81_000 + s;
        out.push(case(part, CaseClass::NoisyTables, &[], 0.3, seed, false));
    }
    for s in 0..stale {
        let seed = 82_000 + s;
        out.push(case(part, CaseClass::StaleTable, &[], 0.3, seed, false));
    }
    for s in 0..options.decoy_runs {
        let seed = 90_000 + s;
        // Half with no effect, half with one.
        let effects: Vec<Effect> = if s % 2 == 0 {
            Vec::new()
        } else {
            let kind = kinds[(s as usize / 2) % kinds.len()];
            vec![random_effect(kind, ctx, (2.0, 6.0), &mut effect_rng(seed))]
        };
        out.push(case(part, CaseClass::Decoy, &effects, 0.3, seed, true));
        out.push(case(part, CaseClass::Clean, &effects, 0.3, seed, false));
    }
    out
}

/// The verdicts of one diagnosis of a case.
#[derive(Clone, Debug, Default)]
pub struct Score {
    /// `selected[0]` is the injected effect (single effects).
    pub top1: bool,
    /// Every injected effect is selected.
    pub all_found: bool,
    /// Some effect is selected although none was injected.
    pub false_positive: bool,
    /// The report names the machine model as wrong (its model check found a mismatch).
    pub model_named: bool,
    /// A local anomaly within 15 mm of the bump (decoys), or any (others).
    pub anomaly: bool,
    /// Selected parameters outside their physical range or undetermined
    /// (independent of the report's own flags), and of those, the unflagged.
    pub implausible: usize,
    /// Selected parameters outside their physical range or undetermined.
    pub unflagged: usize,
    /// Alias relations (A lists B) and those listed both ways.
    pub alias_relations: usize,
    /// Alias relations (A lists B as an alias).
    pub alias_two_way: usize,
}

/// Score a diagnosis of `case` (duration of the program `duration_min`).
pub fn score(case: &Case, report: &DiagnoseReport, duration_min: f64) -> Score {
    let injected: Vec<&str> = case.injected.iter().map(|k| k.name()).collect();
    let selected: Vec<&str> = report.selected.iter().map(String::as_str).collect();
    let mut s = Score {
        top1: injected.len() == 1 && selected.first() == injected.first(),
        all_found: !injected.is_empty() && injected.iter().all(|k| selected.contains(k)),
        false_positive: injected.is_empty() && !selected.is_empty(),
        model_named: report.model_check.mismatch,
        anomaly: match case.bump {
            Some([x, y]) => report
                .local_anomalies
                .iter()
                .any(|a| ((a.centre[0] - x).powi(2) + (a.centre[1] - y).powi(2)).sqrt() < 15.0),
            None => !report.local_anomalies.is_empty(),
        },
        ..Score::default()
    };
    for (effect, checks) in &report.after.checks {
        for c in checks {
            let tau = effect == "thermal_drift" && c.name == "tau";
            let bad = if tau {
                !(duration_min / 50.0..=2.0 * duration_min).contains(&c.value)
            } else {
                let negative = matches!(
                    effect.as_str(),
                    "tool_wear" | "tool_deflection" | "servo_lag" | "backlash"
                ) && c.value < 0.0;
                let size = match c.unit.as_str() {
                    "µrad" => c.value.abs() > 5000.0,
                    "µm" => c.value.abs() > 500.0,
                    _ => false,
                };
                negative || size || c.std > c.value.abs()
            };
            if bad {
                s.implausible += 1;
                if c.plausible && c.identifiable {
                    s.unflagged += 1;
                }
            }
        }
    }
    for e in &report.effects {
        for a in &e.aliases {
            s.alias_relations += 1;
            if report
                .effects
                .iter()
                .any(|b| &b.name == a && b.aliases.contains(&e.name))
            {
                s.alias_two_way += 1;
            }
        }
    }
    s
}

/// Radius of the follow-up stylus on the generator's synthetic machine, mm
/// (the `diagnose --probe-radius` default).
pub const PROBE_RADIUS_MM: f64 = 1.0;

/// Settings of [`followup_run`].
#[derive(Clone, Debug, PartialEq)]
pub struct FollowupRunOptions {
    /// The design's settings (12 probes, 0.25 min each by default).
    pub design: FollowupOptions,
    /// A table error that does NOT cancel in a re-probe at another pose
    /// (one σ per reading, µm; 0 by default). In the generator the model's
    /// table error is a function of the part point, so it cancels in every
    /// re-probe of the same point; on a machine it is a function of the
    /// joints and changes with the pose: `√2 ×` [`MODEL_U_UM`] is the
    /// worst case of two independent draws. Added to readings whose pose
    /// differs from the cut's.
    pub uncancelled_table_error_um: f64,
}

impl Default for FollowupRunOptions {
    fn default() -> Self {
        FollowupRunOptions {
            design: FollowupOptions::default(),
            uncancelled_table_error_um: 0.0,
        }
    }
}

/// A case diagnosed, followed up when its report has rivals, and diagnosed
/// again with the follow-up (docs/diagnose.md "Issue 36, sixth pass").
#[derive(Clone, Debug)]
pub struct FollowupRun {
    /// The diagnosis of the measurement alone.
    pub before: DiagnoseReport,
    /// Its score.
    pub before_score: Score,
    /// Candidate probes the design chose from.
    pub candidates: usize,
    /// The follow-up designed from `before` (`None`: nothing to separate).
    pub design: Option<FollowupDesign>,
    /// The diagnosis of the measurement and the follow-up together (`before`
    /// when nothing was designed).
    pub after: DiagnoseReport,
    /// Its score.
    pub after_score: Score,
    /// Expected and achieved separations of the probes taken.
    pub outcome: Option<FollowupOutcome>,
}

/// Follow-up readings of `probes` on `case`'s machine: each probe re-reads
/// its cut point, so the machine's own error and the model's table error
/// (functions of the part point in this generator) cancel; the readings are
/// the injected effects' `n·(Δ_cut − Δ_probe)` ([`super::simulate_followup`]),
/// the decoy's bump where there is one (it is in the cut surface), the case's
/// probing noise, and `uncancelled_um` of table error at other poses.
fn followup_readings(
    case: &Case,
    probes: Vec<followup::Probe>,
    uncancelled_um: f64,
) -> Result<Vec<ProbeReading>, DiagnoseError> {
    let truth: Vec<f64> = probes
        .iter()
        .map(|p| {
            let cut = case.contexts.get(p.of).ok_or_else(|| {
                DiagnoseError::BadOption(format!("probe {}: no plan point {}", p.id, p.of))
            })?;
            Ok(case.bump.map_or(0.0, |centre| bump_um(centre, cut.point)))
        })
        .collect::<Result<_, DiagnoseError>>()?;
    let seed = case.seed ^ 0xf011_0f01;
    let readings = super::simulate_followup(
        &case.contexts,
        &probes,
        &truth,
        &case.effects,
        &SimulateOptions {
            noise_um: case.noise_um,
            seed,
        },
    )?;
    if !(uncancelled_um.is_finite() && uncancelled_um >= 0.0) {
        return Err(DiagnoseError::BadOption(format!(
            "the uncancelled table error must be a finite number ≥ 0 µm, found {uncancelled_um}"
        )));
    }
    let table = Normal::new(0.0, uncancelled_um)
        .map_err(|e| DiagnoseError::BadOption(format!("uncancelled table error: {e}")))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(1));
    Ok(probes
        .into_iter()
        .zip(readings)
        .map(|(probe, reading_um)| {
            let moved = case.contexts.get(probe.of).is_some_and(|cut| {
                cut.rotary.iter().any(|&axis| {
                    (probe.context.joints.get(axis) - cut.joints.get(axis)).abs() > 1e-6
                })
            });
            let extra = if moved && uncancelled_um > 0.0 {
                table.sample(&mut rng)
            } else {
                0.0
            };
            ProbeReading {
                probe,
                reading_um: reading_um + extra,
            }
        })
        .collect())
}

/// Diagnose `case`; when its report has rivals (a follow-up can be
/// designed), design the follow-up (`followup::design`, the candidates every
/// cut point in the 12 poses on the generator's synthetic machine,
/// [`super::synthetic::probe_context`]), simulate its readings with the
/// case's own truth (`followup_readings`) and diagnose the measurement and
/// the follow-up together. `duration_min` is the program's duration (for
/// [`score`]).
pub fn followup_run(
    case: &Case,
    options: &FollowupRunOptions,
    duration_min: f64,
) -> Result<FollowupRun, DiagnoseError> {
    let diagnose_options = DiagnoseOptions::default();
    let before = super::diagnose(&case.contexts, &case.measured_um, &diagnose_options)?;
    let before_score = score(case, &before, duration_min);
    let end = crate::toolpath::last_time_min(&case.contexts);
    let candidates = followup::candidates(&case.contexts, |cut, rotary| {
        Ok::<_, DiagnoseError>(Some(super::synthetic::probe_context(
            cut,
            rotary,
            end,
            PROBE_RADIUS_MM,
        )))
    })?;
    let design = followup::design(
        &case.contexts,
        &case.measured_um,
        &before,
        &candidates,
        end,
        &options.design,
    )?;
    let Some(design) = design else {
        return Ok(FollowupRun {
            after: before.clone(),
            after_score: before_score.clone(),
            before,
            before_score,
            candidates: candidates.len(),
            design: None,
            outcome: None,
        });
    };
    let probes: Vec<followup::Probe> = design.probes.iter().map(|p| p.probe.clone()).collect();
    let readings = followup_readings(case, probes, options.uncancelled_table_error_um)?;
    let after = super::diagnose_with_followup(
        &case.contexts,
        &case.measured_um,
        &readings,
        &diagnose_options,
    )?;
    let outcome = followup::outcome(&case.contexts, &case.measured_um, &before, &readings)?;
    let after_score = score(case, &after, duration_min);
    Ok(FollowupRun {
        before,
        before_score,
        candidates: candidates.len(),
        design: Some(design),
        after,
        after_score,
        outcome: Some(outcome),
    })
}
