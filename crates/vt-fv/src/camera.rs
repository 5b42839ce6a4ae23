//! Pinhole cameras `P = K [R | t]`, the Middlebury `*_par.txt` parser, and new-view cameras.
//!
//! Conventions (Middlebury's): a world point `X` maps to camera coordinates `R X + t`, then to
//! homogeneous pixels `K (R X + t)`; the image origin is top-left, `x` grows to the right
//! (columns) and `y` downwards (rows), and pixel centres sit at integer coordinates, so the pixel
//! holding a projection `(u, v)` is `(round(u), round(v))`. A point is in front of the camera when
//! its camera-space `z` is positive.

use nalgebra::{Matrix3, Matrix3x4, Rotation3, UnitQuaternion, Vector3};

use crate::{Error, Result};

/// A calibrated pinhole camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Name (the image file name in a `*_par.txt` file).
    pub name: String,
    /// Intrinsics (upper triangular, `k33 = 1`).
    pub k: Matrix3<f64>,
    /// World-to-camera rotation.
    pub r: Matrix3<f64>,
    /// World-to-camera translation.
    pub t: Vector3<f64>,
}

/// Smallest camera-space depth counted as "in front of the camera".
pub const MIN_DEPTH: f64 = 1e-9;

impl Camera {
    /// A camera from its parts; fails for a singular `K` or a non-finite entry.
    pub fn new(
        name: impl Into<String>,
        k: Matrix3<f64>,
        r: Matrix3<f64>,
        t: Vector3<f64>,
    ) -> Result<Self> {
        let name = name.into();
        if k.iter()
            .chain(r.iter())
            .chain(t.iter())
            .any(|v| !v.is_finite())
        {
            return Err(Error::BadCamera {
                name,
                what: "non-finite matrix entry".into(),
            });
        }
        if k.determinant().abs() < 1e-12 {
            return Err(Error::BadCamera {
                name,
                what: format!("K is singular (det {:e})", k.determinant()),
            });
        }
        Ok(Self { name, k, r, t })
    }

    /// A camera at `centre` looking at `target`, with image "down" as close as possible to
    /// `down` (a world direction), and intrinsics `k`.
    pub fn look_at(
        name: impl Into<String>,
        k: Matrix3<f64>,
        centre: Vector3<f64>,
        target: Vector3<f64>,
        down: Vector3<f64>,
    ) -> Result<Self> {
        let name = name.into();
        let z = target - centre;
        if z.norm() < 1e-12 {
            return Err(Error::BadCamera {
                name,
                what: "centre and target coincide".into(),
            });
        }
        let z = z.normalize();
        let mut y = down - z * down.dot(&z);
        if y.norm() < 1e-9 {
            // `down` is parallel to the viewing direction: take any perpendicular.
            let any = if z.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            y = any - z * any.dot(&z);
        }
        let y = y.normalize();
        let x = y.cross(&z);
        // Rows of R are the camera axes in world coordinates.
        let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let t = -(r * centre);
        Self::new(name, k, r, t)
    }

    /// The 3x4 projection matrix `P = K [R | t]`.
    pub fn projection(&self) -> Matrix3x4<f64> {
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r);
        rt.set_column(3, &self.t);
        self.k * rt
    }

    /// Camera-space coordinates `R X + t` of a world point.
    #[inline]
    pub fn to_camera(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.r * x + self.t
    }

    /// Projects a world point to continuous pixel coordinates `(u, v)` and its camera-space
    /// depth; `None` when the point is not in front of the camera.
    #[inline]
    pub fn project(&self, x: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let c = self.to_camera(x);
        if c.z <= MIN_DEPTH {
            return None;
        }
        let p = self.k * c;
        Some((p.x / p.z, p.y / p.z, c.z))
    }

    /// The camera centre in world coordinates, `C = -R^T t`.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.r.transpose() * self.t)
    }

    /// The unit viewing direction (optical axis) in world coordinates.
    pub fn forward(&self) -> Vector3<f64> {
        self.r.row(2).transpose().normalize()
    }

    /// The unit world direction of the ray through pixel `(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let kinv = self
            .k
            .try_inverse()
            .expect("K is invertible: checked by Camera::new");
        let d = self.r.transpose() * (kinv * Vector3::new(u, v, 1.0));
        d.normalize()
    }

    /// The world point on the ray through pixel `(u, v)` at camera-space depth `depth`.
    pub fn back_project(&self, u: f64, v: f64, depth: f64) -> Vector3<f64> {
        let kinv = self
            .k
            .try_inverse()
            .expect("K is invertible: checked by Camera::new");
        let c = kinv * Vector3::new(u, v, 1.0) * depth;
        self.r.transpose() * (c - self.t)
    }

    /// The same camera for an image scaled by `s` (e.g. 0.5 for half size): scales `K`'s first
    /// two rows so pixel centres stay at integer coordinates.
    pub fn scaled(&self, s: f64) -> Self {
        let mut k = self.k;
        // Pixel centres at integers: u' = s (u + 0.5) - 0.5.
        for c in 0..3 {
            k[(0, c)] *= s;
            k[(1, c)] *= s;
        }
        k[(0, 2)] += 0.5 * s - 0.5;
        k[(1, 2)] += 0.5 * s - 0.5;
        Self {
            name: self.name.clone(),
            k,
            r: self.r,
            t: self.t,
        }
    }
}

