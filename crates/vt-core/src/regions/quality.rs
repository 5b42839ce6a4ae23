//! Measuring a baked loop: tile wraps, sharpness near wraps, error to the source frames.

use super::*;

/// What a baked loop looks like, measured on its frames inside the dynamic region.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Quality {
    /// The output time whose step to the next is the smallest (where [`Bake::rotated`] puts the
    /// player's wrap).
    pub smoothest: usize,
    /// The largest step of the baked loop (its wrap `L -> 1` included) over its median step,
    /// over the dynamic region: any seam anywhere in the loop.
    pub worst_step: f64,
    /// Per tile, its own wrap's step over its median ordinary step (inside the tile; the unit
    /// floored at [`crate::seam::MIN_UNIT`]): the median over the tiles with at least 10% of
    /// their pixels dynamic, weighted by their share of the dynamic region.
    pub tile_wrap: f64,
    /// The same ratio's weighted 90th percentile over the tiles.
    pub tile_wrap_p90: f64,
    /// Mean gradient energy of the baked frames over that of the source frames.
    pub sharpness: f64,
    /// Mean absolute error (grey levels) of each baked frame to the nearest source frame,
    /// tile by tile (the nearest frame may differ per tile), weighted by the dynamic region;
    /// the nearest among the frames the tile and its eight neighbours show at that time, so
    /// an upper bound of the distance to the nearest source frame of all.
    pub source_error: f64,
    /// Sharpness near the jumps: per tile, the mean gradient energy of the baked frames from
    /// one before to two after each of its wraps over that of its source frames (weighted
    /// sums over the tiles as [`Quality::source_error`]); 1 = as sharp as the source.
    pub sharpness_near: f64,
}

impl Quality {
    /// Whether a loop measuring `self` is better than one measuring `other` (the thesis's loop
    /// measured alike), by their tiles' wraps (the median [`Quality::tile_wrap`]): the other's
    /// shows (its tiles wrap at more than 1.25x their ordinary step) and this one's are at
    /// most 90% of it. A loop about as good as the thesis's keeps the thesis's, and so does
    /// one that already wraps as it steps: exact synthetic loops measure 0.9-1.1x under their
    /// sensor noise, real footage that never repeats 1.6-2.1x (tree.avi and its 5-view scene).
    /// The 90th percentile is not used: tiles the object crosses only now and then have a
    /// median step near zero, and their ratios are noise (6-12x on exact synthetic loops).
    pub fn better_than(&self, other: &Quality) -> bool {
        other.shows() && self.tile_wrap < 0.9 * other.tile_wrap
    }

    /// Whether this loop's wraps show: its tiles' median wrap over 1.25 ordinary steps (see
    /// [`Quality::better_than`]).
    pub fn shows(&self) -> bool {
        self.tile_wrap > 1.25
    }
}

/// The frames a single-label loop from [`single_loop`] plays, as [`compose`] would make them
/// without feather or correction (`L + 1` of them, the last the first again), borrowed from
/// `frames`.
pub fn single_frames<'a>(frames: &'a [RgbImage], rl: &RegionLoop) -> Vec<&'a RgbImage> {
    (0..=rl.length)
        .map(|t| &frames[single_frame(rl, t)])
        .collect()
}

/// The source frame a single-label loop from [`single_loop`] shows at output time `t`.
pub fn single_frame(rl: &RegionLoop, t: usize) -> usize {
    rl.labels[0].frame((t + rl.phase) % rl.length)
}

/// Pixel index `i` of frame `f` of `frames`, `w` pixels wide.
#[inline]
pub(super) fn at<F: Frames + ?Sized>(frames: &F, f: usize, i: usize, w: u32) -> [u8; 3] {
    frames.px(f, (i % w as usize) as u32, (i / w as usize) as u32)
}

