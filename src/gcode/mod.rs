//! The G-code front end: syntax (lossless parser), meaning (modal interpreter),
//! and the rewriter.
//!
//! Invariants: `gcode` knows nothing about kinematics or machines; every block
//! keeps its byte span, line number and raw text; numbers are f64; syntax and
//! modal state are separate layers. Every line of the input is one [`Block`]
//! (blank and comment lines included), so block index = line − 1. No input
//! makes any function here panic (proptested over arbitrary bytes).
//!
//! Layers (a folder each; a dialect is a syntax, and where it differs a
//! language, feeding the same machine-state layer):
//! - `syntax`: bytes → [`Block`]s (`block`, `parser`, `expression`,
//!   `reader`: the streaming [`BlockReader`] and [`parse_program`]); no
//!   meaning;
//! - `language`: parameters ([`Parameters`]), O-word control flow,
//!   subroutine files → executed blocks ([`Executed`]);
//! - `machine`: LinuxCNC's interpreter ([`Interpreter`] → one
//!   [`BlockEvent`] per block, with what it moves ([`Moves`]: [`Motion`]s,
//!   absolute, mm/deg, in the block's frame), its duration, [`ToolInUse`]);
//!   modal state, origins, tools, canned cycles, splines;
//! - `write`: [`Rewriter`] / [`rewrite_stream`] → program text, unchanged
//!   blocks byte for byte, changed blocks word by word, splits, flat cycles.
//!
//! Across the layers: `execution` joins them ([`Program`] → [`Execution`],
//! the one seam every command reads programs through); `summary`: what
//! `volcomp check` reports ([`ProgramSummary`]); `error`: located errors
//! rendered like rustc ([`GcodeError`]).
//!
//! Typical use (a compensator):
//!
//! ```
//! use volcomp::gcode::{InterpretOptions, Program, RewriteOptions, rewrite_stream};
//! let program = Program::from_text("G21 G90 G93\nN10 G1 X10 Y0 Z0 A0 C0 F2.\n", "p.nc");
//! let mut out = Vec::new();
//! let run = program.run(InterpretOptions::default());
//! let stats = rewrite_stream(run, &mut out, RewriteOptions::default(), |_block, event, via| {
//!         let m = event.motion()?;
//!         via.push(m.start.lerp(&m.end, 0.5)); // split in two
//!         Some(m.end)                           // keep the end
//!     }).unwrap();
//! assert_eq!(stats.pieces, 1);
//! assert_eq!(String::from_utf8(out).unwrap(),
//!            "G21 G90 G93\nG1 X5.0000 F4.000000\nN10 G1 X10 Y0 Z0 A0 C0 F4.000000\n");
//! ```
pub(crate) mod contour_corners;
pub(crate) mod dialect;
pub(crate) mod error;
pub(crate) mod execution;
pub(crate) mod front;
pub(crate) mod heidenhain;
pub(crate) mod language;
pub(crate) mod machine;
pub(crate) mod sinumerik;
pub(crate) mod streamed_program;
pub(crate) mod summary;
pub(crate) mod syntax;
pub(crate) mod write;

// The modules under their names before the layers had folders (code outside
// `gcode` names them).
pub(crate) use language::parameters;
pub(crate) use machine::{interpret, motion};
pub(crate) use syntax::block;

pub use block::{Block, Keyword, KeywordWord, LineEnding, ORIENTATION_VECTOR_LETTERS, Word};
pub use dialect::{Branch, Dialect, DialectChoice, OrientationSolver, detect as detect_dialect};
pub use error::{ErrorKind, GcodeError};
pub use execution::{Execution, Program, ProgramSetup, normalise_system_variable};
pub(crate) use heidenhain::write::KlartextStamp;
pub use interpret::{
    BlockEvent, InterpretOptions, Interpreter, Moves, Warning, WarningKind, duration_from_lengths,
    duration_min, interpret_program,
};
pub use language::{Executed, LanguageOptions, ProgramInput};
pub use machine::modal::{CutterComp, Distance, ModalState, MotionMode, Units};
pub use machine::origin::{FrameTransform, Origin};
pub use machine::tools::{CutterShape, NamedTool, ToolEntry, ToolInUse, ToolTable, ToolTableError};
pub use motion::{Feed, Frame, Motion, MotionKind, Plane, Pose};
pub use parameters::Parameters;
pub use summary::ProgramSummary;
pub use syntax::parser::{parse_block, parse_line};
pub use syntax::reader::{
    BlockReader, ReadOptions, parse_program, parse_program_bytes, print_program,
};
pub use write::rewrite::{
    Emitted, RewriteError, RewriteOptions, RewriteStats, Rewriter, Target, rewrite_stream,
};
