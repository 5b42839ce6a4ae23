//! Image quality against a reference, for System B: vt-core's PSNR and SSIM
//! ([`vt_core::metrics`], the workspace's one definition) over a silhouette [`Mask`].

use image::RgbImage;

use crate::silhouette::Mask;
use crate::Result;

/// PSNR in dB over all channels of the pixels in `mask` (all pixels without one); infinite for
/// identical images. Errors for a size mismatch or an empty mask.
pub fn psnr(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    Ok(vt_core::metrics::psnr(a, reference, mask)?)
}

/// Mean SSIM of luma over 11x11 windows inside the image whose centre is in `mask`. Errors for a
/// size mismatch, images smaller than 11x11 or a mask with no valid centre.
pub fn ssim(a: &RgbImage, reference: &RgbImage, mask: Option<&Mask>) -> Result<f64> {
    Ok(vt_core::metrics::ssim(a, reference, mask)?)
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
