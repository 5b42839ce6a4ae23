//! NeRF camera files: `transforms.json` / `transforms_{train,test}.json` as the NeRF synthetic
//! data, instant-ngp and nerfstudio write them.
//!
//! Intrinsics are shared at the top level and may be overridden per frame: `camera_angle_x`
//! (horizontal field of view, radians; `camera_angle_y` for the vertical one) or `fl_x` /
//! `fl_y` in pixels, `cx` / `cy` (default: the image centre), `w` / `h` (default: the photo's
//! own size), and OpenCV's `k1 k2 p1 p2`. Each frame has `file_path` (relative to the file's
//! folder, with or without its extension) and `transform_matrix`, camera-to-world in OpenGL
//! camera axes (x right, y up, looking down -z). Pixel coordinates in the file have their first
//! pixel's centre at (0.5, 0.5); vt's is at (0, 0), so `cx, cy` lose 0.5 here as COLMAP's do.
//! Anything vt cannot read correctly (a fisheye, `k3`/`k4`, a pose that is not a rotation) is
//! refused by name.

use nalgebra::{Matrix3, Matrix4, Vector3};
use serde_json::Value;

use crate::camera::{Camera, MAX_CAMERAS};
use crate::lens::Lens;
use crate::{Error, Result};

/// One frame of a transforms file, its intrinsics not yet tied to a photo size.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// `file_path` as written (relative to the file's folder; the extension may be missing).
    pub file_path: String,
    /// Camera-to-world, OpenGL camera axes.
    pub c2w: Matrix4<f64>,
    /// The frame's intrinsics (the file's shared ones with the frame's own on top).
    pub intrinsics: Intrinsics,
}

/// Intrinsics as a transforms file gives them; missing values come from the photo's size.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Intrinsics {
    /// Horizontal field of view, radians.
    pub angle_x: Option<f64>,
    /// Vertical field of view, radians.
    pub angle_y: Option<f64>,
    /// Focal lengths in pixels.
    pub fl_x: Option<f64>,
    /// Vertical focal length in pixels.
    pub fl_y: Option<f64>,
    /// Principal point, first pixel centre at 0.5.
    pub cx: Option<f64>,
    /// Principal point's row.
    pub cy: Option<f64>,
    /// The size the intrinsics are given for.
    pub w: Option<f64>,
    /// Its height.
    pub h: Option<f64>,
    /// OpenCV radial and tangential coefficients (0 when absent).
    pub k1: f64,
    /// `r^4` coefficient.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
}

fn err(what: impl Into<String>) -> Error {
    Error::Transforms { what: what.into() }
}

fn number(v: &Value, key: &str, whose: &str) -> Result<Option<f64>> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => match x.as_f64() {
            Some(f) if f.is_finite() => Ok(Some(f)),
            _ => Err(err(format!("{whose}: {key} is {x}, not a finite number"))),
        },
    }
}

impl Intrinsics {
    /// `base` with the values `v` (the top level or a frame) sets on top; refuses what vt does
    /// not model.
    fn read(v: &Value, base: Intrinsics, whose: &str) -> Result<Intrinsics> {
        for key in ["k3", "k4"] {
            if number(v, key, whose)?.is_some_and(|k| k != 0.0) {
                return Err(err(format!(
                    "{whose}: {key} is not 0; vt models k1 k2 p1 p2 only (OpenCV's 4-parameter model)"
                )));
            }
        }
        if v.get("is_fisheye").and_then(Value::as_bool) == Some(true) {
            return Err(err(format!(
                "{whose}: a fisheye camera (is_fisheye); vt models pinholes with k1 k2 p1 p2"
            )));
        }
        if let Some(m) = v.get("camera_model") {
            let m = m.as_str().unwrap_or_default();
            if !matches!(m, "OPENCV" | "PINHOLE" | "SIMPLE_PINHOLE") {
                return Err(err(format!(
                    "{whose}: camera_model {m:?}; vt reads OPENCV, PINHOLE and SIMPLE_PINHOLE"
                )));
            }
        }
        let mut i = base;
        let set = |slot: &mut Option<f64>, key: &str| -> Result<()> {
            if let Some(x) = number(v, key, whose)? {
                *slot = Some(x);
            }
            Ok(())
        };
        set(&mut i.angle_x, "camera_angle_x")?;
        set(&mut i.angle_y, "camera_angle_y")?;
        set(&mut i.fl_x, "fl_x")?;
        set(&mut i.fl_y, "fl_y")?;
        set(&mut i.cx, "cx")?;
        set(&mut i.cy, "cy")?;
        set(&mut i.w, "w")?;
        set(&mut i.h, "h")?;
        for (slot, key) in [
            (&mut i.k1, "k1"),
            (&mut i.k2, "k2"),
            (&mut i.p1, "p1"),
            (&mut i.p2, "p2"),
        ] {
            if let Some(x) = number(v, key, whose)? {
                *slot = x;
            }
        }
        Ok(i)
    }

