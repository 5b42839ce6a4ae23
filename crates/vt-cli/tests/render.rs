//! Rendering (System A online) against ray-cast truth, continuity in q, a single view, and bad
//! input. Scenes are made and analysed by the real binary; the renders are checked in-process
//! (vt-core's Player and Renderer over vt-io's loaded scene) so the source frame, and so the
//! true motion phase, of every output frame is known. Truth images come from vt-synth's ray
//! caster, never from vt-core's warps.

mod common;

use std::path::Path;

use common::*;
use image::RgbImage;
use vt_core::render::{Player, RenderParams, Renderer};
use vt_io::scene::LoadedScene;
use vt_synth::{TextureParams, TextureScene};

fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    vt_core::metrics::psnr(a, b, None).unwrap()
}

fn max_abs_diff(a: &RgbImage, b: &RgbImage) -> u8 {
    a.as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(&x, &y)| x.abs_diff(y))
        .max()
        .unwrap_or(0)
}

/// A synthetic scene, analysed; returns the scene directory and the truth generator.
fn scene(root: &Path, name: &str, extra: &[&str]) -> (std::path::PathBuf, TextureScene) {
    let mut args = vec![
        "--views", "3", "--frames", "72", "--size", "160x96", "--period", "12", "--seed", "5",
    ];
    args.extend_from_slice(extra);
    let syn = synth(root, name, &args);
    let out = root.join(format!("{name}-scene"));
    analyze(&syn, &out, &["--min-length", "24"]);
    let truth = read_json(&syn.dir.join("truth.json"));
    let params: TextureParams = serde_json::from_value(truth["params"].clone()).unwrap();
    (out, TextureScene::new(params).unwrap())
}

/// PSNR of the render at `q` (first frame of a fresh player) against the ray-cast truth at the
/// same viewpoint and the source frame's true phase.
fn psnr_at(scene: &LoadedScene, synth: &TextureScene, q: f64, params: RenderParams) -> f64 {
    let (choice, out) = first_frame(scene, q, params);
    let truth = synth.truth(q, synth.phase_of(choice.view, choice.frame));
    if let Some(d) = std::env::var_os("VT_DUMP") {
        let d = Path::new(&d);
        out.save(d.join(format!("render_q{q}.png"))).unwrap();
        truth.save(d.join(format!("truth_q{q}.png"))).unwrap();
    }
    psnr(&out, &truth)
}

#[test]
fn planar_scene_renders_match_ray_cast_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, synth) = scene(tmp.path(), "planar", &["--planar", "--exposure", "0"]);
    let loaded = LoadedScene::open(&dir).unwrap();
    for q in [0.0, 0.25, 0.5, 0.8, 1.0, 1.37, 1.5, 2.0] {
        let p = psnr_at(&loaded, &synth, q, RenderParams::default());
        eprintln!("planar q={q}: {p:.2} dB");
        assert!(p >= 35.0, "planar scene at q={q}: {p:.2} dB < 35 dB");
    }
    // The background with real depth cannot be explained by one plane: state the figure.
    let (dir, synth) = scene(tmp.path(), "depth", &["--exposure", "0"]);
    let loaded = LoadedScene::open(&dir).unwrap();
    let figures: Vec<String> = [0.5, 1.0, 1.5]
        .iter()
        .map(|&q| {
            format!(
                "q={q}: {:.2} dB",
                psnr_at(&loaded, &synth, q, RenderParams::default())
            )
        })
        .collect();
    eprintln!(
        "non-planar scene (off-plane parallax): {}",
        figures.join(", ")
    );
}

/// With gain compensation, q = p shows view p as taken and a view between two takes lies between
/// their exposures, as a camera there would record it (the truth's `exposure_at`; the real line
/// scenes' held-out views agree, `tests/depth.rs`). Views up to 10 % apart in exposure: 43.0-43.3
/// dB; renders at the views' common exposure (before) scored 36.9-41.9 dB here.
#[test]
fn renders_keep_the_exposure_of_the_views_around_q() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, synth) = scene(tmp.path(), "exposure", &["--planar", "--exposure", "0.1"]);
    let loaded = LoadedScene::open(&dir).unwrap();
    for q in [0.0, 0.5, 1.0, 1.37, 2.0] {
        let p = psnr_at(&loaded, &synth, q, RenderParams::default());
        eprintln!("planar, 10 % exposure spread, q={q}: {p:.2} dB");
        assert!(p >= 42.0, "q={q}: {p:.2} dB < 42 dB");
    }
}

