//! volcomp: volumetric error compensation for five-axis machine tools.
//!
//! The library behind the `volcomp` command line. Its front door:
//!
//! - [`machine`]: a machine file, its error tables and the fitted SMEM error
//!   model ([`machine::Machine`], [`machine::ErrorModel`]);
//! - [`nurbs`]: the SMEM curves themselves (cubic NURBS fitted by least squares,
//!   knots and weights optimised);
//! - [`kinematics`]: any serial five-axis chain, forward and inverse, with the
//!   homogeneous-transform error model;
//! - [`gcode`]: the LinuxCNC-dialect reader (syntax, language, machine state)
//!   and the byte-preserving rewriter;
//! - [`compensate`], [`predict`], [`diff`], [`diagnose`]: the commands' engines;
//! - [`inspection`], [`laser`], [`export`]: measurement data in, controller
//!   data out.
//!
//! ```no_run
//! use volcomp::machine::{ErrorModel, Machine, ModelOptions};
//!
//! let machine = Machine::load("machines/ref-trt.toml".as_ref())?;
//! let model = ErrorModel::from_machine(&machine, &ModelOptions::default())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! See `ARCHITECTURE.md` for the pipeline and the invariants of each module.
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// A located error carries its file, line, column and the line's text (what
// the message shows), so `GcodeError` is 160 bytes; errors are the cold path
// and boxing them would put an allocation on every failed lookup instead.
#![allow(clippy::result_large_err)]
// The NURBS and band-matrix algorithms are written with indices as their
// references (Piegl & Tiller) write them; `!(a < b)` is meant where a NaN
// must take the other branch.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod axes;
mod cli;
pub mod compensate;
pub mod diagnose;
pub mod diff;
pub mod export;
pub mod gcode;
pub mod inspection;
pub(crate) mod io;
pub mod kinematics;
pub mod laser;
pub mod machine;
pub mod nurbs;
pub mod predict;
pub mod progress;
pub(crate) mod report;
pub(crate) mod sample;
pub mod stamp;
pub mod toolpath;
pub(crate) mod vec3;
pub(crate) mod warnings;

/// Runs the `volcomp` command line on the process's arguments and returns its
/// exit code (0 success, 1 an input or output error, 2 a usage error, 141 a
/// closed standard output). This is
/// the whole of the `volcomp` binary; the command line is not library API.
pub fn run_command_line() -> i32 {
    cli::main()
}

/// The command line's definition: every command, option and help text, as
/// `volcomp --help` shows them; for the tests and tools that walk it (which
/// options write files, completions, manual pages).
pub fn command_line() -> clap::Command {
    <cli::Cli as clap::CommandFactory>::command()
}
