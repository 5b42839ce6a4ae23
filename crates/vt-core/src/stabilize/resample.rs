//! The still camera's warps: bicubic (Keys' cubic convolution, a = -0.5), edge replicated,
//! interleaved RGB or 4:2:0 planes.

use image::RgbImage;
use rayon::prelude::*;

use crate::yuv::Yuv420Image;
use crate::Homography;

/// Warps `src` by `h` (source pixels to output pixels) into `out` (every pixel written),
/// bicubic, edge replicated.
pub fn warp_rgb_cubic(src: &RgbImage, h: &Homography, out: &mut RgbImage) {
    let m = inverse_rows(h);
    let (sw, sh) = (src.width() as usize, src.height() as usize);
    let ow = out.width() as usize;
    warp_channels(src.as_raw(), (sw, sh), 3, out, ow, &|x, y| {
        project(&m, x, y)
    });
}

/// Warps a 4:2:0 frame by `h` (source pixels to output pixels) into `out`, plane by plane,
/// bicubic, edge replicated. Chroma samples sit at the centre of their 2x2 luma block.
pub fn warp_yuv420(src: &Yuv420Image, h: &Homography, out: &mut Yuv420Image) {
    let m = inverse_rows(h);
    let (sw, sh) = (src.width() as usize, src.height() as usize);
    let ow = out.width() as usize;
    let oh = out.height() as usize;
    let (sy, sc) = src.as_raw().split_at(sw * sh);
    let (su, sv) = sc.split_at(sw * sh / 4);
    let (oy, oc) = out.as_raw_mut().split_at_mut(ow * oh);
    let (ou, ov) = oc.split_at_mut(ow * oh / 4);
    // Luma: output pixel (x, y) reads the source at H^-1 (x, y).
    warp_channels(sy, (sw, sh), 1, oy, ow, &|x, y| project(&m, x, y));
    // Chroma: sample (i, j) sits at luma (2i + 0.5, 2j + 0.5).
    let chroma = |x: f64, y: f64| {
        let (u, v) = project(&m, 2.0 * x + 0.5, 2.0 * y + 0.5);
        ((u - 0.5) / 2.0, (v - 0.5) / 2.0)
    };
    rayon::join(
        || warp_channels(su, (sw / 2, sh / 2), 1, ou, ow / 2, &chroma),
        || warp_channels(sv, (sw / 2, sh / 2), 1, ov, ow / 2, &chroma),
    );
}

/// `H^-1` row-major.
fn inverse_rows(h: &Homography) -> [f64; 9] {
    let inv = h.raw().1;
    std::array::from_fn(|k| inv[(k / 3, k % 3)])
}

fn project(m: &[f64; 9], x: f64, y: f64) -> (f64, f64) {
    let d = m[6] * x + m[7] * y + m[8];
    (
        (m[0] * x + m[1] * y + m[2]) / d,
        (m[3] * x + m[4] * y + m[5]) / d,
    )
}

/// Keys' cubic convolution weights (a = -0.5) of the four taps around a fraction `t`.
fn cubic_weights(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    ]
}

/// Warps `channels`-interleaved bytes: output pixel (x, y) of rows `ow` wide is the bicubic
/// sample of `src` at `at(x, y)` (clamped to the image; not finite: its corner).
fn warp_channels(
    src: &[u8],
    (sw, sh): (usize, usize),
    channels: usize,
    out: &mut [u8],
    ow: usize,
    at: &(dyn Fn(f64, f64) -> (f64, f64) + Sync),
) {
    if ow == 0 || sw == 0 || sh == 0 {
        return;
    }
    let (xmax, ymax) = ((sw - 1) as f64, (sh - 1) as f64);
    let clamp = |v: f64, hi: f64| if v.is_finite() { v.clamp(0.0, hi) } else { 0.0 };
    out.par_chunks_mut(ow * channels)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..ow {
                let (u, v) = at(x as f64, y as f64);
                let (u, v) = (clamp(u, xmax), clamp(v, ymax));
                let (x0, y0) = (u.floor(), v.floor());
                let (wx, wy) = (
                    cubic_weights((u - x0) as f32),
                    cubic_weights((v - y0) as f32),
                );
                let (x0, y0) = (x0 as isize, y0 as isize);
                let xs: [usize; 4] = std::array::from_fn(|i| {
                    (x0 - 1 + i as isize).clamp(0, sw as isize - 1) as usize
                });
                let ys: [usize; 4] = std::array::from_fn(|j| {
                    (y0 - 1 + j as isize).clamp(0, sh as isize - 1) as usize
                });
                for c in 0..channels {
                    let mut acc = 0.0f32;
                    for (j, &yy) in ys.iter().enumerate() {
                        let line = &src[yy * sw * channels..(yy + 1) * sw * channels];
                        let mut h = 0.0f32;
                        for (i, &xx) in xs.iter().enumerate() {
                            h += wx[i] * line[xx * channels + c] as f32;
                        }
                        acc += wy[j] * h;
                    }
                    row[x * channels + c] = (acc + 0.5).clamp(0.0, 255.0) as u8;
                }
            }
        });
}
