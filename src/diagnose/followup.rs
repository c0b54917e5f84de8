//! Follow-up measurements that tell aliases apart (docs/diagnose.md
//! "Follow-up"). When the effect `diagnose` selects has rivals that explain the
//! measurement about as well (its aliases on this part), the cheapest
//! measurement that separates them is designed here: plan points probed again
//! on the machine, right after the program, in the cutting pose or at other
//! A/C angles. After a model verdict, the same design tells the error
//! model's own factors (a table error: a function of the axis positions
//! alone) from the effects (issue 36).
//!
//! A probe reading on the machine is `n·(Δ_cut − Δ_probe)`: the cut surface
//! carries every effect as it was when the point was cut; the probe is moved by
//! the effects that act on it ([`EffectKind::acts_on_probe`]) at its own time,
//! approach and pose. So a set-up error cancels (the part is where it was cut),
//! a thermal drift shows its change since the cut, and a rotary location error
//! its change between two poses.
//!
//! The design is T-optimal for model discrimination (Atkinson and Fedorov,
//! 1975), maximin over the rivals: each hypothesis is fitted to the
//! measurement; for each ordered pair (truth H, rival G) the lack of fit of G
//! refitted to H's noise-free values on the measurement and the chosen probes
//! is the expected separation (squared, over σ²); probes are added greedily to
//! maximise the smallest of these over the pairs.
//!
//! Invariant: no I/O and no kinematics: candidate probes come with their
//! contexts (built by `toolpath::cut::probe_context`).
use super::effects::EffectKind;
use super::fit::{Row, SetFit, Signatures, fit_terms};
use super::{DiagnoseError, DiagnoseReport};
use crate::toolpath::PointContext;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::collections::BTreeMap;

/// Plan point `of` (index among the contexts) probed again on the machine.
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// Probe id (`F01`, …).
    pub id: String,
    /// Index of the probed plan point among the contexts (a cut point).
    pub of: usize,
    /// The probe's context: the plan point and its normal, the probe's pose,
    /// time and approach (`toolpath::cut::probe_context`).
    pub context: PointContext,
}

/// A probe and what it read: `n·(m − p)`, µm.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeReading {
    /// The probe.
    pub probe: Probe,
    /// Its reading `n·(m − p)`, µm.
    pub reading_um: f64,
}

/// The fitted row of a probe, checked: its plan point was cut and its
/// context is finite.
pub(crate) fn probe_row<'a>(
    contexts: &'a [PointContext],
    probe: &'a Probe,
) -> Result<Row<'a>, DiagnoseError> {
    let cut = contexts.get(probe.of).filter(|c| c.cut).ok_or_else(|| {
        DiagnoseError::BadOption(format!(
            "follow-up probe {}: plan point {} was not cut by the program",
            probe.id, probe.context.id
        ))
    })?;
    super::check_context(&probe.context)?;
    Ok(Row {
        cut,
        probe: Some(&probe.context),
    })
}

/// The fitted row of a reading, checked.
pub(crate) fn check_reading<'a>(
    contexts: &'a [PointContext],
    reading: &'a ProbeReading,
) -> Result<Row<'a>, DiagnoseError> {
    if !reading.reading_um.is_finite() {
        return Err(DiagnoseError::NonFinite {
            what: "its follow-up reading",
            id: reading.probe.id.clone(),
        });
    }
    probe_row(contexts, &reading.probe)
}

/// A changes (degrees) of the candidate poses, relative to the cut.
pub const CANDIDATE_A_OFFSETS_DEG: [f64; 3] = [0.0, -15.0, 15.0];
/// C changes (degrees) of the candidate poses, relative to the cut.
pub const CANDIDATE_C_OFFSETS_DEG: [f64; 4] = [0.0, 90.0, 180.0, 270.0];
/// A pose is a candidate only when the stylus axis lies within 60° of the
/// surface normal (`n·u ≥ 0.5`), so the shank clears the surface.
pub const MIN_CONTACT_COS: f64 = 0.5;

