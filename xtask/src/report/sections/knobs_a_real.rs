//! System A's knobs that only real footage can judge: homography refinement, the appearance term
//! of eq. (1)-(2) and noise-model masks, on the real-footage scene (tree.avi on a slanted plane,
//! known homographies and clock offsets, 2 px marking noise). A transition is right when the
//! frame it continues with shows the same source frame playback would have reached.

use anyhow::Result;
use vt_core::analysis::{AnalyzeParams, SceneAnalysis};
use vt_core::model::{ModelParams, MotionModel};
use vt_core::noise::NoiseParams;

use super::knobs_a::circ;
use super::Knob;
use crate::report::data::{build_scene, real, Real};
use crate::report::model::{Axis, Better, Curve, Setting};
use crate::report::Ctx;

/// The real-footage knobs, in page order.
pub fn knobs() -> Vec<Knob> {
    vec![
        Knob::new(
            "Registration: automatic vs marked points vs OpenCV",
            registration,
        ),
        Knob::new("Homography from points vs refined", homography_refine),
        Knob::new("Appearance weight in eq. (1) and (2)", appearance),
        Knob::new("Window w on real footage", window),
        Knob::new("Noise-model masks", noise_masks),
        Knob::new("Loops on footage that never repeats", loop_options),
        Knob::new("Switch fade between views", switch_fade),
        Knob::new("Object store quality", store_quality),
    ]
}

const SCENE: &str = "the real-footage scene (tree.avi, 68 real frames looped, as 3 views of a \
slanted plane with known homographies and clock offsets, 2 px marking noise; 5 views in the full \
report)";

/// Analyses the real scene with `params` through `vt analyze`'s sequence: (analysis, seconds,
/// the seam score measured on rendered frames).
fn run(
    ctx: &mut Ctx,
    r: &Real,
    params: &AnalyzeParams,
    tag: &str,
) -> Result<(SceneAnalysis, f64, f64)> {
    let mut params = *params;
    params.loops.min_length = r.frames[0].len() / 3;
    let dir = ctx.work.path().join(format!("real-{tag}"));
    let (a, secs, loaded) = build_scene(&r.frames, &r.points, &params, &dir)?;
    std::fs::remove_dir_all(&dir).ok();
    Ok((a, secs, loaded.file.seam_score))
}

/// (mean transition error in source frames, share within +-1) over the frames on each loop.
fn transition_errors(r: &Real, a: &SceneAnalysis) -> (f64, f64) {
    let usable = r.scene.usable();
    let (mut sum, mut n, mut ok) = (0usize, 0usize, 0usize);
    for (p, link) in a.links.iter().enumerate() {
        for (from, to, table) in [(p, p + 1, &link.to_next), (p + 1, p, &link.to_prev)] {
            let l = &a.views[from].best_loop;
            for s in l.start + 1..=l.end {
                if let Some(t) = table[s] {
                    let e = circ(
                        r.scene.source_index(from, s + 1),
                        r.scene.source_index(to, t + 1),
                        usable,
                    );
                    sum += e;
                    ok += (e <= 1) as usize;
                    n += 1;
                }
            }
        }
    }
    (sum as f64 / n.max(1) as f64, ok as f64 / n.max(1) as f64)
}

fn corner_error(r: &Real, a: &SceneAnalysis) -> f64 {
    a.links
        .iter()
        .enumerate()
        .map(|(p, l)| r.scene.corner_error(p, p + 1, &l.homography.matrix()))
        .sum::<f64>()
        / a.links.len().max(1) as f64
}

/// Points as marked with `noise` px per coordinate: the scene's 2 px marks scaled about the truth.
fn points_with_noise(r: &Real, noise: f64) -> Vec<Vec<vt_core::Point>> {
    let scale = noise / r.scene.params().marking_noise;
    (0..r.points.len())
        .map(|p| {
            r.scene
                .true_points(p)
                .into_iter()
                .zip(&r.points[p])
                .map(|((x, y), m)| {
                    vt_core::Point::new(x + (m.x - x) * scale, y + (m.y - y) * scale)
                })
                .collect()
        })
        .collect()
}

