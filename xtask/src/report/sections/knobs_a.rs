//! System A's knobs, each one function returning its curve: settings timed on this machine and
//! scored against the synthetic scene's truth (vt-synth's ray caster: true backgrounds, true
//! object masks, true motion phases, true renders). To add a knob, write a function here and
//! list it in [`knobs`].

use anyhow::Result;
use image::RgbImage;
use vt_core::analysis::{foreground_mask, median_frame_indices, threshold_mask, MaskParams};
use vt_core::blur::{gaussian_blur, GaussianParams};
use vt_core::loops::{find_loop, LoopParams};
use vt_core::mask::xor_count;
use vt_core::median::temporal_median;
use vt_core::metrics::{mean_abs_diff, psnr};
use vt_core::render::{Player, RenderParams, Renderer, Step};
use vt_core::transition::{transition_table, warp_masks};
use vt_core::warp::Interpolation;
use vt_core::Mask;

use super::Knob;
use crate::report::data::{synth_a, tree, SynthA};
use crate::report::model::{Axis, Better, Curve, Setting};
use crate::report::{timed, Ctx};

/// System A's knobs, in page order.
pub fn knobs() -> Vec<Knob> {
    vec![
        Knob::new(
            "Median background: exact vs frame subsampling",
            median_subsampling,
        ),
        Knob::new("Blur kernel size", blur_size),
        Knob::new("Mask threshold", mask_threshold),
        Knob::new("Window w of eq. (1) and (2)", window),
        Knob::new("Loop search at reduced mask resolution", mask_resolution),
        Knob::new(
            "Loop search at reduced mask resolution, real footage",
            mask_resolution_real,
        ),
        Knob::new(
            "Rendering: interpolation, gain compensation, neighbour fill",
            render_modes,
        ),
        Knob::new("Crossfade and dissolve length", crossfade),
    ]
}

const SCENE: &str = "the synthetic 3-view scene of `vt demo` (vt-synth, 320x180, period 24, \
sensor noise 2 grey levels, per-view exposure up to 4 %)";

/// Circular distance between two phases.
pub fn circ(a: usize, b: usize, period: usize) -> usize {
    let d = a.abs_diff(b) % period;
    d.min(period - d)
}

/// (recall, false positives as a fraction of the true background, disagreement as a fraction of
/// the true object) of `got` against `truth`.
fn mask_scores(got: &Mask, truth: &Mask) -> (u64, u64, u64, u64) {
    let (g, t) = (got.count_ones(), truth.count_ones());
    let x = xor_count(got, truth);
    let both = (g + t - x) / 2;
    let fp = g - both;
    (both, fp, t, x)
}

/// Frames of view 0 used for mask knobs: every other frame, at most 48.
fn mask_frames(sa: &SynthA) -> Vec<usize> {
    (0..sa.frames[0].len()).step_by(2).take(48).collect()
}

fn median_subsampling(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let counts: Vec<usize> = ctx.pick(vec![8, 32, 128, 0], vec![4, 8, 16, 32, 64, 128, 0]);
    let views = sa.frames.len();
    let truth: Vec<RgbImage> = (0..views).map(|p| sa.background_as_recorded(p)).collect();
    let n = sa.frames[0].len();
    let mut pts = Vec::new();
    for &k in &counts {
        let (mut secs, mut err) = (0.0, 0.0);
        for p in 0..views {
            let picked = median_frame_indices(sa.frames[p].len(), k);
            let (t, bg) = timed(ctx.pick(1, 3), || {
                temporal_median(picked.iter().map(|&i| &sa.frames[p][i]))
            });
            secs += t;
            err += mean_abs_diff(&bg?, &truth[p], None)?;
        }
        let used = median_frame_indices(n, k).len();
        let label = if k == 0 {
            "every frame".to_string()
        } else {
            format!("{k} frames")
        };
        pts.push(
            Setting::new(
                label,
                secs * 1e3,
                err / views as f64,
                k == vt_core::analysis::DEFAULT_MEDIAN_FRAMES,
            )
            .with("frames per view", used as f64),
        );
    }
    Ok(vec![Curve::new(
        "a-median",
        "Median background: every frame vs evenly spaced frames (--median-frames)",
        format!(
            "Per-pixel temporal median of K evenly spaced frames of each view (the middle frame \
             of each of K equal spans, vt_core::analysis::median_frame_indices, as `vt analyze \
             --median-frames K` picks them; 'every frame' is 0, the thesis), all views of \
             {SCENE} ({n} frames per view, so K >= {n} is every frame). x: time for the \
             backgrounds; y: mean absolute difference from the true background (ray cast \
             without the object, the view's exposure applied), grey levels. Default K = {}. The \
             performance section measures the default against every frame on real footage at \
             full size.",
            vt_core::analysis::DEFAULT_MEDIAN_FRAMES
        ),
        Axis::new("median time (ms)", Better::Lower),
        Axis::new("background error (grey levels)", Better::Lower),
        pts,
    )])
}

