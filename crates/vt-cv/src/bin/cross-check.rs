//! `cargo xtask cross-check`: runs vt-core and vt-cv (OpenCV) on the same inputs and asserts
//! that they agree within documented tolerances; prints one table and exits non-zero on any
//! failure.
//!
//! Inputs: synthetic texture scenes from `vt-synth` (several sizes and seeds), real data from
//! `testdata/` (tree.avi, the graf pair with its true homography, temple photos), and extremes
//! (far, near-collinear and tiny point sets, nearly singular homographies, 1x1 and 8K images,
//! all-empty and all-full masks).
//!
//! Tolerances, and why:
//! - median, masks from the same blurred frames, morphology, XOR costs, loops, transition tables,
//!   nearest-neighbour warps: **identical** (integer or exact operations on both sides).
//! - Gaussian blur: **within 1 grey level**. OpenCV's 8-bit `GaussianBlur` is fixed point
//!   (taps rounded to 8-bit fractions per pass, integer sums), vt-core's is `f32`; a value whose
//!   exact result lies near `k + 0.5` can round either way.
//! - masks where each side uses its own blur: **<= 0.1% of pixels**, since a one-level blur
//!   difference flips pixels whose difference from the background sits right at the threshold.
//! - bilinear warps: **>= 99.9% of pixels within 1 grey level**. OpenCV quantises the mapped
//!   coordinate to 1/32 pixel (`INTER_BITS = 5`) and uses 15-bit integer weights; vt-core
//!   interpolates with the exact fraction. A 1/64-pixel coordinate error times a local gradient of
//!   up to 255 levels per pixel gives up to ~4 levels at the sharpest edges, on few pixels.
//! - homographies on well-conditioned points: **relative difference <= 1e-6** (matrices scaled
//!   to unit norm). OpenCV converts points to `f32`, so both sides get the same `f32`-rounded
//!   points there, and the figure measures the algorithms, not the input rounding.
//! - stability: vt-core's RMS transfer error on the original `f64` points is never worse than
//!   OpenCV's (slack `1e-9` relative plus `1e-12` px absolute, the floor of `f64` arithmetic on
//!   exact data), and vt-core never returns a non-finite homography (an error is fine).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use image::RgbImage;
use nalgebra::Matrix3;
use vt_core::analysis::{foreground_mask, FrameSource, MaskParams};
use vt_core::blur::GaussianParams;
use vt_core::homography::HomographyFit;
use vt_core::loops::{Loop, LoopParams};
use vt_core::warp::Interpolation;
use vt_core::{Homography, Mask, Point};
use vt_synth::{Rig, TextureParams, TextureScene};

/// One line of the table.
struct Row {
    op: String,
    input: String,
    figure: String,
    tolerance: String,
    pass: bool,
}

#[derive(Default)]
struct Table {
    rows: Vec<Row>,
}

impl Table {
    fn add(
        &mut self,
        op: &str,
        input: &str,
        figure: impl Into<String>,
        tolerance: &str,
        pass: bool,
    ) {
        let row = Row {
            op: op.into(),
            input: input.into(),
            figure: figure.into(),
            tolerance: tolerance.into(),
            pass,
        };
        self.rows.push(row);
    }

    /// Records an error from either side as a failed row (the run goes on).
    fn error(&mut self, op: &str, input: &str, e: impl std::fmt::Display) {
        self.add(op, input, format!("error: {e}"), "no error", false);
    }