#[test]
fn renders_are_continuous_in_q() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, _) = scene(tmp.path(), "cont", &["--planar"]);
    let loaded = LoadedScene::open(&dir).unwrap();
    let mut renderer = Renderer::new(loaded.render.clone(), RenderParams::default()).unwrap();
    let (w, h) = renderer.size();
    let (mut a, mut b) = (RgbImage::new(w, h), RgbImage::new(w, h));
    // Same source frame, q and q + 1e-6: the background blend and the warp move by 1e-6.
    for q in [0.0, 0.3, 1.0 - 1e-6, 1.0, 1.2, 2.0 - 1e-6] {
        let choice = Player::new().advance(&loaded.render, q).unwrap();
        renderer
            .render_into(&loaded.objects, q, &choice, &mut a)
            .unwrap();
        renderer
            .render_into(&loaded.objects, q + 1e-6, &choice, &mut b)
            .unwrap();
        let d = max_abs_diff(&a, &b);
        assert!(
            d <= 1,
            "q={q}: renders at q and q+1e-6 differ by up to {d} grey levels"
        );
    }
    // At the 0.5 tie the object's source switches view through the transition table; from the
    // same history, the two sides must show the same motion phase, so they differ only by what the
    // two views disagree on (noise, exposure, resampling).
    for tie in [0.5, 1.5] {
        let mut left = Player::new();
        let start = left.advance(&loaded.render, tie - 0.3).unwrap();
        let mut right = left.clone();
        let cl = left.advance(&loaded.render, tie - 1e-6).unwrap();
        let cr = right.advance(&loaded.render, tie).unwrap();
        assert_ne!(cl.view, cr.view, "the tie switches view");
        renderer
            .render_into(&loaded.objects, tie - 1e-6, &cl, &mut a)
            .unwrap();
        renderer
            .render_into(&loaded.objects, tie, &cr, &mut b)
            .unwrap();
        let p = psnr(&a, &b);
        eprintln!(
            "tie {tie}: from view {} frame {}: {cl:?} vs {cr:?}: {p:.2} dB",
            start.view, start.frame
        );
        assert!(p >= 30.0, "across the tie at q={tie}: {p:.2} dB");
    }
}

#[test]
fn gain_compensation_removes_the_exposure_jump() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, synth) = scene(tmp.path(), "gain", &["--planar", "--exposure", "0.1"]);
    let loaded = LoadedScene::open(&dir).unwrap();
    let gains = Renderer::new(
        loaded.render.clone(),
        RenderParams {
            gain_compensation: true,
            ..Default::default()
        },
    )
    .unwrap()
    .gains()
    .to_vec();
    // Estimated relative gains match the true ones (up to the common factor).
    let truth = synth.gains();
    for p in 1..3 {
        for c in 0..3 {
            let est = gains[p][c] / gains[0][c];
            let want = (truth[p] / truth[0]) as f32;
            assert!(
                (est - want).abs() < 0.01,
                "view {p} channel {c}: gain ratio {est} vs true {want}"
            );
        }
    }
    // Brightness jump across the tie: smaller with compensation.
    let jump = |comp: bool| {
        let mut r = Renderer::new(
            loaded.render.clone(),
            RenderParams {
                gain_compensation: comp,
                ..Default::default()
            },
        )
        .unwrap();
        let (w, h) = r.size();
        let (mut a, mut b) = (RgbImage::new(w, h), RgbImage::new(w, h));
        let mut left = Player::new();
        left.advance(&loaded.render, 0.2).unwrap();
        let mut right = left.clone();
        let cl = left.advance(&loaded.render, 0.5 - 1e-6).unwrap();
        let cr = right.advance(&loaded.render, 0.5).unwrap();
        r.render_into(&loaded.objects, 0.5 - 1e-6, &cl, &mut a)
            .unwrap();
        r.render_into(&loaded.objects, 0.5, &cr, &mut b).unwrap();
        psnr(&a, &b)
    };
    let (off, on) = (jump(false), jump(true));
    eprintln!("across the tie with 10% exposure spread: {off:.2} dB plain, {on:.2} dB compensated");
    assert!(
        on > off + 1.0,
        "compensation should help: {off:.2} -> {on:.2} dB"
    );
}

