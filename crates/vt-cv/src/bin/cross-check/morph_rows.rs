//! The background beyond the plane: vt-core's dense parallax and morph against OpenCV's DIS
//! optical-flow morph, both after the same plane (vt-core's automatic registration), both
//! scored against held-out real views (Middlebury 2005/2006: the even views in, the odd views
//! the truth at q = 0.5, 1.5, 2.5), beside the plane warp of eq. (3) alone.

#[allow(unused_imports)]
use super::*;

fn load(scene: &str, view: usize) -> Result<RgbImage> {
    load_png(
        &testdata()
            .join("middlebury-line")
            .join(scene)
            .join(format!("view{view}.png")),
    )
}

/// The true disparity of view 1 or 5 (half size, full-size units: 1/4 of a value is a pixel of
/// disparity between views two apart), or None for the views without one.
pub(super) fn truth_disparity(scene: &str, view: usize) -> Result<Option<image::GrayImage>> {
    if view != 1 && view != 5 {
        return Ok(None);
    }
    let path = testdata()
        .join("middlebury-line")
        .join(scene)
        .join(format!("disp{view}.png"));
    Ok(Some(image::open(&path)?.to_luma8()))
}

/// PSNR (dB) of the plane warp, vt-core's morph and OpenCV's.
type MorphScores = (f64, f64, f64);

/// PSNR of the plane warp, vt-core's morph and OpenCV's at q = k + 0.5 between views 2k and
/// 2k + 2, against view 2k + 1 ([`vt_cv::cases::morph_scores`], which the report shares), and
/// on the plane where the truth's disparity is known (plane warp, vt-core).
fn scores(scene: &str, k: usize) -> Result<(MorphScores, Option<(f64, f64)>)> {
    let (a, b, truth) = (
        load(scene, 2 * k)?,
        load(scene, 2 * k + 2)?,
        load(scene, 2 * k + 1)?,
    );
    let disp = truth_disparity(scene, 2 * k + 1)?;
    let (s, _) = vt_cv::cases::morph_scores(&a, &b, &truth, disp.as_ref().map(|d| (d, 0.25)))?;
    Ok((
        (s.plane, s.vt, s.cv),
        s.split.map(|sp| (sp.on[0], sp.on[1])),
    ))
}

pub(super) fn morphs(t: &mut Table) -> Result<()> {
    // Issue #19's bar: at least 5 dB over the plane and ahead of OpenCV's DIS morph, per scene.
    for scene in ["Dolls", "Moebius", "Reindeer"] {
        let (mut rows, mut on_plane) = (Vec::new(), Vec::new());
        for k in 0..3 {
            let (r, on) = scores(scene, k)?;
            rows.push(r);
            on_plane.extend(on);
        }
        let mean = |f: fn(&(f64, f64, f64)) -> f64| rows.iter().map(f).sum::<f64>() / 3.0;
        let (p, v, c) = (mean(|r| r.0), mean(|r| r.1), mean(|r| r.2));
        t.add(
            "background morph (parallax)",
            &format!("Middlebury {scene}, views 0-2-4-6 -> 1, 3, 5"),
            format!(
                "PSNR mean over q = 0.5, 1.5, 2.5: plane {p:.2} dB, vt-core morph {v:.2} dB, OpenCV DIS morph {c:.2} dB (per q: {:.2?})",
                rows
            ),
            "vt-core's morph beats the plane by 5 dB and OpenCV's DIS morph",
            v >= p + 5.0 && v > c,
        );
        t.add(
            "background morph (parallax)",
            &format!("Middlebury {scene}, on the plane (true disparity within 1 px), q = 0.5, 2.5"),
            format!("PSNR (plane warp, vt-core morph): {on_plane:.2?}"),
            "the morph never loses to the plane warp on the plane (0.1 dB slack)",
            on_plane.len() == 2 && on_plane.iter().all(|&(p, v)| v >= p - 0.1),
        );
    }
    Ok(())
}
