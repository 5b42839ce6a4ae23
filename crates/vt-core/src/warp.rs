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

/// How colour images are sampled when warped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Nearest neighbour, round half to even (OpenCV `INTER_NEAREST`).
    Nearest,
    /// Bilinear (OpenCV `INTER_LINEAR`) at the exact `f64` coordinate, interpolated in `f32`:
    /// the default.
    #[default]
    Bilinear,
    /// Bilinear in OpenCV's fixed point: the coordinate rounded to 1/32 pixel (`INTER_BITS = 5`)
    /// and integer weights `(32 - ay)(32 - ax)` etc., rounded once, `(sum + 512) >> 10`. With
    /// the constant border it reproduces OpenCV's `warpPerspective(INTER_LINEAR)` bit for bit;
    /// against [`Interpolation::Bilinear`] it differs by up to `R/32 + 1` levels, `R` the local
    /// value range (a speed/accuracy knob, measured in `crates/vt-cv/README.md`).
    BilinearFixed,
}

/// What a sample reads outside the source image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Border {
    /// Black (OpenCV `BORDER_CONSTANT`, value 0), also inside the partial weights at the edge.
    #[default]
    Constant,
    /// The nearest edge pixel (OpenCV `BORDER_REPLICATE`).
    Replicate,
}

/// Per-pixel outcome of [`Sampler::run`].
pub(crate) mod state {
    /// No sample: the coordinate is not finite (or beyond 1e9 px for the plain warp).
    pub const NONE: u32 = 0;
    /// A sample, from a coordinate outside the source's pixel area.
    pub const OUTSIDE: u32 = 1;
    /// A sample from inside `-0.5 <= x < w - 0.5`, `-0.5 <= y < h - 0.5`.
    pub const INSIDE: u32 = 2;
}

/// Which formula maps output pixels to source coordinates (they differ in the last bit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mapping {
    /// [`warp_rgb`]'s, OpenCV's order (reciprocal of `w`), with samples beyond 1e9 px dropped.
    Reciprocal,
    /// The renderer's (a division per coordinate), every finite coordinate sampled.
    Division,
}

/// Samples of one run of output pixels: the value before rounding (`f32`, unrounded for the
/// bilinear modes) per channel, and the [`state`] of each pixel.
pub(crate) struct Run {
    /// Per channel, per pixel (structure of arrays), from [`Sampler::run`] (the tests' view of
    /// the sampler; the renderer reads [`sample_value`] directly).
    #[cfg(test)]
    pub value: [[f32; CHUNK]; 3],
    /// Per pixel, one of [`state`].
    pub state: [u32; CHUNK],
    /// Source coordinates of the run's pixels (set by [`Sampler::map_into`] or the caller of
    /// [`Sampler::taps_at`]).
    pub sx: [f64; CHUNK],
    /// See `sx`.
    pub sy: [f64; CHUNK],
    ix: [i32; CHUNK],
    iy: [i32; CHUNK],
    fx: [f32; CHUNK],
    fy: [f32; CHUNK],
    /// Fixed point: the 1/32 fractions.
    wx: [i32; CHUNK],
    wy: [i32; CHUNK],
    /// Per pixel, the taps `a b / c d` of the 2x2 block (nearest: `a` only), each an RGB pixel
    /// in the low three bytes of a `u32` (little-endian; the top byte is not used).
    taps: [[u32; CHUNK]; 4],
}

impl Default for Run {
    fn default() -> Self {
        Self {
            #[cfg(test)]
            value: [[0.0; CHUNK]; 3],
            state: [0; CHUNK],
            sx: [0.0; CHUNK],
            sy: [0.0; CHUNK],
            ix: [0; CHUNK],
            iy: [0; CHUNK],
            fx: [0.0; CHUNK],
            fy: [0.0; CHUNK],
            wx: [0; CHUNK],
            wy: [0; CHUNK],
            taps: [[0; CHUNK]; 4],
        }
    }
}

