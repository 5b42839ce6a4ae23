//! Image quality against a reference, the workspace's one definition of each: PSNR, SSIM and
//! mean absolute difference, over all pixels or only those set in a [`Mask`].
//!
//! SSIM is Wang et al. (2004): 11x11 Gaussian window (sigma 1.5, the kernel of
//! [`crate::blur::gaussian_kernel`]), `C1 = (0.01 * 255)^2`, `C2 = (0.03 * 255)^2`, on luma
//! `Y = 0.299 R + 0.587 G + 0.114 B`, averaged over the window centres whose window lies inside
//! the image ("valid" filtering, as the reference code does) and, with a mask, whose centre is set.
//!
//! Gradient energy (detail, which a blend of two slightly different frames loses): the mean
//! squared forward difference of luma both ways, [`gradient_energy`] over a frame and
//! [`gradient_energy_at`] over a list of pixels, optionally weighted.

use image::RgbImage;
use rayon::prelude::*;

use crate::blur::gaussian_kernel;
use crate::{Error, Mask, Result};

fn check_sizes(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<()> {
    let (w, h) = reference.dimensions();
    if w == 0 || h == 0 {
        return Err(Error::EmptyImage {
            what: "quality reference".into(),
            w,
            h,
        });
    }
    let mismatch = |what: &str, (got_w, got_h): (u32, u32)| Error::SizeMismatch {
        what: what.into(),
        expected_w: w,
        expected_h: h,
        got_w,
        got_h,
    };
    if a.dimensions() != (w, h) {
        return Err(mismatch("image vs reference", a.dimensions()));
    }
    if let Some(m) = mask {
        if (m.width(), m.height()) != (w, h) {
            return Err(mismatch("mask vs reference", (m.width(), m.height())));
        }
    }
    Ok(())
}

fn empty_mask(what: &str) -> Error {
    Error::InvalidParameter {
        name: "mask",
        value: "0 usable pixels".into(),
        why: format!("{what} needs at least one"),
    }
}

/// Sum of `f(value, reference value)` over every channel of the pixels in `mask` (all pixels
/// without one), and how many channel values were summed.
fn masked_sum(
    a: &RgbImage,
    reference: &RgbImage,
    mask: Option<&Mask>,
    f: impl Fn(u8, u8) -> u64,
) -> (u64, u64) {
    let w = reference.width() as usize;
    let (mut sum, mut n) = (0u64, 0u64);
    for (i, (pa, pb)) in a
        .as_raw()
        .chunks_exact(3)
        .zip(reference.as_raw().chunks_exact(3))
        .enumerate()
    {
        if mask.is_some_and(|m| !m.get((i % w) as u32, (i / w) as u32)) {
            continue;
        }
        sum += (0..3).map(|k| f(pa[k], pb[k])).sum::<u64>();
        n += 3;
    }
    (sum, n)
}

/// PSNR in dB over all channels of the pixels in `mask` (all pixels without one); infinite for
/// identical images. Errors for a size mismatch, an empty image or an empty mask.
pub fn psnr(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    check_sizes(a, reference, mask)?;
    let (se, n) = masked_sum(a, reference, mask, |x, y| (x.abs_diff(y) as u64).pow(2));
    if n == 0 {
        return Err(empty_mask("PSNR"));
    }
    let mse = se as f64 / n as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    })
}

/// Mean absolute channel difference (grey levels) over the pixels in `mask` (all without one).
pub fn mean_abs_diff(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    check_sizes(a, reference, mask)?;
    let (sum, n) = masked_sum(a, reference, mask, |x, y| x.abs_diff(y) as u64);
    if n == 0 {
        return Err(empty_mask("mean absolute difference"));
    }
    Ok(sum as f64 / n as f64)
}

/// Luma `0.299 R + 0.587 G + 0.114 B` of pixel `i` of packed RGB.
pub(crate) fn luma_at(raw: &[u8], i: usize) -> f32 {
    0.299 * raw[3 * i] as f32 + 0.587 * raw[3 * i + 1] as f32 + 0.114 * raw[3 * i + 2] as f32
}

