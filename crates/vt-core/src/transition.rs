//! Transition tables between neighbouring views, eq. (2) of the seed thesis (Sec. 3.2.3):
//!
//! `t_{p'}(s, p) = argmin_t sum_{i=0}^{w-1} XOR(H_(p,p')(I_p(s+i)), I_{p'}(t+i))`, `t + 1 < n_{p'}`.
//!
//! Every frame `s` of view `p` gets an entry. For the last `w - 1` frames, where the window
//! would leave the video, the window is shortened to the frames that exist (`s + i < N_p`);
//! these frames are never on a loop (`n + w - 1 < N`), so playback does not depend on this rule.
//! Ties go to the smallest `t`. An entry is `None` only when the target loop ends too early for
//! any `t` (`n_{p'} < 2`).

use rayon::prelude::*;

use crate::mask::{union_active_words, xor_count_in};
use crate::warp::warp_mask_into;
use crate::{Error, Homography, Mask, Result};

/// Warps every mask of a view by `h` (the `H_(p,p')(I_p(s))` of eq. (2)).
pub fn warp_masks(masks: &[Mask], h: &Homography, width: u32, height: u32) -> Vec<Mask> {
    masks
        .par_iter()
        .map_init(
            || Mask::new(width, height),
            |buf, m| {
                warp_mask_into(m, h, buf);
                buf.clone()
            },
        )
        .collect()
}

/// Eq. (2) for every frame of the source view. `warped` are the source view's masks already
/// warped into the target view, `target` the target's masks, `target_loop_end` its `n_{p'}`.
pub fn transition_table(
    warped: &[Mask],
    target: &[Mask],
    target_loop_end: usize,
    window: usize,
) -> Result<Vec<Option<usize>>> {
    Ok(
        transition_table_with_costs(warped, target, target_loop_end, window)?
            .into_iter()
            .map(|e| e.map(|(t, _)| t))
            .collect(),
    )
}

/// [`transition_table`] with each entry's eq. (2) cost (the window sum at the chosen t).
pub fn transition_table_with_costs(
    warped: &[Mask],
    target: &[Mask],
    target_loop_end: usize,
    window: usize,
) -> Result<Vec<Option<(usize, u64)>>> {
    let Some((t_max, t_frames)) = transition_range(warped, target, target_loop_end, window)? else {
        return Ok(vec![None; warped.len()]);
    };
    let d = xor_pair_costs(warped, target, t_frames);
    Ok(transitions_from_pair_costs(
        &d,
        warped.len(),
        t_frames,
        t_max,
        window,
    ))
}

/// Row-major `warped.len() x t_frames` matrix `D(s, t) = XOR(H(I_p(s)), I_{p'}(t))`.
pub fn xor_pair_costs(warped: &[Mask], target: &[Mask], t_frames: usize) -> Vec<u64> {
    let active = union_active_words(warped.iter().chain(&target[..t_frames]));
    let ns = warped.len();
    let mut d = vec![0u64; ns * t_frames];
    d.par_chunks_mut(t_frames.max(1))
        .enumerate()
        .for_each(|(s, row)| {
            for (t, v) in row.iter_mut().enumerate() {
                *v = xor_count_in(&warped[s], &target[t], active.clone());
            }
        });
    d
}

/// Checks eq. (2)'s inputs. `None` when the target loop is too short for any t (every entry is
/// then `None`); else `(t_max, t_frames)`: t runs over `0..=t_max` (`t + 1 < n_{p'}`) and windows
/// touch target frames below `t_frames`. Shared with vt-cv.
pub fn transition_range(
    warped: &[Mask],
    target: &[Mask],
    target_loop_end: usize,
    window: usize,
) -> Result<Option<(usize, usize)>> {
    if window == 0 {
        return Err(Error::InvalidParameter {
            name: "window",
            value: "0".into(),
            why: "w must be at least 1".into(),
        });
    }
    if let (Some(a), Some(b)) = (warped.first(), target.first()) {
        if (a.width(), a.height()) != (b.width(), b.height()) {
            return Err(Error::SizeMismatch {
                what: "transition masks".into(),
                expected_w: b.width(),
                expected_h: b.height(),
                got_w: a.width(),
                got_h: a.height(),
            });
        }
    }
    if target_loop_end < 2 {
        return Ok(None);
    }
    // t + 1 < n_{p'}. Frames of the target any window may touch: t + i <= t_max + w - 1,
    // which is < N_{p'} since n + w - 1 < N.
    let t_max = target_loop_end - 2;
    let t_frames = (t_max + window).min(target.len());
    if t_max + 1 > t_frames {
        return Err(Error::TooFewFrames {
            what: "transition target".into(),
            got: target.len(),
            need: t_max + 1,
            why: "the target loop end lies beyond the target video".into(),
        });
    }
    Ok(Some((t_max, t_frames)))
}

