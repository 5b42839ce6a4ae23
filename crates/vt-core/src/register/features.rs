//! Features and matching: FAST-9 corners on a pyramid, steered BRIEF descriptors, mutual-best matches.

use super::*;

/// A feature: position in full-resolution pixels, orientation, level and descriptor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    /// Position (pixel centres at integers).
    pub pos: Point,
    /// Orientation, radians (image coordinates, y down).
    pub angle: f32,
    /// Pyramid level.
    pub level: u8,
    /// FAST score.
    pub score: f32,
    /// Steered BRIEF, 256 bits.
    pub descriptor: [u64; 4],
}

/// BRIEF offsets are at most this far from the centre (per coordinate).
const PATTERN_CLIP: i32 = 13;
/// Half size of a BRIEF box.
const BOX_HALF: i32 = 2;
/// Radius of the orientation disc.
const ORIENT_RADIUS: i32 = 15;
/// Border kept free at every level: a rotated offset and its box, or the orientation disc.
const EDGE: u32 = 22;

/// The 256 BRIEF test pairs, drawn once (deterministically) from a Gaussian of sigma 31/5.
fn pattern() -> &'static [[f32; 4]; 256] {
    static PATTERN: std::sync::OnceLock<[[f32; 4]; 256]> = std::sync::OnceLock::new();
    PATTERN.get_or_init(|| {
        let mut rng = crate::rng::Rng::new(0xB81E_F000);
        let mut draw = || loop {
            let v = (rng.normal() * 31.0 / 5.0).round();
            if v.abs() <= PATTERN_CLIP as f64 {
                return v as f32;
            }
        };
        let mut p = [[0.0f32; 4]; 256];
        for t in p.iter_mut() {
            *t = [draw(), draw(), draw(), draw()];
        }
        p
    })
}

/// Grey level of an RGB image (BT.601 weights, as OpenCV's `COLOR_RGB2GRAY`).
pub fn grey(img: &RgbImage) -> GrayImage {
    let (w, h) = img.dimensions();
    let mut out = GrayImage::new(w, h);
    for (o, p) in out.as_mut().iter_mut().zip(img.as_raw().chunks_exact(3)) {
        let v = 4899 * p[0] as u32 + 9617 * p[1] as u32 + 1868 * p[2] as u32;
        *o = ((v + 8192) >> 14) as u8;
    }
    out
}

/// Summed-area table with a zero first row and column.
struct Integral {
    w: usize,
    v: Vec<u32>,
}

impl Integral {
    fn new(img: &GrayImage) -> Self {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let mut v = vec![0u32; (w + 1) * (h + 1)];
        let raw = img.as_raw();
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += raw[y * w + x] as u32;
                v[(y + 1) * (w + 1) + x + 1] = v[y * (w + 1) + x + 1] + row;
            }
        }
        Self { w: w + 1, v }
    }

    /// Sum of the (2 BOX_HALF + 1)^2 box centred at (x, y) (inside the image by the caller).
    #[inline(always)]
    fn box_sum(&self, x: i32, y: i32) -> u32 {
        let (x0, y0) = ((x - BOX_HALF) as usize, (y - BOX_HALF) as usize);
        let (x1, y1) = ((x + BOX_HALF + 1) as usize, (y + BOX_HALF + 1) as usize);
        let w = self.w;
        self.v[y1 * w + x1] + self.v[y0 * w + x0] - self.v[y0 * w + x1] - self.v[y1 * w + x0]
    }
}

/// Orientation of the patch at (x, y) by its intensity centroid over a disc.
fn orientation(img: &GrayImage, x: u32, y: u32) -> f32 {
    let (w, raw) = (img.width() as i64, img.as_raw());
    let (mut m10, mut m01) = (0i64, 0i64);
    let r = ORIENT_RADIUS as i64;
    for dy in -r..=r {
        let half = ((r * r - dy * dy) as f64).sqrt() as i64;
        let row = (y as i64 + dy) * w;
        for dx in -half..=half {
            let v = raw[(row + x as i64 + dx) as usize] as i64;
            m10 += dx * v;
            m01 += dy * v;
        }
    }
    (m01 as f32).atan2(m10 as f32)
}

/// The steered BRIEF descriptor of the feature at (x, y) with `angle`, through
/// [`crate::simd::dispatch`]: its rounding then compiles to an instruction rather than a call
/// (the same bits on every path).
fn descriptor(ii: &Integral, x: i32, y: i32, angle: f32) -> [u64; 4] {
    crate::simd::dispatch(Descriptor { ii, x, y, angle })
}

struct Descriptor<'a> {
    ii: &'a Integral,
    x: i32,
    y: i32,
    angle: f32,
}

impl crate::simd::Kernel for Descriptor<'_> {
    type Output = [u64; 4];

    #[inline(always)]
    fn run(self) -> [u64; 4] {
        let Descriptor { ii, x, y, angle } = self;
        let (s, c) = angle.sin_cos();
        let mut d = [0u64; 4];
        for (i, t) in pattern().iter().enumerate() {
            let a = ii.box_sum(
                x + (c * t[0] - s * t[1]).round() as i32,
                y + (s * t[0] + c * t[1]).round() as i32,
            );
            let b = ii.box_sum(
                x + (c * t[2] - s * t[3]).round() as i32,
                y + (s * t[2] + c * t[3]).round() as i32,
            );
            if a < b {
                d[i / 64] |= 1 << (i % 64);
            }
        }
        d
    }
}

