//! Reports: SVG charts and self-contained HTML pages (no I/O here).
pub(crate) mod diagnose_html;
pub(crate) mod error_map_svg;
pub(crate) mod fit_plot;
pub(crate) mod predict_html;
pub(crate) mod svg;
