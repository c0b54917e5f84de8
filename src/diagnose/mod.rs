//! The sim-to-real gap engine (effects.md): the catalogue of unmodelled effects,
//! `simulate` (inject them into synthetic measurements) and `diagnose` (explain a
//! measured-vs-predicted gap: where it lies, which effect causes it, and how far
//! it shrinks once that effect is added).
//!
//! Method (docs/diagnose.md): residuals `r = measured − predicted` on the cut
//! points; a noise floor estimated from the data (robust difference estimator
//! along the cut, [`noise`]) unless given; every effect fitted by least squares
//! on its signature columns (no intercept; `tau` profiled), judged by its
//! cross-validated error (folds by region and by time) with a BIC penalty for
//! parameters; aliases by the cosine of an effect's contribution with another
//! effect's span; forward selection of up to two effects, each kept only when
//! its penalised held-out error improves and it explains more than
//! `min_explained_ratio` × the noise floor (RMS).
//!
//! Invariants: inputs are checked (equal lengths, finite values) before any
//! arithmetic; the result is deterministic; no I/O.
pub(crate) mod effects;
mod fit;
pub mod followup;
pub(crate) mod html;
pub(crate) mod localization;
pub(crate) mod noise;
pub(crate) mod probing_program;
pub(crate) mod report;
pub(crate) mod simulate;
#[cfg(any(test, feature = "testkit"))]
pub mod synthetic;