/// Byte `k` of `v` (little-endian).
#[inline(always)]
fn byte(v: u32, k: usize) -> i32 {
    ((v >> (8 * k)) & 0xff) as i32
}

/// Channel `k` of pixel `i`, exact bilinear: `top + (bottom - top) * fy`.
#[inline(always)]
fn lerp2(run: &Run, i: usize, k: usize) -> f32 {
    let [ta, tb, tc, td] = &run.taps;
    let (a, b) = (byte(ta[i], k) as f32, byte(tb[i], k) as f32);
    let (c, d) = (byte(tc[i], k) as f32, byte(td[i], k) as f32);
    let top = a + (b - a) * run.fx[i];
    let bottom = c + (d - c) * run.fx[i];
    top + (bottom - top) * run.fy[i]
}

/// Channel `k` of pixel `i` of a run prepared by [`Sampler::taps`], as [`Sampler::run`] gives
/// it, for the interpolation `MODE` ([`NEAREST`], [`BILINEAR`] or [`BILINEAR_FIXED`]).
#[inline(always)]
pub(crate) fn sample_value<const MODE: u8>(run: &Run, i: usize, k: usize) -> f32 {
    match MODE {
        NEAREST => byte(run.taps[0][i], k) as f32,
        BILINEAR => lerp2(run, i, k),
        // OpenCV's sum over (32 - ay)(32 - ax) a + ..., exact in f32 (< 2^18); rounding it half
        // up gives OpenCV's (sum + 512) >> 10.
        _ => fixed_sum(run, i, k) as f32 * (1.0 / 1024.0),
    }
}

/// [`sample_value`]'s `MODE` for nearest, exact bilinear, fixed-point bilinear.
pub(crate) const NEAREST: u8 = 0;
/// See [`NEAREST`].
pub(crate) const BILINEAR: u8 = 1;
/// See [`NEAREST`].
pub(crate) const BILINEAR_FIXED: u8 = 2;

/// Channel `k` of pixel `i`, OpenCV's fixed point: `sum = (32 - ay)(32 - ax) a + ...` (the
/// value times 1024, below 2^18).
#[inline(always)]
fn fixed_sum(run: &Run, i: usize, k: usize) -> i32 {
    let [ta, tb, tc, td] = &run.taps;
    let (ax, ay) = (run.wx[i], run.wy[i]);
    let top = byte(ta[i], k) * (32 - ax) + byte(tb[i], k) * ax;
    let bottom = byte(tc[i], k) * (32 - ax) + byte(td[i], k) * ax;
    top * (32 - ay) + bottom * ay
}

/// `floor(v)` for `|v| < 2^51` as an exact `f64`, by the rounding trick (vectorises).
#[inline(always)]
fn floor_exact(v: f64) -> f64 {
    let r = round_even(v);
    if r > v {
        r - 1.0
    } else {
        r
    }
}

/// An integer-valued `f64` of magnitude below `2^31` as `i32`, from the low mantissa bits of
/// `v + 2^52 + 2^51` (no saturating conversion, so it vectorises).
#[inline(always)]
fn int_bits(v: f64) -> i32 {
    (v + ROUND_MAGIC).to_bits() as u32 as i32
}

/// The one RGB sampler: a source, `H^-1`, an interpolation, a border and a mapping.
pub(crate) struct Sampler<'a> {
    raw: &'a [u8],
    sw: usize,
    sh: usize,
    /// `raw` is a [`Padded`] image: every tap of a coordinate clamped to `[-1, size]` lies in
    /// it, so the gather has no border branch (only [`Border::Replicate`]).
    padded: bool,
    m: [f64; 9],
    interp: Interpolation,
    border: Border,
    mapping: Mapping,
    block_w: usize,
}

