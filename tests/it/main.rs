//! The one integration-test binary: a module per area.
mod cli;
mod diagnose;
mod gcode;
mod inspection;
mod kinematics;
mod toolpath;
