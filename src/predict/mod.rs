//! `predict`: the predicted deviation of every plan point (formats.md: `n · e` at
//! the path point that cut it) and the profile error of the part, or, without a
//! plan, the volumetric error along the path block by block.
pub(crate) mod run;

pub use run::{
    PathErrors, PathReportStream, PathSummary, PredictError, predict_path, predict_plan,
};

use serde::Serialize;

/// One plan point in the predict report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictedPoint {
    /// The plan point's id.
    pub id: String,
    /// Predicted deviation `n · e`, µm (absent when not cut).
    pub deviation_um: Option<f64>,
    /// Whether a path point cut it (its contact point within `match_distance_mm`).
    pub cut: bool,
    /// Program line of the block that cut the point.
    pub line: Option<usize>,
    /// The tool that cut it (0: the default tool, the machine file's `[tool]`).
    pub tool: Option<u32>,
    /// Plan point and normal (part coordinates).
    pub point: [f64; 3],
    /// Unit outward normal of the plan point (part coordinates).
    pub normal: [f64; 3],
    /// Volumetric error at the cutting path point, µm, part coordinates.
    pub e_um: Option<[f64; 3]>,
    /// Distance of the contact point from the plan point, mm.
    pub distance_mm: Option<f64>,
    /// `n·e + n·(c − p)`: the deviation including where the program's own path
    /// puts the nominal contact point `c` relative to the plan point `p` (µm). Equal
    /// to `deviation_um` (up to the program's rounding) when the path passes through
    /// the plan points; for a compensated program it is what the part would measure.
    pub deviation_with_path_um: Option<f64>,
    /// Standard uncertainty of `deviation_um` from the model's own noise (table
    /// noise and fit; extension: docs/extensions.md). Absent when not cut or
    /// the model carries no uncertainties.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deviation_u_um: Option<f64>,
}

/// Error along the path at the end of one block (no plan).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlockError {
    /// Program line of the block.
    pub line: usize,
    /// The tool in the spindle (0: the default tool).
    pub tool: u32,
    /// Volumetric error `e` at the block's end, µm, part coordinates.
    pub e_um: [f64; 3],
    /// `|e|`, µm.
    pub norm_um: f64,
    /// Tool-axis error, µrad, part coordinates.
    pub axis_urad: [f64; 3],
}

/// The `predict --report` JSON (formats.md fields first; more follow).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PredictReport {
    /// Profile error `2 · max |deviation|` over the cut points, µm.
    pub profile_um: f64,
    /// Range `max − min` of the deviations of the cut points, µm.
    pub range_um: f64,
    /// Standard uncertainty of `profile_um` (twice that of the deviation that
    /// sets it; extension), absent when the model carries no uncertainties.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub profile_u_um: Option<f64>,
    /// RMS of the points' `deviation_u_um`: how much of the prediction is
    /// model noise, on average (extension).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_deviation_u_um: Option<f64>,
    /// Every plan point, in plan order.
    pub points: Vec<PredictedPoint>,
    /// Number of plan points.
    pub points_total: usize,
    /// Number of plan points cut.
    pub points_cut: usize,
    /// Profile and range of `deviation_with_path_um` (extension: see docs/extensions.md).
    pub profile_with_path_um: f64,
    /// Range of `deviation_with_path_um` over the cut points, µm.
    pub range_with_path_um: f64,
    /// Largest |n·(c − p)| over the cut points, µm.
    pub max_path_offset_um: f64,
    /// A plan point farther than this from every path point is not cut, mm.
    pub match_distance_mm: f64,
    /// Without a plan: the error at every block end, and its maximum and RMS.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<BlockError>,
    /// Largest `|e|` along the path, µm.
    pub max_error_um: f64,
    /// RMS of `|e|` along the path, µm.
    pub rms_error_um: f64,
    /// Wall-clock time of the run, seconds.
    pub seconds: f64,
    /// The program carries volcomp's provenance stamp: it is already
    /// compensated (extension: docs/extensions.md). Set by the command line.
    pub compensated: bool,
    /// That stamp, when there is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stamp: Option<crate::stamp::Stamp>,
    /// The warnings of the run (`crate::warnings`; the command fills it).
    pub warnings: Vec<crate::warnings::WarningGroup>,
}

impl PredictedPoint {
    /// The deviation a report shows first: what the part would measure,
    /// `deviation_with_path_um`, for a compensated program; `deviation_um`
    /// (formats.md) otherwise.
    pub fn shown_um(&self, compensated: bool) -> Option<f64> {
        if compensated {
            self.deviation_with_path_um
        } else {
            self.deviation_um
        }
    }
}
