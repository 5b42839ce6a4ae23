//! Test scenes with truth made from *real* video: one real video (e.g. `testdata/tree.avi`) becomes
//! M views of a slanted plane textured with the video, seen by cameras on a line.
//!
//! Geometry. The source frame is the texture of a plane slanted by `slant_deg` about the vertical
//! axis, `distance` units in front of the middle camera; one source pixel is `1 / width` units.
//! Camera q (real q in `[0, M-1]`) sits at `x = baseline * (q - (M-1)/2)` on the x axis and turns
//! to look at the plane's centre, so neighbouring views differ by a clearly projective homography
//! (the cameras rotate and the plane is slanted), not an affine one. `G(q)` maps source pixels to
//! camera q's pixels; the focal length is the smallest (times 1.02) that keeps every view's frame
//! inside the source, so no view ever sees past the texture's edge.
//!
//! Time. View p starts at a random offset: frame s of view p shows source frame
//! `(offset[p] + s) mod usable` (asynchronous clocks; the first `usable` source frames are looped
//! for length). Each view has its own exposure gain.
//!
//! Truth. The marked points are K points of the plane seen through `G(p)`, optionally with
//! Gaussian marking noise. The *ideal* view at a fractional q is what System A's B-1 defines: the
//! source frame warped by `T(q)`, the homography from the source positions of the K points to the
//! virtual points `x(q)` interpolated from the *true* points of the first and last view.
//!
//! Everything is computed here with nalgebra and a bilinear sampler of this crate, never with
//! vt-core, so the truth is independent of what it checks. Same frames, same parameters, same
//! pixels.

use image::RgbImage;
use nalgebra::{DMatrix, Matrix3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{hash, unit};

/// Parameters of [`RealScene`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RealParams {
    /// Number of views M.
    pub views: usize,
    /// Frames per view.
    pub frames: usize,
    /// How many leading source frames are used (looped for length); 0 = all.
    pub usable: usize,
    /// Seed of offsets, gains, points and marking noise.
    pub seed: u64,
    /// Plane slant about the vertical axis, degrees.
    pub slant_deg: f64,
    /// Distance from the middle camera to the plane's centre (the plane is 1 unit wide).
    pub distance: f64,
    /// Distance between neighbouring cameras.
    pub baseline: f64,
    /// Largest per-view exposure gain difference (0.06 = gains in 0.94..1.06).
    pub exposure: f64,
    /// Number of marked points K (4 to 8).
    pub points: usize,
    /// Standard deviation of the Gaussian marking noise added to each marked coordinate, pixels.
    pub marking_noise: f64,
}

impl Default for RealParams {
    fn default() -> Self {
        Self {
            views: 5,
            frames: 120,
            usable: 0,
            seed: 1,
            slant_deg: 35.0,
            distance: 2.0,
            baseline: 0.12,
            exposure: 0.06,
            points: 6,
            marking_noise: 0.0,
        }
    }
}

/// A scene made from real frames.
#[derive(Debug, Clone)]
pub struct RealScene {
    params: RealParams,
    source: Vec<RgbImage>,
    usable: usize,
    width: u32,
    height: u32,
    focal: f64,
    offsets: Vec<usize>,
    gains: Vec<f64>,
    plane_points: Vec<(f64, f64)>,
}

/// Row-major rows of a 3x3 matrix (the truth-file form).
pub fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// Applies a homography to a point (None at infinity).
pub fn apply(h: &Matrix3<f64>, x: f64, y: f64) -> Option<(f64, f64)> {
    let v = h * Vector3::new(x, y, 1.0);
    (v.z.abs() > 1e-12).then(|| (v.x / v.z, v.y / v.z))
}

