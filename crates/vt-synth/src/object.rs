//! System B's synthetic scene: a textured object (the union of a sphere and a box) photographed
//! by pinhole cameras on a ring, with exact masks and ground truth for extra viewpoints.
//!
//! The truth is independent of vt-fv: pixels come from analytic ray-primitive intersections,
//! and the cameras are [`PinholeCamera`]s whose projection and back-projection are written here
//! (Middlebury's conventions: `x ~ K [R | t] X`, pixel centres at integer coordinates), not
//! vt-fv's `Camera`. A test in vt-fv checks the two agree on the temple's real cameras; callers
//! turn the cameras into vt-fv's with [`SynthData::try_map_cameras`] or through the par file.

use image::{Rgb, RgbImage};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use vt_core::Mask;

/// A calibrated pinhole camera, `x ~ K [R | t] X`, with `K` upper triangular.
#[derive(Debug, Clone, PartialEq)]
pub struct PinholeCamera {
    /// Name (the image file name in a par file).
    pub name: String,
    /// Intrinsics, upper triangular.
    pub k: Matrix3<f64>,
    /// World-to-camera rotation.
    pub r: Matrix3<f64>,
    /// World-to-camera translation.
    pub t: Vector3<f64>,
}

impl PinholeCamera {
    /// A camera from its parts; fails unless `K` is upper triangular with a non-zero diagonal
    /// and every entry is finite (the back-projection below solves with `K` by substitution).
    pub fn new(
        name: impl Into<String>,
        k: Matrix3<f64>,
        r: Matrix3<f64>,
        t: Vector3<f64>,
    ) -> Result<Self, String> {
        let name = name.into();
        let finite = k
            .iter()
            .chain(r.iter())
            .chain(t.iter())
            .all(|v| v.is_finite());
        let triangular = k[(1, 0)] == 0.0 && k[(2, 0)] == 0.0 && k[(2, 1)] == 0.0;
        let diagonal = (0..3).all(|i| k[(i, i)] != 0.0);
        if !(finite && triangular && diagonal) {
            return Err(format!(
                "camera {name}: K must be finite and upper triangular with a non-zero diagonal"
            ));
        }
        Ok(Self { name, k, r, t })
    }

    /// The camera at `centre` whose optical axis points at `target`, turned about that axis so
    /// the image's downward direction is as close as possible to the world direction `down`.
    pub fn looking_at(
        name: impl Into<String>,
        k: Matrix3<f64>,
        centre: Vector3<f64>,
        target: Vector3<f64>,
        down: Vector3<f64>,
    ) -> Result<Self, String> {
        let name = name.into();
        let axis = (target - centre)
            .try_normalize(1e-12)
            .ok_or_else(|| format!("camera {name}: centre and target coincide"))?;
        // Image rows grow along `down` with its component along the axis removed.
        let row_dir = (down - axis * axis.dot(&down))
            .try_normalize(1e-9)
            .ok_or_else(|| format!("camera {name}: `down` is parallel to the optical axis"))?;
        let col_dir = row_dir.cross(&axis);
        // World-to-camera: the camera's axes in world coordinates are the rows.
        let mut r = Matrix3::zeros();
        for (i, a) in [col_dir, row_dir, axis].iter().enumerate() {
            for j in 0..3 {
                r[(i, j)] = a[j];
            }
        }
        let t = -(r * centre);
        Self::new(name, k, r, t)
    }

    /// Pixel `(u, v)` of a world point, `None` unless it is in front of the camera.
    pub fn project(&self, x: &Vector3<f64>) -> Option<(f64, f64)> {
        let c = self.r * x + self.t;
        if c.z <= 0.0 {
            return None;
        }
        let h = self.k * c;
        Some((h.x / h.z, h.y / h.z))
    }

    /// The centre in world coordinates: the point `C` with `R C + t = 0`.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.r.transpose() * self.t)
    }

    /// The unit world direction of the ray through pixel `(u, v)`: `R^T K^-1 (u, v, 1)`, with
    /// `K^-1` applied by back substitution (K is upper triangular).
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let k = &self.k;
        let z = 1.0 / k[(2, 2)];
        let y = (v - k[(1, 2)] * z) / k[(1, 1)];
        let x = (u - k[(0, 1)] * y - k[(0, 2)] * z) / k[(0, 0)];
        (self.r.transpose() * Vector3::new(x, y, z)).normalize()
    }
}