/// Candidate probes: every cut point in every pose of
/// [`CANDIDATE_A_OFFSETS_DEG`] × [`CANDIDATE_C_OFFSETS_DEG`] that `probe_at`
/// (the caller's kinematics: `toolpath::cut::probe_context`) accepts and whose
/// stylus meets the surface within 60° of its normal. `probe_at(cut, rotary)`
/// gives the probe's context at the end time at the rotary joints `rotary`
/// (the machine's two rotary axes in letter order; the A offsets apply to the
/// first, the C offsets to the second), or `None` outside the travel.
pub fn candidates<E>(
    contexts: &[PointContext],
    mut probe_at: impl FnMut(&PointContext, [f64; 2]) -> Result<Option<PointContext>, E>,
) -> Result<Vec<Probe>, E> {
    let mut out = Vec::new();
    for (of, cut) in contexts.iter().enumerate().filter(|(_, c)| c.cut) {
        let [r1, r2] = cut.rotary;
        for da in CANDIDATE_A_OFFSETS_DEG {
            for dc in CANDIDATE_C_OFFSETS_DEG {
                let at = [cut.joints.get(r1) + da, cut.joints.get(r2) + dc];
                let Some(context) = probe_at(cut, at)? else {
                    continue;
                };
                if crate::vec3::dot(context.normal, context.tool_axis) < MIN_CONTACT_COS {
                    continue;
                }
                out.push(Probe {
                    id: format!("candidate-{}", out.len() + 1),
                    of,
                    context,
                });
            }
        }
    }
    Ok(out)
}

/// Settings of [`design`].
#[derive(Clone, Debug, PartialEq)]
pub struct FollowupOptions {
    /// Probes in the follow-up.
    pub probes: usize,
    /// Minutes per probe (rotate, position, touch, retract): the i-th probe
    /// (from 1) is taken at the program's end + i × this.
    pub probe_minutes: f64,
}

impl Default for FollowupOptions {
    fn default() -> Self {
        FollowupOptions {
            probes: 12,
            probe_minutes: 0.25,
        }
    }
}

/// A set of terms a follow-up tells apart: catalogue effects, and whether
/// the error model's own factors are in it (after a model verdict).
pub type HypothesisTerms = (Vec<EffectKind>, bool);

/// The error model's own columns at a row (as the diagnosis fits them,
/// docs/diagnose.md step 10): what the model attributes to each measured
/// axis's tables, and the rest of its prediction. At a probe row, the cut's
/// less the probe's: a table error cancels in the cutting pose and shows its
/// change between two poses.
#[derive(Clone, Debug, Default)]
struct ModelColumns {
    axes: Vec<usize>,
    rest: bool,
}

impl ModelColumns {
    /// The columns the measurement's rows carry (an axis whose tables are
    /// zero on the part has none).
    fn of(rows: &[Row]) -> ModelColumns {
        let axes: Vec<usize> = (0..5)
            .filter(|&k| rows.iter().any(|r| r.axis_deviation_um(k) != 0.0))
            .collect();
        let rest: Vec<f64> = rows.iter().map(Self::rest_at).collect();
        ModelColumns {
            rest: !axes.is_empty() && super::noise::rms(&rest) > 1e-3,
            axes,
        }
    }

    fn rest_at(row: &Row) -> f64 {
        row.predicted_um() - (0..5).map(|k| row.axis_deviation_um(k)).sum::<f64>()
    }

    fn row(&self, row: &Row, out: &mut Vec<f64>) {
        out.extend(self.axes.iter().map(|&k| row.axis_deviation_um(k)));
        if self.rest {
            out.push(Self::rest_at(row));
        }
    }

    fn columns(&self, rows: &[Row]) -> Vec<Vec<f64>> {
        let values: Vec<Vec<f64>> = rows
            .iter()
            .map(|r| {
                let mut v = Vec::new();
                self.row(r, &mut v);
                v
            })
            .collect();
        let width = self.axes.len() + usize::from(self.rest);
        (0..width)
            .map(|j| values.iter().map(|v| v[j]).collect())
            .collect()
    }
}

/// Fit `kinds` (and the model's columns when `model`) on `rows`.
fn fit_rows(rows: &[Row], terms: &HypothesisTerms, cols: &ModelColumns, y: &[f64]) -> SetFit {
    let mut sig = Signatures::new(rows);
    if terms.1 {
        sig.model = cols.columns(rows);
    }
    let all: Vec<usize> = (0..rows.len()).collect();
    fit_terms(&sig, &terms.0, terms.1, &all, y)
}

/// One hypothesis: a set of effects (and the model's factors) with its
/// parameters fitted to the measurement.
#[derive(Clone, Debug)]
struct Hypothesis {
    kinds: Vec<EffectKind>,
    /// The model's columns when its factors are in the hypothesis.
    model: Option<ModelColumns>,
    tau: f64,
    coefs: Vec<f64>,
}

