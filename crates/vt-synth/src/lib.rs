//! vt-synth: synthetic scenes with known truth, rendered by ray casting (never by vt-core's warps),
//! so that every step of vt can be measured against an independent answer.
//!
//! [`TextureScene`] is System A's test scene: M pinhole cameras on a line (x axis, looking down +z,
//! y down), each filming at its own time (a random clock offset per view), a planar textured
//! object swaying periodically on the plane `z = object_depth` in front of a background with
//! real depth (a far wall and two pillars, so off-plane parallax exists), with sensor noise and a
//! small per-view exposure difference. Everything is a pure function of the parameters and seed:
//! same seed, same pixels.
//!
//! [`object`] is System B's: a textured object ray cast from calibrated cameras on a ring, with
//! its own pinhole camera maths. [`real`] builds System A scenes from a real video; [`files`]
//! writes the scenes with their truth and checks an analysis against it.
#![deny(missing_docs)]

pub mod files;
pub mod object;
pub mod real;
pub mod surface;

use image::RgbImage;
use nalgebra::{Matrix3, Point3, Rotation3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How the cameras are set up along their line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Rig {
    /// All cameras look straight ahead: views of the object plane differ by a translation.
    Parallel,
    /// Each camera turns to look at the object's centre: views differ by a general homography.
    Converging,
}

impl std::str::FromStr for Rig {
    type Err = String;

    /// `parallel` or `converging`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "parallel" => Ok(Rig::Parallel),
            "converging" => Ok(Rig::Converging),
            _ => Err(format!("rig '{s}' is not parallel or converging")),
        }
    }
}

/// Most pixels in one synthetic frame (3840 x 2160).
pub const MAX_PIXELS: u64 = 3840 * 2160;
/// Most views of a synthetic texture scene.
pub const MAX_VIEWS: usize = 64;
/// Most frames of a synthetic texture scene, all views together.
pub const MAX_FRAMES: usize = 100_000;

/// Parameters of [`TextureScene`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TextureParams {
    /// Number of views M.
    pub views: usize,
    /// Frames per view.
    pub frames: usize,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Motion period in frames.
    pub period: usize,
    /// Seed of all randomness.
    pub seed: u64,
    /// Camera arrangement.
    pub rig: Rig,
    /// Put the background on the object's plane (a scene one homography explains exactly).
    pub planar: bool,
    /// Distance between neighbouring cameras (scene units; the object is 4 units away).
    pub baseline: f64,
    /// Sensor noise, grey levels (standard deviation).
    pub noise: f64,
    /// Largest per-view exposure gain difference (e.g. 0.04 = up to +-4%).
    pub exposure: f64,
}

impl Default for TextureParams {
    fn default() -> Self {
        Self {
            views: 3,
            frames: 150,
            width: 320,
            height: 180,
            period: 24,
            seed: 1,
            rig: Rig::Parallel,
            planar: false,
            baseline: 0.12,
            noise: 2.0,
            exposure: 0.04,
        }
    }
}

/// A pinhole camera: `x ~ K R (X - C)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Intrinsics.
    pub k: Matrix3<f64>,
    /// World-to-camera rotation.
    pub r: Matrix3<f64>,
    /// Centre in the world.
    pub centre: Point3<f64>,
}

impl Camera {
    /// Projects a world point to pixels (origin top-left, pixel centres at integers).
    pub fn project(&self, x: &Point3<f64>) -> (f64, f64) {
        let v = self.k * (self.r * (x - self.centre));
        (v.x / v.z, v.y / v.z)
    }

    /// World direction of the ray through pixel `(x, y)`.
    pub fn ray(&self, x: f64, y: f64) -> Vector3<f64> {
        let kinv = self.k.try_inverse().expect("K is invertible");
        self.r.transpose() * (kinv * Vector3::new(x, y, 1.0))
    }
}

