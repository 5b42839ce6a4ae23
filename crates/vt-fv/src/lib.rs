//! vt-fv: free-viewpoint images from a few calibrated photos (SPEC System B, seed 004).
//!
//! Pipeline: [`silhouette`]s -> [`hull`] (visual hull on a bit-packed voxel grid) -> [`photo`]
//! (photo hull by voxel colouring, colours for unseen voxels) -> [`render`] (rough view of the
//! coloured voxels from a new [`camera`]) -> [`guided`] (guided texture synthesis with
//! [`patchmatch`], the rough view as guide and a reference photo as input) -> [`eval`].
//! Tests and benchmarks measure against `vt_synth::object`, a ray-cast synthetic object with
//! ground truth computed with its own camera maths.
//!
//! Images are the `image` crate's [`image::RgbImage`]; pixel centres sit at integer coordinates
//! `(x, y) = (column, row)`, origin top-left, as in the Middlebury camera files. No I/O except
//! writing PLY to a caller's writer and [`dataset`] (a data folder: Middlebury par file, COLMAP
//! model ([`colmap`]) or projection matrices, photos undistorted by [`lens`]; read and
//! written through vt-io).
#![deny(missing_docs)]

pub mod camera;
pub mod colmap;
pub mod composite;
pub mod dataset;
mod error;
pub mod hull;
pub mod lens;
pub mod modelfile;
pub mod nerf;
pub mod orbit;
pub mod silhouette;
pub mod stereo;

pub use camera::Camera;
pub use error::{Error, Result};
pub use hull::{visual_hull, Aabb, HullParams, VoxelGrid};
pub use silhouette::Mask;
pub mod photo;
pub mod render;
pub mod rng;

pub use photo::{
    photo_hull, photo_hull_keeping, Consistency, PhotoParams, SurfaceVoxel, Visibility, VoxelModel,
};
pub use render::{render_rough, Rendered};

/// Builds the coloured voxel model: visual hull (SPEC B.1) then photo hull and colours (B.2,
/// B.3), keeping what the silhouettes prove is there unless `photo.keep_silhouettes` is off. `progress(stage, done, total)` reports the stages.
pub fn build_model(
    cams: &[Camera],
    images: &[image::RgbImage],
    silhouettes: &[Mask],
    hull: &HullParams,
    photo: &PhotoParams,
    progress: &mut dyn FnMut(&str, u64, u64),
) -> Result<VoxelModel> {
    if cams.len() != images.len() {
        return Err(Error::CountMismatch {
            what: "cameras vs images".into(),
            a: cams.len(),
            b: images.len(),
        });
    }
    for (i, (img, m)) in images.iter().zip(silhouettes).enumerate() {
        if img.dimensions() != (m.width(), m.height()) {
            return Err(vt_core::Error::SizeMismatch {
                what: format!("silhouette of view {i} vs its image"),
                expected_w: img.width(),
                expected_h: img.height(),
                got_w: m.width(),
                got_h: m.height(),
            }
            .into());
        }
    }
    progress("visual hull", 0, 1);
    let grid = visual_hull(cams, silhouettes, hull)?;
    progress("visual hull", 1, 1);
    photo_hull_keeping(grid, cams, images, Some(silhouettes), photo, progress)
}
pub mod eval;
pub mod guided;
pub mod patchmatch;
pub mod pipeline;
pub mod texture;
pub mod voting;

pub use guided::{guided_synthesis, GuidedParams};
pub use pipeline::{leave_one_out, novel_view, EvalReport, Method, NovelView, ViewParams};