fn blur_size(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let sizes: Vec<usize> = ctx.pick(vec![1, 3, 5, 9, 15], vec![1, 3, 5, 7, 9, 11, 15, 21]);
    let frames = mask_frames(&sa);
    let bg = &sa.analysis.views[0].background;
    let mut pts = Vec::new();
    for &k in &sizes {
        let params = GaussianParams {
            ksize: k,
            sigma: 0.0,
        };
        let bgb = gaussian_blur(bg, &params)?;
        let (mut secs, mut both, mut fp, mut truth, mut xor) = (0.0, 0, 0, 0, 0);
        let mut n_bg = 0u64;
        for &s in &frames {
            let (t, m) = timed(1, || -> Result<Mask> {
                let fb = gaussian_blur(&sa.frames[0][s], &params)?;
                Ok(foreground_mask(&fb, &bgb, &MaskParams::default())?)
            });
            secs += t;
            let tm = sa.truth_mask(0, s);
            let (b, f, tt, x) = mask_scores(&m?, tm);
            both += b;
            fp += f;
            truth += tt;
            xor += x;
            n_bg += tm.len() as u64 - tt;
        }
        let n = frames.len() as f64;
        pts.push(
            Setting::new(
                format!("ksize {k}"),
                secs * 1e3 / n,
                100.0 * xor as f64 / truth as f64,
                k == GaussianParams::default().ksize,
            )
            .with("motion kept (%)", 100.0 * both as f64 / truth as f64)
            .with(
                "false positives (% of background)",
                100.0 * fp as f64 / n_bg as f64,
            ),
        );
    }
    Ok(vec![Curve::new(
        "a-blur",
        "Blur kernel size",
        format!(
            "Gaussian smoothing of frame and background before subtraction (OpenCV's kernel, \
             sigma from ksize), threshold 25, on {} frames of view 0 of {SCENE}. x: blur + \
             subtraction time per frame; y: pixels where the mask disagrees with the true object \
             mask (object pixels changed by more than {} levels in the noise-free render), as % \
             of the true object's pixels. Default: 3x3 (the thesis).",
            frames.len(),
            crate::report::data::TRUTH_MASK_LEVELS
        ),
        Axis::new("time per frame (ms)", Better::Lower),
        Axis::new("mask error (% of object pixels)", Better::Lower),
        pts,
    )])
}

fn mask_threshold(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let thresholds: Vec<u8> = ctx.pick(
        vec![5, 10, 15, 25, 40, 60],
        vec![4, 6, 8, 10, 15, 20, 25, 30, 40, 50, 60, 80],
    );
    let frames = mask_frames(&sa);
    let params = GaussianParams::default();
    let bgb = gaussian_blur(&sa.analysis.views[0].background, &params)?;
    let blurred: Vec<RgbImage> = frames
        .iter()
        .map(|&s| gaussian_blur(&sa.frames[0][s], &params))
        .collect::<Result<_, _>>()?;
    let mut pts = Vec::new();
    for &th in &thresholds {
        let (mut both, mut fp, mut truth, mut n_bg, mut secs) = (0u64, 0u64, 0u64, 0u64, 0.0);
        for (fb, &s) in blurred.iter().zip(&frames) {
            let (t, m) = timed(1, || threshold_mask(fb, &bgb, th));
            secs += t;
            let tm = sa.truth_mask(0, s);
            let (b, f, tt, _) = mask_scores(&m?, tm);
            both += b;
            fp += f;
            truth += tt;
            n_bg += tm.len() as u64 - tt;
        }
        pts.push(
            Setting::new(
                format!("T {th}"),
                100.0 * fp as f64 / n_bg as f64,
                100.0 * both as f64 / truth as f64,
                th == MaskParams::default().threshold,
            )
            .with("time per frame (ms)", secs * 1e3 / frames.len() as f64),
        );
    }
    Ok(vec![Curve::new(
        "a-threshold",
        "Mask threshold T",
        format!(
            "Background subtraction threshold (max over RGB of |frame - background| > T, both \
             3x3-smoothed) on {} frames of view 0 of {SCENE}. The threshold costs no time, so this \
             plot trades the two errors instead: x: false positives (% of true background pixels \
             marked moving, sensor noise and exposure); y: motion kept (% of true object pixels \
             marked). Up and left is better. Default T = 25.",
            frames.len()
        ),
        Axis::log("false positives (% of background)", Better::Lower),
        Axis::new("motion kept (% of object)", Better::Higher),
        pts,
    )])
}

