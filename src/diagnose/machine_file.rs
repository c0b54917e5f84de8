//! What of a diagnosis belongs in the machine file (`diagnose --write-machine`,
//! docs/diagnose.md "Writing the diagnosis back"): the selected effects that are
//! properties of the machine, as new values of the machine file, each with its
//! reason; the others as comments.
//!
//! - `rotary_location` and `squareness` (effects.md: added on top of the
//!   machine's own values): the new value is the file's plus the diagnosed one.
//! - `backlash`: a `REVERSAL` column (formats.md "Laser positioning runs and
//!   reversal") for X, Y, Z: `bx` is the displacement of the cut surface
//!   between the two directions of travel, and a positioning error of an axis
//!   that carries the tool moves the tip with it (`REVERSAL = bx`), one that
//!   carries the workpiece the other way (`REVERSAL = −bx`).
//! - `setup_error`: a work-offset suggestion in the comment block (the part's
//!   placement, not a property of the machine).
//! - the other effects: named in the comment block, not written (the tool, the
//!   cut or the controller's tuning, not the machine file).
//!
//! Invariant: pure; no I/O.
use super::DiagnoseReport;
use super::effects::EffectKind;
use crate::axes::Axis;
use crate::kinematics::chain::Side;
use crate::kinematics::error_values::SQUARENESS_NAMES;
use crate::machine::Machine;
use crate::machine::update::{MachineEdits, ValueEdit, rounded};
use std::collections::BTreeMap;

/// A `REVERSAL` to add to an axis's table.
#[derive(Clone, Debug, PartialEq)]
pub struct ReversalEdit {
    pub axis: Axis,
    /// Added to the table's `REVERSAL` at every position, µm.
    pub add_um: f64,
    /// Why (for the table's own comment and the machine file's).
    pub note: String,
}

/// The machine file's changes from one diagnosis.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MachineUpdate {
    /// Header, squareness and location (the `[errors]` paths are the
    /// command's: it knows where the tables are written).
    pub edits: MachineEdits,
    /// Reversal columns to write, per axis with a table.
    pub reversal: Vec<ReversalEdit>,
    /// One line per change or advice, for the command's summary.
    pub changes: Vec<String>,
}

/// The ± of `param` of `effect`: the joint fit's (`after.checks`), since the
/// values written are the joint fit's (`after.params`); the effect fitted
/// alone only for a parameter the joint fit gives no ± (`tau`, profiled).
fn value_std(report: &DiagnoseReport, effect: &str, param: &str) -> Option<f64> {
    report
        .after
        .checks
        .get(effect)
        .and_then(|list| list.iter().find(|c| c.name == param && c.name != "tau"))
        .map(|c| c.std)
        .or_else(|| {
            report
                .effects
                .iter()
                .find(|e| e.name == effect)
                .and_then(|e| e.params_std.get(param).copied())
        })
        .filter(|s| s.is_finite())
}

fn pm(value: f64, std: Option<f64>, unit: &str) -> String {
    let small = value != 0.0 && value.abs() < 0.01;
    let text = match (std, small) {
        (Some(s), true) => format!("{value:+.3e} ± {s:.2e} {unit}"),
        (None, true) => format!("{value:+.3e} {unit}"),
        (Some(s), false) => format!("{value:+.2} ± {s:.2} {unit}"),
        (None, false) => format!("{value:+.2} {unit}"),
    };
    text.trim_end().to_string()
}

/// Why an effect that is not a machine property is not written.
fn not_written(kind: EffectKind) -> &'static str {
    match kind {
        EffectKind::ThermalDrift => {
            "the machine's warm-up, not a geometric error: warm up before cutting or tune the controller's thermal compensation"
        }
        EffectKind::ServoLag => {
            "the servo tuning (the error model has no dynamics): raise the position-loop gain or feed-forward"
        }
        EffectKind::ToolDeflection | EffectKind::ToolWear | EffectKind::RadiusOffset => {
            "a property of the tool and the cut, not of the machine: correct the tool's offsets or the cutting conditions"
        }
        _ => "",
    }
}

