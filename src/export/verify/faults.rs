//! What `verify` reports: each fault with its check, its file and a message, collected rather
//! than stopping at the first.

use serde::Serialize;

/// One thing wrong with a package.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fault {
    /// The kind of check: manifest, special, missing, unlisted, hash, mesh, orientation, quality,
    /// atlas, scene.
    pub check: &'static str,
    /// The file it is about, relative to the package.
    pub file: String,
    pub message: String,
}

/// Collects faults.
#[derive(Default)]
pub(super) struct Faults(pub(super) Vec<Fault>);

impl Faults {
    pub(super) fn add(&mut self, check: &'static str, file: &str, message: impl Into<String>) {
        self.0.push(Fault {
            check,
            file: file.to_string(),
            message: message.into(),
        });
    }
}
