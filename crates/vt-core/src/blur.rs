//! Separable Gaussian blur whose kernel follows OpenCV's `getGaussianKernel` definition.
//!
//! For an odd `ksize` and `sigma > 0`: `G_i = a * exp(-(i - (ksize-1)/2)^2 / (2 sigma^2))`, scaled to
//! sum 1. For `sigma <= 0`, `sigma = 0.3 * ((ksize - 1) * 0.5 - 1) + 0.8`, except that OpenCV uses
//! fixed binomial-like tables for ksize 1, 3, 5 and 7, which are reproduced here.
//! Borders use OpenCV's default `BORDER_REFLECT_101` (`gfedcb|abcdefgh|gfedcba`).
//! Filtering runs in `f32` and rounds to nearest; OpenCV's 8-bit path is fixed point, so the two
//! agree within one grey level (checked by `cargo xtask cross-check`).

use image::RgbImage;
use rayon::prelude::*;

use crate::{round_u8, round_u8_in_range};
use crate::{Error, Result};

/// Gaussian smoothing parameters. The thesis uses a 3x3 kernel (Table 2) with OpenCV's default
/// sigma, which is the [`Default`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GaussianParams {
    /// Kernel side, odd and >= 1.
    pub ksize: usize,
    /// Standard deviation in pixels; `<= 0` derives it from `ksize` as OpenCV does.
    pub sigma: f64,
}

impl Default for GaussianParams {
    fn default() -> Self {
        Self {
            ksize: 3,
            sigma: 0.0,
        }
    }
}

/// The 1-D kernel, exactly as OpenCV's `getGaussianKernel(ksize, sigma, CV_64F)`.
pub fn gaussian_kernel(ksize: usize, sigma: f64) -> Result<Vec<f64>> {
    if ksize == 0 || ksize.is_multiple_of(2) {
        return Err(Error::InvalidParameter {
            name: "ksize",
            value: ksize.to_string(),
            why: "a Gaussian kernel size must be odd and positive".into(),
        });
    }
    if !sigma.is_finite() {
        return Err(Error::NonFinite(format!("Gaussian sigma {sigma}")));
    }
    // OpenCV's small_gaussian_tab, used when sigma <= 0 and ksize <= 7.
    const SMALL: [&[f64]; 4] = [
        &[1.0],
        &[0.25, 0.5, 0.25],
        &[0.0625, 0.25, 0.375, 0.25, 0.0625],
        &[
            0.03125, 0.109375, 0.21875, 0.28125, 0.21875, 0.109375, 0.03125,
        ],
    ];
    if sigma <= 0.0 && ksize <= 7 {
        return Ok(SMALL[ksize / 2].to_vec());
    }
    let sigma = if sigma > 0.0 {
        sigma
    } else {
        ((ksize - 1) as f64 * 0.5 - 1.0) * 0.3 + 0.8
    };
    let scale2x = -0.5 / (sigma * sigma);
    let mut k: Vec<f64> = (0..ksize)
        .map(|i| {
            let x = i as f64 - (ksize - 1) as f64 * 0.5;
            (scale2x * x * x).exp()
        })
        .collect();
    let sum: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    Ok(k)
}

/// OpenCV's `borderInterpolate` for `BORDER_REFLECT_101`: the index inside `0..len` that
/// position `i` reads (`len >= 1`).
#[inline]
pub fn reflect101(mut i: isize, len: usize) -> usize {
    let n = len as isize;
    if n == 1 {
        return 0;
    }
    loop {
        if i < 0 {
            i = -i;
        } else if i >= n {
            i = 2 * n - 2 - i;
        } else {
            return i as usize;
        }
    }
}

/// Blurs `src` into a new image.
pub fn gaussian_blur(src: &RgbImage, params: &GaussianParams) -> Result<RgbImage> {
    let mut out = RgbImage::new(src.width(), src.height());
    gaussian_blur_into(src, params, &mut out)?;
    Ok(out)
}

