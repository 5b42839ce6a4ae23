//! Photometric refinement of a homography between two views' median backgrounds, so hand-marked
//! points (a few pixels of marking error) stop deciding the geometry alone.
//!
//! Method: Gauss-Newton (Lucas-Kanade, forward additive) on a coarse-to-fine pyramid of grey
//! images, under the scene's chosen model (translation 2, similarity 4, affine 6 or homography 8
//! parameters), minimising over the pixels of `region` (in view a)
//!
//! `E(H) = sum_x (I_b(H x) - alpha I_a(x) - beta)^2`,
//!
//! with the gain `alpha` and offset `beta` re-fitted by least squares at every evaluation, so a
//! per-view exposure difference does not pull the geometry. Steps are damped
//! (Levenberg-Marquardt) and taken only when they lower `E`. The result is *kept* only if it
//! lowers the RMS photometric error at full resolution; the caller may add its own checks (the
//! analysis also requires the refined homography to stay consistent with the marked points).
//! OpenCV's `findTransformECC` solves the same problem with a correlation criterion; vt-cv's
//! twin runs it for the cross-check.

use image::RgbImage;
use nalgebra::{DMatrix, DVector, Matrix3};

use crate::model::MotionModel;
use crate::{Error, Homography, Mask, Point, Result};

/// Refinement settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignParams {
    /// Pyramid levels (1 = full resolution only).
    pub levels: usize,
    /// Gauss-Newton iterations per level at most.
    pub iterations: usize,
    /// Region pixels used per level at most (evenly subsampled beyond).
    pub max_pixels: usize,
}

impl Default for AlignParams {
    fn default() -> Self {
        Self {
            levels: 4,
            iterations: 40,
            max_pixels: 60_000,
        }
    }
}

/// What the refinement found.
#[derive(Debug, Clone, Copy)]
pub struct Alignment {
    /// The refined homography (a to b); equal to the initial one when not kept.
    pub homography: Homography,
    /// RMS photometric error (grey levels, after gain and offset) with the initial homography.
    pub error_before: f64,
    /// RMS photometric error with the refined homography.
    pub error_after: f64,
    /// Whether the refinement lowered the error (and so was kept).
    pub improved: bool,
    /// Region pixels compared at full resolution.
    pub pixels: usize,
}

/// A grey image in f32.
#[derive(Debug, Clone)]
pub(crate) struct Grey {
    pub(crate) w: usize,
    pub(crate) h: usize,
    pub(crate) v: Vec<f32>,
}

impl Grey {
    /// A grey image's values as they are.
    pub(crate) fn from_luma(img: &image::GrayImage) -> Self {
        Self {
            w: img.width() as usize,
            h: img.height() as usize,
            v: img.as_raw().iter().map(|&p| p as f32).collect(),
        }
    }

    fn from_rgb(img: &RgbImage) -> Self {
        Self {
            w: img.width() as usize,
            h: img.height() as usize,
            v: img
                .as_raw()
                .chunks_exact(3)
                .map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0)
                .collect(),
        }
    }

    fn half(&self) -> Self {
        let (w, h) = ((self.w / 2).max(1), (self.h / 2).max(1));
        let mut v = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let (x0, y0) = ((2 * x).min(self.w - 1), (2 * y).min(self.h - 1));
                let (x1, y1) = ((2 * x + 1).min(self.w - 1), (2 * y + 1).min(self.h - 1));
                v[y * w + x] = 0.25
                    * (self.v[y0 * self.w + x0]
                        + self.v[y0 * self.w + x1]
                        + self.v[y1 * self.w + x0]
                        + self.v[y1 * self.w + x1]);
            }
        }
        Self { w, h, v }
    }

    /// Bilinear sample and gradient at (x, y); None outside `[0, w-1] x [0, h-1]`.
    pub(crate) fn sample_grad(&self, x: f64, y: f64) -> Option<(f32, f32, f32)> {
        if !(x >= 0.0 && y >= 0.0 && x <= (self.w - 1) as f64 && y <= (self.h - 1) as f64) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let at = |xx: usize, yy: usize| self.v[yy * self.w + xx];
        let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        let top = a + (b - a) * fx;
        let bottom = c + (d - c) * fx;
        let v = top + (bottom - top) * fy;
        let gx = (b - a) * (1.0 - fy) + (d - c) * fy;
        let gy = (c - a) * (1.0 - fx) + (d - b) * fx;
        Some((v, gx, gy))
    }
}