impl Hypothesis {
    fn label(&self) -> String {
        label(&self.kinds, self.model.is_some())
    }

    fn terms(&self) -> HypothesisTerms {
        (self.kinds.clone(), self.model.is_some())
    }

    /// Every term of `other` is in this one: this one fits any values of
    /// `other` exactly, so only `other`'s lack of fit under this one
    /// separates them (e.g. the model's factors with an effect, and alone).
    fn nests(&self, other: &Hypothesis) -> bool {
        other.kinds.iter().all(|k| self.kinds.contains(k))
            && (other.model.is_none() || self.model.is_some())
    }

    /// Design row (∂reading/∂θ) at `row`.
    fn design_row(&self, row: &Row) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.coefs.len());
        for k in &self.kinds {
            row.signature(*k, self.tau, &mut out);
        }
        if let Some(cols) = &self.model {
            cols.row(row, &mut out);
        }
        out
    }

    fn value(&self, row: &Row) -> f64 {
        self.value_of(&self.design_row(row))
    }

    /// The value at a row whose design row is `design_row`.
    fn value_of(&self, design_row: &[f64]) -> f64 {
        design_row.iter().zip(&self.coefs).map(|(g, b)| g * b).sum()
    }
}

/// The words of the model's factors in a hypothesis (as the selection
/// notes name them).
pub const MODEL_FACTORS: &str = "model factors";

fn label(kinds: &[EffectKind], model: bool) -> String {
    let mut names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
    if model {
        names.push(MODEL_FACTORS);
    }
    names.join(" + ")
}

/// The hypotheses a follow-up must separate: the selection first (with the
/// model's factors when they are in it), then the sets the summary says the
/// data cannot tell from it (`report.rivals`, whole), then each selection
/// with one member replaced by one of its aliases. After a model verdict
/// (`model_check.mismatch`, issue 36) also the hypotheses it cannot yet be
/// told from: the model's factors without the effects and the effects
/// without them; the effects beside the factors when the verdict is that
/// what remains is unexplained; the verdict's alternative (the model's
/// factors with other effects) when the verdict is given beside a
/// selection without them; and, when the verdict names no effect, the
/// effect that explains most alone. Empty when there is nothing to tell
/// apart.
pub fn hypotheses(report: &DiagnoseReport) -> Vec<HypothesisTerms> {
    let selected: Vec<EffectKind> = report
        .selected
        .iter()
        .filter_map(|s| EffectKind::from_name(s))
        .collect();
    let check = &report.model_check;
    let with_model = check.follows_model;
    if selected.is_empty() && !check.mismatch {
        return Vec::new();
    }
    let first = (selected.clone(), with_model || selected.is_empty());
    let mut out: Vec<HypothesisTerms> = vec![first.clone()];
    // The same set in another order is the same hypothesis.
    let sorted = |h: &HypothesisTerms| {
        let mut kinds = h.0.clone();
        kinds.sort();
        (kinds, h.1)
    };
    let push = |h: HypothesisTerms, out: &mut Vec<HypothesisTerms>| {
        let key = sorted(&h);
        if (!h.0.is_empty() || h.1) && !out.iter().any(|o| sorted(o) == key) {
            out.push(h);
        }
    };
    if check.mismatch {
        let best_alone = report
            .effects
            .first()
            .and_then(|e| EffectKind::from_name(&e.name));
        if first.1 {
            push((Vec::new(), true), &mut out);
            if selected.is_empty() {
                if let Some(k) = best_alone {
                    push((vec![k], false), &mut out);
                }
            } else {
                push((selected.clone(), false), &mut out);
            }
        } else {
            push((selected.clone(), true), &mut out);
        }
        if let Some(alt) = &check.alternative {
            let kinds: Vec<EffectKind> = alt
                .effects
                .iter()
                .filter_map(|s| EffectKind::from_name(s))
                .collect();
            push((kinds, true), &mut out);
        }
    }
    // The sets the summary says the data cannot tell from the selection,
    // whole (a pair against one effect is no single replacement).
    for rival in &report.rivals {
        push((rival.effects.clone(), rival.model_factors), &mut out);
    }
    for (m, kind) in selected.iter().enumerate() {
        let Some(fit) = report.effects.iter().find(|e| e.name == kind.name()) else {
            continue;
        };
        for alias in fit.aliases.iter().filter_map(|a| EffectKind::from_name(a)) {
            if selected.contains(&alias) {
                continue;
            }
            let mut h = selected.clone();
            h[m] = alias;
            push((h, first.1), &mut out);
        }
    }
    if out.len() == 1 { Vec::new() } else { out }
}

