//! The diagnosis report (effects.md "volcomp diagnose"): the fixed JSON fields of
//! the contract plus details (per-effect BIC, parameter standard errors, the
//! machinist's summary, per-point residuals).
//!
//! Invariant: every number is finite; `effects` lists every catalogue effect,
//! best first; `selected` names effects in `effects`.
use super::effects::EffectKind;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The report of [`diagnose`](super::diagnose) (`--report` JSON; effects.md "volcomp diagnose").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnoseReport {
    /// Points in the measurement.
    pub points: usize,
    /// Points used (cut by the program).
    pub points_used: usize,
    /// The gap between the measurement and the model's prediction, and the noise floor.
    pub gap: Gap,
    /// Where the residual is largest (worst points and program lines).
    pub localization: Localization,
    /// Every catalogue effect fitted, best first (by held-out gain).
    pub effects: Vec<EffectFit>,
    /// The effects the evidence supports (possibly none, possibly two).
    pub selected: Vec<String>,
    /// The model with the selected effects added.
    pub after: After,
    /// What a machinist should do, one sentence per finding.
    pub summary: Vec<String>,
    /// Why the selection is what it is (one line per decision).
    pub selection_notes: Vec<String>,
    /// Per used point: measured, predicted, residual before and after.
    pub residuals: Vec<PointResidual>,
    /// The machine's rotary axes, first and second (`["A", "C"]`, `["B", "C"]`):
    /// the axes of the residuals' `a_deg` and `c_deg`.
    #[serde(default = "default_rotary_axes")]
    pub rotary_axes: Vec<String>,
    /// Whether the gap follows the error model itself (extension; absent in
    /// reports written before it).
    #[serde(default)]
    pub model_check: ModelCheck,
    /// The follow-up measurement designed to separate the selection from its
    /// aliases (`--followup-program`; extension, not read back).
    #[serde(default, skip_deserializing, skip_serializing_if = "Option::is_none")]
    pub followup_design: Option<super::followup::FollowupDesign>,
    /// Significant local clusters of the residual after the selection that no
    /// catalogue effect explains (extension; largest first).
    #[serde(default)]
    pub local_anomalies: Vec<LocalAnomaly>,
    /// What a measured follow-up showed (`--followup`; extension, not read back).
    #[serde(default, skip_deserializing, skip_serializing_if = "Option::is_none")]
    pub followup: Option<super::followup::FollowupOutcome>,
    /// The warnings of reading the program (`crate::warnings`; the command
    /// fills it).
    #[serde(default)]
    pub warnings: Vec<crate::warnings::WarningGroup>,
    /// The sets the data cannot tell from the selection that the summary
    /// names ("The data cannot tell … from …"), closest first: the
    /// follow-up design separates the selection from each (in memory only:
    /// neither written nor read back).
    #[serde(skip)]
    pub rivals: Vec<RivalSet>,
}

/// A set of terms the data cannot tell from the selection (issue 36).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RivalSet {
    /// Its catalogue effects.
    pub effects: Vec<EffectKind>,
    /// Whether the error model's own factors are in it.
    pub model_factors: bool,
}

/// Is the machine's error model itself off? The residual is fitted as factors
/// of what the model attributes to each measured axis and to the machine
/// file's position-independent errors, `r ≈ Σ β_k · n·e_k` (a table k that is
/// β_k off in scale, or stale, or of another machine), and cross-validated like
/// the effects.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelCheck {
    /// Held-out RMS of the residual before and after the axis factors, µm.
    pub heldout_rms_before_um: f64,
    pub heldout_rms_after_um: f64,
    /// RMS the factors explain on held-out points, √(MSE_before − MSE_after).
    pub explained_um: f64,
    /// `β` per measured axis (and for the machine file's squareness and
    /// location, `"squareness and location"`): the machine's errors look like
    /// `(1 + β)` × the modelled ones.
    pub factors: BTreeMap<String, f64>,
    pub bic: f64,
    /// The gap follows the model's own errors (explains ≥ the selection ratio ×
    /// the noise floor, some |β| ≥ 0.1, and a lower BIC than no effect).
    pub follows_model: bool,
    /// What remains unexplained after the selected effects, on held-out points,
    /// is at least three times the noise floor.
    pub unexplained: bool,
    /// The verdict: the error model does not match this machine (the model
    /// explains the gap at least as well as the catalogue, or the gap stays
    /// unexplained).
    pub mismatch: bool,
    /// RMS over the points of the model's own standard uncertainty along n, µm
    /// (0 when the model carries none).
    #[serde(default)]
    pub model_uncertainty_um: f64,
    /// What noise and the model's uncertainty allow: √(σ² + u²), µm.
    #[serde(default)]
    pub expected_rms_um: f64,
    /// RMS of the residual after the selection, local anomalies left out, µm.
    #[serde(default)]
    pub remaining_rms_um: f64,
    /// By how much the model's uncertainty would have to grow to explain what
    /// remains (√(remaining² − σ²)/u; absent when u is 0 or nothing remains).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty_factor: Option<f64>,
    /// The model's factors, with other effects, fit as well as a selection
    /// without them (a rival the data cannot tell from it): the verdict is
    /// given beside the selected effects (issue 36).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alternative: Option<ModelAlternative>,
}

