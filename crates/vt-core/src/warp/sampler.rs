//! RGB sampling shared by the plain warps and the renderer's blend: interpolations, borders, runs of CHUNK pixels.

use super::*;

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
    /// value range (a speed/accuracy knob, measured in docs/measuring.md).
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
pub(super) fn int_bits(v: f64) -> i32 {
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
