//! Dense parallax between two neighbouring median backgrounds, beyond the plane of eq. (3).
//!
//! The plane homography `H` (view a to view b) explains the marked plane only; everything off
//! it shows twice at an intermediate viewpoint. Cameras on a line see a scene point move along
//! one direction once the plane is taken out (the epipolar lines are near parallel when the
//! cameras move sideways), so what is left is a *disparity* along a line through each pixel:
//! a's pixel `x` is b's pixel `H(x + o(x) + d(x) t(x))`, with `o` the offset to the line and
//! `t` its direction ([`line_frame`]).
//!
//! # Search lines ([`geometry`])
//! The direction `v` and the range come from the feature matches ([`direction_and_range`]):
//! the residuals of the matches off the plane, after `H`. A registration's homography need not
//! agree with the cameras' epipolar geometry (on a scene with depth the best-fitting plane can
//! shear across the parallax), so each frame's lines are fitted to the residuals: an offset
//! across `v` quadratic in the position, a tilt linear in it (robust least squares).
//!
//! # Estimation ([`estimate`])
//! b is warped into a's frame by `H^-1`; both become grey; a 7x7 census transform of each;
//! matching cost = Hamming distance of the census words at `x` and at the point `d` along its
//! line (nearest pixel), for every integer `d` in the range; semi-global matching
//! (Hirschmüller 2008) along 8 paths with penalties `P1`, `P2`; winner takes all with a
//! parabola, then Gauss-Newton steps on a 5x5 window for the sub-pixel part; the same from b's
//! side; pixels whose match does not lead back within a pixel are marked invalid (occluded or
//! unmatched), then filled from the farther of their valid neighbours along the row (an
//! occluded pixel belongs to what lies behind), so the field is defined everywhere.
//!
//! # Morph ([`morph`])
//! Each output pixel is traced back into both views by a fixed point along the fields, and the
//! two samples blended `(1 - f, f)`, the view whose trace converged preferred where only one
//! did (near an occluding edge, the view that sees the surface behind converges; the other's
//! trace jumps between the two surfaces).

use image::{GrayImage, RgbImage};
use rayon::prelude::*;

use crate::{Homography, Point};

/// Settings of the dense parallax.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParallaxParams {
    /// SGM's penalty for a one-step disparity change between neighbours.
    pub p1: u16,
    /// SGM's penalty for a larger change.
    pub p2: u16,
    /// Left-right consistency threshold, pixels.
    pub lr_threshold: f32,
}

impl Default for ParallaxParams {
    fn default() -> Self {
        Self {
            p1: 8,
            p2: 96,
            lr_threshold: 1.0,
        }
    }
}

/// A disparity field in one view's (plane-aligned) frame: each pixel's match lies on its search
/// line ([`line_frame`]: fitted to the pair's matches, or one straight direction), at signed
/// distance `disparity` from the line's point nearest the pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    width: u32,
    height: u32,
    direction: [f32; 2],
    lines: Option<[f64; 9]>,
    disparity: Vec<f32>,
    valid: Vec<bool>,
    /// The displacement per pixel, `o(x) + d(x) t(x)`, derived from the above, in units of
    /// [`FLOW_UNIT`] px (half the memory of `f32`, which the renderer's 1080p frame measured:
    /// the two views' fields are read four times a frame).
    flow: Vec<[i16; 2]>,
}

/// The unit of [`Field::flow`]: 1/32 px (displacements up to 1024 px; the scene stores
/// disparities to 1/8 px).
pub const FLOW_UNIT: f32 = 1.0 / 32.0;

/// A pixel's search line: the offset `o` from the pixel to the line's nearest point, and the
/// line's unit direction `t` (signed to agree with the field's direction).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineFrame {
    /// Offset to the foot point.
    pub offset: [f32; 2],
    /// Unit direction along the line.
    pub along: [f32; 2],
}

/// Pixel `(x, y)`'s search line under the line model `m` ([`Geometry::lines_a`]): through
/// `x + q(x) n` along `dir + l(x) n` (normalised), `n` the normal of `dir`, `q` quadratic and
/// `l` linear in the pixel's position (coefficients `m[0..6]` and `m[6..9]`); straight along
/// `dir` through the pixel without a model.
pub fn line_frame(m: Option<&[f64; 9]>, dir: [f32; 2], x: f64, y: f64) -> LineFrame {
    let Some(m) = m else {
        return LineFrame {
            offset: [0.0, 0.0],
            along: dir,
        };
    };
    let (vx, vy) = (f64::from(dir[0]), f64::from(dir[1]));
    let (nx, ny) = (-vy, vx);
    let q = m[0] + m[1] * x + m[2] * y + m[3] * x * x + m[4] * x * y + m[5] * y * y;
    let l = m[6] + m[7] * x + m[8] * y;
    let (tx, ty) = (vx + l * nx, vy + l * ny);
    let tn = tx.hypot(ty);
    LineFrame {
        offset: [(q * nx) as f32, (q * ny) as f32],
        along: [(tx / tn) as f32, (ty / tn) as f32],
    }
}

/// The line model's terms at a match: position `(x, y)` and its distance `d` along the line.
fn model_terms(x: f64, y: f64, d: f64) -> [f64; 9] {
    [1.0, x, y, x * x, x * y, y * y, d, d * x, d * y]
}

