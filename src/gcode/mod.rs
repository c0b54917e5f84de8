//! The G-code front end: syntax (lossless parser), meaning (modal interpreter),
//! and the rewriter.
//!
//! Invariants: `gcode` knows nothing about kinematics or machines; every block
//! keeps its byte span, line number and raw text; numbers are f64; syntax and
//! modal state are separate layers.
pub mod motion;

pub use motion::{Feed, Frame, Motion, MotionKind, Plane};
