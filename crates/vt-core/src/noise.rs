//! Keep the motion: a per-pixel noise model for the moving-object masks, and each view's
//! *dynamic region* (the pixels that move often enough), which the renderer shows from the source
//! frame itself instead of the static median background.
//!
//! Why. One global threshold (the thesis's scheme, vt's old default 25) fails on real foliage: the
//! median background of a tree in wind contains the tree, and the frame-to-background differences
//! of moving leaves are mostly below 25, so masks mark speckles and a rendered view freezes.
//!
//! # Noise model
//! From a sample of the view's smoothed frames (at most [`NoiseParams::sample_frames`], evenly
//! spaced) and the smoothed median `B`, per pixel `d_t(x) = max over RGB |F_t(x) - B(x)|`:
//! - `sigma(x) = 1.4826 * median_t d_t(x)`, the temporal median absolute deviation around the
//!   median, scaled to a Gaussian's standard deviation;
//! - `sigma0` = the 10th percentile of `sigma(x)` over the image (the quietest tenth of the
//!   pixels: sensor noise, even when moving foliage fills most of the frame), at least 0.5;
//! - the mask threshold `T(x) = max(min_threshold, ceil(k * max(sigma(x), sigma0)))`: a pixel is
//!   moving when it departs from the median by more than its own noise explains. Pixels that
//!   flutter all the time (leaves) get a high threshold, so the masks used by eq. (1) and (2)
//!   keep the motion that stands out; the flutter itself is kept by the dynamic region.
//!
//! # Dynamic region
//! `D` = pixels with `d_t(x) > k * sigma0` in at least [`NoiseParams::dynamic_fraction`] of the
//! sampled frames, opened by 1 (isolated specks out) and dilated by
//! [`NoiseParams::dynamic_dilate`]. Its alpha is 255 inside `D` and falls linearly to 0 over
//! [`NoiseParams::feather`] pixels outside it (chessboard distance). The renderer shows the source
//! frame's own pixels with this alpha over the background; a static part of the scene costs
//! nothing per frame.

use image::{GrayImage, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{Error, Mask, Result};

/// Noise-model masks and dynamic region. [`NoiseParams::off`] is the thesis (one global
/// threshold, no dynamic region).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NoiseParams {
    /// Threshold in noise standard deviations; 0 = off (the global `MaskParams::threshold`).
    pub k: f32,
    /// Lowest per-pixel threshold, grey levels.
    pub min_threshold: u8,
    /// Frames sampled (evenly) for the model.
    pub sample_frames: usize,
    /// Build the dynamic region.
    pub dynamic: bool,
    /// Share of sampled frames a pixel must move in to be dynamic.
    pub dynamic_fraction: f32,
    /// Dilation of the dynamic region, pixels.
    pub dynamic_dilate: u32,
    /// Width of the alpha ramp outside the dynamic region, pixels.
    pub feather: u32,
}

impl NoiseParams {
    /// The thesis: no noise model, no dynamic region.
    pub fn off() -> Self {
        Self {
            k: 0.0,
            dynamic: false,
            ..Self::default()
        }
    }

    /// Whether anything here is on.
    pub fn enabled(&self) -> bool {
        self.k > 0.0 || self.dynamic
    }

    /// Checks the values.
    pub fn check(&self) -> Result<()> {
        let bad = |name: &'static str, value: String, why: &str| {
            Err(Error::InvalidParameter {
                name,
                value,
                why: why.into(),
            })
        };
        if !(self.k.is_finite() && self.k >= 0.0 && self.k <= 100.0) {
            return bad(
                "noise.k",
                self.k.to_string(),
                "must be in 0..=100 (0 = off)",
            );
        }
        if !(self.dynamic_fraction.is_finite() && self.dynamic_fraction > 0.0)
            || self.dynamic_fraction > 1.0
        {
            return bad(
                "dynamic fraction",
                self.dynamic_fraction.to_string(),
                "must be in (0, 1]",
            );
        }
        if self.enabled() && self.sample_frames < 3 {
            return bad(
                "noise sample frames",
                self.sample_frames.to_string(),
                "must be at least 3",
            );
        }
        if self.dynamic_dilate > 256 || self.feather > 256 {
            return bad(
                "dynamic dilate/feather",
                format!("{}/{}", self.dynamic_dilate, self.feather),
                "must be at most 256 pixels",
            );
        }
        Ok(())
    }
}

