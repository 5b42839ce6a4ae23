//! The one error type of vt-io. Every variant names the file it is about.

use std::path::PathBuf;

/// Result alias for vt-io.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong reading or writing vt's files.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An operating-system error on a path. The OS error is part of the message and not also
    /// exposed as `source()`, so error chains print it once.
    #[error("{}: {cause}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The OS error.
        cause: std::io::Error,
    },
    /// An output that cannot be written where asked (see [`crate::output`]).
    #[error("{}: {message}", path.display())]
    Output {
        /// The output path.
        path: PathBuf,
        /// What is there, and how to proceed.
        message: String,
    },
    /// A size or count from the input beyond vt's documented limit (refused before allocating).
    #[error("{}: {message}", path.display())]
    Limit {
        /// The file or value.
        path: PathBuf,
        /// The number and the limit.
        message: String,
    },
    /// A video that cannot be decoded, or a decoder that cannot run.
    #[error("{}: {message}", path.display())]
    Video {
        /// The video file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// An image that cannot be read or written.
    #[error("{}: {message}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A malformed points file, or points that do not fit the views.
    #[error("{}{}: {message}", path.display(), if *line == 0 { String::new() } else { format!(":{line}") })]
    Points {
        /// The points file.
        path: PathBuf,
        /// 1-based line number (0 for the whole file, then not printed).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A scene directory that is missing parts, corrupted, or of another format version.
    #[error("{}: {message}", path.display())]
    Scene {
        /// The file in the scene.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A view path that is neither a video nor a frame folder.
    #[error("{}: {message}", path.display())]
    View {
        /// The view path.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Views whose frames differ in size (refused before any decoding).
    #[error(
        "views have different sizes: view 0 ({}) is {}x{}, view {view} ({}) is {}x{}",
        first.display(), first_size.0, first_size.1, path.display(), size.0, size.1
    )]
    ViewSizes {
        /// View 0's path.
        first: PathBuf,
        /// View 0's frame size.
        first_size: (u32, u32),
        /// The first view of another size.
        view: usize,
        /// Its path.
        path: PathBuf,
        /// Its frame size.
        size: (u32, u32),
    },
    /// A value given on the command line or in a file that breaks its rule (the message names
    /// the flag or file with the number and the rule).
    #[error("{0}")]
    Param(String),
    /// An error from the algorithms.
    #[error(transparent)]
    Core(#[from] vt_core::Error),
}

impl Error {
    /// Wraps an OS error with its path.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            cause: source,
        }
    }
}