impl Camera {
    /// Checks what every loaded camera must be, whatever file it came from: `K` upper
    /// triangular with positive focal lengths and `k33 > 0`, `R` a rotation (orthonormal,
    /// determinant +1, within [`ROTATION_TOLERANCE`]); entries are finite by construction.
    pub fn check(&self) -> Result<()> {
        let k = &self.k;
        let bad = |what: String| Error::BadCamera {
            name: self.name.clone(),
            what,
        };
        if k[(1, 0)] != 0.0 || k[(2, 0)] != 0.0 || k[(2, 1)] != 0.0 {
            return Err(bad(format!(
                "K is not upper triangular (k21 {}, k31 {}, k32 {})",
                k[(1, 0)],
                k[(2, 0)],
                k[(2, 1)]
            )));
        }
        if !(k[(0, 0)] > 0.0 && k[(1, 1)] > 0.0 && k[(2, 2)] > 0.0) {
            return Err(bad(format!(
                "K's diagonal ({}, {}, {}) must be positive (focal lengths in pixels, k33 = 1; a y axis pointing up is not vt's convention)",
                k[(0, 0)],
                k[(1, 1)],
                k[(2, 2)]
            )));
        }
        let det = self.r.determinant();
        let ortho = (self.r.transpose() * self.r - Matrix3::identity())
            .abs()
            .max();
        if (det - 1.0).abs() > ROTATION_TOLERANCE || ortho > ROTATION_TOLERANCE {
            return Err(bad(format!(
                "R is not a rotation (det {det:.4}, max |R^T R - I| {ortho:.4}; tolerance {ROTATION_TOLERANCE})"
            )));
        }
        Ok(())
    }

    /// The camera of a 3x4 projection matrix `P ~ K [R | t]` (any scale and sign), by RQ
    /// decomposition of its left 3x3 block: `K` upper triangular with a positive diagonal and
    /// `k33 = 1`, `R` a rotation (det +1), `t = K^-1 p4`. The result is checked to give `P`
    /// back (relative difference under 1e-9 after scaling), so a matrix that is no projection
    /// (a singular left block) is refused.
    pub fn from_projection(name: impl Into<String>, p: &Matrix3x4<f64>) -> Result<Self> {
        let name = name.into();
        let bad = |what: String| Error::BadCamera {
            name: name.clone(),
            what,
        };
        if p.iter().any(|v| !v.is_finite()) {
            return Err(bad("projection matrix has a non-finite entry".into()));
        }
        let scale = p.norm();
        if scale == 0.0 {
            return Err(bad("projection matrix is zero".into()));
        }
        // P is defined up to scale: make the left block's determinant positive, so that a
        // positive-diagonal K leaves det R = +1.
        let mut p = p / scale;
        let m = p.fixed_view::<3, 3>(0, 0).into_owned();
        let det = m.determinant();
        if det.abs() < 1e-12 {
            return Err(bad(format!(
                "the left 3x3 block of P is singular (det {det:e} after scaling P to norm 1): not a perspective camera"
            )));
        }
        if det < 0.0 {
            p = -p;
        }
        let m = p.fixed_view::<3, 3>(0, 0).into_owned();
        // RQ by QR of the row-reversed transpose: with J the exchange matrix,
        // (J M)^T = Q U  =>  M = (J U^T J) (J Q^T), J U^T J upper triangular.
        let j = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
        let qr = (j * m).transpose().qr();
        let (q, u) = (qr.q(), qr.r());
        let mut k = j * u.transpose() * j;
        let mut r = j * q.transpose();
        // Signs: K's diagonal positive (D K, D R with D = D^-1).
        for i in 0..3 {
            if k[(i, i)] < 0.0 {
                for row in 0..3 {
                    k[(row, i)] = -k[(row, i)];
                }
                for col in 0..3 {
                    r[(i, col)] = -r[(i, col)];
                }
            }
        }
        let kinv = k
            .try_inverse()
            .ok_or_else(|| bad("K of the decomposition is singular".into()))?;
        let t = kinv * p.column(3);
        let k33 = k[(2, 2)];
        let k = k / k33;
        // Exact zeros below the diagonal (QR leaves rounding there).
        let k = Matrix3::new(
            k[(0, 0)],
            k[(0, 1)],
            k[(0, 2)],
            0.0,
            k[(1, 1)],
            k[(1, 2)],
            0.0,
            0.0,
            1.0,
        );
        let cam = Camera::new(name.clone(), k, r, t)?;
        cam.check()?;
        // Reprojection check: K [R | t] is P up to the positive factor k33.
        let back = cam.projection() * k33;
        let diff = (back - p).abs().max();
        if diff > 1e-9 {
            return Err(bad(format!(
                "K [R | t] differs from P by {diff:e} (relative): the decomposition failed"
            )));
        }
        Ok(cam)
    }
}