/// Normal equations of one ordered pair: the rival `G` refitted to the values
/// of the truth `H`: `M = Σ g gᵀ`, `b = Σ g y`, `c = Σ y²`.
#[derive(Clone, Debug)]
struct PairSums {
    truth: usize,
    rival: usize,
    m: DMatrix<f64>,
    b: DVector<f64>,
    c: f64,
}

impl PairSums {
    fn new(truth: usize, rival: usize, p: usize) -> PairSums {
        PairSums {
            truth,
            rival,
            m: DMatrix::zeros(p, p),
            b: DVector::zeros(p),
            c: 0.0,
        }
    }

    fn add(&mut self, g: &[f64], y: f64) {
        for a in 0..g.len() {
            self.b[a] += g[a] * y;
            for b in 0..g.len() {
                self.m[(a, b)] += g[a] * g[b];
            }
        }
        self.c += y * y;
    }

    /// `c − bᵀM⁺b` with `g`, `y` added (not stored): the rival's lack of fit.
    fn lack_of_fit_with(&self, extra: Option<(&[f64], f64)>) -> f64 {
        let (mut m, mut b, mut c) = (self.m.clone(), self.b.clone(), self.c);
        if let Some((g, y)) = extra {
            for a in 0..g.len() {
                b[a] += g[a] * y;
                for k in 0..g.len() {
                    m[(a, k)] += g[a] * g[k];
                }
            }
            c += y * y;
        }
        lack_of_fit(m, b, c)
    }
}

/// `c − bᵀM⁺b` (≥ 0), through the eigendecomposition of the Jacobi-scaled `M`
/// with eigenvalues below 1e-10 × the largest dropped (the rival's
/// unidentifiable combinations fit nothing).
fn lack_of_fit(m: DMatrix<f64>, b: DVector<f64>, c: f64) -> f64 {
    let p = m.nrows();
    let scale: Vec<f64> = (0..p)
        .map(|a| {
            let d = m[(a, a)];
            if d > 0.0 { 1.0 / d.sqrt() } else { 0.0 }
        })
        .collect();
    let ms = DMatrix::from_fn(p, p, |a, k| m[(a, k)] * scale[a] * scale[k]);
    let bs = DVector::from_fn(p, |a, _| b[a] * scale[a]);
    let eig = ms.symmetric_eigen();
    let l_max = eig.eigenvalues.max().max(0.0);
    let vtb = eig.eigenvectors.transpose() * &bs;
    let explained: f64 = eig
        .eigenvalues
        .iter()
        .zip(vtb.iter())
        .filter(|(l, _)| **l > l_max * 1e-10 && **l > 0.0)
        .map(|(l, v)| v * v / l)
        .sum();
    (c - explained).max(0.0)
}

/// The separation of the selection from one rival, in noise units (σ).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Separation {
    /// The selected effects (`a + b` for a pair).
    pub selected: String,
    /// The rival hypothesis.
    pub rival: String,
    /// On the measurement alone: √(lack of fit)/σ, the smaller of the two directions.
    pub before_sigma: f64,
    /// With the follow-up, if the selection is the truth: the rival's lack of fit.
    pub if_selected_sigma: f64,
    /// With the follow-up, if the rival is the truth: the selection's lack of fit.
    pub if_rival_sigma: f64,
    /// The smaller of the two (of nested hypotheses, the lack of fit of the
    /// smaller one): what the follow-up guarantees.
    pub expected_sigma: f64,
    /// After the follow-up was measured: √|SSE(rival) − SSE(selection)|/σ,
    /// positive when the selection fits better (only in an outcome).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub achieved_sigma: Option<f64>,
}

