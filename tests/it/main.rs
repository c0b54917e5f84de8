//! The one integration-test binary: a module per area.
mod cli;
mod compensate;
mod diagnose;
mod diff;
mod fit;
mod gcode;
mod inspection;
mod kinematics;
mod machine;
mod nurbs;
mod predict;
mod programs;
mod rs274;
mod safety;
mod sample;
mod support;
mod toolpath;