/// Blurs `src` into `out`, which must have the same size, using all threads (rows in parallel).
pub fn gaussian_blur_into(
    src: &RgbImage,
    params: &GaussianParams,
    out: &mut RgbImage,
) -> Result<()> {
    let blur = GaussianBlur::new(params)?;
    check_sizes(src, out)?;
    let (w, h) = (src.width() as usize, src.height() as usize);
    if w == 0 || h == 0 {
        return Ok(());
    }
    let row_len = w * 3;
    let raw = src.as_raw();
    // Bands of rows in parallel: each computes the horizontal pass of its rows plus `r` above
    // and below (reflected) into a small buffer that stays in cache, then the vertical pass.
    // Same arithmetic per pixel as the whole-image passes, so the same bytes.
    let r = blur.radius();
    if blur.binomial3 {
        out.as_mut()
            .par_chunks_mut(row_len * BAND_ROWS)
            .enumerate()
            .for_each(|(band, rows)| {
                let (y0, n) = (band * BAND_ROWS, rows.len() / row_len);
                let mut tmp = vec![0u16; row_len * (n + 2)];
                crate::simd::dispatch(Binomial {
                    raw,
                    h,
                    y0,
                    tmp: &mut tmp,
                    rows,
                });
            });
        return Ok(());
    }
    // General kernels: bands of rows in parallel, each with a ring of `ksize` horizontal rows
    // (only `2 r` rows per band are computed twice).
    let band_rows = GENERAL_BAND_ROWS.max(4 * r);
    if let Some((ints, shift)) = &blur.dyadic {
        out.as_mut()
            .par_chunks_mut(row_len * band_rows)
            .enumerate()
            .for_each(|(band, rows)| {
                let mut ring = vec![0u16; row_len * ints.len()];
                let mut padded = vec![0u16; (w + 2 * r) * 3];
                crate::simd::dispatch(DyadicBand {
                    kernel: ints,
                    shift: *shift,
                    raw,
                    w,
                    h,
                    y0: band * band_rows,
                    rows,
                    ring: &mut ring,
                    padded: &mut padded,
                });
            });
        return Ok(());
    }
    out.as_mut()
        .par_chunks_mut(row_len * band_rows)
        .enumerate()
        .for_each(|(band, rows)| {
            let mut ring = vec![0f32; row_len * blur.kernel.len()];
            let mut padded = vec![0f32; (w + 2 * r) * 3];
            blur.band(raw, w, h, band * band_rows, rows, &mut ring, &mut padded);
        });
    Ok(())
}

/// One band of [`GaussianBlur::band`], as a [`crate::simd::Kernel`].
struct Band<'a> {
    blur: &'a GaussianBlur,
    raw: &'a [u8],
    w: usize,
    h: usize,
    y0: usize,
    rows: &'a mut [u8],
    ring: &'a mut [f32],
    padded: &'a mut [f32],
}

impl crate::simd::Kernel for Band<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let Band {
            blur,
            raw,
            w,
            h,
            y0,
            rows,
            ring,
            padded,
        } = self;
        let (r, k, row_len) = (blur.radius(), blur.kernel.len(), w * 3);
        let n = rows.len() / row_len;
        for j in 0..n + 2 * r {
            // Ring slot j % k holds image row reflect101(y0 + j - r).
            let yy = reflect101(y0 as isize + j as isize - r as isize, h);
            let slot = &mut ring[(j % k) * row_len..(j % k + 1) * row_len];
            blur.horizontal_row(&raw[yy * row_len..(yy + 1) * row_len], w, padded, slot);
            if j >= 2 * r {
                let y = j - 2 * r;
                blur.vertical_row(ring, y, &mut rows[y * row_len..(y + 1) * row_len]);
            }
        }
    }
}

/// A band of a symmetric dyadic kernel (taps `kernel[t] / 2^shift`, `shift <= 7`) in
/// integers: the horizontal sums `sum kernel[t] v_t <= 2^7 * 255` in `u16`, the vertical ones
/// in `u32`, then `(sum + 2^(2 shift - 1)) >> 2 shift`. These are the bytes of the `f32` path,
/// whose every product and sum is then exact (at most 14 + 8 significant bits), rounded half
/// up. Integer sums do not depend on their order, so mirrored taps are added first (`k_t (v_t +
/// v_(K-1-t))`, every partial sum bounded by the total, so no `u16` overflows).
struct DyadicBand<'a> {
    kernel: &'a [u16],
    shift: u32,
    raw: &'a [u8],
    w: usize,
    h: usize,
    y0: usize,
    rows: &'a mut [u8],
    ring: &'a mut [u16],
    padded: &'a mut [u16],
}

