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
    mad_rows((y0..y1).map(|y| {
        let r = 3 * (y * w + x0)..3 * (y * w + x1);
        (&ra[r.clone()], &rb[r.clone()], &wt3[r])
    }))
}

/// [`mad_rect`] of frame `a`'s rectangle against `b`, the same rectangle's pixels row after
/// row (as [`Frames::rect_into`] gives them).
fn mad_rect_buf(
    a: &RgbImage,
    [x0, x1, y0, y1]: [usize; 4],
    w: usize,
    wt3: &[u8],
    b: &[u8],
) -> (f64, f64) {
    let ra = a.as_raw();
    let row = 3 * (x1 - x0);
    mad_rows((y0..y1).zip(b.chunks_exact(row.max(1))).map(|(y, pb)| {
        let r = 3 * (y * w + x0)..3 * (y * w + x1);
        (&ra[r.clone()], pb, &wt3[r])
    }))
}

/// The weighted sums of [`mad_rect`] over rows given as (a's bytes, b's bytes, weights).
fn mad_rows<'a>(rows: impl Iterator<Item = (&'a [u8], &'a [u8], &'a [u8])>) -> (f64, f64) {
    let (mut s, mut n) = (0u64, 0u64);
    // A row's sums fit a u32 up to 22,000 pixels; tiles are at most 256.
    for (pa, pb, pw) in rows {
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
    let energy = SourceEnergy::of(source, rl.tile, alpha);
    quality_with(make, source, &energy, rl, alpha)
}

/// [`quality_of`] with the source's gradient energy measured beforehand (`energy`, of the same
/// `source`, `alpha` and tile size; another tile size is measured anew), so that loops of the
/// same window share it.
pub fn quality_with<M, F>(
    make: M,
    source: &F,
    energy: &SourceEnergy,
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    M: FnMut(usize, &mut RgbImage),
    F: Frames + ?Sized,
{
    let fresh;
    let energy = if energy.fits(rl) {
        energy
    } else {
        fresh = SourceEnergy::of(source, rl.tile, alpha);
        &fresh
    };
    measure(
        make,
        source.dimensions(),
        Against::Source(source, energy),
        rl,
        alpha,
    )
}

/// [`quality_of`] of a single-label loop from [`single_loop`] (the thesis's loop), whose
/// frames are the source's own (`source` frame [`single_frame`] at output time `t`): each
/// frame's gradient energy is read from `energy` (see [`quality_with`]) and its distance to
/// the nearest source frame is 0, so only the steps are measured. The same figures as
/// [`quality_of`] of those frames.
pub fn quality_of_single<F>(
    source: &F,
    energy: &SourceEnergy,
    one: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    F: Frames + ?Sized,
{
    let make = |t, out: &mut RgbImage| source.rgb_into(single_frame(one, t), out);
    let single = one.blend.is_none() && one.labels.iter().all(|l| *l == one.labels[0]);
    if !single || !energy.fits(one) {
        // Not one label, or other tiles: measured as any loop.
        return quality_with(make, source, energy, one, alpha);
    }
    measure(
        make,
        source.dimensions(),
        Against::Own::<F>(energy),
        one,
        alpha,
    )
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
    measure(make, source.dimensions(), Against::<F>::Nothing, rl, alpha)
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
    measure(make, dims, Against::<[RgbImage]>::Nothing, rl, alpha)
}

/// The source frames' gradient energy per tile (the weighted sums and weights of
/// [`crate::metrics::gradient_sums_at`] over each tile's pixels), which every loop measured on
/// the same window, alpha and tile size shares.
pub struct SourceEnergy {
    tile: u32,
    dims: (u32, u32),
    /// Per source frame, per tile (row by row).
    frames: Vec<Vec<(f64, f64)>>,
}

impl SourceEnergy {
    /// The energy of every frame of `source` over tiles of `tile` pixels, weighted by `alpha`.
    pub fn of<F: Frames + ?Sized>(source: &F, tile: u32, alpha: Option<&image::GrayImage>) -> Self {
        let (w, h) = source.dimensions();
        let rects = tile_rects(tile, (w, h));
        let wt = weights(alpha, (w, h));
        let frames = (0..source.count())
            .into_par_iter()
            .map_init(
                || RgbImage::new(w, h),
                |buf, f| {
                    source.rgb_into(f, buf);
                    tile_energies(buf, &rects, &wt)
                },
            )
            .collect();
        Self {
            tile,
            dims: (w, h),
            frames,
        }
    }

    /// Whether this measures `rl`'s tiles.
    fn fits(&self, rl: &RegionLoop) -> bool {
        let (w, h) = self.dims;
        self.tile == rl.tile
            && rl.grid == (w.div_ceil(rl.tile) as usize, h.div_ceil(rl.tile) as usize)
            && self.frames.iter().all(|f| f.len() == rl.labels.len())
    }
}

/// The rectangles `[x0, x1, y0, y1]` of the tiles of `tile` pixels over a `w x h` frame, row by
/// row (as [`tile_pixels`] lists their pixels).
fn tile_rects(tile: u32, (w, h): (u32, u32)) -> Vec<[usize; 4]> {
    let (cols, rows) = (w.div_ceil(tile) as usize, h.div_ceil(tile) as usize);
    let t = tile as usize;
    (0..cols * rows)
        .map(|ti| {
            let (x0, y0) = ((ti % cols) * t, (ti / cols) * t);
            [x0, (x0 + t).min(w as usize), y0, (y0 + t).min(h as usize)]
        })
        .collect()
}

/// Per-pixel weights: the alpha's levels over 255, or 1 without one.
fn weights(alpha: Option<&image::GrayImage>, (w, h): (u32, u32)) -> Vec<f32> {
    match alpha {
        Some(a) => a.as_raw().iter().map(|&v| v as f32 / 255.0).collect(),
        None => vec![1.0; (w * h) as usize],
    }
}

/// [`crate::metrics::gradient_sums_at`] of `f` over each of `rects`, with weights `wt`: the
/// same terms summed in the same order (each tile's pixels row by row), so the same figures,
/// with the frame's luma computed once instead of three times a pixel.
fn tile_energies(f: &RgbImage, rects: &[[usize; 4]], wt: &[f32]) -> Vec<(f64, f64)> {
    let (w, h) = (f.width() as usize, f.height() as usize);
    let mut luma = vec![0f32; w * h];
    luma.par_chunks_mut(w.max(1))
        .zip(f.as_raw().par_chunks(3 * w.max(1)))
        .for_each(|(out, row)| {
            for (k, l) in out.iter_mut().enumerate() {
                *l = crate::metrics::luma_at(row, k);
            }
        });
    rects
        .par_iter()
        .map(|&[x0, x1, y0, y1]| {
            let (mut s, mut n) = (0f64, 0f64);
            for y in y0..y1.min(h.saturating_sub(1)) {
                for x in x0..x1.min(w.saturating_sub(1)) {
                    let i = y * w + x;
                    let a = wt[i] as f64;
                    if a == 0.0 {
                        continue;
                    }
                    let v = luma[i];
                    let (gx, gy) = (luma[i + 1] - v, luma[i + w] - v);
                    s += a * (gx * gx + gy * gy) as f64;
                    n += a;
                }
            }
            (s, n)
        })
        .collect()
}

/// What [`measure`] measures a loop against besides its own steps.
enum Against<'a, F: ?Sized> {
    /// Nothing: the step figures alone.
    Nothing,
    /// The source frames (and their energy): the baked frames' sharpness and distance to them.
    Source(&'a F, &'a SourceEnergy),
    /// The source frames' energy, the loop a single label showing them: its frames' energy is
    /// theirs and their distance to the source 0.
    Own(&'a SourceEnergy),
}

/// The loop's step figures, and against a source the figures against it.
fn measure<M, F>(
    mut make: M,
    (w, h): (u32, u32),
    against: Against<'_, F>,
    rl: &RegionLoop,
    alpha: Option<&image::GrayImage>,
) -> Quality
where
    M: FnMut(usize, &mut RgbImage),
    F: Frames + ?Sized,
{
    let (source, src_energy) = match &against {
        Against::Nothing => (None, None),
        Against::Source(s, e) => (Some(*s), Some(*e)),
        Against::Own(e) => (None, Some(*e)),
    };
    let wt = weights(alpha, (w, h));
    // Each tile's rectangle (x0, x1, y0, y1), as `tile_pixels` lists them, and the weights as
    // the alpha's levels (255 without one), one per byte, for integer sums.
    let rects = tile_rects(rl.tile, (w, h));
    debug_assert_eq!(rects.len(), rl.labels.len());
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
    let rows = rl.labels.len() / cols;
    let at_t = |t: usize| (t + rl.phase) % l;
    // Per tile: its share of the dynamic region, whether it counts (at least 10% dynamic), and
    // the frames near its wraps (from one before to two after each).
    let share: Vec<f64> = rects
        .iter()
        .map(|&[x0, x1, y0, y1]| {
            (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| y * w as usize + x))
                .map(|i| wt[i] as f64)
                .sum::<f64>()
        })
        .collect();
    let counts: Vec<bool> = rects
        .iter()
        .zip(&share)
        .map(|(&[x0, x1, y0, y1], &s)| s >= 0.1 * ((x1 - x0) * (y1 - y0)) as f64)
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
        // The frame's gradient energy, summed from its tiles' (every tile, counted or not):
        // measured, or a source frame's own.
        let measured;
        let energy: Option<&[(f64, f64)]> = match &against {
            Against::Nothing => None,
            Against::Source(..) => {
                measured = tile_energies(a, &rects, &wt);
                Some(&measured)
            }
            Against::Own(e) => Some(&e.frames[rl.labels[0].frame(at_t(t))]),
        };
        if let Some(e) = energy {
            let (s, n) = e.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
            ge_baked += s / n.max(1e-9);
        }
        tally
            .par_iter_mut()
            .enumerate()
            .filter(|(ti, _)| counts[*ti])
            .for_each_init(Vec::new, |buf, (ti, tt)| {
                let lab = &rl.labels[ti];
                let (s, n) = tile_steps[ti];
                let step = s / n.max(1e-9);
                if wraps_at(lab, t) {
                    tt.wraps.push(step);
                } else {
                    tt.ordinary.push(step);
                }
                let Some(energy) = energy else {
                    return;
                };
                // A single label's frames are the source's: 0 from the nearest.
                if let Some(source) = source {
                    let rect = rects[ti];
                    tt.error += candidates(ti, t)
                        .into_iter()
                        .map(|f| {
                            source.rect_into(f, rect, buf);
                            let (e, n) = mad_rect_buf(a, rect, w as usize, &wt8, buf);
                            e / n.max(1e-9)
                        })
                        .fold(f64::INFINITY, f64::min);
                }
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
    // The source frames' gradient energy, per tile (counted ones) and over the frame.
    let n_src = src_energy.map_or(0, |e| e.frames.len());
    let mut ge_src_tiles = vec![0.0; rects.len()];
    let mut ge_src = 0.0;
    for sums in src_energy.iter().flat_map(|e| &e.frames) {
        let (s, n) = sums.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
        ge_src += s / n.max(1e-9);
        for ((a, &(s, n)), &c) in ge_src_tiles.iter_mut().zip(sums).zip(&counts) {
            if c {
                *a += s / n.max(1e-9);
            }
        }
    }
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
        let (a, b) = (noise_frame(w, h, 1), noise_frame(w, h, 2));
        let alpha: Vec<u8> = (0..w * h).map(|i| (i * 13 % 256) as u8).collect();
        let wt: Vec<f32> = alpha.iter().map(|&v| v as f32 / 255.0).collect();
        let wt3: Vec<u8> = alpha.iter().flat_map(|&v| [v; 3]).collect();
        let (lists, rects) = tiles(w, h, tile);
        assert_eq!(lists.len(), 5 * 3);
        assert_eq!(rects[14], [32, 37, 16, 23]);
        for (ti, (px, &rect)) in lists.iter().zip(&rects).enumerate() {
            let (s, n) = mad(&a, &b, px, &wt);
            let (rs, rn) = mad_rect(&a, &b, rect, w as usize, &wt3);
            assert!(n > 0.0 && s > 0.0, "tile {ti}");
            assert!((rs - s).abs() <= 1e-6 * s, "tile {ti}: {rs} vs {s}");
            assert!((rn - n).abs() <= 1e-6 * n, "tile {ti}: {rn} vs {n}");
        }
    }

    /// The tiles of `tile` pixels over a `w x h` frame: their pixel lists and rectangles.
    fn tiles(w: u32, h: u32, tile: u32) -> (Vec<Vec<usize>>, Vec<[usize; 4]>) {
        let rl = single_loop(
            Label {
                start: 0,
                period: 4,
            },
            (w, h),
            tile,
        );
        (tile_pixels(&rl, w, h), tile_rects(tile, (w, h)))
    }

    fn noise_frame(w: u32, h: u32, seed: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let v = (x * 31 + y * 17 + seed * 101).wrapping_mul(2654435761) >> 24;
            image::Rgb([v as u8, (v * 3) as u8, (v * 7) as u8])
        })
    }

    /// The per-tile energies from one luma plane are `gradient_sums_at`'s over each tile's
    /// pixel list, exactly, with weights that are zero in places and a frame no multiple of
    /// the tile.
    #[test]
    fn tile_energies_match_the_pixel_lists() {
        let (w, h, tile) = (37u32, 23u32, 8u32);
        let f = noise_frame(w, h, 3);
        let wt: Vec<f32> = (0..w * h).map(|i| (i * 13 % 256) as f32 / 255.0).collect();
        let (lists, rects) = tiles(w, h, tile);
        let fast = tile_energies(&f, &rects, &wt);
        assert_eq!(fast.len(), lists.len());
        for (ti, px) in lists.iter().enumerate() {
            let slow = crate::metrics::gradient_sums_at(&f, Some(px), Some(&wt));
            assert!(slow.0 > 0.0, "tile {ti}");
            assert_eq!(fast[ti], slow, "tile {ti}");
        }
    }

    /// A rectangle read from 4:2:0 frames a row at a time is what `px` reads pixel by pixel,
    /// at even and odd edges.
    #[test]
    fn rectangles_read_as_the_pixels() {
        let (w, h) = (38u32, 22u32);
        let data: Vec<u8> = (0..w * h * 3 / 2)
            .map(|i| (i.wrapping_mul(2654435761) >> 24) as u8)
            .collect();
        let yuv = crate::yuv::Yuv420Image::from_raw(
            w,
            h,
            crate::yuv::YuvMatrix::Bt709,
            crate::yuv::YuvRange::Limited,
            data,
        )
        .expect("an even frame");
        let frames = vec![
            crate::analysis::Frame::Rgb(noise_frame(w, h, 1)),
            crate::analysis::Frame::Yuv420(yuv),
        ];
        let mut buf = Vec::new();
        for rect in [
            [0, 38, 0, 22],
            [16, 32, 8, 16],
            [32, 38, 16, 22],
            [3, 9, 5, 6],
        ] {
            for f in 0..2 {
                frames.as_slice().rect_into(f, rect, &mut buf);
                let [x0, x1, y0, y1] = rect;
                let want: Vec<u8> = (y0..y1)
                    .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                    .flat_map(|(x, y)| frames.as_slice().px(f, x as u32, y as u32))
                    .collect();
                assert_eq!(buf, want, "frame {f}, rect {rect:?}");
            }
        }
    }

    /// The thesis's loop measured from the source's energy (its frames are the source's) gives
    /// the figures of the same frames measured as any baked loop.
    #[test]
    fn a_single_label_measures_as_its_frames() {
        let (w, h, tile) = (40u32, 24u32, 8u32);
        // A drifting pattern with a jump at the wrap.
        let frames: Vec<RgbImage> = (0..14).map(|k| noise_frame(w, h, k / 2)).collect();
        let alpha = image::GrayImage::from_fn(w, h, |x, _| image::Luma([(x * 7) as u8]));
        let one = single_loop(
            Label {
                start: 2,
                period: 10,
            },
            (w, h),
            tile,
        );
        let slow = quality_of(
            |t, out: &mut RgbImage| frames.rgb_into(single_frame(&one, t), out),
            &frames,
            &one,
            Some(&alpha),
        );
        let energy = SourceEnergy::of(&frames, tile, Some(&alpha));
        let fast = quality_of_single(&frames, &energy, &one, Some(&alpha));
        assert!(slow.sharpness > 0.5 && slow.tile_wrap > 0.0, "{slow:?}");
        assert_eq!(slow.source_error, 0.0);
        assert_eq!(fast, slow);
    }
}
