//! Baking the labels into L + 1 frames: feathered tiles, the wrap correction spread over frames.

use super::*;

/// One pixel's place along one axis: its tile, the tile it blends with, and the second's
/// weight.
pub type AxisBlend = (usize, usize, f32);

/// Per pixel along one axis: the two tiles blended and the second's weight.
fn axis_blend(len: u32, tile: u32, count: usize, feather: u32) -> Vec<AxisBlend> {
    (0..len)
        .map(|x| {
            let c = (x / tile) as usize;
            let d = (x % tile) as f32 + 0.5;
            let half = feather as f32 / 2.0;
            if feather > 0 && d < half && c > 0 {
                (c, c - 1, 0.5 - d / feather as f32)
            } else if feather > 0 && tile as f32 - d < half && c + 1 < count {
                (c, c + 1, 0.5 - (tile as f32 - d) / feather as f32)
            } else {
                (c, c, 0.0)
            }
        })
        .collect()
}

/// The baked loop: `L + 1` frames (frame `L` is frame 0 again) and their masks, each pixel's
/// colour the feathered mix of its tiles' source frames, its mask bit its own tile's; with
/// `rl.blend`, plus the wrap correction of [`correction`]. All at once: [`Bake`] makes them one
/// at a time.
pub fn compose<F: Frames + ?Sized>(
    frames: &F,
    masks: &[Mask],
    rl: &RegionLoop,
    feather: u32,
) -> (Vec<RgbImage>, Vec<Mask>) {
    let bake = Bake::new(frames, masks, rl, feather);
    (0..=rl.length)
        .into_par_iter()
        .map(|t| bake.frame(t))
        .unzip()
}

/// A baked loop's frames made one at a time ([`Bake::frame`]), so that a long loop of large
/// frames streams instead of being held: what every frame shares (each axis's tile blend, each
/// tile's correction spread) is computed once.
pub struct Bake<'a, F: ?Sized> {
    frames: &'a F,
    masks: &'a [Mask],
    rl: &'a RegionLoop,
    bx: Vec<AxisBlend>,
    by: Vec<AxisBlend>,
    /// Per tile column, the pixels `lo..hi` along a row whose blend reads it (empty when none).
    reach: Vec<(usize, usize)>,
    spread: Vec<usize>,
    /// Output frame 0 shows the labels' time `phase` (`rl.phase`, or as [`Bake::rotated`]).
    phase: usize,
}

impl<'a, F: Frames + ?Sized> Bake<'a, F> {
    /// The bake of `rl` from `frames` (the source window `rl`'s labels count in) and their
    /// `masks`, tiles feathered over `feather` pixels.
    pub fn new(frames: &'a F, masks: &'a [Mask], rl: &'a RegionLoop, feather: u32) -> Self {
        let (w, h) = frames.dimensions();
        let (cols, rows) = rl.grid;
        let spread = match rl.blend {
            Some(_) => spreads(frames, rl),
            None => vec![1; rl.labels.len()],
        };
        let bx = axis_blend(w, rl.tile, cols, feather);
        let mut reach = vec![(usize::MAX, 0usize); cols];
        for (x, &(c, o, _)) in bx.iter().enumerate() {
            for k in [c, o] {
                reach[k] = (reach[k].0.min(x), reach[k].1.max(x + 1));
            }
        }
        Self {
            frames,
            masks,
            rl,
            bx,
            by: axis_blend(h, rl.tile, rows, feather),
            reach,
            spread,
            phase: rl.phase,
        }
    }

    /// The same bake with its frame 0 the old frame `by`: the player's wrap `L -> 1` then
    /// shows the old step `by -> by + 1`.
    pub fn rotated(mut self, by: usize) -> Self {
        self.phase = (self.phase + by) % self.rl.length;
        self
    }

    /// The loop the frames show (its phase as rotated).
    pub fn region_loop(&self) -> RegionLoop {
        RegionLoop {
            phase: self.phase,
            ..self.rl.clone()
        }
    }