impl Default for NoiseParams {
    fn default() -> Self {
        Self {
            k: 3.0,
            min_threshold: 4,
            sample_frames: 48,
            dynamic: true,
            dynamic_fraction: 0.1,
            dynamic_dilate: 2,
            feather: 3,
        }
    }
}

/// A view's noise model and dynamic region.
#[derive(Debug, Clone)]
pub struct NoiseModel {
    /// Sensor noise estimate `sigma0`, grey levels.
    pub sigma0: f32,
    /// Per-pixel mask threshold `T(x)`, row-major.
    pub thresholds: Vec<u8>,
    /// The dynamic region `D` (None when off or empty).
    pub dynamic: Option<Mask>,
    /// Its feathered alpha (255 inside `D`), None with `dynamic`.
    pub alpha: Option<GrayImage>,
}

/// Evenly spaced sample of at most `cap` frames out of a stream of unknown length: keeps every
/// `stride`-th frame, doubling the stride (and dropping every other kept frame) when full.
#[derive(Debug, Clone)]
pub struct FrameSample<T = RgbImage> {
    cap: usize,
    stride: usize,
    frames: Vec<T>,
}

impl<T> FrameSample<T> {
    /// An empty sample holding at most `cap` (>= 2) frames.
    pub fn new(cap: usize) -> Self {
        Self {
            cap: cap.max(2),
            stride: 1,
            frames: Vec::new(),
        }
    }

    /// Whether [`FrameSample::offer`] would keep frame `index` (to skip preparing the others).
    pub fn wants(&self, index: usize) -> bool {
        let stride = if self.frames.len() == self.cap {
            2 * self.stride
        } else {
            self.stride
        };
        index.is_multiple_of(stride)
    }

    /// Offers frame `index` (frames must come in order from 0), made by `make` if kept.
    pub fn offer_with(&mut self, index: usize, make: impl FnOnce() -> T) {
        if !index.is_multiple_of(self.stride) {
            return;
        }
        if self.frames.len() == self.cap {
            let mut i = 0;
            self.frames.retain(|_| {
                i += 1;
                (i - 1) % 2 == 0
            });
            self.stride *= 2;
            if !index.is_multiple_of(self.stride) {
                return;
            }
        }
        self.frames.push(make());
    }

    /// The sampled frames, in order.
    pub fn frames(&self) -> &[T] {
        &self.frames
    }

    /// Takes the frames out.
    pub fn into_frames(self) -> Vec<T> {
        self.frames
    }
}

impl FrameSample<usize> {
    /// The indices a sample of at most `cap` frames keeps from `n` frames offered in order.
    pub fn indices(n: usize, cap: usize) -> Vec<usize> {
        let mut s = Self::new(cap);
        for i in 0..n {
            s.offer_with(i, || i);
        }
        s.into_frames()
    }
}

impl FrameSample<RgbImage> {
    /// Offers frame `index` (frames must come in order from 0).
    pub fn offer(&mut self, index: usize, frame: &RgbImage) {
        self.offer_with(index, || frame.clone());
    }
}

/// `max over RGB |a - b|` per pixel.
pub fn max_abs_diff(a: &RgbImage, b: &RgbImage, out: &mut Vec<u8>) {
    out.clear();
    out.extend(
        a.as_raw()
            .chunks_exact(3)
            .zip(b.as_raw().chunks_exact(3))
            .map(|(p, q)| {
                p[0].abs_diff(q[0])
                    .max(p[1].abs_diff(q[1]))
                    .max(p[2].abs_diff(q[2]))
            }),
    );
}

