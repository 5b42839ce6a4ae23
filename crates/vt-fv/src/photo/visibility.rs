//! Which camera sees which surface voxel: splats into per-camera ID buffers, updated incrementally, and the colour samples they give.

use super::*;

/// A projected surface voxel: continuous pixel position, depth and splat half-width.
#[derive(Clone, Copy)]
pub(crate) struct Splat {
    pub u: f64,
    pub v: f64,
    pub z: f32,
    pub half: f64,
}

/// Projects a voxel centre for splatting: half-width is `0.5 * scale * f * size / z`.
#[inline]
pub(crate) fn splat(
    cam: &Camera,
    f: f64,
    size: f64,
    scale: f64,
    c: &Vector3<f64>,
) -> Option<Splat> {
    let (u, v, z) = cam.project(c)?;
    Some(Splat {
        u,
        v,
        z: z as f32,
        half: 0.5 * scale * f * size / z,
    })
}

/// Inclusive pixel range covered by a splat, clipped to `w x h`; always holds the centre pixel
/// when that is inside the image.
#[inline]
pub(crate) fn footprint(s: &Splat, w: u32, h: u32) -> Option<(i64, i64, i64, i64)> {
    let (cx, cy) = ((s.u + 0.5).floor() as i64, (s.v + 0.5).floor() as i64);
    let x0 = ((s.u - s.half).ceil() as i64).min(cx).max(0);
    let x1 = ((s.u + s.half).floor() as i64).max(cx).min(w as i64 - 1);
    let y0 = ((s.v - s.half).ceil() as i64).min(cy).max(0);
    let y1 = ((s.v + s.half).floor() as i64).max(cy).min(h as i64 - 1);
    (x0 <= x1 && y0 <= y1).then_some((x0, y0, x1, y1))
}

pub(crate) fn focal(cam: &Camera) -> f64 {
    0.5 * (cam.k[(0, 0)].abs() + cam.k[(1, 1)].abs())
}

/// Side of the square pixel tiles that index which voxels touch which pixels.
const TILE: usize = 8;

/// One camera's ID buffer, kept up to date as voxels come and go.
///
/// IDs are `slot + 1` (0 = no voxel), slots being positions in the carver's voxel list, which
/// only grows (removed voxels leave dead slots), so IDs are stable across passes. Each tile of
/// `TILE x TILE` pixels lists the slots whose footprint touches it, in slot order; a change
/// marks the tiles under the voxel's footprint dirty, and only dirty tiles are re-rendered (by
/// z-buffering their listed live slots in slot order, the same result as rendering every voxel
/// in list order).
pub(super) struct IdBuffer {
    w: u32,
    h: u32,
    f: f64,
    tiles_x: usize,
    depth: Vec<f32>,
    ids: Vec<u32>,
    buckets: Vec<Vec<u32>>,
    dirty: Vec<bool>,
}

impl IdBuffer {
    pub(super) fn new(cam: &Camera, w: u32, h: u32) -> Self {
        let tiles_x = (w as usize).div_ceil(TILE);
        let tiles = tiles_x * (h as usize).div_ceil(TILE);
        Self {
            w,
            h,
            f: focal(cam),
            tiles_x,
            depth: vec![f32::INFINITY; (w * h) as usize],
            ids: vec![0; (w * h) as usize],
            buckets: vec![Vec::new(); tiles],
            dirty: vec![false; tiles],
        }
    }

    /// Tiles `(tx0, ty0, tx1, ty1)` (inclusive) under a voxel's footprint.
    fn tiles_of(
        &self,
        cam: &Camera,
        c: &Vector3<f64>,
        size: f64,
        scale: f64,
    ) -> Option<[usize; 4]> {
        let s = splat(cam, self.f, size, scale, c)?;
        let (x0, y0, x1, y1) = footprint(&s, self.w, self.h)?;
        Some([
            x0 as usize / TILE,
            y0 as usize / TILE,
            x1 as usize / TILE,
            y1 as usize / TILE,
        ])
    }

    fn mark(&mut self, t: [usize; 4]) {
        for ty in t[1]..=t[3] {
            for tx in t[0]..=t[2] {
                self.dirty[ty * self.tiles_x + tx] = true;
            }
        }
    }

    /// Adds a voxel (slots must arrive in increasing order).
    pub(super) fn add(&mut self, cam: &Camera, slot: u32, c: &Vector3<f64>, size: f64, scale: f64) {
        if let Some(t) = self.tiles_of(cam, c, size, scale) {
            for ty in t[1]..=t[3] {
                for tx in t[0]..=t[2] {
                    self.buckets[ty * self.tiles_x + tx].push(slot);
                }
            }
            self.mark(t);
        }
    }

