//! The SMEM (He et al. 2016, §2–3): NURBS curves and surfaces, least-squares
//! fitting, knot placement (UKM, EPM, LAM, the improved GA, exhaustive search and
//! volcomp's own optimiser) and the adaptive fit of one error parameter.
//!
//! Layout by concept: `basis` (eq. 2), `knot_vector` (eq. 3), `curve` (eq. 1),
//! `parameterization` (eq. 11–12), `least_squares` (eq. 5–10), `knot_placement`
//! (eq. 13–15), `knot_grid` (the candidate grid the searches share), `genetic`
//! (§3.2), `exhaustive` (Table 4's combination search), `optimise` (method `best`), `problem` (the shared objective), `lookup` (the
//! inversion `position → value`), `smem` (the adaptive loop, Fig. 8).
pub mod banded;
pub mod basis;
pub mod curve;
pub mod exhaustive;
pub mod fit_error;
pub mod genetic;
pub mod knot_grid;
pub mod knot_placement;
pub mod knot_vector;
pub mod least_squares;
pub mod lookup;
pub mod model_file;
pub mod optimise;
pub mod parameterization;
pub mod plot;
pub mod problem;
pub mod smem;
pub mod smoothing;
pub mod surface;
pub mod synthetic;

pub use curve::NurbsCurve;
pub use genetic::GaSettings;
pub use model_file::{ParameterFit, SmemModelFile, fnv1a64};
pub use parameterization::Parameterization;
pub use smem::{
    FitError, FitOptions, FitStats, KnotMethod, ParameterKind, Selection, SmemCurve, SmemCurveData,
    fit_parameter,
};
pub use surface::{NurbsSurface, SurfaceError, SurfaceFitOptions, fit_surface};
