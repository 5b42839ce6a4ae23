//! System A on real footage: `testdata/tree.avi` itself (a real tree in wind), and a 5-view scene
//! built from it by `vt synth real` (known homographies, clock offsets, gains, marking noise,
//! H.264). The scenes are made and analysed by the real binary; renders are checked in-process
//! (vt-core's Player and Renderer over vt-io's loaded scene), so the source frame of every output
//! frame is known. Truth comes from the decoded source video and vt-synth's own warps, never from
//! vt-core.
//!
//! Figures are printed with `VT_TEST_VERBOSE=1`.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use image::RgbImage;
use vt_core::render::{Player, RenderParams, Renderer, Step, SwitchPolicy};
use vt_io::scene::LoadedScene;
use vt_synth::real::{RealParams, RealScene};

fn tree() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi")
}

fn decode(path: &Path) -> Vec<RgbImage> {
    let mut src = vt_io::frames::ViewSource::open(path).unwrap();
    let mut frames = Vec::new();
    src.as_source()
        .for_each_frame(&mut |_, f| {
            frames.push(f.clone());
            Ok(())
        })
        .unwrap();
    frames
}

fn mad(a: &RgbImage, b: &RgbImage) -> f64 {
    vt_core::metrics::mean_abs_diff(a, b, None).unwrap()
}

fn verbose() -> bool {
    std::env::var_os("VT_TEST_VERBOSE").is_some()
}

/// Renders `n` frames at a fixed q; returns (choice, frame) per output frame.
fn play(
    scene: &LoadedScene,
    params: RenderParams,
    q: impl Fn(usize) -> f64,
    n: usize,
) -> Vec<(vt_core::render::FrameChoice, RgbImage)> {
    let mut renderer = Renderer::new(scene.render.clone(), params).unwrap();
    let mut player = Player::new();
    let (w, h) = renderer.size();
    (0..n)
        .map(|i| {
            let choice = player.advance(&scene.render, q(i)).unwrap();
            let mut out = RgbImage::new(w, h);
            renderer
                .render_into(&scene.objects, q(i), &choice, &mut out)
                .unwrap();
            (choice, out)
        })
        .collect()
}

/// The default loop on tree.avi (68 frames, a hand entering from frame 54; no frame repeats):
/// a per-region loop whose rendered wrap is no larger than an ordinary rendered step (the
/// thesis's loop wraps at about 1.9 of them, below), every frame close to a real one, and as
/// sharp as the source around the wrap.
#[test]
fn tree_default_loop_wraps_as_it_steps() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tree();
    let source = decode(&tree);
    let mut wraps = Vec::new();
    for loops in ["auto", "single"] {
        let out = tmp.path().join(loops);
        let mut args = vec!["analyze", s(&tree), "--out", s(&out), "--min-length", "20"];
        if loops == "single" {
            args.extend(["--loops", "single"]);
        }
        let stdout = vt_ok(&args);
        assert_eq!(
            stdout.contains("per-region loop of"),
            loops == "auto",
            "{stdout}"
        );
        let scene = LoadedScene::open(&out).unwrap();
        let frames = play(&scene, RenderParams::default(), |_| 0.0, 64);
        let (wrap, step) = wrap_and_step(&frames, 0);
        // Each rendered frame's distance to real content: per 16 px tile the mean absolute
        // difference to the nearest source frame (a per-region loop shows different source
        // times in different tiles), averaged over the tiles; and the gradient energy of the
        // frames just before and after each wrap over the source's.
        let (w, h) = source[0].dimensions();
        let tile_err = |f: &RgbImage, tx: u32, ty: u32| {
            let (x1, y1) = ((tx + 16).min(w), (ty + 16).min(h));
            source
                .iter()
                .map(|g| {
                    let mut e = 0u64;
                    for y in ty..y1 {
                        for x in tx..x1 {
                            let (a, b) = (f.get_pixel(x, y), g.get_pixel(x, y));
                            e += (0..3).map(|c| a[c].abs_diff(b[c]) as u64).sum::<u64>();
                        }
                    }
                    e as f64 / (3 * (x1 - tx) * (y1 - ty)) as f64
                })
                .fold(f64::INFINITY, f64::min)
        };
        let per_frame: Vec<f64> = frames
            .iter()
            .map(|(_, f)| {
                let tiles: Vec<f64> = (0..h)
                    .step_by(16)
                    .flat_map(|ty| (0..w).step_by(16).map(move |tx| (tx, ty)))
                    .map(|(tx, ty)| tile_err(f, tx, ty))
                    .collect();
                tiles.iter().sum::<f64>() / tiles.len() as f64
            })
            .collect();
        let nearest = per_frame.iter().sum::<f64>() / per_frame.len() as f64;
        let worst_frame = per_frame.iter().cloned().fold(0.0, f64::max);
        let energy = |f: &RgbImage| {
            let g = image::imageops::grayscale(f);
            let (w, h) = g.dimensions();
            let mut e = 0f64;
            for y in 0..h - 1 {
                for x in 0..w - 1 {
                    let v = g.get_pixel(x, y)[0] as f64;
                    e += (g.get_pixel(x + 1, y)[0] as f64 - v).powi(2)
                        + (g.get_pixel(x, y + 1)[0] as f64 - v).powi(2);
                }
            }
            e
        };
        let src_energy = source[..54].iter().map(energy).sum::<f64>() / 54.0;
        let near: Vec<f64> = frames
            .windows(2)
            .filter(|w| w[1].0.step == Step::Wrap)
            .flat_map(|w| [energy(&w[0].1), energy(&w[1].1)])
            .collect();
        let sharp = near.iter().sum::<f64>() / near.len() as f64 / src_energy;
        if verbose() {
            eprintln!(
                "tree.avi --loops {loops}: wrap {:.2} ordinary steps, {nearest:.2} grey levels from the nearest source frame per tile (worst frame {worst_frame:.2}), sharpness at the wraps {sharp:.3} of the source's",
                wrap / step
            );
        }
        wraps.push(wrap / step);
        if loops == "auto" {
            assert!(wrap <= step, "wrap {wrap:.3} vs ordinary step {step:.3}");
            assert!(
                nearest <= 2.0,
                "{nearest:.2} grey levels from the source frames"
            );
            assert!(sharp >= 0.95, "sharpness at the wraps {sharp:.3}");
        }
    }
    assert!(wraps[1] > 1.5, "the thesis's loop wraps at {:.2}", wraps[1]);
}

