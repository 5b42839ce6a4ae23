//! A Middlebury-style data folder: one `*_par.txt` camera file, the images it names, and their
//! silhouettes (same-named mask images, or the photos thresholded); the model built from it with
//! a summary of each stage, and leave-one-out over its views. This module (and nothing else in
//! vt-fv) reads and writes files, through vt-io.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;

use crate::camera::{parse_camera_spec, parse_par, parse_projection, Camera, MAX_CAMERAS};
use crate::colmap;
use crate::hull::{auto_bounds, dims_for, visual_hull, Aabb, HullParams};
use crate::lens::{Lens, Resample};
use crate::modelfile::{decode, encode, view_prints, ModelHeader};
use crate::photo::{photo_hull_keeping, PhotoParams, VoxelModel};
use crate::pipeline::{
    error_map, leave_one_out_from, score_withheld, EvalImages, EvalReport, Others, Score,
    ViewParams,
};
use crate::silhouette::{
    backdrop_silhouette, border_level, mask_from_image, threshold_silhouette, BackdropParams, Mask,
    SilhouetteParams,
};

/// Everything that can go wrong reading or writing a data folder. Each cause is printed once.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A file that cannot be read, or is over vt's limits (vt-io's error).
    #[error(transparent)]
    Io(#[from] vt_io::Error),
    /// vt-fv refused the data (a camera, a silhouette, the volume).
    #[error(transparent)]
    Fv(#[from] crate::Error),
    /// A file whose contents vt-fv refused; the path and vt-fv's reason.
    #[error("{}: {cause}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        cause: crate::Error,
    },
    /// A folder or file that is missing, unreadable or inconsistent with the others.
    #[error("{}: {what}", path.display())]
    Path {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
}

fn path_err(path: &Path, what: impl Into<String>) -> DataError {
    DataError::Path {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

/// Where silhouettes come from and how photos are scaled.
#[derive(Debug, Clone, PartialEq)]
pub struct DataOptions {
    /// Folder of silhouette images named like the photos (non-zero = object). `None`: the data
    /// folder's `masks/` when it exists, else threshold the photos.
    pub masks: Option<PathBuf>,
    /// Threshold of the silhouettes the model is carved from, a fraction of full scale (0.19,
    /// the Middlebury recipe's).
    pub threshold: f64,
    /// Thresholded silhouettes the model is carved from: dilation radius (3).
    pub carve_dilate: u32,
    /// ... then erosion radius (3).
    pub carve_erode: u32,
    /// Scale factor applied to photos, silhouettes and cameras (1).
    pub scale: f64,
    /// How photos whose size differs from their camera's recorded size (COLMAP models) relate
    /// to it ([`PhotoFit::Scale`]).
    pub fit: PhotoFit,
    /// Thresholded silhouettes scores are measured inside
    /// ([`SilhouetteParams::scoring`]: 0.25, dilate 5, erode 5; the Middlebury recipe is 0.19,
    /// 10, 7).
    pub score: SilhouetteParams,
    /// How silhouettes are made when no mask images are given ([`SilhouetteMode::Auto`]).
    pub silhouettes: SilhouetteMode,
    /// Settings of the plain-backdrop segmentation ([`BackdropParams::default`]).
    pub backdrop: BackdropParams,
}

/// How silhouettes are made when there is no masks folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SilhouetteMode {
    /// Per photo: its alpha channel when it has transparency; else the dark-backdrop threshold
    /// when the border band's median brightest channel is below the threshold (a dark
    /// backdrop, the Middlebury recipe), else [`backdrop_silhouette`].
    #[default]
    Auto,
    /// Always the dark-backdrop threshold (the Middlebury recipe).
    Threshold,
    /// Always the plain-backdrop segmentation.
    Backdrop,
}

impl Default for DataOptions {
    fn default() -> Self {
        let carving = SilhouetteParams::carving();
        Self {
            masks: None,
            threshold: carving.threshold,
            carve_dilate: carving.dilate,
            carve_erode: carving.erode,
            scale: 1.0,
            fit: PhotoFit::Scale,
            score: SilhouetteParams::scoring(),
            silhouettes: SilhouetteMode::Auto,
            backdrop: BackdropParams::default(),
        }
    }
}

fn bad(name: &str, value: impl ToString, why: impl Into<String>) -> crate::Error {
    crate::Error::BadParam {
        name: name.into(),
        value: value.to_string(),
        why: why.into(),
    }
}

impl DataOptions {
    /// Checks the ranges: `scale` in (0, 4], radii at most 100, `threshold` in [0, 1).
    pub fn check(&self) -> crate::Result<()> {
        if !(self.scale > 0.0 && self.scale <= 4.0) {
            return Err(bad("scale", self.scale, "must be in (0, 4]"));
        }
        for (name, r) in [
            ("carve_dilate", self.carve_dilate),
            ("carve_erode", self.carve_erode),
            ("score_dilate", self.score.dilate),
            ("score_erode", self.score.erode),
        ] {
            if r > 100 {
                return Err(bad(name, r, "at most 100 pixels"));
            }
        }
        for (name, t) in [
            ("threshold", self.threshold),
            ("score_threshold", self.score.threshold),
        ] {
            if !(0.0..1.0).contains(&t) {
                return Err(bad(name, t, "must be in [0, 1)"));
            }
        }
        let b = &self.backdrop;
        if !(b.darker > 0.0 && b.darker < 1.0) {
            return Err(bad("backdrop_darker", b.darker, "must be in (0, 1)"));
        }
        if !(b.brighter > 1.0 && b.brighter.is_finite()) {
            return Err(bad(
                "backdrop_brighter",
                b.brighter,
                "must be a number above 1",
            ));
        }
        for (name, f) in [
            ("backdrop_border", b.border),
            ("backdrop_cell", b.cell),
            ("backdrop_open", b.open),
            ("backdrop_close", b.close),
        ] {
            if !(0.0..=0.25).contains(&f) {
                return Err(bad(
                    name,
                    f,
                    "must be in [0, 0.25] (a fraction of the shorter side)",
                ));
            }
        }
        if !(b.chroma >= 0.0 && b.chroma_spread >= 0.0 && (0.0..=1.0).contains(&b.keep)) {
            return Err(bad(
                "backdrop",
                format!(
                    "chroma {}, spread {}, keep {}",
                    b.chroma, b.chroma_spread, b.keep
                ),
                "chroma and spread must be >= 0, keep in [0, 1]",
            ));
        }
        Ok(())
    }
}

/// Downscales a mask: a pixel is set when any full-size pixel under it is.
pub fn scale_mask(m: &Mask, w: u32, h: u32) -> Mask {
    let (sx, sy) = (m.width() as f64 / w as f64, m.height() as f64 / h as f64);
    Mask::from_fn(w, h, |x, y| {
        let (x0, x1) = (
            (x as f64 * sx).floor() as i64,
            ((x + 1) as f64 * sx).ceil() as i64,
        );
        let (y0, y1) = (
            (y as f64 * sy).floor() as i64,
            ((y + 1) as f64 * sy).ceil() as i64,
        );
        (y0..y1.max(y0 + 1)).any(|yy| (x0..x1.max(x0 + 1)).any(|xx| m.get_or_false(xx, yy)))
    })
}

/// A supplied silhouette image: non-zero = object, the size of its photo.
fn read_mask(path: &Path, name: &str, size: (u32, u32), photo: &Path) -> Result<Mask, DataError> {
    if !path.is_file() {
        return Err(path_err(path, format!("mask for image {name} is missing")));
    }
    let bytes = vt_io::limits::read_bytes(path, vt_io::limits::MAX_IMAGE_FILE_BYTES, "mask image")?;
    let m = image::load_from_memory(&bytes)
        .map_err(|e| path_err(path, e.to_string()))?
        .to_luma8();
    if m.dimensions() != size {
        return Err(path_err(
            path,
            format!(
                "mask is {}x{} but image {} is {}x{}",
                m.width(),
                m.height(),
                photo.display(),
                size.0,
                size.1
            ),
        ));
    }
    Ok(mask_from_image(&m))
}

/// Photos, cameras and silhouettes of a data folder.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The camera file (`*_par.txt`, COLMAP's `images.txt` or `images.bin`) or folder
    /// (`cameras/` of projection matrices).
    pub cameras_file: PathBuf,
    /// Which format the cameras came in.
    pub format: CameraFormat,
    /// The cameras (ideal pinholes: lens distortion is taken out of the photos), scaled.
    pub cams: Vec<Camera>,
    /// The photos, scaled (and resampled into their pinhole camera where a lens or a size
    /// required it); all the same size.
    pub images: Vec<RgbImage>,
    /// Silhouettes the model is carved from.
    pub masks: Vec<Mask>,
    /// Silhouettes scores are measured inside ([`DataOptions::score`] when thresholding; the
    /// same as `masks` for supplied mask images).
    pub score_masks: Vec<Mask>,
    /// Where the silhouettes came from, in words.
    pub silhouettes: String,
    /// What loading did beyond reading (intrinsics fitted to resized photos, distortion
    /// removed, quaternions normalised), one line each, to be said once.
    pub notes: Vec<String>,
}

/// The formats a data folder's cameras can come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraFormat {
    /// One Middlebury `*_par.txt` (`name K R t` per line).
    Par,
    /// A COLMAP sparse model in text: `cameras.txt` + `images.txt`.
    ColmapText,
    /// A COLMAP sparse model in binary: `cameras.bin` + `images.bin`.
    ColmapBinary,
    /// A `cameras/` folder with one 3x4 projection matrix per photo (`<photo stem>.txt`).
    Matrices,
}