fn registration(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let r = real(ctx)?;
    let base = crate::report::data::thesis_params();
    let mut params = base;
    params.loops.min_length = r.frames[0].len() / 3;
    let mut pts = Vec::new();
    // Without a points file: the default when none is given.
    let dir = ctx.work.path().join("real-auto");
    let (auto, _, _) = build_scene(&r.frames, &[], &params, &dir)?;
    std::fs::remove_dir_all(&dir).ok();
    let (err, within) = transition_errors(&r, &auto);
    pts.push(
        Setting::new(
            "automatic (no points file)",
            auto.timings.homographies.as_secs_f64() * 1e3,
            corner_error(&r, &auto),
            true,
        )
        .with("transition error (frames)", err)
        .with("transitions within +-1 (%)", 100.0 * within),
    );
    for noise in ctx.pick(vec![0.0, 2.0], vec![0.0, 1.0, 2.0, 4.0]) {
        let points = points_with_noise(&r, noise);
        let dir = ctx.work.path().join(format!("real-marked-{noise}"));
        let (a, _, _) = build_scene(&r.frames, &points, &params, &dir)?;
        std::fs::remove_dir_all(&dir).ok();
        let (err, within) = transition_errors(&r, &a);
        pts.push(
            Setting::new(
                format!("marked, {noise} px noise"),
                a.timings.homographies.as_secs_f64() * 1e3,
                corner_error(&r, &a),
                false,
            )
            .with("transition error (frames)", err)
            .with("transitions within +-1 (%)", 100.0 * within),
        );
    }
    // OpenCV's ORB + RANSAC on the same median backgrounds (its first guess, unrefined).
    let t = std::time::Instant::now();
    let mut sum = 0.0;
    for p in 0..auto.views.len() - 1 {
        let cv = vt_cv::register::register_pair(
            &auto.views[p].background,
            &auto.views[p + 1].background,
            &base.register,
            (p, p + 1),
        )?;
        sum += r.scene.corner_error(p, p + 1, &cv.homography.matrix());
    }
    let cv_ms = t.elapsed().as_secs_f64() * 1e3;
    pts.push(Setting::new(
        "OpenCV ORB + RANSAC (backgrounds)",
        cv_ms,
        sum / (auto.views.len() - 1) as f64,
        false,
    ));
    Ok(vec![Curve::new(
        "a-registration",
        "Registration: automatic vs marked points vs OpenCV",
        format!(
            "How H(p,p+1) is found on {SCENE}: without a points file (features on the median \
             backgrounds, RANSAC, sub-pixel patches, GRIC on the inliers, photometric \
             refinement, and the moving object's own plane checked against its silhouettes), \
             from points marked with 0, 1, 2 and 4 px of noise per coordinate (0 and 2 in \
             the quick report; then refined as \
             usual), and OpenCV's ORB + brute-force Hamming + findHomography (RANSAC) on the \
             same backgrounds, unrefined. x: time of the registration, model and homography \
             stage (for OpenCV: its registration of every pair); y: the largest distance \
             between where the estimate and the true homography put the image corners, pixels, \
             mean over neighbour pairs."
        ),
        Axis::new("registration and homography stage (ms)", Better::Lower),
        Axis::log("corner error vs truth (px)", Better::Lower),
        pts,
    )])
}

fn homography_refine(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let r = real(ctx)?;
    let base = crate::report::data::thesis_params();
    let settings = [
        (
            "points, model by GRIC",
            AnalyzeParams {
                refine: false,
                ..base
            },
        ),
        (
            "points, homography",
            AnalyzeParams {
                refine: false,
                model: ModelParams {
                    force: Some(MotionModel::Homography),
                    ..base.model
                },
                ..base
            },
        ),
        (
            "refined from backgrounds",
            AnalyzeParams {
                refine: true,
                ..base
            },
        ),
    ];
    let mut pts = Vec::new();
    for (i, (label, params)) in settings.iter().enumerate() {
        let (a, ..) = run(ctx, &r, params, &format!("refine-{i}"))?;
        let (err, within) = transition_errors(&r, &a);
        pts.push(
            Setting::new(
                *label,
                a.timings.homographies.as_secs_f64() * 1e3,
                corner_error(&r, &a),
                params.refine == base.refine && params.model == base.model,
            )
            .with("transition error (frames)", err)
            .with("transitions within +-1 (%)", 100.0 * within)
            .with(
                "links whose refinement was kept",
                a.links
                    .iter()
                    .filter(|l| l.refinement.is_some_and(|r| r.kept))
                    .count() as f64,
            ),
        );
    }
    Ok(vec![Curve::new(
        "a-refine",
        "Homography from points vs refined",
        format!(
            "H(p,p+1) fitted to the marked points (the model GRIC picks, or a homography forced) \
             or refined by aligning the two median backgrounds, on {SCENE}. x: time of the model \
             and homography stage; y: the largest distance between where the estimate and the \
             true homography put the image corners, pixels, mean over neighbour pairs. A \
             refinement is kept only where it lowers the photometric error and still agrees \
             with the points (the table says how many links kept theirs)."
        ),
        Axis::new("homography stage (ms)", Better::Lower),
        Axis::log("corner error vs truth (px)", Better::Lower),
        pts,
    )])
}

