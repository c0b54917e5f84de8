//! Machine files (TOML) and their measured error tables (CSV), validated, and the
//! fitted error model that turns a pose into the values of every error parameter.
//!
//! Invariants: `machine` reads files but never prints; every error names the file
//! and the key or line.
pub mod definition;
pub mod error_map;
pub mod error_model;
pub mod model_cache;
pub mod resampled;
pub mod reversal;
pub mod synthetic;
pub mod table;
pub mod tool_models;
pub mod update;

pub use definition::{
    DEFAULT_RAPID_MM_PER_MIN, ExtrapolationPolicy, KinematicsType, Limits, LoadOptions, Machine,
    MachineError, Tool,
};
pub use error_model::{
    Contribution, ErrorModel, LookupError, ModelError, ModelOptions, ModelUncertainty,
};
pub use reversal::{Approach, AxisReversal, Direction, DirectionTracker};
pub use model_cache::{CacheOutcome, CacheReport, ModelCache};
pub use tool_models::ToolModels;
