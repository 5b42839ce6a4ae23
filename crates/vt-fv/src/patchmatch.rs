//! PatchMatch nearest-neighbour fields (Barnes et al. 2009), SPEC B.5, and the iteration engine
//! shared with guided synthesis ([`crate::guided`]).
//!
//! Patches are `p x p` squares (`p` odd) centred on a pixel. The field maps every pixel `a` of
//! image A to the centre `b` of a patch lying wholly inside image B; pixels of A's patch that fall
//! outside A are left out of the distance (the same ones for every candidate `b`, so distances
//! stay comparable). The distance is the sum of squared RGB differences, optionally over every
//! `step`-th row and column of the patch only (offsets that are multiples of `step`, centre
//! included). Candidates are rejected as soon as the partial sum reaches the best so far.
//!
//! Parallelism: with `strips > 1` the rows are cut into horizontal strips run in parallel; inside
//! a strip the scan order is exact, and values from other strips are read as they were at the
//! start of the iteration. `strips = 1` is the paper's sequential algorithm.

use image::RgbImage;
use rayon::prelude::*;

use crate::rng::Rng;
use crate::{Error, Result};

/// PatchMatch parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchMatchParams {
    /// Patch side, odd (7).
    pub patch: usize,
    /// Patch subsampling step: compare every `step`-th row and column (1 = all).
    pub step: usize,
    /// Random-search start radius in pixels; `None` = the larger side of B.
    pub search_radius: Option<usize>,
    /// Random-search radius shrink factor alpha in (0, 1) (0.5, Barnes et al.).
    pub alpha: f64,
    /// Most iterations (16).
    pub max_iters: usize,
    /// Stop when (offsets changed this iteration) / (offsets changed in the first) <= this (0 =
    /// iterate until nothing changes; negative = always run `max_iters`).
    pub stop_ratio: f64,
    /// Parallel row strips (1 = exact sequential scan).
    pub strips: usize,
    /// Random seed.
    pub seed: u64,
}

impl Default for PatchMatchParams {
    fn default() -> Self {
        Self {
            patch: 7,
            step: 1,
            search_radius: None,
            alpha: 0.5,
            max_iters: 16,
            stop_ratio: 0.0,
            strips: 1,
            seed: 0,
        }
    }
}

/// A nearest-neighbour field: per pixel of A, the centre of its patch in B and the distance.
#[derive(Debug, Clone, PartialEq)]
pub struct Nnf {
    /// Width of A.
    pub width: usize,
    /// Height of A.
    pub height: usize,
    /// Matched patch centre `(x, y)` in B, row-major over A.
    pub pos: Vec<(u32, u32)>,
    /// Patch distance of each match.
    pub dist: Vec<u64>,
}

impl Nnf {
    /// The offset `f(a) = b - a` of pixel `(x, y)`.
    pub fn offset(&self, x: usize, y: usize) -> (i64, i64) {
        let (bx, by) = self.pos[y * self.width + x];
        (bx as i64 - x as i64, by as i64 - y as i64)
    }
}

/// Pixels as `[u8; 3]`, row-major.
pub(crate) fn pixels(img: &RgbImage) -> Vec<[u8; 3]> {
    img.pixels().map(|p| p.0).collect()
}

/// The image B side of a search: pixels and the valid range of patch centres.
pub(crate) struct Source<'a> {
    pub px: &'a [[u8; 3]],
    pub w: usize,
    pub h: usize,
    pub r: usize,
}

impl Source<'_> {
    #[inline]
    pub fn clamp(&self, x: i64, y: i64) -> (u32, u32) {
        let r = self.r as i64;
        (
            x.clamp(r, self.w as i64 - 1 - r) as u32,
            y.clamp(r, self.h as i64 - 1 - r) as u32,
        )
    }
}

/// A query patch: linear offsets into B (relative to the candidate centre) and colours.
#[derive(Default)]
pub(crate) struct Query {
    pub off: Vec<isize>,
    pub col: Vec<[i32; 3]>,
}