impl<'a> Sampler<'a> {
    /// A sampler of `src` through `h` (output pixel -> `h^-1` -> source) for an output of
    /// `out_w x out_h` (which fixes OpenCV's coordinate blocks in [`Interpolation::BilinearFixed`]).
    pub fn new(
        src: &'a RgbImage,
        h: &Homography,
        interp: Interpolation,
        border: Border,
        mapping: Mapping,
        (out_w, out_h): (u32, u32),
    ) -> Self {
        let m = inverse_rows(h);
        Self {
            raw: src.as_raw(),
            sw: src.width() as usize,
            sh: src.height() as usize,
            padded: false,
            m,
            interp,
            border,
            mapping,
            block_w: opencv_block_width(out_w as usize, out_h as usize),
        }
    }

    /// [`Sampler::new`] with [`Border::Replicate`] over a [`Padded`] copy of the source: the
    /// same samples, without the border branch in the gather.
    pub fn padded(
        src: &'a Padded,
        h: &Homography,
        interp: Interpolation,
        mapping: Mapping,
        (out_w, out_h): (u32, u32),
    ) -> Self {
        Self {
            raw: &src.raw,
            sw: src.width,
            sh: src.height,
            padded: src.width > 0 && src.height > 0,
            m: inverse_rows(h),
            interp,
            border: Border::Replicate,
            mapping,
            block_w: opencv_block_width(out_w as usize, out_h as usize),
        }
    }

    /// The interpolation this sampler uses.
    pub fn interpolation(&self) -> Interpolation {
        self.interp
    }

    /// Samples output pixels `x0 .. x0 + n` of row `y` (`n <= CHUNK`) into `run` (what
    /// [`Sampler::taps`] and [`sample_value`] give, written out for the tests).
    ///
    /// Per pixel, with `(sx, sy)` the mapped coordinate: [`Interpolation::Nearest`] reads pixel
    /// `(round_even(sx), round_even(sy))`; [`Interpolation::Bilinear`] takes `x0 = floor(sx)`,
    /// `fx = (sx - x0) as f32` (same for y) and the four taps `a b / c d` as `f32`, and gives
    /// `top + (bottom - top) * fy` with `top = a + (b - a) * fx`, `bottom = c + (d - c) * fx`;
    /// [`Interpolation::BilinearFixed`] gives `sum / 1024` of OpenCV's integer sum (see there).
    /// Taps outside read 0 ([`Border::Constant`]) or the clamped pixel ([`Border::Replicate`]).
    #[cfg(test)]
    pub fn run(&self, y: usize, x0: usize, n: usize, run: &mut Run) {
        if !self.taps(y, x0, n, run) {
            for v in &mut run.value {
                v[..n].fill(0.0);
            }
            return;
        }
        #[inline(always)]
        fn values<const MODE: u8>(run: &mut Run) {
            for k in 0..3 {
                for i in 0..CHUNK {
                    run.value[k][i] = sample_value::<MODE>(run, i, k);
                }
            }
        }
        match self.interp {
            Interpolation::Nearest => values::<NEAREST>(run),
            Interpolation::Bilinear => values::<BILINEAR>(run),
            Interpolation::BilinearFixed => values::<BILINEAR_FIXED>(run),
        }
    }

    /// The bytes of [`Sampler::run`] rounded (half up, saturating) and packed one RGB pixel per
    /// `u32` (channel `k` in byte `k`), black where the state is [`state::NONE`]: what the
    /// plain warps write.
    #[inline(always)]
    pub fn run_packed(&self, y: usize, x0: usize, n: usize, run: &mut Run, out: &mut [u32; CHUNK]) {
        if !self.taps_with::<false>(y, x0, n, run) {
            out.fill(0);
            return;
        }
        match self.interp {
            Interpolation::Nearest => {
                for i in 0..CHUNK {
                    let keep = if run.state[i] != state::NONE {
                        0xff_ffff
                    } else {
                        0
                    };
                    out[i] = run.taps[0][i] & keep;
                }
            }
            Interpolation::Bilinear => {
                for i in 0..CHUNK {
                    let keep = if run.state[i] != state::NONE { !0 } else { 0 };
                    let mut p = 0u32;
                    for k in 0..3 {
                        // A bilinear blend stays in [0, 255]: each step of `lerp2` lies between its
                        // operands, whose bounds are representable.
                        p |= round_u8_in_range(lerp2(run, i, k)) << (8 * k);
                    }
                    out[i] = p & keep;
                }
            }
            Interpolation::BilinearFixed => {
                // Every pixel has a sample; the sum is below 2^18, so (sum + 512) >> 10 <= 255.
                for i in 0..CHUNK {
                    let mut p = 0u32;
                    for k in 0..3 {
                        p |= (((fixed_sum(run, i, k) + 512) >> 10) as u32) << (8 * k);
                    }
                    out[i] = p;
                }
            }
        }
    }

