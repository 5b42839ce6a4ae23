//! Background alignment: vt-core's Lucas-Kanade refinement against OpenCV's `findTransformECC`,
//! both started from the same perturbed homography, both scored against a known truth.
//!
//! Inputs with truth: the real graf pair with its published homography (H1to3p, a strong
//! viewpoint change), and graf1 against itself warped by a known projective map with an exposure
//! gain and offset (exact truth, and the gain the two criteria must both ignore).

#[allow(unused_imports)]
use super::*;

use vt_core::align::AlignParams;
use vt_core::model::MotionModel;
use vt_cv::cases::noise;

/// The mean distance between where `est` and `truth` send the region's pixels (every 8th in
/// each direction), pixels: the misalignment where the two images overlap. (At a's corners,
/// outside the overlap, a strong viewpoint change extrapolates a small error into a large one.)
pub(super) fn region_error(est: &Homography, truth: &Homography, region: &Mask) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for y in (0..region.height()).step_by(8) {
        for x in (0..region.width()).step_by(8) {
            if !region.get(x, y) {
                continue;
            }
            let p = Point::new(f64::from(x), f64::from(y));
            sum += match (est.apply(p), truth.apply(p)) {
                (Some(e), Some(t)) => (e.x - t.x).hypot(e.y - t.y),
                _ => f64::INFINITY,
            };
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// `truth` with a's corners' images moved by up to `px` pixels (deterministic), as hand-marked
/// points would give.
fn perturbed(truth: &Homography, w: u32, h: u32, px: f64, seed: u64) -> Result<Homography> {
    let (fw, fh) = (f64::from(w) - 1.0, f64::from(h) - 1.0);
    let src = [
        Point::new(0.0, 0.0),
        Point::new(fw, 0.0),
        Point::new(fw, fh),
        Point::new(0.0, fh),
    ];
    let dst: Vec<Point> = src
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = truth
                .apply(*p)
                .context("truth sends a corner to infinity")?;
            let i = i as u64;
            Ok(Point::new(
                q.x + px * noise(seed, 2 * i),
                q.y + px * noise(seed, 2 * i + 1),
            ))
        })
        .collect::<Result<_>>()?;
    Ok(Homography::from_correspondences(&src, &dst)?.homography)
}

/// a's pixels whose image under `truth` lands inside b (inset by `margin`), so neither side is
/// asked to match what b does not show.
pub(super) fn overlap(truth: &Homography, w: u32, h: u32, margin: f64) -> Mask {
    let mut m = Mask::new(w, h);
    for y in 0..h {
        for x in 0..w {
            if let Some(q) = truth.apply(Point::new(f64::from(x), f64::from(y))) {
                let inside = q.x >= margin
                    && q.y >= margin
                    && q.x <= f64::from(w) - 1.0 - margin
                    && q.y <= f64::from(h) - 1.0 - margin;
                m.set(x, y, inside);
            }
        }
    }
    m
}

/// One row: both refinements from `init`, their corner errors against `truth` and each other.
#[allow(clippy::too_many_arguments)]
fn align_row(
    t: &mut Table,
    input: &str,
    a: &RgbImage,
    b: &RgbImage,
    truth: &Homography,
    init: &Homography,
    model: MotionModel,
    (truth_px, agree_px): (f64, f64),
) {
    let (w, h) = a.dimensions();
    let region = overlap(truth, w, h, 8.0);
    let params = AlignParams::default();
    let op = format!("align backgrounds ({model:?})");
    let vt = match vt_core::align::align_backgrounds(a, b, init, &region, model, &params) {
        Ok(r) => r.homography,
        Err(e) => return t.error(&op, input, format!("vt-core: {e}")),
    };
    let cv = match vt_cv::align::align_backgrounds(a, b, init, &region, model, &params) {
        Ok(r) => r.homography,
        Err(e) => return t.error(&op, input, format!("OpenCV: {e}")),
    };
    let (e0, ev, ec, evc) = (
        region_error(init, truth, &region),
        region_error(&vt, truth, &region),
        region_error(&cv, truth, &region),
        region_error(&vt, &cv, &region),
    );
    t.add(
        &op,
        input,
        format!(
            "mean misalignment over the overlap vs truth: start {e0:.2} px, vt-core {ev:.3} px, OpenCV ECC {ec:.3} px; \
             vt-core vs ECC {evc:.3} px"
        ),
        &format!(
            "both <= {truth_px} px of truth, <= {agree_px} px of each other, 3x better than the start"
        ),
        ev <= truth_px
            && ec <= truth_px
            && evc <= agree_px
            && ev * 3.0 <= e0
            && ec * 3.0 <= e0,
    );
}

pub(super) fn alignment(t: &mut Table) -> Result<()> {
    let dir = testdata();
    let g1 = load_png(&dir.join("graf1.png"))?;
    let g3 = load_png(&dir.join("graf3.png"))?;
    let (w, h) = g1.dimensions();

    // The real pair: graf1 -> graf3 by the published homography, start 3 px off at the corners.
    let truth = Homography::from_matrix(read_h1to3p(&dir.join("H1to3p.xml"))?)?;
    let init = perturbed(&truth, w, h, 3.0, 11)?;
    align_row(
        t,
        &format!("graf1 -> graf3 {w}x{h} (H1to3p), start +-3 px"),
        &g1,
        &g3,
        &truth,
        &init,
        MotionModel::Homography,
        // H1to3p is itself an estimate (sub-pixel); the pair has strong foreshortening.
        (0.6, 0.5),
    );

    // graf1 against itself under a known projective map, gain 1.2 and offset -15: exact truth.
    let m = Matrix3::new(0.96, -0.08, 25.0, 0.06, 1.01, -12.0, 6e-5, -4e-5, 1.0);
    let known = Homography::from_matrix(m)?;
    let mut b = vt_core::warp::warp_rgb(&g1, &known, w, h, Interpolation::Bilinear);
    for v in b.iter_mut() {
        *v = (f64::from(*v) * 1.2 - 15.0).round().clamp(0.0, 255.0) as u8;
    }
    let init = perturbed(&known, w, h, 4.0, 12)?;
    align_row(
        t,
        &format!("graf1 {w}x{h} by a known projective map, gain 1.2, offset -15, start +-4 px"),
        &g1,
        &b,
        &known,
        &init,
        MotionModel::Homography,
        (0.1, 0.1),
    );

    // The same under an affine map, refined under the affine model.
    let m = Matrix3::new(0.97, -0.1, 30.0, 0.08, 1.02, -10.0, 0.0, 0.0, 1.0);
    let known = Homography::from_matrix(m)?;
    let mut b = vt_core::warp::warp_rgb(&g1, &known, w, h, Interpolation::Bilinear);
    for v in b.iter_mut() {
        *v = (f64::from(*v) * 0.85 + 10.0).round().clamp(0.0, 255.0) as u8;
    }
    let init = Homography::from_matrix(
        known.matrix() + Matrix3::new(0.0, 0.0, 2.5, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0),
    )?;
    align_row(
        t,
        &format!("graf1 {w}x{h} by a known affine map, gain 0.85, offset +10, start 3 px off"),
        &g1,
        &b,
        &known,
        &init,
        MotionModel::Affine,
        (0.1, 0.1),
    );
    Ok(())
}
