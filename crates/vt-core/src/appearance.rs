//! The appearance term of eq. (1) and (2): what the masks' XOR cannot see.
//!
//! Masks say *where* something moves, not *what it looks like*; on foliage (a tree filling the
//! frame) two frames with similar masks can show the leaves in quite different places, and a
//! switch between them pops. vt adds to every pair cost of eq. (1) and (2) a colour term computed
//! inside the masks' world:
//!
//! `A(a, b) = sum over thumbnail pixels x of |C_a(x) - C_b(x)|`, where `C(x)` is a frame's
//! *change image*: its smoothed grey level minus the smoothed background's, averaged over
//! `factor x factor` blocks (a thumbnail of about [`TARGET_PIXELS`] pixels). Using the change
//! (frame minus its own view's median) cancels most of the exposure difference between views and
//! keeps only what moves; small thumbnails make the term cheap (eq. (2) over a 70-frame pair costs
//! about 8 million absolute differences).
//!
//! The two terms are put in the same unit before adding: the pair cost is
//! `XOR(a, b) + kappa * A(a, b)` with `kappa = weight * (mean XOR step) / (mean A step)` of the
//! view the costs are compared in, so with weight 1 an ordinary frame step costs as much in
//! appearance as in masks. Weight 0 is the thesis (masks only). For eq. (2) the source view's
//! change thumbnails are warped into the target view by `H_(p,p')` (nearest neighbour, thumbnail
//! coordinates), and only target pixels the warp covers are compared.

use image::RgbImage;
use rayon::prelude::*;

use crate::Homography;

/// Thumbnail size the block factor aims for, pixels.
pub const TARGET_PIXELS: usize = 2000;

/// A frame's change image at thumbnail scale.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Thumb {
    /// Thumbnail width.
    pub width: u32,
    /// Thumbnail height.
    pub height: u32,
    /// Grey change (frame - background) in quarter grey levels (mean of R, G, B, block-averaged,
    /// times 4), row-major.
    pub data: Vec<i16>,
}

/// Block factor for a `w x h` image: the smallest whole factor giving at most
/// [`TARGET_PIXELS`] thumbnail pixels.
pub fn thumb_factor(w: u32, h: u32) -> u32 {
    let n = w as f64 * h as f64;
    (n / TARGET_PIXELS as f64).sqrt().ceil().max(1.0) as u32
}

/// The change thumbnail of a smoothed frame against the smoothed background.
pub fn change_thumb(frame: &RgbImage, background: &RgbImage, factor: u32) -> Thumb {
    let (w, h) = frame.dimensions();
    let (tw, th) = (w / factor, h / factor);
    let (f, b) = (frame.as_raw(), background.as_raw());
    let mut data = vec![0i16; tw as usize * th as usize];
    let scale = 4.0 / (3.0 * (factor * factor) as f32);
    // Block sums row by row: each block's 3 * factor contiguous bytes per row summed at once.
    let block = 3 * factor as usize;
    let mut acc = vec![0i32; tw as usize];
    for ty in 0..th {
        acc.fill(0);
        for y in ty * factor..(ty + 1) * factor {
            let row = y as usize * w as usize * 3;
            let (fr, br) = (
                &f[row..row + tw as usize * block],
                &b[row..row + tw as usize * block],
            );
            for ((a, fc), bc) in acc
                .iter_mut()
                .zip(fr.chunks_exact(block))
                .zip(br.chunks_exact(block))
            {
                let sf: i32 = fc.iter().map(|&v| v as i32).sum();
                let sb: i32 = bc.iter().map(|&v| v as i32).sum();
                *a += sf - sb;
            }
        }
        for (d, &a) in data[(ty * tw) as usize..((ty + 1) * tw) as usize]
            .iter_mut()
            .zip(&acc)
        {
            *d = (a as f32 * scale).round() as i16;
        }
    }
    Thumb {
        width: tw,
        height: th,
        data,
    }
}