/// Columns `dh/dp` (8 x k) of the model's parameters in the 8 free homography entries
/// (row-major, `h22 = 1`).
fn model_basis(model: MotionModel) -> DMatrix<f64> {
    let cols: Vec<[f64; 8]> = match model {
        MotionModel::Translation => vec![
            [0., 0., 1., 0., 0., 0., 0., 0.],
            [0., 0., 0., 0., 0., 1., 0., 0.],
        ],
        MotionModel::Similarity => vec![
            [1., 0., 0., 0., 1., 0., 0., 0.],
            [0., -1., 0., 1., 0., 0., 0., 0.],
            [0., 0., 1., 0., 0., 0., 0., 0.],
            [0., 0., 0., 0., 0., 1., 0., 0.],
        ],
        MotionModel::Affine => (0..6)
            .map(|i| {
                let mut c = [0.; 8];
                c[i] = 1.0;
                c
            })
            .collect(),
        MotionModel::Homography => (0..8)
            .map(|i| {
                let mut c = [0.; 8];
                c[i] = 1.0;
                c
            })
            .collect(),
    };
    DMatrix::from_fn(8, cols.len(), |r, c| cols[c][r])
}

fn to_vec(m: &Matrix3<f64>) -> [f64; 8] {
    let m = m / m[(2, 2)];
    [
        m[(0, 0)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 0)],
        m[(1, 1)],
        m[(1, 2)],
        m[(2, 0)],
        m[(2, 1)],
    ]
}

fn to_mat(h: &[f64; 8]) -> Matrix3<f64> {
    Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0)
}

/// `S_l`: full-resolution pixels to level-l pixels (pixel centres at integers).
fn level_scale(l: usize) -> Matrix3<f64> {
    let s = 0.5f64.powi(l as i32);
    let t = 0.5 * s - 0.5;
    Matrix3::new(s, 0.0, t, 0.0, s, t, 0.0, 0.0, 1.0)
}

/// The photometric error over `pts` (level coordinates of region pixels in a, with their grey
/// values) for homography `h`, after the best gain and offset: (RMS, count, alpha, beta).
fn error(pts: &[(f64, f64, f32, usize)], b: &[&Grey], h: &[f64; 8]) -> (f64, usize, f64, f64) {
    let mut pairs = Vec::with_capacity(pts.len());
    for &(x, y, ia, i) in pts {
        if let Some((u, v)) = apply8(h, x, y) {
            if let Some((ib, _, _)) = b[i].sample_grad(u, v) {
                pairs.push((ia as f64, ib as f64));
            }
        }
    }
    let (alpha, beta) = gain_offset(&pairs);
    let n = pairs.len();
    if n == 0 {
        return (f64::INFINITY, 0, 1.0, 0.0);
    }
    let sse: f64 = pairs
        .iter()
        .map(|&(a, b)| (b - alpha * a - beta).powi(2))
        .sum();
    ((sse / n as f64).sqrt(), n, alpha, beta)
}

fn gain_offset(pairs: &[(f64, f64)]) -> (f64, f64) {
    let n = pairs.len() as f64;
    if n < 2.0 {
        return (1.0, 0.0);
    }
    let (ma, mb) = pairs
        .iter()
        .fold((0.0, 0.0), |s, p| (s.0 + p.0 / n, s.1 + p.1 / n));
    let (mut cov, mut var) = (0.0, 0.0);
    for &(a, b) in pairs {
        cov += (a - ma) * (b - mb);
        var += (a - ma) * (a - ma);
    }
    let alpha = if var > 1e-9 { cov / var } else { 1.0 };
    (alpha, mb - alpha * ma)
}

#[inline]
fn apply8(h: &[f64; 8], x: f64, y: f64) -> Option<(f64, f64)> {
    let d = h[6] * x + h[7] * y + 1.0;
    if d.abs() < 1e-12 {
        return None;
    }
    Some((
        (h[0] * x + h[1] * y + h[2]) / d,
        (h[3] * x + h[4] * y + h[5]) / d,
    ))
}

