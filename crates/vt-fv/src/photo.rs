//! Photo hull by voxel colouring (SPEC B.2), colours for unseen surface voxels (B.3), and the
//! coloured [`VoxelModel`].
//!
//! Visibility: each pass renders the current surface voxels into an ID buffer per camera
//! (square splats of [`PhotoParams::splat_scale`] times the voxel's projected size, z-buffered
//! on camera depth, IDs are `u32` so any grid size works); a voxel is visible in a camera when its
//! own ID is at the pixel of its projected centre. Its colour sample in that camera is the mean of
//! the pixels of its footprint that hold its ID.
//!
//! Consistency: a voxel seen by at least two cameras is kept when, on every channel, the standard
//! deviation of its per-camera samples is at most [`PhotoParams::threshold`] (0..255 scale);
//! voxels seen by fewer than two cameras cannot be tested and stay.

use std::collections::HashMap;
use std::io::Write;

use image::RgbImage;
use nalgebra::Vector3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::hull::VoxelGrid;
use crate::{Error, Result};

/// Photo hull parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct PhotoParams {
    /// Largest per-channel standard deviation (0..255) of a voxel's colour samples across the
    /// cameras that see it for the voxel to count as photo-consistent (20). Lower carves more
    /// (and risks holes under lighting changes); higher keeps the visual hull.
    pub threshold: f64,
    /// Most carving passes (64); 0 skips carving and only colours the visual hull's surface.
    pub max_passes: usize,
    /// Splat side as a multiple of a voxel's projected size, for ID buffers and rough renders
    /// (1.5: overlapping a little so no background shows between voxels).
    pub splat_scale: f64,
    /// Radius in voxels of the offset table searched for the nearest seen voxel (8); beyond it
    /// the nearest seen voxel is found by a linear scan.
    pub fill_radius: usize,
}

impl Default for PhotoParams {
    fn default() -> Self {
        Self {
            threshold: 20.0,
            max_passes: 64,
            splat_scale: 1.5,
            fill_radius: 8,
        }
    }
}

/// A surface voxel with its colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceVoxel {
    /// Linear index in the grid.
    pub index: usize,
    /// Colour (mean over the cameras that see it, or the nearest seen voxel's colour).
    pub colour: [u8; 3],
    /// Number of cameras that see it (0: colour copied from the nearest seen voxel).
    pub seen_by: u32,
}

/// The coloured voxel model: occupancy and coloured surface voxels.
#[derive(Debug, Clone)]
pub struct VoxelModel {
    /// Occupancy after carving.
    pub grid: VoxelGrid,
    /// The surface voxels (occupied, with an empty 6-neighbour), ascending by index.
    pub surface: Vec<SurfaceVoxel>,
    /// Carving passes run.
    pub passes: usize,
    /// Voxels removed by photo-consistency.
    pub removed: usize,
}

impl VoxelModel {
    /// World centre of a surface voxel.
    pub fn centre(&self, v: &SurfaceVoxel) -> Vector3<f64> {
        self.grid.centre(self.grid.coords(v.index))
    }

    /// Writes the surface voxels' centres and colours as an ASCII PLY point cloud.
    pub fn to_ply(&self, w: &mut impl Write) -> std::io::Result<()> {
        writeln!(
            w,
            "ply\nformat ascii 1.0\ncomment vt-fv voxel model, grid {:?}",
            self.grid.dims()
        )?;
        writeln!(w, "element vertex {}", self.surface.len())?;
        writeln!(w, "property float x\nproperty float y\nproperty float z")?;
        writeln!(
            w,
            "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header"
        )?;
        for v in &self.surface {
            let c = self.centre(v);
            writeln!(
                w,
                "{} {} {} {} {} {}",
                c.x as f32, c.y as f32, c.z as f32, v.colour[0], v.colour[1], v.colour[2]
            )?;
        }
        Ok(())
    }
}

