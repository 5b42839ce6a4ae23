//! Census transform, semi-global matching along the lines, sub-pixel refinement and the fill
//! of unmatched pixels.

use super::*;

/// Matching cost where the other view shows nothing (outside its frame): a middling census
/// distance, so the smoothness terms decide there instead of a wall of maximal costs that
/// pushes near objects at the image's edge to the wrong disparity.
pub(super) const OUTSIDE_COST: u8 = 64;

/// Most cells (pixels x disparities) of the matching volume, 120 M: 600 MB with the aggregate.
pub const MAX_VOLUME: usize = 120_000_000;

/// Largest disparity range (values of d) the estimation searches.
pub const MAX_RANGE: i32 = 256;

/// 7x7 census: one bit per neighbour, set where it is darker than the centre (48 bits).
pub(super) fn census(img: &GrayImage) -> Vec<u64> {
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
pub(super) fn sgm(
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
pub(super) const REFINE_RADIUS: i64 = 2;

/// Sub-pixel refinement of the semi-global disparities: at each pixel, Gauss-Newton steps on
/// the grey difference between `a` and `b` (both in a's frame) over a 5x5 window, every
/// window pixel moved along its own line by the same disparity; window pixels whose SGM
/// disparity differs from the centre's by more than a pixel are left out (another surface).
/// A step is kept only while the disparity stays within a pixel of SGM's (which chose the
/// surface; this only places it). SGM's parabola through three integer costs locks onto whole
/// pixels, and a textured surface a third of a pixel off blurs at every intermediate view.
pub(super) fn refine(a: &GrayImage, b: &GrayImage, lines: &[LineFrame], d: &mut [f32]) {
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
pub(super) fn fill(d: &mut [f32], valid: &[bool], w: usize, near: f32) {
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
