//! The sim-to-real gap engine (effects.md): the catalogue of unmodelled effects,
//! `simulate` (inject them into synthetic measurements) and `diagnose` (explain a
//! measured-vs-predicted gap: where it lies, which effect causes it, and how far
//! it shrinks once that effect is added).
//!
//! Method (docs/diagnose.md): residuals `r = measured − predicted` on the cut
//! points; a noise floor estimated from the data (robust difference estimator
//! along the cut, `noise`) unless given; every effect fitted by least squares
//! on its signature columns (no intercept; `tau` profiled), judged by its
//! cross-validated error (folds by region and by time) with a BIC penalty for
//! parameters; symmetric aliases (two effects whose fitted contributions
//! coincide to within the noise floor); selection on evidence (`selection`:
//! up to three effects and the error model's own axis factors, each member
//! significant by a penalised held-out likelihood ratio against the noise and
//! the model's own uncertainty); the model verdict; local anomalies of the
//! residual; units, ± and plausibility of every selected parameter
//! (`plausibility`).
//!
//! Invariants: inputs are checked (equal lengths, finite values) before any
//! arithmetic; the result is deterministic; no I/O.
pub(crate) mod effects;
mod fit;
pub mod followup;
#[cfg(any(test, feature = "testkit"))]
pub mod ideal_observer;
pub(crate) mod localization;
pub(crate) mod machine_file;
pub(crate) mod noise;
#[cfg(any(test, feature = "testkit"))]
pub mod oracle;
pub(crate) mod plausibility;
pub(crate) mod probing_program;
pub(crate) mod report;
#[cfg(any(test, feature = "testkit"))]
pub mod robustness;
mod selection;
pub(crate) mod simulate;
#[cfg(any(test, feature = "testkit"))]
pub mod synthetic;

use crate::inspection::profile;
/// The `diagnose --html` page of a report; it is rendered in the crate's
/// `report` module (domain modules do not render), and kept here as the
/// public path.
pub use crate::report::diagnose_html::render as render_html;
use crate::toolpath::PointContext;
pub use effects::{Effect, EffectError, EffectKind};
use fit::{Folds, SetFit, Signatures, cross_validate, fit_set};
pub use machine_file::machine_update;
use noise::rms;
use report::{After, EffectFit, Gap, ModelCheck, PointResidual};
pub use report::{DiagnoseReport, RivalSet};
pub use simulate::{SimulateOptions, simulate, simulate_followup};
use std::collections::BTreeMap;

/// Why a diagnosis (or a simulation) was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DiagnoseError {
    /// An input list does not hold one value per plan point.
    #[error("{what}: expected {expected} values (one per plan point), found {found}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Plan points.
        expected: usize,
        /// Values given.
        found: usize,
    },
    /// A value of a point (measurement or context) is NaN or infinite.
    #[error("point `{id}`: {what} is not finite")]
    NonFinite {
        /// Which value.
        what: &'static str,
        /// The plan point's id.
        id: String,
    },
    /// The program cut none of the plan's points.
    #[error("no plan point was cut by the program: nothing to diagnose")]
    NoPoints,
    /// An option is out of its range or malformed (the message says which).
    #[error("{0}")]
    BadOption(String),
}

/// Settings of [`diagnose`].
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnoseOptions {
    /// Probing noise (µm, one σ) when known; estimated from the data otherwise.
    pub noise_um: Option<f64>,
    /// At most this many effects are selected (0–3).
    pub max_selected: usize,
    /// Each selected term's penalised held-out likelihood ratio must reach
    /// this (docs/diagnose.md "Selection").
    pub significance: f64,
    /// Cosine above which another effect's span reproduces an effect's
    /// contribution (an alias, when the part it misses is also below the
    /// noise floor, RMS).
    pub alias_cosine: f64,
    /// Number of time folds (region folds are a 3 × 3 grid by x and y terciles).
    pub time_folds: usize,
    /// Counts the selection's scored sets (its progress), if given.
    pub progress: Option<std::sync::Arc<crate::progress::WorkCounter>>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            noise_um: None,
            max_selected: 3,
            significance: SIGNIFICANCE,
            alias_cosine: 0.98,
            time_folds: 6,
            progress: None,
        }
    }
}

pub(crate) fn check_context(ctx: &PointContext) -> Result<(), DiagnoseError> {
    let mut values = vec![
        ctx.time_min,
        ctx.speed_mm_s,
        ctx.curvature_per_mm,
        ctx.cut_length_m,
        ctx.predicted_um,
    ];
    values.extend(ctx.point);
    values.extend(ctx.normal);
    values.extend(ctx.sigma);
    values.extend(ctx.principal_normal);
    values.extend(ctx.tool_axis);
    values.extend(ctx.joints.to_array());
    values.extend(ctx.squareness_jacobian.iter().flatten());
    values.extend(ctx.location_jacobian.iter().flatten());
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(DiagnoseError::NonFinite {
            what: "its tool-path context",
            id: ctx.id.clone(),
        })
    }
}

fn named_params(
    fit: &SetFit,
    member: usize,
    rotary: [crate::axes::Axis; 2],
) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let offset: usize = fit.kinds[..member].iter().map(|k| k.linear_count()).sum();
    let kind = fit.kinds[member];
    let mut params = BTreeMap::new();
    let mut std = BTreeMap::new();
    for (j, name) in kind
        .parameters_for(rotary)
        .iter()
        .enumerate()
        .take(kind.linear_count())
    {
        params.insert(name.to_string(), fit.linear.coefs[offset + j]);
        std.insert(name.to_string(), fit.linear.inverse_diagonal[offset + j]);
    }
    if let (true, Some(tau)) = (kind.is_nonlinear(), fit.tau) {
        params.insert("tau".into(), tau);
    }
    (params, std)
}

/// Explain the gap between `measured_um` (deviations, one per context) and the
/// contexts' predicted deviations.
pub fn diagnose(
    contexts: &[PointContext],
    measured_um: &[f64],
    options: &DiagnoseOptions,
) -> Result<DiagnoseReport, DiagnoseError> {
    diagnose_with_followup(contexts, measured_um, &[], options)
}

