//! Object silhouettes: binary masks by thresholding (the Middlebury recipe) or from a mask image,
//! square-element morphology, and a summed-area table for rectangle queries.

use image::{GrayImage, RgbImage};

use crate::{Error, Result};

/// vt-core's bit-packed mask, the workspace's one mask type. Its morphology
/// ([`Mask::erode`], [`Mask::dilate`]) treats pixels outside the image as not eroding and not
/// dilating (OpenCV's default border), as the Middlebury recipe assumes.
pub use vt_core::Mask;

/// A mask as a grey-level image (255 = set), for saving.
pub fn mask_image(m: &Mask) -> GrayImage {
    GrayImage::from_raw(m.width(), m.height(), m.to_bytes()).expect("one byte per pixel")
}

/// Pixel `i` (row-major) of a mask, read straight from its words (hot loops).
#[inline]
pub fn bit(m: &Mask, i: usize) -> bool {
    (m.words()[i >> 6] >> (i & 63)) & 1 == 1
}

/// A mask as one 0/1 byte per pixel, row-major, for hot loops that index pixels directly.
pub fn mask_bytes(m: &Mask) -> Vec<u8> {
    let mut b = m.to_bytes();
    b.iter_mut().for_each(|v| *v &= 1);
    b
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

impl SilhouetteParams {
    /// Silhouettes to score a withheld view inside: threshold 0.25, dilate 5, erode 5 (a
    /// closing with no net growth). On templeSparseRing the recipe's 0.19 takes in the lit folds
    /// of the black cloth behind the temple (their brightest channel sits at 0.19-0.25 of full
    /// scale, where the temple's own pixels are few and strongly coloured), and its 10/7
    /// closing grows the outline by 3 px and fills the gaps between the columns.
    pub fn scoring() -> Self {
        Self {
            threshold: 0.25,
            dilate: 5,
            erode: 5,
        }
    }
}

/// Silhouette of an object on a dark background: threshold on the max channel, then dilate and
/// erode (a closing that also grows the mask by `dilate - erode` pixels, keeping the visual hull
/// conservative).
pub fn threshold_silhouette(img: &RgbImage, p: &SilhouetteParams) -> Mask {
    let t = p.threshold * 255.0;
    let px = img.as_raw();
    let m = Mask::from_index_fn(img.width(), img.height(), |i| {
        px[3 * i].max(px[3 * i + 1]).max(px[3 * i + 2]) as f64 > t
    });
    m.dilate(p.dilate).erode(p.erode)
}

/// Silhouette from a supplied mask image: non-zero pixels are object.
pub fn mask_from_image(img: &GrayImage) -> Mask {
    let px = img.as_raw();
    Mask::from_index_fn(img.width(), img.height(), |i| px[i] != 0)
}

/// Automatic segmentation of an object on a plain backdrop of any colour (white, grey, green
/// cloth...), estimated from the image border. Fractions are of the image's shorter side, so one
/// setting serves every photo size.
#[derive(Debug, Clone, PartialEq)]
pub struct BackdropParams {
    /// Width of the border band the backdrop is estimated from (0.03 of the shorter side, at
    /// least 2 pixels). The object may touch an edge: the statistics are medians.
    pub border: f64,
    /// A pixel is object when its chromaticity (`rgb / (r + g + b)`) lies farther than this
    /// from the backdrop's (0.045), or farther than `chroma_spread` times the border pixels'
    /// median distance, whichever is larger (sensor noise on a dark backdrop).
    pub chroma: f64,
    /// ... (4: for noise spread evenly about the backdrop's chromaticity, a Rayleigh
    /// distribution, 4 medians are 4.7 standard deviations, 2 in 100,000 pixels).
    pub chroma_spread: f64,
    /// A pixel is object when its brightness is below this ratio of the local backdrop's
    /// brightness (0.62): shading, folds and the object's shadow stay above it.
    pub darker: f64,
    /// ... or above this ratio (1.45).
    pub brighter: f64,
    /// Side of the cells the local backdrop brightness is measured in (0.0625 of the shorter
    /// side): a smooth brightness field, so shading across the cloth is not object.
    pub cell: f64,
    /// Opening radius (0.008 of the shorter side, at least 1): removes creases and specks.
    pub open: f64,
    /// Closing radius (0.012, at least 1): joins the object across thin gaps.
    pub close: f64,
    /// Components smaller than this share of the largest are dropped (0.2); holes (backdrop
    /// enclosed by object) are filled.
    pub keep: f64,
    /// Components lying along the image edge are clutter beyond the backdrop (the floor, a
    /// cloth's end), not the object: a component whose pixels on the image's outermost rows
    /// and columns exceed this share of its bounding box's perimeter is dropped (0.4; a corner
    /// wedge or an edge strip has about 0.5, an object standing on the bottom edge less),
    /// unless nothing else is left.
    pub edge_contact: f64,
}

impl Default for BackdropParams {
    fn default() -> Self {
        Self {
            border: 0.03,
            chroma: 0.045,
            chroma_spread: 4.0,
            darker: 0.62,
            brighter: 1.45,
            cell: 0.0625,
            open: 0.004,
            close: 0.012,
            keep: 0.2,
            edge_contact: 0.4,
        }
    }
}

/// The backdrop as [`backdrop_silhouette`] estimated it (for the log and tests).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backdrop {
    /// Median colour of the border band.
    pub colour: [u8; 3],
    /// Its brightness ((r + g + b) / 3).
    pub brightness: f64,
    /// The chromaticity distance above which a pixel is object.
    pub chroma_threshold: f64,
}

