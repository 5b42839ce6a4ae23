//! 4:2:0 frames as video decoders hold them, and their conversion to RGB.
//!
//! A [`Yuv420Image`] is planar: the luma plane (`width * height` bytes), then the U and V planes
//! at half width and half height, one chroma sample per 2x2 block of pixels. It takes half the
//! memory of the same frame in RGB, so the analysis keeps video frames in this form between its
//! two passes (twice as many frames fit its cache) and converts a frame when it needs its pixels.
//!
//! Conversion is fixed point with 20 fractional bits, each chroma sample shared by its 2x2 block
//! (no chroma interpolation). For BT.601 limited range the constants and rounding are OpenCV's
//! (`COLOR_YUV2RGB_I420`: 1.164, 1.596, -0.391, -0.813, 2.018), so the result is byte for byte
//! OpenCV's (cross-checked in vt-cv); BT.709 and full range use the same arithmetic with their
//! own constants. ffmpeg's fast unscaled converter, which `-pix_fmt rgb24` uses, is less exact:
//! it differs from this by about one grey level on average.

use image::RgbImage;
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The colour matrix of a YUV frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum YuvMatrix {
    /// ITU-R BT.601 (SD video, and what decoders assume when a file does not say).
    #[default]
    Bt601,
    /// ITU-R BT.709 (HD video).
    Bt709,
}

/// The value range of a YUV frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum YuvRange {
    /// Y in 16..=235, U and V in 16..=240 ("tv", "mpeg"; the usual one).
    #[default]
    Limited,
    /// Y, U and V in 0..=255 ("pc", "jpeg").
    Full,
}

/// A planar 4:2:0 frame (even width and height).
#[derive(Clone, PartialEq, Eq)]
pub struct Yuv420Image {
    width: u32,
    height: u32,
    matrix: YuvMatrix,
    range: YuvRange,
    data: Vec<u8>,
}

impl std::fmt::Debug for Yuv420Image {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Yuv420Image")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("matrix", &self.matrix)
            .field("range", &self.range)
            .finish_non_exhaustive()
    }
}

impl Yuv420Image {
    /// Bytes of a `width x height` frame: `w * h * 3 / 2`.
    pub fn byte_len(width: u32, height: u32) -> usize {
        let n = width as usize * height as usize;
        n + n / 2
    }

    /// A frame of all zero bytes (a buffer to read into).
    pub fn new(width: u32, height: u32, matrix: YuvMatrix, range: YuvRange) -> Result<Self> {
        Self::from_raw(
            width,
            height,
            matrix,
            range,
            vec![0; Self::byte_len(width, height)],
        )
    }

