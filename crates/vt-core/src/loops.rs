//! Loop search within one view, eq. (1) of the seed thesis (Sec. 3.2.2):
//!
//! `(m, n) = argmin_{n - m >= k} sum_{i=0}^{w-1} XOR(I(m+i), I(n+i))`, with `n + w - 1 < N`.
//!
//! Playback loops over frames `m+1 ..= n`. Ties are broken by the smallest `m`, then the smallest
//! `n`, so every implementation (vt-cv's included) picks the same loop.
//!
//! Cost: one XOR popcount per frame pair `(a, b)` with `b - a >= k`, restricted to the words
//! where any mask of the view is set, computed in parallel; the windowed sums then reuse them.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::mask::{union_active_words, xor_count_in};
use crate::{Error, Mask, Result};

/// Loop-search parameters; the thesis's values (Table 2) are the [`Default`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct LoopParams {
    /// Window `w`: consecutive frames compared (thesis: 3).
    pub window: usize,
    /// Minimum loop length `k = n - m` (thesis: 100).
    pub min_length: usize,
}

impl Default for LoopParams {
    fn default() -> Self {
        Self {
            window: 3,
            min_length: 100,
        }
    }
}

/// A loop: play `start + 1 ..= end`, then jump back to `start + 1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Loop {
    /// `m`.
    pub start: usize,
    /// `n`.
    pub end: usize,
    /// The eq. (1) cost: pixels that differ, summed over the window.
    pub cost: u64,
}

impl Loop {
    /// Frames played per cycle, `n - m`.
    pub fn len(&self) -> usize {
        self.end - self.start
    }

