//! Section 2: stability at the extremes. vt-core and OpenCV (through vt-cv) on the cross-check's
//! extreme inputs (points far from the origin, near-collinear, tiny spread, nearly singular maps,
//! non-finite and too few points; tiny and oversized-kernel images; too-short clips), and the
//! renderer's continuity at the q where its formulas switch cases.

use anyhow::Result;
use image::RgbImage;
use nalgebra::Matrix3;
use serde_json::json;
use vt_core::blur::GaussianParams;
use vt_core::loops::LoopParams;
use vt_core::metrics::psnr;
use vt_core::render::{Player, RenderParams, Renderer};
use vt_core::{Homography, Mask, Point};

use crate::report::data::synth_a;
use crate::report::model::{Item, Table};
use crate::report::Ctx;

/// RMS transfer error of `m` on the points (infinite when a point maps to infinity).
fn rms(m: &Matrix3<f64>, src: &[Point], dst: &[Point]) -> f64 {
    let mapped = vt_cv::cases::map_points(m, src);
    let se: f64 = mapped
        .iter()
        .zip(dst)
        .map(|(a, b)| (a - b).norm_squared())
        .sum();
    let v = (se / src.len().max(1) as f64).sqrt();
    if v.is_finite() {
        v
    } else {
        f64::INFINITY
    }
}

fn short(e: impl std::fmt::Display) -> String {
    let s = e.to_string();
    let mut out: String = s.chars().take(70).collect();
    if s.chars().count() > 70 {
        out.push_str("...");
    }
    out
}

fn homography_table() -> Table {
    let mut t = Table::new(
        "stability-homography",
        "Homography from points at the extremes: vt-core vs OpenCV",
        "vt-core's normalised DLT + Levenberg-Marquardt (Homography::from_correspondences) and \
         OpenCV's findHomography (method 0, through vt-cv) on the same points. RMS: transfer error \
         on the original f64 points, pixels (inf: a point maps to infinity). 'error' is a clear \
         refusal, which is the right answer for degenerate input; a non-finite matrix returned as \
         a success would be a bug.",
        &[
            "input",
            "vt-core",
            "vt-core RMS (px)",
            "OpenCV",
            "OpenCV RMS (px)",
            "vt-core at least as good",
        ],
    );
    for vt_cv::cases::PointSet { name, src, dst, .. } in vt_cv::cases::extreme_point_sets() {
        let vt = Homography::from_correspondences(&src, &dst);
        let cv = vt_cv::homography::estimate_matrix(&src, &dst);
        let (vt_what, vt_rms) = match &vt {
            Ok(fit) => {
                let m = fit.homography.matrix();
                let finite = m.iter().all(|v| v.is_finite());
                (
                    if finite {
                        "ok".to_string()
                    } else {
                        "NON-FINITE matrix".to_string()
                    },
                    rms(&m, &src, &dst),
                )
            }
            Err(e) => (format!("error: {}", short(e)), f64::NAN),
        };
        let (cv_what, cv_rms) = match &cv {
            Ok(m) if m.iter().all(|v| v.is_finite()) && m.iter().any(|v| *v != 0.0) => {
                ("ok".to_string(), rms(m, &src, &dst))
            }
            Ok(_) => ("empty or non-finite matrix".to_string(), f64::NAN),
            Err(e) => (format!("error: {}", short(e)), f64::NAN),
        };
        let better = match (vt_rms.is_nan(), cv_rms.is_nan()) {
            (true, _) => "refused",
            (false, true) => "yes (OpenCV failed)",
            (false, false) if vt_rms <= cv_rms * (1.0 + 1e-9) + 1e-12 => "yes",
            _ => "NO",
        };
        let num = |v: f64| {
            if v.is_nan() {
                json!(null)
            } else if v.is_infinite() {
                json!("inf")
            } else {
                json!(v)
            }
        };
        t.row(vec![
            json!(name),
            json!(vt_what),
            num(vt_rms),
            json!(cv_what),
            num(cv_rms),
            json!(better),
        ]);
    }
    t
}

fn outcome<T>(r: &Result<T, impl std::fmt::Display>, ok: impl Fn(&T) -> String) -> String {
    match r {
        Ok(v) => ok(v),
        Err(e) => format!("error: {}", short(e)),
    }
}

