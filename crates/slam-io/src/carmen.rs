//! CARMEN logs (TODO).
use crate::error::IoError;
use slam_models::ScanDataset;
use std::collections::BTreeMap;
use std::path::Path;

/// A CARMEN log.
pub struct CarmenLog {
    /// The records.
    pub dataset: ScanDataset,
    /// Unknown record types and their counts.
    pub unknown_records: BTreeMap<String, usize>,
}
impl CarmenLog {
    /// One-line summary.
    pub fn summary(&self, path: &Path) -> String {
        format!("{}", path.display())
    }
}
/// Reads a log.
pub fn read_carmen(path: &Path) -> Result<CarmenLog, IoError> {
    Err(IoError::invalid(path, "todo"))
}
