//! Section 4: accuracy on real data. System A on a multi-view scene built from the real tree.avi
//! with known geometry and clock offsets (vt-synth's `RealScene`) next to the synthetic scene:
//! transitions within +-1 frame, loop wraps, homography corner error against marking noise.
//! System B leave-one-out on templeSparseRing: nearest photo, rough render, rough render
//! blurred (sigma 2), the paper's guided result and vt's default method, inside the withheld
//! photo's silhouette and over the whole image; on the real kettle (COLMAP cameras, automatic
//! silhouettes) against the blurred rough render; orbit steadiness on both.

use anyhow::Result;
use serde_json::json;
use vt_core::model::{select_model, ModelParams, MotionModel};
use vt_core::Point;
use vt_fv::dataset::ModelParams as FvModel;
use vt_fv::pipeline::{Scores, ViewParams};
use vt_fv::GuidedParams;
use vt_synth::real::{RealParams, RealScene};

use super::knobs_a::{circ, loop_phase_error, transition_phase_errors};
use super::timed;
use crate::report::data::{build_scene, real, synth_a, temple, tree};
use crate::report::model::{Gallery, Item, Table};
use crate::report::Ctx;

fn pts(v: &[(f64, f64)]) -> Vec<Point> {
    v.iter().map(|&(x, y)| Point::new(x, y)).collect()
}

/// The real-footage scene's parameters.
pub fn real_params(quick: bool) -> RealParams {
    RealParams {
        views: if quick { 3 } else { 5 },
        frames: if quick { 80 } else { 120 },
        ..Default::default()
    }
}

fn system_a_table(ctx: &mut Ctx) -> Result<Table> {
    let mut t = Table::new(
        "real-a-transitions",
        "System A: transitions and loops against the true clocks",
        "Each scene analysed with vt's defaults (minimum loop length scaled to the clip). A \
         transition from frame s of view p to view p' is right when the frame it continues with, \
         t + 1, shows the moment frame s + 1 of view p shows: for the synthetic scene the same \
         motion phase, for the real-footage scene the same source frame of tree.avi (its views \
         are one real video seen through known homographies, each started at a random clock \
         offset). Counted over every frame on each loop, both directions of every neighbour pair. \
         The loop wrap error is the same measure for frame n followed by m + 1.",
        &[
            "scene",
            "views x frames",
            "model chosen",
            "transitions within +-1 frame (%)",
            "mean transition error (frames)",
            "mean loop wrap error (frames)",
            "analysis (s)",
        ],
    );
    let sa = synth_a(ctx)?;
    let loops: Vec<(usize, usize)> = sa
        .analysis
        .views
        .iter()
        .map(|v| (v.best_loop.start, v.best_loop.end))
        .collect();
    let tables: Vec<_> = sa
        .analysis
        .links
        .iter()
        .map(|l| (l.to_next.clone(), l.to_prev.clone()))
        .collect();
    let (err, within) = transition_phase_errors(&sa, &loops, &tables);
    let p = sa.scene.params();
    t.row(vec![
        json!("synthetic (vt demo scene, period 24)"),
        json!(format!("{} x {}", p.views, p.frames)),
        json!(sa.analysis.model().map(|m| m.name())),
        json!(100.0 * within),
        json!(err),
        json!(loop_phase_error(&sa, &loops)),
        json!(sa.analysis_secs),
    ]);

    let r = real(ctx)?;
    let (scene, frames, points) = (&r.scene, &r.frames, &r.points);
    let rp = *scene.params();
    let mut params = crate::report::data::thesis_params();
    params.loops.min_length = rp.frames / 3;
    let dir = ctx.work.path().join("real-scene");
    let (a, secs, _) = build_scene(frames, points, &params, &dir)?;
    let usable = scene.usable();
    let (mut sum, mut n, mut ok) = (0usize, 0usize, 0usize);
    for (p, link) in a.links.iter().enumerate() {
        for (from, to, table) in [(p, p + 1, &link.to_next), (p + 1, p, &link.to_prev)] {
            let l = &a.views[from].best_loop;
            for s in l.start + 1..=l.end {
                if let Some(tt) = table[s] {
                    let e = circ(
                        scene.source_index(from, s + 1),
                        scene.source_index(to, tt + 1),
                        usable,
                    );
                    sum += e;
                    ok += (e <= 1) as usize;
                    n += 1;
                }
            }
        }
    }
    let wrap: f64 = a
        .views
        .iter()
        .enumerate()
        .map(|(p, v)| {
            circ(
                scene.source_index(p, v.best_loop.end + 1),
                scene.source_index(p, v.best_loop.start + 1),
                usable,
            ) as f64
        })
        .sum::<f64>()
        / a.views.len() as f64;
    t.row(vec![
        json!(format!(
            "real footage: tree.avi on a slanted plane ({} source frames, looped)",
            usable
        )),
        json!(format!("{} x {}", rp.views, rp.frames)),
        json!(a.model().map(|m| m.name())),
        json!(100.0 * ok as f64 / n.max(1) as f64),
        json!(sum as f64 / n.max(1) as f64),
        json!(wrap),
        json!(secs),
    ]);
    Ok(t)
}

