//! Patch-voting synthesis (ebsynth style), coarse to fine: an alternative refinement of a guide
//! from a reference photo, measured against the default (see docs/system-b.md).
//!
//! Per pyramid level (coarsest first) and per EM iteration, PatchMatch matches every patch of
//! the query image `(1 - guide_weight) * output + guide_weight * guide` to the input photo;
//! then every pixel of the output becomes the mean of what all the patches covering it say
//! (each matched patch votes its colour at the pixel's place), instead of the colour of its own
//! patch's centre as in the paper's synthesis. The field and the output are doubled onto the
//! next level. Pixels where the guide is black (no object) stay black.

use image::{Rgb, RgbImage};
use rayon::prelude::*;

use crate::guided::{half, upsample};
use crate::patchmatch::{
    check_alpha, check_patch, iterate, patch_offsets, pixels, random_nnf, recompute_dist, Iter,
    Mode, Nnf, Source,
};
use crate::{Error, Result};

/// Patch-voting synthesis settings.
#[derive(Debug, Clone, PartialEq)]
pub struct VotingParams {
    /// Patch side, odd, at least 3 (7).
    pub patch: usize,
    /// Pyramid levels (3; 1 = full resolution only).
    pub levels: usize,
    /// EM iterations (match, vote) per level (2).
    pub em_iters: usize,
    /// PatchMatch iterations per EM iteration (4).
    pub pm_iters: usize,
    /// Weight of the guide against the current output in the query (0.5).
    pub guide_weight: f64,
    /// Random seed.
    pub seed: u64,
}

impl Default for VotingParams {
    fn default() -> Self {
        Self {
            patch: 7,
            levels: 3,
            em_iters: 2,
            pm_iters: 4,
            guide_weight: 0.5,
            seed: 0,
        }
    }
}

/// Synthesises an image the size of `guide` from the texture of `input` by patch voting.
pub fn voting_synthesis(input: &RgbImage, guide: &RgbImage, p: &VotingParams) -> Result<RgbImage> {
    if p.patch < 3 || p.patch.is_multiple_of(2) {
        return Err(Error::BadParam {
            name: "patch".into(),
            value: p.patch.to_string(),
            why: "must be odd and at least 3".into(),
        });
    }
    if !(0.0..=1.0).contains(&p.guide_weight) {
        return Err(Error::BadParam {
            name: "guide_weight".into(),
            value: p.guide_weight.to_string(),
            why: "must be in 0..=1".into(),
        });
    }
    check_alpha(0.5)?;
    let levels = p.levels.max(1);
    // Pyramids, finest first.
    let mut ins = vec![(
        pixels(input),
        input.width() as usize,
        input.height() as usize,
    )];
    let mut gds = vec![(
        pixels(guide),
        guide.width() as usize,
        guide.height() as usize,
    )];
    for _ in 1..levels {
        let (i, iw, ih) = ins.last().expect("level");
        let (g, gw, gh) = gds.last().expect("level");
        if iw / 2 < p.patch || ih / 2 < p.patch || *gw < 2 || *gh < 2 {
            break;
        }
        let ni = half(i, *iw, *ih);
        let ng = half(g, *gw, *gh);
        ins.push(ni);
        gds.push(ng);
    }
    let offsets = patch_offsets(p.patch, 1);
    let strips = rayon::current_num_threads().max(1);
    let mut state: Option<(Nnf, Vec<[u8; 3]>)> = None;
    for lv in (0..ins.len()).rev() {
        let (ipx, iw, ih) = &ins[lv];
        let (gpx, gw, gh) = &gds[lv];
        let (iw, ih, gw, gh) = (*iw, *ih, *gw, *gh);
        check_patch("voting input photo", iw, ih, p.patch)?;
        let src = Source {
            px: ipx,
            w: iw,
            h: ih,
            r: p.patch / 2,
        };
        let (mut nnf, mut out) = match state.take() {
            None => (random_nnf(gw, gh, &src, gpx, &offsets, p.seed), gpx.clone()),
            Some((coarse, cout)) => {
                let (cw, ch) = (coarse.width, coarse.height);
                let up: Vec<[u8; 3]> = (0..gw * gh)
                    .map(|i| cout[((i / gw) / 2).min(ch - 1) * cw + ((i % gw) / 2).min(cw - 1)])
                    .collect();
                (upsample(&coarse, gw, gh, &src), up)
            }
        };
        for em in 0..p.em_iters.max(1) {
            let gwt = p.guide_weight;
            let query: Vec<[u8; 3]> = gpx
                .iter()
                .zip(&out)
                .map(|(g, o)| {
                    [0, 1, 2].map(|k| (gwt * g[k] as f64 + (1.0 - gwt) * o[k] as f64).round() as u8)
                })
                .collect();
            recompute_dist(&mut nnf, &src, &query, &offsets);
            let mut dummy = vec![[0u8; 3]; gw * gh];
            for it in 0..p.pm_iters {
                let step = Iter {
                    src: Source { ..src },
                    offsets: &offsets,
                    radius: iw.max(ih) as f64,
                    alpha: 0.5,
                    reverse: it % 2 == 1,
                    strips,
                    seed: p.seed.wrapping_add((lv * 1000 + em * 100 + it + 1) as u64),
                    active: None,
                };
                iterate(&step, &Mode::Plain { a: &query }, &mut nnf, &mut dummy);
            }
            out = vote(&nnf, &src, p.patch / 2, gpx);
        }
        state = Some((nnf, out));
    }
    let (_, out) = state.expect("at least one level");
    let (w, h) = guide.dimensions();
    Ok(RgbImage::from_fn(w, h, |x, y| {
        Rgb(out[(y * w + x) as usize])
    }))
}

