//! Automatic registration against independent truth: the graffiti pair of the Mikolajczyk
//! benchmark (graf1 -> graf3, a planar wall from two viewpoints about 40 degrees apart, with its
//! published homography H1to3p), and synthetic warps of a real photo.

use image::RgbImage;
use nalgebra::Matrix3;
use vt_core::register::{register_pair, RegisterParams};
use vt_core::Homography;

fn testdata(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
}

fn load(name: &str) -> RgbImage {
    image::open(testdata(name)).unwrap().to_rgb8()
}

/// H1to3p.xml's matrix (OpenCV FileStorage: the nine numbers of the `data` element).
fn h1to3p() -> Matrix3<f64> {
    let text = std::fs::read_to_string(testdata("H1to3p.xml")).unwrap();
    let data = text
        .split("<data>")
        .nth(1)
        .unwrap()
        .split("</data>")
        .next()
        .unwrap();
    let v: Vec<f64> = data
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    Matrix3::from_row_slice(&v)
}

/// Distances between the images of a's corners under the two maps: (largest, mean).
fn corner_errors(h: &Homography, truth: &Matrix3<f64>, w: u32, hgt: u32) -> (f64, f64) {
    let t = Homography::from_matrix(*truth).unwrap();
    let (w, hgt) = (w as f64 - 1.0, hgt as f64 - 1.0);
    let e: Vec<f64> = [(0.0, 0.0), (w, 0.0), (0.0, hgt), (w, hgt)]
        .iter()
        .map(|&(x, y)| {
            let p = vt_core::Point::new(x, y);
            (h.apply(p).unwrap() - t.apply(p).unwrap()).norm()
        })
        .collect();
    (
        e.iter().cloned().fold(0.0, f64::max),
        e.iter().sum::<f64>() / 4.0,
    )
}

/// Mean distance between where the two maps send a's pixels that `truth` keeps inside b (8 px
/// in; every 8th pixel each way): the misalignment where the images overlap.
fn overlap_error(h: &Homography, truth: &Matrix3<f64>, w: u32, hgt: u32) -> f64 {
    let t = Homography::from_matrix(*truth).unwrap();
    let (mut sum, mut n) = (0.0, 0);
    for y in (0..hgt).step_by(8) {
        for x in (0..w).step_by(8) {
            let p = vt_core::Point::new(x as f64, y as f64);
            let q = t.apply(p).unwrap();
            if q.x < 8.0 || q.y < 8.0 || q.x > w as f64 - 9.0 || q.y > hgt as f64 - 9.0 {
                continue;
            }
            sum += (h.apply(p).unwrap() - q).norm();
            n += 1;
        }
    }
    sum / n as f64
}

#[test]
fn graf1_to_graf3_within_a_pixel_of_h1to3p() {
    let (a, b) = (load("graf1.png"), load("graf3.png"));
    let r = register_pair(&a, &b, None, &RegisterParams::default(), (0, 1)).unwrap();
    let (e, e_mean) = corner_errors(&r.homography, &h1to3p(), a.width(), a.height());
    let o = overlap_error(&r.homography, &h1to3p(), a.width(), a.height());
    eprintln!(
        "graf1->graf3: {} sub-pixel inliers of {} matches; mean misalignment over the overlap {o:.3} px; at graf1's corners {e_mean:.3} px mean, {e:.3} px largest",
        r.inliers.len(),
        r.matches,
    );
    // Where the two photos overlap the fit is within a third of a pixel of the published
    // homography (OpenCV's ORB + RANSAC: 1.08 px, cross-check); graf1's corners fall outside
    // graf3 (one maps 20 px below it), where both the estimate and H1to3p (itself fitted to
    // the overlap) extrapolate: 0.82 px mean, 1.48 px at the worst corner.
    assert!(o <= 0.5, "mean misalignment over the overlap {o} px");
    assert!(e_mean <= 1.0, "mean corner error {e_mean} px");
    assert!(e <= 2.0, "largest corner error {e} px");
}
