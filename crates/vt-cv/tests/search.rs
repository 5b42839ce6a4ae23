//! The eq. (1) and eq. (2) searches of vt-core and vt-cv on the same cost matrices. Costs are
//! small integers, so ties are everywhere: a changed tie rule or index bound on either side shows.

use proptest::prelude::*;
use vt_core::loops::LoopParams;

/// A row-major `rows x cols` matrix of costs in `0..levels`.
fn costs(rows: usize, cols: usize, levels: u64) -> impl Strategy<Value = Vec<u64>> {
    proptest::collection::vec(0..levels, rows * cols)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, .. ProptestConfig::default() })]

    #[test]
    fn loop_searches_agree(
        (n, d) in (6usize..24).prop_flat_map(|n| (Just(n), costs(n, n, 4))),
        window in 1usize..4,
        min_length in 1usize..5,
        count in 1usize..5,
        min_separation in 0usize..3,
    ) {
        let params = LoopParams { window, min_length };
        prop_assume!(vt_core::loops::check_loop_input(n, &params, "t").is_ok());
        let vt = vt_core::loops::loops_from_pair_costs(&d, n, &params, count, min_separation);
        let cv = vt_cv::search::loops_from_pair_costs(&d, n, &params, count, min_separation).unwrap();
        prop_assert_eq!(vt, cv);
    }

    #[test]
    fn transition_searches_agree(
        (ns, t_frames, d) in (1usize..16, 2usize..16)
            .prop_flat_map(|(ns, tf)| (Just(ns), Just(tf), costs(ns, tf, 3))),
        window in 1usize..4,
        shorten in 0usize..4,
    ) {
        // As vt_core::transition::transition_range gives them: t_max + 1 <= t_frames, and
        // t_frames = min(t_max + w, frames that exist).
        let t_max = t_frames.saturating_sub(1 + shorten.min(window - 1));
        let vt = vt_core::transition::transitions_from_pair_costs(&d, ns, t_frames, t_max, window);
        let cv = vt_cv::search::transitions_from_pair_costs(&d, ns, t_frames, t_max, window).unwrap();
        prop_assert_eq!(vt, cv);
    }
}

#[test]
fn ties_go_to_the_smallest_start_then_end() {
    // Every cost equal: the first candidate in row-major order wins, and the next best distinct
    // loops follow in that order.
    let n = 10;
    let d = vec![1u64; n * n];
    let params = LoopParams {
        window: 2,
        min_length: 3,
    };
    for loops in [
        vt_core::loops::loops_from_pair_costs(&d, n, &params, 3, 0),
        vt_cv::search::loops_from_pair_costs(&d, n, &params, 3, 0).unwrap(),
    ] {
        let got: Vec<(usize, usize)> = loops.iter().map(|l| (l.start, l.end)).collect();
        assert_eq!(got, [(0, 3), (0, 4), (0, 5)]);
    }
}