/// Parses a projection-matrix file: 12 numbers, the rows of `P` (3 rows of 4, any layout), `#`
/// comments; a first line `CONTOUR` (PMVS/VisualSFM's `txt/` files) is skipped. Errors name the
/// 1-based line.
pub fn parse_projection(text: &str) -> Result<Matrix3x4<f64>> {
    let mut v = Vec::with_capacity(12);
    let mut last = 1;
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() || (v.is_empty() && line == "CONTOUR") {
            continue;
        }
        last = i + 1;
        for tok in line.split_whitespace() {
            if v.len() == 12 {
                return Err(Error::Line {
                    line: i + 1,
                    what: "more than 12 numbers (a projection matrix is 3 rows of 4)".into(),
                });
            }
            let x: f64 = tok.parse().map_err(|_| Error::Line {
                line: i + 1,
                what: format!("{:?} is not a number", shorten(tok)),
            })?;
            if !x.is_finite() {
                return Err(Error::Line {
                    line: i + 1,
                    what: format!("{:?} is not finite", shorten(tok)),
                });
            }
            v.push(x);
        }
    }
    if v.len() != 12 {
        return Err(Error::Line {
            line: last,
            what: format!(
                "{} numbers, a projection matrix has 12 (3 rows of 4)",
                v.len()
            ),
        });
    }
    Ok(Matrix3x4::from_row_slice(&v))
}

/// Parses a Middlebury `*_par.txt` camera file: the first line is the camera count, then one
/// line per camera, `name k11 k12 k13 k21 k22 k23 k31 k32 k33 r11 .. r33 t1 t2 t3`.
/// Blank lines are skipped. Errors name the 1-based line number and what is wrong.
pub fn parse_par(text: &str) -> Result<Vec<Camera>> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (hline, header) = lines.next().ok_or(Error::ParLine {
        line: 1,
        what: "empty file, expected a camera count".into(),
    })?;
    let declared: usize = header.trim().parse().map_err(|_| Error::ParLine {
        line: hline + 1,
        what: format!(
            "expected the camera count, got {:?}",
            shorten(header.trim())
        ),
    })?;
    if declared > MAX_CAMERAS {
        return Err(Error::ParLine {
            line: hline + 1,
            what: format!("{declared} cameras, more than the {MAX_CAMERAS} vt reads"),
        });
    }
    let mut cams = Vec::with_capacity(declared);
    for (i, line) in lines {
        let lineno = i + 1;
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 22 {
            return Err(Error::ParLine {
                line: lineno,
                what: format!(
                    "expected 22 fields (name + 9 K + 9 R + 3 t), got {}",
                    fields.len()
                ),
            });
        }
        let mut v = [0.0f64; 21];
        for (j, f) in fields[1..].iter().enumerate() {
            let x: f64 = f.parse().map_err(|_| Error::ParLine {
                line: lineno,
                what: format!(
                    "field {} ({}) is not a number: {:?}",
                    j + 2,
                    field_name(j),
                    shorten(f)
                ),
            })?;
            if !x.is_finite() {
                return Err(Error::ParLine {
                    line: lineno,
                    what: format!(
                        "field {} ({}) is not finite: {:?}",
                        j + 2,
                        field_name(j),
                        shorten(f)
                    ),
                });
            }
            v[j] = x;
        }
        let k = Matrix3::from_row_slice(&v[0..9]);
        let r = Matrix3::from_row_slice(&v[9..18]);
        let t = Vector3::new(v[18], v[19], v[20]);
        check_par_camera(fields[0], &r).map_err(|what| Error::ParLine { line: lineno, what })?;
        let cam = Camera::new(fields[0], k, r, t).map_err(|e| Error::ParLine {
            line: lineno,
            what: e.to_string(),
        })?;
        cams.push(cam);
    }
    if cams.len() != declared {
        return Err(Error::ParCount {
            declared,
            found: cams.len(),
        });
    }
    Ok(cams)
}

/// Most cameras a par file may declare (checked before anything is allocated).
pub const MAX_CAMERAS: usize = 10_000;
/// Largest deviation of a par file's R from a rotation: `max |R^T R - I|` and `|det R - 1|`.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// A user's value shortened for a message (at most 40 characters): vt-io's rule, for every
/// message of every command.
pub(crate) use vt_io::output::shorten;

/// Checks one par-file camera: its image name stays inside the data folder (relative, no `..`)
/// and its R is a rotation (orthonormal, determinant +1, within [`ROTATION_TOLERANCE`]).
fn check_par_camera(name: &str, r: &Matrix3<f64>) -> std::result::Result<(), String> {
    let p = std::path::Path::new(name);
    let inside = !name.contains('\\')
        && p.components().all(|c| {
            matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        });
    if !inside {
        return Err(format!(
            "image name {:?} points outside the data folder (use a name relative to it, without ..)",
            shorten(name)
        ));
    }
    let det = r.determinant();
    let ortho = (r.transpose() * r - Matrix3::identity()).abs().max();
    if (det - 1.0).abs() > ROTATION_TOLERANCE || ortho > ROTATION_TOLERANCE {
        return Err(format!(
            "camera {:?}: R is not a rotation (det {det:.4}, max |R^T R - I| {ortho:.4}; tolerance {ROTATION_TOLERANCE})",
            shorten(name)
        ));
    }
    Ok(())
}

fn field_name(j: usize) -> String {
    match j {
        0..=8 => format!("k{}{}", j / 3 + 1, j % 3 + 1),
        9..=17 => format!("r{}{}", (j - 9) / 3 + 1, (j - 9) % 3 + 1),
        _ => format!("t{}", j - 17),
    }
}

