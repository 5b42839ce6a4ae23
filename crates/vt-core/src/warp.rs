//! Warping by a homography: `dst(x, y) = src(H^-1 (x, y))`, OpenCV's `warpPerspective` convention.
//!
//! Masks use nearest-neighbour lookup with round-half-to-even (OpenCV's `saturate_cast<int>`);
//! samples that fall outside the source are clear (OpenCV's constant border 0).
//! Only the part of the output that the source's set pixels can reach is visited: the source's
//! bounding box is mapped forward, so the cost follows the moving object, not the frame.

use crate::{Homography, Mask, Point};

/// Warps `src` by `h` into a new `width x height` mask.
pub fn warp_mask(src: &Mask, h: &Homography, width: u32, height: u32) -> Mask {
    let mut out = Mask::new(width, height);
    warp_mask_into(src, h, &mut out);
    out
}

/// Warps `src` by `h` into `out` (cleared first), reusing its storage.
pub fn warp_mask_into(src: &Mask, h: &Homography, out: &mut Mask) {
    out.clear();
    let Some((x0, y0, x1, y1)) = src.bounding_box() else { return };
    let (ow, oh) = (out.width(), out.height());
    let region = forward_box(h, (x0, y0, x1, y1), ow, oh).unwrap_or((0, 0, ow, oh));
    let inv = h.raw().1;
    let (sw, sh) = (src.width() as f64, src.height() as f64);
    for y in region.1..region.3 {
        let yf = y as f64;
        let (bx, by, bw) = (inv[(0, 1)] * yf + inv[(0, 2)], inv[(1, 1)] * yf + inv[(1, 2)], inv[(2, 1)] * yf + inv[(2, 2)]);
        for x in region.0..region.2 {
            let xf = x as f64;
            let w = bw + inv[(2, 0)] * xf;
            if w == 0.0 {
                continue;
            }
            let w = 1.0 / w;
            let sx = ((bx + inv[(0, 0)] * xf) * w).round_ties_even();
            let sy = ((by + inv[(1, 0)] * xf) * w).round_ties_even();
            if sx >= 0.0 && sy >= 0.0 && sx < sw && sy < sh && src.get(sx as u32, sy as u32) {
                out.set(x, y, true);
            }
        }
    }
}

/// Output-pixel box covering the forward image of a source box (expanded by 2 px), or `None`
/// when part of the box maps across the line at infinity (then the whole output is visited).
fn forward_box(h: &Homography, (x0, y0, x1, y1): (u32, u32, u32, u32), ow: u32, oh: u32) -> Option<(u32, u32, u32, u32)> {
    let m = h.raw().0;
    let corners = [(x0 as f64 - 1.0, y0 as f64 - 1.0), (x1 as f64, y0 as f64 - 1.0), (x0 as f64 - 1.0, y1 as f64), (x1 as f64, y1 as f64)];
    // w is affine in (x, y): same strict sign at the 4 corners means the same sign on the box.
    let ws: Vec<f64> = corners.iter().map(|&(x, y)| m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)]).collect();
    if !(ws.iter().all(|&w| w > 0.0) || ws.iter().all(|&w| w < 0.0)) {
        return None;
    }
    let (mut lx, mut ly, mut hx, mut hy) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for &(x, y) in &corners {
        let p = h.apply(Point::new(x, y))?;
        lx = lx.min(p.x);
        ly = ly.min(p.y);
        hx = hx.max(p.x);
        hy = hy.max(p.y);
    }
    let clamp = |v: f64, hi: u32| v.max(0.0).min(hi as f64) as u32;
    Some((clamp(lx.floor() - 2.0, ow), clamp(ly.floor() - 2.0, oh), clamp(hx.ceil() + 3.0, ow), clamp(hy.ceil() + 3.0, oh)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use proptest::prelude::*;

    /// Brute force over every output pixel, no bounding box.
    fn reference(src: &Mask, h: &Homography, w: u32, hgt: u32) -> Mask {
        Mask::from_fn(w, hgt, |x, y| {
            let inv = h.raw().1;
            let (xf, yf) = (x as f64, y as f64);
            let ww = inv[(2, 0)] * xf + (inv[(2, 1)] * yf + inv[(2, 2)]);
            if ww == 0.0 { return false; }
            let ww = 1.0 / ww;
            let sx = ((inv[(0, 1)] * yf + inv[(0, 2)] + inv[(0, 0)] * xf) * ww).round_ties_even();
            let sy = ((inv[(1, 1)] * yf + inv[(1, 2)] + inv[(1, 0)] * xf) * ww).round_ties_even();
            sx >= 0.0 && sy >= 0.0 && sx < src.width() as f64 && sy < src.height() as f64 && src.get(sx as u32, sy as u32)
        })
    }

    #[test]
    fn identity_and_integer_translation_are_exact() {
        let m = Mask::from_fn(50, 40, |x, y| (x * 7 + y * 3) % 5 == 0 && x > 10 && y < 30);
        assert_eq!(warp_mask(&m, &Homography::identity(), 50, 40), m);
        let t = warp_mask(&m, &Homography::translation(3.0, -2.0), 50, 40);
        for y in 0..40 { for x in 0..50 {
            let want = x >= 3 && y + 2 < 40 && m.get(x - 3, y + 2);
            assert_eq!(t.get(x, y), want, "({x},{y})");
        }}
    }

    proptest! {
        #[test]
        fn bounding_box_shortcut_equals_brute_force(
            p0 in -2e-3f64..2e-3, p1 in -2e-3f64..2e-3, r in -0.5f64..0.5, tx in -30f64..30.0,
            bx in 0u32..40, by in 0u32..30,
        ) {
            let src = Mask::from_fn(64, 48, |x, y| x >= bx && x < bx + 15 && y >= by && y < by + 10 && (x + y) % 3 != 0);
            let h = Homography::from_matrix(Matrix3::new(r.cos(), -r.sin(), tx, r.sin(), r.cos(), 5.0, p0, p1, 1.0)).unwrap();
            prop_assert_eq!(warp_mask(&src, &h, 70, 50), reference(&src, &h, 70, 50));
        }
    }
}
