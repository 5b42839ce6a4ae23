//! Warping by a homography: `dst(x, y) = src(H^-1 (x, y))`, OpenCV's `warpPerspective` convention.
//!
//! Masks use nearest-neighbour lookup with round-half-to-even (OpenCV's `saturate_cast<int>`);
//! samples that fall outside the source are clear (OpenCV's constant border 0).
//! Only the part of the output that the source's set pixels can reach is visited: the source's
//! bounding box is mapped forward, so the cost follows the moving object, not the frame.

use image::RgbImage;
use rayon::prelude::*;

use crate::round_u8;
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
    let Some((x0, y0, x1, y1)) = src.bounding_box() else {
        return;
    };
    let (ow, oh) = (out.width(), out.height());
    let region = forward_box(h, (x0, y0, x1, y1), ow, oh).unwrap_or((0, 0, ow, oh));
    let inv = h.raw().1;
    let (sw, sh) = (src.width() as f64, src.height() as f64);
    for y in region.1..region.3 {
        let yf = y as f64;
        let (bx, by, bw) = (
            inv[(0, 1)] * yf + inv[(0, 2)],
            inv[(1, 1)] * yf + inv[(1, 2)],
            inv[(2, 1)] * yf + inv[(2, 2)],
        );
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
fn forward_box(
    h: &Homography,
    (x0, y0, x1, y1): (u32, u32, u32, u32),
    ow: u32,
    oh: u32,
) -> Option<(u32, u32, u32, u32)> {
    let m = h.raw().0;
    let corners = [
        (x0 as f64 - 1.0, y0 as f64 - 1.0),
        (x1 as f64, y0 as f64 - 1.0),
        (x0 as f64 - 1.0, y1 as f64),
        (x1 as f64, y1 as f64),
    ];
    // w is affine in (x, y): same strict sign at the 4 corners means the same sign on the box.
    let ws: Vec<f64> = corners
        .iter()
        .map(|&(x, y)| m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)])
        .collect();
    if !(ws.iter().all(|&w| w > 0.0) || ws.iter().all(|&w| w < 0.0)) {
        return None;
    }
    let (mut lx, mut ly, mut hx, mut hy) = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in &corners {
        let p = h.apply(Point::new(x, y))?;
        lx = lx.min(p.x);
        ly = ly.min(p.y);
        hx = hx.max(p.x);
        hy = hy.max(p.y);
    }
    let clamp = |v: f64, hi: u32| v.max(0.0).min(hi as f64) as u32;
    Some((
        clamp(lx.floor() - 2.0, ow),
        clamp(ly.floor() - 2.0, oh),
        clamp(hx.ceil() + 3.0, ow),
        clamp(hy.ceil() + 3.0, oh),
    ))
}

/// How colour images are sampled when warped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Nearest neighbour, round half to even (OpenCV `INTER_NEAREST`).
    Nearest,
    /// Bilinear (OpenCV `INTER_LINEAR`), the default.
    #[default]
    Bilinear,
}

/// Warps an RGB image by `h` into a new `width x height` image; outside the source is black
/// (OpenCV `BORDER_CONSTANT`, value 0, including the partial weights at the border).
pub fn warp_rgb(
    src: &RgbImage,
    h: &Homography,
    width: u32,
    height: u32,
    interp: Interpolation,
) -> RgbImage {
    let mut out = RgbImage::new(width, height);
    warp_rgb_into(src, h, interp, &mut out);
    out
}