/// Intermediate views of real scenes with depth: the Middlebury multi-view photos (even views
/// in, the odd view between as truth), through `vt_cv::cases::morph_scores` (the cross-check's
/// morph rows measure the same), and a picture of the four at q = 0.5.
fn depth_table(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let mut t = Table::new(
        "real-a-depth",
        "System A: intermediate views of real scenes with depth",
        "Middlebury 2005/2006 multi-view photos (testdata/middlebury-line, half size): views k and \
         k + 2 as a neighbour pair, the real view k + 1 as the truth at q = 0.5; PSNR, dB, after \
         the same plane (vt's automatic registration) for the plane warp of eq. (3), vt's morph \
         along the dense parallax (the default where the scene has parallax), OpenCV's DIS \
         optical-flow morph (thirty lines of OpenCV) and a 50/50 blend without warping; whole \
         image, then on and off the registration's plane where view k + 1's true disparity is \
         known (views 1 and 5; on: within a pixel of the plane's disparity). The quick report \
         scores the first pair of each scene.",
        &[
            "scene",
            "views",
            "plane warp (dB)",
            "vt morph (dB)",
            "OpenCV DIS morph (dB)",
            "50/50 blend (dB)",
            "on the plane (% of pixels)",
            "on: plane / vt / DIS (dB)",
            "off: plane / vt / DIS (dB)",
        ],
    );
    let ks: Vec<usize> = ctx.pick(vec![0], vec![0, 2, 4]);
    let mut gallery = Vec::new();
    for scene in ["Dolls", "Moebius", "Reindeer"] {
        for &k in &ks {
            let dir = crate::report::testdata()
                .join("middlebury-line")
                .join(scene);
            let load = |v: usize| -> Result<image::RgbImage> {
                Ok(image::open(dir.join(format!("view{v}.png")))?.to_rgb8())
            };
            let disp = match k + 1 {
                v @ (1 | 5) => Some(image::open(dir.join(format!("disp{v}.png")))?.to_luma8()),
                _ => None,
            };
            let truth = load(k + 1)?;
            // A disparity value is a quarter pixel between views two apart (half size,
            // full-size units over four view steps).
            let (s, imgs) = vt_cv::cases::morph_scores(
                &load(k)?,
                &load(k + 2)?,
                &truth,
                disp.as_ref().map(|d| (d, 0.25)),
            )?;
            let three = |v: [f64; 4]| format!("{:.2} / {:.2} / {:.2}", v[0], v[1], v[2]);
            t.row(vec![
                json!(scene),
                json!(format!("{k}, {} -> {}", k + 2, k + 1)),
                json!(s.plane),
                json!(s.vt),
                json!(s.cv),
                json!(s.blend),
                json!(s.split.map(|sp| 100.0 * sp.on_share)),
                json!(s.split.map(|sp| three(sp.on))),
                json!(s.split.map(|sp| three(sp.off))),
            ]);
            if k == 0 && scene == "Reindeer" {
                // The right half, where the near board occludes the cushion and the basket.
                let (w, h) = truth.dimensions();
                let half = |img: &image::RgbImage| {
                    image::imageops::crop_imm(img, w / 2, 0, w - w / 2, h).to_image()
                };
                for (name, img, score) in [
                    ("plane warp", &imgs.plane, s.plane),
                    ("vt morph", &imgs.vt, s.vt),
                    ("OpenCV DIS morph", &imgs.cv, s.cv),
                ] {
                    let file = ctx.save_image(
                        &format!("depth-reindeer-{}", name.replace(' ', "-").to_lowercase()),
                        &half(img),
                    )?;
                    gallery.push((file, format!("{name}, {score:.2} dB (whole image)")));
                }
                let file = ctx.save_image("depth-reindeer-truth", &half(&truth))?;
                gallery.push((file, "the real view 1 (truth)".to_string()));
            }
        }
    }
    Ok(vec![
        Item::Table(t),
        Item::Gallery(Gallery {
            title: "System A: the background at q = 0.5 on Middlebury Reindeer".into(),
            caption: "Between views 0 and 2, the right half of the image: the plane warp shows \
                      everything off the plane twice; the morphs follow the depth; the real \
                      view 1 for comparison."
                .into(),
            images: gallery,
        }),
    ])
}