/// A probe of the design with the reading each hypothesis expects.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DesignedProbe {
    /// Probe id (`F01`, …).
    pub id: String,
    /// The plan point probed.
    pub point_id: String,
    /// The probe's first rotary joint (A on an A/C machine), degrees.
    pub a_deg: f64,
    /// The probe's second rotary joint (C on an A/C machine), degrees.
    pub c_deg: f64,
    /// When the probe is taken (program time), minutes.
    pub time_min: f64,
    /// How this pose differs from the cut: `cutting pose`, or the A/C change.
    pub pose: String,
    /// Expected reading beyond the model's (µm) under each hypothesis.
    pub expected_um: BTreeMap<String, f64>,
    /// The probe itself (its context), for the fit of the outcome.
    #[serde(skip)]
    pub probe: Probe,
}

/// A follow-up measurement designed to separate the selection from its rivals.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FollowupDesign {
    /// The selected hypothesis (`a + b` for a pair).
    pub selected: String,
    /// The rival hypotheses to tell from it.
    pub rivals: Vec<String>,
    /// The probing noise assumed (the report's noise floor), µm.
    pub noise_um: f64,
    /// The probes to take, in order.
    pub probes: Vec<DesignedProbe>,
    /// The expected separation from each rival.
    pub separations: Vec<Separation>,
    /// The smallest expected separation over the rivals, σ.
    pub expected_separation_sigma: f64,
    /// Sentences for the summary.
    pub explanation: Vec<String>,
}

/// The measurement's rows and residuals, and the hypotheses fitted to them.
struct Fitted<'a> {
    rows: Vec<Row<'a>>,
    /// The measurement's residuals (measured − predicted) on `rows`.
    r: Vec<f64>,
    hypotheses: Vec<Hypothesis>,
    noise: f64,
}

fn fit_hypotheses<'a>(
    contexts: &'a [PointContext],
    measured_um: &[f64],
    report: &DiagnoseReport,
    sets: &[HypothesisTerms],
) -> Result<Fitted<'a>, DiagnoseError> {
    if contexts.len() != measured_um.len() {
        return Err(DiagnoseError::LengthMismatch {
            what: "measured deviations",
            expected: contexts.len(),
            found: measured_um.len(),
        });
    }
    let used: Vec<usize> = (0..contexts.len()).filter(|&i| contexts[i].cut).collect();
    let rows: Vec<Row> = used
        .iter()
        .map(|&i| Row {
            cut: &contexts[i],
            probe: None,
        })
        .collect();
    let r: Vec<f64> = used
        .iter()
        .map(|&i| measured_um[i] - contexts[i].predicted_um)
        .collect();
    let cols = ModelColumns::of(&rows);
    let hypotheses = sets
        .iter()
        .map(|terms| {
            let fit = fit_rows(&rows, terms, &cols, &r);
            Hypothesis {
                kinds: terms.0.clone(),
                model: terms.1.then(|| cols.clone()),
                tau: fit.tau.unwrap_or(1.0),
                coefs: fit.linear.coefs,
            }
        })
        .collect();
    Ok(Fitted {
        rows,
        r,
        hypotheses,
        noise: report.gap.noise_floor_um.max(1e-6),
    })
}

/// The ordered pairs (selection, rival) and (rival, selection), with the
/// measurement's rows summed in.
fn pair_sums(fitted: &Fitted) -> Vec<PairSums> {
    let h = &fitted.hypotheses;
    let mut pairs = Vec::new();
    for j in 1..h.len() {
        for (truth, rival) in [(0, j), (j, 0)] {
            if h[rival].nests(&h[truth]) {
                continue;
            }
            let mut s = PairSums::new(truth, rival, h[rival].coefs.len());
            for row in &fitted.rows {
                s.add(&h[rival].design_row(row), h[truth].value(row));
            }
            pairs.push(s);
        }
    }
    pairs
}

