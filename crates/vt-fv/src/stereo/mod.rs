//! Geometry from the photos themselves: a depth map per photo by stereo inside the visual hull,
//! checked against the other photos' depth maps, then the hull carved to the free space the
//! depth maps prove.
//!
//! By default each depth map comes from PatchMatch over slanted planes ([`planes`]): each cell
//! holds a depth and a normal, and its window is compared with the sources through the
//! homography of that plane. The fronto-parallel plane sweep below (`patchmatch: 0`) is kept
//! as the measured alternative; the rest (sources, scores, acceptance, confirmation, carving)
//! is the same for both. What follows describes the sweep.
//!
//! The visual hull of a few views is fat: every concavity and every region between the views'
//! silhouette cones stays full. Colours see what silhouettes cannot. For each photo (the
//! reference) and each pixel inside its silhouette, the ray's stretch inside the hull is swept
//! in steps of half a voxel; at each depth a window around the pixel, taken as a fronto-parallel
//! patch at that depth, is compared with its projection into the nearest photos by normalised
//! cross-correlation (NCC) of luma. The score of a depth is the mean of the best `best` sources'
//! NCC (a source where the point is hidden scores low and drops out). The best depth is kept
//! when its score is at least `min_ncc` and the window has texture. Each kept depth must then be
//! confirmed by another photo's depth map: the point, projected into another photo, lands on a
//! depth within `agree` voxels. Finally every hull voxel that lies in front of a confirmed depth
//! by more than `margin` voxels, in every confirmed pixel around its projection, is empty space
//! and is carved, unless another photo's depth puts it on a surface (`protect`). This runs
//! `passes` times; after the first, what no photo can see beyond `unseen_keep` voxels from
//! what they see goes too ([`carve_unseen`]). The last pass also carves in front of the depth
//! maps' holes, filled from the depths around them ([`StereoParams::hole_fill`]).

use image::RgbImage;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::hull::VoxelGrid;
use crate::silhouette::Mask;
use crate::texture::nearest_by_direction;
use crate::{Error, Result};

mod planes;

