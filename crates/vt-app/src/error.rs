//! The one error type of vt-app: the libraries' errors as they are, plus what a use case itself
//! refuses.

use std::path::PathBuf;

/// Result alias for vt-app.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong in a use case.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An algorithm's error (a parameter out of range is vt-core's `InvalidParameter`, naming
    /// the parameter).
    #[error(transparent)]
    Core(#[from] vt_core::Error),
    /// A file's error (each names its file).
    #[error(transparent)]
    Io(#[from] vt_io::Error),
    /// The web export's error.
    #[error(transparent)]
    Web(#[from] vt_web::Error),
    /// System B's error (a camera, a silhouette, the volume, a parameter).
    #[error(transparent)]
    Fv(#[from] vt_fv::Error),
    /// A System B data folder's error (each names its file).
    #[error(transparent)]
    FvData(#[from] vt_fv::dataset::DataError),
    /// The live viewer's error.
    #[error(transparent)]
    View(#[from] vt_view::Error),
    /// A job's parameter out of its range, by the job's name of it (`fps`, `crf`, ...).
    #[error("{name} {value}: {why}")]
    Param {
        /// The parameter's name in the job struct.
        name: &'static str,
        /// The value given.
        value: String,
        /// What it must be.
        why: String,
    },
    /// An error about one input file (the points file of degenerate points, a view that cannot
    /// be opened): the file, then what is wrong.
    #[error("{}: {cause}", path.display())]
    Input {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        cause: Box<Error>,
    },
    /// A view that cannot be opened: its place in the camera order, then vt-io's error (which
    /// names the file).
    #[error("view {view}: {cause}")]
    OpenView {
        /// The view's index.
        view: usize,
        /// What is wrong.
        cause: vt_io::Error,
    },
    /// An error in a step of a use case, said with the step (`silhouette check: ...`).
    #[error("{what}: {cause}")]
    In {
        /// The step, or the thing it was about.
        what: String,
        /// What went wrong.
        cause: Box<Error>,
    },
    /// An error about the value of a job's field (`camera`, `method`), said after its name.
    #[error("{name} {cause}")]
    Field {
        /// The field.
        name: &'static str,
        /// What is wrong with its value.
        cause: Box<Error>,
    },
    /// A synthetic scene that could not be made or written (vt-synth's message, naming the file).
    #[error("{0}")]
    Synth(String),
    /// A clip too short for the minimum loop length, with the way out: a minimum loop length of
    /// `max_min_length` or less.
    #[error(
        "{cause}; for a clip this short use a minimum loop length of {max_min_length} or less"
    )]
    TooShort {
        /// vt-core's error (frames found and needed).
        cause: vt_core::Error,
        /// The longest minimum loop length the clip allows.
        max_min_length: usize,
    },
}
