//! Gaussian blur by OpenCV's `GaussianBlur`, mirroring [`vt_core::blur::gaussian_blur`].
//!
//! Same kernel definition (OpenCV's, which vt-core reproduces) and border (`BORDER_DEFAULT`,
//! i.e. `BORDER_REFLECT_101`). OpenCV's 8-bit path is bit-exact *fixed point* (kernel taps
//! rounded to 16-bit fractions, integer accumulation, one rounding at the end), vt-core's is
//! `f32` with one rounding: the two agree within one grey level, which the cross-check asserts.

use image::RgbImage;
use opencv::core::{Mat, Size, BORDER_DEFAULT};
use opencv::imgproc;
use vt_core::blur::GaussianParams;

use crate::convert::{mat_to_rgb, rgb_view};
use crate::error::{Context, Result};

/// Blurs `src` into a new image (twin of [`vt_core::blur::gaussian_blur`]).
pub fn gaussian_blur(src: &RgbImage, params: &GaussianParams) -> Result<RgbImage> {
    // The same parameter rules and messages as vt-core (even ksize, non-finite sigma).
    vt_core::blur::gaussian_kernel(params.ksize, params.sigma)?;
    if src.width() == 0 || src.height() == 0 {
        return Ok(src.clone());
    }
    let k = params.ksize as i32;
    let mut out = Mat::default();
    imgproc::gaussian_blur(
        &rgb_view(src)?,
        &mut out,
        Size::new(k, k),
        params.sigma,
        params.sigma,
        BORDER_DEFAULT,
    )
    .with_ctx(|| {
        format!(
            "GaussianBlur {}x{} ksize {k} sigma {}",
            src.width(),
            src.height(),
            params.sigma
        )
    })?;
    mat_to_rgb(&out)
}
