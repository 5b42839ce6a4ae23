//! Transition tables, eq. (2) of the seed thesis, on OpenCV warps and XOR costs; mirrors
//! [`vt_core::transition::warp_masks`] and [`vt_core::transition::transition_table`]: the same
//! range `t + 1 < n_{p'}`, windows shortened to the frames that exist for the last `w - 1`
//! source frames, ties to the smallest `t`, `None` everywhere when `n_{p'} < 2`.

use opencv::core::Mat;
use rayon::prelude::*;
use vt_core::{Error as CoreError, Homography, Mask};

use crate::error::Result;
use crate::loops::masks_to_mats;
use crate::mask::xor_count_mat;
use crate::warp::warp_mask;

/// Warps every mask by `h` with `warpPerspective` (twin of [`vt_core::transition::warp_masks`]).
pub fn warp_masks(masks: &[Mask], h: &Homography, width: u32, height: u32) -> Result<Vec<Mask>> {
    masks
        .par_iter()
        .map(|m| warp_mask(m, h, width, height))
        .collect()
}

/// Eq. (2) for every source frame (twin of [`vt_core::transition::transition_table`]).
pub fn transition_table(
    warped: &[Mask],
    target: &[Mask],
    target_loop_end: usize,
    window: usize,
) -> Result<Vec<Option<usize>>> {
    if window == 0 {
        return Err(CoreError::InvalidParameter {
            name: "window",
            value: "0".into(),
            why: "w must be at least 1".into(),
        }
        .into());
    }
    if let (Some(a), Some(b)) = (warped.first(), target.first()) {
        if (a.width(), a.height()) != (b.width(), b.height()) {
            return Err(CoreError::SizeMismatch {
                what: "transition masks".into(),
                expected_w: b.width(),
                expected_h: b.height(),
                got_w: a.width(),
                got_h: a.height(),
            }
            .into());
        }
    }
    if target_loop_end < 2 {
        return Ok(vec![None; warped.len()]);
    }
    let t_max = target_loop_end - 2;
    let t_frames = (t_max + window).min(target.len());
    if t_max + 1 > t_frames {
        return Err(CoreError::TooFewFrames {
            what: "transition target".into(),
            got: target.len(),
            need: t_max + 1,
            why: "the target loop end lies beyond the target video".into(),
        }
        .into());
    }
    let src = masks_to_mats(warped, "transition source")?;
    let dst = masks_to_mats(&target[..t_frames], "transition target")?;
    let ns = warped.len();
    let mut d = vec![0u64; ns * t_frames];
    d.par_chunks_mut(t_frames).enumerate().try_for_each_init(
        Mat::default,
        |scratch, (s, row)| -> Result<()> {
            for (t, v) in row.iter_mut().enumerate() {
                *v = xor_count_mat(&src[s], &dst[t], scratch)?;
            }
            Ok(())
        },
    )?;
    Ok((0..ns)
        .map(|s| {
            let ws = window.min(ns - s);
            (0..=t_max)
                .filter(|t| t + ws <= t_frames)
                .map(|t| {
                    (
                        (0..ws).map(|i| d[(s + i) * t_frames + t + i]).sum::<u64>(),
                        t,
                    )
                })
                .min()
                .map(|(_, t)| t)
        })
        .collect())
}