/// Eq. (2) from the cost matrix `d[s * t_frames + t] = XOR(H(I_p(s)), I_{p'}(t))`: for every s
/// the t of least window sum (shortened windows at the tail, ties to the smallest t) and its cost.
/// vt-cv feeds it OpenCV's costs, so both implementations share the search.
pub fn transitions_from_pair_costs(
    d: &[u64],
    ns: usize,
    t_frames: usize,
    t_max: usize,
    window: usize,
) -> Vec<Option<(usize, u64)>> {
    (0..ns)
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
                .map(|(cost, t)| (t, cost))
        })
        .collect()
}

/// Mean `XOR(I(s), I(s + 1))` over a sequence: the size of an ordinary frame-to-frame step,
/// the unit of the seam scores.
pub fn mean_step(masks: &[Mask]) -> f64 {
    if masks.len() < 2 {
        return 0.0;
    }
    let active = union_active_words(masks);
    let total: u64 = masks
        .par_windows(2)
        .map(|w| xor_count_in(&w[0], &w[1], active.clone()))
        .sum();
    total as f64 / (masks.len() - 1) as f64
}

/// A seam score: how much a jump whose windowed XOR cost is `cost` (over `window` frames)
/// differs from ordinary playback, in units of the mean frame-to-frame step. 0 = invisible,
/// 1 = like one ordinary step, larger = a visible jump. A scene with no motion scores 0.
pub fn seam_score(cost: u64, window: usize, mean_step: f64) -> f64 {
    if mean_step <= 0.0 {
        return 0.0;
    }
    cost as f64 / (window as f64 * mean_step)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask::xor_count;

    fn blob(f: usize, period: usize, shift: i64) -> Mask {
        let ph = (f % period) as f64 / period as f64 * std::f64::consts::TAU;
        let cx = 30.0 + 10.0 * ph.sin() + shift as f64;
        Mask::from_fn(64, 32, |x, y| {
            let (dx, dy) = (x as f64 - cx, y as f64 - 16.0 - 5.0 * ph.cos());
            dx * dx + dy * dy < 36.0
        })
    }

    #[test]
    fn lands_on_the_same_phase_after_a_known_shift() {
        // Source view: phase 0 at frame 0; target: phase 0 at frame 4, 7 px to the right.
        let (period, offset) = (12, 4);
        let src: Vec<Mask> = (0..40).map(|f| blob(f, period, 0)).collect();
        let dst: Vec<Mask> = (0..40)
            .map(|f| blob(f + period - offset, period, 7))
            .collect();
        let warped = warp_masks(&src, &Homography::translation(7.0, 0.0), 64, 32);
        let table = transition_table(&warped, &dst, 30, 3).unwrap();
        for (s, t) in table.iter().enumerate() {
            let t = t.unwrap();
            assert!(t + 1 < 30);
            assert_eq!((t + period - offset) % period, s % period, "s={s} t={t}");
        }
    }

    #[test]
    fn equals_brute_force_with_shortened_tail_windows() {
        let src: Vec<Mask> = (0..9).map(|f| blob(f * 5, 7, 0)).collect();
        let dst: Vec<Mask> = (0..11).map(|f| blob(f * 3, 7, 1)).collect();
        let (n_end, w) = (8, 3);
        let table = transition_table(&src, &dst, n_end, w).unwrap();
        for s in 0..src.len() {
            let ws = w.min(src.len() - s);
            let best = (0..n_end - 1)
                .map(|t| {
                    (
                        (0..ws)
                            .map(|i| xor_count(&src[s + i], &dst[t + i]))
                            .sum::<u64>(),
                        t,
                    )
                })
                .min()
                .unwrap()
                .1;
            assert_eq!(table[s], Some(best), "s={s}");
        }
        assert_eq!(transition_table(&src, &dst, 1, w).unwrap(), vec![None; 9]);
    }
}