/// Fits the line model to residuals `(x, y, along, perp)`: `perp ~ q(x, y) + along l(x, y)`,
/// iteratively reweighted least squares (Cauchy weights, scale from the median absolute
/// residual, at least 0.5 px). Positions are taken in units of `scale` pixels for conditioning
/// and the coefficients converted back. None with fewer than 20 residuals or a singular fit.
fn fit_lines(res: &[(f64, f64, f64, f64)], scale: f64) -> Option<[f64; 9]> {
    if res.len() < 20 {
        return None;
    }
    let s = scale.max(1.0);
    let mut w = vec![1.0f64; res.len()];
    let mut c = nalgebra::SVector::<f64, 9>::zeros();
    for _ in 0..12 {
        let mut ata = nalgebra::SMatrix::<f64, 9, 9>::zeros();
        let mut atb = nalgebra::SVector::<f64, 9>::zeros();
        for (&(x, y, d, p), &wi) in res.iter().zip(&w) {
            let t = nalgebra::SVector::<f64, 9>::from(model_terms(x / s, y / s, d / s));
            ata += wi * t * t.transpose();
            atb += wi * p * t;
        }
        // A little ridge: terms the matches do not constrain stay near zero.
        for k in 0..9 {
            ata[(k, k)] += 1e-6 * res.len() as f64;
        }
        c = ata.cholesky()?.solve(&atb);
        let e: Vec<f64> = res
            .iter()
            .map(|&(x, y, d, p)| {
                p - nalgebra::SVector::<f64, 9>::from(model_terms(x / s, y / s, d / s)).dot(&c)
            })
            .collect();
        let mut abs: Vec<f64> = e.iter().map(|v| v.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let sigma = (1.4826 * abs[abs.len() / 2]).max(0.5);
        for (wi, ei) in w.iter_mut().zip(&e) {
            *wi = 1.0 / (1.0 + (ei / (2.385 * sigma)).powi(2));
        }
    }
    // Back to pixel units: a term of degree k in (x, y, d) is s^k times larger.
    let deg = [0, 1, 1, 2, 2, 2, 1, 2, 2];
    let out: [f64; 9] = std::array::from_fn(|k| c[k] / s.powi(deg[k]));
    out.iter().all(|v| v.is_finite()).then_some(out)
}

impl Field {
    /// A field of `width x height` pixels (row-major `disparity` and `valid`), its lines from
    /// the line map `lines` (None: straight along `direction`). Refuses sizes that disagree,
    /// a direction that is not a unit vector, and non-finite values.
    pub fn new(
        width: u32,
        height: u32,
        direction: [f32; 2],
        lines: Option<[f64; 9]>,
        disparity: Vec<f32>,
        valid: Vec<bool>,
    ) -> crate::Result<Self> {
        let n = width as usize * height as usize;
        let norm = (direction[0] as f64).hypot(direction[1] as f64);
        let bad = |why: String| crate::Error::InvalidParameter {
            name: "parallax field",
            value: format!("{width}x{height}"),
            why,
        };
        if n == 0 || disparity.len() != n || valid.len() != n {
            return Err(bad(format!(
                "{} disparities and {} flags for {n} pixels",
                disparity.len(),
                valid.len()
            )));
        }
        if !(0.99..=1.01).contains(&norm) {
            return Err(bad(format!("direction {direction:?} is not a unit vector")));
        }
        if disparity.iter().any(|d| !d.is_finite())
            || lines.is_some_and(|m| m.iter().any(|v| !v.is_finite()))
        {
            return Err(bad("non-finite disparity or line map".into()));
        }
        let w = width as usize;
        let flow = disparity
            .par_iter()
            .enumerate()
            .map(|(i, &d)| {
                let f = line_frame(lines.as_ref(), direction, (i % w) as f64, (i / w) as f64);
                [f.offset[0] + d * f.along[0], f.offset[1] + d * f.along[1]]
                    .map(|v| (v / FLOW_UNIT).round().clamp(-32767.0, 32767.0) as i16)
            })
            .collect();
        Ok(Self {
            width,
            height,
            direction,
            lines,
            disparity,
            valid,
            flow,
        })
    }

    /// Width.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Unit direction of the parallax in this view's frame (the lines' sign).
    pub fn direction(&self) -> [f32; 2] {
        self.direction
    }

    /// The line map (row-major 3x3: pixel `x`'s line is `m x`), None for straight lines.
    pub fn lines(&self) -> Option<[f64; 9]> {
        self.lines
    }

    /// Disparity per pixel (row-major) along its line. Defined everywhere (invalid pixels
    /// filled).
    pub fn disparity(&self) -> &[f32] {
        &self.disparity
    }

    /// Whether each pixel passed the left-right check (seen by both views).
    pub fn valid(&self) -> &[bool] {
        &self.valid
    }

    /// Displacement per pixel in units of [`FLOW_UNIT`] px: this view's pixel `x` is the other
    /// view's (plane-warped) pixel `x + flow(x)`.
    pub fn flow(&self) -> &[[i16; 2]] {
        &self.flow
    }

    /// Displacement of pixel `i` (row-major), pixels.
    #[inline]
    pub fn flow_px(&self, i: usize) -> [f32; 2] {
        self.flow[i].map(|v| f32::from(v) * FLOW_UNIT)
    }

    /// Displacement at the nearest pixel (clamped to the image), pixels.
    #[inline]
    pub fn flow_at(&self, x: f64, y: f64) -> [f32; 2] {
        let xi = (x.round().max(0.0) as usize).min(self.width as usize - 1);
        let yi = (y.round().max(0.0) as usize).min(self.height as usize - 1);
        self.flow_px(yi * self.width as usize + xi)
    }

    /// Validity at the nearest pixel (false outside).
    #[inline]
    pub fn valid_at(&self, x: f64, y: f64) -> bool {
        if !(x >= -0.5 && y >= -0.5) {
            return false;
        }
        let (xi, yi) = (x.round() as usize, y.round() as usize);
        xi < self.width as usize
            && yi < self.height as usize
            && self.valid[yi * self.width as usize + xi]
    }
}

/// Both views' fields of a neighbour pair.
#[derive(Debug, Clone, PartialEq)]
pub struct PairParallax {
    /// In view a's frame (a's pixel to b through `H`).
    pub a: Field,
    /// In view b's frame (b's pixel to a through `H^-1`).
    pub b: Field,
}

/// The parallax direction (unit, in a's frame) and the disparity range from matches `(a, b)`
/// under the plane `h` (a to b): residual `r = H^-1(b) - a`; matches off the plane (|r| > 1.5 px)
/// give the direction (principal axis, sign so that the mean along it is positive); the range
/// covers them with a margin. None when fewer than 10 matches are off the plane: the plane
/// explains the scene.
pub fn direction_and_range(
    matches: &[(Point, Point)],
    h: &Homography,
) -> Option<([f32; 2], i32, i32)> {
    let res: Vec<(f64, f64)> = matches
        .iter()
        .filter_map(|(a, b)| h.apply_inverse(*b).map(|q| (q.x - a.x, q.y - a.y)))
        .filter(|r| r.0.is_finite() && r.1.is_finite() && r.0.hypot(r.1) < 400.0)
        .collect();
    let off: Vec<(f64, f64)> = res
        .iter()
        .copied()
        .filter(|r| r.0.hypot(r.1) > 1.5)
        .collect();
    if off.len() < 10 {
        return None;
    }
    // The direction: the peak of a histogram of the residuals' angles (mod 180 degrees, 1-degree
    // bins, weighted by length, smoothed over +-3 bins), refined as the weighted mean axis of
    // the residuals within 6 degrees of it. Mismatches scatter over all angles; the parallax
    // piles up on one.
    let mut hist = [0f64; 180];
    let angle_of = |r: &(f64, f64)| r.1.atan2(r.0).to_degrees().rem_euclid(180.0);
    for r in &off {
        hist[(angle_of(r) as usize).min(179)] += r.0.hypot(r.1).min(30.0);
    }
    let smooth = |i: usize| (0..7).map(|k| hist[(i + 180 + k - 3) % 180]).sum::<f64>();
    let peak = (0..180)
        .max_by(|&i, &j| smooth(i).total_cmp(&smooth(j)))
        .expect("180 bins") as f64
        + 0.5;
    let (mut sc, mut ss) = (0.0, 0.0);
    for r in &off {
        let d = (angle_of(r) - peak + 90.0).rem_euclid(180.0) - 90.0;
        if d.abs() <= 6.0 {
            let wgt = r.0.hypot(r.1).min(30.0);
            let t = 2.0 * (peak + d).to_radians();
            sc += wgt * t.cos();
            ss += wgt * t.sin();
        }
    }
    let angle = 0.5 * ss.atan2(sc);
    let (mut vx, mut vy) = (angle.cos(), angle.sin());
    let mean: f64 = off.iter().map(|r| r.0 * vx + r.1 * vy).sum::<f64>();
    if mean < 0.0 {
        (vx, vy) = (-vx, -vy);
    }
    // Range: the matches' components along v, those close to the line only.
    let along: Vec<f64> = res
        .iter()
        .filter(|r| (r.0 * -vy + r.1 * vx).abs() <= 2.0)
        .map(|r| r.0 * vx + r.1 * vy)
        .collect();
    let (lo, hi) = range_of(along)?;
    Some(([vx as f32, vy as f32], lo, hi))
}

/// The disparity range covering the 1st to 99th percentile of `along` with a margin (None with
/// fewer than 10 values).
fn range_of(mut along: Vec<f64>) -> Option<(i32, i32)> {
    along.sort_by(f64::total_cmp);
    if along.len() < 10 {
        return None;
    }
    let pick = |q: f64| along[((along.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = (pick(0.01), pick(0.99));
    let margin = 4.0 + 0.25 * (hi - lo);
    let lo = ((lo - margin).floor() as i32).min(-2);
    let hi = ((hi + margin).ceil() as i32).max(2);
    Some((lo, hi))
}

/// Where each pixel's match is searched, in both views' plane-aligned frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// Mean unit direction of the parallax in a's frame.
    pub direction: [f32; 2],
    /// The line models of a's and b's frames ([`line_frame`]), None: straight lines.
    pub lines: Option<[[f64; 9]; 2]>,
    /// Smallest disparity searched.
    pub lo: i32,
    /// Largest disparity searched.
    pub hi: i32,
}

impl Geometry {
    /// Straight lines along `direction` over `lo..=hi`.
    pub fn straight(direction: [f32; 2], lo: i32, hi: i32) -> Self {
        Self {
            direction,
            lines: None,
            lo,
            hi,
        }
    }
}

/// b's parallax direction: `v` (a's frame) carried through `h` at the image centre, reversed
/// (b's pixel is a's plane-warped pixel minus the parallax).
fn direction_b(h: &Homography, v: [f32; 2], w: u32, hgt: u32) -> [f32; 2] {
    let c = Point::new(f64::from(w) / 2.0, f64::from(hgt) / 2.0);
    match (
        h.apply(c),
        h.apply(Point::new(c.x + f64::from(v[0]), c.y + f64::from(v[1]))),
    ) {
        (Some(p), Some(q)) => {
            let (x, y) = (q.x - p.x, q.y - p.y);
            let n = x.hypot(y).max(1e-9);
            [(-x / n) as f32, (-y / n) as f32]
        }
        _ => [-v[0], -v[1]],
    }
}

/// The search geometry of a pair of `size` from its feature matches `(a, b)` under the plane
/// `h`: the direction and range of [`direction_and_range`] (None when the plane explains the
/// scene), then each frame's line model fitted to the matches' residuals (a registration's
/// plane need not agree with the cameras' epipolar geometry: on a scene with depth the best
/// fitting homography can shear across the parallax, Middlebury Reindeer's by 11 px at the
/// image's edge, and one straight direction then misses the true matches); the range then
/// measured along the fitted lines. Straight lines where the model cannot be fitted.
pub fn geometry(matches: &[(Point, Point)], h: &Homography, size: (u32, u32)) -> Option<Geometry> {
    let (v, lo, hi) = direction_and_range(matches, h)?;
    let straight = Geometry::straight(v, lo, hi);
    let vb = direction_b(h, v, size.0, size.1);
    // Residuals (position, along, across) in one frame: `from` is the frame's point, `to` the
    // other view's point carried into it.
    let residuals = |dir: [f32; 2], pts: &mut dyn Iterator<Item = (Point, Option<Point>)>| {
        let (vx, vy) = (f64::from(dir[0]), f64::from(dir[1]));
        pts.filter_map(|(p, q)| {
            let q = q?;
            let r = (q.x - p.x, q.y - p.y);
            let ok = r.0.is_finite() && r.1.is_finite() && r.0.hypot(r.1) < 400.0;
            ok.then(|| (p.x, p.y, r.0 * vx + r.1 * vy, -r.0 * vy + r.1 * vx))
        })
        .collect::<Vec<_>>()
    };
    let ra = residuals(
        v,
        &mut matches.iter().map(|&(a, b)| (a, h.apply_inverse(b))),
    );
    let rb = residuals(vb, &mut matches.iter().map(|&(a, b)| (b, h.apply(a))));
    let scale = f64::from(size.0.max(size.1));
    let (Some(la), Some(lb)) = (fit_lines(&ra, scale), fit_lines(&rb, scale)) else {
        return Some(straight);
    };
    // The range along a's fitted lines, from the matches the model explains (within 2 px).
    let along: Vec<f64> = ra
        .iter()
        .filter_map(|&(x, y, d, p)| {
            let t = model_terms(x, y, d);
            let e = p - t.iter().zip(&la).map(|(a, b)| a * b).sum::<f64>();
            (e.abs() <= 2.0).then_some(d)
        })
        .collect();
    match range_of(along) {
        Some((lo, hi)) => Some(Geometry {
            direction: v,
            lines: Some([la, lb]),
            lo,
            hi,
        }),
        None => Some(straight),
    }
}

/// Matching cost where the other view shows nothing (outside its frame): a middling census
/// distance, so the smoothness terms decide there instead of a wall of maximal costs that
/// pushes near objects at the image's edge to the wrong disparity.
const OUTSIDE_COST: u8 = 64;

/// Most cells (pixels x disparities) of the matching volume, 120 M: 600 MB with the aggregate.
pub const MAX_VOLUME: usize = 120_000_000;

/// Largest disparity range (values of d) the estimation searches.
pub const MAX_RANGE: i32 = 256;

/// 7x7 census: one bit per neighbour, set where it is darker than the centre (48 bits).
fn census(img: &GrayImage) -> Vec<u64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let raw = img.as_raw();
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let c = raw[y * w + x];
            let mut bits = 0u64;
            for dy in -3i64..=3 {
                let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                for dx in -3i64..=3 {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let xx = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                    bits = (bits << 1) | u64::from(raw[yy * w + xx] < c);
                }
            }
            *o = bits;
        }
    });
    out
}

