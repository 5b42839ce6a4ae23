//! COLMAP sparse models: `cameras.txt` + `images.txt` (text) or `cameras.bin` + `images.bin`
//! (binary), parsed from memory (the [`crate::dataset`] module reads the files).
//!
//! Conventions (COLMAP's, <https://colmap.github.io/format.html> and `colmap/sensor/models.h`):
//! - an image's pose `QW QX QY QZ TX TY TZ` is world-to-camera: `x_cam = R(q) X + t`, the same
//!   direction as vt's [`Camera`] (`R X + t`), so `R` and `t` are taken as they are;
//! - pixel coordinates have the image's top-left *corner* at `(0, 0)`, so the centre of the
//!   first pixel is `(0.5, 0.5)`; vt puts pixel centres at integers, so `cx, cy` lose 0.5;
//! - camera models and their parameters: `SIMPLE_PINHOLE f cx cy`, `PINHOLE fx fy cx cy`,
//!   `SIMPLE_RADIAL f cx cy k`, `RADIAL f cx cy k1 k2`, `OPENCV fx fy cx cy k1 k2 p1 p2`
//!   (binary model ids 0 to 4); other models are refused by name.
//!
//! `images.txt` has two lines per image, the second (its 2-D points, `X Y POINT3D_ID` triples)
//! possibly empty; blank lines and `#` comments are skipped between images, as COLMAP's reader
//! does. The image name is the rest of the first line after the camera id (so a name with spaces,
//! which COLMAP writes but cannot read back, is kept whole). A `# Number of images: N` (or
//! `cameras`) comment, as COLMAP writes it, is checked against what the file holds, so a file
//! cut short between two images is refused rather than read as a smaller model.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

use crate::camera::{Camera, MAX_CAMERAS};
use crate::lens::Lens;
use crate::{Error, Result};

/// One camera (intrinsics) of a COLMAP model, as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapCamera {
    /// `CAMERA_ID`.
    pub id: u32,
    /// Model name (`PINHOLE`, `SIMPLE_RADIAL`, ...).
    pub model: String,
    /// Recorded image width in pixels.
    pub width: u64,
    /// Recorded image height in pixels.
    pub height: u64,
    /// The model's parameters, in COLMAP's order and pixel convention.
    pub params: Vec<f64>,
}

/// One 2-D point of an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point2D {
    /// Pixel position, COLMAP's convention (first pixel's centre at 0.5, 0.5).
    pub x: f64,
    /// See `x`.
    pub y: f64,
    /// The 3-D point it observes; `None` for COLMAP's -1.
    pub point3d: Option<u64>,
}

/// One registered image of a COLMAP model, as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    /// `IMAGE_ID`.
    pub id: u32,
    /// `QW QX QY QZ` as stored (not normalised).
    pub q: [f64; 4],
    /// `TX TY TZ`.
    pub t: [f64; 3],
    /// `CAMERA_ID`.
    pub camera_id: u32,
    /// `NAME`: the photo's path relative to the image folder.
    pub name: String,
    /// Its 2-D points.
    pub points: Vec<Point2D>,
}

/// The camera models vt reads, with their parameter counts and binary ids.
pub const MODELS: [(&str, usize, i32); 5] = [
    ("SIMPLE_PINHOLE", 3, 0),
    ("PINHOLE", 4, 1),
    ("SIMPLE_RADIAL", 4, 2),
    ("RADIAL", 5, 3),
    ("OPENCV", 8, 4),
];

/// COLMAP's other model ids, named in messages.
const OTHER_MODELS: [(&str, i32); 6] = [
    ("OPENCV_FISHEYE", 5),
    ("FULL_OPENCV", 6),
    ("FOV", 7),
    ("SIMPLE_RADIAL_FISHEYE", 8),
    ("RADIAL_FISHEYE", 9),
    ("THIN_PRISM_FISHEYE", 10),
];