fn appearance(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let r = real(ctx)?;
    let base = crate::report::data::thesis_params();
    let weights: Vec<f32> = ctx.pick(vec![0.0, 1.0, 4.0], vec![0.0, 0.25, 0.5, 1.0, 2.0, 4.0]);
    let mut pts = Vec::new();
    for (i, &w) in weights.iter().enumerate() {
        let params = AnalyzeParams {
            appearance: w,
            ..base
        };
        let (a, ..) = run(ctx, &r, &params, &format!("appearance-{i}"))?;
        let (err, within) = transition_errors(&r, &a);
        let t = a.timings.loops + a.timings.transitions;
        pts.push(
            Setting::new(
                format!("{w}"),
                t.as_secs_f64() * 1e3,
                err,
                w == base.appearance,
            )
            .with("transitions within +-1 (%)", 100.0 * within),
        );
    }
    Ok(vec![Curve::new(
        "a-appearance",
        "Appearance weight in eq. (1) and (2)",
        format!(
            "Weight of the appearance term added to the mask XOR cost of the loop and transition \
             searches (0 = masks only, the thesis), on {SCENE}. x: loop + transition search time; \
             y: mean transition error in source frames over the frames on each loop."
        ),
        Axis::new("loop + transition search (ms)", Better::Lower),
        Axis::new("transition error (frames)", Better::Lower),
        pts,
    )])
}

fn noise_masks(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let r = real(ctx)?;
    let base = crate::report::data::thesis_params();
    let settings = [
        ("off (global threshold)", NoiseParams::off()),
        (
            "noise model, no dynamic region",
            NoiseParams {
                dynamic: false,
                ..NoiseParams::default()
            },
        ),
        ("noise model + dynamic region", NoiseParams::default()),
    ];
    let mut pts = Vec::new();
    for (i, (label, noise)) in settings.iter().enumerate() {
        let params = AnalyzeParams {
            noise: *noise,
            ..base
        };
        let (a, ..) = run(ctx, &r, &params, &format!("noise-{i}"))?;
        let (err, within) = transition_errors(&r, &a);
        pts.push(
            Setting::new(
                *label,
                a.timings.masks.as_secs_f64() * 1e3,
                err,
                *noise == base.noise,
            )
            .with("transitions within +-1 (%)", 100.0 * within),
        );
    }
    Ok(vec![Curve::new(
        "a-noise",
        "Noise-model masks",
        format!(
            "Moving-object masks by the global threshold (the thesis) or by a per-pixel noise \
             model, with or without the dynamic region, on {SCENE}. x: mask stage time; y: mean \
             transition error in source frames over the frames on each loop."
        ),
        Axis::new("mask stage (ms)", Better::Lower),
        Axis::new("transition error (frames)", Better::Lower),
        pts,
    )])
}

