//! Object silhouettes: binary masks by thresholding (the Middlebury recipe) or from a mask image,
//! square-element morphology, and a summed-area table for rectangle queries.

use image::{GrayImage, RgbImage};

use crate::{Error, Result};

/// A binary image, one byte per pixel (0 or 1), row-major.
#[derive(Clone, PartialEq, Eq)]
pub struct Mask {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl std::fmt::Debug for Mask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Mask({}x{}, {} set)",
            self.width,
            self.height,
            self.count()
        )
    }
}

impl Mask {
    /// An all-clear mask.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            data: vec![0; width as usize * height as usize],
        }
    }

    /// A mask from a predicate on pixel coordinates `(x, y)`.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> bool) -> Self {
        let mut m = Self::new(width, height);
        for y in 0..height {
            for x in 0..width {
                m.data[(y * width + x) as usize] = f(x, y) as u8;
            }
        }
        m
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Whether pixel `(x, y)` is set; `false` outside the image.
    #[inline]
    pub fn get(&self, x: i64, y: i64) -> bool {
        x >= 0
            && y >= 0
            && x < self.width as i64
            && y < self.height as i64
            && self.data[(y as usize) * self.width as usize + x as usize] != 0
    }

    /// Sets pixel `(x, y)` (which must be inside the image).
    pub fn set(&mut self, x: u32, y: u32, v: bool) {
        self.data[(y * self.width + x) as usize] = v as u8;
    }

    /// The pixels as 0/1 bytes, row-major.
    pub fn as_slice(&self) -> &[u8] {
        &self.data
    }

    /// Number of set pixels.
    pub fn count(&self) -> usize {
        self.data.iter().map(|&v| v as usize).sum()
    }

    /// Bounding box `(x0, y0, x1, y1)` (inclusive) of the set pixels; `None` when empty.
    pub fn bbox(&self) -> Option<(u32, u32, u32, u32)> {
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
        for y in 0..self.height {
            for x in 0..self.width {
                if self.data[(y * self.width + x) as usize] != 0 {
                    x0 = x0.min(x);
                    y0 = y0.min(y);
                    x1 = x1.max(x);
                    y1 = y1.max(y);
                }
            }
        }
        (x0 != u32::MAX).then_some((x0, y0, x1, y1))
    }

    /// Dilation by a square of side `2 radius + 1` (separable running count).
    pub fn dilate(&self, radius: u32) -> Self {
        self.morph(radius, false)
    }

    /// Erosion by a square of side `2 radius + 1`. Pixels outside the image do not count, so
    /// the image border does not erode the object.
    pub fn erode(&self, radius: u32) -> Self {
        self.morph(radius, true)
    }

    fn morph(&self, radius: u32, erode: bool) -> Self {
        if radius == 0 {
            return self.clone();
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let rows = pass(&self.data, w, h, 1, w, radius as usize, erode);
        let data = pass(&rows, h, w, w, 1, radius as usize, erode);
        Self {
            width: self.width,
            height: self.height,
            data,
        }
    }

    /// Per pixel, a grey-level image (255 = set), for saving.
    pub fn to_image(&self) -> GrayImage {
        GrayImage::from_fn(self.width, self.height, |x, y| {
            image::Luma([self.data[(y * self.width + x) as usize] * 255])
        })
    }
}

/// One 1-D morphology pass along lines of length `n` (stride `step`), `m` lines (stride `line`).
fn pass(
    src: &[u8],
    n: usize,
    m: usize,
    step: usize,
    line: usize,
    r: usize,
    erode: bool,
) -> Vec<u8> {
    let mut out = vec![0u8; src.len()];
    for l in 0..m {
        let base = l * line;
        let at = |i: usize| src[base + i * step] as usize;
        // Running count of set pixels in [i - r, i + r] clipped to [0, n).
        let mut count: usize = (0..r.min(n)).map(at).sum();
        for i in 0..n {
            if i + r < n {
                count += at(i + r);
            }
            if i > r {
                count -= at(i - r - 1);
            }
            let lo = i.saturating_sub(r);
            let hi = (i + r).min(n - 1);
            let v = if erode {
                count == hi - lo + 1
            } else {
                count > 0
            };
            out[base + i * step] = v as u8;
        }
    }
    out
}

/// How to threshold a photo into a silhouette. Defaults are the Middlebury recipe.
#[derive(Debug, Clone, PartialEq)]
pub struct SilhouetteParams {
    /// A pixel is object when its largest channel exceeds this fraction of full scale (0.19).
    pub threshold: f64,
    /// Dilation radius in pixels, square element of side `2 r + 1` (10).
    pub dilate: u32,
    /// Erosion radius in pixels after dilation (7).
    pub erode: u32,
}

impl Default for SilhouetteParams {
    fn default() -> Self {
        Self {
            threshold: 0.19,
            dilate: 10,
            erode: 7,
        }
    }
}

impl SilhouetteParams {
    /// Silhouettes to carve a model from: the Middlebury threshold with a 3 px dilation and a
    /// 3 px erosion, which closes speckle but not the gaps between the temple's columns (the
    /// recipe's 10/7 closes those, and the hull keeps them filled).
    pub fn carving() -> Self {
        Self {
            dilate: 3,
            erode: 3,
            ..Self::default()
        }
    }
}

