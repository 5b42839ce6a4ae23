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
//! two samples blended `(1 - f, f)` ([`morph_weights`]): the view whose trace converged
//! preferred where only one did (near an occluding edge, the view that sees the surface behind
//! converges; the other's trace jumps between the two surfaces); the nearer surface alone
//! where both converged on surfaces more than [`OCCLUSION_PX`] apart (beside an occluding edge
//! one view still sees the surface behind, which the edge hides at the new viewpoint).

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
        // Measured on the Middlebury line scenes (mean dB over three q, automatic / marked
        // points): p2 96 -> 64 and the left-right threshold 1 -> 2 px lift Dolls 37.09 /
        // 37.43 -> 37.29 / 37.60, Moebius 36.88 / 36.54 -> 37.08 / 36.70, Reindeer 31.98 /
        // 30.41 -> 32.19 / 30.68; a threshold of 0.5 px lost 0.3-0.6 dB on all six, 3 px
        // lost on Dolls, p2 40 or 140 and p1 4 or 14 moved each by 0.1 dB or less.
        Self {
            p1: 8,
            p2: 64,
            lr_threshold: 2.0,
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

mod lines;
mod matching;
mod morph;
#[cfg(test)]
mod tests;

pub use lines::*;
pub use matching::*;
pub use morph::*;