impl crate::simd::Kernel for DyadicBand<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let DyadicBand {
            kernel,
            shift,
            raw,
            w,
            h,
            y0,
            rows,
            ring,
            padded,
        } = self;
        let (k, row_len) = (kernel.len(), w * 3);
        let r = k / 2;
        let n = rows.len() / row_len;
        let (half, shift2) = (1u32 << (2 * shift) >> 1, 2 * shift);
        for j in 0..n + 2 * r {
            // Ring slot j % k holds image row reflect101(y0 + j - r).
            let yy = reflect101(y0 as isize + j as isize - r as isize, h);
            let src_row = &raw[yy * row_len..(yy + 1) * row_len];
            for (p, &v) in padded[3 * r..3 * (r + w)].iter_mut().zip(src_row) {
                *p = v as u16;
            }
            for i in (0..r).chain(w + r..w + 2 * r) {
                let xx = reflect101(i as isize - r as isize, w);
                for c in 0..3 {
                    padded[i * 3 + c] = src_row[xx * 3 + c] as u16;
                }
            }
            let slot = &mut ring[(j % k) * row_len..(j % k + 1) * row_len];
            macro_rules! horizontal {
                ($($m:literal)*) => {
                    match k {
                        $($m => {
                            let kern: &[u16; $m] = kernel.try_into().expect("length");
                            let p = &padded[..row_len + ($m - 1) * 3];
                            for (i, o) in slot.iter_mut().enumerate() {
                                let mut acc = kern[$m / 2] * p[i + 3 * ($m / 2)];
                                for t in 0..$m / 2 {
                                    acc += kern[t] * (p[i + 3 * t] + p[i + 3 * ($m - 1 - t)]);
                                }
                                *o = acc;
                            }
                        })*
                        _ => {
                            for (i, o) in slot.iter_mut().enumerate() {
                                let mut acc = 0u16;
                                for t in 0..k {
                                    acc = acc.wrapping_add(kernel[t].wrapping_mul(padded[i + 3 * t]));
                                }
                                *o = acc;
                            }
                        }
                    }
                };
            }
            horizontal!(3 5 7);
            if j < 2 * r {
                continue;
            }
            let y = j - 2 * r;
            let out = &mut rows[y * row_len..(y + 1) * row_len];
            let ring = &*ring;
            let tap = |t: usize| &ring[((y + t) % k) * row_len..((y + t) % k + 1) * row_len];
            macro_rules! vertical {
                ($($m:literal)*) => {
                    match k {
                        $($m => {
                            let kern: &[u16; $m] = kernel.try_into().expect("length");
                            let taps: [&[u16]; $m] = std::array::from_fn(tap);
                            for i in 0..row_len {
                                let mut acc = half + kern[$m / 2] as u32 * taps[$m / 2][i] as u32;
                                for t in 0..$m / 2 {
                                    let pair = taps[t][i] + taps[$m - 1 - t][i];
                                    acc += kern[t] as u32 * pair as u32;
                                }
                                // At most 255 already; the `min` lets the compiler pack with saturation.
                                out[i] = (acc >> shift2).min(255) as u8;
                            }
                        })*
                        _ => {
                            for i in 0..row_len {
                                let mut acc = half;
                                for t in 0..k {
                                    acc += kernel[t] as u32 * tap(t)[i] as u32;
                                }
                                // At most 255 already; the `min` lets the compiler pack with saturation.
                                out[i] = (acc >> shift2).min(255) as u8;
                            }
                        }
                    }
                };
            }
            vertical!(3 5 7);
        }
    }
}

/// Three-tap binomial bands ([`binomial_h_row`], [`binomial_v_rows`]) as a kernel.
struct Binomial<'a> {
    raw: &'a [u8],
    h: usize,
    y0: usize,
    tmp: &'a mut [u16],
    rows: &'a mut [u8],
}

impl crate::simd::Kernel for Binomial<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let Binomial {
            raw,
            h,
            y0,
            tmp,
            rows,
        } = self;
        let row_len = raw.len() / h;
        for (j, t) in tmp.chunks_exact_mut(row_len).enumerate() {
            let yy = reflect101(y0 as isize + j as isize - 1, h);
            binomial_h_row(&raw[yy * row_len..(yy + 1) * row_len], t);
        }
        for (j, row) in rows.chunks_exact_mut(row_len).enumerate() {
            binomial_v_rows(
                &tmp[j * row_len..(j + 1) * row_len],
                &tmp[(j + 1) * row_len..(j + 2) * row_len],
                &tmp[(j + 2) * row_len..(j + 3) * row_len],
                row,
            );
        }
    }
}