#[test]
fn tree_single_view_keeps_the_motion() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("tree-scene");
    // The thesis's loop: rendered frames are its source frames.
    let stdout = vt_ok(&[
        "analyze",
        s(&tree()),
        "--out",
        s(&out),
        "--min-length",
        "30",
        "--loops",
        "single",
    ]);
    assert!(stdout.contains("motion kept"), "{stdout}");
    let json = read_json(&out.join("scene.json"));
    let kept = json["views"][0]["motion_kept"].as_f64().unwrap();
    // The source's real frame rate (VFR: median interval 0.4 s) is the scene's default rate, and
    // a folder name with a dot is a PNG folder.
    let fps = json["fps"].as_f64().unwrap();
    assert!((fps - 2.5).abs() < 0.01, "scene fps {fps}");
    let frames_dir = tmp.path().join("frames.v1");
    let stdout = vt_ok(&[
        "render",
        s(&out),
        "--path",
        "0s:0",
        "--duration",
        "2",
        "--out",
        s(&frames_dir),
    ]);
    assert!(stdout.contains("rendered 5 frames"), "{stdout}");
    assert_eq!(count_pngs(&frames_dir), 5);
    let source = decode(&tree());
    let scene = LoadedScene::open(&out).unwrap();
    let frames = play(&scene, RenderParams::default(), |_| 0.0, 50);
    let mut worst: f64 = 0.0;
    for (c, img) in &frames {
        worst = worst.max(mad(img, &source[c.frame]));
    }
    let (wrap, mean_step) = wrap_and_step(&frames, 0);
    // tree.avi has no true repeat in its 68 frames: the best 30-frame loop's wrap is 1.86
    // ordinary steps. A crossfade of the continuing sequences only spreads it (1.2-1.4 steps at
    // 1-6 frames: 1.19-1.44). A dissolve replaces the frames after the wrap by in-between frames
    // from the last frame shown into the new sequence: one such frame brings it under one
    // ordinary step (0.95; 2 frames 0.69).
    let dissolved = RenderParams {
        dissolve: 1,
        ..Default::default()
    };
    let (wrap_d, step_d) = wrap_and_step(&play(&scene, dissolved, |_| 0.0, 50), 1);
    if verbose() {
        for crossfade in [1, 2, 4, 6] {
            let params = RenderParams {
                crossfade,
                ..Default::default()
            };
            let (w, st) = wrap_and_step(&play(&scene, params, |_| 0.0, 50), crossfade);
            eprintln!("crossfade {crossfade}: wrap / step = {:.2}", w / st);
        }
        for dissolve in [2, 3] {
            let params = RenderParams {
                dissolve,
                ..Default::default()
            };
            let (w, st) = wrap_and_step(&play(&scene, params, |_| 0.0, 50), dissolve);
            eprintln!("dissolve {dissolve}: wrap / step = {:.2}", w / st);
        }
        eprintln!(
            "tree.avi single view: motion kept {:.1}%, worst frame MAD {worst:.3}, wrap {wrap:.2} / step {mean_step:.2} = {:.2}; dissolve 1: {:.2}",
            100.0 * kept,
            wrap / mean_step,
            wrap_d / step_d
        );
    }
    assert!(kept >= 0.9, "motion kept {kept}");
    // Within the store's error: the default keeps its frames at 40 dB PSNR or more (an RMS error
    // of 2.55 grey levels) under the masks; measured 1.59 (1.2 at the finest quantiser).
    assert!(
        worst <= 2.0,
        "rendered frame {worst} grey levels from its source frame"
    );
    assert!(
        wrap <= 2.0 * mean_step && wrap_d <= 1.1 * step_d,
        "loop wrap {wrap:.2} vs ordinary step {mean_step:.2}; dissolve 1: {wrap_d:.2} vs {step_d:.2}"
    );
}

