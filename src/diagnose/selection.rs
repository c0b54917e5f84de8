//! Selection on evidence (docs/diagnose.md "Selection"): sets of terms (up to
//! three catalogue effects, and the error model's own axis factors) are
//! cross-validated and a set is kept only when every member is significant on
//! held-out points.
//!
//! The test of a member `m` of a set `S` is a penalised held-out likelihood
//! ratio, `z_m = n·(MSE(S∖m) − MSE(S)) / v(S) − p_m·ln n ≥ threshold`, with
//! `v(S) = σ² + (n / N_EFF)·max(u², MSE(S) − σ²)`: σ the noise floor, u the
//! model's own standard uncertainty (RMS over the rows). The second term is the
//! systematic part of what stays unexplained (the model's error, or a local
//! anomaly): it is smooth over the part, so it counts as `N_EFF` independent
//! values, not `n`. A localised effect of many σ passes however small its RMS
//! over the part; a fraction of a smooth model error, of a decoy or of noise
//! does not.
//!
//! Invariant: deterministic (sets are scored in a fixed order; ties broken by
//! the order of the catalogue).
use super::effects::EffectKind;
use super::fit::{Folds, Signatures, cross_validate_terms, fit_terms};
use crate::toolpath::PointContext;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// A set of terms: catalogue effects (sorted) and whether the model's own
/// factors are in it.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) struct Terms {
    pub kinds: Vec<EffectKind>,
    pub model: bool,
}

impl Terms {
    fn new(mut kinds: Vec<EffectKind>, model: bool) -> Terms {
        kinds.sort();
        Terms { kinds, model }
    }

    pub fn label(&self) -> String {
        let mut names: Vec<&str> = self.kinds.iter().map(|k| k.name()).collect();
        if self.model {
            names.push("model factors");
        }
        if names.is_empty() {
            "nothing".into()
        } else {
            names.join(" + ")
        }
    }

    fn len(&self) -> usize {
        self.kinds.len() + usize::from(self.model)
    }

    /// The set without its member `m` (the model last).
    fn without(&self, m: usize) -> Terms {
        if m < self.kinds.len() {
            let mut kinds = self.kinds.clone();
            kinds.remove(m);
            Terms::new(kinds, self.model)
        } else {
            Terms::new(self.kinds.clone(), false)
        }
    }

    fn member_label(&self, m: usize) -> &'static str {
        self.kinds.get(m).map_or("model factors", |k| k.name())
    }
}

/// Settings of the selection.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SelectionSettings {
    pub noise_um: f64,
    /// Mean square of the model's standard uncertainty over the rows, µm².
    pub model_u2: f64,
    pub max_effects: usize,
    /// Penalised held-out likelihood ratio each member must reach.
    pub threshold: f64,
    /// The model's columns may enter (there are some).
    pub model_available: bool,
}

/// Independent values that a smooth systematic error counts as over a part.
pub const N_EFF: f64 = 30.0;
/// In a set of several terms, each explains at least this × the noise floor
/// (RMS, held out) beyond the others.
pub const MEMBER_RATIO: f64 = 1.0;
/// The model's factors must reach this × the threshold.
pub const MODEL_THRESHOLD_FACTOR: f64 = 2.0;

/// The outcome of the selection.
#[derive(Clone, Debug)]
pub(crate) struct Selection {
    pub terms: Terms,
    pub mse: f64,
    /// `z` of each member (effects first, then the model), in the order of
    /// `terms`.
    pub significance: Vec<(String, f64)>,
    pub notes: Vec<String>,
}

pub(crate) struct Scorer<'a> {
    pub sig: &'a Signatures,
    pub folds: &'a Folds,
    pub r: &'a [f64],
    pub mse_before: f64,
    pub settings: SelectionSettings,
    /// Model factors accepted in a set (largest |β| ≥ the minimum), by set.
    pub model_plausible: &'a (dyn Fn(&Terms) -> bool + Sync),
    pub cache: BTreeMap<Terms, f64>,
    /// The patch of every row (`patches`): the scale over which a smooth
    /// systematic error is coherent.
    pub patches: &'a [usize],
    /// In-sample contribution of every set scored (fitted on all rows).
    pub fitted: BTreeMap<Terms, Vec<f64>>,
    /// Counts each set cross-validated (the selection's progress), if given.
    pub progress: Option<&'a crate::progress::WorkCounter>,
    /// The rows inside a local anomaly of a residual (the tie's fits leave
    /// them out).
    pub anomalous: &'a dyn AnomalousRows,
}

