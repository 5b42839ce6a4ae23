//! Golden renders: a small synthetic scene, analysed by the real binary and rendered in-process at
//! a few viewpoints, compared with PNGs kept in `testdata/golden/`. They pin the output so that a
//! change in analysis or rendering shows up as a failing test naming the render, with the
//! difference written beside the build (`target/golden-diff/`), rather than silently; accuracy
//! against truth is checked elsewhere (tests/render.rs). After a change that is meant to alter the
//! output, look at the diff images and regenerate: `REGENERATE=1 cargo test -p vt-cli --test golden`.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use image::RgbImage;
use vt_core::render::RenderParams;
use vt_io::scene::LoadedScene;

/// Largest per-channel difference a golden render may show (rounding in float arithmetic that
/// differs between compilers or CPUs), and the share of values allowed to differ at all.
const MAX_DIFF: u8 = 2;
const MAX_DIFFERING: f64 = 0.001;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/golden")
}

fn diff_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target"))
        .join("golden-diff")
}

/// Compares `got` with the golden image `name`; with `REGENERATE=1`, rewrites the golden instead.
/// On failure writes `got`, the golden and their difference (x16) and names the operation.
fn compare_to_golden(name: &str, op: &str, got: &RgbImage) {
    let path = golden_dir().join(name);
    if std::env::var_os("REGENERATE").is_some() {
        std::fs::create_dir_all(golden_dir()).unwrap();
        got.save(&path).unwrap();
        eprintln!("regenerated {}", path.display());
        return;
    }
    let want = image::open(&path)
        .unwrap_or_else(|e| {
            panic!(
                "{op}: golden {} unreadable ({e}); run with REGENERATE=1",
                path.display()
            )
        })
        .to_rgb8();
    assert_eq!(
        want.dimensions(),
        got.dimensions(),
        "{op}: size differs from {name}"
    );
    let (mut max, mut differ) = (0u8, 0usize);
    for (a, b) in got.as_raw().iter().zip(want.as_raw()) {
        let d = a.abs_diff(*b);
        max = max.max(d);
        differ += (d > 0) as usize;
    }
    let share = differ as f64 / got.as_raw().len() as f64;
    if max > MAX_DIFF || share > MAX_DIFFERING {
        let dir = diff_dir();
        std::fs::create_dir_all(&dir).unwrap();
        let stem = name.trim_end_matches(".png");
        got.save(dir.join(format!("{stem}-got.png"))).unwrap();
        want.save(dir.join(format!("{stem}-golden.png"))).unwrap();
        let diff = RgbImage::from_fn(got.width(), got.height(), |x, y| {
            let (a, b) = (got.get_pixel(x, y).0, want.get_pixel(x, y).0);
            image::Rgb([0, 1, 2].map(|c| a[c].abs_diff(b[c]).saturating_mul(16)))
        });
        diff.save(dir.join(format!("{stem}-diff.png"))).unwrap();
        panic!(
            "{op}: differs from golden {name}: max |diff| {max} (tolerance {MAX_DIFF}), \
             {:.3}% of values differ (tolerance {:.1}%); images in {}",
            100.0 * share,
            100.0 * MAX_DIFFERING,
            dir.display()
        );
    }
}

/// The first frame a fresh player shows at `q`.
fn render(scene: &LoadedScene, q: f64, params: RenderParams) -> RgbImage {
    first_frame(scene, q, params).1
}

#[test]
fn renders_match_their_goldens() {
    let tmp = tempfile::tempdir().unwrap();
    let syn = synth(
        tmp.path(),
        "golden",
        &[
            "--views", "3", "--frames", "72", "--size", "160x96", "--period", "12", "--seed", "5",
        ],
    );
    let dir = tmp.path().join("golden-scene");
    // The goldens pin the renderer, so its input is the lossless store: the default H.264
    // store's error is measured against the raw frames on its own (vt-io's store tests).
    analyze(
        &syn,
        &dir,
        &["--min-length", "24", "--store-quality", "lossless"],
    );
    let scene = LoadedScene::open(&dir).unwrap();
    for q in [0.0, 0.5, 1.37, 2.0] {
        let name = format!("render_q{q}.png");
        compare_to_golden(
            &name,
            &format!("render q = {q}, default parameters"),
            &render(&scene, q, RenderParams::default()),
        );
    }
    let nearest = RenderParams {
        interpolation: vt_core::warp::Interpolation::Nearest,
        ..RenderParams::default()
    };
    compare_to_golden(
        "render_q1.37_nearest.png",
        "render q = 1.37, nearest",
        &render(&scene, 1.37, nearest),
    );
}
