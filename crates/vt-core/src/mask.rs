//! Bit-packed binary masks and the XOR cost between them.
//!
//! A [`Mask`] stores one bit per pixel, row-major and contiguous (rows are *not* word-aligned),
//! in `u64` words. Invariant: bits past `width * height` are always zero, so whole-word
//! operations (popcount, XOR) never see garbage.

use std::ops::Range;

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

    /// Number of set pixels.
    pub fn count_ones(&self) -> u64 {
        self.words.iter().map(|w| w.count_ones() as u64).sum()
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
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0u32, 0u32);
        for wi in words {
            let mut bits = self.words[wi];
            while bits != 0 {
                let i = wi * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (x, y) = ((i % w) as u32, (i / w) as u32);
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x + 1);
                y1 = y1.max(y + 1);
            }
        }
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

    /// Separable square min (erode) or max (dilate) on a byte copy.
    fn morph(&self, radius: u32, erode: bool) -> Mask {
        if radius == 0 || self.is_empty() {
            return self.clone();
        }
        let (w, h, r) = (self.width as usize, self.height as usize, radius as usize);
        let src: Vec<bool> = (0..self.len()).map(|i| self.get_index(i)).collect();
        let combine = |acc: bool, v: bool| if erode { acc && v } else { acc || v };
        let mut tmp = vec![false; src.len()];
        for y in 0..h {
            for x in 0..w {
                let mut acc = erode;
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    acc = combine(acc, src[y * w + xx]);
                }
                tmp[y * w + x] = acc;
            }
        }
        let mut out = Mask::new(self.width, self.height);
        for y in 0..h {
            for x in 0..w {
                let mut acc = erode;
                for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                    acc = combine(acc, tmp[yy * w + x]);
                }
                if acc {
                    out.set(x as u32, y as u32, true);
                }
            }
        }
        out
    }
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
    let aw = &a.words[words.clone()];
    let bw = &b.words[words];
    aw.iter()
        .zip(bw)
        .map(|(x, y)| (x ^ y).count_ones() as u64)
        .sum()
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

    proptest! {
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