/// Detects up to `params.max_features` oriented features with steered BRIEF descriptors.
pub fn detect(img: &GrayImage, params: &RegisterParams) -> Vec<Feature> {
    let (w0, h0) = img.dimensions();
    let mut levels = vec![img.clone()];
    for l in 1..params.levels.clamp(1, 8) {
        let f = params.scale.powi(l as i32);
        let (w, h) = (
            (w0 as f64 / f).round() as u32,
            (h0 as f64 / f).round() as u32,
        );
        if w < 4 * EDGE || h < 4 * EDGE {
            break;
        }
        levels.push(image::imageops::resize(
            img,
            w,
            h,
            image::imageops::FilterType::Triangle,
        ));
    }
    // Share of the features per level, proportional to its area (as ORB does).
    let areas: Vec<f64> = levels
        .iter()
        .map(|l| l.width() as f64 * l.height() as f64)
        .collect();
    let total: f64 = areas.iter().sum();
    let per_level: Vec<Vec<Feature>> = levels
        .par_iter()
        .enumerate()
        .map(|(l, li)| {
            let want = ((params.max_features as f64 * areas[l] / total).ceil() as usize).max(1);
            level_features(li, l as u8, want, params.fast_threshold, (w0, h0))
        })
        .collect();
    per_level.into_iter().flatten().collect()
}

fn level_features(
    img: &GrayImage,
    level: u8,
    want: usize,
    threshold: u8,
    full: (u32, u32),
) -> Vec<Feature> {
    let (w, h) = img.dimensions();
    if w <= 2 * EDGE || h <= 2 * EDGE {
        return Vec::new();
    }
    let corners = imageproc::corners::corners_fast9(img, threshold);
    // 3x3 non-maximum suppression on the score (ties to the first in raster order).
    let mut score = vec![0f32; (w * h) as usize];
    for c in &corners {
        score[(c.y * w + c.x) as usize] = c.score + 1.0;
    }
    let idx = |x: u32, y: u32| (y * w + x) as usize;
    let mut kept: Vec<(u32, u32, f32)> = corners
        .iter()
        .filter(|c| c.x >= EDGE && c.y >= EDGE && c.x < w - EDGE && c.y < h - EDGE)
        .filter(|c| {
            let s = score[idx(c.x, c.y)];
            (-1i32..=1).all(|dy| {
                (-1i32..=1).all(|dx| {
                    if dx == 0 && dy == 0 {
                        return true;
                    }
                    let o = score[idx((c.x as i32 + dx) as u32, (c.y as i32 + dy) as u32)];
                    o < s || (o == s && (dy > 0 || (dy == 0 && dx > 0)))
                })
            })
        })
        .map(|c| (c.x, c.y, c.score))
        .collect();
    // Spread: the strongest per cell of a grid with about 4x the wanted count of cells... each
    // cell keeps its share, the rest by score.
    let cells = 16u32;
    let (cw, ch) = (w.div_ceil(cells), h.div_ceil(cells));
    kept.sort_by(|a, b| b.2.total_cmp(&a.2).then((a.1, a.0).cmp(&(b.1, b.0))));
    let per_cell = want.div_ceil((cells * cells) as usize).max(1);
    let mut count = vec![0usize; (cells * cells) as usize];
    let mut chosen = Vec::with_capacity(want);
    let mut rest = Vec::new();
    for k in kept {
        let c = ((k.1 / ch) * cells + k.0 / cw) as usize;
        if count[c] < per_cell && chosen.len() < want {
            count[c] += 1;
            chosen.push(k);
        } else {
            rest.push(k);
        }
    }
    for k in rest {
        if chosen.len() >= want {
            break;
        }
        chosen.push(k);
    }
    let ii = Integral::new(img);
    let (fx, fy) = (full.0 as f64 / w as f64, full.1 as f64 / h as f64);
    chosen
        .into_iter()
        .map(|(x, y, s)| {
            let angle = orientation(img, x, y);
            Feature {
                pos: Point::new((x as f64 + 0.5) * fx - 0.5, (y as f64 + 0.5) * fy - 0.5),
                angle,
                level,
                score: s,
                descriptor: descriptor(&ii, x as i32, y as i32, angle),
            }
        })
        .collect()
}

#[inline]
fn hamming(a: &[u64; 4], b: &[u64; 4]) -> u32 {
    (a[0] ^ b[0]).count_ones()
        + (a[1] ^ b[1]).count_ones()
        + (a[2] ^ b[2]).count_ones()
        + (a[3] ^ b[3]).count_ones()
}

/// Best and second-best distance and the best's index of `d` among `set`.
fn nearest(d: &[u64; 4], set: &[Feature]) -> (u32, u32, usize) {
    let (mut b1, mut b2, mut bi) = (u32::MAX, u32::MAX, usize::MAX);
    for (j, f) in set.iter().enumerate() {
        let h = hamming(d, &f.descriptor);
        if h < b1 {
            (b2, b1, bi) = (b1, h, j);
        } else if h < b2 {
            b2 = h;
        }
    }
    (b1, b2, bi)
}

/// Matches by Hamming distance: `(i, j)` when `b[j]` is `a[i]`'s best and `a[i]` is `b[j]`'s,
/// the best is at most `max_distance` and below `ratio` times the second best.
pub fn match_features(
    a: &[Feature],
    b: &[Feature],
    ratio: f32,
    max_distance: u32,
) -> Vec<(usize, usize)> {
    let fwd: Vec<(u32, u32, usize)> = a.par_iter().map(|f| nearest(&f.descriptor, b)).collect();
    let back: Vec<usize> = b.par_iter().map(|f| nearest(&f.descriptor, a).2).collect();
    fwd.iter()
        .enumerate()
        .filter(|&(i, &(d1, d2, j))| {
            j != usize::MAX
                && back[j] == i
                && d1 <= max_distance
                && (d2 == u32::MAX || (d1 as f32) < ratio * d2 as f32)
        })
        .map(|(i, &(_, _, j))| (i, j))
        .collect()
}
