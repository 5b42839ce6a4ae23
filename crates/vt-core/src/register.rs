//! Automatic registration of two views' median backgrounds: the first guess of `H_(p,p+1)` when
//! no points are marked (the thesis's marked box is something users do not have).
//!
//! # Steps
//! 1. **Features** ([`detect`]): FAST-9 corners (imageproc's detector) on a pyramid of the grey
//!    image (factor [`RegisterParams::scale`] per level), 3x3 non-maximum suppression on the
//!    FAST score, then the strongest few per cell of a grid so the points cover the image.
//!    Each corner gets an orientation (intensity centroid over a disc of radius 15, Rublee et al.
//!    2011) and a 256-bit *steered* BRIEF descriptor: 256 fixed box-mean comparisons (5x5 boxes
//!    at offsets drawn once from a Gaussian by `vt_core::rng`) rotated by that orientation.
//!    Written here because imageproc's BRIEF is not steered (graf1 -> graf3 turns by about 20
//!    degrees, which upright BRIEF does not survive) and its oriented FAST keeps the top corners
//!    without suppression or spread (they cluster on the most textured patch).
//! 2. **Matching** ([`match_features`]): brute-force Hamming distance, a pair kept when it is
//!    the mutual best and passes the ratio test against the second best.
//! 3. **Robust fit** ([`ransac`]): RANSAC on 4-point homographies with adaptive iteration
//!    count, then local optimisation (refit by normalised DLT + Levenberg-Marquardt on the
//!    inliers, inliers recomputed, until they stop changing).
//! 4. **The plane that matters** ([`register_pair`]): the moving object is warped with the plane
//!    it stands in (eqs. 4-5), so when a focus region is given (the dynamic region grown by
//!    [`RegisterParams::focus_px`]) the fit uses the matches inside it, and reports how well the
//!    rest of the background agrees ([`PairRegistration::rest_inliers`]).
//! 5. **Verification**: a fit with fewer than [`RegisterParams::min_inliers`] inliers, or
//!    inliers in fewer than [`RegisterParams::min_cells`] cells of an 8x8 grid, is refused
//!    ([`crate::Error::Registration`]); nothing downstream runs on an unverified mapping.
//!
//! The analysis then selects the model by GRIC on the inliers and refines photometrically
//! ([`crate::align`]), as for marked points.

use image::{GrayImage, RgbImage};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::align::Grey;
use crate::{Error, Homography, Mask, Point, Result};

/// Registration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisterParams {
    /// Features kept per image at most (over all levels).
    pub max_features: usize,
    /// FAST threshold, grey levels.
    pub fast_threshold: u8,
    /// Pyramid levels.
    pub levels: usize,
    /// Downscale factor between levels.
    pub scale: f64,
    /// Ratio test: best distance below this fraction of the second best.
    pub ratio: f32,
    /// Largest Hamming distance (of 256) of a match.
    pub max_distance: u32,
    /// Inlier threshold of the transfer error, pixels.
    pub threshold: f64,
    /// RANSAC iterations at most.
    pub iterations: usize,
    /// Fewest inliers of a verified fit.
    pub min_inliers: usize,
    /// Fewest cells of an 8x8 grid over the first image holding an inlier.
    pub min_cells: usize,
    /// The focus region: the dynamic region grown by this many pixels.
    pub focus_px: u32,
    /// Seed of the random samples (same seed, same result).
    pub seed: u64,
}

impl Default for RegisterParams {
    fn default() -> Self {
        Self {
            max_features: 2000,
            fast_threshold: 12,
            levels: 4,
            scale: 1.3,
            ratio: 0.8,
            max_distance: 80,
            threshold: 3.0,
            iterations: 4000,
            min_inliers: 20,
            min_cells: 6,
            focus_px: 48,
            seed: 0x7652_6567,
        }
    }
}

impl RegisterParams {
    /// Checks every value against its rule (errors name the field as `register.<name>`).
    pub fn check(&self) -> Result<()> {
        let bad = |name, value: String, why: &str| {
            Err(Error::InvalidParameter {
                name,
                value,
                why: why.into(),
            })
        };
        if !(1..=100_000).contains(&self.max_features) {
            return bad(
                "register.max_features",
                self.max_features.to_string(),
                "1 to 100000",
            );
        }
        if !(1..=8).contains(&self.levels) {
            return bad("register.levels", self.levels.to_string(), "1 to 8");
        }
        if !(self.scale.is_finite() && self.scale > 1.0 && self.scale <= 2.0) {
            return bad(
                "register.scale",
                self.scale.to_string(),
                "above 1, at most 2",
            );
        }
        if !(self.ratio > 0.0 && self.ratio <= 1.0) {
            return bad("register.ratio", self.ratio.to_string(), "in (0, 1]");
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0 && self.threshold <= 100.0) {
            return bad(
                "register.threshold",
                self.threshold.to_string(),
                "a positive number of pixels, at most 100",
            );
        }
        if !(1..=1_000_000).contains(&self.iterations) {
            return bad(
                "register.iterations",
                self.iterations.to_string(),
                "1 to 1000000",
            );
        }
        if self.min_inliers < 4 {
            return bad(
                "register.min_inliers",
                self.min_inliers.to_string(),
                "at least 4 (a homography)",
            );
        }
        if self.min_cells > 64 {
            return bad(
                "register.min_cells",
                self.min_cells.to_string(),
                "at most 64 (an 8x8 grid)",
            );
        }
        if self.focus_px > 4096 {
            return bad(
                "register.focus_px",
                self.focus_px.to_string(),
                "at most 4096",
            );
        }
        Ok(())
    }
}