/// Weighted mean absolute difference over `px` (full-resolution pixel indices).
pub(super) fn mad(a: &RgbImage, b: &RgbImage, px: &[usize], wt: &[f32]) -> (f64, f64) {
    let (ra, rb) = (a.as_raw(), b.as_raw());
    mad_by(
        |i| [ra[3 * i], ra[3 * i + 1], ra[3 * i + 2]],
        |i| [rb[3 * i], rb[3 * i + 1], rb[3 * i + 2]],
        px,
        wt,
    )
}

/// [`mad`] over the pixels `x0..x1` of rows `y0..y1` of `w`-wide frames, with the weights as
/// levels of 255 (an alpha) given per byte (`wt3`: each pixel's three times), summed exactly in
/// integers row by row: the same figures but for the rounding of [`mad`]'s `f32` weights (1e-7
/// relative), and many times faster over whole frames (the rows vectorise).
pub(super) fn mad_rect(
    a: &RgbImage,
    b: &RgbImage,
    [x0, x1, y0, y1]: [usize; 4],
    w: usize,
    wt3: &[u8],
) -> (f64, f64) {
    let (ra, rb) = (a.as_raw(), b.as_raw());
    let (mut s, mut n) = (0u64, 0u64);
    // A row's sums fit a u32 up to 22,000 pixels; tiles are at most 256.
    for y in y0..y1 {
        let r = 3 * (y * w + x0)..3 * (y * w + x1);
        let (pa, pb, pw) = (&ra[r.clone()], &rb[r.clone()], &wt3[r]);
        let (mut rs, mut rn) = (0u32, 0u32);
        for ((&p, &q), &wv) in pa.iter().zip(pb).zip(pw) {
            rs += u32::from(wv) * u32::from(p.abs_diff(q));
            rn += u32::from(wv);
        }
        s += u64::from(rs);
        n += u64::from(rn);
    }
    (s as f64 / (3.0 * 255.0), n as f64 / (3.0 * 255.0))
}