/// Cameras in the Middlebury `*_par.txt` format: the count, then per camera its name and `K`,
/// `R` (row by row) and `t`, written here rather than by vt-fv so its parser is checked too.
pub fn format_par(cams: &[PinholeCamera]) -> String {
    let mut out = format!("{}\n", cams.len());
    for cam in cams {
        let rows = |m: &Matrix3<f64>| (0..9).map(move |i| m[(i / 3, i % 3)]).collect::<Vec<_>>();
        let numbers: Vec<String> = rows(&cam.k)
            .into_iter()
            .chain(rows(&cam.r))
            .chain(cam.t.iter().copied())
            .map(|v| format!("{v:.17e}"))
            .collect();
        out.push_str(&format!("{} {}\n", cam.name, numbers.join(" ")));
    }
    out
}

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cuboid {
    /// Smallest corner.
    pub min: Vector3<f64>,
    /// Largest corner.
    pub max: Vector3<f64>,
}

/// The union of a sphere and an axis-aligned box, with a procedural colour texture defined on
/// world coordinates (so every view sees the same colour at a surface point: exactly
/// photo-consistent, no shading). Every colour channel is at least 60, above the 0.19 silhouette
/// threshold; the background is black.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthObject {
    /// Sphere centre.
    pub sphere_centre: Vector3<f64>,
    /// Sphere radius.
    pub sphere_radius: f64,
    /// The box.
    pub cuboid: Cuboid,
}

impl Default for SynthObject {
    /// A sphere of radius 0.5 at the origin with a flat box poking out of it along x.
    fn default() -> Self {
        Self {
            sphere_centre: Vector3::zeros(),
            sphere_radius: 0.5,
            cuboid: Cuboid {
                min: Vector3::new(-0.75, -0.22, -0.4),
                max: Vector3::new(0.6, 0.25, 0.0),
            },
        }
    }
}