    /// Never true for a found loop (`n - m >= k >= 1`).
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// Checks `w`, `k` and the frame count; returns the largest valid `n` (`N - w`).
/// Checks `w`, `k` and the frame count of a view named `what`; returns the largest valid `n`
/// (`N - w`). Shared with vt-cv so both refuse the same inputs with the same words.
pub fn check_loop_input(n_frames: usize, params: &LoopParams, what: &str) -> Result<usize> {
    if params.window == 0 {
        return Err(Error::InvalidParameter {
            name: "window",
            value: "0".into(),
            why: "w must be at least 1".into(),
        });
    }
    if params.min_length == 0 {
        return Err(Error::InvalidParameter {
            name: "min_length",
            value: "0".into(),
            why: "k must be at least 1".into(),
        });
    }
    let need = params.window + params.min_length;
    if n_frames < need {
        return Err(Error::TooFewFrames {
            what: what.to_string(),
            got: n_frames,
            need,
            why: format!(
                "a loop needs w + k = {} + {} frames",
                params.window, params.min_length
            ),
        });
    }
    Ok(n_frames - params.window)
}

/// Row-major matrix of `XOR(I(a), I(b))` for `b - a >= k`, `b < N` (0 elsewhere).
pub fn pair_costs(masks: &[Mask], k: usize) -> Vec<u64> {
    let n = masks.len();
    let active = union_active_words(masks);
    let mut d = vec![0u64; n * n];
    d.par_chunks_mut(n).enumerate().for_each(|(a, row)| {
        for b in a + k..n {
            row[b] = xor_count_in(&masks[a], &masks[b], active.clone());
        }
    });
    d
}

/// The best loop of eq. (1). `what` names the view in errors.
pub fn find_loop(masks: &[Mask], params: &LoopParams, what: &str) -> Result<Loop> {
    Ok(find_loops(masks, params, 1, 0, what)?[0])
}

/// The `count` best *distinct* loops, best first: each differs from every better one by more than
/// `min_separation` frames in `m` or in `n` (Chebyshev distance), so near-copies of one good loop
/// do not crowd out a second, different one. `count = 1` gives [`find_loop`].
pub fn find_loops(
    masks: &[Mask],
    params: &LoopParams,
    count: usize,
    min_separation: usize,
    what: &str,
) -> Result<Vec<Loop>> {
    check_loop_input(masks.len(), params, what)?;
    crate::mask::check_same_size(masks, what)?;
    let d = pair_costs(masks, params.min_length);
    Ok(loops_from_pair_costs(
        &d,
        masks.len(),
        params,
        count,
        min_separation,
    ))
}

/// Eq. (1) from a pair-cost matrix: `d[a * n + b] = XOR(I(a), I(b))` for `b - a >= k` (row-major,
/// `n x n`, other entries unused). Window sums, then the `count` best distinct loops with the
/// tie-breaking of [`find_loops`]. Inputs must have passed [`check_loop_input`]. vt-cv feeds it
/// OpenCV's costs, so both implementations share the search and differ only in the costs.
pub fn loops_from_pair_costs(
    d: &[u64],
    n: usize,
    params: &LoopParams,
    count: usize,
    min_separation: usize,
) -> Vec<Loop> {
    let (w, k) = (params.window, params.min_length);
    let n_max = n - w;
    let cost = |m: usize, nn: usize| (0..w).map(|i| d[(m + i) * n + nn + i]).sum::<u64>();
    let mut all: Vec<Loop> = (0..=n_max - k)
        .flat_map(|m| (m + k..=n_max).map(move |e| (m, e)))
        .map(|(m, e)| Loop {
            start: m,
            end: e,
            cost: cost(m, e),
        })
        .collect();
    all.sort_unstable_by_key(|l| (l.cost, l.start, l.end));
    let mut out: Vec<Loop> = Vec::with_capacity(count);
    for l in all {
        if out.len() >= count {
            break;
        }
        let distinct = out
            .iter()
            .all(|o| o.start.abs_diff(l.start).max(o.end.abs_diff(l.end)) > min_separation);
        if distinct {
            out.push(l);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask::xor_count;
    use proptest::prelude::*;

    /// Masks of a blob moving with the given period (plus a unique speck per frame so no two
    /// frames are identical unless the period says so).
    fn periodic(n: usize, period: usize) -> Vec<Mask> {
        (0..n)
            .map(|f| {
                let ph = (f % period) as f64 / period as f64 * std::f64::consts::TAU;
                let cx = 32.0 + 12.0 * ph.sin();
                let cy = 20.0 + 6.0 * (2.0 * ph).sin();
                Mask::from_fn(64, 40, |x, y| {
                    let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                    dx * dx / 64.0 + dy * dy / 25.0 < 1.0 || (x as usize == f % 64 && y == 39)
                })
            })
            .collect()
    }

    #[test]
    fn loop_length_is_a_multiple_of_the_period() {
        let masks = periodic(60, 13);
        let l = find_loop(
            &masks,
            &LoopParams {
                window: 3,
                min_length: 20,
            },
            "test",
        )
        .unwrap();
        assert_eq!(l.len() % 13, 0, "{l:?}");
        assert!(l.len() >= 20);
    }

    #[test]
    fn distinct_loops_are_separated() {
        let masks = periodic(80, 11);
        let loops = find_loops(
            &masks,
            &LoopParams {
                window: 2,
                min_length: 15,
            },
            5,
            3,
            "test",
        )
        .unwrap();
        assert_eq!(loops.len(), 5);
        for (i, a) in loops.iter().enumerate() {
            for b in &loops[..i] {
                assert!(a.start.abs_diff(b.start).max(a.end.abs_diff(b.end)) > 3);
                assert!(a.cost >= b.cost);
            }
        }
    }

    #[test]
    fn too_few_frames_names_the_numbers() {
        let masks = periodic(10, 5);
        let err = find_loop(
            &masks,
            &LoopParams {
                window: 3,
                min_length: 8,
            },
            "view 2",
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "view 2: 10 frames, need at least 11 (a loop needs w + k = 3 + 8 frames)"
        );
    }

    proptest! {
        #[test]
        fn equals_brute_force(n in 6usize..24, w in 1usize..4, k in 1usize..6, seed in any::<u64>()) {
            prop_assume!(n >= w + k);
            let masks: Vec<Mask> = (0..n).map(|f| Mask::from_fn(9, 7, |x, y| {
                (seed.wrapping_mul(f as u64 + 1) >> ((x + 9 * y) % 60)) & 1 == 1
            })).collect();
            let params = LoopParams { window: w, min_length: k };
            let got = find_loop(&masks, &params, "p").unwrap();
            let mut best: Option<Loop> = None;
            for m in 0..n { for e in m + k..n {
                if e + w > n { continue; }
                let c: u64 = (0..w).map(|i| xor_count(&masks[m + i], &masks[e + i])).sum();
                if best.is_none_or(|b| c < b.cost) { best = Some(Loop { start: m, end: e, cost: c }); }
            }}
            prop_assert_eq!(got, best.unwrap());
        }
    }
}