/// Semi-global matching of `a` against `b` (both in a's frame) along each pixel's line
/// (`lines`, row-major) over `lo..=hi`: sub-pixel disparity per pixel.
fn sgm(
    a: &GrayImage,
    b: &GrayImage,
    b_seen: &[bool],
    lines: &[LineFrame],
    lo: i32,
    hi: i32,
    params: &ParallaxParams,
) -> Vec<f32> {
    let (w, h) = (a.width() as usize, a.height() as usize);
    let nd = (hi - lo + 1) as usize;
    let (ca, cb) = (census(a), census(b));
    // Matching costs, u8 (a census distance is at most 48); 64 outside b.
    let mut cost = vec![0u8; w * h * nd];
    cost.par_chunks_mut(w * nd)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let c0 = ca[y * w + x];
                let lf = lines[y * w + x];
                let (ox, oy) = (x as f32 + lf.offset[0], y as f32 + lf.offset[1]);
                for k in 0..nd {
                    let d = (lo + k as i32) as f32;
                    let bx = (ox + d * lf.along[0]).round() as i64;
                    let by = (oy + d * lf.along[1]).round() as i64;
                    let inside = bx >= 0 && by >= 0 && (bx as usize) < w && (by as usize) < h;
                    row[x * nd + k] = if inside && b_seen[by as usize * w + bx as usize] {
                        (c0 ^ cb[by as usize * w + bx as usize]).count_ones() as u8
                    } else {
                        OUTSIDE_COST
                    };
                }
            }
        });
    // Aggregation along 8 paths into `total`. Horizontal paths: one row each, rows in
    // parallel. The others advance one row at a time (down or up), every pixel of a row in
    // parallel, from the previous row's path costs shifted by the path's dx.
    let mut total = vec![0u32; w * h * nd];
    let (p1, p2) = (params.p1 as u32, params.p2 as u32);
    let step = |c: &[u8], prev: Option<&[u32]>, cur: &mut [u32]| match prev {
        None => {
            for k in 0..nd {
                cur[k] = c[k] as u32;
            }
        }
        Some(prev) => {
            let m = *prev.iter().min().expect("nd >= 1");
            for k in 0..nd {
                let mut best = prev[k];
                if k > 0 {
                    best = best.min(prev[k - 1] + p1);
                }
                if k + 1 < nd {
                    best = best.min(prev[k + 1] + p1);
                }
                best = best.min(m + p2);
                cur[k] = c[k] as u32 + best - m;
            }
        }
    };
    for dx in [1i64, -1] {
        total
            .par_chunks_mut(w * nd)
            .enumerate()
            .for_each(|(y, trow)| {
                let mut prev = vec![0u32; nd];
                let mut cur = vec![0u32; nd];
                let xs: Box<dyn Iterator<Item = usize>> = if dx > 0 {
                    Box::new(0..w)
                } else {
                    Box::new((0..w).rev())
                };
                for (n, x) in xs.enumerate() {
                    let i = y * w + x;
                    step(
                        &cost[i * nd..(i + 1) * nd],
                        (n > 0).then_some(&prev[..]),
                        &mut cur,
                    );
                    for (t, v) in trow[x * nd..(x + 1) * nd].iter_mut().zip(&cur) {
                        *t += v;
                    }
                    std::mem::swap(&mut prev, &mut cur);
                }
            });
    }
    for dy in [1i64, -1] {
        for dx in [-1i64, 0, 1] {
            let mut prev_row = vec![0u32; w * nd];
            let mut cur_row = vec![0u32; w * nd];
            let ys: Vec<usize> = if dy > 0 {
                (0..h).collect()
            } else {
                (0..h).rev().collect()
            };
            for (n, &y) in ys.iter().enumerate() {
                let trow = &mut total[y * w * nd..(y + 1) * w * nd];
                cur_row
                    .par_chunks_mut(nd)
                    .zip(trow.par_chunks_mut(nd))
                    .enumerate()
                    .for_each(|(x, (cur, t))| {
                        let px = x as i64 - dx;
                        let prev = (n > 0 && px >= 0 && px < w as i64)
                            .then(|| &prev_row[px as usize * nd..(px as usize + 1) * nd]);
                        let i = y * w + x;
                        step(&cost[i * nd..(i + 1) * nd], prev, cur);
                        for (tt, v) in t.iter_mut().zip(cur.iter()) {
                            *tt += v;
                        }
                    });
                std::mem::swap(&mut prev_row, &mut cur_row);
            }
        }
    }
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let s = &total[i * nd..(i + 1) * nd];
            let (k, _) = s
                .iter()
                .enumerate()
                .min_by_key(|&(k, &v)| (v, k))
                .expect("nd >= 1");
            let mut d = (lo + k as i32) as f32;
            if k > 0 && k + 1 < nd {
                let (cm, c0, cp) = (s[k - 1] as f32, s[k] as f32, s[k + 1] as f32);
                let den = cm - 2.0 * c0 + cp;
                if den > 0.0 {
                    d += 0.5 * (cm - cp) / den;
                }
            }
            d
        })
        .collect()
}

