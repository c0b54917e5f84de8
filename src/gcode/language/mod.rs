//! The language layer: parameters, expressions, O-word control flow and
//! subroutine files, run as LinuxCNC runs them; it hands on *executed*
//! blocks, every word a number (see [`flow`]).
//!
//! - [`flow`]: the [`Executor`] (LinuxCNC's skip/seek model: sub/call with
//!   arguments and return values, if/while/do/repeat, break/continue,
//!   subroutine files on a search path) and [`Executed`] blocks;
//! - [`parameters`]: the numbered and named parameter table, `.var` files.
//!
//! Invariants: knows no kinematics and no machine state beyond what the
//! parameter table holds; streams (memory bounded by the call stack, the
//! parameter table and a bounded line cache).
pub(crate) mod flow;
pub(crate) mod parameters;

pub use flow::*;
