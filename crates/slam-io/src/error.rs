//! The one error type of slam-io.

use std::path::PathBuf;
use thiserror::Error;

/// What went wrong while reading or writing. File errors always name the file,
/// and parse errors the 1-based line number and what was expected there.
#[derive(Debug, Error)]
pub enum IoError {
    /// The operating system refused to open, read or write a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A compressed (`.gz`) file could not be decompressed: truncated or corrupt.
    #[error("{path}: cannot decompress gzip data (truncated or corrupt file): {source}")]
    Decompress {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: std::io::Error,
    },
    /// A line did not have the expected form.
    #[error("{path}:{line}: expected {expected}, found {found:?}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What the reader expected, in words.
        expected: String,
        /// The offending text (a field or the whole line, shortened).
        found: String,
    },
    /// A number was NaN or infinite.
    #[error("{path}:{line}: {what} is not finite ({value})")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Which quantity.
        what: String,
        /// The value read.
        value: f64,
    },
    /// A finite number outside the physical bound of its field (see [`crate::bounds`]).
    #[error("{path}:{line}: {what} = {value:?} is out of bounds: expected {bound}")]
    OutOfBounds {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Which field.
        what: String,
        /// The value read.
        value: f64,
        /// The bound, in words (with units).
        bound: String,
    },
    /// A file is larger than the reader accepts (see [`crate::bounds::MAX_TEXT_BYTES`]).
    #[error("{path}: {what} is larger than the limit of {limit} bytes")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// What was too large ("file", "decompressed gzip data").
        what: String,
        /// The limit, bytes.
        limit: u64,
    },
    /// The file held no data (only blank lines or comments, or nothing).
    #[error("{path}: file is empty (expected {expected})")]
    Empty {
        /// The file.
        path: PathBuf,
        /// What the file should have held.
        expected: String,
    },
    /// A folder did not hold a file the format needs, or a path is not what was expected.
    #[error("{path}: {what}")]
    NotFound {
        /// The path looked at.
        path: PathBuf,
        /// What was missing, in words.
        what: String,
    },
    /// The data cannot be written in the requested format, or a whole-file check failed.
    #[error("{path}: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// A ROS bag's topic or message is not what the reader expects (a message that does not
    /// decode, a value out of bounds, a missing transform).
    #[error("{path}: topic {topic}: {what}")]
    Bag {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// What was wrong and what was expected, in words.
        what: String,
    },
}

impl IoError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        IoError::Invalid {
            path: path.into(),
            reason: reason.into(),
        }
    }
}