/// Settings of [`carve_by_stereo`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoParams {
    /// Photos compared with each reference: the nearest by viewing direction (6; with NCC 0.4
    /// against 4 and 0.5: lego 8-view 20.45 against 20.33 dB, kettle and temple leave-one-out
    /// 24.72 / 21.95 against 24.73 / 21.96, examples test_knobs and loo_data).
    pub sources: usize,
    /// A depth's score is the mean NCC of this many best sources (2).
    pub best: usize,
    /// Half side of the NCC window in pixels (3: 7x7), sampled every `stride` pixels.
    pub radius: i32,
    /// Window sampling stride in pixels (2: a 4x4 lattice over the 7x7 window).
    pub stride: i32,
    /// Depth step along a ray, in voxels (0.5).
    pub step: f64,
    /// The sweep first tries every `coarse`-th step, then every step within `coarse` steps of
    /// the best (4).
    pub coarse: usize,
    /// Depths are measured every `pixel_step` pixels in both directions (2). Every pixel in
    /// every round (1, with `fine` 0): lego 8-view 22.02 -> 22.12 dB, the model 13.8 -> 28.2 s,
    /// at the edge of the benchmark's 30 s; not yet measured on the real scenes.
    pub pixel_step: usize,
    /// Least score a depth is kept at (0.4).
    pub min_ncc: f64,
    /// Sweep only: least lead of the best depth's score over any other depth farther than
    /// `apart` voxels (0: off). A repeated pattern matches at several depths; 0.1-0.2 drops those and carves
    /// less, safer on periodic texture (the synthetic object) but less on real photos (the
    /// report's stereo table).
    pub distinct: f64,
    /// How far, in voxels, a rival depth must lie (3).
    pub apart: f64,
    /// Least luma standard deviation of the reference window (2 levels of 255): flat windows
    /// have no depth.
    pub min_texture: f64,
    /// Two depth maps agree on a point within this many voxels (1.5).
    pub agree: f64,
    /// A depth is kept when this many other photos' maps agree with it (1).
    pub confirmations: usize,
    /// A voxel is carved when it lies this many voxels in front of the confirmed depths (2).
    pub margin: f64,
    /// ... unless some photo's confirmed depth puts it on a surface, within this many voxels
    /// (1.5; 0: no protection).
    pub protect: f64,
    /// After the first pass, keep only voxels within this many voxels of one a photo sees
    /// ([`carve_unseen`]; 3); `None` keeps them all.
    pub unseen_keep: Option<usize>,
    /// Sweep and carve up to this many times (2): each pass measures inside what the one
    /// before left, where fewer phantom surfaces hide the real ones.
    pub passes: usize,
    /// PatchMatch iterations over slanted planes ([`planes`]) instead of the fronto-parallel
    /// plane sweep (3; 0: the sweep). On the synthetic object's ray-cast truth (tests/stereo.rs)
    /// the median depth error falls from 1.24 to 0.60 voxels and the 90th percentile from 19.9
    /// to 5.6, with more cells confirmed; lego 8-view 20.45 -> 20.86 dB (6 iterations 20.90),
    /// kettle leave-one-out 24.72 -> 24.76. `distinct` and `coarse` apply to the sweep only.
    pub patchmatch: usize,
    /// PatchMatch only: iterations of a second round, started from the first round's planes,
    /// in which each source's NCC is docked for the forward-backward reprojection error
    /// through that source's first-round depth map (Schönberger et al. 2016's geometric
    /// consistency) (2; 0: none). Lego 8-view 21.28 -> 21.53 dB (2 more iterations without the
    /// term: 21.35), kettle leave-one-out 24.66 -> 24.67 inside the silhouette, 23.32 -> 23.40
    /// over it and the view's own coverage; the model takes about 1.7 times as long.
    pub geo_iters: usize,
    /// Largest NCC docked for the geometric term, reached at 3 pixels of reprojection error
    /// (0.2; 0.1: 21.45 dB on lego, 0.3: 21.39, 0.5: 21.04).
    pub geo_weight: f64,
    /// Compare windows in all three colour channels (each centred on its own mean) instead of
    /// luma alone (off). Colour tells apart parts of equal luma (the lego's yellow and grey):
    /// with NCC 0.3, lego 8-view 21.78 -> 21.88 dB (IoU 0.948 -> 0.951), kettle leave-one-out
    /// 24.75 -> 24.79, templeSparseRing leave-one-out (grid 128) 22.19 -> 22.18, the model
    /// 1.5-1.7 times as long (the temple's 38 -> 63 s a view); off: the gain is small for the
    /// time (the report's stereo table has the row). Measured again with the fine iterations,
    /// the softening's backdrop and the homography kernel: lego 22.02 -> 21.97 dB, the model
    /// 15.7 -> 24.0 s.
    pub colour: bool,
    /// PatchMatch only: iterations at every pixel after the rounds at `pixel_step`, each pixel
    /// started from its nearest cell's plane (carried along the plane to its own ray), with the
    /// geometric term against the rounds' maps; in the last pass, whose maps the model keeps
    /// (2; 0: none, the maps stay at `pixel_step`). Finer maps carve and clip closer to the
    /// outline. Lego 8-view 21.78 -> 21.92 dB (IoU 0.948 -> 0.950; 1 iteration 21.88; every
    /// pixel in every round, `pixel_step` 1, 22.03 at 6x the model time), the model about 1.8
    /// times as long; kettle leave-one-out 24.75 -> 24.73 inside the silhouette, 23.53 ->
    /// 23.58 over it and the view's own coverage; templeSparseRing 22.19 -> 22.23, 21.25 ->
    /// 21.30 (its worst view's lead over the blurred rough render +0.16 -> +0.07). Skipped for
    /// photos over 4.2 million pixels, or 33.5 million all together (the cells' memory, the
    /// model file's size).
    pub fine: usize,
    /// In the last pass, the free space is also carved in front of the holes of each photo's
    /// confirmed depth map inside its silhouette, each hole cell taking the nearest of the first
    /// depths found within this many cells in the eight directions, when three of them find one
    /// (6; 0: off). PatchMatch leaves holes where the surface is seen edge-on (near the
    /// outline, where the hull's phantom volume lies) and where it has no texture; the nearest
    /// of the depths around a hole errs towards the camera, a voxel some photo's confirmed depth
    /// puts on a surface is still kept, and the model keeps the confirmed maps, not the filled
    /// ones. Lego 8-view 22.02 -> 22.23 dB, coverage IoU 0.949 -> 0.953, inside the silhouette
    /// 18.41 -> 18.44 (radius 4: 22.23; 8: 22.21; in every pass, radius 4: 22.19, inside 18.25);
    /// the kettle's and templeSparseRing's leave-one-out the same as without (kettle 24.74 dB
    /// inside the silhouette, worst lead over the blurred rough render +0.94 against +0.93,
    /// 24.51 over it and the view's own coverage; temple 22.23, +0.09 against +0.07, 21.30).
    /// The model's time is the same (lego 18.8 against 18.7 s).
    pub hole_fill: usize,
}

impl Default for StereoParams {
    fn default() -> Self {
        Self {
            sources: 6,
            best: 2,
            radius: 3,
            stride: 2,
            step: 0.5,
            coarse: 4,
            pixel_step: 2,
            min_ncc: 0.4,
            distinct: 0.0,
            apart: 3.0,
            min_texture: 2.0,
            agree: 1.5,
            confirmations: 1,
            margin: 2.0,
            protect: 1.5,
            unseen_keep: Some(3),
            passes: 2,
            patchmatch: 3,
            geo_iters: 2,
            geo_weight: 0.2,
            colour: false,
            fine: 2,
            hole_fill: 6,
        }
    }
}

impl StereoParams {
    /// Checks the ranges.
    pub fn check(&self) -> Result<()> {
        let bad = |name: &str, v: String, why: &str| {
            Err(Error::BadParam {
                name: name.into(),
                value: v,
                why: why.into(),
            })
        };
        if self.best == 0 || self.sources < self.best {
            return bad(
                "stereo_best",
                format!("{} of {}", self.best, self.sources),
                "at least 1, and at most the sources",
            );
        }
        if !(1..=15).contains(&self.radius) || !(1..=self.radius).contains(&self.stride) {
            return bad(
                "stereo_radius",
                format!("{} (stride {})", self.radius, self.stride),
                "radius in 1..=15, stride in 1..=radius",
            );
        }
        if self.patchmatch > 16 {
            return bad(
                "stereo_patchmatch",
                self.patchmatch.to_string(),
                "in 0..=16",
            );
        }
        if self.fine > 16 {
            return bad("stereo_fine", self.fine.to_string(), "in 0..=16");
        }
        if self.hole_fill > 64 {
            return bad(
                "stereo_hole_fill",
                self.hole_fill.to_string(),
                "in 0..=64 cells",
            );
        }
        if !(1..=8).contains(&self.passes) {
            return bad("stereo_passes", self.passes.to_string(), "in 1..=8");
        }
        if !(1..=16).contains(&self.coarse) || !(1..=8).contains(&self.pixel_step) {
            return bad(
                "stereo_coarse",
                format!("{} (pixel step {})", self.coarse, self.pixel_step),
                "coarse in 1..=16, pixel step in 1..=8",
            );
        }
        if !(self.step > 0.01 && self.step <= 4.0) {
            return bad("stereo_step", self.step.to_string(), "in (0.01, 4] voxels");
        }
        if !(-1.0..=1.0).contains(&self.min_ncc) {
            return bad("stereo_min_ncc", self.min_ncc.to_string(), "in [-1, 1]");
        }
        for (n, v) in [
            ("stereo_min_texture", self.min_texture),
            ("stereo_agree", self.agree),
            ("stereo_margin", self.margin),
            ("stereo_protect", self.protect),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return bad(n, v.to_string(), "a finite number >= 0");
            }
        }
        Ok(())
    }
}