/// [`diagnose`] with follow-up readings taken on the machine after the cut
/// (`followup::ProbeReading`): they are fitted together with the measurement,
/// as rows `n·(Δ_cut − Δ_probe)` (docs/diagnose.md "Follow-up"). The gap, the
/// noise floor, the localisation and the residuals are the measurement's.
pub fn diagnose_with_followup(
    contexts: &[PointContext],
    measured_um: &[f64],
    followup: &[followup::ProbeReading],
    options: &DiagnoseOptions,
) -> Result<DiagnoseReport, DiagnoseError> {
    validate(contexts, measured_um, options)?;
    let mut p = Problem::new(contexts, measured_um, followup, options)?;
    let candidates = single_effects(&p);
    let mut picked = select_terms(&p, &candidates, options);
    if !p.invisible.is_empty() {
        picked.notes.insert(
            0,
            format!(
                "fixed at 0, not seen by this part (their largest plausible effect explains less than a parameter costs, n·reach² < σ²·ln n): {}",
                p.invisible
                    .iter()
                    .map(|(k, j)| format!("{} of {}", k.parameters_for(p.rotary)[*j], k.name()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        );
    }
    let mut effects = effect_table(&p, &candidates, options.alias_cosine);
    let mut not_named = guard_not_named(&p, &mut picked);
    not_named.extend(guard_table_shape(&mut p, &mut picked, options.significance));
    if !not_named.is_empty() || (picked.selected.is_empty() && !picked.with_model) {
        picked.rivals.clear();
    }
    rival_aliases(&mut effects, &picked);
    let joint = joint_fit(&p, &picked.selected, picked.with_model);
    let outcome = check_model(&p, &picked, &joint);
    let summary = summary_sentences(&p, &picked, &joint, &outcome, &effects, &not_named);
    if picked.with_model {
        picked.notes.push(format!(
            "the error model's own factors are in the selection: {}",
            outcome
                .model_check
                .factors
                .iter()
                .map(|(k, b)| format!("{k} ×{:.2}", 1.0 + b))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(assemble(p, picked, effects, joint, outcome, summary))
}

/// Stage 1: the inputs are one finite value per plan point, the options in
/// their ranges.
fn validate(
    contexts: &[PointContext],
    measured_um: &[f64],
    options: &DiagnoseOptions,
) -> Result<(), DiagnoseError> {
    if contexts.len() != measured_um.len() {
        return Err(DiagnoseError::LengthMismatch {
            what: "measured deviations",
            expected: contexts.len(),
            found: measured_um.len(),
        });
    }
    for (ctx, m) in contexts.iter().zip(measured_um) {
        check_context(ctx)?;
        if !m.is_finite() {
            return Err(DiagnoseError::NonFinite {
                what: "its measured deviation",
                id: ctx.id.clone(),
            });
        }
    }
    if let Some(s) = options.noise_um {
        if !(s.is_finite() && s > 0.0) {
            return Err(DiagnoseError::BadOption(format!(
                "the noise floor must be a finite number > 0 µm, found {s}"
            )));
        }
    }
    if options.max_selected > 3 {
        return Err(DiagnoseError::BadOption(format!(
            "at most three effects can be selected, asked for {}",
            options.max_selected
        )));
    }
    Ok(())
}

/// Stage 2: what is fitted. The measurement's used points and residuals, the
/// follow-up's rows after them, the noise floor, the signatures (with the
/// model's own columns), the folds and the model's uncertainty.
struct Problem<'a> {
    /// The plan's points (cut or not).
    points: usize,
    /// The cut points, in plan order.
    used: Vec<&'a PointContext>,
    /// Their measured and predicted deviations and residuals (µm).
    measured: Vec<f64>,
    predicted: Vec<f64>,
    r0: Vec<f64>,
    /// The residual of every row fitted (the measurement's, then the
    /// follow-up's).
    r: Vec<f64>,
    rotary: [crate::axes::Axis; 2],
    noise_floor: f64,
    noise_source: &'static str,
    /// The noise floor guarded against zero (noise-free synthetic data).
    floor: f64,
    sig: Signatures,
    folds: Folds,
    /// The patch of every row (`selection::patches`).
    patches: Vec<usize>,
    all_rows: Vec<usize>,
    /// Mean square of the residual with nothing fitted.
    mse_before: f64,
    /// The error model's own columns, with their names.
    named_cols: Vec<(String, Vec<f64>)>,
    /// Per axis named in `named_cols`, the columns of an unknown smooth
    /// table of that axis (`shape_columns`).
    shape_cols: Vec<(String, Vec<Vec<f64>>)>,
    /// The model's own standard uncertainty: mean square over the rows, and
    /// RMS over the measurement's points.
    model_u2: f64,
    model_u: f64,
    /// √(σ² + u²): what the noise and the model's uncertainty allow.
    expected: f64,
    /// Parameters the part cannot see, fixed at 0 (`Signatures::drop_invisible`).
    invisible: Vec<(EffectKind, usize)>,
}

impl<'a> Problem<'a> {
    /// A scorer of term sets on this problem's rows (selection.rs).
    fn scorer<'s>(
        &'s self,
        settings: selection::SelectionSettings,
        model_plausible: &'s (dyn Fn(&selection::Terms) -> bool + Sync),
        cache: BTreeMap<selection::Terms, f64>,
    ) -> selection::Scorer<'s> {
        selection::Scorer {
            sig: &self.sig,
            folds: &self.folds,
            r: &self.r,
            mse_before: self.mse_before,
            settings,
            model_plausible,
            cache,
            patches: &self.patches,
            fitted: BTreeMap::new(),
            progress: None,
            anomalous: self,
        }
    }

    /// The rows inside a local anomaly of the measurement's residual
    /// `r_rows` (one value per row; a follow-up row is never inside).
    fn anomalous_rows(&self, r_rows: &[f64]) -> Vec<bool> {
        let n0 = self.r0.len();
        let anomalies = localization::local_anomalies(
            &self.used,
            &r_rows[..n0.min(r_rows.len())],
            self.floor,
            self.model_u,
        );
        let mut inside = inside_anomalies(&self.used, &anomalies);
        inside.resize(r_rows.len(), false);
        inside
    }

    fn new(
        contexts: &'a [PointContext],
        measured_um: &[f64],
        followup: &'a [followup::ProbeReading],
        options: &DiagnoseOptions,
    ) -> Result<Problem<'a>, DiagnoseError> {
        let used_idx: Vec<usize> = (0..contexts.len()).filter(|&i| contexts[i].cut).collect();
        if used_idx.is_empty() {
            return Err(DiagnoseError::NoPoints);
        }
        let used: Vec<&PointContext> = used_idx.iter().map(|&i| &contexts[i]).collect();
        let measured: Vec<f64> = used_idx.iter().map(|&i| measured_um[i]).collect();
        // The machine's axes, as the contexts name them (one machine per diagnosis).
        let slot_letters = used[0].slot_letters();
        let rotary = used[0].rotary;
        let predicted: Vec<f64> = used.iter().map(|c| c.predicted_um).collect();
        let r0: Vec<f64> = measured
            .iter()
            .zip(&predicted)
            .map(|(m, p)| m - p)
            .collect();
        let n0 = r0.len();
        let (noise_floor, noise_source) = match options.noise_um {
            Some(s) => (s, "given"),
            None => (noise::estimate_noise_floor(&used, &r0), "estimated"),
        };
        let floor = noise_floor.max(1e-6);
        let mut rows: Vec<fit::Row> = used
            .iter()
            .map(|c| fit::Row {
                cut: c,
                probe: None,
            })
            .collect();
        let mut r = r0.clone();
        for reading in followup {
            let row = followup::check_reading(contexts, reading)?;
            r.push(reading.reading_um - row.predicted_um());
            rows.push(row);
        }
        let n = r.len();
        let row_points: Vec<&PointContext> = rows.iter().map(|row| row.cut).collect();
        let mut sig = Signatures::new(&rows);
        let invisible = sig.drop_invisible(floor);
        let folds = Folds::new(&row_points, options.time_folds);
        let patches = selection::patches(&row_points);
        // The error model's own columns: one per measured axis (what the model
        // attributes to its tables), and one for the rest of the prediction (the
        // machine file's position-independent errors: squareness, rotary location).
        let named_cols = model_columns(&rows, &slot_letters);
        sig.model = named_cols.iter().map(|(_, c)| c.clone()).collect();
        let shape_cols = slot_letters
            .iter()
            .filter(|a| {
                named_cols
                    .iter()
                    .any(|(name, _)| *name == a.letter().to_string())
            })
            .map(|a| (a.letter().to_string(), shape_columns(&rows, *a)))
            .collect();
        let model_u2 = rows
            .iter()
            .map(|row| row.cut.model_u_um.powi(2) + row.probe.map_or(0.0, |p| p.model_u_um.powi(2)))
            .sum::<f64>()
            / n as f64;
        let model_u = (used.iter().map(|c| c.model_u_um.powi(2)).sum::<f64>() / n0 as f64).sqrt();
        Ok(Problem {
            points: contexts.len(),
            mse_before: r.iter().map(|v| v * v).sum::<f64>() / n as f64,
            all_rows: (0..n).collect(),
            expected: (floor * floor + model_u * model_u).sqrt(),
            used,
            measured,
            predicted,
            r0,
            r,
            rotary,
            noise_floor,
            noise_source,
            floor,
            sig,
            folds,
            patches,
            named_cols,
            shape_cols,
            model_u2,
            model_u,
            invisible,
        })
    }

    /// Rows fitted (the measurement's and the follow-up's).
    fn n(&self) -> usize {
        self.r.len()
    }

    /// `n·ln(MSE) + p·ln(n)`.
    fn bic(&self, mse: f64, p: usize) -> f64 {
        let n = self.n() as f64;
        n * mse.max(1e-300).ln() + p as f64 * n.ln()
    }

    /// `terms` (effects and, when `model`, the model's columns) fitted on all rows.
    fn fit(&self, kinds: &[EffectKind], model: bool) -> SetFit {
        fit::fit_terms(&self.sig, kinds, model, &self.all_rows, &self.r)
    }

    /// The measurement's residual less `contribution`.
    fn residual_after(&self, contribution: &[f64]) -> Vec<f64> {
        self.r0
            .iter()
            .zip(contribution)
            .map(|(a, c)| a - c)
            .collect()
    }
}

impl selection::AnomalousRows for Problem<'_> {
    fn anomalous_rows(&self, r_rows: &[f64]) -> Vec<bool> {
        Problem::anomalous_rows(self, r_rows)
    }
}

/// One catalogue effect fitted alone (stage 3).
struct Candidate {
    kind: EffectKind,
    fit: SetFit,
    /// Held-out mean square error.
    mse: f64,
    bic: f64,
    contribution: Vec<f64>,
}

/// Stage 3: every catalogue effect fitted alone and cross-validated, best
/// (lowest held-out BIC) first.
fn single_effects(p: &Problem) -> Vec<Candidate> {
    let mut candidates: Vec<Candidate> = EffectKind::ALL
        .iter()
        .map(|&kind| {
            let fit = fit_set(&p.sig, &[kind], &p.all_rows, &p.r);
            let mse = cross_validate(&p.sig, &p.folds, &[kind], &p.r);
            let contribution = fit.contribution(&p.sig);
            Candidate {
                kind,
                bic: p.bic(mse, fit.parameter_count()),
                fit,
                mse,
                contribution,
            }
        })
        .collect();
    candidates.sort_by(|a, b| a.bic.total_cmp(&b.bic).then(a.kind.cmp(&b.kind)));
    candidates
}

/// What the selection picked (stage 4), after the "not named" guard (stage 6).
struct Picked {
    chosen: selection::Selection,
    /// The selected effects, in the order of the single-effect ranking.
    selected: Vec<EffectKind>,
    /// The model's own factors are in the selection.
    with_model: bool,
    /// Held-out mean square error of what is selected.
    selected_mse: f64,
    /// Held-out mean square error of the model's factors alone.
    model_only_mse: f64,
    notes: Vec<String>,
    /// Sets the data cannot tell from the selection (`selection::rivals`).
    rivals: Vec<selection::Rival>,
}

/// Stage 4: selection on evidence (selection.rs), effects and the model's
/// own factors.
fn select_terms(p: &Problem, candidates: &[Candidate], options: &DiagnoseOptions) -> Picked {
    let max_factor = |t: &selection::Terms| -> bool {
        let fit = p.fit(&t.kinds, true);
        let offset: usize = t.kinds.iter().map(|k| k.linear_count()).sum();
        fit.linear.coefs[offset..]
            .iter()
            .any(|b| b.abs() >= MODEL_FACTOR_MIN)
    };
    let cache = candidates
        .iter()
        .map(|c| {
            (
                selection::Terms {
                    kinds: vec![c.kind],
                    model: false,
                },
                c.mse,
            )
        })
        .collect();
    let settings = selection::SelectionSettings {
        noise_um: p.floor,
        model_u2: p.model_u2,
        max_effects: options.max_selected,
        threshold: options.significance,
        model_available: !p.named_cols.is_empty(),
    };
    let mut scorer = p.scorer(settings, &max_factor, cache);
    scorer.progress = options.progress.as_deref();
    let chosen = selection::select(&mut scorer, &EffectKind::ALL);
    let rivals = selection::rivals(&scorer, &chosen.terms);
    let mut notes = chosen.notes.clone();
    for r in &rivals {
        notes.push(format!(
            "{} (held-out RMS {:.3} µm) cannot be told from {} (held-out RMS {:.3} µm): z = {:.1} < {:.0}",
            chosen.terms.label(),
            chosen.mse.sqrt(),
            r.terms.label(),
            r.mse.sqrt(),
            r.z,
            options.significance
        ));
    }
    let model_only_mse = if p.named_cols.is_empty() {
        p.mse_before
    } else {
        scorer.mse(&selection::Terms {
            kinds: Vec::new(),
            model: true,
        })
    };
    // Order the selected effects by their single-effect ranking.
    let rank = |k: EffectKind| {
        candidates
            .iter()
            .position(|c| c.kind == k)
            .unwrap_or(usize::MAX)
    };
    let mut selected: Vec<EffectKind> = chosen.terms.kinds.clone();
    selected.sort_by_key(|k| rank(*k));
    Picked {
        selected,
        with_model: chosen.terms.model,
        selected_mse: chosen.mse,
        model_only_mse,
        notes,
        chosen,
        rivals,
    }
}

/// Stage 5: the effects table, each effect fitted alone, with its
/// (symmetric) aliases: two effects whose fitted contributions coincide to
/// within the probing noise (cosine ≥ `alias_cosine` and the RMS of their
/// difference below the noise floor), both being larger than it.
fn effect_table(p: &Problem, candidates: &[Candidate], alias_cosine: f64) -> Vec<EffectFit> {
    let n = p.n();
    let floor = p.floor;
    let alias_of = |a: &Candidate, b: &Candidate| -> bool {
        let (ra, rb) = (rms(&a.contribution), rms(&b.contribution));
        if ra < floor || rb < floor {
            return false;
        }
        let dot: f64 = a
            .contribution
            .iter()
            .zip(&b.contribution)
            .map(|(x, y)| x * y)
            .sum();
        let cos = dot / (ra * rb * n as f64);
        let diff: Vec<f64> = a
            .contribution
            .iter()
            .zip(&b.contribution)
            .map(|(x, y)| x - y)
            .collect();
        cos >= alias_cosine && rms(&diff) < floor
    };
    candidates
        .iter()
        .map(|c| {
            let (params, var) = named_params(&c.fit, 0, p.rotary);
            let dof = (n as f64 - c.fit.linear.rank as f64).max(1.0);
            let s2 = c.fit.linear.sse / dof;
            let params_std = var.into_iter().map(|(k, v)| (k, (v * s2).sqrt())).collect();
            let contribution_rms = rms(&c.contribution);
            let aliases = candidates
                .iter()
                .filter(|b| b.kind != c.kind && alias_of(c, b))
                .map(|b| b.kind.name().to_string())
                .collect();
            let before = p.mse_before.sqrt();
            let after = c.mse.sqrt();
            EffectFit {
                name: c.kind.name().to_string(),
                params,
                params_std,
                heldout_rms_before_um: before,
                heldout_rms_after_um: after,
                shrink_pct: if before > 0.0 {
                    100.0 * (1.0 - after / before)
                } else {
                    0.0
                },
                aliases,
                parameter_count: c.fit.parameter_count(),
                rank: c.fit.linear.rank,
                bic: c.bic,
                contribution_rms_um: contribution_rms,
            }
        })
        .collect()
}

/// Stage 6a: aliases from the fit (issue 36). Each rival of the selection
/// (a set the data cannot tell from it, `selection::rivals`) pairs the
/// selected effects it leaves out with the effects it names instead; both
/// list each other as aliases (the follow-up design separates them).
fn rival_aliases(effects: &mut [EffectFit], picked: &Picked) {
    let mut pairs: Vec<(EffectKind, EffectKind)> = Vec::new();
    for rival in &picked.rivals {
        let left: Vec<EffectKind> = picked
            .selected
            .iter()
            .filter(|k| !rival.terms.kinds.contains(k))
            .copied()
            .collect();
        for instead in rival
            .terms
            .kinds
            .iter()
            .filter(|k| !picked.selected.contains(k))
        {
            for out in &left {
                pairs.push((*out, *instead));
                pairs.push((*instead, *out));
            }
        }
    }
    for (a, b) in pairs {
        if let Some(e) = effects.iter_mut().find(|e| e.name == a.name()) {
            if !e.aliases.iter().any(|x| x == b.name()) {
                e.aliases.push(b.name().to_string());
            }
        }
    }
}

/// Stage 6: effects are named only when, with them, the gap is explained:
/// when what remains (local anomalies left out) stays well above what the
/// noise and the model's uncertainty allow, the model is off in a way its
/// factors do not describe, and catalogue effects fitted to part of its
/// error would be guesses. Returns the effects not named (taken out of
/// `picked`).
fn guard_not_named(p: &Problem, picked: &mut Picked) -> Vec<EffectKind> {
    if picked.selected.is_empty() {
        return Vec::new();
    }
    let contribution = p
        .fit(&picked.selected, picked.with_model)
        .contribution(&p.sig);
    let r_after = p.residual_after(&contribution);
    let anomalies = localization::local_anomalies(&p.used, &r_after, p.floor, p.model_u);
    let remaining = remaining_outside(&p.used, &r_after, &anomalies);
    if remaining < UNEXPLAINED_RATIO * p.expected {
        return Vec::new();
    }
    picked.notes.push(format!(
        "with {} the residual stays at {:.3} µm RMS ≥ {:.1} × √(σ² + u²) = {:.3} µm: the model is off beyond its factors; {} not named",
        picked.chosen.terms.label(),
        remaining,
        UNEXPLAINED_RATIO,
        p.expected,
        picked
            .selected
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(" + ")
    ));
    picked.selected_mse = if picked.with_model {
        picked.model_only_mse
    } else {
        p.mse_before
    };
    std::mem::take(&mut picked.selected)
}

/// Stage 6b: when the model's own factors are in the selection, the tables
/// they name are off, and not necessarily by a scale: a table can be wrong in
/// shape (stale, or another machine's), and what a scale leaves of it can be
/// taken for an effect. An effect beside the factors is named only when
/// - it stays significant against that alternative, each named axis's table
///   being also an unknown smooth function of its own position
///   (`shape_columns`, cross-validated like any term), or
/// - its own evidence (`z`) exceeds that of the model's factors: it is then
///   the main explanation of the gap, not what remains of a table error the
///   data sees more strongly.
///
/// Returns the effects not named (taken out of `picked`).
fn guard_table_shape(p: &mut Problem, picked: &mut Picked, threshold: f64) -> Vec<EffectKind> {
    if !picked.with_model || picked.selected.is_empty() {
        return Vec::new();
    }
    let mut kinds = picked.selected.clone();
    kinds.sort();
    let fit = p.fit(&kinds, true);
    let offset: usize = kinds.iter().map(|k| k.linear_count()).sum();
    let off: Vec<usize> = p
        .named_cols
        .iter()
        .zip(&fit.linear.coefs[offset..])
        .filter(|(_, b)| b.abs() >= MODEL_FACTOR_MIN)
        .filter_map(|((name, _), _)| p.shape_cols.iter().position(|(axis, _)| axis == name))
        .collect();
    if off.is_empty() {
        return Vec::new();
    }
    let own = p.sig.model.len();
    for &k in &off {
        let cols = p.shape_cols[k].1.clone();
        p.sig.model.extend(cols);
    }
    let terms = selection::Terms { kinds, model: true };
    let significance = {
        let any = |_: &selection::Terms| true;
        let settings = selection::SelectionSettings {
            noise_um: p.floor,
            model_u2: p.model_u2,
            max_effects: terms.kinds.len(),
            threshold,
            model_available: true,
        };
        let mut scorer = p.scorer(settings, &any, BTreeMap::new());
        scorer.significance_of(&terms)
    };
    p.sig.model.truncate(own);
    let axes = off
        .iter()
        .map(|&k| p.shape_cols[k].0.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    // The evidence of the model's factors beside the effects (the selection's).
    let model_z = picked
        .chosen
        .significance
        .iter()
        .find(|(name, _)| !terms.kinds.iter().any(|k| k.name() == name))
        .map_or(f64::INFINITY, |(_, z)| *z);
    let own_z = |k: &EffectKind| {
        picked
            .chosen
            .significance
            .iter()
            .find(|(name, _)| name == k.name())
            .map_or(0.0, |(_, z)| *z)
    };
    let failing: Vec<EffectKind> = terms
        .kinds
        .iter()
        .zip(&significance)
        .filter(|(k, (_, z))| *z < threshold && own_z(k) <= model_z)
        .map(|(k, _)| *k)
        .collect();
    picked.notes.push(format!(
        "with the tables of {axes} also free in shape (smooth in their own positions): {}; threshold {threshold:.0}; model factors z = {model_z:.1} beside them{}",
        terms
            .kinds
            .iter()
            .zip(&significance)
            .map(|(k, (_, z))| format!("{} z = {z:.1}", k.name()))
            .collect::<Vec<_>>()
            .join(", "),
        if failing.is_empty() {
            String::new()
        } else {
            format!(
                ": {} not named (what a table of another shape would explain, with less evidence than the model's factors)",
                failing.iter().map(|k| k.name()).collect::<Vec<_>>().join(" + ")
            )
        }
    ));
    if failing.is_empty() {
        return failing;
    }
    picked.selected.retain(|k| !failing.contains(k));
    picked.chosen.terms.kinds.retain(|k| !failing.contains(k));
    picked.selected_mse = if picked.selected.is_empty() {
        picked.model_only_mse
    } else {
        fit::cross_validate_terms(&p.sig, &p.folds, &picked.chosen.terms.kinds, true, &p.r)
    };
    failing
}

/// Columns of an unknown smooth error table of `axis` over `rows` (the
/// alternative "the table is wrong in shape"): the machine-frame components
/// of the normal times Legendre polynomials of degree ≤ `SHAPE_DEGREE` of the
/// axis's position, scaled to [−1, 1] over the rows (the translation part of
/// a table that is smooth over the part's travel; at a follow-up row, the
/// cut's less the probe's).
fn shape_columns(rows: &[fit::Row], axis: crate::axes::Axis) -> Vec<Vec<f64>> {
    let points = || {
        rows.iter()
            .flat_map(|r| std::iter::once(r.cut).chain(r.probe))
    };
    let (lo, hi) = points()
        .map(|c| c.joints.get(axis))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(q), hi.max(q))
        });
    let span = hi - lo;
    let degree = if span > 1e-9 { SHAPE_DEGREE } else { 0 };
    let legendre = |s: f64, m: usize| match m {
        0 => 1.0,
        1 => s,
        2 => 1.5 * s * s - 0.5,
        _ => 2.5 * s * s * s - 1.5 * s,
    };
    let value = |c: &PointContext, j: usize, m: usize| {
        let mut e = [0.0; 3];
        e[j] = 1.0;
        let s = if degree > 0 {
            2.0 * (c.joints.get(axis) - lo) / span - 1.0
        } else {
            0.0
        };
        crate::vec3::dot(c.normal, c.machine_to_part(e)) * legendre(s, m)
    };
    let mut cols = Vec::new();
    for j in 0..3 {
        for m in 0..=degree {
            cols.push(
                rows.iter()
                    .map(|r| value(r.cut, j, m) - r.probe.map_or(0.0, |c| value(c, j, m)))
                    .collect(),
            );
        }
    }
    cols
}