/// A feature: position in full-resolution pixels, orientation, level and descriptor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    /// Position (pixel centres at integers).
    pub pos: Point,
    /// Orientation, radians (image coordinates, y down).
    pub angle: f32,
    /// Pyramid level.
    pub level: u8,
    /// FAST score.
    pub score: f32,
    /// Steered BRIEF, 256 bits.
    pub descriptor: [u64; 4],
}

/// BRIEF offsets are at most this far from the centre (per coordinate).
const PATTERN_CLIP: i32 = 13;
/// Half size of a BRIEF box.
const BOX_HALF: i32 = 2;
/// Radius of the orientation disc.
const ORIENT_RADIUS: i32 = 15;
/// Border kept free at every level: a rotated offset and its box, or the orientation disc.
const EDGE: u32 = 22;

/// The 256 BRIEF test pairs, drawn once (deterministically) from a Gaussian of sigma 31/5.
fn pattern() -> &'static [[f32; 4]; 256] {
    static PATTERN: std::sync::OnceLock<[[f32; 4]; 256]> = std::sync::OnceLock::new();
    PATTERN.get_or_init(|| {
        let mut rng = crate::rng::Rng::new(0xB81E_F000);
        let mut draw = || loop {
            let v = (rng.normal() * 31.0 / 5.0).round();
            if v.abs() <= PATTERN_CLIP as f64 {
                return v as f32;
            }
        };
        let mut p = [[0.0f32; 4]; 256];
        for t in p.iter_mut() {
            *t = [draw(), draw(), draw(), draw()];
        }
        p
    })
}

/// Grey level of an RGB image (BT.601 weights, as OpenCV's `COLOR_RGB2GRAY`).
pub fn grey(img: &RgbImage) -> GrayImage {
    let (w, h) = img.dimensions();
    let mut out = GrayImage::new(w, h);
    for (o, p) in out.as_mut().iter_mut().zip(img.as_raw().chunks_exact(3)) {
        let v = 4899 * p[0] as u32 + 9617 * p[1] as u32 + 1868 * p[2] as u32;
        *o = ((v + 8192) >> 14) as u8;
    }
    out
}

/// Summed-area table with a zero first row and column.
struct Integral {
    w: usize,
    v: Vec<u32>,
}

impl Integral {
    fn new(img: &GrayImage) -> Self {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let mut v = vec![0u32; (w + 1) * (h + 1)];
        let raw = img.as_raw();
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += raw[y * w + x] as u32;
                v[(y + 1) * (w + 1) + x + 1] = v[y * (w + 1) + x + 1] + row;
            }
        }
        Self { w: w + 1, v }
    }

    /// Sum of the (2 BOX_HALF + 1)^2 box centred at (x, y) (inside the image by the caller).
    #[inline]
    fn box_sum(&self, x: i32, y: i32) -> u32 {
        let (x0, y0) = ((x - BOX_HALF) as usize, (y - BOX_HALF) as usize);
        let (x1, y1) = ((x + BOX_HALF + 1) as usize, (y + BOX_HALF + 1) as usize);
        let w = self.w;
        self.v[y1 * w + x1] + self.v[y0 * w + x0] - self.v[y0 * w + x1] - self.v[y1 * w + x0]
    }
}

/// Orientation of the patch at (x, y) by its intensity centroid over a disc.
fn orientation(img: &GrayImage, x: u32, y: u32) -> f32 {
    let (w, raw) = (img.width() as i64, img.as_raw());
    let (mut m10, mut m01) = (0i64, 0i64);
    let r = ORIENT_RADIUS as i64;
    for dy in -r..=r {
        let half = ((r * r - dy * dy) as f64).sqrt() as i64;
        let row = (y as i64 + dy) * w;
        for dx in -half..=half {
            let v = raw[(row + x as i64 + dx) as usize] as i64;
            m10 += dx * v;
            m01 += dy * v;
        }
    }
    (m01 as f32).atan2(m10 as f32)
}

fn descriptor(ii: &Integral, x: i32, y: i32, angle: f32) -> [u64; 4] {
    let (s, c) = angle.sin_cos();
    let at = |u: f32, v: f32| {
        let px = x + (c * u - s * v).round() as i32;
        let py = y + (s * u + c * v).round() as i32;
        ii.box_sum(px, py)
    };
    let mut d = [0u64; 4];
    for (i, t) in pattern().iter().enumerate() {
        if at(t[0], t[1]) < at(t[2], t[3]) {
            d[i / 64] |= 1 << (i % 64);
        }
    }
    d
}