/// One photo's depth map: camera depth every `step` pixels, `NaN` where there is none.
#[derive(Debug, Clone)]
pub struct DepthMap {
    /// Width in cells (one every `step` pixels).
    pub w: usize,
    /// Height in cells.
    pub h: usize,
    /// Pixels between cells: cell `(x, y)` is pixel `(step x, step y)`.
    pub step: usize,
    /// Depths, row-major.
    pub depth: Vec<f32>,
}

impl DepthMap {
    fn at(&self, x: i64, y: i64) -> f32 {
        if x < 0 || y < 0 || x >= self.w as i64 || y >= self.h as i64 {
            return f32::NAN;
        }
        self.depth[y as usize * self.w + x as usize]
    }

    /// The depth at the cell nearest pixel `(u, v)` (`NaN` where there is none or outside).
    pub fn nearest(&self, u: f64, v: f64) -> f32 {
        let (x, y) = self.cell(u, v);
        self.at(x, y)
    }

    /// The cell nearest pixel `(u, v)`.
    fn cell(&self, u: f64, v: f64) -> (i64, i64) {
        let s = self.step as f64;
        ((u / s).round() as i64, (v / s).round() as i64)
    }

    /// Pixels with a depth.
    pub fn count(&self) -> usize {
        self.depth.iter().filter(|d| d.is_finite()).count()
    }
}

/// What [`carve_by_stereo`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StereoSummary {
    /// Silhouette pixels with a depth kept by the sweep, over all photos.
    pub matched: usize,
    /// Of those, confirmed by another photo.
    pub confirmed: usize,
    /// Silhouette pixels over all photos.
    pub silhouette: usize,
    /// Voxels carved as free space.
    pub carved: usize,
    /// Voxels carved as seen by no photo ([`carve_unseen`]).
    pub unseen: usize,
}

struct Plane {
    w: usize,
    h: usize,
    /// Channels per pixel, interleaved in `v`.
    c: usize,
    v: Vec<f32>,
}

impl Plane {
    /// One channel (luma) or the three of `img` ([`StereoParams::colour`]).
    fn of(img: &RgbImage, colour: bool) -> Self {
        let v = if colour {
            img.pixels().flat_map(|p| p.0.map(f32::from)).collect()
        } else {
            img.pixels()
                .map(|p| 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32)
                .collect()
        };
        Plane {
            w: img.width() as usize,
            h: img.height() as usize,
            c: if colour { 3 } else { 1 },
            v,
        }
    }
}

/// The map from a reference pixel at camera depth `d` to a source pixel:
/// `x_s ~ d A [u v 1] + b`.
struct Transfer {
    a: Matrix3<f64>,
    b: Vector3<f64>,
    src: usize,
}

impl Transfer {
    fn new(r: &Camera, s: &Camera, src: usize) -> Self {
        let kinv =
            r.k.try_inverse()
                .expect("K is invertible: checked by Camera::new");
        let rel = s.r * r.r.transpose();
        Transfer {
            a: s.k * rel * kinv,
            b: s.k * (s.t - rel * r.t),
            src,
        }
    }
}

/// What every depth map of photo `i` starts from: its inverse intrinsics, the maps into its
/// `p.sources` nearest other photos by viewing direction, and the window's samples (half side
/// `p.radius`, every `p.stride` pixels) as offsets.
fn setup(
    i: usize,
    cams: &[Camera],
    centre: &Vector3<f64>,
    p: &StereoParams,
) -> (Matrix3<f64>, Vec<Transfer>, Window) {
    let kinv = cams[i]
        .k
        .try_inverse()
        .expect("K is invertible: checked by Camera::new");
    let transfers = nearest_by_direction(cams, &cams[i], centre, p.sources + 1)
        .into_iter()
        .filter(|&j| j != i)
        .take(p.sources)
        .map(|j| Transfer::new(&cams[i], &cams[j], j))
        .collect();
    let (r, stride) = (p.radius, p.stride as usize);
    let offsets = (-r..=r)
        .step_by(stride)
        .flat_map(|dy| (-r..=r).step_by(stride).map(move |dx| (dx, dy)))
        .collect();
    (kinv, transfers, Window::new(offsets))
}

