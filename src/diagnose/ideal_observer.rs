//! The ideal observer of the robustness tables (issue 36): does the evidence
//! on this part, in expectation, tell the injected effects from every other
//! explanation of their size by the selection's threshold?
//!
//! It knows the truth: the injected effects' own deviations `e` (µm, no noise)
//! at the measured points. For every other set `S` of at most as many
//! catalogue effects, `S` is fitted to `e` itself (least squares, `tau`
//! profiled), and what it cannot reproduce, in units of the variance the
//! selection weighs (`σ² + u²`: the noise floor and the model's declared
//! uncertainty), is the expected likelihood ratio by which the data prefer
//! the truth: `d²(S) = min_θ ‖e − X_S θ‖² / (σ² + u²)`. With the selection's
//! parameter penalty, the expected margin over `S` is
//! `d²(S) − (p_truth − p_S)·ln n`; the truth is *separable* when its margin
//! over every such `S` reaches the selection's threshold.
//!
//! The observer is given the noise as white and exactly known, with the
//! model's smooth error counted as white noise of its RMS (a smooth error
//! hides more than that). A pair it does not separate is one whose evidence on
//! all points stays below the threshold in expectation: a selection that names
//! it anyway does so below its threshold (a tie-break, or a rival that
//! extrapolates worse held out than the truth). A pair it separates may still
//! be missed on one draw of the noise and the model's error, or where the truth
//! extrapolates worse held out than its rival.
//!
//! Evaluation only: `diagnose` never calls it. Invariant: no I/O; deterministic.
use super::effects::{Effect, EffectKind};
use super::fit::fit_terms;
use super::{DiagnoseError, DiagnoseOptions, Problem};
use crate::toolpath::PointContext;

/// What the ideal observer says of one set of injected effects on one part.
#[derive(Clone, Debug)]
pub struct Separation {
    /// The smallest expected margin of the truth over another set (module doc).
    pub margin: f64,
    /// The set with that margin: the closest other explanation.
    pub closest: Vec<EffectKind>,
    /// The threshold the margin is held to (the selection's).
    pub threshold: f64,
}

impl Separation {
    /// The truth's expected margin over every other set reaches the threshold.
    pub fn separable(&self) -> bool {
        self.margin >= self.threshold
    }
}

impl std::fmt::Display for Separation {
    /// `expected margin 29.5 over tool_wear + rotary_location (separable)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let closest: Vec<&str> = self.closest.iter().map(|k| k.name()).collect();
        write!(
            f,
            "expected margin {:.1} over {} ({})",
            self.margin,
            closest.join(" + "),
            if self.separable() {
                "separable"
            } else {
                "not separable"
            }
        )
    }
}

/// Every set of 1 to `size` distinct catalogue effects, in catalogue order.
fn sets_up_to(size: usize) -> Vec<Vec<EffectKind>> {
    let kinds = EffectKind::ALL;
    let mut out: Vec<Vec<EffectKind>> = Vec::new();
    let mut frontier: Vec<Vec<EffectKind>> = vec![Vec::new()];
    for _ in 0..size {
        let mut next = Vec::new();
        for set in &frontier {
            let start = set
                .last()
                .and_then(|l| kinds.iter().position(|k| k == l))
                .map_or(0, |i| i + 1);
            for k in &kinds[start..] {
                let mut s = set.clone();
                s.push(*k);
                next.push(s);
            }
        }
        out.extend(next.iter().cloned());
        frontier = next;
    }
    out
}