/// Detects up to `params.max_features` oriented features with steered BRIEF descriptors.
pub fn detect(img: &GrayImage, params: &RegisterParams) -> Vec<Feature> {
    let (w0, h0) = img.dimensions();
    let mut levels = vec![img.clone()];
    for l in 1..params.levels.clamp(1, 8) {
        let f = params.scale.powi(l as i32);
        let (w, h) = (
            (w0 as f64 / f).round() as u32,
            (h0 as f64 / f).round() as u32,
        );
        if w < 4 * EDGE || h < 4 * EDGE {
            break;
        }
        levels.push(image::imageops::resize(
            img,
            w,
            h,
            image::imageops::FilterType::Triangle,
        ));
    }
    // Share of the features per level, proportional to its area (as ORB does).
    let areas: Vec<f64> = levels
        .iter()
        .map(|l| l.width() as f64 * l.height() as f64)
        .collect();
    let total: f64 = areas.iter().sum();
    let per_level: Vec<Vec<Feature>> = levels
        .par_iter()
        .enumerate()
        .map(|(l, li)| {
            let want = ((params.max_features as f64 * areas[l] / total).ceil() as usize).max(1);
            level_features(li, l as u8, want, params.fast_threshold, (w0, h0))
        })
        .collect();
    per_level.into_iter().flatten().collect()
}

fn level_features(
    img: &GrayImage,
    level: u8,
    want: usize,
    threshold: u8,
    full: (u32, u32),
) -> Vec<Feature> {
    let (w, h) = img.dimensions();
    if w <= 2 * EDGE || h <= 2 * EDGE {
        return Vec::new();
    }
    let corners = imageproc::corners::corners_fast9(img, threshold);
    // 3x3 non-maximum suppression on the score (ties to the first in raster order).
    let mut score = vec![0f32; (w * h) as usize];
    for c in &corners {
        score[(c.y * w + c.x) as usize] = c.score + 1.0;
    }
    let idx = |x: u32, y: u32| (y * w + x) as usize;
    let mut kept: Vec<(u32, u32, f32)> = corners
        .iter()
        .filter(|c| c.x >= EDGE && c.y >= EDGE && c.x < w - EDGE && c.y < h - EDGE)
        .filter(|c| {
            let s = score[idx(c.x, c.y)];
            (-1i32..=1).all(|dy| {
                (-1i32..=1).all(|dx| {
                    if dx == 0 && dy == 0 {
                        return true;
                    }
                    let o = score[idx((c.x as i32 + dx) as u32, (c.y as i32 + dy) as u32)];
                    o < s || (o == s && (dy > 0 || (dy == 0 && dx > 0)))
                })
            })
        })
        .map(|c| (c.x, c.y, c.score))
        .collect();
    // Spread: the strongest per cell of a grid with about 4x the wanted count of cells... each
    // cell keeps its share, the rest by score.
    let cells = 16u32;
    let (cw, ch) = (w.div_ceil(cells), h.div_ceil(cells));
    kept.sort_by(|a, b| b.2.total_cmp(&a.2).then((a.1, a.0).cmp(&(b.1, b.0))));
    let per_cell = want.div_ceil((cells * cells) as usize).max(1);
    let mut count = vec![0usize; (cells * cells) as usize];
    let mut chosen = Vec::with_capacity(want);
    let mut rest = Vec::new();
    for k in kept {
        let c = ((k.1 / ch) * cells + k.0 / cw) as usize;
        if count[c] < per_cell && chosen.len() < want {
            count[c] += 1;
            chosen.push(k);
        } else {
            rest.push(k);
        }
    }
    for k in rest {
        if chosen.len() >= want {
            break;
        }
        chosen.push(k);
    }
    let ii = Integral::new(img);
    let (fx, fy) = (full.0 as f64 / w as f64, full.1 as f64 / h as f64);
    chosen
        .into_iter()
        .map(|(x, y, s)| {
            let angle = orientation(img, x, y);
            Feature {
                pos: Point::new((x as f64 + 0.5) * fx - 0.5, (y as f64 + 0.5) * fy - 0.5),
                angle,
                level,
                score: s,
                descriptor: descriptor(&ii, x as i32, y as i32, angle),
            }
        })
        .collect()
}

#[inline]
fn hamming(a: &[u64; 4], b: &[u64; 4]) -> u32 {
    (a[0] ^ b[0]).count_ones()
        + (a[1] ^ b[1]).count_ones()
        + (a[2] ^ b[2]).count_ones()
        + (a[3] ^ b[3]).count_ones()
}

/// Best and second-best distance and the best's index of `d` among `set`.
fn nearest(d: &[u64; 4], set: &[Feature]) -> (u32, u32, usize) {
    let (mut b1, mut b2, mut bi) = (u32::MAX, u32::MAX, usize::MAX);
    for (j, f) in set.iter().enumerate() {
        let h = hamming(d, &f.descriptor);
        if h < b1 {
            (b2, b1, bi) = (b1, h, j);
        } else if h < b2 {
            b2 = h;
        }
    }
    (b1, b2, bi)
}

