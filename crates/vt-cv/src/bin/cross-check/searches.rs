//! The eq. (1) and eq. (2) searches alone, on cost matrices full of ties: vt-core sorts
//! candidates, vt-cv takes OpenCV `minMaxLoc` over window sums built by OpenCV additions, so a
//! changed tie rule or index bound on either side fails these rows even where real masks never
//! tie.

#[allow(unused_imports)]
use super::*;

/// Costs in `0..levels`, deterministic in `seed`.
fn tie_costs(seed: u64, rows: usize, cols: usize, levels: u64) -> Vec<u64> {
    (0..rows * cols)
        .map(|i| vt_core::rng::mix_at(seed, i as u64) % levels)
        .collect()
}

pub(super) fn searches(t: &mut Table) -> Result<()> {
    let (mut cases, mut differ) = (0usize, Vec::new());
    for seed in 0..40u64 {
        let n = 8 + (seed as usize * 7) % 40;
        let d = tie_costs(seed, n, n, 1 + seed % 4);
        for (window, min_length) in [(1, 1), (3, 2), (2, 5), (3, n / 2)] {
            let params = LoopParams { window, min_length };
            if vt_core::loops::check_loop_input(n, &params, "ties").is_err() {
                continue;
            }
            for (count, sep) in [(1, 0), (4, 0), (4, 2)] {
                cases += 1;
                let vt = vt_core::loops::loops_from_pair_costs(&d, n, &params, count, sep);
                let cv = vt_cv::search::loops_from_pair_costs(&d, n, &params, count, sep)?;
                if vt != cv {
                    differ.push(format!(
                        "n {n} w {window} k {min_length} count {count} sep {sep} seed {seed}"
                    ));
                }
            }
        }
    }
    t.add(
        "loop search eq. (1)",
        "tie-heavy costs (0..4), 40 matrices",
        format!(
            "{} of {cases} searches differ{}",
            differ.len(),
            first(&differ)
        ),
        "identical",
        differ.is_empty(),
    );

    let (mut cases, mut differ) = (0usize, Vec::new());
    for seed in 0..40u64 {
        let ns = 3 + (seed as usize * 5) % 30;
        let t_frames = 2 + (seed as usize * 11) % 30;
        let d = tie_costs(seed + 1000, ns, t_frames, 1 + seed % 3);
        for window in 1..=3 {
            for t_max in t_frames.saturating_sub(window)..t_frames {
                cases += 1;
                let vt = vt_core::transition::transitions_from_pair_costs(
                    &d, ns, t_frames, t_max, window,
                );
                let cv =
                    vt_cv::search::transitions_from_pair_costs(&d, ns, t_frames, t_max, window)?;
                if vt != cv {
                    differ.push(format!(
                        "ns {ns} t_frames {t_frames} t_max {t_max} w {window} seed {seed}"
                    ));
                }
            }
        }
    }
    t.add(
        "transition search eq. (2)",
        "tie-heavy costs (0..3), 40 matrices",
        format!(
            "{} of {cases} tables differ{}",
            differ.len(),
            first(&differ)
        ),
        "identical",
        differ.is_empty(),
    );
    Ok(())
}

fn first(cases: &[String]) -> String {
    cases
        .first()
        .map(|c| format!(" (first: {c})"))
        .unwrap_or_default()
}
