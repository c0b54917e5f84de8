//! The one integration-test binary: a module per area.
mod cli;
mod fit;
mod gcode;
mod kinematics;
mod nurbs;