/// The machine file's changes for `report` on `machine`. `provenance` names
/// the diagnosis' inputs (one line each) for the comment block.
pub fn machine_update(
    report: &DiagnoseReport,
    machine: &Machine,
    provenance: &[String],
) -> MachineUpdate {
    let mut update = MachineUpdate::default();
    let mut header = header_lines(report, provenance);
    let selected: Vec<EffectKind> = report
        .selected
        .iter()
        .filter_map(|n| EffectKind::from_name(n))
        .collect();
    let nothing = if report.model_check.mismatch {
        Some(
            "Nothing changed: the diagnosis says the error model itself does not match this machine (see its report's model_check); re-measure the error tables rather than adding effects to this file.",
        )
    } else if selected.is_empty() {
        Some(
            "Nothing changed: no unmodelled effect is supported by the measurement (the gap is within the noise floor and the model's uncertainty).",
        )
    } else {
        None
    };
    if let Some(line) = nothing {
        header.push(line.to_string());
        update.changes.push(line.to_string());
        header.push(String::new());
        update.edits.header = header;
        return update;
    }
    header.push(format!(
        "Selected: {}; held-out residual RMS {:.2} -> {:.2} µm.",
        report.selected.join(" + "),
        report.gap.residual_rms_um,
        report.after.heldout_rms_um
    ));
    header.push(format!(
        "What changed and why (each value: the file's own plus the diagnosed one, ± one standard error of {}):",
        if selected.len() > 1 {
            "the joint fit of the selected effects"
        } else {
            "the fit"
        }
    ));
    let empty = BTreeMap::new();
    let mut advice = Vec::new();
    for kind in &selected {
        let all = report.after.params.get(kind.name()).unwrap_or(&empty);
        // Only what the advice names is written (issue 36): a value the part
        // does not determine, or within 2 σ of zero, is said and left as is.
        let checks = report.after.checks.get(kind.name());
        let advised = |name: &str| {
            checks
                .and_then(|list| list.iter().find(|c| c.name == name))
                .is_none_or(|c| c.advised(*kind))
        };
        for (name, value) in all.iter().filter(|(n, _)| !advised(n)) {
            let std = value_std(report, kind.name(), name);
            let unit = kind
                .parameters_for(machine.chain.rotary())
                .iter()
                .position(|p| p == name)
                .and_then(|j| kind.units().get(j).copied())
                .unwrap_or("");
            header.push(format!(
                "  {}: {name} {} is not advised (not determined by this part, or not distinguishable from zero within 2 σ): not written.",
                kind.name(),
                pm(*value, std, unit)
            ));
        }
        let params: BTreeMap<String, f64> = all
            .iter()
            .filter(|(n, _)| advised(n))
            .map(|(n, v)| (n.clone(), *v))
            .collect();
        let params = &params;
        let mut out = Written {
            header: &mut header,
            update: &mut update,
            advice: &mut advice,
        };
        match kind {
            EffectKind::RotaryLocation | EffectKind::Squareness => {
                write_values(report, machine, *kind, params, &mut out)
            }
            EffectKind::Backlash => write_reversal(report, machine, params, &mut out),
            EffectKind::SetupError => {
                let line = setup_advice(params);
                out.advice.push(line.clone());
                out.update.changes.push(line);
            }
            other => {
                let line = effect_advice(report, *other, params);
                out.advice.push(line.clone());
                out.update.changes.push(line);
            }
        }
    }
    header.extend(advice);
    for e in report
        .effects
        .iter()
        .filter(|e| report.selected.contains(&e.name) && !e.aliases.is_empty())
    {
        header.push(format!(
            "Caution: on the diagnosed part {} cannot be told apart from {}; confirm with a dedicated test (diagnose --followup-program) before relying on these values on other parts.",
            e.name,
            e.aliases.join(", ")
        ));
    }
    header.push(String::new());
    update.edits.header = header;
    update
}

/// Where an effect's changes go: the comment block, the update, and the
/// advice (written after every value).
struct Written<'a> {
    header: &'a mut Vec<String>,
    update: &'a mut MachineUpdate,
    advice: &'a mut Vec<String>,
}

/// The comment block's first lines: what wrote it, from what, and the gap.
fn header_lines(report: &DiagnoseReport, provenance: &[String]) -> Vec<String> {
    let mut header = vec![format!(
        "Written by `volcomp diagnose --write-machine` (volcomp {}) from the diagnosis of:",
        env!("CARGO_PKG_VERSION")
    )];
    header.extend(provenance.iter().map(|p| format!("  {p}")));
    let g = &report.gap;
    header.push(format!(
        "Measured profile {:.2} µm, predicted {:.2} µm; residual RMS {:.2} µm, noise floor {:.2} µm ({}).",
        g.measured_profile_um,
        g.predicted_profile_um,
        g.residual_rms_um,
        g.noise_floor_um,
        g.noise_floor_source
    ));
    header
}