    /// Wraps planar bytes (Y, then U, then V). Width and height must be even and non-zero, and
    /// `data` exactly [`Yuv420Image::byte_len`] long.
    pub fn from_raw(
        width: u32,
        height: u32,
        matrix: YuvMatrix,
        range: YuvRange,
        data: Vec<u8>,
    ) -> Result<Self> {
        if width == 0 || height == 0 || width % 2 == 1 || height % 2 == 1 {
            return Err(Error::InvalidParameter {
                name: "yuv420 size",
                value: format!("{width}x{height}"),
                why: "4:2:0 frames need an even, non-zero width and height".into(),
            });
        }
        let need = Self::byte_len(width, height);
        if data.len() != need {
            return Err(Error::InvalidParameter {
                name: "yuv420 data",
                value: format!("{} bytes", data.len()),
                why: format!("a {width}x{height} 4:2:0 frame has {need} bytes"),
            });
        }
        Ok(Self {
            width,
            height,
            matrix,
            range,
            data,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// `(width, height)`.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The colour matrix.
    pub fn matrix(&self) -> YuvMatrix {
        self.matrix
    }

    /// The value range.
    pub fn range(&self) -> YuvRange {
        self.range
    }

    /// The planar bytes.
    pub fn as_raw(&self) -> &[u8] {
        &self.data
    }

    /// The planar bytes, to fill in place (a decoder reading into a reused frame).
    pub fn as_raw_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// Takes the planar bytes back (to reuse the buffer).
    pub fn into_raw(self) -> Vec<u8> {
        self.data
    }

    /// The frame in RGB.
    pub fn to_rgb(&self) -> RgbImage {
        let mut out = RgbImage::new(self.width, self.height);
        self.to_rgb_into(&mut out);
        out
    }

    /// Converts into `out`, resized to this frame's size if it differs.
    pub fn to_rgb_into(&self, out: &mut RgbImage) {
        if out.dimensions() != self.dimensions() {
            *out = RgbImage::new(self.width, self.height);
        }
        let c = Coefficients::of(self.matrix, self.range);
        let (w, h) = (self.width as usize, self.height as usize);
        let (y_plane, chroma) = self.data.split_at(w * h);
        let (u_plane, v_plane) = chroma.split_at(w * h / 4);
        let cw = w / 2;
        // Two output rows share a chroma row.
        for (row_pair, (ys, rgb)) in y_plane
            .chunks_exact(2 * w)
            .zip(out.chunks_exact_mut(6 * w))
            .enumerate()
        {
            let us = &u_plane[row_pair * cw..(row_pair + 1) * cw];
            let vs = &v_plane[row_pair * cw..(row_pair + 1) * cw];
            let (y0, y1) = ys.split_at(w);
            let (r0, r1) = rgb.split_at_mut(3 * w);
            convert_row(&c, y0, us, vs, r0);
            convert_row(&c, y1, us, vs, r1);
        }
    }
}

impl Yuv420Image {
    /// Pixel `(x, y)` in RGB, byte for byte what [`Yuv420Image::to_rgb_into`] gives there (for
    /// readers that need a few pixels of many frames, not whole frames).
    #[inline(always)]
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let (w, h) = (self.width as usize, self.height as usize);
        let (x, y) = (x as usize, y as usize);
        let chroma = w * h + (y / 2) * (w / 2) + x / 2;
        yuv_to_rgb(
            self.matrix,
            self.range,
            self.data[y * w + x],
            self.data[chroma],
            self.data[chroma + w * h / 4],
        )
    }

    /// Converts pixels `x0..x1` of row `y` into `out` (`3 * (x1 - x0)` bytes), byte for byte
    /// what [`Yuv420Image::pixel`] gives there; `x0` and `x1` even (whole chroma samples).
    pub fn segment_to_rgb(&self, y: u32, x0: u32, x1: u32, out: &mut [u8]) {
        debug_assert!(x0.is_multiple_of(2) && x1.is_multiple_of(2) && x0 <= x1 && x1 <= self.width);
        let c = Coefficients::of(self.matrix, self.range);
        let (w, h) = (self.width as usize, self.height as usize);
        let (y, x0, x1) = (y as usize, x0 as usize, x1 as usize);
        let chroma = w * h + (y / 2) * (w / 2);
        let (c0, c1) = (chroma + x0 / 2, chroma + x1 / 2);
        convert_row(
            &c,
            &self.data[y * w + x0..y * w + x1],
            &self.data[c0..c1],
            &self.data[c0 + w * h / 4..c1 + w * h / 4],
            &mut out[..3 * (x1 - x0)],
        );
    }

    /// Converts row `y` into `out` (`3 * width` bytes).
    pub fn row_to_rgb(&self, y: u32, out: &mut [u8]) {
        let c = Coefficients::of(self.matrix, self.range);
        let (w, h) = (self.width as usize, self.height as usize);
        let (y, cw) = (y as usize, w / 2);
        let chroma = w * h + (y / 2) * cw;
        let (us, vs) = (
            &self.data[chroma..chroma + cw],
            &self.data[chroma + w * h / 4..chroma + w * h / 4 + cw],
        );
        convert_row(
            &c,
            &self.data[y * w..(y + 1) * w],
            us,
            vs,
            &mut out[..3 * w],
        );
    }
}

/// Fixed-point conversion constants, 20 fractional bits.
struct Coefficients {
    /// Luma scale.
    cy: i32,
    /// Luma offset subtracted first (16 for limited range).
    y_offset: i32,
    cvr: i32,
    cug: i32,
    cvg: i32,
    cub: i32,
}

const SHIFT: u32 = 20;

impl Coefficients {
    fn of(matrix: YuvMatrix, range: YuvRange) -> Self {
        let fix = |v: f64| (v * (1 << SHIFT) as f64).round() as i32;
        match (matrix, range) {
            // OpenCV's ITUR_BT_601_* constants, exactly.
            (YuvMatrix::Bt601, YuvRange::Limited) => Self {
                cy: 1_220_542,
                y_offset: 16,
                cvr: 1_673_527,
                cug: -409_993,
                cvg: -852_492,
                cub: 2_116_026,
            },
            (YuvMatrix::Bt709, YuvRange::Limited) => Self {
                cy: 1_220_542,
                y_offset: 16,
                cvr: fix(1.793),
                cug: fix(-0.213),
                cvg: fix(-0.533),
                cub: fix(2.112),
            },
            (YuvMatrix::Bt601, YuvRange::Full) => Self {
                cy: 1 << SHIFT,
                y_offset: 0,
                cvr: fix(1.402),
                cug: fix(-0.344_136),
                cvg: fix(-0.714_136),
                cub: fix(1.772),
            },
            (YuvMatrix::Bt709, YuvRange::Full) => Self {
                cy: 1 << SHIFT,
                y_offset: 0,
                cvr: fix(1.5748),
                cug: fix(-0.187_324),
                cvg: fix(-0.468_124),
                cub: fix(1.8556),
            },
        }
    }
}

/// One pixel's luma and chroma in RGB, as the row conversion makes it.
#[inline(always)]
pub(crate) fn yuv_to_rgb(matrix: YuvMatrix, range: YuvRange, y: u8, u: u8, v: u8) -> [u8; 3] {
    let c = Coefficients::of(matrix, range);
    let (uu, vv) = (u as i32 - 128, v as i32 - 128);
    let yy = (y as i32 - c.y_offset).max(0) * c.cy + (1 << (SHIFT - 1));
    [
        clamp_u8((yy + c.cvr * vv) >> SHIFT),
        clamp_u8((yy + c.cvg * vv + c.cug * uu) >> SHIFT),
        clamp_u8((yy + c.cub * uu) >> SHIFT),
    ]
}

#[inline(always)]
fn clamp_u8(v: i32) -> u8 {
    v.clamp(0, 255) as u8
}

/// One row: `ys` luma, `us`/`vs` its chroma row (half width), `rgb` the output row.
#[inline]
fn convert_row(c: &Coefficients, ys: &[u8], us: &[u8], vs: &[u8], rgb: &mut [u8]) {
    crate::simd::dispatch(RowKernel { c, ys, us, vs, rgb });
}

struct RowKernel<'a> {
    c: &'a Coefficients,
    ys: &'a [u8],
    us: &'a [u8],
    vs: &'a [u8],
    rgb: &'a mut [u8],
}

/// Pixels per block: fixed-size arrays the compiler turns into vector registers.
const BLOCK: usize = 16;

impl crate::simd::Kernel for RowKernel<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let c = self.c;
        let half = 1 << (SHIFT - 1);
        let w = self.ys.len();
        let blocks = w / BLOCK;
        for (((yb, ub), vb), ob) in self
            .ys
            .chunks_exact(BLOCK)
            .zip(self.us.chunks_exact(BLOCK / 2))
            .zip(self.vs.chunks_exact(BLOCK / 2))
            .zip(self.rgb.chunks_exact_mut(3 * BLOCK))
        {
            let (mut r, mut g, mut b) = ([0u8; BLOCK], [0u8; BLOCK], [0u8; BLOCK]);
            for k in 0..BLOCK {
                let (uu, vv) = (ub[k / 2] as i32 - 128, vb[k / 2] as i32 - 128);
                let y = (yb[k] as i32 - c.y_offset).max(0) * c.cy + half;
                r[k] = clamp_u8((y + c.cvr * vv) >> SHIFT);
                g[k] = clamp_u8((y + c.cvg * vv + c.cug * uu) >> SHIFT);
                b[k] = clamp_u8((y + c.cub * uu) >> SHIFT);
            }
            for k in 0..BLOCK {
                ob[3 * k] = r[k];
                ob[3 * k + 1] = g[k];
                ob[3 * k + 2] = b[k];
            }
        }
        // The last pixels, two at a time (the width is even).
        let done = blocks * BLOCK;
        for (((y2, &u), &v), out) in self.ys[done..]
            .chunks_exact(2)
            .zip(&self.us[done / 2..])
            .zip(&self.vs[done / 2..])
            .zip(self.rgb[3 * done..].chunks_exact_mut(6))
        {
            let (uu, vv) = (u as i32 - 128, v as i32 - 128);
            let ruv = half + c.cvr * vv;
            let guv = half + c.cvg * vv + c.cug * uu;
            let buv = half + c.cub * uu;
            for k in 0..2 {
                let y = (y2[k] as i32 - c.y_offset).max(0) * c.cy;
                out[3 * k] = clamp_u8((y + ruv) >> SHIFT);
                out[3 * k + 1] = clamp_u8((y + guv) >> SHIFT);
                out[3 * k + 2] = clamp_u8((y + buv) >> SHIFT);
            }
        }
    }
}

