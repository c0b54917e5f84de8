//! The one integration-test binary: a module per area.
mod cli;
mod compensate;
mod diagnose;
mod diff;
mod gcode;
mod inspection;
mod kinematics;
mod predict;
mod sample;
mod toolpath;
