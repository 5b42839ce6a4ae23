//! Image quality against a reference: PSNR and SSIM, optionally within a mask.
//!
//! SSIM is Wang et al. (2004): 11x11 Gaussian window, sigma 1.5, `C1 = (0.01 * 255)^2`,
//! `C2 = (0.03 * 255)^2`, on luma `Y = 0.299 R + 0.587 G + 0.114 B`, averaged over the window
//! centres whose window lies inside the image ("valid" filtering, as the reference code does)
//! and, with a mask, whose centre is in the mask.

use image::RgbImage;

use crate::silhouette::Mask;
use crate::{Error, Result};

fn check_sizes(a: &RgbImage, b: &RgbImage, mask: Option<&Mask>) -> Result<()> {
    if a.dimensions() != b.dimensions() {
        return Err(Error::SizeMismatch {
            what: "image vs reference".into(),
            expected_w: b.width(),
            expected_h: b.height(),
            got_w: a.width(),
            got_h: a.height(),
        });
    }
    if let Some(m) = mask {
        if (m.width(), m.height()) != b.dimensions() {
            return Err(Error::SizeMismatch {
                what: "mask vs reference".into(),
                expected_w: b.width(),
                expected_h: b.height(),
                got_w: m.width(),
                got_h: m.height(),
            });
        }
    }
    Ok(())
}

/// PSNR in dB over all channels of the pixels in `mask` (all pixels without one); infinite for
/// identical images. Errors for a size mismatch or an empty mask.
pub fn psnr(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    check_sizes(a, reference, mask)?;
    let (mut se, mut n) = (0.0f64, 0u64);
    for (y, (pa, pb)) in a.rows().zip(reference.rows()).enumerate() {
        for (x, (qa, qb)) in pa.zip(pb).enumerate() {
            if mask.is_some_and(|m| !m.get(x as i64, y as i64)) {
                continue;
            }
            for k in 0..3 {
                let d = qa.0[k] as f64 - qb.0[k] as f64;
                se += d * d;
            }
            n += 3;
        }
    }
    if n == 0 {
        return Err(Error::TooFew {
            what: "pixels in the PSNR mask".into(),
            got: 0,
            need: 1,
        });
    }
    let mse = se / n as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    })
}

fn luma(img: &RgbImage) -> Vec<f64> {
    img.pixels()
        .map(|p| 0.299 * p.0[0] as f64 + 0.587 * p.0[1] as f64 + 0.114 * p.0[2] as f64)
        .collect()
}

/// Separable "valid" Gaussian filter: output is `(w - 10) x (h - 10)`.
fn gauss_valid(src: &[f64], w: usize, h: usize, k: &[f64; 11]) -> Vec<f64> {
    let (ow, oh) = (w - 10, h - 10);
    let mut tmp = vec![0.0; ow * h];
    for y in 0..h {
        for x in 0..ow {
            tmp[y * ow + x] = (0..11).map(|i| k[i] * src[y * w + x + i]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..11).map(|i| k[i] * tmp[(y + i) * ow + x]).sum();
        }
    }
    out
}

/// Mean SSIM of luma over window centres inside the image (and in `mask`). Errors for a size
/// mismatch, images smaller than 11x11 or a mask with no valid centre.
pub fn ssim(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    check_sizes(a, reference, mask)?;
    let (w, h) = (a.width() as usize, a.height() as usize);
    if w < 11 || h < 11 {
        return Err(Error::ImageTooSmall {
            what: "SSIM input".into(),
            w: w as u32,
            h: h as u32,
            need: 11,
        });
    }
    let mut k = [0.0f64; 11];
    for (i, v) in k.iter_mut().enumerate() {
        let d = i as f64 - 5.0;
        *v = (-d * d / (2.0 * 1.5 * 1.5)).exp();
    }
    let s: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= s);
    let (x, y) = (luma(a), luma(reference));
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a * b).collect();
    let [mx, my, sxx, syy, sxy] = [&x, &y, &xx, &yy, &xy].map(|v| gauss_valid(v, w, h, &k));
    let (c1, c2) = ((0.01 * 255.0f64).powi(2), (0.03 * 255.0f64).powi(2));
    let ow = w - 10;
    let (mut total, mut n) = (0.0, 0usize);
    for i in 0..mx.len() {
        let (cx, cy) = (i % ow + 5, i / ow + 5);
        if mask.is_some_and(|m| !m.get(cx as i64, cy as i64)) {
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
        return Err(Error::TooFew {
            what: "window centres in the SSIM mask".into(),
            got: 0,
            need: 1,
        });
    }
    Ok(total / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: u32, h: u32, seed: u64, amp: i32, base: &RgbImage) -> RgbImage {
        let mut r = crate::rng::Rng::new(seed);
        RgbImage::from_fn(w, h, |x, y| {
            image::Rgb(
                base.get_pixel(x, y).0.map(|c| {
                    (c as i32 + r.range(-amp as i64, amp as i64) as i32).clamp(0, 255) as u8
                }),
            )
        })
    }

    #[test]
    fn identical_images_score_perfectly_and_noise_scores_lower() {
        let base = RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([(x * 6) as u8, (y * 8) as u8, ((x + y) * 3) as u8])
        });
        assert_eq!(psnr(&base, &base, None).unwrap(), f64::INFINITY);
        assert!((ssim(&base, &base, None).unwrap() - 1.0).abs() < 1e-12);
        let n1 = noise(40, 30, 1, 5, &base);
        let n2 = noise(40, 30, 2, 30, &base);
        assert!(psnr(&n1, &base, None).unwrap() > psnr(&n2, &base, None).unwrap());
        assert!(ssim(&n1, &base, None).unwrap() > ssim(&n2, &base, None).unwrap());
        // Uniform error e on every channel: PSNR = 20 log10(255 / e).

        let plus = RgbImage::from_pixel(40, 30, image::Rgb([10, 10, 10]));
        let zero = RgbImage::new(40, 30);
        assert!((psnr(&plus, &zero, None).unwrap() - 20.0 * (25.5f64).log10()).abs() < 1e-9);
        let empty = Mask::new(40, 30);
        assert!(psnr(&plus, &zero, Some(&empty)).is_err());
        assert!(ssim(&plus, &zero.clone(), Some(&empty)).is_err());
    }
}