impl std::fmt::Display for CameraFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CameraFormat::Par => "Middlebury par file",
            CameraFormat::ColmapText => "COLMAP text model",
            CameraFormat::ColmapBinary => "COLMAP binary model",
            CameraFormat::Matrices => "projection matrices",
        })
    }
}

/// How a photo whose size differs from the size its camera was recorded at (COLMAP's
/// `WIDTH HEIGHT`) relates to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PhotoFit {
    /// The photo was resized after calibration: the intrinsics are scaled per axis (pixel
    /// centres kept at integers). The two scales must agree within [`UNIFORM_TOLERANCE`].
    #[default]
    Scale,
    /// The photo is a centred crop (or pad) of the recorded frame: the principal point moves by
    /// half the size difference, the focal lengths stay.
    Crop,
}

/// Largest relative difference between a resized photo's horizontal and vertical scale that
/// [`PhotoFit::Scale`] accepts as a uniform rescale (0.5 %).
pub const UNIFORM_TOLERANCE: f64 = 0.005;

/// Largest COLMAP model file vt reads (`images.bin` carries every 2-D point).
pub const MAX_MODEL_FILE_BYTES: u64 = 1 << 30;

/// Photo file extensions looked for beside a projection matrix, in this order.
pub const PHOTO_EXTENSIONS: [&str; 6] = ["png", "jpg", "jpeg", "bmp", "tif", "tiff"];

/// Where a folder's cameras are: the format and the file (or folder) to read.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraSource {
    /// The format.
    pub format: CameraFormat,
    /// `*_par.txt`; COLMAP's folder holding the model; the `cameras/` folder.
    pub path: PathBuf,
    /// Said once: e.g. that both a text and a binary COLMAP model were there.
    pub note: Option<String>,
}