/// `rotary_location` or `squareness`: the machine file's values plus the
/// diagnosed ones.
fn write_values(
    report: &DiagnoseReport,
    machine: &Machine,
    kind: EffectKind,
    params: &BTreeMap<String, f64>,
    out: &mut Written,
) {
    let name = kind.name();
    let layout = machine.layout();
    let location_names = layout.location_names();
    let (section, keys, own): (&str, Vec<&str>, Vec<f64>) = if kind == EffectKind::Squareness {
        (
            "squareness",
            SQUARENESS_NAMES.to_vec(),
            machine.squareness.to_vec(),
        )
    } else {
        (
            "location",
            location_names.to_vec(),
            machine.location.to_vec(),
        )
    };
    let units: BTreeMap<&str, &str> = kind
        .parameters_for(machine.chain.rotary())
        .iter()
        .copied()
        .zip(kind.units().iter().copied())
        .collect();
    let rank = report
        .effects
        .iter()
        .find(|e| e.name == name)
        .map(|e| (e.rank, e.parameter_count));
    for (param, delta) in params {
        let Some(k) = keys.iter().position(|key| key == param) else {
            continue;
        };
        let new = own[k] + delta;
        if rounded(new) == rounded(own[k]) {
            continue;
        }
        let unit = units.get(param.as_str()).copied().unwrap_or("");
        let std = value_std(report, name, param);
        let weak = std.is_some_and(|s| s >= delta.abs());
        let note = format!(
            "was {:.2}; {name} {}{}",
            own[k],
            pm(*delta, std, unit),
            if weak {
                " (not significant on this part)"
            } else {
                ""
            }
        );
        out.header.push(format!(
            "  [{section}] {param}: {:.2} -> {:.2} {unit} ({name} {}){}",
            own[k],
            rounded(new),
            pm(*delta, std, unit),
            if weak {
                ": not significant (its standard error is at least its value)"
            } else {
                ""
            }
        ));
        let edit = ValueEdit {
            key: param.clone(),
            value: new,
            note,
        };
        if kind == EffectKind::Squareness {
            out.update.edits.squareness.push(edit);
        } else {
            out.update.edits.location.push(edit);
        }
    }
    if let Some((rank, count)) = rank {
        if rank < count {
            out.header.push(format!(
                "  ({name}: rank {rank} of {count} on this part: some combinations cannot be identified from it and are written at minimum norm; they cancel this part's deviations, not necessarily another's)"
            ));
        }
    }
    out.update.changes.push(format!(
        "[{section}]: {name} added to the machine file's values"
    ));
}

/// `backlash`: a `REVERSAL` column for each of X, Y, Z with a table, of the
/// sign of the side the axis carries.
fn write_reversal(
    report: &DiagnoseReport,
    machine: &Machine,
    params: &BTreeMap<String, f64>,
    out: &mut Written,
) {
    let name = EffectKind::Backlash.name();
    for (axis, param) in [(Axis::X, "bx"), (Axis::Y, "by"), (Axis::Z, "bz")] {
        let b = params.get(param).copied().unwrap_or(0.0);
        if rounded(b) == 0.0 {
            continue;
        }
        let std = value_std(report, name, param);
        let sign = match machine.chain.side_of(axis) {
            Some(Side::Workpiece) => -1.0,
            _ => 1.0,
        };
        let carries = if sign < 0.0 {
            "the workpiece"
        } else {
            "the tool"
        };
        let why = format!(
            "backlash {param} = {} ({} carries {carries}: REVERSAL = {}{param})",
            pm(b, std, "µm"),
            axis.letter(),
            if sign < 0.0 { "−" } else { "" }
        );
        if machine.table(axis).is_some() {
            out.header.push(format!(
                "  [errors] {}: REVERSAL {:+.2} µm at every position ({why})",
                axis.letter().to_ascii_lowercase(),
                rounded(sign * b)
            ));
            out.update.reversal.push(ReversalEdit {
                axis,
                add_um: rounded(sign * b),
                note: why,
            });
        } else {
            out.header.push(format!(
                "  {}: not written ({why}): the machine file has no error table for {} to carry a REVERSAL column",
                axis.letter(),
                axis.letter()
            ));
        }
    }
    out.update
        .changes
        .push("[errors]: backlash as REVERSAL columns of copies of the axis tables".into());
}