/// Silhouette of an object on a dark background: threshold on the max channel, then dilate and
/// erode (a closing that also grows the mask by `dilate - erode` pixels, keeping the visual hull
/// conservative).
pub fn threshold_silhouette(img: &RgbImage, p: &SilhouetteParams) -> Mask {
    let t = p.threshold * 255.0;
    let m = Mask::from_fn(img.width(), img.height(), |x, y| {
        let px = img.get_pixel(x, y).0;
        px[0].max(px[1]).max(px[2]) as f64 > t
    });
    m.dilate(p.dilate).erode(p.erode)
}

/// Silhouette from a supplied mask image: non-zero pixels are object.
pub fn mask_from_image(img: &GrayImage) -> Mask {
    Mask::from_fn(img.width(), img.height(), |x, y| {
        img.get_pixel(x, y).0[0] != 0
    })
}

/// Summed-area table of a mask, for counting set pixels in rectangles in O(1).
#[derive(Debug, Clone)]
pub struct Integral {
    width: usize,
    height: usize,
    sums: Vec<u32>,
}

impl Integral {
    /// Builds the table.
    pub fn new(m: &Mask) -> Self {
        let (w, h) = (m.width as usize, m.height as usize);
        let mut sums = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += m.data[y * w + x] as u32;
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        Self {
            width: w,
            height: h,
            sums,
        }
    }

    /// Set pixels in the inclusive rectangle `[x0, x1] x [y0, y1]`, clipped to the image, and
    /// the clipped area.
    #[inline]
    pub fn count(&self, x0: i64, y0: i64, x1: i64, y1: i64) -> (u64, u64) {
        let x0 = x0.max(0);
        let y0 = y0.max(0);
        let x1 = x1.min(self.width as i64 - 1);
        let y1 = y1.min(self.height as i64 - 1);
        if x0 > x1 || y0 > y1 {
            return (0, 0);
        }
        let w1 = self.width + 1;
        let s = |x: i64, y: i64| self.sums[y as usize * w1 + x as usize] as i64;
        let c = s(x1 + 1, y1 + 1) - s(x0, y1 + 1) - s(x1 + 1, y0) + s(x0, y0);
        (c as u64, ((x1 - x0 + 1) * (y1 - y0 + 1)) as u64)
    }
}

/// Checks that masks match their images in size and none is empty.
pub(crate) fn check_masks(masks: &[Mask], sizes: &[(u32, u32)], names: &[&str]) -> Result<()> {
    if masks.len() != sizes.len() {
        return Err(Error::CountMismatch {
            what: "silhouettes vs cameras".into(),
            a: masks.len(),
            b: sizes.len(),
        });
    }
    for (i, (m, &(w, h))) in masks.iter().zip(sizes).enumerate() {
        if (m.width, m.height) != (w, h) {
            return Err(Error::SizeMismatch {
                what: format!("silhouette of view {i} ({})", names[i]),
                expected_w: w,
                expected_h: h,
                got_w: m.width,
                got_h: m.height,
            });
        }
        if m.count() == 0 {
            return Err(Error::EmptySilhouette {
                index: i,
                name: names[i].to_string(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn naive(m: &Mask, r: i64, erode: bool) -> Mask {
        Mask::from_fn(m.width, m.height, |x, y| {
            let mut all = true;
            let mut any = false;
            for dy in -r..=r {
                for dx in -r..=r {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= m.width as i64 || yy >= m.height as i64 {
                        continue;
                    }
                    let v = m.get(xx, yy);
                    all &= v;
                    any |= v;
                }
            }
            if erode {
                all
            } else {
                any
            }
        })
    }

    proptest! {
        #[test]
        fn morphology_matches_naive(w in 1u32..20, h in 1u32..20, seed in any::<u64>(), r in 0u32..5) {
            let mut s = seed | 1;
            let m = Mask::from_fn(w, h, |_, _| { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s % 3 == 0 });
            prop_assert_eq!(m.dilate(r), naive(&m, r as i64, false));
            prop_assert_eq!(m.erode(r), naive(&m, r as i64, true));
            let ii = Integral::new(&m);
            let (c, a) = ii.count(-2, 1, w as i64, h as i64 - 2);
            let direct = (0..w as i64).flat_map(|x| (1..(h as i64 - 1)).map(move |y| (x, y))).filter(|&(x, y)| m.get(x, y)).count();
            prop_assert_eq!(c as usize, direct);
            prop_assert_eq!(a, if h >= 3 { w as u64 * (h as u64 - 2) } else { 0 });
        }
    }

    #[test]
    fn threshold_recipe_closes_and_grows() {
        let img = RgbImage::from_fn(60, 60, |x, y| {
            let inside = (20..40).contains(&x) && (20..40).contains(&y) && x != 30;
            image::Rgb(if inside { [10, 60, 0] } else { [20, 20, 20] })
        });
        let m = threshold_silhouette(&img, &SilhouetteParams::default());
        // The one-pixel crack at x = 30 is closed, and the square grew by 10 - 7 = 3 pixels.
        assert!(m.get(30, 30));
        assert_eq!(m.bbox(), Some((17, 17, 42, 42)));
    }
}