/// Window w of eq. (1) and (2) where it matters: real footage never repeats exactly, so the
/// window decides how much of the motion around a jump must agree.
fn window(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let r = real(ctx)?;
    // Each window is a scene analysed, twice over (the real-footage scene and tree.avi).
    let windows: Vec<usize> = ctx.pick(vec![1, 3, 8], vec![1, 2, 3, 4, 5, 6, 8, 10]);
    let base = crate::report::data::thesis_params();
    let mut pts = Vec::new();
    for &win in &windows {
        let mut params = base;
        params.loops.window = win;
        let (a, _, seam) = run(ctx, &r, &params, &format!("window-{win}"))?;
        let (err, within) = transition_errors(&r, &a);
        let search = a.timings.loops + a.timings.transitions;
        pts.push(
            Setting::new(
                format!("w {win}"),
                search.as_secs_f64() * 1e3,
                err,
                win == base.loops.window,
            )
            .with("seam score (rendered jump / ordinary step)", seam)
            .with("transitions within +-1 (%)", 100.0 * within),
        );
    }
    // Footage with no exact repeat: tree.avi's hand-free frames as one view, where the window
    // decides which near-repeat becomes the wrap.
    let tr = crate::report::data::tree(ctx)?;
    let clip = vec![tr.frames[..54.min(tr.frames.len())].to_vec()];
    let mut single = Vec::new();
    for &win in &windows {
        let mut params = base;
        params.loops.window = win;
        params.loops.min_length = 20;
        let dir = ctx.work.path().join(format!("tree-window-{win}"));
        let (a, _, loaded) = build_scene(&clip, &[], &params, &dir)?;
        std::fs::remove_dir_all(&dir).ok();
        let l = a.views[0].best_loop;
        single.push(
            Setting::new(
                format!("w {win}"),
                a.timings.loops.as_secs_f64() * 1e3,
                loaded.file.seam_score,
                win == base.loops.window,
            )
            .with("loop start m", l.start as f64)
            .with("loop end n", l.end as f64),
        );
    }
    Ok(vec![
        Curve::new(
            "a-window-tree",
            "Window w of eq. (1) on footage that never repeats",
            "The loop search with window w on tree.avi's 54 hand-free frames as one view \
             (a real tree in wind: no exact repeat; minimum length 20). x: loop search time; y: \
             the seam score `vt analyze` prints, the wrap's rendered step over the median \
             ordinary step (1 = as large as an ordinary step). Default w = 3."
                .to_string(),
            Axis::new("loop search (ms)", Better::Lower),
            Axis::new("seam score (rendered wrap / ordinary step)", Better::Lower),
            single,
        ),
        Curve::new(
            "a-window-real",
            "Window w of eq. (1) and (2) on real footage",
            format!(
                "The loop and transition searches with window w on {SCENE} (its 68 source \
             frames repeat, so every w finds an exact loop; the transitions carry the marking \
             noise: with 3 short views w 8 was best, with 5 longer ones every w is alike). x: loop + transition \
             search time; y: mean transition error in source frames over the frames on each \
             loop; also the seam score `vt analyze` prints (each wrap's rendered step over the \
             median ordinary step, each switch's over the steps it replaced). Default w = 3 \
             (the thesis)."
            ),
            Axis::new("loop + transition search (ms)", Better::Lower),
            Axis::new("transition error (frames)", Better::Lower),
            pts,
        ),
    ])
}