/// `setup_error`: a work-offset suggestion (not written).
fn setup_advice(params: &BTreeMap<String, f64>) -> String {
    let p = |k: &str| params.get(k).copied().unwrap_or(0.0);
    format!(
        "Set-up (not written: the part's placement on the table is not a property of the machine, and changes with every set-up): the surface was cut shifted by ({:.1}, {:.1}, {:.1}) µm and turned by ({:.0}, {:.0}, {:.0}) µrad about X, Y, Z in part coordinates. To cancel it, move the work offset (G54…) by ({:.1}, {:.1}, {:.1}) µm in part coordinates (the machine frame at rotary zero) and turn the part by ({:.0}, {:.0}, {:.0}) µrad, or re-probe the part zero and alignment.",
        p("tx"),
        p("ty"),
        p("tz"),
        p("rx"),
        p("ry"),
        p("rz"),
        -p("tx"),
        -p("ty"),
        -p("tz"),
        -p("rx"),
        -p("ry"),
        -p("rz")
    )
}

/// An effect that is not a property of the machine: its values and why it
/// is not written.
fn effect_advice(
    report: &DiagnoseReport,
    kind: EffectKind,
    params: &BTreeMap<String, f64>,
) -> String {
    let name = kind.name();
    let units: BTreeMap<&str, &str> = kind
        .parameters()
        .iter()
        .copied()
        .zip(kind.units().iter().copied())
        .collect();
    let values: Vec<String> = params
        .iter()
        .map(|(k, v)| {
            let unit = units.get(k.as_str()).copied().unwrap_or("");
            format!("{k} = {}", pm(*v, value_std(report, name, k), unit))
        })
        .collect();
    format!(
        "{name} ({}): not written: {}.",
        values.join(", "),
        not_written(kind)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::synthetic::{SyntheticOptions, saddle_raster};
    use crate::diagnose::{DiagnoseOptions, Effect, SimulateOptions, diagnose, simulate};

    /// A report of `effects` on the synthetic saddle raster.
    fn report(effects: &[&str]) -> DiagnoseReport {
        let part = saddle_raster(&SyntheticOptions::default());
        let effects: Vec<Effect> = effects.iter().map(|s| Effect::parse(s).unwrap()).collect();
        let m = simulate(
            &part.contexts,
            &part.truth_um,
            &effects,
            &SimulateOptions::default(),
        )
        .unwrap();
        diagnose(
            &part.contexts,
            &m.deviations_um(),
            &DiagnoseOptions::default(),
        )
        .unwrap()
    }

    /// A machine whose X carries the workpiece (under the rotary table), with
    /// ref-trt's X table.
    fn workpiece_x_machine() -> Machine {
        let table = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/ref-trt/x.csv");
        let text = format!(
            "name = \"wx\"\nkinematics = \"chain\"\nworkpiece_side = [\"X\", \"A\", \"C\"]\ntool_side = [\"Y\", \"Z\"]\n\
             [axes.A]\ndirection = [1.0, 0.0, 0.0]\npoint = [0.0, 0.0, 0.0]\n\
             [axes.C]\ndirection = [0.0, 0.0, 1.0]\npoint = [0.0, 0.0, 0.0]\n\
             [tool]\nlength = 100.0\nradius = 3.0\n\
             [limits]\nx = [-200.0, 200.0]\ny = [-150.0, 150.0]\nz = [-200.0, 100.0]\na = [-110.0, 110.0]\n\
             [errors]\nx = {:?}\n",
            table.display().to_string()
        );
        Machine::parse(
            &text,
            std::path::Path::new("wx.toml"),
            &crate::machine::LoadOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn backlash_becomes_a_reversal_of_the_sign_of_the_side_the_axis_carries() {
        let r = report(&["backlash:bx=8,by=5,bz=3"]);
        assert_eq!(r.selected, ["backlash"]);
        let bx = r.after.params["backlash"]["bx"];
        let machine = workpiece_x_machine();
        let update = machine_update(&r, &machine, &["test".into()]);
        // X carries the workpiece: REVERSAL = −bx; Y and Z have no table.
        assert_eq!(update.reversal.len(), 1, "{update:?}");
        assert_eq!(update.reversal[0].axis, Axis::X);
        assert_eq!(update.reversal[0].add_um, rounded(-bx));
        assert!((bx - 8.0).abs() < 1.0, "{bx}");
        let header = update.edits.header.join("\n");
        assert!(
            header.contains("X carries the workpiece: REVERSAL = −bx"),
            "{header}"
        );
        assert!(header.contains("Y: not written"), "{header}");
    }

    #[test]
    fn location_and_squareness_add_to_the_file_and_setup_is_advice() {
        let machine = workpiece_x_machine();
        let r = report(&["squareness:s_xy=40,s_xz=-20"]);
        assert_eq!(r.selected, ["squareness"]);
        let update = machine_update(&r, &machine, &[]);
        let s_xy = update
            .edits
            .squareness
            .iter()
            .find(|e| e.key == "s_xy")
            .unwrap();
        assert!((s_xy.value - 40.0).abs() < 3.0, "{s_xy:?}");
        assert!(update.edits.location.is_empty());
        let r = report(&["setup_error:tx=10,ty=-5"]);
        assert_eq!(r.selected, ["setup_error"]);
        let update = machine_update(&r, &machine, &[]);
        assert_eq!(
            update.edits.squareness.len() + update.edits.location.len(),
            0
        );
        let header = update.edits.header.join("\n");
        assert!(header.contains("Set-up (not written"), "{header}");
        let r = report(&[]);
        let update = machine_update(&r, &machine, &[]);
        assert!(update.edits.header.join("\n").contains("Nothing changed"));
    }

    /// Issue 26: with two effects selected, the values written and their ±
    /// are the joint fit's (`after`), not those of each effect fitted alone.
    #[test]
    fn a_pair_is_written_with_the_joint_fits_values_and_standard_errors() {
        let machine = workpiece_x_machine();
        let r = report(&["squareness:s_xy=40,s_xz=-20", "backlash:bx=8,by=5,bz=3"]);
        assert_eq!(r.selected.len(), 2, "{:?}", r.selected);
        assert!(r.selected.iter().any(|s| s == "squareness"));
        assert!(r.selected.iter().any(|s| s == "backlash"));
        let update = machine_update(&r, &machine, &[]);
        let joint = |effect: &str, param: &str| {
            r.after.checks[effect]
                .iter()
                .find(|c| c.name == param)
                .map(|c| (c.value, c.std))
                .unwrap()
        };
        let alone = |effect: &str, param: &str| {
            let e = r.effects.iter().find(|e| e.name == effect).unwrap();
            (e.params[param], e.params_std[param])
        };
        // Backlash on X (the workpiece side): REVERSAL = −bx of the joint fit,
        // its note with the joint fit's ±.
        let (bx, bx_std) = joint("backlash", "bx");
        let (_, bx_alone_std) = alone("backlash", "bx");
        assert_ne!(pm(bx, Some(bx_std), "µm"), pm(bx, Some(bx_alone_std), "µm"));
        assert_eq!(update.reversal[0].add_um, rounded(-bx));
        assert!(
            update.reversal[0]
                .note
                .contains(&pm(bx, Some(bx_std), "µm")),
            "{:?} (joint ± {bx_std}, alone ± {bx_alone_std})",
            update.reversal[0]
        );
        // Squareness: the file's value plus the joint fit's, with its ±.
        let (s_xy, s_xy_std) = joint("squareness", "s_xy");
        let (_, s_xy_alone_std) = alone("squareness", "s_xy");
        assert_ne!(
            pm(s_xy, Some(s_xy_std), "µrad"),
            pm(s_xy, Some(s_xy_alone_std), "µrad")
        );
        let edit = update
            .edits
            .squareness
            .iter()
            .find(|e| e.key == "s_xy")
            .unwrap();
        assert_eq!(edit.value, machine.squareness[0] + s_xy);
        assert!(
            edit.note.contains(&pm(s_xy, Some(s_xy_std), "µrad")),
            "{edit:?} (joint ± {s_xy_std}, alone ± {s_xy_alone_std})"
        );
        let header = update.edits.header.join("\n");
        assert!(
            header.contains("the joint fit of the selected effects"),
            "{header}"
        );
    }
}