/// Region pixels of a level: `(x, y, I_a)` at most `cap`, evenly strided.
fn region_points(a: &Grey, region: &Mask, level: usize, cap: usize) -> Vec<(f64, f64, f32)> {
    let f = 1usize << level;
    let mut all = Vec::new();
    for y in 0..a.h {
        for x in 0..a.w {
            // Level pixel (x, y) covers full-resolution block [f x, f x + f) x [f y, f y + f).
            let (fx, fy) = ((f * x + f / 2) as u32, (f * y + f / 2) as u32);
            if fx < region.width() && fy < region.height() && region.get(fx, fy) {
                all.push((x as f64, y as f64, a.v[y * a.w + x]));
            }
        }
    }
    if all.len() > cap {
        let stride = all.len().div_ceil(cap);
        all = all.into_iter().step_by(stride).collect();
    }
    all
}

/// The rule both alignments (this one and vt-cv's ECC twin) apply to their inputs: b and the
/// region have a's size.
pub fn check_inputs(a: &RgbImage, b: &RgbImage, region: &Mask) -> Result<()> {
    for (what, (got_w, got_h)) in [
        ("background alignment: second background", b.dimensions()),
        (
            "background alignment: region",
            (region.width(), region.height()),
        ),
    ] {
        if (got_w, got_h) != a.dimensions() {
            return Err(Error::SizeMismatch {
                what: what.into(),
                expected_w: a.width(),
                expected_h: a.height(),
                got_w,
                got_h,
            });
        }
    }
    Ok(())
}

/// Refines `init` (view a to view b) by aligning the two backgrounds over `region` (view a's
/// pixels), under `model`.
pub fn align_backgrounds(
    a: &RgbImage,
    b: &RgbImage,
    init: &Homography,
    region: &Mask,
    model: MotionModel,
    params: &AlignParams,
) -> Result<Alignment> {
    align_stack(&[(a, b)], init, region, model, params)
}

