//! The search lines: the direction and range of the parallax from the feature matches, and
//! each view's lines fitted to their residuals.

use super::*;

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
pub(super) fn model_terms(x: f64, y: f64, d: f64) -> [f64; 9] {
    [1.0, x, y, x * x, x * y, y * y, d, d * x, d * y]
}

/// Fits the line model to residuals `(x, y, along, perp)`: `perp ~ q(x, y) + along l(x, y)`,
/// iteratively reweighted least squares (Cauchy weights, scale from the median absolute
/// residual, at least 0.5 px). Positions are taken in units of `scale` pixels for conditioning
/// and the coefficients converted back. None with fewer than 20 residuals or a singular fit.
pub(super) fn fit_lines(res: &[(f64, f64, f64, f64)], scale: f64) -> Option<[f64; 9]> {
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
pub(super) fn range_of(mut along: Vec<f64>) -> Option<(i32, i32)> {
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
pub(super) fn direction_b(h: &Homography, v: [f32; 2], w: u32, hgt: u32) -> [f32; 2] {
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
