//! The G-code front end: syntax (lossless parser), meaning (modal interpreter),
//! and the rewriter.
//!
//! Invariants: `gcode` knows nothing about kinematics or machines; every block
//! keeps its byte span, line number and raw text; numbers are f64; syntax and
//! modal state are separate layers. Every line of the input is one [`Block`]
//! (blank and comment lines included), so block index = line − 1. No input
//! makes any function here panic (proptested over arbitrary bytes).
//!
//! Layers:
//! - [`block`]: the syntax of one line ([`Block`], [`Word`]), lossless;
//! - [`parser`]: one line's bytes → words (nom; `grammar/gcode.ebnf` is the
//!   exact grammar);
//! - [`reader`]: streaming [`BlockReader`] over any `BufRead` (reuses its
//!   buffers: memory does not grow with the program), and [`parse_program`];
//! - [`modal`]: modal state and the meaning of G/M codes;
//! - [`interpret`]: [`Interpreter`] → one [`BlockEvent`] per block (with the
//!   [`Motion`], absolute, mm/deg, in the block's frame, and its duration); the
//!   module docs list the decisions (initial position, G28, frames, G93);
//! - [`rewrite`]: [`Rewriter`] / [`rewrite_stream`] → program text, unchanged
//!   blocks byte for byte, changed blocks word by word, splits;
//! - [`summary`]: what `volcomp check` reports ([`ProgramSummary`]);
//! - [`tools`]: LinuxCNC's tool table and the tool in the spindle
//!   ([`ToolTable`], [`ToolInUse`], carried by every [`BlockEvent`]);
//! - [`error`]: located errors rendered like rustc ([`GcodeError`]).
//!
//! Typical use (a compensator):
//!
//! ```
//! use volcomp::gcode::{InterpretOptions, Program, RewriteOptions, rewrite_stream};
//! let program = Program::from_text("G21 G90 G93\nN10 G1 X10 Y0 Z0 A0 C0 F2.\n", "p.nc");
//! let mut out = Vec::new();
//! let run = program.run(InterpretOptions::default());
//! let stats = rewrite_stream(run, &mut out, RewriteOptions::default(), |_block, event, via| {
//!         let m = event.motion.as_ref()?;
//!         via.push(m.start.lerp(&m.end, 0.5)); // split in two
//!         Some(m.end)                           // keep the end
//!     }).unwrap();
//! assert_eq!(stats.pieces, 1);
//! assert_eq!(String::from_utf8(out).unwrap(),
//!            "G21 G90 G93\nG1 X5.0000 F4.000000\nN10 G1 X10 Y0 Z0 A0 C0 F4.000000\n");
//! ```
pub mod block;
pub mod cycles;
pub mod error;
pub mod execution;
pub mod expression;
pub mod interpret;
pub mod language;
pub mod modal;
pub mod motion;
pub mod origin;
pub mod parameters;
pub mod parser;
pub mod reader;
pub mod rewrite;
pub mod spline;
pub mod summary;
pub mod tools;

pub use block::{Block, Keyword, KeywordWord, LineEnding, Word};
pub use error::{ErrorKind, GcodeError};
pub use execution::{Execution, Program, ProgramSetup};
pub use interpret::{
    BlockEvent, InterpretOptions, Interpreter, Warning, WarningKind, duration_from_lengths,
    duration_min, interpret_program,
};
pub use language::{Executed, LanguageOptions, ProgramInput};
pub use modal::{CutterComp, Distance, ModalState, MotionMode, Units};
pub use motion::{Feed, Frame, Motion, MotionKind, Plane};
pub use origin::Origin;
pub use parameters::Parameters;
pub use parser::{parse_block, parse_line};
pub use reader::{BlockReader, ReadOptions, parse_program, parse_program_bytes, print_program};
pub use rewrite::{
    Emitted, RewriteError, RewriteOptions, RewriteStats, Rewriter, Target, rewrite_stream,
};
pub use summary::ProgramSummary;
pub use tools::{CutterShape, ToolEntry, ToolInUse, ToolTable, ToolTableError};