/// Builds the noise model of one view from smoothed sample frames and the smoothed median.
pub fn noise_model(
    background: &RgbImage,
    sample: &[RgbImage],
    params: &NoiseParams,
) -> Result<NoiseModel> {
    let (w, h) = background.dimensions();
    if let Some(f) = sample.iter().find(|f| f.dimensions() != (w, h)) {
        return Err(Error::SizeMismatch {
            what: "noise-model sample frame".into(),
            expected_w: w,
            expected_h: h,
            got_w: f.width(),
            got_h: f.height(),
        });
    }
    // The parameters and an empty sample are refused by `noise_model_from_diffs`.
    let rows: Vec<Vec<u8>> = sample
        .iter()
        .map(|f| {
            let mut row = Vec::new();
            max_abs_diff(f, background, &mut row);
            row
        })
        .collect();
    noise_model_from_diffs(w, h, &rows, params)
}

/// [`noise_model`] from the sample frames' differences to the background, one
/// [`max_abs_diff`] row per frame (so a caller can drop each frame once its row is made).
pub fn noise_model_from_diffs(
    w: u32,
    h: u32,
    rows: &[Vec<u8>],
    params: &NoiseParams,
) -> Result<NoiseModel> {
    params.check()?;
    let n_px = w as usize * h as usize;
    if rows.is_empty() {
        return Err(Error::InvalidParameter {
            name: "noise sample",
            value: "0 frames".into(),
            why: "the noise model needs frames".into(),
        });
    }
    if rows.iter().any(|r| r.len() != n_px) {
        return Err(Error::InvalidParameter {
            name: "noise sample",
            value: format!(
                "rows of {:?} pixels",
                rows.iter().map(Vec::len).collect::<Vec<_>>()
            ),
            why: format!("one difference per pixel of {w}x{h}"),
        });
    }
    // Per pixel, the sample's differences: pixel-major so each pixel's median is one slice.
    let n = rows.len();
    let mut diffs = vec![0u8; n_px * n];
    for (t, row) in rows.iter().enumerate() {
        for (i, &d) in row.iter().enumerate() {
            diffs[i * n + t] = d;
        }
    }
    let sigma: Vec<f32> = diffs
        .par_chunks_mut(n)
        .map(|d| {
            let mid = (n - 1) / 2;
            let (_, m, _) = d.select_nth_unstable(mid);
            1.4826 * *m as f32
        })
        .collect();
    let mut sorted = sigma.clone();
    let p10 = (sorted.len() - 1) / 10;
    let (_, s0, _) = sorted.select_nth_unstable_by(p10, f32::total_cmp);
    let sigma0 = s0.max(0.5);
    let k = params.k;
    let thresholds: Vec<u8> = sigma
        .iter()
        .map(|&s| {
            let t = if k > 0.0 {
                (k * s.max(sigma0)).ceil()
            } else {
                0.0
            };
            t.clamp(params.min_threshold as f32, 255.0) as u8
        })
        .collect();
    let (dynamic, alpha) = if params.dynamic {
        // The differences were reordered by the medians, but counts do not care about order.
        let limit = (k.max(1.0) * sigma0).ceil() as u8;
        let need = ((params.dynamic_fraction * n as f32).ceil() as usize).max(1);
        let moving = Mask::from_index_fn(w, h, |i| {
            diffs[i * n..(i + 1) * n]
                .iter()
                .filter(|&&d| d > limit)
                .count()
                >= need
        });
        let d = moving.open(1).dilate(params.dynamic_dilate);
        if d.count_ones() == 0 {
            (None, None)
        } else {
            let alpha = feather(&d, params.feather);
            (Some(d), Some(alpha))
        }
    } else {
        (None, None)
    };
    Ok(NoiseModel {
        sigma0,
        thresholds,
        dynamic,
        alpha,
    })
}

/// Alpha of a region: 255 inside, falling linearly to 0 over `width` pixels outside
/// (chessboard distance d: `255 * (1 - d / (width + 1))`).
pub fn feather(region: &Mask, width: u32) -> GrayImage {
    let (w, h) = (region.width(), region.height());
    let mut alpha = GrayImage::new(w, h);
    let mut ring = region.clone();
    let mut inside = region.clone();
    for y in 0..h {
        for x in 0..w {
            if region.get(x, y) {
                alpha.put_pixel(x, y, image::Luma([255]));
            }
        }
    }
    for d in 1..=width {
        let grown = ring.dilate(1);
        let a = (255.0 * (1.0 - d as f32 / (width + 1) as f32)).round() as u8;
        for y in 0..h {
            for x in 0..w {
                if grown.get(x, y) && !inside.get(x, y) {
                    alpha.put_pixel(x, y, image::Luma([a]));
                    inside.set(x, y, true);
                }
            }
        }
        ring = grown;
    }
    alpha
}