/// The reference window at pixel `(x, y)` into `refv` (`offsets.len()` times the channels,
/// interleaved), each channel centred (mean 0); returns its energy (the sum of squares) and its
/// standard deviation.
fn reference_window(
    plane: &Plane,
    x: usize,
    y: usize,
    offsets: &[(i32, i32)],
    refv: &mut [f32],
) -> (f32, f64) {
    let c = plane.c;
    let n = offsets.len() as f32;
    let mut mean = [0f32; 3];
    for (k, &(dx, dy)) in offsets.iter().enumerate() {
        let i = ((y as i64 + dy as i64) as usize * plane.w + (x as i64 + dx as i64) as usize) * c;
        for ch in 0..c {
            refv[k * c + ch] = plane.v[i + ch];
            mean[ch] += plane.v[i + ch];
        }
    }
    let mut var = 0.0;
    for (j, v) in refv.iter_mut().enumerate() {
        *v -= mean[j % c] / n;
        var += *v * *v;
    }
    (var, ((var / refv.len() as f32) as f64).sqrt())
}

/// The window's sample offsets ([`setup`]) and the four corners of their lattice: the
/// offsets span a square lattice, so a map that is linear (or projective with a positive
/// denominator) over the square reaches its extremes at these corners.
pub(super) struct Window {
    offsets: Vec<(i32, i32)>,
    /// The offsets' coordinates as floats, apart.
    dx: Vec<f32>,
    dy: Vec<f32>,
    corners: [(i32, i32); 4],
}

impl Window {
    fn new(offsets: Vec<(i32, i32)>) -> Self {
        let x0 = offsets.iter().map(|o| o.0).min().unwrap_or(0);
        let x1 = offsets.iter().map(|o| o.0).max().unwrap_or(0);
        let y0 = offsets.iter().map(|o| o.1).min().unwrap_or(0);
        let y1 = offsets.iter().map(|o| o.1).max().unwrap_or(0);
        Window {
            dx: offsets.iter().map(|o| o.0 as f32).collect(),
            dy: offsets.iter().map(|o| o.1 as f32).collect(),
            offsets,
            corners: [(x0, y0), (x1, y0), (x0, y1), (x1, y1)],
        }
    }

    fn len(&self) -> usize {
        self.offsets.len()
    }
}

/// NCC of the centred reference window `refv` (energy `var`) against photo `src` through the
/// homography `h` (columns): the window's sample at offset `(dx, dy)` lands at the homogeneous
/// source pixel `h0 dx + h1 dy + h2`, each channel centred. `None` when the window reaches
/// behind the source camera or out of its photo; both are decided at the lattice's corners
/// (the image of the window's square under a homography whose denominator stays positive is
/// the convex quadrilateral of the corners' images), so the samples themselves need no test.
#[inline]
fn ncc(src: &Plane, refv: &[f32], var: f32, window: &Window, h: [Vector3<f64>; 3]) -> Option<f32> {
    let at = |dx: f64, dy: f64| h[0] * dx + h[1] * dy + h[2];
    let (wmax, hmax) = ((src.w - 1) as f64, (src.h - 1) as f64);
    for &(dx, dy) in &window.corners {
        let q = at(dx as f64, dy as f64);
        if q.z <= 1e-9 {
            return None;
        }
        let (x, y) = (q.x / q.z, q.y / q.z);
        // Strictly inside: a bilinear sample needs the pixel to its right and below.
        if !(x >= 0.0 && y >= 0.0 && x < wmax && y < hmax) {
            return None;
        }
    }
    // The samples in f32, relative to the window's centre (coordinates of a few pixels).
    let h: [[f32; 3]; 3] = h.map(|c| [c.x as f32, c.y as f32, c.z as f32]);
    match src.c {
        1 => Some(ncc_lattice::<1>(src, refv, var, window, &h)),
        _ => Some(ncc_lattice::<3>(src, refv, var, window, &h)),
    }
}

/// [`ncc`]'s samples and sums for `C` channels, in one pass: the reference is centred, so the
/// covariance is the plain sum of products, and each source channel's energy is its sum of
/// squares less its mean's share, taken about the first sample (no cancellation).
#[inline]
fn ncc_lattice<const C: usize>(
    src: &Plane,
    refv: &[f32],
    var: f32,
    window: &Window,
    h: &[[f32; 3]; 3],
) -> f32 {
    let row = src.w * C;
    // The corners bound every sample; the clamps only absorb f32 rounding at the rim.
    let (xmax, ymax) = ((src.w - 2) as u32, (src.h - 2) as u32);
    let (mut cov, mut sum, mut sq) = (0f32, [0f32; C], [0f32; C]);
    let mut pivot = [0f32; C];
    // Sixteen samples at a time: where each lands (the top-left pixel's index and the bilinear
    // weights) for all of them first, a loop with no dependence between samples that runs in
    // vector registers, then their values.
    const LANES: usize = 16;
    let (mut px, mut py) = ([0u32; LANES], [0u32; LANES]);
    let (mut wx, mut wy) = ([0f32; LANES], [0f32; LANES]);
    for (chunk, ((dxs, dys), refs)) in window
        .dx
        .chunks(LANES)
        .zip(window.dy.chunks(LANES))
        .zip(refv.chunks(LANES * C))
        .enumerate()
    {
        let m = dxs.len();
        for (((((&dx, &dy), x0), y0), fx), fy) in dxs
            .iter()
            .zip(dys)
            .zip(&mut px[..m])
            .zip(&mut py[..m])
            .zip(&mut wx[..m])
            .zip(&mut wy[..m])
        {
            let iz = 1.0 / (h[0][2] * dx + h[1][2] * dy + h[2][2]);
            let x = ((h[0][0] * dx + h[1][0] * dy + h[2][0]) * iz).max(0.0);
            let y = ((h[0][1] * dx + h[1][1] * dy + h[2][1]) * iz).max(0.0);
            *x0 = (x as u32).min(xmax);
            *y0 = (y as u32).min(ymax);
            *fx = x - *x0 as f32;
            *fy = y - *y0 as f32;
        }
        for (k, ((((&x0, &y0), &fx), &fy), r)) in px[..m]
            .iter()
            .zip(&py[..m])
            .zip(&wx[..m])
            .zip(&wy[..m])
            .zip(refs.chunks_exact(C))
            .enumerate()
        {
            let i = y0 as usize * row + x0 as usize * C;
            let top = &src.v[i..i + 2 * C];
            let bottom = &src.v[i + row..i + row + 2 * C];
            for ch in 0..C {
                let a = top[ch] + (top[ch + C] - top[ch]) * fx;
                let b = bottom[ch] + (bottom[ch + C] - bottom[ch]) * fx;
                let v = a + (b - a) * fy;
                if chunk == 0 && k == 0 {
                    pivot[ch] = v;
                }
                let s = v - pivot[ch];
                cov += r[ch] * s;
                sum[ch] += s;
                sq[ch] += s * s;
            }
        }
    }
    let n = window.len() as f32;
    let svar: f32 = (0..C)
        .map(|ch| (sq[ch] - sum[ch] * sum[ch] / n).max(0.0))
        .sum();
    if svar > 1e-6 {
        cov / (var * svar).sqrt()
    } else {
        0.0
    }
}

