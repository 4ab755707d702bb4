//! What can stop a report from being written: a slice overlay that cannot be encoded, or a
//! metrics document that does not hold what `run` writes.

/// A report could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
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
