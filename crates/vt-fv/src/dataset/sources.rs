//! Where a data folder's cameras come from (a Middlebury par file, a COLMAP model, projection
//! matrices) and how its photos are matched to them.

use super::*;

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
    /// A NeRF transforms file (`transforms.json`, `transforms_train.json`; [`crate::nerf`]).
    Nerf,
}

impl std::fmt::Display for CameraFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CameraFormat::Par => "Middlebury par file",
            CameraFormat::ColmapText => "COLMAP text model",
            CameraFormat::ColmapBinary => "COLMAP binary model",
            CameraFormat::Matrices => "projection matrices",
            CameraFormat::Nerf => "NeRF transforms file",
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

pub(super) fn files_ending(dir: &Path, suffix: &str) -> Vec<PathBuf> {
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

/// The NeRF transforms files a data folder's cameras are read from (a test set's file is given
/// by name: `vt fv eval --test`).
pub const NERF_FILES: [&str; 2] = ["transforms.json", "transforms_train.json"];

/// Finds a data folder's cameras: one `*_par.txt` in it; a COLMAP model (`cameras.txt` +
/// `images.txt`, or `cameras.bin` + `images.bin`; binary wins when both are there) in it, in
/// `sparse/` or in `sparse/0/`; a `cameras/` folder of projection matrices; or a NeRF
/// transforms file ([`NERF_FILES`]). More than one of these is refused (keep one).
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
    for name in NERF_FILES {
        let path = dir.join(name);
        if path.is_file() {
            found.push(CameraSource {
                format: CameraFormat::Nerf,
                path,
                note: None,
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
            "no cameras in it: no *_par.txt camera file, no COLMAP model (cameras.txt + images.txt or cameras.bin + images.bin, here or in sparse/ or sparse/0/), no cameras/ folder of projection matrices, no transforms.json or transforms_train.json (NeRF)",
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
pub(super) struct Source {
    pub(super) cam: Camera,
    pub(super) lens: Lens,
    pub(super) recorded: Option<(u32, u32)>,
    pub(super) photo: PathBuf,
}

/// A photo name from a camera file: relative, inside the folder, no `..`.
pub(super) fn inside(name: &str) -> bool {
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
pub(super) fn photo_folder(dir: &Path) -> PathBuf {
    let d = dir.join("images");
    if d.is_dir() {
        d
    } else {
        dir.to_path_buf()
    }
}

pub(super) fn file_err(path: &Path) -> impl Fn(crate::Error) -> DataError + '_ {
    move |cause| DataError::File {
        path: path.to_path_buf(),
        cause,
    }
}

/// The views of a COLMAP model in `model_dir`, photos in [`photo_folder`].
pub(super) fn colmap_sources(
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
pub(super) fn matrix_sources(dir: &Path, mats: &Path) -> Result<Vec<Source>, DataError> {
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

/// The views of a NeRF transforms file `file`: photos at each frame's `file_path` relative to
/// the file's folder (with the extension it has, else the first of [`PHOTO_EXTENSIONS`] that
/// exists), each camera recorded at the file's `w`, `h` or its photo's own size.
pub(super) fn nerf_sources(file: &Path) -> Result<Vec<Source>, DataError> {
    let text = vt_io::limits::read_text(file, MAX_MODEL_FILE_BYTES, "NeRF transforms file")?;
    let frames = crate::nerf::parse_transforms(&text).map_err(file_err(file))?;
    let folder = file.parent().unwrap_or(Path::new("."));
    let mut out = Vec::with_capacity(frames.len());
    for (i, f) in frames.iter().enumerate() {
        let rel = f.file_path.trim_start_matches("./");
        if !inside(rel) {
            return Err(path_err(
                file,
                format!(
                    "frame {i}: file_path {:?} points outside {} (use a path relative to it, without ..)",
                    f.file_path,
                    folder.display()
                ),
            ));
        }
        let given = folder.join(rel);
        let has_ext = Path::new(rel)
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| PHOTO_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        let photo = if has_ext {
            Some(given.clone()).filter(|p| p.is_file())
        } else {
            PHOTO_EXTENSIONS
                .iter()
                .flat_map(|e| [e.to_string(), e.to_ascii_uppercase()])
                .map(|e| folder.join(format!("{rel}.{e}")))
                .find(|p| p.is_file())
        };
        let Some(photo) = photo else {
            return Err(path_err(
                file,
                format!(
                    "frame {i}: no photo {}{} for file_path {:?}",
                    given.display(),
                    if has_ext { "" } else { ".png/.jpg/..." },
                    f.file_path
                ),
            ));
        };
        let dims = image::ImageReader::open(&photo)
            .and_then(|r| r.with_guessed_format())
            .map_err(|e| vt_io::Error::io(&photo, e))?
            .into_dimensions()
            .map_err(|e| path_err(&photo, e.to_string()))?;
        let named = |e: crate::Error| DataError::File {
            path: file.to_path_buf(),
            cause: crate::Error::Transforms {
                what: format!("frame {i} ({}): {e}", f.file_path),
            },
        };
        let size = f.intrinsics.size(dims).map_err(named)?;
        let (k, lens) = f.intrinsics.k(size).map_err(named)?;
        let name = photo
            .strip_prefix(folder)
            .unwrap_or(&photo)
            .to_string_lossy()
            .into_owned();
        let cam = crate::nerf::camera_from_c2w(&name, &f.c2w, k).map_err(file_err(file))?;
        out.push(Source {
            cam,
            lens,
            recorded: Some(size),
            photo,
        });
    }
    Ok(out)
}

/// The views `sel` picks from `sources`, in `sel`'s order: each a 0-based index in camera order,
/// a camera's name (its photo's path as the camera file names it) or that name's file stem.
pub(super) fn select_views(
    sources: Vec<Source>,
    sel: &[String],
    cameras_file: &Path,
) -> Result<Vec<Source>, DataError> {
    if sel.is_empty() {
        return Ok(sources);
    }
    let n = sources.len();
    let stem = |name: &str| {
        Path::new(name)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let mut picked: Vec<usize> = Vec::with_capacity(sel.len());
    for s in sel {
        let s = s.trim();
        let i = match s.parse::<usize>() {
            Ok(i) if i < n => i,
            Ok(i) => {
                return Err(DataError::Fv(bad(
                    "views",
                    i,
                    format!(
                        "{} has {n} views (0-based, 0..{})",
                        cameras_file.display(),
                        n.saturating_sub(1)
                    ),
                )))
            }
            Err(_) => {
                let by_name: Vec<usize> =
                    (0..n)
                        .filter(|&i| sources[i].cam.name == s)
                        .chain((0..n).filter(|&i| {
                            sources[i].cam.name != s && stem(&sources[i].cam.name) == s
                        }))
                        .collect();
                match by_name.as_slice() {
                    [i] => *i,
                    [] => {
                        return Err(DataError::Fv(bad(
                            "views",
                            s,
                            format!(
                                "no view of that index or name in {}",
                                cameras_file.display()
                            ),
                        )))
                    }
                    _ => {
                        return Err(DataError::Fv(bad(
                            "views",
                            s,
                            format!(
                                "names more than one view in {}; give the full name or the index",
                                cameras_file.display()
                            ),
                        )))
                    }
                }
            }
        };
        if picked.contains(&i) {
            return Err(DataError::Fv(bad(
                "views",
                s,
                format!("view {i} is chosen twice"),
            )));
        }
        picked.push(i);
    }
    let mut sources: Vec<Option<Source>> = sources.into_iter().map(Some).collect();
    Ok(picked
        .into_iter()
        .map(|i| sources[i].take().expect("picked once"))
        .collect())
}
