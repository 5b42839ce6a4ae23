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

use crate::camera::{parse_camera_spec, parse_par, Camera};
use crate::hull::{auto_bounds, dims_for, visual_hull, Aabb, HullParams};
use crate::photo::{photo_hull_keeping, PhotoParams, VoxelModel};
use crate::pipeline::{
    error_map, leave_one_out_from, EvalImages, EvalReport, Others, Score, ViewParams,
};
use crate::silhouette::{mask_from_image, threshold_silhouette, Mask, SilhouetteParams};

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
    /// Thresholded silhouettes scores are measured inside
    /// ([`SilhouetteParams::scoring`]: 0.25, dilate 5, erode 5; the Middlebury recipe is 0.19,
    /// 10, 7).
    pub score: SilhouetteParams,
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
            score: SilhouetteParams::scoring(),
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
        Ok(())
    }
}

/// Photos, cameras and silhouettes of a data folder.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The camera file.
    pub par: PathBuf,
    /// The cameras, scaled.
    pub cams: Vec<Camera>,
    /// The photos, scaled; all the same size.
    pub images: Vec<RgbImage>,
    /// Silhouettes the model is carved from.
    pub masks: Vec<Mask>,
    /// Silhouettes scores are measured inside ([`DataOptions::score`] when thresholding; the
    /// same as `masks` for supplied mask images).
    pub score_masks: Vec<Mask>,
    /// Where the silhouettes came from, in words.
    pub silhouettes: String,
}

/// The one `*_par.txt` file in `dir`.
pub fn find_par(dir: &Path) -> Result<PathBuf, DataError> {
    let entries = std::fs::read_dir(dir).map_err(|e| path_err(dir, e.to_string()))?;
    let mut pars: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.ends_with("_par.txt"))
        })
        .collect();
    pars.sort();
    match pars.len() {
        0 => Err(path_err(dir, "no *_par.txt camera file in it")),
        1 => Ok(pars.remove(0)),
        _ => Err(path_err(
            dir,
            format!(
                "more than one *_par.txt camera file ({}); keep one",
                pars.iter()
                    .map(|p| p.file_name().unwrap_or_default().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
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

impl Dataset {
    /// Reads a data folder: the camera file, every image it names (checked to exist and to share
    /// one size), the silhouettes, all scaled by `opt.scale`.
    pub fn load(dir: &Path, opt: &DataOptions) -> Result<Self, DataError> {
        opt.check()?;
        if !dir.is_dir() {
            return Err(path_err(dir, "not a folder"));
        }
        let par = find_par(dir)?;
        let text = vt_io::limits::read_text(&par, vt_io::limits::MAX_TEXT_BYTES, "camera file")?;
        let cams = parse_par(&text).map_err(|cause| DataError::File {
            path: par.clone(),
            cause,
        })?;
        for (i, c) in cams.iter().enumerate() {
            let p = dir.join(&c.name);
            if !p.is_file() {
                return Err(path_err(
                    &par,
                    format!("camera {i} names image {}, which is missing", p.display()),
                ));
            }
        }
        let mask_dir = match &opt.masks {
            Some(d) if !d.is_dir() => return Err(path_err(d, "mask folder: not a folder")),
            Some(d) => Some(d.clone()),
            None => Some(dir.join("masks")).filter(|d| d.is_dir()),
        };
        let silhouettes = match &mask_dir {
            Some(d) => format!("mask images in {}", d.display()),
            None => format!(
                "photos thresholded (carving: at {}, dilate {}, erode {}; scoring: at {}, dilate {}, erode {})",
                opt.threshold,
                opt.carve_dilate,
                opt.carve_erode,
                opt.score.threshold,
                opt.score.dilate,
                opt.score.erode
            ),
        };
        let scoring = opt.score.clone();
        let carve = SilhouetteParams {
            threshold: opt.threshold,
            dilate: opt.carve_dilate,
            erode: opt.carve_erode,
        };
        let loaded: Vec<(RgbImage, Mask, Mask)> = cams
            .par_iter()
            .map(|c| {
                let path = dir.join(&c.name);
                let img = vt_io::frames::read_rgb(&path)?;
                let (mask, score) = match &mask_dir {
                    Some(d) => {
                        let m = read_mask(&d.join(&c.name), &c.name, img.dimensions(), &path)?;
                        (m.clone(), m)
                    }
                    None => (
                        threshold_silhouette(&img, &carve),
                        threshold_silhouette(&img, &scoring),
                    ),
                };
                if opt.scale == 1.0 {
                    return Ok((img, mask, score));
                }
                let (w, h) = (
                    ((img.width() as f64 * opt.scale).round() as u32).max(1),
                    ((img.height() as f64 * opt.scale).round() as u32).max(1),
                );
                let small =
                    image::imageops::resize(&img, w, h, image::imageops::FilterType::Triangle);
                Ok((small, scale_mask(&mask, w, h), scale_mask(&score, w, h)))
            })
            .collect::<Result<_, DataError>>()?;
        let mut images = Vec::with_capacity(loaded.len());
        let (mut masks, mut score_masks) = (Vec::new(), Vec::new());
        for (i, m, sm) in loaded {
            images.push(i);
            masks.push(m);
            score_masks.push(sm);
        }
        // A photo of another size in a calibrated dataset is a mistake, not a view: refuse it.
        if let Some(k) = images
            .iter()
            .position(|i| i.dimensions() != images[0].dimensions())
        {
            return Err(path_err(
                &par,
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
        let cams = if opt.scale == 1.0 {
            cams
        } else {
            cams.iter().map(|c| c.scaled(opt.scale)).collect()
        };
        Ok(Self {
            par,
            cams,
            images,
            masks,
            score_masks,
            silhouettes,
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
            let why = format!("needs at least 3 views, {} has {n}", self.par.display());
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

/// The volume a model is built in: `given`, else found from the silhouettes ([`auto_bounds`]
/// with [`HullParams::default`]).
pub fn volume(given: Option<Aabb>, cams: &[Camera], masks: &[Mask]) -> crate::Result<Aabb> {
    match given {
        Some(b) => Ok(b),
        None => auto_bounds(cams, masks, &HullParams::default()),
    }
}

/// How to build the voxel model.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelParams {
    /// Voxels along the longest side of the volume (paper: 256); voxels are cubes.
    pub grid: usize,
    /// The volume to carve; `None`: found from the silhouettes.
    pub bounds: Option<Aabb>,
    /// Photo-consistency threshold ([`PhotoParams::threshold`]).
    pub photo_threshold: f64,
    /// Carve as the paper does (no [`PhotoParams::keep_silhouettes`]).
    pub paper_carving: bool,
}

impl Default for ModelParams {
    fn default() -> Self {
        Self {
            grid: 256,
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
}

/// Writes `hull.ply` (the coloured surface voxels) and `summary.json` into `dir`.
pub fn write_hull(
    dir: &Path,
    d: &Dataset,
    model: &VoxelModel,
    photo_threshold: f64,
    build: &BuildSummary,
) -> Result<(), DataError> {
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
        cameras: d.par.display().to_string(),
        views: d.cams.len(),
        image_size: [w, h],
        silhouettes: d.silhouettes.clone(),
        photo_threshold,
        build: build.clone(),
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
            "({} surface voxels seen by no camera took the nearest seen colour)",
            s.surface_unseen
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