/// [`align_backgrounds`] for a stack of image pairs that share one homography (each `b` is its
/// `a` seen through it), one gain and offset: the sum of their squared errors is minimised.
/// Used for the moving object's silhouettes at matching phases in two views.
pub fn align_stack(
    pairs: &[(&RgbImage, &RgbImage)],
    init: &Homography,
    region: &Mask,
    model: MotionModel,
    params: &AlignParams,
) -> Result<Alignment> {
    for (a, b) in pairs {
        check_inputs(pairs[0].0, a, region)?;
        check_inputs(a, b, region)?;
    }
    let levels = params.levels.clamp(1, 8);
    // pyr[l][i]: pair i's images at level l.
    let mut pyr: Vec<Vec<(Grey, Grey)>> = vec![pairs
        .iter()
        .map(|(a, b)| (Grey::from_rgb(a), Grey::from_rgb(b)))
        .collect()];
    for l in 1..levels {
        let Some(first) = pyr[l - 1].first() else {
            break;
        };
        if first.0.w < 32 || first.0.h < 32 {
            break;
        }
        let next = pyr[l - 1]
            .iter()
            .map(|(a, b)| (a.half(), b.half()))
            .collect();
        pyr.push(next);
    }
    let basis = model_basis(model);
    let k = basis.ncols();
    let stack_points = |l: usize, cap: usize| -> Vec<(f64, f64, f32, usize)> {
        let per = cap / pyr[l].len().max(1);
        pyr[l]
            .iter()
            .enumerate()
            .flat_map(|(i, (ga, _))| {
                region_points(ga, region, l, per)
                    .into_iter()
                    .map(move |(x, y, v)| (x, y, v, i))
            })
            .collect()
    };
    // The errors before and after: every region pixel of one pair (the background refinement),
    // at most 4x the per-level cap over a stack.
    let full_cap = if pairs.len() > 1 {
        4 * params.max_pixels
    } else {
        usize::MAX
    };
    let full_pts = stack_points(0, full_cap);
    let full_b: Vec<&Grey> = pyr[0].iter().map(|(_, b)| b).collect();
    let init_v = to_vec(&init.matrix());
    let (error_before, pixels, _, _) = error(&full_pts, &full_b, &init_v);
    let mut h_full = init.matrix();
    for l in (0..pyr.len()).rev() {
        let gb: Vec<&Grey> = pyr[l].iter().map(|(_, b)| b).collect();
        let gb = &gb;
        let s = level_scale(l);
        let s_inv = s.try_inverse().expect("scale is invertible");
        let mut h = to_vec(&(s * h_full * s_inv));
        let pts = stack_points(l, params.max_pixels);
        if pts.len() < 4 * k {
            continue;
        }
        let mut lambda = 1e-3;
        let (mut e, _, mut alpha, mut beta) = error(&pts, gb, &h);
        for _ in 0..params.iterations {
            let mut jtj = DMatrix::<f64>::zeros(k, k);
            let mut jtr = DVector::<f64>::zeros(k);
            for &(x, y, ia, i) in &pts {
                let d = h[6] * x + h[7] * y + 1.0;
                if d.abs() < 1e-12 {
                    continue;
                }
                let (u, v) = (
                    (h[0] * x + h[1] * y + h[2]) / d,
                    (h[3] * x + h[4] * y + h[5]) / d,
                );
                let Some((ib, gx, gy)) = gb[i].sample_grad(u, v) else {
                    continue;
                };
                let r = ib as f64 - alpha * ia as f64 - beta;
                let (gx, gy) = (gx as f64, gy as f64);
                // d(u, v)/dh for the 8 entries.
                let du = [x / d, y / d, 1.0 / d, 0.0, 0.0, 0.0, -x * u / d, -y * u / d];
                let dv = [0.0, 0.0, 0.0, x / d, y / d, 1.0 / d, -x * v / d, -y * v / d];
                let mut jh = [0f64; 8];
                for i in 0..8 {
                    jh[i] = gx * du[i] + gy * dv[i];
                }
                let mut j = vec![0f64; k];
                for c in 0..k {
                    j[c] = (0..8).map(|i| jh[i] * basis[(i, c)]).sum();
                }
                for r1 in 0..k {
                    jtr[r1] += j[r1] * r;
                    for c in 0..k {
                        jtj[(r1, c)] += j[r1] * j[c];
                    }
                }
            }
            let mut stepped = false;
            for _ in 0..6 {
                let mut damped = jtj.clone();
                for i in 0..k {
                    damped[(i, i)] *= 1.0 + lambda;
                }
                let Some(delta) = damped.lu().solve(&(-&jtr)) else {
                    lambda *= 10.0;
                    continue;
                };
                let dh = &basis * &delta;
                let mut cand = h;
                for i in 0..8 {
                    cand[i] += dh[i];
                }
                let (ce, cn, ca, cb) = error(&pts, gb, &cand);
                if cn >= pts.len() / 2 && ce < e {
                    let small = dh.iter().map(|v| v.abs()).fold(0.0, f64::max) < 1e-7;
                    h = cand;
                    (e, alpha, beta) = (ce, ca, cb);
                    lambda = (lambda * 0.3).max(1e-7);
                    stepped = !small;
                    break;
                }
                lambda *= 10.0;
            }
            if !stepped {
                break;
            }
        }
        h_full = s_inv * to_mat(&h) * s;
    }
    let refined = to_vec(&h_full);
    let (error_after, _, _, _) = error(&full_pts, &full_b, &refined);
    let improved = error_after.is_finite() && error_after < error_before;
    let homography = if improved {
        Homography::from_matrix(h_full).unwrap_or(*init)
    } else {
        *init
    };
    Ok(Alignment {
        homography,
        error_before,
        error_after: if improved { error_after } else { error_before },
        improved,
        pixels,
    })
}

/// Pixels inside the convex polygon of `points` (hull order found here), for the region of the
/// marked plane.
pub fn hull_mask(points: &[Point], width: u32, height: u32) -> Mask {
    // Monotone chain convex hull.
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.x.is_finite() && p.y.is_finite())
        .map(|p| (p.x, p.y))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    pts.dedup();
    if pts.len() < 3 {
        return Mask::new(width, height);
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut hull: Vec<(f64, f64)> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    Mask::from_fn(width, height, |x, y| {
        let p = (x as f64, y as f64);
        (0..hull.len()).all(|i| cross(hull[i], hull[(i + 1) % hull.len()], p) >= 0.0)
    })
}

