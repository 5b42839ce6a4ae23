//! Guided ("user-controlled") texture synthesis (SPEC B.6): the output takes its texture from an
//! input photo and its layout from a target image (the rough view), searched with PatchMatch.
//!
//! Stage (i), initialisation-correction: PatchMatch from the target's full patches to the input
//! (alternating scan order), writing each output pixel as the centre of its match; at most `M`
//! iterations. Stage (ii), synthesis: always in normal scanline order, the comparison patch is the
//! upper-left L of the output (the already processed pixels within Chebyshev distance L of `a`:
//! rows above and pixels left of `a` on its row) plus the target for the rest of the square
//! (centre included); limiting the output part to distance L keeps large patches tied to the
//! guide (with the whole upper half from the output, a 41x41 patch drifts away from it and
//! scores 1.3 dB below its own stage (i) on the synthetic object); propagation tries the matches of every
//! processed pixel in the causal `(2L + 1) x (L + 1)` window (Chebyshev distance <= L), then random
//! search; each chosen colour is written at once. A stage stops when (matches changed this
//! iteration) / (matches changed in the first stage-(i) iteration) <= `T`.
//!
//! Speed options (off in [`GuidedParams::default`], the paper's settings): a Gaussian-free 2x box
//! pyramid (the coarse field, doubled, seeds the next level; the patch side halves per level, at
//! least 3), patch subsampling (`step`), and parallel row strips (see [`crate::patchmatch`]).

use image::{Rgb, RgbImage};

use crate::patchmatch::{
    check_alpha, check_patch, iterate, patch_offsets, pixels, random_nnf, recompute_dist, Iter,
    Mode, Nnf, Source,
};
use crate::silhouette::Mask;
use crate::{Error, Result};

/// Guided synthesis parameters; `Default` is the paper's (patch 41, L 4, w = 1/4 of the image,
/// alpha 0.8, T 0.06, M 10) with no speed options.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidedParams {
    /// Patch side, odd (41).
    pub patch: usize,
    /// L: reach of the L-shaped patch split and of propagation in stage (ii) (4).
    pub l: usize,
    /// Random-search start radius w in pixels at full resolution; `None` = a quarter of the
    /// input's larger side (the paper's w = 100 at 400x400).
    pub search_radius: Option<usize>,
    /// Radius shrink factor alpha in (0, 1) (0.8).
    pub alpha: f64,
    /// Update-ratio stop threshold T (0.06).
    pub stop_ratio: f64,
    /// Most initialisation-correction iterations M (10).
    pub max_init_iters: usize,
    /// Most synthesis-stage iterations (20; the paper gives no cap).
    pub max_synth_iters: usize,
    /// Pyramid levels (1 = full resolution only).
    pub levels: usize,
    /// Patch subsampling step (1 = every pixel).
    pub step: usize,
    /// Parallel row strips (1 = exact scanline order; 0 = one per rayon thread).
    pub strips: usize,
    /// Copy the target where its whole patch is black (nothing of the model there) instead of
    /// synthesising (false: the paper synthesises every pixel). The rough view is black exactly
    /// where no voxel lands, and there the synthesis could only copy background.
    pub skip_black: bool,
    /// Random seed.
    pub seed: u64,
}

impl Default for GuidedParams {
    fn default() -> Self {
        Self {
            patch: 41,
            l: 4,
            search_radius: None,
            alpha: 0.8,
            stop_ratio: 0.06,
            max_init_iters: 10,
            max_synth_iters: 20,
            levels: 1,
            step: 1,
            strips: 1,
            skip_black: false,
            seed: 0,
        }
    }
}

impl GuidedParams {
    /// The paper's parameters with every speed option on: 3 pyramid levels, step 2, strips per
    /// thread.
    pub fn fast() -> Self {
        Self {
            levels: 3,
            step: 2,
            strips: 0,
            skip_black: true,
            ..Self::default()
        }
    }

    /// The recommended speed options for a patch side: small patches (up to 9) run at full
    /// resolution over every pixel with parallel strips; larger ones add [`Self::fast`]'s
    /// pyramid and patch subsampling.
    pub fn fast_for(patch: usize) -> Self {
        if patch <= 9 {
            Self {
                patch,
                strips: 0,
                skip_black: true,
                ..Self::default()
            }
        } else {
            Self {
                patch,
                ..Self::fast()
            }
        }
    }
}