/// How far the effects `truth` stand, on the points of `contexts`, from every
/// other set of at most as many catalogue effects (module doc), with probing
/// noise `noise_um` (one σ).
pub fn separation(
    contexts: &[PointContext],
    truth: &[Effect],
    noise_um: f64,
    options: &DiagnoseOptions,
) -> Result<Separation, DiagnoseError> {
    // A measurement that is exactly the prediction plus the truth: the rows'
    // residual is then `e` itself.
    let noiseless: Vec<f64> = contexts
        .iter()
        .map(|c| c.predicted_um + truth.iter().map(|e| e.deviation_um(c)).sum::<f64>())
        .collect();
    let options = DiagnoseOptions {
        noise_um: Some(noise_um),
        ..options.clone()
    };
    super::validate(contexts, &noiseless, &options)?;
    let p = Problem::new(contexts, &noiseless, &[], &options)?;
    let n = p.n() as f64;
    let variance = p.floor * p.floor + p.model_u * p.model_u;
    let mut truth_kinds: Vec<EffectKind> = truth.iter().map(|e| e.kind).collect();
    truth_kinds.sort();
    let params = |kinds: &[EffectKind]| -> f64 {
        kinds.iter().map(|k| k.parameters().len()).sum::<usize>() as f64
    };
    let p_truth = params(&truth_kinds);
    let mut closest: Option<(f64, Vec<EffectKind>)> = None;
    for set in sets_up_to(truth_kinds.len().max(1)) {
        let mut sorted = set.clone();
        sorted.sort();
        if sorted == truth_kinds {
            continue;
        }
        let fit = fit_terms(&p.sig, &set, false, &p.all_rows, &p.r);
        let d2 = fit.linear.sse / variance;
        let margin = d2 - (p_truth - params(&set)) * n.ln();
        if closest.as_ref().is_none_or(|(m, _)| margin < *m) {
            closest = Some((margin, set));
        }
    }
    let (margin, closest) = closest.unwrap_or((f64::INFINITY, Vec::new()));
    Ok(Separation {
        margin,
        closest,
        threshold: options.significance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::robustness::{Case, RobustnessOptions, cases, part};

    /// The robustness generator's pair runs (docs/diagnose.md "seventh pass").
    fn pair(seed: u64) -> Case {
        let options = RobustnessOptions {
            pair_runs: 20,
            ..RobustnessOptions::none()
        };
        cases(&part(), &options)
            .into_iter()
            .find(|c| c.seed == seed)
            .expect("a pair run")
    }

    fn separation_of(c: &Case) -> Separation {
        separation(
            &c.contexts,
            &c.effects,
            c.noise_um,
            &DiagnoseOptions::default(),
        )
        .expect("separation")
    }

    #[test]
    fn a_pair_of_distinct_signatures_is_separable() {
        // backlash + servo_lag: nothing else reproduces two reversal steps.
        let c = pair(70004);
        let s = separation_of(&c);
        assert!(s.separable() && s.margin > 1000.0, "{s:?}");
    }

    #[test]
    fn a_pair_that_rotary_location_reproduces_is_not_separable() {
        // squareness + rotary_location: on the nearly flat saddle a second
        // set with rotary_location reproduces the pair within the threshold.
        let c = pair(70013);
        let s = separation_of(&c);
        assert!(!s.separable(), "{s:?}");
        assert!(s.closest.contains(&EffectKind::RotaryLocation), "{s:?}");
    }

    #[test]
    fn more_noise_separates_less() {
        // d² is weighed against σ² + u²: at 1 µm the same pair stands less
        // far from its closest rival than at 0.3 µm.
        let c = pair(70000);
        let at = |noise: f64| {
            separation(&c.contexts, &c.effects, noise, &DiagnoseOptions::default())
                .expect("separation")
                .margin
        };
        let (low, high) = (at(0.3), at(1.0));
        assert!(low.is_finite() && high < low, "{low} {high}");
    }

    #[test]
    fn the_sets_are_every_combination_once() {
        assert_eq!(sets_up_to(1).len(), 9);
        let two = sets_up_to(2);
        assert_eq!(two.len(), 9 + 36);
        let mut seen: Vec<Vec<EffectKind>> = two.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), two.len());
        assert!(two.iter().all(|s| s.len() < 2 || s[0] != s[1]));
    }
}