/// Rows per parallel job of the general (non-3x3) blur.
const GENERAL_BAND_ROWS: usize = 32;

/// Horizontal `[1 2 1]` sums of one RGB row (reflect-101 borders), exact in `u16` (<= 1020).
/// Same numbers as the f32 path times 4: the thesis's kernel is dyadic, so integers are exact.
#[inline(always)]
fn binomial_h_row(src: &[u8], row: &mut [u16]) {
    let n = src.len();
    if n == 3 {
        for c in 0..3 {
            row[c] = 4 * src[c] as u16;
        }
        return;
    }
    for c in 0..3 {
        row[c] = 2 * src[c] as u16 + 2 * src[3 + c] as u16;
        row[n - 3 + c] = 2 * src[n - 6 + c] as u16 + 2 * src[n - 3 + c] as u16;
    }
    for i in 3..n - 3 {
        row[i] = src[i - 3] as u16 + 2 * src[i] as u16 + src[i + 3] as u16;
    }
}

/// Rows per parallel job of [`gaussian_blur_into`].
const BAND_ROWS: usize = 16;

/// Vertical `[1 2 1]` of three horizontal-sum rows, divided by 16 and rounded half up.
#[inline(always)]
fn binomial_v_rows(a: &[u16], b: &[u16], c: &[u16], out: &mut [u8]) {
    let n = out.len();
    let (a, b, c) = (&a[..n], &b[..n], &c[..n]);
    for i in 0..n {
        out[i] = ((a[i] + 2 * b[i] + c[i] + 8) >> 4) as u8;
    }
}

/// Vertical `[1 2 1]` of the horizontal sums, divided by 16 and rounded half up: the same bytes
/// as the f32 path (whose sums are exact multiples of 1/16).
fn binomial_v_row(tmp: &[u16], y: usize, h: usize, out: &mut [u8]) {
    let n = out.len();
    let row = |yy: usize| &tmp[yy * n..(yy + 1) * n];
    let (a, b, c) = (
        row(reflect101(y as isize - 1, h)),
        row(y),
        row(reflect101(y as isize + 1, h)),
    );
    for i in 0..n {
        out[i] = ((a[i] + 2 * b[i] + c[i] + 8) >> 4) as u8;
    }
}

fn check_sizes(src: &RgbImage, out: &RgbImage) -> Result<()> {
    if out.dimensions() != src.dimensions() {
        return Err(Error::SizeMismatch {
            what: "blur output".into(),
            expected_w: src.width(),
            expected_h: src.height(),
            got_w: out.width(),
            got_h: out.height(),
        });
    }
    Ok(())
}

/// A prepared blur (kernel computed once) for many images, e.g. every frame of a view blurred
/// on its own thread with [`GaussianBlur::apply_into`] and reused [`BlurScratch`].
#[derive(Debug, Clone)]
pub struct GaussianBlur {
    kernel: Vec<f32>,
    /// The thesis's 3x3 kernel (OpenCV's table `[1/4, 1/2, 1/4]`), run in exact integers.
    binomial3: bool,
    /// Symmetric dyadic kernels (OpenCV's tables for ksize 5 and 7): the taps times `2^shift`
    /// as integers, `shift <= 7`, run in exact integers ([`DyadicBand`]).
    dyadic: Option<(Vec<u16>, u32)>,
}

/// Reusable buffers of [`GaussianBlur::apply_into`]: no allocation once warm.
#[derive(Debug, Default)]
pub struct BlurScratch {
    ring: Vec<f32>,
    padded: Vec<f32>,
    tmp16: Vec<u16>,
    ring16: Vec<u16>,
    padded16: Vec<u16>,
}

