//! Reports a person reads to accept or reject a case or a cohort: charts (SVG), slice overlays
//! (PNG) and the self-contained HTML page that holds them.

pub mod html;
pub mod overlay;
pub mod plot;