    /// The size the intrinsics are given for: `w`, `h` when the file says, else `photo`.
    pub fn size(&self, photo: (u32, u32)) -> Result<(u32, u32)> {
        match (self.w, self.h) {
            (Some(w), Some(h)) => {
                let ok = |x: f64| (1.0..=1e6).contains(&x) && x.fract() == 0.0;
                if !ok(w) || !ok(h) {
                    return Err(err(format!("w, h = {w}, {h}: not a whole image size")));
                }
                Ok((w as u32, h as u32))
            }
            (None, None) => Ok(photo),
            _ => Err(err("only one of w and h is given")),
        }
    }

    /// `K` (vt's pixel centres) and the lens for an image of `size` (the size the intrinsics
    /// are given for).
    pub fn k(&self, size: (u32, u32)) -> Result<(Matrix3<f64>, Lens)> {
        let (w, h) = (size.0 as f64, size.1 as f64);
        let from_angle = |a: f64, side: f64, key: &str| -> Result<f64> {
            if !(a > 0.0 && a < std::f64::consts::PI) {
                return Err(err(format!(
                    "{key} = {a}: a field of view must be in (0, pi) radians"
                )));
            }
            Ok(0.5 * side / (0.5 * a).tan())
        };
        let fx = match (self.fl_x, self.angle_x) {
            (Some(f), _) => f,
            (None, Some(a)) => from_angle(a, w, "camera_angle_x")?,
            (None, None) => match (self.fl_y, self.angle_y) {
                (Some(f), _) => f,
                (None, Some(a)) => from_angle(a, h, "camera_angle_y")?,
                (None, None) => {
                    return Err(err(
                        "no focal length: give camera_angle_x or fl_x (shared or per frame)",
                    ))
                }
            },
        };
        let fy = match (self.fl_y, self.angle_y) {
            (Some(f), _) => f,
            (None, Some(a)) => from_angle(a, h, "camera_angle_y")?,
            (None, None) => fx,
        };
        if !(fx > 0.0 && fy > 0.0) {
            return Err(err(format!("focal lengths {fx}, {fy}: must be positive")));
        }
        let cx = self.cx.unwrap_or(0.5 * w) - 0.5;
        let cy = self.cy.unwrap_or(0.5 * h) - 0.5;
        let k = Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
        let lens = if [self.k1, self.k2, self.p1, self.p2] == [0.0; 4] {
            Lens::None
        } else {
            Lens::OpenCv {
                k1: self.k1,
                k2: self.k2,
                p1: self.p1,
                p2: self.p2,
            }
        };
        Ok((k, lens))
    }
}