/// The largest image change (mean absolute difference) at a loop wrap, counting the `spread`
/// frames after it that a crossfade or dissolve spreads it over, and the mean ordinary step (the
/// other played frames), in rendered frames.
fn wrap_and_step(frames: &[(vt_core::render::FrameChoice, RgbImage)], spread: usize) -> (f64, f64) {
    let (mut steps, mut wraps) = (Vec::new(), Vec::new());
    let mut since_wrap = usize::MAX;
    for w in frames.windows(2) {
        let d = mad(&w[1].1, &w[0].1);
        match w[1].0.step {
            Step::Wrap => {
                since_wrap = 0;
                wraps.push(d)
            }
            Step::Play if since_wrap < spread => {
                since_wrap += 1;
                wraps.push(d)
            }
            Step::Play => steps.push(d),
            _ => {}
        }
    }
    assert!(!wraps.is_empty(), "no loop wrap in {} frames", frames.len());
    let mean_step = steps.iter().sum::<f64>() / steps.len() as f64;
    (wraps.iter().cloned().fold(0.0, f64::max), mean_step)
}

/// The generated scene and its truth.
struct Real {
    dir: PathBuf,
    views: usize,
    truth: RealScene,
}

fn real_scene(root: &Path, name: &str, noise: &str, frames: &str) -> Real {
    real_scene_of(root, name, noise, frames, 5)
}

fn real_scene_of(root: &Path, name: &str, noise: &str, frames: &str, views: usize) -> Real {
    let dir = root.join(name);
    let n_views = views.to_string();
    vt_ok(&[
        "synth",
        "real",
        s(&tree()),
        "--out",
        s(&dir),
        "--views",
        &n_views,
        "--frames",
        frames,
        "--usable",
        "54",
        "--marking-noise",
        noise,
    ]);
    let json = read_json(&dir.join("truth.json"));
    let params: RealParams = serde_json::from_value(json["params"].clone()).unwrap();
    let truth = RealScene::new(decode(&tree()), params).unwrap();
    assert_eq!(
        json["offsets"].as_array().unwrap().len(),
        truth.offsets().len()
    );
    Real { dir, views, truth }
}

fn analyze_real(real: &Real, out: &Path, extra: &[&str]) -> LoadedScene {
    let points = real.dir.join("points.txt");
    let mut args = vec!["--points", s(&points)];
    args.extend_from_slice(extra);
    analyze_real_with(real, out, &args).0
}

/// Analyses the scene's views with `extra` flags (no points file unless given); returns the
/// scene and vt's summary.
fn analyze_real_with(real: &Real, out: &Path, extra: &[&str]) -> (LoadedScene, String) {
    let views: Vec<String> = (0..real.views)
        .map(|p| s(&real.dir.join(format!("view_{p:02}.mp4"))).to_string())
        .collect();
    let mut args = vec!["analyze"];
    args.extend(views.iter().map(String::as_str));
    args.extend_from_slice(&["--out", s(out), "--min-length", "40"]);
    args.extend_from_slice(extra);
    let stdout = vt_ok(&args);
    if verbose() {
        eprintln!("{stdout}");
    }
    (LoadedScene::open(out).unwrap(), stdout)
}