/// [`warp_rgb`] into an existing image (every pixel is written).
pub fn warp_rgb_into(src: &RgbImage, h: &Homography, interp: Interpolation, out: &mut RgbImage) {
    let inv = *h.raw().1;
    let (sw, sh) = (src.width() as i64, src.height() as i64);
    let sraw = src.as_raw();
    let ow = out.width() as usize;
    let px = |x: i64, y: i64| -> [f32; 3] {
        if x < 0 || y < 0 || x >= sw || y >= sh {
            return [0.0; 3];
        }
        let i = (y as usize * sw as usize + x as usize) * 3;
        [sraw[i] as f32, sraw[i + 1] as f32, sraw[i + 2] as f32]
    };
    out.as_mut()
        .par_chunks_mut(ow * 3)
        .enumerate()
        .for_each(|(y, row)| {
            let yf = y as f64;
            let (bx, by, bw) = (
                inv[(0, 1)] * yf + inv[(0, 2)],
                inv[(1, 1)] * yf + inv[(1, 2)],
                inv[(2, 1)] * yf + inv[(2, 2)],
            );
            for x in 0..ow {
                let xf = x as f64;
                let w = bw + inv[(2, 0)] * xf;
                let o = &mut row[x * 3..x * 3 + 3];
                let (sx, sy) = if w == 0.0 {
                    (f64::NAN, f64::NAN)
                } else {
                    let w = 1.0 / w;
                    ((bx + inv[(0, 0)] * xf) * w, (by + inv[(1, 0)] * xf) * w)
                };
                if !(sx.is_finite() && sy.is_finite()) || sx.abs() > 1e9 || sy.abs() > 1e9 {
                    o.fill(0);
                    continue;
                }
                match interp {
                    Interpolation::Nearest => {
                        let c = px(sx.round_ties_even() as i64, sy.round_ties_even() as i64);
                        for k in 0..3 {
                            o[k] = c[k] as u8;
                        }
                    }
                    Interpolation::Bilinear => {
                        let (x0, y0) = (sx.floor(), sy.floor());
                        let (fx, fy) = ((sx - x0) as f32, (sy - y0) as f32);
                        let (x0, y0) = (x0 as i64, y0 as i64);
                        if x0 >= 0 && y0 >= 0 && x0 + 1 < sw && y0 + 1 < sh {
                            // Interior: the four taps directly, no border logic.
                            let i = (y0 as usize * sw as usize + x0 as usize) * 3;
                            let j = i + sw as usize * 3;
                            for k in 0..3 {
                                let (a, b) = (sraw[i + k] as f32, sraw[i + 3 + k] as f32);
                                let (c, d) = (sraw[j + k] as f32, sraw[j + 3 + k] as f32);
                                let top = a + (b - a) * fx;
                                let bottom = c + (d - c) * fx;
                                o[k] = round_u8(top + (bottom - top) * fy);
                            }
                            continue;
                        }
                        let (a, b, c, d) = (
                            px(x0, y0),
                            px(x0 + 1, y0),
                            px(x0, y0 + 1),
                            px(x0 + 1, y0 + 1),
                        );
                        for k in 0..3 {
                            let top = a[k] + (b[k] - a[k]) * fx;
                            let bottom = c[k] + (d[k] - c[k]) * fx;
                            o[k] = round_u8(top + (bottom - top) * fy);
                        }
                    }
                }
            }
        });
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
            if ww == 0.0 {
                return false;
            }
            let ww = 1.0 / ww;
            let sx = ((inv[(0, 1)] * yf + inv[(0, 2)] + inv[(0, 0)] * xf) * ww).round_ties_even();
            let sy = ((inv[(1, 1)] * yf + inv[(1, 2)] + inv[(1, 0)] * xf) * ww).round_ties_even();
            sx >= 0.0
                && sy >= 0.0
                && sx < src.width() as f64
                && sy < src.height() as f64
                && src.get(sx as u32, sy as u32)
        })
    }

    #[test]
    fn identity_and_integer_translation_are_exact() {
        let m = Mask::from_fn(50, 40, |x, y| (x * 7 + y * 3) % 5 == 0 && x > 10 && y < 30);
        assert_eq!(warp_mask(&m, &Homography::identity(), 50, 40), m);
        let t = warp_mask(&m, &Homography::translation(3.0, -2.0), 50, 40);
        for y in 0..40 {
            for x in 0..50 {
                let want = x >= 3 && y + 2 < 40 && m.get(x - 3, y + 2);
                assert_eq!(t.get(x, y), want, "({x},{y})");
            }
        }
    }

    #[test]
    fn rgb_identity_translation_and_half_pixel() {
        let img = RgbImage::from_fn(20, 10, |x, y| image::Rgb([x as u8 * 10, y as u8 * 20, 7]));
        for interp in [Interpolation::Nearest, Interpolation::Bilinear] {
            assert_eq!(warp_rgb(&img, &Homography::identity(), 20, 10, interp), img);
            let t = warp_rgb(&img, &Homography::translation(2.0, 1.0), 20, 10, interp);
            assert_eq!(t.get_pixel(5, 5), img.get_pixel(3, 4));
            assert_eq!(t.get_pixel(1, 5).0, [0, 0, 0], "outside is black");
        }
        // Half a pixel right: bilinear averages neighbours (x*10 -> x*10 - 5).
        let t = warp_rgb(
            &img,
            &Homography::translation(0.5, 0.0),
            20,
            10,
            Interpolation::Bilinear,
        );
        assert_eq!(t.get_pixel(6, 3).0[0], 55);
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