/// What a synthesis run did, per pyramid level (coarsest first).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SynthStats {
    /// `(stage (i) iterations, stage (ii) iterations)` per level.
    pub iterations: Vec<(usize, usize)>,
    /// Matches changed in the first stage (i) iteration, per level (the ratio's denominator).
    pub first_changed: Vec<usize>,
}

/// Guided synthesis of an output the size of `target` from the texture of `input`.
pub fn guided_synthesis(input: &RgbImage, target: &RgbImage, p: &GuidedParams) -> Result<RgbImage> {
    guided_synthesis_stats(input, target, p).map(|r| r.0)
}

struct Level {
    input: Vec<[u8; 3]>,
    iw: usize,
    ih: usize,
    target: Vec<[u8; 3]>,
    tw: usize,
    th: usize,
}

pub(crate) fn half(px: &[[u8; 3]], w: usize, h: usize) -> (Vec<[u8; 3]>, usize, usize) {
    let (hw, hh) = ((w / 2).max(1), (h / 2).max(1));
    let mut out = Vec::with_capacity(hw * hh);
    for y in 0..hh {
        for x in 0..hw {
            let mut acc = [0u32; 3];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let p = px[(2 * y + dy).min(h - 1) * w + (2 * x + dx).min(w - 1)];
                for k in 0..3 {
                    acc[k] += p[k] as u32;
                }
            }
            out.push(acc.map(|a| ((a + 2) / 4) as u8));
        }
    }
    (out, hw, hh)
}

/// [`guided_synthesis`] that also reports iteration counts.
pub fn guided_synthesis_stats(
    input: &RgbImage,
    target: &RgbImage,
    p: &GuidedParams,
) -> Result<(RgbImage, SynthStats)> {
    check_patch(
        "guided synthesis input",
        input.width() as usize,
        input.height() as usize,
        p.patch,
    )?;
    check_patch(
        "guided synthesis target",
        target.width() as usize,
        target.height() as usize,
        1,
    )?;
    check_alpha(p.alpha)?;
    if p.l == 0 {
        return Err(Error::BadParam {
            name: "l".into(),
            value: "0".into(),
            why: "must be at least 1".into(),
        });
    }
    let strips = if p.strips == 0 {
        rayon::current_num_threads()
    } else {
        p.strips
    };
    let radius = p
        .search_radius
        .unwrap_or(input.width().max(input.height()) as usize / 4)
        .max(1) as f64;
    // Build the pyramid, finest first, stopping before the input gets smaller than its patch.
    let mut levels = vec![Level {
        input: pixels(input),
        iw: input.width() as usize,
        ih: input.height() as usize,
        target: pixels(target),
        tw: target.width() as usize,
        th: target.height() as usize,
    }];
    while levels.len() < p.levels.max(1) {
        let l = levels.last().expect("pyramid has its finest level");
        let (i2, iw, ih) = half(&l.input, l.iw, l.ih);
        let (t2, tw, th) = half(&l.target, l.tw, l.th);
        let patch = level_patch(p.patch, levels.len());
        if iw < patch + 2 || ih < patch + 2 || tw < 2 || th < 2 {
            break;
        }
        levels.push(Level {
            input: i2,
            iw,
            ih,
            target: t2,
            tw,
            th,
        });
    }
    let mut stats = SynthStats::default();
    let mut nnf: Option<Nnf> = None;
    let mut out = Vec::new();
    for (li, lv) in levels.iter().enumerate().rev() {
        let patch = level_patch(p.patch, li);
        let src = Source {
            px: &lv.input,
            w: lv.iw,
            h: lv.ih,
            r: patch / 2,
        };
        let offsets = patch_offsets(patch, p.step);
        let seed = p.seed.wrapping_add(li as u64 * 1000);
        let mut field = match nnf.take() {
            None => random_nnf(lv.tw, lv.th, &src, &lv.target, &offsets, seed),
            Some(coarse) => {
                let mut f = upsample(&coarse, lv.tw, lv.th, &src);
                recompute_dist(&mut f, &src, &lv.target, &offsets);
                f
            }
        };
        let lr = radius / (1u64 << li) as f64;
        // Pixels whose whole target patch is black (no voxel there) copy the target.
        let active: Option<Vec<bool>> = p.skip_black.then(|| {
            let covered = Mask::from_fn(lv.tw as u32, lv.th as u32, |x, y| {
                lv.target[y as usize * lv.tw + x as usize] != [0, 0, 0]
            });
            covered
                .dilate((patch / 2) as u32)
                .to_bytes()
                .iter()
                .map(|&v| v != 0)
                .collect()
        });
        let mut o = vec![[0u8; 3]; lv.tw * lv.th];
        let write = |f: &Nnf, o: &mut Vec<[u8; 3]>| {
            for (c, &(x, y)) in o.iter_mut().zip(&f.pos) {
                *c = lv.input[y as usize * lv.iw + x as usize];
            }
        };
        // Stage (i): initialisation-correction.
        let mut first = 1;
        let mut it1 = 0;
        for i in 0..p.max_init_iters {
            let it = Iter {
                src: Source { ..src },
                offsets: &offsets,
                radius: lr,
                alpha: p.alpha,
                reverse: i % 2 == 1,
                strips,
                seed: seed.wrapping_add(i as u64 + 1),
                active: active.as_deref(),
            };
            let changed = iterate(&it, &Mode::Plain { a: &lv.target }, &mut field, &mut o);
            it1 += 1;
            if i == 0 {
                first = changed.max(1);
            }
            if changed as f64 / first as f64 <= p.stop_ratio {
                break;
            }
        }
        write(&field, &mut o);
        if let Some(a) = &active {
            for ((c, &t), &on) in o.iter_mut().zip(&lv.target).zip(a.iter()) {
                if !on {
                    *c = t;
                }
            }
        }
        // Stage (ii): synthesis with the L-shaped mixed patch, normal scanline order only.
        let mut it2 = 0;
        for i in 0..p.max_synth_iters {
            let it = Iter {
                src: Source { ..src },
                offsets: &offsets,
                radius: lr,
                alpha: p.alpha,
                reverse: false,
                strips,
                seed: seed.wrapping_add(100 + i as u64),
                active: active.as_deref(),
            };
            let changed = iterate(
                &it,
                &Mode::Mixed {
                    target: &lv.target,
                    l: p.l,
                },
                &mut field,
                &mut o,
            );
            it2 += 1;
            if changed as f64 / first as f64 <= p.stop_ratio {
                break;
            }
        }
        stats.iterations.push((it1, it2));
        stats.first_changed.push(first);
        nnf = Some(field);
        out = o;
    }
    let (w, h) = (target.width(), target.height());
    Ok((
        RgbImage::from_fn(w, h, |x, y| Rgb(out[(y * w + x) as usize])),
        stats,
    ))
}