/// Homography mapping `from[i]` to `to[i]` (least squares by DLT on normalised points; exact for
/// four points in general position). None when the points are degenerate.
pub fn fit_homography(from: &[(f64, f64)], to: &[(f64, f64)]) -> Option<Matrix3<f64>> {
    if from.len() != to.len() || from.len() < 4 {
        return None;
    }
    let norm = |pts: &[(f64, f64)]| {
        let n = pts.len() as f64;
        let (mx, my) = pts
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
        let d = pts
            .iter()
            .map(|p| ((p.0 - mx).powi(2) + (p.1 - my).powi(2)).sqrt())
            .sum::<f64>()
            / n;
        let s = if d > 0.0 { 2f64.sqrt() / d } else { 1.0 };
        Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0)
    };
    let (ta, tb) = (norm(from), norm(to));
    let n = from.len();
    let mut a = DMatrix::<f64>::zeros(2 * n.max(5), 9);
    for i in 0..n {
        let (x, y) = apply(&ta, from[i].0, from[i].1)?;
        let (u, v) = apply(&tb, to[i].0, to[i].1)?;
        let r = 2 * i;
        let row0 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
        let row1 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        for j in 0..9 {
            a[(r, j)] = row0[j];
            a[(r + 1, j)] = row1[j];
        }
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t?;
    let (imin, _) = svd
        .singular_values
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))?;
    let h = vt.row(imin);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let m = tb.try_inverse()? * hn * ta;
    let s = m[(2, 2)];
    (s.abs() > 1e-12).then(|| m / s)
}

/// Bilinear sample of an RGB image at `(x, y)`, None outside `[0, w-1] x [0, h-1]`.
fn sample(img: &RgbImage, x: f64, y: f64) -> Option<[f64; 3]> {
    let (w, h) = (img.width() as f64, img.height() as f64);
    if !(x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0) {
        return None;
    }
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as u32, y0 as u32);
    let (x1, y1) = (
        (x0 + 1).min(img.width() - 1),
        (y0 + 1).min(img.height() - 1),
    );
    let p = |x, y| img.get_pixel(x, y).0;
    let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
    let mut out = [0.0; 3];
    for k in 0..3 {
        let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
        let bottom = c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx;
        out[k] = top * (1.0 - fy) + bottom * fy;
    }
    Some(out)
}

/// Warps `src` by `h` (source pixels to output pixels) into a `w x h` image, bilinear, scaling by
/// `gain`; pixels whose source falls outside are black.
pub fn warp(src: &RgbImage, h: &Matrix3<f64>, w: u32, ht: u32, gain: f64) -> RgbImage {
    let inv = h.try_inverse().unwrap_or_else(Matrix3::identity);
    let mut out = RgbImage::new(w, ht);
    out.as_mut()
        .par_chunks_mut(w as usize * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                if let Some(c) =
                    apply(&inv, x as f64, y as f64).and_then(|(sx, sy)| sample(src, sx, sy))
                {
                    for k in 0..3 {
                        px[k] = (c[k] * gain).round().clamp(0.0, 255.0) as u8;
                    }
                }
            }
        });
    out
}

impl RealScene {
    /// Builds the scene over `source` (the real frames, all one size).
    pub fn new(source: Vec<RgbImage>, params: RealParams) -> Result<Self, String> {
        let first = source.first().ok_or("the source video has no frames")?;
        let (width, height) = first.dimensions();
        if width < 16 || height < 16 {
            return Err(format!("source frames of {width}x{height} are too small"));
        }
        if let Some((i, f)) = source
            .iter()
            .enumerate()
            .find(|(_, f)| f.dimensions() != (width, height))
        {
            return Err(format!(
                "source frame {i} is {}x{}, frame 0 is {width}x{height}",
                f.width(),
                f.height()
            ));
        }
        let usable = if params.usable == 0 {
            source.len()
        } else {
            params.usable
        };
        if usable > source.len() {
            return Err(format!(
                "usable frames {usable} but the source has only {}",
                source.len()
            ));
        }
        if params.views == 0 || params.views > 64 {
            return Err(format!("views {} must be in 1..=64", params.views));
        }
        if params.frames == 0 || params.frames > 100_000 {
            return Err(format!("frames {} must be in 1..=100000", params.frames));
        }
        if !(4..=8).contains(&params.points) {
            return Err(format!("points {} must be in 4..=8", params.points));
        }
        let ok = params.distance.is_finite()
            && params.distance > 0.0
            && params.baseline.is_finite()
            && params.baseline >= 0.0
            && params.slant_deg.is_finite()
            && params.slant_deg.abs() < 75.0
            && params.exposure.is_finite()
            && (0.0..0.5).contains(&params.exposure)
            && params.marking_noise.is_finite()
            && params.marking_noise >= 0.0;
        if !ok {
            return Err(format!(
                "geometry out of range: distance {} (> 0), baseline {} (>= 0), slant {} (|.| < 75), exposure {} (0 to 0.5), marking noise {} (>= 0)",
                params.distance, params.baseline, params.slant_deg, params.exposure, params.marking_noise
            ));
        }
        let seed = params.seed;
        let offsets = (0..params.views)
            .map(|p| (unit(hash(&[seed, 1, p as u64])) * usable as f64) as usize % usable)
            .collect();
        let gains = (0..params.views)
            .map(|p| 1.0 + params.exposure * (2.0 * unit(hash(&[seed, 2, p as u64])) - 1.0))
            .collect();
        let mut scene = Self {
            params,
            source,
            usable,
            width,
            height,
            focal: 1.0,
            offsets,
            gains,
            plane_points: Vec::new(),
        };
        scene.focal = scene.fit_focal()?;
        scene.plane_points = scene.choose_points();
        Ok(scene)
    }

