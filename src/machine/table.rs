//! Measured component-error tables (formats.md "Error table"). Under construction.