/// Parses a transforms file's text into its frames (in file order).
pub fn parse_transforms(text: &str) -> Result<Vec<Frame>> {
    let v: Value = serde_json::from_str(text).map_err(|e| Error::Line {
        line: e.line(),
        what: format!("not valid JSON: {e}"),
    })?;
    if !v.is_object() {
        return Err(err("the top level is not a JSON object"));
    }
    let shared = Intrinsics::read(&v, Intrinsics::default(), "top level")?;
    let frames = v
        .get("frames")
        .and_then(Value::as_array)
        .ok_or_else(|| err("no \"frames\" array"))?;
    if frames.is_empty() {
        return Err(err("\"frames\" is empty"));
    }
    if frames.len() > MAX_CAMERAS {
        return Err(err(format!(
            "{} frames, more than the {MAX_CAMERAS} vt reads",
            frames.len()
        )));
    }
    frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let whose = format!("frame {i}");
            let file_path = f
                .get("file_path")
                .and_then(Value::as_str)
                .ok_or_else(|| err(format!("{whose}: no file_path string")))?
                .to_string();
            let whose = format!("frame {i} ({file_path})");
            let rows = f
                .get("transform_matrix")
                .and_then(Value::as_array)
                .ok_or_else(|| err(format!("{whose}: no transform_matrix")))?;
            let bad_matrix = || {
                err(format!(
                    "{whose}: transform_matrix is not 4x4 (or 3x4) finite numbers"
                ))
            };
            if !(rows.len() == 4 || rows.len() == 3) {
                return Err(bad_matrix());
            }
            let mut c2w = Matrix4::identity();
            for (r, row) in rows.iter().enumerate() {
                let row = row
                    .as_array()
                    .filter(|r| r.len() == 4)
                    .ok_or_else(bad_matrix)?;
                for (c, x) in row.iter().enumerate() {
                    c2w[(r, c)] = x
                        .as_f64()
                        .filter(|x| x.is_finite())
                        .ok_or_else(bad_matrix)?;
                }
            }
            if rows.len() == 4
                && (c2w.row(3) - nalgebra::RowVector4::new(0.0, 0.0, 0.0, 1.0))
                    .abs()
                    .max()
                    > 1e-6
            {
                return Err(err(format!(
                    "{whose}: transform_matrix's last row is not 0 0 0 1"
                )));
            }
            let intrinsics = Intrinsics::read(f, shared, &whose)?;
            Ok(Frame {
                file_path,
                c2w,
                intrinsics,
            })
        })
        .collect()
}

