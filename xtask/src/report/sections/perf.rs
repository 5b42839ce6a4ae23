//! Section 6: performance, measured side by side in this run: analysis against plain decoding,
//! render frames per second at 640x360 and 1280x720, vt-core against OpenCV per operation
//! (warps, blurs, masks, morphology, searches),
//! guided synthesis time per setting, peak memory. Ratios first.

use anyhow::Result;
use image::RgbImage;
use serde_json::json;
use vt_core::analysis::{threshold_mask, AnalyzeParams};
use vt_core::blur::GaussianParams;
use vt_core::render::RenderParams;
use vt_core::warp::Interpolation;
use vt_core::{Homography, Point};
use vt_fv::eval::psnr as fv_psnr;
use vt_fv::{guided_synthesis, GuidedParams};

use crate::report::data::{analyze_frames, build_scene, synth_a, synth_b, synth_b_model, tree};
use crate::report::model::{Item, Table};
use crate::report::{peak_rss_mib, timed, Ctx};

fn analysis_table(ctx: &mut Ctx) -> Result<Table> {
    let tr = tree(ctx)?;
    let mut params = AnalyzeParams::default();
    params.loops.min_length = 20;
    // `vt analyze`'s own sequence (vt_app), into a fresh scene folder each time.
    let dir = ctx.work.path().join("perf-analysis");
    let (secs, a) = timed(ctx.pick(1, 3), || {
        std::fs::remove_dir_all(&dir).ok();
        analyze_frames(std::slice::from_ref(&tr.frames), &[], &params, &dir)
    });
    let done = a?;
    let (a, analysis_secs, seams_secs) = (done.analysis, done.analysis_secs, done.seams_secs);
    std::fs::remove_dir_all(&dir).ok();
    let tm = a.timings;
    let mut t = Table::new(
        "perf-analysis",
        "Analysis against plain decoding (tree.avi)",
        format!(
            "tree.avi ({} frames of {}x{}): decoding every frame with ffmpeg through vt-io, against \
             the whole single-view analysis as `vt analyze` runs it (vt_app: median, masks, loop, \
             object store, scene files, seams measured on rendered frames) of the decoded frames \
             held in memory. A ratio below 1 means the analysis costs less than reading the video once. \
             Thesis scale (15 views x 500 frames x 640x360) is measured by `cargo xtask bench`.",
            tr.frames.len(),
            tr.frames[0].width(),
            tr.frames[0].height()
        ),
        &["what", "seconds", "ratio to decode"],
    );
    let d = tr.decode_secs;
    for (what, s) in [
        ("decode (ffmpeg)", d),
        ("analysis, all stages (vt analyze's sequence)", secs),
        ("  vt-core's analysis", analysis_secs),
        ("  median", tm.median.as_secs_f64()),
        ("  blur + masks", tm.masks.as_secs_f64()),
        ("  loop search", tm.loops.as_secs_f64()),
        (
            "  object store, scene files",
            secs - analysis_secs - seams_secs,
        ),
        ("  seams measured on rendered frames", seams_secs),
    ] {
        t.row(vec![json!(what), json!(s), json!(s / d)]);
    }
    Ok(t)
}

