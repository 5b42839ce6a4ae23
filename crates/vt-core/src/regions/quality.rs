//! Measuring a baked loop: tile wraps, sharpness near wraps, error to the source frames.

use super::*;

/// What a baked loop looks like, measured on its frames inside the dynamic region.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Quality {
    /// The output time whose step to the next is the smallest (where [`rotate`] puts the
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
        .map(|t| &frames[rl.labels[0].frame((t + rl.phase) % rl.length)])
        .collect()
}

/// Weighted mean absolute difference over `px` (full-resolution pixel indices).
pub(super) fn mad(a: &RgbImage, b: &RgbImage, px: &[usize], wt: &[f32]) -> (f64, f64) {
    let (ra, rb) = (a.as_raw(), b.as_raw());
    let mut s = 0f64;
    let mut n = 0f64;
    for &i in px {
        let w = wt[i] as f64;
        if w == 0.0 {
            continue;
        }
        let d = (0..3)
            .map(|c| ra[3 * i + c].abs_diff(rb[3 * i + c]) as u32)
            .sum::<u32>();
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
pub fn quality<B: Borrow<RgbImage> + Sync>(
    baked: &[B],
    source: &[RgbImage],
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality {
    let (w, h) = source[0].dimensions();
    let wt: Vec<f32> = match alpha {
        Some(a) => a.as_raw().iter().map(|&v| v as f32 / 255.0).collect(),
        None => vec![1.0; (w * h) as usize],
    };
    let all: Vec<usize> = (0..(w * h) as usize).collect();
    let l = rl.length;
    // Steps 0 -> 1 .. L-1 -> L, then the player's wrap L -> 1.
    let mut steps: Vec<f64> = (0..l)
        .into_par_iter()
        .map(|t| {
            let (s, n) = mad(baked[t].borrow(), baked[t + 1].borrow(), &all, &wt);
            s / n.max(1e-9)
        })
        .collect();
    let (s, n) = mad(baked[l].borrow(), baked[1.min(l)].borrow(), &all, &wt);
    steps.push(s / n.max(1e-9));
    let med = median(steps.clone()).max(1e-9);
    let smoothest = (0..l)
        .min_by(|&a, &b| steps[a].total_cmp(&steps[b]))
        .unwrap_or(0);
    let worst_step = steps.iter().cloned().fold(0.0, f64::max) / med;
    // Per tile.
    let (cols, _) = rl.grid;
    let tile_px = tile_pixels(rl, w, h);
    let rows = rl.labels.len() / cols;
    let at = |t: usize| (t + rl.phase) % l;
    // Per tile: its wrap ratio, its source error, its gradient energy near its wraps and in
    // the source, and its share of the dynamic region.
    let per_tile: Vec<(f64, f64, f64, f64, f64)> = tile_px
        .par_iter()
        .zip(&rl.labels)
        .enumerate()
        .map(|(ti, (px, lab))| {
            let share: f64 = px.iter().map(|&i| wt[i] as f64).sum::<f64>();
            if share < 0.1 * px.len() as f64 {
                return (0.0, 0.0, 0.0, 0.0, share);
            }
            let mut ordinary = Vec::new();
            let mut wraps = Vec::new();
            let mut near = vec![false; l];
            for t in 0..l {
                let (s, n) = mad(baked[t].borrow(), baked[t + 1].borrow(), px, &wt);
                let step = s / n.max(1e-9);
                if lab.frame(at(t + 1)) == lab.frame(at(t)) + 1 {
                    ordinary.push(step);
                } else {
                    wraps.push(step);
                    for k in [t + l - 1, t, t + 1, t + 2] {
                        near[k % l] = true;
                    }
                }
            }
            let med = median(ordinary).max(crate::seam::MIN_UNIT);
            let wrap = wraps.iter().sum::<f64>() / wraps.len().max(1) as f64 / med;
            // Per baked frame, the nearest of the source frames the tile and its eight
            // neighbours show at that time (an upper bound of the distance to the nearest
            // source frame of all).
            let (tx, ty) = (ti % cols, ti / cols);
            let err: f64 = (0..l)
                .map(|t| {
                    let mut cand: Vec<usize> = (ty.saturating_sub(1)..(ty + 2).min(rows))
                        .flat_map(|y| {
                            (tx.saturating_sub(1)..(tx + 2).min(cols))
                                .map(move |x| rl.labels[y * cols + x].frame(at(t)))
                        })
                        .collect();
                    cand.sort_unstable();
                    cand.dedup();
                    cand.iter()
                        .map(|&f| {
                            let (e, n) = mad(baked[t].borrow(), &source[f], px, &wt);
                            e / n.max(1e-9)
                        })
                        .fold(f64::INFINITY, f64::min)
                })
                .sum::<f64>()
                / l as f64;
            let ge_near = {
                let v: Vec<f64> = (0..l)
                    .filter(|&t| near[t])
                    .map(|t| {
                        crate::metrics::gradient_energy_at(baked[t].borrow(), Some(px), Some(&wt))
                    })
                    .collect();
                v.iter().sum::<f64>() / v.len().max(1) as f64
            };
            let ge_src = source
                .iter()
                .map(|f| crate::metrics::gradient_energy_at(f, Some(px), Some(&wt)))
                .sum::<f64>()
                / source.len() as f64;
            (wrap, err, ge_near, ge_src, share)
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
    let ge = |v: &[&RgbImage]| {
        v.par_iter()
            .map(|f| crate::metrics::gradient_energy_at(f, None, Some(&wt)))
            .sum::<f64>()
            / v.len() as f64
    };
    let baked: Vec<&RgbImage> = baked[..l].iter().map(|f| f.borrow()).collect();
    let source: Vec<&RgbImage> = source.iter().collect();
    Quality {
        smoothest,
        worst_step,
        tile_wrap: quantile(0.5),
        tile_wrap_p90: quantile(0.9),
        sharpness: ge(&baked) / ge(&source).max(1e-9),
        source_error: wmean(|t| t.1),
        sharpness_near: wmean(|t| t.2) / wmean(|t| t.3).max(1e-9),
    }
}