/// The mean of the `best` highest scores (sorted in place); `-inf` with fewer.
fn best_mean(scores: &mut [f32], best: usize) -> f64 {
    if scores.len() < best {
        return f64::NEG_INFINITY;
    }
    scores.sort_by(|a, b| b.total_cmp(a));
    scores[..best].iter().sum::<f32>() as f64 / best as f64
}

/// The occupied voxels along pixel `(u, v)`'s ray, sampled every half voxel inside the grid's
/// bounds from camera depth `from` on: `(t, voxel index)` in order, `t` the ray parameter,
/// which is the camera depth.
pub(crate) fn occupied_along<'a>(
    grid: &'a VoxelGrid,
    cam: &Camera,
    kinv: &Matrix3<f64>,
    (u, v): (f64, f64),
    from: f64,
) -> impl Iterator<Item = (f64, usize)> + 'a {
    let dir = cam.r.transpose() * (kinv * Vector3::new(u, v, 1.0));
    let c = cam.centre();
    let (t0, t1) = grid
        .bounds()
        .ray_span(&c, &dir)
        .map_or((0.0, -1.0), |(a, e)| (a.max(from), e));
    let dt = 0.5 * grid.voxel_size().min() / dir.norm();
    let steps = if t1 >= t0 {
        ((t1 - t0) / dt) as usize + 1
    } else {
        0
    };
    (0..steps).filter_map(move |k| {
        let t = t0 + k as f64 * dt;
        let v = grid.voxel_of(&(c + dir * t))?;
        grid.get(v[0] as i64, v[1] as i64, v[2] as i64)
            .then(|| (t, grid.index(v[0], v[1], v[2])))
    })
}

/// The stretch `[near, far]` of camera depth along pixel `(u, v)`'s ray that lies in occupied
/// voxels of `grid`, or `None`.
fn hull_interval(
    grid: &VoxelGrid,
    cam: &Camera,
    kinv: &Matrix3<f64>,
    u: f64,
    v: f64,
) -> Option<(f64, f64)> {
    let mut along = occupied_along(grid, cam, kinv, (u, v), 0.0);
    let (near, _) = along.next()?;
    let far = along.last().map_or(near, |(t, _)| t);
    Some((near, far))
}

