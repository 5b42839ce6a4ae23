//! Automatic registration: vt-core's features, matching, RANSAC and sub-pixel refinement
//! against OpenCV's ORB + brute-force Hamming matching + `findHomography` (RANSAC), on the same
//! pairs, both scored against truth: the real graf pair with its published homography, and real
//! images warped by known maps (a line-rig-like viewpoint change with an exposure change).
//! Pairs without a mapping (a flat wall, two unrelated photos) must be refused by both.

#[allow(unused_imports)]
use super::*;

use vt_core::register::RegisterParams;

/// One row: both registrations of `a` to `b`, their misalignment over the overlap against
/// `truth`; vt-core must be within `vt_px`, OpenCV within `cv_px`, and vt-core no worse than
/// OpenCV (plus 0.02 px).
fn register_row(
    t: &mut Table,
    input: &str,
    a: &RgbImage,
    b: &RgbImage,
    truth: &Homography,
    (vt_px, cv_px): (f64, f64),
) {
    let (w, h) = a.dimensions();
    let region = overlap(truth, w, h, 8.0);
    let params = RegisterParams::default();
    let op = "register (features, RANSAC)";
    let t0 = Instant::now();
    let vt = match vt_core::register::register_pair(a, b, None, &params, (0, 1)) {
        Ok(r) => r,
        Err(e) => return t.error(op, input, format!("vt-core: {e}")),
    };
    let vt_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let cv = match vt_cv::register::register_pair(a, b, &params, (0, 1)) {
        Ok(r) => r,
        Err(e) => return t.error(op, input, format!("OpenCV: {e}")),
    };
    let cv_s = t0.elapsed().as_secs_f64();
    let (ev, ec) = (
        region_error(&vt.homography, truth, &region),
        region_error(&cv.homography, truth, &region),
    );
    t.add(
        op,
        input,
        format!(
            "mean misalignment over the overlap vs truth: vt-core {ev:.3} px ({} inliers, {:.0} ms), OpenCV ORB+RANSAC {ec:.3} px ({} inliers, {:.0} ms)",
            vt.inliers.len(),
            vt_s * 1e3,
            cv.inliers.len(),
            cv_s * 1e3
        ),
        &format!("vt-core <= {vt_px} px, OpenCV <= {cv_px} px, vt-core no worse than OpenCV"),
        ev <= vt_px && ec <= cv_px && ev <= ec + 0.02,
    );
}

/// Both must refuse a pair that has no verifiable mapping.
fn refuse_row(t: &mut Table, input: &str, a: &RgbImage, b: &RgbImage) {
    let params = RegisterParams::default();
    let vt = vt_core::register::register_pair(a, b, None, &params, (0, 1));
    let cv = vt_cv::register::register_pair(a, b, &params, (0, 1));
    let say = |r: std::result::Result<String, String>| match r {
        Ok(s) => format!("accepted ({s})"),
        Err(e) => format!("refused ({e})"),
    };
    let (vt_ok, cv_ok) = (vt.is_ok(), cv.is_ok());
    t.add(
        "register (features, RANSAC)",
        input,
        format!(
            "vt-core {}; OpenCV {}",
            say(vt
                .map(|r| format!("{} inliers", r.inliers.len()))
                .map_err(|e| e.to_string())),
            say(cv
                .map(|r| format!("{} inliers", r.inliers.len()))
                .map_err(|e| e.to_string()))
        ),
        "both refuse",
        !vt_ok && !cv_ok,
    );
}

pub(super) fn registration(t: &mut Table) -> Result<()> {
    let dir = testdata();
    let g1 = load_png(&dir.join("graf1.png"))?;
    let g3 = load_png(&dir.join("graf3.png"))?;
    let (w, h) = g1.dimensions();
    let truth = Homography::from_matrix(read_h1to3p(&dir.join("H1to3p.xml"))?)?;
    register_row(
        t,
        &format!("graf1 -> graf3 {w}x{h} (H1to3p)"),
        &g1,
        &g3,
        &truth,
        (0.5, 3.0),
    );

    // A viewpoint step along a line (shift, slight perspective) with an exposure change.
    let step = Matrix3::new(0.985, 0.01, -18.0, -0.006, 0.99, 4.0, -3e-5, 1e-5, 1.0);
    let known = Homography::from_matrix(step)?;
    let exposed = |img: &RgbImage, gain: f64, offset: f64| {
        let mut out = img.clone();
        for v in out.iter_mut() {
            *v = (f64::from(*v) * gain + offset).round().clamp(0.0, 255.0) as u8;
        }
        out
    };
    let b = exposed(
        &vt_core::warp::warp_rgb(&g1, &known, w, h, Interpolation::Bilinear),
        1.15,
        -8.0,
    );
    register_row(
        t,
        &format!("graf1 {w}x{h} by a known line-rig step, gain 1.15, offset -8"),
        &g1,
        &b,
        &known,
        (0.1, 1.0),
    );

    let frames = vt_io::frames::ViewSource::open(&dir.join("tree.avi"))?.read_all()?;
    let f0 = frames.first().context("tree.avi has no frame")?;
    let (tw, th) = f0.dimensions();
    let b = exposed(
        &vt_core::warp::warp_rgb(f0, &known, tw, th, Interpolation::Bilinear),
        0.9,
        6.0,
    );
    register_row(
        t,
        &format!("tree.avi frame 0 {tw}x{th} by the same step, gain 0.9, offset +6"),
        f0,
        &b,
        &known,
        (0.1, 1.0),
    );

    let flat = RgbImage::from_pixel(320, 240, image::Rgb([128, 128, 128]));
    refuse_row(t, "a flat grey wall, 320x240, twice", &flat, &flat.clone());
    let unrelated = image::imageops::resize(&g1, tw, th, image::imageops::FilterType::Triangle);
    refuse_row(
        t,
        "tree.avi frame 0 against graf1 (unrelated)",
        f0,
        &unrelated,
    );
    Ok(())
}
