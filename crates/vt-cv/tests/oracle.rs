//! The oracle pattern on small inputs: every vt-cv function against its vt-core twin, one
//! table of cases per operation, failures naming the operation and the input.

use image::RgbImage;
use nalgebra::Matrix3;
use vt_core::analysis::MaskParams;
use vt_core::blur::GaussianParams;
use vt_core::loops::LoopParams;
use vt_core::warp::Interpolation;
use vt_core::{Homography, Mask, Point};
use vt_cv::mask::Morph;

const W: u32 = 64;
const H: u32 = 48;

use vt_core::rng::mix_at as mix;

/// A smooth pattern plus noise of amplitude `noise`, with a bright moving blob at `shift`.
fn image(seed: u64, noise: u64, shift: u32) -> RgbImage {
    RgbImage::from_fn(W, H, |x, y| {
        let n = |c: u64| (mix(seed, (y * W + x) as u64 * 3 + c) % (noise + 1)) as i32;
        let base = (x * 3 + y * 2) as i32;
        let blob = if (x as i32 - shift as i32 - 10).pow(2) + (y as i32 - 24).pow(2) < 64 {
            120
        } else {
            0
        };
        let px = |v: i32| v.clamp(0, 255) as u8;
        image::Rgb([
            px(base + blob + n(0)),
            px(200 - base / 2 + n(1)),
            px(60 + blob / 2 + n(2)),
        ])
    })
}

fn random_mask(seed: u64, density_pct: u64) -> Mask {
    Mask::from_fn(W, H, |x, y| {
        mix(seed, (y * W + x) as u64) % 100 < density_pct
    })
}

fn blob_mask(frame: usize, period: usize, dx: i64) -> Mask {
    let ph = (frame % period) as f64 / period as f64 * std::f64::consts::TAU;
    let (cx, cy) = (
        32.0 + 14.0 * ph.sin() + dx as f64,
        24.0 + 8.0 * (2.0 * ph).cos(),
    );
    Mask::from_fn(W, H, |x, y| {
        (x as f64 - cx).powi(2) / 49.0 + (y as f64 - cy).powi(2) / 25.0 < 1.0
            || (x as usize == frame % 64 && y == 47)
    })
}

fn max_diff(a: &RgbImage, b: &RgbImage) -> u8 {
    a.as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(p, q)| p.abs_diff(*q))
        .max()
        .unwrap_or(0)
}

fn mask_diff(op: &str, input: &str, vt: &Mask, cv: &Mask) {
    assert_eq!(
        vt_core::mask::xor_count(vt, cv),
        0,
        "{op} on {input}: vt-core {vt:?} vs OpenCV {cv:?}"
    );
}

#[test]
fn median_is_identical() {
    for (n, noise) in [(1, 255), (2, 255), (5, 40), (8, 255), (13, 3)] {
        let frames: Vec<RgbImage> = (0..n)
            .map(|i| image(100 + i as u64, noise, i * 3))
            .collect();
        let (vt, cv) = (
            vt_core::median::temporal_median(&frames).unwrap(),
            vt_cv::median::temporal_median(&frames).unwrap(),
        );
        assert!(
            vt == cv,
            "median of {n} frames (noise {noise}): max diff {}",
            max_diff(&vt, &cv)
        );
    }
    let err = vt_cv::median::temporal_median([&image(1, 0, 0), &RgbImage::new(3, 4)]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "median frame 1: size mismatch: expected 64x48, got 3x4"
    );
    assert!(vt_cv::median::temporal_median(std::iter::empty::<&RgbImage>()).is_err());
}

#[test]
fn gaussian_is_within_one_level() {
    let img = image(7, 255, 5);
    for (ksize, sigma) in [
        (1, 0.0),
        (3, 0.0),
        (5, 0.0),
        (7, 0.0),
        (3, 0.8),
        (5, 1.2),
        (9, 0.0),
        (11, 3.0),
    ] {
        let p = GaussianParams { ksize, sigma };
        let (vt, cv) = (
            vt_core::blur::gaussian_blur(&img, &p).unwrap(),
            vt_cv::blur::gaussian_blur(&img, &p).unwrap(),
        );
        assert!(
            max_diff(&vt, &cv) <= 1,
            "GaussianBlur {ksize}x{ksize} sigma {sigma} on 64x48 noise: max diff {}",
            max_diff(&vt, &cv)
        );
    }
    for bad in [
        GaussianParams {
            ksize: 4,
            sigma: 1.0,
        },
        GaussianParams {
            ksize: 3,
            sigma: f64::NAN,
        },
    ] {
        assert!(
            vt_cv::blur::gaussian_blur(&img, &bad).is_err(),
            "{bad:?} must be refused like vt-core does"
        );
    }
}