fn files_ending(dir: &Path, suffix: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && p.file_name()
                            .and_then(|n| n.to_str())
                            .is_some_and(|n| n.ends_with(suffix))
                })
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Finds a data folder's cameras: one `*_par.txt` in it; a COLMAP model (`cameras.txt` +
/// `images.txt`, or `cameras.bin` + `images.bin`; binary wins when both are there) in it, in
/// `sparse/` or in `sparse/0/`; or a `cameras/` folder of projection matrices. More than one of
/// these is refused (keep one).
pub fn find_cameras(dir: &Path) -> Result<CameraSource, DataError> {
    std::fs::read_dir(dir).map_err(|e| path_err(dir, e.to_string()))?;
    let mut found: Vec<CameraSource> = Vec::new();
    let pars = files_ending(dir, "_par.txt");
    if pars.len() > 1 {
        return Err(path_err(
            dir,
            format!(
                "more than one *_par.txt camera file ({}); keep one",
                pars.iter()
                    .map(|p| p.file_name().unwrap_or_default().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    found.extend(pars.into_iter().map(|path| CameraSource {
        format: CameraFormat::Par,
        path,
        note: None,
    }));
    for sub in [
        dir.to_path_buf(),
        dir.join("sparse"),
        dir.join("sparse").join("0"),
    ] {
        let has = |a: &str, b: &str| sub.join(a).is_file() && sub.join(b).is_file();
        let (text, bin) = (
            has("cameras.txt", "images.txt"),
            has("cameras.bin", "images.bin"),
        );
        if bin || text {
            found.push(CameraSource {
                format: if bin {
                    CameraFormat::ColmapBinary
                } else {
                    CameraFormat::ColmapText
                },
                path: sub.clone(),
                note: (bin && text).then(|| {
                    format!(
                        "{} holds a text and a binary COLMAP model; the binary one is read",
                        sub.display()
                    )
                }),
            });
        }
    }
    let mats = dir.join("cameras");
    if mats.is_dir() {
        found.push(CameraSource {
            format: CameraFormat::Matrices,
            path: mats,
            note: None,
        });
    }
    match found.len() {
        0 => Err(path_err(
            dir,
            "no cameras in it: no *_par.txt camera file, no COLMAP model (cameras.txt + images.txt or cameras.bin + images.bin, here or in sparse/ or sparse/0/), no cameras/ folder of projection matrices",
        )),
        1 => Ok(found.remove(0)),
        _ => Err(path_err(
            dir,
            format!(
                "cameras in more than one place ({}); keep one",
                found
                    .iter()
                    .map(|s| format!("{} {}", s.format, s.path.display()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// One view before its photo is read: its camera at the recorded size, lens, recorded size
/// (`None`: the photo's own size is the camera's) and photo.
struct Source {
    cam: Camera,
    lens: Lens,
    recorded: Option<(u32, u32)>,
    photo: PathBuf,
}

/// A photo name from a camera file: relative, inside the folder, no `..`.
fn inside(name: &str) -> bool {
    let p = Path::new(name);
    !name.is_empty()
        && !name.contains('\\')
        && p.components().all(|c| {
            matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        })
}

/// The folder COLMAP's image names are relative to: `DATA/images` when it exists, else `DATA`.
fn photo_folder(dir: &Path) -> PathBuf {
    let d = dir.join("images");
    if d.is_dir() {
        d
    } else {
        dir.to_path_buf()
    }
}

fn file_err(path: &Path) -> impl Fn(crate::Error) -> DataError + '_ {
    move |cause| DataError::File {
        path: path.to_path_buf(),
        cause,
    }
}

/// The views of a COLMAP model in `model_dir`, photos in [`photo_folder`].
fn colmap_sources(
    dir: &Path,
    model_dir: &Path,
    binary: bool,
    notes: &mut Vec<String>,
) -> Result<(PathBuf, Vec<Source>), DataError> {
    let (cams_path, imgs_path) = if binary {
        (model_dir.join("cameras.bin"), model_dir.join("images.bin"))
    } else {
        (model_dir.join("cameras.txt"), model_dir.join("images.txt"))
    };
    let read = |p: &Path| vt_io::limits::read_bytes(p, MAX_MODEL_FILE_BYTES, "COLMAP model file");
    let text = |p: &Path| -> Result<String, DataError> {
        String::from_utf8(read(p)?).map_err(|e| {
            path_err(
                p,
                format!(
                    "not UTF-8 text (invalid byte at offset {})",
                    e.utf8_error().valid_up_to()
                ),
            )
        })
    };
    let (cams, imgs) = if binary {
        (
            colmap::parse_cameras_bin(&read(&cams_path)?).map_err(file_err(&cams_path))?,
            colmap::parse_images_bin(&read(&imgs_path)?).map_err(file_err(&imgs_path))?,
        )
    } else {
        (
            colmap::parse_cameras_text(&text(&cams_path)?).map_err(file_err(&cams_path))?,
            colmap::parse_images_text(&text(&imgs_path)?).map_err(file_err(&imgs_path))?,
        )
    };
    let views = colmap::views(&cams, &imgs).map_err(file_err(&imgs_path))?;
    let folder = photo_folder(dir);
    let off: Vec<String> = views
        .iter()
        .filter(|v| (v.q_norm - 1.0).abs() > colmap::QUATERNION_NOTE)
        .map(|v| format!("{} ({:.4})", v.camera.name, v.q_norm))
        .collect();
    if !off.is_empty() {
        notes.push(format!(
            "{} quaternion(s) in {} were far from unit length and were normalised: {}",
            off.len(),
            imgs_path.display(),
            off.join(", ")
        ));
    }
    let mut models: Vec<&str> = views.iter().map(|v| v.model.as_str()).collect();
    models.sort();
    models.dedup();
    notes.push(format!(
        "cameras: {} in {} ({} images; {}), photos in {}",
        if binary {
            CameraFormat::ColmapBinary
        } else {
            CameraFormat::ColmapText
        },
        model_dir.display(),
        views.len(),
        models.join(", "),
        folder.display()
    ));
    let mut out = Vec::with_capacity(views.len());
    for v in views {
        let name = v.camera.name.clone();
        if !inside(&name) {
            return Err(path_err(
                &imgs_path,
                format!(
                    "image name {name:?} points outside the photo folder (use a name relative to it, without ..)"
                ),
            ));
        }
        let photo = folder.join(&name);
        if !photo.is_file() {
            // A name with a word dropped (a date stamp) is a common renaming: say so.
            let last = name.rsplit(' ').next().unwrap_or(&name);
            let hint = if last != name && folder.join(last).is_file() {
                format!(
                    " ({} exists: rename the photos to the names the model records)",
                    folder.join(last).display()
                )
            } else {
                String::new()
            };
            return Err(path_err(
                &imgs_path,
                format!(
                    "image {name:?} names photo {}, which is missing{hint}",
                    photo.display()
                ),
            ));
        }
        out.push(Source {
            cam: v.camera,
            lens: v.lens,
            recorded: Some(v.size),
            photo,
        });
    }
    Ok((imgs_path, out))
}

/// The views of a `cameras/` folder of projection matrices: one `<photo stem>.txt` (or `.P`)
/// per photo, the photo (`<stem>.png`, `.jpg`, ...) in `DATA/images/` or `DATA/`; sorted by
/// file name.
fn matrix_sources(dir: &Path, mats: &Path) -> Result<Vec<Source>, DataError> {
    let mut files: Vec<PathBuf> = files_ending(mats, ".txt");
    files.extend(files_ending(mats, ".P"));
    files.sort();
    if files.is_empty() {
        return Err(path_err(
            mats,
            "no projection matrix files (<photo stem>.txt or .P) in it",
        ));
    }
    if files.len() > MAX_CAMERAS {
        return Err(path_err(
            mats,
            format!(
                "{} matrix files, more than the {MAX_CAMERAS} vt reads",
                files.len()
            ),
        ));
    }
    let folder = photo_folder(dir);
    let mut out = Vec::with_capacity(files.len());
    for f in files {
        let stem = f
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_string();
        let text =
            vt_io::limits::read_text(&f, vt_io::limits::MAX_TEXT_BYTES, "projection matrix file")?;
        let p = parse_projection(&text).map_err(file_err(&f))?;
        let photos: Vec<PathBuf> = PHOTO_EXTENSIONS
            .iter()
            .flat_map(|e| [e.to_string(), e.to_ascii_uppercase()])
            .map(|e| folder.join(format!("{stem}.{e}")))
            .filter(|p| p.is_file())
            .collect();
        let photo = match photos.len() {
            1 => photos[0].clone(),
            0 => {
                return Err(path_err(
                    &f,
                    format!(
                        "no photo {stem}.png/.jpg/... in {} for this matrix",
                        folder.display()
                    ),
                ))
            }
            _ => {
                return Err(path_err(
                    &f,
                    format!(
                        "more than one photo named {stem}.* in {}; keep one",
                        folder.display()
                    ),
                ))
            }
        };
        let name = photo
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let cam = Camera::from_projection(name, &p).map_err(file_err(&f))?;
        out.push(Source {
            cam,
            lens: Lens::None,
            recorded: None,
            photo,
        });
    }
    Ok(out)
}

/// `k` of a camera recorded at `rec` fitted to a photo of `size` by `fit`; the message says
/// why not.
pub fn fit_intrinsics(
    k: &nalgebra::Matrix3<f64>,
    rec: (u32, u32),
    size: (u32, u32),
    fit: PhotoFit,
) -> Result<nalgebra::Matrix3<f64>, String> {
    if rec == size {
        return Ok(*k);
    }
    let (sx, sy) = (size.0 as f64 / rec.0 as f64, size.1 as f64 / rec.1 as f64);
    let mut k = *k;
    match fit {
        PhotoFit::Scale => {
            if (sx / sy - 1.0).abs() > UNIFORM_TOLERANCE {
                return Err(format!(
                    "is {}x{} but its camera was recorded at {}x{}: scales {sx:.4} and {sy:.4} differ by more than {}% (not a uniform rescale; a centred crop is --photo-fit crop)",
                    size.0,
                    size.1,
                    rec.0,
                    rec.1,
                    UNIFORM_TOLERANCE * 100.0
                ));
            }
            // Pixel centres at integers: u' = s (u + 0.5) - 0.5, per axis.
            for (row, s) in [(0, sx), (1, sy)] {
                for c in 0..3 {
                    k[(row, c)] *= s;
                }
                k[(row, 2)] += 0.5 * s - 0.5;
            }
        }
        PhotoFit::Crop => {
            k[(0, 2)] += (size.0 as f64 - rec.0 as f64) / 2.0;
            k[(1, 2)] += (size.1 as f64 - rec.1 as f64) / 2.0;
        }
    }
    Ok(k)
}

/// Where one view's silhouette came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SilhouetteKind {
    /// A mask image in the masks folder.
    Masks,
    /// The photo's alpha channel.
    Alpha,
    /// The dark-backdrop threshold.
    Dark,
    /// The plain-backdrop segmentation.
    Backdrop,
}

/// A photo, and its alpha channel as a mask (alpha >= 128 = object) when it has one that is not
/// fully opaque. Decoded through vt-io's limits.
fn read_photo(path: &Path) -> Result<(RgbImage, Option<Mask>), DataError> {
    let bytes = vt_io::limits::read_bytes(path, vt_io::limits::MAX_IMAGE_FILE_BYTES, "image file")?;
    let rgb = vt_io::frames::decode_rgb(&bytes, path)?;
    let has_alpha = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .ok()
        .and_then(|r| r.into_decoder().ok())
        .is_some_and(|d| image::ImageDecoder::color_type(&d).has_alpha());
    if !has_alpha {
        return Ok((rgb, None));
    }
    // The same bytes decode_rgb accepted (its size limits hold), now keeping the alpha.
    let rgba = image::load_from_memory(&bytes)
        .map_err(|e| path_err(path, e.to_string()))?
        .to_rgba8();
    let a = rgba.as_raw();
    if a.chunks_exact(4).all(|p| p[3] == 255) {
        return Ok((rgb, None));
    }
    let m = Mask::from_index_fn(rgba.width(), rgba.height(), |i| a[4 * i + 3] >= 128);
    if m.count_ones() == 0 {
        return Err(path_err(
            path,
            "its alpha channel is transparent everywhere (below 128): no object in the mask",
        ));
    }
    Ok((rgb, Some(m)))
}

/// The silhouettes' origin in words; photos with an alpha mask beside photos without are
/// refused (naming both).
fn describe_silhouettes(
    kinds: &[SilhouetteKind],
    mask_dir: Option<&Path>,
    opt: &DataOptions,
    sources: &[Source],
) -> Result<String, DataError> {
    if let Some(d) = mask_dir {
        return Ok(format!("mask images in {}", d.display()));
    }
    let count = |k| kinds.iter().filter(|&&x| x == k).count();
    let n = kinds.len();
    let alpha = count(SilhouetteKind::Alpha);
    if alpha > 0 && alpha < n {
        let with = kinds
            .iter()
            .position(|&k| k == SilhouetteKind::Alpha)
            .unwrap_or(0);
        let without = kinds
            .iter()
            .position(|&k| k != SilhouetteKind::Alpha)
            .unwrap_or(0);
        return Err(path_err(
            &sources[without].photo,
            format!(
                "has no transparency, but {} carries its silhouette in its alpha channel: give every photo an alpha mask, or none",
                sources[with].photo.display()
            ),
        ));
    }
    if alpha == n {
        return Ok("the photos' alpha channels (alpha >= 128 = object)".into());
    }
    let dark = format!(
        "photos thresholded (carving: at {}, dilate {}, erode {}; scoring: at {}, dilate {}, erode {})",
        opt.threshold, opt.carve_dilate, opt.carve_erode, opt.score.threshold, opt.score.dilate, opt.score.erode
    );
    let plain =
        "photos segmented from their plain backdrop (colour estimated from each photo's border)";
    Ok(match count(SilhouetteKind::Dark) {
        0 => plain.to_string(),
        d if d == n => dark,
        d => format!("{d} of {n} {dark}; {} of {n} {plain}", n - d),
    })
}

fn range(v: &[f64]) -> String {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if (hi - lo).abs() < 5e-5 {
        format!("{lo:.4}")
    } else {
        format!("{lo:.4}-{hi:.4}")
    }
}

impl Dataset {
    /// Reads a data folder: the cameras ([`find_cameras`]), every photo they name (checked to
    /// exist; photos of a COLMAP model fitted to their camera's recorded size by `opt.fit` and
    /// resampled into ideal pinhole cameras of one size when a lens or the sizes require it;
    /// others must share one size), the silhouettes, all scaled by `opt.scale`. Every camera is
    /// checked ([`Camera::check`]); errors name the file and the photo.
    pub fn load(dir: &Path, opt: &DataOptions) -> Result<Self, DataError> {
        opt.check()?;
        if !dir.is_dir() {
            return Err(path_err(dir, "not a folder"));
        }
        let found = find_cameras(dir)?;
        let mut notes: Vec<String> = found.note.iter().cloned().collect();
        let (cameras_file, sources) = match found.format {
            CameraFormat::Par => {
                let par = found.path.clone();
                let text =
                    vt_io::limits::read_text(&par, vt_io::limits::MAX_TEXT_BYTES, "camera file")?;
                let cams = parse_par(&text).map_err(file_err(&par))?;
                let mut sources = Vec::with_capacity(cams.len());
                for (i, c) in cams.into_iter().enumerate() {
                    let p = dir.join(&c.name);
                    if !p.is_file() {
                        return Err(path_err(
                            &par,
                            format!("camera {i} names image {}, which is missing", p.display()),
                        ));
                    }
                    sources.push(Source {
                        cam: c,
                        lens: Lens::None,
                        recorded: None,
                        photo: p,
                    });
                }
                (par, sources)
            }
            CameraFormat::ColmapText | CameraFormat::ColmapBinary => colmap_sources(
                dir,
                &found.path,
                found.format == CameraFormat::ColmapBinary,
                &mut notes,
            )?,
            CameraFormat::Matrices => {
                let s = matrix_sources(dir, &found.path)?;
                notes.push(format!(
                    "cameras: {} projection matrices in {}, decomposed into K [R | t]",
                    s.len(),
                    found.path.display()
                ));
                (found.path.clone(), s)
            }
        };
        for s in &sources {
            s.cam.check().map_err(file_err(&cameras_file))?;
        }
        let mask_dir = match &opt.masks {
            Some(d) if !d.is_dir() => return Err(path_err(d, "mask folder: not a folder")),
            Some(d) => Some(d.clone()),
            None => Some(dir.join("masks")).filter(|d| d.is_dir()),
        };
        let scoring = opt.score.clone();
        let carve = SilhouetteParams {
            threshold: opt.threshold,
            dilate: opt.carve_dilate,
            erode: opt.carve_erode,
        };
        // The photos' size after fitting: the first photo's (a uniform rescale) or the first
        // camera's recorded size (a centred crop); read the first photo's header only once.
        let first = read_photo(
            &sources
                .first()
                .ok_or_else(|| path_err(&cameras_file, "no cameras in it"))?
                .photo,
        )?;
        let target = match (sources[0].recorded, opt.fit) {
            (Some(rec), PhotoFit::Crop) => rec,
            _ => first.0.dimensions(),
        };
        let mut first = Some(first);
        // Each view: (photo, carving mask, scoring mask, camera, resampled?, scales, where the
        // silhouette came from).
        type Loaded = (
            RgbImage,
            Mask,
            Mask,
            Camera,
            bool,
            Option<(f64, f64)>,
            SilhouetteKind,
        );
        type Photo = (RgbImage, Option<Mask>);
        let firsts: Vec<Option<Photo>> = (0..sources.len())
            .map(|i| if i == 0 { first.take() } else { None })
            .collect();
        let loaded: Vec<Loaded> = sources
            .par_iter()
            .zip(firsts)
            .map(|(s, pre)| -> Result<Loaded, DataError> {
                let (img, alpha) = match pre {
                    Some(i) => i,
                    None => read_photo(&s.photo)?,
                };
                let (supplied, kind) = match (&mask_dir, alpha) {
                    (Some(d), _) => (
                        Some(read_mask(&d.join(&s.cam.name), &s.cam.name, img.dimensions(), &s.photo)?),
                        SilhouetteKind::Masks,
                    ),
                    (None, Some(a)) => (Some(a), SilhouetteKind::Alpha),
                    (None, None) => {
                        let dark = match opt.silhouettes {
                            SilhouetteMode::Threshold => true,
                            SilhouetteMode::Backdrop => false,
                            SilhouetteMode::Auto => {
                                border_level(&img, &opt.backdrop) < opt.threshold * 255.0
                            }
                        };
                        let kind = if dark {
                            SilhouetteKind::Dark
                        } else {
                            SilhouetteKind::Backdrop
                        };
                        (None, kind)
                    }
                };
                // Fit and undistort where the camera was recorded at another size or through a
                // lens: the output is the ideal pinhole at `target`.
                let (img, supplied, cam, resampled, scales) = match s.recorded {
                    None => (img, supplied, s.cam.clone(), false, None),
                    Some(rec) => {
                        let size = img.dimensions();
                        let name = |e: String| path_err(&s.photo, format!("photo {e}"));
                        let k_src = fit_intrinsics(&s.cam.k, rec, size, opt.fit).map_err(name)?;
                        let k_out = fit_intrinsics(&s.cam.k, rec, target, opt.fit).map_err(|e| {
                            path_err(
                                &s.photo,
                                format!(
                                    "its camera cannot be fitted to the first photo's size {}x{}: camera {e}",
                                    target.0, target.1
                                ),
                            )
                        })?;
                        let cam = Camera::new(s.cam.name.clone(), k_out, s.cam.r, s.cam.t)?;
                        let scales = Some((size.0 as f64 / rec.0 as f64, size.1 as f64 / rec.1 as f64));
                        let map = Resample::new(&k_src, &s.lens, &k_out, target.0, target.1);
                        if map.is_identity(size.0, size.1, 1e-4) {
                            (img, supplied, cam, false, scales)
                        } else {
                            let m = supplied.map(|m| map.mask(&m));
                            (map.rgb(&img), m, cam, true, scales)
                        }
                    }
                };
                let (mask, score) = match supplied {
                    Some(m) => (m.clone(), m),
                    None if kind == SilhouetteKind::Dark => (
                        threshold_silhouette(&img, &carve),
                        threshold_silhouette(&img, &scoring),
                    ),
                    None => {
                        let m = backdrop_silhouette(&img, &opt.backdrop);
                        (m.clone(), m)
                    }
                };
                let cam = if opt.scale == 1.0 { cam } else { cam.scaled(opt.scale) };
                if opt.scale == 1.0 {
                    return Ok((img, mask, score, cam, resampled, scales, kind));
                }
                let (w, h) = (
                    ((img.width() as f64 * opt.scale).round() as u32).max(1),
                    ((img.height() as f64 * opt.scale).round() as u32).max(1),
                );
                let small =
                    image::imageops::resize(&img, w, h, image::imageops::FilterType::Triangle);
                Ok((small, scale_mask(&mask, w, h), scale_mask(&score, w, h), cam, resampled, scales, kind))
            })
            .collect::<Result<_, DataError>>()?;
        let n = loaded.len();
        let (mut images, mut cams) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let (mut masks, mut score_masks) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let (mut resampled, mut sx, mut sy) = (0, Vec::new(), Vec::new());
        let mut kinds = Vec::with_capacity(n);
        for (i, m, sm, c, r, s, k) in loaded {
            kinds.push(k);
            images.push(i);
            masks.push(m);
            score_masks.push(sm);
            cams.push(c);
            resampled += r as usize;
            if let Some((x, y)) = s.filter(|&(x, y)| x != 1.0 || y != 1.0) {
                sx.push(x);
                sy.push(y);
            }
        }
        if !sx.is_empty() {
            notes.push(match opt.fit {
                PhotoFit::Scale => format!(
                    "{} of {n} photos differ in size from their camera's recorded size: intrinsics scaled by {} x {} (--photo-fit scale: resized photos)",
                    sx.len(),
                    range(&sx),
                    range(&sy)
                ),
                PhotoFit::Crop => format!(
                    "{} of {n} photos differ in size from their camera's recorded size ({} x {} of it): taken as centred crops (--photo-fit crop)",
                    sx.len(),
                    range(&sx),
                    range(&sy)
                ),
            });
        }
        if resampled > 0 {
            let (w, h) = target;
            notes.push(format!(
                "{resampled} of {n} photos resampled into ideal pinhole cameras at {w}x{h} (lens distortion removed, sizes fitted)"
            ));
        }
        let silhouettes = describe_silhouettes(&kinds, mask_dir.as_deref(), opt, &sources)?;
        if kinds.contains(&SilhouetteKind::Backdrop) {
            let k = kinds
                .iter()
                .filter(|&&k| k == SilhouetteKind::Backdrop)
                .count();
            notes.push(format!(
                "silhouettes: {k} of {n} photos are on a light or coloured backdrop: segmented automatically (backdrop colour from each photo's border, object where the colour or the brightness ratio to the local backdrop differs; --masks DIR or an alpha channel gives them instead)"
            ));
        }
        // A photo of another size in a calibrated dataset is a mistake, not a view: refuse it.
        if let Some(k) = images
            .iter()
            .position(|i| i.dimensions() != images[0].dimensions())
        {
            return Err(path_err(
                &cameras_file,
                format!(
                    "image {} is {}x{}, but {} is {}x{} (every photo of a dataset has the same size)",
                    cams[k].name,
                    images[k].width(),
                    images[k].height(),
                    cams[0].name,
                    images[0].width(),
                    images[0].height()
                ),
            ));
        }
        Ok(Self {
            cameras_file,
            format: found.format,
            cams,
            images,
            masks,
            score_masks,
            silhouettes,
            notes,
        })
    }

    /// The photos' size.
    pub fn size(&self) -> (u32, u32) {
        self.images.first().map_or((0, 0), |i| i.dimensions())
    }

    /// A new camera from a spec ([`parse_camera_spec`], scaled as the photos were by `scale`;
    /// ring cameras look at `target`), refused when it sees none of `bounds`.
    pub fn camera(
        &self,
        spec: &str,
        scale: f64,
        target: &nalgebra::Vector3<f64>,
        bounds: &Aabb,
    ) -> crate::Result<Camera> {
        let cam = parse_camera_spec(spec, &self.cams, scale, target)?;
        let (w, h) = self.size();
        if !crate::hull::sees_box(&cam, bounds, w, h) {
            return Err(crate::Error::CameraSpec {
                spec: cam.name.clone(),
                what: format!(
                    "camera sees none of the volume {:?}..{:?}",
                    <[f64; 3]>::from(bounds.min),
                    <[f64; 3]>::from(bounds.max)
                ),
            });
        }
        Ok(cam)
    }

    /// Checks views to withhold: at least 3 views, every index among them.
    pub fn check_withheld(&self, views: &[usize]) -> crate::Result<()> {
        let n = self.cams.len();
        if n < 3 {
            let why = format!(
                "needs at least 3 views, {} has {n}",
                self.cameras_file.display()
            );
            return Err(bad("leave_out", "", why));
        }
        match views.iter().find(|&&k| k >= n) {
            Some(&k) => Err(bad(
                "leave_out",
                k,
                format!("there are {n} views (0-based, 0..{})", n - 1),
            )),
            None => Ok(()),
        }
    }

    /// Checks the carving silhouettes against each other: each view's IoU against the visual
    /// hull of the others ([`crate::hull::silhouette_agreement`] at [`CHECK_GRID`]) in
    /// `bounds`; views below [`crate::hull::AGREEMENT_IOU`] are named.
    pub fn check_silhouettes(&self, bounds: Aabb) -> crate::Result<SilhouetteCheck> {
        let iou = crate::hull::silhouette_agreement(&self.cams, &self.masks, bounds, CHECK_GRID)?;
        let threshold = crate::hull::AGREEMENT_IOU;
        Ok(SilhouetteCheck {
            threshold,
            views: self
                .cams
                .iter()
                .map(|c| c.name.clone())
                .zip(iou.iter().copied())
                .collect(),
            disagreeing: iou
                .iter()
                .enumerate()
                .filter(|(_, &v)| v < threshold)
                .map(|(i, &v)| (i, self.cams[i].name.clone(), v))
                .collect(),
            full: self
                .masks
                .iter()
                .enumerate()
                .map(|(i, m)| (i, m.count_ones() as f64 / m.len().max(1) as f64))
                .filter(|&(_, share)| share > FULL_SHARE)
                .map(|(i, share)| (i, self.cams[i].name.clone(), share))
                .collect(),
        })
    }

    /// The volume to carve: `given`, else found from the carving silhouettes.
    pub fn volume(&self, given: Option<Aabb>) -> crate::Result<Aabb> {
        volume(given, &self.cams, &self.masks)
    }

    /// Leaves view `k` out: builds the model from the other views (the volume from their
    /// silhouettes unless `model.bounds` is given), makes view `k` as `view` says and scores it
    /// and the baselines inside `k`'s scoring silhouette. The report's times start with
    /// `bounds`.
    pub fn leave_one_out(
        &self,
        k: usize,
        model: &ModelParams,
        view: &ViewParams,
    ) -> crate::Result<(EvalReport, EvalImages)> {
        // One copy of the other views, used for the bounds and the model; view k is scored
        // inside its scoring silhouette.
        let keep: Vec<usize> = (0..self.cams.len()).filter(|&i| i != k).collect();
        let others = Others::of(&self.cams, &self.images, &self.masks, &keep);
        let t = Instant::now();
        let bounds = volume(model.bounds, &others.cams, &others.masks)?;
        let bounds_secs = t.elapsed().as_secs_f64();
        let view_k = (k, &self.cams[k], &self.images[k], &self.score_masks[k]);
        let (mut r, imgs) = leave_one_out_from(
            &others,
            &keep,
            view_k,
            &model.hull(bounds),
            &model.photo(),
            view,
        )?;
        r.times.insert(0, ("bounds", bounds_secs));
        Ok((r, imgs))
    }
}

/// The model file's name inside a hull folder (`vt fv hull`).
pub const MODEL_FILE: &str = "model.vtfv";

/// Largest model file read (a 1024^3 grid's occupancy is 128 MiB as bits; runs and surface
/// voxels take less on any real model).
pub const MAX_MODEL_BYTES: u64 = 1 << 30;

impl Dataset {
    /// The views a model is built from: all, or all but `withheld`.
    pub fn model_views(&self, withheld: Option<usize>) -> Vec<usize> {
        (0..self.cams.len())
            .filter(|&i| Some(i) != withheld)
            .collect()
    }

    /// The header of a model built from this folder's views (all but `withheld`) with `m`.
    pub fn model_header(
        &self,
        withheld: Option<usize>,
        m: &ModelParams,
        build: &BuildSummary,
    ) -> ModelHeader {
        let (w, h) = self.size();
        let views = self.model_views(withheld);
        ModelHeader {
            cameras: self.cameras_file.display().to_string(),
            all_views: self.cams.len(),
            views: view_prints(&views, &self.cams, &self.images, &self.masks),
            withheld,
            image_size: [w, h],
            silhouettes: self.silhouettes.clone(),
            photo_threshold: m.photo_threshold,
            paper_carving: m.paper_carving,
            build_secs: build.visual_hull_secs + build.photo_hull_secs,
        }
    }

    /// Builds the model from all views but `withheld` (the volume from their silhouettes unless
    /// `m.bounds` is given), as [`Dataset::leave_one_out`] builds it; `None` builds from all.
    pub fn build_without(
        &self,
        withheld: Option<usize>,
        m: &ModelParams,
        progress: &mut dyn FnMut(&str, u64, u64),
    ) -> crate::Result<(VoxelModel, BuildSummary)> {
        let keep = self.model_views(withheld);
        if withheld.is_none() {
            let bounds = self.volume(m.bounds)?;
            return build_summarised(&self.cams, &self.images, &self.masks, bounds, m, progress);
        }
        let o = Others::of(&self.cams, &self.images, &self.masks, &keep);
        let bounds = volume(m.bounds, &o.cams, &o.masks)?;
        build_summarised(&o.cams, &o.images, &o.masks, bounds, m, progress)
    }

    /// Checks that a model file's header describes this folder's views as loaded: same number
    /// of views and photo size, and for each view it was built from the same photo name,
    /// camera, photo and carving silhouette (fingerprints). The error names the file and the
    /// first difference.
    pub fn check_model(&self, path: &Path, h: &ModelHeader) -> Result<(), DataError> {
        let n = self.cams.len();
        let err = |what: String| path_err(path, what);
        if h.all_views != n {
            return Err(err(format!(
                "built from a data folder of {} views ({}), but {} has {n}",
                h.all_views,
                h.cameras,
                self.cameras_file.display()
            )));
        }
        let (w, ht) = self.size();
        if h.image_size != [w, ht] {
            return Err(err(format!(
                "built from {}x{} photos, these are {w}x{ht} (another data folder or --scale?)",
                h.image_size[0], h.image_size[1]
            )));
        }
        let expect = self.model_views(h.withheld.filter(|&k| k < n));
        if h.withheld.is_some_and(|k| k >= n)
            || h.views.iter().map(|v| v.index).ne(expect.iter().copied())
        {
            return Err(err(
                "its list of views is inconsistent (damaged file?)".into()
            ));
        }
        let here = view_prints(&expect, &self.cams, &self.images, &self.masks);
        for (a, b) in h.views.iter().zip(&here) {
            let what = if a.name != b.name {
                format!("is {} there, {} here: another data folder", a.name, b.name)
            } else if a.camera != b.camera {
                "its camera differs from the one the model was built from (another data folder, --scale or --photo-fit?)".into()
            } else if a.photo != b.photo {
                "its photo differs from the one the model was built from".into()
            } else if a.silhouette != b.silhouette {
                format!(
                    "its silhouette differs from the one the model was built from (model: {}; here: {}; use the --masks, --silhouettes, --threshold and --carve-* the model was built with)",
                    h.silhouettes, self.silhouettes
                )
            } else {
                continue;
            };
            return Err(err(format!("view {} ({}) {what}", a.index, b.name)));
        }
        Ok(())
    }

    /// Leaves view `k` out with a model read from a file (`vt fv hull --leave-out k`), which
    /// must have been built without view `k`: the same report as [`Dataset::leave_one_out`]
    /// gives, without carving again. The report's build times are the file's.
    pub fn leave_one_out_with(
        &self,
        k: usize,
        model: &VoxelModel,
        header: &ModelHeader,
        path: &Path,
        view: &ViewParams,
    ) -> Result<(EvalReport, EvalImages), DataError> {
        if header.withheld != Some(k) {
            let built = match header.withheld {
                None => "from all views".to_string(),
                Some(j) => format!("without view {j}"),
            };
            return Err(path_err(
                path,
                format!(
                    "built {built}, not without view {k}: the withheld view must not be in the model (build it with `vt fv hull DATA --leave-out {k}`)"
                ),
            ));
        }
        let keep = self.model_views(Some(k));
        let others = Others::of(&self.cams, &self.images, &self.masks, &keep);
        let view_k = (k, &self.cams[k], &self.images[k], &self.score_masks[k]);
        let times = Vec::new();
        Ok(score_withheld(&others, &keep, view_k, model, view, times)?)
    }
}

/// Writes a model file (inside an output folder being built).
pub fn write_model(path: &Path, model: &VoxelModel, header: &ModelHeader) -> Result<(), DataError> {
    std::fs::write(path, encode(model, header)).map_err(|e| path_err(path, e.to_string()))
}

/// Reads a model file (or a hull folder's [`MODEL_FILE`]) and checks it against the data
/// folder `d` was loaded from ([`Dataset::check_model`]). Errors name the file.
pub fn read_model(path: &Path, d: &Dataset) -> Result<(VoxelModel, ModelHeader), DataError> {
    let file = if path.is_dir() {
        path.join(MODEL_FILE)
    } else {
        path.to_path_buf()
    };
    if !file.is_file() {
        return Err(path_err(
            &file,
            "no model file here (`vt fv hull DATA --out DIR` writes DIR/model.vtfv)",
        ));
    }
    let bytes = vt_io::limits::read_bytes(&file, MAX_MODEL_BYTES, "model file")?;
    let (model, header) = decode(&bytes).map_err(|cause| DataError::File {
        path: file.clone(),
        cause,
    })?;
    d.check_model(&file, &header)?;
    Ok((model, header))
}

/// The volume a model is built in: `given`, else found from the silhouettes ([`auto_bounds`]
/// with [`HullParams::default`]).
/// Every camera is checked to have the volume's centre in front of it (a pose read the wrong
/// way round, camera-to-world for world-to-camera, puts it behind).
pub fn volume(given: Option<Aabb>, cams: &[Camera], masks: &[Mask]) -> crate::Result<Aabb> {
    let b = match given {
        Some(b) => b,
        None => auto_bounds(cams, masks, &HullParams::default())?,
    };
    check_in_front(cams, &b)?;
    Ok(b)
}

/// Checks that the centre of `bounds` lies in front of every camera; the error names the first
/// camera that has it behind (or beside) it.
pub fn check_in_front(cams: &[Camera], bounds: &Aabb) -> crate::Result<()> {
    let centre = bounds.centre();
    for c in cams {
        let z = c.to_camera(&centre).z;
        if z.is_nan() || z <= crate::camera::MIN_DEPTH {
            return Err(crate::Error::BadCamera {
                name: c.name.clone(),
                what: format!(
                    "the volume's centre {:?} is behind the camera (depth {z:.4}); is its pose world-to-camera (x_cam = R X + t)?",
                    <[f64; 3]>::from(centre)
                ),
            });
        }
    }
    Ok(())
}

/// How to build the voxel model.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelParams {
    /// Voxels along the longest side of the volume (128; paper: 256); voxels are cubes. 128 is
    /// measured best under the time budget: on templeSparseRing the result scores the same at
    /// 128, 192 and 256, and one leave-one-out takes 2.4x longer at 256 (the crate README).
    pub grid: usize,
    /// The volume to carve; `None`: found from the silhouettes.
    pub bounds: Option<Aabb>,
    /// Photo-consistency threshold ([`PhotoParams::threshold`]).
    pub photo_threshold: f64,
    /// Carve and colour as the paper does (no [`PhotoParams::keep_silhouettes`], no
    /// [`PhotoParams::colour_partly_seen`]).
    pub paper_carving: bool,
}

impl Default for ModelParams {
    fn default() -> Self {
        Self {
            grid: 128,
            bounds: None,
            photo_threshold: PhotoParams::default().threshold,
            paper_carving: false,
        }
    }
}

/// Largest [`ModelParams::grid`] (voxels per side).
pub const MAX_GRID: usize = 1024;

impl ModelParams {
    /// Checks the ranges before anything is allocated: `grid` in 2..=[`MAX_GRID`] and within
    /// [`HullParams::max_bytes`], `photo_threshold` in [0, 255].
    pub fn check(&self) -> crate::Result<()> {
        if self.grid < 2 {
            return Err(bad("grid", self.grid, "too small (at least 2)"));
        }
        // The bit array's limit alone lets 1600^3 through, whose photo hull then asks for GiBs
        // of voxel indices: the working memory is bounded by the side too.
        if self.grid > MAX_GRID {
            return Err(bad(
                "grid",
                self.grid,
                format!("more than {MAX_GRID} voxels per side (the photo hull's working memory grows with the cube of it; refused before allocating)"),
            ));
        }
        crate::hull::grid_bytes([self.grid; 3], HullParams::default().max_bytes).map_err(|e| {
            bad(
                "grid",
                self.grid,
                format!("{e} (refused before allocating)"),
            )
        })?;
        let t = self.photo_threshold;
        if !(t.is_finite() && (0.0..=255.0).contains(&t)) {
            return Err(bad(
                "photo_threshold",
                vt_io::output::num(t),
                "must be a number in [0, 255] (grey levels)",
            ));
        }
        Ok(())
    }

    /// Visual-hull settings for `bounds`.
    pub fn hull(&self, bounds: Aabb) -> HullParams {
        HullParams {
            dims: dims_for(&bounds, self.grid),
            bounds: Some(bounds),
            ..Default::default()
        }
    }

    /// Photo-hull settings.
    pub fn photo(&self) -> PhotoParams {
        PhotoParams {
            threshold: self.photo_threshold,
            keep_silhouettes: !self.paper_carving,
            colour_partly_seen: !self.paper_carving,
            ..Default::default()
        }
    }
}

/// Timings and counts of a model build (the `summary.json` of `vt fv hull`, flattened).
#[derive(Debug, Serialize, Clone, PartialEq)]
pub struct BuildSummary {
    /// Voxels per axis.
    pub grid: [usize; 3],
    /// Volume minimum corner.
    pub bounds_min: [f64; 3],
    /// Volume maximum corner.
    pub bounds_max: [f64; 3],
    /// Voxels of the visual hull.
    pub visual_hull_voxels: usize,
    /// Seconds for the visual hull.
    pub visual_hull_secs: f64,
    /// Voxels of the photo hull.
    pub photo_hull_voxels: usize,
    /// Carving passes.
    pub photo_hull_passes: usize,
    /// Voxels the photo hull removed.
    pub photo_hull_removed: usize,
    /// Seconds for the photo hull.
    pub photo_hull_secs: f64,
    /// Surface voxels.
    pub surface_voxels: usize,
    /// Surface voxels seen by no camera.
    pub surface_unseen: usize,
}

/// Visual hull then photo hull in `bounds`, with a summary. `progress(stage, done, total)`
/// reports the stages (`visual hull`, `photo hull`).
pub fn build_summarised(
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    bounds: Aabb,
    m: &ModelParams,
    progress: &mut dyn FnMut(&str, u64, u64),
) -> crate::Result<(VoxelModel, BuildSummary)> {
    let hp = m.hull(bounds);
    let t = Instant::now();
    progress("visual hull", 0, 1);
    let grid = visual_hull(cams, masks, &hp)?;
    progress("visual hull", 1, 1);
    let vh_secs = t.elapsed().as_secs_f64();
    let vh_voxels = grid.count();
    let t = Instant::now();
    let model = photo_hull_keeping(grid, cams, images, Some(masks), &m.photo(), progress)?;
    let summary = BuildSummary {
        grid: hp.dims,
        bounds_min: bounds.min.into(),
        bounds_max: bounds.max.into(),
        visual_hull_voxels: vh_voxels,
        visual_hull_secs: vh_secs,
        photo_hull_voxels: model.grid.count(),
        photo_hull_passes: model.passes,
        photo_hull_removed: model.removed,
        photo_hull_secs: t.elapsed().as_secs_f64(),
        surface_voxels: model.surface.len(),
        surface_unseen: model.surface.iter().filter(|v| v.seen_by == 0).count(),
    };
    Ok((model, summary))
}

/// `summary.json` of a hull folder.
#[derive(Debug, Serialize)]
pub struct HullSummary {
    /// `vt-fv-hull`.
    pub format: &'static str,
    /// Format version (1).
    pub version: u32,
    /// The camera file.
    pub cameras: String,
    /// Number of views.
    pub views: usize,
    /// Photo size.
    pub image_size: [u32; 2],
    /// Where the silhouettes came from.
    pub silhouettes: String,
    /// Photo-consistency threshold.
    pub photo_threshold: f64,
    /// The build.
    #[serde(flatten)]
    pub build: BuildSummary,
    /// The silhouettes' cross-view consistency, when it was checked.
    pub silhouette_check: Option<SilhouetteCheck>,
}

/// Grid of the visual hulls [`Dataset::check_silhouettes`] carves (64 voxels along the longest
/// side: a tenth of a second per view on the kettle).
pub const CHECK_GRID: usize = 64;

/// The silhouettes' cross-view consistency ([`crate::hull::silhouette_agreement`]).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SilhouetteCheck {
    /// IoU below which a view is named.
    pub threshold: f64,
    /// Each view's photo name and IoU against the hull of the others, in camera order.
    pub views: Vec<(String, f64)>,
    /// The views that disagree: (index, photo name, IoU).
    pub disagreeing: Vec<(usize, String, f64)>,
    /// Views whose silhouette covers more than [`FULL_SHARE`] of the photo (index, photo name,
    /// share): no segmentation at all, which agrees with anything (e.g. the dark-backdrop
    /// threshold on a light backdrop).
    pub full: Vec<(usize, String, f64)>,
}

/// Share of a photo above which [`SilhouetteCheck`] names a silhouette as covering all of it
/// (0.9).
pub const FULL_SHARE: f64 = 0.9;

/// One line: the IoU range, and the photos that disagree by name.
impl std::fmt::Display for SilhouetteCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let iou: Vec<f64> = self.views.iter().map(|v| v.1).collect();
        let lo = iou.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = iou.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        write!(
            f,
            "silhouette check: IoU of each view's silhouette against the hull of the others {lo:.2}-{hi:.2}; "
        )?;
        if !self.full.is_empty() {
            let names: Vec<String> = self
                .full
                .iter()
                .map(|(i, n, v)| format!("view {i} ({n}): {:.0}%", v * 100.0))
                .collect();
            write!(
                f,
                "{} cover nearly the whole photo (not segmented: a light backdrop thresholded as dark? try --silhouettes backdrop): {}; ",
                names.len(),
                names.join(", ")
            )?;
        }
        if self.disagreeing.is_empty() {
            return write!(f, "all {} agree (>= {})", self.views.len(), self.threshold);
        }
        let names: Vec<String> = self
            .disagreeing
            .iter()
            .map(|(i, n, v)| format!("view {i} ({n}): {v:.2}"))
            .collect();
        write!(
            f,
            "{} below {} disagree with the others (a wrong silhouette or camera; give masks with --masks or drop the photo): {}",
            names.len(),
            self.threshold,
            names.join(", ")
        )
    }
}

/// Writes `hull.ply` (the coloured surface voxels), `summary.json` and the model file
/// [`MODEL_FILE`] (what `render`, `orbit` and `eval` read with `--model`) into `dir`.
pub fn write_hull(
    dir: &Path,
    d: &Dataset,
    model: &VoxelModel,
    header: &ModelHeader,
    build: &BuildSummary,
    check: Option<&SilhouetteCheck>,
) -> Result<(), DataError> {
    write_model(&dir.join(MODEL_FILE), model, header)?;
    let photo_threshold = header.photo_threshold;
    let ply = dir.join("hull.ply");
    let mut bytes = Vec::new();
    model
        .to_ply(&mut bytes)
        .map_err(|e| path_err(&ply, e.to_string()))?;
    std::fs::write(&ply, bytes).map_err(|e| path_err(&ply, e.to_string()))?;
    let (w, h) = d.size();
    let summary = HullSummary {
        format: "vt-fv-hull",
        version: 1,
        cameras: d.cameras_file.display().to_string(),
        views: d.cams.len(),
        image_size: [w, h],
        silhouettes: d.silhouettes.clone(),
        photo_threshold,
        build: build.clone(),
        silhouette_check: check.cloned(),
    };
    write_json(&dir.join("summary.json"), &summary)
}

/// Writes `value` as pretty JSON to `path`.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<(), DataError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| path_err(path, e.to_string()))?;
    std::fs::write(path, text).map_err(|e| path_err(path, e.to_string()))
}

/// Writes one withheld view's images into `dir` (which must exist): `truth`, `nearest_photo`,
/// `rough`, `rough_blur2`, `guide`, `guided` and the error maps of `rough`, `rough_blur2` and
/// `guided` against the truth (`*_error.png`), and the scoring `silhouette.png`.
pub fn write_eval_images(dir: &Path, imgs: &EvalImages, mask: &Mask) -> Result<(), DataError> {
    let err = |img: &RgbImage| error_map(img, &imgs.truth, mask);
    let files = [
        ("truth.png", &imgs.truth),
        ("nearest_photo.png", &imgs.nearest_photo),
        ("rough.png", &imgs.rough),
        ("rough_blur2.png", &imgs.rough_blur2),
        ("guide.png", &imgs.guide),
        ("guided.png", &imgs.guided),
        ("rough_error.png", &err(&imgs.rough)),
        ("rough_blur2_error.png", &err(&imgs.rough_blur2)),
        ("guided_error.png", &err(&imgs.guided)),
    ];
    for (name, img) in files {
        let p = dir.join(name);
        img.save(&p).map_err(|e| path_err(&p, e.to_string()))?;
    }
    let p = dir.join("silhouette.png");
    crate::silhouette::mask_image(mask)
        .save(&p)
        .map_err(|e| path_err(&p, e.to_string()))
}

/// One withheld view in `vt fv eval`'s JSON: scores inside the withheld silhouette (and `whole`,
/// over the whole image), the model's silhouette IoU, and seconds per stage.
#[derive(Debug, Serialize)]
pub struct ViewSummary {
    /// The withheld view (0-based).
    pub withheld: usize,
    /// Its image name.
    pub name: String,
    /// The nearest reference photo.
    pub reference: usize,
    /// The rough render.
    pub rough: Score,
    /// The rough render blurred (sigma 2).
    pub rough_blur2: Score,
    /// The nearest photo as it is.
    pub nearest_photo: Score,
    /// The guide.
    pub guide: Score,
    /// The result.
    pub guided: Score,
    /// The same five over the whole image.
    pub whole: BTreeMap<&'static str, Score>,
    /// IoU of the rough render's coverage against the withheld silhouette.
    pub silhouette_iou: f64,
    /// Surface voxels of the model.
    pub surface_voxels: usize,
    /// Seconds per stage.
    pub secs: BTreeMap<&'static str, f64>,
    /// Seconds in all.
    pub total_secs: f64,
}

impl ViewSummary {
    /// The summary of a report; `name` is the withheld view's image name.
    pub fn new(r: &EvalReport, name: &str) -> Self {
        Self {
            withheld: r.withheld,
            name: name.to_string(),
            reference: r.reference,
            rough: r.rough.inside,
            rough_blur2: r.rough_blur2.inside,
            nearest_photo: r.nearest_photo.inside,
            guide: r.guide.inside,
            guided: r.guided.inside,
            whole: r.candidates().iter().map(|(n, s)| (*n, s.whole)).collect(),
            silhouette_iou: r.silhouette_iou,
            surface_voxels: r.surface_voxels,
            secs: r.times.iter().copied().collect(),
            total_secs: r.total_secs(),
        }
    }
}

/// `vt fv eval --json`: means over the withheld views inside their silhouettes, and every view.
#[derive(Debug, Serialize)]
pub struct EvalSummary {
    /// [`ViewParams::name`].
    pub method: &'static str,
    /// Mean of the rough render's scores.
    pub rough: Score,
    /// ... of the blurred rough render.
    pub rough_blur2: Score,
    /// ... of the nearest photo.
    pub nearest_photo: Score,
    /// ... of the guide.
    pub guide: Score,
    /// ... of the result.
    pub guided: Score,
    /// Mean silhouette IoU.
    pub silhouette_iou: f64,
    /// Every view.
    pub views: Vec<ViewSummary>,
}

impl EvalSummary {
    /// Means over `reports` (at least one), the views named from `cams`.
    pub fn new(method: &'static str, reports: &[EvalReport], cams: &[Camera]) -> Self {
        let mean = |k: usize| mean_score(reports, k);
        Self {
            method,
            nearest_photo: mean(0),
            rough: mean(1),
            rough_blur2: mean(2),
            guide: mean(3),
            guided: mean(4),
            silhouette_iou: reports.iter().map(|r| r.silhouette_iou).sum::<f64>()
                / reports.len().max(1) as f64,
            views: reports
                .iter()
                .map(|r| ViewSummary::new(r, &cams[r.withheld].name))
                .collect(),
        }
    }
}

/// The means table: PSNR and SSIM of each candidate, and the silhouette IoU.
impl std::fmt::Display for EvalSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.views.len();
        writeln!(
            f,
            "mean over {n} views, inside the silhouettes: PSNR dB / SSIM"
        )?;
        for (name, s) in [
            ("nearest_photo", self.nearest_photo),
            ("rough", self.rough),
            ("rough_blur2", self.rough_blur2),
            ("guide", self.guide),
            ("guided", self.guided),
        ] {
            writeln!(f, "{name:<14} {:>10.2} {:>8.3}", s.psnr, s.ssim)?;
        }
        write!(f, "silhouette IoU {:.3}", self.silhouette_iou)
    }
}

/// Mean inside-silhouette score of candidate `k` ([`EvalReport::candidates`] order) over
/// `reports`.
pub fn mean_score(reports: &[EvalReport], k: usize) -> Score {
    let n = reports.len().max(1) as f64;
    let s = |f: &dyn Fn(Score) -> f64| {
        reports
            .iter()
            .map(|r| f(r.candidates()[k].1.inside))
            .sum::<f64>()
            / n
    };
    Score {
        psnr: s(&|x| x.psnr),
        ssim: s(&|x| x.ssim),
    }
}

/// A volume from text `x0,y0,z0,x1,y1,z1` (world units); the message says what is wrong.
pub fn parse_bounds(s: &str) -> Result<Aabb, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|f| {
            f.trim()
                .parse::<f64>()
                .map_err(|_| format!("bounds value {f:?} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "bounds {s:?} must be six finite numbers x0,y0,z0,x1,y1,z1"
        ));
    }
    let s = vt_io::output::shorten(s);
    if (0..3).any(|i| v[i + 3] <= v[i]) {
        return Err(format!("bounds {s:?}: x1, y1, z1 must exceed x0, y0, z0"));
    }
    // A box too thin for its coordinates (1e-300 wide) has no voxel size that means anything.
    let scale = v.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        let side = v[i + 3] - v[i];
        if !side.is_finite() || side < 1e-6 * scale {
            return Err(format!(
                "bounds {s:?}: the {axis} side is {side:e} wide; vt needs at least {:e} (1e-6 of the coordinates' size)",
                1e-6 * scale
            ));
        }
    }
    Ok(Aabb::new(
        nalgebra::Vector3::new(v[0], v[1], v[2]),
        nalgebra::Vector3::new(v[3], v[4], v[5]),
    ))
}

/// The stage table: voxels, passes and seconds of each stage, then the surface.
impl std::fmt::Display for BuildSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self;
        writeln!(
            f,
            "{:<14} {:>12} {:>7} {:>9}",
            "stage", "voxels", "passes", "time"
        )?;
        let (vh, ph) = (s.visual_hull_voxels, s.photo_hull_voxels);
        writeln!(
            f,
            "{:<14} {vh:>12} {:>7} {:>7.2} s",
            "visual hull", "-", s.visual_hull_secs
        )?;
        let (passes, secs) = (s.photo_hull_passes, s.photo_hull_secs);
        writeln!(f, "{:<14} {ph:>12} {passes:>7} {secs:>7.2} s", "photo hull")?;
        writeln!(
            f,
            "{:<14} {:>12} {:>7} {:>9}",
            "surface", s.surface_voxels, "-", "-"
        )?;
        write!(
            f,
            "{:.1} % of the surface ({} of {} voxels) is seen by no camera; those took the nearest seen colour",
            100.0 * s.surface_unseen as f64 / s.surface_voxels.max(1) as f64,
            s.surface_unseen,
            s.surface_voxels
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::Scores;

    #[test]
    fn bounds_text_is_checked() {
        let b = parse_bounds("-1, 0,0.5, 1,2,3").unwrap();
        assert_eq!(<[f64; 3]>::from(b.min), [-1.0, 0.0, 0.5]);
        assert_eq!(<[f64; 3]>::from(b.max), [1.0, 2.0, 3.0]);
        for (text, says) in [
            ("1,2,3", "six finite numbers"),
            ("0,0,0,1,1,x", "\"x\" is not a number"),
            ("0,0,0,-1,1,1", "must exceed"),
            ("0,0,0,1e-300,1,1", "the x side is 1e-300 wide"),
        ] {
            let e = parse_bounds(text).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn intrinsics_fit_resized_and_cropped_photos() {
        let k = nalgebra::Matrix3::new(1000.0, 0.0, 639.5, 0.0, 1000.0, 479.5, 0.0, 0.0, 1.0);
        // Half size, pixel centres at integers: c' = s (c + 0.5) - 0.5 = 0.5 * 640 - 0.5.
        let h = fit_intrinsics(&k, (1280, 960), (640, 480), PhotoFit::Scale).unwrap();
        assert_eq!((h[(0, 0)], h[(0, 2)], h[(1, 2)]), (500.0, 319.5, 239.5));
        let c = fit_intrinsics(&k, (1280, 960), (1250, 936), PhotoFit::Crop).unwrap();
        assert_eq!((c[(0, 0)], c[(0, 2)], c[(1, 2)]), (1000.0, 624.5, 467.5));
        let e = fit_intrinsics(&k, (1280, 960), (640, 400), PhotoFit::Scale).unwrap_err();
        assert!(e.contains("not a uniform rescale"), "{e}");
        assert_eq!(
            fit_intrinsics(&k, (1280, 960), (1280, 960), PhotoFit::Scale).unwrap(),
            k
        );
    }

    #[test]
    fn option_ranges_name_the_field() {
        let name = |e: crate::Error| match e {
            crate::Error::BadParam { name, .. } => name,
            e => panic!("{e}"),
        };
        let d = DataOptions::default();
        assert!(d.check().is_ok());
        let bad = DataOptions {
            scale: 0.0,
            ..d.clone()
        };
        assert_eq!(name(bad.check().unwrap_err()), "scale");
        let bad = DataOptions {
            carve_erode: 101,
            ..d.clone()
        };
        assert_eq!(name(bad.check().unwrap_err()), "carve_erode");
        let m = ModelParams::default();
        assert!(m.check().is_ok());
        for grid in [1, MAX_GRID + 1] {
            let bad = ModelParams { grid, ..m.clone() };
            assert_eq!(name(bad.check().unwrap_err()), "grid");
        }
        let bad = ModelParams {
            photo_threshold: f64::NAN,
            ..m
        };
        assert_eq!(name(bad.check().unwrap_err()), "photo_threshold");
    }

    #[test]
    fn summary_means_are_over_the_views() {
        let s = |p: f64, q: f64| Scores {
            inside: Score { psnr: p, ssim: q },
            whole: Score {
                psnr: 0.0,
                ssim: 0.0,
            },
        };
        let report = |k: usize, p: f64| EvalReport {
            withheld: k,
            reference: 0,
            nearest_photo: s(p, 0.1),
            rough: s(p + 1.0, 0.2),
            rough_blur2: s(p + 2.0, 0.3),
            guide: s(p + 3.0, 0.4),
            guided: s(p + 4.0, 0.5),
            silhouette_iou: p / 100.0,
            surface_voxels: 1,
            times: vec![("scoring", 1.0)],
        };
        let cam = |n: &str| {
            Camera::new(
                n,
                nalgebra::Matrix3::identity(),
                nalgebra::Matrix3::identity(),
                nalgebra::Vector3::zeros(),
            )
            .unwrap()
        };
        let cams = [cam("a.png"), cam("b.png")];
        let e = EvalSummary::new("textured", &[report(0, 10.0), report(1, 20.0)], &cams);
        assert_eq!(e.nearest_photo.psnr, 15.0);
        assert_eq!(e.guided.psnr, 19.0);
        assert!((e.guided.ssim - 0.5).abs() < 1e-12);
        assert!((e.silhouette_iou - 0.15).abs() < 1e-12);
        assert_eq!(e.views[1].name, "b.png");
        assert_eq!(e.views[1].rough.psnr, 21.0);
        assert_eq!(e.views[0].total_secs, 1.0);
    }
}
