//! Dense parallax between two neighbouring median backgrounds, beyond the plane of eq. (3).
//!
//! The plane homography `H` (view a to view b) explains the marked plane only; everything off
//! it shows twice at an intermediate viewpoint. Cameras on a line see a scene point move along
//! one direction once the plane is taken out (the epipolar lines are near parallel when the
//! cameras move sideways), so what is left is a *disparity* along a direction `v`: a's pixel
//! `x` is b's pixel `H(x + d(x) v)`.
//!
//! # Estimation ([`estimate`])
//! b is warped into a's frame by `H^-1`; both become grey; a 7x7 census transform of each;
//! matching cost = Hamming distance of the census words at `x` and `x + d v` (nearest pixel),
//! for every integer `d` in the range; semi-global matching (Hirschmüller 2008) along 8 paths
//! with penalties `P1`, `P2`; winner takes all with a parabola for the sub-pixel part; the
//! same from b's side; pixels whose two disparities disagree by more than a pixel are marked
//! invalid (occluded or unmatched), then filled from their valid neighbours along the row so
//! the field is defined everywhere (the renderer weights invalid pixels to zero).
//!
//! The direction and range come from the feature matches ([`direction_and_range`]): the
//! residuals of the matches off the plane, after `H`.

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

/// A disparity field along `direction` in one view's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Unit direction of the parallax in this view's (plane-aligned) frame.
    pub direction: [f32; 2],
    /// Disparity per pixel (row-major): this view's pixel `x` is the other view's (plane-warped)
    /// pixel `x + d v`. Defined everywhere (invalid pixels filled).
    pub disparity: Vec<f32>,
    /// Whether each pixel passed the left-right check (seen by both views).
    pub valid: Vec<bool>,
}