/// A rival of the selection with the model's own factors in it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelAlternative {
    /// The rival set's label (`thermal_drift + model factors`).
    pub terms: String,
    /// Its catalogue effects.
    pub effects: Vec<String>,
    /// `z` of the change from it to the selection (below the threshold: the
    /// selection is not significantly better).
    pub z: f64,
    /// Its held-out RMS, µm.
    pub heldout_rms_um: f64,
    /// The factors `β` of its joint fit, per table (`1 + β` × the model's).
    pub factors: BTreeMap<String, f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Gap {
    pub measured_profile_um: f64,
    pub predicted_profile_um: f64,
    pub measured_range_um: f64,
    pub predicted_range_um: f64,
    pub residual_rms_um: f64,
    pub residual_mean_um: f64,
    pub noise_floor_um: f64,
    /// `"estimated"` (from the data) or `"given"` (`--noise-um`).
    pub noise_floor_source: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Localization {
    /// Plan ids by |residual|, largest first.
    pub worst_points: Vec<String>,
    pub worst_points_detail: Vec<WorstPoint>,
    /// Program lines by |mean residual| of the points they cut, largest first.
    pub worst_blocks: Vec<BlockResidual>,
    pub by_time: Vec<TimeBand>,
    /// Quadrants about the centre of the plan's bounding box.
    pub by_region: Vec<Region>,
    /// Bands of each of the machine's rotary axes, under its letter (A and C
    /// on an A/C machine, B and C on a B/C one); empty for an axis the
    /// machine does not have (and then left out of the report).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub by_a: Vec<AngleBand>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub by_b: Vec<AngleBand>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub by_c: Vec<AngleBand>,
    /// By the sign of each linear axis's most recent motion.
    pub by_direction: Vec<DirectionGroup>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorstPoint {
    pub id: String,
    pub residual_um: f64,
    pub point: [f64; 3],
    pub time_min: f64,
    pub line: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockResidual {
    pub line: usize,
    pub residual_um: f64,
    pub points: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TimeBand {
    pub from_min: f64,
    pub to_min: f64,
    pub rms_um: f64,
    pub mean_um: f64,
    pub points: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Region {
    pub name: String,
    pub rms_um: f64,
    pub mean_um: f64,
    pub points: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AngleBand {
    pub from_deg: f64,
    pub to_deg: f64,
    pub rms_um: f64,
    pub mean_um: f64,
    pub points: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DirectionGroup {
    pub axis: String,
    pub sign: String,
    pub rms_um: f64,
    pub mean_um: f64,
    pub points: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectFit {
    pub name: String,
    /// Parameters fitted on all used points.
    pub params: BTreeMap<String, f64>,
    /// Standard errors of the linear parameters (noise from the fit's residual).
    pub params_std: BTreeMap<String, f64>,
    pub heldout_rms_before_um: f64,
    pub heldout_rms_after_um: f64,
    pub shrink_pct: f64,
    pub aliases: Vec<String>,
    /// Free parameters (linear + `tau`).
    pub parameter_count: usize,
    /// Numerical rank of the signature on this part (< linear parameters: some
    /// combinations are not identifiable and reported at minimum norm).
    pub rank: usize,
    /// `n·ln(held-out MSE) + p·ln(n)`: lower is better.
    pub bic: f64,
    /// RMS of the fitted contribution n·Δ over the used points, µm.
    pub contribution_rms_um: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct After {
    pub predicted_profile_um: f64,
    pub residual_rms_um: f64,
    /// Held-out residual RMS of the selected set (cross-validated like `effects`).
    pub heldout_rms_um: f64,
    /// Parameters of the selected effects fitted jointly on all used points.
    pub params: BTreeMap<String, BTreeMap<String, f64>>,
    /// The same parameters with unit, ± and checks (identifiable, plausible).
    #[serde(default)]
    pub checks: BTreeMap<String, Vec<super::plausibility::ParameterCheck>>,
    /// Each selected term's significance, the penalised held-out likelihood
    /// ratio `z` (docs/diagnose.md "Selection").
    #[serde(default)]
    pub significance: BTreeMap<String, f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointResidual {
    pub id: String,
    pub point: [f64; 3],
    pub time_min: f64,
    /// The joint of the machine's first and second rotary axes (A and C, or
    /// B and C: `DiagnoseReport::rotary_axes`), degrees.
    pub a_deg: f64,
    pub c_deg: f64,
    pub measured_um: f64,
    pub predicted_um: f64,
    pub residual_um: f64,
    pub residual_after_um: f64,
}

fn p(params: &BTreeMap<String, f64>, name: &str) -> f64 {
    params.get(name).copied().unwrap_or(0.0)
}

/// A parameter with `decimals`, or "n/a" when it was left out of the advice
/// (not identifiable on the part).
fn f(params: &BTreeMap<String, f64>, name: &str, decimals: usize) -> String {
    match params.get(name) {
        Some(v) => format!("{v:.decimals$}"),
        None => "n/a".into(),
    }
}

/// One sentence a machinist can act on, for a selected effect. Parameters
/// missing from `params` were left out (not identifiable) and read "n/a".
pub fn machinist_sentence(
    kind: EffectKind,
    params: &BTreeMap<String, f64>,
    max_cut_m: f64,
) -> String {
    match kind {
        EffectKind::Backlash => {
            let axes: Vec<String> = [("X", "bx"), ("Y", "by"), ("Z", "bz")]
                .iter()
                .filter(|(_, k)| params.get(*k).is_some_and(|v| v.abs() >= 1.0))
                .map(|(a, k)| format!("{:.1} µm on {a}", p(params, k)))
                .collect();
            let list = if axes.is_empty() {
                "below 1 µm".to_string()
            } else {
                axes.join(", ")
            };
            format!(
                "Backlash of about {list} (bx={}, by={}, bz={} µm): check the reversal (backlash) compensation of those axes and the ball-screw/nut preload.",
                f(params, "bx", 1),
                f(params, "by", 1),
                f(params, "bz", 1)
            )
        }
        EffectKind::ThermalDrift => {
            let warm = match params.get("tau") {
                Some(tau) => format!(
                    "settling with a time constant of {tau:.1} min: warm the machine up for at least {:.0} min before cutting, or enable/tune the thermal compensation",
                    3.0 * tau
                ),
                None => "with a time constant this part does not determine: warm the machine up before cutting, or enable/tune the thermal compensation".into(),
            };
            format!(
                "Thermal drift of about ({}, {}, {}) µm in machine X/Y/Z, {warm}.",
                f(params, "dx", 1),
                f(params, "dy", 1),
                f(params, "dz", 1),
            )
        }
        EffectKind::ServoLag => format!(
            "Servo lag (contour error ∝ v²κ) with k = {:.2e} s², i.e. about {:.1} µm at 1 mm/s² of centripetal acceleration: raise the position-loop gain or feed-forward, or slow down in tight curvature.",
            p(params, "k"),
            p(params, "k") * 1000.0
        ),
        EffectKind::ToolDeflection => format!(
            "Tool deflection of about {} µm across the tool axis: reduce the step-over or feed, use a shorter or stiffer tool, or add a finishing pass.",
            f(params, "c", 1)
        ),
        EffectKind::ToolWear => format!(
            "Tool wear of about {:.2} µm per metre of cut ({:.1} µm by the end of this program): change the tool earlier or enable wear compensation.",
            p(params, "w"),
            p(params, "w") * max_cut_m
        ),
        EffectKind::RadiusOffset => format!(
            "A constant offset of {} µm along the surface normal: check the tool radius / length offset entered in the controller (re-measure the tool).",
            f(params, "r", 1)
        ),
        EffectKind::SetupError => format!(
            "Workpiece set-up error: shift ({}, {}, {}) µm and rotation ({}, {}, {}) µrad: re-probe the part zero and alignment before cutting.",
            f(params, "tx", 1),
            f(params, "ty", 1),
            f(params, "tz", 1),
            f(params, "rx", 0),
            f(params, "ry", 0),
            f(params, "rz", 0)
        ),
        EffectKind::Squareness => format!(
            "Squareness errors beyond the machine file: s_xy={}, s_xz={}, s_yz={} µrad: re-measure the axis squareness and update [squareness] in the machine file.",
            f(params, "s_xy", 0),
            f(params, "s_xz", 0),
            f(params, "s_yz", 0)
        ),
        EffectKind::RotaryLocation => {
            let list: Vec<String> = params.iter().map(|(k, v)| format!("{k}={v:.1}")).collect();
            format!(
                "Rotary-axis location errors beyond the machine file ({}; µm and µrad): re-run the rotary axes' location test (ISO 230-7) and update [location].",
                list.join(", ")
            )
        }
    }
}

/// A significant local cluster of the residual that no selected effect
/// explains (docs/diagnose.md "Local anomalies").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LocalAnomaly {
    /// Points in the cluster.
    pub points: usize,
    /// Plan ids, largest |residual| first (at most 20).
    pub ids: Vec<String>,
    /// Mean position of its points, part coordinates, mm.
    pub centre: [f64; 3],
    /// Distance from the centre to its farthest point plus the scan radius, mm.
    pub radius_mm: f64,
    /// Program lines that cut it (at most 12, increasing).
    pub lines: Vec<usize>,
    /// Largest residual in it (signed) and the mean, µm.
    pub peak_um: f64,
    pub mean_um: f64,
    /// Largest |neighbourhood mean| / its standard deviation.
    pub sigma: f64,
    /// When it was cut: first and last time, min.
    pub time_min: [f64; 2],
}

fn default_rotary_axes() -> Vec<String> {
    vec!["A".into(), "C".into()]
}
