//! The searches of eq. (1) and eq. (2) written independently of vt-core: window sums by OpenCV
//! matrix additions of shifted views of the pair-cost matrix, argmins by OpenCV `minMaxLoc` over
//! a candidate mask. `minMaxLoc` scans row-major and keeps the first minimum, which *is* the
//! tie rule vt-core implements by sorting (smallest cost, then smallest row, then smallest
//! column), so the cross-check compares two searches that share no code: flip a tie rule or an
//! index bound in vt-core and its rows fail.

use opencv::core::{Mat, Point, Rect, Scalar, ToInputArray, CV_64F, CV_8U};
use opencv::prelude::*;
use vt_core::loops::{Loop, LoopParams};

use crate::error::{Context, Result};

/// A `rows x cols` `CV_64F` mat holding `d` (row-major `d_rows x d_cols`) in its top-left corner
/// and zeros elsewhere (`rows >= d_rows`, `cols >= d_cols`). Costs are pixel counts, far below
/// 2^53, so `f64` holds them exactly.
fn padded_costs(d: &[u64], d_rows: usize, d_cols: usize, rows: usize, cols: usize) -> Result<Mat> {
    let mut m = Mat::new_rows_cols_with_default(rows as i32, cols as i32, CV_64F, Scalar::all(0.0))
        .ctx("Mat::zeros (costs)")?;
    for r in 0..d_rows {
        let row = m
            .at_row_mut::<f64>(r as i32)
            .ctx("Mat::at_row_mut (costs)")?;
        for (v, &c) in row.iter_mut().zip(&d[r * d_cols..(r + 1) * d_cols]) {
            *v = c as f64;
        }
    }
    Ok(m)
}

/// `E(a, b) = sum_{i < w} D(a + i, b + i)` for `a < rows`, `b < cols`, as OpenCV adds of the
/// `rows x cols` views of `d` shifted by `(i, i)`; `d` must be at least `rows + w - 1` by
/// `cols + w - 1`.
fn window_sums(d: &Mat, rows: usize, cols: usize, window: usize) -> Result<Mat> {
    let mut e = Mat::new_rows_cols_with_default(rows as i32, cols as i32, CV_64F, Scalar::all(0.0))
        .ctx("Mat::zeros (window sums)")?;
    for i in 0..window as i32 {
        let view = d
            .roi(Rect::new(i, i, cols as i32, rows as i32))
            .ctx("Mat::roi (shifted costs)")?;
        let mut sum = Mat::default();
        opencv::core::add(&e, &view, &mut sum, &opencv::core::no_array(), -1).ctx("add")?;
        e = sum;
    }
    Ok(e)
}

/// `minMaxLoc` of `e` under `mask`: `(value, row, column)` of the first minimum in row-major
/// order, or `None` when the mask selects nothing.
fn first_min(
    e: &impl ToInputArray,
    mask: &impl ToInputArray,
) -> Result<Option<(f64, usize, usize)>> {
    let (mut min, mut at) = (0.0f64, Point::new(-1, -1));
    opencv::core::min_max_loc(e, Some(&mut min), None, Some(&mut at), None, mask)
        .ctx("minMaxLoc")?;
    Ok((at.x >= 0 && at.y >= 0).then_some((min, at.y as usize, at.x as usize)))
}

/// Eq. (1) from the pair costs `d[a * n + b] = XOR(I(a), I(b))` (`b - a >= k`; vt-core's
/// layout): the `count` best loops, each more than `min_separation` frames (Chebyshev) from
/// every better one. Inputs must have passed `vt_core::loops::check_loop_input`.
pub fn loops_from_pair_costs(
    d: &[u64],
    n: usize,
    params: &LoopParams,
    count: usize,
    min_separation: usize,
) -> Result<Vec<Loop>> {
    let (w, k) = (params.window, params.min_length);
    // Loop ends n run to N - w, so the window of n = N - w touches frame N - 1.
    let side = n - w + 1;
    let dm = padded_costs(d, n, n, n, n)?;
    let e = window_sums(&dm, side, side, w)?;
    // Candidates: m + k <= n (upper band of the square).
    let mut mask =
        Mat::new_rows_cols_with_default(side as i32, side as i32, CV_8U, Scalar::all(0.0))
            .ctx("Mat::zeros (candidates)")?;
    for m in 0..side {
        let row = mask
            .at_row_mut::<u8>(m as i32)
            .ctx("Mat::at_row_mut (candidates)")?;
        for v in row.iter_mut().skip(m + k) {
            *v = 255;
        }
    }
    let mut out = Vec::with_capacity(count);
    while out.len() < count {
        let Some((cost, m, end)) = first_min(&e, &mask)? else {
            break;
        };
        out.push(Loop {
            start: m,
            end,
            cost: cost as u64,
        });
        // Exclude every loop within min_separation of this one (Chebyshev), itself included.
        let s = min_separation;
        let (r0, c0) = (m.saturating_sub(s), end.saturating_sub(s));
        let (r1, c1) = ((m + s + 1).min(side), (end + s + 1).min(side));
        let mut block = mask
            .roi_mut(Rect::new(
                c0 as i32,
                r0 as i32,
                (c1 - c0) as i32,
                (r1 - r0) as i32,
            ))
            .ctx("Mat::roi_mut (exclusion)")?;
        block
            .set_to(&Scalar::all(0.0), &opencv::core::no_array())
            .ctx("setTo")?;
    }
    Ok(out)
}

/// Eq. (2) from `d[s * t_frames + t] = XOR(H(I_p(s)), I_{p'}(t))` (vt-core's layout): for every
/// source frame s the t in `0..=t_max` of least window sum, windows shortened to
/// `min(w, ns - s)` frames and kept inside the `t_frames` target frames; ties to the smallest t.
pub fn transitions_from_pair_costs(
    d: &[u64],
    ns: usize,
    t_frames: usize,
    t_max: usize,
    window: usize,
) -> Result<Vec<Option<(usize, u64)>>> {
    let cols = t_max + 1;
    // Zero rows below the last source frame make the full-window sum equal the shortened one.
    let dm = padded_costs(
        d,
        ns,
        t_frames,
        ns + window - 1,
        cols.max(t_frames) + window - 1,
    )?;
    let e = window_sums(&dm, ns, cols, window)?;
    let mut out = Vec::with_capacity(ns);
    for s in 0..ns {
        let ws = window.min(ns - s);
        // t + ws <= t_frames keeps every summed target frame real.
        let usable = (t_frames + 1).saturating_sub(ws).min(cols);
        if usable == 0 {
            out.push(None);
            continue;
        }
        let row = e
            .roi(Rect::new(0, s as i32, usable as i32, 1))
            .ctx("Mat::roi (transition row)")?;
        out.push(first_min(&row, &opencv::core::no_array())?.map(|(c, _, t)| (t, c as u64)));
    }
    Ok(out)
}
