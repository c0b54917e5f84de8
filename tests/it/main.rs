//! The one integration-test binary: a module per area.
mod cli;
mod diagnose;
mod fit;
mod gcode;
mod inspection;
mod kinematics;
mod nurbs;
mod toolpath;