/// Largest recorded image side vt accepts.
pub const MAX_SIDE: u64 = 1 << 16;

/// Largest deviation of a stored quaternion's norm from 1 that passes without a note (COLMAP
/// writes unit quaternions to about 6 digits).
pub const QUATERNION_NOTE: f64 = 1e-3;

fn known_models() -> String {
    MODELS.iter().map(|m| m.0).collect::<Vec<_>>().join(", ")
}

fn param_count(model: &str) -> Result<usize, String> {
    if let Some(m) = MODELS.iter().find(|m| m.0 == model) {
        return Ok(m.1);
    }
    Err(format!(
        "camera model {:?} is not supported (vt reads {})",
        short(model),
        known_models()
    ))
}

use crate::camera::shorten as short;

fn num(tok: &str, what: &str) -> Result<f64, String> {
    let v: f64 = tok
        .parse()
        .map_err(|_| format!("{what} is not a number: {:?}", short(tok)))?;
    if !v.is_finite() {
        return Err(format!("{what} is not finite: {:?}", short(tok)));
    }
    Ok(v)
}

fn id(tok: &str, what: &str) -> Result<u32, String> {
    tok.parse()
        .map_err(|_| format!("{what} is not a whole number: {:?}", short(tok)))
}

/// The count a COLMAP header comment declares (`# Number of images: 28, mean ...`).
fn declared(line: &str, what: &str) -> Option<usize> {
    let rest = line.trim_start_matches('#').trim();
    let rest = rest.strip_prefix(&format!("Number of {what}:"))?;
    rest.split(|c: char| c == ',' || c.is_whitespace())
        .find(|s| !s.is_empty())?
        .parse()
        .ok()
}

fn line_err(line: usize) -> impl Fn(String) -> Error {
    move |what| Error::Line { line, what }
}

/// Checks a camera's fields (model known, parameter count, size, positive focal lengths).
fn check_camera(c: &ColmapCamera) -> Result<(), String> {
    let n = param_count(&c.model)?;
    if c.params.len() != n {
        return Err(format!(
            "camera {}: model {} has {n} parameters, got {}",
            c.id,
            c.model,
            c.params.len()
        ));
    }
    if c.width == 0 || c.height == 0 || c.width > MAX_SIDE || c.height > MAX_SIDE {
        return Err(format!(
            "camera {}: size {}x{} is outside 1..={MAX_SIDE}",
            c.id, c.width, c.height
        ));
    }
    if let Some(v) = c.params.iter().find(|v| !v.is_finite()) {
        return Err(format!("camera {}: parameter {v} is not finite", c.id));
    }
    let focal = match c.model.as_str() {
        "PINHOLE" | "OPENCV" => &c.params[..2],
        _ => &c.params[..1],
    };
    if focal.iter().any(|&f| f <= 0.0) {
        return Err(format!(
            "camera {}: focal length {:?} is not positive",
            c.id, focal
        ));
    }
    Ok(())
}