/// [`mad`] of two pixel readers.
pub(super) fn mad_by(
    a: impl Fn(usize) -> [u8; 3],
    b: impl Fn(usize) -> [u8; 3],
    px: &[usize],
    wt: &[f32],
) -> (f64, f64) {
    let mut s = 0f64;
    let mut n = 0f64;
    for &i in px {
        let w = wt[i] as f64;
        if w == 0.0 {
            continue;
        }
        let (p, q) = (a(i), b(i));
        let d = (0..3).map(|c| p[c].abs_diff(q[c]) as u32).sum::<u32>();
        s += w * d as f64 / 3.0;
        n += w;
    }
    (s, n)
}

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Measures `baked` (from [`compose`]) against `source` inside the dynamic region `alpha`.
pub fn quality<B, F>(
    baked: &[B],
    source: &F,
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    B: Borrow<RgbImage> + Sync,
    F: Frames + ?Sized,
{
    quality_of(
        |t, out: &mut RgbImage| out.clone_from(baked[t].borrow()),
        source,
        rl,
        alpha,
    )
}

/// One tile's running measurements over the baked frames.
#[derive(Default)]
struct TileTally {
    ordinary: Vec<f64>,
    wraps: Vec<f64>,
    /// Sum over frames of the distance to the nearest candidate source frame.
    error: f64,
    /// Sum and count of the gradient energy of the frames near its wraps.
    near: (f64, usize),
}

/// [`quality`] of a loop whose baked frames `make(t, out)` writes into `out` (`t` in `0..=L`,
/// in order, each once): the frames stream, three held at a time in buffers reused, so a long
/// loop of large frames is measured in the memory of a few.
pub fn quality_of<M, F>(
    make: M,
    source: &F,
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    M: FnMut(usize, &mut RgbImage),
    F: Frames + ?Sized,
{
    measure(make, source.dimensions(), Some(source), rl, alpha)
}

/// [`quality_of`]'s step figures alone ([`Quality::smoothest`], [`Quality::worst_step`],
/// [`Quality::tile_wrap`] and its 90th percentile; the others 0), which decide whether a loop
/// [`Quality::shows`] at a fraction of the cost: no source frame is read.
pub fn wraps_of<M, F>(
    make: M,
    source: &F,
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    M: FnMut(usize, &mut RgbImage),
    F: Frames + ?Sized,
{
    measure(make, source.dimensions(), None::<&F>, rl, alpha)
}

/// [`wraps_of`] of `w x h` frames that `make` gives without a source behind them (e.g. decoded
/// as they are measured).
pub fn wraps_in<M>(
    make: M,
    dims: (u32, u32),
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    M: FnMut(usize, &mut RgbImage),
{
    measure(make, dims, None::<&[RgbImage]>, rl, alpha)
}

/// The loop's step figures, and with `source` the figures against it.
fn measure<M, F>(
    mut make: M,
    (w, h): (u32, u32),
    source: Option<&F>,
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    M: FnMut(usize, &mut RgbImage),
    F: Frames + ?Sized,
{
    let full = source.is_some();
    let wt: Vec<f32> = match alpha {
        Some(a) => a.as_raw().iter().map(|&v| v as f32 / 255.0).collect(),
        None => vec![1.0; (w * h) as usize],
    };
    // Each tile's rectangle (x0, x1, y0, y1), as `tile_pixels` lists them, and the weights as
    // the alpha's levels (255 without one), one per byte, for integer sums.
    let rects: Vec<[usize; 4]> = (0..rl.labels.len())
        .map(|ti| {
            let t = rl.tile as usize;
            let (x0, y0) = ((ti % rl.grid.0) * t, (ti / rl.grid.0) * t);
            [x0, (x0 + t).min(w as usize), y0, (y0 + t).min(h as usize)]
        })
        .collect();
    let wt8: Vec<u8> = match alpha {
        Some(a) => a.as_raw().iter().flat_map(|&v| [v; 3]).collect(),
        None => vec![255; 3 * (w * h) as usize],
    };
    // Every tile's step from `a` to `b` in one parallel pass.
    let tile_steps_of = |a: &RgbImage, b: &RgbImage| -> Vec<(f64, f64)> {
        rects
            .par_iter()
            .map(|&r| mad_rect(a, b, r, w as usize, &wt8))
            .collect()
    };
    let sum = |v: &[(f64, f64)]| v.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
    let l = rl.length;
    let (cols, _) = rl.grid;
    let tile_px = tile_pixels(rl, w, h);
    let rows = rl.labels.len() / cols;
    let at_t = |t: usize| (t + rl.phase) % l;
    // Per tile: its share of the dynamic region, whether it counts (at least 10% dynamic), and
    // the frames near its wraps (from one before to two after each).
    let share: Vec<f64> = tile_px
        .iter()
        .map(|px| px.iter().map(|&i| wt[i] as f64).sum::<f64>())
        .collect();
    let counts: Vec<bool> = tile_px
        .iter()
        .zip(&share)
        .map(|(px, &s)| s >= 0.1 * px.len() as f64)
        .collect();
    let wraps_at = |lab: &Label, t: usize| lab.frame(at_t(t + 1)) != lab.frame(at_t(t)) + 1;
    let near: Vec<Vec<bool>> = rl
        .labels
        .iter()
        .map(|lab| {
            let mut near = vec![false; l];
            for t in (0..l).filter(|&t| wraps_at(lab, t)) {
                for k in [t + l - 1, t, t + 1, t + 2] {
                    near[k % l] = true;
                }
            }
            near
        })
        .collect();
    // Per baked frame, per tile: the nearest of the source frames the tile and its eight
    // neighbours show at that time (an upper bound of the distance to the nearest source
    // frame of all).
    let candidates = |ti: usize, t: usize| -> Vec<usize> {
        let (tx, ty) = (ti % cols, ti / cols);
        let mut cand: Vec<usize> = (ty.saturating_sub(1)..(ty + 2).min(rows))
            .flat_map(|y| {
                (tx.saturating_sub(1)..(tx + 2).min(cols))
                    .map(move |x| rl.labels[y * cols + x].frame(at_t(t)))
            })
            .collect();
        cand.sort_unstable();
        cand.dedup();
        cand
    };
    let mut tally: Vec<TileTally> = (0..rl.labels.len()).map(|_| TileTally::default()).collect();
    // Steps 0 -> 1 .. L-1 -> L, then the player's wrap L -> 1.
    let mut steps = Vec::with_capacity(l + 1);
    let mut ge_baked = 0.0;
    let (mut prev, mut next) = (RgbImage::new(0, 0), RgbImage::new(0, 0));
    make(0, &mut prev);
    let mut second = None;
    for t in 0..l {
        make(t + 1, &mut next);
        let (a, b) = (&prev, &next);
        // The frame's step is the sum of its tiles' (they partition it).
        let tile_steps = tile_steps_of(a, b);
        let (s, n) = sum(&tile_steps);
        steps.push(s / n.max(1e-9));
        // The frame's gradient energy, summed from its tiles' (every tile, counted or not).
        let energy = full.then(|| {
            tile_px
                .par_iter()
                .map(|px| crate::metrics::gradient_sums_at(a, Some(px), Some(&wt)))
                .collect::<Vec<_>>()
        });
        if let Some(e) = &energy {
            let (s, n) = e.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
            ge_baked += s / n.max(1e-9);
        }
        tally
            .par_iter_mut()
            .enumerate()
            .filter(|(ti, _)| counts[*ti])
            .for_each(|(ti, tt)| {
                let (px, lab) = (&tile_px[ti], &rl.labels[ti]);
                let (s, n) = tile_steps[ti];
                let step = s / n.max(1e-9);
                if wraps_at(lab, t) {
                    tt.wraps.push(step);
                } else {
                    tt.ordinary.push(step);
                }
                let (Some(energy), Some(source)) = (&energy, source) else {
                    return;
                };
                tt.error += candidates(ti, t)
                    .into_iter()
                    .map(|f| {
                        let (e, n) = mad_by(
                            |i| {
                                [
                                    a.as_raw()[3 * i],
                                    a.as_raw()[3 * i + 1],
                                    a.as_raw()[3 * i + 2],
                                ]
                            },
                            |i| at(source, f, i, w),
                            px,
                            &wt,
                        );
                        e / n.max(1e-9)
                    })
                    .fold(f64::INFINITY, f64::min);
                if near[ti][t] {
                    let (s, n) = energy[ti];
                    tt.near.0 += s / n.max(1e-9);
                    tt.near.1 += 1;
                }
            });
        if t == 0 {
            second = Some(next.clone());
        }
        std::mem::swap(&mut prev, &mut next);
    }
    if let Some(first) = second.as_ref().filter(|_| l >= 1) {
        let (s, n) = sum(&tile_steps_of(&prev, first));
        steps.push(s / n.max(1e-9));
    } else {
        steps.push(0.0);
    }
    drop((prev, next, second));
    let med = median(steps.clone()).max(1e-9);
    let smoothest = (0..l)
        .min_by(|&a, &b| steps[a].total_cmp(&steps[b]))
        .unwrap_or(0);
    let worst_step = steps.iter().cloned().fold(0.0, f64::max) / med;
    // The source frames' gradient energy, per tile and over the frame, one frame in RGB at a
    // time per thread.
    let n_src = source.map_or(0, |s| s.count());
    let (ge_src_tiles, ge_src) = (0..n_src)
        .into_par_iter()
        .map_init(
            || RgbImage::new(w, h),
            |buf, f| {
                source
                    .expect("n_src > 0 only with a source")
                    .rgb_into(f, buf);
                let sums: Vec<(f64, f64)> = tile_px
                    .iter()
                    .map(|px| crate::metrics::gradient_sums_at(buf, Some(px), Some(&wt)))
                    .collect();
                let (s, n) = sums.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
                let tiles: Vec<f64> = sums
                    .iter()
                    .zip(&counts)
                    .map(|(&(s, n), &c)| if c { s / n.max(1e-9) } else { 0.0 })
                    .collect();
                (tiles, s / n.max(1e-9))
            },
        )
        .reduce(
            || (vec![0.0; tile_px.len()], 0.0),
            |(mut a, x), (b, y)| {
                for (a, b) in a.iter_mut().zip(&b) {
                    *a += b;
                }
                (a, x + y)
            },
        );
    // Per tile: its wrap ratio, its source error, its gradient energy near its wraps and in
    // the source, and its share of the dynamic region.
    let per_tile: Vec<(f64, f64, f64, f64, f64)> = tally
        .into_iter()
        .enumerate()
        .map(|(ti, tt)| {
            if !counts[ti] {
                return (0.0, 0.0, 0.0, 0.0, share[ti]);
            }
            let med = median(tt.ordinary).max(crate::seam::MIN_UNIT);
            let wrap = tt.wraps.iter().sum::<f64>() / tt.wraps.len().max(1) as f64 / med;
            (
                wrap,
                tt.error / l as f64,
                tt.near.0 / tt.near.1.max(1) as f64,
                ge_src_tiles[ti] / n_src.max(1) as f64,
                share[ti],
            )
        })
        .collect();
    let total: f64 = per_tile.iter().filter(|t| t.0 > 0.0).map(|t| t.4).sum();
    let quantile = |q: f64| -> f64 {
        let mut v: Vec<(f64, f64)> = per_tile
            .iter()
            .filter(|t| t.0 > 0.0)
            .map(|t| (t.0, t.4))
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut acc = 0.0;
        for (r, w) in &v {
            acc += w;
            if acc >= q * total {
                return *r;
            }
        }
        v.last().map_or(0.0, |x| x.0)
    };
    let wmean = |k: fn(&(f64, f64, f64, f64, f64)) -> f64| {
        per_tile
            .iter()
            .filter(|t| t.0 > 0.0)
            .map(|t| k(t) * t.4)
            .sum::<f64>()
            / total.max(1e-9)
    };
    Quality {
        smoothest,
        worst_step,
        tile_wrap: quantile(0.5),
        tile_wrap_p90: quantile(0.9),
        sharpness: (ge_baked / l.max(1) as f64) / (ge_src / n_src.max(1) as f64).max(1e-9),
        source_error: wmean(|t| t.1),
        sharpness_near: wmean(|t| t.2) / wmean(|t| t.3).max(1e-9),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row-wise integer sums over a tile's rectangle give `mad`'s figures over the same
    /// tile's pixel list, on a frame whose size is no multiple of the tile.
    #[test]
    fn rectangle_sums_match_the_pixel_lists() {
        let (w, h, tile) = (37u32, 23u32, 8u32);
        let noise = |seed: u32| {
            RgbImage::from_fn(w, h, |x, y| {
                let v = (x * 31 + y * 17 + seed).wrapping_mul(2654435761) >> 24;
                image::Rgb([v as u8, (v * 3) as u8, (v * 7) as u8])
            })
        };
        let (a, b) = (noise(1), noise(2));
        let alpha: Vec<u8> = (0..w * h).map(|i| (i * 13 % 256) as u8).collect();
        let wt: Vec<f32> = alpha.iter().map(|&v| v as f32 / 255.0).collect();
        let wt3: Vec<u8> = alpha.iter().flat_map(|&v| [v; 3]).collect();
        let rl = crate::regions::single_loop(
            Label {
                start: 0,
                period: 4,
            },
            (w, h),
            tile,
        );
        let lists = tile_pixels(&rl, w, h);
        assert_eq!(lists.len(), 5 * 3);
        for (ti, px) in lists.iter().enumerate() {
            let (x0, y0) = ((ti % 5) * 8, (ti / 5) * 8);
            let rect = [x0, (x0 + 8).min(37), y0, (y0 + 8).min(23)];
            let (s, n) = mad(&a, &b, px, &wt);
            let (rs, rn) = mad_rect(&a, &b, rect, w as usize, &wt3);
            assert!(n > 0.0 && s > 0.0, "tile {ti}");
            assert!((rs - s).abs() <= 1e-6 * s, "tile {ti}: {rs} vs {s}");
            assert!((rn - n).abs() <= 1e-6 * n, "tile {ti}: {rn} vs {n}");
        }
    }
}
