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
    /// The views to build from, in this order: 0-based indices in camera order, camera names or
    /// their file stems (`r_26`). Empty: every view.
    pub views: Vec<String>,
    /// The colour photos with an alpha channel are composited over, and new views' uncovered
    /// pixels take ([`Background::Data`]: white for NeRF transforms files, as the NeRF
    /// synthetic data is scored; transparent for the other formats).
    pub background: crate::composite::Background,
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
            views: Vec::new(),
            background: Default::default(),
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
    /// The background colour: photos with an alpha channel were composited over it, and new
    /// views' uncovered pixels take it. `None`: photos keep their colours, uncovered pixels are
    /// transparent (black where the format has no alpha).
    pub background: Option<[u8; 3]>,
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
        Self::load_from(dir, found, opt)
    }

    /// Reads a second camera set, e.g. a test set: a data folder as [`Dataset::load`] reads it,
    /// or a NeRF transforms file (`transforms_test.json`), its photos relative to its folder.
    pub fn load_set(path: &Path, opt: &DataOptions) -> Result<Self, DataError> {
        if path.is_dir() {
            return Self::load(path, opt);
        }
        opt.check()?;
        if !path.is_file() {
            return Err(path_err(path, "no such file or folder"));
        }
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            return Err(path_err(
                path,
                "not a data folder nor a NeRF transforms file (.json)",
            ));
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        let found = CameraSource {
            format: CameraFormat::Nerf,
            path: path.to_path_buf(),
            note: None,
        };
        Self::load_from(dir, found, opt)
    }

    fn load_from(dir: &Path, found: CameraSource, opt: &DataOptions) -> Result<Self, DataError> {
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
            CameraFormat::Nerf => {
                let s = nerf_sources(&found.path)?;
                notes.push(format!(
                    "cameras: {} frames in {} (NeRF transforms, camera-to-world in OpenGL axes)",
                    s.len(),
                    found.path.display()
                ));
                (found.path.clone(), s)
            }
        };
        let all = sources.len();
        let sources = select_views(sources, &opt.views, &cameras_file)?;
        if sources.len() < all {
            notes.push(format!(
                "views: {} of {all} chosen by --views ({})",
                sources.len(),
                sources
                    .iter()
                    .map(|s| s.cam.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        // The NeRF synthetic data is scored over white (its `white_bkgd`).
        let background = match opt.background {
            crate::composite::Background::Colour(c) => Some(c),
            crate::composite::Background::Transparent => None,
            crate::composite::Background::Data => {
                (found.format == CameraFormat::Nerf).then_some([255; 3])
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
            background,
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
                    None => read_photo(&s.photo, background)?,
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
            background,
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

mod model;
mod outputs;
mod photos;
mod sources;
#[cfg(test)]
mod tests;
mod testset;

pub use model::*;
pub use outputs::*;
pub use photos::*;
pub use sources::*;
pub use testset::*;