impl SynthObject {
    /// Whether a point is inside the solid.
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (p - self.sphere_centre).norm_squared() <= self.sphere_radius * self.sphere_radius
            || in_box(&self.cuboid, p)
    }

    /// A box holding the whole object.
    pub fn bounds(&self) -> Cuboid {
        let r = Vector3::repeat(self.sphere_radius);
        let (a, b) = (self.sphere_centre - r, self.sphere_centre + r);
        Cuboid {
            min: a.inf(&self.cuboid.min),
            max: b.sup(&self.cuboid.max),
        }
    }

    /// First intersection `t > 0` of the ray `o + t d` with the solid (camera outside it).
    pub fn intersect(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        // The first entry into a union of convex solids is the earliest entry into either.
        let s = sphere_entry(&self.sphere_centre, self.sphere_radius, o, d);
        let b = box_entry(&self.cuboid, o, d);
        match (s, b) {
            (Some(s), Some(b)) => Some(s.min(b)),
            (s, b) => s.or(b),
        }
    }

    /// The texture colour at a world point.
    pub fn colour(&self, p: &Vector3<f64>) -> [u8; 3] {
        let (x, y, z) = (p.x, p.y, p.z);
        let s1 = (5.0 * x + 2.0 * z).sin();
        let s2 = (6.0 * y - 3.0 * x + z).sin();
        let s3 = (11.0 * (x + y + z)).sin();
        let checker = ((3.0 * x).floor() + (3.0 * y).floor() + (3.0 * z).floor()).rem_euclid(2.0);
        let r = 150.0 + 60.0 * s1 + 35.0 * s3;
        let g = 140.0 + 55.0 * s2 + 45.0 * (2.0 * checker - 1.0);
        let b = 140.0 + 50.0 * s1 * s2 + 55.0 * (1.0 - 2.0 * checker) * s3.signum();
        [r, g, b].map(|c| c.clamp(60.0, 255.0).round() as u8)
    }

    /// Renders a view: colour (averaging `ss x ss` samples per pixel, black background) and the
    /// object mask (hit at the pixel centre).
    pub fn render(&self, cam: &PinholeCamera, w: u32, h: u32, ss: u32) -> (RgbImage, Mask) {
        let ss = ss.max(1);
        let o = cam.centre();
        let rows: Vec<(Vec<[u8; 3]>, Vec<bool>)> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut colours = Vec::with_capacity(w as usize);
                let mut hits = Vec::with_capacity(w as usize);
                for x in 0..w {
                    let mut acc = [0.0f64; 3];
                    for sy in 0..ss {
                        for sx in 0..ss {
                            let u = x as f64 - 0.5 + (sx as f64 + 0.5) / ss as f64;
                            let v = y as f64 - 0.5 + (sy as f64 + 0.5) / ss as f64;
                            let d = cam.ray(u, v);
                            if let Some(t) = self.intersect(&o, &d) {
                                let c = self.colour(&(o + d * t));
                                for k in 0..3 {
                                    acc[k] += c[k] as f64;
                                }
                            }
                        }
                    }
                    let n = (ss * ss) as f64;
                    colours.push(acc.map(|a| (a / n).round() as u8));
                    hits.push(self.intersect(&o, &cam.ray(x as f64, y as f64)).is_some());
                }
                (colours, hits)
            })
            .collect();
        let mut img = RgbImage::new(w, h);
        let mut mask = Mask::new(w, h);
        for (y, (cs, hs)) in rows.iter().enumerate() {
            for x in 0..w as usize {
                img.put_pixel(x as u32, y as u32, Rgb(cs[x]));
                mask.set(x as u32, y as u32, hs[x]);
            }
        }
        (img, mask)
    }

    /// `n` points on the true surface (deterministic for a `seed`), split between the sphere and
    /// the box in proportion to their areas, keeping only points not inside the other solid.
    pub fn surface_samples(&self, n: usize, seed: u64) -> Vec<Vector3<f64>> {
        let mut rng = vt_core::rng::Rng::new(seed);
        let e = self.cuboid.max - self.cuboid.min;
        let faces = [
            e.y * e.z,
            e.y * e.z,
            e.x * e.z,
            e.x * e.z,
            e.x * e.y,
            e.x * e.y,
        ];
        let box_area: f64 = faces.iter().sum();
        let sphere_area = 4.0 * std::f64::consts::PI * self.sphere_radius.powi(2);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let p = if rng.f64() * (box_area + sphere_area) < sphere_area {
                let z = rng.f64() * 2.0 - 1.0;
                let phi = rng.f64() * std::f64::consts::TAU;
                let s = (1.0 - z * z).sqrt();
                let p = self.sphere_centre
                    + Vector3::new(s * phi.cos(), s * phi.sin(), z) * self.sphere_radius;
                if in_box_strict(&self.cuboid, &p) {
                    continue;
                }
                p
            } else {
                let mut pick = rng.f64() * box_area;
                let mut face = 0;
                while face < 5 && pick > faces[face] {
                    pick -= faces[face];
                    face += 1;
                }
                let (a, b) = (rng.f64(), rng.f64());
                let (lo, hi) = (self.cuboid.min, self.cuboid.max);
                let p = match face / 2 {
                    0 => Vector3::new(
                        if face == 0 { lo.x } else { hi.x },
                        lo.y + a * e.y,
                        lo.z + b * e.z,
                    ),
                    1 => Vector3::new(
                        lo.x + a * e.x,
                        if face == 2 { lo.y } else { hi.y },
                        lo.z + b * e.z,
                    ),
                    _ => Vector3::new(
                        lo.x + a * e.x,
                        lo.y + b * e.y,
                        if face == 4 { lo.z } else { hi.z },
                    ),
                };
                if (p - self.sphere_centre).norm() < self.sphere_radius {
                    continue;
                }
                p
            };
            out.push(p);
        }
        out
    }

    /// Volume of the solid by the midpoint rule on an `n^3` grid over [`Self::bounds`].
    pub fn volume(&self, n: usize) -> f64 {
        let b = self.bounds();
        let e = b.max - b.min;
        let count: usize = (0..n)
            .into_par_iter()
            .map(|k| {
                let mut c = 0;
                for j in 0..n {
                    for i in 0..n {
                        let p = b.min
                            + Vector3::new(
                                (i as f64 + 0.5) * e.x,
                                (j as f64 + 0.5) * e.y,
                                (k as f64 + 0.5) * e.z,
                            ) / n as f64;
                        c += self.contains(&p) as usize;
                    }
                }
                c
            })
            .sum();
        count as f64 / (n * n * n) as f64 * e.x * e.y * e.z
    }
}