/// The separations of the selection from each rival with the probes `extra`
/// added to the measurement's rows: each rival refitted (τ profiled, as the
/// diagnosis does) to the other hypothesis's noise-free values.
fn separations(fitted: &Fitted, extra: &[Row]) -> Vec<Separation> {
    let h = &fitted.hypotheses;
    let cols = ModelColumns::of(&fitted.rows);
    let lack = |rows: &[Row], truth: &Hypothesis, rival: &Hypothesis| {
        let y: Vec<f64> = rows.iter().map(|r| truth.value(r)).collect();
        fit_rows(rows, &rival.terms(), &cols, &y).linear.sse.sqrt() / fitted.noise
    };
    let mut rows = fitted.rows.clone();
    rows.extend_from_slice(extra);
    (1..h.len())
        .map(|j| {
            let (if_selected, if_rival) = (lack(&rows, &h[0], &h[j]), lack(&rows, &h[j], &h[0]));
            // Of nested hypotheses only the smaller one's lack of fit counts.
            let guaranteed = |if_selected: f64, if_rival: f64| {
                if h[0].nests(&h[j]) {
                    if_selected
                } else if h[j].nests(&h[0]) {
                    if_rival
                } else {
                    if_selected.min(if_rival)
                }
            };
            Separation {
                selected: h[0].label(),
                rival: h[j].label(),
                before_sigma: guaranteed(
                    lack(&fitted.rows, &h[0], &h[j]),
                    lack(&fitted.rows, &h[j], &h[0]),
                ),
                if_selected_sigma: if_selected,
                if_rival_sigma: if_rival,
                expected_sigma: guaranteed(if_selected, if_rival),
                achieved_sigma: None,
            }
        })
        .collect()
}

/// The words of a probe in the cutting pose.
const CUTTING_POSE: &str = "cutting pose";

/// The pose of a probe relative to the cut, in words.
fn pose_words(cut: &PointContext, probe: &PointContext) -> String {
    let mut parts = Vec::new();
    for axis in cut.rotary {
        let d = probe.joints.get(axis) - cut.joints.get(axis);
        if d.abs() > 1e-6 {
            parts.push(format!("{} {d:+.0}°", axis.letter()));
        }
    }
    if parts.is_empty() {
        CUTTING_POSE.into()
    } else {
        parts.join(", ")
    }
}

/// The bits of `x` as an unsigned number whose order is the numbers' order
/// (negative ones and ±∞ included): the sign bit set on non-negative
/// numbers, every bit flipped on negative ones; −0 is 0.
fn ordered_bits(x: f64) -> u64 {
    let bits = (x + 0.0).to_bits();
    if bits >> 63 == 0 {
        bits | (1 << 63)
    } else {
        !bits
    }
}

/// Candidates scored first at each step of [`design`] (the best of the last
/// step), so that the bar that lets the others stop early rises soon.
const LEADING_CANDIDATES: usize = 16;