use crate::inspection::profile;
use crate::toolpath::PointContext;
pub use effects::{Effect, EffectError, EffectKind};
use fit::{
    Folds, SetFit, Signatures, cross_validate, cross_validate_columns, fit_set, least_squares,
    span_cosine,
};
pub use html::render as render_html;
use noise::rms;
pub use report::DiagnoseReport;
use report::{After, EffectFit, Gap, ModelCheck, PointResidual};
pub use simulate::{SimulateOptions, simulate, simulate_followup};
use std::collections::BTreeMap;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DiagnoseError {
    #[error("{what}: expected {expected} values (one per plan point), found {found}")]
    LengthMismatch {
        what: &'static str,
        expected: usize,
        found: usize,
    },
    #[error("point `{id}`: {what} is not finite")]
    NonFinite { what: &'static str, id: String },
    #[error("no plan point was cut by the program: nothing to diagnose")]
    NoPoints,
    #[error("{0}")]
    BadOption(String),
}

/// Settings of [`diagnose`].
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnoseOptions {
    /// Probing noise (µm, one σ) when known; estimated from the data otherwise.
    pub noise_um: Option<f64>,
    /// At most this many effects are selected (0–2).
    pub max_selected: usize,
    /// An effect is kept only if the RMS it explains on held-out points,
    /// √(MSE_before − MSE_after), is at least this × the noise floor.
    pub min_explained_ratio: f64,
    /// Cosine above which another effect's span reproduces an effect's
    /// contribution (an alias, when the part it misses is also below the
    /// noise floor, RMS).
    pub alias_cosine: f64,
    /// Number of time folds (region folds are a 3 × 3 grid by x and y terciles).
    pub time_folds: usize,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            noise_um: None,
            max_selected: 2,
            min_explained_ratio: 2.0,
            alias_cosine: 0.98,
            time_folds: 6,
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
    if options.max_selected > 2 {
        return Err(DiagnoseError::BadOption(format!(
            "at most two effects can be selected, asked for {}",
            options.max_selected
        )));
    }
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
    // The measurement's points.
    let n0 = r0.len();
    let (noise_floor, noise_source) = match options.noise_um {
        Some(s) => (s, "given"),
        None => (noise::estimate_noise_floor(&used, &r0), "estimated"),
    };
    // Guard the thresholds against a zero floor (noise-free synthetic data).
    let floor = noise_floor.max(1e-6);

    // Every row fitted: the measurement's, then the follow-up's.
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
    let sig = Signatures::new(&rows);
    let folds = Folds::new(&row_points, options.time_folds);
    let all_rows: Vec<usize> = (0..n).collect();
    let mse_before = r.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let ln_n = (n as f64).ln();
    let bic = |mse: f64, p: usize| n as f64 * mse.max(1e-300).ln() + p as f64 * ln_n;
    let bic_before = bic(mse_before, 0);

    struct Candidate {
        kind: EffectKind,
        fit: SetFit,
        mse: f64,
        bic: f64,
        contribution: Vec<f64>,
    }
    let mut candidates: Vec<Candidate> = EffectKind::ALL
        .iter()
        .map(|&kind| {
            let fit = fit_set(&sig, &[kind], &all_rows, &r);
            let mse = cross_validate(&sig, &folds, &[kind], &r);
            let contribution = fit.contribution(&sig);
            Candidate {
                kind,
                bic: bic(mse, fit.parameter_count()),
                fit,
                mse,
                contribution,
            }
        })
        .collect();
    candidates.sort_by(|a, b| a.bic.total_cmp(&b.bic).then(a.kind.cmp(&b.kind)));

    // Forward selection.
    let mut notes = Vec::new();
    let mut selected: Vec<EffectKind> = Vec::new();
    let mut selected_mse = mse_before;
    let mut selected_params = 0usize;
    let mut selected_bic = bic_before;
    if options.max_selected >= 1 {
        let best = &candidates[0];
        let explained = (mse_before - best.mse).max(0.0).sqrt();
        if best.bic < bic_before && explained >= options.min_explained_ratio * floor {
            notes.push(format!(
                "{}: held-out RMS {:.3} → {:.3} µm, explains {:.3} µm RMS ≥ {:.1} × noise floor {:.3} µm: selected",
                best.kind.name(), mse_before.sqrt(), best.mse.sqrt(), explained, options.min_explained_ratio, noise_floor
            ));
            selected.push(best.kind);
            selected_params = best.kind.parameters().len();
            selected_mse = best.mse;
            selected_bic = best.bic;
        } else {
            notes.push(format!(
                "best single effect {} explains {:.3} µm RMS on held-out points (needs ≥ {:.1} × noise floor {:.3} µm and a lower BIC: {:.1} vs {:.1}): none selected",
                best.kind.name(), explained, options.min_explained_ratio, noise_floor, best.bic, bic_before
            ));
        }
    }
    if options.max_selected >= 2 && selected.len() == 1 {
        // The best pair overall by BIC among pairs where each member explains a
        // significant part on its own (beyond the other member alone); its
        // members need not include the best single effect.
        let single_mse = |k: EffectKind| {
            candidates
                .iter()
                .find(|c| c.kind == k)
                .map_or(mse_before, |c| c.mse)
        };
        let pairs: Vec<(EffectKind, EffectKind)> = EffectKind::ALL
            .iter()
            .enumerate()
            .flat_map(|(i, a)| EffectKind::ALL[i + 1..].iter().map(move |b| (*a, *b)))
            .collect();
        use rayon::prelude::*;
        let scored: Vec<(Vec<EffectKind>, f64, f64, f64)> = pairs
            .par_iter()
            .map(|&(a, b)| {
                let kinds = vec![a, b];
                let mse = cross_validate(&sig, &folds, &kinds, &r);
                let p = a.parameters().len() + b.parameters().len();
                // The smaller of the two members' added held-out RMS.
                let added = (single_mse(a) - mse)
                    .min(single_mse(b) - mse)
                    .max(0.0)
                    .sqrt();
                (kinds, mse, bic(mse, p), added)
            })
            .collect();
        let best_pair = scored
            .into_iter()
            .filter(|(_, _, _, added)| *added >= options.min_explained_ratio * floor)
            .min_by(|x, y| x.2.total_cmp(&y.2));
        match best_pair {
            // A pair with more parameters than the single effect must also
            // explain significantly more (≥ the ratio × noise floor) on held-out
            // points; one with fewer or as many needs only the lower BIC.
            Some((kinds, mse, score, added))
                if score < selected_bic
                    && (kinds.iter().map(|k| k.parameters().len()).sum::<usize>()
                        <= selected_params
                        || (selected_mse - mse).max(0.0).sqrt()
                            >= options.min_explained_ratio * floor) =>
            {
                let names = format!("{} + {}", kinds[0].name(), kinds[1].name());
                notes.push(format!(
                    "{names}: held-out RMS {:.3} → {:.3} µm (BIC {:.1} < {:.1}); each member adds ≥ {:.3} µm RMS ≥ {:.1} × noise floor: two effects selected",
                    selected_mse.sqrt(), mse.sqrt(), score, selected_bic, added, options.min_explained_ratio
                ));
                // Order the pair by their single-effect ranking.
                let rank = |k: EffectKind| candidates.iter().position(|c| c.kind == k).unwrap_or(usize::MAX);
                let mut kinds = kinds;
                kinds.sort_by_key(|k| rank(*k));
                selected = kinds;
                selected_mse = mse;
                selected_bic = score;
            }
            Some((kinds, mse, score, _)) => notes.push(format!(
                "best pair {} + {} (BIC {:.1} vs {:.1}, held-out RMS {:.3} vs {:.3} µm) does not improve significantly on the single effect: one effect kept",
                kinds[0].name(), kinds[1].name(), score, selected_bic, mse.sqrt(), selected_mse.sqrt()
            )),
            None => notes.push(format!(
                "no pair whose members each add ≥ {:.1} × noise floor on held-out points: one effect kept",
                options.min_explained_ratio
            )),
        }
    }

    // Does the gap follow the error model itself?
    let model_check = {
        // One column per measured axis (what the model attributes to its
        // tables), and one for the rest of the prediction: the machine file's
        // position-independent errors (squareness, rotary location).
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
                .map(|row| {
                    row.predicted_um() - (0..5).map(|k| row.axis_deviation_um(k)).sum::<f64>()
                })
                .collect();
            if rms(&rest) > 1e-3 {
                named_cols.push((POSITION_INDEPENDENT.to_string(), rest));
            }
        }
        let cols: Vec<Vec<f64>> = named_cols.iter().map(|(_, c)| c.clone()).collect();
        let (mse, factors) = if cols.is_empty() {
            (mse_before, BTreeMap::new())
        } else {
            let fit = least_squares(&cols, &all_rows, &r);
            let factors = named_cols
                .iter()
                .zip(&fit.coefs)
                .map(|((name, _), b)| (name.clone(), *b))
                .collect();
            (cross_validate_columns(&cols, &folds, &r), factors)
        };
        let model_bic = bic(mse, cols.len());
        let explained = (mse_before - mse).max(0.0).sqrt();
        let largest = factors
            .values()
            .fold(0.0f64, |m: f64, b: &f64| m.max(b.abs()));
        let follows_model = explained >= options.min_explained_ratio * floor
            && largest >= MODEL_FACTOR_MIN
            && model_bic < bic_before;
        let unexplained = selected_mse.sqrt() >= UNEXPLAINED_RATIO * floor;
        // The model is blamed only when it explains the gap better than the
        // selection and than every single catalogue effect: small effects
        // that no one selects are not a model error.
        let best_catalogue = candidates[0].bic.min(selected_bic);
        let mismatch = (follows_model && model_bic < best_catalogue) || unexplained;
        ModelCheck {
            heldout_rms_before_um: mse_before.sqrt(),
            heldout_rms_after_um: mse.sqrt(),
            explained_um: explained,
            factors,
            bic: model_bic,
            follows_model,
            unexplained,
            mismatch,
        }
    };
    if model_check.mismatch && model_check.follows_model && !selected.is_empty() {
        notes.push(format!(
            "the error model's own axis factors explain the gap better (BIC {:.1} < {:.1}): {} not selected",
            model_check.bic,
            selected_bic,
            selected.iter().map(|k| k.name()).collect::<Vec<_>>().join(" + ")
        ));
        selected.clear();
        selected_mse = mse_before;
    }

    // Aliases: another effect whose span reproduces this effect's contribution.
    let spans: Vec<(EffectKind, Vec<Vec<f64>>)> = candidates
        .iter()
        .map(|c| (c.kind, sig.columns(c.kind, c.fit.tau.unwrap_or(1.0))))
        .collect();
    let effects: Vec<EffectFit> = candidates
        .iter()
        .map(|c| {
            let (params, var) = named_params(&c.fit, 0, rotary);
            let dof = (n as f64 - c.fit.linear.rank as f64).max(1.0);
            let s2 = c.fit.linear.sse / dof;
            let params_std = var.into_iter().map(|(k, v)| (k, (v * s2).sqrt())).collect();
            let contribution_rms = rms(&c.contribution);
            let aliases = if contribution_rms >= floor {
                spans
                    .iter()
                    .filter(|(k, _)| *k != c.kind)
                    .filter(|(_, cols)| {
                        // B reproduces this contribution (cosine) and what it
                        // misses is below the noise floor (RMS).
                        let cos = span_cosine(cols, &c.contribution);
                        let missed = contribution_rms * (1.0 - cos * cos).max(0.0).sqrt();
                        cos >= options.alias_cosine && missed < floor
                    })
                    .map(|(k, _)| k.name().to_string())
                    .collect()
            } else {
                Vec::new()
            };
            let before = mse_before.sqrt();
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
        .collect();

    // After: the selected set fitted jointly on all used points.
    let (after_contribution, after_params) = if selected.is_empty() {
        (vec![0.0; n], BTreeMap::new())
    } else {
        let fit = fit_set(&sig, &selected, &all_rows, &r);
        let params = (0..selected.len())
            .map(|m| {
                (
                    selected[m].name().to_string(),
                    named_params(&fit, m, rotary).0,
                )
            })
            .collect();
        (fit.contribution(&sig), params)
    };
    let predicted_after: Vec<f64> = predicted
        .iter()
        .zip(&after_contribution)
        .map(|(p, c)| p + c)
        .collect();
    // The measurement's residuals after (the follow-up's are in `followup`).
    let r_after: Vec<f64> = r0
        .iter()
        .zip(&after_contribution)
        .map(|(a, c)| a - c)
        .collect();
    let max_cut = used.iter().map(|c| c.cut_length_m).fold(0.0f64, f64::max);
    let mut summary = Vec::new();
    if model_check.mismatch {
        summary.push(model_sentence(
            &model_check,
            rms(&r0),
            selected_mse.sqrt(),
            noise_floor,
        ));
    } else if selected.is_empty() {
        summary.push(format!(
            "The gap between measured and predicted deviations (residual RMS {:.2} µm) is within what the noise floor ({:.2} µm) and the model explain: no unmodelled effect is supported by the data.",
            rms(&r0), noise_floor
        ));
    }
    if !selected.is_empty() {
        for kind in &selected {
            let params = after_params.get(kind.name()).cloned().unwrap_or_default();
            summary.push(report::machinist_sentence(*kind, &params, max_cut));
        }
        summary.push(format!(
            "With {} added, the residual RMS falls from {:.2} to {:.2} µm (held-out {:.2} µm; noise floor {:.2} µm).",
            selected.iter().map(|k| k.name()).collect::<Vec<_>>().join(" and "),
            rms(&r0), rms(&r_after), selected_mse.sqrt(), noise_floor
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
    let measured_profile = profile(&measured);
    let predicted_profile = profile(&predicted);
    let residuals = (0..n0)
        .map(|i| PointResidual {
            id: used[i].id.clone(),
            point: used[i].point,
            time_min: used[i].time_min,
            a_deg: used[i].joints.a,
            c_deg: used[i].joints.c,
            measured_um: measured[i],
            predicted_um: predicted[i],
            residual_um: r0[i],
            residual_after_um: r_after[i],
        })
        .collect();
    Ok(DiagnoseReport {
        points: contexts.len(),
        points_used: n0,
        gap: Gap {
            measured_profile_um: measured_profile.profile_um,
            predicted_profile_um: predicted_profile.profile_um,
            measured_range_um: measured_profile.range_um,
            predicted_range_um: predicted_profile.range_um,
            residual_rms_um: rms(&r0),
            residual_mean_um: r0.iter().sum::<f64>() / n0 as f64,
            noise_floor_um: noise_floor,
            noise_floor_source: noise_source.to_string(),
        },
        localization: localization::localize(&used, &r0),
        effects,
        selected: selected.iter().map(|k| k.name().to_string()).collect(),
        after: After {
            predicted_profile_um: profile(&predicted_after).profile_um,
            residual_rms_um: rms(&r_after),
            heldout_rms_um: selected_mse.sqrt(),
            params: after_params,
        },
        summary,
        selection_notes: notes,
        residuals,
        model_check,
        followup_design: None,
        followup: None,
        warnings: Vec::new(),
    })
}

/// The model-check factor of the machine file's position-independent errors.
pub const POSITION_INDEPENDENT: &str = "squareness and location";

/// A table is named as off when its factor is at least this (10 %).
pub const MODEL_FACTOR_MIN: f64 = 0.1;
/// The gap is unexplained when the held-out RMS after the selection is at
/// least this × the noise floor.
pub const UNEXPLAINED_RATIO: f64 = 3.0;

/// The sentence for a model that does not match the machine.
fn model_sentence(
    check: &ModelCheck,
    residual_rms: f64,
    remaining: f64,
    noise_floor: f64,
) -> String {
    let mut named: Vec<(&String, &f64)> = check
        .factors
        .iter()
        .filter(|(_, b)| b.abs() >= MODEL_FACTOR_MIN)
        .collect();
    named.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let axes = named
        .iter()
        .map(|(axis, b)| format!("{axis} ×{:.2}", 1.0 + **b))
        .collect::<Vec<_>>()
        .join(", ");
    let plausible = named.iter().all(|(_, b)| (0.0..3.0).contains(&(1.0 + **b)));
    if check.follows_model && !axes.is_empty() && !plausible {
        format!(
            "The error model does not match this machine: the gap (residual RMS {residual_rms:.2} µm, noise floor {noise_floor:.2} µm) follows the model's own errors, but as no plausible scale of any axis ({axes}): the tables do not describe this machine (another machine's, or stale). Re-measure the axes' error tables (or check that the machine file is this machine's) before compensating with this model."
        )
    } else if check.follows_model && !axes.is_empty() {
        format!(
            "The error model does not match this machine: the gap (residual RMS {residual_rms:.2} µm, noise floor {noise_floor:.2} µm) follows the model's own errors, as if the machine's were {axes} the modelled ones (explains {:.2} µm RMS on held-out points). Re-measure those axes' error tables (or check that the machine file is this machine's) before compensating with this model.",
            check.explained_um
        )
    } else {
        format!(
            "The error model does not match this machine: of the gap (residual RMS {residual_rms:.2} µm), {remaining:.2} µm RMS stays unexplained on held-out points by the catalogue effects ({:.1} × the noise floor of {noise_floor:.2} µm). Re-measure the axes' error tables (or check that the machine file is this machine's) before compensating with this model.",
            remaining / noise_floor.max(1e-6)
        )
    }
}