/// Matches by Hamming distance: `(i, j)` when `b[j]` is `a[i]`'s best and `a[i]` is `b[j]`'s,
/// the best is at most `max_distance` and below `ratio` times the second best.
pub fn match_features(
    a: &[Feature],
    b: &[Feature],
    ratio: f32,
    max_distance: u32,
) -> Vec<(usize, usize)> {
    let fwd: Vec<(u32, u32, usize)> = a.par_iter().map(|f| nearest(&f.descriptor, b)).collect();
    let back: Vec<usize> = b.par_iter().map(|f| nearest(&f.descriptor, a).2).collect();
    fwd.iter()
        .enumerate()
        .filter(|&(i, &(d1, d2, j))| {
            j != usize::MAX
                && back[j] == i
                && d1 <= max_distance
                && (d2 == u32::MAX || (d1 as f32) < ratio * d2 as f32)
        })
        .map(|(i, &(_, _, j))| (i, j))
        .collect()
}

/// The homography through exactly four pairs (None when degenerate).
fn four_point(src: [&Point; 4], dst: [&Point; 4]) -> Option<nalgebra::Matrix3<f64>> {
    // Refuse samples with three nearly collinear points in either image.
    for pts in [&src, &dst] {
        for (i, j, k) in [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)] {
            let (a, b, c) = (pts[i], pts[j], pts[k]);
            let area = ((b - a).x * (c - a).y - (b - a).y * (c - a).x).abs();
            if area < 4.0 {
                return None;
            }
        }
    }
    // Centre and scale for conditioning.
    let norm = |p: [&Point; 4]| {
        let c = (p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0;
        let d = p.iter().map(|q| (q.coords - c).norm()).sum::<f64>() / 4.0;
        let s = std::f64::consts::SQRT_2 / d.max(1e-12);
        (c, s)
    };
    let ((cs, ss), (cd, sd)) = (norm(src), norm(dst));
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut b = SVector::<f64, 8>::zeros();
    for i in 0..4 {
        let (x, y) = ((src[i].x - cs.x) * ss, (src[i].y - cs.y) * ss);
        let (u, v) = ((dst[i].x - cd.x) * sd, (dst[i].y - cd.y) * sd);
        let r = 2 * i;
        a.set_row(
            r,
            &SVector::<f64, 8>::from([x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]).transpose(),
        );
        a.set_row(
            r + 1,
            &SVector::<f64, 8>::from([0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]).transpose(),
        );
        b[r] = u;
        b[r + 1] = v;
    }
    let h = a.lu().solve(&b)?;
    let hn = nalgebra::Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
    let ts = nalgebra::Matrix3::new(ss, 0.0, -ss * cs.x, 0.0, ss, -ss * cs.y, 0.0, 0.0, 1.0);
    let td_inv = nalgebra::Matrix3::new(1.0 / sd, 0.0, cd.x, 0.0, 1.0 / sd, cd.y, 0.0, 0.0, 1.0);
    let m = td_inv * hn * ts;
    m.iter().all(|v| v.is_finite()).then_some(m)
}

#[inline]
fn transfer2(m: &nalgebra::Matrix3<f64>, s: &Point, d: &Point) -> f64 {
    let w = m[(2, 0)] * s.x + m[(2, 1)] * s.y + m[(2, 2)];
    if w.abs() < 1e-12 {
        return f64::INFINITY;
    }
    let x = (m[(0, 0)] * s.x + m[(0, 1)] * s.y + m[(0, 2)]) / w;
    let y = (m[(1, 0)] * s.x + m[(1, 1)] * s.y + m[(1, 2)]) / w;
    (x - d.x).powi(2) + (y - d.y).powi(2)
}

fn inliers_of(m: &nalgebra::Matrix3<f64>, src: &[Point], dst: &[Point], t2: f64) -> Vec<bool> {
    src.iter()
        .zip(dst)
        .map(|(s, d)| transfer2(m, s, d) <= t2)
        .collect()
}

/// A robust homography: RANSAC on 4-point samples (adaptive count, confidence 0.999) then
/// local optimisation on the inliers. Returns the homography and the inlier flags, or None when
/// no sample gives a finite, invertible map with at least 4 inliers.
pub fn ransac(
    src: &[Point],
    dst: &[Point],
    threshold: f64,
    iterations: usize,
    seed: u64,
) -> Option<(Homography, Vec<bool>)> {
    let n = src.len().min(dst.len());
    if n < 4 {
        return None;
    }
    let t2 = threshold * threshold;
    let mut rng = crate::rng::Rng::new(seed);
    let mut best: Option<(usize, nalgebra::Matrix3<f64>)> = None;
    let mut needed = iterations;
    let mut it = 0;
    while it < needed.min(iterations) {
        it += 1;
        let mut idx = [0usize; 4];
        for k in 0..4 {
            loop {
                let c = rng.range(0, n as i64 - 1) as usize;
                if !idx[..k].contains(&c) {
                    idx[k] = c;
                    break;
                }
            }
        }
        let Some(m) = four_point(idx.map(|i| &src[i]), idx.map(|i| &dst[i])) else {
            continue;
        };
        let count = src[..n]
            .iter()
            .zip(&dst[..n])
            .filter(|(s, d)| transfer2(&m, s, d) <= t2)
            .count();
        if best.as_ref().is_none_or(|(b, _)| count > *b) {
            best = Some((count, m));
            let w = count as f64 / n as f64;
            let p_fail = 1.0 - w.powi(4);
            if p_fail <= 0.0 {
                needed = 0;
            } else {
                let k = (0.001f64).ln() / p_fail.ln();
                needed = (k.ceil() as usize).max(50);
            }
        }
    }
    let (_, mut m) = best?;
    let mut flags = inliers_of(&m, &src[..n], &dst[..n], t2);
    // Local optimisation: least squares on the inliers until they stop changing.
    for _ in 0..8 {
        let (s, d): (Vec<Point>, Vec<Point>) = flags
            .iter()
            .enumerate()
            .filter(|(_, &f)| f)
            .map(|(i, _)| (src[i], dst[i]))
            .unzip();
        let Ok(fit) = Homography::from_correspondences(&s, &d) else {
            break;
        };
        let m2 = fit.homography.matrix();
        let f2 = inliers_of(&m2, &src[..n], &dst[..n], t2);
        let (c1, c2) = (
            flags.iter().filter(|&&f| f).count(),
            f2.iter().filter(|&&f| f).count(),
        );
        if c2 < c1 {
            break;
        }
        let same = f2 == flags;
        m = m2;
        flags = f2;
        if same {
            break;
        }
    }
    let h = Homography::from_matrix(m).ok()?;
    (flags.iter().filter(|&&f| f).count() >= 4).then_some((h, flags))
}

