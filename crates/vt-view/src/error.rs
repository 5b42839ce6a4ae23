//! The one error type of vt-view.

/// Result alias for vt-view.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can stop the viewer or the marking page from starting.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A viewer parameter out of its range: [`ViewerParams`](crate::ViewerParams)'s field
    /// `name` (also `vt view`'s flag), its value and the rule it breaks.
    #[error("{name} {value} {why}")]
    Param {
        /// The field.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// The rule, e.g. "must be in 1..=100".
        why: String,
    },
    /// The port cannot be listened on. The OS error is part of the message, not also `source()`.
    #[error("port {port}: cannot listen on 127.0.0.1: {cause}")]
    Listen {
        /// The port asked for.
        port: u16,
        /// The OS error.
        cause: std::io::Error,
    },
    /// The renderer refused the scene or its parameters, or a view's frames could not be read.
    #[error(transparent)]
    Core(#[from] vt_core::Error),
    /// A file that could not be read or written (vt-io names it).
    #[error(transparent)]
    Io(#[from] vt_io::Error),
    /// An input the marking page cannot use: the path and why.
    #[error("{}: {message}", path.display())]
    Input {
        /// The input path.
        path: std::path::PathBuf,
        /// What is wrong.
        message: String,
    },
}