fn in_box(b: &Cuboid, p: &Vector3<f64>) -> bool {
    (0..3).all(|i| p[i] >= b.min[i] && p[i] <= b.max[i])
}

fn in_box_strict(b: &Cuboid, p: &Vector3<f64>) -> bool {
    (0..3).all(|i| p[i] > b.min[i] && p[i] < b.max[i])
}

fn sphere_entry(c: &Vector3<f64>, r: f64, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let oc = o - c;
    let b = d.dot(&oc);
    let disc = b * b - (oc.norm_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then_some(t)
}

fn box_entry(bx: &Cuboid, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        if d[i].abs() < 1e-300 {
            if o[i] < bx.min[i] || o[i] > bx.max[i] {
                return None;
            }
            continue;
        }
        let (a, b) = ((bx.min[i] - o[i]) / d[i], (bx.max[i] - o[i]) / d[i]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t1 >= t0 && t0 > 0.0).then_some(t0)
}

/// How to photograph the synthetic object.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneParams {
    /// Cameras on the ring, evenly spaced from angle 0 (8, as in the paper).
    pub n_views: usize,
    /// Image width (400, as in the paper).
    pub width: u32,
    /// Image height (400).
    pub height: u32,
    /// Distance of the cameras from the object centre (3.0).
    pub distance: f64,
    /// Elevation of the ring above the object's equator, degrees (25).
    pub elevation_deg: f64,
    /// Focal length as a multiple of the image width (1.3: the object fills about 70 %).
    pub focal_factor: f64,
    /// Ring angles (degrees, from the first camera) of extra viewpoints with ground truth
    /// ([10, 22.5]).
    pub extra_angles_deg: Vec<f64>,
    /// Samples per pixel along each axis, for anti-aliasing (2).
    pub supersample: u32,
    /// Ring angle of the first camera, degrees (0); the extra viewpoints turn with it.
    pub start_angle_deg: f64,
}

impl Default for SceneParams {
    fn default() -> Self {
        Self {
            n_views: 8,
            width: 400,
            height: 400,
            distance: 3.0,
            elevation_deg: 25.0,
            focal_factor: 1.3,
            extra_angles_deg: vec![10.0, 22.5],
            supersample: 2,
            start_angle_deg: 0.0,
        }
    }
}

/// Photos of the synthetic object with their cameras (vt-synth's own [`PinholeCamera`], or any
/// camera type after [`SynthData::try_map_cameras`]), masks and ground truth for extra views.
#[derive(Debug, Clone)]
pub struct SynthData<C = PinholeCamera> {
    /// The object.
    pub object: SynthObject,
    /// Reference cameras.
    pub cameras: Vec<C>,
    /// Reference photos.
    pub photos: Vec<RgbImage>,
    /// Exact object masks of the reference photos.
    pub masks: Vec<Mask>,
    /// Cameras of the extra viewpoints.
    pub extra_cameras: Vec<C>,
    /// Ground-truth photos of the extra viewpoints.
    pub extra_truth: Vec<RgbImage>,
    /// Exact object masks of the extra viewpoints.
    pub extra_masks: Vec<Mask>,
}

impl<C> SynthData<C> {
    /// The same data with every camera converted by `f` (e.g. into vt-fv's `Camera`).
    pub fn try_map_cameras<D, E>(self, f: impl Fn(&C) -> Result<D, E>) -> Result<SynthData<D>, E> {
        let cameras = self.cameras.iter().map(&f).collect::<Result<_, _>>()?;
        let extra_cameras = self
            .extra_cameras
            .iter()
            .map(&f)
            .collect::<Result<_, _>>()?;
        Ok(SynthData {
            object: self.object,
            cameras,
            photos: self.photos,
            masks: self.masks,
            extra_cameras,
            extra_truth: self.extra_truth,
            extra_masks: self.extra_masks,
        })
    }
}

