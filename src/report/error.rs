//! What can stop a report from being written: a chart or an image that cannot be drawn, or a
//! metrics document that does not hold what `run` writes.

use super::plot::PlotError;

/// A report could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error("cannot encode the slice overlay {figure:?} as PNG: {source}")]
    Png {
        figure: String,
        #[source]
        source: png::EncodingError,
    },
    #[error("case {case:?}: metrics field {field:?} is not {expected}: {message}")]
    Metrics {
        case: String,
        field: String,
        expected: &'static str,
        message: String,
    },
}