    /// Puts a removed voxel back (its slot goes into each tile list at its place in slot
    /// order) and marks its tiles for re-rendering.
    pub(super) fn restore(
        &mut self,
        cam: &Camera,
        slot: u32,
        c: &Vector3<f64>,
        size: f64,
        scale: f64,
    ) {
        if let Some(t) = self.tiles_of(cam, c, size, scale) {
            for ty in t[1]..=t[3] {
                for tx in t[0]..=t[2] {
                    let b = &mut self.buckets[ty * self.tiles_x + tx];
                    if let Err(at) = b.binary_search(&slot) {
                        b.insert(at, slot);
                    }
                }
            }
            self.mark(t);
        }
    }

    /// Marks the tiles under a removed voxel for re-rendering.
    pub(super) fn remove(&mut self, cam: &Camera, c: &Vector3<f64>, size: f64, scale: f64) {
        if let Some(t) = self.tiles_of(cam, c, size, scale) {
            self.mark(t);
        }
    }

    /// Re-renders the dirty tiles; pushes `(old id, new id, pixel index)` of every pixel that
    /// changed.
    pub(super) fn refresh(
        &mut self,
        cam: &Camera,
        centres: &[Vector3<f64>],
        alive: &[bool],
        size: f64,
        scale: f64,
        changed: &mut Vec<(u32, u32, u32)>,
    ) {
        let (w, h) = (self.w as usize, self.h as usize);
        let mut old = Vec::with_capacity(TILE * TILE);
        for t in 0..self.dirty.len() {
            if !std::mem::take(&mut self.dirty[t]) {
                continue;
            }
            let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
            let (px0, py0) = (tx * TILE, ty * TILE);
            let (px1, py1) = ((px0 + TILE).min(w), (py0 + TILE).min(h));
            old.clear();
            for y in py0..py1 {
                let row = y * w;
                old.extend_from_slice(&self.ids[row + px0..row + px1]);
                self.ids[row + px0..row + px1].fill(0);
                self.depth[row + px0..row + px1].fill(f32::INFINITY);
            }
            let mut bucket = std::mem::take(&mut self.buckets[t]);
            bucket.retain(|&slot| alive[slot as usize]);
            for &slot in &bucket {
                let Some(s) = splat(cam, self.f, size, scale, &centres[slot as usize]) else {
                    continue;
                };
                let Some((x0, y0, x1, y1)) = footprint(&s, self.w, self.h) else {
                    continue;
                };
                let (x0, x1) = ((x0 as usize).max(px0), (x1 as usize).min(px1 - 1));
                let (y0, y1) = ((y0 as usize).max(py0), (y1 as usize).min(py1 - 1));
                for y in y0..=y1 {
                    let row = y * w;
                    for x in x0..=x1 {
                        let p = row + x;
                        if s.z < self.depth[p] {
                            self.depth[p] = s.z;
                            self.ids[p] = slot + 1;
                        }
                    }
                }
            }
            self.buckets[t] = bucket;
            let tw = px1 - px0;
            for (k, &o) in old.iter().enumerate() {
                let p = (py0 + k / tw) * w + px0 + k % tw;
                let n = self.ids[p];
                if n != o {
                    changed.push((o, n, p as u32));
                }
            }
        }
    }
}

/// A voxel's verdict over the cameras that see it: how many, its colour, and whether they
/// agree.
#[derive(Clone, Copy)]
pub(super) struct Stats {
    pub(super) n: u32,
    pub(super) colour: [u8; 3],
    pub(super) consistent: bool,
}

impl Default for Stats {
    fn default() -> Self {
        Self {
            n: 0,
            colour: [0; 3],
            consistent: true,
        }
    }
}

