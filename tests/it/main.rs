//! The one integration-test binary: a module per area.
mod cli;
mod gcode;
mod kinematics;
mod machine;