/// Half the side of the window of the sub-pixel refinement (5x5).
const REFINE_RADIUS: i64 = 2;

/// Sub-pixel refinement of the semi-global disparities: at each pixel, Gauss-Newton steps on
/// the grey difference between `a` and `b` (both in a's frame) over a 5x5 window, every
/// window pixel moved along its own line by the same disparity; window pixels whose SGM
/// disparity differs from the centre's by more than a pixel are left out (another surface).
/// A step is kept only while the disparity stays within a pixel of SGM's (which chose the
/// surface; this only places it). SGM's parabola through three integer costs locks onto whole
/// pixels, and a textured surface a third of a pixel off blurs at every intermediate view.
fn refine(a: &GrayImage, b: &GrayImage, lines: &[LineFrame], d: &mut [f32]) {
    let (w, h) = (a.width() as usize, a.height() as usize);
    let (ra, rb) = (a.as_raw(), b.as_raw());
    let sample = |x: f32, y: f32| -> Option<f32> {
        if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f32 && y <= (h - 1) as f32) {
            return None;
        }
        let (x0, y0) = (x as usize, y as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let p = |xx: usize, yy: usize| f32::from(rb[yy * w + xx]);
        let top = p(x0, y0) + (p(x1, y0) - p(x0, y0)) * fx;
        let bot = p(x0, y1) + (p(x1, y1) - p(x0, y1)) * fx;
        Some(top + (bot - top) * fy)
    };
    let d0 = d.to_vec();
    d.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let i = y * w + x;
            let di = d0[i];
            let mut dd = di;
            for _ in 0..3 {
                let (mut num, mut den) = (0f32, 0f32);
                for wy in
                    (y as i64 - REFINE_RADIUS).max(0)..=(y as i64 + REFINE_RADIUS).min(h as i64 - 1)
                {
                    for wx in (x as i64 - REFINE_RADIUS).max(0)
                        ..=(x as i64 + REFINE_RADIUS).min(w as i64 - 1)
                    {
                        let j = wy as usize * w + wx as usize;
                        if (d0[j] - di).abs() > 1.0 {
                            continue;
                        }
                        let lf = lines[j];
                        let bx = wx as f32 + lf.offset[0] + dd * lf.along[0];
                        let by = wy as f32 + lf.offset[1] + dd * lf.along[1];
                        let (Some(v), Some(vp), Some(vm)) = (
                            sample(bx, by),
                            sample(bx + 0.5 * lf.along[0], by + 0.5 * lf.along[1]),
                            sample(bx - 0.5 * lf.along[0], by - 0.5 * lf.along[1]),
                        ) else {
                            continue;
                        };
                        let g = vp - vm;
                        num += g * (v - f32::from(ra[j]));
                        den += g * g;
                    }
                }
                if den < 1.0 {
                    break;
                }
                let step = (-num / den).clamp(-0.5, 0.5);
                if (dd + step - di).abs() > 1.0 {
                    break;
                }
                dd += step;
                if step.abs() < 0.01 {
                    break;
                }
            }
            *out = dd;
        }
    });
}