/// The same scenes as a four-view rig through the whole analysis (as `vt analyze` runs it: the
/// even views as still clips, with and without testdata's marked points), against what a
/// two-view morph with perfect geometry shows (`vt_cv::cases::disparity_references`, from the
/// true disparity of views 1 and 5).
fn reference_table(ctx: &mut Ctx) -> Result<Table> {
    let mut t = Table::new(
        "real-a-references",
        "System A: intermediate views of the four-view rigs against perfect geometry",
        "Middlebury scenes (testdata/middlebury-line): the even views 0, 2, 4, 6 analysed as a \
         four-view rig of still clips by vt's defaults, without points (automatic registration) \
         and with testdata's marked points (six points on the dominant plane, from the true \
         disparity); rendered at q = 0.5, 1.5, 2.5 against the real odd views 1, 3, 5 (PSNR, \
         dB). At views 1 and 5 the true disparity gives two references on the pixels where it \
         is known: per pixel the better of the two outer views' samples (what the two views can \
         show; exposure differences, which vt compensates, count against it) and their 50/50 \
         blend (a naive morph with perfect geometry). The quick report scores Reindeer alone.",
        &[
            "scene",
            "registration",
            "mean over q, whole image (dB)",
            "view 1: vt / best of two / naive (dB)",
            "view 5: vt / best of two / naive (dB)",
            "analysis (s)",
        ],
    );
    let scenes: Vec<&str> = ctx.pick(vec!["Reindeer"], vec!["Dolls", "Moebius", "Reindeer"]);
    for scene in scenes {
        let dir = crate::report::testdata()
            .join("middlebury-line")
            .join(scene);
        let load = |v: usize| -> Result<image::RgbImage> {
            Ok(image::open(dir.join(format!("view{v}.png")))?.to_rgb8())
        };
        let frames: Vec<Vec<image::RgbImage>> = [0, 2, 4, 6]
            .iter()
            .map(|&k| Ok(vec![load(k)?; 8]))
            .collect::<Result<_>>()?;
        let marked = vt_io::points::read_points(&dir.join("points_0246.txt"))?;
        let mut params = vt_core::analysis::AnalyzeParams::default();
        params.loops.min_length = 4;
        for (name, points) in [("automatic", Vec::new()), ("marked points", marked)] {
            let out = ctx.work.path().join(format!("refs-{scene}-{name}"));
            let (_, secs, loaded) = build_scene(&frames, &points, &params, &out)?;
            let render = |q: f64| -> Result<image::RgbImage> {
                let choice = vt_core::render::Player::new().advance(&loaded.render, q)?;
                let mut r = vt_core::render::Renderer::new(
                    loaded.render.clone(),
                    vt_core::render::RenderParams::default(),
                )?;
                let (w, h) = r.size();
                let mut img = image::RgbImage::new(w, h);
                r.render_into(&loaded.objects, q, &choice, &mut img)?;
                Ok(img)
            };
            let mut whole = 0.0;
            let mut at = Vec::new();
            for (i, q) in [0.5, 1.5, 2.5].into_iter().enumerate() {
                let v = 2 * i + 1;
                let (img, truth) = (render(q)?, load(v)?);
                whole += vt_core::metrics::psnr(&img, &truth, None)? / 3.0;
                if v != 3 {
                    let disp = image::open(dir.join(format!("disp{v}.png")))?.to_luma8();
                    // A value is a quarter pixel between views two apart (half size).
                    let r = vt_cv::cases::disparity_references(
                        &load(v - 1)?,
                        &load(v + 1)?,
                        &truth,
                        &disp,
                        0.25,
                    );
                    let m = Some(&r.mask);
                    at.push(format!(
                        "{:.2} / {:.2} / {:.2}",
                        vt_core::metrics::psnr(&img, &truth, m)?,
                        vt_core::metrics::psnr(&r.best_of_two, &truth, m)?,
                        vt_core::metrics::psnr(&r.naive, &truth, m)?
                    ));
                }
            }
            t.row(vec![
                json!(scene),
                json!(name),
                json!(whole),
                json!(at[0]),
                json!(at[1]),
                json!(secs),
            ]);
        }
    }
    Ok(t)
}

