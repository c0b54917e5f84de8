//! The writers: program text from blocks and their events.
//!
//! - [`rewrite`]: the [`Rewriter`](rewrite::Rewriter) and
//!   [`rewrite_stream`](rewrite::rewrite_stream): unchanged blocks byte for
//!   byte, changed blocks word by word, splits.
//!
//! - [`flat`]: canned cycles and splines written flat, move by move
//!   ([`Rewriter::emit_flat`](rewrite::Rewriter::emit_flat)).
//!
//! - [`format`]: numbers with fixed decimals, as printed.
//!
//! Invariant: a block is written byte for byte unless something it must say
//! changes.
pub(crate) mod flat;
pub(crate) mod format;
pub(crate) mod rewrite;
