//! Per-region loops baked into one seamless loop (issue 23, beyond the thesis's one loop per
//! view; after Liao, Joshi and Hoppe 2013, "Automated video looping with progressive dynamism").
//!
//! The view is cut into square tiles. Each tile gets its own label: a start `s` and a period `p`
//! from a small set of periods that all divide one loop length `L`, so that output frame `t` shows
//! at that tile source frame `phi(t) = s + ((t - s) mod p)` and the whole output repeats after
//! `L` frames. Labels minimise, at reduced resolution and weighted by the dynamic region,
//!
//! - the temporal cost of each tile's own wrap, `|V(s) - V(s + p)|^2 + |V(s - 1) - V(s + p - 1)|^2`
//!   summed over the tile's pixels (what would follow frame `s + p - 1` against what does), and
//! - `lambda` times the spatial cost of each pair of neighbouring tiles, the mean over the loop's
//!   `L` frames of `|V(phi_a(t)) - V(phi_b(t))|^2` on the pixels either side of their shared
//!   edge (zero where the two tiles share a label),
//!
//! by iterated conditional modes ([`Problem::icm`]) from the best single label and from each
//! tile's own best label (the lower energy kept), for each loop
//! length in a short list (the thesis's own period among them, so its single loop stays a
//! candidate), keeping the lowest energy. [`compose`] then bakes the `L + 1` frames (frame `L`
//! repeats frame 0, so a player looping `(0, L)` wraps onto the frame that would come next),
//! feathering each tile into its neighbours over `feather` pixels; masks follow each pixel's own
//! tile. Everything is computed offline: the renderer plays the baked frames as any loop.

use std::borrow::Borrow;

use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{Error, Mask, Result};

mod bake;
mod quality;
mod solve;

#[cfg(test)]
use bake::tile_pixels;
pub use bake::{compose, correction, single_loop, spreads, AxisBlend, Bake};
use quality::{mad, median};
pub use quality::{
    quality, quality_of, quality_of_single, quality_with, single_frame, single_frames, wraps_in,
    wraps_of, Quality, SourceEnergy,
};
pub use solve::{reduction, search_bytes, solve, Problem, Strips, Temporal};

/// The parameters of per-region loops.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionParams {
    /// Tile side, full-resolution pixels, at the base reduction `scale`: frames reduced further
    /// get tiles as much larger (the chosen side is [`RegionLoop::tile`]).
    pub tile: u32,
    /// Reduction of the frames the labels are chosen on (block mean of `scale` x `scale`), at
    /// least: doubled for large frames, the tile side with it, to at most 32,768 reduced
    /// pixels (or a 256-pixel tile).
    pub scale: u32,
    /// Longest baked loop, frames.
    pub max_length: usize,
    /// Weight of the spatial term against the temporal one.
    pub spatial: f32,
    /// Width of the feather between tiles with different labels, full-resolution pixels.
    pub feather: u32,
    /// Most ICM sweeps per loop length.
    pub sweeps: usize,
    /// Most source frames considered (a window holding the thesis's loop).
    pub max_frames: usize,
    /// The wrap correction ([`correction`]): the Gaussian sigma (pixels) of its spatial
    /// low-pass, 0 for none (the default: on tree.avi's frames 0-53 it brings the tiles' wraps
    /// from 1.83x to 1.11x their ordinary step, measured before the correction was spread over
    /// only the frames it needs ([`spreads`]): sigma 1 and 2 kept 1.56x and 1.75x); None: no
    /// correction (each tile's wrap is one step).
    #[serde(default)]
    pub blend: Option<f32>,
    /// Keep the baked loop only where it measures better than the thesis's loop on the same
    /// frames ([`Quality::better_than`]); the view keeps its thesis loop otherwise
    /// (`vt analyze --loops auto`, the default). False: always bake (`--loops regions`).
    #[serde(default)]
    pub only_if_better: bool,
    /// The most a frame of a tile's wrap correction may add, in the tile's ordinary steps: the
    /// correction is spread over as few frames around the wrap as that allows ([`spreads`]), so
    /// the rest keep their source frames; 0: over the whole cycle (the least-squares solution).
    #[serde(default = "default_spread")]
    pub spread: f32,
}

fn default_spread() -> f32 {
    DEFAULT_SPREAD
}

