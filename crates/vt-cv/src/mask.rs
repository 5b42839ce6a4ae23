//! Background subtraction, morphology and XOR costs by OpenCV, mirroring vt-core's
//! [`vt_core::analysis::threshold_mask`], [`vt_core::analysis::foreground_mask`],
//! [`vt_core::Mask`]'s `erode`/`dilate`/`open`/`close` and [`vt_core::mask::xor_count`].
//!
//! The rule is vt-core's: a pixel is set when `max over R,G,B of |frame - background| > threshold`
//! (`absdiff`, `split` + `max`, then `threshold(THRESH_BINARY)`, which also tests `>`).
//! Morphology uses a `(2r+1)x(2r+1)` `MORPH_RECT` kernel with OpenCV's default border value,
//! which for erosion treats outside pixels as set and for dilation as clear: vt-core's rule.

use image::RgbImage;
use opencv::core::{self, Mat, Point, Size, Vector, BORDER_CONSTANT};
use opencv::imgproc;
use opencv::prelude::*;
use vt_core::analysis::MaskParams;
use vt_core::{Error as CoreError, Mask};

use crate::convert::{mask_to_mat, mat_to_mask, rgb_view};
use crate::error::{Context, Result};

/// The raw threshold step on two (smoothed) images (twin of
/// [`vt_core::analysis::threshold_mask`]).
pub fn threshold_mask(frame: &RgbImage, background: &RgbImage, threshold: u8) -> Result<Mask> {
    mat_to_mask(&threshold_mat(frame, background, threshold)?)
}

/// [`threshold_mask`] followed by opening and closing (twin of
/// [`vt_core::analysis::foreground_mask`]).
pub fn foreground_mask(
    frame: &RgbImage,
    background: &RgbImage,
    params: &MaskParams,
) -> Result<Mask> {
    let m = threshold_mat(frame, background, params.threshold)?;
    let m = morph_mat(&m, params.open_radius, Morph::Open)?;
    let m = morph_mat(&m, params.close_radius, Morph::Close)?;
    mat_to_mask(&m)
}

/// [`threshold_mask`] as a 0/255 `CV_8UC1` mat.
pub fn threshold_mat(frame: &RgbImage, background: &RgbImage, threshold: u8) -> Result<Mat> {
    if frame.dimensions() != background.dimensions() {
        return Err(CoreError::SizeMismatch {
            what: "mask frame vs background".into(),
            expected_w: background.width(),
            expected_h: background.height(),
            got_w: frame.width(),
            got_h: frame.height(),
        }
        .into());
    }
    if frame.width() == 0 || frame.height() == 0 {
        return mask_to_mat(&Mask::new(frame.width(), frame.height()));
    }
    let op = || {
        format!(
            "background subtraction {}x{}",
            frame.width(),
            frame.height()
        )
    };
    let mut diff = Mat::default();
    core::absdiff(&rgb_view(frame)?, &rgb_view(background)?, &mut diff)
        .with_ctx(|| format!("absdiff ({})", op()))?;
    let mut channels = Vector::<Mat>::new();
    core::split(&diff, &mut channels).with_ctx(|| format!("split ({})", op()))?;
    let (mut max01, mut max012) = (Mat::default(), Mat::default());
    let ch = |i| {
        channels
            .get(i)
            .with_ctx(|| format!("channel {i} ({})", op()))
    };
    core::max(&ch(0)?, &ch(1)?, &mut max01).with_ctx(|| format!("max ({})", op()))?;
    core::max(&max01, &ch(2)?, &mut max012).with_ctx(|| format!("max ({})", op()))?;
    let mut out = Mat::default();
    imgproc::threshold(
        &max012,
        &mut out,
        threshold as f64,
        255.0,
        imgproc::THRESH_BINARY,
    )
    .with_ctx(|| format!("threshold > {threshold} ({})", op()))?;
    Ok(out)
}

/// A morphological operation with a square kernel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Morph {
    /// Erosion: a pixel stays set when its whole square is set (outside counts as set).
    Erode,
    /// Dilation: a pixel becomes set when any of its square is set (outside counts as clear).
    Dilate,
    /// Erosion then dilation.
    Open,
    /// Dilation then erosion.
    Close,
}

/// Applies `op` with a `(2 radius + 1)`-sided square (twin of [`vt_core::Mask::erode`],
/// `dilate`, `open`, `close`). Radius 0 returns the mask unchanged.
pub fn morph(mask: &Mask, radius: u32, op: Morph) -> Result<Mask> {
    if radius == 0 || mask.is_empty() {
        return Ok(mask.clone());
    }
    mat_to_mask(&morph_mat(&mask_to_mat(mask)?, radius, op)?)
}

/// [`morph`] on a 0/255 `CV_8UC1` mat.
pub fn morph_mat(mask: &Mat, radius: u32, op: Morph) -> Result<Mat> {
    if radius == 0 || mask.empty() {
        return mask.try_clone().ctx("Mat::clone");
    }
    let side = 2 * radius as i32 + 1;
    let kernel = imgproc::get_structuring_element(
        imgproc::MORPH_RECT,
        Size::new(side, side),
        Point::new(-1, -1),
    )
    .with_ctx(|| format!("getStructuringElement MORPH_RECT {side}x{side}"))?;
    let border = imgproc::morphology_default_border_value().ctx("morphologyDefaultBorderValue")?;
    let one = |src: &Mat, erode: bool| -> Result<Mat> {
        let mut dst = Mat::default();
        let anchor = Point::new(-1, -1);
        if erode {
            imgproc::erode(src, &mut dst, &kernel, anchor, 1, BORDER_CONSTANT, border)
                .with_ctx(|| format!("erode {side}x{side} on {}x{}", src.cols(), src.rows()))?;
        } else {
            imgproc::dilate(src, &mut dst, &kernel, anchor, 1, BORDER_CONSTANT, border)
                .with_ctx(|| format!("dilate {side}x{side} on {}x{}", src.cols(), src.rows()))?;
        }
        Ok(dst)
    };
    match op {
        Morph::Erode => one(mask, true),
        Morph::Dilate => one(mask, false),
        Morph::Open => one(&one(mask, true)?, false),
        Morph::Close => one(&one(mask, false)?, true),
    }
}

/// `XOR(a, b)`: pixels set in exactly one mask, by `bitwise_xor` + `countNonZero` (twin of
/// [`vt_core::mask::xor_count`], which panics on a size mismatch where this returns an error).
pub fn xor_count(a: &Mask, b: &Mask) -> Result<u64> {
    if (a.width(), a.height()) != (b.width(), b.height()) {
        return Err(CoreError::SizeMismatch {
            what: "xor_count masks".into(),
            expected_w: a.width(),
            expected_h: a.height(),
            got_w: b.width(),
            got_h: b.height(),
        }
        .into());
    }
    if a.is_empty() {
        return Ok(0);
    }
    let mut scratch = Mat::default();
    xor_count_mat(&mask_to_mat(a)?, &mask_to_mat(b)?, &mut scratch)
}

/// [`xor_count`] on two 0/255 mats of one size, with a reusable scratch mat.
pub fn xor_count_mat(a: &Mat, b: &Mat, scratch: &mut Mat) -> Result<u64> {
    if a.empty() {
        return Ok(0);
    }
    core::bitwise_xor(a, b, scratch, &core::no_array()).ctx("bitwise_xor")?;
    Ok(core::count_non_zero(scratch).ctx("countNonZero")? as u64)
}
