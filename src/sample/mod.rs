//! Bundled sample parts: deterministic generators of programs and inspection plans.
pub mod flank;
pub mod saddle;
