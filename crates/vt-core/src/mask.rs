//! Bit-packed binary masks and the XOR cost between them.
//!
//! A [`Mask`] stores one bit per pixel, row-major and contiguous (rows are *not* word-aligned),
//! in `u64` words. Invariant: bits past `width * height` are always zero, so whole-word
//! operations (popcount, XOR) never see garbage.

use std::ops::Range;

use rayon::prelude::*;

use crate::{Error, Result};

/// A binary image, one bit per pixel.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Mask {
    width: u32,
    height: u32,
    words: Vec<u64>,
}

impl std::fmt::Debug for Mask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Mask({}x{}, {} set)",
            self.width,
            self.height,
            self.count_ones()
        )
    }
}

fn n_words(width: u32, height: u32) -> usize {
    (width as usize * height as usize).div_ceil(64)
}

impl Mask {
    /// An all-clear mask.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            words: vec![0; n_words(width, height)],
        }
    }

    /// A mask from a predicate on pixel coordinates.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> bool) -> Self {
        let mut m = Self::new(width, height);
        for y in 0..height {
            for x in 0..width {
                if f(x, y) {
                    m.set(x, y, true);
                }
            }
        }
        m
    }

    /// A mask from a predicate on the row-major pixel index, packed 64 pixels at a time.
    pub fn from_index_fn(width: u32, height: u32, f: impl Fn(usize) -> bool) -> Self {
        let n = width as usize * height as usize;
        let mut m = Self::new(width, height);
        for (wi, word) in m.words.iter_mut().enumerate() {
            let base = wi * 64;
            let mut bits = 0u64;
            for i in 0..64.min(n - base) {
                bits |= (f(base + i) as u64) << i;
            }
            *word = bits;
        }
        m
    }

    /// A mask whose pixels each come from one of `masks` (all of this size): pixel `(x, y)`
    /// is `masks[pick(x / tile, y / tile)]`'s, `tile` pixels square, copied 64 pixels (a word)
    /// at a time where the choice holds along a row.
    pub fn from_tiles(
        width: u32,
        height: u32,
        tile: u32,
        masks: &[Mask],
        pick: impl Fn(usize, usize) -> usize,
    ) -> Self {
        let (w, n, tile) = (
            width as usize,
            width as usize * height as usize,
            tile.max(1) as usize,
        );
        let mut m = Self::new(width, height);
        for (wi, word) in m.words.iter_mut().enumerate() {
            let (base, end) = (wi * 64, (wi * 64 + 64).min(n));
            let mut i = base;
            while i < end {
                let (x, y) = (i % w, i / w);
                // To the end of the tile, the row or the word.
                let run = (y * w + ((x / tile + 1) * tile).min(w)).min(end) - i;
                let bits = if run == 64 {
                    !0
                } else {
                    ((1u64 << run) - 1) << (i - base)
                };
                let src = &masks[pick(x / tile, y / tile)];
                debug_assert_eq!((src.width, src.height), (width, height));
                *word |= src.words[wi] & bits;
                i += run;
            }
        }
        m
    }

    /// A mask from one byte per pixel (non-zero = set), row-major.
    pub fn from_bytes(width: u32, height: u32, bytes: &[u8]) -> Result<Self> {
        let n = width as usize * height as usize;
        if bytes.len() != n {
            return Err(Error::InvalidParameter {
                name: "bytes",
                value: bytes.len().to_string(),
                why: format!("a {width}x{height} mask needs {n} bytes"),
            });
        }
        let mut m = Self::new(width, height);
        for (w, chunk) in m.words.iter_mut().zip(bytes.chunks(64)) {
            let mut bits = 0u64;
            for (i, &b) in chunk.iter().enumerate() {
                bits |= ((b != 0) as u64) << i;
            }
            *w = bits;
        }
        Ok(m)
    }

    /// One byte per pixel: 255 where set, 0 elsewhere (OpenCV's mask convention).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.len();
        (0..n)
            .map(|i| if self.get_index(i) { 255 } else { 0 })
            .collect()
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// True when the mask has no pixels at all (0 width or height).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The packed words (bit `i` of the image is bit `i % 64` of word `i / 64`).
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Pixel value at `(x, y)`. Panics when out of bounds, like slice indexing.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> bool {
        assert!(
            x < self.width && y < self.height,
            "mask index ({x},{y}) out of bounds"
        );
        self.get_index(y as usize * self.width as usize + x as usize)
    }

    /// Pixel value at `(x, y)`, `false` outside the image (for neighbourhood and projection
    /// tests that may step off the edge; [`Mask::get`] panics there instead).
    #[inline]
    pub fn get_or_false(&self, x: i64, y: i64) -> bool {
        x >= 0
            && y >= 0
            && x < self.width as i64
            && y < self.height as i64
            && self.get_index(y as usize * self.width as usize + x as usize)
    }

    #[inline]
    fn get_index(&self, i: usize) -> bool {
        (self.words[i >> 6] >> (i & 63)) & 1 == 1
    }

    /// Sets the pixel at `(x, y)`. Panics when out of bounds.
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, value: bool) {
        assert!(
            x < self.width && y < self.height,
            "mask index ({x},{y}) out of bounds"
        );
        let i = y as usize * self.width as usize + x as usize;
        let bit = 1u64 << (i & 63);
        if value {
            self.words[i >> 6] |= bit;
        } else {
            self.words[i >> 6] &= !bit;
        }
    }

    /// Clears every pixel.
    pub fn clear(&mut self) {
        self.words.fill(0);
    }

    /// ORs `bits` (bit `i` = pixel index `start + i`) into the mask. The caller keeps every set
    /// bit below `len()`, so the invariant (nothing set past the last pixel) holds.
    #[inline]
    pub(crate) fn or_bits(&mut self, start: usize, bits: u64) {
        if bits == 0 {
            return;
        }
        debug_assert!(start + 64 - bits.leading_zeros() as usize <= self.len());
        let (w, s) = (start >> 6, start & 63);
        self.words[w] |= bits << s;
        if s != 0 && bits >> (64 - s) != 0 {
            self.words[w + 1] |= bits >> (64 - s);
        }
    }

    /// Number of set pixels.
    pub fn count_ones(&self) -> u64 {
        self.words.iter().map(|w| w.count_ones() as u64).sum()
    }

    /// Pixels set in either mask (same size; panics otherwise).
    pub fn union(&self, other: &Mask) -> Mask {
        self.combine(other, "union", |a, b| a | b)
    }

    /// Pixels set in this mask and not in `other` (same size; panics otherwise).
    pub fn difference(&self, other: &Mask) -> Mask {
        self.combine(other, "difference", |a, b| a & !b)
    }

    /// `op` word by word (it must keep bits past `width * height` clear, as `|` and `& !` do).
    fn combine(&self, other: &Mask, what: &str, op: impl Fn(u64, u64) -> u64) -> Mask {
        assert_eq!(
            (self.width, self.height),
            (other.width, other.height),
            "{what} of masks of different sizes"
        );
        Mask {
            width: self.width,
            height: self.height,
            words: self
                .words
                .iter()
                .zip(&other.words)
                .map(|(&a, &b)| op(a, b))
                .collect(),
        }
    }

    /// Range of words holding any set bit (empty range when nothing is set).
    pub fn active_words(&self) -> Range<usize> {
        let first = self.words.iter().position(|&w| w != 0);
        match first {
            None => 0..0,
            Some(f) => {
                let last = self.words.iter().rposition(|&w| w != 0).unwrap_or(f);
                f..last + 1
            }
        }
    }

    /// Bounding box `(x0, y0, x1, y1)` of the set pixels, exclusive upper bounds; `None` when empty.
    pub fn bounding_box(&self) -> Option<(u32, u32, u32, u32)> {
        let w = self.width as usize;
        let words = self.active_words();
        if words.is_empty() {
            return None;
        }
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        // Per word, per row segment of it: only the lowest and highest set bits matter.
        for wi in words {
            let mut bits = self.words[wi];
            let base = wi * 64;
            while bits != 0 {
                let i = base + bits.trailing_zeros() as usize;
                let y = i / w;
                let row_end = ((y + 1) * w - base).min(64);
                let seg = if row_end == 64 {
                    bits
                } else {
                    bits & ((1u64 << row_end) - 1)
                };
                let last = base + 63 - seg.leading_zeros() as usize;
                x0 = x0.min(i - y * w);
                x1 = x1.max(last - y * w + 1);
                y0 = y0.min(y);
                y1 = y1.max(y + 1);
                bits &= !seg;
            }
        }
        let (x0, y0, x1, y1) = (x0 as u32, y0 as u32, x1 as u32, y1 as u32);
        Some((x0, y0, x1, y1))
    }

    /// Erosion by a (2r+1)x(2r+1) square; pixels outside the image count as set, so a full
    /// mask stays full (OpenCV's default border for erosion).
    pub fn erode(&self, radius: u32) -> Mask {
        self.morph(radius, true)
    }

    /// Dilation by a (2r+1)x(2r+1) square; pixels outside the image count as clear.
    pub fn dilate(&self, radius: u32) -> Mask {
        self.morph(radius, false)
    }

    /// Opening (erode, then dilate): removes specks smaller than the square.
    pub fn open(&self, radius: u32) -> Mask {
        if radius == 0 {
            return self.clone();
        }
        self.erode(radius).dilate(radius)
    }

    /// Closing (dilate, then erode): fills holes smaller than the square.
    pub fn close(&self, radius: u32) -> Mask {
        if radius == 0 {
            return self.clone();
        }
        self.dilate(radius).erode(radius)
    }

    /// Separable square min (erode) or max (dilate) on bits: each row is copied into aligned
    /// words with the outside filled (set for erosion, clear for dilation), combined with its
    /// shifts by `-r..=r` (64 pixels per operation), then with the rows `y - r ..= y + r`.
    fn morph(&self, radius: u32, erode: bool) -> Mask {
        if radius == 0 || self.is_empty() {
            return self.clone();
        }
        crate::simd::dispatch(Morph {
            mask: self,
            r: radius as usize,
            erode,
        })
    }

    /// Background subtraction (SPEC A-1): a `width x height` mask set where
    /// `max over R, G, B of |frame - background| > threshold`, from two interleaved RGB byte
    /// buffers of `3 * width * height` bytes. Words in parallel; per word, the 192 channel
    /// tests in one vectorisable sweep, then the pixels' bits packed 8 at a time.
    pub fn from_rgb_difference(
        width: u32,
        height: u32,
        frame: &[u8],
        background: &[u8],
        threshold: u8,
    ) -> Result<Mask> {
        let n = width as usize * height as usize;
        for (name, buf) in [("frame", frame), ("background", background)] {
            if buf.len() != 3 * n {
                return Err(Error::InvalidParameter {
                    name: "rgb bytes",
                    value: buf.len().to_string(),
                    why: format!(
                        "the {name} of a {width}x{height} mask needs {} bytes",
                        3 * n
                    ),
                });
            }
        }
        let mut m = Self::new(width, height);
        // 256 words (16,384 pixels) per job.
        m.words
            .par_chunks_mut(256)
            .enumerate()
            .for_each(|(job, words)| {
                for (k, word) in words.iter_mut().enumerate() {
                    let base = (job * 256 + k) * 64;
                    let len = 64.min(n - base);
                    let (f, b) = (
                        &frame[base * 3..(base + len) * 3],
                        &background[base * 3..(base + len) * 3],
                    );
                    *word = if len == 64 {
                        let f: &[u8; 192] = f.try_into().expect("64 pixels");
                        let b: &[u8; 192] = b.try_into().expect("64 pixels");
                        diff_word(f, b, threshold)
                    } else {
                        let (mut fb, mut bb) = ([0u8; 192], [0u8; 192]);
                        fb[..len * 3].copy_from_slice(f);
                        bb[..len * 3].copy_from_slice(b);
                        diff_word(&fb, &bb, threshold)
                    };
                }
            });
        Ok(m)
    }
}