    fn print(&self) {
        let head = ["operation", "input", "figure", "tolerance", "pass/fail"];
        let cells: Vec<[String; 5]> = self
            .rows
            .iter()
            .map(|r| {
                [
                    r.op.clone(),
                    r.input.clone(),
                    r.figure.clone(),
                    r.tolerance.clone(),
                    (if r.pass { "pass" } else { "FAIL" }).into(),
                ]
            })
            .collect();
        let mut width = head.map(str::len);
        for c in &cells {
            for i in 0..5 {
                width[i] = width[i].max(c[i].chars().count());
            }
        }
        let line = |c: &[String; 5]| {
            let parts: Vec<String> = (0..5)
                .map(|i| format!("{:<w$}", c[i], w = width[i]))
                .collect();
            println!("| {} |", parts.join(" | "));
        };
        line(&head.map(String::from));
        let sep: Vec<String> = width.iter().map(|w| "-".repeat(*w)).collect();
        println!("|-{}-|", sep.join("-|-"));
        for c in &cells {
            line(c);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Measures.

/// Per-pixel differences between two RGB images (a pixel's difference is its largest channel's).
#[derive(Clone)]
struct ImageDiff {
    max: u8,
    differ: usize,
    over_one: usize,
    pixels: usize,
}

fn image_diff(a: &RgbImage, b: &RgbImage) -> ImageDiff {
    assert_eq!(
        a.dimensions(),
        b.dimensions(),
        "compared images share a size"
    );
    let mut d = ImageDiff {
        max: 0,
        differ: 0,
        over_one: 0,
        pixels: (a.width() * a.height()) as usize,
    };
    for (p, q) in a.as_raw().chunks_exact(3).zip(b.as_raw().chunks_exact(3)) {
        let m = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        d.max = d.max.max(m);
        d.differ += (m > 0) as usize;
        d.over_one += (m > 1) as usize;
    }
    d
}

fn pct(n: usize, of: usize) -> f64 {
    if of == 0 {
        0.0
    } else {
        100.0 * n as f64 / of as f64
    }
}

/// Blur rows: every value within one grey level.
fn check_blur(t: &mut Table, op: &str, input: &str, vt: &RgbImage, cv: &RgbImage) {
    blur_row(t, op, input, image_diff(vt, cv));
}

/// One blur row from a computed difference: every value within one grey level.
fn blur_row(t: &mut Table, op: &str, input: &str, d: ImageDiff) {
    t.add(
        op,
        input,
        format!(
            "max |diff| {}, {:.3}% of pixels differ",
            d.max,
            pct(d.differ, d.pixels)
        ),
        "max |diff| <= 1",
        d.max <= 1,
    );
}

/// OpenCV's bilinear `warpPerspective` modelled in Rust: the source coordinate computed in
/// `f64` in `warpPerspective`'s order (blocks of 64 columns), rounded to 1/32 pixel
/// (`INTER_BITS = 5`, `cvRound`), then `remap`'s 15-bit integer weights
/// `(32 - fy)(32 - fx) * 32` etc. and `(sum + 2^14) >> 15`, constant border 0.
fn opencv_bilinear_model(src: &RgbImage, inv: &Matrix3<f64>, width: u32, height: u32) -> RgbImage {
    use rayon::prelude::*;
    let (sw, sh) = (src.width() as i64, src.height() as i64);
    let m = inv.transpose(); // row-major, as OpenCV's M[0..9]
    let m = m.as_slice();
    let (w, h) = (width as usize, height as usize);
    let block_h = 16.min(h);
    let block_w = (1024 / block_h).min(w);
    let mut out = vec![0u8; w * h * 3];
    out.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        let yf = y as f64;
        for x in 0..w {
            let xb = (x / block_w * block_w) as f64;
            let x1 = (x % block_w) as f64;
            let x0 = m[0] * xb + m[1] * yf + m[2];
            let y0 = m[3] * xb + m[4] * yf + m[5];
            let w0 = m[6] * xb + m[7] * yf + m[8];
            let ww = w0 + m[6] * x1;
            let ww = if ww != 0.0 { 32.0 / ww } else { 0.0 };
            let fx = ((x0 + m[0] * x1) * ww).clamp(i32::MIN as f64, i32::MAX as f64);
            let fy = ((y0 + m[3] * x1) * ww).clamp(i32::MIN as f64, i32::MAX as f64);
            let (qx, qy) = (fx.round_ties_even() as i64, fy.round_ties_even() as i64);
            let (sx, sy) = (
                (qx >> 5).clamp(-32768, 32767),
                (qy >> 5).clamp(-32768, 32767),
            );
            let (ax, ay) = (qx & 31, qy & 31);
            if sx >= sw || sx + 1 < 0 || sy >= sh || sy + 1 < 0 {
                continue; // wholly outside: the border value 0
            }
            for c in 0..3 {
                let at = |xx: i64, yy: i64| src_value(src, xx, yy, c);
                let sum = at(sx, sy) * (32 - ay) * (32 - ax) * 32
                    + at(sx + 1, sy) * (32 - ay) * ax * 32
                    + at(sx, sy + 1) * ay * (32 - ax) * 32
                    + at(sx + 1, sy + 1) * ay * ax * 32;
                row[x * 3 + c] = ((sum + (1 << 14)) >> 15).clamp(0, 255) as u8;
            }
        }
    });
    RgbImage::from_raw(width, height, out).expect("buffer is w*h*3")
}

/// A source value with the constant border 0.
fn src_value(src: &RgbImage, x: i64, y: i64, c: usize) -> i64 {
    if x < 0 || y < 0 || x >= src.width() as i64 || y >= src.height() as i64 {
        0
    } else {
        src.as_raw()[((y * src.width() as i64 + x) * 3) as usize + c] as i64
    }
}

/// The bound `1 + R / 32` on `|vt-core - OpenCV|` at output pixel `(x, y)`, channel `c`, where
/// `R` is the value range of the 4x4 source block around vt-core's exact sample: the bilinear
/// interpolant changes by at most `R` per pixel in each axis there, OpenCV's quantised
/// coordinate is within 1/64 pixel of the exact one in each axis, and the two roundings add
/// less than one level.
fn quantisation_bound(src: &RgbImage, inv: &Matrix3<f64>, x: usize, y: usize, c: usize) -> f64 {
    let v = inv * nalgebra::Vector3::new(x as f64, y as f64, 1.0);
    let (ex, ey) = (v.x / v.z, v.y / v.z);
    if !(ex.is_finite() && ey.is_finite() && ex.abs() < 1e9 && ey.abs() < 1e9) {
        return 1.0;
    }
    let (bx, by) = (ex.floor() as i64, ey.floor() as i64);
    let (mut lo, mut hi) = (255i64, 0i64);
    for yy in by - 1..by + 3 {
        for xx in bx - 1..bx + 3 {
            let s = src_value(src, xx, yy, c);
            lo = lo.min(s);
            hi = hi.max(s);
        }
    }
    1.0 + (hi - lo).max(0) as f64 / 32.0
}

/// The blur in `f64` with OpenCV's kernel and `BORDER_REFLECT_101`, unrounded: the exact answer
/// that both 8-bit results approximate.
fn exact_blur(src: &RgbImage, p: &GaussianParams) -> Result<Vec<f64>> {
    let k = vt_core::blur::gaussian_kernel(p.ksize, p.sigma)?;
    let (w, h, r) = (
        src.width() as isize,
        src.height() as isize,
        (p.ksize / 2) as isize,
    );
    let reflect = |mut i: isize, n: isize| -> usize {
        if n == 1 {
            return 0;
        }
        loop {
            if i < 0 {
                i = -i;
            } else if i >= n {
                i = 2 * n - 2 - i;
            } else {
                return i as usize;
            }
        }
    };
    let raw = src.as_raw();
    let mut tmp = vec![0f64; raw.len()];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let row = (y * w) as usize;
                tmp[(row + x as usize) * 3 + c] = k
                    .iter()
                    .enumerate()
                    .map(|(j, kv)| kv * raw[(row + reflect(x + j as isize - r, w)) * 3 + c] as f64)
                    .sum();
            }
        }
    }
    let mut out = vec![0f64; raw.len()];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                out[((y * w + x) as usize) * 3 + c] = k
                    .iter()
                    .enumerate()
                    .map(|(j, kv)| {
                        kv * tmp[(reflect(y + j as isize - r, h) * w as usize + x as usize) * 3 + c]
                    })
                    .sum();
            }
        }
    }
    Ok(out)
}

/// Blur against the exact `f64` result: vt-core must be correctly rounded up to its `f32`
/// accumulation (within 0.5 + 1e-3);
/// OpenCV's error is reported (its fixed-point taps drift further as the kernel grows).
fn check_blur_exact(t: &mut Table, input: &str, src: &RgbImage, p: &GaussianParams) -> Result<()> {
    let exact = exact_blur(src, p)?;
    let vt = vt_core::blur::gaussian_blur(src, p)?;
    let cv = vt_cv::blur::gaussian_blur(src, p)?;
    let err = |img: &RgbImage| {
        img.as_raw()
            .iter()
            .zip(&exact)
            .map(|(a, e)| (*a as f64 - e).abs())
            .fold(0.0, f64::max)
    };
    let off = |img: &RgbImage| {
        img.as_raw()
            .iter()
            .zip(&exact)
            .filter(|(a, e)| (**a as f64 - **e).abs() > 0.5 + 1e-3)
            .count()
    };
    let d = image_diff(&vt, &cv);
    t.add(
        &format!("Gaussian {0}x{0} s{1} vs exact f64", p.ksize, p.sigma),
        input,
        format!(
            "max |err| vt {:.3} cv {:.3}; cv {} values off by > 0.5; max |vt-cv| {}",
            err(&vt),
            err(&cv),
            off(&cv),
            d.max
        ),
        "vt within 0.5 + 1e-3 (f32)",
        off(&vt) == 0,
    );
    Ok(())
}

/// Bilinear warp rows. vt-core against OpenCV: every value within [`quantisation_bound`], with
/// the share of pixels within one grey level reported (">= 99.9% within 1" holds on smooth
/// images, not at sharp edges, see the README). The model against OpenCV: identical, which
/// shows that `INTER_BITS` is the whole difference.
fn check_warp_bilinear(
    t: &mut Table,
    input: &str,
    src: &RgbImage,
    h: &Homography,
    width: u32,
    height: u32,
) -> Result<()> {
    let vt = vt_core::warp::warp_rgb(src, h, width, height, Interpolation::Bilinear);
    let cv = vt_cv::warp::warp_rgb(src, h, width, height, Interpolation::Bilinear)?;
    let d = image_diff(&vt, &cv);
    let within = 100.0 - pct(d.over_one, d.pixels);
    let inv = h.raw().1;
    // The bound is at least 1, so only values differing by more need it.
    let outside = vt
        .as_raw()
        .iter()
        .zip(cv.as_raw())
        .enumerate()
        .filter(|(_, (a, b))| a.abs_diff(**b) > 1)
        .filter(|(i, (a, b))| {
            let (px, c) = (i / 3, i % 3);
            a.abs_diff(**b) as f64
                > quantisation_bound(src, inv, px % width as usize, px / width as usize, c)
        })
        .count();
    t.add(
        "warp RGB bilinear",
        input,
        format!(
            "{within:.3}% within 1, max {}, {outside} values over bound",
            d.max
        ),
        "|d| <= 1 + R/32 (INTER_BITS)",
        outside == 0,
    );
    let m = image_diff(&opencv_bilinear_model(src, inv, width, height), &cv);
    t.add(
        "warp bilinear, 1/32 px model",
        input,
        format!("{} of {} pixels differ (max {})", m.differ, m.pixels, m.max),
        "identical",
        m.differ == 0,
    );
    Ok(())
}