/// Default [`RegionParams::spread`]: on tree.avi's frames 0-53 the tiles' wraps 1.11x their
/// ordinary step, sharpness near them 0.954, 0.34 grey levels from the source (0.5: 1.04x,
/// 0.946, 0.47; 1: 1.18x, 0.957, 0.30; the whole cycle: 1.02x, 0.960, 2.02).
pub const DEFAULT_SPREAD: f32 = 0.75;

impl Default for RegionParams {
    fn default() -> Self {
        Self {
            tile: 16,
            scale: 2,
            max_length: 240,
            spatial: 10.0,
            feather: 8,
            sweeps: 12,
            max_frames: 128,
            blend: Some(0.0),
            only_if_better: false,
            spread: DEFAULT_SPREAD,
        }
    }
}

impl RegionParams {
    /// The parameters' rules.
    pub fn check(&self) -> Result<()> {
        let bad = |name, value: String, why: &str| {
            Err(Error::InvalidParameter {
                name,
                value,
                why: why.into(),
            })
        };
        if !(4..=256).contains(&self.tile) {
            return bad("regions.tile", self.tile.to_string(), "4 to 256 pixels");
        }
        if self.scale == 0 || self.scale > self.tile || !self.tile.is_multiple_of(self.scale) {
            return bad(
                "regions.scale",
                self.scale.to_string(),
                "at least 1 and dividing the tile side",
            );
        }
        if !(2..=2000).contains(&self.max_length) {
            return bad(
                "regions.max_length",
                self.max_length.to_string(),
                "2 to 2000 frames",
            );
        }
        if !(self.spatial.is_finite() && (0.0..=1e6).contains(&self.spatial)) {
            return bad("regions.spatial", self.spatial.to_string(), "0 to 1e6");
        }
        if self.feather > self.tile {
            return bad(
                "regions.feather",
                self.feather.to_string(),
                "at most the tile side",
            );
        }
        if let Some(b) = self.blend {
            if !(b.is_finite() && (0.0..=64.0).contains(&b)) {
                return bad("regions.blend", b.to_string(), "0 to 64 pixels");
            }
        }
        if !(self.spread.is_finite() && (0.0..=100.0).contains(&self.spread)) {
            return bad(
                "regions.spread",
                self.spread.to_string(),
                "0 (the whole cycle) to 100 ordinary steps",
            );
        }
        if !(4..=1000).contains(&self.max_frames) {
            return bad(
                "regions.max_frames",
                self.max_frames.to_string(),
                "4 to 1000 frames",
            );
        }
        Ok(())
    }
}

/// A tile's loop: output frame `t` shows source frame `start + ((t - start) mod period)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Label {
    /// First source frame of the loop.
    pub start: usize,
    /// Frames per cycle.
    pub period: usize,
}

impl Label {
    /// The source frame shown at output frame `t`.
    pub fn frame(&self, t: usize) -> usize {
        let p = self.period;
        self.start + (t + p - self.start % p) % p
    }
}

/// The source frames a per-region loop is chosen and baked from: RGB images, or the frames as
/// the analysis holds them ([`crate::analysis::Frame`]: 4:2:0 video frames, converted pixel by
/// pixel as the bake reads them, so that a window of HD frames takes half the memory of RGB).
pub trait Frames: Sync {
    /// How many frames.
    fn count(&self) -> usize;
    /// `(width, height)` of every frame.
    fn dimensions(&self) -> (u32, u32);
    /// Pixel `(x, y)` of frame `f`, RGB.
    fn px(&self, f: usize, x: u32, y: u32) -> [u8; 3];
    /// Frame `f` in RGB, into `out` (resized if needed).
    fn rgb_into(&self, f: usize, out: &mut RgbImage);
    /// Pixels `x0..x1` of rows `y0..y1` of frame `f` in RGB, row after row, into `out` (its
    /// length set): what [`Frames::px`] gives there, read a row at a time where the frames
    /// allow.
    fn rect_into(&self, f: usize, [x0, x1, y0, y1]: [usize; 4], out: &mut Vec<u8>) {
        out.clear();
        for y in y0..y1 {
            for x in x0..x1 {
                out.extend_from_slice(&self.px(f, x as u32, y as u32));
            }
        }
    }
}

/// [`Frames::rect_into`] of one RGB image.
fn rgb_rect_into(img: &RgbImage, [x0, x1, y0, y1]: [usize; 4], out: &mut Vec<u8>) {
    let (w, raw) = (img.width() as usize, img.as_raw());
    out.clear();
    for y in y0..y1 {
        out.extend_from_slice(&raw[3 * (y * w + x0)..3 * (y * w + x1)]);
    }
}