/// One word of [`Mask::from_rgb_difference`]: 64 interleaved RGB pixels.
#[inline(always)]
fn diff_word(f: &[u8; 192], b: &[u8; 192], threshold: u8) -> u64 {
    let mut over = [0u8; 192];
    for j in 0..192 {
        over[j] = (f[j].abs_diff(b[j]) > threshold) as u8;
    }
    let mut px = [0u8; 64];
    for p in 0..64 {
        px[p] = over[3 * p] | over[3 * p + 1] | over[3 * p + 2];
    }
    pack_bytes(&px)
}

/// Masks where `max over RGB |frame - background| > thresholds[pixel]` (the noise model's
/// per-pixel rule, [`crate::noise::noise_mask`]), 64 pixels per word, run through
/// [`crate::simd::dispatch`]. Lengths are the caller's to check.
pub(crate) struct PerPixelDiff<'a> {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) frame: &'a [u8],
    pub(crate) background: &'a [u8],
    pub(crate) thresholds: &'a [u8],
}

impl crate::simd::Kernel for PerPixelDiff<'_> {
    type Output = Mask;

    #[inline(always)]
    fn run(self) -> Mask {
        let n = self.width as usize * self.height as usize;
        let mut m = Mask::new(self.width, self.height);
        for (k, word) in m.words.iter_mut().enumerate() {
            let base = k * 64;
            let len = 64.min(n - base);
            let (mut fb, mut bb, mut tb) = ([0u8; 192], [0u8; 192], [255u8; 64]);
            let (f, b, t): (&[u8; 192], &[u8; 192], &[u8; 64]) = if len == 64 {
                (
                    self.frame[base * 3..base * 3 + 192]
                        .try_into()
                        .expect("64 pixels"),
                    self.background[base * 3..base * 3 + 192]
                        .try_into()
                        .expect("64 pixels"),
                    self.thresholds[base..base + 64]
                        .try_into()
                        .expect("64 pixels"),
                )
            } else {
                fb[..len * 3].copy_from_slice(&self.frame[base * 3..(base + len) * 3]);
                bb[..len * 3].copy_from_slice(&self.background[base * 3..(base + len) * 3]);
                tb[..len].copy_from_slice(&self.thresholds[base..base + len]);
                (&fb, &bb, &tb)
            };
            let mut d = [0u8; 192];
            for j in 0..192 {
                d[j] = f[j].abs_diff(b[j]);
            }
            let mut px = [0u8; 64];
            for p in 0..64 {
                px[p] = (d[3 * p].max(d[3 * p + 1]).max(d[3 * p + 2]) > t[p]) as u8;
            }
            *word = pack_bytes(&px);
        }
        m
    }
}