fn corner_table(ctx: &mut Ctx) -> Result<Table> {
    let mut t = Table::new(
        "real-a-corners",
        "System A: homography corner error against marking noise",
        "The real-footage scene's marked points (6 per view) with Gaussian marking noise of the \
         given sigma (vt-synth's RealScene, seeded); H(p,p+1) fitted by vt's model selection \
         (auto) and by a forced homography; the error is the largest distance between where the \
         fitted and the true homography put the image corners, pixels, averaged over the \
         neighbour pairs. The true maps are projective (rotating cameras, slanted plane).",
        &[
            "marking noise (px)",
            "model chosen",
            "corner error, auto (px)",
            "corner error, homography (px)",
        ],
    );
    let tr = tree(ctx)?;
    let sigmas: Vec<f64> = ctx.pick(
        vec![0.0, 0.5, 1.0, 2.0, 4.0],
        vec![0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0],
    );
    for sigma in sigmas {
        let rp = RealParams {
            marking_noise: sigma,
            ..real_params(ctx.quick)
        };
        let scene = RealScene::new(tr.frames.clone(), rp).map_err(anyhow::Error::msg)?;
        let points: Vec<Vec<Point>> = (0..rp.views)
            .map(|v| pts(&scene.marked_points(v)))
            .collect();
        let pairs: Vec<(&[Point], &[Point])> = (0..rp.views - 1)
            .map(|p| (points[p].as_slice(), points[p + 1].as_slice()))
            .collect();
        let err = |params: &ModelParams| -> Result<(MotionModel, f64)> {
            let sel = select_model(&pairs, params)?;
            let e = sel
                .fits
                .iter()
                .enumerate()
                .map(|(p, f)| scene.corner_error(p, p + 1, &f.homography.matrix()))
                .sum::<f64>()
                / sel.fits.len() as f64;
            Ok((sel.model, e))
        };
        let (model, auto) = err(&ModelParams::default())?;
        let (_, forced) = err(&ModelParams {
            force: Some(MotionModel::Homography),
            ..Default::default()
        })?;
        t.row(vec![
            json!(sigma),
            json!(model.name()),
            json!(auto),
            json!(forced),
        ]);
    }
    Ok(t)
}

fn score_cells(s: &Scores) -> Vec<serde_json::Value> {
    vec![
        json!(s.inside.psnr),
        json!(s.inside.ssim),
        json!(s.whole.psnr),
        json!(s.whole.ssim),
    ]
}