impl Frames for [RgbImage] {
    fn count(&self) -> usize {
        self.len()
    }
    fn dimensions(&self) -> (u32, u32) {
        self[0].dimensions()
    }
    #[inline]
    fn px(&self, f: usize, x: u32, y: u32) -> [u8; 3] {
        self[f].get_pixel(x, y).0
    }
    fn rgb_into(&self, f: usize, out: &mut RgbImage) {
        crate::analysis::FrameRef::Rgb(&self[f]).to_rgb_into(out)
    }
    fn rect_into(&self, f: usize, rect: [usize; 4], out: &mut Vec<u8>) {
        rgb_rect_into(&self[f], rect, out)
    }
}

impl Frames for [crate::analysis::Frame] {
    fn count(&self) -> usize {
        self.len()
    }
    fn dimensions(&self) -> (u32, u32) {
        self[0].as_ref().dimensions()
    }
    #[inline(always)]
    fn px(&self, f: usize, x: u32, y: u32) -> [u8; 3] {
        match &self[f] {
            crate::analysis::Frame::Rgb(img) => img.get_pixel(x, y).0,
            crate::analysis::Frame::Yuv420(img) => img.pixel(x, y),
        }
    }
    fn rgb_into(&self, f: usize, out: &mut RgbImage) {
        self[f].as_ref().to_rgb_into(out)
    }
    fn rect_into(&self, f: usize, rect: [usize; 4], out: &mut Vec<u8>) {
        let [x0, x1, y0, y1] = rect;
        match &self[f] {
            crate::analysis::Frame::Rgb(img) => rgb_rect_into(img, rect, out),
            crate::analysis::Frame::Yuv420(img) if x0.is_multiple_of(2) && x1.is_multiple_of(2) => {
                let row = 3 * (x1 - x0);
                out.resize(row * (y1 - y0), 0);
                for (y, dst) in (y0..y1).zip(out.chunks_exact_mut(row.max(1))) {
                    img.segment_to_rgb(y as u32, x0 as u32, x1 as u32, dst);
                }
            }
            crate::analysis::Frame::Yuv420(img) => {
                out.clear();
                for y in y0..y1 {
                    for x in x0..x1 {
                        out.extend_from_slice(&img.pixel(x as u32, y as u32));
                    }
                }
            }
        }
    }
}

impl Frames for crate::packed::PackedFrames {
    fn count(&self) -> usize {
        self.len()
    }
    fn dimensions(&self) -> (u32, u32) {
        crate::packed::PackedFrames::dimensions(self)
    }
    #[inline]
    fn px(&self, f: usize, x: u32, y: u32) -> [u8; 3] {
        self.pixel(f, x, y)
    }
    fn rgb_into(&self, f: usize, out: &mut RgbImage) {
        crate::packed::PackedFrames::rgb_into(self, f, out)
    }
}

impl<T> Frames for Vec<T>
where
    [T]: Frames,
    T: Sync,
{
    fn count(&self) -> usize {
        self.len()
    }
    fn dimensions(&self) -> (u32, u32) {
        self.as_slice().dimensions()
    }
    #[inline]
    fn px(&self, f: usize, x: u32, y: u32) -> [u8; 3] {
        self.as_slice().px(f, x, y)
    }
    fn rgb_into(&self, f: usize, out: &mut RgbImage) {
        self.as_slice().rgb_into(f, out)
    }
    fn rect_into(&self, f: usize, rect: [usize; 4], out: &mut Vec<u8>) {
        self.as_slice().rect_into(f, rect, out)
    }
}

/// Frames reduced for the label search: RGB block means in fixed point, per-pixel weights (the
/// dynamic region).
pub struct Reduced {
    /// Width and height.
    pub size: (usize, usize),
    /// One `3 * w * h` plane per frame: each block's mean times [`FIXED`], rounded (exact for
    /// the whole blocks of the power-of-two scales used, whose pixel counts divide it; half
    /// the memory of `f32`).
    pub frames: Vec<Vec<u16>>,
    /// Per-pixel weight.
    pub weight: Vec<f32>,
}

/// The fixed-point unit of [`Reduced::frames`]: 1/256 of a grey level (255 * 256 fits `u16`).
pub const FIXED: u32 = 256;

/// Most pixels of the reduced frames the labels are chosen on (320 x 240 at scale 2 holds
/// 19,200; 768 x 576 is reduced by 4 to 27,648).
const MAX_REDUCED: usize = 32_768;