/// vt's camera (world-to-camera, x right, y down, looking down +z) from a camera-to-world pose
/// in OpenGL camera axes and `K`; refused (naming `name`) when the pose's rotation is not one.
pub fn camera_from_c2w(name: &str, c2w: &Matrix4<f64>, k: Matrix3<f64>) -> Result<Camera> {
    let r_gl: Matrix3<f64> = c2w.fixed_view::<3, 3>(0, 0).into_owned();
    let centre: Vector3<f64> = c2w.fixed_view::<3, 1>(0, 3).into_owned();
    // OpenGL camera axes to vt's: y and z flip.
    let r_c2w = r_gl * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let r = r_c2w.transpose();
    let t = -(r * centre);
    let cam = Camera::new(name, k, r, t)?;
    cam.check()?;
    Ok(cam)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LEGO: &str = r#"{"camera_angle_x": 0.6911112070083618, "frames": [
        {"file_path": "./train/r_0", "rotation": 0.0125,
         "transform_matrix": [[-0.9999021887779236, 0.004192245192825794, -0.013345719315111637, -0.05379832163453102],
                              [-0.013988681137561798, -0.2996590733528137, 0.95394366979599, 3.845470428466797],
                              [-4.656612873077393e-10, 0.9540371894836426, 0.29968830943107605, 1.2080823183059692],
                              [0.0, 0.0, 0.0, 1.0]]}]}"#;

    #[test]
    fn lego_frame_looks_at_the_origin_upright() {
        let f = parse_transforms(LEGO).unwrap();
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].file_path, "./train/r_0");
        let size = f[0].intrinsics.size((400, 400)).unwrap();
        let (k, lens) = f[0].intrinsics.k(size).unwrap();
        assert_eq!(lens, Lens::None);
        // 0.5 * 400 / tan(0.5 * angle) = 555.555 (the NeRF data's focal length at 400 px).
        approx::assert_relative_eq!(k[(0, 0)], 555.5555, epsilon = 1e-3);
        assert_eq!((k[(0, 2)], k[(1, 2)]), (199.5, 199.5));
        let cam = camera_from_c2w("r_0", &f[0].c2w, k).unwrap();
        // The centre comes back; the world origin (the object) projects near the image centre
        // and in front; world +z (Blender's up) points up in the image (smaller row).
        let c = cam.centre();
        approx::assert_relative_eq!(c, Vector3::new(-0.0538, 3.8455, 1.2081), epsilon = 1e-3);
        let (px, py, depth) = cam.project(&Vector3::zeros()).unwrap();
        assert!(depth > 3.9 && depth < 4.1, "{depth}");
        assert!(
            (px - 199.5).abs() < 5.0 && (py - 199.5).abs() < 5.0,
            "{px} {py}"
        );
        let (_, up_y, _) = cam.project(&Vector3::new(0.0, 0.0, 0.5)).unwrap();
        assert!(up_y < py - 50.0, "{up_y} vs {py}");
    }

    #[test]
    fn explicit_intrinsics_and_lens_per_frame() {
        let text = r#"{"fl_x": 500, "fl_y": 510, "cx": 320.5, "cy": 240.5, "w": 640, "h": 480,
            "k1": 0.1, "frames": [
            {"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]},
            {"file_path": "b", "fl_x": 600, "k1": 0, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}"#;
        let f = parse_transforms(text).unwrap();
        let (k, lens) = f[0].intrinsics.k((640, 480)).unwrap();
        assert_eq!(
            (k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)]),
            (500.0, 510.0, 320.0, 240.0)
        );
        assert!(matches!(lens, Lens::OpenCv { k1, .. } if k1 == 0.1));
        let (k, lens) = f[1].intrinsics.k((640, 480)).unwrap();
        assert_eq!((k[(0, 0)], k[(1, 1)]), (600.0, 510.0));
        assert_eq!(lens, Lens::None);
        assert_eq!(f[1].intrinsics.size((1, 1)).unwrap(), (640, 480));
        // Camera at z = 3 looking down -z (OpenGL): the origin is 3 in front.
        let cam = camera_from_c2w("a", &f[0].c2w, k).unwrap();
        let (px, _, depth) = cam.project(&Vector3::zeros()).unwrap();
        approx::assert_relative_eq!(depth, 3.0, epsilon = 1e-12);
        approx::assert_relative_eq!(px, 320.0, epsilon = 1e-9);
    }

    #[test]
    fn refuses_what_it_cannot_read() {
        let m = r#""transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]"#;
        for (text, needle) in [
            ("[1, 2]", "not a JSON object"),
            ("{\"frames\": [", "not valid JSON"),
            ("{\"camera_angle_x\": 0.7}", "no \"frames\""),
            ("{\"camera_angle_x\": 0.7, \"frames\": []}", "empty"),
            (&format!("{{\"frames\": [{{\"file_path\": \"a\", {m}}}]}}") as &str, "no focal length"),
            (&format!("{{\"camera_angle_x\": 4, \"frames\": [{{\"file_path\": \"a\", {m}}}]}}"), "field of view"),
            (&format!("{{\"camera_angle_x\": 0.7, \"k3\": 0.1, \"frames\": [{{\"file_path\": \"a\", {m}}}]}}"), "k3"),
            (&format!("{{\"camera_angle_x\": 0.7, \"camera_model\": \"OPENCV_FISHEYE\", \"frames\": [{{\"file_path\": \"a\", {m}}}]}}"), "OPENCV_FISHEYE"),
            (&format!("{{\"camera_angle_x\": \"wide\", \"frames\": [{{\"file_path\": \"a\", {m}}}]}}"), "not a finite number"),
            ("{\"camera_angle_x\": 0.7, \"frames\": [{\"file_path\": \"a\", \"transform_matrix\": [[1,0,0]]}]}", "not 4x4"),
            ("{\"camera_angle_x\": 0.7, \"frames\": [{\"transform_matrix\": [[1,0,0]]}]}", "no file_path"),
        ] {
            let e = parse_transforms(text)
                .and_then(|f| f[0].intrinsics.k((10, 10)).map(|_| ()))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
        // A scaled pose is not a rotation.
        let mut c2w = Matrix4::identity();
        c2w[(0, 0)] = 2.0;
        let e = camera_from_c2w("s", &c2w, Matrix3::identity())
            .unwrap_err()
            .to_string();
        assert!(e.contains("camera s"), "{e}");
    }
}