/// The scene's fixed geometry.
const OBJECT_DEPTH: f64 = 4.0;
const WALL_DEPTH: f64 = 9.0;
/// Pillars: (x centre, half width, depth), all spanning the full height.
const PILLARS: [(f64, f64, f64); 2] = [(-1.1, 0.18, 6.0), (0.95, 0.14, 7.0)];
/// Marked points on the object plane (x, y), the "box" the thesis places in the scene.
const MARKERS: [(f64, f64); 6] = [
    (-0.75, -0.5),
    (0.8, -0.45),
    (0.7, 0.55),
    (-0.65, 0.5),
    (0.05, -0.62),
    (-0.1, 0.62),
];

/// System A's synthetic scene.
#[derive(Debug, Clone)]
pub struct TextureScene {
    params: TextureParams,
    cameras: Vec<Camera>,
    phases: Vec<usize>,
    gains: Vec<f64>,
}

use vt_core::rng::{hash, mix, unit};

/// Smooth value noise in [0, 1] on a unit lattice.
fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(fx), s(fy));
    let at = |i: f64, j: f64| unit(hash(&[seed, i as i64 as u64, j as i64 as u64]));
    let top = at(x0, y0) * (1.0 - sx) + at(x0 + 1.0, y0) * sx;
    let bottom = at(x0, y0 + 1.0) * (1.0 - sx) + at(x0 + 1.0, y0 + 1.0) * sx;
    top * (1.0 - sy) + bottom * sy
}