/// `A(a, b)` over the pixels where `valid` is true (all when None).
pub fn thumb_cost(a: &Thumb, b: &Thumb, valid: Option<&[bool]>) -> u64 {
    match valid {
        None => a
            .data
            .iter()
            .zip(&b.data)
            .map(|(&x, &y)| (x as i32 - y as i32).unsigned_abs() as u64)
            .sum(),
        Some(v) => a
            .data
            .iter()
            .zip(&b.data)
            .zip(v)
            .filter(|(_, &ok)| ok)
            .map(|((&x, &y), _)| (x as i32 - y as i32).unsigned_abs() as u64)
            .sum(),
    }
}

/// Mean `A(s, s + 1)` over `frames` (a range of a view's thumbnails); 0 with fewer than two.
pub fn mean_thumb_step(thumbs: &[Thumb]) -> f64 {
    if thumbs.len() < 2 {
        return 0.0;
    }
    let total: u64 = thumbs
        .par_windows(2)
        .map(|w| thumb_cost(&w[0], &w[1], None))
        .sum();
    total as f64 / (thumbs.len() - 1) as f64
}

/// Row-major `n x n` matrix of `A(a, b)` for `b - a >= k` (0 elsewhere), as eq. (1) needs.
pub fn loop_pair_costs(thumbs: &[Thumb], k: usize) -> Vec<u64> {
    let n = thumbs.len();
    let mut d = vec![0u64; n * n];
    d.par_chunks_mut(n.max(1)).enumerate().for_each(|(a, row)| {
        for b in a + k..n {
            row[b] = thumb_cost(&thumbs[a], &thumbs[b], None);
        }
    });
    d
}

/// Warps thumbnails by a full-resolution homography `h` (source view to target view) taken to
/// thumbnail coordinates (block `i` covers pixels `i*f .. i*f+f-1`, centre `i*f + (f-1)/2`).
/// Returns the warped thumbnails and which target pixels the warp covers.
pub fn warp_thumbs(thumbs: &[Thumb], h: &Homography, factor: u32) -> (Vec<Thumb>, Vec<bool>) {
    let Some(first) = thumbs.first() else {
        return (Vec::new(), Vec::new());
    };
    let (tw, th) = (first.width, first.height);
    let f = factor as f64;
    let c = (f - 1.0) / 2.0;
    // For every target thumbnail pixel, the source thumbnail pixel it samples.
    let map: Vec<Option<usize>> = (0..th)
        .flat_map(|y| (0..tw).map(move |x| (x, y)))
        .map(|(x, y)| {
            let p = crate::Point::new(f * x as f64 + c, f * y as f64 + c);
            let s = h.apply_inverse(p)?;
            let (sx, sy) = (
                ((s.x - c) / f).round_ties_even(),
                ((s.y - c) / f).round_ties_even(),
            );
            (sx >= 0.0 && sy >= 0.0 && sx < tw as f64 && sy < th as f64)
                .then(|| sy as usize * tw as usize + sx as usize)
        })
        .collect();
    let valid: Vec<bool> = map.iter().map(Option::is_some).collect();
    let warped = thumbs
        .par_iter()
        .map(|t| Thumb {
            width: tw,
            height: th,
            data: map.iter().map(|m| m.map_or(0, |i| t.data[i])).collect(),
        })
        .collect();
    (warped, valid)
}

/// Row-major `ns x t_frames` matrix of `A(warped(s), target(t))` over the covered pixels, as
/// eq. (2) needs.
pub fn cross_pair_costs(
    warped: &[Thumb],
    valid: &[bool],
    target: &[Thumb],
    t_frames: usize,
) -> Vec<u64> {
    let ns = warped.len();
    let mut d = vec![0u64; ns * t_frames];
    d.par_chunks_mut(t_frames.max(1))
        .enumerate()
        .for_each(|(s, row)| {
            for (t, v) in row.iter_mut().enumerate() {
                *v = thumb_cost(&warped[s], &target[t], Some(valid));
            }
        });
    d
}

