//! The field's benchmark for System B's own setting: the NeRF synthetic lego scene from the
//! sparse-view protocol's 8 training views, scored on its 25 test views over white, beside the
//! published figures; and what the stereo carving's knobs trade there.

use anyhow::Result;
use serde_json::json;
use vt_fv::dataset::{DataOptions, Dataset, ModelParams, TestSummary};
use vt_fv::pipeline::ViewParams;
use vt_fv::stereo::StereoParams;

use crate::report::model::{Item, Table};
use crate::report::Ctx;

/// Published PSNR / SSIM on this protocol (FSGS, ECCV 2024, Table 3; DropGaussian, CVPR 2025,
/// Table 3; as listed in testdata/nerf-lego/README.md).
const PUBLISHED: [(&str, f64, f64); 10] = [
    ("Mip-NeRF", 20.89, 0.830),
    ("3DGS", 21.56, 0.847),
    ("DietNeRF", 22.50, 0.823),
    ("RegNeRF", 23.86, 0.852),
    ("SparseNeRF", 24.04, 0.876),
    ("FreeNeRF", 24.26, 0.883),
    ("DNGaussian", 24.31, 0.886),
    ("CoR-GS", 24.43, 0.896),
    ("FSGS", 24.64, 0.895),
    ("DropGaussian", 25.42, 0.888),
];

/// The training and test sets, the test set cut to its first `views` views.
fn load(views: usize) -> Result<(Dataset, Dataset)> {
    let dir = crate::report::testdata().join("nerf-lego");
    let train = Dataset::load(&dir, &DataOptions::default())?;
    let mut test = Dataset::load_set(&dir.join("transforms_test.json"), &DataOptions::default())?;
    test.cams.truncate(views);
    test.images.truncate(views);
    test.masks.truncate(views);
    test.score_masks.truncate(views);
    Ok((train, test))
}

/// Builds the model with `model`, scores every test view, and times both.
fn measure(
    train: &Dataset,
    test: &Dataset,
    model: &ModelParams,
    view: &ViewParams,
) -> Result<TestSummary> {
    let t = std::time::Instant::now();
    let (m, _) = train.build_without(None, model, &mut |_, _, _| {})?;
    let model_secs = t.elapsed().as_secs_f64();
    let (views, _) = train.score_test_set(&m, test, view, &mut |_| {})?;
    Ok(TestSummary::new(
        view.name(),
        train.background,
        train.cams.len(),
        model_secs,
        views,
    ))
}