impl Query {
    /// Distance to B's patch centred at `b`, stopping early once it reaches `best`.
    #[inline]
    pub fn dist(&self, src: &Source, b: (u32, u32), best: u64) -> u64 {
        let base = (b.1 as usize * src.w + b.0 as usize) as isize;
        let mut total = 0u64;
        for (offs, cols) in self.off.chunks(16).zip(self.col.chunks(16)) {
            let mut s = 0u32;
            for (o, c) in offs.iter().zip(cols) {
                let p = src.px[(base + o) as usize];
                let d0 = p[0] as i32 - c[0];
                let d1 = p[1] as i32 - c[1];
                let d2 = p[2] as i32 - c[2];
                s += (d0 * d0 + d1 * d1 + d2 * d2) as u32;
            }
            total += s as u64;
            if total >= best {
                return total;
            }
        }
        total
    }
}

/// Patch offsets `(dx, dy)` on the subsampling grid, row by row.
pub(crate) fn patch_offsets(patch: usize, step: usize) -> Vec<(i64, i64)> {
    let r = (patch / 2) as i64;
    let s = step.max(1) as i64;
    let mut v = Vec::new();
    for dy in -r..=r {
        if dy % s != 0 {
            continue;
        }
        for dx in -r..=r {
            if dx % s == 0 {
                v.push((dx, dy));
            }
        }
    }
    v
}

/// How an iteration builds query patches and chooses propagation neighbours.
pub(crate) enum Mode<'a> {
    /// Plain PatchMatch: query from image A, propagation from the previous pixel in scan order
    /// horizontally and vertically.
    Plain { a: &'a [[u8; 3]] },
    /// Guided synthesis stage (ii): query from the output above and left of `a` within distance
    /// `l` (the upper-left L) and from the target elsewhere, centre included; propagation from every processed pixel
    /// within `l` (a causal `(2l + 1) x (l + 1)` window); writes each chosen colour at once.
    Mixed { target: &'a [[u8; 3]], l: usize },
}

/// Settings of one iteration.
pub(crate) struct Iter<'a> {
    pub src: Source<'a>,
    pub offsets: &'a [(i64, i64)],
    pub radius: f64,
    pub alpha: f64,
    pub reverse: bool,
    pub strips: usize,
    pub seed: u64,
    /// Pixels to process (row-major over A); `None` = all. Skipped pixels keep their match and
    /// output.
    pub active: Option<&'a [bool]>,
}

/// One iteration over the field (and, in mixed mode, the output). Returns how many matches
/// changed.
pub(crate) fn iterate(it: &Iter, mode: &Mode, nnf: &mut Nnf, out: &mut [[u8; 3]]) -> usize {
    let (w, h) = (nnf.width, nnf.height);
    let strips = it.strips.clamp(1, h.max(1));
    let rows = h.div_ceil(strips);
    let prev_pos = if strips > 1 {
        nnf.pos.clone()
    } else {
        Vec::new()
    };
    let prev_out = if strips > 1 && matches!(mode, Mode::Mixed { .. }) {
        out.to_vec()
    } else {
        Vec::new()
    };
    let chunk = rows * w;
    nnf.pos
        .par_chunks_mut(chunk)
        .zip(nnf.dist.par_chunks_mut(chunk))
        .zip(out.par_chunks_mut(chunk))
        .enumerate()
        .map(|(s, ((pos, dist), o))| {
            let y0 = s * rows;
            let strip = Strip {
                y0,
                y1: y0 + pos.len() / w,
                w,
                h,
                prev_pos: &prev_pos,
                prev_out: &prev_out,
            };
            strip.run(
                it,
                mode,
                pos,
                dist,
                o,
                it.seed.wrapping_mul(0x9E37_79B9).wrapping_add(s as u64),
            )
        })
        .sum()
}

struct Strip<'a> {
    y0: usize,
    y1: usize,
    w: usize,
    h: usize,
    prev_pos: &'a [(u32, u32)],
    prev_out: &'a [[u8; 3]],
}

