//! The G-code front end: syntax (lossless parser), meaning (modal interpreter),
//! and the rewriter.
//!
//! Invariants: `gcode` knows nothing about kinematics or machines; every block
//! keeps its byte span, line number and raw text; numbers are f64; syntax and
//! modal state are separate layers.
//!
//! Layers:
//! - [`block`]: the syntax of one line ([`Block`], [`Word`]), lossless;
//! - [`parser`]: one line's bytes → words (nom; grammar/gcode.ebnf);
//! - [`reader`]: streaming [`BlockReader`] over any `BufRead`, and [`parse_program`];
//! - [`modal`]: modal state and the meaning of G/M codes;
//! - [`interpret`]: [`Interpreter`] → one [`BlockEvent`] per block (with the [`Motion`]);
//! - [`rewrite`]: [`Rewriter`] → program text, unchanged blocks byte for byte;
//! - [`summary`]: what `volcomp check` reports ([`ProgramSummary`]);
//! - [`error`]: located errors rendered like rustc ([`GcodeError`]).
pub mod block;
pub mod error;
pub mod interpret;
pub mod modal;
pub mod motion;
pub mod parser;
pub mod reader;
pub mod rewrite;
pub mod summary;

pub use block::{Block, Keyword, KeywordWord, LineEnding, Word};
pub use error::{ErrorKind, GcodeError};
pub use interpret::{
    BlockEvent, InterpretOptions, Interpreter, Warning, WarningKind, duration_min,
    interpret_program,
};
pub use modal::{CutterComp, Distance, ModalState, MotionMode, Units};
pub use motion::{Feed, Frame, Motion, MotionKind, Plane};
pub use parser::{parse_block, parse_line};
pub use reader::{BlockReader, ReadOptions, parse_program, parse_program_bytes, print_program};
pub use rewrite::{RewriteError, RewriteOptions, Rewriter, Target};
pub use summary::ProgramSummary;