/// One row of a full-range BT.601 4:2:0 picture (JPEG's matrix, the object store's pixels) to
/// RGB where `mask` is non-zero, and 0 elsewhere, in 16-bit fixed point (JPEG's coefficients
/// times 2^16, rounded; integer, so every machine gives the same bytes):
/// `r = (y 2^16 + 91881 v + 2^15) >> 16` and so on, with `u`, `v` centred on 128. Chroma is each
/// 2x2 block's own sample
/// (nearest, not interpolated: on tree.avi, whose own chroma is per 2x2 block, bilinear
/// upsampling lost 2.9 dB).
///
/// `ys` is the row's luma from the first pixel on; `us` and `vs` its chroma row from the first
/// pixel's block on (`odd`: the first pixel is the right one of its block, so it shares the
/// block with no other pixel of the row). `mask` and `rgb` (3 bytes a pixel) have `ys`'s
/// length. Panics when the chroma rows are too short.
pub fn masked_full_range_row_to_rgb(
    ys: &[u8],
    us: &[u8],
    vs: &[u8],
    odd: bool,
    mask: &[u8],
    rgb: &mut [u8],
) {
    let n = ys.len();
    assert!(
        mask.len() == n
            && rgb.len() == 3 * n
            && us.len().min(vs.len()) >= (n + odd as usize).div_ceil(2),
        "row lengths"
    );
    if n == 0 {
        return;
    }
    if odd {
        let px = store_pixel(ys[0], us[0], vs[0], mask[0]);
        rgb[..3].copy_from_slice(&px);
        masked_full_range_row_to_rgb(
            &ys[1..],
            &us[1..],
            &vs[1..],
            false,
            &mask[1..],
            &mut rgb[3..],
        );
        return;
    }
    crate::simd::dispatch(MaskedRowKernel {
        ys,
        us,
        vs,
        mask,
        rgb,
    });
}