/// The noise-model mask: moving where `max over RGB |frame - background| > T(x)`.
pub fn noise_mask(frame: &RgbImage, background: &RgbImage, thresholds: &[u8]) -> Result<Mask> {
    if frame.dimensions() != background.dimensions()
        || thresholds.len() != frame.width() as usize * frame.height() as usize
    {
        return Err(Error::SizeMismatch {
            what: "noise mask frame vs background".into(),
            expected_w: background.width(),
            expected_h: background.height(),
            got_w: frame.width(),
            got_h: frame.height(),
        });
    }
    Ok(crate::simd::dispatch(crate::mask::PerPixelDiff {
        width: frame.width(),
        height: frame.height(),
        frame: frame.as_raw(),
        background: background.as_raw(),
        thresholds,
    }))
}

/// The real and the shown change between consecutive frames `(f0, m0)` and `(f1, m1)`, summed
/// over pixels and channels ([`MotionKept`]'s terms; one thread): `(real, kept)`, the real change
/// in grey levels and the shown one in 1/255 grey levels (exact integers).
pub fn pair_change(
    f0: &RgbImage,
    m0: &Mask,
    f1: &RgbImage,
    m1: &Mask,
    background: &RgbImage,
    alpha: Option<&GrayImage>,
) -> (u64, u64) {
    // In integers: with alphas in 0..=255, 255 R_t = a_t F_t + (255 - a_t) B, so
    // 255 (R_{t+1} - R_t) = a1 F1 - a0 F0 + (a0 - a1) B, summed as is.
    let w = f1.width() as usize;
    let (mut real, mut kept) = (0u64, 0u64);
    for (y, ((r0, r1), g)) in f0
        .as_raw()
        .chunks_exact(3 * w)
        .zip(f1.as_raw().chunks_exact(3 * w))
        .zip(background.as_raw().chunks_exact(3 * w))
        .enumerate()
    {
        let (r, k) = crate::simd::dispatch(KeptRow {
            f0: r0,
            f1: r1,
            g,
            alpha: alpha.map_or(&[][..], |al| &al.as_raw()[y * w..(y + 1) * w]),
            m0: m0.words(),
            m1: m1.words(),
            start: y * w,
        });
        real += r;
        kept += k;
    }
    (real, kept)
}

/// One row of [`pair_change`]: `(sum |F1 - F0|, sum |a1 F1 - a0 F0 + (a0 - a1) B|)` over
/// pixels and channels (the second is 255 times the shown change).
struct KeptRow<'a> {
    f0: &'a [u8],
    f1: &'a [u8],
    g: &'a [u8],
    /// The row's dynamic-region alpha (empty: none).
    alpha: &'a [u8],
    /// The two frames' masks, and the row's first pixel index in them.
    m0: &'a [u64],
    m1: &'a [u64],
    start: usize,
}

