//! The syntax layer: bytes → blocks, with no meaning. A block keeps its byte
//! span, line number, raw text and line ending; every word its text range,
//! decimal count and, for a computed word (`X[#1+2]`), its expression tree.
//! Assignments and O-word lines are parsed, never evaluated.
//!
//! - [`block`]: the syntax of one line ([`Block`](block::Block),
//!   [`Word`](block::Word)), lossless;
//! - [`parser`]: one line's bytes → words (nom; `grammar/gcode.ebnf` is the
//!   exact grammar);
//! - [`expression`]: the expressions of RS274NGC (`[#1 + 2]`, functions,
//!   comparisons), parsed here and evaluated by the language layer;
//! - [`reader`]: streaming [`BlockReader`](reader::BlockReader) over any
//!   `BufRead` (it reuses its buffers: memory does not grow with the program).
//!
//! Invariants: knows no parameter values, no modal state, no machine; no
//! input makes it panic.
pub(crate) mod block;
pub(crate) mod expression;
pub(crate) mod parser;
pub(crate) mod reader;