/// Median colour of the border band of `img` (band `band` pixels wide).
fn border_pixels(img: &RgbImage, band: u32) -> Vec<[u8; 3]> {
    let (w, h) = img.dimensions();
    let b = band.min(w / 2).min(h / 2).max(1);
    let mut v = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if x < b || y < b || x + b >= w || y + b >= h {
                v.push(img.get_pixel(x, y).0);
            }
        }
    }
    v
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let m = v.len() / 2;
    *v.select_nth_unstable_by(m, f64::total_cmp).1
}

fn chroma(p: [u8; 3]) -> [f64; 3] {
    let s = p[0] as f64 + p[1] as f64 + p[2] as f64 + 3.0;
    [
        (p[0] as f64 + 1.0) / s,
        (p[1] as f64 + 1.0) / s,
        (p[2] as f64 + 1.0) / s,
    ]
}

fn brightness(p: [u8; 3]) -> f64 {
    (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0
}

fn chroma_dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn radius(frac: f64, short: u32) -> u32 {
    ((frac * short as f64).round() as u32).max(1)
}

/// The photos' backdrop: the per-channel median colour of the pixels outside their silhouettes
/// (every 4th pixel, row-major), `None` when no pixel lies outside. Photos with an alpha channel
/// were composited over the data's background, which this gives back exactly.
pub fn colour_outside(images: &[RgbImage], masks: &[Mask]) -> Option<[u8; 3]> {
    let mut hist = [[0u64; 256]; 3];
    for (img, m) in images.iter().zip(masks) {
        if img.dimensions() != (m.width(), m.height()) {
            continue;
        }
        let raw = img.as_raw();
        for i in (0..raw.len() / 3).step_by(4) {
            if !bit(m, i) {
                for c in 0..3 {
                    hist[c][raw[3 * i + c] as usize] += 1;
                }
            }
        }
    }
    let n: u64 = hist[0].iter().sum();
    (n > 0).then(|| {
        hist.map(|h| {
            let mut acc = 0;
            h.iter()
                .position(|&k| {
                    acc += k;
                    2 * acc > n
                })
                .unwrap_or(0) as u8
        })
    })
}

/// Median brightness of the border band of a photo and the largest channel's median there:
/// what decides between the dark-backdrop threshold and [`backdrop_silhouette`].
pub fn border_level(img: &RgbImage, p: &BackdropParams) -> f64 {
    let short = img.width().min(img.height());
    let px = border_pixels(img, radius(p.border, short).max(2));
    median(px.iter().map(|q| q[0].max(q[1]).max(q[2]) as f64).collect())
}

/// Estimates the backdrop of `img` from its border band.
pub fn estimate_backdrop(img: &RgbImage, p: &BackdropParams) -> Backdrop {
    let short = img.width().min(img.height());
    let px = border_pixels(img, radius(p.border, short).max(2));
    let colour = [0, 1, 2].map(|c| median(px.iter().map(|q| q[c] as f64).collect()) as u8);
    let c0 = chroma(colour);
    let spread = median(px.iter().map(|&q| chroma_dist(chroma(q), c0)).collect());
    Backdrop {
        colour,
        brightness: median(px.iter().map(|&q| brightness(q)).collect()),
        chroma_threshold: p.chroma.max(p.chroma_spread * spread),
    }
}

/// Silhouette of an object on a plain backdrop of any colour ([`BackdropParams`]): the
/// backdrop's colour from the border band (medians), its brightness as a smooth field measured
/// in cells over the pixels that look like backdrop (cells the object covers filled from their
/// neighbours), each pixel object when its chromaticity is far from the backdrop's or its
/// brightness ratio to the local backdrop is outside `[darker, brighter]`; then an opening, a
/// closing, small components dropped and holes filled.
pub fn backdrop_silhouette(img: &RgbImage, p: &BackdropParams) -> Mask {
    let (w, h) = img.dimensions();
    let (wu, hu) = (w as usize, h as usize);
    let short = w.min(h);
    let bd = estimate_backdrop(img, p);
    let c0 = chroma(bd.colour);
    let l0 = bd.brightness.max(1.0);
    let px = img.as_raw();
    let pix = |i: usize| [px[3 * i], px[3 * i + 1], px[3 * i + 2]];
    let off_chroma = |q: [u8; 3]| chroma_dist(chroma(q), c0) > bd.chroma_threshold;
    // Provisional backdrop: the global brightness, generous bounds.
    let looks_backdrop = |q: [u8; 3]| {
        let r = brightness(q) / l0;
        !off_chroma(q) && (0.75..=1.3).contains(&r)
    };
    // The local brightness field: median per cell of the provisional backdrop pixels.
    let cs = radius(p.cell, short).max(4) as usize;
    let (gw, gh) = (wu.div_ceil(cs), hu.div_ceil(cs));
    let mut field: Vec<Option<f64>> = vec![None; gw * gh];
    for gy in 0..gh {
        for gx in 0..gw {
            let mut v = Vec::with_capacity(cs * cs);
            for y in gy * cs..((gy + 1) * cs).min(hu) {
                for x in gx * cs..((gx + 1) * cs).min(wu) {
                    let q = pix(y * wu + x);
                    if looks_backdrop(q) {
                        v.push(brightness(q));
                    }
                }
            }
            let area = (((gy + 1) * cs).min(hu) - gy * cs) * (((gx + 1) * cs).min(wu) - gx * cs);
            if v.len() * 5 >= area * 2 {
                field[gy * gw + gx] = Some(median(v));
            }
        }
    }
    // Cells without enough backdrop take the mean of their measured neighbours, ring by ring.
    for _ in 0..gw.max(gh) {
        if field.iter().all(Option::is_some) {
            break;
        }
        let prev = field.clone();
        for gy in 0..gh {
            for gx in 0..gw {
                if prev[gy * gw + gx].is_some() {
                    continue;
                }
                let (mut s, mut n) = (0.0, 0);
                for (dx, dy) in [
                    (-1i64, 0i64),
                    (1, 0),
                    (0, -1),
                    (0, 1),
                    (-1, -1),
                    (1, 1),
                    (-1, 1),
                    (1, -1),
                ] {
                    let (x, y) = (gx as i64 + dx, gy as i64 + dy);
                    if x >= 0 && y >= 0 && (x as usize) < gw && (y as usize) < gh {
                        if let Some(v) = prev[y as usize * gw + x as usize] {
                            s += v;
                            n += 1;
                        }
                    }
                }
                if n > 0 {
                    field[gy * gw + gx] = Some(s / n as f64);
                }
            }
        }
    }
    let field: Vec<f64> = field
        .into_iter()
        .map(|v| v.unwrap_or(l0).clamp(0.7 * l0, 1.4 * l0))
        .collect();
    // Bilinear between cell centres.
    let local = |x: usize, y: usize| {
        let fx = ((x as f64 + 0.5) / cs as f64 - 0.5).clamp(0.0, (gw - 1) as f64);
        let fy = ((y as f64 + 0.5) / cs as f64 - 0.5).clamp(0.0, (gh - 1) as f64);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(gw - 1), (y0 + 1).min(gh - 1));
        let (ax, ay) = (fx - x0 as f64, fy - y0 as f64);
        let f = |x: usize, y: usize| field[y * gw + x];
        (f(x0, y0) * (1.0 - ax) + f(x1, y0) * ax) * (1.0 - ay)
            + (f(x0, y1) * (1.0 - ax) + f(x1, y1) * ax) * ay
    };
    let raw = Mask::from_index_fn(w, h, |i| {
        let q = pix(i);
        let r = brightness(q) / local(i % wu, i / wu);
        off_chroma(q) || r < p.darker || r > p.brighter
    });
    let m = raw
        .open(radius(p.open, short))
        .close(radius(p.close, short));
    fill_holes(&keep_large_components(&m, p.keep, p.edge_contact))
}