/// Points consistent with chained homographies: `hs[p]` maps view p to p + 1. Every view's
/// marked point is taken to view 0 through the chain, the M estimates averaged, and the mean
/// carried back out, so marking noise averages over the views (about 1/sqrt(M)).
pub fn consistent_points(points: &[Vec<Point>], hs: &[Homography]) -> Option<Vec<Vec<Point>>> {
    let m = points.len();
    if m == 0 || hs.len() + 1 != m {
        return None;
    }
    // to0[p]: view p to view 0.
    let mut to0 = vec![Homography::identity()];
    for p in 1..m {
        to0.push(to0[p - 1].after(&hs[p - 1].inverse()).ok()?);
    }
    let k = points[0].len();
    let mut base = Vec::with_capacity(k);
    for j in 0..k {
        let (mut sx, mut sy) = (0.0, 0.0);
        for p in 0..m {
            let q = to0[p].apply(*points[p].get(j)?)?;
            sx += q.x;
            sy += q.y;
        }
        base.push(Point::new(sx / m as f64, sy / m as f64));
    }
    let mut out = vec![base];
    for p in 1..m {
        let next: Option<Vec<Point>> = out[p - 1].iter().map(|&q| hs[p - 1].apply(q)).collect();
        out.push(next?);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured image (smooth blobs, so the pyramid sees structure at every level).
    fn texture(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let (xf, yf) = (x as f64, y as f64);
            let v = 128.0
                + 50.0 * (xf * 0.07).sin() * (yf * 0.05).cos()
                + 30.0 * ((xf + 2.0 * yf) * 0.13).sin()
                + 20.0 * ((xf * 0.31).cos() * (yf * 0.23).sin());
            let v = v.clamp(0.0, 255.0) as u8;
            image::Rgb([v, v, v])
        })
    }

    fn warp(src: &RgbImage, h: &Homography, gain: f64) -> RgbImage {
        let g = Grey::from_rgb(src);
        RgbImage::from_fn(src.width(), src.height(), |x, y| {
            let p = h.apply_inverse(Point::new(x as f64, y as f64)).unwrap();
            let v = g.sample_grad(p.x, p.y).map_or(0.0, |s| s.0 as f64) * gain;
            let v = v.round().clamp(0.0, 255.0) as u8;
            image::Rgb([v, v, v])
        })
    }

    #[test]
    fn recovers_a_perturbed_homography_despite_a_gain() {
        let a = texture(200, 150);
        let truth = Homography::from_matrix(Matrix3::new(
            1.02, 0.03, 3.0, -0.02, 0.99, -2.0, 2e-5, -1e-5, 1.0,
        ))
        .unwrap();
        let b = warp(&a, &truth, 1.05);
        let init = Homography::from_matrix(
            truth.matrix() * Matrix3::new(1.0, 0.0, 2.5, 0.0, 1.0, -1.5, 0.0, 0.0, 1.0),
        )
        .unwrap();
        let region = Mask::from_fn(200, 150, |x, y| {
            (30..170).contains(&x) && (25..125).contains(&y)
        });
        let r = align_backgrounds(
            &a,
            &b,
            &init,
            &region,
            MotionModel::Homography,
            &AlignParams::default(),
        )
        .unwrap();
        assert!(r.improved, "{r:?}");
        let corner = [(0.0, 0.0), (199.0, 0.0), (0.0, 149.0), (199.0, 149.0)]
            .iter()
            .map(|&(x, y)| {
                let p = Point::new(x, y);
                (r.homography.apply(p).unwrap() - truth.apply(p).unwrap()).norm()
            })
            .fold(0.0, f64::max);
        assert!(corner < 0.1, "corner error {corner}, {r:?}");
        assert!(r.error_after < 0.5 && r.error_before > 3.0, "{r:?}");
    }

    #[test]
    fn hull_and_consistent_points() {
        let sq = [
            Point::new(2.0, 2.0),
            Point::new(8.0, 2.0),
            Point::new(8.0, 8.0),
            Point::new(2.0, 8.0),
            Point::new(5.0, 5.0),
        ];
        let m = hull_mask(&sq, 12, 12);
        assert!(m.get(5, 5) && m.get(2, 2) && m.get(8, 8));
        assert!(!m.get(1, 5) && !m.get(9, 5));
        // Three views shifted by 10 px each; view 1's points are off by (+3, 0): the consistent
        // points spread that error over the three views.
        let hs = vec![Homography::translation(10.0, 0.0); 2];
        let pts: Vec<Vec<Point>> = (0..3)
            .map(|p| {
                sq.iter()
                    .map(|q| {
                        Point::new(q.x + 10.0 * p as f64 + if p == 1 { 3.0 } else { 0.0 }, q.y)
                    })
                    .collect()
            })
            .collect();
        let c = consistent_points(&pts, &hs).unwrap();
        assert!((c[0][0].x - 3.0).abs() < 1e-9 && (c[1][0].x - 13.0).abs() < 1e-9);
    }
}