impl Field {
    /// Disparity at the nearest pixel (clamped to the image).
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> f32 {
        let xi = (x.round().max(0.0) as usize).min(self.width as usize - 1);
        let yi = (y.round().max(0.0) as usize).min(self.height as usize - 1);
        self.disparity[yi * self.width as usize + xi]
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
    let mut along: Vec<f64> = res
        .iter()
        .filter(|r| (r.0 * -vy + r.1 * vx).abs() <= 2.0)
        .map(|r| r.0 * vx + r.1 * vy)
        .collect();
    along.sort_by(f64::total_cmp);
    if along.len() < 10 {
        return None;
    }
    let pick = |q: f64| along[((along.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = (pick(0.01), pick(0.99));
    let margin = 4.0 + 0.25 * (hi - lo);
    let lo = ((lo - margin).floor() as i32).min(-2);
    let hi = ((hi + margin).ceil() as i32).max(2);
    Some(([vx as f32, vy as f32], lo, hi))
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

/// Semi-global matching of `a` against `b` (both in a's frame) along `v` over `lo..=hi`:
/// sub-pixel disparity per pixel (NaN where no cost was defined).
fn sgm(
    a: &GrayImage,
    b: &GrayImage,
    b_seen: &[bool],
    v: [f32; 2],
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
                for k in 0..nd {
                    let d = (lo + k as i32) as f32;
                    let bx = (x as f32 + d * v[0]).round() as i64;
                    let by = (y as f32 + d * v[1]).round() as i64;
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

/// Fills invalid pixels from the nearest valid ones on their row (the farther-looking of the two
/// by the smaller disparity magnitude... the mean when only one side has one).
fn fill(d: &mut [f32], valid: &[bool], w: usize) {
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
                    if l.abs() < r.abs() {
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
/// direction `v` in a's frame and the range of d, from [`direction_and_range`].
pub fn estimate(
    a: &RgbImage,
    b: &RgbImage,
    h: &Homography,
    (v, lo, hi): ([f32; 2], i32, i32),
    params: &ParallaxParams,
) -> PairParallax {
    let (w, hgt) = a.dimensions();
    let lo = lo.max(-MAX_RANGE / 2);
    let hi = hi.min(MAX_RANGE / 2).max(lo);
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
    let da = sgm(&ga, &b_in_a, &seen(h), v, lo, hi, params);
    // In b's frame the direction maps through H (locally); at b's centre.
    let c = Point::new(w as f64 / 2.0, hgt as f64 / 2.0);
    let vb = match (
        h.apply(c),
        h.apply(Point::new(c.x + v[0] as f64, c.y + v[1] as f64)),
    ) {
        (Some(p), Some(q)) => {
            let (x, y) = (q.x - p.x, q.y - p.y);
            let n = x.hypot(y).max(1e-9);
            [(x / n) as f32, (y / n) as f32]
        }
        _ => v,
    };
    // From b's side the same points move the other way: b's pixel y is a's (plane-warped)
    // pixel y - d vb.
    let db = sgm(
        &gb,
        &a_in_b,
        &seen(&h.inverse()),
        [-vb[0], -vb[1]],
        lo,
        hi,
        params,
    );
    let (wu, hu) = (w as usize, hgt as usize);
    // Left-right check: a's x is b_in_a's x + d v, which is b's pixel H(x + d v); b's field
    // there must hold (about) the same disparity, and the other way round through H^-1.
    let check = |d1: &[f32], v1: [f32; 2], map: &Homography, d2: &[f32]| -> Vec<bool> {
        (0..wu * hu)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % wu) as f64, (i / wu) as f64);
                let d = d1[i];
                let p = Point::new(x + (d * v1[0]) as f64, y + (d * v1[1]) as f64);
                let Some(q) = map.apply(p) else {
                    return false;
                };
                let (qx, qy) = (q.x.round(), q.y.round());
                if qx < 0.0 || qy < 0.0 || qx >= w as f64 || qy >= hgt as f64 {
                    return false;
                }
                let j = qy as usize * wu + qx as usize;
                (d - d2[j]).abs() <= params.lr_threshold
            })
            .collect()
    };
    let va = check(&da, v, h, &db);
    let vbv = check(&db, [-vb[0], -vb[1]], &h.inverse(), &da);
    let (mut da, mut db) = (da, db);
    fill(&mut da, &va, wu);
    fill(&mut db, &vbv, wu);
    PairParallax {
        a: Field {
            width: w,
            height: hgt,
            direction: v,
            disparity: da,
            valid: va,
        },
        b: Field {
            width: w,
            height: hgt,
            direction: [-vb[0], -vb[1]],
            disparity: db,
            valid: vbv,
        },
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

/// Iterations of the backward fixed point `x = x0 - f d(x) v`.
const FIXED_POINT_STEPS: usize = 4;

/// The background at fraction `f` between views a (0) and b (1): each output pixel `z` is traced
/// back into both views (`x0 = H_(a,q)^-1 z`, then `x = x0 - f d_a(x) v_a` by a few fixed-point
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
    let trace = |field: &Field, h: &Homography, frac: f64, z: Point| -> Option<(f64, f64)> {
        let x0 = h.apply_inverse(z)?;
        let (mut x, mut y) = (x0.x, x0.y);
        for _ in 0..FIXED_POINT_STEPS {
            let d = field.at(x, y) as f64 * frac;
            x = x0.x - d * field.direction[0] as f64;
            y = x0.y - d * field.direction[1] as f64;
        }
        Some((x, y))
    };
    out.as_mut()
        .par_chunks_mut(3 * width as usize)
        .enumerate()
        .for_each(|(yy, row)| {
            for xx in 0..width as usize {
                let z = Point::new(xx as f64, yy as f64);
                let sa = trace(&pair.a, h_aq, f, z).and_then(|(x, y)| bilinear(a, x, y));
                let sb = trace(&pair.b, h_bq, 1.0 - f, z).and_then(|(x, y)| bilinear(b, x, y));
                // Weights (1 - f, f) whether or not the left-right check confirmed the pixel:
                // letting a confirmed view take it alone measured worse on every Middlebury
                // pair (Dolls q=0.5 36.3 -> 34.1 dB).
                let (wa, wb) = (1.0 - f as f32, f as f32);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A random texture (blocks of 2 px so census sees structure), seen by two cameras on a
    /// horizontal line: the left half is a plane at disparity 0 (the marked plane), the right
    /// half a nearer one shifted by 6 px.
    fn pair() -> (RgbImage, RgbImage) {
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

    #[test]
    fn sgm_finds_the_parallax_of_a_nearer_plane() {
        let (a, b) = pair();
        let h = Homography::identity();
        let par = estimate(&a, &b, &h, ([1.0, 0.0], -4, 12), &ParallaxParams::default());
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
    let Some((v, lo, hi)) = direction_and_range(matches, h) else {
        let none = ParallaxFigures {
            residual_px: 0.0,
            confirmed: 0.0,
            morph: false,
        };
        return Some((none, None));
    };
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
    let pair = estimate(a, b, h, (v, lo, hi), params);
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