/// Analysis of a real video at a real size, end to end from the file: tree.avi's hand-free
/// frames upscaled to 768x576 and looped, encoded to H.264, against decoding the same file.
fn real_size_table(ctx: &mut Ctx) -> Result<Table> {
    use vt_core::analysis::{FrameRef, FrameSource};
    let tr = tree(ctx)?;
    let (w, h, n) = (768u32, 576u32, ctx.pick(160usize, 800));
    let hand_free = 54.min(tr.frames.len());
    let scaled: Vec<RgbImage> = tr.frames[..hand_free]
        .iter()
        .map(|f| image::imageops::resize(f, w, h, image::imageops::FilterType::Triangle))
        .collect();
    let path = ctx.work.path().join("tree-768x576.mp4");
    vt_io::video::encode_h264(&path, w, h, 25.0, 18, n, &mut |i| {
        Ok(scaled[i % scaled.len()].clone())
    })?;
    let mut src = vt_io::frames::VideoSource::open(&path)?;
    let (decode, decoded) = timed(ctx.pick(1, 3), || {
        src.for_each_native(&mut |_, f: FrameRef<'_>| {
            std::hint::black_box(f.dimensions());
            Ok(())
        })
    });
    decoded?;
    let mut t = Table::new(
        "perf-analysis-real",
        "Analysis of a real video at 768x576 against decoding it",
        format!(
            "tree.avi's hand-free frames upscaled to {w}x{h} and looped to {n} frames, H.264: \
             `vt analyze` at default settings (vt_app::analyze), end to end from the file to \
             the scene folder (decode, median of {} evenly spaced frames, noise-model masks, \
             dynamic region, appearance, loop, object store, seams), against decoding the file alone (ffmpeg through vt-io, frames \
             thrown away). The every-frame median row is the same analysis with \
             --median-frames 0; its background error column is the default's distance from it. \
             The frame-cache row keeps all the frames between the two passes (--cache-mb 768: \
             the video decoded once) where the default's {} MiB makes frames past it stream \
             (decoded twice, memory bounded: about 320 MB at 960x720 against 820 for 720 frames \
             cached; a stream's median sample is every k-th frame, k a power of two, a cache's \
             the middle of equal spans, hence its own background error). The default measures \
             the camera's shake during the first pass (frame 0's corners looked for in every \
             8th frame, the spacing doubling past frame 64; the clip is still, so nothing is \
             warped); the last row skips that.",
            vt_core::analysis::DEFAULT_MEDIAN_FRAMES,
            vt_core::analysis::DEFAULT_CACHE_MB
        ),
        &[
            "what",
            "seconds",
            "ratio to decode",
            "background vs every-frame median (grey levels)",
        ],
    );
    t.row(vec![
        json!("decode (ffmpeg)"),
        json!(decode),
        json!(1.0),
        json!("-"),
    ]);
    // `vt analyze` itself (vt_app::analyze::analyze): from the file into a scene folder.
    let out = ctx.work.path().join("perf-analysis-real");
    let run = |median_frames: usize,
               cache_mb: usize,
               stabilize: vt_core::stabilize::StabilizeMode|
     -> Result<(f64, vt_core::analysis::SceneAnalysis)> {
        let job = vt_app::analyze::AnalyzeJob {
            views: vec![path.clone()],
            points: None,
            out: out.clone(),
            params: AnalyzeParams {
                median_frames,
                cache_bytes: cache_mb << 20,
                stabilize: vt_core::stabilize::StabilizeParams {
                    mode: stabilize,
                    ..Default::default()
                },
                ..Default::default()
            },
            fps: None,
            store: Default::default(),
        };
        let (secs, a) = timed(1, || vt_app::analyze::analyze(&job, &mut vt_app::Silent));
        std::fs::remove_dir_all(&out).ok();
        Ok((secs, a?.analysis))
    };
    let cache = vt_core::analysis::DEFAULT_CACHE_MB;
    use vt_core::stabilize::StabilizeMode::{Auto, Off};
    let (fast, a) = run(vt_core::analysis::DEFAULT_MEDIAN_FRAMES, cache, Auto)?;
    let (exact, b) = run(0, cache, Auto)?;
    let (cached, c) = run(vt_core::analysis::DEFAULT_MEDIAN_FRAMES, 768, Auto)?;
    let (unmeasured, d) = run(vt_core::analysis::DEFAULT_MEDIAN_FRAMES, cache, Off)?;
    let err =
        vt_core::metrics::mean_abs_diff(&a.views[0].background, &b.views[0].background, None)?;
    t.row(vec![
        json!(format!(
            "analysis (default, {} frames for the median)",
            vt_core::analysis::DEFAULT_MEDIAN_FRAMES
        )),
        json!(fast),
        json!(fast / decode),
        json!(err),
    ]);
    t.row(vec![
        json!("analysis, every-frame median"),
        json!(exact),
        json!(exact / decode),
        json!(0.0),
    ]);
    t.row(vec![
        json!("analysis, all frames cached (--cache-mb 768)"),
        json!(cached),
        json!(cached / decode),
        json!(vt_core::metrics::mean_abs_diff(
            &c.views[0].background,
            &b.views[0].background,
            None
        )?),
    ]);
    t.row(vec![
        json!("analysis, camera shake not measured (--stabilize off)"),
        json!(unmeasured),
        json!(unmeasured / decode),
        json!(vt_core::metrics::mean_abs_diff(
            &d.views[0].background,
            &b.views[0].background,
            None
        )?),
    ]);
    Ok(t)
}

