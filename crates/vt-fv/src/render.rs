//! Rough render of a coloured voxel model from any camera (SPEC B.4): z-buffered square splats.

use image::{Rgb, RgbImage};

use crate::camera::Camera;
use crate::photo::{focal, footprint, splat, VoxelModel};
use crate::silhouette::Mask;

/// A rendered view.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// Colours; black where no voxel lands.
    pub image: RgbImage,
    /// Pixels covered by some voxel.
    pub coverage: Mask,
    /// Camera depth per pixel (`f32::INFINITY` where uncovered).
    pub depth: Vec<f32>,
}

/// Splat scale of [`render_rough`] (as [`crate::photo::PhotoParams::splat_scale`]'s default).
pub const DEFAULT_SPLAT_SCALE: f64 = 1.5;

/// Renders the model's surface voxels from `cam` into a `w x h` image (the rough view).
pub fn render_rough(model: &VoxelModel, cam: &Camera, w: u32, h: u32) -> Rendered {
    render_rough_with(model, cam, w, h, DEFAULT_SPLAT_SCALE)
}

/// [`render_rough`] with a chosen splat scale (splat side over the voxel's projected size).
pub fn render_rough_with(
    model: &VoxelModel,
    cam: &Camera,
    w: u32,
    h: u32,
    splat_scale: f64,
) -> Rendered {
    let vs = model.grid.voxel_size();
    let size = (vs.x * vs.y * vs.z).cbrt();
    let f = focal(cam);
    let mut depth = vec![f32::INFINITY; (w as usize) * (h as usize)];
    let mut colour = vec![[0u8; 3]; depth.len()];
    for v in &model.surface {
        let Some(s) = splat(cam, f, size, splat_scale, &model.centre(v)) else {
            continue;
        };
        let Some((x0, y0, x1, y1)) = footprint(&s, w, h) else {
            continue;
        };
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = (y as usize) * w as usize + x as usize;
                if s.z < depth[p] {
                    depth[p] = s.z;
                    colour[p] = v.colour;
                }
            }
        }
    }
    let image = RgbImage::from_fn(w, h, |x, y| Rgb(colour[(y * w + x) as usize]));
    let coverage = Mask::from_fn(w, h, |x, y| depth[(y * w + x) as usize].is_finite());
    Rendered {
        image,
        coverage,
        depth,
    }
}