impl Strip<'_> {
    #[inline]
    fn pos(&self, local: &[(u32, u32)], x: usize, y: usize) -> (u32, u32) {
        if y >= self.y0 && y < self.y1 {
            local[(y - self.y0) * self.w + x]
        } else {
            self.prev_pos[y * self.w + x]
        }
    }

    #[inline]
    fn out(&self, local: &[[u8; 3]], x: usize, y: usize) -> [u8; 3] {
        if y >= self.y0 && y < self.y1 {
            local[(y - self.y0) * self.w + x]
        } else {
            self.prev_out[y * self.w + x]
        }
    }

    fn run(
        &self,
        it: &Iter,
        mode: &Mode,
        pos: &mut [(u32, u32)],
        dist: &mut [u64],
        out: &mut [[u8; 3]],
        seed: u64,
    ) -> usize {
        let mut rng = Rng::new(seed);
        let mut q = Query::default();
        let mut tried: Vec<(u32, u32)> = Vec::with_capacity(64);
        let mut changed = 0;
        let (w, h) = (self.w as i64, self.h as i64);
        let src = &it.src;
        let n = (self.y1 - self.y0) * self.w;
        for k in 0..n {
            let k = if it.reverse { n - 1 - k } else { k };
            let (ax, ay) = (k % self.w, self.y0 + k / self.w);
            if it.active.is_some_and(|a| !a[ay * self.w + ax]) {
                continue;
            }
            // Build the query patch.
            q.off.clear();
            q.col.clear();
            for &(dx, dy) in it.offsets {
                let (x, y) = (ax as i64 + dx, ay as i64 + dy);
                if x < 0 || y < 0 || x >= w || y >= h {
                    continue;
                }
                let c = match mode {
                    Mode::Plain { a } => a[y as usize * self.w + x as usize],
                    Mode::Mixed { target, l } => {
                        // The output's upper-left L: processed pixels within distance L of a
                        // (the pixels propagation looks at); the target fills the rest.
                        let causal = dy < 0 || (dy == 0 && dx < 0);
                        if causal && dx.abs().max(dy.abs()) <= *l as i64 {
                            self.out(out, x as usize, y as usize)
                        } else {
                            target[y as usize * self.w + x as usize]
                        }
                    }
                };
                q.off.push(dy as isize * src.w as isize + dx as isize);
                q.col.push([c[0] as i32, c[1] as i32, c[2] as i32]);
            }
            let start = pos[k];
            let mut best = start;
            let mut best_d = match mode {
                Mode::Plain { .. } => dist[k],
                Mode::Mixed { .. } => q.dist(src, best, u64::MAX),
            };
            // Candidates already measured for this pixel are skipped: in coherent regions
            // most propagation neighbours propose the same patch.
            tried.clear();
            tried.push(start);
            let mut try_cand =
                |c: (u32, u32), best: &mut (u32, u32), best_d: &mut u64, dedupe: bool| {
                    if c != *best && !(dedupe && tried.contains(&c)) {
                        if dedupe {
                            tried.push(c);
                        }
                        let d = q.dist(src, c, *best_d);
                        if d < *best_d {
                            *best_d = d;
                            *best = c;
                        }
                    }
                };
            // Propagation.
            match mode {
                Mode::Plain { .. } => {
                    let s: i64 = if it.reverse { 1 } else { -1 };
                    for (dx, dy) in [(s, 0), (0, s)] {
                        let (qx, qy) = (ax as i64 + dx, ay as i64 + dy);
                        if qx < 0 || qy < 0 || qx >= w || qy >= h {
                            continue;
                        }
                        let p = self.pos(pos, qx as usize, qy as usize);
                        let c = src.clamp(p.0 as i64 - dx, p.1 as i64 - dy);
                        try_cand(c, &mut best, &mut best_d, true);
                    }
                }
                Mode::Mixed { l, .. } => {
                    let l = *l as i64;
                    for dy in -l..=0 {
                        for dx in -l..=l {
                            if dy == 0 && dx >= 0 {
                                break;
                            }
                            let (qx, qy) = (ax as i64 + dx, ay as i64 + dy);
                            if qx < 0 || qy < 0 || qx >= w || qy >= h {
                                continue;
                            }
                            let p = self.pos(pos, qx as usize, qy as usize);
                            let c = src.clamp(p.0 as i64 - dx, p.1 as i64 - dy);
                            try_cand(c, &mut best, &mut best_d, true);
                        }
                    }
                }
            }
            // Random search around the current best, radius shrinking by alpha.
            let mut radius = it.radius;
            while radius >= 1.0 {
                let rr = radius as i64;
                let c = src.clamp(
                    best.0 as i64 + rng.range(-rr, rr),
                    best.1 as i64 + rng.range(-rr, rr),
                );
                try_cand(c, &mut best, &mut best_d, false);
                radius *= it.alpha;
            }
            pos[k] = best;
            dist[k] = best_d;
            if best != start {
                changed += 1;
            }
            if let Mode::Mixed { .. } = mode {
                out[k] = src.px[best.1 as usize * src.w + best.0 as usize];
            }
        }
        changed
    }
}

