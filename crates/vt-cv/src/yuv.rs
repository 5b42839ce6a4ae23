//! 4:2:0 to RGB by OpenCV's `cvtColor(COLOR_YUV2RGB_I420)`, mirroring
//! [`vt_core::yuv::Yuv420Image::to_rgb`].
//!
//! OpenCV's I420 conversion is BT.601, limited range, each chroma sample shared by its 2x2 block,
//! in 20-bit fixed point; vt-core uses the same constants and rounding for that form, so the
//! two agree byte for byte. OpenCV has no BT.709 or full-range variant of it: those forms are
//! refused here.

use image::RgbImage;
use opencv::core::Mat;
use opencv::imgproc;
use vt_core::yuv::{Yuv420Image, YuvMatrix, YuvRange};

use crate::convert::mat_to_rgb;
use crate::error::{Context, Error, Result};

/// Converts a BT.601 limited-range 4:2:0 frame to RGB (twin of
/// [`vt_core::yuv::Yuv420Image::to_rgb`]).
pub fn yuv420_to_rgb(img: &Yuv420Image) -> Result<RgbImage> {
    if (img.matrix(), img.range()) != (YuvMatrix::Bt601, YuvRange::Limited) {
        return Err(Error::NoResult {
            op: "cvtColor(COLOR_YUV2RGB_I420)".into(),
            why: format!(
                "OpenCV converts BT.601 limited range only, not {:?} {:?}",
                img.matrix(),
                img.range()
            ),
        });
    }
    let (w, h) = img.dimensions();
    // I420 as OpenCV takes it: one CV_8UC1 mat of height * 3 / 2 rows, planes one after another.
    let planes = Mat::new_rows_cols_with_bytes::<u8>(h as i32 * 3 / 2, w as i32, img.as_raw())
        .with_ctx(|| format!("Mat over a {w}x{h} I420 frame"))?;
    let mut out = Mat::default();
    imgproc::cvt_color(&planes, &mut out, imgproc::COLOR_YUV2RGB_I420, 0)
        .with_ctx(|| format!("cvtColor YUV2RGB_I420 {w}x{h}"))?;
    mat_to_rgb(&out)
}
