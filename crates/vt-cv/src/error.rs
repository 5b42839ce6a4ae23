//! The one error type of vt-cv: OpenCV's errors with the operation that raised them, and
//! vt-core's errors where vt-cv applies the same rules (so both crates fail alike).

use thiserror::Error;

/// Result alias for vt-cv.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in vt-cv.
#[derive(Debug, Error)]
pub enum Error {
    /// An OpenCV call failed; `op` names the call and its input. OpenCV's error is part of the
    /// message and not also exposed as `source()`, so error chains print it once.
    #[error("OpenCV {op}: {cause}")]
    OpenCv {
        /// The OpenCV function and what it was given (e.g. "warpPerspective 640x360 -> 320x180").
        op: String,
        /// OpenCV's own error (code and message).
        cause: opencv::Error,
    },
    /// OpenCV returned an empty or malformed result where one was expected.
    #[error("OpenCV {op} returned no usable result: {why}")]
    NoResult {
        /// The OpenCV function.
        op: String,
        /// What was wrong with its output.
        why: String,
    },
    /// A rule shared with vt-core was broken (sizes, frame counts, parameters, points).
    #[error(transparent)]
    Core(#[from] vt_core::Error),
}

/// Attaches the operation name to an OpenCV result (the name is only formatted on failure).
pub(crate) trait Context<T> {
    /// Wraps an `opencv::Error` as [`Error::OpenCv`] naming `op`.
    fn ctx(self, op: &str) -> Result<T>;
    /// Like [`Context::ctx`] with a lazily built name.
    fn with_ctx(self, op: impl FnOnce() -> String) -> Result<T>;
}

impl<T> Context<T> for opencv::Result<T> {
    fn ctx(self, op: &str) -> Result<T> {
        self.map_err(|cause| Error::OpenCv {
            op: op.to_string(),
            cause,
        })
    }

    fn with_ctx(self, op: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|cause| Error::OpenCv { op: op(), cause })
    }
}