/// The forward and backward transition tables of one neighbour pair.
pub type TablePair = (Vec<Option<usize>>, Vec<Option<usize>>);

/// Mean phase error (frames) of the transitions p -> p+1 and back over the frames on each loop,
/// and the share within +-1 frame.
pub fn transition_phase_errors(
    sa: &SynthA,
    loops: &[(usize, usize)],
    tables: &[TablePair],
) -> (f64, f64) {
    let period = sa.scene.params().period;
    let (mut sum, mut n, mut within) = (0usize, 0usize, 0usize);
    for (p, (fwd, back)) in tables.iter().enumerate() {
        for (from, to, table) in [(p, p + 1, fwd), (p + 1, p, back)] {
            let (m, end) = loops[from];
            for s in m + 1..=end {
                if let Some(t) = table[s] {
                    let e = circ(
                        sa.scene.phase_of(from, s + 1),
                        sa.scene.phase_of(to, t + 1),
                        period,
                    );
                    sum += e;
                    within += (e <= 1) as usize;
                    n += 1;
                }
            }
        }
    }
    (
        sum as f64 / n.max(1) as f64,
        within as f64 / n.max(1) as f64,
    )
}

/// Mean phase error (frames) of the loop wraps: frame n is followed by m + 1.
pub fn loop_phase_error(sa: &SynthA, loops: &[(usize, usize)]) -> f64 {
    let period = sa.scene.params().period;
    loops
        .iter()
        .enumerate()
        .map(|(p, &(m, n))| {
            circ(
                sa.scene.phase_of(p, n + 1),
                sa.scene.phase_of(p, m + 1),
                period,
            ) as f64
        })
        .sum::<f64>()
        / loops.len() as f64
}

fn window(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let windows: Vec<usize> = ctx.pick(vec![1, 2, 3, 5, 8], vec![1, 2, 3, 4, 5, 6, 8, 10]);
    let (w, h) = (sa.analysis.width, sa.analysis.height);
    let mut pts = Vec::new();
    for &win in &windows {
        let lp = LoopParams {
            window: win,
            ..sa.params.loops
        };
        let (secs, res) = timed(1, || -> Result<_> {
            let loops: Vec<(usize, usize)> = sa
                .analysis
                .views
                .iter()
                .enumerate()
                .map(|(p, v)| {
                    find_loop(&v.masks, &lp, &format!("view {p}")).map(|l| (l.start, l.end))
                })
                .collect::<Result<_, _>>()?;
            let mut tables = Vec::new();
            for (p, link) in sa.analysis.links.iter().enumerate() {
                let (a, b) = (&sa.analysis.views[p], &sa.analysis.views[p + 1]);
                let fwd = transition_table(
                    &warp_masks(&a.masks, &link.homography, w, h),
                    &b.masks,
                    loops[p + 1].1,
                    win,
                )?;
                let back = transition_table(
                    &warp_masks(&b.masks, &link.homography.inverse(), w, h),
                    &a.masks,
                    loops[p].1,
                    win,
                )?;
                tables.push((fwd, back));
            }
            Ok((loops, tables))
        });
        let (loops, tables) = res?;
        let (err, within) = transition_phase_errors(&sa, &loops, &tables);
        pts.push(
            Setting::new(
                format!("w {win}"),
                secs * 1e3,
                err,
                win == LoopParams::default().window,
            )
            .with("loop wrap error (frames)", loop_phase_error(&sa, &loops))
            .with("transitions within +-1 frame (%)", 100.0 * within),
        );
    }
    Ok(vec![Curve::new(
        "a-window",
        "Window w of eq. (1) and (2)",
        format!(
            "Loop search (eq. 1) of every view and both transition tables (eq. 2) of every \
             neighbour pair, on the masks of {SCENE}, with the window w. x: search time; y: mean \
             phase error of the transitions (frames; the true motion phase of the frame shown \
             after a switch against the phase playback would have reached), over the frames on \
             each loop. Default w = 3 (the thesis). The synthetic motion repeats exactly, so every \
             w finds the true phases here; the same knob on real footage has its own curve, \
             \"Window w of eq. (1) and (2) on real footage\"."
        ),
        Axis::new("loop + transition search (ms)", Better::Lower),
        Axis::new("transition phase error (frames)", Better::Lower),
        pts,
    )])
}