    /// Coordinates, states, weights and taps of a run; false (and states NONE) for an empty
    /// source. [`sample_value`] then gives the values of [`Sampler::run`].
    #[inline(always)]
    pub fn taps(&self, y: usize, x0: usize, n: usize, run: &mut Run) -> bool {
        self.taps_with::<true>(y, x0, n, run)
    }

    /// [`Sampler::taps`]; without `INSIDE` the states only tell [`state::NONE`] from a sample
    /// ([`state::OUTSIDE`] for every sample), which is all the plain warps need.
    #[inline(always)]
    fn taps_with<const INSIDE: bool>(&self, y: usize, x0: usize, n: usize, run: &mut Run) -> bool {
        debug_assert!(n <= CHUNK);
        if self.sw == 0 || self.sh == 0 {
            run.state[..n].fill(state::NONE);
            return false;
        }
        match self.interp {
            Interpolation::BilinearFixed => self.coords_fixed::<INSIDE>(y, x0, run),
            Interpolation::Nearest => self.coords_float::<true, INSIDE>(y, x0, run),
            Interpolation::Bilinear => self.coords_float::<false, INSIDE>(y, x0, run),
        }
        self.gather(n, run, self.interp != Interpolation::Nearest);
        true
    }

    #[inline(always)]
    fn coords_float<const NEAREST: bool, const INSIDE: bool>(
        &self,
        y: usize,
        x0: usize,
        run: &mut Run,
    ) {
        self.map_into(y, x0, run);
        self.classify::<NEAREST, INSIDE>(run);
    }

    /// The source coordinates of output pixels `x0 .. x0 + CHUNK` of row `y` into `run.sx`,
    /// `run.sy` (the sampler's mapping).
    #[inline(always)]
    pub fn map_into(&self, y: usize, x0: usize, run: &mut Run) {
        match self.mapping {
            Mapping::Reciprocal => map_reciprocal(&self.m, y, x0, &mut run.sx, &mut run.sy),
            Mapping::Division => map_division(&self.m, y, x0, &mut run.sx, &mut run.sy),
        }
    }

    /// [`Sampler::taps`] (exact bilinear or nearest) at the coordinates the caller put in
    /// `run.sx`, `run.sy` (the morph's traced points) instead of the mapped ones.
    #[inline(always)]
    pub fn taps_at(&self, n: usize, run: &mut Run) -> bool {
        debug_assert!(n <= CHUNK);
        if self.sw == 0 || self.sh == 0 {
            run.state[..n].fill(state::NONE);
            return false;
        }
        match self.interp {
            Interpolation::Nearest => self.classify::<true, true>(run),
            _ => self.classify::<false, true>(run),
        }
        self.gather(n, run, self.interp != Interpolation::Nearest);
        true
    }