/// 4-connected components of the set (or, with `set = false`, the clear) pixels: a label per
/// pixel (`u32::MAX` for the others) and each component's size.
fn components(m: &Mask, set: bool) -> (Vec<u32>, Vec<usize>) {
    let (w, h) = (m.width() as usize, m.height() as usize);
    let bytes = mask_bytes(m);
    let mut label = vec![u32::MAX; w * h];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if (bytes[start] == 1) != set || label[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        label[start] = id;
        stack.push(start);
        let mut n = 0;
        while let Some(i) = stack.pop() {
            n += 1;
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if (bytes[j] == 1) == set && label[j] == u32::MAX {
                    label[j] = id;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        sizes.push(n);
    }
    (label, sizes)
}

/// Keeps the 4-connected components of `m` that do not lie along the image edge (pixels on the
/// outermost rows and columns above `edge_contact` of their bounding box's perimeter; all of
/// them when every component does) and are at least `share` of the largest kept one's size.
pub fn keep_large_components(m: &Mask, share: f64, edge_contact: f64) -> Mask {
    let (w, h) = (m.width() as usize, m.height() as usize);
    let (label, sizes) = components(m, true);
    if sizes.is_empty() {
        return m.clone();
    }
    let n = sizes.len();
    let (mut contact, mut bbox) = (vec![0usize; n], vec![(usize::MAX, usize::MAX, 0, 0); n]);
    for (i, &l) in label.iter().enumerate() {
        if l == u32::MAX {
            continue;
        }
        let (x, y) = (i % w, i / w);
        let l = l as usize;
        if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
            contact[l] += 1;
        }
        let b = &mut bbox[l];
        *b = (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y));
    }
    let inner: Vec<bool> = (0..n)
        .map(|l| {
            let (x0, y0, x1, y1) = bbox[l];
            let perimeter = 2 * (x1 - x0 + 1 + y1 - y0 + 1);
            contact[l] as f64 <= edge_contact * perimeter as f64
        })
        .collect();
    let any_inner = inner.iter().any(|&b| b);
    let candidate = |l: usize| inner[l] || !any_inner;
    let largest = (0..n)
        .filter(|&l| candidate(l))
        .map(|l| sizes[l])
        .max()
        .unwrap_or(0);
    let keep: Vec<bool> = (0..n)
        .map(|l| candidate(l) && sizes[l] as f64 >= share * largest as f64)
        .collect();
    Mask::from_index_fn(m.width(), m.height(), |i| {
        label[i] != u32::MAX && keep[label[i] as usize]
    })
}