/// A projected surface voxel: continuous pixel position, depth and splat half-width.
#[derive(Clone, Copy)]
pub(crate) struct Splat {
    pub u: f64,
    pub v: f64,
    pub z: f32,
    pub half: f64,
}

/// Projects a voxel centre for splatting: half-width is `0.5 * scale * f * size / z`.
#[inline]
pub(crate) fn splat(
    cam: &Camera,
    f: f64,
    size: f64,
    scale: f64,
    c: &Vector3<f64>,
) -> Option<Splat> {
    let (u, v, z) = cam.project(c)?;
    Some(Splat {
        u,
        v,
        z: z as f32,
        half: 0.5 * scale * f * size / z,
    })
}

/// Inclusive pixel range covered by a splat, clipped to `w x h`; always holds the centre pixel
/// when that is inside the image.
#[inline]
pub(crate) fn footprint(s: &Splat, w: u32, h: u32) -> Option<(i64, i64, i64, i64)> {
    let (cx, cy) = ((s.u + 0.5).floor() as i64, (s.v + 0.5).floor() as i64);
    let x0 = ((s.u - s.half).ceil() as i64).min(cx).max(0);
    let x1 = ((s.u + s.half).floor() as i64).max(cx).min(w as i64 - 1);
    let y0 = ((s.v - s.half).ceil() as i64).min(cy).max(0);
    let y1 = ((s.v + s.half).floor() as i64).max(cy).min(h as i64 - 1);
    (x0 <= x1 && y0 <= y1).then_some((x0, y0, x1, y1))
}

pub(crate) fn focal(cam: &Camera) -> f64 {
    0.5 * (cam.k[(0, 0)].abs() + cam.k[(1, 1)].abs())
}

/// Renders IDs (`list position + 1`, 0 = none) of the voxels at `centres` into a z-buffer.
fn id_buffer(
    cam: &Camera,
    w: u32,
    h: u32,
    centres: &[Vector3<f64>],
    size: f64,
    scale: f64,
) -> Vec<u32> {
    let f = focal(cam);
    let mut depth = vec![f32::INFINITY; (w * h) as usize];
    let mut ids = vec![0u32; (w * h) as usize];
    for (i, c) in centres.iter().enumerate() {
        let Some(s) = splat(cam, f, size, scale, c) else {
            continue;
        };
        let Some((x0, y0, x1, y1)) = footprint(&s, w, h) else {
            continue;
        };
        for y in y0..=y1 {
            let row = (y as usize) * w as usize;
            for x in x0..=x1 {
                let p = row + x as usize;
                if s.z < depth[p] {
                    depth[p] = s.z;
                    ids[p] = i as u32 + 1;
                }
            }
        }
    }
    ids
}

/// Per-voxel colour statistics over the cameras that see it.
#[derive(Clone, Copy, Default)]
struct Stats {
    n: u32,
    sum: [f64; 3],
    sumsq: [f64; 3],
}

impl Stats {
    fn mean(&self) -> [u8; 3] {
        self.sum
            .map(|s| (s / self.n.max(1) as f64).round().clamp(0.0, 255.0) as u8)
    }

    fn consistent(&self, threshold: f64) -> bool {
        if self.n < 2 {
            return true;
        }
        let n = self.n as f64;
        (0..3).all(|k| {
            let m = self.sum[k] / n;
            (self.sumsq[k] / n - m * m).max(0.0).sqrt() <= threshold
        })
    }
}