/// The rows of a residual (one value per row) that lie inside a local
/// anomaly of the part (localization.rs).
pub(crate) trait AnomalousRows {
    fn anomalous_rows(&self, r_rows: &[f64]) -> Vec<bool>;
}

impl Scorer<'_> {
    fn n(&self) -> f64 {
        self.r.len() as f64
    }

    fn params(&self, t: &Terms) -> usize {
        t.kinds.iter().map(|k| k.parameters().len()).sum::<usize>()
            + if t.model { self.sig.model.len() } else { 0 }
    }

    fn member_params(&self, t: &Terms, m: usize) -> usize {
        t.kinds
            .get(m)
            .map_or(self.sig.model.len(), |k| k.parameters().len())
    }

    /// Cross-validate every set not yet in the cache, and fit it on all rows
    /// (in parallel).
    fn ensure(&mut self, sets: &[Terms]) {
        let missing: Vec<Terms> = sets
            .iter()
            .filter(|t| t.len() > 0 && !self.cache.contains_key(*t))
            .cloned()
            .collect();
        let (sig, folds, r, progress) = (self.sig, self.folds, self.r, self.progress);
        let scored: Vec<(Terms, f64)> = missing
            .into_par_iter()
            .map(|t| {
                let mse = cross_validate_terms(sig, folds, &t.kinds, t.model, r);
                progress.inspect(|c| c.step());
                (t, mse)
            })
            .collect();
        self.cache.extend(scored);
        let unfitted: Vec<Terms> = sets
            .iter()
            .filter(|t| t.len() > 0 && !self.fitted.contains_key(*t))
            .cloned()
            .collect();
        let all: Vec<usize> = (0..r.len()).collect();
        let fitted: Vec<(Terms, Vec<f64>)> = unfitted
            .into_par_iter()
            .map(|t| {
                let c = fit_terms(sig, &t.kinds, t.model, &all, r).contribution(sig);
                (t, c)
            })
            .collect();
        self.fitted.extend(fitted);
    }

    /// How many times its noise share a smooth systematic error weighs in the
    /// change from `from` to `to` (module doc): `Σ_P (Σ_{i∈P} d_i)² / Σ d_i²`
    /// over the patches P, `d` the change of the in-sample contribution,
    /// between 1 (a change carried by a few points apart) and `n / N_EFF` (a
    /// change as smooth as the error).
    fn inflation(&self, from: &Terms, to: &Terms) -> f64 {
        let most = (self.n() / N_EFF).max(1.0);
        // Only a term added to the same set is localised evidence: a swap of
        // explanations compares two fits of the same smooth gap.
        let nested = from.kinds.iter().all(|k| to.kinds.contains(k)) && (!from.model || to.model);
        if !nested {
            return most;
        }
        let zero = Vec::new();
        let fitted = |t: &Terms| {
            if t.len() == 0 {
                Some(&zero)
            } else {
                self.fitted.get(t)
            }
        };
        let (Some(a), Some(b)) = (fitted(from), fitted(to)) else {
            return most;
        };
        let at = |v: &Vec<f64>, i: usize| v.get(i).copied().unwrap_or(0.0);
        let patches = self.patches.iter().copied().max().map_or(0, |m| m + 1);
        let mut sums = vec![0.0; patches];
        let mut total = 0.0;
        for (i, &patch) in self.patches.iter().enumerate() {
            let d = at(b, i) - at(a, i);
            sums[patch] += d;
            total += d * d;
        }
        if total <= 0.0 {
            return most;
        }
        (sums.iter().map(|s| s * s).sum::<f64>() / total).clamp(1.0, most)
    }

    /// `z` of every member of `t`, cross-validating the sets it needs.
    pub fn significance_of(&mut self, t: &Terms) -> Vec<(String, f64)> {
        let mut needed = vec![t.clone()];
        needed.extend((0..t.len()).map(|m| t.without(m)));
        self.ensure(&needed);
        self.members(t)
    }

    pub fn mse(&self, t: &Terms) -> f64 {
        if t.len() == 0 {
            self.mse_before
        } else {
            self.cache.get(t).copied().unwrap_or(self.mse_before)
        }
    }

    /// The variance a held-out gain is judged against (module doc), for a
    /// change whose smooth systematic error weighs `inflation` times.
    pub fn variance(&self, mse: f64, inflation: f64) -> f64 {
        let s2 = self.settings.noise_um.powi(2);
        let systematic = self.settings.model_u2.max(mse - s2);
        (s2 + inflation * systematic).max(1e-12)
    }

    /// The penalised held-out likelihood ratio of going from `from` to `to`.
    pub fn z(&self, from: &Terms, to: &Terms) -> f64 {
        let (a, b) = (self.mse(from), self.mse(to));
        let dp = self.params(to) as f64 - self.params(from) as f64;
        self.n() * (a - b) / self.variance(b, self.inflation(from, to)) - dp * self.n().ln()
    }

    /// `z` of every member of `t` (needs the subsets without one member cached).
    fn members(&self, t: &Terms) -> Vec<(String, f64)> {
        let n = self.n();
        (0..t.len())
            .map(|m| {
                let without = t.without(m);
                let v = self.variance(self.mse(t), self.inflation(&without, t));
                let z = n * (self.mse(&without) - self.mse(t)) / v
                    - self.member_params(t, m) as f64 * n.ln();
                (t.member_label(m).to_string(), z)
            })
            .collect()
    }

    /// Mean square of the residual after the set's fit on all rows, over
    /// the rows not `left_out`, and their number.
    fn fitted_mse_outside(&self, t: &Terms, left_out: &[bool]) -> (f64, usize) {
        let (mut sse, mut n) = (0.0, 0usize);
        for (i, r) in self.r.iter().enumerate() {
            if left_out.get(i).copied().unwrap_or(false) {
                continue;
            }
            let c = self
                .fitted
                .get(t)
                .and_then(|c| c.get(i))
                .copied()
                .unwrap_or(0.0);
            sse += (r - c).powi(2);
            n += 1;
        }
        (sse / n.max(1) as f64, n)
    }

    /// `n·ln(MSE) + p·ln n` of the set's fit on all rows, over the rows not
    /// `left_out` (`n` of them).
    fn fitted_bic(&self, t: &Terms, left_out: &[bool]) -> f64 {
        let (mse, n) = self.fitted_mse_outside(t, left_out);
        let n = n.max(1) as f64;
        n * mse.max(1e-300).ln() + self.params(t) as f64 * n.ln()
    }

    /// The rows inside a local anomaly of what the set's fit on all rows
    /// leaves.
    fn anomalous_after(&self, t: &Terms) -> Vec<bool> {
        let after: Vec<f64> = self
            .r
            .iter()
            .enumerate()
            .map(|(i, r)| {
                r - self
                    .fitted
                    .get(t)
                    .and_then(|c| c.get(i))
                    .copied()
                    .unwrap_or(0.0)
            })
            .collect();
        self.anomalous.anomalous_rows(&after)
    }

    fn bic(&self, t: &Terms) -> f64 {
        let n = self.n();
        n * self.mse(t).max(1e-300).ln() + self.params(t) as f64 * n.ln()
    }

    /// Every member reaches the threshold (the model's factors twice it: they
    /// overlap the catalogue, e.g. a table's constant part is a translation),
    /// and the model's factors, when in, name some table off by ≥ 10 %.
    /// In a set of two or more terms, each member must also explain at least
    /// the noise floor (RMS) on held-out points beyond the others: below that,
    /// how a gap splits between effects is within what an unknown model error
    /// mimics (calibrated on the blind cases of the reference implementation,
    /// whose model carries no uncertainty).
    fn admissible(&self, t: &Terms) -> bool {
        let s2 = self.settings.noise_um.powi(2);
        let size_ok = |m: usize| {
            t.len() < 2 || self.mse(&t.without(m)) - self.mse(t) >= MEMBER_RATIO * MEMBER_RATIO * s2
        };
        self.members(t).iter().enumerate().all(|(m, (_, z))| {
            let factor = if m >= t.kinds.len() {
                MODEL_THRESHOLD_FACTOR
            } else {
                1.0
            };
            *z >= factor * self.settings.threshold && size_ok(m)
        }) && (!t.model || (self.model_plausible)(t))
    }
}