pub(crate) fn check_patch(what: &str, w: usize, h: usize, patch: usize) -> Result<()> {
    if patch.is_multiple_of(2) {
        return Err(Error::BadParam {
            name: "patch".into(),
            value: patch.to_string(),
            why: "must be odd".into(),
        });
    }
    if w < patch || h < patch {
        return Err(Error::ImageTooSmall {
            what: what.into(),
            w: w as u32,
            h: h as u32,
            need: patch as u32,
        });
    }
    Ok(())
}

pub(crate) fn check_alpha(alpha: f64) -> Result<()> {
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(Error::BadParam {
            name: "alpha".into(),
            value: alpha.to_string(),
            why: "must be in (0, 1)".into(),
        });
    }
    Ok(())
}

/// A random field over `w x h` into `src` with distances for query patches from `a`.
pub(crate) fn random_nnf(
    w: usize,
    h: usize,
    src: &Source,
    a: &[[u8; 3]],
    offsets: &[(i64, i64)],
    seed: u64,
) -> Nnf {
    let mut rng = Rng::new(seed);
    let r = src.r as i64;
    let pos: Vec<(u32, u32)> = (0..w * h)
        .map(|_| {
            (
                rng.range(r, src.w as i64 - 1 - r) as u32,
                rng.range(r, src.h as i64 - 1 - r) as u32,
            )
        })
        .collect();
    let mut nnf = Nnf {
        width: w,
        height: h,
        pos,
        dist: vec![0; w * h],
    };
    recompute_dist(&mut nnf, src, a, offsets);
    nnf
}

/// Recomputes every distance of a field for query patches from `a`.
pub(crate) fn recompute_dist(nnf: &mut Nnf, src: &Source, a: &[[u8; 3]], offsets: &[(i64, i64)]) {
    let (w, h) = (nnf.width, nnf.height);
    let pos = &nnf.pos;
    nnf.dist.par_iter_mut().enumerate().for_each(|(k, d)| {
        let q = plain_query(a, w, h, k % w, k / w, offsets, src.w);
        *d = q.dist(src, pos[k], u64::MAX);
    });
}

fn plain_query(
    a: &[[u8; 3]],
    w: usize,
    h: usize,
    ax: usize,
    ay: usize,
    offsets: &[(i64, i64)],
    bw: usize,
) -> Query {
    let mut q = Query::default();
    for &(dx, dy) in offsets {
        let (x, y) = (ax as i64 + dx, ay as i64 + dy);
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            continue;
        }
        let c = a[y as usize * w + x as usize];
        q.off.push(dy as isize * bw as isize + dx as isize);
        q.col.push([c[0] as i32, c[1] as i32, c[2] as i32]);
    }
    q
}