    /// The parameters.
    pub fn params(&self) -> &RealParams {
        &self.params
    }

    /// Frame size (views have the source's size).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Source frames in use (the looped prefix).
    pub fn usable(&self) -> usize {
        self.usable
    }

    /// Per view, the source frame shown at view frame 0.
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// Per view exposure gain.
    pub fn gains(&self) -> &[f64] {
        &self.gains
    }

    /// The source frame that frame `s` of view `p` shows.
    pub fn source_index(&self, p: usize, s: usize) -> usize {
        (self.offsets[p] + s) % self.usable
    }

    /// The source frames.
    pub fn source(&self) -> &[RgbImage] {
        &self.source
    }

    /// `G(q)` with focal length `f`: source pixels to camera q's pixels.
    fn camera_homography(&self, q: f64, f: f64) -> Matrix3<f64> {
        let p = &self.params;
        let (w, h) = (self.width as f64, self.height as f64);
        let s = 1.0 / w;
        let th = p.slant_deg.to_radians();
        let e1 = Vector3::new(th.cos(), 0.0, th.sin());
        let e2 = Vector3::new(0.0, 1.0, 0.0);
        let centre = Vector3::new(0.0, 0.0, p.distance);
        let mid = (p.views as f64 - 1.0) / 2.0;
        let cam = Vector3::new(p.baseline * (q - mid), 0.0, 0.0);
        // Look-at rotation: z towards the plane's centre, y down (world y), x = y cross z.
        let z = (centre - cam).normalize();
        let x = Vector3::new(0.0, 1.0, 0.0).cross(&z).normalize();
        let y = z.cross(&x);
        let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let k = Matrix3::new(
            f,
            0.0,
            (w - 1.0) / 2.0,
            0.0,
            f,
            (h - 1.0) / 2.0,
            0.0,
            0.0,
            1.0,
        );
        // World point of source pixel (u, v): centre + (u - cx) s e1 + (v - cy) s e2.
        let (cx, cy) = ((w - 1.0) / 2.0, (h - 1.0) / 2.0);
        let t = centre - cx * s * e1 - cy * s * e2 - cam;
        let m = Matrix3::from_columns(&[s * e1, s * e2, t]);
        let g = k * r * m;
        g / g[(2, 2)]
    }

    /// Whether camera q's whole frame sees the source (2 px margin) at focal length `f`.
    fn covered(&self, q: f64, f: f64) -> bool {
        let g = self.camera_homography(q, f);
        let Some(inv) = g.try_inverse() else {
            return false;
        };
        let (w, h) = (self.width as f64, self.height as f64);
        let n = 8;
        (0..=n).all(|i| {
            let t = i as f64 / n as f64;
            [
                (t * (w - 1.0), 0.0),
                (t * (w - 1.0), h - 1.0),
                (0.0, t * (h - 1.0)),
                (w - 1.0, t * (h - 1.0)),
            ]
            .iter()
            .all(|&(x, y)| {
                apply(&inv, x, y)
                    .is_some_and(|(u, v)| u >= 2.0 && v >= 2.0 && u <= w - 3.0 && v <= h - 3.0)
            })
        })
    }

