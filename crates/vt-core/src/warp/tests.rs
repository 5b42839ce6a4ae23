use super::*;
use crate::round_u8;
use nalgebra::Matrix3;
use proptest::prelude::*;

/// Brute force over every output pixel, no bounding box, no runs.
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

/// The scalar warp as it was before the run-based sampler (one pixel at a time, `f64::floor`,
/// `round_ties_even`): the bytes [`Interpolation::Nearest`] and [`Interpolation::Bilinear`]
/// must keep.
fn reference_rgb(
    src: &RgbImage,
    h: &Homography,
    interp: Interpolation,
    w: u32,
    hgt: u32,
) -> RgbImage {
    let inv = *h.raw().1;
    let (sw, sh) = (src.width() as i64, src.height() as i64);
    let px = |x: i64, y: i64| -> [f32; 3] {
        if x < 0 || y < 0 || x >= sw || y >= sh {
            return [0.0; 3];
        }
        let p = src.get_pixel(x as u32, y as u32).0;
        [p[0] as f32, p[1] as f32, p[2] as f32]
    };
    RgbImage::from_fn(w, hgt, |x, y| {
        let (xf, yf) = (x as f64, y as f64);
        let (bx, by, bw) = (
            inv[(0, 1)] * yf + inv[(0, 2)],
            inv[(1, 1)] * yf + inv[(1, 2)],
            inv[(2, 1)] * yf + inv[(2, 2)],
        );
        let w = bw + inv[(2, 0)] * xf;
        let (sx, sy) = if w == 0.0 {
            (f64::NAN, f64::NAN)
        } else {
            let w = 1.0 / w;
            ((bx + inv[(0, 0)] * xf) * w, (by + inv[(1, 0)] * xf) * w)
        };
        if !(sx.is_finite() && sy.is_finite()) || sx.abs() > 1e9 || sy.abs() > 1e9 {
            return image::Rgb([0; 3]);
        }
        let c = match interp {
            Interpolation::Nearest => px(sx.round_ties_even() as i64, sy.round_ties_even() as i64),
            _ => {
                let (x0, y0) = (sx.floor(), sy.floor());
                let (fx, fy) = ((sx - x0) as f32, (sy - y0) as f32);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let (a, b, c, d) = (
                    px(x0, y0),
                    px(x0 + 1, y0),
                    px(x0, y0 + 1),
                    px(x0 + 1, y0 + 1),
                );
                std::array::from_fn(|k| {
                    let top = a[k] + (b[k] - a[k]) * fx;
                    let bottom = c[k] + (d[k] - c[k]) * fx;
                    top + (bottom - top) * fy
                })
            }
        };
        image::Rgb(c.map(round_u8))
    })
}