    /// Output frame `t` (`0..=L`; `L` is frame 0 again) and its mask.
    pub fn frame(&self, t: usize) -> (RgbImage, Mask) {
        let mut img = RgbImage::new(0, 0);
        let mask = self.frame_into(t, &mut img);
        (img, mask)
    }

    /// [`Bake::frame`] into `img` (resized if needed), returning the mask.
    pub fn frame_into(&self, t: usize, img: &mut RgbImage) -> Mask {
        let (rl, frames) = (self.rl, self.frames);
        let (w, h) = frames.dimensions();
        let cols = rl.grid.0;
        let t = (t + self.phase) % rl.length;
        let src = |tx: usize, ty: usize| rl.labels[ty * cols + tx].frame(t);
        let shown = ramps(rl, &self.spread, t);
        // Unsmoothed, the correction is added pixel by pixel below; smoothed, as a field.
        let inline = rl.blend == Some(0.0);
        let corr = rl
            .blend
            .filter(|&s| s > 0.0)
            .map(|sigma| correction(frames, rl, &self.spread, (&self.bx, &self.by), t, sigma));
        if img.dimensions() != (w, h) {
            *img = RgbImage::new(w, h);
        }
        img.par_chunks_mut(3 * w as usize)
            .enumerate()
            .for_each(|(y, row)| {
                crate::simd::dispatch(BakeRow {
                    frames,
                    shown: &shown,
                    bx: &self.bx,
                    by: self.by[y],
                    reach: &self.reach,
                    cols,
                    inline,
                    corr: corr
                        .as_deref()
                        .map(|c| &c[3 * y * w as usize..3 * (y + 1) * w as usize]),
                    y: y as u32,
                    row,
                })
            });
        Mask::from_tiles(w, h, rl.tile, self.masks, src)
    }
}

/// One row of [`Bake::frame_into`], as a [`crate::simd::Kernel`]: the frames' pixels read and
/// mixed in a function compiled for the CPU at hand, their rounding an instruction.
struct BakeRow<'a, F: ?Sized> {
    frames: &'a F,
    /// Per tile: the frame shown, its wrap's two frames and the correction's share ([`ramps`]).
    shown: &'a [(usize, usize, usize, f32)],
    bx: &'a [(usize, usize, f32)],
    by: (usize, usize, f32),
    /// [`Bake`]'s `reach`.
    reach: &'a [(usize, usize)],
    cols: usize,
    /// Whether the unsmoothed correction is added pixel by pixel.
    inline: bool,
    /// The row's smoothed correction, 3 values a pixel (None: none).
    corr: Option<&'a [f32]>,
    y: u32,
    row: &'a mut [u8],
}