fn images_table() -> Table {
    let mut t = Table::new(
        "stability-images",
        "Images and clips at the extremes: vt-core vs OpenCV",
        "Gaussian blur on tiny images and kernels larger than the image (reflect-101 border), and \
         the loop search on clips too short for the window and minimum length. 'same' means the \
         two outputs are identical byte for byte.",
        &["operation", "input", "vt-core", "OpenCV", "agree"],
    );
    let img = |w: u32, h: u32| {
        RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([(x * 37 + y * 11) as u8, (x * 5) as u8, 200])
        })
    };
    for (input, src, ksize) in [
        ("1x1 image, 3x3", img(1, 1), 3),
        ("7x1 image, 3x3", img(7, 1), 3),
        ("5x5 image, 31x31 kernel", img(5, 5), 31),
        ("64x48 image, 1x1 kernel", img(64, 48), 1),
        ("64x48 image, even kernel 4", img(64, 48), 4),
    ] {
        let p = GaussianParams { ksize, sigma: 0.0 };
        let vt = vt_core::blur::gaussian_blur(&src, &p);
        let cv = vt_cv::blur::gaussian_blur(&src, &p);
        let agree = match (&vt, &cv) {
            (Ok(a), Ok(b)) => {
                let d = a
                    .as_raw()
                    .iter()
                    .zip(b.as_raw())
                    .map(|(x, y)| x.abs_diff(*y))
                    .max()
                    .unwrap_or(0);
                if d == 0 {
                    "same".to_string()
                } else {
                    format!("differ by up to {d}")
                }
            }
            (Err(_), Err(_)) => "both refuse".into(),
            _ => "NO: one refuses".into(),
        };
        t.row(vec![
            json!("Gaussian blur"),
            json!(input),
            json!(outcome(&vt, |_| "ok".into())),
            json!(outcome(&cv, |_| "ok".into())),
            json!(agree),
        ]);
    }
    let masks = |n: usize| -> Vec<Mask> {
        (0..n)
            .map(|i| Mask::from_fn(16, 8, |x, y| (x + y + i as u32).is_multiple_of(5)))
            .collect()
    };
    for (input, n, params) in [
        (
            "2 frames, w 3",
            2,
            LoopParams {
                window: 3,
                min_length: 1,
            },
        ),
        ("10 frames, min length 100", 10, LoopParams::default()),
        (
            "10 frames, w 0",
            10,
            LoopParams {
                window: 0,
                min_length: 2,
            },
        ),
        (
            "12 frames, w 3, min length 8",
            12,
            LoopParams {
                window: 3,
                min_length: 8,
            },
        ),
    ] {
        let m = masks(n);
        let vt = vt_core::loops::find_loop(&m, &params, "clip");
        let cv = vt_cv::loops::find_loop(&m, &params, "clip");
        let show = |l: &vt_core::loops::Loop| format!("({}, {}) cost {}", l.start, l.end, l.cost);
        let agree = match (&vt, &cv) {
            (Ok(a), Ok(b)) if a == b => "same".to_string(),
            (Ok(_), Ok(_)) => "NO: different loops".into(),
            (Err(_), Err(_)) => "both refuse".into(),
            _ => "NO: one refuses".into(),
        };
        t.row(vec![
            json!("loop search (eq. 1)"),
            json!(input),
            json!(outcome(&vt, show)),
            json!(outcome(&cv, show)),
            json!(agree),
        ]);
    }
    t
}

fn renderer_table(ctx: &mut Ctx) -> Result<Table> {
    let sa = synth_a(ctx)?;
    let scene = &sa.loaded;
    let q_max = scene.render.q_max();
    let mut t = Table::new(
        "stability-render",
        "The renderer where its formulas switch cases",
        format!(
            "Eq. (3)-(6) on the synthetic scene (M = {}), each q rendered by a player with the \
             same history (it showed q = 0.2 first). The difference to the previous row is the \
             mean and largest absolute difference in grey levels and the PSNR: within one case \
             a 1e-9 step must change nothing visible; at the 0.5 tie the object's source view \
             switches (a seam, by design of eq. 4-5). Rows past the ends and NaN show what the \
             renderer does with a q outside [0, M-1].",
            scene.render.views.len()
        ),
        &[
            "q",
            "source view, frame",
            "mean diff to previous q",
            "max diff to previous q",
            "PSNR to previous q (dB)",
        ],
    );
    let mut renderer = Renderer::new(scene.render.clone(), RenderParams::default())?;
    let (w, h) = renderer.size();
    let mut history = Player::new();
    history.advance(&scene.render, 0.2)?;
    let mut prev: Option<RgbImage> = None;
    let qs = [
        ("0", 0.0),
        ("1e-9", 1e-9),
        ("0.5 - 1e-9", 0.5 - 1e-9),
        ("0.5", 0.5),
        ("0.5 + 1e-9", 0.5 + 1e-9),
        ("M-1 - 1e-9", q_max - 1e-9),
        ("M-1", q_max),
    ];
    for (label, q) in qs {
        let mut player = history.clone();
        let choice = player.advance(&scene.render, q)?;
        let mut out = RgbImage::new(w, h);
        renderer.render_into(&scene.objects, q, &choice, &mut out)?;
        let (mean, max, p) = match &prev {
            Some(a) => {
                let diffs: Vec<u8> = a
                    .as_raw()
                    .iter()
                    .zip(out.as_raw())
                    .map(|(x, y)| x.abs_diff(*y))
                    .collect();
                let mean = diffs.iter().map(|&d| d as f64).sum::<f64>() / diffs.len() as f64;
                let max = diffs.iter().copied().max().unwrap_or(0);
                let p = psnr(&out, a, None)?;
                (
                    json!(mean),
                    json!(max),
                    if p.is_finite() {
                        json!(p)
                    } else {
                        json!("inf (identical)")
                    },
                )
            }
            None => (json!(null), json!(null), json!(null)),
        };
        t.row(vec![
            json!(label),
            json!(format!("{}, {}", choice.view, choice.frame)),
            mean,
            max,
            p,
        ]);
        prev = Some(out);
    }
    for (label, q) in [
        ("-1e-9", -1e-9),
        ("M-1 + 1e-9", q_max + 1e-9),
        ("NaN", f64::NAN),
    ] {
        let mut player = history.clone();
        let r = player.advance(&scene.render, q);
        t.row(vec![
            json!(label),
            json!(outcome(&r, |c| format!(
                "{}, {} (accepted)",
                c.view, c.frame
            ))),
            json!(null),
            json!(null),
            json!(null),
        ]);
    }
    Ok(t)
}

/// Builds the section.
pub fn build(ctx: &mut Ctx) -> Result<Vec<Item>> {
    Ok(vec![
        Item::Table(homography_table()),
        Item::Table(images_table()),
        Item::Table(renderer_table(ctx)?),
    ])
}
