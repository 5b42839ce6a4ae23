//! Synthetic texture scenes: every System A stage on both sides, view by view.

#[allow(unused_imports)]
use super::*;

pub(super) fn testdata() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata")
}

/// Sums of per-view image differences (max of maxima, sums of counts).
pub(super) fn merge_diffs(diffs: impl IntoIterator<Item = ImageDiff>) -> ImageDiff {
    diffs.into_iter().fold(
        ImageDiff {
            max: 0,
            differ: 0,
            over_one: 0,
            pixels: 0,
        },
        |a, d| ImageDiff {
            max: a.max.max(d.max),
            differ: a.differ + d.differ,
            over_one: a.over_one + d.over_one,
            pixels: a.pixels + d.pixels,
        },
    )
}

/// Differing pixels, total pixels and set pixels of two mask sequences.
pub(super) fn mask_counts(vt: &[Mask], cv: &[Mask]) -> (u64, u64, u64) {
    let differ = vt
        .iter()
        .zip(cv)
        .map(|(a, b)| vt_core::mask::xor_count(a, b))
        .sum();
    (
        differ,
        vt.iter().map(|m| m.len() as u64).sum(),
        vt.iter().map(|m| m.count_ones()).sum(),
    )
}

/// One view's figures for [`view_checks`].
pub(super) struct ViewFigures {
    pub(super) median_memory: ImageDiff,
    pub(super) median_stream: ImageDiff,
    pub(super) blur_background: ImageDiff,
    pub(super) blur_frames: ImageDiff,
    pub(super) blur_5x5: ImageDiff,
    pub(super) mask_same: (u64, u64, u64),
    pub(super) threshold_same: (u64, u64, u64),
    pub(super) mask_own: (u64, u64, u64),
    pub(super) xor_wrong: usize,
    pub(super) xor_pairs: usize,
    pub(super) loop_vt: Loop,
    pub(super) loop_cv: Loop,
    pub(super) loops3_equal: bool,
    pub(super) loop_own_cv: Loop,
    pub(super) masks: Vec<Mask>,
}