/// The depth map of photo `i` by plane sweep inside `grid` against its nearest photos.
fn sweep(
    i: usize,
    grid: &VoxelGrid,
    cams: &[Camera],
    planes: &[Plane],
    masks: &[Mask],
    centre: &Vector3<f64>,
    p: &StereoParams,
) -> DepthMap {
    let cam = &cams[i];
    let plane = &planes[i];
    let (w, h) = (plane.w, plane.h);
    let (kinv, transfers, window) = setup(i, cams, centre, p);
    let vs = grid.voxel_size().min();
    let step = p.pixel_step;
    let (mw, mh) = (w.div_ceil(step), h.div_ceil(step));
    let rows: Vec<Vec<f32>> = (0..mh)
        .into_par_iter()
        .map(|my| {
            let y = my * step;
            let mut row = vec![f32::NAN; mw];
            let mut refv = vec![0f32; window.len() * plane.c];
            let mut scores = Vec::with_capacity(transfers.len());
            let mut samples: Vec<(f64, f64)> = Vec::new();
            let r = p.radius as usize;
            for (mx, out) in row.iter_mut().enumerate() {
                let x = mx * step;
                if !masks[i].get(x as u32, y as u32) || x < r || y < r || x + r >= w || y + r >= h {
                    continue;
                }
                let (var, spread) = reference_window(plane, x, y, &window.offsets, &mut refv);
                if spread < p.min_texture {
                    continue;
                }
                let Some((near, far)) = hull_interval(grid, cam, &kinv, x as f64, y as f64) else {
                    continue;
                };
                // Camera depth per step: the ray's depth grows by |dir| per unit of t, and t is
                // the camera depth itself.
                let ray = kinv * Vector3::new(x as f64, y as f64, 1.0);
                let dt = p.step * vs / (cam.r.transpose() * ray).norm();
                // The score of depth d: the mean NCC of the best sources.
                let mut score = |d: f64| -> f64 {
                    scores.clear();
                    for tr in &transfers {
                        // Fronto-parallel at depth d: the offsets map affinely.
                        let base = tr.a * Vector3::new(x as f64, y as f64, 1.0) * d + tr.b;
                        let h = [tr.a.column(0) * d, tr.a.column(1) * d, base];
                        if let Some(v) = ncc(&planes[tr.src], &refv, var, &window, h) {
                            scores.push(v);
                        }
                    }
                    best_mean(&mut scores, p.best)
                };
                // Coarse to fine: every `coarse` steps, then every step around the best.
                let coarse = dt * p.coarse as f64;
                samples.clear();
                let mut d = near;
                while d <= far + 1e-9 {
                    samples.push((d, score(d)));
                    d += coarse;
                }
                let Some(&(coarse_d, coarse_s)) = samples.iter().max_by(|a, b| a.1.total_cmp(&b.1))
                else {
                    continue;
                };
                // Distinct: no other depth, farther than `apart` voxels, scores nearly as well
                // (a repeated pattern matches at several depths; none of them is trusted).
                let apart = p.apart * vs / (cam.r.transpose() * ray).norm();
                let rival = samples
                    .iter()
                    .filter(|(d, _)| (d - coarse_d).abs() > apart)
                    .map(|&(_, s)| s)
                    .fold(f64::NEG_INFINITY, f64::max);
                if coarse_s - rival < p.distinct {
                    continue;
                }
                let (mut best_d, mut best_s) = (coarse_d, coarse_s);
                if p.coarse > 1 {
                    for k in 1..p.coarse as i64 {
                        for d in [coarse_d - k as f64 * dt, coarse_d + k as f64 * dt] {
                            if d < near - 1e-9 || d > far + 1e-9 {
                                continue;
                            }
                            let s = score(d);
                            if s > best_s {
                                (best_s, best_d) = (s, d);
                            }
                        }
                    }
                }
                if best_s >= p.min_ncc {
                    *out = best_d as f32;
                }
            }
            row
        })
        .collect();
    DepthMap {
        w: mw,
        h: mh,
        step,
        depth: rows.concat(),
    }
}

/// Keeps the depths another photo's map confirms (the point lands within `agree` voxels of a
/// depth there).
fn confirm(maps: &[DepthMap], cams: &[Camera], agree: f64, confirmations: usize) -> Vec<DepthMap> {
    (0..maps.len())
        .into_par_iter()
        .map(|i| {
            let m = &maps[i];
            let cam = &cams[i];
            let kinv = cam
                .k
                .try_inverse()
                .expect("K is invertible: checked by Camera::new");
            let c = cam.centre();
            let mut out = m.clone();
            for y in 0..m.h {
                for x in 0..m.w {
                    let d = m.depth[y * m.w + x];
                    if !d.is_finite() {
                        continue;
                    }
                    let (px, py) = ((x * m.step) as f64, (y * m.step) as f64);
                    let dir = cam.r.transpose() * (kinv * Vector3::new(px, py, 1.0));
                    let pt = c + dir * d as f64;
                    let agreeing = (0..maps.len())
                        .filter(|&j| j != i)
                        .filter(|&j| {
                            cams[j].project(&pt).is_some_and(|(u, v, z)| {
                                let (cu, cv) = maps[j].cell(u, v);
                                let dj = maps[j].at(cu, cv);
                                dj.is_finite() && ((dj as f64) - z).abs() <= agree
                            })
                        })
                        .count();
                    let ok = agreeing >= confirmations;
                    if !ok {
                        out.depth[y * m.w + x] = f32::NAN;
                    }
                }
            }
            out
        })
        .collect()
}

/// Depth maps of every photo (plane sweep inside `grid`, confirmed across photos).
pub fn depth_maps(
    grid: &VoxelGrid,
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    p: &StereoParams,
) -> Result<(Vec<DepthMap>, StereoSummary)> {
    p.check()?;
    Ok(measure(
        grid,
        cams,
        &planes_of(cams, images, masks, p.colour)?,
        masks,
        p,
    ))
}

/// The photos' planes (luma, or colour with [`StereoParams::colour`]), once the counts agree.
fn planes_of(
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    colour: bool,
) -> Result<Vec<Plane>> {
    if cams.len() != images.len() || cams.len() != masks.len() {
        return Err(Error::CountMismatch {
            what: "cameras vs photos vs silhouettes".into(),
            a: cams.len(),
            b: images.len().min(masks.len()),
        });
    }
    Ok(images.iter().map(|i| Plane::of(i, colour)).collect())
}

/// [`depth_maps`] from the photos' luma planes (settings checked).
fn measure(
    grid: &VoxelGrid,
    cams: &[Camera],
    planes: &[Plane],
    masks: &[Mask],
    p: &StereoParams,
) -> (Vec<DepthMap>, StereoSummary) {
    let centre = grid.bounds().centre();
    let raw: Vec<DepthMap> = if p.patchmatch > 0 {
        planes::patchmatch_all(grid, cams, planes, masks, &centre, p)
    } else {
        (0..cams.len())
            .map(|i| sweep(i, grid, cams, planes, masks, &centre, p))
            .collect()
    };
    let vs = grid.voxel_size().min();
    let maps = confirm(&raw, cams, p.agree * vs, p.confirmations);
    let summary = StereoSummary {
        matched: raw.iter().map(DepthMap::count).sum(),
        confirmed: maps.iter().map(DepthMap::count).sum(),
        silhouette: masks.iter().map(|m| m.count_ones() as usize).sum(),
        carved: 0,
        unseen: 0,
    };
    (maps, summary)
}

