//! The background morph through OpenCV, the twin of [`vt_core::parallax`] (estimate + morph):
//! what a user gets from thirty lines of OpenCV on top of vt's plane. The plane is taken out
//! with `warpPerspective` (each background into the other's frame), the residual motion is
//! `DISOpticalFlow` (preset medium) on the grey images both ways, and the view at fraction
//! `frac` samples each background with `remap` at `x0 - frac * flow(x0)` (one backward lookup,
//! `x0 = H_(p,q)^-1 z`) and blends with weights `(1 - frac, frac)`: a plain flow morph, no
//! occlusion reasoning. vt-core differs in the correspondence (census + semi-global matching
//! along fitted search lines, sub-pixel refinement, left-right check, occlusions filled from
//! the farther side) and in the morph (a fixed point per pixel, the view whose trace converges
//! preferred).

use image::RgbImage;
use opencv::core::{self, Mat, Size, Vec2f};
use opencv::imgproc;
use opencv::prelude::*;
use opencv::video;
use vt_core::Homography;

use crate::convert::{mat_to_rgb, rgb_view};
use crate::error::{Context, Result};

fn grey(img: &RgbImage) -> Result<Mat> {
    let view = rgb_view(img)?;
    let mut g = Mat::default();
    imgproc::cvt_color_def(&view, &mut g, imgproc::COLOR_RGB2GRAY).ctx("cvtColor RGB2GRAY")?;
    Ok(g)
}

fn cv_matrix(h: &Homography) -> Result<Mat> {
    let m = h.matrix();
    let rows: Vec<[f64; 3]> = (0..3).map(|r| [m[(r, 0)], m[(r, 1)], m[(r, 2)]]).collect();
    Mat::from_slice_2d(&rows).ctx("Mat::from_slice_2d")
}

/// `src` warped by `h` into a `size` image (bilinear, black outside).
fn warp(src: &Mat, h: &Homography, size: Size) -> Result<Mat> {
    let mut out = Mat::default();
    imgproc::warp_perspective(
        src,
        &mut out,
        &cv_matrix(h)?,
        size,
        imgproc::INTER_LINEAR,
        core::BORDER_CONSTANT,
        core::Scalar::default(),
    )
    .ctx("warpPerspective")?;
    Ok(out)
}

/// DIS flow from `a` to `b` (same size, grey): `a(x) ~ b(x + flow(x))`.
fn dis(a: &Mat, b: &Mat) -> Result<Mat> {
    let mut dis = video::DISOpticalFlow::create(video::DISOpticalFlow_PRESET_MEDIUM)
        .ctx("DISOpticalFlow::create")?;
    let mut flow = Mat::default();
    dis.calc(a, b, &mut flow).ctx("DISOpticalFlow::calc")?;
    Ok(flow)
}

/// The flows of a pair, each in its own view's (plane-aligned) frame.
pub struct FlowPair {
    /// a's pixel x is (b warped into a by `H^-1`)'s pixel `x + flow_a(x)`.
    pub a: Mat,
    /// b's pixel y is (a warped into b by `H`)'s pixel `y + flow_b(y)`.
    pub b: Mat,
}

/// DIS both ways after the plane `h` (a to b).
pub fn estimate(a: &RgbImage, b: &RgbImage, h: &Homography) -> Result<FlowPair> {
    let size = Size::new(a.width() as i32, a.height() as i32);
    let (ga, gb) = (grey(a)?, grey(b)?);
    let b_in_a = warp(&gb, &h.inverse(), size)?;
    let a_in_b = warp(&ga, h, size)?;
    Ok(FlowPair {
        a: dis(&ga, &b_in_a)?,
        b: dis(&gb, &a_in_b)?,
    })
}

/// One background traced back from the output: `x0 = H_(p,q)^-1 z`, then `x0 - frac * flow(x0)`
/// (a point at x moves by `frac * flow(x)` toward the other view; the flow is read at x0, the
/// usual one-lookup approximation), sampled by `remap` (bilinear, edges replicated).
fn trace(
    img: &RgbImage,
    flow: &Mat,
    h_to_q: &Homography,
    frac: f64,
    size: (u32, u32),
) -> Result<Mat> {
    let (w, hgt) = (size.0 as usize, size.1 as usize);
    let (fw, fh) = (img.width() as i32, img.height() as i32);
    let mut map = Mat::new_rows_cols_with_default(
        hgt as i32,
        w as i32,
        core::CV_32FC2,
        core::Scalar::all(-1.0),
    )
    .ctx("Mat::new (map)")?;
    for y in 0..hgt {
        for x in 0..w {
            let Some(p) = h_to_q.apply_inverse(vt_core::Point::new(x as f64, y as f64)) else {
                continue;
            };
            let (xi, yi) = (p.x.round() as i32, p.y.round() as i32);
            let f = if xi >= 0 && yi >= 0 && xi < fw && yi < fh {
                *flow.at_2d::<Vec2f>(yi, xi).ctx("flow")?
            } else {
                Vec2f::from([0.0, 0.0])
            };
            let sx = p.x - frac * f[0] as f64;
            let sy = p.y - frac * f[1] as f64;
            *map.at_2d_mut::<Vec2f>(y as i32, x as i32).ctx("map")? =
                Vec2f::from([sx as f32, sy as f32]);
        }
    }
    let src = rgb_view(img)?;
    let mut out = Mat::default();
    imgproc::remap(
        &src,
        &mut out,
        &map,
        &core::no_array(),
        imgproc::INTER_LINEAR,
        core::BORDER_REPLICATE,
        core::Scalar::default(),
    )
    .ctx("remap")?;
    Ok(out)
}

/// The background at fraction `frac` between a (0) and b (1): both traced back along their
/// flows and blended `(1 - frac, frac)` (`addWeighted`). `h_aq`, `h_bq`: the plane homographies
/// of eq. (3) to the output.
pub fn morph(
    a: &RgbImage,
    b: &RgbImage,
    flows: &FlowPair,
    h_aq: &Homography,
    h_bq: &Homography,
    frac: f64,
    width: u32,
    height: u32,
) -> Result<RgbImage> {
    let ta = trace(a, &flows.a, h_aq, frac, (width, height))?;
    let tb = trace(b, &flows.b, h_bq, 1.0 - frac, (width, height))?;
    let mut out = Mat::default();
    core::add_weighted(&ta, 1.0 - frac, &tb, frac, 0.0, &mut out, -1).ctx("addWeighted")?;
    mat_to_rgb(&out)
}