/// Each loop option on footage with no exact repeat, measured on the frames it bakes and on the
/// frames `vt render` shows: the thesis's one loop per view, per-region loops, and per-region
/// loops with the wrap correction at two low-pass widths.
fn loop_options(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    use vt_core::regions::{quality, single_frames, single_loop, Label, Quality, RegionParams};
    let options: Vec<(&str, Option<RegionParams>)> = vec![
        ("thesis: one loop (m, n) per view (--loops single)", None),
        (
            "regions where they measure better, else the thesis's (--loops auto)",
            Some(RegionParams {
                only_if_better: true,
                ..Default::default()
            }),
        ),
        (
            "regions, no wrap correction",
            Some(RegionParams {
                blend: None,
                ..Default::default()
            }),
        ),
        (
            "regions + wrap correction, sigma 0 (--loops regions)",
            Some(RegionParams::default()),
        ),
        (
            "regions + wrap correction over whole cycles (--region-spread 0)",
            Some(RegionParams {
                spread: 0.0,
                ..Default::default()
            }),
        ),
        (
            "regions + wrap correction, spread 0.25 ordinary steps a frame",
            Some(RegionParams {
                spread: 0.25,
                ..Default::default()
            }),
        ),
        (
            "regions + wrap correction, sigma 2",
            Some(RegionParams {
                blend: Some(2.0),
                ..Default::default()
            }),
        ),
    ];
    // Quick: the thesis, the default and `--loops regions` (three points a curve).
    let options: Vec<_> = if ctx.quick {
        options
            .into_iter()
            .enumerate()
            .filter(|(i, _)| matches!(i, 0 | 1 | 3))
            .map(|(_, o)| o)
            .collect()
    } else {
        options
    };
    let default = AnalyzeParams::default().regions;
    let tr = crate::report::data::tree(ctx)?;
    let tree_clip = vec![tr.frames[..54.min(tr.frames.len())].to_vec()];
    let r = real(ctx)?;
    let mut curves = Vec::new();
    for (id, title, frames, points, min_length, what) in [
        (
            "a-loops-tree",
            "Loop options on tree.avi (one view)",
            &tree_clip,
            &Vec::new(),
            20,
            "tree.avi's 54 hand-free frames as one view (minimum length 20)".to_string(),
        ),
        (
            "a-loops-real",
            "Loop options on the real-footage scene",
            &r.frames,
            &r.points,
            r.frames[0].len() / 3,
            format!(
                "{SCENE} (minimum length a third of the clip; its source repeats exactly every 68 \
                 frames, so every option finds that repeat and the correction has nothing to \
                 spread)"
            ),
        ),
    ] {
        let mut pts = Vec::new();
        for (i, (label, regions)) in options.iter().enumerate() {
            let mut params = AnalyzeParams {
                regions: *regions,
                ..Default::default()
            };
            params.loops.min_length = min_length;
            let dir = ctx.work.path().join(format!("{id}-{i}"));
            let (a, secs, loaded) = build_scene(frames, points, &params, &dir)?;
            std::fs::remove_dir_all(&dir).ok();
            // The baked loop's own measures; the thesis's loop measured the same way.
            let qs: Vec<Quality> = a
                .views
                .iter()
                .enumerate()
                .map(|(p, v)| match (&v.region_loop, &v.region_rejected) {
                    (Some(res), _) => res.quality,
                    (None, Some(res)) => res.single,
                    (None, None) => {
                        let src = &frames[p];
                        let (w, h) = src[0].dimensions();
                        let one = single_loop(
                            Label {
                                start: v.best_loop.start + 1,
                                period: v.best_loop.len(),
                            },
                            (w, h),
                            RegionParams::default().tile,
                        );
                        quality(
                            &single_frames(src, &one),
                            src,
                            &one,
                            v.dynamic_alpha.as_ref(),
                        )
                    }
                })
                .collect();
            let max = |f: fn(&Quality) -> f64| qs.iter().map(f).fold(0.0, f64::max);
            let min = |f: fn(&Quality) -> f64| qs.iter().map(f).fold(f64::INFINITY, f64::min);
            let views = &loaded.file.views;
            let wrap = views.iter().map(|v| v.loop_seam).fold(0.0, f64::max);
            let switch = views
                .iter()
                .filter_map(|v| v.to_next.as_ref().map(|l| l.seam))
                .fold(f64::NAN, f64::max);
            pts.push(
                Setting::new(*label, secs, loaded.file.seam_score, *regions == default)
                    .with("rendered wrap, worst view (x median step)", wrap)
                    .with(
                        "rendered switch, worst link (x the steps it replaced)",
                        switch,
                    )
                    .with(
                        "worst step of the loop (x its median step)",
                        max(|q| q.worst_step),
                    )
                    .with(
                        "tile wraps, median (x the tile's median step)",
                        max(|q| q.tile_wrap),
                    )
                    .with("tile wraps, 90th percentile", max(|q| q.tile_wrap_p90))
                    .with(
                        "sharpness near the wraps (of the source's)",
                        min(|q| q.sharpness_near),
                    )
                    .with(
                        "sharpness, all frames (of the source's)",
                        min(|q| q.sharpness),
                    )
                    .with(
                        "error to the nearest source frame (grey levels)",
                        max(|q| q.source_error),
                    ),
            );
        }
        curves.push(Curve::new(
            id,
            title,
            format!(
                "The loop options on {what}. x: vt-core's analysis time (s); y: the seam score \
                 `vt analyze` prints (mean of each wrap's rendered step over the median ordinary \
                 rendered step and each switch's, through its fade, over the steps it replaced; \
                 1 = no larger than ordinary playback). The table: the \
                 worst rendered wrap and switch; on the loop's own frames inside the dynamic \
                 region (the thesis's loop baked the same way): the worst frame step over the \
                 median (a loop of real footage has its own uneven steps: tree.avi's 53 source \
                 steps reach 1.48x their median), each 16 px tile's wrap step over the tile's \
                 median ordinary step (the thesis's loop wraps every tile at once), the gradient \
                 energy from one frame before to two after each tile's wrap over the tile's \
                 source frames' (a crossfade ghosts and loses it), and the mean error to the \
                 nearest source frame (among those the tile and its neighbours show). Worst view \
                 for each figure."
            ),
            Axis::new("analysis (s)", Better::Lower),
            Axis::new("seam score (rendered jump / ordinary step)", Better::Lower),
            pts,
        ));
    }
    Ok(curves)
}

