//! The one error type of vt-core.

use thiserror::Error;

/// Result alias for vt-core.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in vt-core. Messages carry the numbers involved.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// Two images or masks that must share a size do not.
    #[error("{what}: size mismatch: expected {expected_w}x{expected_h}, got {got_w}x{got_h}")]
    SizeMismatch {
        /// What was being combined (e.g. "view 3 frame 12").
        what: String,
        /// Expected width.
        expected_w: u32,
        /// Expected height.
        expected_h: u32,
        /// Width found.
        got_w: u32,
        /// Height found.
        got_h: u32,
    },
    /// A view whose frames differ in size from view 0's.
    #[error("views have different sizes: view 0 is {}x{}, {view} is {}x{}", first.0, first.1, size.0, size.1)]
    ViewSizes {
        /// View 0's size.
        first: (u32, u32),
        /// The other view, named.
        view: String,
        /// Its size.
        size: (u32, u32),
    },
    /// An image with zero width or height.
    #[error("{what}: empty image ({w}x{h})")]
    EmptyImage {
        /// What the image was.
        what: String,
        /// Width.
        w: u32,
        /// Height.
        h: u32,
    },
    /// Too few frames for an operation.
    #[error("{what}: {got} frames, need at least {need} ({why})")]
    TooFewFrames {
        /// Which view or sequence.
        what: String,
        /// Frames present.
        got: usize,
        /// Frames needed.
        need: usize,
        /// Which rule sets the minimum.
        why: String,
    },
    /// More frames than a counter can hold.
    #[error("{what}: {got} frames, at most {max} supported")]
    TooManyFrames {
        /// Which view.
        what: String,
        /// Frames pushed.
        got: usize,
        /// Limit.
        max: usize,
    },
    /// A parameter out of its valid range.
    #[error("invalid parameter {name} = {value}: {why}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// The rule it breaks.
        why: String,
    },
    /// Two views' backgrounds that automatic registration could not verify a mapping between.
    #[error("views {} and {}: cannot register the backgrounds automatically: {why}; mark the same points on every view and pass them with --points", pair.0, pair.1)]
    Registration {
        /// The view pair (p, p + 1).
        pair: (usize, usize),
        /// The figures: features, matches, inliers, coverage, residual.
        why: String,
    },
    /// A clip whose camera moves in a way vt cannot hold still (a cut, a pan).
    #[error("{view}: {why}; pass --stabilize off to take the frames as they are")]
    Unsteady {
        /// Which clip.
        view: String,
        /// What was measured.
        why: String,
    },
    /// Point correspondences that cannot determine a transformation.
    #[error("degenerate points: {0}")]
    DegeneratePoints(String),
    /// A non-finite number where a finite one is required.
    #[error("non-finite value in {0}")]
    NonFinite(String),
    /// A singular or non-finite 3x3 matrix where an invertible one is needed.
    #[error("singular homography: {0}")]
    SingularHomography(String),
    /// A frame source (decoder) failed; the message comes from the source.
    #[error("{view}: {message}")]
    Source {
        /// Which view.
        view: String,
        /// What the source reported.
        message: String,
    },
    /// A typed error from outside vt-core (a file, a decoder, an object sink behind one of
    /// vt-core's traits), kept whole as the [`std::error::Error::source`] so callers can print
    /// the chain once and downcast it; the message itself only names the view.
    #[error("{view}")]
    External {
        /// Which view or stage.
        view: String,
        /// The error as its crate raised it.
        #[source]
        source: ExternalError,
    },
}

impl Error {
    /// Wraps another crate's error for a view, keeping its type ([`Error::External`]).
    pub fn external(
        view: impl Into<String>,
        e: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Error::External {
            view: view.into(),
            source: ExternalError(std::sync::Arc::new(e)),
        }
    }
}

/// Another crate's error inside [`Error::External`]: shared so [`Error`] stays `Clone`, compared
/// by message so it stays `PartialEq`.
#[derive(Debug, Clone)]
pub struct ExternalError(pub std::sync::Arc<dyn std::error::Error + Send + Sync>);

impl ExternalError {
    /// The wrapped error, for downcasting (`e.inner().downcast_ref::<vt_io::Error>()`).
    pub fn inner(&self) -> &(dyn std::error::Error + Send + Sync + 'static) {
        &*self.0
    }
}

impl std::fmt::Display for ExternalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for ExternalError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

impl PartialEq for ExternalError {
    fn eq(&self, other: &Self) -> bool {
        self.0.to_string() == other.0.to_string()
    }
}
