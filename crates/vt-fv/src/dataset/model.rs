//! The voxel model of a data folder: its parameters, build, summary and model file.

use super::*;
use crate::stereo::StereoParams;

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
            stereo: m.stereo,
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
    /// 128, 192 and 256, and one leave-one-out takes 2.4x longer at 256 (docs/system-b.md).
    pub grid: usize,
    /// The volume to carve; `None`: found from the silhouettes.
    pub bounds: Option<Aabb>,
    /// Photo-consistency threshold ([`PhotoParams::threshold`]).
    pub photo_threshold: f64,
    /// Carve and colour as the paper does (no [`PhotoParams::keep_silhouettes`], no
    /// [`PhotoParams::colour_partly_seen`]).
    pub paper_carving: bool,
    /// Carve the visual hull by multi-view stereo before the photo hull
    /// ([`PhotoParams::stereo`]; true).
    pub stereo: bool,
    /// The stereo carving's settings ([`StereoParams::default`]).
    pub stereo_params: StereoParams,
}

impl Default for ModelParams {
    fn default() -> Self {
        Self {
            grid: 128,
            bounds: None,
            photo_threshold: PhotoParams::default().threshold,
            paper_carving: false,
            stereo: true,
            stereo_params: StereoParams::default(),
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
        if self.stereo {
            self.stereo_params.check()?;
        }
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
            stereo: self.stereo.then_some(self.stereo_params),
            ..Default::default()
        }
    }
}

/// How a model's depth maps are spaced, in words: `depth maps at every pixel` (the fine
/// iterations ran) or `depth maps every k pixels`.
pub fn depth_spacing(step: usize) -> String {
    if step == 1 {
        "depth maps at every pixel".into()
    } else {
        format!("depth maps every {step} pixels")
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
    /// Voxels the stereo carving removed before the photo hull (free space and unseen).
    pub stereo_carved: usize,
    /// Pixels between the kept depth maps' cells (1: every pixel, the fine iterations ran;
    /// `None` without stereo).
    pub depth_step: Option<usize>,
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
        stereo_carved: model.stereo.as_ref().map_or(0, |s| s.carved + s.unseen),
        depth_step: model.depths.first().map(|m| m.step),
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
        if s.stereo_carved > 0 {
            writeln!(
                f,
                "(the photo hull's time includes the stereo carving, which removed {} voxels first{})",
                s.stereo_carved,
                match s.depth_step {
                    Some(k) => format!(", from {}", depth_spacing(k)),
                    None => String::new(),
                }
            )?;
        }
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