/// Fills invalid pixels from the nearest valid ones on their row: of the two, the farther
/// surface (an occluded pixel belongs to what lies behind the occluder), `near` telling which
/// sign of disparity is nearer (+1 or -1; 0: the smaller magnitude); the one there is when only
/// one side has one.
fn fill(d: &mut [f32], valid: &[bool], w: usize, near: f32) {
    for (row, vrow) in d.chunks_mut(w).zip(valid.chunks(w)) {
        let mut left: Vec<Option<f32>> = vec![None; w];
        let mut last = None;
        for x in 0..w {
            if vrow[x] {
                last = Some(row[x]);
            }
            left[x] = last;
        }
        let mut next = None;
        for x in (0..w).rev() {
            if vrow[x] {
                next = Some(row[x]);
                continue;
            }
            row[x] = match (left[x], next) {
                (Some(l), Some(r)) => {
                    let far = |v: f32| if near == 0.0 { v.abs() } else { near * v };
                    if far(l) < far(r) {
                        l
                    } else {
                        r
                    }
                }
                (Some(v), None) | (None, Some(v)) => v,
                (None, None) => 0.0,
            };
        }
    }
}

/// The dense parallax of a neighbour pair: backgrounds `a` and `b`, plane `h` (a to b), the
/// search geometry from [`geometry`].
pub fn estimate(
    a: &RgbImage,
    b: &RgbImage,
    h: &Homography,
    geo: &Geometry,
    params: &ParallaxParams,
) -> PairParallax {
    let (w, hgt) = a.dimensions();
    let v = geo.direction;
    let lo = geo.lo.max(-MAX_RANGE / 2);
    let hi = geo.hi.min(MAX_RANGE / 2).max(lo);
    // Memory: a byte of cost and four of aggregate per pixel and disparity. At most
    // MAX_VOLUME cells: a wider range at a large size is narrowed about its middle.
    let pixels = (w as usize * hgt as usize).max(1);
    let most = ((MAX_VOLUME / pixels) as i32).max(8);
    let (lo, hi) = if hi - lo + 1 > most {
        let mid = (lo + hi) / 2;
        (mid - most / 2, mid - most / 2 + most - 1)
    } else {
        (lo, hi)
    };
    let ga = crate::register::grey(a);
    let gb = crate::register::grey(b);
    // b in a's frame and a in b's frame (the plane taken out).
    let warp_grey = |src: &RgbImage, map: &Homography| {
        let warped = crate::warp::warp_rgb(src, map, w, hgt, crate::warp::Interpolation::Bilinear);
        crate::register::grey(&warped)
    };
    let b_in_a = warp_grey(b, &h.inverse());
    let a_in_b = warp_grey(a, h);
    // Which pixels of each warped image the other view really shows (inside its frame).
    let seen = |map: &Homography| -> Vec<bool> {
        (0..(w * hgt) as usize)
            .map(|i| {
                let p = Point::new((i % w as usize) as f64, (i / w as usize) as f64);
                map.apply(p).is_some_and(|q| {
                    q.x >= 0.0 && q.y >= 0.0 && q.x <= (w - 1) as f64 && q.y <= (hgt - 1) as f64
                })
            })
            .collect()
    };
    let frames = |m: Option<[f64; 9]>, dir: [f32; 2]| -> Vec<LineFrame> {
        (0..(w * hgt) as usize)
            .into_par_iter()
            .map(|i| {
                line_frame(
                    m.as_ref(),
                    dir,
                    (i % w as usize) as f64,
                    (i / w as usize) as f64,
                )
            })
            .collect()
    };
    let (lines_a, lines_b) = (geo.lines.map(|l| l[0]), geo.lines.map(|l| l[1]));
    let frames_a = frames(lines_a, v);
    let mut da = sgm(&ga, &b_in_a, &seen(h), &frames_a, lo, hi, params);
    refine(&ga, &b_in_a, &frames_a, &mut da);
    // From b's side the same points move the other way: b's pixel y is a's (plane-warped)
    // pixel y - d vb.
    let vb = direction_b(h, v, w, hgt);
    let frames_b = frames(lines_b, vb);
    let mut db = sgm(&gb, &a_in_b, &seen(&h.inverse()), &frames_b, lo, hi, params);
    refine(&gb, &a_in_b, &frames_b, &mut db);
    let (wu, hu) = (w as usize, hgt as usize);
    let field = |dir, lines, d: Vec<f32>| {
        let valid = vec![true; wu * hu];
        Field::new(w, hgt, dir, lines, d, valid).expect("sizes and values checked above")
    };
    let (fa, fb) = (field(v, lines_a, da), field(vb, lines_b, db));
    // Left-right check: a's x is b_in_a's x + flow, which is b's pixel y = H(x + flow); b's
    // flow there must lead back to (about) x through H^-1, and the other way round.
    let check = |f1: &Field, map: &Homography, f2: &Field| -> Vec<bool> {
        (0..wu * hu)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % wu) as f64, (i / wu) as f64);
                let u = f1.flow_px(i);
                let p = Point::new(x + u[0] as f64, y + u[1] as f64);
                let Some(q) = map.apply(p) else {
                    return false;
                };
                if !(q.x >= -0.5 && q.y >= -0.5 && q.x < w as f64 - 0.5 && q.y < hgt as f64 - 0.5) {
                    return false;
                }
                let u2 = f2.flow_at(q.x, q.y);
                let Some(back) =
                    map.apply_inverse(Point::new(q.x + u2[0] as f64, q.y + u2[1] as f64))
                else {
                    return false;
                };
                (back.x - x).hypot(back.y - y) <= params.lr_threshold as f64
            })
            .collect()
    };
    let va = check(&fa, h, &fb);
    let vbv = check(&fb, &h.inverse(), &fa);
    // Which sign of disparity is nearer than the plane: points nearer move farther than the
    // plane does, farther ones less (the plane's own motion at the centre, along the field's
    // direction); none when the plane hardly moves.
    let near = |map: &Homography, dir: [f32; 2]| -> f32 {
        let c = Point::new(f64::from(w) / 2.0, f64::from(hgt) / 2.0);
        let m = map.apply(c).map_or(0.0, |q| {
            (q.x - c.x) * f64::from(dir[0]) + (q.y - c.y) * f64::from(dir[1])
        });
        if m.abs() < 0.5 {
            0.0
        } else {
            m.signum() as f32
        }
    };
    let (mut da, mut db) = (fa.disparity, fb.disparity);
    fill(&mut da, &va, wu, near(h, v));
    fill(&mut db, &vbv, wu, near(&h.inverse(), vb));
    PairParallax {
        a: Field::new(w, hgt, v, lines_a, da, va).expect("checked"),
        b: Field::new(w, hgt, vb, lines_b, db, vbv).expect("checked"),
    }
}