#[test]
fn single_view_renders_without_switching() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi");
    let scene = tmp.path().join("tree");
    vt_ok(&[
        "analyze",
        s(&tree),
        "--out",
        s(&scene),
        "--min-length",
        "20",
    ]);
    let out = tmp.path().join("frames");
    let stdout = vt_ok(&[
        "render",
        s(&scene),
        "--path",
        "sweep",
        "--duration",
        "3",
        "--fps",
        "20",
        "--out",
        s(&out),
    ]);
    assert!(
        stdout.contains("rendered 60 frames") && stdout.contains("0 view switches"),
        "{stdout}"
    );
    assert_eq!(count_pngs(&out), 60);
    // 60 frames of a loop shorter than 60 frames wrap at least once.
    let l = &read_json(&scene.join("scene.json"))["views"][0]["loop"];
    if l["end"].as_u64().unwrap() - l["start"].as_u64().unwrap() < 59 {
        assert!(!stdout.contains(" 0 loop wraps"), "{stdout}");
    }
}

#[test]
fn render_outputs_and_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (dir, _) = scene(t, "out", &[]);
    let d = s(&dir);
    // Every output kind, from every path kind.
    let qfile = t.join("qs.txt");
    std::fs::write(&qfile, "0\n0.5\n# comment\n1.25\n2\n").unwrap();
    let at = format!("@{}", s(&qfile));
    for (path, out, frames) in [
        ("0s:0,1s:2,2s:0", "a.mp4", 20),
        ("sweep:4", "b.gif", 10),
        (at.as_str(), "c", 4),
    ] {
        let o = t.join(out);
        let stdout = vt_ok(&["render", d, "--path", path, "--fps", "10", "--out", s(&o)]);
        assert!(
            stdout.contains(&format!("rendered {frames} frames")),
            "{path}: {stdout}"
        );
        assert!(o.exists());
    }
    assert_eq!(count_pngs(&t.join("c")), 4);

    // The ownership mark cannot be copied: vt's own mp4 is replaced, a copy or an ffmpeg remux
    // of it under another name (which keeps its metadata, vt's mark included) is refused.
    let a = t.join("a.mp4");
    let (copy, remux) = (t.join("copy.mp4"), t.join("remux.mp4"));
    std::fs::copy(&a, &copy).unwrap();
    let status = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-i", s(&a), "-c", "copy", s(&remux)])
        .status()
        .expect("run ffmpeg");
    assert!(status.success());
    for other in [&copy, &remux] {
        let before = std::fs::read(other).unwrap();
        assert!(
            before.windows(9).any(|w| w == b"vt-output"),
            "{} carries vt's mark",
            s(other)
        );
        vt_err(
            &["render", d, "--path", "sweep:4", "--out", s(other)],
            &[s(other)],
        );
        assert_eq!(
            std::fs::read(other).unwrap(),
            before,
            "{} untouched",
            s(other)
        );
    }
    vt_ok(&[
        "render",
        d,
        "--path",
        "sweep:4",
        "--fps",
        "10",
        "--out",
        s(&a),
    ]);

    let out = t.join("never.mp4");
    vt_err(
        &["render", d, "--path", "0s:0,1s:5", "--out", s(&out)],
        &["outside [0, 2]"],
    );
    vt_err(
        &["render", d, "--path", "sweep", "--out", s(&t.join("x.avi"))],
        &["unknown output extension", ".avi"],
    );
    vt_err(
        &[
            "render",
            s(&t.join("nope")),
            "--path",
            "sweep",
            "--out",
            s(&out),
        ],
        &["nope", "not a scene"],
    );
    // An older format version, then corruption, each with a clear line.
    let json = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    std::fs::write(
        dir.join("scene.json"),
        json.replace("\"version\": 1", "\"version\": 0"),
    )
    .unwrap();
    vt_err(
        &["render", d, "--path", "sweep", "--out", s(&out)],
        &["version 0", "reads version 1"],
    );
    std::fs::write(dir.join("scene.json"), &json[..json.len() / 2]).unwrap();
    vt_err(
        &["render", d, "--path", "sweep", "--out", s(&out)],
        &["scene.json", "corrupted"],
    );
    std::fs::write(dir.join("scene.json"), &json).unwrap();
    let obj = dir.join("objects_001.bin");
    let bytes = std::fs::read(&obj).unwrap();
    std::fs::write(&obj, &bytes[..bytes.len() - 7]).unwrap();
    vt_err(
        &["render", d, "--path", "sweep", "--out", s(&out)],
        &["objects_001.bin", "corrupted"],
    );
    assert!(!out.exists(), "no output after a failure");
    let leftovers: Vec<_> = std::fs::read_dir(t)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".vt-tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// `--crf` sets the mp4's fidelity: decoded back, CRF 0 is within a few dB of the exact PNG