/// Share of transition-table entries within +-1 frame of the truth.
fn transitions_within_one(scene: &LoadedScene, truth: &RealScene) -> f64 {
    let u = truth.usable() as i64;
    let (mut good, mut all) = (0usize, 0usize);
    for p in 0..scene.render.views.len() {
        let v = &scene.render.views[p];
        for (table, q) in [(&v.to_next, p + 1), (&v.to_prev, p.wrapping_sub(1))] {
            if q >= scene.render.views.len() {
                continue;
            }
            for (s_, t) in table.iter().enumerate() {
                let Some(t) = t else { continue };
                let a = (truth.source_index(p, s_)) as i64;
                let b = (truth.source_index(q, *t)) as i64;
                let d = (a - b).rem_euclid(u);
                all += 1;
                if d.min(u - d) <= 1 {
                    good += 1;
                }
            }
        }
    }
    good as f64 / all.max(1) as f64
}

#[test]
fn real_scene_registered_without_points() {
    // Issue #18: four views of tree.avi on a slanted plane, no points file. The homographies
    // come from the backgrounds alone (features, RANSAC, GRIC on the inliers, refinement).
    let tmp = tempfile::tempdir().unwrap();
    let real = real_scene_of(tmp.path(), "auto", "2", "100", 4);
    let out = tmp.path().join("auto-scene");
    let (scene, stdout) = analyze_real_with(&real, &out, &[]);
    let corner = corner_error(&scene, &real.truth);
    let within = transitions_within_one(&scene, &real.truth);
    if verbose() {
        eprintln!(
            "auto registration, 4 views: corner error {corner:.3} px, transitions within +-1 {:.1}%",
            100.0 * within
        );
    }
    assert!(corner <= 0.5, "corner error {corner} px");
    assert!(within >= 0.95, "transitions within +-1 frame: {within}");
    // The summary says which quantiser each view's store took for the 40 dB target.
    assert!(
        stdout.contains("object stores: H.264 at quantisers")
            && stdout.contains("the coarsest predicted to keep 40 dB"),
        "{stdout}"
    );
    // The summary says how each link was registered and where to look.
    for p in 0..3 {
        let line = format!("registered {p}->{}", p + 1);
        assert!(stdout.contains(&line), "{stdout}");
        assert!(out.join(format!("fit_{p:03}.png")).is_file());
    }
    switches_fade_without_a_pop(&scene);
    seams_on_sampled_rows_match_every_row(&scene);
    let json = read_json(&out.join("scene.json"));
    let reg = &json["views"][0]["to_next"]["registration"];
    assert!(reg["inliers"].as_u64().unwrap() >= 20, "{reg}");
    // The virtual points are the same physical points: view p's carried by H to view p + 1.
    for p in 0..3 {
        let h = scene.file.views[p]
            .to_next
            .as_ref()
            .unwrap()
            .homography()
            .unwrap();
        let (a, b) = (&scene.file.views[p].points, &scene.file.views[p + 1].points);
        assert_eq!(a.len(), 4);
        for (pa, pb) in a.iter().zip(b) {
            let q = h.apply(vt_core::Point::new(pa[0], pa[1])).unwrap();
            assert!((q.x - pb[0]).abs() < 1e-6 && (q.y - pb[1]).abs() < 1e-6);
        }
    }
}

/// Issue #34: `vt analyze` measures seams on a sample of each frame's rows. What it recorded is
/// that measurement, and every score is within 0.03 of the same steps and switches measured on
/// every row.
fn seams_on_sampled_rows_match_every_row(scene: &LoadedScene) {
    use vt_core::seam::{measure_seams, SeamSampling};
    let measure = |sampling| {
        measure_seams(
            &scene.render,
            &scene.objects,
            RenderParams::default(),
            sampling,
        )
        .unwrap()
    };
    let sampled = measure(SeamSampling::default());
    assert!(SeamSampling::default().every(scene.render.views[0].background.height()) > 1);
    let every_row = measure(SeamSampling {
        rows: 0,
        ..SeamSampling::default()
    });
    for (p, (a, b)) in sampled.iter().zip(&every_row).enumerate() {
        assert_eq!(
            a.wrap,
            Some(scene.file.views[p].loop_seam),
            "recorded: view {p}"
        );
        for (x, y) in [
            (a.wrap, b.wrap),
            (a.to_next, b.to_next),
            (a.to_prev, b.to_prev),
        ] {
            match (x, y) {
                (Some(x), Some(y)) => assert!((x - y).abs() <= 0.03, "view {p}: {a:?} {b:?}"),
                (x, y) => assert_eq!(x.is_some(), y.is_some(), "view {p}"),
            }
        }
    }
}