/// The PatchMatch field from every pixel of `a` to patches of `b`, with the iteration count run.
pub fn patchmatch(a: &RgbImage, b: &RgbImage, p: &PatchMatchParams) -> Result<(Nnf, usize)> {
    check_patch(
        "PatchMatch image B",
        b.width() as usize,
        b.height() as usize,
        p.patch,
    )?;
    check_patch(
        "PatchMatch image A",
        a.width() as usize,
        a.height() as usize,
        1,
    )?;
    check_alpha(p.alpha)?;
    let (ap, bp) = (pixels(a), pixels(b));
    let src = Source {
        px: &bp,
        w: b.width() as usize,
        h: b.height() as usize,
        r: p.patch / 2,
    };
    let offsets = patch_offsets(p.patch, p.step);
    let (w, h) = (a.width() as usize, a.height() as usize);
    let mut nnf = random_nnf(w, h, &src, &ap, &offsets, p.seed);
    let radius = p.search_radius.unwrap_or(src.w.max(src.h)) as f64;
    let mut dummy = vec![[0u8; 3]; w * h];
    let mut first = 0;
    let mut iters = 0;
    while iters < p.max_iters {
        let it = Iter {
            src: Source { ..src },
            offsets: &offsets,
            radius,
            alpha: p.alpha,
            reverse: iters % 2 == 1,
            strips: p.strips,
            seed: p.seed.wrapping_add(iters as u64 + 1),
            active: None,
        };
        let changed = iterate(&it, &Mode::Plain { a: &ap }, &mut nnf, &mut dummy);
        iters += 1;
        if iters == 1 {
            first = changed.max(1);
        }
        if changed as f64 / first as f64 <= p.stop_ratio {
            break;
        }
    }
    Ok((nnf, iters))
}

