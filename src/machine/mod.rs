//! Machine files (TOML) and their measured error tables (CSV), validated, and the
//! fitted error model that turns a pose into the values of every error parameter.
//!
//! Invariants: `machine` reads files but never prints; every error names the file
//! and the key or line.
pub mod table;
