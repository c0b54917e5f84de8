//! Machine files (TOML) and their measured error tables (CSV), validated, and the
//! fitted error model that turns a pose into the values of every error parameter.
//!
//! Invariants: `machine` reads files but never prints; every error names the file
//! and the key or line.
pub(crate) mod definition;
pub(crate) mod error_map;
pub(crate) mod error_model;
pub(crate) mod model_cache;
pub mod physical_ranges;
pub(crate) mod resampled;
pub(crate) mod reversal;
#[cfg(any(test, feature = "testkit"))]
pub mod synthetic;
pub(crate) mod table;
pub(crate) mod tool_models;
pub(crate) mod update;

pub use definition::{
    DEFAULT_RAPID_MM_PER_MIN, ExtrapolationPolicy, KinematicsType, Limits, LoadOptions, Machine,
    MachineError, Tool,
};
pub use error_model::{
    Contribution, ErrorModel, LookupError, ModelError, ModelOptions, ModelUncertainty,
};
pub use model_cache::{CacheOutcome, CacheReport, ModelCache};
pub use reversal::{Approach, AxisReversal, Direction, DirectionTracker};
pub use table::ErrorTable;
pub use tool_models::{ToolModels, kinematics_with};
pub use update::edit_machine_text;