/// Every pixel the mean of the votes of the patches covering it; black where the guide is.
fn vote(nnf: &Nnf, src: &Source, r: usize, guide: &[[u8; 3]]) -> Vec<[u8; 3]> {
    let (w, h) = (nnf.width as i64, nnf.height as i64);
    let r = r as i64;
    (0..(w * h) as usize)
        .into_par_iter()
        .map(|i| {
            if guide[i] == [0, 0, 0] {
                return [0, 0, 0];
            }
            let (x, y) = (i as i64 % w, i as i64 / w);
            let (mut acc, mut n) = ([0u32; 3], 0u32);
            for dy in -r..=r {
                for dx in -r..=r {
                    // The patch centred at q = (x - dx, y - dy) holds this pixel at offset (dx, dy).
                    let (qx, qy) = (x - dx, y - dy);
                    if qx < 0 || qy < 0 || qx >= w || qy >= h {
                        continue;
                    }
                    let (bx, by) = nnf.pos[(qy * w + qx) as usize];
                    let c = src.px[(by as i64 + dy) as usize * src.w + (bx as i64 + dx) as usize];
                    for k in 0..3 {
                        acc[k] += c[k] as u32;
                    }
                    n += 1;
                }
            }
            acc.map(|a| ((a + n / 2) / n.max(1)) as u8)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guide_equal_to_input_is_reproduced_closely() {
        let img = RgbImage::from_fn(64, 48, |x, y| {
            Rgb([
                (x * 4 + y) as u8 | 1,
                ((y * 5) as u8 ^ (x as u8 * 3)) | 1,
                ((x * y) % 251) as u8 | 1,
            ])
        });
        // With the input as its own guide every patch has an exact match; PatchMatch finds
        // most of them (a random field scores about 8 dB here), and the votes of the rest
        // blur a little: 29.1 dB measured.
        let out = voting_synthesis(&img, &img, &VotingParams::default()).unwrap();
        let psnr = crate::eval::psnr(&out, &img, None).unwrap();
        assert!(psnr > 25.0, "psnr {psnr}");
    }

    #[test]
    fn even_patch_is_refused() {
        let img = RgbImage::new(32, 32);
        let p = VotingParams {
            patch: 6,
            ..Default::default()
        };
        assert!(voting_synthesis(&img, &img, &p).is_err());
    }
}