/// Issue #23: a view switch goes to the frame eq. (2) matches, so the views show the same moment
/// and differ only where they disagree (resampling, registration, gains). A hard switch shows
/// that difference at once: its step is larger than the ordinary steps it replaces. The
/// default's fade spreads it, so switches add nothing to ordinary playback, and the blended
/// frames keep their detail (the views are registered to a fraction of a pixel).
fn switches_fade_without_a_pop(scene: &LoadedScene) {
    let links: Vec<f64> = scene
        .file
        .views
        .iter()
        .filter_map(|v| v.to_next.as_ref().map(|l| l.seam))
        .collect();
    let hard = RenderParams {
        switch_fade: 0,
        ..RenderParams::default()
    };
    let measure = |params| {
        vt_core::seam::measure_switch_fades(&scene.render, &scene.objects, params, 6).unwrap()
    };
    let (plain, faded) = (measure(hard), measure(RenderParams::default()));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    if verbose() {
        eprintln!(
            "switches (x the steps they replace): analysis {links:.3?}; hard {:.3?}, faded {:.3?}; blended frames' sharpness mean {:.3}",
            plain.seams,
            faded.seams,
            mean(&faded.sharpness)
        );
    }
    assert!(links.iter().all(|&l| l <= 1.02), "{links:?}");
    assert!(
        mean(&plain.seams) >= 1.04,
        "a hard switch shows: {:?}",
        plain.seams
    );
    for (h, f) in plain.seams.iter().zip(&faded.seams) {
        assert!(f < h, "the fade lowers every link's seam: {h} -> {f}");
    }
    assert!(plain.sharpness.is_empty());
    assert!(mean(&faded.sharpness) >= 0.95, "{:?}", faded.sharpness);
}

/// Largest corner error of the scene's `H_(p,p+1)` against the truth, pixels.
fn corner_error(scene: &LoadedScene, truth: &RealScene) -> f64 {
    let mut worst: f64 = 0.0;
    for p in 0..scene.file.views.len() - 1 {
        let l = scene.file.views[p].to_next.as_ref().unwrap();
        let h = nalgebra::Matrix3::from_fn(|r, c| l.homography[r][c]);
        let e = truth.corner_error(p, p + 1, &h);
        if verbose() {
            eprintln!("link {p}: corner error {e:.3} px, {:?}", l.refinement);
        }
        worst = worst.max(e);
    }
    worst
}

#[test]
fn real_scene_with_marking_noise() {
    let tmp = tempfile::tempdir().unwrap();
    let real = real_scene(tmp.path(), "real", "2", "70");
    let scene = analyze_real(&real, &tmp.path().join("real-scene"), &[]);
    let within = transitions_within_one(&scene, &real.truth);
    let corner = corner_error(&scene, &real.truth);
    // Fractional q against the ideal view of the source frame shown.
    let psnrs = psnr_at_fractional_q(&scene, &real.truth, RenderParams::default());
    if verbose() {
        let other = RenderParams {
            gain_compensation: !RenderParams::default().gain_compensation,
            ..Default::default()
        };
        eprintln!(
            "PSNR with gain compensation {}: {:.2?}",
            other.gain_compensation,
            psnr_at_fractional_q(&scene, &real.truth, other)
        );
    }
    let min_psnr = psnrs.iter().cloned().fold(f64::INFINITY, f64::min);
    if verbose() {
        eprintln!(
            "real 5-view scene, 2 px marking noise: transitions within +-1: {:.1}%, corner error {corner:.3} px, PSNR at fractional q {psnrs:.2?}",
            100.0 * within
        );
    }
    assert!(within >= 0.95, "transitions within +-1 frame: {within}");
    assert!(corner <= 0.5, "corner error {corner} px");
    // Issue #10's target. Measured 35.26-36.46 dB from the lossless object store: the refined
    // points still carry about 2 / sqrt(5) px of marking error into x(q); where the shown view
    // does not see, the other view's matching frame fills in (34.46 dB worst without). The
    // default H.264 store (issue #21) costs 0.27 dB at the worst q at its finest quantiser
    // (34.99-36.07 dB), and 0.6 at the 40 dB quality target (issue #34): 34.67-35.66 dB. Each view
    // brought to the exposure at q instead of the views' common one: 35.40-35.83 dB.
    assert!(min_psnr >= 34.5, "PSNR at fractional q: {psnrs:?}");

    // Switch where it matches: along a slow sweep, the seams of the switches the player makes,
    // with eq. (6) as is and with bad switches postponed.
    let (thesis_mean, thesis_max, _) = switch_seams(&scene, SwitchPolicy::thesis());
    let (mean, max, postponed) = switch_seams(&scene, SwitchPolicy::default());
    if verbose() {
        eprintln!(
            "switch seams along a sweep: eq. (6) mean {thesis_mean:.2} max {thesis_max:.2}; postponed ({postponed} frames) mean {mean:.2} max {max:.2}"
        );
    }
    assert!(mean <= thesis_mean && max <= thesis_max.max(SwitchPolicy::default().max_seam));
}