/// The store's conversion of one pixel (see [`masked_full_range_row_to_rgb`]), 0 where `m` is 0.
#[inline(always)]
fn store_pixel(y: u8, u: u8, v: u8, m: u8) -> [u8; 3] {
    let (y, u, v) = (
        ((y as i32) << 16) + (1 << 15),
        u as i32 - 128,
        v as i32 - 128,
    );
    let c = |x: i32| if m != 0 { clamp_u8(x >> 16) } else { 0 };
    [
        c(y + 91_881 * v),
        c(y - 22_554 * u - 46_802 * v),
        c(y + 116_130 * u),
    ]
}

/// [`masked_full_range_row_to_rgb`] from an even first pixel, as a [`crate::simd::Kernel`].
struct MaskedRowKernel<'a> {
    ys: &'a [u8],
    us: &'a [u8],
    vs: &'a [u8],
    mask: &'a [u8],
    rgb: &'a mut [u8],
}

impl crate::simd::Kernel for MaskedRowKernel<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let MaskedRowKernel {
            ys,
            us,
            vs,
            mask,
            rgb,
        } = self;
        let blocks = ys.len() / BLOCK;
        for ((((yb, ub), vb), mb), ob) in ys
            .chunks_exact(BLOCK)
            .zip(us.chunks_exact(BLOCK / 2))
            .zip(vs.chunks_exact(BLOCK / 2))
            .zip(mask.chunks_exact(BLOCK))
            .zip(rgb.chunks_exact_mut(3 * BLOCK))
        {
            // Each pixel as one little-endian word `r | g << 8 | b << 16`, stored 4 bytes at a
            // time 3 bytes apart (the next pixel's store overwrites the spare byte): a third of
            // the stores of byte-wise interleaving.
            let mut px = [0u32; BLOCK];
            for k in 0..BLOCK {
                let [r, g, b] = store_pixel(yb[k], ub[k / 2], vb[k / 2], mb[k]);
                px[k] = r as u32 | (g as u32) << 8 | (b as u32) << 16;
            }
            for k in 0..BLOCK - 1 {
                ob[3 * k..3 * k + 4].copy_from_slice(&px[k].to_le_bytes());
            }
            ob[3 * BLOCK - 3..].copy_from_slice(&px[BLOCK - 1].to_le_bytes()[..3]);
        }
        for i in blocks * BLOCK..ys.len() {
            let px = store_pixel(ys[i], us[i / 2], vs[i / 2], mask[i]);
            rgb[3 * i..3 * i + 3].copy_from_slice(&px);
        }
    }
}