fn bilinear(img: &RgbImage, x: f64, y: f64) -> Option<[f32; 3]> {
    let (w, h) = (img.width() as f64, img.height() as f64);
    if !(x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0) {
        return None;
    }
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let (x1, y1) = (
        (x0 + 1).min(img.width() - 1),
        (y0 + 1).min(img.height() - 1),
    );
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let p = |xx, yy| img.get_pixel(xx, yy).0;
    let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
    let mut out = [0f32; 3];
    for k in 0..3 {
        let top = a[k] as f32 + (b[k] as f32 - a[k] as f32) * fx;
        let bot = c[k] as f32 + (d[k] as f32 - c[k] as f32) * fx;
        out[k] = top + (bot - top) * fy;
    }
    Some(out)
}

/// Iterations of the backward fixed point `x = x0 - f u(x)`.
pub const FIXED_POINT_STEPS: usize = 3;

/// A trace has converged when its last fixed-point step moved it less than this (pixels).
pub const CONVERGED_PX: f64 = 1.0;

/// Weight of a view whose trace did not converge while the other's did, relative to its
/// `(1 - f, f)` share.
pub const UNCONVERGED_WEIGHT: f32 = 1.0 / 16.0;

/// The background at fraction `f` between views a (0) and b (1): each output pixel `z` is traced
/// back into both views (`x0 = H_(a,q)^-1 z`, then `x = x0 - f u_a(x)` by a few fixed-point
/// steps; the same from b with `1 - f`) and the two samples blended with weights `(1 - f, f)`
/// (one alone where the other falls outside its image). `h_aq`, `h_bq`: the plane homographies of eq. (3) to the output.
pub fn morph(
    a: &RgbImage,
    b: &RgbImage,
    pair: &PairParallax,
    h_aq: &Homography,
    h_bq: &Homography,
    f: f64,
    width: u32,
    height: u32,
) -> RgbImage {
    let mut out = RgbImage::new(width, height);
    // The trace and whether it converged (its last step moved less than CONVERGED_PX): where a
    // surface in front covers the output pixel at fraction f in one view only, that view's
    // trace jumps between the two surfaces instead.
    let trace = |field: &Field, h: &Homography, frac: f64, z: Point| -> Option<(f64, f64, bool)> {
        let x0 = h.apply_inverse(z)?;
        let (mut x, mut y) = (x0.x, x0.y);
        let mut moved = f64::INFINITY;
        for _ in 0..FIXED_POINT_STEPS {
            let u = field.flow_at(x, y);
            let (nx, ny) = (x0.x - u[0] as f64 * frac, x0.y - u[1] as f64 * frac);
            moved = (nx - x).hypot(ny - y);
            (x, y) = (nx, ny);
        }
        Some((x, y, moved < CONVERGED_PX))
    };
    out.as_mut()
        .par_chunks_mut(3 * width as usize)
        .enumerate()
        .for_each(|(yy, row)| {
            for xx in 0..width as usize {
                let z = Point::new(xx as f64, yy as f64);
                let ta = trace(&pair.a, h_aq, f, z);
                let tb = trace(&pair.b, h_bq, 1.0 - f, z);
                let sa = ta.and_then(|(x, y, _)| bilinear(a, x, y));
                let sb = tb.and_then(|(x, y, _)| bilinear(b, x, y));
                let conv_a = ta.is_some_and(|t| t.2);
                let conv_b = tb.is_some_and(|t| t.2);
                // Weights (1 - f, f), the view whose trace converged preferred where only one
                // did (measured, mean PSNR over three q: Reindeer 28.4 -> 30.0 dB, Dolls and
                // Moebius +0.7 / +0.9). Preferring the view that the left-right check
                // confirmed, or the one it did not, measured worse on every Middlebury pair.
                let (mut wa, mut wb) = (1.0 - f as f32, f as f32);
                if conv_a != conv_b {
                    wa *= if conv_a { 1.0 } else { UNCONVERGED_WEIGHT };
                    wb *= if conv_b { 1.0 } else { UNCONVERGED_WEIGHT };
                }
                let (ca, cb) = (sa, sb);
                let px = match (ca, cb) {
                    (Some(ca), Some(cb)) => {
                        let s = wa + wb;
                        [0, 1, 2].map(|k| (ca[k] * wa + cb[k] * wb) / s)
                    }
                    (Some(c), None) | (None, Some(c)) => c,
                    (None, None) => [0.0; 3],
                };
                for k in 0..3 {
                    row[3 * xx + k] = px[k].round().clamp(0.0, 255.0) as u8;
                }
            }
        });
    out
}