/// Degree of the polynomials of an unknown smooth table (`shape_columns`):
/// cubic, a table with a slope, a curvature and an inflection over the
/// part's travel.
pub const SHAPE_DEGREE: usize = 3;

/// The selection fitted jointly on all used points (stage 7).
struct Joint {
    /// Its contribution at every row.
    contribution: Vec<f64>,
    /// Parameters per selected effect.
    params: BTreeMap<String, BTreeMap<String, f64>>,
    /// The same with unit, ± (the joint fit's) and checks.
    checks: BTreeMap<String, Vec<plausibility::ParameterCheck>>,
    /// The model's factors of the joint fit (or of the model alone).
    factors: BTreeMap<String, f64>,
}

/// Stage 7: the selected effects (and, when selected, the model's factors)
/// fitted jointly on all used points, with each parameter's ± and
/// plausibility (`plausibility`).
fn joint_fit(p: &Problem, selected: &[EffectKind], with_model: bool) -> Joint {
    let duration = crate::toolpath::last_time_min(p.used.iter().copied());
    let joint = (!selected.is_empty() || with_model).then(|| p.fit(selected, with_model));
    let (contribution, params, checks) = match &joint {
        None => (vec![0.0; p.n()], BTreeMap::new(), BTreeMap::new()),
        Some(fit) => {
            let (params, checks) = joint_checks(p, fit, duration);
            (fit.contribution(&p.sig), params, checks)
        }
    };
    let factors: BTreeMap<String, f64> = match &joint {
        Some(fit) if fit.model => {
            let offset: usize = fit.kinds.iter().map(|k| k.linear_count()).sum();
            p.named_cols
                .iter()
                .zip(&fit.linear.coefs[offset..])
                .map(|((name, _), b)| (name.clone(), *b))
                .collect()
        }
        _ if !p.named_cols.is_empty() => {
            let fit = p.fit(&[], true);
            p.named_cols
                .iter()
                .zip(&fit.linear.coefs)
                .map(|((name, _), b)| (name.clone(), *b))
                .collect()
        }
        _ => BTreeMap::new(),
    };
    Joint {
        contribution,
        params,
        checks,
        factors,
    }
}