fn benchmark(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let n = ctx.pick(5, 25);
    let (train, test) = load(n)?;
    let mut t = Table::new(
        "benchmark-lego",
        "System B on the field's benchmark: NeRF synthetic lego, 8 views",
        format!(
            "testdata/nerf-lego: the sparse-view protocol's 8 training views (r_26 r_86 r_2 \
             r_55 r_75 r_93 r_16 r_73, 400x400 RGBA, composited over white) and {n} of its 25 \
             test views, scored on the whole image over white as the papers do (PSNR over RGB, \
             SSIM as the mean over RGB channels, 11x11 Gaussian windows); `vt fv eval \
             testdata/nerf-lego --test transforms_test.json` prints the same row. 'inside' \
             scores inside the test view's alpha >= 128; IoU is the new view's coverage against \
             it. Published rows are the papers' own figures (GPU training for minutes to \
             hours); vt's model and view times are this machine's, 2 cores."
        ),
        &[
            "method",
            "PSNR (dB)",
            "SSIM",
            "inside PSNR (dB)",
            "coverage IoU mean",
            "coverage IoU worst",
            "model (s)",
            "a view (s)",
        ],
    );
    for (name, p, s) in PUBLISHED {
        t.row(vec![
            json!(format!("{name} (published)")),
            json!(p),
            json!(s),
            json!(null),
            json!(null),
            json!(null),
            json!(null),
            json!(null),
        ]);
    }
    let view = ViewParams::default();
    let default = measure(&train, &test, &ModelParams::default(), &view)?;
    let hull = measure(
        &train,
        &test,
        &ModelParams {
            stereo: false,
            ..Default::default()
        },
        &view,
    )?;
    let row = |name: &str, s: &TestSummary| {
        vec![
            json!(name),
            json!(s.whole.psnr),
            json!(s.whole.ssim),
            json!(s.inside.psnr),
            json!(s.coverage_iou),
            json!(s.coverage_iou_worst),
            json!(s.model_secs),
            json!(s.view_secs_median),
        ]
    };
    t.row(row(
        "vt default (PatchMatch-carved hull, depth clip, textured)",
        &default,
    ));
    t.row(row("vt --no-stereo (photo hull, textured)", &hull));
    for (name, sc) in [
        ("baseline: vt's rough render", default.rough),
        (
            "baseline: the nearest training photo",
            default.nearest_photo,
        ),
    ] {
        t.row(vec![
            json!(name),
            json!(sc.psnr),
            json!(sc.ssim),
            json!(null),
            json!(null),
            json!(null),
            json!(null),
            json!(null),
        ]);
    }

    // The stereo carving's knobs, one at a time from the default.
    let mut k = Table::new(
        "benchmark-stereo-knobs",
        "System B: the stereo carving's knobs on the lego benchmark",
        format!(
            "Each row changes one setting of `StereoParams` from vt's default and rebuilds the \
             model from the 8 views; scored on {n} test views as above. Time is the model's \
             (visual hull, stereo carving, photo hull) on this machine, a view's the median over the \
             test views; the last rows change the view's settings instead."
        ),
        &[
            "setting",
            "PSNR (dB)",
            "SSIM",
            "coverage IoU mean",
            "model (s)",
            "view (s, median)",
        ],
    );
    let d = StereoParams::default();
    // The default's row is the model measured above, not built again.
    let knob_row = |name: &str, s: &TestSummary| {
        vec![
            json!(name),
            json!(s.whole.psnr),
            json!(s.whole.ssim),
            json!(s.coverage_iou),
            json!(s.model_secs),
            json!(s.view_secs_median),
        ]
    };
    k.row(knob_row("default", &default));
    let mut settings: Vec<(String, StereoParams)> = Vec::new();
    if !ctx.quick {
        settings.extend([
            ("1 pass".into(), StereoParams { passes: 1, ..d }),
            ("3 passes".into(), StereoParams { passes: 3, ..d }),
            (
                "depth every pixel".into(),
                StereoParams { pixel_step: 1, ..d },
            ),
            (
                "no fine iterations (depth every 2 pixels)".into(),
                StereoParams { fine: 0, ..d },
            ),
            ("1 fine iteration".into(), StereoParams { fine: 1, ..d }),
            (
                "no hole filling for the carving".into(),
                StereoParams { hole_fill: 0, ..d },
            ),
            (
                "plane sweep, not PatchMatch".into(),
                StereoParams { patchmatch: 0, ..d },
            ),
            (
                "PatchMatch 6 iterations".into(),
                StereoParams { patchmatch: 6, ..d },
            ),
            (
                "colour windows, NCC 0.3".into(),
                StereoParams {
                    colour: true,
                    min_ncc: 0.3,
                    ..d
                },
            ),
            (
                "no geometric round".into(),
                StereoParams { geo_iters: 0, ..d },
            ),
            (
                "window 7x7 every pixel".into(),
                StereoParams { stride: 1, ..d },
            ),
            (
                "plane sweep, distinct 0.2".into(),
                StereoParams {
                    patchmatch: 0,
                    distinct: 0.2,
                    ..d
                },
            ),
            (
                "2 confirmations".into(),
                StereoParams {
                    confirmations: 2,
                    ..d
                },
            ),
            ("margin 3 voxels".into(), StereoParams { margin: 3.0, ..d }),
            (
                "the best source's NCC alone".into(),
                StereoParams { best: 1, ..d },
            ),
            (
                "no surface protection".into(),
                StereoParams { protect: 0.0, ..d },
            ),
            (
                "unseen voxels kept".into(),
                StereoParams {
                    unseen_keep: None,
                    ..d
                },
            ),
            (
                "unseen kept within 8".into(),
                StereoParams {
                    unseen_keep: Some(8),
                    ..d
                },
            ),
        ]);
    }
    for (name, sp) in settings {
        let s = measure(
            &train,
            &test,
            &ModelParams {
                stereo_params: sp,
                ..Default::default()
            },
            &ViewParams::default(),
        )?;
        k.row(knob_row(&name, &s));
    }
    if !ctx.quick {
        // The view's clip to the depth maps' free space (the default model).
        let s = measure(
            &train,
            &test,
            &ModelParams::default(),
            &ViewParams {
                depth_clip: None,
                ..Default::default()
            },
        )?;
        k.row(knob_row("no depth clip in the view", &s));
        // The texturing's registration to each reference's own depth map.
        let mut view = ViewParams::default();
        view.texture.snap = 0.0;
        let s = measure(&train, &test, &ModelParams::default(), &view)?;
        k.row(knob_row("no snapping to the photos' depth maps", &s));
        // The splat depth box-filtered before the refinement (the default before the snapping).
        let mut view = ViewParams::default();
        view.texture.depth_smooth = 2;
        let s = measure(&train, &test, &ModelParams::default(), &view)?;
        k.row(knob_row("splat depth smoothed over 5x5 px", &s));
        // The silhouette clip as for real photos (closed, 1 px of slack) although lego's agree
        // exactly.
        let s = measure(
            &train,
            &test,
            &ModelParams::default(),
            &ViewParams {
                clip: Some(vt_fv::render::ClipParams {
                    exact: false,
                    ..Default::default()
                }),
                ..Default::default()
            },
        )?;
        k.row(knob_row("clip closed with 1 px slack (not raw)", &s));
    }
    Ok(vec![Item::Table(t), Item::Table(k)])
}

/// Builds the section.
pub fn build(ctx: &mut Ctx) -> Result<Vec<Item>> {
    benchmark(ctx)
}