/// `XOR + kappa * A`, element by element (the arrays have one length).
pub fn combine(xor: &mut [u64], app: &[u64], kappa: f64) {
    if kappa <= 0.0 {
        return;
    }
    xor.iter_mut()
        .zip(app)
        .for_each(|(x, &a)| *x += (kappa * a as f64).round() as u64);
}

/// `kappa` for a view: `weight * xor_step / app_step`; with no mask motion the appearance term
/// counts alone in its own unit (`weight`), with no appearance change it is off.
pub fn kappa(weight: f64, xor_step: f64, app_step: f64) -> f64 {
    if weight <= 0.0 || app_step <= 0.0 {
        0.0
    } else if xor_step <= 0.0 {
        weight
    } else {
        weight * xor_step / app_step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn change_thumb_averages_blocks_and_cancels_the_background() {
        let bg = RgbImage::from_pixel(8, 4, image::Rgb([100, 100, 100]));
        let mut f = bg.clone();
        for y in 0..2 {
            for x in 0..2 {
                f.put_pixel(x, y, image::Rgb([130, 130, 130]));
            }
        }
        let t = change_thumb(&f, &bg, 2);
        assert_eq!((t.width, t.height), (4, 2));
        assert_eq!(t.data[0], 120); // +30 grey levels, times 4
        assert!(t.data[1..].iter().all(|&v| v == 0));
        assert_eq!(thumb_cost(&t, &change_thumb(&bg, &bg, 2), None), 120);
    }

    #[test]
    fn change_thumb_is_the_block_mean_of_the_channel_sums() {
        let mut rng = crate::rng::Rng::new(4);
        let mut random = |w, h| {
            RgbImage::from_fn(w, h, |_, _| {
                let v = rng.next_u64();
                image::Rgb([v as u8, (v >> 8) as u8, (v >> 16) as u8])
            })
        };
        for (w, h, factor) in [(37u32, 23u32, 3u32), (40, 16, 4), (5, 5, 1)] {
            let (f, b) = (random(w, h), random(w, h));
            let t = change_thumb(&f, &b, factor);
            let (tw, th) = (w / factor, h / factor);
            assert_eq!((t.width, t.height), (tw, th));
            for ty in 0..th {
                for tx in 0..tw {
                    let mut acc = 0i32;
                    for y in ty * factor..(ty + 1) * factor {
                        for x in tx * factor..(tx + 1) * factor {
                            for c in 0..3 {
                                acc +=
                                    f.get_pixel(x, y).0[c] as i32 - b.get_pixel(x, y).0[c] as i32;
                            }
                        }
                    }
                    let want = (acc as f32 * 4.0 / (3.0 * (factor * factor) as f32)).round() as i16;
                    assert_eq!(
                        t.data[(ty * tw + tx) as usize],
                        want,
                        "{w}x{h}/{factor} ({tx}, {ty})"
                    );
                }
            }
        }
    }

    #[test]
    fn warped_thumbs_follow_a_translation() {
        let bg = RgbImage::from_pixel(16, 8, image::Rgb([0, 0, 0]));
        let mut f = bg.clone();
        f.put_pixel(4, 2, image::Rgb([90, 90, 90]));
        f.put_pixel(5, 2, image::Rgb([90, 90, 90]));
        f.put_pixel(4, 3, image::Rgb([90, 90, 90]));
        f.put_pixel(5, 3, image::Rgb([90, 90, 90]));
        let t = change_thumb(&f, &bg, 2);
        // Shift by 4 px = 2 thumbnail pixels to the right.
        let (w, valid) = warp_thumbs(
            std::slice::from_ref(&t),
            &Homography::translation(4.0, 0.0),
            2,
        );
        assert_eq!(w[0].data[8 + 4], t.data[8 + 2]);
        assert!(!valid[0] && !valid[1] && valid[2]);
    }

    #[test]
    fn kappa_balances_the_units() {
        assert_eq!(kappa(1.0, 200.0, 50.0), 4.0);
        assert_eq!(kappa(0.0, 200.0, 50.0), 0.0);
        assert_eq!(kappa(2.0, 0.0, 50.0), 2.0);
    }
}