/// Which matches the plane was estimated from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaneSource {
    /// The matches within [`RegisterParams::focus_px`] of the dynamic region (the moving
    /// object's plane).
    Focus,
    /// All matches (no dynamic region, or too few matches around it).
    Whole,
}

impl std::fmt::Display for PlaneSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PlaneSource::Focus => "around the moving region",
            PlaneSource::Whole => "whole background",
        })
    }
}

/// The verified registration of one view pair (a to b).
#[derive(Debug, Clone)]
pub struct PairRegistration {
    /// The robust homography from a to b (before model selection and refinement).
    pub homography: Homography,
    /// Inlier pairs (a's point, b's point).
    pub inliers: Vec<(Point, Point)>,
    /// Features detected in a and b.
    pub features: (usize, usize),
    /// Matches (mutual best, ratio test).
    pub matches: usize,
    /// Cells of an 8x8 grid over a holding an inlier.
    pub cells: usize,
    /// RMS transfer error of the inliers, pixels.
    pub rms: f64,
    /// Where the plane was estimated.
    pub plane: PlaneSource,
    /// Matches outside the focus region, and how many of them the plane explains (within the
    /// threshold): (explained, total). (0, 0) when the whole background was used.
    pub rest_inliers: (usize, usize),
}

/// Registers background `a` to background `b`: features, matching, RANSAC, verification. `focus`
/// (a's pixels) is the region whose plane is wanted (the dynamic region); matches within
/// `params.focus_px` of it are used when at least `2 * params.min_inliers` lie there. `pair`
/// names the views in errors.
pub fn register_pair(
    a: &RgbImage,
    b: &RgbImage,
    focus: Option<&Mask>,
    params: &RegisterParams,
    pair: (usize, usize),
) -> Result<PairRegistration> {
    if a.dimensions() != b.dimensions() {
        return Err(Error::SizeMismatch {
            what: format!("registration of views {} and {}", pair.0, pair.1),
            expected_w: a.width(),
            expected_h: a.height(),
            got_w: b.width(),
            got_h: b.height(),
        });
    }
    let (ga, gb) = (grey(a), grey(b));
    let (fa, fb) = rayon::join(|| detect(&ga, params), || detect(&gb, params));
    let mut reg = register_features(&fa, &fb, a.dimensions(), focus, params, pair)?;
    refine_inliers(&ga, &gb, &mut reg, params);
    Ok(reg)
}