#[test]
fn masks_are_identical() {
    let bg = image(1, 6, 0);
    let frame = image(2, 6, 20);
    for (threshold, open_radius, close_radius) in [
        (0, 0, 0),
        (10, 0, 0),
        (25, 1, 0),
        (25, 0, 2),
        (40, 2, 1),
        (255, 1, 1),
    ] {
        let p = MaskParams {
            threshold,
            open_radius,
            close_radius,
        };
        let vt = vt_core::analysis::foreground_mask(&frame, &bg, &p).unwrap();
        let cv = vt_cv::mask::foreground_mask(&frame, &bg, &p).unwrap();
        mask_diff("foreground_mask", &format!("64x48 blob, {p:?}"), &vt, &cv);
    }
    assert!(vt_cv::mask::threshold_mask(&frame, &RgbImage::new(3, 3), 25).is_err());
}

#[test]
fn morphology_is_identical() {
    for (seed, density) in [(1, 0), (2, 5), (3, 50), (4, 95), (5, 100)] {
        let m = random_mask(seed, density);
        for r in 0..4 {
            for (op, vt) in [
                (Morph::Erode, m.erode(r)),
                (Morph::Dilate, m.dilate(r)),
                (Morph::Open, m.open(r)),
                (Morph::Close, m.close(r)),
            ] {
                mask_diff(
                    &format!("{op:?} r {r}"),
                    &format!("random mask {density}% set"),
                    &vt,
                    &vt_cv::mask::morph(&m, r, op).unwrap(),
                );
            }
        }
    }
}

#[test]
fn xor_counts_are_identical() {
    for (a, b) in [(0, 0), (0, 100), (30, 70), (50, 50), (100, 100)] {
        let (ma, mb) = (random_mask(a + 10, a), random_mask(b + 20, b));
        assert_eq!(
            vt_core::mask::xor_count(&ma, &mb),
            vt_cv::mask::xor_count(&ma, &mb).unwrap(),
            "XOR of {a}% and {b}% masks"
        );
    }
    assert!(vt_cv::mask::xor_count(&Mask::new(3, 4), &Mask::new(4, 3)).is_err());
}

fn homographies() -> Vec<(&'static str, Homography)> {
    let m = |v: [f64; 9]| Homography::from_matrix(Matrix3::from_row_slice(&v)).unwrap();
    vec![
        ("identity", Homography::identity()),
        ("shift (3, -2)", Homography::translation(3.0, -2.0)),
        ("shift (0.5, 0.5)", Homography::translation(0.5, 0.5)),
        (
            "rotation",
            m([0.95, -0.3, 8.0, 0.3, 0.95, -6.0, 0.0, 0.0, 1.0]),
        ),
        (
            "projective",
            m([1.05, 0.1, -4.0, -0.08, 0.97, 3.0, 1.5e-3, -1e-3, 1.0]),
        ),
    ]
}

#[test]
fn warps_agree() {
    let img = image(3, 30, 12);
    let mask = blob_mask(3, 10, 0);
    for (name, h) in homographies() {
        mask_diff(
            "warpPerspective mask",
            name,
            &vt_core::warp::warp_mask(&mask, &h, W, H),
            &vt_cv::warp::warp_mask(&mask, &h, W, H).unwrap(),
        );
        let vt = vt_core::warp::warp_rgb(&img, &h, W, H, Interpolation::Nearest);
        let cv = vt_cv::warp::warp_rgb(&img, &h, W, H, Interpolation::Nearest).unwrap();
        assert!(
            vt == cv,
            "warpPerspective INTER_NEAREST by {name}: max diff {}",
            max_diff(&vt, &cv)
        );
        // Bilinear: OpenCV's 1/32-pixel coordinates move a value by at most 1 + 255/32 levels.
        let vt = vt_core::warp::warp_rgb(&img, &h, W, H, Interpolation::Bilinear);
        let cv = vt_cv::warp::warp_rgb(&img, &h, W, H, Interpolation::Bilinear).unwrap();
        let over_one = vt
            .as_raw()
            .iter()
            .zip(cv.as_raw())
            .filter(|(a, b)| a.abs_diff(**b) > 1)
            .count();
        assert!(
            max_diff(&vt, &cv) <= 8 && over_one * 100 <= vt.as_raw().len(),
            "warpPerspective INTER_LINEAR by {name}: max diff {}, {over_one} values over 1",
            max_diff(&vt, &cv)
        );
    }
}

