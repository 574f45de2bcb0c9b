//! The one error type of slam-viz.

use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why a picture could not be drawn or written. Its messages read as slam-io's did when the
/// pictures lived there ("picture: …", "FILE: cannot write PNG: …").
#[derive(Debug, Error)]
pub enum VizError {
    /// Nothing finite to draw, or no room to draw it.
    #[error("picture: {0}")]
    Draw(String),
    /// A point of a picture lies beyond the drawable extent (a diverged estimate, a glitched
    /// log): at such coordinates an f64 cannot resolve the metre grid of the axes.
    #[error("picture: {layer} has a point at ({x:e}, {y:e}) m, beyond the drawable ±{bound:e} m")]
    Extent {
        /// The layer holding the point (e.g. "ground truth", "trajectory `estimate`").
        layer: String,
        /// The point's x, metres.
        x: f64,
        /// The point's y, metres.
        y: f64,
        /// The bound on |x| and |y|, metres (`picture::MAX_COORDINATE_M`).
        bound: f64,
    },
    /// The data handed to a plot cannot be plotted (series of unequal length, nothing
    /// finite); `path` is the file the plot was for.
    #[error("{path}: {reason}")]
    Invalid {
        /// The file the plot was for.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// The PNG file could not be encoded or written.
    #[error("{path}: cannot write PNG: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The encoder's or the operating system's message.
        message: String,
    },
}

impl VizError {
    pub(crate) fn invalid(path: &Path, reason: impl Into<String>) -> Self {
        VizError::Invalid {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }

    pub(crate) fn write(path: &Path, e: image::ImageError) -> Self {
        VizError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }
}
