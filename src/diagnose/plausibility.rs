//! Plausibility and identifiability of fitted effect parameters
//! (docs/diagnose.md "Parameters"): every parameter of a selected effect gets
//! its unit, its standard uncertainty and a check. A parameter is *not
//! identifiable* on the part when its standard uncertainty exceeds its value or
//! when its signature column lies (almost) in the span of the other columns of
//! the fit (a rank-deficient direction, e.g. a rotation about the axis of a
//! surface of revolution); it is then left out of the advice. A value outside
//! its physical range (a time constant outside duration/50 … 2 × duration, a
//! negative wear, deflection, lag or backlash, an angle beyond 5 000 µrad or an
//! offset beyond 500 µm) is flagged as implausible. A value within 2 standard
//! uncertainties of zero is *not distinguishable from zero*: reported so, and
//! left out of the advice and of `--write-machine` (issue 36).
use super::effects::EffectKind;
use serde::{Deserialize, Serialize};

/// One parameter of a selected effect and its checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterCheck {
    pub name: String,
    pub value: f64,
    /// Standard uncertainty (one σ, from the fit's residual); `tau`'s is not
    /// computed (0).
    pub std: f64,
    pub unit: String,
    /// The part determines it (see the module documentation).
    pub identifiable: bool,
    /// Within its physical range.
    pub plausible: bool,
    /// At least `DISTINGUISHABLE_SIGMAS` standard uncertainties from zero
    /// (issue 36): a value within them is not advice.
    #[serde(default = "distinguishable_default")]
    pub distinguishable: bool,
    /// Why it is not identifiable or not plausible (empty when it is both).
    pub notes: Vec<String>,
}

impl ParameterCheck {
    /// `value ± std unit` with `decimals`.
    pub fn display(&self) -> String {
        let d = if self.unit == "s²" { 2 } else { 1 };
        if self.unit == "s²" {
            format!(
                "{} = {:.2e} ± {:.1e} {}",
                self.name, self.value, self.std, self.unit
            )
        } else {
            format!(
                "{} = {:.*} ± {:.*} {}",
                self.name, d, self.value, d, self.std, self.unit
            )
        }
    }
}

/// A parameter within this many standard uncertainties of zero is reported
/// as not distinguishable from zero, not as an error to fix.
pub const DISTINGUISHABLE_SIGMAS: f64 = 2.0;

fn distinguishable_default() -> bool {
    true
}

impl ParameterCheck {
    /// The advice may name it: determined by the part and distinguishable
    /// from zero (`tau`: within its plausible range).
    pub fn advised(&self, kind: EffectKind) -> bool {
        if kind.is_nonlinear() && self.name == "tau" {
            self.plausible
        } else {
            self.identifiable && self.distinguishable
        }
    }
}

/// Columns whose share outside the span of the others is below this are
/// rank-deficient directions.
pub const INDEPENDENCE_MIN: f64 = 0.01;
/// Largest plausible angle (µrad) and offset (µm) of an unmodelled effect.
pub const MAX_ANGLE_URAD: f64 = 5000.0;
pub const MAX_OFFSET_UM: f64 = 500.0;

/// Check the parameters of one selected effect. `values`, `stds` and
/// `independence` are in the order of `names` (`tau` last for thermal drift,
/// with std and independence ignored); `duration_min` is the program's.
pub fn check(
    kind: EffectKind,
    names: &[&str],
    values: &[f64],
    stds: &[f64],
    independence: &[f64],
    duration_min: f64,
) -> Vec<ParameterCheck> {
    let units = kind.units();
    names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let value = values.get(j).copied().unwrap_or(0.0);
            let std = stds.get(j).copied().unwrap_or(0.0);
            let unit = units.get(j).copied().unwrap_or("").to_string();
            let mut notes = Vec::new();
            let mut identifiable = true;
            let mut plausible = true;
            let is_tau = kind.is_nonlinear() && *name == "tau";
            if !is_tau {
                let ind = independence.get(j).copied().unwrap_or(1.0);
                if ind < INDEPENDENCE_MIN {
                    identifiable = false;
                    notes.push(format!(
                        "not identifiable on this part: its signature lies in the span of the others ({:.1} % outside it)",
                        100.0 * ind
                    ));
                } else if std > value.abs() {
                    identifiable = false;
                    notes.push(format!(
                        "not determined by this part: its uncertainty ({std:.3} {unit}) exceeds its value (consistent with 0)"
                    ));
                }
            }
            if is_tau {
                let (lo, hi) = (duration_min / 50.0, 2.0 * duration_min);
                if !(lo..=hi).contains(&value) {
                    plausible = false;
                    notes.push(format!(
                        "outside the plausible range {lo:.2}–{hi:.1} min (the program's duration / 50 … 2 × its duration): the time constant is not determined by this part"
                    ));
                }
            } else {
                let negative = match kind {
                    EffectKind::ToolWear => Some("a negative wear (the tool would grow)"),
                    EffectKind::ToolDeflection => {
                        Some("a negative deflection (the tool pulled into the surface)")
                    }
                    EffectKind::ServoLag => Some("a negative lag (the path cut outside the curve)"),
                    EffectKind::Backlash => Some("a negative backlash (an overshoot at reversals)"),
                    _ => None,
                };
                if let Some(why) = negative {
                    if value < 0.0 && identifiable {
                        plausible = false;
                        notes.push(format!("implausible sign: {why}"));
                    }
                }
                let limit = match unit.as_str() {
                    "µrad" => Some(MAX_ANGLE_URAD),
                    "µm" => Some(MAX_OFFSET_UM),
                    _ => None,
                };
                if let Some(limit) = limit {
                    if value.abs() > limit {
                        plausible = false;
                        notes.push(format!(
                            "implausible size: |{name}| > {limit:.0} {unit}"
                        ));
                    }
                }
            }
            let distinguishable = is_tau || value.abs() >= DISTINGUISHABLE_SIGMAS * std;
            if !distinguishable && identifiable {
                notes.push(format!(
                    "not distinguishable from zero: within {DISTINGUISHABLE_SIGMAS:.0} σ ({:.1} σ)",
                    value.abs() / std.max(1e-300)
                ));
            }
            ParameterCheck {
                name: name.to_string(),
                value,
                std,
                unit,
                identifiable,
                plausible,
                distinguishable,
                notes,
            }
        })
        .collect()
}
