//! The one integration-test binary: a module per area.
mod cli;
mod kinematics;
mod machine;
