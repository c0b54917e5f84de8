//! Heidenhain TNC Klartext programs (dialects.md "Heidenhain TNC
//! (Klartext)"): their syntax, language and machine state, feeding the same
//! seam as LinuxCNC's programs.
pub(crate) mod language;
pub(crate) mod syntax;
