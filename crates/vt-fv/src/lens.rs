//! Lens distortion of calibrated photos (COLMAP's SIMPLE_RADIAL, RADIAL and OPENCV models) and
//! its removal: a photo taken through a distorting lens is resampled on load into the ideal
//! pinhole camera `K [R | t]` that every other part of vt-fv assumes, so the hull, photo hull and
//! renderers stay exact and free of distortion terms.
//!
//! Distortion acts on normalised camera coordinates `(x, y) = (X / Z, Y / Z)` as COLMAP defines
//! it (`colmap/sensor/models.h`): with `r^2 = x^2 + y^2`,
//! - radial: `(x, y) (1 + k1 r^2 + k2 r^4)`;
//! - OpenCV: radial as above plus tangential `dx = 2 p1 x y + p2 (r^2 + 2 x^2)`,
//!   `dy = 2 p2 x y + p1 (r^2 + 2 y^2)`.
//!
//! Pixels are then `K (x_d, y_d, 1)`.

use image::RgbImage;
use nalgebra::{Matrix3, Vector3};

use crate::silhouette::Mask;

/// A lens distortion model; `None` is an ideal pinhole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lens {
    /// No distortion.
    None,
    /// Radial, up to two coefficients (`k2` is 0 for SIMPLE_RADIAL).
    Radial {
        /// `r^2` coefficient.
        k1: f64,
        /// `r^4` coefficient.
        k2: f64,
    },
    /// OpenCV's radial and tangential model (COLMAP's OPENCV camera).
    OpenCv {
        /// `r^2` coefficient.
        k1: f64,
        /// `r^4` coefficient.
        k2: f64,
        /// First tangential coefficient.
        p1: f64,
        /// Second tangential coefficient.
        p2: f64,
    },
}

impl Lens {
    /// Whether the lens leaves every point where it is.
    pub fn is_identity(&self) -> bool {
        match *self {
            Lens::None => true,
            Lens::Radial { k1, k2 } => k1 == 0.0 && k2 == 0.0,
            Lens::OpenCv { k1, k2, p1, p2 } => k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0,
        }
    }

    /// The distorted normalised coordinates of the ideal ones `(x, y)`.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        match *self {
            Lens::None => (x, y),
            Lens::Radial { k1, k2 } => {
                let r2 = x * x + y * y;
                let f = 1.0 + k1 * r2 + k2 * r2 * r2;
                (x * f, y * f)
            }
            Lens::OpenCv { k1, k2, p1, p2 } => {
                let (x2, y2, xy) = (x * x, y * y, x * y);
                let r2 = x2 + y2;
                let f = 1.0 + k1 * r2 + k2 * r2 * r2;
                (
                    x * f + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2),
                    y * f + 2.0 * p2 * xy + p1 * (r2 + 2.0 * y2),
                )
            }
        }
    }

    /// The ideal normalised coordinates whose distortion is `(xd, yd)`, by Newton's method on
    /// the 2x2 Jacobian (numerical); `None` when it does not converge to 1e-12.
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        if self.is_identity() {
            return Some((xd, yd));
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..100 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-12 && ey.abs() < 1e-12 {
                return Some((x, y));
            }
            let h = 1e-7;
            let (ax, ay) = self.distort(x + h, y);
            let (bx, by) = self.distort(x, y + h);
            let (j11, j21, j12, j22) = ((ax - fx) / h, (ay - fy) / h, (bx - fx) / h, (by - fy) / h);
            let det = j11 * j22 - j12 * j21;
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            x -= (j22 * ex - j12 * ey) / det;
            y -= (-j21 * ex + j11 * ey) / det;
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
        }
        None
    }
}

/// A resampling of a photo taken by `(k_src, lens)` into the ideal pinhole `k_out` of size
/// `w x h` (same pose): for each output pixel, its ray `k_out^-1 (u, v, 1)` distorted by the lens
/// and projected by `k_src` gives the source position. Positions outside the source take the
/// nearest edge pixel (the few corner pixels a pincushion lens leaves uncovered).
#[derive(Debug, Clone)]
pub struct Resample {
    w: u32,
    h: u32,
    /// Source position of each output pixel, row-major.
    map: Vec<(f32, f32)>,
}

impl Resample {
    /// The map for a source photo `k_src` with `lens`, output `k_out` at `w x h`. `k_out` must
    /// be invertible (a [`crate::Camera`]'s `K` is).
    pub fn new(k_src: &Matrix3<f64>, lens: &Lens, k_out: &Matrix3<f64>, w: u32, h: u32) -> Self {
        let kinv = k_out.try_inverse().unwrap_or_else(Matrix3::identity);
        let mut map = Vec::with_capacity(w as usize * h as usize);
        for y in 0..h {
            for x in 0..w {
                let n = kinv * Vector3::new(x as f64, y as f64, 1.0);
                let (xd, yd) = lens.distort(n.x / n.z, n.y / n.z);
                let p = k_src * Vector3::new(xd, yd, 1.0);
                map.push(((p.x / p.z) as f32, (p.y / p.z) as f32));
            }
        }
        Self { w, h, map }
    }

