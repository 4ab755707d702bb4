//! Reports a person reads to accept or reject a case or a cohort: charts (SVG), slice overlays
//! (PNG) and the self-contained HTML page that holds them.

pub mod axis;
pub mod case;
pub mod cohort;
pub mod error;
pub mod html;
pub mod mechanics_plots;
pub mod metrics;
pub mod overlay;
pub mod plot;
pub mod slices;

pub use case::{Accuracy, CaseReportInput, Proposed, case_report_html};
pub use cohort::{CohortEntry, CohortReport, cohort_report};
pub use error::ReportError;