fn render_table(ctx: &mut Ctx) -> Result<Table> {
    let sa = synth_a(ctx)?;
    let frames_per_view = ctx.pick(40, 72);
    let sweep = ctx.pick(60, 240);
    let mut t = Table::new(
        "perf-render",
        "Render speed at 640x360 and 1280x720",
        format!(
            "The demo scene's first {frames_per_view} frames per view scaled up (bilinear) to each \
             size, analysed and written as a scene, then rendered over a {sweep}-frame sweep across \
             all views (the viewpoint moves every frame, so the background blend is recomputed \
             each time) by `vt render`'s driver (vt_app::play, seams scored, no encoding): \
             frames per second, this machine's cores. Ratio: nearest's \
             speed over bilinear's."
        ),
        &["size", "bilinear fps", "nearest fps", "nearest / bilinear", "bilinear ms per frame"],
    );
    for (w, h) in [(640u32, 360u32), (1280, 720)] {
        let frames: Vec<Vec<RgbImage>> = sa
            .frames
            .iter()
            .map(|v| {
                v[..frames_per_view.min(v.len())]
                    .iter()
                    .map(|f| {
                        image::imageops::resize(f, w, h, image::imageops::FilterType::Triangle)
                    })
                    .collect()
            })
            .collect();
        let sx = w as f64 / sa.scene.params().width as f64;
        let points: Vec<Vec<Point>> = sa
            .points
            .iter()
            .map(|v| {
                v.iter()
                    .map(|p| Point::new((p.x + 0.5) * sx - 0.5, (p.y + 0.5) * sx - 0.5))
                    .collect()
            })
            .collect();
        let mut params = sa.params;
        params.loops.min_length = frames_per_view / 2;
        let dir = ctx.work.path().join(format!("perf-{w}x{h}"));
        let (_, _, scene) = build_scene(&frames, &points, &params, &dir)?;
        let q_max = scene.render.q_max();
        let mut fps = Vec::new();
        let qs: Vec<f64> = (0..sweep)
            .map(|i| q_max * (0.5 - 0.5 * (i as f64 / sweep as f64 * std::f64::consts::TAU).cos()))
            .collect();
        for interpolation in [Interpolation::Bilinear, Interpolation::Nearest] {
            let params = RenderParams {
                interpolation,
                ..Default::default()
            };
            // `vt render`'s driver (vt_app::play) with the frames thrown away.
            let (secs, res) = timed(1, || {
                vt_app::play::play(&scene, &qs, params, &mut |f, _| -> vt_app::Result<()> {
                    std::hint::black_box(f);
                    Ok(())
                })
            });
            // Less the frames rendered only to score the switches' seams.
            let played = res?;
            fps.push(sweep as f64 / (secs - played.measure_secs).max(1e-9));
        }
        t.row(vec![
            json!(format!("{w}x{h}")),
            json!(fps[0]),
            json!(fps[1]),
            json!(fps[1] / fps[0]),
            json!(1e3 / fps[0]),
        ]);
        std::fs::remove_dir_all(&dir).ok();
    }
    Ok(t)
}