/// Parameters of a joint `fit`, per effect, and their checks (unit, ± from
/// the fit's residual, identifiability and plausibility over a program of
/// `duration` minutes).
#[allow(clippy::type_complexity)]
fn joint_checks(
    p: &Problem,
    fit: &SetFit,
    duration: f64,
) -> (
    BTreeMap<String, BTreeMap<String, f64>>,
    BTreeMap<String, Vec<plausibility::ParameterCheck>>,
) {
    let dof = (p.n() as f64 - fit.linear.rank as f64).max(1.0);
    let s2 = fit.linear.sse / dof;
    let design = p
        .sig
        .design_with(&fit.kinds, fit.model, fit.tau.unwrap_or(1.0));
    let independence = fit::column_independence(&design);
    let mut params = BTreeMap::new();
    let mut checks = BTreeMap::new();
    let mut offset = 0;
    for kind in &fit.kinds {
        let names = kind.parameters_for(p.rotary);
        let lc = kind.linear_count();
        let mut values: Vec<f64> = fit.linear.coefs[offset..offset + lc].to_vec();
        let mut stds: Vec<f64> = fit.linear.inverse_diagonal[offset..offset + lc]
            .iter()
            .map(|v| (v * s2).sqrt())
            .collect();
        if let (true, Some(tau)) = (kind.is_nonlinear(), fit.tau) {
            values.push(tau);
            stds.push(0.0);
        }
        let ind = &independence[offset..offset + lc];
        let list = plausibility::check(*kind, names, &values, &stds, ind, duration.max(1e-6));
        params.insert(
            kind.name().to_string(),
            list.iter().map(|c| (c.name.clone(), c.value)).collect(),
        );
        checks.insert(kind.name().to_string(), list);
        offset += lc;
    }
    (params, checks)
}

