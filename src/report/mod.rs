//! Reports: SVG charts and self-contained HTML pages (no I/O here).
pub(crate) mod svg;