/// A random texture (blocks of 2 px so census sees structure), seen by two cameras on a
/// horizontal line: the left half is a plane at disparity 0 (the marked plane), the right half a
/// nearer one shifted by 6 px. 160x96. (The parallax tests and the renderer's.)
#[cfg(test)]
pub(crate) fn test_pair() -> (RgbImage, RgbImage) {
    let (w, h) = (160u32, 96u32);
    let tex = |x: i64, y: i64| {
        let v = crate::rng::mix_at(7, ((y.div_euclid(2)) * 1000 + x.div_euclid(2)) as u64);
        let g = (v % 200) as u8 + 30;
        image::Rgb([g, g / 2 + 40, 255 - g])
    };
    let a = RgbImage::from_fn(w, h, |x, y| tex(x as i64, y as i64));
    let b = RgbImage::from_fn(w, h, |x, y| {
        let shift = if x >= 80 { 6 } else { 0 };
        tex(x as i64 - shift, y as i64)
    });
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair() -> (RgbImage, RgbImage) {
        super::test_pair()
    }

    #[test]
    fn sgm_finds_the_parallax_of_a_nearer_plane() {
        let (a, b) = pair();
        let h = Homography::identity();
        let par = estimate(
            &a,
            &b,
            &h,
            &Geometry::straight([1.0, 0.0], -4, 12),
            &ParallaxParams::default(),
        );
        let w = 160usize;
        let (mut good, mut n) = (0, 0);
        for y in 8..88 {
            for x in 8..152 {
                if !(70..=92).contains(&x) {
                    let want = if x >= 80 - 6 + 6 { 6.0 } else { 0.0 };
                    n += 1;
                    good += ((par.a.disparity[y * w + x] - want).abs() < 0.5) as usize;
                }
            }
        }
        assert!(good * 100 >= 95 * n, "{good} of {n} within 0.5 px");
    }

    /// A registration's homography that shears across the parallax (incompatible with the rig:
    /// the true matches move along x only): the fitted lines pass through the true matches,
    /// straight lines along the mean direction miss them by pixels.
    #[test]
    fn fitted_lines_absorb_a_sheared_plane() {
        let h = Homography::from_matrix(nalgebra::Matrix3::new(
            1.0, -0.03, -12.0, 0.012, 1.03, -6.0, 0.0, 2e-5, 1.0,
        ))
        .unwrap();
        let (w, hgt) = (640u32, 480u32);
        let mut matches = Vec::new();
        for i in 0..400u64 {
            let a = Point::new(
                10.0 + 620.0 * crate::rng::unit(crate::rng::mix_at(1, i)),
                10.0 + 460.0 * crate::rng::unit(crate::rng::mix_at(2, i)),
            );
            let depth = 4.0 + 24.0 * crate::rng::unit(crate::rng::mix_at(3, i));
            matches.push((a, Point::new(a.x - depth, a.y)));
        }
        let geo = geometry(&matches, &h, (w, hgt)).unwrap();
        let lines = geo.lines.expect("fitted lines");
        let across = |m: Option<&[f64; 9]>| -> f64 {
            matches
                .iter()
                .map(|&(a, b)| {
                    let q = h.apply_inverse(b).unwrap();
                    let f = line_frame(m, geo.direction, a.x, a.y);
                    let (rx, ry) = (
                        q.x - a.x - f64::from(f.offset[0]),
                        q.y - a.y - f64::from(f.offset[1]),
                    );
                    (rx * f64::from(f.along[1]) - ry * f64::from(f.along[0])).abs()
                })
                .fold(0.0, f64::max)
        };
        let (fitted, straight) = (across(Some(&lines[0])), across(None));
        assert!(
            fitted < 0.5 && straight > 3.0,
            "fitted {fitted} px, straight {straight} px"
        );
    }

    /// An occluded run between a far (smaller motion than the plane's) and a near surface takes
    /// the far one's disparity.
    #[test]
    fn occlusions_are_filled_from_the_farther_side() {
        // The plane moves +x (near = +), far surface d = -3, near surface d = +5.
        let mut d = vec![-3.0, -3.0, 0.0, 0.0, 5.0, 5.0];
        let valid = [true, true, false, false, true, true];
        fill(&mut d, &valid, 6, 1.0);
        assert_eq!(d, [-3.0, -3.0, -3.0, -3.0, 5.0, 5.0]);
        let mut d = vec![5.0, 0.0, -3.0];
        fill(&mut d, &[true, false, true], 3, -1.0);
        assert_eq!(d, [5.0, 5.0, -3.0]);
    }

    #[test]
    fn a_field_refuses_what_does_not_fit_and_derives_its_flow() {
        let ok = |d: Vec<f32>, dir: [f32; 2], lines: Option<[f64; 9]>| {
            Field::new(3, 2, dir, lines, d, vec![true; 6])
        };
        assert!(ok(vec![0.0; 5], [1.0, 0.0], None).is_err());
        assert!(ok(vec![0.0; 6], [2.0, 0.0], None).is_err());
        assert!(ok(vec![0.0, f32::NAN, 0.0, 0.0, 0.0, 0.0], [1.0, 0.0], None).is_err());
        let mut nan_lines = [0.0; 9];
        nan_lines[4] = f64::INFINITY;
        assert!(ok(vec![0.0; 6], [1.0, 0.0], Some(nan_lines)).is_err());
        // Straight along (0, -1): d = 2 moves 2 px up; a line model's constant offset of 1.5 px
        // moves the line across, along the direction's normal (-vy, vx) = (1, 0).
        let f = ok(vec![2.0; 6], [0.0, -1.0], None).unwrap();
        assert_eq!(f.flow_px(4), [0.0, -2.0]);
        let mut m = [0.0; 9];
        m[0] = 1.5;
        let f = ok(vec![2.0; 6], [0.0, -1.0], Some(m)).unwrap();
        assert_eq!(f.flow_px(4), [1.5, -2.0]);
    }

    #[test]
    fn direction_comes_from_the_off_plane_matches() {
        let h = Homography::identity();
        let mut matches = Vec::new();
        for i in 0..60 {
            let a = Point::new(10.0 + 7.0 * i as f64, 20.0 + 3.0 * (i % 9) as f64);
            // A third on the plane, the rest moved along (0.96, 0.28) by 3..12 px, plus a few
            // mismatches.
            let d = if i % 3 == 0 {
                0.0
            } else {
                3.0 + (i % 10) as f64
            };
            let b = if i % 17 == 5 {
                Point::new(a.x - 40.0, a.y + 25.0)
            } else {
                Point::new(a.x + 0.96 * d, a.y + 0.28 * d)
            };
            matches.push((a, b));
        }
        let (v, lo, hi) = direction_and_range(&matches, &h).unwrap();
        assert!(
            (v[0] - 0.96).abs() < 0.02 && (v[1] - 0.28).abs() < 0.03,
            "{v:?}"
        );
        assert!(lo <= -2 && hi >= 12, "{lo}..{hi}");
        // On the plane: no parallax to model.
        let flat: Vec<(Point, Point)> = matches.iter().map(|&(a, _)| (a, a)).collect();
        assert!(direction_and_range(&flat, &h).is_none());
    }
}

