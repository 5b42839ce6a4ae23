//! Warping by a homography: `dst(x, y) = src(H^-1 (x, y))`, OpenCV's `warpPerspective` convention.
//!
//! Masks use nearest-neighbour lookup with round-half-to-even (OpenCV's `saturate_cast<int>`);
//! samples that fall outside the source are clear (OpenCV's constant border 0).
//! Only the part of the output that the source's set pixels can reach is visited: the source's
//! bounding box is mapped forward, so the cost follows the moving object, not the frame.
//!
//! RGB images have one sampler ([`Sampler`]) for every caller, the plain warps here and the
//! renderer's background blend: three interpolations ([`Interpolation`]: nearest, exact bilinear,
//! OpenCV's fixed-point bilinear) and two borders ([`Border`]: constant black, replicated edge).
//! It works on runs of [`CHUNK`] output pixels: first every source coordinate of the run
//! (plain `f64` arithmetic over fixed-size arrays, which the compiler vectorises; floor and
//! rounding by integer conversion instead of `f64::floor`, a library call on baseline x86-64),
//! then the taps with no bounds checks in the interior. The arithmetic per pixel is exactly the
//! scalar definition written in each function's doc, so results do not depend on the chunking.

use image::RgbImage;
use rayon::prelude::*;

use crate::round_u8_in_range;
use crate::{Homography, Mask, Point};

mod sampler;
#[cfg(test)]
mod tests;

use sampler::*;
pub(crate) use sampler::{
    sample_value, state, Mapping, Padded, Run, Sampler, BILINEAR, BILINEAR_FIXED, NEAREST,
};
pub use sampler::{Border, Interpolation};

/// Output pixels per run of the sampler (coordinates of a run are computed together).
pub const CHUNK: usize = 64;

/// `2^52 + 2^51`: adding and subtracting it rounds an `f64` of magnitude below `2^51` to an
/// integer, half to even (the default rounding mode), without SSE4.1's `roundsd`.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

/// Round half to even for `|v| < 2^51` (callers clamp first).
#[inline(always)]
fn round_even(v: f64) -> f64 {
    (v + ROUND_MAGIC) - ROUND_MAGIC
}

/// Row-major index of the pixel of a `w x h` grid (each side below 2^22) nearest `(x, y)`,
/// clamped to the grid (NaN to its first row or column), in `f32`: the clamped value plus
/// `1.5 * 2^23` holds the rounded (half to even) integer in its low mantissa bits. No saturating
/// conversion, so it vectorises (16 lanes with AVX-512).
#[inline(always)]
pub(crate) fn nearest_cell(x: f32, y: f32, w: usize, h: usize) -> usize {
    const MAGIC: f32 = 12_582_912.0;
    let clamp = |v: f32, hi: f32| {
        let v = if v >= 0.0 { v } else { 0.0 };
        if v <= hi {
            v
        } else {
            hi
        }
    };
    let cx = clamp(x, (w - 1) as f32);
    let cy = clamp(y, (h - 1) as f32);
    let ix = ((cx + MAGIC).to_bits() & 0x3f_ffff) as usize;
    let iy = ((cy + MAGIC).to_bits() & 0x3f_ffff) as usize;
    ix + iy * w
}

/// `H^-1` row-major: `m[3 r + c]`.
fn inverse_rows(h: &Homography) -> [f64; 9] {
    let inv = h.raw().1;
    std::array::from_fn(|i| inv[(i / 3, i % 3)])
}

/// Warps `src` by `h` into a new `width x height` mask.
pub fn warp_mask(src: &Mask, h: &Homography, width: u32, height: u32) -> Mask {
    let mut out = Mask::new(width, height);
    warp_mask_into(src, h, &mut out);
    out
}