fn gather(
    cams: &[Camera],
    images: &[RgbImage],
    ids: &[Vec<u32>],
    centres: &[Vector3<f64>],
    size: f64,
    scale: f64,
) -> Vec<Stats> {
    centres
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let id = i as u32 + 1;
            let mut st = Stats::default();
            for ((cam, img), buf) in cams.iter().zip(images).zip(ids) {
                let (w, h) = img.dimensions();
                let Some(s) = splat(cam, focal(cam), size, scale, c) else {
                    continue;
                };
                let (cx, cy) = ((s.u + 0.5).floor() as i64, (s.v + 0.5).floor() as i64);
                if cx < 0
                    || cy < 0
                    || cx >= w as i64
                    || cy >= h as i64
                    || buf[(cy as usize) * w as usize + cx as usize] != id
                {
                    continue;
                }
                let Some((x0, y0, x1, y1)) = footprint(&s, w, h) else {
                    continue;
                };
                let mut acc = [0.0f64; 3];
                let mut n = 0.0;
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        if buf[(y as usize) * w as usize + x as usize] == id {
                            let p = img.get_pixel(x as u32, y as u32).0;
                            for k in 0..3 {
                                acc[k] += p[k] as f64;
                            }
                            n += 1.0;
                        }
                    }
                }
                st.n += 1;
                for k in 0..3 {
                    let m = acc[k] / n;
                    st.sum[k] += m;
                    st.sumsq[k] += m * m;
                }
            }
            st
        })
        .collect()
}

/// Linear indices of the grid's surface voxels.
fn surface_of(grid: &VoxelGrid) -> Vec<usize> {
    grid.occupied()
        .into_par_iter()
        .filter(|&i| grid.is_surface(grid.coords(i)))
        .collect()
}

/// Carves the photo hull out of `grid` (a visual hull) and colours its surface.
///
/// `progress(stage, done, total)` is called once per pass.
pub fn photo_hull(
    mut grid: VoxelGrid,
    cams: &[Camera],
    images: &[RgbImage],
    params: &PhotoParams,
    progress: &mut dyn FnMut(&str, u64, u64),
) -> Result<VoxelModel> {
    if cams.len() != images.len() {
        return Err(Error::CountMismatch {
            what: "cameras vs images".into(),
            a: cams.len(),
            b: images.len(),
        });
    }
    if params.threshold.is_nan() || params.threshold < 0.0 {
        return Err(Error::BadParam {
            name: "threshold".into(),
            value: params.threshold.to_string(),
            why: "must be >= 0".into(),
        });
    }
    if !(params.splat_scale > 0.0 && params.splat_scale.is_finite()) {
        return Err(Error::BadParam {
            name: "splat_scale".into(),
            value: params.splat_scale.to_string(),
            why: "must be > 0".into(),
        });
    }
    let vs = grid.voxel_size();
    let size = (vs.x * vs.y * vs.z).cbrt();
    let mut surface = surface_of(&grid);
    let mut removed_total = 0;
    let mut passes = 0;
    let mut in_surface: std::collections::HashSet<usize> = surface.iter().copied().collect();
    let stats = loop {
        let centres: Vec<Vector3<f64>> = surface
            .iter()
            .map(|&i| grid.centre(grid.coords(i)))
            .collect();
        let ids: Vec<Vec<u32>> = cams
            .par_iter()
            .zip(images)
            .map(|(c, img)| {
                id_buffer(
                    c,
                    img.width(),
                    img.height(),
                    &centres,
                    size,
                    params.splat_scale,
                )
            })
            .collect();
        let stats = gather(cams, images, &ids, &centres, size, params.splat_scale);
        if passes >= params.max_passes {
            break stats;
        }
        let bad: Vec<usize> = surface
            .iter()
            .zip(&stats)
            .filter(|(_, s)| !s.consistent(params.threshold))
            .map(|(&i, _)| i)
            .collect();
        if bad.is_empty() {
            break stats;
        }
        passes += 1;
        progress("photo hull", passes as u64, params.max_passes as u64);
        for &i in &bad {
            grid.set_index(i, false);
            in_surface.remove(&i);
        }
        removed_total += bad.len();
        let mut kept: Vec<usize> = surface
            .iter()
            .copied()
            .filter(|i| grid.get_index(*i))
            .collect();
        for &i in &bad {
            let [x, y, z] = grid.coords(i).map(|c| c as i64);
            for (dx, dy, dz) in [
                (-1, 0, 0),
                (1, 0, 0),
                (0, -1, 0),
                (0, 1, 0),
                (0, 0, -1),
                (0, 0, 1),
            ] {
                let (nx, ny, nz) = (x + dx, y + dy, z + dz);
                if grid.get(nx, ny, nz) {
                    let j = grid.index(nx as usize, ny as usize, nz as usize);
                    if in_surface.insert(j) {
                        kept.push(j);
                    }
                }
            }
        }
        surface = kept;
        if surface.is_empty() {
            return Err(Error::EmptyModel {
                stage: "photo hull".into(),
            });
        }
    };
    let mut order: Vec<usize> = (0..surface.len()).collect();
    order.sort_unstable_by_key(|&k| surface[k]);
    let mut voxels: Vec<SurfaceVoxel> = order
        .iter()
        .map(|&k| SurfaceVoxel {
            index: surface[k],
            colour: stats[k].mean(),
            seen_by: stats[k].n,
        })
        .collect();
    fill_unseen(&grid, &mut voxels, params.fill_radius);
    Ok(VoxelModel {
        grid,
        surface: voxels,
        passes,
        removed: removed_total,
    })
}