/// The cameras whose viewing direction is more than half the ring's median spacing away from
/// every other camera's.
fn distinct_poses(cams: &[vt_fv::Camera]) -> Vec<usize> {
    let angle = |a: usize, b: usize| {
        cams[a]
            .forward()
            .dot(&cams[b].forward())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    };
    let nearest: Vec<f64> = (0..cams.len())
        .map(|i| {
            (0..cams.len())
                .filter(|&j| j != i)
                .map(|j| angle(i, j))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let mut sorted = nearest.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    (0..cams.len())
        .filter(|&i| nearest[i] > 0.5 * median)
        .collect()
}

fn system_b(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let tp = temple(ctx)?;
    let grid = ctx.pick(64, 128);
    let n = tp.ds.cams.len();
    // Withheld views: only those whose pose no other camera duplicates (the ring closes, so its
    // first and last photos look from almost the same place), spread around the ring.
    let unique = distinct_poses(&tp.ds.cams);
    // The quick report (the test suite's) withholds two, half the ring apart: each costs two
    // models, and the table and gallery are the same shape.
    let withheld: Vec<usize> = if ctx.quick {
        let step = (unique.len() / 2).max(1);
        unique.iter().copied().step_by(step).take(2).collect()
    } else {
        unique.clone()
    };
    let model = FvModel {
        grid,
        ..Default::default()
    };
    let paper_model = FvModel {
        grid,
        paper_carving: true,
        ..Default::default()
    };
    let (w, h) = tp.ds.images[0].dimensions();
    let mut t = Table::new(
        "real-b-temple",
        "System B: leave-one-out on templeSparseRing",
        format!(
            "Withheld: the photos whose pose no other camera duplicates (nearest other viewing \
             direction more than half the ring's median spacing away). Each withheld photo is \
             rebuilt from the other {} as `vt fv eval` does it (vt-fv's Dataset: model at \
             {grid}^3 carved from thresholded silhouettes dilated and eroded by 3, images {w}x{h}, \
             {:.0} % of the 640x480 photos) and compared with the photo it replaces: PSNR and \
             SSIM inside the withheld photo's scoring silhouette (threshold 0.25, closed by 5 px: \
             the Middlebury recipe's 0.19 takes in the lit folds of the background cloth) and \
             over the whole image; IoU is that silhouette's overlap with the rough render of the \
             model the row's image comes from (vt's default trims it to the visual hull at pixel \
             accuracy, the paper's mode does not). Baselines, all from vt-fv's default model: the nearest reference photo as it \
             is, the rough render (flat voxel colours), the rough render blurred (Gaussian sigma \
             2). 'paper, guided' is the paper's method end to end (paper carving rule, guided \
             synthesis of the rough render, patch 7); 'vt default' is vt-fv's default model and \
             new-view method (ViewParams::default()).",
            n - 1,
            100.0 * tp.scale
        ),
        &[
            "withheld",
            "image",
            "PSNR inside (dB)",
            "SSIM inside",
            "PSNR whole (dB)",
            "SSIM whole",
            "silhouette IoU",
        ],
    );
    let mut gallery = Vec::new();
    let mut sums = [[0.0f64; 5]; 5];
    for &k in &withheld {
        let (paper, pimg) = tp.ds.leave_one_out(
            k,
            &paper_model,
            &ViewParams::paper(GuidedParams::fast_for(7)),
        )?;
        let (def, dimg) = tp.ds.leave_one_out(k, &model, &ViewParams::default())?;
        let name = tp.ds.cams[k].name.clone();
        let rows: [(&str, &Scores); 5] = [
            ("nearest photo", &def.nearest_photo),
            ("rough render", &def.rough),
            ("rough render, blur sigma 2", &def.rough_blur2),
            ("paper, guided", &paper.guided),
            ("vt default", &def.guided),
        ];
        for (i, (label, s)) in rows.iter().enumerate() {
            let iou = if i == 3 {
                paper.silhouette_iou
            } else {
                def.silhouette_iou
            };
            let mut row = vec![json!(name.clone()), json!(label)];
            row.extend(score_cells(s));
            row.push(json!(iou));
            t.row(row);
            for (j, v) in [
                s.inside.psnr,
                s.inside.ssim,
                s.whole.psnr,
                s.whole.ssim,
                iou,
            ]
            .iter()
            .enumerate()
            {
                sums[i][j] += v;
            }
        }
        if gallery.is_empty() {
            let stem = format!("temple-{}", k);
            for (label, img, s) in [
                ("withheld photo", &pimg.truth, None),
                (
                    "nearest photo",
                    &pimg.nearest_photo,
                    Some(&paper.nearest_photo),
                ),
                ("rough render", &pimg.rough, Some(&paper.rough)),
                ("paper, guided", &pimg.guided, Some(&paper.guided)),
                ("vt default", &dimg.guided, Some(&def.guided)),
            ] {
                let file =
                    ctx.save_image(&format!("{stem}-{}", label.replace([' ', ','], "-")), img)?;
                let cap = match s {
                    Some(s) => format!(
                        "{label}: {:.2} dB / SSIM {:.3} inside the silhouette",
                        s.inside.psnr, s.inside.ssim
                    ),
                    None => format!("{label} ({name})"),
                };
                gallery.push((file, cap));
            }
        }
    }
    for (i, label) in [
        "nearest photo",
        "rough render",
        "rough render, blur sigma 2",
        "paper, guided",
        "vt default",
    ]
    .iter()
    .enumerate()
    {
        let mut row = vec![json!("mean"), json!(label)];
        row.extend(sums[i].iter().map(|v| json!(v / withheld.len() as f64)));
        t.row(row);
    }
    Ok(vec![
        Item::Table(t),
        Item::Gallery(Gallery {
            title: "System B on templeSparseRing, one withheld view".into(),
            caption: "The withheld photo, the nearest reference photo, the rough render, the \
                      paper's guided result and vt's default, with their scores."
                .into(),
            images: gallery,
        }),
    ])
}

/// System B on the real kettle (COLMAP cameras, white cloth, automatic silhouettes): every
/// view (two, opposite, with `--quick`) left out and made by vt's default, against the blurred
/// rough render; then the orbit's steadiness on the kettle and the temple.
fn system_b_kettle(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let ds = vt_fv::dataset::Dataset::load(
        &crate::report::testdata().join("kettle"),
        &vt_fv::dataset::DataOptions::default(),
    )?;
    let model = FvModel::default();
    let view = ViewParams::default();
    let (w, h) = ds.size();
    let n = ds.cams.len();
    let withheld: Vec<usize> = (0..n).step_by(ctx.pick(n.div_ceil(2).max(1), 1)).collect();
    let mut t = Table::new(
        "real-b-kettle",
        "System B: leave-one-out on the real kettle (COLMAP model, white cloth)",
        format!(
            "testdata/kettle: {n} phone photos of a kettle on white cloth at {w}x{h}, cameras \
             from COLMAP's text model (SIMPLE_RADIAL, undistorted on load), silhouettes found \
             automatically from the backdrop. Each withheld photo is rebuilt from the other \
             {} as `vt fv eval` does it, with vt's defaults (model at {}^3, textured view). \
             'inside' is PSNR inside the withheld photo's silhouette, as the issue's goal \
             reads (vt default against the rough render blurred with sigma 2, goal: ahead by \
             1 dB or more on every view). 'silhouette + own region' scores over the silhouette \
             united with the pixels each image paints (the blurred render's from its unblurred \
             render), so an object region grown past the true outline pays for what it paints \
             over the cloth. vt's clip tests the other photos' silhouettes with 1 px of \
             slack (their cones meet about a pixel inside each photo's own outline): that \
             gains here as well as inside (lead +0.98 -> +2.60 dB here); growing the region \
             further by 1-2 rings 'wins' another 1 dB inside and loses 0.4-0.5 dB here, so vt \
             does not.",
            n - 1,
            model.grid
        ),
        &[
            "withheld",
            "blurred rough, inside (dB)",
            "vt default, inside (dB)",
            "lead inside (dB)",
            "lead over silhouette + own region (dB)",
            "SSIM vt default, inside",
            "silhouette IoU",
        ],
    );
    let (mut leads, mut fair) = (Vec::new(), Vec::new());
    let mut gallery = Vec::new();
    for &k in &withheld {
        let (r, imgs) = ds.leave_one_out(k, &model, &view)?;
        let sil = &ds.score_masks[k];
        let ours =
            vt_fv::pipeline::score_with_region(&imgs.guided, &imgs.truth, sil, &imgs.guided)?;
        let base =
            vt_fv::pipeline::score_with_region(&imgs.rough_blur2, &imgs.truth, sil, &imgs.rough)?;
        let lead = r.guided.inside.psnr - r.rough_blur2.inside.psnr;
        leads.push(lead);
        fair.push(ours.psnr - base.psnr);
        t.row(vec![
            json!(ds.cams[k].name.clone()),
            json!(r.rough_blur2.inside.psnr),
            json!(r.guided.inside.psnr),
            json!(lead),
            json!(ours.psnr - base.psnr),
            json!(r.guided.inside.ssim),
            json!(r.silhouette_iou),
        ]);
        if gallery.is_empty() {
            for (label, img) in [
                ("withheld photo", &imgs.truth),
                ("rough render blurred", &imgs.rough_blur2),
                ("vt default", &imgs.guided),
            ] {
                let file =
                    ctx.save_image(&format!("kettle-{k}-{}", label.replace(' ', "-")), img)?;
                gallery.push((file, format!("{label} (view {k})")));
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let ahead = leads.iter().filter(|&&l| l >= 1.0).count();
    t.row(vec![
        json!(format!(
            "mean ({ahead} of {} views ahead by >= 1 dB)",
            leads.len()
        )),
        json!(null),
        json!(null),
        json!(mean(&leads)),
        json!(mean(&fair)),
        json!(null),
        json!(null),
    ]);

    // Orbit steadiness (issue #24 item 6): the largest step between consecutive frames over the
    // median step, inside the object, on both real sets.
    let mut o = Table::new(
        "real-b-orbit",
        "System B: orbit steadiness on real photos",
        "`vt fv orbit` with vt's defaults: one model from every photo, then frames evenly round \
         the cameras' ring. Step: mean absolute difference (0-255) between consecutive frames \
         inside the object; the goal is a largest step at most 2x the median (no pop when the \
         reference photos change).",
        &[
            "data",
            "frames",
            "median step",
            "largest step",
            "largest / median",
            "s per frame",
        ],
    );
    let temple = temple(ctx)?;
    let frames = ctx.pick(24, 72);
    for (name, d) in [("kettle", &ds), ("templeSparseRing", &temple.ds)] {
        let (m, _) = d.build_without(None, &model, &mut |_, _, _| {})?;
        let ring = vt_fv::camera::Ring::fit(&d.cams)?;
        let target = vt_fv::texture::model_centre(&m);
        let start = std::time::Instant::now();
        let steady = vt_fv::orbit::orbit::<vt_fv::Error>(
            &m,
            &d.cams,
            &d.images,
            Some(&d.masks),
            &ring,
            &target,
            frames,
            d.size(),
            &view,
            &mut |_, _, _| Ok(()),
        )?;
        let secs = start.elapsed().as_secs_f64() / frames as f64;
        o.row(vec![
            json!(name),
            json!(frames),
            json!(steady.median()),
            json!(steady.largest().1),
            json!(steady.ratio()),
            json!(secs),
        ]);
    }
    Ok(vec![
        Item::Table(t),
        Item::Gallery(Gallery {
            title: "System B on the real kettle, one withheld view".into(),
            caption: "The withheld photo, the blurred rough render (the baseline) and vt's \
                      default."
                .into(),
            images: gallery,
        }),
        Item::Table(o),
    ])
}

/// Builds the section.
pub fn build(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let mut items = vec![
        Item::Table(timed(
            "Transitions and loops against the true clocks",
            || system_a_table(ctx),
        )?),
        Item::Table(timed(
            "Homography corner error against marking noise",
            || corner_table(ctx),
        )?),
    ];
    items.extend(timed(
        "Intermediate views of real scenes with depth",
        || depth_table(ctx),
    )?);
    items.push(Item::Table(timed(
        "The four-view rigs against perfect geometry",
        || reference_table(ctx),
    )?));
    items.extend(timed("System B on templeSparseRing", || system_b(ctx))?);
    items.extend(timed("System B on the real kettle", || {
        system_b_kettle(ctx)
    })?);
    Ok(items)
}