/// frames' ceiling (4:2:0 chroma) and clearly closer to them than CRF 40, which is smaller.
#[test]
fn crf_trades_mp4_size_for_fidelity() {
    if !vt_io::video::ffmpeg_available() {
        println!("skipped: ffmpeg is not installed");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (dir, _) = scene(t, "crf", &[]);
    let d = s(&dir);
    let args = |out: &Path, crf: Option<&str>| {
        let mut a = vec!["render", d, "--path", "sweep:4", "--fps", "10"];
        if let Some(c) = crf {
            a.extend(["--crf", c]);
        }
        vt_ok(&[a, vec!["--out", s(out)]].concat());
    };
    let exact = t.join("png");
    args(&exact, None);
    let truth = vt_io::frames::ViewSource::open(&exact)
        .unwrap()
        .read_all()
        .unwrap();
    let mut seen = Vec::new();
    for crf in ["0", "40"] {
        let out = t.join(format!("crf{crf}.mp4"));
        args(&out, Some(crf));
        let frames = vt_io::frames::ViewSource::open(&out)
            .unwrap()
            .read_all()
            .unwrap();
        assert_eq!(frames.len(), truth.len(), "crf {crf}");
        let mean = frames
            .iter()
            .zip(&truth)
            .map(|(a, b)| psnr(a, b))
            .sum::<f64>()
            / truth.len() as f64;
        seen.push((mean, std::fs::metadata(&out).unwrap().len()));
    }
    let [(best, big), (worst, small)] = seen[..] else {
        unreachable!()
    };
    assert!(best > 36.0, "crf 0: {best:.1} dB");
    assert!(
        best > worst + 3.0,
        "crf 0 {best:.1} dB vs crf 40 {worst:.1} dB"
    );
    assert!(big > small, "crf 0 {big} bytes vs crf 40 {small}");
}

/// Mean absolute difference between two frames, grey levels.
fn mad(a: &RgbImage, b: &RgbImage) -> f64 {
    a.as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(&x, &y)| x.abs_diff(y) as f64)
        .sum::<f64>()
        / a.as_raw().len() as f64
}

#[test]
fn crossfade_softens_real_loop_wraps() {
    // tree.avi's thesis loops are real, imperfect seams: the wrap is a visible jump without
    // crossfade. (The default per-region loop wraps within an ordinary step: real_scene.rs.)
    let tmp = tempfile::tempdir().unwrap();
    let tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi");
    let dir = tmp.path().join("tree");
    vt_ok(&[
        "analyze",
        s(&tree),
        "--out",
        s(&dir),
        "--min-length",
        "20",
        "--loops",
        "single",
    ]);
    let loaded = LoadedScene::open(&dir).unwrap();
    // Largest frame-to-frame change within 2 frames of each wrap, and the median ordinary step.
    let measure = |crossfade: usize| {
        let params = RenderParams {
            crossfade,
            ..Default::default()
        };
        let mut r = Renderer::new(loaded.render.clone(), params).unwrap();
        let (w, h) = r.size();
        let mut player = Player::new();
        let (mut prev, mut cur) = (RgbImage::new(w, h), RgbImage::new(w, h));
        let (mut steps, mut wrap_steps) = (Vec::new(), Vec::new());
        let mut since_wrap = usize::MAX;
        for i in 0..70 {
            let c = player.advance(&loaded.render, 0.0).unwrap();
            if c.step == vt_core::render::Step::Wrap {
                since_wrap = 0;
            }
            r.render_into(&loaded.objects, 0.0, &c, &mut cur).unwrap();
            if i > 0 {
                let d = mad(&prev, &cur);
                if since_wrap <= 2 {
                    wrap_steps.push(d);
                } else {
                    steps.push(d);
                }
            }
            since_wrap = since_wrap.saturating_add(1);
            std::mem::swap(&mut prev, &mut cur);
        }
        steps.sort_by(f64::total_cmp);
        let worst_wrap = wrap_steps.iter().copied().fold(0.0, f64::max);
        (worst_wrap, steps[steps.len() / 2], player.wraps)
    };
    let (plain, ordinary, wraps) = measure(0);
    let (faded, _, _) = measure(3);
    eprintln!(
        "tree.avi, {wraps} wraps: largest step near a wrap {plain:.3} plain, {faded:.3} with a 3-frame crossfade; median ordinary step {ordinary:.3} (grey levels)"
    );
    assert!(wraps >= 2);
    assert!(
        faded < plain,
        "crossfade should soften the wrap: {plain:.3} -> {faded:.3}"
    );
}