/// Fills the holes of `m`: clear regions that do not reach the image border become set.
pub fn fill_holes(m: &Mask) -> Mask {
    let (w, h) = (m.width() as usize, m.height() as usize);
    let (label, sizes) = components(m, false);
    let mut outside = vec![false; sizes.len()];
    for x in 0..w {
        for y in [0, h.saturating_sub(1)] {
            if let Some(&l) = label.get(y * w + x).filter(|&&l| l != u32::MAX) {
                outside[l as usize] = true;
            }
        }
    }
    for y in 0..h {
        for x in [0, w.saturating_sub(1)] {
            if let Some(&l) = label.get(y * w + x).filter(|&&l| l != u32::MAX) {
                outside[l as usize] = true;
            }
        }
    }
    Mask::from_index_fn(m.width(), m.height(), |i| {
        label[i] == u32::MAX || !outside[label[i] as usize]
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
        let (w, h) = (m.width() as usize, m.height() as usize);
        let bytes = mask_bytes(m);
        let mut sums = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += bytes[y * w + x] as u32;
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
        if (m.width(), m.height()) != (w, h) {
            return Err(vt_core::Error::SizeMismatch {
                what: format!("silhouette of view {i} ({})", names[i]),
                expected_w: w,
                expected_h: h,
                got_w: m.width(),
                got_h: m.height(),
            }
            .into());
        }
        if m.count_ones() == 0 {
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

    #[test]
    fn the_backdrop_is_the_median_colour_outside_the_silhouettes() {
        // Two 8x8 photos: a red square inside each silhouette, white outside but for a few
        // dark pixels (a shadow), which the median ignores.
        let sil = Mask::from_fn(8, 8, |x, y| (2..6).contains(&x) && (2..6).contains(&y));
        let photo = |shadow: u32| {
            RgbImage::from_fn(8, 8, |x, y| match (sil.get(x, y), y * 8 + x < shadow) {
                (true, _) => image::Rgb([200, 0, 0]),
                (false, true) => image::Rgb([10, 10, 10]),
                (false, false) => image::Rgb([250, 251, 252]),
            })
        };
        let both = [photo(4), photo(0)];
        let masks = [sil.clone(), sil.clone()];
        assert_eq!(colour_outside(&both, &masks), Some([250, 251, 252]));
        // No pixel outside: unknown.
        let full = Mask::from_fn(8, 8, |_, _| true);
        assert_eq!(colour_outside(&both[..1], &[full]), None);
    }

    fn naive(m: &Mask, r: i64, erode: bool) -> Mask {
        Mask::from_fn(m.width(), m.height(), |x, y| {
            let mut all = true;
            let mut any = false;
            for dy in -r..=r {
                for dx in -r..=r {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= m.width() as i64 || yy >= m.height() as i64 {
                        continue;
                    }
                    let v = m.get_or_false(xx, yy);
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
            let direct = (0..w as i64).flat_map(|x| (1..(h as i64 - 1)).map(move |y| (x, y))).filter(|&(x, y)| m.get_or_false(x, y)).count();
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
        assert_eq!(m.bounding_box(), Some((17, 17, 43, 43))); // exclusive upper bounds
    }
}