/// Warps `src` by `h` into `out` (cleared first), reusing its storage.
///
/// Per output pixel: `w = (m7 y + m8) + m6 x`; none where `w = 0`; else the source pixel
/// `(round_even((m1 y + m2 + m0 x) / w), ...)` with the reciprocal of `w` taken once, clear
/// outside the source. Runs of [`CHUNK`] pixels are mapped together and written as one word.
pub fn warp_mask_into(src: &Mask, h: &Homography, out: &mut Mask) {
    out.clear();
    let Some(bbox) = src.bounding_box() else {
        return;
    };
    let (ow, oh) = (out.width(), out.height());
    let region = forward_box(h, bbox, ow, oh).unwrap_or((0, 0, ow, oh));
    let m = inverse_rows(h);
    let (sw, sh) = (src.width() as usize, src.height() as usize);
    let (swf, shf) = (sw as f64, sh as f64);
    let words = src.words();
    let (mut sx, mut sy) = ([0f64; CHUNK], [0f64; CHUNK]);
    let (mut ix, mut iy) = ([0i32; CHUNK], [0i32; CHUNK]);
    for y in region.1 as usize..region.3 as usize {
        let mut x0 = region.0 as usize;
        while x0 < region.2 as usize {
            let n = (region.2 as usize - x0).min(CHUNK);
            map_reciprocal(&m, y, x0, &mut sx, &mut sy);
            // Clamped to [-1, size] (NaN and infinity too): outside stays outside.
            for i in 0..CHUNK {
                ix[i] = round_even(clamp_nan_lo(sx[i], -1.0, swf)) as i32;
                iy[i] = round_even(clamp_nan_lo(sy[i], -1.0, shf)) as i32;
            }
            let mut bits = 0u64;
            for i in 0..n {
                let (x, y) = (ix[i], iy[i]);
                if x >= 0 && y >= 0 && (x as usize) < sw && (y as usize) < sh {
                    let k = y as usize * sw + x as usize;
                    bits |= ((words[k >> 6] >> (k & 63)) & 1) << i;
                }
            }
            out.or_bits(y * ow as usize + x0, bits);
            x0 += n;
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
    let ws = corners.map(|(x, y)| m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)]);
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

/// `iota[i] = i`, so `x as f64` of a run is `x0 as f64 + iota[i]` (exact, and vectorises).
const IOTA: [f64; CHUNK] = {
    let mut a = [0.0; CHUNK];
    let mut i = 0;
    while i < CHUNK {
        a[i] = i as f64;
        i += 1;
    }
    a
};

/// `v` clamped to `[lo, hi]`, NaN to `lo`.
#[inline(always)]
fn clamp_nan_lo(v: f64, lo: f64, hi: f64) -> f64 {
    let v = if v >= lo { v } else { lo };
    if v <= hi {
        v
    } else {
        hi
    }
}

/// Source coordinates of output pixels `x0 .. x0 + CHUNK` of row `y`, in [`warp_rgb`]'s and
/// [`warp_mask`]'s order: `w = (m7 y + m8) + m6 x`, then `(m1 y + m2 + m0 x) * (1 / w)` (the
/// reciprocal once, as OpenCV does).
#[inline(always)]
fn map_reciprocal(m: &[f64; 9], y: usize, x0: usize, sx: &mut [f64; CHUNK], sy: &mut [f64; CHUNK]) {
    let (yf, x0f) = (y as f64, x0 as f64);
    let (bx, by, bw) = (m[1] * yf + m[2], m[4] * yf + m[5], m[7] * yf + m[8]);
    for i in 0..CHUNK {
        let xf = x0f + IOTA[i];
        let r = 1.0 / (bw + m[6] * xf);
        sx[i] = (bx + m[0] * xf) * r;
        sy[i] = (by + m[3] * xf) * r;
    }
}

/// The same coordinates in the renderer's order: `(m0 x + m1 y + m2) / (m6 x + m7 y + m8)`.
#[inline(always)]
fn map_division(m: &[f64; 9], y: usize, x0: usize, sx: &mut [f64; CHUNK], sy: &mut [f64; CHUNK]) {
    let (yf, x0f) = (y as f64, x0 as f64);
    let (cx, cy, cw) = (m[1] * yf, m[4] * yf, m[7] * yf);
    for i in 0..CHUNK {
        let xf = x0f + IOTA[i];
        let ww = m[6] * xf + cw + m[8];
        sx[i] = (m[0] * xf + cx + m[2]) / ww;
        sy[i] = (m[3] * xf + cy + m[5]) / ww;
    }
}

/// OpenCV's `warpPerspective` coordinates in 1/32 pixel (`INTER_BITS = 5`): per block of
/// `block_w` columns starting at `xb`, `X0 = m0 xb + m1 y + m2` (and `Y0`, `W0`), then per column
/// `x1` of the block `W = 32 / (W0 + m6 x1)` (0 where the denominator is 0) and
/// `X = cvRound(clamp((X0 + m0 x1) W, INT_MIN, INT_MAX))`.
#[inline(always)]
fn map_fixed(
    m: &[f64; 9],
    y: usize,
    x0: usize,
    block_w: usize,
    qx: &mut [i32; CHUNK],
    qy: &mut [i32; CHUNK],
) {
    let yf = y as f64;
    let (cx, cy, cw) = (m[1] * yf, m[4] * yf, m[7] * yf);
    // The run starts in block `xb0` at column `x1_0`; pixel `split` (if below CHUNK) starts the
    // next block, and with `block_w >= CHUNK` no run reaches a third. A narrower block is a
    // whole row (`block_w = width < CHUNK`): the lanes past it are not used.
    let (xb0, x1_0) = (x0 / block_w * block_w, x0 % block_w);
    let split = (block_w - x1_0) as f64;
    let (xb0, x1_0, bwf) = (xb0 as f64, x1_0 as f64, block_w as f64);
    debug_assert!(block_w >= CHUNK || x0 == 0);
    let (lo, hi) = (i32::MIN as f64, i32::MAX as f64);
    for i in 0..CHUNK {
        let first = IOTA[i] < split;
        let xb = if first { xb0 } else { xb0 + bwf };
        let x1 = if first {
            x1_0 + IOTA[i]
        } else {
            IOTA[i] - split
        };
        let (bx, by, bw) = (
            m[0] * xb + cx + m[2],
            m[3] * xb + cy + m[5],
            m[6] * xb + cw + m[8],
        );
        let w = bw + m[6] * x1;
        let w = if w != 0.0 { 32.0 / w } else { 0.0 };
        qx[i] = int_bits(round_even(clamp_nan_lo((bx + m[0] * x1) * w, lo, hi)));
        qy[i] = int_bits(round_even(clamp_nan_lo((by + m[3] * x1) * w, lo, hi)));
    }
}

/// OpenCV's `warpPerspective` block width for a `width x height` output (`BLOCK_SZ = 32`).
fn opencv_block_width(width: usize, height: usize) -> usize {
    let block_h = 16.min(height).max(1);
    (1024 / block_h).min(width).max(1)
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
    warp_rgb_into(src, h, interp, Border::Constant, &mut out);
    out
}

/// [`warp_rgb`] into an existing image (every pixel is written), with a choice of border.
/// A pixel whose source coordinate is not finite or beyond 1e9 px is black with either border.
pub fn warp_rgb_into(
    src: &RgbImage,
    h: &Homography,
    interp: Interpolation,
    border: Border,
    out: &mut RgbImage,
) {
    let ow = out.width() as usize;
    if ow == 0 {
        return;
    }
    let sampler = Sampler::new(
        src,
        h,
        interp,
        border,
        Mapping::Reciprocal,
        out.dimensions(),
    );
    // Bands of rows per job, so the run buffer is set up once per band, on the stack (rayon's
    // per-job init would allocate).
    out.as_mut()
        .par_chunks_mut(ow * 3 * ROWS_PER_JOB)
        .enumerate()
        .for_each(|(band, rows)| {
            crate::simd::dispatch(WarpBand {
                sampler: &sampler,
                y0: band * ROWS_PER_JOB,
                rows,
                ow,
            })
        });
}

/// Rows of [`warp_rgb_into`] as a [`crate::simd::Kernel`].
struct WarpBand<'a, 'b> {
    sampler: &'a Sampler<'b>,
    y0: usize,
    rows: &'a mut [u8],
    ow: usize,
}

impl crate::simd::Kernel for WarpBand<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let run = &mut Run::default();
        let mut packed = [0u32; CHUNK];
        for (r, row) in self.rows.chunks_mut(self.ow * 3).enumerate() {
            for (c, px) in row.chunks_mut(CHUNK * 3).enumerate() {
                let n = px.len() / 3;
                self.sampler
                    .run_packed(self.y0 + r, c * CHUNK, n, run, &mut packed);
                write_packed(&packed, px);
            }
        }
    }
}

/// Writes packed pixels (RGB in the low three bytes) as interleaved RGB (`px.len() / 3` pixels).
#[inline(always)]
pub(crate) fn write_packed(packed: &[u32; CHUNK], px: &mut [u8]) {
    let n = px.len() / 3;
    if n == 0 {
        return;
    }
    // Four bytes per pixel, the fourth overwritten by the next pixel; the last one exactly.
    for i in 0..n - 1 {
        px[3 * i..3 * i + 4].copy_from_slice(&packed[i].to_le_bytes());
    }
    px[3 * (n - 1)..3 * n].copy_from_slice(&packed[n - 1].to_le_bytes()[..3]);
}

/// Rows per parallel job of the row passes (warps, the renderer's blend).
pub(crate) const ROWS_PER_JOB: usize = 4;