/// Weighted mean over the pixels `px` (indices; `None`: all) of the squared forward differences
/// of luma both ways, with weights `wt` per pixel (`None`: 1); pixels on the last row or column
/// and pixels of weight 0 do not count.
pub fn gradient_energy_at(f: &RgbImage, px: Option<&[usize]>, wt: Option<&[f32]>) -> f64 {
    let (sum, n) = gradient_sums_at(f, px, wt);
    sum / n.max(1e-9)
}

/// The weighted sum of [`gradient_energy_at`]'s terms and the sum of their weights, so that the
/// energies of several pixel sets add up (a frame's from its tiles').
pub fn gradient_sums_at(f: &RgbImage, px: Option<&[usize]>, wt: Option<&[f32]>) -> (f64, f64) {
    let (w, h) = (f.width() as usize, f.height() as usize);
    let raw = f.as_raw();
    let term = |i: usize| -> (f64, f64) {
        let a = wt.map_or(1.0, |wt| wt[i] as f64);
        if a == 0.0 || i % w + 1 >= w || i / w + 1 >= h {
            return (0.0, 0.0);
        }
        let v = luma_at(raw, i);
        let (gx, gy) = (luma_at(raw, i + 1) - v, luma_at(raw, i + w) - v);
        (a * (gx * gx + gy * gy) as f64, a)
    };
    let add = |x: (f64, f64), y: (f64, f64)| (x.0 + y.0, x.1 + y.1);
    let (sum, n) = match px {
        Some(px) => px.iter().map(|&i| term(i)).fold((0.0, 0.0), add),
        None => (0..h)
            .into_par_iter()
            .map(|y| (y * w..(y + 1) * w).map(term).fold((0.0, 0.0), add))
            .reduce(|| (0.0, 0.0), add),
    };
    (sum, n)
}

/// [`gradient_energy_at`] over the whole frame, unweighted.
pub fn gradient_energy(f: &RgbImage) -> f64 {
    gradient_energy_at(f, None, None)
}

fn luma(img: &RgbImage) -> Vec<f64> {
    img.pixels()
        .map(|p| 0.299 * p.0[0] as f64 + 0.587 * p.0[1] as f64 + 0.114 * p.0[2] as f64)
        .collect()
}

/// Separable "valid" filter with an odd kernel: output is `(w - k + 1) x (h - k + 1)`.
fn filter_valid(src: &[f64], w: usize, h: usize, k: &[f64]) -> Vec<f64> {
    let r = k.len() - 1;
    let (ow, oh) = (w - r, h - r);
    let mut tmp = vec![0.0; ow * h];
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        for x in 0..ow {
            tmp[y * ow + x] = k.iter().zip(&row[x..]).map(|(a, b)| a * b).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = k
                .iter()
                .enumerate()
                .map(|(i, c)| c * tmp[(y + i) * ow + x])
                .sum();
        }
    }
    out
}

/// SSIM's window side.
const SSIM_WINDOW: usize = 11;

/// Mean SSIM of luma over window centres inside the image (and in `mask`). Errors for a size
/// mismatch, images smaller than 11x11 or a mask with no valid centre.
pub fn ssim(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    check_ssim(a, reference, mask)?;
    ssim_plane(&luma(a), &luma(reference), a.width() as usize, mask)
}

/// SSIM as the NeRF benchmarks report it (mip-NeRF's `compute_ssim`, skimage with
/// `channel_axis`): each RGB channel's mean SSIM over the same windows as [`ssim`], averaged
/// over the channels. Errors as [`ssim`].
pub fn ssim_rgb(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    check_ssim(a, reference, mask)?;
    let plane = |img: &RgbImage, c: usize| -> Vec<f64> {
        img.as_raw().chunks_exact(3).map(|p| p[c] as f64).collect()
    };
    let mut total = 0.0;
    for c in 0..3 {
        total += ssim_plane(&plane(a, c), &plane(reference, c), a.width() as usize, mask)?;
    }
    Ok(total / 3.0)
}

