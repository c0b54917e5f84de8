//! Every error table as fitted, on a grid the user chooses: one CSV per
//! measured axis in the error-table format (formats.md "Error table", so volcomp
//! reads it back), for controllers whose compensation tables are typed in.
use std::fmt::Write as _;

use super::{ExportError, interpolate};
use crate::axes::Axis;
use crate::machine::table::{DIRECTIONS, parameter_name};
use crate::machine::{ErrorModel, Machine};

/// The grid.
#[derive(Clone, Copy, Debug)]
pub struct GridSettings {
    /// Spacing on linear axes, mm.
    pub step_mm: f64,
    /// Spacing on rotary axes, degrees.
    pub step_deg: f64,
}

/// Most rows a table may have.
pub const MAX_ROWS: usize = 1_000_000;

/// One axis's fitted table.
#[derive(Clone, Debug)]
pub struct FittedTable {
    pub axis: Axis,
    pub columns: Vec<String>,
    pub rows: usize,
    pub text: String,
}

/// A position as written: rounded to 1e-9, shortest form.
fn position(v: f64) -> String {
    let s = format!("{:.9}", v + 0.0);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.to_string() }
}

/// The grid over `[lo, hi]`: lo, lo + step, …, and hi itself.
pub fn grid(lo: f64, hi: f64, step: f64) -> Result<Vec<f64>, ExportError> {
    if !(step.is_finite() && step > 0.0) {
        return Err(ExportError::Setting(format!(
            "the grid step must be a positive number, not {step}"
        )));
    }
    // At least one interval when the table spans any: a step longer than the
    // table keeps its first and last positions.
    let n = ((hi - lo) / step - 1e-9)
        .ceil()
        .max(if hi > lo { 1.0 } else { 0.0 });
    if n + 1.0 > MAX_ROWS as f64 {
        return Err(ExportError::Setting(format!(
            "a step of {step} gives {n} rows over [{lo}, {hi}]; at most {MAX_ROWS}"
        )));
    }
    let n = n as usize;
    let mut v: Vec<f64> = (0..n).map(|k| lo + step * k as f64).collect();
    v.push(hi);
    Ok(v)
}

/// The fitted tables of every measured axis of `machine`.
pub fn fitted_tables(
    machine: &Machine,
    model: &ErrorModel,
    settings: &GridSettings,
) -> Result<Vec<FittedTable>, ExportError> {
    let mut out = Vec::new();
    for axis in machine.letters().iter() {
        let Some(table) = machine.table(axis) else {
            continue;
        };
        let (Some(&lo), Some(&hi)) = (table.positions.first(), table.positions.last()) else {
            continue;
        };
        let step = if axis.is_rotary() {
            settings.step_deg
        } else {
            settings.step_mm
        };
        let points = grid(lo, hi, step)?;
        let curves: Vec<(String, &crate::nurbs::SmemCurve)> = DIRECTIONS
            .iter()
            .map(|&d| parameter_name(d, axis))
            .filter_map(|n| model.curve(&n).map(|c| (n, c)))
            .collect();
        let mut columns: Vec<String> = curves.iter().map(|(n, _)| n.clone()).collect();
        // The fitted curves' standard uncertainty (formats.md's `u_` columns).
        let uncertain: Vec<&(String, &crate::nurbs::SmemCurve)> = curves
            .iter()
            .filter(|(_, c)| !c.uncertainty().is_empty())
            .collect();
        columns.extend(uncertain.iter().map(|(n, _)| format!("u_{n}")));
        if table.reversal.is_some() {
            columns.push("REVERSAL".into());
        }
        let mut text = String::new();
        let _ = writeln!(
            text,
            "# volcomp export tables: machine {}, axis {}, fitted error curves (SMEM) of {}",
            machine.name,
            axis.letter(),
            table.path.display()
        );
        let _ = writeln!(
            text,
            "# on a grid of {} {} from {} to {}; lengths µm, angles µrad; error = actual - nominal; u_: the fitted curve's standard uncertainty{}",
            position(step),
            if axis.is_rotary() { "deg" } else { "mm" },
            position(lo),
            position(hi),
            if table.reversal.is_some() {
                "; REVERSAL (up minus down) linear between the measured positions"
            } else {
                ""
            }
        );
        if !table.missing.is_empty() {
            let _ = writeln!(text, "# not measured (zero): {}", table.missing.join(", "));
        }
        let _ = writeln!(text, "position,{}", columns.join(","));
        for &p in &points {
            text.push_str(&position(p));
            for (_, c) in &curves {
                let _ = write!(text, ",{:.4}", c.value_at(p) + 0.0);
            }
            for (_, c) in &uncertain {
                let _ = write!(text, ",{:.4}", c.uncertainty_at(p).unwrap_or(0.0) + 0.0);
            }
            if let Some(r) = &table.reversal {
                let _ = write!(text, ",{:.4}", interpolate(&table.positions, r, p) + 0.0);
            }
            text.push('\n');
        }
        out.push(FittedTable {
            axis,
            columns,
            rows: points.len(),
            text,
        });
    }
    if out.is_empty() {
        return Err(ExportError::Nothing(format!(
            "{}: the machine has no error tables: nothing to export",
            machine.source.display()
        )));
    }
    Ok(out)
}
