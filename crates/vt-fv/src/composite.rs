//! Photos and new views with a background: a photo's alpha channel composited over a colour,
//! and a new view's coverage as a soft-edged alpha (for a PNG with transparency, or composited
//! over the data's background as the NeRF benchmarks score it).

use image::{RgbImage, RgbaImage};

use crate::silhouette::Mask;

/// What new views' uncovered pixels (and photos' transparent ones) become.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Background {
    /// The data's own: white for NeRF transforms files (as the NeRF synthetic data is scored),
    /// transparent for the other formats.
    #[default]
    Data,
    /// Transparent: photos keep their colours, a PNG view gets its coverage as alpha (black
    /// where the format has no alpha).
    Transparent,
    /// This colour: photos with an alpha channel are composited over it, and so are new views.
    Colour([u8; 3]),
}

impl std::str::FromStr for Background {
    type Err = String;

    /// `data`, `transparent` (or `none`), `white`, `black`, `grey`, `#rrggbb` or `r,g,b`
    /// (0..255 each).
    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim().to_ascii_lowercase();
        let colour = |c| Ok(Background::Colour(c));
        match t.as_str() {
            "data" => return Ok(Background::Data),
            "transparent" | "none" => return Ok(Background::Transparent),
            "white" => return colour([255; 3]),
            "black" => return colour([0; 3]),
            "grey" | "gray" => return colour([128; 3]),
            _ => {}
        }
        let bad = || {
            format!("{s:?}: a background is data, transparent, white, black, grey, #rrggbb or r,g,b (0..255)")
        };
        if let Some(hex) = t.strip_prefix('#') {
            if hex.len() != 6 || !hex.chars().all(|c| c.is_ascii_hexdigit()) {
                return Err(bad());
            }
            let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
            return colour([byte(0)?, byte(2)?, byte(4)?]);
        }
        let parts: Vec<&str> = t.split(',').collect();
        if parts.len() != 3 {
            return Err(bad());
        }
        let c: Vec<u8> = parts
            .iter()
            .map(|p| p.trim().parse::<u8>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        colour([c[0], c[1], c[2]])
    }
}

/// `rgba` (straight alpha) composited over `bg`: `c a + bg (1 - a)`, rounded.
pub fn over(rgba: &RgbaImage, bg: [u8; 3]) -> RgbImage {
    RgbImage::from_fn(rgba.width(), rgba.height(), |x, y| {
        let p = rgba.get_pixel(x, y).0;
        let a = p[3] as u32;
        image::Rgb(std::array::from_fn(|c| {
            ((p[c] as u32 * a + bg[c] as u32 * (255 - a) + 127) / 255) as u8
        }))
    })
}

/// A new view's alpha from its coverage, with anti-aliased edges: each pixel's alpha is the
/// share of covered pixels in its 3x3 neighbourhood (edge pixels replicated), so a straight
/// outline keeps its place on average and steps soften as a renderer's coverage would. Inside
/// the coverage and away from it alpha is 1 and 0 exactly.
pub fn soft_alpha(coverage: &Mask) -> Vec<u8> {
    let (w, h) = (coverage.width() as i64, coverage.height() as i64);
    let at = |x: i64, y: i64| coverage.get(x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32);
    let mut out = vec![0u8; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let mut n = 0u32;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    n += at(x + dx, y + dy) as u32;
                }
            }
            out[(y * w + x) as usize] = ((n * 255 + 4) / 9) as u8;
        }
    }
    out
}

/// The colour of every pixel that `alpha` gives some weight: the view's own where covered, the
/// mean of the covered 8-neighbours just outside the coverage (whose own colour is no colour).
fn edge_filled(img: &RgbImage, coverage: &Mask, alpha: &[u8]) -> RgbImage {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let mut out = img.clone();
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if alpha[i] == 0 || coverage.get(x as u32, y as u32) {
                continue;
            }
            let (mut sum, mut n) = ([0u32; 3], 0u32);
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (u, v) = (x + dx, y + dy);
                    if u < 0 || v < 0 || u >= w || v >= h || !coverage.get(u as u32, v as u32) {
                        continue;
                    }
                    let p = img.get_pixel(u as u32, v as u32).0;
                    for c in 0..3 {
                        sum[c] += p[c] as u32;
                    }
                    n += 1;
                }
            }
            if n > 0 {
                let p = std::array::from_fn(|c| ((sum[c] + n / 2) / n) as u8);
                out.put_pixel(x as u32, y as u32, image::Rgb(p));
            }
        }
    }
    out
}