/// The switch fade's length on the real-footage scene, registered automatically (the default):
/// each link's switches both ways, measured as `vt analyze` measures them (the rendered steps
/// through the switch and its fade over the ones the old view would have shown), the sharpness
/// of the blended frames, and what a sweep across the views costs to render.
fn switch_fade(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    use vt_core::render::{RenderParams, DEFAULT_SWITCH_FADE};
    let r = real(ctx)?;
    let mut params = AnalyzeParams::default();
    params.loops.min_length = r.frames[0].len() / 3;
    let dir = ctx.work.path().join("real-switch-fade");
    let (_, _, scene) = build_scene(&r.frames, &[], &params, &dir)?;
    let samples = ctx.pick(6, 16);
    let q_max = scene.render.q_max();
    let sweep = ctx.pick(120, 400);
    // Slowly across all views and back: 2 (M - 1) switches.
    let qs: Vec<f64> = (0..sweep)
        .map(|i| q_max * (0.5 - 0.5 * (i as f64 / sweep as f64 * std::f64::consts::TAU).cos()))
        .collect();
    let mut pts = Vec::new();
    for fade in ctx.pick(vec![0, 2, 4], vec![0, 1, 2, 3, 4, 6]) {
        let rp = RenderParams {
            switch_fade: fade,
            ..RenderParams::default()
        };
        let f = vt_core::seam::measure_switch_fades(&scene.render, &scene.objects, rp, samples)?;
        let t = std::time::Instant::now();
        let played = vt_app::play::play(&scene, &qs, rp, &mut |f, _| -> vt_app::Result<()> {
            std::hint::black_box(f);
            Ok(())
        })?;
        let ms = (t.elapsed().as_secs_f64() - played.measure_secs) * 1e3 / sweep as f64;
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let mut sharp = f.sharpness.clone();
        sharp.sort_by(f64::total_cmp);
        let label = match fade {
            0 => "0: a hard switch (the thesis)".to_string(),
            k => format!("{k} frames"),
        };
        let mut s = Setting::new(label, ms, mean(&f.seams), fade == DEFAULT_SWITCH_FADE).with(
            "worst link direction (x replaced steps)",
            f.seams.iter().copied().fold(0.0, f64::max),
        );
        if !sharp.is_empty() {
            s = s
                .with("sharpness of the blended frames, mean", mean(&sharp))
                .with(
                    "sharpness, 10th percentile",
                    sharp[(sharp.len() / 10).min(sharp.len() - 1)],
                );
        }
        pts.push(s.with(
            "sweep seam score, wraps included (vt render's)",
            played.mean_seam.unwrap_or(f64::NAN),
        ));
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(vec![Curve::new(
        "a-switch-fade",
        "Switch fade between views",
        format!(
            "How many frames a view switch fades over, on {SCENE}, registered automatically \
             (no points file, the default). A switch goes to the frame eq. (2) matches, so \
             the two views show the same moment and differ only where the views disagree \
             (resampling, registration, exposure); a hard switch shows that difference at \
             once. x: ms per rendered frame over a slow sweep across all views and back (a \
             faded frame composites two layers); y: mean switch seam over every link both \
             ways, the rendered steps through the switch and its fade over the steps the old \
             view would have shown over the same frames (1: the switch adds nothing to \
             ordinary playback). Sharpness: each blended frame's gradient energy over the \
             blend of its two layers' own (1: blending loses no detail). Default \
             {DEFAULT_SWITCH_FADE} frames."
        ),
        Axis::new("render (ms per frame, sweep)", Better::Lower),
        Axis::new("switch seam (x the steps replaced)", Better::Lower),
        pts,
    )])
}

/// The object store's quality: each setting's scene against the lossless store's, the same
/// analysis (loops and tables do not depend on the store), rendered at the same frames.
fn store_quality(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    use vt_io::objects::StoreQuality;
    let r = real(ctx)?;
    let mut params = AnalyzeParams::default();
    params.loops.min_length = r.frames[0].len() / 3;
    let store_bytes = |dir: &std::path::Path| -> u64 {
        (0..r.frames.len())
            .map(|p| {
                std::fs::metadata(dir.join(vt_io::scene::objects_name(p))).map_or(0, |m| m.len())
            })
            .sum()
    };
    // Frames of every view at its own viewpoint and at the ties, spread over the loops.
    let renders = |scene: &vt_io::scene::LoadedScene| -> Result<Vec<image::RgbImage>> {
        let mut renderer = vt_core::render::Renderer::new(
            scene.render.clone(),
            vt_core::render::RenderParams::default(),
        )?;
        let (w, h) = renderer.size();
        let mut out = Vec::new();
        for (p, v) in scene.render.views.iter().enumerate() {
            for q in [p as f64, p as f64 + 0.5] {
                if q > scene.render.q_max() {
                    continue;
                }
                for k in 0..4 {
                    let f = v.loop_start + 1 + k * (v.loop_end - v.loop_start).max(1) / 4;
                    let mut img = image::RgbImage::new(w, h);
                    renderer.render_plain_into(&scene.objects, q, p, f, &mut img)?;
                    out.push(img);
                }
            }
        }
        Ok(out)
    };
    let build = |ctx: &mut Ctx,
                 quality: StoreQuality|
     -> Result<(f64, u64, Vec<image::RgbImage>, String)> {
        let dir = ctx.work.path().join(format!("real-store-{quality}"));
        std::fs::remove_dir_all(&dir).ok();
        let t = std::time::Instant::now();
        crate::report::data::analyze_frames_with(&r.frames, &[], &params, &dir, quality)?;
        let secs = t.elapsed().as_secs_f64();
        let scene = vt_io::scene::LoadedScene::open(&dir)?;
        let chosen: Vec<String> = scene
            .objects
            .stores
            .iter()
            .map(|s| s.quality().to_string())
            .collect();
        let frames = renders(&scene)?;
        let bytes = store_bytes(&dir);
        drop(scene);
        std::fs::remove_dir_all(&dir).ok();
        Ok((secs, bytes, frames, chosen.join(" ")))
    };
    let (_, lossless_bytes, reference, _) = build(ctx, StoreQuality::Lossless)?;
    let mut pts = Vec::new();
    let settings: Vec<StoreQuality> = ctx
        .pick(
            vec!["12", "35db", "40db"],
            vec![
                "12", "14", "16", "18", "20", "24", "35db", "38db", "40db", "42db", "45db",
            ],
        )
        .into_iter()
        .map(|q| q.parse().expect("a store quality"))
        .collect();
    for quality in settings {
        let (secs, bytes, frames, chosen) = build(ctx, quality)?;
        let mut worst = f64::INFINITY;
        let mut se = 0.0;
        for (a, b) in frames.iter().zip(&reference) {
            let p = vt_core::metrics::psnr(a, b, None)?;
            worst = worst.min(p);
            se += 10f64.powf(-p / 10.0);
        }
        let mean = -10.0 * (se / frames.len().max(1) as f64).log10();
        let label = match quality {
            StoreQuality::Target { .. } => format!("{quality} (quantisers {chosen})"),
            q => format!("quantiser {q}"),
        };
        pts.push(
            Setting::new(
                label,
                bytes as f64 / 1e6,
                mean,
                quality == StoreQuality::default(),
            )
            .with("worst rendered frame (dB)", worst)
            .with(
                "bytes against the lossless store's",
                bytes as f64 / lossless_bytes.max(1) as f64,
            )
            .with("analysis, store included (s)", secs),
        );
    }
    Ok(vec![Curve::new(
        "a-store-quality",
        "Object store quality",
        format!(
            "How the moving-object stores keep the pixels, on {SCENE}, registered \
             automatically: x: the stores' bytes (MB); y: PSNR of rendered frames (every view at \
             its own viewpoint and at the ties, four frames along each loop) against the same \
             frames rendered from the lossless store, from the mean squared error. A fixed \
             quantiser keeps every frame at one quantiser; a target (the default, {}) \
             stores each view's first 8 frames at quantiser 16 in memory and takes the \
             coarsest quantiser predicted to keep that PSNR under the masks.",
            StoreQuality::default()
        ),
        Axis::new("object stores (MB)", Better::Lower),
        Axis::new("renders against the lossless store's (dB)", Better::Higher),
        pts,
    )])
}