/// Weight of pixels outside the dynamic region (labels there stay defined).
const OUTSIDE: f32 = 0.02;

/// Block-mean reduction of `frames` by `scale`, weighted by `alpha` (0..255; None: all 1).
pub fn reduce<F: Frames + ?Sized>(
    frames: &F,
    alpha: Option<&image::GrayImage>,
    scale: u32,
) -> Reduced {
    let (w, h) = frames.dimensions();
    let (rw, rh) = (w.div_ceil(scale) as usize, h.div_ceil(scale) as usize);
    let reduce_one = |f: &RgbImage| -> Vec<u16> {
        let mut sum = vec![0u32; 3 * rw * rh];
        let mut count = vec![0u32; rw * rh];
        for (x, y, px) in f.enumerate_pixels() {
            let i = (y / scale) as usize * rw + (x / scale) as usize;
            for c in 0..3 {
                sum[3 * i + c] += px[c] as u32;
            }
            count[i] += 1;
        }
        sum.iter()
            .enumerate()
            .map(|(k, &s)| {
                let n = count[k / 3] as u64;
                ((s as u64 * FIXED as u64 + n / 2) / n) as u16
            })
            .collect()
    };
    // One frame in RGB at a time per thread.
    let reduced: Vec<Vec<u16>> = (0..frames.count())
        .into_par_iter()
        .map_init(
            || RgbImage::new(w, h),
            |buf, i| {
                frames.rgb_into(i, buf);
                reduce_one(buf)
            },
        )
        .collect();
    let mut weight = vec![0f32; rw * rh];
    let mut count = vec![0f32; rw * rh];
    for y in 0..h {
        for x in 0..w {
            let i = (y / scale) as usize * rw + (x / scale) as usize;
            weight[i] += alpha.map_or(1.0, |a| a.get_pixel(x, y)[0] as f32 / 255.0);
            count[i] += 1.0;
        }
    }
    for (wt, n) in weight.iter_mut().zip(&count) {
        *wt = (*wt / n).max(OUTSIDE);
    }
    Reduced {
        size: (rw, rh),
        frames: reduced,
        weight,
    }
}

/// The values of [`Reduced::frames`] on a set of pixels, gathered once so that many frame pairs'
/// weighted squared RGB differences read them contiguously: `planes[3 * k + c]` holds channel
/// `c` of the set's `k`-th pixel in every frame, frame after frame.
struct Gathered {
    planes: Vec<Vec<f32>>,
    weight: Vec<f32>,
}

impl Gathered {
    fn new(r: &Reduced, pixels: &[usize]) -> Self {
        let planes = pixels
            .iter()
            .flat_map(|&k| (0..3).map(move |c| 3 * k + c))
            .map(|at| r.frames.iter().map(|f| f[at] as f32).collect())
            .collect();
        Self {
            planes,
            weight: pixels.iter().map(|&k| r.weight[k]).collect(),
        }
    }

    /// `out[t]`, for `t` in `0..out.len()`: the weighted squared RGB difference of frames
    /// `a0 + t * da` (`da` 0 or 1) and `b0 + t` over the pixels, `sum_k w_k (d0^2 + d1^2 + d2^2)` in grey
    /// levels squared, summed pixel after pixel in the set's order for each `t` (many `t` at
    /// once), so each is bit for bit the plain sum (the tests' `diff`).
    fn diffs(&self, a0: usize, da: usize, b0: usize, out: &mut [f32]) {
        // The empty sum: what `Iterator::sum` of f32 starts from.
        debug_assert!(da <= 1, "frame a steps by 0 or 1");
        let zero: f32 = std::iter::empty::<f32>().sum();
        out.fill(zero);
        let n = out.len();
        for (k, &w) in self.weight.iter().enumerate() {
            let [p0, p1, p2] = [0, 1, 2].map(|c| &self.planes[3 * k + c]);
            let (b0s, b1s, b2s) = (&p0[b0..b0 + n], &p1[b0..b0 + n], &p2[b0..b0 + n]);
            if da == 0 {
                let (a0v, a1v, a2v) = (p0[a0], p1[a0], p2[a0]);
                for t in 0..n {
                    let (d0, d1, d2) = (a0v - b0s[t], a1v - b1s[t], a2v - b2s[t]);
                    out[t] += w * (d0 * d0 + d1 * d1 + d2 * d2);
                }
            } else {
                let (a0s, a1s, a2s) = (&p0[a0..a0 + n], &p1[a0..a0 + n], &p2[a0..a0 + n]);
                for t in 0..n {
                    let (d0, d1, d2) = (a0s[t] - b0s[t], a1s[t] - b1s[t], a2s[t] - b2s[t]);
                    out[t] += w * (d0 * d0 + d1 * d1 + d2 * d2);
                }
            }
        }
        for v in out.iter_mut() {
            *v *= 1.0 / (FIXED * FIXED) as f32;
        }
    }
}