/// 64 bytes of 0 or 1 into one word, byte `i` to bit `i`: per 8 bytes, one multiplication
/// moves byte `k`'s bit to bit `56 + k` (no carries, the bits never meet).
#[inline(always)]
fn pack_bytes(px: &[u8; 64]) -> u64 {
    let mut bits = 0u64;
    for k in 0..8 {
        let v = u64::from_le_bytes(px[k * 8..k * 8 + 8].try_into().expect("8 bytes"));
        bits |= (v.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (k * 8);
    }
    bits
}

/// [`Mask::morph`] as a [`crate::simd::Kernel`].
struct Morph<'a> {
    mask: &'a Mask,
    r: usize,
    erode: bool,
}

impl crate::simd::Kernel for Morph<'_> {
    type Output = Mask;

    #[inline(always)]
    fn run(self) -> Mask {
        let Morph { mask, r, erode } = self;
        let (w, h) = (mask.width as usize, mask.height as usize);
        let wpr = w.div_ceil(64);
        let fill = if erode { u64::MAX } else { 0 };
        let combine = |a: u64, b: u64| if erode { a & b } else { a | b };
        // Rows start on word boundaries: whole words in and out, no bit shifting.
        let aligned = w % 64 == 0;
        // A row with `pad` fill words on each side, so every shift reads inside the buffer.
        let pad = r.div_ceil(64) + 1;
        let mut ext = vec![fill; wpr + 2 * pad];
        let mut horizontal = vec![0u64; wpr * h];
        let tail = w - (wpr - 1) * 64; // pixels in a row's last word, 1..=64
        let tail_mask = if tail == 64 {
            u64::MAX
        } else {
            (1u64 << tail) - 1
        };
        for (y, out_row) in horizontal.chunks_exact_mut(wpr).enumerate() {
            if aligned {
                ext[pad..pad + wpr].copy_from_slice(&mask.words[y * wpr..(y + 1) * wpr]);
            } else {
                for j in 0..wpr {
                    ext[pad + j] = bits_at(&mask.words, y * w + j * 64);
                }
            }
            ext[pad + wpr - 1] = (ext[pad + wpr - 1] & tail_mask) | (fill & !tail_mask);
            // Pixel x + d is bit d of the (word, next word) pair shifted right by d; the
            // usual radii unrolled (constant shifts, vectorised across words).
            macro_rules! shifts {
                ($rr:expr) => {
                    for (j, o) in out_row.iter_mut().enumerate() {
                        let (p, c, n) = (ext[pad + j - 1], ext[pad + j], ext[pad + j + 1]);
                        let mut acc = c;
                        for d in 1..=$rr {
                            acc = combine(acc, (c >> d) | (n << (64 - d)));
                            acc = combine(acc, (c << d) | (p >> (64 - d)));
                        }
                        *o = acc;
                    }
                };
            }
            if r < 64 {
                match r {
                    1 => shifts!(1),
                    2 => shifts!(2),
                    3 => shifts!(3),
                    4 => shifts!(4),
                    _ => shifts!(r),
                }
            } else {
                for (j, o) in out_row.iter_mut().enumerate() {
                    let at = (pad + j) * 64;
                    let mut acc = ext[pad + j];
                    for d in 1..=r {
                        acc = combine(acc, bits_at(&ext, at - d));
                        acc = combine(acc, bits_at(&ext, at + d));
                    }
                    *o = acc;
                }
            }
        }
        // Vertical pass: rows outside the image are the identity of `combine`, so skipped.
        let mut out = Mask::new(mask.width, mask.height);
        let mut acc_row = vec![0u64; wpr];
        for y in 0..h {
            let (lo, hi) = (y.saturating_sub(r), (y + r).min(h - 1));
            acc_row.copy_from_slice(&horizontal[lo * wpr..(lo + 1) * wpr]);
            for yy in lo + 1..=hi {
                for (a, &b) in acc_row
                    .iter_mut()
                    .zip(&horizontal[yy * wpr..(yy + 1) * wpr])
                {
                    *a = combine(*a, b);
                }
            }
            acc_row[wpr - 1] &= tail_mask;
            if aligned {
                out.words[y * wpr..(y + 1) * wpr].copy_from_slice(&acc_row);
            } else {
                for (j, &bits) in acc_row.iter().enumerate() {
                    out.or_bits(y * w + j * 64, bits);
                }
            }
        }
        out
    }
}