/// Gives every unseen surface voxel the colour of the nearest seen one (SPEC B.3), searching a
/// table of relative offsets sorted by distance, then by a linear scan beyond `radius`.
fn fill_unseen(grid: &VoxelGrid, voxels: &mut [SurfaceVoxel], radius: usize) {
    let seen: HashMap<usize, [u8; 3]> = voxels
        .iter()
        .filter(|v| v.seen_by > 0)
        .map(|v| (v.index, v.colour))
        .collect();
    if seen.is_empty() {
        return;
    }
    let r = radius as i64;
    let mut offsets: Vec<(i64, i64, i64)> = Vec::new();
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                if (dx, dy, dz) != (0, 0, 0) && dx * dx + dy * dy + dz * dz <= r * r {
                    offsets.push((dx, dy, dz));
                }
            }
        }
    }
    offsets.sort_by_key(|&(x, y, z)| (x * x + y * y + z * z, z, y, x));
    let seen_list: Vec<(usize, [u8; 3])> = seen.iter().map(|(&i, &c)| (i, c)).collect();
    let fills: Vec<(usize, [u8; 3])> = voxels
        .par_iter()
        .enumerate()
        .filter(|(_, v)| v.seen_by == 0)
        .map(|(k, v)| {
            let [x, y, z] = grid.coords(v.index).map(|c| c as i64);
            for &(dx, dy, dz) in &offsets {
                if grid.get(x + dx, y + dy, z + dz) {
                    let j = grid.index((x + dx) as usize, (y + dy) as usize, (z + dz) as usize);
                    if let Some(c) = seen.get(&j) {
                        return (k, *c);
                    }
                }
            }
            let d2 = |i: usize| {
                let [a, b, c] = grid.coords(i).map(|c| c as i64);
                (a - x).pow(2) + (b - y).pow(2) + (c - z).pow(2)
            };
            let best = seen_list
                .iter()
                .min_by_key(|(i, _)| d2(*i))
                .expect("seen is not empty: checked above");
            (k, best.1)
        })
        .collect();
    for (k, c) in fills {
        voxels[k].colour = c;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_holds_the_centre_pixel() {
        let s = Splat {
            u: 10.4,
            v: 3.6,
            z: 1.0,
            half: 0.1,
        };
        assert_eq!(footprint(&s, 20, 20), Some((10, 4, 10, 4)));
        let s = Splat {
            u: 10.0,
            v: 3.0,
            z: 1.0,
            half: 1.5,
        };
        assert_eq!(footprint(&s, 20, 20), Some((9, 2, 11, 4)));
        let s = Splat {
            u: -3.0,
            v: 3.0,
            z: 1.0,
            half: 1.5,
        };
        assert_eq!(footprint(&s, 20, 20), None);
    }
}