/// Forward selection by levels: every single term, then every pair, then the
/// selection extended by one term (up to `max_effects` effects and the
/// model). A level's best admissible set (lowest held-out BIC) replaces the
/// current one when it is significantly better than it.
pub(crate) fn select(scorer: &mut Scorer, singles: &[EffectKind]) -> Selection {
    let s = scorer.settings;
    let mut notes = Vec::new();
    let mut current = Terms::new(Vec::new(), false);
    let mut terms: Vec<Terms> = singles
        .iter()
        .map(|k| Terms::new(vec![*k], false))
        .collect();
    if s.model_available {
        terms.push(Terms::new(Vec::new(), true));
    }
    let max_terms = s.max_effects + usize::from(s.model_available);
    if let Some(c) = scorer.progress {
        // Sets the search may cross-validate (the single effects come
        // scored): every pair, then a term added to the current set per
        // further level, and the model's own set.
        let t = terms.len() as u64;
        c.add_total(1 + t * t.saturating_sub(1) / 2 + t * (max_terms as u64).saturating_sub(2));
    }
    for level in 1..=max_terms {
        let sets: Vec<Terms> = match level {
            1 => terms.clone(),
            2 => {
                let mut v = Vec::new();
                for (i, a) in terms.iter().enumerate() {
                    for b in &terms[i + 1..] {
                        let mut kinds = a.kinds.clone();
                        kinds.extend(&b.kinds);
                        v.push(Terms::new(kinds, a.model || b.model));
                    }
                }
                v
            }
            _ => {
                if current.len() + 1 != level {
                    break;
                }
                terms
                    .iter()
                    .filter(|t| {
                        !((t.model && current.model)
                            || t.kinds.iter().any(|k| current.kinds.contains(k)))
                    })
                    .map(|t| {
                        let mut kinds = current.kinds.clone();
                        kinds.extend(&t.kinds);
                        Terms::new(kinds, current.model || t.model)
                    })
                    .collect()
            }
        };
        let sets: Vec<Terms> = sets
            .into_iter()
            .filter(|t| t.kinds.len() <= s.max_effects)
            .collect();
        if sets.is_empty() {
            break;
        }
        // Every set and its subsets without one member.
        let mut needed = sets.clone();
        for t in &sets {
            needed.extend((0..t.len()).map(|m| t.without(m)));
        }
        scorer.ensure(&needed);
        // The best admissible set (lowest held-out BIC) among those
        // significantly better than the current one; else the best admissible.
        let admissible: Vec<&Terms> = sets.iter().filter(|t| scorer.admissible(t)).collect();
        let by_bic =
            |a: &&&Terms, b: &&&Terms| scorer.bic(a).total_cmp(&scorer.bic(b)).then(a.cmp(b));
        let better: Vec<&Terms> = admissible
            .iter()
            .filter(|t| ***t != current && scorer.z(&current, t) >= s.threshold)
            .copied()
            .collect();
        let mut best = better
            .iter()
            .min_by(by_bic)
            .or_else(|| admissible.iter().min_by(by_bic))
            .copied();
        // The same test among the candidates: the lowest BIC gives way to a
        // candidate significantly better than it (the held-out BIC counts
        // every residual as noise, the test weighs the smooth remainder).
        // Not beside the model's factors: there the remainder is a table
        // error of unknown shape, and which effect fits it is the question
        // of the test against a table of another shape (mod.rs, stage 6b).
        while let Some(b) = best.filter(|b| !b.model) {
            let Some(over) = better
                .iter()
                .filter(|t| !t.model && scorer.z(b, t) >= s.threshold)
                .max_by(|x, y| scorer.z(b, x).total_cmp(&scorer.z(b, y)).then(y.cmp(x)))
            else {
                break;
            };
            notes.push(format!(
                "{} (held-out RMS {:.3} µm) is significantly better than {} (held-out RMS {:.3} µm, the lower BIC): z = {:.1}",
                over.label(),
                scorer.mse(over).sqrt(),
                b.label(),
                scorer.mse(b).sqrt(),
                scorer.z(b, over)
            ));
            best = Some(over);
        }
        // Between candidates the held-out test cannot tell apart (neither is
        // significantly better than the other), the likelihood on all points
        // decides: the lowest BIC of the in-sample fit (`fitted_bic`). The
        // held-out BIC charges a flexible set twice (its held-out error
        // already carries its extrapolation, then `p·ln n`), and a
        // time-dependent effect whose folds extrapolate in time (thermal
        // drift) more still; the test has already guarded both against
        // over-fitting. Not beside the model's factors (as above).
        if let Some(b) = best.filter(|b| !b.model && level == 1) {
            // A local anomaly (a defect, a clamp) is no catalogue effect:
            // the likelihood on all points leaves out what lies inside one
            // after the headline's fit, else the set with more parameters
            // takes part of it.
            let left_out = scorer.anomalous_after(b);
            let fitted_bic = |t: &Terms| scorer.fitted_bic(t, &left_out);
            let kept = left_out.iter().filter(|x| !**x).count();
            let tied = better
                .iter()
                .filter(|t| {
                    !t.model
                        && **t != b
                        && scorer.z(t, b) < s.threshold
                        && scorer.z(b, t) < s.threshold
                })
                .min_by(|x, y| fitted_bic(x).total_cmp(&fitted_bic(y)).then(x.cmp(y)));
            if let Some(t) = tied.filter(|t| fitted_bic(t) < fitted_bic(b)) {
                notes.push(format!(
                    "{} and {} cannot be told apart on held-out points (z = {:.1} and {:.1} < {:.0}); on all points{} {} fits with the lower BIC (RMS {:.3} µm, {} parameters, against {:.3} µm, {}): named first",
                    t.label(),
                    b.label(),
                    scorer.z(b, t),
                    scorer.z(t, b),
                    s.threshold,
                    if kept < left_out.len() {
                        format!(" ({} inside a local anomaly left out)", left_out.len() - kept)
                    } else {
                        String::new()
                    },
                    t.label(),
                    scorer.fitted_mse_outside(t, &left_out).0.sqrt(),
                    scorer.params(t),
                    scorer.fitted_mse_outside(b, &left_out).0.sqrt(),
                    scorer.params(b)
                ));
                best = Some(t);
            }
        }
        match best {
            Some(t) if *t != current && scorer.z(&current, t) >= s.threshold => {
                let members = scorer.members(t);
                notes.push(format!(
                    "{}: held-out RMS {:.3} → {:.3} µm, z = {:.1} over {} (each member: {}; threshold {:.0}): selected",
                    t.label(),
                    scorer.mse(&current).sqrt(),
                    scorer.mse(t).sqrt(),
                    scorer.z(&current, t),
                    current.label(),
                    members
                        .iter()
                        .map(|(name, z)| format!("{name} z = {z:.1}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    s.threshold
                ));
                current = t.clone();
            }
            Some(t) if *t != current => notes.push(format!(
                "best admissible set of {level}, {} (held-out RMS {:.3} µm), is not significantly better than {} (z = {:.1} < {:.0}): kept",
                t.label(),
                scorer.mse(t).sqrt(),
                current.label(),
                scorer.z(&current, t),
                s.threshold
            )),
            Some(_) => {}
            None => {
                // Report the strongest candidate of the level and why it fails.
                let strongest = sets.iter().max_by(|a, b| {
                    let za = scorer.z(&current, a);
                    let zb = scorer.z(&current, b);
                    za.total_cmp(&zb).then(b.cmp(a))
                });
                if let Some(t) = strongest {
                    let weakest = scorer
                        .members(t)
                        .into_iter()
                        .min_by(|a, b| a.1.total_cmp(&b.1))
                        .map(|(name, z)| format!("{name} z = {z:.1}"))
                        .unwrap_or_default();
                    let plausible = !t.model || (scorer.model_plausible)(t);
                    notes.push(format!(
                        "no set of {level} with every member significant (threshold {:.0}); strongest {} (held-out RMS {:.3} µm, weakest member {weakest}{}): {} kept",
                        s.threshold,
                        t.label(),
                        scorer.mse(t).sqrt(),
                        if plausible { "" } else { "; model factors all below 10 %" },
                        current.label()
                    ));
                }
            }
        }
    }
    let significance = scorer.members(&current);
    if let Some(c) = scorer.progress {
        c.finish();
    }
    Selection {
        mse: scorer.mse(&current),
        terms: current,
        significance,
        notes,
    }
}

/// The patch of every point: a grid of about `N_EFF` cells over the part by
/// quantiles of x (6 bands) and y (5 bands), the scale over which a smooth
/// systematic error (the model's) is taken as one value.
pub(crate) fn patches(points: &[&PointContext]) -> Vec<usize> {
    let n = points.len();
    let bands = |axis: usize, count: usize| -> Vec<usize> {
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| points[a].point[axis].total_cmp(&points[b].point[axis]));
        let mut band = vec![0; n];
        for (rank, &i) in order.iter().enumerate() {
            band[i] = (rank * count / n.max(1)).min(count - 1);
        }
        // Equal coordinates share a band (the lowest rank's).
        for w in order.windows(2) {
            if points[w[1]].point[axis] == points[w[0]].point[axis] {
                band[w[1]] = band[w[0]];
            }
        }
        band
    };
    let (bx, by) = (bands(0, 6), bands(1, 5));
    (0..n).map(|i| bx[i] + 6 * by[i]).collect()
}

/// A set of terms the data cannot tell from the selection (issue 36):
/// every member significant in it, and the selection not significantly
/// better than it on held-out points.
#[derive(Clone, Debug)]
pub(crate) struct Rival {
    pub terms: Terms,
    /// `z` of the change from the rival to the selection (below the threshold).
    pub z: f64,
    /// Held-out mean square error of the rival.
    pub mse: f64,
}

/// The rivals of `current` among the sets scored (closest first, at most
/// `MAX_RIVALS`): admissible sets whose members and subsets were all
/// cross-validated, from which going to `current` is not significant.
pub(crate) fn rivals(scorer: &Scorer, current: &Terms) -> Vec<Rival> {
    if current.len() == 0 {
        return Vec::new();
    }
    let mut list: Vec<Rival> = scorer
        .cache
        .keys()
        .filter(|t| *t != current && t.len() > 0)
        .filter(|t| {
            (0..t.len()).all(|m| {
                let w = t.without(m);
                w.len() == 0 || scorer.cache.contains_key(&w)
            })
        })
        .filter(|t| scorer.admissible(t))
        .map(|t| Rival {
            terms: t.clone(),
            z: scorer.z(t, current),
            mse: scorer.mse(t),
        })
        .filter(|r| r.z < scorer.settings.threshold)
        .collect();
    list.sort_by(|a, b| a.z.total_cmp(&b.z).then(a.terms.cmp(&b.terms)));
    // The closest, and the closest with the model's factors (the verdict
    // beside the effects).
    let with_model = list.iter().position(|r| r.terms.model && !current.model);
    let mut kept: Vec<Rival> = list.iter().take(MAX_RIVALS).cloned().collect();
    if let Some(i) = with_model.filter(|&i| i >= MAX_RIVALS) {
        kept.push(list[i].clone());
    }
    kept
}

/// Rivals reported at most.
pub const MAX_RIVALS: usize = 3;