/// Parses `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]` per line. Errors name the
/// 1-based line.
pub fn parse_cameras_text(text: &str) -> Result<Vec<ColmapCamera>> {
    let mut cams: Vec<ColmapCamera> = Vec::new();
    let mut header = None;
    for (i, line) in text.lines().enumerate() {
        let lineno = i + 1;
        let err = line_err(lineno);
        let line = line.trim();
        if line.starts_with('#') {
            header = header.or(declared(line, "cameras"));
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() < 4 {
            return Err(err(format!(
                "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], got {} fields",
                f.len()
            )));
        }
        let size = |tok: &str, what: &str| -> Result<u64> {
            tok.parse()
                .map_err(|_| err(format!("{what} is not a whole number: {:?}", short(tok))))
        };
        let cam = ColmapCamera {
            id: id(f[0], "CAMERA_ID").map_err(&err)?,
            model: f[1].to_string(),
            width: size(f[2], "WIDTH")?,
            height: size(f[3], "HEIGHT")?,
            params: f[4..]
                .iter()
                .enumerate()
                .map(|(j, t)| num(t, &format!("parameter {}", j + 1)))
                .collect::<Result<_, _>>()
                .map_err(&err)?,
        };
        check_camera(&cam).map_err(&err)?;
        if cams.iter().any(|c| c.id == cam.id) {
            return Err(err(format!("camera id {} appears twice", cam.id)));
        }
        if cams.len() >= MAX_CAMERAS {
            return Err(err(format!("more than the {MAX_CAMERAS} cameras vt reads")));
        }
        cams.push(cam);
    }
    match header {
        Some(n) if n != cams.len() => Err(Error::Line {
            line: text.lines().count(),
            what: format!(
                "header says {n} cameras, found {} (is the file cut short?)",
                cams.len()
            ),
        }),
        _ => Ok(cams),
    }
}

/// Parses `images.txt` (two lines per image; see the module's notes). Errors name the 1-based
/// line.
pub fn parse_images_text(text: &str) -> Result<Vec<ColmapImage>> {
    let mut images: Vec<ColmapImage> = Vec::new();
    let mut header = None;
    let mut lines = text.lines().enumerate();
    let mut last = 0;
    while let Some((i, raw)) = lines.next() {
        let lineno = i + 1;
        last = lineno;
        let err = line_err(lineno);
        let line = raw.trim();
        if line.starts_with('#') {
            header = header.or(declared(line, "images"));
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() < 10 {
            return Err(err(format!(
                "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got {} fields",
                f.len()
            )));
        }
        let names = ["QW", "QX", "QY", "QZ", "TX", "TY", "TZ"];
        let v: Vec<f64> = f[1..8]
            .iter()
            .zip(names)
            .map(|(t, n)| num(t, n))
            .collect::<Result<_, _>>()
            .map_err(&err)?;
        // The name is the rest of the line after the camera id.
        let mut rest = line;
        for tok in &f[..9] {
            rest = rest.trim_start();
            rest = &rest[tok.len()..];
        }
        let image = ColmapImage {
            id: id(f[0], "IMAGE_ID").map_err(&err)?,
            q: [v[0], v[1], v[2], v[3]],
            t: [v[4], v[5], v[6]],
            camera_id: id(f[8], "CAMERA_ID").map_err(&err)?,
            name: rest.trim().to_string(),
            points: match lines.next() {
                None => Vec::new(),
                Some((j, pl)) => {
                    last = j + 1;
                    parse_points(pl).map_err(line_err(j + 1))?
                }
            },
        };
        if images.iter().any(|m| m.id == image.id) {
            return Err(err(format!("image id {} appears twice", image.id)));
        }
        if images.len() >= MAX_CAMERAS {
            return Err(err(format!("more than the {MAX_CAMERAS} images vt reads")));
        }
        images.push(image);
    }
    match header {
        Some(n) if n != images.len() => Err(Error::Line {
            line: last.max(1),
            what: format!(
                "header says {n} images, found {} (is the file cut short?)",
                images.len()
            ),
        }),
        _ => Ok(images),
    }
}

fn parse_points(line: &str) -> Result<Vec<Point2D>, String> {
    let f: Vec<&str> = line.split_whitespace().collect();
    if !f.len().is_multiple_of(3) {
        return Err(format!(
            "2-D points: {} numbers, not X Y POINT3D_ID triples (is the file cut short?)",
            f.len()
        ));
    }
    f.chunks(3)
        .enumerate()
        .map(|(k, c)| {
            let p3: i64 = c[2].parse().map_err(|_| {
                format!(
                    "2-D point {}: POINT3D_ID is not a whole number: {:?}",
                    k + 1,
                    short(c[2])
                )
            })?;
            Ok(Point2D {
                x: num(c[0], &format!("2-D point {}: X", k + 1))?,
                y: num(c[1], &format!("2-D point {}: Y", k + 1))?,
                point3d: u64::try_from(p3).ok(),
            })
        })
        .collect()
}

/// A little-endian reader that names the byte where a binary file goes wrong.
struct Bytes<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.b.len() - self.at < n {
            return Err(Error::Binary {
                offset: self.at,
                what: format!(
                    "file ends inside {what} ({n} bytes needed, {} left)",
                    self.b.len() - self.at
                ),
            });
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().unwrap_or([0; 4]),
        ))
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(
            self.take(4, what)?.try_into().unwrap_or([0; 4]),
        ))
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        let at = self.at;
        let v = f64::from_le_bytes(self.take(8, what)?.try_into().unwrap_or([0; 8]));
        if !v.is_finite() {
            return Err(Error::Binary {
                offset: at,
                what: format!("{what} is not finite ({v})"),
            });
        }
        Ok(v)
    }
    fn err(&self, at: usize, what: String) -> Error {
        Error::Binary { offset: at, what }
    }
    /// A count of records of at least `min_bytes` each, checked against the bytes left before
    /// anything is allocated.
    fn count(&mut self, what: &str, min_bytes: usize, limit: u64) -> Result<usize> {
        let at = self.at;
        let n = self.u64(&format!("the number of {what}"))?;
        let left = (self.b.len() - self.at) as u64;
        if n > limit || n.saturating_mul(min_bytes as u64) > left {
            return Err(self.err(
                at,
                format!(
                    "{n} {what} declared; the file holds at most {} (limit {limit})",
                    left / min_bytes.max(1) as u64
                ),
            ));
        }
        Ok(n as usize)
    }
}