impl crate::simd::Kernel for KeptRow<'_> {
    type Output = (u64, u64);

    #[inline(always)]
    fn run(self) -> (u64, u64) {
        let (mut real, mut kept) = (0u64, 0u64);
        let w = self.f0.len() / 3;
        let has_alpha = self.alpha.len() == w;
        // Pixels in runs that share a mask word: each word read once, its bits shifted out.
        let mut x = 0;
        while x < w {
            let i = self.start + x;
            let (wi, off) = (i / 64, i % 64);
            let n = (64 - off).min(w - x);
            let (b0, b1) = (self.m0[wi] >> off, self.m1[wi] >> off);
            let span = x..x + n;
            let (f0, f1, g) = (
                &self.f0[3 * span.start..3 * span.end],
                &self.f1[3 * span.start..3 * span.end],
                &self.g[3 * span.start..3 * span.end],
            );
            for k in 0..n {
                let d = if has_alpha {
                    self.alpha[x + k] as i32
                } else {
                    0
                };
                // The dynamic alpha where it is set, else the mask bit as 0 or 255.
                let keep = ((d == 0) as i32) * 255;
                let a0 = d | (keep * ((b0 >> k) & 1) as i32);
                let a1 = d | (keep * ((b1 >> k) & 1) as i32);
                for c in 0..3 {
                    let (v0, v1, gv) = (
                        f0[3 * k + c] as i32,
                        f1[3 * k + c] as i32,
                        g[3 * k + c] as i32,
                    );
                    real += (v1 - v0).unsigned_abs() as u64;
                    kept += (a1 * v1 - a0 * v0 + (a0 - a1) * gv).unsigned_abs() as u64;
                }
            }
            x += n;
        }
        (real, kept)
    }
}

/// Accumulates the share of the real frame-to-frame change a view keeps when shown as eq. (3)-(5)
/// at its own viewpoint: shown frame `R_t = a_t F_t + (1 - a_t) B` with
/// `a_t(x)` = the dynamic-region alpha where it is set, else the object mask `I_t(x)`; kept share
/// = `sum |R_{t+1} - R_t| / sum |F_{t+1} - F_t|` over pixels, channels and consecutive frames.
#[derive(Debug, Clone, Default)]
pub struct MotionKept {
    prev: Option<(RgbImage, Mask)>,
    /// `sum |F_{t+1} - F_t|`, grey levels.
    real: u64,
    /// `sum |R_{t+1} - R_t|`, in 1/255 grey levels (integers, so the order pairs are added in
    /// never changes the figure).
    kept: u64,
}

impl MotionKept {
    /// A new, empty tally.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the next frame (raw) with its mask.
    pub fn push(
        &mut self,
        frame: &RgbImage,
        mask: &Mask,
        background: &RgbImage,
        alpha: Option<&GrayImage>,
    ) {
        if let Some((pf, pm)) = &mut self.prev {
            let (real, kept) = pair_change(pf, pm, frame, mask, background, alpha);
            self.real += real;
            self.kept += kept;
            // Reuse the buffers: no allocation per frame once warm.
            if pf.dimensions() == frame.dimensions() {
                pf.copy_from_slice(frame.as_raw());
                pm.clone_from(mask);
                return;
            }
        }
        self.prev = Some((frame.clone(), mask.clone()));
    }

    /// Adds a pair's `(real, kept)` change measured apart ([`pair_change`]); pairs may come in
    /// any order, but each consecutive pair once, and none through [`MotionKept::push`] too.
    pub fn add(&mut self, (real, kept): (u64, u64)) {
        self.real += real;
        self.kept += kept;
    }

