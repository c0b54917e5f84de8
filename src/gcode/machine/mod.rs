//! The machine-state layer: LinuxCNC's interpreter. Executed blocks →
//! [`BlockEvent`](interpret::BlockEvent)s with their motions in machine
//! coordinates.
//!
//! - [`interpret`]: the [`Interpreter`](interpret::Interpreter): reads a
//!   block into a decoded block, checks it, converts it in LinuxCNC's order;
//! - [`modal`]: modal state and the meaning of G/M codes;
//! - [`origin`]: work origins, G92 and the XY rotation (machine =
//!   rot(program + G92) + work origin);
//! - [`tools`]: the tool table and the tool in the spindle;
//! - [`cycles`]: LinuxCNC's canned-cycle expansion;
//! - [`motion`]: one motion (straight, arc) and its planes;
//! - [`spline`]: G5/G5.1/G5.2 curves as straight pieces.
//!
//! Invariants: knows no kinematics and does no file I/O (a `.var` file or a
//! tool table comes in as data); refuses what LinuxCNC refuses, with its
//! messages; a block that fails leaves the state as it was.
pub(crate) mod cycles;
pub(crate) mod interpret;
pub(crate) mod modal;
pub(crate) mod motion;
pub(crate) mod origin;
pub(crate) mod spline;
pub(crate) mod tools;