fn level_patch(patch: usize, level: usize) -> usize {
    ((patch >> level) | 1).max(3)
}

/// Doubles a coarse field onto a `w x h` level.
pub(crate) fn upsample(coarse: &Nnf, w: usize, h: usize, src: &Source) -> Nnf {
    let mut pos = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (cx, cy) = (
                (x / 2).min(coarse.width - 1),
                (y / 2).min(coarse.height - 1),
            );
            let (bx, by) = coarse.pos[cy * coarse.width + cx];
            pos.push(src.clamp(
                2 * bx as i64 + (x % 2) as i64,
                2 * by as i64 + (y % 2) as i64,
            ));
        }
    }
    Nnf {
        width: w,
        height: h,
        pos,
        dist: vec![0; w * h],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_equal_to_input_is_reproduced() {
        // With the input as its own guide every patch has an exact match: the output is the input
        // (up to the few pixels left when the update ratio stops the stages early)
        // away from the borders.
        let img = RgbImage::from_fn(48, 40, |x, y| {
            Rgb([
                (x * 5 + y) as u8,
                (y * 6) as u8 ^ (x as u8 * 3),
                ((x * y) % 251) as u8,
            ])
        });
        for p in [
            GuidedParams {
                patch: 7,
                ..Default::default()
            },
            GuidedParams {
                patch: 7,
                levels: 2,
                step: 2,
                strips: 3,
                ..Default::default()
            },
        ] {
            let (out, stats) = guided_synthesis_stats(&img, &img, &p).unwrap();
            let bad = (3..37)
                .flat_map(|y| (3..45).map(move |x| (x, y)))
                .filter(|&(x, y)| out.get_pixel(x, y) != img.get_pixel(x, y))
                .count();
            assert!(bad <= 30, "{p:?}: {bad} interior pixels differ; {stats:?}");
        }
    }

    #[test]
    fn bad_params_are_refused() {
        let img = RgbImage::new(20, 20);
        assert!(matches!(
            guided_synthesis(&img, &img, &GuidedParams::default()),
            Err(Error::ImageTooSmall { need: 41, .. })
        ));
        assert!(matches!(
            guided_synthesis(
                &img,
                &img,
                &GuidedParams {
                    patch: 5,
                    l: 0,
                    ..Default::default()
                }
            ),
            Err(Error::BadParam { .. })
        ));
    }
}