fn check_identical_rgb(t: &mut Table, op: &str, input: &str, vt: &RgbImage, cv: &RgbImage) {
    let d = image_diff(vt, cv);
    t.add(
        op,
        input,
        format!("{} of {} pixels differ (max {})", d.differ, d.pixels, d.max),
        "identical",
        d.differ == 0,
    );
}

fn check_identical_masks(t: &mut Table, op: &str, input: &str, vt: &[Mask], cv: &[Mask]) {
    let differ: u64 = vt
        .iter()
        .zip(cv)
        .map(|(a, b)| vt_core::mask::xor_count(a, b))
        .sum();
    let total: u64 = vt.iter().map(|m| m.len() as u64).sum();
    let set: u64 = vt.iter().map(|m| m.count_ones()).sum();
    t.add(
        op,
        input,
        format!(
            "{differ} of {total} pixels differ ({:.2}% set)",
            100.0 * set as f64 / total.max(1) as f64
        ),
        "identical",
        differ == 0 && vt.len() == cv.len(),
    );
}

/// Unit-norm, sign-aligned Frobenius distance between two matrices of one projective map.
fn h_rel_diff(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let (a, b) = (a / a.norm(), b / b.norm());
    let sign = if a.dot(&b) < 0.0 { -1.0 } else { 1.0 };
    (a - b * sign).norm()
}

/// RMS transfer error of a raw matrix (infinite when a point maps to infinity).
fn rms(m: &Matrix3<f64>, src: &[Point], dst: &[Point]) -> f64 {
    let mut sum = 0.0;
    for (s, d) in src.iter().zip(dst) {
        let v = m * nalgebra::Vector3::new(s.x, s.y, 1.0);
        if v.z == 0.0 {
            return f64::INFINITY;
        }
        sum += (v.x / v.z - d.x).powi(2) + (v.y / v.z - d.y).powi(2);
    }
    let r = (sum / src.len().max(1) as f64).sqrt();
    if r.is_nan() {
        f64::INFINITY
    } else {
        r
    }
}

fn round_f32(pts: &[Point]) -> Vec<Point> {
    pts.iter()
        .map(|p| Point::new(p.x as f32 as f64, p.y as f32 as f64))
        .collect()
}