/// The exact field by exhaustive search (for testing PatchMatch).
pub fn brute_force_nnf(a: &RgbImage, b: &RgbImage, patch: usize, step: usize) -> Result<Nnf> {
    check_patch(
        "brute force image B",
        b.width() as usize,
        b.height() as usize,
        patch,
    )?;
    let (ap, bp) = (pixels(a), pixels(b));
    let src = Source {
        px: &bp,
        w: b.width() as usize,
        h: b.height() as usize,
        r: patch / 2,
    };
    let offsets = patch_offsets(patch, step);
    let (w, h) = (a.width() as usize, a.height() as usize);
    let r = src.r as u32;
    let best: Vec<((u32, u32), u64)> = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let q = plain_query(&ap, w, h, k % w, k / w, &offsets, src.w);
            let mut best = ((r, r), u64::MAX);
            for by in r..src.h as u32 - r {
                for bx in r..src.w as u32 - r {
                    let d = q.dist(&src, (bx, by), best.1);
                    if d < best.1 {
                        best = ((bx, by), d);
                    }
                }
            }
            best
        })
        .collect();
    Ok(Nnf {
        width: w,
        height: h,
        pos: best.iter().map(|b| b.0).collect(),
        dist: best.iter().map(|b| b.1).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texture(seed: u64, w: u32, h: u32) -> RgbImage {
        let mut rng = Rng::new(seed);
        let coef: Vec<f64> = (0..12).map(|_| rng.f64() * 0.9 + 0.1).collect();
        RgbImage::from_fn(w, h, |x, y| {
            let (x, y) = (x as f64, y as f64);
            image::Rgb(std::array::from_fn(|c| {
                let k = &coef[c * 4..c * 4 + 4];
                (128.0
                    + 60.0 * (k[0] * x + k[1] * y).sin()
                    + 50.0 * (k[2] * x * 0.7 - k[3] * y * 1.3).cos()) as u8
            }))
        })
    }

    /// A built from `b` by `source(x, y)`, plus noise in 0..=`noise`.
    fn build(
        b: &RgbImage,
        w: u32,
        h: u32,
        seed: u64,
        noise: i64,
        source: impl Fn(u32, u32) -> (u32, u32),
    ) -> RgbImage {
        let mut rng = Rng::new(seed);
        RgbImage::from_fn(w, h, |x, y| {
            let (sx, sy) = source(x, y);
            image::Rgb(
                b.get_pixel(sx, sy)
                    .0
                    .map(|c| c.saturating_add(rng.range(0, noise) as u8)),
            )
        })
    }

    fn wrong_count(a: &RgbImage, b: &RgbImage, p: &PatchMatchParams) -> (usize, f64, usize) {
        let exact = brute_force_nnf(a, b, p.patch, p.step).unwrap();
        let (nnf, iters) = patchmatch(a, b, p).unwrap();
        assert!(
            nnf.dist.iter().zip(&exact.dist).all(|(x, y)| x >= y),
            "PatchMatch beat brute force"
        );
        let wrong = nnf
            .dist
            .iter()
            .zip(&exact.dist)
            .filter(|(x, y)| x != y)
            .count();
        let ratio =
            nnf.dist.iter().sum::<u64>() as f64 / exact.dist.iter().sum::<u64>().max(1) as f64;
        (wrong, ratio, iters)
    }

    #[test]
    fn patchmatch_reaches_brute_force() {
        // A is a noisy window of B: every patch of A has its true copy in B.
        for (seed, strips) in [(1, 1), (2, 1), (3, 4)] {
            let b = texture(seed, 32, 32);
            let a = build(&b, 24, 24, seed, 4, |x, y| (x + 5, y + 3));
            let p = PatchMatchParams {
                patch: 5,
                max_iters: 60,
                alpha: 0.8,
                stop_ratio: -1.0,
                seed,
                strips,
                ..Default::default()
            };
            let (wrong, _, iters) = wrong_count(&a, &b, &p);
            assert_eq!(wrong, 0, "seed {seed} strips {strips}: {wrong} of 576 pixels not at the exact nearest neighbour after {iters} iterations");
        }
    }

    #[test]
    fn patchmatch_is_near_exact_across_seams() {
        // A is two differently shifted pieces of B: patches on the seams have no true copy, and
        // their nearest neighbours are incoherent, which random search only finds by luck.
        for seed in [1, 2] {
            let b = texture(seed, 32, 32);
            let a = build(&b, 32, 32, seed, 6, |x, y| {
                if x < 16 {
                    (x + 9, y / 2 + 5)
                } else {
                    (x - 13, (y + 7) % 32)
                }
            });
            let p = PatchMatchParams {
                patch: 5,
                max_iters: 100,
                alpha: 0.8,
                stop_ratio: -1.0,
                seed,
                ..Default::default()
            };
            let (wrong, ratio, _) = wrong_count(&a, &b, &p);
            assert!(
                wrong <= 20 && ratio < 1.01,
                "seed {seed}: {wrong} of 1024 not exact, total distance {ratio} x exact"
            );
        }
    }

    #[test]
    fn identical_images_match_themselves() {
        let b = texture(5, 32, 32);
        let (nnf, _) = patchmatch(
            &b,
            &b,
            &PatchMatchParams {
                patch: 5,
                ..Default::default()
            },
        )
        .unwrap();
        // Interior pixels find their own patch (distance 0).
        for y in 2..30 {
            for x in 2..30 {
                assert_eq!(nnf.dist[y * 32 + x], 0, "pixel {x},{y}");
            }
        }
    }

    #[test]
    fn bad_params_are_refused() {
        let b = texture(1, 32, 32);
        let a = b.clone();
        assert!(matches!(
            patchmatch(
                &a,
                &b,
                &PatchMatchParams {
                    patch: 4,
                    ..Default::default()
                }
            ),
            Err(Error::BadParam { .. })
        ));
        assert!(matches!(
            patchmatch(
                &a,
                &b,
                &PatchMatchParams {
                    patch: 41,
                    ..Default::default()
                }
            ),
            Err(Error::ImageTooSmall { .. })
        ));
        assert!(matches!(
            patchmatch(
                &a,
                &b,
                &PatchMatchParams {
                    alpha: 1.0,
                    ..Default::default()
                }
            ),
            Err(Error::BadParam { .. })
        ));
    }
}
