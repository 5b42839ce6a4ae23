//! vt-app's use cases against independent truth: a synthetic two-view scene (ray cast, exact
//! points) analysed in memory, rendered by `play` and by the `render` job (the same frames,
//! byte for byte), and parameters refused before any file is touched.

use std::path::Path;

use image::RgbImage;
use vt_app::analyze::{analyze_into, AnalyzeJob};
use vt_app::render::{render, RenderJob};
use vt_app::{Error, Silent};
use vt_core::analysis::{AnalyzeParams, MemorySource};
use vt_core::render::RenderParams;
use vt_io::scene::LoadedScene;
use vt_synth::{TextureParams, TextureScene};

/// A 2-view synthetic scene analysed into `dir` through vt analyze's sequence.
fn scene(dir: &Path) -> (TextureScene, vt_app::analyze::Analyzed) {
    let syn = TextureScene::new(TextureParams {
        views: 2,
        frames: 48,
        ..Default::default()
    })
    .unwrap();
    let mut sources: Vec<MemorySource> = (0..2)
        .map(|p| MemorySource {
            name: format!("view {p}"),
            frames: (0..48).map(|i| syn.frame(p, i)).collect(),
        })
        .collect();
    let mut refs: Vec<&mut dyn vt_core::analysis::FrameSource> = sources
        .iter_mut()
        .map(|s| s as &mut dyn vt_core::analysis::FrameSource)
        .collect();
    let mut params = AnalyzeParams::default();
    params.loops.min_length = 20;
    std::fs::create_dir_all(dir).unwrap();
    let done = analyze_into(
        dir,
        &mut refs,
        &syn.marked_points(),
        &params,
        Default::default(),
        Some(25.0),
        &mut Silent,
    )
    .unwrap();
    (syn, done)
}

#[test]
fn analysed_scene_renders_the_same_through_play_and_the_render_job() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let (syn, done) = scene(&dir);
    // The seams were measured on rendered frames and recorded in scene.json.
    let file = vt_io::scene::SceneFile::read(&dir).unwrap();
    // (JSON keeps it to the last bit or so: serde_json's default float parsing.)
    assert!((file.seam_score - done.scene.seam_score).abs() <= 1e-12 * done.scene.seam_score);
    assert!(file.seam_score.is_finite() && file.seam_score > 0.0);
    assert!(file.views.iter().all(|v| v.loop_seam > 0.0));
    assert_eq!(file.fps, Some(25.0));

    // play: every frame of a path across both views, with the player's choice.
    let loaded = LoadedScene::open(&dir).unwrap();
    let qs: Vec<f64> = (0..30).map(|i| i as f64 / 29.0).collect();
    let mut frames: Vec<RgbImage> = Vec::new();
    let mut views = Vec::new();
    let played = vt_app::play::play(
        &loaded,
        &qs,
        RenderParams::default(),
        &mut |f, c| -> vt_app::Result<()> {
            frames.push(f.clone());
            views.push((c.view, c.frame));
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(played.frames, 30);
    assert_eq!(frames.len(), 30);
    assert_eq!(played.switches, 1, "one switch from view 0 to view 1");
    assert_eq!(views.first().map(|v| v.0), Some(0));
    assert_eq!(views.last().map(|v| v.0), Some(1));
    // At q = 0 the render is view 0's camera: close to the ray-cast truth at that phase.
    let truth = syn.truth(0.0, syn.phase_of(0, views[0].1));
    let psnr = vt_core::metrics::psnr(&frames[0], &truth, None).unwrap();
    assert!(psnr > 25.0, "first frame {psnr:.1} dB against the truth");

    // The render job writes exactly play's frames (PNG folder: lossless).
    let path_file = tmp.path().join("path.txt");
    let text: Vec<String> = qs.iter().map(|q| q.to_string()).collect();
    std::fs::write(&path_file, text.join("\n")).unwrap();
    let out = tmp.path().join("frames");
    let job = RenderJob {
        scene: dir.clone(),
        path: format!("@{}", path_file.display()),
        out: out.clone(),
        fps: None,
        duration: None,
        long: false,
        cycle: false,
        params: RenderParams::default(),
        encode: Default::default(),
    };
    let rendered = render(&job, &mut Silent).unwrap();
    // The same playback, but for the time spent measuring (a timing).
    let untimed = |p: vt_app::play::Playback| vt_app::play::Playback {
        measure_secs: 0.0,
        ..p
    };
    assert_eq!(untimed(rendered.playback), untimed(played));
    assert!(played.measured >= 1, "the switch is measured");
    assert_eq!(rendered.fps, 25.0, "the scene's source frame rate");
    let mut names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    names.sort();
    assert_eq!(names.len(), frames.len());
    for (p, f) in names.iter().zip(&frames) {
        let written = image::open(p).unwrap().to_rgb8();
        assert!(written == *f, "{} differs from play's frame", p.display());
    }
}

#[test]
fn parameters_are_refused_by_name_before_any_file_is_touched() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("never");
    let job = RenderJob {
        scene: tmp.path().join("no-scene"),
        path: "sweep".into(),
        out: out.clone(),
        fps: None,
        duration: None,
        long: false,
        cycle: false,
        params: RenderParams {
            crossfade: vt_core::render::MAX_CROSSFADE + 1,
            ..Default::default()
        },
        encode: Default::default(),
    };
    match render(&job, &mut Silent) {
        Err(Error::Core(vt_core::Error::InvalidParameter { name, .. })) => {
            assert_eq!(name, "crossfade")
        }
        other => panic!("expected the crossfade refused, got {:?}", other.err()),
    }
    let mut params = AnalyzeParams::default();
    params.loops.window = 0;
    let analyze = AnalyzeJob {
        views: vec![tmp.path().join("missing.mp4")],
        points: None,
        out: out.clone(),
        params,
        fps: Some(-1.0),
        store: Default::default(),
    };
    match vt_app::analyze::analyze(&analyze, &mut Silent) {
        Err(Error::Core(vt_core::Error::InvalidParameter { name, .. })) => {
            assert_eq!(name, "loops.window")
        }
        other => panic!("expected the window refused, got {:?}", other.err()),
    }
    let analyze = AnalyzeJob {
        params: AnalyzeParams::default(),
        ..analyze
    };
    match vt_app::analyze::analyze(&analyze, &mut Silent) {
        Err(Error::Param { name, .. }) => assert_eq!(name, "fps"),
        other => panic!("expected the frame rate refused, got {:?}", other.err()),
    }
    assert!(!out.exists(), "nothing written");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
}