impl Stats {
    /// Judges a voxel's per-camera colour samples (see [`Consistency`]).
    pub(super) fn judge(samples: &[[f64; 3]], threshold: f64, rule: Consistency) -> Self {
        let n = samples.len();
        let mean = |set: &mut dyn Iterator<Item = &[f64; 3]>| {
            let (mut acc, mut k) = ([0.0f64; 3], 0usize);
            for c in set {
                for i in 0..3 {
                    acc[i] += c[i];
                }
                k += 1;
            }
            acc.map(|a| (a / k.max(1) as f64).round().clamp(0.0, 255.0) as u8)
        };
        match rule {
            Consistency::StdDev => {
                let (mut sum, mut sumsq) = ([0.0f64; 3], [0.0f64; 3]);
                for c in samples {
                    for k in 0..3 {
                        sum[k] += c[k];
                        sumsq[k] += c[k] * c[k];
                    }
                }
                let nf = n as f64;
                let consistent = n < 2
                    || (0..3).all(|k| {
                        let m = sum[k] / nf;
                        (sumsq[k] / nf - m * m).max(0.0).sqrt() <= threshold
                    });
                Self {
                    n: n as u32,
                    colour: mean(&mut samples.iter()),
                    consistent,
                }
            }
            Consistency::AgreeFrom { share, min } => {
                let rule = if n >= min.max(2) {
                    Consistency::Agree(share)
                } else {
                    Consistency::StdDev
                };
                Self::judge(samples, threshold, rule)
            }
            Consistency::Agree(share) => {
                if n < 2 {
                    return Self::judge(samples, threshold, Consistency::StdDev);
                }
                // The samples nearest the per-channel median (largest channel difference),
                // as many as the share asks and at least two, judged by the paper's rule.
                let mut median = [0.0f64; 3];
                let mut ch: Vec<f64> = Vec::with_capacity(n);
                for k in 0..3 {
                    ch.clear();
                    ch.extend(samples.iter().map(|c| c[k]));
                    ch.sort_by(f64::total_cmp);
                    median[k] = if n % 2 == 1 {
                        ch[n / 2]
                    } else {
                        0.5 * (ch[n / 2 - 1] + ch[n / 2])
                    };
                }
                let keep = ((share * n as f64 - 1e-9).ceil() as usize).clamp(2, n);
                let mut near: Vec<(f64, usize)> = samples
                    .iter()
                    .enumerate()
                    .map(|(i, c)| {
                        let d = (0..3).map(|k| (c[k] - median[k]).abs()).fold(0.0, f64::max);
                        (d, i)
                    })
                    .collect();
                near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let kept: Vec<[f64; 3]> = near[..keep].iter().map(|&(_, i)| samples[i]).collect();
                let verdict = Self::judge(&kept, threshold, Consistency::StdDev);
                Self {
                    n: n as u32,
                    ..verdict
                }
            }
        }
    }
}

/// Colour statistics of the voxels in `slots` over the cameras whose ID buffers show them
/// (by `params.visibility`), judged by `params.consistency`.
pub(super) fn gather(
    cams: &[Camera],
    images: &[RgbImage],
    bufs: &[IdBuffer],
    centres: &[Vector3<f64>],
    slots: &[u32],
    size: f64,
    params: &PhotoParams,
) -> Vec<Stats> {
    let (scale, visibility) = (params.splat_scale, params.visibility);
    slots
        .par_iter()
        .map(|&slot| {
            let c = &centres[slot as usize];
            let id = slot + 1;
            let mut samples: Vec<[f64; 3]> = Vec::with_capacity(cams.len());
            let mut partly: Vec<[f64; 3]> = Vec::new();
            for ((cam, img), b) in cams.iter().zip(images).zip(bufs) {
                let buf = &b.ids;
                let (w, h) = img.dimensions();
                let Some(s) = splat(cam, b.f, size, scale, c) else {
                    continue;
                };
                let Some((x0, y0, x1, y1)) = footprint(&s, w, h) else {
                    continue;
                };
                let mut acc = [0.0f64; 3];
                let mut n = 0usize;
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        if buf[(y as usize) * w as usize + x as usize] == id {
                            let p = img.get_pixel(x as u32, y as u32).0;
                            for k in 0..3 {
                                acc[k] += p[k] as f64;
                            }
                            n += 1;
                        }
                    }
                }
                if n == 0 {
                    continue;
                }
                let judges = match visibility {
                    Visibility::Centre => {
                        let (cx, cy) = ((s.u + 0.5).floor() as i64, (s.v + 0.5).floor() as i64);
                        cx >= 0
                            && cy >= 0
                            && cx < w as i64
                            && cy < h as i64
                            && buf[(cy as usize) * w as usize + cx as usize] == id
                    }
                    Visibility::Footprint(share) => {
                        n as f64 >= share * ((x1 - x0 + 1) * (y1 - y0 + 1)) as f64
                    }
                };
                let mean = acc.map(|a| a / n as f64);
                if judges {
                    samples.push(mean);
                } else {
                    partly.push(mean);
                }
            }
            if samples.is_empty() && params.colour_partly_seen && !partly.is_empty() {
                // Seen, but by no camera that may judge it: coloured, never carved.
                let st = Stats::judge(&partly, params.threshold, Consistency::StdDev);
                return Stats {
                    consistent: true,
                    ..st
                };
            }
            Stats::judge(&samples, params.threshold, params.consistency)
        })
        .collect()
}