/// Parses `cameras.bin`.
pub fn parse_cameras_bin(bytes: &[u8]) -> Result<Vec<ColmapCamera>> {
    let mut r = Bytes { b: bytes, at: 0 };
    let n = r.count("cameras", 24, MAX_CAMERAS as u64)?;
    let mut cams: Vec<ColmapCamera> = Vec::with_capacity(n);
    for k in 0..n {
        let at = r.at;
        let what = format!("camera {}", k + 1);
        let id = r.u32(&what)?;
        let model_id = r.i32(&what)?;
        let model = match MODELS.iter().find(|m| m.2 == model_id) {
            Some(m) => m.0.to_string(),
            None => {
                let name = OTHER_MODELS
                    .iter()
                    .find(|m| m.1 == model_id)
                    .map_or(format!("id {model_id}"), |m| m.0.to_string());
                return Err(r.err(
                    at,
                    format!(
                        "camera {id}: camera model {name} is not supported (vt reads {})",
                        known_models()
                    ),
                ));
            }
        };
        let width = r.u64(&what)?;
        let height = r.u64(&what)?;
        let np = param_count(&model).map_err(|w| r.err(at, w))?;
        let params = (0..np)
            .map(|_| r.f64(&format!("camera {id}'s parameters")))
            .collect::<Result<_>>()?;
        let cam = ColmapCamera {
            id,
            model,
            width,
            height,
            params,
        };
        check_camera(&cam).map_err(|w| r.err(at, w))?;
        if cams.iter().any(|c| c.id == id) {
            return Err(r.err(at, format!("camera id {id} appears twice")));
        }
        cams.push(cam);
    }
    if r.at != bytes.len() {
        return Err(r.err(
            r.at,
            format!("{} bytes after the last camera", bytes.len() - r.at),
        ));
    }
    Ok(cams)
}

