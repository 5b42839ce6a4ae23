//! Warping by `warpPerspective`, mirroring [`vt_core::warp::warp_rgb`] and
//! [`vt_core::warp::warp_mask`]: `dst(x, y) = src(H^-1 (x, y))`, constant border 0.
//!
//! OpenCV is given vt-core's own stored inverse with `WARP_INVERSE_MAP`, so both sides map
//! every output pixel through the same matrix and the comparison isolates the sampling.
//! Nearest neighbour (`INTER_NEAREST`) rounds the mapped coordinate in `f64` like vt-core.
//! Bilinear (`INTER_LINEAR`) does not: OpenCV quantises the mapped coordinate to 1/32 pixel
//! (`INTER_BITS = 5`) and interpolates with 15-bit fixed-point weights, where vt-core uses the
//! exact fraction in `f32`; the results differ by at most one grey level on a small share of
//! pixels (measured by the cross-check).

use image::RgbImage;
use opencv::core::{Mat, Scalar, Size, BORDER_CONSTANT};
use opencv::imgproc;
use vt_core::warp::Interpolation;
use vt_core::{Homography, Mask};

use crate::convert::{mask_to_mat, mat_to_mask, mat_to_rgb, rgb_view};
use crate::error::{Context, Result};
use crate::homography::matrix3_to_mat;

fn flags(interp: Interpolation) -> i32 {
    let base = match interp {
        Interpolation::Nearest => imgproc::INTER_NEAREST,
        // OpenCV's bilinear is the fixed-point one; vt-core's exact mode differs from it by
        // the 1/32-pixel quantisation, its fixed-point mode not at all.
        Interpolation::Bilinear | Interpolation::BilinearFixed => imgproc::INTER_LINEAR,
    };
    base | imgproc::WARP_INVERSE_MAP
}

/// Warps `src` into a `width x height` mat (`src` is any mat `warpPerspective` accepts).
pub fn warp_mat(
    src: &impl opencv::core::ToInputArray,
    h: &Homography,
    width: u32,
    height: u32,
    interp: Interpolation,
) -> Result<Mat> {
    let inv = matrix3_to_mat(h.raw().1)?;
    let mut out = Mat::default();
    imgproc::warp_perspective(
        src,
        &mut out,
        &inv,
        Size::new(width as i32, height as i32),
        flags(interp),
        BORDER_CONSTANT,
        Scalar::all(0.0),
    )
    .with_ctx(|| format!("warpPerspective -> {width}x{height} ({interp:?})"))?;
    Ok(out)
}

/// Warps an RGB image (twin of [`vt_core::warp::warp_rgb`]).
pub fn warp_rgb(
    src: &RgbImage,
    h: &Homography,
    width: u32,
    height: u32,
    interp: Interpolation,
) -> Result<RgbImage> {
    if width == 0 || height == 0 || src.width() == 0 || src.height() == 0 {
        return Ok(RgbImage::new(width, height));
    }
    mat_to_rgb(&warp_mat(&rgb_view(src)?, h, width, height, interp)?)
}

/// Warps a mask with `INTER_NEAREST` on its 0/255 mat (twin of [`vt_core::warp::warp_mask`]).
pub fn warp_mask(src: &Mask, h: &Homography, width: u32, height: u32) -> Result<Mask> {
    if width == 0 || height == 0 || src.is_empty() {
        return Ok(Mask::new(width, height));
    }
    mat_to_mask(&warp_mat(
        &mask_to_mat(src)?,
        h,
        width,
        height,
        Interpolation::Nearest,
    )?)
}