/// [`register_pair`] from detected features (`size` is a's image size).
pub fn register_features(
    fa: &[Feature],
    fb: &[Feature],
    size: (u32, u32),
    focus: Option<&Mask>,
    params: &RegisterParams,
    pair: (usize, usize),
) -> Result<PairRegistration> {
    let matches = match_features(fa, fb, params.ratio, params.max_distance);
    let (src, dst): (Vec<Point>, Vec<Point>) =
        matches.iter().map(|&(i, j)| (fa[i].pos, fb[j].pos)).unzip();
    let fail = |why: String| Error::Registration {
        pair,
        why: format!(
            "{} and {} features, {} matches: {why}",
            fa.len(),
            fb.len(),
            matches.len()
        ),
    };
    // The focus: matches whose point in a lies within focus_px of the dynamic region.
    let near: Vec<bool> = match focus {
        Some(mask) if mask.count_ones() > 0 => {
            let grown = mask.dilate(params.focus_px);
            src.iter()
                .map(|p| {
                    let (x, y) = (p.x.round() as i64, p.y.round() as i64);
                    x >= 0
                        && y >= 0
                        && (x as u32) < grown.width()
                        && (y as u32) < grown.height()
                        && grown.get(x as u32, y as u32)
                })
                .collect()
        }
        _ => vec![false; src.len()],
    };
    let n_near = near.iter().filter(|&&f| f).count();
    let plane = if n_near >= 2 * params.min_inliers {
        PlaneSource::Focus
    } else {
        PlaneSource::Whole
    };
    let pick = |v: &[Point]| -> Vec<Point> {
        v.iter()
            .zip(&near)
            .filter(|(_, &f)| plane == PlaneSource::Whole || f)
            .map(|(p, _)| *p)
            .collect()
    };
    let (s, d) = (pick(&src), pick(&dst));
    let Some((h, flags)) = ransac(&s, &d, params.threshold, params.iterations, params.seed) else {
        return Err(fail("no consistent homography".into()));
    };
    let inliers: Vec<(Point, Point)> = flags
        .iter()
        .enumerate()
        .filter(|(_, &f)| f)
        .map(|(i, _)| (s[i], d[i]))
        .collect();
    let (w, hgt) = size;
    let mut grid = [false; 64];
    for (p, _) in &inliers {
        let cx = ((p.x.max(0.0) / w as f64 * 8.0) as usize).min(7);
        let cy = ((p.y.max(0.0) / hgt as f64 * 8.0) as usize).min(7);
        grid[cy * 8 + cx] = true;
    }
    let cells = grid.iter().filter(|&&g| g).count();
    let (is, id): (Vec<Point>, Vec<Point>) = inliers.iter().copied().unzip();
    let rms = h.rms_error(&is, &id);
    if inliers.len() < params.min_inliers || cells < params.min_cells {
        return Err(fail(format!(
            "{} inliers in {cells} of 64 image cells, residual {rms:.2} px (a verified fit needs {} inliers in {} cells)",
            inliers.len(),
            params.min_inliers,
            params.min_cells
        )));
    }
    let rest_inliers = if plane == PlaneSource::Focus {
        let t2 = params.threshold * params.threshold;
        let m = h.matrix();
        let rest: Vec<usize> = (0..src.len()).filter(|&i| !near[i]).collect();
        let ok = rest
            .iter()
            .filter(|&&i| transfer2(&m, &src[i], &dst[i]) <= t2)
            .count();
        (ok, rest.len())
    } else {
        (0, 0)
    };
    Ok(PairRegistration {
        homography: h,
        inliers,
        features: (fa.len(), fb.len()),
        matches: matches.len(),
        cells,
        rms,
        plane,
        rest_inliers,
    })
}

/// A picture to judge a fit at a glance: `a` and `b` warped into a by `h` (a to b) in a
/// checkerboard of `cell`-pixel squares (a misfit shows as broken edges at the squares'
/// borders), with `points` (a's) drawn as small crosses.
pub fn fit_picture(
    a: &RgbImage,
    b: &RgbImage,
    h: &Homography,
    points: &[Point],
    cell: u32,
) -> RgbImage {
    let (w, hgt) = a.dimensions();
    // b warped into a's frame: out(x) = b(H x); warp_rgb takes the map from output to source.
    let warped = crate::warp::warp_rgb(
        b,
        &h.inverse(),
        w,
        hgt,
        crate::warp::Interpolation::Bilinear,
    );
    let cell = cell.max(1);
    let mut out = RgbImage::from_fn(w, hgt, |x, y| {
        if ((x / cell) + (y / cell)).is_multiple_of(2) {
            *a.get_pixel(x, y)
        } else {
            *warped.get_pixel(x, y)
        }
    });
    // At most about 300 points drawn, evenly picked, so the picture stays readable.
    let step = points.len().div_ceil(300).max(1);
    for p in points.iter().step_by(step) {
        let (cx, cy) = (p.x.round() as i64, p.y.round() as i64);
        for k in -2i64..=2 {
            for (x, y) in [(cx + k, cy), (cx, cy + k)] {
                if x >= 0 && y >= 0 && (x as u32) < w && (y as u32) < hgt {
                    out.put_pixel(x as u32, y as u32, image::Rgb([255, 40, 200]));
                }
            }
        }
    }
    out
}

/// The moving object's footprint: the share of frames each pixel is in the moving-object mask,
/// scaled to 0..=255 and replicated to RGB (for [`crate::align::align_backgrounds`]). Over whole
/// periods it depends only on where on its plane the object moves, so two views' footprints
/// are related by the object plane's homography, which the static background may not show
/// (an object swaying in front of a far wall). None when nothing moves.
pub fn footprint(masks: &[Mask]) -> Option<RgbImage> {
    let first = masks.first()?;
    let (w, h) = (first.width(), first.height());
    let n = w as usize * h as usize;
    let mut count = vec![0u32; n];
    for m in masks {
        for (wi, &word) in m.words().iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let b = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let i = wi * 64 + b;
                if i < n {
                    count[i] += 1;
                }
            }
        }
    }
    if count.iter().all(|&c| c == 0) {
        return None;
    }
    let k = masks.len() as f64;
    let mut out = RgbImage::new(w, h);
    for (px, &c) in out.as_mut().chunks_exact_mut(3).zip(&count) {
        let v = (255.0 * c as f64 / k).round() as u8;
        px.copy_from_slice(&[v, v, v]);
    }
    Some(out)
}

/// Half size of the patches of [`refine_inliers`].
const PATCH: i64 = 7;

