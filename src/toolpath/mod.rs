//! The tool path in both frames: blocks sampled at ≤ 0.5 mm, joints and part
//! coordinates of every path point, nearest path point of a plan point, and the
//! context (time, direction, speed, curvature, …) that effects depend on.
//!
//! Invariant: this is where programs meet kinematics for reading; it writes nothing.
pub(crate) mod contact;
pub(crate) mod context;
pub(crate) mod cut;
pub(crate) mod orientation;
pub(crate) mod plan_match;
pub(crate) mod pose;
pub(crate) mod program;
pub(crate) mod walk;
pub(crate) mod work_origin;
pub(crate) mod workpiece;

pub use context::{PointContext, last_time_min};
pub use cut::{CutError, CutOptions, ProbeTool, probe_context};
pub use orientation::ChainOrientation;
pub use plan_match::{PlanMatch, PlanMatcher};
pub use pose::{joints_of, pose_of};
pub use program::{WalkSummary, walk_program, walk_program_tracking};
pub use walk::{PathPoint, PathWalker, WalkOptions};
pub use workpiece::{WorkpieceFrame, WorkpieceTarget};
