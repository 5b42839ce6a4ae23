//! Temporal median by `cv::sort`, mirroring [`vt_core::median::temporal_median`].
//!
//! The frames are stacked as the rows of one `CV_8UC1` mat (a row holds every value of a band of
//! image rows), `cv::sort(SORT_EVERY_COLUMN)` sorts each pixel-channel's values, and the row of
//! rank `(n - 1) / 2` is the lower median, vt-core's definition. Image rows are processed in
//! bands so the stack stays under [`STACK_BYTES`] whatever the frame count.

use image::RgbImage;
use opencv::core::{self, Mat, Scalar, CV_8UC1, SORT_ASCENDING, SORT_EVERY_COLUMN};
use opencv::prelude::*;
use vt_core::Error as CoreError;

use crate::error::{Context, Result};

/// Upper bound on the bytes of one stacked band (frames x band values).
pub const STACK_BYTES: usize = 64 << 20;

/// The per-pixel, per-channel lower median of the frames (twin of
/// [`vt_core::median::temporal_median`]; same errors for no frames and mismatched sizes).
pub fn temporal_median<'a>(frames: impl IntoIterator<Item = &'a RgbImage>) -> Result<RgbImage> {
    let frames: Vec<&RgbImage> = frames.into_iter().collect();
    let Some(first) = frames.first() else {
        return Err(CoreError::TooFewFrames {
            what: "median".into(),
            got: 0,
            need: 1,
            why: "a median needs a frame".into(),
        }
        .into());
    };
    let (w, h) = first.dimensions();
    for (i, f) in frames.iter().enumerate() {
        if f.dimensions() != (w, h) {
            return Err(CoreError::SizeMismatch {
                what: format!("median frame {i}"),
                expected_w: w,
                expected_h: h,
                got_w: f.width(),
                got_h: f.height(),
            }
            .into());
        }
    }
    let n = frames.len();
    let row_values = w as usize * 3;
    let mut out = vec![0u8; row_values * h as usize];
    if out.is_empty() {
        return Ok(RgbImage::new(w, h));
    }
    let rank = (n - 1) / 2;
    let band_rows = (STACK_BYTES / (n * row_values)).clamp(1, h as usize);
    let mut sorted = Mat::default();
    for y0 in (0..h as usize).step_by(band_rows) {
        let y1 = (y0 + band_rows).min(h as usize);
        let (lo, hi) = (y0 * row_values, y1 * row_values);
        let cols = (hi - lo) as i32;
        let mut stack = Mat::new_rows_cols_with_default(n as i32, cols, CV_8UC1, Scalar::all(0.0))
            .with_ctx(|| format!("Mat {n}x{cols} (median stack)"))?;
        {
            let bytes = stack
                .data_bytes_mut()
                .ctx("Mat::data_bytes_mut (median stack)")?;
            for (row, f) in bytes.chunks_exact_mut(hi - lo).zip(&frames) {
                row.copy_from_slice(&f.as_raw()[lo..hi]);
            }
        }
        core::sort(&stack, &mut sorted, SORT_EVERY_COLUMN + SORT_ASCENDING)
            .with_ctx(|| format!("sort {n}x{cols} SORT_EVERY_COLUMN"))?;
        let row = sorted.row(rank as i32).ctx("Mat::row (median rank)")?;
        out[lo..hi].copy_from_slice(row.data_bytes().ctx("Mat::data_bytes (median row)")?);
    }
    Ok(RgbImage::from_raw(w, h, out).expect("buffer sized width*height*3"))
}