/// Parses `images.bin`.
pub fn parse_images_bin(bytes: &[u8]) -> Result<Vec<ColmapImage>> {
    let mut r = Bytes { b: bytes, at: 0 };
    // id, q, t, camera id, name's terminator, point count.
    let n = r.count("images", 4 + 56 + 4 + 1 + 8, MAX_CAMERAS as u64)?;
    let mut images: Vec<ColmapImage> = Vec::with_capacity(n);
    for k in 0..n {
        let at = r.at;
        let what = format!("image {}", k + 1);
        let id = r.u32(&what)?;
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = r.f64(&format!("image {id}'s pose"))?;
        }
        let camera_id = r.u32(&what)?;
        let rest = &bytes[r.at..];
        let len = rest.iter().position(|&c| c == 0).ok_or_else(|| {
            r.err(
                r.at,
                format!("image {id}: its name has no terminating zero byte"),
            )
        })?;
        let name = std::str::from_utf8(&rest[..len])
            .map_err(|_| r.err(r.at, format!("image {id}: its name is not UTF-8")))?
            .to_string();
        r.at += len + 1;
        let np = r.count(&format!("image {id}'s 2-D points"), 24, u32::MAX as u64)?;
        let mut points = Vec::with_capacity(np);
        for _ in 0..np {
            let x = r.f64(&format!("image {id}'s 2-D points"))?;
            let y = r.f64(&format!("image {id}'s 2-D points"))?;
            let p = r.u64(&format!("image {id}'s 2-D points"))?;
            points.push(Point2D {
                x,
                y,
                point3d: (p != u64::MAX).then_some(p),
            });
        }
        if images.iter().any(|m| m.id == id) {
            return Err(r.err(at, format!("image id {id} appears twice")));
        }
        images.push(ColmapImage {
            id,
            q: [v[0], v[1], v[2], v[3]],
            t: [v[4], v[5], v[6]],
            camera_id,
            name,
            points,
        });
    }
    if r.at != bytes.len() {
        return Err(r.err(
            r.at,
            format!("{} bytes after the last image", bytes.len() - r.at),
        ));
    }
    Ok(images)
}

/// One image of a model as vt uses it: an ideal pinhole [`Camera`] at the recorded size (vt's
/// pixel convention), the lens, and the recorded size.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Named by the image's `NAME`; `K` without distortion, `R`, `t` world-to-camera.
    pub camera: Camera,
    /// The lens distortion the photo was taken through.
    pub lens: Lens,
    /// The recorded image size.
    pub size: (u32, u32),
    /// The camera model's name.
    pub model: String,
    /// The stored quaternion's norm (normalised for `camera`).
    pub q_norm: f64,
}

/// `K` (vt's pixel convention) and the lens of a COLMAP camera.
pub fn intrinsics(c: &ColmapCamera) -> Result<(Matrix3<f64>, Lens), String> {
    check_camera(c)?;
    let p = &c.params;
    let (fx, fy, cx, cy, lens) = match c.model.as_str() {
        "SIMPLE_PINHOLE" => (p[0], p[0], p[1], p[2], Lens::None),
        "PINHOLE" => (p[0], p[1], p[2], p[3], Lens::None),
        "SIMPLE_RADIAL" => (p[0], p[0], p[1], p[2], Lens::Radial { k1: p[3], k2: 0.0 }),
        "RADIAL" => (p[0], p[0], p[1], p[2], Lens::Radial { k1: p[3], k2: p[4] }),
        "OPENCV" => (
            p[0],
            p[1],
            p[2],
            p[3],
            Lens::OpenCv {
                k1: p[4],
                k2: p[5],
                p1: p[6],
                p2: p[7],
            },
        ),
        m => return Err(param_count(m).err().unwrap_or_default()),
    };
    // COLMAP's first pixel centre is (0.5, 0.5), vt's (0, 0).
    let k = Matrix3::new(fx, 0.0, cx - 0.5, 0.0, fy, cy - 0.5, 0.0, 0.0, 1.0);
    Ok((k, lens))
}