/// A new view with its coverage as a soft alpha channel ([`soft_alpha`]), for compositing.
pub fn with_alpha(img: &RgbImage, coverage: &Mask) -> RgbaImage {
    let alpha = soft_alpha(coverage);
    let colour = edge_filled(img, coverage, &alpha);
    RgbaImage::from_fn(img.width(), img.height(), |x, y| {
        let p = colour.get_pixel(x, y).0;
        image::Rgba([p[0], p[1], p[2], alpha[(y * img.width() + x) as usize]])
    })
}

/// A new view composited over `bg` through its soft alpha: what a viewer sees on that
/// background, and what the NeRF benchmarks score.
pub fn onto(img: &RgbImage, coverage: &Mask, bg: [u8; 3]) -> RgbImage {
    over(&with_alpha(img, coverage), bg)
}

/// A new view as shown on `background`: composited over it ([`onto`]), or as it is (black
/// where uncovered) without one.
pub fn placed<'a>(
    img: &'a RgbImage,
    coverage: &Mask,
    background: Option<[u8; 3]>,
) -> std::borrow::Cow<'a, RgbImage> {
    match background {
        Some(bg) => std::borrow::Cow::Owned(onto(img, coverage, bg)),
        None => std::borrow::Cow::Borrowed(img),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backgrounds_parse() {
        for (s, b) in [
            ("white", Background::Colour([255; 3])),
            ("#FF8000", Background::Colour([255, 128, 0])),
            ("0, 10,255", Background::Colour([0, 10, 255])),
            ("none", Background::Transparent),
            ("data", Background::Data),
        ] {
            assert_eq!(s.parse::<Background>(), Ok(b), "{s}");
        }
        for s in ["#12345", "1,2", "1,2,256", "purple", "#gg0000"] {
            let e = s.parse::<Background>().unwrap_err();
            assert!(e.contains(s) && e.contains("#rrggbb"), "{e}");
        }
    }

    #[test]
    fn over_mixes_by_alpha() {
        let mut rgba = RgbaImage::new(3, 1);
        rgba.put_pixel(0, 0, image::Rgba([10, 20, 30, 255]));
        rgba.put_pixel(1, 0, image::Rgba([200, 0, 0, 0]));
        rgba.put_pixel(2, 0, image::Rgba([0, 0, 0, 51]));
        let out = over(&rgba, [255, 255, 255]);
        assert_eq!(out.get_pixel(0, 0).0, [10, 20, 30]);
        assert_eq!(out.get_pixel(1, 0).0, [255, 255, 255]);
        // 0.2 black over white: 204.
        assert_eq!(out.get_pixel(2, 0).0, [204, 204, 204]);
    }

    #[test]
    fn soft_alpha_is_exact_inside_and_out_and_soft_on_the_edge() {
        // The left half of an 8x4 image covered.
        let m = Mask::from_index_fn(8, 4, |i| i % 8 < 4);
        let a = soft_alpha(&m);
        let row: Vec<u8> = a[8..16].to_vec();
        // 3 of 9 covered just outside, 6 of 9 just inside.
        assert_eq!(row, vec![255, 255, 255, 170, 85, 0, 0, 0]);
        // The outline's place: the alpha sums to the covered count.
        let total: u32 = a.iter().map(|&x| x as u32).sum();
        assert_eq!(total, 16 * 255);
    }

    #[test]
    fn onto_keeps_covered_colours_and_fills_the_rest_with_the_background() {
        let m = Mask::from_index_fn(8, 4, |i| i % 8 < 4);
        let img = RgbImage::from_fn(8, 4, |x, _| {
            if x < 4 {
                image::Rgb([100, 50, 0])
            } else {
                image::Rgb([0, 0, 0])
            }
        });
        let out = onto(&img, &m, [255, 255, 255]);
        assert_eq!(out.get_pixel(0, 1).0, [100, 50, 0]);
        assert_eq!(out.get_pixel(7, 1).0, [255, 255, 255]);
        // Just outside: a third of the view's colour (not of black) over white.
        assert_eq!(out.get_pixel(4, 1).0, [203, 187, 170]);
    }
}
