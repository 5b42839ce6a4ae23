//! Transition tables, eq. (2) of the seed thesis, on OpenCV warps and XOR costs; mirrors
//! [`vt_core::transition::warp_masks`] and [`vt_core::transition::transition_table`]: the same
//! range `t + 1 < n_{p'}`, windows shortened to the frames that exist for the last `w - 1`
//! source frames, ties to the smallest `t`, `None` everywhere when `n_{p'} < 2`.

use opencv::core::Mat;
use rayon::prelude::*;
use vt_core::{Homography, Mask};

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
    let Some((t_max, t_frames)) =
        vt_core::transition::transition_range(warped, target, target_loop_end, window)?
    else {
        return Ok(vec![None; warped.len()]);
    };
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
    Ok(
        crate::search::transitions_from_pair_costs(&d, ns, t_frames, t_max, window)?
            .into_iter()
            .map(|e| e.map(|(t, _)| t))
            .collect(),
    )
}