fn lerp3(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

impl TextureParams {
    /// Checks the sizes against [`MAX_PIXELS`], [`MAX_VIEWS`] and [`MAX_FRAMES`] before anything
    /// is allocated; messages name the values as `vt synth textures`'s flags.
    pub fn check_limits(&self) -> Result<(), String> {
        let px = self.width as u64 * self.height as u64;
        if px > MAX_PIXELS {
            return Err(format!(
                "--size {}x{} is {px} pixels per frame, more than {MAX_PIXELS} (3840x2160)",
                self.width, self.height
            ));
        }
        if self.views == 0 || self.views > MAX_VIEWS {
            return Err(format!("--views {} must be in 1..={MAX_VIEWS}", self.views));
        }
        let total = self.views.saturating_mul(self.frames);
        if self.frames == 0 || total > MAX_FRAMES {
            return Err(format!(
                "--views {} x --frames {} = {total} frames, more than {MAX_FRAMES} (or no frames)",
                self.views, self.frames
            ));
        }
        Ok(())
    }
}

impl TextureScene {
    /// Builds the scene; fails on parameters that cannot make one.
    pub fn new(params: TextureParams) -> Result<Self, String> {
        if params.views == 0
            || params.frames == 0
            || params.period < 2
            || params.width < 8
            || params.height < 8
        {
            return Err(format!(
                "need views >= 1, frames >= 1, period >= 2 and a size of at least 8x8 (got {} views, {} frames, period {}, {}x{})",
                params.views, params.frames, params.period, params.width, params.height
            ));
        }
        if !(params.exposure.is_finite() && (0.0..=0.5).contains(&params.exposure)) {
            return Err(format!(
                "exposure must be in [0, 0.5] (got {})",
                params.exposure
            ));
        }
        let baseline_ok = params.baseline.is_finite() && params.baseline > 0.0;
        let noise_ok = params.noise.is_finite() && params.noise >= 0.0;
        if !(baseline_ok && noise_ok) {
            return Err(format!(
                "baseline must be > 0 and noise >= 0 (got {}, {})",
                params.baseline, params.noise
            ));
        }
        let cameras = (0..params.views)
            .map(|p| Self::camera_at(&params, p as f64))
            .collect();
        let phases = (0..params.views)
            .map(|p| (mix(hash(&[params.seed, 1, p as u64])) % params.period as u64) as usize)
            .collect();
        let gains = (0..params.views)
            .map(|p| 1.0 + params.exposure * (2.0 * unit(hash(&[params.seed, 2, p as u64])) - 1.0))
            .collect();
        Ok(Self {
            params,
            cameras,
            phases,
            gains,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &TextureParams {
        &self.params
    }

    /// Camera at real view position `q` in `[0, M-1]`: the centre moves linearly along the line
    /// (B-1's virtual viewpoint); a converging rig keeps looking at the object's centre.
    pub fn camera(&self, q: f64) -> Camera {
        Self::camera_at(&self.params, q)
    }

    fn camera_at(params: &TextureParams, q: f64) -> Camera {
        let (w, h) = (params.width as f64, params.height as f64);
        let f = 0.9 * w;
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
        let x = (q - (params.views as f64 - 1.0) / 2.0) * params.baseline;
        let yaw = match params.rig {
            Rig::Parallel => 0.0,
            Rig::Converging => (-x).atan2(OBJECT_DEPTH),
        };
        // Camera looks along +z rotated by yaw about the y axis; r is world-to-camera.
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), yaw)
            .inverse()
            .into_inner();
        Camera {
            k,
            r,
            centre: Point3::new(x, 0.0, 0.0),
        }
    }

    /// `phase[p]`: the frame of view p where the motion is at phase 0.
    pub fn phase_offsets(&self) -> &[usize] {
        &self.phases
    }

    /// Motion phase (in frames, `0..period`) of frame `s` of view `p`.
    pub fn phase_of(&self, view: usize, frame: usize) -> usize {
        let p = self.params.period as i64;
        (frame as i64 - self.phases[view] as i64).rem_euclid(p) as usize
    }

    /// Exposure gain of each view.
    pub fn gains(&self) -> &[f64] {
        &self.gains
    }

    /// The marked points of view p (exact projections of the markers).
    pub fn points(&self, view: usize) -> Vec<(f64, f64)> {
        MARKERS
            .iter()
            .map(|&(x, y)| self.cameras[view].project(&Point3::new(x, y, OBJECT_DEPTH)))
            .collect()
    }

    /// Every view's marked points as vt-core points, as a points file holds them (one list per
    /// view, the same markers in the same order).
    pub fn marked_points(&self) -> Vec<Vec<vt_core::Point>> {
        (0..self.cameras.len())
            .map(|p| {
                self.points(p)
                    .into_iter()
                    .map(|(x, y)| vt_core::Point::new(x, y))
                    .collect()
            })
            .collect()
    }

    /// The true homography of the object plane from view `a`'s image to view `b`'s:
    /// `H = K R_b ((C_a - C_b) n^T + (d - n.C_a) I) R_a^T K^-1`, `n = (0,0,1)`, `d` = object depth.
    pub fn plane_homography(&self, a: f64, b: f64) -> Matrix3<f64> {
        let (ca, cb) = (self.camera(a), self.camera(b));
        let n = Vector3::new(0.0, 0.0, 1.0);
        let m = (ca.centre - cb.centre) * n.transpose()
            + Matrix3::identity() * (OBJECT_DEPTH - n.dot(&ca.centre.coords));
        let h = cb.k * cb.r * m * ca.r.transpose() * ca.k.try_inverse().expect("K is invertible");
        h / h[(2, 2)]
    }

    /// Object pose at a phase (fraction of a period): centre offset and rotation on its plane.
    /// The swing (0.55) exceeds the half-width (0.3), so every pixel shows the background most
    /// of the time, as the median background of A-1 assumes.
    fn pose(&self, phase: f64) -> (f64, f64, f64) {
        let a = phase * std::f64::consts::TAU;
        (
            0.55 * a.sin(),
            0.12 * (2.0 * a).sin() + 0.05 * a.cos(),
            0.35 * (a + 0.5).sin(),
        )
    }

    /// Colour along a ray from `origin`, with the object at `phase` (fraction of a period).
    fn shade(&self, origin: &Point3<f64>, dir: &Vector3<f64>, phase: f64) -> [f64; 3] {
        let seed = self.params.seed;
        let at_depth = |z: f64| {
            let t = (z - origin.z) / dir.z;
            (origin.x + t * dir.x, origin.y + t * dir.y)
        };
        // The object: an ellipse with a leafy texture, in its own (rotating) frame.
        let (ox, oy, rot) = self.pose(phase);
        let (px, py) = at_depth(OBJECT_DEPTH);
        let (dx, dy) = (px - ox, py - oy);
        let (u, v) = (
            dx * rot.cos() + dy * rot.sin(),
            -dx * rot.sin() + dy * rot.cos(),
        );
        let e = (u / 0.3).powi(2) + (v / 0.2).powi(2);
        if e < 1.0 {
            let vein = 0.5 + 0.5 * (u * 38.0).sin() * (v * 20.0).cos();
            let spots = value_noise(seed ^ 7, u * 9.0, v * 9.0);
            let base = lerp3([40.0, 150.0, 45.0], [150.0, 210.0, 60.0], spots);
            return lerp3(base, [25.0, 90.0, 30.0], 0.35 * vein + 0.3 * e);
        }
        let wall = |x: f64, y: f64| {
            let n1 = value_noise(seed ^ 11, x * 3.0, y * 3.0);
            let n2 = value_noise(seed ^ 13, x * 8.0, y * 8.0);
            let bands = 0.5 + 0.5 * (x * 5.0 + 2.0 * n1).sin();
            lerp3(
                lerp3([60.0, 80.0, 140.0], [200.0, 170.0, 120.0], n1),
                [120.0, 60.0, 50.0],
                0.4 * bands * n2,
            )
        };
        if self.params.planar {
            // The background lies on the object's plane, just behind it.
            let (x, y) = at_depth(OBJECT_DEPTH + 1e-6);
            return wall(x, y);
        }
        for &(cx, half, z) in &PILLARS {
            let (x, y) = at_depth(z);
            if (x - cx).abs() < half {
                let g = 90.0 + 80.0 * value_noise(seed ^ 17, x * 10.0, y * 6.0);
                return [g, g * 0.95, g * 0.85];
            }
        }
        let (x, y) = at_depth(WALL_DEPTH);
        wall(x, y)
    }

    /// Noise-free, gain-free image from camera `cam` with the object at `phase` (fraction of a
    /// period), 2x2 supersampled.
    pub fn render(&self, cam: &Camera, phase: f64) -> Vec<[f64; 3]> {
        let (w, h) = (self.params.width as usize, self.params.height as usize);
        let kinv = cam.k.try_inverse().expect("K is invertible");
        let rt = cam.r.transpose();
        let mut out = vec![[0.0; 3]; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let mut acc = [0.0; 3];
                for (sx, sy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                    let d = rt * (kinv * Vector3::new(x as f64 + sx, y as f64 + sy, 1.0));
                    let c = self.shade(&cam.centre, &d, phase);
                    for i in 0..3 {
                        acc[i] += c[i] * 0.25;
                    }
                }
                *px = acc;
            }
        });
        out
    }

    /// Ground truth at viewpoint `q` with the object at integer phase `phase` (frames): no noise,
    /// the exposure of a camera at q ([`exposure_at`]).
    pub fn truth(&self, q: f64, phase: usize) -> RgbImage {
        let img = self.render(&self.camera(q), phase as f64 / self.params.period as f64);
        let gain = exposure_at(&self.gains, q);
        to_rgb(self.params.width, self.params.height, &img, |_, v| v * gain)
    }

    /// Frame `frame` of view `view` as the camera records it: with its exposure gain and noise.
    pub fn frame(&self, view: usize, frame: usize) -> RgbImage {
        let phase = self.phase_of(view, frame) as f64 / self.params.period as f64;
        let img = self.render(&self.cameras[view], phase);
        let (gain, sigma, seed) = (self.gains[view], self.params.noise, self.params.seed);
        to_rgb(self.params.width, self.params.height, &img, |i, v| {
            // Box-Muller from two hashed uniforms per value: independent of thread order.
            let h = hash(&[seed, 3, view as u64, frame as u64, i as u64]);
            let (u1, u2) = (unit(h).max(1e-12), unit(mix(h)));
            let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            v * gain + sigma * n
        })
    }
}