/// Deterministic noise in [-1, 1] (splitmix64), so the run needs no RNG crate.
fn noise(seed: u64, i: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i.wrapping_mul(0xBF58_476D_1CE4_E5B9));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// One splitmix64 step.
fn mix_u64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn map_points(h: &Matrix3<f64>, pts: &[Point]) -> Vec<Point> {
    pts.iter()
        .map(|p| {
            let v = h * nalgebra::Vector3::new(p.x, p.y, 1.0);
            Point::new(v.x / v.z, v.y / v.z)
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Homography rows.

/// Agreement on well-conditioned points: both sides get the same f32-rounded points.
fn homography_agreement(
    t: &mut Table,
    input: &str,
    src: &[Point],
    dst: &[Point],
    truth: Option<&Matrix3<f64>>,
) {
    let (s32, d32) = (round_f32(src), round_f32(dst));
    let op = if src.len() == 4 {
        "homography (4 pts, getPerspectiveTransform)"
    } else {
        "homography (findHomography 0)"
    };
    let vt = Homography::from_correspondences(&s32, &d32);
    let cv = vt_cv::homography::from_correspondences(&s32, &d32);
    match (vt, cv) {
        (Ok(vt), Ok(cv)) => {
            let (mv, mc) = (vt.homography.matrix(), cv.homography.matrix());
            let rel = h_rel_diff(&mv, &mc);
            let truth_txt = truth
                .map(|h| {
                    format!(
                        ", vs truth vt {:.1e} cv {:.1e}",
                        h_rel_diff(&mv, h),
                        h_rel_diff(&mc, h)
                    )
                })
                .unwrap_or_default();
            t.add(
                op,
                input,
                format!(
                    "rel diff {rel:.2e} (rms vt {:.2e} cv {:.2e}{truth_txt})",
                    vt.rms, cv.rms
                ),
                "<= 1e-6",
                rel <= 1e-6,
            );
        }
        (vt, cv) => t.add(
            op,
            input,
            format!("vt {:?} / cv {:?}", vt.map(|f| f.rms), cv.map(|f| f.rms)),
            "both succeed",
            false,
        ),
    }
}

/// Stability: vt-core on the original points never worse than OpenCV, never non-finite.
fn homography_stability(t: &mut Table, input: &str, src: &[Point], dst: &[Point]) {
    let vt: Result<HomographyFit, _> = Homography::from_correspondences(src, dst);
    let cv = vt_cv::homography::estimate_matrix(src, dst);
    let cv_rms = cv
        .as_ref()
        .map(|m| rms(m, src, dst))
        .unwrap_or(f64::INFINITY);
    let cv_txt = match &cv {
        Ok(_) => format!("cv rms {cv_rms:.2e}"),
        Err(_) => "cv error".to_string(),
    };
    match vt {
        Ok(fit) => {
            let m = fit.homography.matrix();
            let vt_rms = rms(&m, src, dst);
            let finite =
                m.iter().all(|v| v.is_finite()) && vt_rms.is_finite() && fit.rms.is_finite();
            let ok = finite && vt_rms <= cv_rms * (1.0 + 1e-9) + 1e-12;
            t.add(
                "homography stability",
                input,
                format!("vt rms {vt_rms:.2e}, {cv_txt}"),
                "finite, vt <= cv (1e-9 rel)",
                ok,
            );
        }
        Err(e) => {
            // An error is an acceptable answer; say which one and what OpenCV did instead.
            let msg = e.to_string();
            let short: String = msg.chars().take(48).collect();
            t.add(
                "homography stability",
                input,
                format!("vt Err ({short}...), {cv_txt}"),
                "finite, vt <= cv (1e-9 rel)",
                true,
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Sections.

fn testdata() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata")
}

/// Sums of per-view image differences (max of maxima, sums of counts).
fn merge_diffs(diffs: impl IntoIterator<Item = ImageDiff>) -> ImageDiff {
    diffs.into_iter().fold(
        ImageDiff {
            max: 0,
            differ: 0,
            over_one: 0,
            pixels: 0,
        },
        |a, d| ImageDiff {
            max: a.max.max(d.max),
            differ: a.differ + d.differ,
            over_one: a.over_one + d.over_one,
            pixels: a.pixels + d.pixels,
        },
    )
}

/// Differing pixels, total pixels and set pixels of two mask sequences.
fn mask_counts(vt: &[Mask], cv: &[Mask]) -> (u64, u64, u64) {
    let differ = vt
        .iter()
        .zip(cv)
        .map(|(a, b)| vt_core::mask::xor_count(a, b))
        .sum();
    (
        differ,
        vt.iter().map(|m| m.len() as u64).sum(),
        vt.iter().map(|m| m.count_ones()).sum(),
    )
}

/// One view's figures for [`view_checks`].
struct ViewFigures {
    median_memory: ImageDiff,
    median_stream: ImageDiff,
    blur_background: ImageDiff,
    blur_frames: ImageDiff,
    blur_5x5: ImageDiff,
    mask_same: (u64, u64, u64),
    threshold_same: (u64, u64, u64),
    mask_own: (u64, u64, u64),
    xor_wrong: usize,
    xor_pairs: usize,
    loop_vt: Loop,
    loop_cv: Loop,
    loops3_equal: bool,
    loop_own_cv: Loop,
    masks: Vec<Mask>,
}

fn view_figures(frames: &[RgbImage], loops: &LoopParams, what: &str) -> Result<ViewFigures> {
    let blur = GaussianParams::default();
    let mask_params = MaskParams {
        threshold: 25,
        open_radius: 1,
        close_radius: 2,
    };
    // Median: vt-core's in-memory route and its streaming accumulator, against cv::sort.
    let vt_bg = vt_core::median::temporal_median(frames)?;
    let mut acc = vt_core::median::MedianAccumulator::new(frames[0].width(), frames[0].height());
    for f in frames {
        acc.push(f)?;
    }
    let vt_bg_stream = acc.median()?;
    drop(acc);
    let cv_bg = vt_cv::median::temporal_median(frames)?;
    // Blur: 3x3 default (fixed table) on background and frames, 5x5 sigma 1.2 (formula).
    let vt_bg_blur = vt_core::blur::gaussian_blur(&vt_bg, &blur)?;
    let cv_bg_blur = vt_cv::blur::gaussian_blur(&vt_bg, &blur)?;
    let vt_blurred: Vec<RgbImage> = frames
        .iter()
        .map(|f| vt_core::blur::gaussian_blur(f, &blur))
        .collect::<Result<_, _>>()?;
    let cv_blurred: Vec<RgbImage> = frames
        .iter()
        .map(|f| vt_cv::blur::gaussian_blur(f, &blur))
        .collect::<Result<_, _>>()?;
    let g5 = GaussianParams {
        ksize: 5,
        sigma: 1.2,
    };
    // Masks: from the same blurred frames (vt-core's), and each side from its own blur.
    let vt_masks: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| foreground_mask(f, &vt_bg_blur, &mask_params))
        .collect::<Result<_, _>>()?;
    let cv_same: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| vt_cv::mask::foreground_mask(f, &vt_bg_blur, &mask_params))
        .collect::<Result<_, _>>()?;
    let vt_raw: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| vt_core::analysis::threshold_mask(f, &vt_bg_blur, 25))
        .collect::<Result<_, _>>()?;
    let cv_raw: Vec<Mask> = vt_blurred
        .iter()
        .map(|f| vt_cv::mask::threshold_mask(f, &vt_bg_blur, 25))
        .collect::<Result<_, _>>()?;
    let cv_masks: Vec<Mask> = cv_blurred
        .iter()
        .map(|f| vt_cv::mask::foreground_mask(f, &cv_bg_blur, &mask_params))
        .collect::<Result<_, _>>()?;
    // XOR costs of every pair of vt-core's masks.
    let mats: Vec<_> = vt_masks
        .iter()
        .map(vt_cv::convert::mask_to_mat)
        .collect::<Result<_, _>>()?;
    let cv_costs = vt_cv::loops::pair_costs(&mats, 0)?;
    let n = vt_masks.len();
    let mut xor_wrong = 0usize;
    for a in 0..n {
        for b in a..n {
            xor_wrong += (vt_core::mask::xor_count(&vt_masks[a], &vt_masks[b])
                != cv_costs[a * n + b]) as usize;
        }
    }
    Ok(ViewFigures {
        median_memory: image_diff(&vt_bg, &cv_bg),
        median_stream: image_diff(&vt_bg_stream, &cv_bg),
        blur_background: image_diff(&vt_bg_blur, &cv_bg_blur),
        blur_frames: merge_diffs(
            vt_blurred
                .iter()
                .zip(&cv_blurred)
                .map(|(a, b)| image_diff(a, b)),
        ),
        blur_5x5: image_diff(
            &vt_core::blur::gaussian_blur(&frames[0], &g5)?,
            &vt_cv::blur::gaussian_blur(&frames[0], &g5)?,
        ),
        mask_same: mask_counts(&vt_masks, &cv_same),
        threshold_same: mask_counts(&vt_raw, &cv_raw),
        mask_own: mask_counts(&vt_masks, &cv_masks),
        xor_wrong,
        xor_pairs: n * (n + 1) / 2,
        loop_vt: vt_core::loops::find_loop(&vt_masks, loops, what)?,
        loop_cv: vt_cv::loops::find_loop(&vt_masks, loops, what)?,
        loops3_equal: vt_core::loops::find_loops(&vt_masks, loops, 3, 2, what)?
            == vt_cv::loops::find_loops(&vt_masks, loops, 3, 2, what)?,
        loop_own_cv: vt_cv::loops::find_loop(&cv_masks, loops, what)?,
        masks: vt_masks,
    })
}

/// The per-view checks shared by synthetic scenes and tree.avi (median, blur, masks, XOR,
/// loops), one row per operation over all the views given. Returns vt-core's masks (from its
/// own blur) and loop per view.
fn view_checks(
    t: &mut Table,
    input: &str,
    views: &[Vec<RgbImage>],
    loops: &LoopParams,
) -> Result<Vec<(Vec<Mask>, Loop)>> {
    let figs: Vec<ViewFigures> = views
        .iter()
        .enumerate()
        .map(|(v, frames)| view_figures(frames, loops, &format!("{input} view {v}")))
        .collect::<Result<_>>()?;
    let n_frames: usize = views.iter().map(Vec::len).sum();
    let all = if views.len() > 1 {
        format!("{input}, {} views", views.len())
    } else {
        input.to_string()
    };
    let identical = |t: &mut Table, op: &str, d: ImageDiff| {
        t.add(
            op,
            &all,
            format!("{} of {} pixels differ (max {})", d.differ, d.pixels, d.max),
            "identical",
            d.differ == 0,
        )
    };
    identical(
        t,
        "median (in memory)",
        merge_diffs(figs.iter().map(|f| f.median_memory.clone())),
    );
    identical(
        t,
        "median (streaming)",
        merge_diffs(figs.iter().map(|f| f.median_stream.clone())),
    );
    blur_row(
        t,
        "Gaussian 3x3 (background)",
        &all,
        merge_diffs(figs.iter().map(|f| f.blur_background.clone())),
    );
    blur_row(
        t,
        "Gaussian 3x3 (every frame)",
        &format!("{all}, {n_frames} frames"),
        merge_diffs(figs.iter().map(|f| f.blur_frames.clone())),
    );
    blur_row(
        t,
        "Gaussian 5x5 s1.2",
        &format!("{all}, frame 0"),
        merge_diffs(figs.iter().map(|f| f.blur_5x5.clone())),
    );
    let masks_row = |t: &mut Table, op: &str, c: Vec<(u64, u64, u64)>| {
        let (differ, total, set) = c
            .iter()
            .fold((0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        t.add(
            op,
            &all,
            format!(
                "{differ} of {total} pixels differ ({:.2}% set)",
                100.0 * set as f64 / total.max(1) as f64
            ),
            "identical",
            differ == 0,
        )
    };
    masks_row(
        t,
        "mask (same blur, open 1 close 2)",
        figs.iter().map(|f| f.mask_same).collect(),
    );
    masks_row(
        t,
        "mask (same blur, threshold only)",
        figs.iter().map(|f| f.threshold_same).collect(),
    );
    let (differ, total) = figs
        .iter()
        .fold((0, 0), |a, f| (a.0 + f.mask_own.0, a.1 + f.mask_own.1));
    let share = 100.0 * differ as f64 / total.max(1) as f64;
    t.add(
        "mask (own blur each)",
        &all,
        format!("{differ} of {total} pixels differ ({share:.4}%)"),
        "<= 0.1%",
        share <= 0.1,
    );
    let (wrong, pairs) = figs
        .iter()
        .fold((0, 0), |a, f| (a.0 + f.xor_wrong, a.1 + f.xor_pairs));
    t.add(
        "XOR cost",
        &format!("{all}, {pairs} pairs"),
        format!("{wrong} costs differ"),
        "identical",
        wrong == 0,
    );
    let lp = |l: &Loop| format!("({}, {}) {}", l.start, l.end, l.cost);
    let per_view =
        |f: &dyn Fn(&ViewFigures) -> String| figs.iter().map(f).collect::<Vec<_>>().join("; ");
    t.add(
        "loop eq. (1), same masks",
        &format!("{all}, w {} k {}", loops.window, loops.min_length),
        format!(
            "(m, n) cost vt/cv: {}",
            per_view(&|f| format!("{} / {}", lp(&f.loop_vt), lp(&f.loop_cv)))
        ),
        "identical",
        figs.iter().all(|f| f.loop_vt == f.loop_cv),
    );
    t.add(
        "3 distinct loops, same masks",
        &all,
        format!(
            "{} of {} views equal",
            figs.iter().filter(|f| f.loops3_equal).count(),
            figs.len()
        ),
        "identical",
        figs.iter().all(|f| f.loops3_equal),
    );
    t.add(
        "loop eq. (1), own pipelines",
        &all,
        format!(
            "(m, n) vt/cv: {}",
            per_view(&|f| format!(
                "({}, {}) / ({}, {})",
                f.loop_vt.start, f.loop_vt.end, f.loop_own_cv.start, f.loop_own_cv.end
            ))
        ),
        "same (m, n)",
        figs.iter()
            .all(|f| (f.loop_vt.start, f.loop_vt.end) == (f.loop_own_cv.start, f.loop_own_cv.end)),
    );
    Ok(figs.into_iter().map(|f| (f.masks, f.loop_vt)).collect())
}

/// Eq. (2) between two views with vt-core's masks and loop: warps and tables.
fn transition_checks(
    t: &mut Table,
    input: &str,
    src: &[Mask],
    dst: &[Mask],
    h: &Homography,
    dst_loop: &Loop,
    window: usize,
) -> Result<()> {
    let (w, hh) = (dst[0].width(), dst[0].height());
    let vt_w = vt_core::transition::warp_masks(src, h, w, hh);
    let cv_w = vt_cv::transition::warp_masks(src, h, w, hh)?;
    check_identical_masks(t, "warp masks (nearest)", input, &vt_w, &cv_w);
    let vt_t = vt_core::transition::transition_table(&vt_w, dst, dst_loop.end, window)?;
    let cv_same = vt_cv::transition::transition_table(&vt_w, dst, dst_loop.end, window)?;
    let cv_t = vt_cv::transition::transition_table(&cv_w, dst, dst_loop.end, window)?;
    let differ = |a: &[Option<usize>], b: &[Option<usize>]| {
        a.iter().zip(b).filter(|(x, y)| x != y).count() + a.len().abs_diff(b.len())
    };
    t.add(
        "transition eq. (2), same warps",
        &format!("{input}, {} frames", vt_t.len()),
        format!("{} entries differ", differ(&vt_t, &cv_same)),
        "identical",
        differ(&vt_t, &cv_same) == 0,
    );
    t.add(
        "transition eq. (2), own warps",
        input,
        format!("{} entries differ", differ(&vt_t, &cv_t)),
        "identical",
        differ(&vt_t, &cv_t) == 0,
    );
    Ok(())
}

fn synthetic(
    t: &mut Table,
    width: u32,
    height: u32,
    seed: u64,
    frames: usize,
    period: usize,
    rig: Rig,
) -> Result<()> {
    let params = TextureParams {
        views: 2,
        frames,
        width,
        height,
        period,
        seed,
        rig,
        ..TextureParams::default()
    };
    let scene = TextureScene::new(params).map_err(anyhow::Error::msg)?;
    let input = format!("synth {width}x{height} s{seed} {rig:?}");
    let t0 = Instant::now();
    let views: Vec<Vec<RgbImage>> = (0..2)
        .map(|v| (0..frames).map(|f| scene.frame(v, f)).collect())
        .collect();
    eprintln!(
        "{input}: rendered {} frames in {:.1?}",
        2 * frames,
        t0.elapsed()
    );
    let loops = LoopParams {
        window: 3,
        min_length: period,
    };
    let results = view_checks(t, &input, &views, &loops)?;

    // Homographies from the marked points (exact projections), 6 and 4 of them.
    let pts = |v: usize| {
        scene
            .points(v)
            .into_iter()
            .map(|(x, y)| Point::new(x, y))
            .collect::<Vec<_>>()
    };
    let (p0, p1) = (pts(0), pts(1));
    let truth = scene.plane_homography(0.0, 1.0);
    homography_agreement(t, &format!("{input} 6 marks"), &p0, &p1, Some(&truth));
    homography_agreement(
        t,
        &format!("{input} 4 marks"),
        &p0[..4],
        &p1[..4],
        Some(&truth),
    );
    let h = Homography::from_correspondences(&p0, &p1)?.homography;

    // Colour warps of frame 0 of view 0 into view 1.
    let f = &views[0][0];
    check_warp_bilinear(t, &format!("{input} frame 0"), f, &h, width, height)?;
    let vt_nn = vt_core::warp::warp_rgb(f, &h, width, height, Interpolation::Nearest);
    let cv_nn = vt_cv::warp::warp_rgb(f, &h, width, height, Interpolation::Nearest)?;
    check_identical_rgb(
        t,
        "warp RGB nearest",
        &format!("{input} frame 0"),
        &vt_nn,
        &cv_nn,
    );

    transition_checks(
        t,
        &format!("{input} 0->1"),
        &results[0].0,
        &results[1].0,
        &h,
        &results[1].1,
        loops.window,
    )?;
    transition_checks(
        t,
        &format!("{input} 1->0"),
        &results[1].0,
        &results[0].0,
        &h.inverse(),
        &results[0].1,
        loops.window,
    )?;
    Ok(())
}

fn tree(t: &mut Table) -> Result<()> {
    let path = testdata().join("tree.avi");
    let mut src = vt_io::frames::VideoSource::open(&path)
        .with_context(|| format!("opening {}", path.display()))?;
    let mut frames = Vec::new();
    src.for_each_frame(&mut |_, f| {
        frames.push(f.clone());
        Ok(())
    })?;
    if frames.len() < 30 {
        bail!("{}: only {} frames decoded", path.display(), frames.len());
    }
    let input = format!(
        "tree.avi {}x{} {} frames",
        frames[0].width(),
        frames[0].height(),
        frames.len()
    );
    view_checks(
        t,
        &input,
        &[frames],
        &LoopParams {
            window: 3,
            min_length: 20,
        },
    )?;
    Ok(())
}

fn read_h1to3p(path: &Path) -> Result<Matrix3<f64>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let data = text
        .split("<data>")
        .nth(1)
        .and_then(|s| s.split("</data>").next())
        .context("no <data> in H1to3p.xml")?;
    let v: Vec<f64> = data
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .context("H1to3p.xml numbers")?;
    if v.len() != 9 {
        bail!("H1to3p.xml: {} numbers, expected 9", v.len());
    }
    Ok(Matrix3::from_row_slice(&v))
}

fn load_png(path: &Path) -> Result<RgbImage> {
    Ok(image::open(path)
        .with_context(|| format!("reading {}", path.display()))?
        .to_rgb8())
}

fn graf(t: &mut Table) -> Result<()> {
    let dir = testdata();
    let truth = read_h1to3p(&dir.join("H1to3p.xml"))?;
    let g1 = load_png(&dir.join("graf1.png"))?;
    let g3 = load_png(&dir.join("graf3.png"))?;
    let h = Homography::from_matrix(truth)?;
    let (w, hh) = g3.dimensions();
    let input = format!("graf1 {}x{} by H1to3p", g1.width(), g1.height());
    check_warp_bilinear(t, &input, &g1, &h, w, hh)?;
    let vt_nn = vt_core::warp::warp_rgb(&g1, &h, w, hh, Interpolation::Nearest);
    let cv_nn = vt_cv::warp::warp_rgb(&g1, &h, w, hh, Interpolation::Nearest)?;
    check_identical_rgb(t, "warp RGB nearest", &input, &vt_nn, &cv_nn);
    check_blur(
        t,
        "Gaussian 3x3",
        "graf3 800x640",
        &vt_core::blur::gaussian_blur(&g3, &GaussianParams::default())?,
        &vt_cv::blur::gaussian_blur(&g3, &GaussianParams::default())?,
    );

    // Points over graf1 mapped by the true homography; then with noise.
    let grid: Vec<Point> = (0..5)
        .flat_map(|i| {
            (0..4).map(move |j| Point::new(60.0 + 170.0 * i as f64, 50.0 + 170.0 * j as f64))
        })
        .collect();
    let mapped = map_points(&truth, &grid);
    homography_agreement(t, "graf 20 pts by H1to3p", &grid, &mapped, Some(&truth));
    homography_agreement(
        t,
        "graf 4 pts by H1to3p",
        &[grid[0], grid[3], grid[16], grid[19]],
        &[mapped[0], mapped[3], mapped[16], mapped[19]],
        Some(&truth),
    );
    let noisy: Vec<Point> = mapped
        .iter()
        .enumerate()
        .map(|(i, p)| {
            Point::new(
                p.x + 0.5 * noise(7, 2 * i as u64),
                p.y + 0.5 * noise(7, 2 * i as u64 + 1),
            )
        })
        .collect();
    homography_agreement(
        t,
        "graf 20 pts, noise +-0.5 px",
        &grid,
        &noisy,
        Some(&truth),
    );
    homography_stability(t, "graf 20 pts, noise +-0.5 px", &grid, &noisy);
    homography_stability(t, "graf 20 pts by H1to3p (f64)", &grid, &mapped);
    Ok(())
}

fn temple(t: &mut Table) -> Result<()> {
    let dir = testdata().join("templeSparseRing");
    let a = load_png(&dir.join("templeSR0001.png"))?;
    let b = load_png(&dir.join("templeSR0003.png"))?;
    let input = format!("templeSR0001 {}x{}", a.width(), a.height());
    check_blur(
        t,
        "Gaussian 3x3",
        &input,
        &vt_core::blur::gaussian_blur(&a, &GaussianParams::default())?,
        &vt_cv::blur::gaussian_blur(&a, &GaussianParams::default())?,
    );
    let g7 = GaussianParams {
        ksize: 7,
        sigma: 2.5,
    };
    check_blur(
        t,
        "Gaussian 7x7 s2.5",
        &input,
        &vt_core::blur::gaussian_blur(&a, &g7)?,
        &vt_cv::blur::gaussian_blur(&a, &g7)?,
    );
    check_blur_exact(t, &input, &a, &GaussianParams::default())?;
    check_blur_exact(
        t,
        &input,
        &a,
        &GaussianParams {
            ksize: 15,
            sigma: 4.0,
        },
    )?;
    // A mild projective map (rotation, scale, perspective) about the image centre.
    let m = Matrix3::new(0.97, -0.12, 40.0, 0.1, 1.02, -15.0, 8e-5, -5e-5, 1.0);
    let h = Homography::from_matrix(m)?;
    let (w, hh) = a.dimensions();
    check_warp_bilinear(t, &format!("{input} projective"), &a, &h, w, hh)?;
    // Two views as frame and background: a mask on real photos.
    let (ba, bb) = (
        vt_core::blur::gaussian_blur(&a, &GaussianParams::default())?,
        vt_core::blur::gaussian_blur(&b, &GaussianParams::default())?,
    );
    let params = MaskParams {
        threshold: 20,
        open_radius: 2,
        close_radius: 1,
    };
    check_identical_masks(
        t,
        "mask (same blur, open 2 close 1)",
        "templeSR0001 vs 0003",
        &[foreground_mask(&ba, &bb, &params)?],
        &[vt_cv::mask::foreground_mask(&ba, &bb, &params)?],
    );
    Ok(())
}

fn extreme_points(t: &mut Table) -> Result<()> {
    let base = [
        (0.0, 0.0),
        (300.0, 10.0),
        (280.0, 250.0),
        (-20.0, 270.0),
        (150.0, 120.0),
        (60.0, 200.0),
    ];
    let h = Matrix3::new(1.01, 0.02, 5.0, -0.01, 0.99, -3.0, 1e-7, -2e-7, 1.0);
    for off in [1e4, 1e5] {
        let src: Vec<Point> = base
            .iter()
            .map(|&(x, y)| Point::new(x + off, y + 0.8 * off))
            .collect();
        let dst = map_points(&h, &src);
        homography_stability(t, &format!("6 pts {off:.0e} px from origin"), &src, &dst);
        homography_stability(
            t,
            &format!("4 pts {off:.0e} px from origin"),
            &src[..4],
            &dst[..4],
        );
        let noisy: Vec<Point> = dst
            .iter()
            .enumerate()
            .map(|(i, p)| {
                Point::new(
                    p.x + 0.3 * noise(3, 2 * i as u64),
                    p.y + 0.3 * noise(3, 2 * i as u64 + 1),
                )
            })
            .collect();
        homography_stability(t, &format!("6 pts {off:.0e} px, noise 0.3"), &src, &noisy);
    }
    // Near-collinear: points within `eps` px of a 300 px line.
    for eps in [1e-2, 1e-5, 1e-9] {
        let src: Vec<Point> = (0..6)
            .map(|i| Point::new(50.0 * i as f64, 20.0 + 10.0 * i as f64 + eps * noise(5, i)))
            .collect();
        let dst: Vec<Point> = (0..6)
            .map(|i| {
                Point::new(
                    40.0 * i as f64 + 3.0,
                    30.0 + 12.0 * i as f64 + eps * noise(6, i),
                )
            })
            .collect();
        homography_stability(
            t,
            &format!("near-collinear, {eps:.0e} px off a line"),
            &src,
            &dst,
        );
    }
    // Tiny spread: a unit square shrunk to `s` px around (320, 180), mapped by a mild homography.
    for s in [1e-1, 1e-3, 1e-6] {
        let src: Vec<Point> = base
            .iter()
            .map(|&(x, y)| Point::new(320.0 + s * x / 300.0, 180.0 + s * y / 300.0))
            .collect();
        let dst = map_points(&h, &src);
        homography_stability(t, &format!("6 pts spread {s:.0e} px"), &src, &dst);
    }
    // Nearly singular maps: singular values 1, 1, eps (rotations either side).
    for eps in [1e-6, 1e-10] {
        let r = |a: f64| nalgebra::Rotation3::from_euler_angles(a, 0.3 * a, -0.7 * a).into_inner();
        let m = r(0.4) * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, eps)) * r(-0.9);
        let src: Vec<Point> = base
            .iter()
            .map(|&(x, y)| Point::new(x * 1e-3, y * 1e-3))
            .collect();
        let dst = map_points(&m, &src);
        homography_stability(
            t,
            &format!("nearly singular H (cond {eps:.0e})"),
            &src,
            &dst,
        );
    }
    Ok(())
}

fn extreme_images(t: &mut Table) -> Result<()> {
    // 1x1 images.
    let one = RgbImage::from_pixel(1, 1, image::Rgb([7, 200, 33]));
    let other = RgbImage::from_pixel(1, 1, image::Rgb([7, 150, 33]));
    check_identical_rgb(
        t,
        "Gaussian 3x3",
        "1x1",
        &vt_core::blur::gaussian_blur(&one, &GaussianParams::default())?,
        &vt_cv::blur::gaussian_blur(&one, &GaussianParams::default())?,
    );
    check_identical_rgb(
        t,
        "median",
        "1x1, 3 frames",
        &vt_core::median::temporal_median([&one, &other, &one])?,
        &vt_cv::median::temporal_median([&one, &other, &one])?,
    );
    for (name, h) in [
        ("identity", Homography::identity()),
        ("shift 0.4 px", Homography::translation(0.4, -0.4)),
    ] {
        check_identical_rgb(
            t,
            "warp RGB nearest",
            &format!("1x1 {name}"),
            &vt_core::warp::warp_rgb(&one, &h, 1, 1, Interpolation::Nearest),
            &vt_cv::warp::warp_rgb(&one, &h, 1, 1, Interpolation::Nearest)?,
        );
        check_warp_bilinear(t, &format!("1x1 {name}"), &one, &h, 1, 1)?;
    }
    let params = MaskParams {
        threshold: 25,
        open_radius: 1,
        close_radius: 1,
    };
    check_identical_masks(
        t,
        "mask (open 1 close 1)",
        "1x1",
        &[foreground_mask(&other, &one, &params)?],
        &[vt_cv::mask::foreground_mask(&other, &one, &params)?],
    );

    // 8K (7680x4320): blur, mask, warps, median of 3 frames.
    let (w, h) = (7680u32, 4320u32);
    let t0 = Instant::now();
    // A smooth pattern (tables per column and row), noise, and one channel of hard edges.
    let cols: Vec<f64> = (0..w)
        .map(|x| (x as f64 * 0.05).sin() * 60.0 + 128.0)
        .collect();
    let rows: Vec<f64> = (0..h).map(|y| (y as f64 * 0.031).cos() * 50.0).collect();
    let tex = |seed: u64| {
        RgbImage::from_fn(w, h, |x, y| {
            let v = (cols[x as usize] + rows[y as usize]) as i32;
            let n = (mix_u64(seed ^ ((y as u64) << 16 | x as u64)) % 41) as i32 - 20;
            image::Rgb([
                (v + n).clamp(0, 255) as u8,
                (255 - v + n).clamp(0, 255) as u8,
                ((x ^ y) & 255) as u8,
            ])
        })
    };
    let (a, b, c) = (tex(1), tex(2), tex(3));
    let input = "8K 7680x4320";
    let g = GaussianParams::default();
    let (vt_a, cv_a) = (
        vt_core::blur::gaussian_blur(&a, &g)?,
        vt_cv::blur::gaussian_blur(&a, &g)?,
    );
    check_blur(t, "Gaussian 3x3", input, &vt_a, &cv_a);
    let vt_b = vt_core::blur::gaussian_blur(&b, &g)?;
    let mp = MaskParams {
        threshold: 25,
        open_radius: 1,
        close_radius: 1,
    };
    check_identical_masks(
        t,
        "mask (same blur, open 1 close 1)",
        input,
        &[foreground_mask(&vt_a, &vt_b, &mp)?],
        &[vt_cv::mask::foreground_mask(&vt_a, &vt_b, &mp)?],
    );
    check_identical_rgb(
        t,
        "median",
        &format!("{input}, 3 frames"),
        &vt_core::median::temporal_median([&a, &b, &c])?,
        &vt_cv::median::temporal_median([&a, &b, &c])?,
    );
    let hm = Homography::from_matrix(Matrix3::new(
        0.98, 0.05, 60.0, -0.04, 1.01, 30.0, 4e-6, -3e-6, 1.0,
    ))?;
    check_warp_bilinear(t, input, &a, &hm, w, h)?;
    check_identical_rgb(
        t,
        "warp RGB nearest",
        input,
        &vt_core::warp::warp_rgb(&a, &hm, w, h, Interpolation::Nearest),
        &vt_cv::warp::warp_rgb(&a, &hm, w, h, Interpolation::Nearest)?,
    );
    eprintln!("8K rows in {:.1?}", t0.elapsed());

    // Warps by a nearly singular homography (the image folds onto a narrow band).
    let small = RgbImage::from_fn(320, 180, |x, y| {
        image::Rgb([(x * 3) as u8, (y * 5) as u8, ((x + y) * 2) as u8])
    });
    for eps in [1e-4, 1e-8] {
        let m = Matrix3::new(1.0, 0.5, 10.0, 1.0, 0.5 + eps, 12.0, 1e-4, 5e-5, 1.0);
        match Homography::from_matrix(m) {
            Ok(hs) => {
                let name = format!("320x180 nearly singular H ({eps:.0e})");
                check_warp_bilinear(t, &name, &small, &hs, 320, 180)?;
                let ms = Mask::from_fn(320, 180, |x, y| (x / 7 + y / 5) % 3 == 0);
                check_identical_masks(
                    t,
                    "warp masks (nearest)",
                    &name,
                    &[vt_core::warp::warp_mask(&ms, &hs, 320, 180)],
                    &[vt_cv::warp::warp_mask(&ms, &hs, 320, 180)?],
                );
            }
            Err(e) => t.add(
                "warp (nearly singular H)",
                &format!("eps {eps:.0e}"),
                format!("vt refuses: {e}"),
                "Err is fine",
                true,
            ),
        }
    }
    Ok(())
}

/// A homography whose line at infinity passes exactly through output column 8 (`w = 0` there in
/// both implementations, as `H` is an involution with power-of-two entries). vt-core leaves those
/// pixels black / clear (they have no preimage); OpenCV's `W ? 1/W : 0` sends them to source pixel
/// (0, 0). The row asserts that this column is the only difference and that vt-core's answer there
/// is the empty one.
fn line_at_infinity(t: &mut Table) -> Result<()> {
    let h = Homography::from_matrix(Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.125, 0.0, -1.0))?;
    let img = RgbImage::from_fn(16, 8, |x, y| image::Rgb([100 + x as u8, 50 + y as u8, 7]));
    let full = Mask::from_fn(16, 8, |_, _| true);
    let (mut other_cols, mut col8_vt_clear, mut col8_differ) = (0, true, 0);
    for interp in [Interpolation::Nearest, Interpolation::Bilinear] {
        let vt = vt_core::warp::warp_rgb(&img, &h, 16, 8, interp);
        let cv = vt_cv::warp::warp_rgb(&img, &h, 16, 8, interp)?;
        for (x, y, p) in vt.enumerate_pixels() {
            if *p != *cv.get_pixel(x, y) {
                if x == 8 {
                    col8_differ += 1;
                    col8_vt_clear &= p.0 == [0, 0, 0];
                } else {
                    other_cols += 1;
                }
            }
        }
    }
    let (vm, cm) = (
        vt_core::warp::warp_mask(&full, &h, 16, 8),
        vt_cv::warp::warp_mask(&full, &h, 16, 8)?,
    );
    for y in 0..8 {
        for x in 0..16 {
            if vm.get(x, y) != cm.get(x, y) {
                if x == 8 {
                    col8_differ += 1;
                    col8_vt_clear &= !vm.get(x, y);
                } else {
                    other_cols += 1;
                }
            }
        }
    }
    t.add(
        "warp on the line at infinity",
        "16x8, w = 0 on column 8",
        format!("{col8_differ} px differ on col 8 (vt empty, cv src(0,0)), {other_cols} elsewhere"),
        "only col 8; vt empty there",
        other_cols == 0 && col8_vt_clear,
    );
    Ok(())
}

fn extreme_masks(t: &mut Table) -> Result<()> {
    let (w, h) = (64u32, 48u32);
    let empty = Mask::new(w, h);
    let full = Mask::from_fn(w, h, |_, _| true);
    for (name, m) in [("all-empty 64x48", &empty), ("all-full 64x48", &full)] {
        let mut differ = 0u64;
        for r in [1u32, 3] {
            use vt_cv::mask::Morph;
            for (vt, op) in [
                (m.erode(r), Morph::Erode),
                (m.dilate(r), Morph::Dilate),
                (m.open(r), Morph::Open),
                (m.close(r), Morph::Close),
            ] {
                differ += vt_core::mask::xor_count(&vt, &vt_cv::mask::morph(m, r, op)?);
            }
        }
        t.add(
            "erode/dilate/open/close r 1, 3",
            name,
            format!("{differ} pixels differ"),
            "identical",
            differ == 0,
        );
        for other in [&empty, &full] {
            let (a, b) = (
                vt_core::mask::xor_count(m, other),
                vt_cv::mask::xor_count(m, other)?,
            );
            t.add(
                "XOR cost",
                &format!(
                    "{name} vs {}",
                    if other.count_ones() == 0 {
                        "empty"
                    } else {
                        "full"
                    }
                ),
                format!("vt {a} / cv {b}"),
                "identical",
                a == b,
            );
        }
        let hm =
            Homography::from_matrix(Matrix3::new(0.9, 0.1, 3.0, -0.1, 1.1, -2.0, 1e-3, 0.0, 1.0))?;
        check_identical_masks(
            t,
            "warp masks (nearest)",
            name,
            &[vt_core::warp::warp_mask(m, &hm, w, h)],
            &[vt_cv::warp::warp_mask(m, &hm, w, h)?],
        );
        // Every cost ties: both must break ties the same way.
        let masks = vec![m.clone(); 30];
        let lp = LoopParams {
            window: 3,
            min_length: 10,
        };
        let (a, b) = (
            vt_core::loops::find_loop(&masks, &lp, name)?,
            vt_cv::loops::find_loop(&masks, &lp, name)?,
        );
        t.add(
            "loop eq. (1), all ties",
            name,
            format!("vt ({}, {}) / cv ({}, {})", a.start, a.end, b.start, b.end),
            "identical",
            a == b,
        );
        let (ta, tb) = (
            vt_core::transition::transition_table(&masks, &masks, 20, 3)?,
            vt_cv::transition::transition_table(&masks, &masks, 20, 3)?,
        );
        t.add(
            "transition eq. (2), all ties",
            name,
            format!(
                "{} entries differ",
                ta.iter().zip(&tb).filter(|(x, y)| x != y).count()
            ),
            "identical",
            ta == tb,
        );
    }
    Ok(())
}

fn main() {
    let start = Instant::now();
    let mut t = Table::default();
    type Section = Box<dyn Fn(&mut Table) -> Result<()>>;
    let sections: Vec<(&str, Section)> = vec![
        (
            "synthetic 160x90 seed 1",
            Box::new(|t| synthetic(t, 160, 90, 1, 48, 12, Rig::Parallel)),
        ),
        (
            "synthetic 320x180 seed 2",
            Box::new(|t| synthetic(t, 320, 180, 2, 60, 16, Rig::Converging)),
        ),
        (
            "synthetic 640x360 seed 3",
            Box::new(|t| synthetic(t, 640, 360, 3, 40, 10, Rig::Converging)),
        ),
        ("tree.avi", Box::new(tree)),
        ("graf", Box::new(graf)),
        ("temple", Box::new(temple)),
        ("extreme points", Box::new(extreme_points)),
        ("extreme images", Box::new(extreme_images)),
        ("extreme masks", Box::new(extreme_masks)),
        ("line at infinity", Box::new(line_at_infinity)),
    ];
    for (name, section) in sections {
        let t0 = Instant::now();
        eprintln!("{name}...");
        if let Err(e) = section(&mut t) {
            t.error(name, "(section aborted)", format!("{e:#}"));
        }
        eprintln!("{name}: {:.1?}", t0.elapsed());
    }
    println!();
    println!(
        "vt-core vs vt-cv (OpenCV {}) cross-check",
        opencv::core::CV_VERSION
    );
    t.print();
    let failed = t.rows.iter().filter(|r| !r.pass).count();
    println!(
        "\n{} checks, {failed} failed, {:.1} s",
        t.rows.len(),
        start.elapsed().as_secs_f64()
    );
    if failed > 0 {
        std::process::exit(1);
    }
}