impl GaussianBlur {
    /// Prepares the kernel of `params`.
    pub fn new(params: &GaussianParams) -> Result<Self> {
        let exact = gaussian_kernel(params.ksize, params.sigma)?;
        let binomial3 = exact == [0.25, 0.5, 0.25];
        let kernel = exact.iter().map(|&v| v as f32).collect();
        let symmetric = exact.iter().eq(exact.iter().rev());
        let dyadic = (0..=7u32).find_map(|shift| {
            let scale = (1u32 << shift) as f64;
            let ints: Vec<u16> = exact.iter().map(|&v| (v * scale) as u16).collect();
            let exact_ints = exact
                .iter()
                .zip(&ints)
                .all(|(&v, &i)| v * scale == i as f64);
            (symmetric && exact_ints).then_some((ints, shift))
        });
        Ok(Self {
            kernel,
            binomial3,
            dyadic,
        })
    }

    fn radius(&self) -> usize {
        self.kernel.len() / 2
    }

    /// Blurs on the calling thread only (for callers that parallelise over images).
    pub fn apply_into(
        &self,
        src: &RgbImage,
        out: &mut RgbImage,
        scratch: &mut BlurScratch,
    ) -> Result<()> {
        check_sizes(src, out)?;
        let (w, h) = (src.width() as usize, src.height() as usize);
        let row_len = w * 3;
        scratch.ring.resize(row_len * self.kernel.len(), 0.0);
        scratch.padded.resize((w + 2 * self.radius()) * 3, 0.0);
        if w == 0 || h == 0 {
            return Ok(());
        }
        if self.binomial3 {
            scratch.tmp16.resize(row_len * h, 0);
            for (y, row) in scratch.tmp16.chunks_mut(row_len).enumerate() {
                binomial_h_row(&src.as_raw()[y * row_len..(y + 1) * row_len], row);
            }
            for (y, row) in out.as_mut().chunks_mut(row_len).enumerate() {
                binomial_v_row(&scratch.tmp16, y, h, row);
            }
            return Ok(());
        }
        if let Some((ints, shift)) = &self.dyadic {
            scratch.ring16.resize(row_len * ints.len(), 0);
            scratch.padded16.resize((w + 2 * self.radius()) * 3, 0);
            crate::simd::dispatch(DyadicBand {
                kernel: ints,
                shift: *shift,
                raw: src.as_raw(),
                w,
                h,
                y0: 0,
                rows: out.as_mut(),
                ring: &mut scratch.ring16,
                padded: &mut scratch.padded16,
            });
            return Ok(());
        }
        self.band(
            src.as_raw(),
            w,
            h,
            0,
            out.as_mut(),
            &mut scratch.ring,
            &mut scratch.padded,
        );
        Ok(())
    }

    /// Output rows `y0 ..` (as many as `rows` holds) of the general blur, with `ring` holding
    /// `ksize` horizontal rows and `padded` one reflected input row (`(w + 2 r) * 3`).
    ///
    /// Per value, both passes sum `kernel[t] * v_t` over the taps in order, from 0 (a plain
    /// `f32` multiply-add sequence, identical whatever the vector width); the vertical sum is
    /// rounded half up to `u8`.
    #[allow(clippy::too_many_arguments)]
    fn band(
        &self,
        raw: &[u8],
        w: usize,
        h: usize,
        y0: usize,
        rows: &mut [u8],
        ring: &mut [f32],
        padded: &mut [f32],
    ) {
        crate::simd::dispatch(Band {
            blur: self,
            raw,
            w,
            h,
            y0,
            rows,
            ring,
            padded,
        })
    }

    /// One row of the horizontal pass: pad by reflection, then per value the taps' sum.
    #[inline(always)]
    fn horizontal_row(&self, src_row: &[u8], w: usize, padded: &mut [f32], row: &mut [f32]) {
        let r = self.radius();
        for (p, &v) in padded[3 * r..3 * (r + w)].iter_mut().zip(src_row) {
            *p = v as f32;
        }
        for i in (0..r).chain(w + r..w + 2 * r) {
            let xx = reflect101(i as isize - r as isize, w);
            for c in 0..3 {
                padded[i * 3 + c] = src_row[xx * 3 + c] as f32;
            }
        }
        macro_rules! fixed {
            ($($n:literal)*) => {
                match self.kernel.len() {
                    $($n => {
                        let kern: &[f32; $n] = self.kernel[..].try_into().expect("length");
                        let p = &padded[..row.len() + ($n - 1) * 3];
                        for (i, o) in row.iter_mut().enumerate() {
                            // `0 + k v` is `k v` (taps and values are >= 0).
                            let mut acc = kern[0] * p[i];
                            for t in 1..$n {
                                acc += kern[t] * p[i + 3 * t];
                            }
                            *o = acc;
                        }
                    })*
                    _ => {
                        // Any size: one sweep per tap, the same sums.
                        row.fill(0.0);
                        for (j, &kv) in self.kernel.iter().enumerate() {
                            for (acc, &v) in row.iter_mut().zip(&padded[j * 3..]) {
                                *acc += kv * v;
                            }
                        }
                    }
                }
            };
        }
        fixed!(3 5 7 9 11 13 15);
    }

