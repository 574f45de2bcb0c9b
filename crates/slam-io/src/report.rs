//! Diagnostics readers return beside the data: what was read but not turned into data.

use serde::Serialize;
use std::path::PathBuf;

/// One input item a reader kept out of the dataset, with where it was and why. Readers never
/// drop data silently: every such item is listed (or, for bulk categories like another
/// robot's barcodes, counted) in the reader's report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Skipped {
    /// The file.
    pub path: PathBuf,
    /// 1-based line number.
    pub line: usize,
    /// Why it was kept out, in words.
    pub reason: String,
}

impl std::fmt::Display for Skipped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.path.display(), self.line, self.reason)
    }
}