/// The chosen per-region loop of a view.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionLoop {
    /// Loop length `L` (the baked sequence holds `L + 1` frames).
    pub length: usize,
    /// Tile side, full-resolution pixels.
    pub tile: u32,
    /// Tiles across and down.
    pub grid: (usize, usize),
    /// One label per tile, row by row, in source frame numbers.
    pub labels: Vec<Label>,
    /// The energy reached, and that of the best single label of the same length.
    pub energy: f64,
    /// The best single label's energy (same loop length).
    pub single_energy: f64,
    /// Distinct periods used.
    pub periods: Vec<usize>,
    /// Seconds spent choosing labels.
    pub solve_secs: f64,
    /// Output frame 0 shows the labels' time `phase` (see [`Bake::rotated`]).
    pub phase: usize,
    /// The wrap correction's sigma ([`RegionParams::blend`]).
    pub blend: Option<f32>,
    /// How far the wrap correction is spread ([`RegionParams::spread`]).
    pub spread: f32,
}
#[cfg(test)]
mod tests {
    use super::*;

    /// Weighted squared RGB difference of frames `i` and `j` over `pixels`: the plain sum.
    fn diff(r: &Reduced, i: usize, j: usize, pixels: &[usize]) -> f32 {
        let (a, b) = (&r.frames[i], &r.frames[j]);
        let d = |k: usize| a[k] as f32 - b[k] as f32;
        // In fixed-point units squared, scaled back once: scaling by a power of two is exact, so
        // the sum is the one over grey levels bit for bit.
        let sum: f32 = pixels
            .iter()
            .map(|&k| {
                let (d0, d1, d2) = (d(3 * k), d(3 * k + 1), d(3 * k + 2));
                r.weight[k] * (d0 * d0 + d1 * d1 + d2 * d2)
            })
            .sum();
        sum * (1.0 / (FIXED * FIXED) as f32)
    }

    #[test]
    fn gathered_differences_are_the_plain_sums_bit_for_bit() {
        let mut rng = crate::rng::Rng::new(11);
        let (size, n) = ((9, 7), 13);
        let px = size.0 * size.1;
        let r = Reduced {
            size,
            frames: (0..n)
                .map(|_| {
                    (0..3 * px)
                        .map(|_| rng.range(0, 255 * FIXED as i64) as u16)
                        .collect()
                })
                .collect(),
            weight: (0..px)
                .map(|k| {
                    if k % 5 == 0 {
                        OUTSIDE
                    } else {
                        1.0 + k as f32 / 7.0
                    }
                })
                .collect(),
        };
        let pixels: Vec<usize> = (0..px).filter(|k| k % 3 != 1).collect();
        let g = Gathered::new(&r, &pixels);
        for i in 0..n {
            // Against every later frame (a strip's triangle row) ...
            let mut row = vec![0.0; n - 1 - i];
            g.diffs(i, 0, i + 1, &mut row);
            for (t, v) in row.iter().enumerate() {
                assert_eq!(v.to_bits(), diff(&r, i, i + 1 + t, &pixels).to_bits());
            }
        }
        for p in 1..n {
            // ... and frame pairs a period apart (a tile's temporal costs).
            let mut per = vec![0.0; n - p];
            g.diffs(0, 1, p, &mut per);
            for (i, v) in per.iter().enumerate() {
                assert_eq!(v.to_bits(), diff(&r, i, i + p, &pixels).to_bits());
            }
        }
    }

    #[test]
    fn label_frames_cycle() {
        let l = Label {
            start: 7,
            period: 5,
        };
        let seq: Vec<usize> = (0..12).map(|t| l.frame(t)).collect();
        assert_eq!(seq, vec![10, 11, 7, 8, 9, 10, 11, 7, 8, 9, 10, 11]);
        // Every frame in the loop, its successor the next but for one wrap per cycle.
        for t in 0..20 {
            let (a, b) = (l.frame(t), l.frame(t + 1));
            assert!((7..12).contains(&a));
            assert!(b == a + 1 || (a == 11 && b == 7));
        }
    }
}