fn mask_resolution(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let factors: Vec<u32> = ctx.pick(vec![1, 2, 4, 8], vec![1, 2, 3, 4, 6, 8]);
    let (w, h) = (sa.analysis.width, sa.analysis.height);
    let blur = GaussianParams::default();
    let mut pts = Vec::new();
    for &f in &factors {
        let (sw, sh) = (w.div_ceil(f), h.div_ceil(f));
        let small = |img: &RgbImage| {
            if f == 1 {
                img.clone()
            } else {
                image::imageops::resize(img, sw, sh, image::imageops::FilterType::Triangle)
            }
        };
        let (mut secs, mut loops) = (0.0, Vec::new());
        for (p, v) in sa.analysis.views.iter().enumerate() {
            let bgb = gaussian_blur(&small(&v.background), &blur)?;
            let masks: Vec<Mask> = sa.frames[p]
                .iter()
                .map(|fr| -> Result<Mask> {
                    Ok(foreground_mask(
                        &gaussian_blur(&small(fr), &blur)?,
                        &bgb,
                        &MaskParams::default(),
                    )?)
                })
                .collect::<Result<_>>()?;
            let (t, l) = timed(ctx.pick(1, 3), || {
                find_loop(&masks, &sa.params.loops, "view")
            });
            secs += t;
            let l = l?;
            loops.push((l.start, l.end));
        }
        pts.push(
            Setting::new(
                format!("1/{f}"),
                secs * 1e3,
                loop_phase_error(&sa, &loops),
                f == 1,
            )
            .with("mask pixels", (sw * sh) as f64),
        );
    }
    Ok(vec![Curve::new(
        "a-mask-resolution",
        "Loop search at reduced mask resolution",
        format!(
            "Eq. (1) on masks computed from frames and background downscaled by 1/f (bilinear), \
             every view of {SCENE}. x: loop search time (all views, masks already made); y: mean \
             phase error of the loop wrap (frames; 0 = the loop is a whole number of motion \
             periods). vt searches at full resolution (the default); no reduced-resolution \
             option exists in the CLI yet, this curve says what one would buy."
        ),
        Axis::new("loop search time (ms)", Better::Lower),
        Axis::new("loop wrap phase error (frames)", Better::Lower),
        pts,
    )])
}

/// Render PSNR against the ray-cast truth at `qs` (each from a fresh player: the first frame of
/// the loop of the nearest view) and frames per second over a sweep.
fn render_figures(
    sa: &SynthA,
    params: RenderParams,
    qs: &[f64],
    sweep: usize,
) -> Result<(f64, f64)> {
    let scene = &sa.loaded;
    let mut renderer = Renderer::new(scene.render.clone(), params)?;
    let (w, h) = renderer.size();
    let mut out = RgbImage::new(w, h);
    let mut total = 0.0;
    for &q in qs {
        let choice = Player::new().advance(&scene.render, q)?;
        renderer.render_into(&scene.objects, q, &choice, &mut out)?;
        let truth = sa
            .scene
            .truth(q, sa.scene.phase_of(choice.view, choice.frame));
        total += psnr(&out, &truth, None)?;
    }
    let q_max = scene.render.q_max();
    let sweep_qs: Vec<f64> = (0..sweep)
        .map(|i| q_max * (0.5 - 0.5 * (i as f64 / sweep as f64 * std::f64::consts::TAU).cos()))
        .collect();
    // Timed through `vt render`'s driver (vt_app::play), frames thrown away.
    let (secs, r) = timed(1, || {
        vt_app::play::play(
            scene,
            &sweep_qs,
            params,
            &mut |f, _| -> vt_app::Result<()> {
                std::hint::black_box(f);
                Ok(())
            },
        )
    });
    r?;
    Ok((total / qs.len() as f64, sweep as f64 / secs))
}