/// The camera at `angle_deg` on the synthetic ring, looking at the origin with world `-z` down.
pub fn ring_camera(p: &SceneParams, angle_deg: f64) -> Result<PinholeCamera, String> {
    let f = p.focal_factor * p.width as f64;
    let (cx, cy) = ((p.width as f64 - 1.0) / 2.0, (p.height as f64 - 1.0) / 2.0);
    let k = Matrix3::new(f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0);
    let (a, e) = (angle_deg.to_radians(), p.elevation_deg.to_radians());
    let c = Vector3::new(a.cos() * e.cos(), a.sin() * e.cos(), e.sin()) * p.distance;
    PinholeCamera::looking_at(
        format!("synth{angle_deg:.1}"),
        k,
        c,
        Vector3::zeros(),
        -Vector3::z(),
    )
}

/// Cameras, photos and masks of a set of viewpoints.
type Shots = (Vec<PinholeCamera>, Vec<RgbImage>, Vec<Mask>);

/// Ray casts the default [`SynthObject`] from `n_views` ring cameras and the extra viewpoints.
pub fn generate(p: &SceneParams) -> Result<SynthData, String> {
    if p.n_views == 0 || p.width == 0 || p.height == 0 {
        return Err(format!(
            "synthetic object: {} views of {}x{} (need at least one view of at least 1x1)",
            p.n_views, p.width, p.height
        ));
    }
    let object = SynthObject::default();
    let shoot = |angles: &[f64]| -> Result<Shots, String> {
        let mut out = (Vec::new(), Vec::new(), Vec::new());
        for &a in angles {
            let cam = ring_camera(p, a)?;
            let (img, mask) = object.render(&cam, p.width, p.height, p.supersample);
            out.0.push(cam);
            out.1.push(img);
            out.2.push(mask);
        }
        Ok(out)
    };
    let angles: Vec<f64> = (0..p.n_views)
        .map(|i| p.start_angle_deg + 360.0 * i as f64 / p.n_views as f64)
        .collect();
    let extra: Vec<f64> = p
        .extra_angles_deg
        .iter()
        .map(|a| p.start_angle_deg + a)
        .collect();
    let (cameras, photos, masks) = shoot(&angles)?;
    let (extra_cameras, extra_truth, extra_masks) = shoot(&extra)?;
    Ok(SynthData {
        object,
        cameras,
        photos,
        masks,
        extra_cameras,
        extra_truth,
        extra_masks,
    })
}

/// Most pixels of a synthetic object's photos and truth images together (2 x views + 1 images).
pub const MAX_OBJECT_PIXELS: u64 = 1 << 28;

/// What `vt synth object` writes ([`crate::files::write_object`]): `views` cameras on the ring,
/// square images of side `size`, and the ring turned by a seed-determined angle (seed 0: the
/// first camera at angle 0). Truth is rendered at each midpoint between cameras and 10 degrees
/// past the first (or half the spacing, when that is less).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingParams {
    /// Cameras on the ring (3..=360; paper: 8).
    pub views: usize,
    /// Square image side, pixels (16..=4096; paper: 400).
    pub size: u32,
    /// Seed of the ring's starting angle.
    pub seed: u64,
}

impl RingParams {
    /// Checks the ranges and the memory the images take (all held at once) against
    /// [`MAX_OBJECT_PIXELS`]; messages name the values as `vt synth object`'s flags.
    pub fn check(&self) -> Result<(), String> {
        if self.views < 3 || self.views > 360 {
            return Err(format!("--views {} must be in 3..=360", self.views));
        }
        if self.size < 16 || self.size > 4096 {
            return Err(format!("--size {} must be in 16..=4096", self.size));
        }
        let pixels = (2 * self.views as u64 + 1) * self.size as u64 * self.size as u64;
        if pixels > MAX_OBJECT_PIXELS {
            return Err(format!(
                "--views {} at --size {} is {pixels} pixels of photos and truth, more than {MAX_OBJECT_PIXELS}",
                self.views, self.size
            ));
        }
        Ok(())
    }

    /// Degrees between neighbouring cameras.
    pub fn spacing(&self) -> f64 {
        360.0 / self.views as f64
    }

    /// Ring angle of the first camera, degrees: SplitMix64 of the seed as a fraction of the
    /// spacing; seed 0 keeps angle 0.
    pub fn start_angle(&self) -> f64 {
        if self.seed == 0 {
            0.0
        } else {
            vt_core::rng::unit(vt_core::rng::mix(self.seed)) * self.spacing()
        }
    }