/// One row's luma for [`ToYuvKernel`], in blocks of [`BLOCK`] pixels: the channels split into
/// arrays first, so the sums vectorise. A function, not a closure, so that it is inlined into
/// the dispatched kernel.
#[inline(always)]
fn to_luma(src: &[u8], dst: &mut [u8]) {
    const HALF: i32 = 1 << 15;
    // 0.299, 0.587, 0.114 (x 2^16): at most 255 x 2^16 in all, so no clamp.
    const Y: [i32; 3] = [19595, 38470, 7471];
    for (p, y) in src.chunks_exact(3 * BLOCK).zip(dst.chunks_exact_mut(BLOCK)) {
        let p: &[u8; 3 * BLOCK] = p.try_into().expect("a block");
        let y: &mut [u8; BLOCK] = y.try_into().expect("a block");
        for k in 0..BLOCK {
            let v =
                Y[0] * p[3 * k] as i32 + Y[1] * p[3 * k + 1] as i32 + Y[2] * p[3 * k + 2] as i32;
            y[k] = ((v + HALF) >> 16) as u8;
        }
    }
    let done = src.len() / (3 * BLOCK) * BLOCK;
    for (p, y) in src[3 * done..].chunks_exact(3).zip(&mut dst[done..]) {
        let v = Y[0] * p[0] as i32 + Y[1] * p[1] as i32 + Y[2] * p[2] as i32;
        *y = ((v + HALF) >> 16) as u8;
    }
}

/// RGB to full-range BT.601 4:2:0, the object store's pictures (JPEG's matrix, all 256 levels:
/// a limited range would cost a quantisation of its own): luma per pixel, chroma from each 2x2
/// block's mean colour. `rgb` is `width` x `height` with even sides; `out` gets the Y, U and V
/// planes. Integer arithmetic with the coefficients in 1/2^16 (each level within one of the
/// exact matrix's rounding), two rows at a time through [`crate::simd::dispatch`]; the inverse
/// is [`masked_full_range_row_to_rgb`]. Panics when `rgb` is not `width` x `height` or a
/// side is odd.
pub fn rgb_to_full_range_yuv420(rgb: &[u8], width: usize, height: usize, out: &mut Vec<u8>) {
    assert!(
        rgb.len() == 3 * width * height && width.is_multiple_of(2) && height.is_multiple_of(2),
        "an RGB picture of even sides"
    );
    let (cw, ch) = (width / 2, height / 2);
    out.clear();
    out.resize(width * height + 2 * cw * ch, 0);
    let (luma, chroma) = out.split_at_mut(width * height);
    let (u_plane, v_plane) = chroma.split_at_mut(cw * ch);
    let stride = 3 * width;
    for (((rows, l), us), vs) in rgb
        .chunks_exact(2 * stride.max(1))
        .zip(luma.chunks_exact_mut(2 * width.max(1)))
        .zip(u_plane.chunks_exact_mut(cw.max(1)))
        .zip(v_plane.chunks_exact_mut(cw.max(1)))
    {
        crate::simd::dispatch(ToYuvKernel { rows, l, us, vs });
    }
}

/// Two rows of [`rgb_to_full_range_yuv420`]: `rows` their RGB, `l` their luma, `us` and `vs`
/// their chroma row.
struct ToYuvKernel<'a> {
    rows: &'a [u8],
    l: &'a mut [u8],
    us: &'a mut [u8],
    vs: &'a mut [u8],
}