    /// The kept share in [0, 1] (1 for a video without change).
    pub fn share(&self) -> f64 {
        if self.real > 0 {
            (self.kept as f64 / 255.0 / self.real as f64).min(1.0)
        } else {
            1.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_is_even_and_bounded() {
        let img = RgbImage::new(2, 2);
        let mut s = FrameSample::new(4);
        for i in 0..17 {
            s.offer(i, &img);
        }
        // 17 frames, cap 4: stride grows 1 -> 2 -> 4 -> 8; kept 0, 8, 16.
        assert!(s.frames().len() <= 4 && s.frames().len() >= 2);
        assert_eq!(s.stride, 8);
    }

    #[test]
    fn wants_says_which_frames_offer_keeps() {
        for cap in [2usize, 3, 5, 8] {
            let mut s = FrameSample::new(cap);
            for i in 0..200usize {
                let img = RgbImage::from_pixel(1, 1, image::Rgb([i as u8, (i >> 8) as u8, 0]));
                let wanted = s.wants(i);
                s.offer(i, &img);
                let kept = s.frames().last() == Some(&img);
                assert_eq!(wanted, kept, "cap {cap}, frame {i}");
            }
        }
    }

    #[test]
    fn indices_are_the_frames_a_sample_keeps() {
        for (n, cap) in [
            (0usize, 4usize),
            (1, 2),
            (17, 4),
            (200, 48),
            (720, 48),
            (33, 128),
        ] {
            let mut s = FrameSample::new(cap);
            for i in 0..n {
                s.offer(
                    i,
                    &RgbImage::from_pixel(1, 1, image::Rgb([i as u8, (i >> 8) as u8, 0])),
                );
            }
            let kept: Vec<usize> = s
                .frames()
                .iter()
                .map(|f| f.get_pixel(0, 0).0[0] as usize + 256 * f.get_pixel(0, 0).0[1] as usize)
                .collect();
            assert_eq!(FrameSample::indices(n, cap), kept, "{n} frames, cap {cap}");
        }
    }

    #[test]
    fn the_model_from_difference_rows_is_the_model_from_frames() {
        let bg = RgbImage::from_fn(9, 7, |x, y| {
            image::Rgb([(10 * x) as u8, (20 * y) as u8, 90])
        });
        let mut rng = crate::rng::Rng::new(3);
        let frames: Vec<RgbImage> = (0..12)
            .map(|_| {
                let mut f = bg.clone();
                for p in f.pixels_mut() {
                    for c in p.0.iter_mut() {
                        *c = c.saturating_add((rng.next_u64() % 9) as u8);
                    }
                }
                f
            })
            .collect();
        let params = NoiseParams::default();
        let a = noise_model(&bg, &frames, &params).unwrap();
        let rows: Vec<Vec<u8>> = frames
            .iter()
            .map(|f| {
                let mut r = Vec::new();
                max_abs_diff(f, &bg, &mut r);
                r
            })
            .collect();
        let b = noise_model_from_diffs(9, 7, &rows, &params).unwrap();
        assert_eq!((a.sigma0, &a.thresholds), (b.sigma0, &b.thresholds));
        assert_eq!(a.alpha, b.alpha);
        assert!(noise_model_from_diffs(
            9,
            7,
            &rows[..1]
                .iter()
                .map(|r| r[1..].to_vec())
                .collect::<Vec<_>>(),
            &params
        )
        .is_err());
    }

    #[test]
    fn fluttering_pixels_are_dynamic_and_quiet_ones_are_not() {
        // Left half flutters by +-30 every other frame; right half has +-1 noise.
        let bg = RgbImage::from_pixel(20, 10, image::Rgb([100, 100, 100]));
        let frames: Vec<RgbImage> = (0..20)
            .map(|t| {
                RgbImage::from_fn(20, 10, |x, y| {
                    let v = if x < 10 {
                        if (t + x + y) % 2 == 0 {
                            130
                        } else {
                            70
                        }
                    } else if (t + y) % 3 == 0 {
                        101
                    } else {
                        100
                    };
                    image::Rgb([v, v, v])
                })
            })
            .collect();
        let p = NoiseParams {
            dynamic_dilate: 0,
            feather: 2,
            ..Default::default()
        };
        let m = noise_model(&bg, &frames, &p).unwrap();
        let d = m.dynamic.unwrap();
        assert!(d.get(3, 5) && d.get(9, 5));
        assert!(!d.get(15, 5));
        let a = m.alpha.unwrap();
        assert_eq!(a.get_pixel(5, 5).0[0], 255);
        assert_eq!(a.get_pixel(10, 5).0[0], 170);
        assert_eq!(a.get_pixel(11, 5).0[0], 85);
        assert_eq!(a.get_pixel(12, 5).0[0], 0);
        // The flutter raises its own threshold above the flutter (30 * 1.48 * 3), quiet pixels
        // stay at the floor.
        assert!(m.thresholds[5 * 20 + 3] > 30);
        assert_eq!(m.thresholds[5 * 20 + 15], p.min_threshold);
    }

    fn random_rgb(w: u32, h: u32, rng: &mut crate::rng::Rng) -> RgbImage {
        RgbImage::from_fn(w, h, |_, _| {
            let v = rng.next_u64();
            image::Rgb([v as u8, (v >> 8) as u8, (v >> 16) as u8])
        })
    }

    #[test]
    fn noise_mask_is_the_per_pixel_rule() {
        let mut rng = crate::rng::Rng::new(5);
        for (w, h) in [(1, 1), (13, 7), (64, 3), (67, 5)] {
            let (f, b) = (random_rgb(w, h, &mut rng), random_rgb(w, h, &mut rng));
            let t: Vec<u8> = (0..w * h).map(|_| rng.next_u64() as u8).collect();
            let m = noise_mask(&f, &b, &t).unwrap();
            for y in 0..h {
                for x in 0..w {
                    let (p, q) = (f.get_pixel(x, y).0, b.get_pixel(x, y).0);
                    let d = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap();
                    assert_eq!(
                        m.get(x, y),
                        d > t[(y * w + x) as usize],
                        "{w}x{h} ({x}, {y})"
                    );
                }
            }
            assert_eq!(
                m.count_ones(),
                (0..w * h).filter(|&i| m.get(i % w, i / w)).count() as u64
            );
        }
    }

    #[test]
    fn motion_kept_matches_the_formula_in_floats() {
        let mut rng = crate::rng::Rng::new(9);
        let (w, h) = (37, 11);
        let bg = random_rgb(w, h, &mut rng);
        let frames: Vec<RgbImage> = (0..4).map(|_| random_rgb(w, h, &mut rng)).collect();
        let masks: Vec<Mask> = (0..4)
            .map(|_| {
                let seed = rng.next_u64();
                Mask::from_fn(w, h, |x, y| (seed >> ((x * 7 + y * 3) % 64)) & 1 == 1)
            })
            .collect();
        // Alpha: set on the left third, partly feathered.
        let alpha = GrayImage::from_fn(w, h, |x, _| {
            image::Luma([if x < 12 { 40 + 17 * (x as u8) } else { 0 }])
        });
        let mut kept = MotionKept::new();
        let (mut real, mut shown) = (0f64, 0f64);
        for t in 0..4 {
            kept.push(&frames[t], &masks[t], &bg, Some(&alpha));
            if t == 0 {
                continue;
            }
            for y in 0..h {
                for x in 0..w {
                    let a = alpha.get_pixel(x, y).0[0] as f64 / 255.0;
                    let pick = |m: &Mask| {
                        if a > 0.0 {
                            a
                        } else if m.get(x, y) {
                            1.0
                        } else {
                            0.0
                        }
                    };
                    let (a0, a1) = (pick(&masks[t - 1]), pick(&masks[t]));
                    for c in 0..3 {
                        let (f0, f1, g) = (
                            frames[t - 1].get_pixel(x, y).0[c] as f64,
                            frames[t].get_pixel(x, y).0[c] as f64,
                            bg.get_pixel(x, y).0[c] as f64,
                        );
                        real += (f1 - f0).abs();
                        shown += (a1 * f1 + (1.0 - a1) * g - a0 * f0 - (1.0 - a0) * g).abs();
                    }
                }
            }
        }
        let want = shown / real;
        assert!(
            (kept.share() - want).abs() < 1e-9,
            "{} vs {want}",
            kept.share()
        );
    }

    #[test]
    fn motion_kept_is_one_when_everything_is_shown_and_zero_when_nothing_is() {
        let bg = RgbImage::from_pixel(4, 4, image::Rgb([50, 50, 50]));
        let f0 = RgbImage::from_pixel(4, 4, image::Rgb([60, 50, 50]));
        let f1 = RgbImage::from_pixel(4, 4, image::Rgb([40, 50, 50]));
        let full = GrayImage::from_pixel(4, 4, image::Luma([255]));
        let none = Mask::new(4, 4);
        let mut all = MotionKept::new();
        all.push(&f0, &none, &bg, Some(&full));
        all.push(&f1, &none, &bg, Some(&full));
        assert!((all.share() - 1.0).abs() < 1e-9);
        let mut nothing = MotionKept::new();
        nothing.push(&f0, &none, &bg, None);
        nothing.push(&f1, &none, &bg, None);
        assert_eq!(nothing.share(), 0.0);
    }
}
