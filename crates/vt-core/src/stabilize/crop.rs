//! The still camera's crop: the largest rectangle every steadied frame covers.

use super::{Crop, Shake};
use crate::Homography;

/// The largest even-sized rectangle of the still camera's pixels that every frame (mapped by
/// `maps`) covers; None when there is none.
pub(super) fn covered(maps: &[Homography], (w, h): (u32, u32)) -> Option<Crop> {
    let inv: Vec<[f64; 9]> = maps
        .iter()
        .map(|m| {
            let i = m.raw().1;
            std::array::from_fn(|k| i[(k / 3, k % 3)])
        })
        .collect();
    let (xmax, ymax) = (w as f64 - 1.0, h as f64 - 1.0);
    let inside = |x: f64, y: f64| {
        inv.iter().all(|m| {
            let d = m[6] * x + m[7] * y + m[8];
            if d.abs() < 1e-12 {
                return false;
            }
            let (u, v) = (
                (m[0] * x + m[1] * y + m[2]) / d,
                (m[3] * x + m[4] * y + m[5]) / d,
            );
            (-1e-9..=xmax + 1e-9).contains(&u) && (-1e-9..=ymax + 1e-9).contains(&v)
        })
    };
    // A frame maps to a convex quadrilateral; a rectangle whose corners all lie in every one
    // lies in their intersection.
    let fits = |r: [f64; 4]| {
        r[0] <= r[2]
            && r[1] <= r[3]
            && inside(r[0], r[1])
            && inside(r[2], r[1])
            && inside(r[0], r[3])
            && inside(r[2], r[3])
    };
    let full = [0.0, 0.0, xmax, ymax];
    let mut rect = full;
    if !fits(rect) {
        let (mut lo, mut hi) = (0.0, xmax.min(ymax) / 2.0);
        let at = |m: f64| [m, m, xmax - m, ymax - m];
        if !fits(at(hi)) {
            return None;
        }
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if fits(at(mid)) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        rect = at(hi);
        // Each side pushed back out as far as the rectangle stays covered.
        for _ in 0..2 {
            for side in 0..4 {
                let (mut good, mut far) = (rect[side], full[side]);
                for _ in 0..40 {
                    let mid = 0.5 * (good + far);
                    let mut r = rect;
                    r[side] = mid;
                    if fits(r) {
                        good = mid;
                    } else {
                        far = mid;
                    }
                }
                rect[side] = good;
            }
        }
    }
    let x0 = rect[0].ceil().max(0.0) as u32;
    let y0 = rect[1].ceil().max(0.0) as u32;
    let x1 = rect[2].floor().min(xmax) as u32;
    let y1 = rect[3].floor().min(ymax) as u32;
    let width = (x1 + 1).saturating_sub(x0) & !1;
    let height = (y1 + 1).saturating_sub(y0) & !1;
    (width >= 2 && height >= 2).then_some(Crop {
        x: x0,
        y: y0,
        width,
        height,
    })
}

/// `shake`'s maps composed with a crop: per frame, the map from its pixels to the crop's.
pub fn crop_maps(shake: &Shake, crop: Crop) -> Vec<Homography> {
    let shift = Homography::translation(-(crop.x as f64), -(crop.y as f64));
    shake
        .maps
        .iter()
        .map(|m| {
            shift
                .after(m)
                .expect("a translation after an invertible map")
        })
        .collect()
}