fn opencv_table(ctx: &mut Ctx) -> Result<Table> {
    let sa = synth_a(ctx)?;
    let reps = ctx.pick(5, 21);
    let mut t = Table::new(
        "perf-opencv",
        "vt-core against OpenCV, per operation",
        format!(
            "The same operation on the same input through vt-core (pure Rust) and through OpenCV \
             4.6 (vt-cv, including its conversion to and from cv::Mat, which a caller of OpenCV \
             from Rust pays too); median of {reps} runs. Input: the demo scene (320x180 frames; \
             640x360 = a frame scaled up). Ratio = vt-core time / OpenCV time: below 1 vt-core \
             is faster."
        ),
        &[
            "operation",
            "input",
            "vt-core (ms)",
            "OpenCV (ms)",
            "ratio vt-core / OpenCV",
        ],
    );
    let f0 = &sa.frames[0][0];
    let big = image::imageops::resize(f0, 640, 360, image::imageops::FilterType::Triangle);
    let bg = &sa.analysis.views[0].background;
    let masks = &sa.analysis.views[0].masks;
    let h = sa.analysis.links[0].homography;
    let gp = GaussianParams::default();
    let g7 = GaussianParams {
        ksize: 7,
        sigma: 0.0,
    };
    let n_med = 31.min(sa.frames[0].len());
    let pts: Vec<Point> = sa.points[0].clone();
    let dst: Vec<Point> = sa.points[1].clone();
    let tilt = Homography::from_matrix(nalgebra::Matrix3::new(
        1.02, 0.03, -4.0, -0.02, 0.99, 3.0, 2e-5, -1e-5, 1.0,
    ))?;
    type Pair<'a> = (
        &'a str,
        String,
        Box<dyn FnMut() -> Result<()> + 'a>,
        Box<dyn FnMut() -> Result<()> + 'a>,
    );
    let ops: Vec<Pair> = vec![
        (
            "Gaussian blur 3x3",
            "640x360 RGB".into(),
            Box::new(|| {
                vt_core::blur::gaussian_blur(&big, &gp)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
            Box::new(|| {
                vt_cv::blur::gaussian_blur(&big, &gp)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "temporal median",
            format!("{n_med} frames 320x180"),
            Box::new(|| {
                vt_core::median::temporal_median(&sa.frames[0][..n_med])
                    .map(|_| ())
                    .map_err(Into::into)
            }),
            Box::new(|| {
                vt_cv::median::temporal_median(&sa.frames[0][..n_med])
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "threshold mask",
            "320x180".into(),
            Box::new(|| threshold_mask(f0, bg, 25).map(|_| ()).map_err(Into::into)),
            Box::new(|| {
                vt_cv::mask::threshold_mask(f0, bg, 25)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "warp RGB, bilinear",
            "640x360".into(),
            Box::new(|| {
                vt_core::warp::warp_rgb(&big, &tilt, 640, 360, Interpolation::Bilinear);
                Ok(())
            }),
            Box::new(|| {
                vt_cv::warp::warp_rgb(&big, &tilt, 640, 360, Interpolation::Bilinear)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "warp RGB, nearest",
            "640x360".into(),
            Box::new(|| {
                vt_core::warp::warp_rgb(&big, &tilt, 640, 360, Interpolation::Nearest);
                Ok(())
            }),
            Box::new(|| {
                vt_cv::warp::warp_rgb(&big, &tilt, 640, 360, Interpolation::Nearest)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "warp RGB, bilinear fixed-point",
            "640x360".into(),
            Box::new(|| {
                vt_core::warp::warp_rgb(&big, &tilt, 640, 360, Interpolation::BilinearFixed);
                Ok(())
            }),
            Box::new(|| {
                vt_cv::warp::warp_rgb(&big, &tilt, 640, 360, Interpolation::BilinearFixed)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "Gaussian blur 7x7",
            "640x360 RGB".into(),
            Box::new(|| {
                vt_core::blur::gaussian_blur(&big, &g7)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
            Box::new(|| {
                vt_cv::blur::gaussian_blur(&big, &g7)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "morphology open + close, r = 2",
            "320x180 mask".into(),
            Box::new(|| {
                std::hint::black_box(masks[0].open(2).close(2));
                Ok(())
            }),
            Box::new(|| {
                use vt_cv::mask::{morph, Morph};
                let o = morph(&masks[0], 2, Morph::Open)?;
                morph(&o, 2, Morph::Close).map(|_| ()).map_err(Into::into)
            }),
        ),
        (
            "warp mask",
            "320x180".into(),
            Box::new(|| {
                vt_core::warp::warp_mask(&masks[0], &h, 320, 180);
                Ok(())
            }),
            Box::new(|| {
                vt_cv::warp::warp_mask(&masks[0], &h, 320, 180)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "XOR count",
            "two 320x180 masks".into(),
            Box::new(|| {
                std::hint::black_box(vt_core::mask::xor_count(&masks[0], &masks[5]));
                Ok(())
            }),
            Box::new(|| {
                vt_cv::mask::xor_count(&masks[0], &masks[5])
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "homography from points",
            format!("{} point pairs", pts.len()),
            Box::new(|| {
                Homography::from_correspondences(&pts, &dst)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
            Box::new(|| {
                vt_cv::homography::from_correspondences(&pts, &dst)
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
        (
            "loop search (eq. 1)",
            format!("{} masks 320x180", masks.len()),
            Box::new(|| {
                vt_core::loops::find_loop(masks, &sa.params.loops, "view 0")
                    .map(|_| ())
                    .map_err(Into::into)
            }),
            Box::new(|| {
                vt_cv::loops::find_loop(masks, &sa.params.loops, "view 0")
                    .map(|_| ())
                    .map_err(Into::into)
            }),
        ),
    ];
    for (op, input, mut vt, mut cv) in ops {
        let (tv, r) = timed(reps, &mut vt);
        r?;
        let (tc, r) = timed(reps, &mut cv);
        r?;
        t.row(vec![
            json!(op),
            json!(input),
            json!(tv * 1e3),
            json!(tc * 1e3),
            json!(tv / tc),
        ]);
    }
    Ok(t)
}

fn synthesis_table(ctx: &mut Ctx) -> Result<Table> {
    let sb = synth_b(ctx)?;
    let m = synth_b_model(ctx)?;
    let d = &sb.data;
    let k = 0;
    let mut t = Table::new(
        "perf-synthesis",
        "Guided synthesis time per setting",
        format!(
            "One new view of the synthetic object ({}x{}, {} degrees from camera 0) synthesised \
             from its nearest reference photo; PSNR inside the true silhouette. Ratio: time over \
             the recommended patch-7 setting's. Section 1 has every knob's full curve.",
            d.photos[0].width(),
            d.photos[0].height(),
            sb.angles[k]
        ),
        &[
            "setting",
            "seconds",
            "ratio to patch 7 fast_for",
            "PSNR (dB)",
        ],
    );
    let mut settings: Vec<(&str, GuidedParams)> = vec![
        (
            "patch 7, fast_for(7) (strips, skip black)",
            GuidedParams::fast_for(7),
        ),
        (
            "patch 7, exact order (sequential, every pixel)",
            GuidedParams {
                patch: 7,
                ..Default::default()
            },
        ),
        (
            "patch 41, fast() (3 levels, step 2, strips)",
            GuidedParams::fast(),
        ),
    ];
    if !ctx.quick {
        settings.push((
            "patch 41, paper-exact (GuidedParams::default())",
            GuidedParams::default(),
        ));
    }
    let mut base = None;
    for (name, p) in settings {
        let (secs, out) = timed(1, || {
            guided_synthesis(&d.photos[m.reference[k]], &m.rough[k], &p)
        });
        let out = out?;
        let b = *base.get_or_insert(secs);
        t.row(vec![
            json!(name),
            json!(secs),
            json!(secs / b),
            json!(fv_psnr(&out, &d.extra_truth[k], Some(&d.extra_masks[k]))?),
        ]);
    }
    Ok(t)
}

/// Builds the section.
pub fn build(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let mut items = vec![
        Item::Table(analysis_table(ctx)?),
        Item::Table(real_size_table(ctx)?),
        Item::Table(render_table(ctx)?),
        Item::Table(opencv_table(ctx)?),
        Item::Table(synthesis_table(ctx)?),
    ];
    items.push(Item::Note {
        text: format!(
            "Peak resident memory of the report process after these measurements: {:.0} MiB \
             (it holds the synthetic scenes' frames in memory; `vt analyze` streams frames \
             instead, see `cargo xtask bench` for its peak at thesis scale).",
            peak_rss_mib()
        ),
    });
    Ok(items)
}
