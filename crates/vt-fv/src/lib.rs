//! vt-fv: free-viewpoint images from a few calibrated photos (SPEC System B, seed 004).
//!
//! Pipeline: [`silhouette`]s -> [`hull`] (visual hull on a bit-packed voxel grid) -> [`photo`]
//! (photo hull by voxel colouring, colours for unseen voxels) -> [`render`] (rough view of the
//! coloured voxels from a new [`camera`]) -> [`synthesis`] (guided texture synthesis with
//! [`patchmatch`], the rough view as guide and a reference photo as input) -> [`eval`].
//! [`synth`] makes a ray-cast synthetic object with ground truth for tests and benchmarks.
//!
//! Images are the `image` crate's [`image::RgbImage`]; pixel centres sit at integer coordinates
//! `(x, y) = (column, row)`, origin top-left, as in the Middlebury camera files. No I/O except
//! writing PLY to a caller's writer.
#![deny(missing_docs)]

pub mod camera;
mod error;
pub mod hull;
pub mod silhouette;

pub use camera::Camera;
pub use error::{Error, Result};
pub use hull::{visual_hull, Aabb, HullParams, VoxelGrid};
pub use silhouette::Mask;
pub mod rng;
pub mod synth;
