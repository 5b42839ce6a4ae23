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

pub mod epipolar;
mod features;
mod ransac;
#[cfg(test)]
mod tests;

pub use features::{detect, grey, match_features, Feature};
pub use ransac::ransac;
use ransac::*;

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
    /// Where the matches show parallax, fit the plane among those the epipolar geometry allows
    /// ([`epipolar`]): two camera positions of a rig. Off for frames of one handheld view.
    pub epipolar: bool,
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
            epipolar: true,
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
    /// The fundamental matrix (a to b) when the matches show parallax off the plane: the plane
    /// is then one that the epipolar geometry allows ([`epipolar`]) and the inliers' points in b
    /// lie on their epipolar lines.
    pub epipolar: Option<nalgebra::Matrix3<f64>>,
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
    register_features_on(fa, fb, size, focus, None, params, pair)
}

/// [`register_features`] with `prior`: points of a on the plane wanted (the previous pair's
/// plane as seen in a, so that every link of a rig registers the same scene plane). Where the
/// matches show parallax, the plane is fitted to the matches at those points when at least
/// `params.min_inliers` lie there; otherwise, and without parallax, `prior` is not used.
pub fn register_features_on(
    fa: &[Feature],
    fb: &[Feature],
    size: (u32, u32),
    focus: Option<&Mask>,
    prior: Option<&[Point]>,
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
    let Some((mut h, mut flags)) = ransac(&s, &d, params.threshold, params.iterations, params.seed)
    else {
        return Err(fail("no consistent homography".into()));
    };
    let epipolar = if params.epipolar {
        rig_plane(&src, &dst, &s, &d, prior, &mut h, &mut flags, params)
    } else {
        None
    };
    let inliers: Vec<(Point, Point)> = flags
        .iter()
        .enumerate()
        .filter(|(_, &f)| f)
        .map(|(i, _)| match &epipolar {
            Some(f) => (s[i], epipolar::onto_line(f, &s[i], &d[i])),
            None => (s[i], d[i]),
        })
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
        epipolar,
    })
}

/// Where all matches (`src -> dst`) show parallax that the plane `h` (fitted to `s -> d`, inlier
/// `flags`) does not explain, the plane is fitted again among those the epipolar geometry allows
/// ([`epipolar::plane_ransac`] on the pairs of `s -> d` that agree with it): `h` and `flags` are
/// replaced and the fundamental matrix returned. None (nothing changed) for a scene without
/// parallax, where the fundamental matrix is not determined, or when the constrained plane
/// finds too few inliers.
fn rig_plane(
    src: &[Point],
    dst: &[Point],
    s: &[Point],
    d: &[Point],
    prior: Option<&[Point]>,
    h: &mut Homography,
    flags: &mut Vec<bool>,
    params: &RegisterParams,
) -> Option<nalgebra::Matrix3<f64>> {
    let (f, f_in) = epipolar::fundamental(src, dst, EPIPOLAR_PX, params.iterations, params.seed)?;
    let m = h.matrix();
    let t2 = params.threshold * params.threshold;
    // Parallax the plane's fit cannot explain: matches on their epipolar lines at least twice
    // the inlier threshold off the plane. Nearer the plane, residuals of corners found on coarse
    // pyramid levels (a planar scene: graf1 -> graf3) line up with a fundamental matrix that
    // the plane alone leaves free by chance.
    let far = 4.0 * t2;
    let off_plane = (0..src.len())
        .filter(|&i| f_in[i] && transfer2(&m, &src[i], &dst[i]) > far)
        .count();
    if off_plane < params.min_inliers {
        return None;
    }
    let mut agree: Vec<usize> = (0..s.len())
        .filter(|&i| epipolar::sampson2(&f, &s[i], &d[i]) <= EPIPOLAR_PX * EPIPOLAR_PX)
        .collect();
    if let Some(prior) = prior {
        let near = |p: &Point| {
            prior
                .iter()
                .any(|q| (q.x - p.x).abs() <= PRIOR_PX && (q.y - p.y).abs() <= PRIOR_PX)
        };
        let on: Vec<usize> = agree.iter().copied().filter(|&i| near(&s[i])).collect();
        if on.len() >= params.min_inliers {
            agree = on;
        }
    }
    let (ss, dd): (Vec<Point>, Vec<Point>) = agree.iter().map(|&i| (s[i], d[i])).unzip();
    let (h2, fl2) =
        epipolar::plane_ransac(&f, &ss, &dd, RIG_PLANE_PX, params.iterations, params.seed)?;
    if inliers(&fl2).count() < params.min_inliers {
        return None;
    }
    let mut flags2 = vec![false; s.len()];
    for k in inliers(&fl2) {
        flags2[agree[k]] = true;
    }
    *h = h2;
    *flags = flags2;
    Some(f)
}

/// The largest Sampson distance, px, of a match that agrees with the epipolar geometry.
const EPIPOLAR_PX: f64 = 1.5;

/// The inlier threshold of the rig's plane, px (transfer error). Tighter than a free
/// homography's 3 px: the constrained plane cannot bend towards matches off it, so its band is
/// a slab of depth. Measured on the Middlebury line scenes (automatic registration, mean dB over
/// three q, Dolls / Moebius / Reindeer): 1.5 px 36.80 / 36.93 / 30.59, 2 px 36.91 / 36.81 /
/// 30.67, 2.5 px 37.09 / 36.88 / 31.98, 3 px 36.85 / 36.65 / 30.40, 4 px 36.83 / 36.56 / 30.96.
/// The plane chosen moves between slabs with it, Reindeer's most.
const RIG_PLANE_PX: f64 = 2.5;

/// How near (px, each axis) a match's point in a lies to a prior point to count as on its plane.
const PRIOR_PX: f64 = 1.5;

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

/// Where the patch around `a`'s pixel `at` lies in `b`, sub-pixel, predicted by `h` (a to b):
/// [`refine_inliers`]'s patch match for one point (None when it fails). For measuring motion
/// (tests, reports); each call converts both images, so batch callers use their own.
pub fn locate(a: &GrayImage, b: &GrayImage, h: &Homography, at: (i64, i64)) -> Option<Point> {
    refine_point(&Grey::from_luma(a), &Grey::from_luma(b), h, at)
}

/// Half size of the patches of [`refine_inliers`].
const PATCH: i64 = 7;

/// Sub-pixel correspondence of a's pixel `xa` in b: the patch around it, predicted in b by `h`
/// (so perspective and scale are accounted for), shifted by the translation (with gain and
/// offset) that minimises the squared difference (Gauss-Newton). None when the patch leaves
/// either image, is flat, moves more than 3 px, or correlates below 0.8.
pub(crate) fn refine_point(a: &Grey, b: &Grey, h: &Homography, xa: (i64, i64)) -> Option<Point> {
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
    // Under the epipolar geometry the refined points move onto their lines, and the plane stays
    // one it allows.
    let refined: Vec<(Point, Point)> = match &reg.epipolar {
        Some(f) => refined
            .into_iter()
            .map(|(s, d)| (s, epipolar::onto_line(f, &s, &d)))
            .collect(),
        None => refined,
    };
    let fit = |pairs: &[(Point, Point)]| {
        let (s, d): (Vec<Point>, Vec<Point>) = pairs.iter().copied().unzip();
        match &reg.epipolar {
            Some(f) => {
                epipolar::plane_through(f, &s, &d).and_then(|m| Homography::from_matrix(m).ok())
            }
            None => Homography::from_correspondences(&s, &d)
                .ok()
                .map(|f| f.homography),
        }
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