    /// States, clamped integer coordinates and fractions of the coordinates in `run.sx`, `run.sy`.
    #[inline(always)]
    fn classify<const NEAREST: bool, const INSIDE: bool>(&self, run: &mut Run) {
        let (swf, shf) = (self.sw as f64, self.sh as f64);
        let limit = match self.mapping {
            Mapping::Reciprocal => 1e9,
            Mapping::Division => f64::MAX,
        };
        // States, then coordinates clamped to [-1, w] (which changes no sample: beyond it every
        // tap is outside, or the same clamped edge pixel), floored (bilinear) or rounded.
        for i in 0..CHUNK {
            let (sx, sy) = (run.sx[i], run.sy[i]);
            let valid = sx.abs() <= limit && sy.abs() <= limit;
            let inside = INSIDE && sx >= -0.5 && sy >= -0.5 && sx < swf - 0.5 && sy < shf - 0.5;
            run.state[i] = if !valid {
                state::NONE
            } else if inside {
                state::INSIDE
            } else {
                state::OUTSIDE
            };
            let (cx, cy) = (clamp_nan_lo(sx, -1.0, swf), clamp_nan_lo(sy, -1.0, shf));
            let (bx, by) = if NEAREST {
                (round_even(cx), round_even(cy))
            } else {
                (floor_exact(cx), floor_exact(cy))
            };
            run.ix[i] = int_bits(bx);
            run.iy[i] = int_bits(by);
            if !NEAREST {
                run.fx[i] = (cx - bx) as f32;
                run.fy[i] = (cy - by) as f32;
            }
        }
    }

    #[inline(always)]
    fn coords_fixed<const INSIDE: bool>(&self, y: usize, x0: usize, run: &mut Run) {
        map_fixed(&self.m, y, x0, self.block_w, &mut run.ix, &mut run.iy);
        let (swq, shq) = (self.sw as i32 * 32 - 16, self.sh as i32 * 32 - 16);
        for i in 0..CHUNK {
            let (qx, qy) = (run.ix[i], run.iy[i]);
            let inside = INSIDE && qx >= -16 && qy >= -16 && qx < swq && qy < shq;
            run.state[i] = if inside {
                state::INSIDE
            } else {
                state::OUTSIDE
            };
            // saturate_cast<short>(X >> INTER_BITS), and the fraction X & 31. A padded
            // (replicated) source takes the block clamped to [-1, size]: beyond, both taps of a
            // side are the same edge pixel either way.
            let (lx, ly, hx, hy) = if self.padded {
                (-1, -1, self.sw as i32, self.sh as i32)
            } else {
                (-32768, -32768, 32767, 32767)
            };
            run.ix[i] = (qx >> 5).clamp(-32768, 32767).clamp(lx, hx);
            run.iy[i] = (qy >> 5).clamp(-32768, 32767).clamp(ly, hy);
            run.wx[i] = qx & 31;
            run.wy[i] = qy & 31;
        }
    }

    /// Loads the taps of pixels `0..n` (`ix`, `iy` set) into `run.taps`: the pixel itself
    /// (`block` false) or the 2x2 block to its lower right. The interior is two unaligned
    /// 8-byte reads; the border goes through [`Sampler::tap`].
    #[inline(always)]
    fn gather(&self, n: usize, run: &mut Run, block: bool) {
        if self.padded {
            self.gather_padded(run, block);
            return;
        }
        let stride = self.sw * 3;
        let (wi, hi) = (self.sw as u32 - 1, self.sh as u32 - 1);
        let len = self.raw.len();
        let read8 =
            |at: usize| u64::from_le_bytes(self.raw[at..at + 8].try_into().expect("8 bytes"));
        let pack = |p: [u8; 3]| u32::from_le_bytes([p[0], p[1], p[2], 0]);
        let [ta, tb, tc, td] = &mut run.taps;
        for i in 0..n {
            let (x, y) = (run.ix[i], run.iy[i]);
            let a = (y as usize)
                .wrapping_mul(stride)
                .wrapping_add((x as usize).wrapping_mul(3));
            if !block {
                ta[i] = if (x as u32) <= wi && (y as u32) <= hi && a + 8 <= len {
                    read8(a) as u32
                } else {
                    pack(self.tap(x, y))
                };
                continue;
            }
            if (x as u32) < wi && (y as u32) < hi && a + stride + 8 <= len {
                let (u, l) = (read8(a), read8(a + stride));
                ta[i] = u as u32;
                tb[i] = (u >> 24) as u32;
                tc[i] = l as u32;
                td[i] = (l >> 24) as u32;
            } else {
                ta[i] = pack(self.tap(x, y));
                tb[i] = pack(self.tap(x + 1, y));
                tc[i] = pack(self.tap(x, y + 1));
                td[i] = pack(self.tap(x + 1, y + 1));
            }
        }
    }