/// The 64 bits of `words` starting at bit `at` (bits past the end read as 0).
#[inline(always)]
fn bits_at(words: &[u64], at: usize) -> u64 {
    let (i, s) = (at >> 6, at & 63);
    let lo = words.get(i).copied().unwrap_or(0);
    if s == 0 {
        return lo;
    }
    let hi = words.get(i + 1).copied().unwrap_or(0);
    (lo >> s) | (hi << (64 - s))
}

/// `XOR(a, b)` of the thesis: the number of pixels set in exactly one of the two masks.
///
/// Panics when the masks differ in size (an internal invariant: callers check sizes once,
/// per view, not per pair).
pub fn xor_count(a: &Mask, b: &Mask) -> u64 {
    xor_count_in(a, b, 0..a.words.len())
}

/// [`xor_count`] restricted to a word range. Exact whenever both masks are clear outside
/// `words`: the analysis passes the union of all masks' [`Mask::active_words`], so only the
/// rows where something moves are ever touched.
pub fn xor_count_in(a: &Mask, b: &Mask, words: Range<usize>) -> u64 {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "xor_count: masks must share a size (checked per view by the caller)"
    );
    crate::simd::dispatch(XorCount {
        a: &a.words[words.clone()],
        b: &b.words[words],
    })
}