    /// Whether the map is the identity to within `tol` pixels on a same-size source.
    pub fn is_identity(&self, src_w: u32, src_h: u32, tol: f32) -> bool {
        (src_w, src_h) == (self.w, self.h)
            && self.map.iter().enumerate().all(|(i, &(u, v))| {
                let (x, y) = ((i % self.w as usize) as f32, (i / self.w as usize) as f32);
                (u - x).abs() <= tol && (v - y).abs() <= tol
            })
    }

    /// The photo resampled (bilinear, edges replicated).
    pub fn rgb(&self, src: &RgbImage) -> RgbImage {
        let mut out = RgbImage::new(self.w, self.h);
        for (px, &(u, v)) in out.pixels_mut().zip(&self.map) {
            let c = crate::texture::bilinear(src, u as f64, v as f64);
            px.0 = c.map(|x| x.round().clamp(0.0, 255.0) as u8);
        }
        out
    }

    /// A mask resampled (nearest pixel, edges replicated).
    pub fn mask(&self, src: &Mask) -> Mask {
        let (sw, sh) = (src.width() as i64, src.height() as i64);
        let w = self.w as usize;
        Mask::from_fn(self.w, self.h, |x, y| {
            let (u, v) = self.map[y as usize * w + x as usize];
            let (sx, sy) = (
                (u.round() as i64).clamp(0, sw - 1),
                (v.round() as i64).clamp(0, sh - 1),
            );
            src.get_or_false(sx, sy)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort() {
        for lens in [
            Lens::Radial { k1: 0.05, k2: 0.0 },
            Lens::Radial { k1: -0.2, k2: 0.03 },
            Lens::OpenCv {
                k1: -0.1,
                k2: 0.01,
                p1: 1e-3,
                p2: -2e-3,
            },
        ] {
            for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.6, 0.45), (0.1, 0.7)] {
                let (xd, yd) = lens.distort(x, y);
                let (ux, uy) = lens.undistort(xd, yd).unwrap();
                assert!(
                    (ux - x).abs() < 1e-10 && (uy - y).abs() < 1e-10,
                    "{lens:?} {x} {y}"
                );
            }
        }
    }

    #[test]
    fn simple_radial_moves_points_outwards_by_k_r_cubed() {
        // COLMAP's SIMPLE_RADIAL: x_d = x (1 + k r^2); at r = 0.5, k = 0.04: 1 %.
        let (xd, yd) = Lens::Radial { k1: 0.04, k2: 0.0 }.distort(0.3, 0.4);
        assert!((xd - 0.303).abs() < 1e-12 && (yd - 0.404).abs() < 1e-12);
    }

    #[test]
    fn resampling_undoes_a_known_distortion() {
        // A photo drawn through a lens (each source pixel coloured by where its ideal ray
        // points), resampled into the pinhole, shows the ideal pattern.
        let k = Matrix3::new(100.0, 0.0, 39.5, 0.0, 100.0, 29.5, 0.0, 0.0, 1.0);
        let lens = Lens::Radial { k1: 0.3, k2: 0.0 };
        let kinv = k.try_inverse().unwrap();
        let ideal = |x: f64, y: f64| {
            // A smooth pattern of the ideal normalised coordinates.
            (
                (x * 300.0 + 128.0).clamp(0.0, 255.0),
                (y * 300.0 + 128.0).clamp(0.0, 255.0),
            )
        };
        let photo = RgbImage::from_fn(80, 60, |u, v| {
            let n = kinv * Vector3::new(u as f64, v as f64, 1.0);
            let (x, y) = lens.undistort(n.x, n.y).unwrap();
            let (a, b) = ideal(x, y);
            image::Rgb([a.round() as u8, b.round() as u8, 0])
        });
        let r = Resample::new(&k, &lens, &k, 80, 60);
        assert!(!r.is_identity(80, 60, 0.01));
        let out = r.rgb(&photo);
        let mut worst = 0.0f64;
        for v in 5..55 {
            for u in 5..75 {
                let n = kinv * Vector3::new(u as f64, v as f64, 1.0);
                let (a, b) = ideal(n.x, n.y);
                let p = out.get_pixel(u, v).0;
                worst = worst
                    .max((p[0] as f64 - a).abs())
                    .max((p[1] as f64 - b).abs());
            }
        }
        assert!(worst <= 1.5, "worst {worst}");
        // Without the lens the same map is the identity.
        assert!(Resample::new(&k, &Lens::None, &k, 80, 60).is_identity(80, 60, 1e-4));
    }
}
