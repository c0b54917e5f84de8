//! The SMEM (He et al. 2016, §2–3): NURBS curves and surfaces, least-squares
//! fitting, knot placement (UKM, EPM, LAM, the improved GA, exhaustive search and
//! volcomp's own optimiser) and the adaptive fit of one error parameter.
//!
//! Layout by concept: `basis` (eq. 2), `knot_vector` (eq. 3), `curve` (eq. 1),
//! `parameterization` (eq. 11–12), `least_squares` (eq. 5–10), `knot_placement`
//! (eq. 13–15), `knot_grid` (the candidate grid the searches share), `genetic`
//! (§3.2), `exhaustive` (Table 4's combination search), `optimise` (method `best`), `problem` (the shared objective), `lookup` (the
//! inversion `position → value`), `smem` (the adaptive loop, Fig. 8).
pub(crate) mod banded;
pub(crate) mod basis;
pub(crate) mod curve;
pub(crate) mod exhaustive;
pub(crate) mod fit_error;
pub(crate) mod genetic;
pub(crate) mod knot_grid;
pub(crate) mod knot_placement;
pub(crate) mod knot_vector;
pub(crate) mod least_squares;
pub(crate) mod lookup;
pub(crate) mod model_file;
pub(crate) mod optimise;
pub(crate) mod parameterization;
pub(crate) mod problem;
pub(crate) mod smem;
pub(crate) mod smoothing;
pub(crate) mod surface;
#[cfg(any(test, feature = "testkit"))]
pub mod synthetic;

pub use basis::{basis_funs, find_span};
pub use curve::NurbsCurve;
pub use genetic::GaSettings;
pub use knot_grid::combinations;
pub use knot_placement::uniform;
pub use knot_vector::{clamped, greville};
pub use least_squares::fit_control_points;
pub use model_file::{ParameterFit, SmemModelFile, fnv1a64};
pub use optimise::{best_knots, default_segments, minimax_knots};
pub use parameterization::Parameterization;
pub use problem::FitProblem;
pub use smem::{
    FitError, FitOptions, FitStats, KnotMethod, ParameterKind, Selection, SmemCurve, SmemCurveData,
    WORK_LIMIT, WORK_LIMIT_BELOW_NOISE, default_work_limit, fit_parameter,
    fit_parameter_with_uncertainty,
};
pub use surface::{NurbsSurface, SurfaceError, SurfaceFitOptions, fit_surface};
