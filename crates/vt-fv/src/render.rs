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

/// How [`clip_to_silhouettes`] searches each pixel's ray.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipParams {
    /// Voxel sizes searched in front of the rendered depth (1).
    pub before: f64,
    /// Voxel sizes searched behind the rendered depth (8): a splat's pixel whose ray misses
    /// its voxel may still meet the surface behind it.
    pub behind: f64,
    /// Search step in voxel sizes (0.25).
    pub step: f64,
    /// Closing radius in pixels applied to the silhouettes first (4): thin dark grooves that
    /// one photo's threshold misses would otherwise cut slits through the object.
    pub close: u32,
}

impl Default for ClipParams {
    fn default() -> Self {
        Self {
            before: 1.0,
            behind: 8.0,
            step: 0.25,
            close: 4,
        }
    }
}

/// Trims a render of a voxel model to the visual hull at pixel accuracy (an image-based visual
/// hull test near the voxel surface): a covered pixel stays covered only when some point on its
/// ray, within `before`/`behind` voxel sizes of its rendered depth, projects inside the
/// silhouette (closed by `close`) of every camera that sees the point in its frame. Voxel splats overshoot the
/// silhouettes by up to about a voxel (a voxel is kept when its centre is inside them); this
/// takes the overshoot back. Returns the number of pixels uncovered (made black, depth
/// infinite).
pub fn clip_to_silhouettes(
    r: &mut Rendered,
    model: &VoxelModel,
    cam: &Camera,
    cams: &[Camera],
    masks: &[Mask],
    p: &ClipParams,
) -> usize {
    use rayon::prelude::*;
    let (w, h) = r.image.dimensions();
    let vs = model.grid.voxel_size();
    let size = (vs.x * vs.y * vs.z).cbrt();
    let Some(kinv) = cam.k.try_inverse() else {
        return 0;
    };
    let a = cam.r.transpose() * kinv;
    let b = -(cam.r.transpose() * cam.t);
    let projs: Vec<_> = cams.iter().map(|c| c.projection()).collect();
    let closed: Vec<Mask> = masks
        .par_iter()
        .map(|m| m.dilate(p.close).erode(p.close))
        .collect();
    let masks = &closed;
    let steps = ((p.before + p.behind) / p.step.max(1e-3)).round() as i64;
    let inside = |x: &nalgebra::Vector3<f64>| {
        projs.iter().zip(masks).all(|(pm, m)| {
            let q = pm * x.push(1.0);
            if q.z <= 0.0 {
                return true;
            }
            let (u, v) = ((q.x / q.z + 0.5).floor(), (q.y / q.z + 0.5).floor());
            if u < 0.0 || v < 0.0 || u >= m.width() as f64 || v >= m.height() as f64 {
                return true;
            }
            m.get(u as u32, v as u32)
        })
    };
    let drop: Vec<usize> = (0..(w as usize * h as usize))
        .into_par_iter()
        .filter(|&i| {
            let d = r.depth[i] as f64;
            if !d.is_finite() {
                return false;
            }
            let ray =
                a * nalgebra::Vector3::new((i % w as usize) as f64, (i / w as usize) as f64, 1.0);
            !(0..=steps).any(|s| {
                let t = d + (s as f64 * p.step - p.before) * size;
                t > 0.0 && inside(&(ray * t + b))
            })
        })
        .collect();
    for &i in &drop {
        r.depth[i] = f32::INFINITY;
        r.image.as_mut()[3 * i..3 * i + 3].fill(0);
        r.coverage.set(i as u32 % w, i as u32 / w, false);
    }
    drop.len()
}
