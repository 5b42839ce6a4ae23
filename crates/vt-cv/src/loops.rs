//! Loop search, eq. (1) of the seed thesis, on OpenCV XOR costs; mirrors
//! [`vt_core::loops::find_loop`] and [`vt_core::loops::find_loops`] with the same checks,
//! the same candidate set (`n - m >= k`, `n + w - 1 < N`) and the same tie-breaking (smallest
//! cost, then smallest `m`, then smallest `n`). Only the input checks are shared with vt-core;
//! the costs and the search ([`crate::search`]) are OpenCV's.

use opencv::core::Mat;
use rayon::prelude::*;
use vt_core::loops::{Loop, LoopParams};
use vt_core::Mask;

use crate::convert::mask_to_mat;
use crate::error::Result;
use crate::mask::xor_count_mat;

/// Masks as 0/255 mats, checking that they share mask 0's size.
pub(crate) fn masks_to_mats(masks: &[Mask], what: &str) -> Result<Vec<Mat>> {
    vt_core::mask::check_same_size(masks, what)?;
    masks.iter().map(mask_to_mat).collect()
}

/// Row-major `n x n` matrix of OpenCV `XOR(I(a), I(b))` for `b - a >= k` (0 elsewhere).
pub fn pair_costs(mats: &[Mat], k: usize) -> Result<Vec<u64>> {
    let n = mats.len();
    let mut d = vec![0u64; n * n];
    d.par_chunks_mut(n.max(1)).enumerate().try_for_each_init(
        Mat::default,
        |scratch, (a, row)| -> Result<()> {
            for b in a + k..n {
                row[b] = xor_count_mat(&mats[a], &mats[b], scratch)?;
            }
            Ok(())
        },
    )?;
    Ok(d)
}

/// The best loop of eq. (1) (twin of [`vt_core::loops::find_loop`]).
pub fn find_loop(masks: &[Mask], params: &LoopParams, what: &str) -> Result<Loop> {
    Ok(find_loops(masks, params, 1, 0, what)?[0])
}

/// The `count` best distinct loops (twin of [`vt_core::loops::find_loops`]).
pub fn find_loops(
    masks: &[Mask],
    params: &LoopParams,
    count: usize,
    min_separation: usize,
    what: &str,
) -> Result<Vec<Loop>> {
    vt_core::loops::check_loop_input(masks.len(), params, what)?;
    let mats = masks_to_mats(masks, what)?;
    let d = pair_costs(&mats, params.min_length)?;
    crate::search::loops_from_pair_costs(&d, masks.len(), params, count, min_separation)
}