/// What remains after the selection (stage 8).
struct Outcome {
    /// The measurement's residual after the joint fit.
    r_after: Vec<f64>,
    local_anomalies: Vec<report::LocalAnomaly>,
    model_check: ModelCheck,
}

/// Stage 8: local anomalies of what remains, and the model check: is the
/// machine's error model itself off? Either its own factors are in the
/// selection, or what remains (local anomalies left out) is well above
/// what the noise and the model's uncertainty allow.
fn check_model(p: &Problem, picked: &Picked, joint: &Joint) -> Outcome {
    // The measurement's residuals after (the follow-up's are in `followup`).
    let r_after = p.residual_after(&joint.contribution);
    let local_anomalies = localization::local_anomalies(&p.used, &r_after, p.floor, p.model_u);
    let remaining = remaining_outside(&p.used, &r_after, &local_anomalies);
    let unexplained = remaining >= UNEXPLAINED_RATIO * p.expected;
    let floor = p.floor;
    let excess = (remaining * remaining - floor * floor).max(0.0).sqrt();
    let model_u = p.model_u;
    // The model's factors beside other effects, a rival the data cannot tell
    // from a selection without them: the verdict is given beside the effects.
    // Only a plausible scale of every table (ALTERNATIVE_SCALES) is such a
    // verdict: factors that flip or remove a table are a flexible fit of
    // the effect, not a model error.
    let alternative = picked
        .rivals
        .iter()
        .filter(|r| r.terms.model && !picked.with_model && r.mse <= picked.chosen.mse)
        .map(|r| {
            let fit = p.fit(&r.terms.kinds, true);
            let offset: usize = r.terms.kinds.iter().map(|k| k.linear_count()).sum();
            report::ModelAlternative {
                terms: r.terms.label(),
                effects: r.terms.kinds.iter().map(|k| k.name().to_string()).collect(),
                z: r.z,
                heldout_rms_um: r.mse.sqrt(),
                factors: p
                    .named_cols
                    .iter()
                    .zip(&fit.linear.coefs[offset..])
                    .map(|((name, _), b)| (name.clone(), *b))
                    .collect(),
            }
        })
        .find(|a| {
            a.factors
                .values()
                .all(|b| ALTERNATIVE_SCALES.contains(&(1.0 + b)))
        });
    let model_check = ModelCheck {
        heldout_rms_before_um: p.mse_before.sqrt(),
        heldout_rms_after_um: picked.model_only_mse.sqrt(),
        explained_um: (p.mse_before - picked.model_only_mse).max(0.0).sqrt(),
        factors: joint.factors.clone(),
        bic: p.bic(picked.model_only_mse, p.named_cols.len()),
        follows_model: picked.with_model,
        unexplained,
        mismatch: picked.with_model || unexplained || alternative.is_some(),
        alternative,
        model_uncertainty_um: model_u,
        expected_rms_um: p.expected,
        remaining_rms_um: remaining,
        uncertainty_factor: (model_u > 1e-9 && excess > 0.0).then(|| excess / model_u),
    };
    Outcome {
        r_after,
        local_anomalies,
        model_check,
    }
}