fn render_modes(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let qs: Vec<f64> = ctx.pick(
        vec![0.25, 0.5, 1.0, 1.5, 1.8],
        vec![0.0, 0.25, 0.4, 0.5, 0.75, 1.0, 1.25, 1.5, 1.6, 1.8, 2.0],
    );
    let sweep = ctx.pick(120, 400);
    let mut pts = Vec::new();
    for (label, interpolation, gain, fill) in [
        ("nearest", Interpolation::Nearest, false, true),
        ("bilinear", Interpolation::Bilinear, false, true),
        ("nearest + gain", Interpolation::Nearest, true, true),
        ("bilinear + gain", Interpolation::Bilinear, true, true),
        (
            "bilinear + gain, no fill",
            Interpolation::Bilinear,
            true,
            false,
        ),
        (
            "fixed-point bilinear",
            Interpolation::BilinearFixed,
            false,
            true,
        ),
    ] {
        let params = RenderParams {
            interpolation,
            gain_compensation: gain,
            neighbour_fill: fill,
            ..Default::default()
        };
        let (p, fps) = render_figures(&sa, params, &qs, sweep)?;
        pts.push(Setting::new(
            label,
            fps,
            p,
            params == RenderParams::default(),
        ));
    }
    Ok(vec![Curve::new(
        "a-render",
        "Rendering: interpolation, gain compensation, neighbour fill",
        format!(
            "Eq. (3)-(6) rendered from the analysed scene of {SCENE} (written and loaded as a \
             scene directory). x: frames per second over a {sweep}-frame sweep across all views \
             (320x180); y: mean PSNR against the ray-cast truth at q in {qs:?}, the truth showing \
             the motion phase of the source frame the player chose. The background has real \
             depth, so one plane cannot explain it: absolute PSNR is limited by parallax, the \
             differences are what the options buy. Fixed-point bilinear is OpenCV's 1/32-pixel \
             integer interpolation; \"no fill\" shows the median background where the shown \
             view does not see, instead of the other view's matching frame. Default: bilinear \
             with gain compensation and neighbour fill."
        ),
        Axis::new("frames per second", Better::Higher),
        Axis::new("PSNR vs truth (dB)", Better::Higher),
        pts,
    )])
}

fn crossfade(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sa = synth_a(ctx)?;
    let lengths: Vec<usize> = ctx.pick(vec![0, 2, 4, 8], vec![0, 1, 2, 3, 4, 6, 8, 12, 16]);
    let n_frames = ctx.pick(240, 600);
    let scene = &sa.loaded;
    let q_max = scene.render.q_max();
    let mut settings: Vec<(String, RenderParams, usize)> = lengths
        .iter()
        .map(|&len| {
            let params = RenderParams {
                crossfade: len,
                ..Default::default()
            };
            (format!("{len} frames"), params, len)
        })
        .collect();
    for len in ctx.pick(vec![1, 2], vec![1, 2, 3, 4]) {
        let params = RenderParams {
            dissolve: len,
            ..Default::default()
        };
        settings.push((format!("dissolve {len}"), params, len));
    }
    let mut pts = Vec::new();
    // A slow sweep back and forth: switches at every half view, wraps in between.
    let qs: Vec<f64> = (0..n_frames)
        .map(|i| q_max * (0.5 - 0.5 * (i as f64 / 150.0 * std::f64::consts::TAU).cos()))
        .collect();
    for (label, params, len) in settings {
        let mut prev: Option<RgbImage> = None;
        let (mut ordinary, mut jumps) = (Vec::new(), Vec::new());
        let mut since_jump: Option<usize> = None;
        let mut worst = 0.0f64;
        let t = std::time::Instant::now();
        // `vt render`'s driver (vt_app::play); each frame's step measured as it comes.
        vt_app::play::play(scene, &qs, params, &mut |out, c| -> Result<()> {
            if let Some(prev) = &prev {
                let d = mean_abs_diff(out, prev, None)?;
                let jump = matches!(c.step, Step::Wrap | Step::Switch { .. });
                if jump {
                    if since_jump.is_some() {
                        jumps.push(worst);
                    }
                    since_jump = Some(0);
                    worst = d;
                } else if let Some(k) = since_jump {
                    // The largest step within 2 frames (or the blend) after a jump belongs to
                    // the jump.
                    if k < len.max(2) {
                        worst = worst.max(d);
                        since_jump = Some(k + 1);
                    } else {
                        jumps.push(worst);
                        since_jump = None;
                        ordinary.push(d);
                    }
                } else {
                    ordinary.push(d);
                }
            }
            match &mut prev {
                Some(p) => p.copy_from_slice(out.as_raw()),
                None => prev = Some(out.clone()),
            }
            Ok(())
        })?;
        if since_jump.is_some() {
            jumps.push(worst);
        }
        let fps = n_frames as f64 / t.elapsed().as_secs_f64();
        ordinary.sort_by(f64::total_cmp);
        let median = ordinary
            .get(ordinary.len() / 2)
            .copied()
            .unwrap_or(f64::NAN);
        let seam = jumps.iter().sum::<f64>() / jumps.len().max(1) as f64 / median;
        pts.push(
            Setting::new(label, fps, seam, len == 0)
                .with("jumps", jumps.len() as f64)
                .with("median ordinary step (grey levels)", median),
        );
    }
    Ok(vec![Curve::new(
        "a-crossfade",
        "Crossfade and dissolve length",
        format!(
            "Object crossfade after a loop wrap or view switch (Schoedl et al. 2000; \"N frames\"), \
             and dissolve (\"dissolve N\": N in-between frames from the last frame shown into \
             the new sequence), {n_frames} frames of a slow back-and-forth sweep over {SCENE}. \
             x: frames per second; y: image seam score: the largest frame-to-frame change (mean \
             absolute difference) within 2 frames (or the blend) after each jump, divided by \
             the median ordinary step, averaged over jumps (1 = a jump looks like an ordinary \
             step). Default: 0 (off, the thesis)."
        ),
        Axis::new("frames per second", Better::Higher),
        Axis::new("image seam score (jump / ordinary step)", Better::Lower),
        pts,
    )])
}