/// Writes cameras in the Middlebury `*_par.txt` format.
pub fn format_par(cams: &[Camera]) -> String {
    let mut s = format!("{}\n", cams.len());
    for c in cams {
        s.push_str(&c.name);
        for v in
            c.k.transpose()
                .iter()
                .chain(c.r.transpose().iter())
                .chain(c.t.iter())
        {
            s.push_str(&format!(" {v:.17e}"));
        }
        s.push('\n');
    }
    s
}

/// The centre of the circle through `points` in the plane through `origin` across `normal`,
/// by the algebraic least-squares fit (x^2 + y^2 + D x + E y + F = 0): photos over part of a
/// turn have their centroid off the axis they turn about. `None` when the points are nearly
/// collinear (the fit is ill-conditioned) or the centre lands absurdly far.
fn circle_centre(
    points: &[Vector3<f64>],
    origin: &Vector3<f64>,
    normal: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let any = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = (any - normal * any.dot(normal)).normalize();
    let e2 = normal.cross(&e1);
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    let mut spread = 0.0f64;
    for p in points {
        let d = p - origin;
        let (x, y) = (d.dot(&e1), d.dot(&e2));
        let row = Vector3::new(x, y, 1.0);
        a += row * row.transpose();
        b -= row * (x * x + y * y);
        spread = spread.max((x * x + y * y).sqrt());
    }
    let eig = a.symmetric_eigen();
    let (lo, hi) = (eig.eigenvalues.min(), eig.eigenvalues.max());
    if spread.is_nan() || spread <= 0.0 || lo <= 1e-9 * hi {
        return None;
    }
    let sol = a.try_inverse()? * b;
    let (cx, cy) = (-sol.x / 2.0, -sol.y / 2.0);
    let c = origin + e1 * cx + e2 * cy;
    ((cx * cx + cy * cy).sqrt() <= 10.0 * spread && c.iter().all(|v| v.is_finite())).then_some(c)
}

/// Length of the mean of the cameras' unit "down" vectors from which [`Ring::fit`] takes the
/// photos as upright (0.9, about 25 degrees of spread): the ring is then fitted across that
/// direction.
pub const UPRIGHT_AGREEMENT: f64 = 0.9;

/// The circle through the camera centres: in the plane across the photos' common down
/// direction when they are upright, else in the plane fitted by least squares.
#[derive(Debug, Clone, PartialEq)]
pub struct Ring {
    /// Centre of the circle fitted to the camera centres in the ring's plane (algebraic least
    /// squares, in the plane through their centroid; the centroid when that fit is
    /// ill-conditioned).
    pub centre: Vector3<f64>,
    /// Mean distance of the centres (projected on the plane) from `centre`.
    pub radius: f64,
    /// Unit normal of the best-fit plane, oriented so angles grow from camera 0 towards camera 1.
    pub normal: Vector3<f64>,
    /// Unit in-plane direction of angle 0 (towards camera 0).
    pub u: Vector3<f64>,
    /// Unit in-plane direction of angle 90 degrees, `normal x u`.
    pub v: Vector3<f64>,
    /// Average intrinsics of the cameras.
    pub k: Matrix3<f64>,
    /// Average image "down" direction of the cameras, in world coordinates.
    pub down: Vector3<f64>,
    /// Average image "down" direction of the cameras in each camera's own place on the ring:
    /// components along `normal`, along the ring's tangent (`normal x radial`) and along the
    /// outward radial direction; `Some` unless the photos agree on one world down direction
    /// ([`UPRIGHT_AGREEMENT`]; photos held sideways, as the temple's, do not). A ring camera
    /// then takes its down direction from these: a world direction in the ring's plane is
    /// parallel to the view somewhere round the ring, where the picture would spin half a turn
    /// between two frames.
    pub down_local: Option<Vector3<f64>>,
}