/// Stage 9: the summary, for the machinist: the model verdict first, one
/// sentence per selected effect (its advice, what is left out and what is
/// implausible), the effects not named, the local anomalies, or that nothing
/// is supported; then the aliases of the selected effects.
fn summary_sentences(
    p: &Problem,
    picked: &Picked,
    joint: &Joint,
    outcome: &Outcome,
    effects: &[EffectFit],
    not_named: &[EffectKind],
) -> Vec<String> {
    let selected = &picked.selected;
    let model_check = &outcome.model_check;
    let local_anomalies = &outcome.local_anomalies;
    let noise_floor = p.noise_floor;
    let max_cut = p.used.iter().map(|c| c.cut_length_m).fold(0.0f64, f64::max);
    let mut summary = Vec::new();
    let label = picked.chosen.terms.label();
    match &model_check.alternative {
        Some(alt) if !model_check.follows_model && !model_check.unexplained => {
            summary.push(alternative_sentence(
                alt,
                &label,
                picked.selected_mse.sqrt(),
            ));
        }
        _ if model_check.mismatch => {
            summary.push(model_sentence(model_check, rms(&p.r0), noise_floor));
        }
        _ => {}
    }
    for kind in selected {
        let list = joint.checks.get(kind.name()).cloned().unwrap_or_default();
        summary.push(effect_sentence(*kind, &list, max_cut));
    }
    for rival in picked
        .rivals
        .iter()
        .filter(|r| !r.terms.model || picked.with_model)
    {
        summary.push(format!(
            "The data cannot tell {} from {} (held-out RMS {:.2} against {:.2} µm; z = {:.1} below the threshold {:.0}): neither is certain; confirm with a dedicated test before acting (--followup-program designs one).",
            label.replace(" + ", " and "),
            rival.terms.label().replace(" + ", " and "),
            picked.selected_mse.sqrt(),
            rival.mse.sqrt(),
            rival.z,
            SIGNIFICANCE
        ));
    }
    if !selected.is_empty() {
        summary.push(format!(
            "With {} added, the residual RMS falls from {:.2} to {:.2} µm (held-out {:.2} µm; noise floor {:.2} µm).",
            picked.chosen.terms.label().replace(" + ", " and "),
            rms(&p.r0), rms(&outcome.r_after), picked.selected_mse.sqrt(), noise_floor
        ));
    }
    if !not_named.is_empty() {
        summary.push(format!(
            "{} would explain part of what remains, but with the model this far off {} cannot be told from its error: not named. Fix the model first, then measure again.",
            not_named.iter().map(|k| k.name()).collect::<Vec<_>>().join(" and "),
            if not_named.len() == 1 { "it" } else { "they" }
        ));
    }
    for a in local_anomalies {
        summary.push(anomaly_sentence(a));
    }
    if selected.is_empty() && !model_check.mismatch && local_anomalies.is_empty() {
        summary.push(format!(
            "The gap between measured and predicted deviations (residual RMS {:.2} µm) is within what the noise floor ({:.2} µm) and the model explain: no unmodelled effect is supported by the data.",
            rms(&p.r0), noise_floor
        ));
    } else if selected.is_empty() && !model_check.mismatch {
        summary.push(format!(
            "No catalogue effect is supported by the data beyond the local anomal{} above (residual RMS {:.2} µm, noise floor {:.2} µm).",
            if local_anomalies.len() == 1 { "y" } else { "ies" },
            rms(&p.r0), noise_floor
        ));
    }
    for e in effects
        .iter()
        .filter(|e| selected.iter().any(|k| k.name() == e.name))
    {
        if !e.aliases.is_empty() {
            summary.push(format!(
                "On this part {} cannot be told apart from {}: confirm with a dedicated test before acting.",
                e.name,
                e.aliases.join(", ")
            ));
        }
    }
    summary
}

