//! The one integration-test binary: a module per area.
// Tests index arrays as the algorithms they check do, name tuple-heavy
// fixtures inline, and hold the library's located errors (160 bytes) in
// closures' results.
#![allow(
    clippy::needless_range_loop,
    clippy::type_complexity,
    clippy::result_large_err
)]
mod bad_inputs;
mod chain;
mod cli;
mod closed_loop;
mod compensate;
mod diagnose;
mod diff;
mod export;
mod fit;
mod gcode;
mod heidenhain;
mod heidenhain_cycles;
mod inspection;
mod kinematics;
mod laser;
mod linuxcnc;
mod machine;
mod machines;
mod nurbs;
mod outputs;
mod predict;
mod programs;
mod readme;
mod report_pages;
mod reversal;
mod rs274;
mod safety;
mod sample;
mod sinumerik;
mod sinumerik_corners;
mod sinumerik_differential;
mod sinumerik_five_axis;
mod sinumerik_splines;
mod sinumerik_system_variables;
mod support;
mod toolpath;
mod tools;
mod work_frame;
mod workpiece_targets;