#[test]
fn loaded_scene_holds_each_transition_table_once() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, _) = scene(tmp.path(), "once", &[]);
    let on_disk = vt_io::scene::SceneFile::read(&dir).unwrap();
    let loaded = LoadedScene::open(&dir).unwrap();
    for (p, (file, view)) in on_disk.views.iter().zip(&loaded.render.views).enumerate() {
        let t = &file.transitions;
        assert!(
            t.next.iter().chain(&t.prev).any(Option::is_some),
            "view {p}: no tables"
        );
        assert_eq!(
            (&view.to_next, &view.to_prev),
            (&t.next, &t.prev),
            "view {p}"
        );
        assert_eq!(view.to_next_seam, t.next_seam, "view {p}");
        assert_eq!(view.to_prev_seam, t.prev_seam, "view {p}");
        // Moved, not copied: the loaded file keeps none.
        let kept = &loaded.file.views[p].transitions;
        assert!(
            kept.next.is_empty() && kept.prev.is_empty(),
            "view {p}: tables held twice"
        );
        assert!(kept.next_seam.is_empty() && kept.prev_seam.is_empty());
    }
}

/// Issue #37: `vt render --cycle` writes one cycle of tree.avi's loop (frames 0-53, the default
/// per-region loop) that repeats seamlessly: the file twice over is what the player shows over
/// two cycles, frame for frame, and its join (last frame to first) is no larger than the median
/// ordinary step, measured here on the written frames; mp4 and GIF hold the same frame count,
/// and the mp4 plays on repeat as a looping `<video>` in headless Chromium.
#[test]
fn one_cycle_files_repeat_seamlessly() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi");
    let clip = dir.join("frames0-53");
    std::fs::create_dir(&clip).unwrap();
    let frames = vt_io::frames::ViewSource::open(&tree)
        .unwrap()
        .read_all()
        .unwrap();
    for (i, f) in frames.iter().take(54).enumerate() {
        f.save(clip.join(format!("{i:03}.png"))).unwrap();
    }
    let scene = dir.join("scene");
    vt_ok(&[
        "analyze",
        s(&clip),
        "--min-length",
        "20",
        "--out",
        s(&scene),
    ]);
    let l = &read_json(&scene.join("scene.json"))["views"][0]["loop"];
    let length = (l["end"].as_u64().unwrap() - l["start"].as_u64().unwrap()) as usize;

    let cycle = dir.join("cycle");
    let stdout = vt_ok(&[
        "render",
        s(&scene),
        "--path",
        "0s:0",
        "--cycle",
        "--out",
        s(&cycle),
    ]);
    assert!(
        stdout.contains(&format!("rendered {length} frames")),
        "{stdout}"
    );
    let read = |d: &Path| -> Vec<RgbImage> {
        let mut names: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .collect();
        names.sort();
        names
            .iter()
            .map(|p| image::open(p).unwrap().to_rgb8())
            .collect()
    };
    let one = read(&cycle);
    assert_eq!(one.len(), length);
    // The player over two cycles (and one frame) at the same viewpoint: the file, twice.
    let fps = read_json(&scene.join("scene.json"))["fps"].as_f64();
    let two = dir.join("two");
    let fps_arg = format!("{}", fps.unwrap_or(30.0));
    let secs = format!("{}", (2 * length) as f64 / fps.unwrap_or(30.0));
    vt_ok(&[
        "render",
        s(&scene),
        "--path",
        "0s:0",
        "--fps",
        &fps_arg,
        "--duration",
        &secs,
        "--out",
        s(&two),
    ]);
    let played = read(&two);
    assert!(played.len() >= 2 * length, "{} frames", played.len());
    for (i, f) in played.iter().take(2 * length).enumerate() {
        assert!(
            *f == one[i % length],
            "frame {i} differs from the cycle's frame {}",
            i % length
        );
    }
    // The join, measured as vt measures wraps: its step over the median ordinary step.
    let mut steps: Vec<f64> = one.windows(2).map(|w| mad(&w[0], &w[1])).collect();
    steps.sort_by(f64::total_cmp);
    let join = mad(&one[length - 1], &one[0]) / steps[steps.len() / 2];
    eprintln!(
        "one cycle of tree.avi 0-53: {length} frames, join {join:.3} ordinary steps; {stdout}"
    );
    assert!(join <= 1.0, "the file's join is {join:.3} ordinary steps");
    for ext in ["mp4", "gif", "apng"] {
        let file = dir.join(format!("cycle.{ext}"));
        vt_ok(&[
            "render",
            s(&scene),
            "--path",
            "0s:0",
            "--cycle",
            "--out",
            s(&file),
        ]);
        let probe = std::process::Command::new("ffprobe")
            .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
            .args(["-show_entries", "stream=nb_read_frames", "-of", "csv=p=0"])
            .arg(&file)
            .output()
            .unwrap();
        let n: usize = String::from_utf8_lossy(&probe.stdout)
            .trim()
            .parse()
            .unwrap();
        assert_eq!(n, length, "{ext}");
        if ext == "apng" {
            // Lossless, and marked to repeat forever: its frames are the cycle's own bytes.
            let raw = std::process::Command::new("ffmpeg")
                .args(["-v", "error", "-i"])
                .arg(&file)
                .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
                .output()
                .unwrap();
            let frame = one[0].as_raw().len();
            assert_eq!(raw.stdout.len(), length * frame);
            for (i, f) in raw.stdout.chunks(frame).enumerate() {
                assert!(f == one[i].as_raw().as_slice(), "apng frame {i}");
            }
            let bytes = std::fs::read(&file).unwrap();
            let actl = bytes.windows(4).position(|w| w == b"acTL").expect("acTL");
            let plays = u32::from_be_bytes(bytes[actl + 8..actl + 12].try_into().unwrap());
            assert_eq!(plays, 0, "the apng repeats forever");
        }
    }
    // The mp4 plays on repeat as a looping <video> in Chromium: at 20 fps (one cycle a
    // second) it wraps twice and never ends, with no media error.
    let fast = dir.join("fast.mp4");
    vt_ok(&[
        "render",
        s(&scene),
        "--path",
        "0s:0",
        "--cycle",
        "--fps",
        "20",
        "--out",
        s(&fast),
    ]);
    std::fs::write(
        dir.join("loop.html"),
        "<video id=v src=fast.mp4 muted loop autoplay playsinline></video><script>\n\
         window.wraps = 0; let last = 0; const v = document.getElementById('v');\n\
         v.addEventListener('timeupdate', () => { if (v.currentTime < last) wraps++; \
         last = v.currentTime; });\n</script>",
    )
    .unwrap();
    let profile = tempfile::tempdir().unwrap();
    match common::cdp::chromium_webgl(profile.path()) {
        None => eprintln!("skipped: the looping <video> check needs chromium, not installed"),
        Some(browser) => {
            let url = format!("file://{}", dir.join("loop.html").display());
            let mut page = common::cdp::Page::open(&browser.ws, &url);
            page.wait_until(
                "window.wraps >= 2 && !v.ended && v.error === null",
                "the one-cycle mp4 to loop twice",
                "JSON.stringify({wraps, t: v.currentTime, ended: v.ended, error: v.error && v.error.code, state: v.readyState})",
            );
        }
    }
    // Refused: a length of its own, a crossfade (a one-view scene has no moving viewpoint).
    for (extra, want) in [
        (vec!["--path", "0s:0", "--duration", "4"], "--duration"),
        (vec!["--path", "0s:0", "--crossfade", "2"], "--crossfade"),
    ] {
        let out = dir.join("refused");
        let mut args = vec!["render", s(&scene), "--cycle", "--out", s(&out)];
        args.extend(extra);
        vt_err(&args, &[want, "--cycle"]);
        assert!(!out.exists());
    }
}