/// The summary sentence of a selected effect: the machinist's advice on its
/// identifiable (and, for `tau`, plausible) parameters, then those left out
/// and those implausible.
fn effect_sentence(
    kind: EffectKind,
    list: &[plausibility::ParameterCheck],
    max_cut: f64,
) -> String {
    let advised: BTreeMap<String, f64> = list
        .iter()
        .filter(|c| c.advised(kind))
        .map(|c| (c.name.clone(), c.value))
        .collect();
    let mut sentence = report::machinist_sentence(kind, &advised, max_cut);
    let left_out: Vec<String> = list
        .iter()
        .filter(|c| !advised.contains_key(&c.name) && (!c.identifiable || c.distinguishable))
        .map(|c| c.display())
        .collect();
    let near_zero: Vec<String> = list
        .iter()
        .filter(|c| c.identifiable && !c.distinguishable)
        .map(|c| c.display())
        .collect();
    if !near_zero.is_empty() {
        sentence.push_str(&format!(
            " Not distinguishable from zero (within {:.0} σ), not an error to fix: {}.",
            plausibility::DISTINGUISHABLE_SIGMAS,
            near_zero.join(", ")
        ));
    }
    if !left_out.is_empty() {
        sentence.push_str(&format!(
            " Not determined by this part, left out of this advice: {}.",
            left_out.join(", ")
        ));
    }
    let implausible: Vec<String> = list
        .iter()
        .filter(|c| !c.plausible)
        .map(|c| format!("{} ({})", c.display(), c.notes.join("; ")))
        .collect();
    if !implausible.is_empty() {
        sentence.push_str(&format!(
            " Implausible, check before acting: {}.",
            implausible.join(", ")
        ));
    }
    sentence
}

/// Stage 10: the report.
fn assemble(
    p: Problem,
    picked: Picked,
    effects: Vec<EffectFit>,
    joint: Joint,
    outcome: Outcome,
    summary: Vec<String>,
) -> DiagnoseReport {
    let n0 = p.r0.len();
    // The rivals the summary names (summary_sentences).
    let rivals = picked
        .rivals
        .iter()
        .filter(|r| !r.terms.model || picked.with_model)
        .map(|r| report::RivalSet {
            effects: r.terms.kinds.clone(),
            model_factors: r.terms.model,
        })
        .collect();
    let predicted_after: Vec<f64> = p
        .predicted
        .iter()
        .zip(&joint.contribution)
        .map(|(p, c)| p + c)
        .collect();
    let measured_profile = profile(&p.measured);
    let predicted_profile = profile(&p.predicted);
    let residuals = (0..n0)
        .map(|i| PointResidual {
            id: p.used[i].id.clone(),
            point: p.used[i].point,
            time_min: p.used[i].time_min,
            a_deg: p.used[i].joints.get(p.rotary[0]),
            c_deg: p.used[i].joints.get(p.rotary[1]),
            measured_um: p.measured[i],
            predicted_um: p.predicted[i],
            residual_um: p.r0[i],
            residual_after_um: outcome.r_after[i],
        })
        .collect();
    DiagnoseReport {
        points: p.points,
        points_used: n0,
        gap: Gap {
            measured_profile_um: measured_profile.profile_um,
            predicted_profile_um: predicted_profile.profile_um,
            measured_range_um: measured_profile.range_um,
            predicted_range_um: predicted_profile.range_um,
            residual_rms_um: rms(&p.r0),
            residual_mean_um: p.r0.iter().sum::<f64>() / n0 as f64,
            noise_floor_um: p.noise_floor,
            noise_floor_source: p.noise_source.to_string(),
        },
        localization: localization::localize(&p.used, &p.r0),
        effects,
        selected: picked
            .selected
            .iter()
            .map(|k| k.name().to_string())
            .collect(),
        after: After {
            predicted_profile_um: profile(&predicted_after).profile_um,
            residual_rms_um: rms(&outcome.r_after),
            heldout_rms_um: picked.selected_mse.sqrt(),
            params: joint.params,
            checks: joint.checks,
            significance: picked.chosen.significance.iter().cloned().collect(),
        },
        summary,
        selection_notes: picked.notes,
        residuals,
        rotary_axes: p.rotary.iter().map(|a| a.letter().to_string()).collect(),
        model_check: outcome.model_check,
        local_anomalies: outcome.local_anomalies,
        followup_design: None,
        followup: None,
        warnings: Vec::new(),
        rivals,
    }
}

/// The error model's own columns over `rows`: one per measured axis, and one
/// for the machine file's position-independent errors (the rest of the
/// prediction), each with its name; columns that are zero everywhere are
/// left out.
fn model_columns(
    rows: &[fit::Row],
    slot_letters: &[crate::axes::Axis; 5],
) -> Vec<(String, Vec<f64>)> {
    let mut named_cols: Vec<(String, Vec<f64>)> = (0..5)
        .map(|k| {
            (
                slot_letters[k].letter().to_string(),
                rows.iter()
                    .map(|row| row.axis_deviation_um(k))
                    .collect::<Vec<f64>>(),
            )
        })
        .filter(|(_, c)| c.iter().any(|v| *v != 0.0))
        .collect();
    if !named_cols.is_empty() {
        let rest: Vec<f64> = rows
            .iter()
            .map(|row| row.predicted_um() - (0..5).map(|k| row.axis_deviation_um(k)).sum::<f64>())
            .collect();
        if rms(&rest) > 1e-3 {
            named_cols.push((POSITION_INDEPENDENT.to_string(), rest));
        }
    }
    named_cols
}

