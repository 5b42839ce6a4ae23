//! Measures: image and mask differences, the blur and warp rows, OpenCV's bilinear model.

#[allow(unused_imports)]
use super::*;

/// Per-pixel differences between two RGB images (a pixel's difference is its largest channel's).
#[derive(Clone)]
pub(super) struct ImageDiff {
    pub(super) max: u8,
    pub(super) differ: usize,
    pub(super) over_one: usize,
    pub(super) pixels: usize,
}

pub(super) fn image_diff(a: &RgbImage, b: &RgbImage) -> ImageDiff {
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

pub(super) fn pct(n: usize, of: usize) -> f64 {
    if of == 0 {
        0.0
    } else {
        100.0 * n as f64 / of as f64
    }
}

/// Blur rows: every value within one grey level.
pub(super) fn check_blur(t: &mut Table, op: &str, input: &str, vt: &RgbImage, cv: &RgbImage) {
    let d = image_diff(vt, cv);
    if d.max > 1 {
        t.add_images(
            op,
            input,
            blur_figure(&d),
            "max |diff| <= 1",
            false,
            (vt, cv),
        );
    } else {
        blur_row(t, op, input, d);
    }
}

fn blur_figure(d: &ImageDiff) -> String {
    format!(
        "max |diff| {}, {:.3}% of pixels differ",
        d.max,
        pct(d.differ, d.pixels)
    )
}

/// One blur row from a computed difference: every value within one grey level.
pub(super) fn blur_row(t: &mut Table, op: &str, input: &str, d: ImageDiff) {
    t.add(op, input, blur_figure(&d), "max |diff| <= 1", d.max <= 1);
}

/// OpenCV's bilinear `warpPerspective` modelled in Rust: the source coordinate computed in
/// `f64` in `warpPerspective`'s order (blocks of 64 columns), rounded to 1/32 pixel
/// (`INTER_BITS = 5`, `cvRound`), then `remap`'s 15-bit integer weights
/// `(32 - fy)(32 - fx) * 32` etc. and `(sum + 2^14) >> 15`, constant border 0.
pub(super) fn opencv_bilinear_model(
    src: &RgbImage,
    inv: &Matrix3<f64>,
    width: u32,
    height: u32,
) -> RgbImage {
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
pub(super) fn src_value(src: &RgbImage, x: i64, y: i64, c: usize) -> i64 {
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
pub(super) fn quantisation_bound(
    src: &RgbImage,
    inv: &Matrix3<f64>,
    x: usize,
    y: usize,
    c: usize,
) -> f64 {
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
pub(super) fn exact_blur(src: &RgbImage, p: &GaussianParams) -> Result<Vec<f64>> {
    let k = vt_core::blur::gaussian_kernel(p.ksize, p.sigma)?;
    let (w, h, r) = (
        src.width() as isize,
        src.height() as isize,
        (p.ksize / 2) as isize,
    );
    // The border index rule is OpenCV's borderInterpolate, checked against OpenCV by the blur rows.
    let reflect = |i: isize, n: isize| vt_core::blur::reflect101(i, n as usize);
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
pub(super) fn check_blur_exact(
    t: &mut Table,
    input: &str,
    src: &RgbImage,
    p: &GaussianParams,
) -> Result<()> {
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
/// images, not at sharp edges, see its README). The model against OpenCV: identical, which
/// shows that `INTER_BITS` is the whole difference.
pub(super) fn check_warp_bilinear(
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
    t.add_images(
        "warp RGB bilinear",
        input,
        format!(
            "{within:.3}% within 1, max {}, {outside} values over bound",
            d.max
        ),
        "|d| <= 1 + R/32 (INTER_BITS)",
        outside == 0,
        (&vt, &cv),
    );
    let model = opencv_bilinear_model(src, inv, width, height);
    let m = image_diff(&model, &cv);
    t.add_images(
        "warp bilinear, 1/32 px model",
        input,
        format!("{} of {} pixels differ (max {})", m.differ, m.pixels, m.max),
        "identical",
        m.differ == 0,
        (&model, &cv),
    );
    // vt-core's fixed-point mode is OpenCV's arithmetic: identical to OpenCV; its distance from
    // the exact mode is the price of the knob (reported, bounded by the exact row's bound).
    let fixed = vt_core::warp::warp_rgb(src, h, width, height, Interpolation::BilinearFixed);
    let f = image_diff(&fixed, &cv);
    let e = image_diff(&fixed, &vt);
    t.add_images(
        "warp RGB bilinear-fixed",
        input,
        format!(
            "{} of {} pixels differ (max {}); vs exact: {:.3}% within 1, max {}",
            f.differ,
            f.pixels,
            f.max,
            100.0 - pct(e.over_one, e.pixels),
            e.max
        ),
        "identical",
        f.differ == 0,
        (&fixed, &cv),
    );
    Ok(())
}

pub(super) fn check_identical_rgb(
    t: &mut Table,
    op: &str,
    input: &str,
    vt: &RgbImage,
    cv: &RgbImage,
) {
    let d = image_diff(vt, cv);
    t.add_images(
        op,
        input,
        format!("{} of {} pixels differ (max {})", d.differ, d.pixels, d.max),
        "identical",
        d.differ == 0,
        (vt, cv),
    );
}

pub(super) fn check_identical_masks(
    t: &mut Table,
    op: &str,
    input: &str,
    vt: &[Mask],
    cv: &[Mask],
) {
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
pub(super) fn h_rel_diff(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let (a, b) = (a / a.norm(), b / b.norm());
    let sign = if a.dot(&b) < 0.0 { -1.0 } else { 1.0 };
    (a - b * sign).norm()
}

/// RMS transfer error of a raw matrix (infinite when a point maps to infinity).
pub(super) fn rms(m: &Matrix3<f64>, src: &[Point], dst: &[Point]) -> f64 {
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

pub(super) fn round_f32(pts: &[Point]) -> Vec<Point> {
    pts.iter()
        .map(|p| Point::new(p.x as f32 as f64, p.y as f32 as f64))
        .collect()
}

pub(super) use vt_cv::cases::noise;

pub(super) use vt_cv::cases::map_points;