/// Design the follow-up: choose `options.probes` of the `candidates` (each at
/// the end time the caller gave; the i-th chosen is re-timed to
/// `end + i × probe_minutes`). `Ok(None)` when there is nothing to separate
/// (no selection, or no alias).
pub fn design(
    contexts: &[PointContext],
    measured_um: &[f64],
    report: &DiagnoseReport,
    candidates: &[Probe],
    end_min: f64,
    options: &FollowupOptions,
) -> Result<Option<FollowupDesign>, DiagnoseError> {
    let sets = hypotheses(report);
    if sets.is_empty() {
        return Ok(None);
    }
    if options.probes == 0 || !(options.probe_minutes.is_finite() && options.probe_minutes >= 0.0) {
        return Err(DiagnoseError::BadOption(format!(
            "a follow-up needs ≥ 1 probe and ≥ 0 minutes per probe, asked for {} probes of {} min",
            options.probes, options.probe_minutes
        )));
    }
    for c in candidates {
        probe_row(contexts, c)?;
    }
    let fitted = fit_hypotheses(contexts, measured_um, report, &sets)?;
    let h = &fitted.hypotheses;
    let mut sums = pair_sums(&fitted);
    let mut chosen: Vec<Probe> = Vec::new();
    let mut used = vec![false; candidates.len()];
    // Per candidate: its score at the last step (for the order of the next)
    // and the pair that gave it (tried first at the next step).
    let mut last_score = vec![f64::INFINITY; candidates.len()];
    let mut last_pair = vec![0usize; candidates.len()];
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicU64, Ordering};
    for step in 0..options.probes.min(candidates.len()) {
        let time = end_min + (step + 1) as f64 * options.probe_minutes;
        let timed: Vec<PointContext> = candidates
            .iter()
            .map(|c| PointContext {
                time_min: time,
                ..c.context.clone()
            })
            .collect();
        // The pairs in ascending order of their lack of fit without a new
        // probe: the smallest is the likeliest to stay the smallest.
        let mut pair_order: Vec<usize> = (0..sums.len()).collect();
        let base: Vec<f64> = sums.iter().map(|s| s.lack_of_fit_with(None)).collect();
        pair_order.sort_by(|&a, &b| base[a].total_cmp(&base[b]).then(a.cmp(&b)));
        // The best score of a candidate scored in full so far (as
        // `ordered_bits`, whose order is the numbers', negative ones
        // included; none yet: −∞): a candidate whose smallest lack of fit
        // so far is already below it cannot be chosen, so its other pairs
        // are skipped. Exact: the chosen candidate and its tie-break are
        // unchanged.
        let bar = AtomicU64::new(ordered_bits(f64::NEG_INFINITY));
        let score = |i: usize| -> (f64, usize) {
            let row = Row {
                cut: &contexts[candidates[i].of],
                probe: Some(&timed[i]),
            };
            let mut rows: Vec<Option<Vec<f64>>> = vec![None; h.len()];
            let mut values: Vec<Option<f64>> = vec![None; h.len()];
            let mut smallest = f64::INFINITY;
            let mut smallest_pair = last_pair[i];
            // The pair that gave this candidate's score at the last step first.
            let first = last_pair[i];
            let pairs = (first < sums.len())
                .then_some(first)
                .into_iter()
                .chain(pair_order.iter().copied().filter(|&p| p != first));
            for p in pairs {
                let s = &sums[p];
                let y = match values[s.truth] {
                    Some(y) => y,
                    None => {
                        let g = rows[s.truth].get_or_insert_with(|| h[s.truth].design_row(&row));
                        let y = h[s.truth].value_of(g);
                        values[s.truth] = Some(y);
                        y
                    }
                };
                let g = rows[s.rival].get_or_insert_with(|| h[s.rival].design_row(&row));
                let lack = s.lack_of_fit_with(Some((g, y)));
                if lack < smallest {
                    smallest = lack;
                    smallest_pair = p;
                }
                if ordered_bits(smallest) < bar.load(Ordering::Relaxed) {
                    return (smallest, smallest_pair);
                }
            }
            bar.fetch_max(ordered_bits(smallest), Ordering::Relaxed);
            (smallest, smallest_pair)
        };
        // The most promising candidates of the last step first, to raise the
        // bar early.
        let open: Vec<usize> = order.iter().copied().filter(|&i| !used[i]).collect();
        let lead = open.len().min(LEADING_CANDIDATES);
        let mut scored: Vec<(usize, (f64, usize))> =
            open[..lead].par_iter().map(|&i| (i, score(i))).collect();
        scored.par_extend(open[lead..].par_iter().map(|&i| (i, score(i))));
        for &(i, (value, pair)) in &scored {
            last_score[i] = value;
            last_pair[i] = pair;
        }
        let best = scored
            .into_iter()
            .map(|(i, (value, _))| (i, value))
            .reduce(|a, b| {
                if b.1 > a.1 || (b.1 == a.1 && b.0 < a.0) {
                    b
                } else {
                    a
                }
            });
        order.sort_by(|&a, &b| last_score[b].total_cmp(&last_score[a]).then(a.cmp(&b)));
        let Some((i, _)) = best else { break };
        used[i] = true;
        let probe = Probe {
            id: format!("F{:02}", step + 1),
            of: candidates[i].of,
            context: timed[i].clone(),
        };
        let row = Row {
            cut: &contexts[probe.of],
            probe: Some(&probe.context),
        };
        for s in &mut sums {
            let g = h[s.rival].design_row(&row);
            s.add(&g, h[s.truth].value(&row));
        }
        chosen.push(probe);
    }
    let chosen_rows: Vec<Row> = chosen
        .iter()
        .map(|p| Row {
            cut: &contexts[p.of],
            probe: Some(&p.context),
        })
        .collect();
    let separations = separations(&fitted, &chosen_rows);
    let expected = separations
        .iter()
        .map(|s| s.expected_sigma)
        .fold(f64::INFINITY, f64::min);
    let probes: Vec<DesignedProbe> = chosen
        .iter()
        .map(|p| {
            let cut = &contexts[p.of];
            let row = Row {
                cut,
                probe: Some(&p.context),
            };
            DesignedProbe {
                id: p.id.clone(),
                point_id: cut.id.clone(),
                a_deg: p.context.joints.get(p.context.rotary[0]),
                c_deg: p.context.joints.get(p.context.rotary[1]),
                time_min: p.context.time_min,
                pose: pose_words(cut, &p.context),
                expected_um: h.iter().map(|x| (x.label(), x.value(&row))).collect(),
                probe: p.clone(),
            }
        })
        .collect();
    let same_pose = probes.iter().filter(|p| p.pose == CUTTING_POSE).count();
    let rotary_names = contexts.first().map_or(['A', 'C'], |c| {
        c.rotary.map(|a| a.letter().to_ascii_uppercase())
    });
    let mut explanation = vec![format!(
        "To tell {} from {}: probe {} plan points again on the machine right after the program ({} in the cutting pose, {} at other {}/{} angles); expected separation {:.1} σ (now {:.1} σ).",
        h[0].label(),
        h[1..]
            .iter()
            .map(Hypothesis::label)
            .collect::<Vec<_>>()
            .join(", "),
        probes.len(),
        same_pose,
        probes.len() - same_pose,
        rotary_names[0],
        rotary_names[1],
        expected,
        separations
            .iter()
            .map(|s| s.before_sigma)
            .fold(f64::INFINITY, f64::min),
    )];
    if expected < 3.0 {
        explanation.push(format!(
            "With {} probes the separation stays below 3 σ: probe more points (--followup-probes) or repeat the measurement.",
            probes.len()
        ));
    }
    Ok(Some(FollowupDesign {
        selected: h[0].label(),
        rivals: h[1..].iter().map(Hypothesis::label).collect(),
        noise_um: fitted.noise,
        probes,
        separations,
        expected_separation_sigma: expected,
        explanation,
    }))
}

