//! The machine left for `volcomp compensate` once LinuxCNC applies the
//! export (`export linuxcnc --residual-machine OUT.toml`; docs/extensions.md
//! "The residual machine"): compensating a program with the full machine file
//! for a controller that also applies the `COMP_FILE`s and the corrected
//! pivots corrects those errors twice.
//!
//! What LinuxCNC applies is modelled exactly as the export says it applies
//! it: a joint commanded to `p` is driven to `p + trim(p)`, `trim` the
//! `COMP_FILE` read back and interpolated as `compute_screw_comp` does (linear,
//! ends held, forward while moving up, reverse while moving down), and the
//! trt module places the rotary axes at the corrected pivots. So:
//! - each exported axis's positioning column becomes what is left at each of
//!   its table's positions, for each direction `d`:
//!   `left_d(p) = trim_d(p)·1000 + E_d(p + trim_d(p))` (µm), `E_d` the fitted
//!   curve ± REVERSAL/2 evaluated where the joint really goes; the column is
//!   the mean of the two directions and `REVERSAL` their difference (the
//!   table's other columns and their `u_` columns are kept, as is the
//!   positioning column's `u_`: the controller's correction is as uncertain as
//!   the curve it was made from);
//! - the location offsets the pivots express are zero, and `[geometry]` holds
//!   the corrected pivots (a location offset of a rotary axis is exactly a move
//!   of its point in the chain, kinematics.md, so the two files describe the
//!   same machine);
//! - everything else (the other tables, squareness, tilts, zero offsets,
//!   rotary axes) is kept.
//!
//! Between the table's positions the COMP_FILE's linear interpolation departs
//! from the fitted curve by up to its `max_error_um` (the export's tolerance):
//! that, and the other columns of an axis evaluated at `p` rather than at
//! `p + trim(p)` (a slope times a trim: below 1e-3 µm on a machine tool), is
//! what separates compensating with the residual machine on LinuxCNC from
//! compensating with the full machine alone.
use std::fmt::Write as _;

use super::linuxcnc::{LinuxCncExport, number, pivots, read_back};
use super::{ExportError, Positioning};
use crate::axes::Axis;
use crate::machine::update::{MachineEdits, ValueEdit};
use crate::machine::{ErrorModel, Machine};

/// The residual table of one exported axis.
#[derive(Clone, Debug)]
pub struct ResidualTable {
    /// The axis.
    pub axis: Axis,
    /// The table (formats.md "Error table"), comments first.
    pub text: String,
}

/// The residual machine: the machine file's edits (the caller adds the
/// `[errors]` paths: it knows where the tables are written) and the tables.
#[derive(Clone, Debug)]
pub struct ResidualMachine {
    /// Header (what was removed and why), `[geometry]`, `[location]`, and
    /// `[reversal]` keys removed.
    pub edits: MachineEdits,
    /// One per exported axis.
    pub tables: Vec<ResidualTable>,
    /// One line per removed part, for the summary.
    pub removed: Vec<String>,
}

/// The residual machine of `machine` for `export` (made with `model`);
/// `comp_dir` names the export's folder in the header.
pub fn residual_machine(
    machine: &Machine,
    model: &ErrorModel,
    export: &LinuxCncExport,
    comp_dir: &str,
) -> Result<ResidualMachine, ExportError> {
    let mut edits = MachineEdits::default();
    let mut tables = Vec::new();
    let mut removed = Vec::new();
    for f in &export.comp_files {
        let (Some(pos), Some(table)) = (
            Positioning::of(machine, model, f.axis),
            machine.table(f.axis),
        ) else {
            return Err(ExportError::Nothing(format!(
                "{}: no positioning curve of {} for the residual machine",
                machine.source.display(),
                f.axis.letter()
            )));
        };
        let comp = read_back(&f.text, export.comp_type);
        let [lo, hi] = pos.range;
        let mut mean = Vec::with_capacity(table.positions.len());
        let mut reversal = Vec::with_capacity(table.positions.len());
        let mut max_left_um: f64 = 0.0;
        for &p in &table.positions {
            let (tf, tr) = comp.trims(p);
            let left = |trim: f64, curve: &dyn Fn(f64) -> f64| {
                trim * 1e3 + curve((p + trim).clamp(lo, hi))
            };
            let up = left(tf, &|q| pos.forward(q));
            let down = left(tr, &|q| pos.reverse(q));
            max_left_um = max_left_um.max(up.abs()).max(down.abs());
            mean.push(0.5 * (up + down));
            reversal.push(up - down);
        }
        let from_constant = pos.reversal_source() == Some("[reversal]");
        if from_constant {
            edits
                .removed
                .push(("reversal".into(), f.axis.letter().to_string()));
        }
        let file = format!("{}.comp", f.axis.lower());
        let what = if f.reversal {
            format!(
                "{} and {} -> {file}",
                f.parameter,
                if from_constant {
                    "[reversal]"
                } else {
                    "REVERSAL"
                }
            )
        } else {
            format!("{} -> {file}", f.parameter)
        };
        removed.push(format!(
            "{}: {what}; left at the table's positions at most {:.4} µm, between them up to {:.4} µm (LinuxCNC's linear interpolation)",
            f.axis.letter(),
            max_left_um,
            f.max_error_um
        ));
        let text = residual_table_text(
            machine,
            table,
            &pos,
            &mean,
            f.reversal.then_some(&reversal),
            &file,
        );
        tables.push(ResidualTable { axis: f.axis, text });
    }
    if export.kinematics_ini.is_some()
        && let Some(p) = pivots(machine)
    {
        for (k, name) in p.names.iter().enumerate() {
            if p.corrected[k] != p.nominal[k] {
                edits.geometry.push(ValueEdit {
                    key: (*name).into(),
                    value: p.corrected[k],
                    note: format!("was {}: kinematics.ini", number(p.nominal[k])),
                });
            }
        }
        let names = machine.layout().location_names();
        let mut moved = Vec::new();
        for name in &p.expressed {
            let Some(k) = names.iter().position(|n| n == name) else {
                continue;
            };
            let v = machine.location[k];
            if v != 0.0 {
                edits.location.push(ValueEdit {
                    key: name.clone(),
                    value: 0.0,
                    note: format!("was {v}: in kinematics.ini's pivots"),
                });
                moved.push(format!("{name} {v}"));
            }
        }
        if !moved.is_empty() {
            removed.push(format!(
                "[location] {} µm -> kinematics.ini's pivots ({}), now in [geometry]",
                moved.join(", "),
                p.formulas
            ));
        }
    }
    edits.header = header(machine, export, comp_dir, &removed);
    Ok(ResidualMachine {
        edits,
        tables,
        removed,
    })
}