pub(super) fn view_figures(
    frames: &[RgbImage],
    loops: &LoopParams,
    what: &str,
) -> Result<ViewFigures> {
    let blur = GaussianParams::default();
    let mask_params = MaskParams {
        threshold: 25,
        open_radius: 1,
        close_radius: 2,
    };
    // Median: vt-core's in-memory route and its streaming accumulator, against cv::sort.
    let vt_bg = vt_core::median::temporal_median(frames)?;
    let mut acc = vt_core::median::MedianAccumulator::new(frames[0].width(), frames[0].height());
    for f in frames {
        acc.push(f)?;
    }
    let vt_bg_stream = acc.median()?;
    drop(acc);
    let cv_bg = vt_cv::median::temporal_median(frames)?;
    // Blur: 3x3 default (fixed table) on background and frames, 5x5 sigma 1.2 (formula).
    let vt_bg_blur = vt_core::blur::gaussian_blur(&vt_bg, &blur)?;
    let cv_bg_blur = vt_cv::blur::gaussian_blur(&vt_bg, &blur)?;
    let vt_blurred: Vec<RgbImage> = frames
        .iter()
        .map(|f| vt_core::blur::gaussian_blur(f, &blur))
        .collect::<Result<_, _>>()?;
    let cv_blurred: Vec<RgbImage> = frames
        .iter()
        .map(|f| vt_cv::blur::gaussian_blur(f, &blur))
        .collect::<Result<_, _>>()?;
    let g5 = GaussianParams {
        ksize: 5,
        sigma: 1.2,
    };
    // Masks: from the same blurred frames (vt-core's), and each side from its own blur.
    let vt_masks: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| foreground_mask(f, &vt_bg_blur, &mask_params))
        .collect::<Result<_, _>>()?;
    let cv_same: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| vt_cv::mask::foreground_mask(f, &vt_bg_blur, &mask_params))
        .collect::<Result<_, _>>()?;
    let vt_raw: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| vt_core::analysis::threshold_mask(f, &vt_bg_blur, 25))
        .collect::<Result<_, _>>()?;
    let cv_raw: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| vt_cv::mask::threshold_mask(f, &vt_bg_blur, 25))
        .collect::<Result<_, _>>()?;
    let cv_masks: Vec<Mask> = cv_blurred
        .iter()
        .map(|f| vt_cv::mask::foreground_mask(f, &cv_bg_blur, &mask_params))
        .collect::<Result<_, _>>()?;
    // XOR costs of every pair of vt-core's masks.
    let mats: Vec<_> = vt_masks
        .iter()
        .map(vt_cv::convert::mask_to_mat)
        .collect::<Result<_, _>>()?;
    let cv_costs = vt_cv::loops::pair_costs(&mats, 0)?;
    let n = vt_masks.len();
    let mut xor_wrong = 0usize;
    for a in 0..n {
        for b in a..n {
            xor_wrong += (vt_core::mask::xor_count(&vt_masks[a], &vt_masks[b])
                != cv_costs[a * n + b]) as usize;
        }
    }
    Ok(ViewFigures {
        median_memory: image_diff(&vt_bg, &cv_bg),
        median_stream: image_diff(&vt_bg_stream, &cv_bg),
        blur_background: image_diff(&vt_bg_blur, &cv_bg_blur),
        blur_frames: merge_diffs(
            vt_blurred
                .iter()
                .zip(&cv_blurred)
                .map(|(a, b)| image_diff(a, b)),
        ),
        blur_5x5: image_diff(
            &vt_core::blur::gaussian_blur(&frames[0], &g5)?,
            &vt_cv::blur::gaussian_blur(&frames[0], &g5)?,
        ),
        mask_same: mask_counts(&vt_masks, &cv_same),
        threshold_same: mask_counts(&vt_raw, &cv_raw),
        mask_own: mask_counts(&vt_masks, &cv_masks),
        xor_wrong,
        xor_pairs: n * (n + 1) / 2,
        loop_vt: vt_core::loops::find_loop(&vt_masks, loops, what)?,
        loop_cv: vt_cv::loops::find_loop(&vt_masks, loops, what)?,
        loops3_equal: vt_core::loops::find_loops(&vt_masks, loops, 3, 2, what)?
            == vt_cv::loops::find_loops(&vt_masks, loops, 3, 2, what)?,
        loop_own_cv: vt_cv::loops::find_loop(&cv_masks, loops, what)?,
        masks: vt_masks,
    })
}