    /// [`Sampler::gather`] from a [`Padded`] source: coordinates are in `[-1, size]`, so every
    /// tap is inside the padded image and each pixel is two 8-byte reads, no branch (the
    /// length check never fails; it keeps the reads checked without a panic path). Runs over
    /// the whole [`CHUNK`] (lanes past `n` read valid, unused pixels).
    #[inline(always)]
    fn gather_padded(&self, run: &mut Run, block: bool) {
        let stride = (self.sw + PAD) * 3;
        let raw = self.raw;
        let [ta, tb, tc, td] = &mut run.taps;
        for i in 0..CHUNK {
            // (x + 1, y + 1) in the padded image, both in [0, size + 1].
            let (x, y) = ((run.ix[i] + 1) as usize, (run.iy[i] + 1) as usize);
            let a = y * stride + x * 3;
            let (u, l) = match (raw.get(a..a + 8), raw.get(a + stride..a + stride + 8)) {
                (Some(u), Some(l)) => (
                    u64::from_le_bytes(u.try_into().expect("8 bytes")),
                    u64::from_le_bytes(l.try_into().expect("8 bytes")),
                ),
                _ => (0, 0),
            };
            ta[i] = u as u32;
            if block {
                tb[i] = (u >> 24) as u32;
                tc[i] = l as u32;
                td[i] = (l >> 24) as u32;
            }
        }
    }

    /// One source pixel with the border rule.
    #[inline(always)]
    fn tap(&self, x: i32, y: i32) -> [u8; 3] {
        let (x, y) = match self.border {
            Border::Constant => {
                if x < 0 || y < 0 || x as usize >= self.sw || y as usize >= self.sh {
                    return [0; 3];
                }
                (x as usize, y as usize)
            }
            Border::Replicate => (
                x.clamp(0, self.sw as i32 - 1) as usize,
                y.clamp(0, self.sh as i32 - 1) as usize,
            ),
        };
        let i = (y * self.sw + x) * 3;
        [self.raw[i], self.raw[i + 1], self.raw[i + 2]]
    }
}

/// Columns and rows a [`Padded`] image adds (one before, two after each side).
const PAD: usize = 3;

/// An RGB image with its edge replicated one pixel before and two after each side, and 8 spare
/// bytes: what a [`Sampler::padded`] reads. Made once per source (the renderer keeps one per
/// view), so the per-frame gather needs no border test.
#[derive(Debug, Clone, Default)]
pub(crate) struct Padded {
    raw: Vec<u8>,
    width: usize,
    height: usize,
}

impl Padded {
    /// The padded copy of `src`.
    pub fn new(src: &RgbImage) -> Self {
        let (w, h) = (src.width() as usize, src.height() as usize);
        if w == 0 || h == 0 {
            return Self {
                raw: Vec::new(),
                width: w,
                height: h,
            };
        }
        let stride = (w + PAD) * 3;
        let mut raw = vec![0u8; (h + PAD) * stride + 8];
        let s = src.as_raw();
        for py in 0..h + PAD {
            let y = py.saturating_sub(1).min(h - 1);
            let row = &s[y * w * 3..(y + 1) * w * 3];
            let out = &mut raw[py * stride..(py + 1) * stride];
            out[3..3 + w * 3].copy_from_slice(row);
            for px in [0, w + 1, w + 2] {
                let x = px.saturating_sub(1).min(w - 1);
                out[px * 3..px * 3 + 3].copy_from_slice(&row[x * 3..x * 3 + 3]);
            }
        }
        Self {
            raw,
            width: w,
            height: h,
        }
    }
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

#[cfg(test)]
mod tests {
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
                Interpolation::Nearest => {
                    px(sx.round_ties_even() as i64, sy.round_ties_even() as i64)
                }
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
    fn reference_fixed(
        src: &RgbImage,
        h: &Homography,
        w: u32,
        hgt: u32,
        border: Border,
    ) -> RgbImage {
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
}