impl crate::simd::Kernel for ToYuvKernel<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        const S: i32 = 16;
        const HALF: i32 = 1 << (S - 1);
        // -0.168736, -0.331264, 0.5; 0.5, -0.418688, -0.081312 (x 2^16).
        const U: [i32; 3] = [-11058, -21710, 32768];
        const V: [i32; 3] = [32768, -27440, -5328];
        let ToYuvKernel { rows, l, us, vs } = self;
        let stride = rows.len() / 2;
        let (r0, r1) = rows.split_at(stride);
        let (l0, l1) = l.split_at_mut(stride / 3);
        to_luma(r0, l0);
        to_luma(r1, l1);
        // Sums of each block's four pixels per channel: the mean is the sum / 4, folded into
        // the shift.
        #[inline(always)]
        fn round(c: i32) -> u8 {
            (((c + (HALF << 2)) >> (S + 2)) + 128).clamp(0, 255) as u8
        }
        const HB: usize = BLOCK / 2;
        let full = us.len() / HB * HB;
        for (((a, b), u), v) in r0
            .chunks_exact(6 * HB)
            .zip(r1.chunks_exact(6 * HB))
            .zip(us.chunks_exact_mut(HB))
            .zip(vs.chunks_exact_mut(HB))
        {
            let a: &[u8; 6 * HB] = a.try_into().expect("a block");
            let b: &[u8; 6 * HB] = b.try_into().expect("a block");
            let u: &mut [u8; HB] = u.try_into().expect("a block");
            let v: &mut [u8; HB] = v.try_into().expect("a block");
            let mut m = [[0i32; HB]; 3];
            for k in 0..HB {
                for (c, mc) in m.iter_mut().enumerate() {
                    mc[k] = a[6 * k + c] as i32
                        + a[6 * k + 3 + c] as i32
                        + b[6 * k + c] as i32
                        + b[6 * k + 3 + c] as i32;
                }
            }
            for k in 0..HB {
                u[k] = round(U[0] * m[0][k] + U[1] * m[1][k] + U[2] * m[2][k]);
                v[k] = round(V[0] * m[0][k] + V[1] * m[1][k] + V[2] * m[2][k]);
            }
        }
        for (((a, b), u), v) in r0[6 * full..]
            .chunks_exact(6)
            .zip(r1[6 * full..].chunks_exact(6))
            .zip(&mut us[full..])
            .zip(&mut vs[full..])
        {
            let m =
                [0, 1, 2].map(|k| a[k] as i32 + a[k + 3] as i32 + b[k] as i32 + b[k + 3] as i32);
            *u = round(U[0] * m[0] + U[1] * m[1] + U[2] * m[2]);
            *v = round(V[0] * m[0] + V[1] * m[1] + V[2] * m[2]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn rgb_to_store_yuv_is_the_full_range_matrix() {
        // Every level within one of the exact matrix, rounded (corners of the cube included); 38
        // pixels a row: two blocks and a tail.
        for (w, h) in [(10usize, 6usize), (38, 4)] {
            check_to_yuv(w, h);
        }
    }

    fn check_to_yuv(w: usize, h: usize) {
        let mut rng = Rng::new(7);
        let mut rgb: Vec<u8> = (0..3 * w * h).map(|_| rng.next_u64() as u8).collect();
        rgb[..6].copy_from_slice(&[255, 255, 255, 0, 0, 0]);
        rgb[3 * w..3 * w + 6].copy_from_slice(&[255, 0, 0, 0, 0, 255]);
        let mut out = Vec::new();
        rgb_to_full_range_yuv420(&rgb, w, h, &mut out);
        assert_eq!(out.len(), w * h * 3 / 2);
        let near = |got: u8, want: f64, what: &str| {
            assert!(
                (got as f64 - want.clamp(0.0, 255.0)).abs() <= 1.0,
                "{what}: {got} vs {want}"
            );
        };
        for i in 0..w * h {
            let p = &rgb[3 * i..3 * i + 3];
            let y = 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64;
            near(out[i], y, &format!("Y {i}"));
        }
        for cy in 0..h / 2 {
            for cx in 0..w / 2 {
                let mut m = [0f64; 3];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    for k in 0..3 {
                        m[k] += 0.25 * rgb[3 * ((2 * cy + dy) * w + 2 * cx + dx) + k] as f64;
                    }
                }
                let u = 128.0 - 0.168_736 * m[0] - 0.331_264 * m[1] + 0.5 * m[2];
                let v = 128.0 + 0.5 * m[0] - 0.418_688 * m[1] - 0.081_312 * m[2];
                let c = cy * w / 2 + cx;
                near(out[w * h + c], u, &format!("U {c}"));
                near(out[w * h + w * h / 4 + c], v, &format!("V {c}"));
            }
        }
    }

    fn random(w: u32, h: u32, matrix: YuvMatrix, range: YuvRange, seed: u64) -> Yuv420Image {
        let mut rng = Rng::new(seed);
        let data = (0..Yuv420Image::byte_len(w, h))
            .map(|_| rng.next_u64() as u8)
            .collect();
        Yuv420Image::from_raw(w, h, matrix, range, data).unwrap()
    }

    /// The textbook formula in f64, chroma shared by each 2x2 block.
    fn reference(img: &Yuv420Image) -> RgbImage {
        let (w, h) = (img.width as usize, img.height as usize);
        let d = img.as_raw();
        let (scale, off, m) = match (img.matrix, img.range) {
            (YuvMatrix::Bt601, YuvRange::Limited) => (1.164, 16.0, [1.596, -0.391, -0.813, 2.018]),
            (YuvMatrix::Bt709, YuvRange::Limited) => (1.164, 16.0, [1.793, -0.213, -0.533, 2.112]),
            (YuvMatrix::Bt601, YuvRange::Full) => {
                (1.0, 0.0, [1.402, -0.344_136, -0.714_136, 1.772])
            }
            (YuvMatrix::Bt709, YuvRange::Full) => {
                (1.0, 0.0, [1.5748, -0.187_324, -0.468_124, 1.8556])
            }
        };
        RgbImage::from_fn(img.width, img.height, |x, y| {
            let (x, y) = (x as usize, y as usize);
            let yy = scale * (d[y * w + x] as f64 - off).max(0.0);
            let ci = (y / 2) * (w / 2) + x / 2;
            let u = d[w * h + ci] as f64 - 128.0;
            let v = d[w * h + w * h / 4 + ci] as f64 - 128.0;
            let px = |v: f64| v.round().clamp(0.0, 255.0) as u8;
            image::Rgb([
                px(yy + m[0] * v),
                px(yy + m[1] * u + m[2] * v),
                px(yy + m[3] * u),
            ])
        })
    }

    #[test]
    fn conversion_matches_the_formula_within_one_level() {
        for (s, matrix) in [YuvMatrix::Bt601, YuvMatrix::Bt709].into_iter().enumerate() {
            for (t, range) in [YuvRange::Limited, YuvRange::Full].into_iter().enumerate() {
                let img = random(38, 26, matrix, range, 7 + 2 * s as u64 + t as u64);
                let (got, want) = (img.to_rgb(), reference(&img));
                let worst = got
                    .as_raw()
                    .iter()
                    .zip(want.as_raw())
                    .map(|(a, b)| a.abs_diff(*b))
                    .max()
                    .unwrap();
                assert!(worst <= 1, "{matrix:?} {range:?}: off by {worst}");
            }
        }
    }

    #[test]
    fn pixels_convert_as_the_whole_frame_does() {
        // 38 wide: two 16-pixel blocks and a tail of 6, so both paths of the row kernel count.
        for (s, matrix) in [YuvMatrix::Bt601, YuvMatrix::Bt709].into_iter().enumerate() {
            for (t, range) in [YuvRange::Limited, YuvRange::Full].into_iter().enumerate() {
                let img = random(38, 26, matrix, range, 31 + 2 * s as u64 + t as u64);
                let whole = img.to_rgb();
                for (x, y, px) in whole.enumerate_pixels() {
                    assert_eq!(img.pixel(x, y), px.0, "{matrix:?} {range:?} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn rows_convert_as_the_whole_frame_does() {
        let img = random(10, 6, YuvMatrix::Bt709, YuvRange::Limited, 11);
        let whole = img.to_rgb();
        let mut row = vec![0u8; 30];
        for y in 0..6 {
            img.row_to_rgb(y, &mut row);
            assert_eq!(
                &row[..],
                &whole.as_raw()[30 * y as usize..30 * (y as usize + 1)]
            );
        }
    }

    #[test]
    fn greys_stay_grey_and_extremes_saturate() {
        // Limited-range black, mid grey and white with neutral chroma.
        for (yv, want) in [(16u8, 0u8), (126, 128), (235, 255), (0, 0), (255, 255)] {
            let mut img = Yuv420Image::new(4, 2, YuvMatrix::Bt601, YuvRange::Limited).unwrap();
            let d = img.as_raw_mut();
            d[..8].fill(yv);
            d[8..].fill(128);
            let rgb = img.to_rgb();
            assert!(
                rgb.as_raw().iter().all(|&c| c.abs_diff(want) <= 1),
                "Y {yv}: {:?}",
                &rgb.as_raw()[..3]
            );
        }
    }

    #[test]
    fn chroma_is_shared_by_its_two_by_two_block() {
        let img = random(6, 4, YuvMatrix::Bt601, YuvRange::Limited, 3);
        let mut flat = img.clone();
        // Same luma everywhere: the four pixels of a block must then be equal.
        flat.as_raw_mut()[..24].fill(100);
        let rgb = flat.to_rgb();
        for by in 0..2 {
            for bx in 0..3 {
                let p = *rgb.get_pixel(2 * bx, 2 * by);
                for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                    assert_eq!(*rgb.get_pixel(2 * bx + dx, 2 * by + dy), p);
                }
            }
        }
    }

    #[test]
    fn masked_store_rows_follow_the_per_pixel_formula() {
        // The object store's former per-pixel conversion, written out.
        let formula = |y: u8, u: u8, v: u8| {
            let (y, u, v) = ((y as i32) << 16, u as i32 - 128, v as i32 - 128);
            let c = |x: i32| ((x + (1 << 15)) >> 16).clamp(0, 255) as u8;
            [
                c(y + 91_881 * v),
                c(y - 22_554 * u - 46_802 * v),
                c(y + 116_130 * u),
            ]
        };
        let mut rng = Rng::new(7);
        for n in [0usize, 1, 2, 3, 15, 16, 17, 33, 100] {
            for odd in [false, true] {
                let ys: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
                let nc = (n + odd as usize).div_ceil(2);
                let us: Vec<u8> = (0..nc).map(|_| rng.next_u64() as u8).collect();
                let vs: Vec<u8> = (0..nc).map(|_| rng.next_u64() as u8).collect();
                let mask: Vec<u8> = (0..n)
                    .map(|_| !rng.next_u64().is_multiple_of(3) as u8)
                    .collect();
                let mut rgb = vec![7u8; 3 * n];
                masked_full_range_row_to_rgb(&ys, &us, &vs, odd, &mask, &mut rgb);
                for i in 0..n {
                    let c = (i + odd as usize) / 2;
                    let want = if mask[i] != 0 {
                        formula(ys[i], us[c], vs[c])
                    } else {
                        [0; 3]
                    };
                    assert_eq!(rgb[3 * i..3 * i + 3], want, "n {n} odd {odd} pixel {i}");
                }
            }
        }
        // Every level at its extremes of chroma.
        for y in 0..=255u8 {
            for (u, v) in [(0u8, 0u8), (0, 255), (255, 0), (255, 255), (128, 128)] {
                let mut rgb = [0u8; 3];
                masked_full_range_row_to_rgb(&[y], &[u], &[v], false, &[1], &mut rgb);
                assert_eq!(rgb, formula(y, u, v));
            }
        }
    }

    #[test]
    fn odd_sizes_and_wrong_lengths_are_refused() {
        let m = (YuvMatrix::Bt601, YuvRange::Limited);
        assert!(Yuv420Image::new(3, 2, m.0, m.1).is_err());
        assert!(Yuv420Image::new(0, 2, m.0, m.1).is_err());
        assert!(Yuv420Image::from_raw(4, 2, m.0, m.1, vec![0; 11]).is_err());
        assert!(Yuv420Image::from_raw(4, 2, m.0, m.1, vec![0; 12]).is_ok());
    }
}