/// Masks of `frames` against `background` at 1/`f` resolution (bilinear), blurred and
/// thresholded as `vt analyze` does with the global threshold.
fn masks_at(frames: &[RgbImage], background: &RgbImage, f: u32) -> Result<Vec<Mask>> {
    let (w, h) = background.dimensions();
    let small = |img: &RgbImage| {
        if f == 1 {
            img.clone()
        } else {
            image::imageops::resize(
                img,
                w.div_ceil(f),
                h.div_ceil(f),
                image::imageops::FilterType::Triangle,
            )
        }
    };
    let blur = GaussianParams::default();
    let bgb = gaussian_blur(&small(background), &blur)?;
    frames
        .iter()
        .map(|fr| {
            Ok(foreground_mask(
                &gaussian_blur(&small(fr), &blur)?,
                &bgb,
                &MaskParams::default(),
            )?)
        })
        .collect()
}

/// The same knob where nothing repeats exactly: tree.avi's hand-free frames, a real tree in
/// wind. Each loop found at 1/f is scored by its eq. (1) cost at full resolution against the
/// full-resolution optimum's (1 = as good a loop; above 1 = a worse wrap).
fn mask_resolution_real(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let tr = tree(ctx)?;
    let frames = &tr.frames[..54.min(tr.frames.len())];
    let background = temporal_median(frames)?;
    let lp = LoopParams {
        window: 3,
        min_length: 20,
    };
    let full = masks_at(frames, &background, 1)?;
    let full_cost = |m: usize, n: usize| -> u64 {
        (0..lp.window)
            .map(|i| xor_count(&full[m + i], &full[n + i]))
            .sum()
    };
    let factors: Vec<u32> = ctx.pick(vec![1, 2, 4, 8], vec![1, 2, 3, 4, 6, 8]);
    let mut best = None;
    let mut pts = Vec::new();
    for &f in &factors {
        let masks = if f == 1 {
            full.clone()
        } else {
            masks_at(frames, &background, f)?
        };
        let (secs, l) = timed(ctx.pick(1, 3), || find_loop(&masks, &lp, "tree.avi"));
        let l = l?;
        let cost = full_cost(l.start, l.end) as f64;
        let base = *best.get_or_insert(cost);
        pts.push(
            Setting::new(format!("1/{f}"), secs * 1e3, cost / base.max(1.0), f == 1)
                .with("loop start m", l.start as f64)
                .with("loop end n", l.end as f64),
        );
    }
    Ok(vec![Curve::new(
        "a-mask-resolution-real",
        "Loop search at reduced mask resolution, real footage",
        format!(
            "Eq. (1) on masks from frames and background downscaled by 1/f, on tree.avi's {} \
             hand-free frames ({}x{}, a real tree in wind: no exact repeat, so resolution decides \
             which near-repeat wins; window 3, minimum length 20). x: loop search time; y: the \
             found loop's eq. (1) cost at full resolution over the full-resolution optimum's \
             (1 = as good a wrap).",
            frames.len(),
            frames[0].width(),
            frames[0].height()
        ),
        Axis::new("loop search time (ms)", Better::Lower),
        Axis::new("full-resolution loop cost / optimum", Better::Lower),
        pts,
    )])
}
