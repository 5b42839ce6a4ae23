//! Section 3: model only what the scene requires. The model each scene gets (GRIC over
//! translation, similarity, affine, homography) with its residual and what the richer models
//! would have gained; then two sweeps with known truth: the true map moving from a translation
//! through affine to strongly projective, and the marking noise growing. The cost of a choice
//! is measured in rendered PSNR: a real photo (graf1) warped by the fitted map against the same
//! photo warped by the true map.

use anyhow::{Context, Result};
use image::RgbImage;
use nalgebra::{Matrix3, Vector3};
use serde_json::json;
use vt_core::metrics::psnr;
use vt_core::model::{fit_model, select_model, ModelParams, MotionModel};
use vt_core::warp::{warp_rgb, Interpolation};
use vt_core::{Homography, Point};
use vt_synth::{Rig, TextureParams, TextureScene};

use crate::report::data::synth_a;
use crate::report::model::{Axis, Better, Item, LinePlot, Series, Table};
use crate::report::{testdata, Ctx};

fn to_points(v: &[(f64, f64)]) -> Vec<Point> {
    v.iter().map(|&(x, y)| Point::new(x, y)).collect()
}

fn map(h: &Matrix3<f64>, p: &Point) -> Point {
    let v = h * Vector3::new(p.x, p.y, 1.0);
    Point::new(v.x / v.z, v.y / v.z)
}