/// RMS of `r_after` outside the local `anomalies` (all of it when fewer than
/// ten points would remain).
fn remaining_outside(
    used: &[&PointContext],
    r_after: &[f64],
    anomalies: &[report::LocalAnomaly],
) -> f64 {
    let inside = inside_anomalies(used, anomalies);
    let rest: Vec<f64> = r_after
        .iter()
        .zip(&inside)
        .filter(|(_, inside)| !**inside)
        .map(|(v, _)| *v)
        .collect();
    if rest.len() >= 10 {
        rms(&rest)
    } else {
        rms(r_after)
    }
}

/// Whether each of the `used` points lies within one of the local `anomalies`.
fn inside_anomalies(used: &[&PointContext], anomalies: &[report::LocalAnomaly]) -> Vec<bool> {
    used.iter()
        .map(|c| {
            anomalies.iter().any(|a| {
                (0..3)
                    .map(|k| (c.point[k] - a.centre[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
                    <= a.radius_mm
            })
        })
        .collect()
}

/// The summary sentence of a local anomaly.
fn anomaly_sentence(a: &report::LocalAnomaly) -> String {
    format!(
        "A local anomaly no catalogue effect explains: {} points around ({:.1}, {:.1}, {:.1}) mm (within {:.0} mm; plan ids {}; program lines {}), peak {:+.2} µm, mean {:+.2} µm, {:.0} σ: inspect the part and the cut there (a local defect, a fixture or a clamp, or an error the model does not describe).",
        a.points,
        a.centre[0],
        a.centre[1],
        a.centre[2],
        a.radius_mm,
        a.ids.iter().take(8).cloned().collect::<Vec<_>>().join(", "),
        a.lines
            .iter()
            .take(6)
            .map(|l| l.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        a.peak_um,
        a.mean_um,
        a.sigma
    )
}

/// The model-check factor of the machine file's position-independent errors.
pub const POSITION_INDEPENDENT: &str = "squareness and location";

/// The default threshold of the selection's significance (calibrated on the
/// robustness generator, docs/diagnose.md "Robustness").
pub const SIGNIFICANCE: f64 = 25.0;

/// The scales `1 + β` of every table in a model verdict given beside the
/// effects as an alternative (a table scaled or stale, not flipped or
/// removed).
pub const ALTERNATIVE_SCALES: std::ops::RangeInclusive<f64> = 0.3..=2.0;

/// A table is named as off when its factor is at least this (10 %).
pub const MODEL_FACTOR_MIN: f64 = 0.1;
/// The gap is unexplained when what remains after the selection (local
/// anomalies left out) is at least this × √(σ² + u²), what the noise and the
/// model's own uncertainty allow.
pub const UNEXPLAINED_RATIO: f64 = 1.5;

/// The model's factors large enough to name (|b| ≥ [`MODEL_FACTOR_MIN`]),
/// largest first, and their text (`X ×1.42, Z ×0.61`).
fn named_factors<'a>(
    factors: impl IntoIterator<Item = (&'a String, &'a f64)>,
) -> (Vec<(&'a String, &'a f64)>, String) {
    let mut named: Vec<(&String, &f64)> = factors
        .into_iter()
        .filter(|(_, b)| b.abs() >= MODEL_FACTOR_MIN)
        .collect();
    named.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let axes = named
        .iter()
        .map(|(axis, b)| format!("{axis} ×{:.2}", 1.0 + **b))
        .collect::<Vec<_>>()
        .join(", ");
    (named, axes)
}

/// The verdict when the model's factors, beside other effects, fit as well
/// as the selected effects alone: both are said.
fn alternative_sentence(alt: &report::ModelAlternative, label: &str, heldout: f64) -> String {
    let (_, axes) = named_factors(&alt.factors);
    let effects = if alt.effects.is_empty() {
        "alone".to_string()
    } else {
        format!("with {}", alt.effects.join(" and "))
    };
    format!(
        "The error model itself may not match this machine (tables scaled or stale?): the model's own errors as if the machine's were {axes} the modelled ones, {effects}, explain the gap as well as {} (held-out RMS {:.2} against {:.2} µm; z = {:.1} below the threshold {:.0}): the data cannot tell them apart. Re-measure the axes' error tables (or check that the machine file is this machine's), then measure again before acting on the effects below.",
        label.replace(" + ", " and "),
        alt.heldout_rms_um,
        heldout,
        alt.z,
        SIGNIFICANCE
    )
}

/// The sentence for a model that does not match the machine.
fn model_sentence(check: &ModelCheck, residual_rms: f64, noise_floor: f64) -> String {
    let (named, axes) = named_factors(&check.factors);
    let plausible = named.iter().all(|(_, b)| (0.0..3.0).contains(&(1.0 + **b)));
    let remaining = check.remaining_rms_um;
    let tail = if check.unexplained {
        format!(
            " What remains ({remaining:.2} µm RMS, local anomalies left out) stays unexplained: {:.1} × what the noise floor ({noise_floor:.2} µm) and the model's own uncertainty ({:.2} µm) allow{}.",
            remaining / check.expected_rms_um.max(1e-9),
            check.model_uncertainty_um,
            match check.uncertainty_factor {
                Some(f) => format!(" (as if the tables' uncertainty were ×{f:.1})"),
                None => String::new(),
            }
        )
    } else {
        String::new()
    };
    if check.follows_model && !axes.is_empty() && !plausible {
        format!(
            "The error model itself does not match this machine (tables scaled or stale?): the gap (residual RMS {residual_rms:.2} µm, noise floor {noise_floor:.2} µm) follows the model's own errors, but as no plausible scale of any axis ({axes}): the tables do not describe this machine (another machine's, or stale).{tail} Re-measure the axes' error tables (or check that the machine file is this machine's) before compensating with this model."
        )
    } else if check.follows_model && !axes.is_empty() {
        format!(
            "The error model itself does not match this machine (tables scaled or stale?): the gap (residual RMS {residual_rms:.2} µm, noise floor {noise_floor:.2} µm) follows the model's own errors, as if the machine's were {axes} the modelled ones.{tail} Re-measure those axes' error tables (or check that the machine file is this machine's) before compensating with this model."
        )
    } else {
        format!(
            "The error model itself does not match this machine (tables scaled or stale?): of the gap (residual RMS {residual_rms:.2} µm), {remaining:.2} µm RMS stays unexplained by the catalogue effects, {:.1} × what the noise floor ({noise_floor:.2} µm) and the model's own uncertainty ({:.2} µm) allow{}. Re-measure the axes' error tables (or check that the machine file is this machine's) before compensating with this model.",
            remaining / check.expected_rms_um.max(1e-9),
            check.model_uncertainty_um,
            match check.uncertainty_factor {
                Some(f) => format!(", as if the tables' uncertainty were ×{f:.1}"),
                None => String::new(),
            }
        )
    }
}