    /// The scene to ray cast: the cameras and the truth viewpoints, relative to the first.
    pub fn scene(&self) -> SceneParams {
        let spacing = self.spacing();
        let mut extra = vec![10.0f64.min(spacing / 2.0)];
        extra.extend((0..self.views).map(|i| (i as f64 + 0.5) * spacing));
        extra.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
        SceneParams {
            n_views: self.views,
            width: self.size,
            height: self.size,
            extra_angles_deg: extra,
            start_angle_deg: self.start_angle(),
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_hit_what_contains_says() {
        let obj = SynthObject::default();
        let p = SceneParams {
            width: 40,
            height: 40,
            ..Default::default()
        };
        let cam = ring_camera(&p, 30.0).unwrap();
        for (u, v) in [(20.0, 20.0), (5.0, 20.0), (33.0, 12.0), (1.0, 1.0)] {
            let d = cam.ray(u, v);
            if let Some(t) = obj.intersect(&cam.centre(), &d) {
                let q = cam.centre() + d * t;
                assert!(
                    obj.contains(&(q + d * 1e-6)) && !obj.contains(&(q - d * 1e-6)),
                    "hit at {q} is not on the surface"
                );
            }
        }
        for s in obj.surface_samples(200, 1) {
            let dirs: Vec<Vector3<f64>> = (0..27)
                .filter(|&i| i != 13)
                .map(|i| {
                    Vector3::new(
                        (i % 3) as f64 - 1.0,
                        (i / 3 % 3) as f64 - 1.0,
                        (i / 9) as f64 - 1.0,
                    )
                })
                .collect();
            let near_surface = dirs.iter().any(|d| obj.contains(&(s + d * 1e-6)))
                && dirs.iter().any(|d| !obj.contains(&(s + d * 1e-6)));
            assert!(near_surface, "{s} is not on the surface");
        }
    }

    #[test]
    fn ray_and_projection_are_inverse() {
        let p = SceneParams::default();
        for angle in [0.0, 37.0, 200.0] {
            let cam = ring_camera(&p, angle).unwrap();
            // The ring cameras look at the origin: it projects to the principal point.
            let (u, v) = cam.project(&Vector3::zeros()).unwrap();
            assert!(
                (u - 199.5).abs() < 1e-9 && (v - 199.5).abs() < 1e-9,
                "({u}, {v})"
            );
            for (u, v) in [(0.0, 0.0), (123.0, 301.5), (399.0, 17.0)] {
                let x = cam.centre() + cam.ray(u, v) * 2.5;
                let (pu, pv) = cam.project(&x).unwrap();
                assert!(
                    (pu - u).abs() < 1e-9 && (pv - v).abs() < 1e-9,
                    "{angle}: ({u}, {v})"
                );
            }
            // R is a rotation and world -z points down the image.
            assert!((cam.r * cam.r.transpose() - Matrix3::identity()).norm() < 1e-12);
            assert!((cam.r.determinant() - 1.0).abs() < 1e-12);
            let below = cam.project(&Vector3::new(0.0, 0.0, -0.1)).unwrap();
            assert!(below.1 > v_of_origin(&cam));
        }
    }

    fn v_of_origin(cam: &PinholeCamera) -> f64 {
        cam.project(&Vector3::zeros()).unwrap().1
    }

    #[test]
    fn ring_params_check_and_angles() {
        let ok = RingParams {
            views: 8,
            size: 400,
            seed: 0,
        };
        assert_eq!(ok.check(), Ok(()));
        assert_eq!(ok.start_angle(), 0.0);
        assert_eq!(ok.scene().extra_angles_deg[..3], [10.0, 22.5, 67.5]);
        let turned = RingParams { seed: 5, ..ok };
        assert!((0.0..45.0).contains(&turned.start_angle()) && turned.start_angle() > 0.0);
        let errors = [
            RingParams { views: 2, ..ok },
            RingParams { size: 8, ..ok },
            RingParams {
                views: 360,
                size: 4096,
                seed: 0,
            },
        ]
        .map(|p| p.check().unwrap_err());
        assert_eq!(errors[0], "--views 2 must be in 3..=360");
        assert_eq!(errors[1], "--size 8 must be in 16..=4096");
        assert!(errors[2].contains("more than 268435456"), "{}", errors[2]);
    }
}