fn check_ssim(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<()> {
    check_sizes(a, reference, mask)?;
    let (w, h) = (a.width() as usize, a.height() as usize);
    if w < SSIM_WINDOW || h < SSIM_WINDOW {
        return Err(Error::InvalidParameter {
            name: "image size",
            value: format!("{w}x{h}"),
            why: format!("SSIM needs at least {SSIM_WINDOW}x{SSIM_WINDOW}"),
        });
    }
    Ok(())
}

/// Mean SSIM of two planes of width `w` (0..255 values) over the valid 11x11 Gaussian windows
/// (sigma 1.5) whose centre is in `mask`.
fn ssim_plane(x: &[f64], y: &[f64], w: usize, mask: Option<&Mask>) -> Result<f64> {
    let h = x.len() / w;
    let k = gaussian_kernel(SSIM_WINDOW, 1.5)?;
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(y).map(|(a, b)| a * b).collect();
    let [mx, my, sxx, syy, sxy] = [x, y, &xx, &yy, &xy].map(|v| filter_valid(v, w, h, &k));
    let (c1, c2) = ((0.01 * 255.0f64).powi(2), (0.03 * 255.0f64).powi(2));
    let half = SSIM_WINDOW / 2;
    let ow = w - 2 * half;
    let (mut total, mut n) = (0.0, 0usize);
    for i in 0..mx.len() {
        let (cx, cy) = (i % ow + half, i / ow + half);
        if mask.is_some_and(|m| !m.get(cx as u32, cy as u32)) {
            continue;
        }
        let (ma, mb) = (mx[i], my[i]);
        let va = sxx[i] - ma * ma;
        let vb = syy[i] - mb * mb;
        let cov = sxy[i] - ma * mb;
        total +=
            ((2.0 * ma * mb + c1) * (2.0 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
        n += 1;
    }
    if n == 0 {
        return Err(empty_mask("SSIM (window centres)"));
    }
    Ok(total / n as f64)
}

#[cfg(test)]
mod tests {

    #[test]
    fn rgb_ssim_is_the_mean_of_the_channels_and_luma_ssim_on_grey() {
        let mut r = Rng::new(7);
        let a = RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb([(x * 7) as u8, (y * 9) as u8, ((x * y) % 251) as u8])
        });
        let b = RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb(
                a.get_pixel(x, y)
                    .0
                    .map(|c| c.saturating_add((r.next_u64() % 40) as u8)),
            )
        });
        // Each channel alone, as a grey image, is a plane whose luma is that channel.
        let grey = |img: &RgbImage, c: usize| {
            RgbImage::from_fn(32, 24, |x, y| image::Rgb([img.get_pixel(x, y).0[c]; 3]))
        };
        let per: Vec<f64> = (0..3)
            .map(|c| ssim(&grey(&a, c), &grey(&b, c), None).unwrap())
            .collect();
        let mean = per.iter().sum::<f64>() / 3.0;
        assert!((ssim_rgb(&a, &b, None).unwrap() - mean).abs() < 1e-12);
        assert!(per.iter().all(|&s| s < 0.999), "{per:?}");
        assert!((ssim_rgb(&a, &a, None).unwrap() - 1.0).abs() < 1e-12);
        let g = grey(&a, 0);
        assert!((ssim_rgb(&g, &grey(&b, 0), None).unwrap() - per[0]).abs() < 1e-12);
    }

    #[test]
    fn gradient_energy_by_hand() {
        // A 3x2 grey ramp 0, 10, 30 over both rows: the pixels with both forward neighbours
        // are (0, 0) and (1, 0), with x differences 10 and 20 and no y difference.
        let f = RgbImage::from_fn(3, 2, |x, _| image::Rgb([[0, 10, 30][x as usize]; 3]));
        let all = gradient_energy(&f);
        assert!((all - (100.0 + 400.0) / 2.0).abs() < 1e-3, "{all}");
        // Weighted: (1 * 100 + 3 * 400) / 4; over a pixel list, only (1, 0).
        let wt = [1.0, 3.0, 0.0, 0.0, 0.0, 0.0];
        let weighted = gradient_energy_at(&f, None, Some(&wt));
        assert!((weighted - 1300.0 / 4.0).abs() < 1e-3, "{weighted}");
        let listed = gradient_energy_at(&f, Some(&[1, 2, 5]), None);
        assert!((listed - 400.0).abs() < 1e-3, "{listed}");
        // Nothing to measure: 0, not NaN.
        assert_eq!(gradient_energy(&RgbImage::new(1, 1)), 0.0);
    }

    use super::*;
    use crate::rng::Rng;

    fn noisy(base: &RgbImage, seed: u64, amp: i64) -> RgbImage {
        let mut r = Rng::new(seed);
        let mut out = base.clone();
        for v in out.iter_mut() {
            *v = (*v as i64 + r.range(-amp, amp)).clamp(0, 255) as u8;
        }
        out
    }

    fn base() -> RgbImage {
        RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([(x * 6) as u8, (y * 8) as u8, ((x + y) * 3) as u8])
        })
    }

    #[test]
    fn identical_images_score_perfectly_and_more_noise_scores_lower() {
        let b = base();
        assert_eq!(psnr(&b, &b, None).unwrap(), f64::INFINITY);
        assert!((ssim(&b, &b, None).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(mean_abs_diff(&b, &b, None).unwrap(), 0.0);
        let (n1, n2) = (noisy(&b, 1, 5), noisy(&b, 2, 30));
        assert!(psnr(&n1, &b, None).unwrap() > psnr(&n2, &b, None).unwrap());
        assert!(ssim(&n1, &b, None).unwrap() > ssim(&n2, &b, None).unwrap());
        assert!(mean_abs_diff(&n1, &b, None).unwrap() < mean_abs_diff(&n2, &b, None).unwrap());
    }

    #[test]
    fn uniform_error_gives_the_closed_form() {
        // Uniform error e on every channel: PSNR = 20 log10(255 / e), MAD = e.
        let plus = RgbImage::from_pixel(40, 30, image::Rgb([10, 10, 10]));
        let zero = RgbImage::new(40, 30);
        assert!((psnr(&plus, &zero, None).unwrap() - 20.0 * 25.5f64.log10()).abs() < 1e-9);
        assert_eq!(mean_abs_diff(&plus, &zero, None).unwrap(), 10.0);
    }

    #[test]
    fn the_mask_selects_pixels_and_an_empty_one_is_an_error() {
        let zero = RgbImage::new(40, 30);
        // Error 20 on the left half only: masked to the right half, the images are identical.
        let half = RgbImage::from_fn(40, 30, |x, _| image::Rgb([if x < 20 { 20 } else { 0 }; 3]));
        let right = Mask::from_fn(40, 30, |x, _| x >= 20);
        let left = Mask::from_fn(40, 30, |x, _| x < 20);
        assert_eq!(psnr(&half, &zero, Some(&right)).unwrap(), f64::INFINITY);
        assert_eq!(mean_abs_diff(&half, &zero, Some(&left)).unwrap(), 20.0);
        let empty = Mask::new(40, 30);
        assert!(psnr(&half, &zero, Some(&empty)).is_err());
        assert!(ssim(&half, &zero, Some(&empty)).is_err());
        assert!(psnr(&half, &RgbImage::new(4, 4), None).is_err());
    }

    #[test]
    fn ssim_matches_a_direct_windowed_computation() {
        // Independent path: each window's statistics summed directly in 2-D with the textbook
        // Gaussian, not through the separable filter.
        let b = base();
        let n = noisy(&b, 9, 12);
        let (w, h) = (40usize, 30usize);
        let g: Vec<f64> = (0..11)
            .map(|i| (-((i as f64 - 5.0).powi(2)) / 4.5).exp())
            .collect();
        let gs: f64 = g.iter().sum::<f64>().powi(2);
        let l = |img: &RgbImage, x: usize, y: usize| {
            let p = img.get_pixel(x as u32, y as u32).0;
            0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64
        };
        let (c1, c2) = (6.5025, 58.5225);
        let mut total = 0.0;
        let mut count = 0;
        for cy in 5..h - 5 {
            for cx in 5..w - 5 {
                let (mut mx, mut my, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for j in 0..11 {
                    for i in 0..11 {
                        let wgt = g[i] * g[j] / gs;
                        let (a, r) = (l(&n, cx + i - 5, cy + j - 5), l(&b, cx + i - 5, cy + j - 5));
                        mx += wgt * a;
                        my += wgt * r;
                        sxx += wgt * a * a;
                        syy += wgt * r * r;
                        sxy += wgt * a * r;
                    }
                }
                let (va, vb, cov) = (sxx - mx * mx, syy - my * my, sxy - mx * my);
                total += ((2.0 * mx * my + c1) * (2.0 * cov + c2))
                    / ((mx * mx + my * my + c1) * (va + vb + c2));
                count += 1;
            }
        }
        let direct = total / count as f64;
        assert!((ssim(&n, &b, None).unwrap() - direct).abs() < 1e-9);
    }
}