/// The exposure gain of a camera at `q` on the line: its two neighbouring views' gains
/// interpolated in log (view p's own at q = p), as vt's renderer shows a view between two takes
/// (`vt_core::render::Renderer::exposure_at`). Real line rigs agree: Middlebury's odd views lie
/// at their neighbours' exposure, not at the mean of all views.
pub fn exposure_at(gains: &[f64], q: f64) -> f64 {
    let last = gains.len().saturating_sub(1);
    let q = q.clamp(0.0, last as f64);
    let (f, c) = (q.floor() as usize, q.ceil() as usize);
    if f == c {
        return gains[f];
    }
    let t = q - f as f64;
    ((1.0 - t) * gains[f].ln() + t * gains[c].ln()).exp()
}

fn to_rgb(w: u32, h: u32, img: &[[f64; 3]], f: impl Fn(usize, f64) -> f64 + Sync) -> RgbImage {
    let mut raw = vec![0u8; img.len() * 3];
    raw.par_chunks_mut(3).enumerate().for_each(|(i, px)| {
        for c in 0..3 {
            px[c] = f(i * 3 + c, img[i][c]).round().clamp(0.0, 255.0) as u8;
        }
    });
    RgbImage::from_raw(w, h, raw).expect("buffer is w*h*3")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small(rig: Rig) -> TextureScene {
        TextureScene::new(TextureParams {
            width: 96,
            height: 64,
            frames: 20,
            period: 8,
            rig,
            ..Default::default()
        })
        .unwrap()
    }

    #[test]
    fn same_seed_same_pixels_and_exact_periodicity() {
        let a = small(Rig::Parallel);
        let b = small(Rig::Parallel);
        assert_eq!(a.frame(1, 3), b.frame(1, 3));
        // Frames one period apart show the same phase; the object really moves in between.
        assert_eq!(a.phase_of(1, 3), a.phase_of(1, 3 + 8));
        let cam = a.camera(1.0);
        assert_ne!(a.render(&cam, 0.25), a.render(&cam, 0.5));
    }

    #[test]
    fn plane_homography_maps_markers_between_views() {
        for rig in [Rig::Parallel, Rig::Converging] {
            let s = small(rig);
            let h = s.plane_homography(0.0, 2.0);
            for ((x0, y0), (x2, y2)) in s.points(0).into_iter().zip(s.points(2)) {
                let v = h * Vector3::new(x0, y0, 1.0);
                assert!(
                    (v.x / v.z - x2).abs() < 1e-9 && (v.y / v.z - y2).abs() < 1e-9,
                    "{rig:?}"
                );
            }
            if rig == Rig::Parallel {
                assert!(
                    h[(2, 0)].abs() < 1e-15 && (h[(0, 0)] - 1.0).abs() < 1e-12,
                    "parallel rig is a translation"
                );
            } else {
                assert!(h[(2, 0)].abs() > 1e-6, "converging rig is projective");
            }
        }
    }

    #[test]
    fn markers_are_in_every_view() {
        let s = TextureScene::new(TextureParams {
            views: 15,
            ..Default::default()
        })
        .unwrap();
        for p in 0..15 {
            for (x, y) in s.points(p) {
                assert!(
                    x > 0.0 && y > 0.0 && x < 319.0 && y < 179.0,
                    "view {p}: ({x}, {y})"
                );
            }
        }
    }
}