/// The per-view checks shared by synthetic scenes and tree.avi (median, blur, masks, XOR,
/// loops), one row per operation over all the views given. Returns vt-core's masks (from its
/// own blur) and loop per view.
pub(super) fn view_checks(
    t: &mut Table,
    input: &str,
    views: &[Vec<RgbImage>],
    loops: &LoopParams,
) -> Result<Vec<(Vec<Mask>, Loop)>> {
    let figs: Vec<ViewFigures> = views
        .iter()
        .enumerate()
        .map(|(v, frames)| view_figures(frames, loops, &format!("{input} view {v}")))
        .collect::<Result<_>>()?;
    let n_frames: usize = views.iter().map(Vec::len).sum();
    let all = if views.len() > 1 {
        format!("{input}, {} views", views.len())
    } else {
        input.to_string()
    };
    let identical = |t: &mut Table, op: &str, d: ImageDiff| {
        t.add(
            op,
            &all,
            format!("{} of {} pixels differ (max {})", d.differ, d.pixels, d.max),
            "identical",
            d.differ == 0,
        )
    };
    identical(
        t,
        "median (in memory)",
        merge_diffs(figs.iter().map(|f| f.median_memory.clone())),
    );
    identical(
        t,
        "median (streaming)",
        merge_diffs(figs.iter().map(|f| f.median_stream.clone())),
    );
    blur_row(
        t,
        "Gaussian 3x3 (background)",
        &all,
        merge_diffs(figs.iter().map(|f| f.blur_background.clone())),
    );
    blur_row(
        t,
        "Gaussian 3x3 (every frame)",
        &format!("{all}, {n_frames} frames"),
        merge_diffs(figs.iter().map(|f| f.blur_frames.clone())),
    );
    blur_row(
        t,
        "Gaussian 5x5 s1.2",
        &format!("{all}, frame 0"),
        merge_diffs(figs.iter().map(|f| f.blur_5x5.clone())),
    );
    let masks_row = |t: &mut Table, op: &str, c: Vec<(u64, u64, u64)>| {
        let (differ, total, set) = c
            .iter()
            .fold((0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        t.add(
            op,
            &all,
            format!(
                "{differ} of {total} pixels differ ({:.2}% set)",
                100.0 * set as f64 / total.max(1) as f64
            ),
            "identical",
            differ == 0,
        )
    };
    masks_row(
        t,
        "mask (same blur, open 1 close 2)",
        figs.iter().map(|f| f.mask_same).collect(),
    );
    masks_row(
        t,
        "mask (same blur, threshold only)",
        figs.iter().map(|f| f.threshold_same).collect(),
    );
    let (differ, total) = figs
        .iter()
        .fold((0, 0), |a, f| (a.0 + f.mask_own.0, a.1 + f.mask_own.1));
    let share = 100.0 * differ as f64 / total.max(1) as f64;
    t.add(
        "mask (own blur each)",
        &all,
        format!("{differ} of {total} pixels differ ({share:.4}%)"),
        "<= 0.1%",
        share <= 0.1,
    );
    let (wrong, pairs) = figs
        .iter()
        .fold((0, 0), |a, f| (a.0 + f.xor_wrong, a.1 + f.xor_pairs));
    t.add(
        "XOR cost",
        &format!("{all}, {pairs} pairs"),
        format!("{wrong} costs differ"),
        "identical",
        wrong == 0,
    );
    let lp = |l: &Loop| format!("({}, {}) {}", l.start, l.end, l.cost);
    let per_view =
        |f: &dyn Fn(&ViewFigures) -> String| figs.iter().map(f).collect::<Vec<_>>().join("; ");
    t.add(
        "loop eq. (1), same masks",
        &format!("{all}, w {} k {}", loops.window, loops.min_length),
        format!(
            "(m, n) cost vt/cv: {}",
            per_view(&|f| format!("{} / {}", lp(&f.loop_vt), lp(&f.loop_cv)))
        ),
        "identical",
        figs.iter().all(|f| f.loop_vt == f.loop_cv),
    );
    t.add(
        "3 distinct loops, same masks",
        &all,
        format!(
            "{} of {} views equal",
            figs.iter().filter(|f| f.loops3_equal).count(),
            figs.len()
        ),
        "identical",
        figs.iter().all(|f| f.loops3_equal),
    );
    t.add(
        "loop eq. (1), own pipelines",
        &all,
        format!(
            "(m, n) vt/cv: {}",
            per_view(&|f| format!(
                "({}, {}) / ({}, {})",
                f.loop_vt.start, f.loop_vt.end, f.loop_own_cv.start, f.loop_own_cv.end
            ))
        ),
        "same (m, n)",
        figs.iter()
            .all(|f| (f.loop_vt.start, f.loop_vt.end) == (f.loop_own_cv.start, f.loop_own_cv.end)),
    );
    Ok(figs.into_iter().map(|f| (f.masks, f.loop_vt)).collect())
}

/// Eq. (2) between two views with vt-core's masks and loop: warps and tables.
pub(super) fn transition_checks(
    t: &mut Table,
    input: &str,
    src: &[Mask],
    dst: &[Mask],
    h: &Homography,
    dst_loop: &Loop,
    window: usize,
) -> Result<()> {
    let (w, hh) = (dst[0].width(), dst[0].height());
    let vt_w = vt_core::transition::warp_masks(src, h, w, hh);
    let cv_w = vt_cv::transition::warp_masks(src, h, w, hh)?;
    check_identical_masks(t, "warp masks (nearest)", input, &vt_w, &cv_w);
    let vt_t = vt_core::transition::transition_table(&vt_w, dst, dst_loop.end, window)?;
    let cv_same = vt_cv::transition::transition_table(&vt_w, dst, dst_loop.end, window)?;
    let cv_t = vt_cv::transition::transition_table(&cv_w, dst, dst_loop.end, window)?;
    let differ = |a: &[Option<usize>], b: &[Option<usize>]| {
        a.iter().zip(b).filter(|(x, y)| x != y).count() + a.len().abs_diff(b.len())
    };
    t.add(
        "transition eq. (2), same warps",
        &format!("{input}, {} frames", vt_t.len()),
        format!("{} entries differ", differ(&vt_t, &cv_same)),
        "identical",
        differ(&vt_t, &cv_same) == 0,
    );
    t.add(
        "transition eq. (2), own warps",
        input,
        format!("{} entries differ", differ(&vt_t, &cv_t)),
        "identical",
        differ(&vt_t, &cv_t) == 0,
    );
    Ok(())
}

pub(super) fn synthetic(
    t: &mut Table,
    width: u32,
    height: u32,
    seed: u64,
    frames: usize,
    period: usize,
    rig: Rig,
) -> Result<()> {
    let params = TextureParams {
        views: 2,
        frames,
        width,
        height,
        period,
        seed,
        rig,
        ..TextureParams::default()
    };
    let scene = TextureScene::new(params).map_err(anyhow::Error::msg)?;
    let input = format!("synth {width}x{height} s{seed} {rig:?}");
    let t0 = Instant::now();
    let views: Vec<Vec<RgbImage>> = (0..2)
        .map(|v| (0..frames).map(|f| scene.frame(v, f)).collect())
        .collect();
    eprintln!(
        "{input}: rendered {} frames in {:.1?}",
        2 * frames,
        t0.elapsed()
    );
    let loops = LoopParams {
        window: 3,
        min_length: period,
    };
    let results = view_checks(t, &input, &views, &loops)?;

    // Homographies from the marked points (exact projections), 6 and 4 of them.
    let pts = |v: usize| {
        scene
            .points(v)
            .into_iter()
            .map(|(x, y)| Point::new(x, y))
            .collect::<Vec<_>>()
    };
    let (p0, p1) = (pts(0), pts(1));
    let truth = scene.plane_homography(0.0, 1.0);
    homography_agreement(t, &format!("{input} 6 marks"), &p0, &p1, Some(&truth));
    homography_agreement(
        t,
        &format!("{input} 4 marks"),
        &p0[..4],
        &p1[..4],
        Some(&truth),
    );
    let h = Homography::from_correspondences(&p0, &p1)?.homography;

    // Colour warps of frame 0 of view 0 into view 1.
    let f = &views[0][0];
    check_warp_bilinear(t, &format!("{input} frame 0"), f, &h, width, height)?;
    let vt_nn = vt_core::warp::warp_rgb(f, &h, width, height, Interpolation::Nearest);
    let cv_nn = vt_cv::warp::warp_rgb(f, &h, width, height, Interpolation::Nearest)?;
    check_identical_rgb(
        t,
        "warp RGB nearest",
        &format!("{input} frame 0"),
        &vt_nn,
        &cv_nn,
    );

    transition_checks(
        t,
        &format!("{input} 0->1"),
        &results[0].0,
        &results[1].0,
        &h,
        &results[1].1,
        loops.window,
    )?;
    transition_checks(
        t,
        &format!("{input} 1->0"),
        &results[1].0,
        &results[0].0,
        &h.inverse(),
        &results[0].1,
        loops.window,
    )?;
    Ok(())
}