impl Ring {
    /// Fits a ring to at least three cameras.
    pub fn fit(cams: &[Camera]) -> Result<Self> {
        if cams.len() < 3 {
            return Err(Error::TooFew {
                what: "cameras to fit a ring".into(),
                got: cams.len(),
                need: 3,
            });
        }
        let centres: Vec<Vector3<f64>> = cams.iter().map(Camera::centre).collect();
        let n = centres.len() as f64;
        let centroid = centres.iter().sum::<Vector3<f64>>() / n;
        let centre = centroid;
        let mut cov = Matrix3::zeros();
        for c in &centres {
            let d = c - centre;
            cov += d * d.transpose();
        }
        let eig = cov.symmetric_eigen();
        let imin = eig.eigenvalues.imin();
        // Photos held upright agree on one world "down" (the mean of their unit down vectors
        // is near 1 long): the ring then lies across it, whatever plane the camera centres fit
        // best (hand-held photos at varying heights over part of a turn tilt that plane, and
        // an orbit in it passes over the object and under it).
        let down_sum = cams
            .iter()
            .map(|c| c.r.row(1).transpose())
            .sum::<Vector3<f64>>();
        let upright = down_sum.norm() / n >= UPRIGHT_AGREEMENT;
        let mut normal: Vector3<f64> = if upright {
            -down_sum.normalize()
        } else {
            eig.eigenvectors.column(imin).into_owned().normalize()
        };
        let centre = circle_centre(&centres, &centroid, &normal).unwrap_or(centroid);
        let inplane = |p: &Vector3<f64>, nrm: &Vector3<f64>| {
            let d = p - centre;
            d - nrm * d.dot(nrm)
        };
        let u = inplane(&centres[0], &normal);
        if u.norm() < 1e-12 {
            return Err(Error::BadCamera {
                name: cams[0].name.clone(),
                what: "camera centre is at the ring centre".into(),
            });
        }
        let u = u.normalize();
        let mut v = normal.cross(&u);
        if inplane(&centres[1], &normal).dot(&v) < 0.0 {
            normal = -normal;
            v = -v;
        }
        let radius = centres
            .iter()
            .map(|c| inplane(c, &normal).norm())
            .sum::<f64>()
            / n;
        let k = cams.iter().map(|c| c.k).sum::<Matrix3<f64>>() / n;
        let down = cams
            .iter()
            .map(|c| c.r.row(1).transpose())
            .sum::<Vector3<f64>>();
        let down = if down.norm() > 1e-9 {
            down.normalize()
        } else {
            -normal
        };
        let mut down_local = Vector3::zeros();
        for (c, cam) in centres.iter().zip(cams) {
            let radial = inplane(c, &normal);
            let d = cam.r.row(1).transpose();
            if radial.norm() < 1e-12 {
                continue;
            }
            let radial = radial.normalize();
            let tangent = normal.cross(&radial);
            down_local += Vector3::new(d.dot(&normal), d.dot(&tangent), d.dot(&radial));
        }
        let down_local = (!upright && down_local.norm() > 1e-9).then(|| down_local.normalize());
        Ok(Self {
            centre,
            radius,
            normal,
            u,
            v,
            k,
            down,
            down_local,
        })
    }

    /// The point of the ring at `angle_deg` (0 = camera 0's direction, growing towards camera 1).
    pub fn point(&self, angle_deg: f64) -> Vector3<f64> {
        let a = angle_deg.to_radians();
        self.centre + (self.u * a.cos() + self.v * a.sin()) * self.radius
    }

    /// The angle (degrees, in `(-180, 180]`) of a world point's projection on the ring plane.
    pub fn angle_of(&self, p: &Vector3<f64>) -> f64 {
        let d = p - self.centre;
        d.dot(&self.v).atan2(d.dot(&self.u)).to_degrees()
    }

    /// A camera on the ring at `angle_deg` looking at `target` (e.g. the ring centre or the volume
    /// centre), with the cameras' average `K` and their average "down" direction relative to
    /// the ring at that angle ([`Ring::down_local`]).
    pub fn camera(&self, angle_deg: f64, target: &Vector3<f64>) -> Result<Camera> {
        let a = angle_deg.to_radians();
        let radial = self.u * a.cos() + self.v * a.sin();
        let tangent = self.normal.cross(&radial);
        let down = match self.down_local {
            Some(l) => self.normal * l.x + tangent * l.y + radial * l.z,
            None => self.down,
        };
        Camera::look_at(
            format!("ring{angle_deg:.2}"),
            self.k,
            self.point(angle_deg),
            *target,
            down,
        )
    }
}

/// A new camera from a spec: a par line `name k11..k33 r11..r33 t1 t2 t3` (scaled by `scale`,
/// like the photos), `angle:DEG` (on the cameras' [`Ring`], 0 = first camera, growing towards
/// the second, looking at `target`) or `between:I,J,T` (between views I and J, 0-based, at T in
/// [0, 1], round `target`: see [`interpolate_around`]).
pub fn parse_camera_spec(
    spec: &str,
    cams: &[Camera],
    scale: f64,
    target: &Vector3<f64>,
) -> Result<Camera> {
    let spec = spec.trim();
    let bad = |what: String| Error::CameraSpec {
        spec: spec.to_string(),
        what,
    };
    if let Some(deg) = spec.strip_prefix("angle:") {
        let deg: f64 = deg
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(format!("angle {deg:?} is not a number")))?;
        let ring = Ring::fit(cams).map_err(|e| bad(e.to_string()))?;
        return ring.camera(deg, target).map_err(|e| bad(e.to_string()));
    }
    if let Some(rest) = spec.strip_prefix("between:") {
        let f: Vec<&str> = rest.split(',').map(str::trim).collect();
        if f.len() != 3 {
            return Err(bad("expected between:I,J,T".into()));
        }
        let idx = |s: &str| -> Result<usize> {
            let i: usize = s
                .parse()
                .map_err(|_| bad(format!("view {s:?} is not a whole number")))?;
            if i >= cams.len() {
                return Err(bad(format!(
                    "view {i} does not exist ({} views, 0-based)",
                    cams.len()
                )));
            }
            Ok(i)
        };
        let (i, j) = (idx(f[0])?, idx(f[1])?);
        let t: f64 = f[2]
            .parse()
            .ok()
            .filter(|t| (0.0..=1.0).contains(t))
            .ok_or_else(|| bad(format!("T {:?} is not in [0, 1]", f[2])))?;
        return interpolate_around(&cams[i], &cams[j], t, target).map_err(|e| bad(e.to_string()));
    }
    // A word and a colon is a named spec, not a par line: an unknown or misspelt name.
    if let Some((word, _)) = spec.split_once(':') {
        if !word.is_empty() && word.chars().all(|c| c.is_ascii_alphabetic()) {
            let near = ["angle", "between"]
                .into_iter()
                .find(|k| edit_distance(&word.to_ascii_lowercase(), k) <= 2)
                .map(|k| format!(" (did you mean {k}:?)"))
                .unwrap_or_default();
            return Err(bad(format!(
                "unknown camera spec '{word}:'{near}; expected angle:DEG, between:I,J,T or a \
                 par line (name k11 .. k33 r11 .. r33 t1 t2 t3)"
            )));
        }
    }
    let cam = parse_par(&format!("1\n{spec}\n"))
        .map_err(|e| {
            // The spec is line 2 of the wrapped text; report it as the spec's.
            let msg = e.to_string();
            let msg = msg.strip_prefix("camera file line 2: ").unwrap_or(&msg);
            bad(format!("par line: {msg}"))
        })?
        .remove(0);
    Ok(if scale == 1.0 { cam } else { cam.scaled(scale) })
}

