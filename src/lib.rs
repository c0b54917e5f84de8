//! volcomp: volumetric error compensation for five-axis machine tools.
//!
//! See `ARCHITECTURE.md` for the pipeline and the invariants of each module.
#![forbid(unsafe_code)]

pub mod axes;
pub mod cli;
pub mod compensate;
pub mod diagnose;
pub mod diff;
pub mod export;
pub mod gcode;
pub mod inspection;
pub mod io;
pub mod kinematics;
pub mod laser;
pub mod machine;
pub mod nurbs;
pub mod predict;
pub mod report;
pub mod sample;
pub mod toolpath;
pub mod vec3;
pub mod warnings;
