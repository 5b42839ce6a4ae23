//! Exposure gain compensation: each view's gain relative to its neighbours.

use super::RenderScene;
use crate::model::fit_model;
use crate::warp::Interpolation;
use crate::Result;

/// Estimates each view's exposure gain (per channel) relative to the geometric mean of all views,
/// from the overlap of neighbouring backgrounds warped into each other: median of per-pixel ratios
/// over pixels both images see with values in 16..240 (clear of noise floor and saturation).
pub fn estimate_gains(scene: &RenderScene) -> Result<Vec<[f32; 3]>> {
    let m = scene.views.len();
    let mut rel = vec![[1.0f64; 3]; m];
    for p in 0..m.saturating_sub(1) {
        let (a, b) = (&scene.views[p].background, &scene.views[p + 1].background);
        let h = fit_model(
            scene.model,
            &scene.views[p + 1].points,
            &scene.views[p].points,
            1.0,
        )?
        .homography;
        let warped = crate::warp::warp_rgb(b, &h, a.width(), a.height(), Interpolation::Bilinear);
        let mut ratios: [Vec<f32>; 3] = Default::default();
        for (pa, pb) in a.pixels().zip(warped.pixels()) {
            if pb.0 == [0, 0, 0] {
                continue;
            }
            for c in 0..3 {
                let (x, y) = (pa.0[c], pb.0[c]);
                if (16..=240).contains(&x) && (16..=240).contains(&y) {
                    ratios[c].push(y as f32 / x as f32);
                }
            }
        }
        for c in 0..3 {
            let r = &mut ratios[c];
            let ratio = if r.len() < 100 {
                1.0
            } else {
                let mid = r.len() / 2;
                *r.select_nth_unstable_by(mid, f32::total_cmp).1 as f64
            };
            rel[p + 1][c] = rel[p][c] * ratio;
        }
    }
    let mut out = vec![[1.0f32; 3]; m];
    for c in 0..3 {
        let log_mean = rel.iter().map(|g| g[c].ln()).sum::<f64>() / m as f64;
        for p in 0..m {
            out[p][c] = (rel[p][c].ln() - log_mean).exp() as f32;
        }
    }
    Ok(out)
}