    /// Output row `y` of a band (its taps in ring slots `(y + t) % ksize`), rounded to u8.
    #[inline(always)]
    fn vertical_row(&self, ring: &[f32], y: usize, out: &mut [u8]) {
        let (k, n) = (self.kernel.len(), out.len());
        let slot = |t: usize| &ring[((y + t) % k) * n..((y + t) % k + 1) * n];
        macro_rules! fixed {
            ($($n:literal)*) => {
                match k {
                    $($n => {
                        let kern: &[f32; $n] = self.kernel[..].try_into().expect("length");
                        let rows: [&[f32]; $n] = std::array::from_fn(slot);
                        for i in 0..n {
                            let mut acc = kern[0] * rows[0][i];
                            for t in 1..$n {
                                acc += kern[t] * rows[t][i];
                            }
                            // A convex combination of bytes (taps sum to 1 up to f32).
                            out[i] = round_u8_in_range(acc) as u8;
                        }
                    })*
                    _ => {
                        for i in 0..n {
                            let mut acc = 0.0f32;
                            for t in 0..k {
                                acc += self.kernel[t] * slot(t)[i];
                            }
                            out[i] = round_u8(acc);
                        }
                    }
                }
            };
        }
        fixed!(3 5 7 9 11 13 15);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    #[test]
    fn kernel_matches_opencv_definition() {
        // Small tables (OpenCV smooth.dispatch / getGaussianKernel, sigma <= 0).
        assert_eq!(gaussian_kernel(3, 0.0).unwrap(), vec![0.25, 0.5, 0.25]);
        assert_eq!(
            gaussian_kernel(5, -1.0).unwrap(),
            vec![0.0625, 0.25, 0.375, 0.25, 0.0625]
        );
        // Formula with derived sigma for ksize 9: sigma = 0.3*(4-1)+0.8 = 1.7.
        let k = gaussian_kernel(9, 0.0).unwrap();
        let s: f64 = 1.7;
        let raw: Vec<f64> = (0..9)
            .map(|i| (-((i as f64 - 4.0).powi(2)) / (2.0 * s * s)).exp())
            .collect();
        let sum: f64 = raw.iter().sum();
        for (a, b) in k.iter().zip(raw.iter().map(|v| v / sum)) {
            assert_relative_eq!(*a, b, max_relative = 1e-14);
        }
        // Explicit sigma on a small kernel uses the formula, not the table.
        let k3 = gaussian_kernel(3, 0.8).unwrap();
        let e = (-1.0f64 / (2.0 * 0.64)).exp();
        assert_relative_eq!(k3[0], e / (1.0 + 2.0 * e), max_relative = 1e-14);
        assert!(gaussian_kernel(4, 1.0).is_err());
        assert!(gaussian_kernel(3, f64::NAN).is_err());
    }

    proptest! {
        #[test]
        fn integer_3x3_path_equals_the_float_path((w, h) in (1u32..20, 1u32..40), seed in any::<u32>()) {
            let img = RgbImage::from_fn(w, h, |x, y| {
                let t = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503) ^ seed) >> 7;
                image::Rgb([t as u8, (t >> 8) as u8, (t >> 16) as u8])
            });
            let int = gaussian_blur(&img, &GaussianParams::default()).unwrap();
            // The same kernel forced through the generic f32 rows.
            let float = GaussianBlur { kernel: vec![0.25, 0.5, 0.25], binomial3: false, dyadic: None };
            let mut out = RgbImage::new(w, h);
            float.apply_into(&img, &mut out, &mut BlurScratch::default()).unwrap();
            prop_assert_eq!(int, out);
        }
    }

    /// The f32 blur written out per value: horizontal sums `k[t] * v` in tap order from 0,
    /// then the vertical sums of those in tap order, rounded half up (the whole-image passes
    /// the banded, vectorised path must reproduce bit for bit).
    fn reference_f32(img: &RgbImage, kernel: &[f32]) -> RgbImage {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let r = kernel.len() / 2;
        let raw = img.as_raw();
        let mut hz = vec![0f32; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let mut acc = 0.0f32;
                    for (t, &k) in kernel.iter().enumerate() {
                        let xx = reflect101(x as isize + t as isize - r as isize, w);
                        acc += k * raw[(y * w + xx) * 3 + c] as f32;
                    }
                    hz[(y * w + x) * 3 + c] = acc;
                }
            }
        }
        let mut out = RgbImage::new(w as u32, h as u32);
        for y in 0..h {
            for i in 0..w * 3 {
                let mut acc = 0.0f32;
                for (t, &k) in kernel.iter().enumerate() {
                    let yy = reflect101(y as isize + t as isize - r as isize, h);
                    acc += k * hz[yy * w * 3 + i];
                }
                out.as_mut()[y * w * 3 + i] = (acc + 0.5).clamp(0.0, 255.0) as u8;
            }
        }
        out
    }

    proptest! {
        #[test]
        fn banded_blur_equals_the_whole_image_passes(
            (w, h) in (1u32..40, 1u32..90), ksize in (0usize..10).prop_map(|k| 2 * k + 1),
            // sigma 0 gives OpenCV's tables for ksize <= 7 (the dyadic integer path).
            sigma in prop_oneof![Just(0.0), 0.0f64..4.0], seed in any::<u32>(),
        ) {
            let img = RgbImage::from_fn(w, h, |x, y| {
                let t = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503) ^ seed) >> 7;
                image::Rgb([t as u8, (t >> 8) as u8, (x * 9 + y * 5) as u8])
            });
            let params = GaussianParams { ksize, sigma };
            let blur = GaussianBlur::new(&params).unwrap();
            prop_assume!(!blur.binomial3);
            let want = reference_f32(&img, &blur.kernel);
            prop_assert_eq!(&gaussian_blur(&img, &params).unwrap(), &want);
            let mut out = RgbImage::new(w, h);
            blur.apply_into(&img, &mut out, &mut BlurScratch::default()).unwrap();
            prop_assert_eq!(&out, &want);
        }
    }

    #[test]
    fn reflect101_matches_opencv() {
        let got: Vec<usize> = (-3..8).map(|i| reflect101(i, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(reflect101(-2, 1), 0);
    }

    #[test]
    fn one_pixel_and_constant_images_are_fixed_points() {
        let one = RgbImage::from_pixel(1, 1, image::Rgb([7, 200, 33]));
        assert_eq!(
            gaussian_blur(
                &one,
                &GaussianParams {
                    ksize: 7,
                    sigma: 2.0
                }
            )
            .unwrap(),
            one
        );
    }

    proptest! {
        #[test]
        fn blur_keeps_constants_and_roughly_the_mean(
            (w, h) in (1u32..24, 1u32..40), v in any::<u8>(), seed in any::<u32>()
        ) {
            let c = RgbImage::from_pixel(w, h, image::Rgb([v, v, v]));
            prop_assert_eq!(gaussian_blur(&c, &GaussianParams::default()).unwrap(), c);
            let img = RgbImage::from_fn(w, h, |x, y| {
                let t = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503) ^ seed) as u8;
                image::Rgb([t, t / 2, 255 - t])
            });
            let b = gaussian_blur(&img, &GaussianParams { ksize: 5, sigma: 1.2 }).unwrap();
            // Values stay within the input's range (a convex combination).
            let (lo, hi) = (img.as_raw().iter().min().unwrap(), img.as_raw().iter().max().unwrap());
            prop_assert!(b.as_raw().iter().all(|v| v >= lo && v <= hi));
            // The single-threaded path with reused scratch gives the same bytes.
            let blur = GaussianBlur::new(&GaussianParams { ksize: 5, sigma: 1.2 }).unwrap();
            let mut scratch = BlurScratch::default();
            let mut out = RgbImage::new(w, h);
            blur.apply_into(&img, &mut out, &mut scratch).unwrap();
            prop_assert_eq!(&out, &b);
        }
    }
}