/// [`xor_count_in`]'s loop, dispatched so the popcounts vectorise (a byte-table popcount in
/// AVX2 registers) where the CPU allows.
struct XorCount<'a> {
    a: &'a [u64],
    b: &'a [u64],
}

impl crate::simd::Kernel for XorCount<'_> {
    type Output = u64;

    #[inline(always)]
    fn run(self) -> u64 {
        self.a
            .iter()
            .zip(self.b)
            .map(|(x, y)| (x ^ y).count_ones() as u64)
            .sum()
    }
}

/// Checks that every mask has mask 0's size; the error names `what` and the mask's index.
pub fn check_same_size(masks: &[Mask], what: &str) -> crate::Result<()> {
    let Some(first) = masks.first() else {
        return Ok(());
    };
    match masks
        .iter()
        .enumerate()
        .find(|(_, m)| (m.width, m.height) != (first.width, first.height))
    {
        None => Ok(()),
        Some((i, m)) => Err(Error::SizeMismatch {
            what: format!("{what} mask {i}"),
            expected_w: first.width,
            expected_h: first.height,
            got_w: m.width,
            got_h: m.height,
        }),
    }
}

/// Smallest word range covering the active words of every mask given.
pub fn union_active_words<'a>(masks: impl IntoIterator<Item = &'a Mask>) -> Range<usize> {
    let mut lo = usize::MAX;
    let mut hi = 0;
    for m in masks {
        let r = m.active_words();
        if !r.is_empty() {
            lo = lo.min(r.start);
            hi = hi.max(r.end);
        }
    }
    if lo == usize::MAX {
        0..0
    } else {
        lo..hi
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arbitrary_mask(max: u32) -> impl Strategy<Value = Mask> {
        (1..max, 1..max).prop_flat_map(|(w, h)| {
            proptest::collection::vec(any::<bool>(), (w * h) as usize).prop_map(move |bits| {
                let bytes: Vec<u8> = bits.iter().map(|&b| b as u8).collect();
                Mask::from_bytes(w, h, &bytes).unwrap()
            })
        })
    }

    /// Sparse random masks (a few set pixels, so boxes are not the whole image), widths below,
    /// at and above one word.
    fn sparse_mask(max: u32) -> impl Strategy<Value = Mask> {
        (1..max, 1..max, any::<u64>()).prop_map(|(w, h, seed)| {
            Mask::from_fn(w, h, |x, y| {
                crate::rng::mix(seed ^ (x as u64) << 20 ^ y as u64).is_multiple_of(23)
            })
        })
    }

    proptest! {
        #[test]
        fn from_tiles_matches_the_pixels_of_the_picked_masks(
            (w, h) in (1u32..150, 1u32..40),
            tile in 1u32..40,
            seed in any::<u64>(),
        ) {
            let masks: Vec<Mask> = (0..4u64)
                .map(|k| Mask::from_fn(w, h, |x, y| {
                    crate::rng::mix(seed ^ k << 40 ^ (x as u64) << 20 ^ y as u64).is_multiple_of(3)
                }))
                .collect();
            let pick = |tx: usize, ty: usize| (tx * 7 + ty * 3 + seed as usize) % masks.len();
            let m = Mask::from_tiles(w, h, tile, &masks, pick);
            let t = tile as usize;
            let want = Mask::from_fn(w, h, |x, y| masks[pick(x as usize / t, y as usize / t)].get(x, y));
            prop_assert_eq!(m.words(), want.words());
        }

        #[test]
        fn bounding_box_matches_per_pixel_scan(m in sparse_mask(150)) {
            let mut want: Option<(u32, u32, u32, u32)> = None;
            for y in 0..m.height() { for x in 0..m.width() {
                if m.get(x, y) {
                    let b = want.get_or_insert((x, y, x + 1, y + 1));
                    *b = (b.0.min(x), b.1.min(y), b.2.max(x + 1), b.3.max(y + 1));
                }
            }}
            prop_assert_eq!(m.bounding_box(), want);
        }

        #[test]
        fn union_and_difference_are_per_pixel(a in arbitrary_mask(40), seed in any::<u64>()) {
            let b = Mask::from_fn(a.width(), a.height(), |x, y| {
                (seed ^ (x as u64 * 31 + y as u64 * 17)).count_ones().is_multiple_of(3)
            });
            let (u, d) = (a.union(&b), a.difference(&b));
            for y in 0..a.height() { for x in 0..a.width() {
                prop_assert_eq!(u.get(x, y), a.get(x, y) || b.get(x, y));
                prop_assert_eq!(d.get(x, y), a.get(x, y) && !b.get(x, y));
            }}
        }

        #[test]
        fn xor_count_matches_per_pixel_count(a in arbitrary_mask(40), seed in any::<u64>()) {
            // A second mask of the same size from a simple hash of the seed.
            let b = Mask::from_fn(a.width(), a.height(), |x, y| {
                (seed ^ (x as u64 * 31 + y as u64 * 17)).count_ones().is_multiple_of(2)
            });
            let mut brute = 0u64;
            for y in 0..a.height() { for x in 0..a.width() {
                brute += (a.get(x, y) != b.get(x, y)) as u64;
            }}
            prop_assert_eq!(xor_count(&a, &b), brute);
            prop_assert_eq!(xor_count(&a, &b), xor_count(&b, &a));
            let active = union_active_words([&a, &b]);
            prop_assert_eq!(xor_count_in(&a, &b, active), brute);
        }

        #[test]
        fn bytes_round_trip(a in arbitrary_mask(30)) {
            let back = Mask::from_bytes(a.width(), a.height(), &a.to_bytes()).unwrap();
            prop_assert_eq!(back, a);
        }

        #[test]
        fn open_and_close_are_ordered(a in arbitrary_mask(24), r in 0u32..3) {
            // open(A) <= A <= close(A), pixel by pixel.
            let o = a.open(r);
            let c = a.close(r);
            for y in 0..a.height() { for x in 0..a.width() {
                prop_assert!(!o.get(x, y) || a.get(x, y));
                prop_assert!(!a.get(x, y) || c.get(x, y));
            }}
        }
    }

    /// Morphology by definition: per pixel, the min (erode) or max (dilate) over the square,
    /// outside pixels set for erosion and clear for dilation.
    fn brute_morph(m: &Mask, r: u32, erode: bool) -> Mask {
        let (w, h, r) = (m.width() as i64, m.height() as i64, r as i64);
        Mask::from_fn(m.width(), m.height(), |x, y| {
            let mut acc = erode;
            for yy in y as i64 - r..=y as i64 + r {
                for xx in x as i64 - r..=x as i64 + r {
                    let v = if xx < 0 || yy < 0 || xx >= w || yy >= h {
                        erode
                    } else {
                        m.get(xx as u32, yy as u32)
                    };
                    acc = if erode { acc && v } else { acc || v };
                }
            }
            acc
        })
    }

    proptest! {
        #[test]
        fn morphology_matches_its_definition(a in arbitrary_mask(140), r in 1u32..4) {
            prop_assert_eq!(a.erode(r), brute_morph(&a, r, true));
            prop_assert_eq!(a.dilate(r), brute_morph(&a, r, false));
        }

    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn morphology_across_words(
            (w, h) in (60u32..200, 1u32..4), r in 60u32..70, seed in any::<u64>()
        ) {
            // Radii around 64 on rows of one to four words: shifts that cross word boundaries.
            let a = Mask::from_fn(w, h, |x, y| (seed >> ((x * 7 + y * 3) % 64)) & 1 == 1);
            prop_assert_eq!(a.erode(r), brute_morph(&a, r, true));
            prop_assert_eq!(a.dilate(r), brute_morph(&a, r, false));
        }

        #[test]
        fn rgb_difference_matches_per_pixel_rule(
            (w, h) in (1u32..100, 1u32..9), t in any::<u8>(), seed in any::<u64>()
        ) {
            let n = (w * h) as usize * 3;
            let byte = |i: usize, s: u64| ((seed ^ s).wrapping_mul(i as u64 * 2 + 1) >> 29) as u8;
            let f: Vec<u8> = (0..n).map(|i| byte(i, 1)).collect();
            let b: Vec<u8> = (0..n).map(|i| byte(i, 7).wrapping_add(f[i] / 2)).collect();
            let got = Mask::from_rgb_difference(w, h, &f, &b, t).unwrap();
            let want = Mask::from_fn(w, h, |x, y| {
                let i = (y * w + x) as usize * 3;
                (0..3).any(|c| (f[i + c] as i32 - b[i + c] as i32).abs() > t as i32)
            });
            prop_assert_eq!(got, want);
        }
    }

    #[test]
    fn rgb_difference_checks_lengths() {
        let e = Mask::from_rgb_difference(4, 2, &[0; 24], &[0; 23], 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("background") && e.contains("23") && e.contains("24"),
            "{e}"
        );
        let big = vec![9u8; 3 * 700 * 300];
        let m = Mask::from_rgb_difference(700, 300, &big, &vec![0u8; big.len()], 8).unwrap();
        assert_eq!(m.count_ones(), 700 * 300, "a full mask over many jobs");
    }

    #[test]
    fn bounding_box_and_extremes() {
        let empty = Mask::new(7, 5);
        assert_eq!(empty.bounding_box(), None);
        assert_eq!(empty.active_words(), 0..0);
        let mut m = Mask::new(70, 3);
        m.set(65, 1, true);
        m.set(3, 2, true);
        assert_eq!(m.bounding_box(), Some((3, 1, 66, 3)));
        let full = Mask::from_fn(9, 9, |_, _| true);
        assert_eq!(full.erode(2), full, "erosion keeps a full mask full");
        assert_eq!(full.count_ones(), 81);
        let one = Mask::from_fn(1, 1, |_, _| true);
        assert_eq!(xor_count(&one, &Mask::new(1, 1)), 1);
    }

    #[test]
    fn opening_removes_a_speck_and_keeps_a_block() {
        let m = Mask::from_fn(20, 20, |x, y| {
            (x == 2 && y == 2) || (8..15).contains(&x) && (8..15).contains(&y)
        });
        let o = m.open(1);
        assert!(!o.get(2, 2));
        assert_eq!(o.count_ones(), 49);
    }
}