/// Levenshtein distance of two short ASCII words.
fn edit_distance(a: &str, b: &str) -> usize {
    let b = b.as_bytes();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, &ca) in a.as_bytes().iter().enumerate() {
        let mut cur = vec![i + 1];
        for (j, &cb) in b.iter().enumerate() {
            cur.push(
                (prev[j] + usize::from(ca != cb))
                    .min(prev[j + 1] + 1)
                    .min(cur[j] + 1),
            );
        }
        prev = cur;
    }
    prev[b.len()]
}

/// A camera between cameras `a` and `b` at `s` in `[0, 1]`: rotation by slerp, centre and `K` by
/// linear interpolation.
pub fn interpolate(a: &Camera, b: &Camera, s: f64) -> Result<Camera> {
    let qa = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&a.r));
    let qb = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&b.r));
    let q = qa
        .try_slerp(&qb, s, 1e-9)
        .unwrap_or(if s < 0.5 { qa } else { qb });
    let r = q.to_rotation_matrix().into_inner();
    let c = a.centre() * (1.0 - s) + b.centre() * s;
    let k = a.k * (1.0 - s) + b.k * s;
    Camera::new(format!("{}~{}@{s:.3}", a.name, b.name), k, r, -(r * c))
}

/// [`interpolate`] carried round `target`: the centre's direction from `target` by slerp and
/// its distance by lerp, and the camera turned with it. Each camera's rotation is split into
/// the look at `target` from its centre (its own down direction kept) and the offset from that
/// look (how far off-centre the target sits in its photo); the new camera looks at `target`
/// from its centre with the lerped down direction, then takes the slerped offset. Views far
/// apart round an object (lego's r_26 and r_86 are 98 degrees apart) would otherwise put the
/// camera inside the orbit, close enough to see only part of the object.
pub fn interpolate_around(a: &Camera, b: &Camera, s: f64, target: &Vector3<f64>) -> Result<Camera> {
    let (da, db) = (a.centre() - target, b.centre() - target);
    let (ra, rb) = (da.norm(), db.norm());
    let angle = if ra < 1e-12 || rb < 1e-12 {
        0.0
    } else {
        (da / ra).dot(&(db / rb)).clamp(-1.0, 1.0).acos()
    };
    // A camera at the target, nearly the same direction, or opposite ones (no unique great
    // circle): the straight line.
    if !(1e-9..=std::f64::consts::PI - 1e-6).contains(&angle) {
        return interpolate(a, b, s);
    }
    let dir = (da / ra * ((1.0 - s) * angle).sin() + db / rb * (s * angle).sin()) / angle.sin();
    let c = target + dir * ((1.0 - s) * ra + s * rb);
    let down = |cam: &Camera| cam.r.row(1).transpose();
    let look = |centre: Vector3<f64>, d: Vector3<f64>| -> Result<Matrix3<f64>> {
        Ok(Camera::look_at("", Matrix3::identity(), centre, *target, d)?.r)
    };
    let quat = |m: Matrix3<f64>| UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m));
    let (la, lb) = (look(a.centre(), down(a))?, look(b.centre(), down(b))?);
    let (oa, ob) = (quat(a.r * la.transpose()), quat(b.r * lb.transpose()));
    let offset = oa
        .try_slerp(&ob, s, 1e-9)
        .unwrap_or(if s < 0.5 { oa } else { ob });
    let d = (down(a) * (1.0 - s) + down(b) * s)
        .try_normalize(1e-9)
        .unwrap_or_else(|| down(a));
    let r = offset.to_rotation_matrix().into_inner() * look(c, d)?;
    let k = a.k * (1.0 - s) + b.k * s;
    Camera::new(format!("{}~{}@{s:.3}", a.name, b.name), k, r, -(r * c))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    const TWO: &str = "2\n\
        a.png 1520.4 0 302.3 0 1525.9 246.9 0 0 1 0.0218 0.9833 -0.1807 0.9986 -0.0127 0.0520 0.0488 -0.1816 -0.9822 -0.07 0.02 0.61\n\
        b.png 1520.4 0 302.3 0 1525.9 246.9 0 0 1 1 0 0 0 1 0 0 0 1 0 0 1\n";

    fn check_err(text: &str, line: usize, needle: &str) {
        match parse_par(text) {
            Err(Error::ParLine { line: l, what }) => {
                assert_eq!(l, line, "wrong line for {text:?}: {what}");
                assert!(what.contains(needle), "message {what:?} lacks {needle:?}");
            }
            other => panic!("expected a ParLine error at line {line}, got {other:?}"),
        }
    }

    #[test]
    fn parses_two_cameras() {
        let cams = parse_par(TWO).unwrap();
        assert_eq!(cams.len(), 2);
        assert_eq!(cams[1].name, "b.png");
        assert_relative_eq!(cams[1].t.z, 1.0);
        assert_relative_eq!(cams[0].k[(0, 2)], 302.3);
    }

    #[test]
    fn par_errors_name_the_line() {
        check_err("2\na.png 1 2 3\n", 2, "got 4");
        check_err(&TWO.replace("0.61", "NaN"), 2, "t3");
        check_err(&TWO.replace("0.61", "inf"), 2, "not finite");
        check_err(
            &TWO.replace(" 0 0 1 0 0 1\n", " 0 0 1 0 0 x\n"),
            3,
            "not a number",
        );
        check_err(
            &TWO.replace("b.png 1520.4 0 302.3 0 1525.9", "b.png 0 0 0 0 0"),
            3,
            "singular",
        );
        check_err("two\n", 1, "count");
        assert_eq!(
            parse_par("3\n".to_string().as_str()).unwrap_err(),
            Error::ParCount {
                declared: 3,
                found: 0
            }
        );
    }

    #[test]
    fn par_round_trip() {
        let cams = parse_par(TWO).unwrap();
        let again = parse_par(&format_par(&cams)).unwrap();
        assert_eq!(cams, again);
    }

    fn test_camera(yaw: f64, pitch: f64, dist: f64) -> Camera {
        let k = Matrix3::new(500.0, 0.0, 200.0, 0.0, 510.0, 190.0, 0.0, 0.0, 1.0);
        let c = Vector3::new(
            yaw.cos() * pitch.cos(),
            yaw.sin() * pitch.cos(),
            pitch.sin(),
        ) * dist;
        Camera::look_at("t", k, c, Vector3::zeros(), -Vector3::z()).unwrap()
    }

    proptest! {
        #[test]
        fn project_back_project_round_trip(yaw in -3.1f64..3.1, pitch in -1.2f64..1.2, dist in 1.0f64..10.0,
                                            u in 0.0f64..400.0, v in 0.0f64..400.0, depth in 0.1f64..20.0) {
            let cam = test_camera(yaw, pitch, dist);
            let x = cam.back_project(u, v, depth);
            let (pu, pv, pd) = cam.project(&x).unwrap();
            prop_assert!((pu - u).abs() < 1e-6 && (pv - v).abs() < 1e-6 && (pd - depth).abs() < 1e-9);
            // The ray through (u, v) passes through x.
            let d = cam.ray(u, v);
            let along = (x - cam.centre()).normalize();
            prop_assert!((d - along).norm() < 1e-9);
            // P = K[R|t] agrees with project.
            let h = cam.projection() * x.push(1.0);
            prop_assert!((h.x / h.z - u).abs() < 1e-6);
        }

        #[test]
        fn scaled_camera_matches_scaled_pixels(u in 0.0f64..400.0, v in 0.0f64..400.0, s in 0.2f64..2.0) {
            let cam = test_camera(0.3, 0.2, 4.0);
            let x = cam.back_project(u, v, 3.0);
            let (su, sv, _) = cam.scaled(s).project(&x).unwrap();
            prop_assert!((su - (s * (u + 0.5) - 0.5)).abs() < 1e-6 && (sv - (s * (v + 0.5) - 0.5)).abs() < 1e-6);
        }
    }

    #[test]
    fn projection_matrix_decomposes_to_its_camera() {
        for (i, (yaw, pitch, dist)) in [(0.3, 0.2, 4.0), (-2.5, -0.9, 1.5), (1.2, 1.1, 9.0)]
            .into_iter()
            .enumerate()
        {
            let mut cam = test_camera(yaw, pitch, dist);
            cam.k[(0, 1)] = 0.7 * i as f64; // skew survives
            let p = cam.projection();
            for s in [1.0, -3.5, 1e-4] {
                let back = Camera::from_projection("p", &(p * s)).unwrap();
                assert!(
                    (back.k - cam.k).abs().max() < 1e-9,
                    "{} vs {}",
                    back.k,
                    cam.k
                );
                assert!((back.r - cam.r).abs().max() < 1e-12);
                assert!((back.t - cam.t).abs().max() < 1e-9);
                assert!((back.r.determinant() - 1.0).abs() < 1e-12);
            }
        }
        let text = "CONTOUR\n# P\n1 0 0 0\n0 1 0 0\n0 0 1 1 # row 3\n";
        let p = parse_projection(text).unwrap();
        let c = Camera::from_projection("id", &p).unwrap();
        assert!((c.t - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12);
        for (text, line, says) in [
            ("1 0 0 0\n0 1 0 0\n0 0 1\n", 3, "11 numbers"),
            ("1 0 0 0\n0 1 0 0\n0 0 1 nan\n", 3, "not finite"),
            ("1 0 0 0 0 1 0 0 0 0 1 0 5\n", 1, "more than 12"),
        ] {
            match parse_projection(text) {
                Err(Error::Line { line: l, what }) => {
                    assert_eq!(l, line);
                    assert!(what.contains(says), "{what}");
                }
                other => panic!("{other:?}"),
            }
        }
        let singular = Matrix3x4::new(1.0, 2.0, 3.0, 0.0, 2.0, 4.0, 6.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let e = Camera::from_projection("s", &singular)
            .unwrap_err()
            .to_string();
        assert!(e.contains("singular"), "{e}");
    }

    #[test]
    fn ring_recovers_cameras() {
        let cams: Vec<Camera> = (0..8)
            .map(|i| test_camera(i as f64 * std::f64::consts::FRAC_PI_4, 0.4, 3.0))
            .collect();
        let ring = Ring::fit(&cams).unwrap();
        assert_relative_eq!(ring.radius, 3.0 * 0.4f64.cos(), epsilon = 1e-9);
        assert_relative_eq!(ring.angle_of(&cams[2].centre()), 90.0, epsilon = 1e-6);
        let target = Vector3::zeros();
        let c2 = ring.camera(90.0, &target).unwrap();
        assert!((c2.centre() - cams[2].centre()).norm() < 1e-9);
        assert!(
            (c2.r - cams[2].r).norm() < 1e-6,
            "{} vs {}",
            c2.r,
            cams[2].r
        );
        // Photos held sideways (image down along the ring's tangent, as the temple's): every
        // ring camera is held the same way, between the cameras too.
        let sideways: Vec<Camera> = (0..8)
            .map(|i| {
                let a = i as f64 * std::f64::consts::FRAC_PI_4;
                let c = Vector3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.5);
                let tangent = Vector3::new(-a.sin(), a.cos(), 0.0);
                let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
                Camera::look_at("s", k, c, target, tangent).unwrap()
            })
            .collect();
        let ring = Ring::fit(&sideways).unwrap();
        for deg in [0.0, 10.0, 22.5, 100.0, 200.0, 300.0] {
            let c = ring.camera(deg, &target).unwrap();
            let a = ring.angle_of(&c.centre()).to_radians();
            let tangent = ring.normal.cross(&(ring.u * a.cos() + ring.v * a.sin()));
            let down = c.r.row(1).transpose();
            assert!(
                down.dot(&tangent) > 0.99,
                "{deg}: down {down} vs tangent {tangent}"
            );
        }
        let mid = interpolate(&cams[0], &cams[2], 0.5).unwrap();
        assert!((mid.r - cams[1].r).norm() < 1e-6);
        let end = interpolate(&cams[0], &cams[2], 1.0).unwrap();
        assert!((end.centre() - cams[2].centre()).norm() < 1e-9);
        // Round the target: views 81 degrees apart at distance 3; the straight line's middle is
        // 3 cos 40.6 = 2.28 from the target, the orbit's stays at 3 and still looks at it.
        let cut = interpolate(&cams[0], &cams[2], 0.5).unwrap();
        assert!(((cut.centre() - target).norm() - 2.28).abs() < 0.01);
        for s in [0.0, 0.25, 0.5, 0.75, 1.0] {
            let c = interpolate_around(&cams[0], &cams[2], s, &target).unwrap();
            assert_relative_eq!((c.centre() - target).norm(), 3.0, epsilon = 1e-9);
            let (u, v, _) = c.project(&target).unwrap();
            let (pu, pv) = (c.k[(0, 2)], c.k[(1, 2)]);
            assert!(
                (u - pu).hypot(v - pv) < 1.0,
                "{s}: target at {u:.2}, {v:.2}"
            );
        }
        let mid = interpolate_around(&cams[0], &cams[2], 0.5, &target).unwrap();
        // The great circle rises above the ring between two views at one elevation (23 degrees
        // here, 31 at the middle): 0.41 from the ring's own middle camera.
        assert!((mid.centre() - cams[1].centre()).norm() < 0.45);
        for (s, cam) in [(0.0, &cams[0]), (1.0, &cams[2])] {
            let end = interpolate_around(&cams[0], &cams[2], s, &target).unwrap();
            assert!((end.centre() - cam.centre()).norm() < 1e-9);
            assert!((end.r - cam.r).norm() < 1e-9);
        }
        // A camera that does not look at the target keeps its offset: the target stays where
        // it was in its photo at both ends, and between them moves between the two places.
        let turn = Rotation3::from_euler_angles(0.0, 0.05, 0.0).into_inner();
        let off = Camera::new(
            "o",
            cams[2].k,
            turn * cams[2].r,
            -(turn * cams[2].r * cams[2].centre()),
        )
        .unwrap();
        let end = interpolate_around(&cams[0], &off, 1.0, &target).unwrap();
        assert!((end.r - off.r).norm() < 1e-9);
        let (u1, _, _) = off.project(&target).unwrap();
        let (um, _, _) = interpolate_around(&cams[0], &off, 0.5, &target)
            .unwrap()
            .project(&target)
            .unwrap();
        assert!((u1 - 200.0).abs() > 10.0 && (um - 200.0).abs() < (u1 - 200.0).abs());
    }
}