/// How the background between two views is made (eq. (3) and beyond).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackgroundMode {
    /// The thesis's plane warp for every pair (and what scenes written before the morph used).
    #[default]
    Plane,
    /// The morph along the dense parallax for every pair with parallax.
    Morph,
    /// Per pair, the morph where the residual parallax after the plane is measurable (at
    /// least [`AUTO_PARALLAX_PX`]: a plane seen through features placed to a pixel shows
    /// about 1 px), else the plane.
    Auto,
}

impl std::str::FromStr for BackgroundMode {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Self> {
        match s {
            "plane" => Ok(Self::Plane),
            "morph" => Ok(Self::Morph),
            "auto" => Ok(Self::Auto),
            _ => Err(crate::Error::InvalidParameter {
                name: "background",
                value: s.into(),
                why: "expected plane, morph or auto".into(),
            }),
        }
    }
}

/// [`BackgroundMode::Auto`] morphs a pair when the 90th percentile of its matches' parallax
/// after the plane reaches this many pixels.
pub const AUTO_PARALLAX_PX: f64 = 2.0;

/// What the analysis found about a pair's parallax.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ParallaxFigures {
    /// 90th percentile of the matches' distance from the plane's prediction along the parallax
    /// direction, pixels (0 when no match is off the plane).
    pub residual_px: f64,
    /// Share of view a's pixels whose disparity both views confirm (0 when not estimated).
    pub confirmed: f64,
    /// Whether the pair is morphed.
    pub morph: bool,
}

/// The parallax of a neighbour pair as the analysis decides it under `mode`: the residuals of
/// the backgrounds' feature `matches` (every mutual-best match, not only the plane's inliers)
/// after the plane `h` measured and, where `mode` asks for it, the dense fields estimated.
/// None for [`BackgroundMode::Plane`].
pub fn analyse_pair(
    a: &RgbImage,
    b: &RgbImage,
    h: &Homography,
    matches: &[(Point, Point)],
    mode: BackgroundMode,
    params: &ParallaxParams,
) -> Option<(ParallaxFigures, Option<PairParallax>)> {
    if mode == BackgroundMode::Plane {
        return None;
    }
    let Some(geo) = geometry(matches, h, a.dimensions()) else {
        let none = ParallaxFigures {
            residual_px: 0.0,
            confirmed: 0.0,
            morph: false,
        };
        return Some((none, None));
    };
    let v = geo.direction;
    let mut along: Vec<f64> = matches
        .iter()
        .filter_map(|(pa, pb)| h.apply_inverse(*pb).map(|q| (q.x - pa.x, q.y - pa.y)))
        .filter(|r| (r.0 * -(v[1] as f64) + r.1 * v[0] as f64).abs() <= 2.0)
        .map(|r| (r.0 * v[0] as f64 + r.1 * v[1] as f64).abs())
        .collect();
    along.sort_by(f64::total_cmp);
    let residual_px = along
        .get(((along.len().max(1) - 1) as f64 * 0.9).round() as usize)
        .copied()
        .unwrap_or(0.0);
    let morph = mode == BackgroundMode::Morph || residual_px >= AUTO_PARALLAX_PX;
    if !morph {
        let f = ParallaxFigures {
            residual_px,
            confirmed: 0.0,
            morph: false,
        };
        return Some((f, None));
    }
    let pair = estimate(a, b, h, &geo, params);
    let confirmed =
        pair.a.valid.iter().filter(|&&x| x).count() as f64 / pair.a.valid.len().max(1) as f64;
    Some((
        ParallaxFigures {
            residual_px,
            confirmed,
            morph: true,
        },
        Some(pair),
    ))
}
