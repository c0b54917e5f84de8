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
pub(crate) mod residual;
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

pub use crate::machine::reversal::interpolate;

/// The positioning error of one axis as fitted: the axis's positioning
/// parameter's SMEM curve and, where the machine has one, its reversal (the
/// error model's: the table's `REVERSAL`, linear between the table's positions,
/// a per-position measurement, not smoothed; or the `[reversal]` constant).
pub struct Positioning<'a> {
    /// The axis.
    pub axis: Axis,
    /// `EXX`, `EYY`, …
    pub parameter: String,
    curve: &'a SmemCurve,
    table: &'a ErrorTable,
    model: &'a ErrorModel,
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
            model,
            range,
        })
    }

    /// Where the axis's reversal comes from (`"REVERSAL column"` or
    /// `"[reversal]"`), `None` without one.
    pub fn reversal_source(&self) -> Option<&'static str> {
        self.model
            .reversal_axes()
            .into_iter()
            .find(|(axis, _)| *axis == self.axis)
            .map(|(_, source)| source)
    }

    /// Whether the axis has a reversal (the table's `REVERSAL` or `[reversal]`).
    pub fn has_reversal(&self) -> bool {
        self.reversal_source().is_some()
    }

    /// The table's positions.
    pub fn positions(&self) -> &[f64] {
        &self.table.positions
    }

    /// E(p), the fitted positioning error (µm or µrad).
    pub fn error(&self, p: f64) -> f64 {
        self.curve.value_at(p)
    }

    /// REVERSAL(p) (0 without one), as the error model applies it.
    pub fn reversal(&self, p: f64) -> f64 {
        self.model.reversal_at(self.axis, p).unwrap_or(0.0)
    }

    /// The standard uncertainty of E at `p` (the fitted curve's), when the
    /// model carries one.
    pub fn uncertainty(&self, p: f64) -> Option<f64> {
        self.curve.uncertainty_at(p)
    }

    /// The smallest and largest [`Self::uncertainty`] at `positions`.
    pub fn uncertainty_range(&self, positions: &[f64]) -> Option<(f64, f64)> {
        let u: Vec<f64> = positions
            .iter()
            .filter_map(|&p| self.uncertainty(p))
            .collect();
        (!u.is_empty()).then(|| {
            u.iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)))
        })
    }

    /// Whether the table gives the uncertainty of its positioning column (`u_`).
    pub fn table_has_uncertainty(&self) -> bool {
        self.table
            .column(&self.parameter)
            .is_some_and(|c| c.uncertainty.is_some())
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