/// The images of a model in `IMAGE_ID` order, each with its camera. Errors name the image.
pub fn views(cameras: &[ColmapCamera], images: &[ColmapImage]) -> Result<Vec<View>> {
    let mut order: Vec<&ColmapImage> = images.iter().collect();
    order.sort_by_key(|m| m.id);
    order
        .into_iter()
        .map(|m| {
            let bad = |what: String| Error::BadCamera {
                name: m.name.clone(),
                what,
            };
            let c = cameras
                .iter()
                .find(|c| c.id == m.camera_id)
                .ok_or_else(|| {
                    bad(format!(
                        "its CAMERA_ID {} is not in the cameras",
                        m.camera_id
                    ))
                })?;
            let (k, lens) = intrinsics(c).map_err(&bad)?;
            let q = Quaternion::new(m.q[0], m.q[1], m.q[2], m.q[3]);
            let q_norm = q.norm();
            if !(q_norm.is_finite() && q_norm > 1e-6) {
                return Err(bad(format!("quaternion {:?} has no direction", m.q)));
            }
            let r = UnitQuaternion::from_quaternion(q)
                .to_rotation_matrix()
                .into_inner();
            let camera = Camera::new(m.name.clone(), k, r, Vector3::from(m.t))?;
            Ok(View {
                camera,
                lens,
                size: (c.width as u32, c.height as u32),
                model: c.model.clone(),
                q_norm,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAMS: &str = "# Camera list with one line of data per camera:\n\
        #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n\
        # Number of cameras: 2\n\
        1 SIMPLE_RADIAL 1280 960 1064.91 640 480 0.0187869\n\
        2 PINHOLE 640 480 500 510 320 240\n";
    const IMAGES: &str = "# Image list with two lines of data per image:\n\
        # Number of images: 2, mean observations per image: 1\n\
        1 0.996141 -0.0797912 -0.0133766 -0.034021 1.31043 -1.02013 -0.625299 1 2021-05-19 20.23.45.jpg\n\
        617.03 443.58 1412 657.178 573.761 -1\n\
        2 1 0 0 0 0 0 1 2 b.png\n\
        \n";

    #[test]
    fn text_model_parses_with_names_and_points() {
        let cams = parse_cameras_text(CAMS).unwrap();
        assert_eq!(cams.len(), 2);
        assert_eq!(cams[0].params, vec![1064.91, 640.0, 480.0, 0.0187869]);
        let imgs = parse_images_text(IMAGES).unwrap();
        assert_eq!(imgs[0].name, "2021-05-19 20.23.45.jpg");
        assert_eq!(imgs[0].points.len(), 2);
        assert_eq!(imgs[0].points[0].point3d, Some(1412));
        assert_eq!(imgs[0].points[1].point3d, None);
        assert!(imgs[1].points.is_empty());
        let v = views(&cams, &imgs).unwrap();
        assert_eq!(v[0].size, (1280, 960));
        assert_eq!(
            v[0].lens,
            Lens::Radial {
                k1: 0.0187869,
                k2: 0.0
            }
        );
        // COLMAP's 640 (corner convention) is vt's 639.5.
        assert_eq!(v[0].camera.k[(0, 2)], 639.5);
        assert_eq!(v[1].camera.k[(1, 1)], 510.0);
        assert_eq!(v[1].camera.t, Vector3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn pose_is_world_to_camera() {
        // A 90 degree turn about y: q = (cos 45, 0, sin 45, 0). R maps world x to camera -z.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let text = format!("1 {h} 0 {h} 0 0 0 5 2 a.png\n\n");
        let imgs = parse_images_text(&text).unwrap();
        let cams = parse_cameras_text("2 PINHOLE 640 480 500 500 320 240\n").unwrap();
        let v = views(&cams, &imgs).unwrap();
        let c = &v[0].camera;
        let x_cam = c.to_camera(&Vector3::new(1.0, 0.0, 0.0));
        assert!(
            (x_cam - Vector3::new(0.0, 0.0, 4.0)).norm() < 1e-12,
            "{x_cam}"
        );
        // The camera centre is -R^T t.
        assert!((c.centre() - Vector3::new(5.0, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn text_errors_name_the_line() {
        let line = |r: Result<Vec<ColmapImage>>| match r {
            Err(Error::Line { line, what }) => (line, what),
            other => panic!("{other:?}"),
        };
        // Cut inside the first image's points.
        let cut = &IMAGES[..IMAGES.find("657.178").unwrap() + 3];
        let (l, w) = line(parse_images_text(cut));
        assert_eq!(l, 4, "{w}");
        assert!(w.contains("not X Y POINT3D_ID triples"), "{w}");
        // Cut between images: the header's count catches it.
        let cut = &IMAGES[..IMAGES.find("2 1 0 0").unwrap()];
        let (_, w) = line(parse_images_text(cut));
        assert!(w.contains("header says 2 images, found 1"), "{w}");
        // Cut inside an image line.
        let cut = &IMAGES[..IMAGES.find("1.31043").unwrap()];
        let (l, w) = line(parse_images_text(cut));
        assert_eq!(l, 3);
        assert!(w.contains("got 5 fields"), "{w}");
        let (l, w) = line(parse_images_text(&IMAGES.replace("-0.625299", "nan")));
        assert_eq!(l, 3);
        assert!(w.contains("TZ is not finite"), "{w}");
        match parse_cameras_text(&CAMS.replace("PINHOLE", "FISHEYE")) {
            Err(Error::Line { line: 5, what }) => {
                assert!(what.contains("\"FISHEYE\" is not supported"), "{what}")
            }
            other => panic!("{other:?}"),
        }
        match parse_cameras_text(&CAMS.replace(" 0.0187869", "")) {
            Err(Error::Line { line: 4, what }) => assert!(what.contains("has 4 parameters, got 3")),
            other => panic!("{other:?}"),
        }
        match parse_cameras_text(&CAMS.replace("500 510", "-500 510")) {
            Err(Error::Line { line: 5, what }) => assert!(what.contains("not positive"), "{what}"),
            other => panic!("{other:?}"),
        }
        let cams = parse_cameras_text(CAMS).unwrap();
        let imgs = parse_images_text(&IMAGES.replace(" 2 b.png", " 7 b.png")).unwrap();
        match views(&cams, &imgs) {
            Err(Error::BadCamera { name, what }) => {
                assert_eq!(name, "b.png");
                assert!(what.contains("CAMERA_ID 7"));
            }
            other => panic!("{other:?}"),
        }
        let imgs = parse_images_text(&IMAGES.replace("2 1 0 0 0", "2 0 0 0 0")).unwrap();
        assert!(matches!(views(&cams, &imgs), Err(Error::BadCamera { .. })));
    }

    fn cameras_bin(model: i32, params: &[f64]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend(1u64.to_le_bytes());
        b.extend(3u32.to_le_bytes());
        b.extend(model.to_le_bytes());
        b.extend(640u64.to_le_bytes());
        b.extend(480u64.to_le_bytes());
        for p in params {
            b.extend(p.to_le_bytes());
        }
        b
    }

    #[test]
    fn binary_cameras_and_their_errors() {
        let b = cameras_bin(4, &[500.0, 501.0, 320.0, 240.0, -0.1, 0.01, 1e-3, 2e-3]);
        let c = parse_cameras_bin(&b).unwrap();
        assert_eq!(c[0].model, "OPENCV");
        assert_eq!(c[0].params[7], 2e-3);
        let e = parse_cameras_bin(&b[..b.len() - 3]).unwrap_err();
        assert!(matches!(e, Error::Binary { offset: 88, .. }), "{e}");
        let e = parse_cameras_bin(&cameras_bin(5, &[1.0; 8]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("OPENCV_FISHEYE is not supported"), "{e}");
        let mut huge = b.clone();
        huge[..8].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = parse_cameras_bin(&huge).unwrap_err().to_string();
        assert!(e.starts_with("byte 0:") && e.contains("declared"), "{e}");
        let mut nan = b;
        let at = nan.len() - 8;
        nan[at..].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(parse_cameras_bin(&nan)
            .unwrap_err()
            .to_string()
            .contains("not finite"));
    }
}