/// OpenCV's bilinear `warpPerspective` written out per pixel in `i64` (independently of the
/// sampler: blocks by division, `round_ties_even`, the `(sum + 2^14) >> 15` of 15-bit weights).
fn reference_fixed(src: &RgbImage, h: &Homography, w: u32, hgt: u32, border: Border) -> RgbImage {
    let inv = h.raw().1;
    let mm = |r: usize, c: usize| inv[(r, c)];
    let (sw, sh) = (src.width() as i64, src.height() as i64);
    let block_h = 16.min(hgt as usize);
    let block_w = (1024 / block_h).min(w as usize);
    RgbImage::from_fn(w, hgt, |x, y| {
        let yf = y as f64;
        let xb = (x as usize / block_w * block_w) as f64;
        let x1 = (x as usize % block_w) as f64;
        let x0 = mm(0, 0) * xb + mm(0, 1) * yf + mm(0, 2);
        let y0 = mm(1, 0) * xb + mm(1, 1) * yf + mm(1, 2);
        let w0 = mm(2, 0) * xb + mm(2, 1) * yf + mm(2, 2);
        let ww = w0 + mm(2, 0) * x1;
        let ww = if ww != 0.0 { 32.0 / ww } else { 0.0 };
        let fx = ((x0 + mm(0, 0) * x1) * ww).clamp(i32::MIN as f64, i32::MAX as f64);
        let fy = ((y0 + mm(1, 0) * x1) * ww).clamp(i32::MIN as f64, i32::MAX as f64);
        let (qx, qy) = (fx.round_ties_even() as i64, fy.round_ties_even() as i64);
        let (sx, sy) = (
            (qx >> 5).clamp(-32768, 32767),
            (qy >> 5).clamp(-32768, 32767),
        );
        let (ax, ay) = (qx & 31, qy & 31);
        let at = |xx: i64, yy: i64, c: usize| -> i64 {
            let (xx, yy) = match border {
                Border::Constant if xx < 0 || yy < 0 || xx >= sw || yy >= sh => return 0,
                Border::Constant => (xx, yy),
                Border::Replicate => (xx.clamp(0, sw - 1), yy.clamp(0, sh - 1)),
            };
            src.get_pixel(xx as u32, yy as u32).0[c] as i64
        };
        image::Rgb(std::array::from_fn(|c| {
            let sum = at(sx, sy, c) * (32 - ay) * (32 - ax) * 32
                + at(sx + 1, sy, c) * (32 - ay) * ax * 32
                + at(sx, sy + 1, c) * ay * (32 - ax) * 32
                + at(sx + 1, sy + 1, c) * ay * ax * 32;
            ((sum + (1 << 14)) >> 15).clamp(0, 255) as u8
        }))
    })
}

fn texture(w: u32, h: u32, seed: u32) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let t = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503) ^ seed) >> 7;
        image::Rgb([t as u8, (t >> 8) as u8, (x * 13 + y * 7) as u8])
    })
}