/// Mean distance between the image corners mapped by `est` and by `truth`, pixels.
pub fn corner_error(est: &Matrix3<f64>, truth: &Matrix3<f64>, w: u32, h: u32) -> f64 {
    let (w, h) = (w as f64 - 1.0, h as f64 - 1.0);
    [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
        .iter()
        .map(|&(x, y)| {
            let p = Point::new(x, y);
            (map(est, &p) - map(truth, &p)).norm()
        })
        .sum::<f64>()
        / 4.0
}

/// One scene's row: chosen model, its residual, and every model's GRIC and RMS.
fn scene_row(
    t: &mut Table,
    name: &str,
    pairs: &[(Vec<Point>, Vec<Point>)],
    truths: &[Matrix3<f64>],
    size: (u32, u32),
) -> Result<()> {
    let refs: Vec<(&[Point], &[Point])> = pairs
        .iter()
        .map(|(a, b)| (a.as_slice(), b.as_slice()))
        .collect();
    let sel = select_model(&refs, &ModelParams::default())?;
    let mut row = vec![json!(name), json!(pairs.len() + 1), json!(sel.model.name())];
    let chosen_rms = sel.fits.iter().map(|f| f.rms).sum::<f64>() / sel.fits.len() as f64;
    row.push(json!(chosen_rms));
    let corner = sel
        .fits
        .iter()
        .zip(truths)
        .map(|(f, tr)| corner_error(&f.homography.matrix(), tr, size.0, size.1))
        .sum::<f64>()
        / truths.len().max(1) as f64;
    row.push(if truths.is_empty() {
        json!(null)
    } else {
        json!(corner)
    });
    for m in MotionModel::ALL {
        let gric = sel.scores.iter().find(|(k, _)| *k == m).map(|s| s.1);
        let rms: f64 = pairs
            .iter()
            .map(|(a, b)| fit_model(m, a, b, 1.0).map(|f| f.rms).unwrap_or(f64::NAN))
            .sum::<f64>()
            / pairs.len() as f64;
        row.push(json!(format!(
            "{} / {}",
            gric.map(crate::report::html::num)
                .unwrap_or_else(|| "-".into()),
            crate::report::html::num(rms)
        )));
    }
    t.row(row);
    Ok(())
}

/// Marked point pairs of neighbouring views.
type PointPairs = Vec<(Vec<Point>, Vec<Point>)>;

fn texture_points(scene: &TextureScene) -> (PointPairs, Vec<Matrix3<f64>>) {
    let m = scene.params().views;
    let pairs = (0..m - 1)
        .map(|p| (to_points(&scene.points(p)), to_points(&scene.points(p + 1))))
        .collect();
    let truths = (0..m - 1)
        .map(|p| scene.plane_homography(p as f64, p as f64 + 1.0))
        .collect();
    (pairs, truths)
}

fn noisy(pts: &[Point], sigma: f64, seed: u64) -> Vec<Point> {
    let mut rng = vt_core::rng::Rng::new(seed);
    pts.iter()
        .map(|p| Point::new(p.x + sigma * rng.normal(), p.y + sigma * rng.normal()))
        .collect()
}

fn graf() -> Result<(RgbImage, Matrix3<f64>)> {
    let img = vt_io::frames::read_rgb(&testdata().join("graf1.png"))?;
    let xml = std::fs::read_to_string(testdata().join("H1to3p.xml")).context("H1to3p.xml")?;
    let data = xml
        .split("<data>")
        .nth(1)
        .and_then(|s| s.split("</data>").next())
        .context("H1to3p.xml: no <data>")?;
    let v: Vec<f64> = data
        .split_whitespace()
        .map(|s| s.parse::<f64>())
        .collect::<Result<_, _>>()
        .context("H1to3p.xml: not numbers")?;
    anyhow::ensure!(v.len() == 9, "H1to3p.xml: {} numbers, expected 9", v.len());
    Ok((img, Matrix3::from_row_slice(&v)))
}

fn scenes_table(ctx: &mut Ctx) -> Result<Table> {
    let mut t = Table::new(
        "models-scenes",
        "The model each scene gets",
        "select_model (GRIC summed over neighbour pairs, point sigma 1 px) on each scene's marked \
         points. RMS: transfer error of the chosen fit, pixels, mean over pairs. Corner error: \
         mean distance of the image corners mapped by the chosen fit and by the true homography. \
         The last four columns: GRIC (lower is better) / RMS px of every model, so the gain a \
         richer model would bring is the drop in RMS, and GRIC says whether it is worth its \
         parameters.",
        &[
            "scene",
            "views",
            "chosen",
            "RMS (px)",
            "corner error vs truth (px)",
            "translation GRIC / RMS",
            "similarity GRIC / RMS",
            "affine GRIC / RMS",
            "homography GRIC / RMS",
        ],
    );
    let sa = synth_a(ctx)?;
    let (pairs, truths) = texture_points(&sa.scene);
    let p = sa.scene.params();
    scene_row(
        &mut t,
        "vt demo scene (parallel rig, exact points)",
        &pairs,
        &truths,
        (p.width, p.height),
    )?;
    for (name, rig, sigma) in [
        ("parallel rig, 5 views, points +-1 px", Rig::Parallel, 1.0),
        (
            "converging rig, 5 views, exact points",
            Rig::Converging,
            0.0,
        ),
        (
            "converging rig, 5 views, points +-1 px",
            Rig::Converging,
            1.0,
        ),
    ] {
        let scene = TextureScene::new(TextureParams {
            views: 5,
            rig,
            ..Default::default()
        })
        .map_err(anyhow::Error::msg)?;
        let (pairs, truths) = texture_points(&scene);
        let pairs: Vec<_> = pairs
            .into_iter()
            .enumerate()
            .map(|(i, (a, b))| {
                (
                    noisy(&a, sigma, 2 * i as u64 + 7),
                    noisy(&b, sigma, 2 * i as u64 + 8),
                )
            })
            .collect();
        scene_row(&mut t, name, &pairs, &truths, (320, 180))?;
    }
    // graf: a real planar wall seen from two viewpoints, its true homography measured.
    let (img, h13) = graf()?;
    let src: Vec<Point> = [
        (120.0, 100.0),
        (650.0, 90.0),
        (700.0, 520.0),
        (90.0, 560.0),
        (400.0, 300.0),
        (250.0, 420.0),
    ]
    .iter()
    .map(|&(x, y)| Point::new(x, y))
    .collect();
    let dst: Vec<Point> = src.iter().map(|p| map(&h13, p)).collect();
    scene_row(
        &mut t,
        "graf1 -> graf3 (real wall, true H, points +-1 px)",
        &[(noisy(&src, 1.0, 21), noisy(&dst, 1.0, 22))],
        &[h13],
        img.dimensions(),
    )?;
    Ok(t)
}

/// The sweeps' truth: translation (s = 0) -> affine (s = 1) -> strongly projective (s = 2).
fn sweep_truth(s: f64) -> Matrix3<f64> {
    let a = s.min(1.0);
    let p = (s - 1.0).max(0.0);
    Matrix3::new(
        1.0 + 0.08 * a,
        0.06 * a,
        14.0,
        -0.05 * a,
        1.0 + 0.07 * a,
        -6.0,
        5e-4 * p,
        -4e-4 * p,
        1.0,
    )
}

/// Fixed marked points spread over a 320x256 image.
fn sweep_points() -> Vec<Point> {
    [
        (30.0, 25.0),
        (290.0, 35.0),
        (280.0, 230.0),
        (40.0, 220.0),
        (160.0, 60.0),
        (150.0, 200.0),
    ]
    .iter()
    .map(|&(x, y)| Point::new(x, y))
    .collect()
}

struct SweepPoint {
    chosen: MotionModel,
    psnr: Vec<f64>,
}

/// Selects a model for points mapped by `truth` plus noise, and the PSNR of the texture warped by
/// each model's fit against it warped by the truth (mean over `trials` noise draws; the chosen
/// model is the most frequent).
fn sweep_point(
    tex: &RgbImage,
    truth: &Matrix3<f64>,
    sigma: f64,
    trials: u64,
) -> Result<SweepPoint> {
    let (w, h) = tex.dimensions();
    let true_h = Homography::from_matrix(*truth)?;
    let reference = warp_rgb(tex, &true_h, w, h, Interpolation::Bilinear);
    let src = sweep_points();
    let mut votes = [0usize; 4];
    let mut psnrs = [0.0; 4];
    for trial in 0..trials {
        let s = noisy(&src, sigma, 100 + 2 * trial);
        let d = noisy(
            &src.iter().map(|p| map(truth, p)).collect::<Vec<_>>(),
            sigma,
            101 + 2 * trial,
        );
        let sel = select_model(&[(&s, &d)], &ModelParams::default())?;
        let k = MotionModel::ALL
            .iter()
            .position(|m| *m == sel.model)
            .expect("one of ALL");
        votes[k] += 1;
        for (i, m) in MotionModel::ALL.iter().enumerate() {
            let fit = fit_model(*m, &s, &d, 1.0)?;
            let img = warp_rgb(tex, &fit.homography, w, h, Interpolation::Bilinear);
            psnrs[i] += psnr(&img, &reference, None)?.min(99.0);
        }
    }
    let best = (0..4).max_by_key(|&i| votes[i]).expect("4 models");
    Ok(SweepPoint {
        chosen: MotionModel::ALL[best],
        psnr: psnrs.iter().map(|p| p / trials as f64).collect(),
    })
}

fn sweep_items(
    id: &str,
    title: &str,
    caption: &str,
    x: Axis,
    xs: &[f64],
    label: impl Fn(f64) -> String,
    point: impl Fn(f64) -> Result<SweepPoint>,
) -> Result<Vec<Item>> {
    let mut t = Table::new(
        id,
        &format!("{title}: the figures"),
        "The points of the plot above, with the model GRIC chose at each step.",
        &[
            x.label.as_str(),
            "chosen model",
            "PSNR of chosen (dB)",
            "best model by PSNR",
            "cost of the choice (dB)",
            "translation (dB)",
            "similarity (dB)",
            "affine (dB)",
            "homography (dB)",
        ],
    );
    let mut series: Vec<Series> = MotionModel::ALL
        .iter()
        .map(|m| Series {
            name: m.name().to_string(),
            points: Vec::new(),
        })
        .collect();
    let mut chosen_series = Series {
        name: "chosen by GRIC".into(),
        points: Vec::new(),
    };
    for &v in xs {
        let sp = point(v)?;
        let k = MotionModel::ALL
            .iter()
            .position(|m| *m == sp.chosen)
            .expect("in ALL");
        let best = (0..4)
            .max_by(|&a, &b| sp.psnr[a].total_cmp(&sp.psnr[b]))
            .expect("4");
        let mut row = vec![
            json!(label(v)),
            json!(sp.chosen.name()),
            json!(sp.psnr[k]),
            json!(MotionModel::ALL[best].name()),
            json!(sp.psnr[best] - sp.psnr[k]),
        ];
        row.extend(sp.psnr.iter().map(|p| json!(p)));
        t.row(row);
        for (i, s) in series.iter_mut().enumerate() {
            s.points.push((v, sp.psnr[i]));
        }
        chosen_series.points.push((v, sp.psnr[k]));
    }
    series.push(chosen_series);
    Ok(vec![
        Item::Plot(LinePlot {
            id: format!("{id}-plot"),
            title: title.into(),
            caption: caption.into(),
            x,
            y: Axis::new("rendered PSNR vs truth (dB)", Better::Higher),
            series,
            plot: format!("plots/{id}.svg"),
        }),
        Item::Table(t),
    ])
}

/// Builds the section.
pub fn build(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let mut items = vec![Item::Table(scenes_table(ctx)?)];
    let (img, _) = graf()?;
    let tex = image::imageops::resize(&img, 320, 256, image::imageops::FilterType::Triangle);
    let trials = ctx.pick(3, 8);
    let steps: Vec<f64> = if ctx.quick {
        (0..=8).map(|i| i as f64 * 0.25).collect()
    } else {
        (0..=20).map(|i| i as f64 * 0.1).collect()
    };
    items.extend(sweep_items(
        "models-sweep-truth",
        "Truth from translation through affine to projective",
        &format!(
            "Six marked points on a 320x256 image mapped by a known map: s = 0 a translation, \
             s = 1 an affine map (8 % scale, 6 % shear), s = 2 strongly projective (perspective \
             terms 5e-4, -4e-4); 1 px marking noise, {trials} noise draws per step. Each model is \
             fitted; graf1 (a real photo, scaled to 320x256) is warped by the fit and by the truth \
             and compared (PSNR, bilinear). The chosen model is GRIC's majority choice. The cost \
             of the choice is the PSNR the best model would have given minus the chosen one's."
        ),
        Axis::new("s (0 translation, 1 affine, 2 projective)", Better::Neutral),
        &steps,
        |s| format!("{s:.2}"),
        |s| sweep_point(&tex, &sweep_truth(s), 1.0, trials),
    )?);
    let sigmas: Vec<f64> = ctx.pick(
        vec![0.1, 0.5, 1.0, 2.0, 4.0, 8.0],
        vec![0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0],
    );
    items.extend(sweep_items(
        "models-sweep-noise",
        "Marking noise grows",
        &format!(
            "The map of s = 1.5 (affine plus moderate perspective), the marked points with \
             Gaussian noise of the given sigma (GRIC still assumes 1 px, the default \
             --point-sigma), {trials} noise draws per step; PSNR as above."
        ),
        Axis::log("marking noise sigma (px)", Better::Neutral),
        &sigmas,
        |s| format!("{s}"),
        |s| sweep_point(&tex, &sweep_truth(1.5), s, trials),
    )?);
    Ok(items)
}