#[test]
fn homographies_agree() {
    let src: Vec<Point> = [
        (3.0, 4.0),
        (60.0, 2.0),
        (58.0, 45.0),
        (1.0, 40.0),
        (30.0, 20.0),
        (12.0, 33.0),
    ]
    .iter()
    .map(|&(x, y)| Point::new(x, y))
    .collect();
    for (name, h) in homographies() {
        // f32-exact inputs: OpenCV converts points to f32, so both sides then see the same numbers.
        let dst: Vec<Point> = src
            .iter()
            .map(|p| h.apply(*p).unwrap())
            .map(|p| Point::new(p.x as f32 as f64, p.y as f32 as f64))
            .collect();
        for k in [4, 6] {
            let vt = Homography::from_correspondences(&src[..k], &dst[..k])
                .unwrap()
                .homography
                .matrix();
            let cv = vt_cv::homography::from_correspondences(&src[..k], &dst[..k])
                .unwrap()
                .homography
                .matrix();
            let rel = (vt / vt.norm() - cv / cv.norm()).norm();
            assert!(
                rel < 1e-6,
                "homography from {k} points by {name}: relative difference {rel:e}"
            );
        }
    }
    assert!(
        vt_cv::homography::from_correspondences(&src[..3], &src[..3])
            .unwrap_err()
            .to_string()
            .contains("at least 4")
    );
    let line: Vec<Point> = (0..5)
        .map(|i| Point::new(i as f64, 2.0 * i as f64))
        .collect();
    assert!(
        vt_cv::homography::from_correspondences(&line, &src[..5]).is_err(),
        "collinear points give an error, not a matrix"
    );
}

#[test]
fn loops_and_transitions_are_identical() {
    for (n, period, w, k) in [(30, 7, 3, 8), (40, 10, 1, 5), (25, 6, 4, 10)] {
        let masks: Vec<Mask> = (0..n).map(|f| blob_mask(f, period, 0)).collect();
        let p = LoopParams {
            window: w,
            min_length: k,
        };
        let input = format!("{n} blob masks, period {period}, w {w} k {k}");
        let vt = vt_core::loops::find_loops(&masks, &p, 3, 1, "t").unwrap();
        let cv = vt_cv::loops::find_loops(&masks, &p, 3, 1, "t").unwrap();
        assert_eq!(vt, cv, "loops eq. (1) on {input}");
        let target: Vec<Mask> = (0..n).map(|f| blob_mask(f + 3, period, 4)).collect();
        let h = Homography::translation(4.0, 0.0);
        let (wv, wc) = (
            vt_core::transition::warp_masks(&masks, &h, W, H),
            vt_cv::transition::warp_masks(&masks, &h, W, H).unwrap(),
        );
        for (i, (a, b)) in wv.iter().zip(&wc).enumerate() {
            mask_diff("warp_masks", &format!("{input}, frame {i}"), a, b);
        }
        for end in [0, 1, 2, n / 2, n - w] {
            let vt = vt_core::transition::transition_table(&wv, &target, end, w).unwrap();
            let cv = vt_cv::transition::transition_table(&wc, &target, end, w).unwrap();
            assert_eq!(
                vt, cv,
                "transition table eq. (2) on {input}, target loop end {end}"
            );
        }
    }
    let few: Vec<Mask> = (0..5).map(|f| blob_mask(f, 4, 0)).collect();
    let p = LoopParams {
        window: 3,
        min_length: 8,
    };
    assert_eq!(
        vt_cv::loops::find_loop(&few, &p, "view 2")
            .unwrap_err()
            .to_string(),
        vt_core::loops::find_loop(&few, &p, "view 2")
            .unwrap_err()
            .to_string()
    );
}

#[test]
fn tiny_images_and_large_kernels_agree() {
    for (w, h) in [(1, 1), (2, 2), (3, 1), (1, 5), (5, 3), (8, 2)] {
        let img = RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([
                (x * 70 + y * 20) as u8,
                255 - (y * 50) as u8,
                ((x * y) * 40) as u8,
            ])
        });
        // Up to 9x9: beyond, OpenCV's 8-bit fixed-point taps drift more than one level from the
        // exact result (the cross-check measures it against an f64 reference).
        for (ksize, sigma) in [(3, 0.0), (7, 0.0), (9, 2.0)] {
            let p = GaussianParams { ksize, sigma };
            let (vt, cv) = (
                vt_core::blur::gaussian_blur(&img, &p).unwrap(),
                vt_cv::blur::gaussian_blur(&img, &p).unwrap(),
            );
            assert!(
                max_diff(&vt, &cv) <= 1,
                "GaussianBlur {ksize}x{ksize} sigma {sigma} on {w}x{h}: max diff {}",
                max_diff(&vt, &cv)
            );
        }
        let m = Mask::from_fn(w, h, |x, y| (x + y) % 2 == 0);
        for r in [1, 3, 30] {
            for (op, vt) in [
                (Morph::Erode, m.erode(r)),
                (Morph::Dilate, m.dilate(r)),
                (Morph::Open, m.open(r)),
                (Morph::Close, m.close(r)),
            ] {
                mask_diff(
                    &format!("{op:?} r {r}"),
                    &format!("{w}x{h} checkerboard"),
                    &vt,
                    &vt_cv::mask::morph(&m, r, op).unwrap(),
                );
            }
        }
    }
}