fn arbitrary_homography() -> impl Strategy<Value = Homography> {
    (
        // Affine maps too.
        prop_oneof![Just(0.0), -3e-3f64..3e-3],
        prop_oneof![Just(0.0), -3e-3f64..3e-3],
        -0.6f64..0.6,
        0.5f64..2.0,
        -40f64..40.0,
        -30f64..30.0,
    )
        .prop_map(|(p0, p1, r, s, tx, ty)| {
            Homography::from_matrix(Matrix3::new(
                s * r.cos(),
                -s * r.sin(),
                tx,
                s * r.sin(),
                s * r.cos(),
                ty,
                p0,
                p1,
                1.0,
            ))
            .unwrap()
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
    for interp in [
        Interpolation::Nearest,
        Interpolation::Bilinear,
        Interpolation::BilinearFixed,
    ] {
        assert_eq!(warp_rgb(&img, &Homography::identity(), 20, 10, interp), img);
        let t = warp_rgb(&img, &Homography::translation(2.0, 1.0), 20, 10, interp);
        assert_eq!(t.get_pixel(5, 5), img.get_pixel(3, 4));
        assert_eq!(t.get_pixel(1, 5).0, [0, 0, 0], "outside is black");
        // Replicated border: the edge pixel instead of black.
        let mut r = RgbImage::new(20, 10);
        warp_rgb_into(
            &img,
            &Homography::translation(2.0, 1.0),
            interp,
            Border::Replicate,
            &mut r,
        );
        assert_eq!(r.get_pixel(1, 5), img.get_pixel(0, 4), "{interp:?}");
        assert_eq!(r.get_pixel(0, 0), img.get_pixel(0, 0), "{interp:?}");
    }
    // Half a pixel right: bilinear averages neighbours (x*10 -> x*10 - 5).
    for interp in [Interpolation::Bilinear, Interpolation::BilinearFixed] {
        let t = warp_rgb(&img, &Homography::translation(0.5, 0.0), 20, 10, interp);
        assert_eq!(t.get_pixel(6, 3).0[0], 55);
    }
}

#[test]
fn fixed_point_quantises_to_a_32nd_of_a_pixel() {
    // A ramp of 8 levels per pixel: shifted by 1/64 px, the exact warp moves by 1/8 of a
    // level (rounds back), 3/64 px by 3/8; OpenCV's fixed point rounds 3/64 to 2/32 = 1/16 px,
    // i.e. half a level: 0.5 rounds up.
    let img = RgbImage::from_fn(40, 4, |x, _| image::Rgb([(x * 8) as u8, 0, 0]));
    let t = Homography::translation(-3.0 / 64.0, 0.0);
    let exact = warp_rgb(&img, &t, 40, 4, Interpolation::Bilinear);
    let fixed = warp_rgb(&img, &t, 40, 4, Interpolation::BilinearFixed);
    assert_eq!(exact.get_pixel(10, 1).0[0], 80); // 80.375
    assert_eq!(fixed.get_pixel(10, 1).0[0], 81); // 80.5
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

    #[test]
    fn runs_keep_the_scalar_warps_bytes(
        h in arbitrary_homography(), (sw, sh) in (1u32..90, 1u32..40), (w, hgt) in (1u32..150, 1u32..40),
        seed in any::<u32>(),
    ) {
        let src = texture(sw, sh, seed);
        for interp in [Interpolation::Nearest, Interpolation::Bilinear] {
            prop_assert_eq!(
                warp_rgb(&src, &h, w, hgt, interp),
                reference_rgb(&src, &h, interp, w, hgt),
                "{:?}", interp
            );
        }
    }

    #[test]
    fn fixed_point_is_opencvs_arithmetic(
        h in arbitrary_homography(), (sw, sh) in (1u32..90, 1u32..40), (w, hgt) in (1u32..150, 1u32..40),
        seed in any::<u32>(),
    ) {
        let src = texture(sw, sh, seed);
        for border in [Border::Constant, Border::Replicate] {
            let mut out = RgbImage::new(w, hgt);
            warp_rgb_into(&src, &h, Interpolation::BilinearFixed, border, &mut out);
            prop_assert_eq!(out, reference_fixed(&src, &h, w, hgt, border), "{:?}", border);
        }
    }
}

/// The renderer's sampling as it was before the sampler (per pixel, division mapping,
/// replicated edges): the value before rounding, and whether the sample is inside.
fn reference_division(
    src: &RgbImage,
    h: &Homography,
    interp: Interpolation,
    x: u32,
    y: u32,
) -> Option<([f32; 3], bool)> {
    let inv = h.raw().1;
    let (xf, yf) = (x as f64, y as f64);
    let ww = inv[(2, 0)] * xf + inv[(2, 1)] * yf + inv[(2, 2)];
    let (sx, sy) = (
        (inv[(0, 0)] * xf + inv[(0, 1)] * yf + inv[(0, 2)]) / ww,
        (inv[(1, 0)] * xf + inv[(1, 1)] * yf + inv[(1, 2)]) / ww,
    );
    if !(sx.is_finite() && sy.is_finite()) {
        return None;
    }
    let (w, h) = (src.width() as i64, src.height() as i64);
    let inside = sx >= -0.5 && sy >= -0.5 && sx < w as f64 - 0.5 && sy < h as f64 - 0.5;
    let at = |x: i64, y: i64| {
        let p = src
            .get_pixel(x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32)
            .0;
        [p[0] as f32, p[1] as f32, p[2] as f32]
    };
    let c = match interp {
        Interpolation::Nearest => at(sx.round_ties_even() as i64, sy.round_ties_even() as i64),
        _ => {
            let (x0, y0) = (sx.floor(), sy.floor());
            let (fx, fy) = ((sx - x0) as f32, (sy - y0) as f32);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let (a, b, c, d) = (
                at(x0, y0),
                at(x0 + 1, y0),
                at(x0, y0 + 1),
                at(x0 + 1, y0 + 1),
            );
            std::array::from_fn(|k| {
                let top = a[k] + (b[k] - a[k]) * fx;
                let bottom = c[k] + (d[k] - c[k]) * fx;
                top + (bottom - top) * fy
            })
        }
    };
    Some((c, inside))
}

proptest! {
    #[test]
    fn renderer_sampling_keeps_its_values(
        h in arbitrary_homography(), (sw, sh) in (1u32..90, 1u32..40), (w, hgt) in (1u32..150, 1u32..20),
        seed in any::<u32>(),
    ) {
        let src = texture(sw, sh, seed);
        let padded = Padded::new(&src);
        let mut run = Run::default();
        for (interp, pad) in [
            (Interpolation::Nearest, false),
            (Interpolation::Bilinear, false),
            (Interpolation::Nearest, true),
            (Interpolation::Bilinear, true),
        ] {
            let sampler = if pad {
                Sampler::padded(&padded, &h, interp, Mapping::Division, (w, hgt))
            } else {
                Sampler::new(&src, &h, interp, Border::Replicate, Mapping::Division, (w, hgt))
            };
            for y in 0..hgt {
                for x0 in (0..w).step_by(CHUNK) {
                    let n = (w - x0).min(CHUNK as u32) as usize;
                    sampler.run(y as usize, x0 as usize, n, &mut run);
                    for i in 0..n {
                        let value = [run.value[0][i], run.value[1][i], run.value[2][i]];
                        let got = (run.state[i] != state::NONE)
                            .then_some((value, run.state[i] == state::INSIDE));
                        let want = reference_division(&src, &h, interp, x0 + i as u32, y);
                        // Bit-identical f32 values (to_bits: exact, -0 vs 0 included).
                        prop_assert_eq!(
                            got.map(|(v, i)| (v.map(f32::to_bits), i)),
                            want.map(|(v, i)| (v.map(f32::to_bits), i)),
                            "{:?} (padded {}) at ({}, {})", interp, pad, x0 + i as u32, y
                        );
                    }
                }
            }
        }
    }

    /// The padded source (the renderer's) reads the same taps as the replicated border, in
    /// the fixed-point mode too (whose coordinates are not clamped to the image first).
    #[test]
    fn padded_source_is_the_replicated_border(
        h in arbitrary_homography(), (sw, sh) in (1u32..90, 1u32..40), (w, hgt) in (1u32..150, 1u32..20),
        seed in any::<u32>(),
    ) {
        let src = texture(sw, sh, seed);
        let padded = Padded::new(&src);
        let (mut a, mut b) = (Run::default(), Run::default());
        for interp in [Interpolation::Nearest, Interpolation::Bilinear, Interpolation::BilinearFixed] {
            let plain = Sampler::new(&src, &h, interp, Border::Replicate, Mapping::Division, (w, hgt));
            let pad = Sampler::padded(&padded, &h, interp, Mapping::Division, (w, hgt));
            for y in 0..hgt as usize {
                for x0 in (0..w as usize).step_by(CHUNK) {
                    let n = (w as usize - x0).min(CHUNK);
                    plain.run(y, x0, n, &mut a);
                    pad.run(y, x0, n, &mut b);
                    for i in 0..n {
                        prop_assert_eq!(a.state[i], b.state[i]);
                        for k in 0..3 {
                            prop_assert_eq!(
                                a.value[k][i].to_bits(), b.value[k][i].to_bits(),
                                "{:?} at ({}, {})", interp, x0 + i, y
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn round_u8_is_the_saturating_cast() {
    let check = |v: f32| assert_eq!(round_u8(v), (v + 0.5) as u8, "{v:?}");
    for i in -20_000..320_000 {
        let v = i as f32 / 1024.0;
        check(v);
        check(v.next_up());
        check(v.next_down());
    }
    for v in [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::MAX,
        f32::MIN,
        1e9,
        -1e9,
        0.0,
        -0.0,
    ] {
        check(v);
    }
}

#[test]
fn line_at_infinity_and_far_samples_are_black() {
    // w = 0 on column 8 of the output (H^-1 has -1/8 in its last row).
    let m = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.125, 0.0, 1.0);
    let h = Homography::from_matrix(m).unwrap();
    let img = texture(16, 8, 3);
    for interp in [Interpolation::Nearest, Interpolation::Bilinear] {
        let out = warp_rgb(&img, &h, 16, 8, interp);
        assert_eq!(out, reference_rgb(&img, &h, interp, 16, 8));
        assert_eq!(out.get_pixel(8, 3).0, [0, 0, 0]);
    }
}