/// Carves from `grid` every voxel that lies more than `margin` voxels in front of the confirmed
/// depth at every confirmed pixel of its 3x3 neighbourhood in some photo (empty space the photos
/// see through). Returns the depth maps and what was done.
pub fn carve_by_stereo(
    grid: &mut VoxelGrid,
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    p: &StereoParams,
) -> Result<(Vec<DepthMap>, StereoSummary)> {
    p.check()?;
    // The luma planes serve every pass.
    let planes = planes_of(cams, images, masks, p.colour)?;
    let mut total = StereoSummary::default();
    let mut maps = Vec::new();
    for pass in 0..p.passes {
        // Every pixel's depth only for the last pass's maps: the ones the model keeps.
        let last = pass + 1 == p.passes;
        let fine = if last { p.fine } else { 0 };
        let (m, s) = measure(grid, cams, &planes, masks, &StereoParams { fine, ..*p });
        // The last pass also carves in front of its maps' holes, filled from around them.
        let filled: Vec<DepthMap>;
        let carve_maps = if last && p.hole_fill > 0 {
            filled = m
                .par_iter()
                .zip(masks)
                .map(|(d, mk)| fill_holes(d, mk, p.hole_fill))
                .collect();
            &filled
        } else {
            &m
        };
        let carved = carve_free_space(grid, cams, &m, carve_maps, p.margin, p.protect);
        maps = m;
        // The last pass's depths (each pass re-measures inside what is left).
        total = StereoSummary {
            carved: total.carved + carved,
            unseen: total.unseen,
            ..s
        };
        if pass == 0 {
            if let Some(k) = p.unseen_keep {
                total.unseen = carve_unseen(grid, cams, masks, k);
            }
        }
        if carved == 0 {
            break;
        }
    }
    Ok((maps, total))
}

/// Directions an empty cell must find a depth in before [`fill_holes`] fills it (of eight).
const FILL_SIDES: usize = 3;

/// The eight directions [`fill_holes`] looks in, in cells.
const DIRECTIONS: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

/// `map` with each empty cell inside the silhouette `mask` given the nearest of the first
/// depths found within `radius` cells in each of the eight directions, when at least
/// [`FILL_SIDES`] directions find one ([`StereoParams::hole_fill`]).
fn fill_holes(map: &DepthMap, mask: &Mask, radius: usize) -> DepthMap {
    let mut out = map.clone();
    for y in 0..map.h {
        for x in 0..map.w {
            if map.depth[y * map.w + x].is_finite() {
                continue;
            }
            let (px, py) = ((x * map.step) as u32, (y * map.step) as u32);
            if px >= mask.width() || py >= mask.height() || !mask.get(px, py) {
                continue;
            }
            let (mut sides, mut nearest) = (0, f32::INFINITY);
            for (dx, dy) in DIRECTIONS {
                let first = (1..=radius as i64)
                    .map(|k| map.at(x as i64 + dx * k, y as i64 + dy * k))
                    .find(|d| d.is_finite());
                if let Some(d) = first {
                    sides += 1;
                    nearest = nearest.min(d);
                }
            }
            if sides >= FILL_SIDES {
                out.depth[y * map.w + x] = nearest;
            }
        }
    }
    out
}

/// Carves every voxel that lies more than `margin` voxels in front of the depth at every cell of
/// its 3x3 neighbourhood in some map of `carve_maps` that has a depth (at least 5 of the 9),
/// unless some map of `maps` puts it on a surface (within `protect` voxels); returns how many.
fn carve_free_space(
    grid: &mut VoxelGrid,
    cams: &[Camera],
    maps: &[DepthMap],
    carve_maps: &[DepthMap],
    margin: f64,
    protect: f64,
) -> usize {
    let margin = margin * grid.voxel_size().min();
    let protect = protect * grid.voxel_size().min();
    let occupied = grid.occupied();
    let carve: Vec<usize> = occupied
        .par_iter()
        .copied()
        .filter(|&idx| {
            let x = grid.centre(grid.coords(idx));
            // A voxel that some photo's depth puts on a surface is kept whatever another
            // photo's (possibly too deep) depth says.
            let on_surface = protect > 0.0
                && cams.iter().zip(maps).any(|(cam, m)| {
                    cam.project(&x).is_some_and(|(u, v, z)| {
                        let (ui, vi) = m.cell(u, v);
                        let d = m.at(ui, vi);
                        d.is_finite() && (z - d as f64).abs() <= protect
                    })
                });
            !on_surface
                && cams.iter().zip(carve_maps).any(|(cam, m)| {
                    let Some((u, v, z)) = cam.project(&x) else {
                        return false;
                    };
                    let (ui, vi) = m.cell(u, v);
                    let mut seen = 0;
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let d = m.at(ui + dx, vi + dy);
                            if d.is_nan() {
                                continue;
                            }
                            if z >= d as f64 - margin {
                                return false;
                            }
                            seen += 1;
                        }
                    }
                    seen >= 5
                })
        })
        .collect();
    for &i in &carve {
        grid.set_index(i, false);
    }
    carve.len()
}