/// The machine file's leading comment block.
fn header(
    machine: &Machine,
    export: &LinuxCncExport,
    comp_dir: &str,
    removed: &[String],
) -> Vec<String> {
    let mut h = vec![
        format!(
            "volcomp export linuxcnc --residual-machine: {} ({}) as `volcomp compensate` sees it",
            machine.name,
            machine.source.display()
        ),
        format!(
            "on a LinuxCNC that applies the export in {comp_dir} (COMP_FILE_TYPE = {}{}).",
            export.comp_type.number(),
            if export.kinematics_ini.is_some() {
                ", kinematics.ini"
            } else {
                ""
            }
        ),
        "Compensate with this file there: with the full machine file the exported errors would be corrected twice.".into(),
        "Removed (the controller applies them):".into(),
    ];
    h.extend(removed.iter().map(|r| format!("  {r}")));
    h.push(
        "Kept: the other component errors, squareness, tilts and zero offsets, the rotary axes' tables."
            .into(),
    );
    h.push(String::new());
    h
}

/// A residual table: the original's columns with the positioning column
/// replaced by `mean` and `REVERSAL` by `reversal` (none when the axis has
/// no reversal).
fn residual_table_text(
    machine: &Machine,
    table: &crate::machine::ErrorTable,
    pos: &Positioning<'_>,
    mean: &[f64],
    reversal: Option<&Vec<f64>>,
    comp_file: &str,
) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "# volcomp export linuxcnc --residual-machine: the {} table of machine {} ({}),",
        table.axis.letter(),
        machine.name,
        table.path.display()
    );
    let _ = writeln!(
        text,
        "# with {p}{r} replaced by what is left once LinuxCNC applies {comp_file}: at each position,",
        p = pos.parameter,
        r = if reversal.is_some() {
            " and REVERSAL"
        } else {
            ""
        }
    );
    let _ = writeln!(
        text,
        "# trim*1000 + E(p + trim) per direction (E the fitted curve +/- REVERSAL/2; {p} their mean{r}).",
        p = pos.parameter,
        r = if reversal.is_some() {
            ", REVERSAL their difference"
        } else {
            ""
        }
    );
    let _ = writeln!(
        text,
        "# The other columns and every u_ column are the original's."
    );
    let mut header = vec!["position".to_string()];
    header.extend(table.columns.iter().map(|c| c.name.clone()));
    header.extend(
        table
            .columns
            .iter()
            .filter(|c| c.uncertainty.is_some())
            .map(|c| format!("u_{}", c.name)),
    );
    if reversal.is_some() {
        header.push("REVERSAL".into());
    }
    let _ = writeln!(text, "{}", header.join(","));
    for (i, &p) in table.positions.iter().enumerate() {
        let mut row = vec![format!("{p}")];
        for c in &table.columns {
            row.push(if c.name == pos.parameter {
                format!("{:.6}", mean[i] + 0.0)
            } else {
                format!("{}", c.values[i])
            });
        }
        for c in &table.columns {
            if let Some(u) = &c.uncertainty {
                row.push(format!("{}", u[i]));
            }
        }
        if let Some(r) = reversal {
            row.push(format!("{:.6}", r[i] + 0.0));
        }
        let _ = writeln!(text, "{}", row.join(","));
    }
    text
}