/// Mean and largest seam score of the switches a player makes over a slow sweep 0 -> 4 -> 0
/// (0.05 views per frame), and the frames it postponed.
fn switch_seams(scene: &LoadedScene, policy: SwitchPolicy) -> (f64, f64, u64) {
    let mut player = Player::with_policy(policy);
    let mut seams = Vec::new();
    for i in 0..=160 {
        let q = if i <= 80 {
            i as f64 * 0.05
        } else {
            (160 - i) as f64 * 0.05
        };
        let c = player.advance(&scene.render, q).unwrap();
        if let (Step::Switch { .. }, Some((pv, next))) = (c.step, c.continuation) {
            let v = &scene.render.views[pv];
            let table = if c.view > pv {
                &v.to_next_seam
            } else {
                &v.to_prev_seam
            };
            seams.push(table[next - 1] as f64);
        }
    }
    assert!(!seams.is_empty(), "a sweep across 5 views switches");
    let mean = seams.iter().sum::<f64>() / seams.len() as f64;
    (
        mean,
        seams.iter().cloned().fold(0.0, f64::max),
        player.postponed_frames,
    )
}

#[test]
fn real_scene_exact_points_renders_the_ideal_view() {
    let tmp = tempfile::tempdir().unwrap();
    let real = real_scene(tmp.path(), "exact", "0", "70");
    let scene = analyze_real(&real, &tmp.path().join("exact-scene"), &[]);
    let psnrs = psnr_at_fractional_q(&scene, &real.truth, RenderParams::default());
    if verbose() {
        eprintln!("real 5-view scene, exact points: PSNR at fractional q {psnrs:.2?}");
    }
    // Exact points fit an affine map to 0.3-0.4 px, so GRIC picks affine; the backgrounds then
    // ask for the homography (5% lower photometric error), which lifts 33.6-34.4 dB to 35.3+
    // (the store at its finest quantiser; at the default 40 dB target, 34.73-35.76).
    assert!(
        psnrs.iter().all(|&p| p >= 34.6),
        "PSNR at fractional q: {psnrs:?}"
    );
    assert!(transitions_within_one(&scene, &real.truth) >= 0.95);
}

/// PSNR of the first rendered frame at several fractional q against the ideal view of the
/// source frame it shows, where the ideal view sees the texture.
fn psnr_at_fractional_q(scene: &LoadedScene, truth: &RealScene, params: RenderParams) -> Vec<f64> {
    let mut psnrs = Vec::new();
    for q in [0.5, 1.25, 2.5, 3.5] {
        let frames = play(scene, params, |_| q, 1);
        let (c, img) = &frames[0];
        let ideal = truth.ideal(q, truth.source_index(c.view, c.frame));
        // Compare where the ideal view sees the texture (it is black outside).
        let inside = vt_core::Mask::from_fn(ideal.width(), ideal.height(), |x, y| {
            ideal.get_pixel(x, y).0 != [0, 0, 0]
        });
        psnrs.push(vt_core::metrics::psnr(img, &ideal, Some(&inside)).unwrap());
    }
    psnrs
}