/// Keeps only the voxels within `keep` voxels (6-connected steps through occupied voxels) of a
/// voxel some photo sees first along one of its silhouette rays; carves the rest. A few views'
/// hull keeps phantom volume that every photo sees only from behind a real surface (under a
/// base plate that every camera looks down on, between parts): no photo can show it, and a new
/// view would show it as a wall. Returns how many voxels were carved.
pub fn carve_unseen(grid: &mut VoxelGrid, cams: &[Camera], masks: &[Mask], keep: usize) -> usize {
    let n = grid.dims().iter().product::<usize>();
    let seen_lists: Vec<Vec<usize>> = cams
        .par_iter()
        .zip(masks)
        .map(|(cam, m)| {
            let kinv = cam
                .k
                .try_inverse()
                .expect("K is invertible: checked by Camera::new");
            let mut hits = Vec::new();
            for y in 0..m.height() {
                for x in 0..m.width() {
                    if !m.get(x, y) {
                        continue;
                    }
                    if let Some(v) = first_hit(grid, cam, &kinv, x as f64, y as f64) {
                        hits.push(v);
                    }
                }
            }
            hits
        })
        .collect();
    let mut dist = vec![u16::MAX; n];
    let mut queue = std::collections::VecDeque::new();
    for &i in seen_lists.iter().flatten() {
        if dist[i] != 0 {
            dist[i] = 0;
            queue.push_back(i);
        }
    }
    let [nx, ny, nz] = grid.dims();
    while let Some(i) = queue.pop_front() {
        let d = dist[i];
        if d as usize >= keep {
            continue;
        }
        let [x, y, z] = grid.coords(i);
        let (x, y, z) = (x as i64, y as i64, z as i64);
        for (dx, dy, dz) in [
            (1, 0, 0),
            (-1, 0, 0),
            (0, 1, 0),
            (0, -1, 0),
            (0, 0, 1),
            (0, 0, -1),
        ] {
            let (a, b, c) = (x + dx, y + dy, z + dz);
            if a < 0 || b < 0 || c < 0 || a >= nx as i64 || b >= ny as i64 || c >= nz as i64 {
                continue;
            }
            if !grid.get(a, b, c) {
                continue;
            }
            let j = grid.index(a as usize, b as usize, c as usize);
            if dist[j] == u16::MAX {
                dist[j] = d + 1;
                queue.push_back(j);
            }
        }
    }
    let mut carved = 0;
    for i in grid.occupied() {
        if dist[i] == u16::MAX {
            grid.set_index(i, false);
            carved += 1;
        }
    }
    carved
}

/// The first occupied voxel along pixel `(u, v)`'s ray.
fn first_hit(grid: &VoxelGrid, cam: &Camera, kinv: &Matrix3<f64>, u: f64, v: f64) -> Option<usize> {
    occupied_along(grid, cam, kinv, (u, v), 0.0)
        .next()
        .map(|(_, i)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 12x10 map at every second pixel of a 24x20 photo: depth 5 everywhere but a hole.
    fn holed(hole: impl Fn(usize, usize) -> bool) -> DepthMap {
        let (w, h) = (12, 10);
        DepthMap {
            w,
            h,
            step: 2,
            depth: (0..w * h)
                .map(|i| {
                    if hole(i % w, i / w) {
                        f32::NAN
                    } else {
                        5.0 + (i % w) as f32 * 0.1
                    }
                })
                .collect(),
        }
    }

    #[test]
    fn holes_take_the_nearest_depth_around_them_inside_the_silhouette_only() {
        let all = Mask::from_fn(24, 20, |_, _| true);
        // A 3x3 hole at cells 4..=6: every cell sees depths on every side within 2 cells.
        let map = holed(|x, y| (4..=6).contains(&x) && (4..=6).contains(&y));
        let f = fill_holes(&map, &all, 2);
        for y in 4..=6 {
            for x in 4..=6 {
                // The nearest (smallest) depth found: the one towards x = 3 or below.
                let nearest = DIRECTIONS
                    .iter()
                    .filter_map(|&(dx, dy)| {
                        (1..=2)
                            .map(|s| map.at(x + dx * s, y + dy * s))
                            .find(|d| d.is_finite())
                    })
                    .fold(f32::INFINITY, f32::min);
                assert_eq!(f.at(x, y), nearest, "cell ({x}, {y})");
                assert!(nearest < 5.0 + 0.1 * x as f32, "cell ({x}, {y})");
            }
        }
        // Out of reach: a radius of 1 cell leaves the hole's centre empty (no depth within 1 cell
        // in any direction), and fills its rim.
        let f1 = fill_holes(&map, &all, 1);
        assert!(f1.at(5, 5).is_nan());
        assert!(f1.at(4, 4).is_finite());
        // Outside the silhouette nothing is filled.
        let left = Mask::from_fn(24, 20, |x, _| x < 10);
        let f2 = fill_holes(&map, &left, 2);
        assert!(f2.at(4, 5).is_finite() && f2.at(5, 5).is_nan() && f2.at(6, 5).is_nan());
        // The depths that were there are kept as they were.
        for (a, b) in map.depth.iter().zip(&f.depth) {
            assert!(a.is_nan() || a == b);
        }
    }

    #[test]
    fn holes_seen_from_fewer_than_three_sides_stay_empty() {
        let all = Mask::from_fn(24, 20, |_, _| true);
        // Every cell with x >= 3 is empty: cell (3, 5) finds depths towards -x only, in three
        // directions ((-1, 0), (-1, 1), (-1, -1)); cell (4, 5) within 1 cell in none.
        let map = holed(|x, _| x >= 3);
        let f = fill_holes(&map, &all, 1);
        assert!(f.at(3, 5).is_finite());
        assert!(f.at(4, 5).is_nan());
        // At the map's corner cell (3, 0) only two of those directions lie inside the map.
        assert!(f.at(3, 0).is_nan());
    }
}