/// What a measured follow-up showed (report field `followup`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FollowupOutcome {
    /// Follow-up readings judged.
    pub probes: usize,
    /// The selection on the measurement alone.
    pub selected_before: Vec<String>,
    /// Per rival: expected (for the probes taken) and achieved separation.
    pub separations: Vec<Separation>,
    /// RMS of the follow-up readings beyond the model, µm.
    pub reading_rms_um: f64,
}

/// Judge a measured follow-up: the hypotheses of the measurement alone
/// (`before`), fitted on the measurement, give the expected separation for
/// the probes actually taken; refitted on everything, the achieved one.
pub fn outcome(
    contexts: &[PointContext],
    measured_um: &[f64],
    before: &DiagnoseReport,
    readings: &[ProbeReading],
) -> Result<FollowupOutcome, DiagnoseError> {
    let sets = hypotheses(before);
    let probe_rows: Vec<Row> = readings
        .iter()
        .map(|r| check_reading(contexts, r))
        .collect::<Result<_, _>>()?;
    let probe_r: Vec<f64> = readings
        .iter()
        .zip(&probe_rows)
        .map(|(r, row)| r.reading_um - row.predicted_um())
        .collect();
    let reading_rms_um = super::noise::rms(&probe_r);
    if sets.is_empty() {
        return Ok(FollowupOutcome {
            probes: readings.len(),
            selected_before: before.selected.clone(),
            separations: Vec::new(),
            reading_rms_um,
        });
    }
    let fitted = fit_hypotheses(contexts, measured_um, before, &sets)?;
    let mut separations = separations(&fitted, &probe_rows);
    // Achieved: each hypothesis refitted on the measurement and the readings.
    let mut rows = fitted.rows.clone();
    rows.extend(probe_rows.iter().copied());
    let mut r = fitted.r.clone();
    r.extend(&probe_r);
    let cols = ModelColumns::of(&fitted.rows);
    let sse: Vec<f64> = sets
        .iter()
        .map(|terms| fit_rows(&rows, terms, &cols, &r).linear.sse)
        .collect();
    for (j, s) in separations.iter_mut().enumerate() {
        let d = sse[j + 1] - sse[0];
        s.achieved_sigma = Some(d.signum() * d.abs().sqrt() / fitted.noise);
    }
    Ok(FollowupOutcome {
        probes: readings.len(),
        selected_before: before.selected.clone(),
        separations,
        reading_rms_um,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn ordered_bits_keep_the_order_of_the_numbers() {
        let values = [
            f64::NEG_INFINITY,
            -1e300,
            -2.5,
            -1e-300,
            -0.0,
            0.0,
            1e-300,
            3.0,
            1e300,
            f64::INFINITY,
        ];
        for a in values {
            for b in values {
                assert_eq!(
                    super::ordered_bits(a).cmp(&super::ordered_bits(b)),
                    a.partial_cmp(&b).expect("no NaN"),
                    "{a} against {b}"
                );
            }
        }
    }
}
