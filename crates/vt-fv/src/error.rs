//! The one error type of vt-fv.

use thiserror::Error;

/// Result alias for vt-fv.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in vt-fv. Messages carry the numbers and names involved.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// A line of a Middlebury `*_par.txt` file could not be parsed.
    #[error("camera file line {line}: {what}")]
    ParLine {
        /// 1-based line number in the file.
        line: usize,
        /// What is wrong with it.
        what: String,
    },
    /// The camera file's count line disagrees with the number of camera lines.
    #[error("camera file: header says {declared} cameras, found {found}")]
    ParCount {
        /// Count on the first line.
        declared: usize,
        /// Camera lines present.
        found: usize,
    },
    /// A line of a text camera file (COLMAP's `cameras.txt` or `images.txt`, a projection
    /// matrix file); the file's path is added by [`crate::dataset`].
    #[error("line {line}: {what}")]
    Line {
        /// 1-based line number in the file.
        line: usize,
        /// What is wrong with it.
        what: String,
    },
    /// A binary camera file (COLMAP's `cameras.bin` or `images.bin`) cut short or inconsistent.
    #[error("byte {offset}: {what}")]
    Binary {
        /// Offset of the record or value that is wrong.
        offset: usize,
        /// What is wrong.
        what: String,
    },
    /// A new-camera spec (par line, `angle:DEG` or `between:I,J,T`) that cannot be used.
    #[error("{spec:?}: {what}")]
    CameraSpec {
        /// The spec as given.
        spec: String,
        /// What is wrong.
        what: String,
    },
    /// A camera whose matrices cannot form a projection (singular K, non-rotation R).
    #[error("camera {name}: {what}")]
    BadCamera {
        /// Camera name.
        name: String,
        /// What is wrong.
        what: String,
    },
    /// Inputs whose counts must match do not.
    #[error("{what}: {a} vs {b}")]
    CountMismatch {
        /// What was being paired (e.g. "cameras vs images").
        what: String,
        /// First count.
        a: usize,
        /// Second count.
        b: usize,
    },
    /// Too few inputs (e.g. fewer than two cameras for a ring).
    #[error("{what}: got {got}, need at least {need}")]
    TooFew {
        /// What is counted.
        what: String,
        /// Count present.
        got: usize,
        /// Minimum count.
        need: usize,
    },
    /// An image with zero width or height, or one smaller than a patch.
    #[error("{what}: image {w}x{h} is too small (need at least {need}x{need})")]
    ImageTooSmall {
        /// What the image was.
        what: String,
        /// Width.
        w: u32,
        /// Height.
        h: u32,
        /// Minimum side.
        need: u32,
    },
    /// A silhouette with no object pixel.
    #[error("silhouette of view {index} ({name}) is empty: no object pixel")]
    EmptySilhouette {
        /// View index.
        index: usize,
        /// Camera name.
        name: String,
    },
    /// A camera whose image does not see any part of the voxel volume.
    #[error("camera {index} ({name}) sees none of the volume {min:?}..{max:?}")]
    CameraSeesNoVolume {
        /// View index.
        index: usize,
        /// Camera name.
        name: String,
        /// Volume minimum corner.
        min: [f64; 3],
        /// Volume maximum corner.
        max: [f64; 3],
    },
    /// A voxel grid that would need more memory than allowed; refused before allocating.
    #[error("voxel grid {nx}x{ny}x{nz} needs {bytes} bytes, limit is {limit} bytes")]
    GridTooLarge {
        /// Voxels along x.
        nx: usize,
        /// Voxels along y.
        ny: usize,
        /// Voxels along z.
        nz: usize,
        /// Bytes needed (saturated at `u64::MAX` on overflow).
        bytes: u64,
        /// Allowed bytes.
        limit: u64,
    },
    /// Volume bounds that are empty, inverted or not finite.
    #[error("bad volume bounds {min:?}..{max:?}: {what}")]
    BadBounds {
        /// Minimum corner.
        min: [f64; 3],
        /// Maximum corner.
        max: [f64; 3],
        /// What is wrong.
        what: String,
    },
    /// Carving removed every voxel.
    #[error("{stage}: no voxel left")]
    EmptyModel {
        /// Which stage emptied the model.
        stage: String,
    },
    /// A parameter out of its valid range.
    #[error("parameter {name} = {value}: {why}")]
    BadParam {
        /// Parameter name.
        name: String,
        /// Its value, printed.
        value: String,
        /// The valid range.
        why: String,
    },
    /// A model file (`vt fv hull`'s `model.vtfv`) that cannot be used; the path is added by
    /// [`crate::dataset`].
    #[error("{what}")]
    ModelFile {
        /// What is wrong with it.
        what: String,
    },
    /// A NeRF transforms file ([`crate::nerf`]) that vt cannot read correctly; the path is
    /// added by [`crate::dataset`].
    #[error("{what}")]
    Transforms {
        /// What is wrong with it.
        what: String,
    },
    /// An error from vt-core's primitives (metrics, masks, images).
    #[error(transparent)]
    Core(#[from] vt_core::Error),
}