/// Sub-pixel correspondence of a's pixel `xa` in b: the patch around it, predicted in b by `h`
/// (so perspective and scale are accounted for), shifted by the translation (with gain and
/// offset) that minimises the squared difference (Gauss-Newton). None when the patch leaves
/// either image, is flat, moves more than 3 px, or correlates below 0.8.
fn refine_point(a: &Grey, b: &Grey, h: &Homography, xa: (i64, i64)) -> Option<Point> {
    let mut samples = Vec::with_capacity(((2 * PATCH + 1) * (2 * PATCH + 1)) as usize);
    for dy in -PATCH..=PATCH {
        for dx in -PATCH..=PATCH {
            let (x, y) = (xa.0 + dx, xa.1 + dy);
            if x < 0 || y < 0 || x as usize >= a.w || y as usize >= a.h {
                return None;
            }
            let va = a.v[y as usize * a.w + x as usize];
            let q = h.apply(Point::new((xa.0 + dx) as f64, (xa.1 + dy) as f64))?;
            samples.push((va as f64, q));
        }
    }
    let n = samples.len() as f64;
    let mean = samples.iter().map(|s| s.0).sum::<f64>() / n;
    let var = samples.iter().map(|s| (s.0 - mean).powi(2)).sum::<f64>() / n;
    if var < 25.0 {
        return None;
    }
    let (mut tx, mut ty, mut alpha, mut beta) = (0.0f64, 0.0f64, 1.0f64, 0.0f64);
    for _ in 0..12 {
        let mut jtj = nalgebra::Matrix4::<f64>::zeros();
        let mut jtr = nalgebra::Vector4::<f64>::zeros();
        for &(va, q) in &samples {
            let (vb, gx, gy) = b.sample_grad(q.x + tx, q.y + ty)?;
            let r = vb as f64 - alpha * va - beta;
            let j = nalgebra::Vector4::new(gx as f64, gy as f64, -va, -1.0);
            jtj += j * j.transpose();
            jtr += j * r;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        tx += step[0];
        ty += step[1];
        alpha += step[2];
        beta += step[3];
        if tx.hypot(ty) > 3.0 {
            return None;
        }
        if step[0].hypot(step[1]) < 1e-3 {
            break;
        }
    }
    // Normalised cross-correlation of the aligned patches.
    let vb: Vec<f64> = samples
        .iter()
        .map(|&(_, q)| b.sample_grad(q.x + tx, q.y + ty).map(|s| s.0 as f64))
        .collect::<Option<_>>()?;
    let mb = vb.iter().sum::<f64>() / n;
    let (mut cov, mut vb2) = (0.0, 0.0);
    for (s, &v) in samples.iter().zip(&vb) {
        cov += (s.0 - mean) * (v - mb);
        vb2 += (v - mb).powi(2);
    }
    let ncc = cov / (var * n * vb2).sqrt().max(1e-12);
    if ncc < 0.8 {
        return None;
    }
    let q = h.apply(Point::new(xa.0 as f64, xa.1 as f64))?;
    Some(Point::new(q.x + tx, q.y + ty))
}

/// Makes a registration's inliers sub-pixel: each inlier's point in a (rounded to its pixel) is
/// matched in b by [`refine_point`] under the robust homography, the homography is fitted again
/// to the refined pairs (normalised DLT + Levenberg-Marquardt) and the pairs beyond the
/// threshold dropped once. Corners found on a pyramid level are only as precise as that level
/// (up to 2 px at the coarsest); this brings the fit down to the patches' precision. Keeps the
/// registration as it was when fewer than `params.min_inliers` points refine.
pub fn refine_inliers(
    a: &GrayImage,
    b: &GrayImage,
    reg: &mut PairRegistration,
    params: &RegisterParams,
) {
    let (ga, gb) = (Grey::from_luma(a), Grey::from_luma(b));
    let h = reg.homography;
    // Each of a's pixels once (features of two levels may round to the same pixel).
    let mut anchors: Vec<(i64, i64)> = reg
        .inliers
        .iter()
        .map(|(pa, _)| (pa.x.round() as i64, pa.y.round() as i64))
        .collect();
    anchors.sort_unstable();
    anchors.dedup();
    let refined: Vec<(Point, Point)> = anchors
        .par_iter()
        .filter_map(|&xa| {
            refine_point(&ga, &gb, &h, xa).map(|pb| (Point::new(xa.0 as f64, xa.1 as f64), pb))
        })
        .collect();
    if refined.len() < params.min_inliers {
        return;
    }
    let fit = |pairs: &[(Point, Point)]| {
        let (s, d): (Vec<Point>, Vec<Point>) = pairs.iter().copied().unzip();
        Homography::from_correspondences(&s, &d)
            .ok()
            .map(|f| f.homography)
    };
    let Some(h1) = fit(&refined) else {
        return;
    };
    let t2 = (params.threshold / 2.0).powi(2);
    let m = h1.matrix();
    let kept: Vec<(Point, Point)> = refined
        .into_iter()
        .filter(|(s, d)| transfer2(&m, s, d) <= t2)
        .collect();
    if kept.len() < params.min_inliers {
        return;
    }
    let Some(h2) = fit(&kept) else {
        return;
    };
    let (s, d): (Vec<Point>, Vec<Point>) = kept.iter().copied().unzip();
    reg.rms = h2.rms_error(&s, &d);
    reg.homography = h2;
    reg.inliers = kept;
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    fn corner_error(a: &Homography, b: &Homography, w: f64, h: f64) -> f64 {
        [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .iter()
            .map(|&(x, y)| {
                let p = Point::new(x, y);
                (a.apply(p).unwrap() - b.apply(p).unwrap()).norm()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn ransac_recovers_a_homography_through_40_percent_outliers() {
        let truth = Homography::from_matrix(Matrix3::new(
            0.97, 0.02, -14.0, -0.01, 1.01, 3.0, -4e-5, 2e-5, 1.0,
        ))
        .unwrap();
        let mut rng = crate::rng::Rng::new(3);
        let (mut src, mut dst, mut truly) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..300 {
            let p = Point::new(rng.f64() * 640.0, rng.f64() * 480.0);
            let inlier = i % 5 >= 2;
            let q = if inlier {
                let t = truth.apply(p).unwrap();
                Point::new(t.x + 0.3 * rng.normal(), t.y + 0.3 * rng.normal())
            } else {
                Point::new(rng.f64() * 640.0, rng.f64() * 480.0)
            };
            src.push(p);
            dst.push(q);
            truly.push(inlier);
        }
        let (h, flags) = ransac(&src, &dst, 3.0, 4000, 1).unwrap();
        assert!(corner_error(&h, &truth, 640.0, 480.0) < 0.5);
        let agree = flags.iter().zip(&truly).filter(|(a, b)| a == b).count();
        assert!(agree >= 295, "{agree} of 300 flags right");
        // Same seed, same answer.
        let (h2, _) = ransac(&src, &dst, 3.0, 4000, 1).unwrap();
        assert_eq!(h.matrix(), h2.matrix());
    }

    #[test]
    fn four_points_give_the_exact_map_and_collinear_ones_none() {
        let truth = Matrix3::new(1.1, 0.1, 5.0, -0.05, 0.9, -3.0, 1e-4, -2e-4, 1.0);
        let h = Homography::from_matrix(truth).unwrap();
        let src = [
            Point::new(10.0, 20.0),
            Point::new(300.0, 40.0),
            Point::new(280.0, 200.0),
            Point::new(30.0, 220.0),
        ];
        let dst = src.map(|p| h.apply(p).unwrap());
        let m = four_point(
            [&src[0], &src[1], &src[2], &src[3]],
            [&dst[0], &dst[1], &dst[2], &dst[3]],
        )
        .unwrap();
        assert!((m / m[(2, 2)] - truth).abs().max() < 1e-9);
        let line = [0.0, 1.0, 2.0, 3.0].map(|t| Point::new(10.0 * t, 5.0 * t + 1.0));
        assert!(four_point(
            [&line[0], &line[1], &line[2], &line[3]],
            [&dst[0], &dst[1], &dst[2], &dst[3]]
        )
        .is_none());
    }

    #[test]
    fn matches_are_mutual_and_pass_the_ratio_test() {
        let f = |bits: [u64; 4], x: f64| Feature {
            pos: Point::new(x, 0.0),
            angle: 0.0,
            level: 0,
            score: 1.0,
            descriptor: bits,
        };
        let a = vec![
            f([0, 0, 0, 0], 0.0),
            f([u64::MAX, 0, 0, 0], 1.0),
            f([0xFF, 0, 0, 0], 2.0),
        ];
        // b[0] matches a[0] exactly; b[1] is as close to a[0] as to a[2] (ratio test fails for
        // it); b[2] matches a[1] exactly.
        let b = vec![
            f([0, 0, 0, 0], 0.0),
            f([0xF, 0, 0, 0], 1.0),
            f([u64::MAX, 0, 0, 0], 2.0),
        ];
        let m = match_features(&a, &b, 0.8, 80);
        assert_eq!(m, vec![(0, 0), (1, 2)]);
    }

    #[test]
    fn footprint_is_the_share_of_frames_each_pixel_moves() {
        let mut m1 = Mask::new(4, 2);
        let mut m2 = Mask::new(4, 2);
        m1.set(1, 0, true);
        m2.set(1, 0, true);
        m2.set(3, 1, true);
        let fp = footprint(&[m1, m2.clone(), Mask::new(4, 2), m2]).unwrap();
        assert_eq!(fp.get_pixel(1, 0).0, [191, 191, 191]);
        assert_eq!(fp.get_pixel(3, 1).0, [128, 128, 128]);
        assert_eq!(fp.get_pixel(0, 0).0, [0, 0, 0]);
        assert!(footprint(&[Mask::new(4, 2)]).is_none());
        assert!(footprint(&[]).is_none());
    }

    #[test]
    fn bad_parameters_are_named() {
        let bad = RegisterParams {
            ratio: 1.5,
            ..Default::default()
        };
        let e = bad.check().unwrap_err().to_string();
        assert!(e.contains("register.ratio") && e.contains("1.5"), "{e}");
        assert!(RegisterParams::default().check().is_ok());
    }
}
