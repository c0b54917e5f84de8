//! Controller files out: the fitted error model as a controller reads it.
//!
//! `linuxcnc`: LinuxCNC's `COMP_FILE` per linear joint (nominal, forward,
//! reverse triplets, as `usrmotLoadComp` reads them) and the trt kinematics
//! modules' pivot parameters corrected by the identified location errors;
//! `tables`: every fitted error table on a grid the user chooses, as a CSV any
//! controller's compensation can be transcribed from.
//!
//! Invariants: pure text building from a loaded machine and its model; no I/O,
//! nothing printed.
pub(crate) mod linuxcnc;
pub(crate) mod tables;

use crate::axes::Axis;
use crate::machine::table::ErrorTable;
use crate::machine::{ErrorModel, Machine};
use crate::nurbs::SmemCurve;

/// Why an export cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The machine has nothing this export can write.
    #[error("{0}")]
    Nothing(String),
    /// A setting out of range.
    #[error("{0}")]
    Setting(String),
}

/// Linear interpolation of `values` over `positions` at `p` (ends held).
pub fn interpolate(positions: &[f64], values: &[f64], p: f64) -> f64 {
    let n = positions.len();
    if n == 0 {
        return 0.0;
    }
    if p <= positions[0] {
        return values[0];
    }
    if p >= positions[n - 1] {
        return values[n - 1];
    }
    let k = positions.partition_point(|x| *x <= p).clamp(1, n - 1);
    let (x0, x1) = (positions[k - 1], positions[k]);
    let t = (p - x0) / (x1 - x0);
    values[k - 1] + t * (values[k] - values[k - 1])
}

/// The positioning error of one axis as fitted: the axis's positioning
/// parameter's SMEM curve and, where the table has one, its `REVERSAL`
/// (linear between the table's positions: a reversal is a per-position
/// measurement, not smoothed).
pub struct Positioning<'a> {
    /// The axis.
    pub axis: Axis,
    /// `EXX`, `EYY`, …
    pub parameter: String,
    curve: &'a SmemCurve,
    table: &'a ErrorTable,
    /// The table's first and last position.
    pub range: [f64; 2],
}

impl<'a> Positioning<'a> {
    /// `None` when the axis has no fitted positioning parameter.
    pub fn of(machine: &'a Machine, model: &'a ErrorModel, axis: Axis) -> Option<Positioning<'a>> {
        let parameter = crate::laser::positioning_parameter(axis);
        let table = machine.table(axis)?;
        let curve = model.curve(&parameter)?;
        let range = [*table.positions.first()?, *table.positions.last()?];
        Some(Positioning {
            axis,
            parameter,
            curve,
            table,
            range,
        })
    }

    /// Whether the table carries `REVERSAL`.
    pub fn has_reversal(&self) -> bool {
        self.table.reversal.is_some()
    }

    /// The table's positions.
    pub fn positions(&self) -> &[f64] {
        &self.table.positions
    }

    /// E(p), the fitted positioning error (µm or µrad).
    pub fn error(&self, p: f64) -> f64 {
        self.curve.value_at(p)
    }

    /// REVERSAL(p) (0 without one).
    pub fn reversal(&self, p: f64) -> f64 {
        self.table
            .reversal
            .as_ref()
            .map_or(0.0, |r| interpolate(&self.table.positions, r, p))
    }

    /// The error approaching `p` moving in the positive direction: E + REVERSAL/2.
    pub fn forward(&self, p: f64) -> f64 {
        self.error(p) + 0.5 * self.reversal(p)
    }

    /// The error approaching `p` moving in the negative direction: E − REVERSAL/2.
    pub fn reverse(&self, p: f64) -> f64 {
        self.error(p) - 0.5 * self.reversal(p)
    }
}
