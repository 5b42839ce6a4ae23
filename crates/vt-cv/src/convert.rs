//! Conversions between vt-core's types and OpenCV `Mat`s.
//!
//! Colour images become `CV_8UC3` mats in the *same byte order* as the `RgbImage` (R, G, B):
//! OpenCV calls the order BGR, but none of the operations mirrored here depends on it, so no
//! `cvtColor` is needed as long as both directions keep the order. Masks become `CV_8UC1` mats
//! with 255 where set and 0 elsewhere (OpenCV's mask convention); any non-zero byte reads back
//! as set.

use image::RgbImage;
use opencv::boxed_ref::BoxedRef;
use opencv::core::{Mat, Vec3b, CV_8UC1, CV_8UC3};
use opencv::prelude::*;
use vt_core::Mask;

use crate::error::{Context, Error, Result};

/// A `CV_8UC3` mat that borrows the image's pixels (no copy). Fails for a 0-sized image.
pub fn rgb_view(img: &RgbImage) -> Result<BoxedRef<'_, Mat>> {
    Mat::new_rows_cols_with_bytes::<Vec3b>(img.height() as i32, img.width() as i32, img.as_raw())
        .with_ctx(|| format!("Mat over a {}x{} RGB image", img.width(), img.height()))
}

/// A `CV_8UC3` mat holding a copy of the image.
pub fn rgb_to_mat(img: &RgbImage) -> Result<Mat> {
    rgb_view(img)?.try_clone().ctx("Mat::clone (RGB)")
}

/// The pixels of a `CV_8UC3` mat as an `RgbImage` (copied; channel order kept as is).
pub fn mat_to_rgb(mat: &Mat) -> Result<RgbImage> {
    let (w, h) = dims(mat, CV_8UC3, "CV_8UC3 image")?;
    let bytes = continuous_bytes(mat)?;
    RgbImage::from_raw(w, h, bytes).ok_or_else(|| Error::NoResult {
        op: "Mat -> RgbImage".into(),
        why: format!("buffer does not hold {w}x{h}x3 bytes"),
    })
}

/// A `CV_8UC1` mat, 255 where the mask is set, 0 elsewhere.
pub fn mask_to_mat(mask: &Mask) -> Result<Mat> {
    let bytes = mask.to_bytes();
    Mat::new_rows_cols_with_bytes::<u8>(mask.height() as i32, mask.width() as i32, &bytes)
        .and_then(|m| m.try_clone())
        .with_ctx(|| format!("Mat over a {}x{} mask", mask.width(), mask.height()))
}

/// A `CV_8UC1` mat as a mask (non-zero = set).
pub fn mat_to_mask(mat: &Mat) -> Result<Mask> {
    let (w, h) = dims(mat, CV_8UC1, "CV_8UC1 mask")?;
    let bytes = continuous_bytes(mat)?;
    Ok(Mask::from_bytes(w, h, &bytes)?)
}

/// Checks the type of `mat` and returns its `(width, height)`.
fn dims(mat: &Mat, typ: i32, what: &str) -> Result<(u32, u32)> {
    if mat.typ() != typ || mat.dims() != 2 {
        return Err(Error::NoResult {
            op: format!("Mat -> {what}"),
            why: format!(
                "mat has type {} and {} dimensions, expected type {typ} in 2",
                mat.typ(),
                mat.dims()
            ),
        });
    }
    Ok((mat.cols().max(0) as u32, mat.rows().max(0) as u32))
}

/// The mat's bytes, row-major without padding (a clone makes a strided view continuous).
fn continuous_bytes(mat: &Mat) -> Result<Vec<u8>> {
    if mat.empty() {
        return Ok(Vec::new());
    }
    if mat.is_continuous() {
        Ok(mat.data_bytes().ctx("Mat::data_bytes")?.to_vec())
    } else {
        let c = mat.try_clone().ctx("Mat::clone (make continuous)")?;
        Ok(c.data_bytes().ctx("Mat::data_bytes")?.to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_keep_every_byte() {
        let img = RgbImage::from_fn(13, 7, |x, y| {
            image::Rgb([x as u8, y as u8 * 3, (x * y) as u8])
        });
        let mat = rgb_to_mat(&img).unwrap();
        assert_eq!((mat.cols(), mat.rows(), mat.typ()), (13, 7, CV_8UC3));
        assert_eq!(
            *mat.at_2d::<Vec3b>(2, 5).unwrap(),
            Vec3b::from([5, 6, 10]),
            "R stays in byte 0"
        );
        assert_eq!(mat_to_rgb(&mat).unwrap(), img);
        let mask = Mask::from_fn(70, 3, |x, y| (x + 2 * y) % 3 == 0);
        let m = mask_to_mat(&mask).unwrap();
        assert_eq!(*m.at_2d::<u8>(0, 0).unwrap(), 255);
        assert_eq!(*m.at_2d::<u8>(0, 1).unwrap(), 0);
        assert_eq!(mat_to_mask(&m).unwrap(), mask);
    }

    #[test]
    fn wrong_types_are_errors() {
        let mask = mask_to_mat(&Mask::new(4, 4)).unwrap();
        assert!(mat_to_rgb(&mask)
            .unwrap_err()
            .to_string()
            .contains("CV_8UC3"));
    }
}