impl<F: Frames + ?Sized> crate::simd::Kernel for BakeRow<'_, F> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let BakeRow {
            frames,
            shown,
            bx,
            by,
            reach,
            cols,
            inline,
            corr,
            y,
            row,
        } = self;
        // The row's stretch of every frame a tile of the row's two bands shows, over that tile
        // column's reach, converted a stretch at a time ([`Frames::rect_into`], what `px`
        // gives): `spans` holds, per band, column and frame (shown, its wrap's start, its
        // wrap's end), where it starts in `buf`.
        let bands = if by.1 == by.0 { 1 } else { 2 };
        let mut spans = vec![usize::MAX; bands * cols * 3];
        let reached: usize = reach.iter().map(|&(lo, hi)| hi.saturating_sub(lo)).sum();
        let mut buf: Vec<u8> = Vec::with_capacity(3 * reached * bands);
        let mut stretch = Vec::new();
        for (b, ty) in [by.0, by.1].into_iter().take(bands).enumerate() {
            for (tx, &(lo, hi)) in reach.iter().enumerate() {
                if lo >= hi {
                    continue;
                }
                let (f, s, e, r) = shown[ty * cols + tx];
                let wanted: &[usize] = if inline && r != 0.0 { &[f, s, e] } else { &[f] };
                for (k, &frame) in wanted.iter().enumerate() {
                    frames.rect_into(frame, [lo, hi, y as usize, y as usize + 1], &mut stretch);
                    // Stored as if it began at x = 0, so pixel x reads at start + 3 x.
                    spans[(b * cols + tx) * 3 + k] = buf.len().wrapping_sub(3 * lo);
                    buf.extend_from_slice(&stretch);
                }
            }
        }
        // Per band and column: its correction's share (0 when none is added inline).
        let share: Vec<f32> = [by.0, by.1]
            .into_iter()
            .take(bands)
            .flat_map(|ty| (0..cols).map(move |tx| ty * cols + tx))
            .map(|tile| if inline { shown[tile].3 } else { 0.0 })
            .collect();
        let px = |slot: usize, k: usize, x: usize| -> [u8; 3] {
            let i = spans[slot * 3 + k].wrapping_add(3 * x);
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        let ob = usize::from(bands == 2) * cols;
        for (x, out) in row.chunks_exact_mut(3).enumerate() {
            let mut acc = [0f32; 3];
            let (cx, ox, _) = bx[x];
            // The four tiles of `tile_weights`, in its order, as band-and-column slots.
            let slots = [cx, ox, ob + cx, ob + ox];
            for (slot, (_, wt)) in slots.into_iter().zip(tile_weights(bx[x], by, cols)) {
                if wt > 0.0 {
                    let r = share[slot];
                    let p = px(slot, 0, x);
                    if r != 0.0 {
                        let a = px(slot, 1, x);
                        let b = px(slot, 2, x);
                        for c in 0..3 {
                            acc[c] += wt * (p[c] as f32 + r * (b[c] as f32 - a[c] as f32));
                        }
                    } else {
                        for c in 0..3 {
                            acc[c] += wt * p[c] as f32;
                        }
                    }
                }
            }
            if let Some(corr) = corr {
                for c in 0..3 {
                    acc[c] += corr[3 * x + c];
                }
            }
            for c in 0..3 {
                out[c] = acc[c].round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// Per tile at labels' time `t`: the source frame shown, its wrap's two frames `s` and `s + p`,
/// and the share of their difference the correction adds at cycle position `k` (see
/// [`correction`]): `((p - 1) / 2 - k) / p` when spread over the whole cycle, and over the
/// tile's `K` frames of [`spreads`] the same ramp with `K` for `p`, zero in the middle of the
/// cycle.
fn ramps(rl: &RegionLoop, spread: &[usize], t: usize) -> Vec<(usize, usize, usize, f32)> {
    rl.labels
        .iter()
        .zip(spread)
        .map(|(l, &k_len)| {
            let p = l.period;
            let k = l.frame(t) - l.start;
            // Over the whole cycle (k_len = p): ((p - 1) / 2 - k) / p. Over the k_len frames
            // around the wrap: the same ramp, flat (zero) in the middle of the cycle.
            let h = (k_len.max(1) - 1) as f32 / 2.0;
            let front = (h - k as f32).max(0.0);
            let back = (h - (p - 1 - k) as f32).max(0.0);
            (
                l.frame(t),
                l.start,
                l.start + p,
                (front - back) / k_len.max(1) as f32,
            )
        })
        .collect()
}

/// Per tile, the frames its wrap correction is spread over: enough that each carries at most
/// `rl.spread` of the tile's median ordinary step (a tile whose wrap mismatch is already that
/// small gets none), at most its whole cycle (`rl.spread` 0: the whole cycle). The less it is
/// spread, the closer the frames stay to the source's.
pub fn spreads<F: Frames + ?Sized>(frames: &F, rl: &RegionLoop) -> Vec<usize> {
    if rl.spread == 0.0 {
        return rl.labels.iter().map(|l| l.period).collect();
    }
    let (w, h) = frames.dimensions();
    let tile_px = tile_pixels(rl, w, h);
    let ones = vec![1f32; (w * h) as usize];
    // Frame by frame (each read whole once per pair, not tile by tile): per pair of frames,
    // each tile's step where a tile needs it. The pairs: each source step `f -> f + 1` inside
    // some tile's cycle, and each tile's wrap `s -> s + p`.
    let mut pairs: Vec<(usize, usize)> = rl
        .labels
        .iter()
        .flat_map(|l| (l.start..l.start + l.period - 1).map(|f| (f, f + 1)))
        .chain(rl.labels.iter().map(|l| (l.start, l.start + l.period)))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let wanted = |l: &Label, (a, b): (usize, usize)| {
        (b == a + 1 && a >= l.start && b < l.start + l.period)
            || (a, b) == (l.start, l.start + l.period)
    };
    let mads: Vec<Vec<f64>> = pairs
        .par_iter()
        .map_init(
            || (RgbImage::new(w, h), RgbImage::new(w, h)),
            |(fa, fb), &(a, b)| {
                frames.rgb_into(a, fa);
                frames.rgb_into(b, fb);
                rl.labels
                    .iter()
                    .zip(&tile_px)
                    .map(|(l, px)| {
                        if wanted(l, (a, b)) {
                            let (s, n) = mad(fa, fb, px, &ones);
                            s / n.max(1e-9)
                        } else {
                            0.0
                        }
                    })
                    .collect()
            },
        )
        .collect();
    let tile_mad =
        |k: usize, pair: (usize, usize)| mads[pairs.binary_search(&pair).expect("listed above")][k];
    rl.labels
        .par_iter()
        .enumerate()
        .map(|(k, l)| {
            let d = tile_mad(k, (l.start, l.start + l.period));
            let steps: Vec<f64> = (l.start..l.start + l.period - 1)
                .map(|f| tile_mad(k, (f, f + 1)))
                .collect();
            let step = median(steps).max(crate::seam::MIN_UNIT);
            ((d / (rl.spread as f64 * step)).ceil() as usize).clamp(1, l.period)
        })
        .collect()
}

/// Each tile's full-resolution pixel indices, row by row, tiles in `rl.labels` order.
pub(super) fn tile_pixels(rl: &RegionLoop, w: u32, h: u32) -> Vec<Vec<usize>> {
    let cols = rl.grid.0;
    let mut tile_px = vec![Vec::new(); rl.labels.len()];
    for y in 0..h {
        for x in 0..w {
            tile_px[(y / rl.tile) as usize * cols + (x / rl.tile) as usize]
                .push((y * w + x) as usize);
        }
    }
    tile_px
}

/// The four tiles a pixel mixes and their weights, from its column's and row's
/// [`axis_blend`] entries, on a grid `cols` tiles wide.
#[inline(always)]
fn tile_weights(
    (cx, ox, ax): (usize, usize, f32),
    (cy, oy, ay): (usize, usize, f32),
    cols: usize,
) -> [(usize, f32); 4] {
    [
        (cy * cols + cx, (1.0 - ax) * (1.0 - ay)),
        (cy * cols + ox, ax * (1.0 - ay)),
        (oy * cols + cx, (1.0 - ax) * ay),
        (oy * cols + ox, ax * ay),
    ]
}

/// The wrap correction of output time `t` (labels' time), `3 * w * h` values to add.
///
/// A tile looping `(s, p)` shows `V(s + k)` at cycle position `k`; at its wrap `V(s)` follows
/// `V(s + p - 1)` where the source goes on to `V(s + p)`, so its temporal gradients differ from
/// the source's by `D = V(s + p) - V(s)` at that one step. The least-squares fit of a cyclic
/// sequence to the source's gradients (the temporal Poisson equation, screened to keep the
/// mean) spreads `D` evenly over the cycle: `c_k = D ((p - 1) / 2 - k) / p` added at position
/// `k`, so every step carries `-D / p` and the wrap no longer one `D`. Spread over only the
/// tile's `spread` frames around the wrap ([`spreads`]: as few as keep each step's share under
/// `rl.spread` of an ordinary step), the frames in the middle of the cycle stay the
/// source's. Pixels mixing tiles mix
/// their tiles' corrections with the same weights; the field is then low-passed by a Gaussian
/// of `sigma` pixels (0: none), which keeps only its smooth part (after Liao, Finch and Hoppe
/// 2015, whose multigrid solve makes a spatially smooth correction): what it removes of `D`,
/// the fine detail, stays at the wrap, so the frames keep the source's detail.
pub fn correction<F: Frames + ?Sized>(
    frames: &F,
    rl: &RegionLoop,
    spread: &[usize],
    (bx, by): (&[AxisBlend], &[AxisBlend]),
    t: usize,
    sigma: f32,
) -> Vec<f32> {
    let (w, h) = frames.dimensions();
    let cols = rl.grid.0;
    let ramp = ramps(rl, spread, t);
    let mut out = vec![0f32; 3 * (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let i = 3 * (y * w + x) as usize;
            for (tile, wt) in tile_weights(bx[x as usize], by[y as usize], cols) {
                if wt > 0.0 {
                    let (_, s, e, r) = ramp[tile];
                    let (a, b) = (frames.px(s, x, y), frames.px(e, x, y));
                    for c in 0..3 {
                        out[i + c] += wt * r * (b[c] as f32 - a[c] as f32);
                    }
                }
            }
        }
    }
    if sigma > 0.0 {
        blur_planes(&mut out, w as usize, h as usize, sigma);
    }
    out
}

/// Separable Gaussian blur of interleaved RGB `f32` values, border reflected (reflect-101):
/// the kernel and border of [`crate::blur`], on floats.
fn blur_planes(v: &mut [f32], w: usize, h: usize, sigma: f32) {
    let r = (3.0 * sigma).ceil() as usize;
    let k: Vec<f32> = crate::blur::gaussian_kernel(2 * r + 1, sigma as f64)
        .expect("an odd size and a finite sigma")
        .into_iter()
        .map(|x| x as f32)
        .collect();
    let mut tmp = vec![0f32; v.len()];
    // One pass along x (step 1 pixel, `w` of them per line) or y (step `w`, `h` of them).
    let pass = |src: &[f32], dst: &mut [f32], along_x: bool| {
        let (len, stride) = if along_x { (w, 1) } else { (h, w) };
        for y in 0..h {
            for x in 0..w {
                let (pos, base) = if along_x { (x, y * w) } else { (y, x) };
                let mut acc = [0f32; 3];
                for (j, kv) in k.iter().enumerate() {
                    let at = crate::blur::reflect101(pos as isize + j as isize - r as isize, len);
                    let i = 3 * (base + at * stride);
                    for c in 0..3 {
                        acc[c] += kv * src[i + c];
                    }
                }
                dst[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&acc);
            }
        }
    };
    pass(v, &mut tmp, true);
    pass(&tmp, v, false);
}

/// A single loop as a [`RegionLoop`] (every tile the same label, output frame 0 its start), to
/// measure the thesis's loop
/// as the per-region ones are.
pub fn single_loop(label: Label, frame: (u32, u32), tile: u32) -> RegionLoop {
    let grid = (
        frame.0.div_ceil(tile) as usize,
        frame.1.div_ceil(tile) as usize,
    );
    RegionLoop {
        length: label.period,
        tile,
        grid,
        labels: vec![label; grid.0 * grid.1],
        energy: 0.0,
        single_energy: 0.0,
        periods: vec![label.period],
        solve_secs: 0.0,
        phase: label.start % label.period,
        blend: None,
        spread: DEFAULT_SPREAD,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::Frame;
    use crate::yuv::{Yuv420Image, YuvMatrix, YuvRange};

    /// [`Bake::frame_into`] pixel by pixel, each frame's pixel read with `px`: the formula the
    /// row kernel computes.
    fn reference<F: Frames + ?Sized>(bake: &Bake<F>, t: usize) -> (RgbImage, Mask) {
        let (rl, frames) = (bake.rl, bake.frames);
        let (w, h) = frames.dimensions();
        let cols = rl.grid.0;
        let t = (t + bake.phase) % rl.length;
        let shown = ramps(rl, &bake.spread, t);
        let inline = rl.blend == Some(0.0);
        let img = RgbImage::from_fn(w, h, |x, y| {
            let mut acc = [0f32; 3];
            for (tile, wt) in tile_weights(bake.bx[x as usize], bake.by[y as usize], cols) {
                if wt > 0.0 {
                    let (f, s, e, r) = shown[tile];
                    let p = frames.px(f, x, y);
                    let (a, b) = (frames.px(s, x, y), frames.px(e, x, y));
                    for c in 0..3 {
                        acc[c] += if inline && r != 0.0 {
                            wt * (p[c] as f32 + r * (b[c] as f32 - a[c] as f32))
                        } else {
                            wt * p[c] as f32
                        };
                    }
                }
            }
            image::Rgb(acc.map(|v| v.round().clamp(0.0, 255.0) as u8))
        });
        let mask = Mask::from_fn(w, h, |x, y| {
            let tile = (y / rl.tile) as usize * cols + (x / rl.tile) as usize;
            bake.masks[rl.labels[tile].frame(t)].get(x, y)
        });
        (img, mask)
    }

    #[test]
    fn the_row_kernel_bakes_what_the_per_pixel_formula_does() {
        let mut rng = crate::rng::Rng::new(5);
        // Tiles that do not divide the frame, feathered; several periods and starts.
        let (w, h, n, tile) = (70u32, 38u32, 30usize, 16u32);
        let grid = (w.div_ceil(tile) as usize, h.div_ceil(tile) as usize);
        let labels: Vec<Label> = (0..grid.0 * grid.1)
            .map(|_| {
                let period = [6, 12, 4][rng.range(0, 2) as usize];
                Label {
                    start: rng.range(1, (n - period - 1) as i64) as usize,
                    period,
                }
            })
            .collect();
        let yuv: Vec<Frame> = (0..n)
            .map(|_| {
                let bytes = (0..Yuv420Image::byte_len(w, h))
                    .map(|_| rng.range(0, 255) as u8)
                    .collect();
                Frame::Yuv420(
                    Yuv420Image::from_raw(w, h, YuvMatrix::Bt601, YuvRange::Limited, bytes)
                        .unwrap(),
                )
            })
            .collect();
        let rgb: Vec<RgbImage> = yuv
            .iter()
            .map(|f| {
                let mut out = RgbImage::new(0, 0);
                f.as_ref().to_rgb_into(&mut out);
                out
            })
            .collect();
        let masks: Vec<Mask> = (0..n)
            .map(|_| Mask::from_fn(w, h, |_, _| rng.range(0, 1) == 1))
            .collect();
        for blend in [Some(0.0), None] {
            let rl = RegionLoop {
                length: 12,
                tile,
                grid,
                labels: labels.clone(),
                energy: 0.0,
                single_energy: 0.0,
                periods: vec![4, 6, 12],
                solve_secs: 0.0,
                phase: 3,
                blend,
                spread: 0.0,
            };
            for t in [0, 1, 5, 11, 12] {
                let bake = Bake::new(yuv.as_slice(), &masks, &rl, 8);
                let mut img = RgbImage::new(0, 0);
                let mask = bake.frame_into(t, &mut img);
                let (want, want_mask) = reference(&bake, t);
                assert!(img == want, "4:2:0 frames, blend {blend:?}, t {t}");
                assert_eq!(mask.words(), want_mask.words());
                let bake = Bake::new(rgb.as_slice(), &masks, &rl, 8);
                bake.frame_into(t, &mut img);
                assert!(
                    img == reference(&bake, t).0,
                    "RGB frames, blend {blend:?}, t {t}"
                );
            }
        }
    }
}
