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
//! - 4:2:0 to RGB (BT.601 limited range, the form OpenCV converts): **identical** (the same
//!   20-bit fixed point on both sides).
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
//! - background alignment (vt-core's Lucas-Kanade against OpenCV's `findTransformECC`, from the
//!   same perturbed start): on images warped by a known map with a gain and offset, both **within
//!   0.1 px** of the truth and of each other (mean over the overlap); on the real graf pair, both
//!   **within 0.6 px** of the published H1to3p (itself an estimate) and 0.5 px of each other.
//!   Always **3x closer than the start**, so a refinement that does nothing fails.
//! - automatic registration (vt-core's features, RANSAC and sub-pixel refinement against
//!   OpenCV's ORB, brute-force Hamming matching and `findHomography` with RANSAC, same
//!   parameters): on real images warped by a known line-rig step with an exposure change,
//!   vt-core **within 0.1 px** of the truth and OpenCV within 1 px (its keypoints are
//!   pyramid-level pixels); on the real graf pair, vt-core within 0.5 px of H1to3p and OpenCV
//!   within 3 px (mean over the overlap); vt-core never worse than OpenCV. A flat wall and two
//!   unrelated photos are refused by both.
//! - background morph (vt-core's census + semi-global parallax and morph against OpenCV's DIS
//!   optical-flow morph, after the same plane) on the real Middlebury views held out: vt-core
//!   **5 dB or more above the plane warp and above OpenCV's morph** on each scene (mean over the
//!   three held-out views).
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

mod align_rows;
mod extremes;
mod homography_rows;
mod measures;
mod morph_rows;
mod real;
mod register_rows;
mod scenes;
mod searches;
mod table;
mod yuv_rows;

use align_rows::*;
use extremes::*;
use homography_rows::*;
use measures::*;
use morph_rows::*;
use real::*;
use register_rows::*;
use scenes::*;
use searches::*;
use table::*;
use yuv_rows::*;

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
        ("searches", Box::new(searches)),
        ("tree.avi", Box::new(tree)),
        ("graf", Box::new(graf)),
        ("temple", Box::new(temple)),
        ("alignment", Box::new(alignment)),
        ("registration", Box::new(registration)),
        ("morph", Box::new(morphs)),
        ("yuv", Box::new(yuv)),
        ("extreme points", Box::new(extreme_points)),
        ("extreme images", Box::new(extreme_images)),
        ("extreme masks", Box::new(extreme_masks)),
        ("line at infinity", Box::new(line_at_infinity)),
    ];
    // Arguments, if any, pick sections by name (substring match), e.g. `cross-check searches`.
    let only: Vec<String> = std::env::args().skip(1).collect();
    let picked: Vec<_> = sections
        .into_iter()
        .filter(|(name, _)| only.is_empty() || only.iter().any(|o| name.contains(o.as_str())))
        .collect();
    if picked.is_empty() {
        eprintln!("cross-check: no section matches {only:?}");
        std::process::exit(2);
    }
    for (name, section) in picked {
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