    /// The smallest focal length (times 1.02) with every view (and every q between) covered.
    fn fit_focal(&self) -> Result<f64, String> {
        let qmax = (self.params.views - 1) as f64;
        let qs: Vec<f64> = (0..=16).map(|i| qmax * i as f64 / 16.0).collect();
        let ok = |f: f64| qs.iter().all(|&q| self.covered(q, f));
        let (mut lo, mut hi) = (1.0, self.width as f64);
        while !ok(hi) {
            hi *= 2.0;
            if hi > 1e7 {
                return Err("no focal length lets the cameras see only the source; lower the baseline or slant".into());
            }
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if ok(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Ok(hi * 1.02)
    }

    /// K points of the plane, seen by every view: a jittered ring around the source's centre,
    /// inside the region all views see.
    fn choose_points(&self) -> Vec<(f64, f64)> {
        let (w, h) = (self.width as f64, self.height as f64);
        let k = self.params.points;
        let seed = self.params.seed;
        let visible = |u: f64, v: f64| {
            (0..self.params.views).all(|p| {
                apply(&self.homography(p), u, v).is_some_and(|(x, y)| {
                    x >= 0.1 * w && y >= 0.1 * h && x <= 0.9 * w && y <= 0.9 * h
                })
            })
        };
        let mut pts = Vec::with_capacity(k);
        for i in 0..k {
            let ang = std::f64::consts::TAU * (i as f64 + 0.3 * unit(hash(&[seed, 3, i as u64])))
                / k as f64;
            let mut r = 0.45 + 0.1 * unit(hash(&[seed, 4, i as u64]));
            loop {
                let (u, v) = (
                    (w - 1.0) / 2.0 + r * 0.5 * w * ang.cos(),
                    (h - 1.0) / 2.0 + r * 0.5 * h * ang.sin(),
                );
                if visible(u, v) || r < 0.05 {
                    pts.push((u, v));
                    break;
                }
                r *= 0.95;
            }
        }
        pts
    }

    /// `H_p = G(p)`: source pixels to view p's pixels.
    pub fn homography(&self, p: usize) -> Matrix3<f64> {
        self.camera_homography(p as f64, self.focal)
    }

    /// True `H_(a,b)`: view a's pixels to view b's pixels.
    pub fn homography_between(&self, a: usize, b: usize) -> Matrix3<f64> {
        let m = self.homography(b) * self.homography(a).try_inverse().expect("G is invertible");
        m / m[(2, 2)]
    }

    /// The marked points' positions in the source (plane coordinates).
    pub fn plane_points(&self) -> &[(f64, f64)] {
        &self.plane_points
    }

    /// The true (noise-free) points of view p.
    pub fn true_points(&self, p: usize) -> Vec<(f64, f64)> {
        let h = self.homography(p);
        self.plane_points
            .iter()
            .map(|&(u, v)| apply(&h, u, v).expect("points are visible"))
            .collect()
    }

    /// The points as a user would mark them: the true points plus Gaussian noise of
    /// [`RealParams::marking_noise`] pixels per coordinate (Box-Muller over splitmix64).
    pub fn marked_points(&self, p: usize) -> Vec<(f64, f64)> {
        let sd = self.params.marking_noise;
        let seed = self.params.seed;
        self.true_points(p)
            .into_iter()
            .enumerate()
            .map(|(i, (x, y))| {
                let g = |axis: u64| {
                    let u1 = unit(hash(&[seed, 5, p as u64, i as u64, axis])).max(1e-12);
                    let u2 = unit(hash(&[seed, 6, p as u64, i as u64, axis]));
                    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
                };
                (x + sd * g(0), y + sd * g(1))
            })
            .collect()
    }

    /// The virtual points `x(q)` of B-1 from the true points of the first and last view.
    pub fn virtual_points(&self, q: f64) -> Vec<(f64, f64)> {
        let m1 = (self.params.views - 1) as f64;
        if m1 == 0.0 {
            return self.true_points(0);
        }
        let (a, b) = (self.true_points(0), self.true_points(self.params.views - 1));
        a.iter()
            .zip(&b)
            .map(|(p0, p1)| {
                (
                    (p0.0 * (m1 - q) + p1.0 * q) / m1,
                    (p0.1 * (m1 - q) + p1.1 * q) / m1,
                )
            })
            .collect()
    }

    /// `T(q)`: source pixels to the ideal view at q (exactly `G(p)` at the first and last view;
    /// a single view's `T` is `G(0)`).
    pub fn ideal_homography(&self, q: f64) -> Matrix3<f64> {
        if self.params.views == 1 {
            return self.homography(0);
        }
        fit_homography(&self.plane_points, &self.virtual_points(q))
            .unwrap_or_else(|| self.homography(0))
    }

    /// Frame `s` of view `p`: its source frame through `G(p)`, times the view's gain.
    pub fn frame(&self, p: usize, s: usize) -> RgbImage {
        warp(
            &self.source[self.source_index(p, s)],
            &self.homography(p),
            self.width,
            self.height,
            self.gains[p],
        )
    }

    /// The ideal view at q of source frame `source_frame`, at the exposure of a camera at q
    /// ([`crate::exposure_at`]).
    pub fn ideal(&self, q: f64, source_frame: usize) -> RgbImage {
        warp(
            &self.source[source_frame % self.source.len()],
            &self.ideal_homography(q),
            self.width,
            self.height,
            crate::exposure_at(&self.gains, q),
        )
    }

    /// Corner error of an estimated `H_(a,b)` against the truth: the largest distance between
    /// where the two map the four image corners, pixels.
    pub fn corner_error(&self, a: usize, b: usize, estimate: &Matrix3<f64>) -> f64 {
        let truth = self.homography_between(a, b);
        let (w, h) = (self.width as f64 - 1.0, self.height as f64 - 1.0);
        [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .iter()
            .map(
                |&(x, y)| match (apply(&truth, x, y), apply(estimate, x, y)) {
                    (Some(t), Some(e)) => ((t.0 - e.0).powi(2) + (t.1 - e.1).powi(2)).sqrt(),
                    _ => f64::INFINITY,
                },
            )
            .fold(0.0, f64::max)
    }
}

/// truth.json of a real-video scene (`vt synth real`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RealTruth {
    /// "vt-synth-real".
    pub format: String,
    /// 1.
    pub version: u32,
    /// The generator's parameters.
    pub params: RealParams,
    /// The source video (as given on the command line).
    pub source: String,
    /// Source frames looped.
    pub usable: usize,
    /// Source frame rate used for the views (frames per second).
    pub fps: f64,
    /// Per view: the source frame of view frame 0; frame s of view p shows source frame
    /// `(offset[p] + s) mod usable`.
    pub offsets: Vec<usize>,
    /// Per view exposure gain.
    pub gains: Vec<f64>,
    /// Per view `G(p)`, source pixels to view pixels, row-major.
    pub view_homographies: Vec<[[f64; 3]; 3]>,
    /// True `H_(p,p+1)`, row-major.
    pub homographies_next: Vec<[[f64; 3]; 3]>,
    /// Marked points in the source (plane coordinates).
    pub plane_points: Vec<[f64; 2]>,
    /// Per view, the true (noise-free) points.
    pub true_points: Vec<Vec<[f64; 2]>>,
    /// Ideal views written to `truth/`.
    pub ideals: Vec<IdealView>,
}

/// One ideal view in the truth folder.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct IdealView {
    /// Viewpoint.
    pub q: f64,
    /// `T(q)`, row-major.
    pub homography: [[f64; 3]; 3],
    /// Source frame shown.
    pub source_frame: usize,
    /// File, relative to the scene directory.
    pub file: String,
}

impl RealScene {
    /// The truth record (without ideal-view files; the writer adds them).
    pub fn truth(&self, source: &str, fps: f64) -> RealTruth {
        let m = self.params.views;
        RealTruth {
            format: "vt-synth-real".into(),
            version: 1,
            params: self.params,
            source: source.into(),
            usable: self.usable,
            fps,
            offsets: self.offsets.clone(),
            gains: self.gains.clone(),
            view_homographies: (0..m).map(|p| rows(&self.homography(p))).collect(),
            homographies_next: (0..m.saturating_sub(1))
                .map(|p| rows(&self.homography_between(p, p + 1)))
                .collect(),
            plane_points: self.plane_points.iter().map(|&(u, v)| [u, v]).collect(),
            true_points: (0..m)
                .map(|p| self.true_points(p).iter().map(|&(x, y)| [x, y]).collect())
                .collect(),
            ideals: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames() -> Vec<RgbImage> {
        (0..6)
            .map(|i| {
                RgbImage::from_fn(96, 72, |x, y| {
                    image::Rgb([
                        (x * 2 + i * 9) as u8,
                        (y * 3) as u8,
                        ((x ^ y) * 4 + i) as u8,
                    ])
                })
            })
            .collect()
    }

    fn scene(noise: f64) -> RealScene {
        RealScene::new(
            frames(),
            RealParams {
                views: 4,
                frames: 10,
                marking_noise: noise,
                ..Default::default()
            },
        )
        .unwrap()
    }

    #[test]
    fn views_are_projective_and_covered() {
        let s = scene(0.0);
        for p in 0..3 {
            let h = s.homography_between(p, p + 1);
            // Clearly projective: the perspective row moves a corner by more than a pixel.
            let persp = h[(2, 0)].abs() * 96.0 + h[(2, 1)].abs() * 72.0;
            assert!(persp > 0.01, "view {p}: perspective row {persp}");
        }
        for p in 0..4 {
            // Every pixel of every view sees the texture (2 px inside its edge).
            assert!(s.covered(p as f64, s.focal));
        }
    }

    #[test]
    fn ideal_at_end_views_is_the_view_itself_and_points_agree() {
        let s = scene(0.0);
        for p in [0usize, 3] {
            let t = s.ideal_homography(p as f64);
            let g = s.homography(p);
            for &(u, v) in s.plane_points() {
                let a = apply(&t, u, v).unwrap();
                let b = apply(&g, u, v).unwrap();
                assert!((a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6);
            }
        }
        // H_(0,1) maps view 0's true points onto view 1's.
        let h = s.homography_between(0, 1);
        for (a, b) in s.true_points(0).iter().zip(s.true_points(1)) {
            let m = apply(&h, a.0, a.1).unwrap();
            assert!((m.0 - b.0).abs() < 1e-6 && (m.1 - b.1).abs() < 1e-6);
        }
    }

    #[test]
    fn marking_noise_has_the_asked_spread() {
        let noisy = RealScene::new(
            frames(),
            RealParams {
                views: 64,
                points: 8,
                marking_noise: 2.0,
                baseline: 0.002,
                ..Default::default()
            },
        )
        .unwrap();
        let mut sq = 0.0;
        let mut n = 0.0;
        for p in 0..64 {
            for (a, b) in noisy.true_points(p).iter().zip(noisy.marked_points(p)) {
                sq += (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2);
                n += 2.0;
            }
        }
        let sd = (sq / n).sqrt();
        assert!((sd - 2.0).abs() < 0.25, "marking noise sd {sd}");
    }

    #[test]
    fn frame_shows_its_source_frame_with_gain() {
        let s = scene(0.0);
        let p = 2;
        let s_idx = s.source_index(p, 7);
        assert_eq!(s_idx, (s.offsets()[p] + 7) % 6);
        let direct = warp(&s.source()[s_idx], &s.homography(p), 96, 72, s.gains()[p]);
        assert_eq!(direct, s.frame(p, 7));
        let fit = fit_homography(s.plane_points(), &s.true_points(p)).unwrap();
        assert!(s.corner_error(0, p, &(fit * s.homography(0).try_inverse().unwrap())) < 1e-6);
    }
}
