//! `vt fv ...`: free-viewpoint images from calibrated photos (SPEC System B): build the voxel
//! model, render new views (rough or guided), encode orbits, and score withheld views.
//!
//! Input is a folder holding one Middlebury `*_par.txt` camera file and the images it names.
//! Silhouettes come from `--masks DIR` (same-named images, non-zero = object), else from a
//! `masks/` folder inside the data folder when there is one (as `vt synth object` writes it),
//! else from thresholding the photos (the Middlebury recipe).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use image::RgbImage;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;
use vt_fv::camera::{interpolate, parse_par, Ring};
use vt_fv::hull::{auto_bounds, dims_for, grid_bytes, Aabb, HullParams};
use vt_fv::photo::{photo_hull_keeping, PhotoParams, VoxelModel};
use vt_fv::pipeline::{leave_one_out, novel_view, EvalReport, Method, ViewParams};
use vt_fv::silhouette::{mask_from_image, threshold_silhouette, SilhouetteParams};
use vt_fv::synthesis::SynthParams;
use vt_fv::{render_rough, visual_hull, Camera, Mask};
use vt_io::atomic::AtomicDir;

use crate::progress::bar;

/// Free-viewpoint commands.
#[derive(Subcommand)]
pub enum FvCommand {
    /// Build the visual hull and the photo hull; write DIR/hull.ply and DIR/summary.json.
    Hull(HullArgs),
    /// Render one new view (rough, or guided by texture synthesis) into an image file.
    Render(RenderArgs),
    /// Render views around the cameras' ring and encode them as an mp4 or gif (needs ffmpeg).
    Orbit(OrbitArgs),
    /// Leave one view out: rebuild without it, render it, and score rough and guided renders.
    Eval(EvalArgs),
}

/// Where the photos, cameras and silhouettes come from.
#[derive(Args, Clone)]
pub struct DataArgs {
    /// Folder holding one *_par.txt (Middlebury format) and the images it names.
    data: PathBuf,
    /// Folder of silhouette images named like the photos (non-zero = object). Default: DATA/masks
    /// when it exists, else threshold the photos.
    #[arg(long)]
    masks: Option<PathBuf>,
    /// Threshold silhouettes at this fraction of full scale (Middlebury: 0.19; then dilate 10 px,
    /// erode 7 px).
    #[arg(long, default_value_t = 0.19)]
    threshold: f64,
    /// Thresholded silhouettes the model is carved from: dilate by this many pixels (the
    /// Middlebury recipe's 10 px dilation then 7 px erosion closes the gaps between the
    /// temple's columns, so carving keeps them filled; scores are always measured inside the
    /// recipe's silhouettes).
    #[arg(long, default_value_t = 3)]
    carve_dilate: u32,
    /// Thresholded silhouettes the model is carved from: then erode by this many pixels.
    #[arg(long, default_value_t = 3)]
    carve_erode: u32,
    /// Scale the photos (and cameras) by this factor first, e.g. 0.5 for half size.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
}

/// How to build the voxel model.
#[derive(Args, Clone)]
pub struct ModelArgs {
    /// Voxels along the longest side of the volume (paper: 256); voxels are cubes.
    #[arg(long, default_value_t = 256)]
    grid: usize,
    /// Volume to carve, x0,y0,z0,x1,y1,z1 in world units. Default: found from the silhouettes.
    #[arg(long, value_parser = parse_bounds, allow_hyphen_values = true)]
    bounds: Option<Aabb>,
    /// Photo-consistency threshold: largest per-channel standard deviation (0..255) of a
    /// voxel's colours across the cameras that see it.
    #[arg(long, default_value_t = 20.0)]
    photo_threshold: f64,
    /// Carve as the paper does: remove every inconsistent voxel, even where that leaves part of
    /// a camera's silhouette empty (default: keep what the silhouettes prove is there).
    #[arg(long)]
    paper_carving: bool,
}

/// Guided synthesis settings.
#[derive(Args, Clone)]
pub struct SynthArgs {
    /// Patch side of the guided synthesis, odd (paper: 41; 7 is faster and scores better on
    /// our data).
    #[arg(long, default_value_t = 7)]
    patch: usize,
    /// Paper-exact synthesis: sequential scanline order, full patches, one resolution level
    /// (default: the speed options, see vt-fv's README).
    #[arg(long)]
    exact: bool,
    /// How new views are made: `textured` (default: the nearest reference photos projected
    /// onto the voxel surface, holes filled) or `paper` (guided synthesis of the rough render
    /// from the nearest photo, as in the paper).
    #[arg(long, value_enum, default_value_t = MethodArg::Textured)]
    method: MethodArg,
    /// With `--method textured`: also run guided synthesis with the textured view as guide.
    #[arg(long)]
    refine: bool,
    /// With `--method textured`: reference photos blended per pixel (nearest by direction).
    #[arg(long, default_value_t = 2)]
    references: usize,
}

/// `--method`.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// View-dependent texturing (the default).
    Textured,
    /// The paper's guided synthesis of the rough render.
    Paper,
}

/// `vt fv hull`.
#[derive(Args)]
pub struct HullArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    model: ModelArgs,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
}

/// `vt fv render`.
#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    synth: SynthArgs,
    /// The new camera: a par line `name k11..k33 r11..r33 t1 t2 t3`, `angle:DEG` (on the
    /// cameras' ring, 0 = first camera, growing towards the second) or `between:I,J,T` (between
    /// views I and J, 0-based in the par file, at T in [0, 1]).
    #[arg(long, allow_hyphen_values = true)]
    camera: String,
    /// Re-texture the rough render by guided synthesis from the nearest photo.
    #[arg(long)]
    guided: bool,
    /// Output image (.png or .jpg), written to a temporary file and renamed.
    #[arg(long)]
    out: PathBuf,
}

/// `vt fv orbit`.
#[derive(Args)]
pub struct OrbitArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    synth: SynthArgs,
    /// Frames in one turn.
    #[arg(long, default_value_t = 48)]
    frames: usize,
    /// Frames per second of the output.
    #[arg(long, default_value_t = 24)]
    fps: u32,
    /// Guided synthesis for every frame (slow) instead of rough renders.
    #[arg(long)]
    guided: bool,
    /// Output .mp4 (H.264) or .gif, written to a temporary file and renamed.
    #[arg(long)]
    out: PathBuf,
}

/// `vt fv eval`.
#[derive(Args)]
pub struct EvalArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    synth: SynthArgs,
    /// The views to withhold one at a time, 0-based in the par file: `2` or `1,2,5`.
    #[arg(long, value_delimiter = ',', required = true, num_args = 1..)]
    leave_out: Vec<usize>,
    /// Print exactly one JSON object on stdout: `rough`, `rough_blur2`, `nearest_photo`,
    /// `guide`, `guided` (each `{"psnr", "ssim"}` inside the withheld silhouette; the mean over
    /// the views when several), `silhouette_iou`, and `views` with every view's details.
    #[arg(long)]
    json: bool,
    /// Write each view's images (truth, nearest photo, rough, rough blurred, guide, result) and
    /// error maps into DIR/view_NN/ (DIR is created, or replaces a previous vt output folder).
    #[arg(long)]
    save: Option<PathBuf>,
}

/// Runs a `vt fv` command.
pub fn run(cmd: FvCommand) -> Result<()> {
    match cmd {
        FvCommand::Hull(a) => hull(a),
        FvCommand::Render(a) => render(a),
        FvCommand::Orbit(a) => orbit(a),
        FvCommand::Eval(a) => eval(a),
    }
}

fn parse_bounds(s: &str) -> Result<Aabb, String> {
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
        Vector3::new(v[0], v[1], v[2]),
        Vector3::new(v[3], v[4], v[5]),
    ))
}

impl DataArgs {
    /// The run's inputs, which no output may replace: the data folder and the masks folder.
    fn inputs(&self) -> Vec<&Path> {
        [Some(self.data.as_path()), self.masks.as_deref()]
            .into_iter()
            .flatten()
            .collect()
    }
}

/// Photos, cameras and silhouettes of a data folder.
struct Data {
    par: PathBuf,
    cams: Vec<Camera>,
    images: Vec<RgbImage>,
    /// Silhouettes the model is carved from.
    masks: Vec<Mask>,
    /// Silhouettes scores are measured inside (the Middlebury recipe when thresholding; the
    /// same as `masks` for supplied mask images).
    score_masks: Vec<Mask>,
    /// Where the silhouettes came from, for the summary.
    silhouettes: String,
}

fn find_par(dir: &Path) -> Result<PathBuf> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))?;
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
        0 => bail!("{}: no *_par.txt camera file in it", dir.display()),
        1 => Ok(pars.remove(0)),
        _ => bail!(
            "{}: more than one *_par.txt camera file ({}); keep one",
            dir.display(),
            pars.iter()
                .map(|p| p.file_name().unwrap_or_default().to_string_lossy())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Downscales a mask: a pixel is set when any full-size pixel under it is.
fn scale_mask(m: &Mask, w: u32, h: u32) -> Mask {
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
        (y0..y1.max(y0 + 1)).any(|yy| (x0..x1.max(x0 + 1)).any(|xx| m.get(xx, yy)))
    })
}

fn load(a: &DataArgs) -> Result<Data> {
    if !(a.scale > 0.0 && a.scale <= 4.0) {
        bail!("--scale {} must be in (0, 4]", a.scale);
    }
    if a.carve_dilate > 100 || a.carve_erode > 100 {
        bail!(
            "--carve-dilate {} / --carve-erode {}: at most 100 pixels",
            a.carve_dilate,
            a.carve_erode
        );
    }
    if !(0.0..1.0).contains(&a.threshold) {
        bail!("--threshold {} must be in [0, 1)", a.threshold);
    }
    if !a.data.is_dir() {
        bail!("{}: not a folder", a.data.display());
    }
    let par = find_par(&a.data)?;
    let text = vt_io::limits::read_text(&par, vt_io::limits::MAX_TEXT_BYTES, "camera file")?;
    let cams = parse_par(&text).with_context(|| par.display().to_string())?;
    for (i, c) in cams.iter().enumerate() {
        let p = a.data.join(&c.name);
        if !p.is_file() {
            bail!(
                "{}: camera {i} names image {}, which is missing",
                par.display(),
                p.display()
            );
        }
    }
    let mask_dir = match &a.masks {
        Some(d) if !d.is_dir() => bail!("--masks {}: not a folder", d.display()),
        Some(d) => Some(d.clone()),
        None => Some(a.data.join("masks")).filter(|d| d.is_dir()),
    };
    let silhouettes = match &mask_dir {
        Some(d) => format!("mask images in {}", d.display()),
        None => format!(
            "photos thresholded at {} (carving: dilate {}, erode {}; scoring: dilate 10, erode 7)",
            a.threshold, a.carve_dilate, a.carve_erode
        ),
    };
    let loaded: Vec<(RgbImage, Mask, Mask)> = cams
        .par_iter()
        .map(|c| {
            let path = a.data.join(&c.name);
            let img = vt_io::frames::read_rgb(&path)?;
            let mask = match &mask_dir {
                Some(d) => {
                    let mp = d.join(&c.name);
                    if !mp.is_file() {
                        bail!("mask {} for image {} is missing", mp.display(), c.name);
                    }
                    let m = image::open(&mp)
                        .with_context(|| mp.display().to_string())?
                        .to_luma8();
                    if m.dimensions() != img.dimensions() {
                        bail!(
                            "mask {} is {}x{} but image {} is {}x{}",
                            mp.display(),
                            m.width(),
                            m.height(),
                            path.display(),
                            img.width(),
                            img.height()
                        );
                    }
                    let m = mask_from_image(&m);
                    (m.clone(), m)
                }
                None => {
                    let recipe = SilhouetteParams {
                        threshold: a.threshold,
                        ..Default::default()
                    };
                    let carve = SilhouetteParams {
                        dilate: a.carve_dilate,
                        erode: a.carve_erode,
                        ..recipe
                    };
                    (
                        threshold_silhouette(&img, &carve),
                        threshold_silhouette(&img, &recipe),
                    )
                }
            };
            let (mask, score) = mask;
            if a.scale == 1.0 {
                return Ok((img, mask, score));
            }
            let (w, h) = (
                ((img.width() as f64 * a.scale).round() as u32).max(1),
                ((img.height() as f64 * a.scale).round() as u32).max(1),
            );
            let small = image::imageops::resize(&img, w, h, image::imageops::FilterType::Triangle);
            Ok((small, scale_mask(&mask, w, h), scale_mask(&score, w, h)))
        })
        .collect::<Result<_>>()?;
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
        bail!(
            "{}: image {} is {}x{}, but {} is {}x{} (every photo of a dataset has the same size)",
            par.display(),
            cams[k].name,
            images[k].width(),
            images[k].height(),
            cams[0].name,
            images[0].width(),
            images[0].height()
        );
    }
    let cams = if a.scale == 1.0 {
        cams
    } else {
        cams.iter().map(|c| c.scaled(a.scale)).collect()
    };
    Ok(Data {
        par,
        cams,
        images,
        masks,
        score_masks,
        silhouettes,
    })
}

/// Refuses a grid whose bit array would exceed the library's limit before loading anything.
/// Largest `--grid` (voxels per side).
const MAX_GRID: usize = 1024;

fn check_grid(m: &ModelArgs) -> Result<()> {
    if m.grid < 2 {
        bail!("--grid {} is too small (at least 2)", m.grid);
    }
    // The bit array's limit alone lets 1600^3 through, whose photo hull then asks for GiBs of
    // voxel indices: the working memory is bounded by the side too.
    if m.grid > MAX_GRID {
        bail!(
            "--grid {} is more than {MAX_GRID} voxels per side (the photo hull's working memory grows with the cube of it; refused before allocating)",
            m.grid
        );
    }
    let limit = HullParams::default().max_bytes;
    grid_bytes([m.grid; 3], limit)
        .map_err(|e| anyhow!("--grid {}: {e} (refused before allocating)", m.grid))?;
    if !(m.photo_threshold.is_finite() && (0.0..=255.0).contains(&m.photo_threshold)) {
        bail!(
            "--photo-threshold {} must be a number in [0, 255] (grey levels)",
            vt_io::output::num(m.photo_threshold)
        );
    }
    Ok(())
}

/// Timings and counts of a model build.
#[derive(Serialize, Clone)]
struct BuildSummary {
    grid: [usize; 3],
    bounds_min: [f64; 3],
    bounds_max: [f64; 3],
    visual_hull_voxels: usize,
    visual_hull_secs: f64,
    photo_hull_voxels: usize,
    photo_hull_passes: usize,
    photo_hull_removed: usize,
    photo_hull_secs: f64,
    surface_voxels: usize,
    surface_unseen: usize,
}

/// Visual hull then photo hull, with progress; `bounds` given or found from the silhouettes.
fn build(
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    m: &ModelArgs,
    what: &str,
) -> Result<(VoxelModel, BuildSummary)> {
    let hp = HullParams::default();
    let bounds = match m.bounds {
        Some(b) => b,
        None => auto_bounds(cams, masks, &hp).with_context(|| format!("{what}: volume bounds"))?,
    };
    let dims = dims_for(&bounds, m.grid);
    let t = Instant::now();
    let pb = bar(1, "visual hull");
    let grid = visual_hull(
        cams,
        masks,
        &HullParams {
            dims,
            bounds: Some(bounds),
            ..hp
        },
    )
    .with_context(|| format!("{what}: visual hull"))?;
    pb.finish_and_clear();
    let vh_secs = t.elapsed().as_secs_f64();
    let vh_voxels = grid.count();
    let params = PhotoParams {
        threshold: m.photo_threshold,
        keep_silhouettes: !m.paper_carving,
        ..Default::default()
    };
    let t = Instant::now();
    let pb = bar(params.max_passes as u64, "photo hull passes");
    let model = photo_hull_keeping(
        grid,
        cams,
        images,
        Some(masks),
        &params,
        &mut |_, done, _| pb.set_position(done),
    )
    .with_context(|| format!("{what}: photo hull"))?;
    pb.finish_and_clear();
    let summary = BuildSummary {
        grid: dims,
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

/// `hull.ply` and `summary.json` contents.
#[derive(Serialize)]
struct HullSummary {
    format: &'static str,
    version: u32,
    cameras: String,
    views: usize,
    image_size: [u32; 2],
    silhouettes: String,
    photo_threshold: f64,
    #[serde(flatten)]
    build: BuildSummary,
}

fn hull(a: HullArgs) -> Result<()> {
    check_grid(&a.model)?;
    // The output is checked before any work: never the data folder, never a foreign path.
    let dir =
        vt_io::output::Output::dir(&a.out, vt_io::output::OutputKind::Hull, &a.data.inputs())?;
    let d = load(&a.data)?;
    let (model, s) = build(
        &d.cams,
        &d.images,
        &d.masks,
        &a.model,
        &a.data.data.display().to_string(),
    )?;
    let ply = dir.path().join("hull.ply");
    {
        let f = std::fs::File::create(&ply).with_context(|| ply.display().to_string())?;
        let mut w = std::io::BufWriter::new(f);
        model
            .to_ply(&mut w)
            .and_then(|_| w.flush())
            .with_context(|| ply.display().to_string())?;
    }
    let summary = HullSummary {
        format: "vt-fv-hull",
        version: 1,
        cameras: d.par.display().to_string(),
        views: d.cams.len(),
        image_size: [d.images[0].width(), d.images[0].height()],
        silhouettes: d.silhouettes.clone(),
        photo_threshold: a.model.photo_threshold,
        build: s.clone(),
    };
    std::fs::write(
        dir.path().join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )
    .context("summary.json")?;
    dir.commit()?;
    println!(
        "{} views {}x{}, grid {}x{}x{}, silhouettes from {}",
        d.cams.len(),
        d.images[0].width(),
        d.images[0].height(),
        s.grid[0],
        s.grid[1],
        s.grid[2],
        d.silhouettes
    );
    println!(
        "{:<14} {:>12} {:>7} {:>9}",
        "stage", "voxels", "passes", "time"
    );
    println!(
        "{:<14} {:>12} {:>7} {:>7.2} s",
        "visual hull", s.visual_hull_voxels, "-", s.visual_hull_secs
    );
    println!(
        "{:<14} {:>12} {:>7} {:>7.2} s",
        "photo hull", s.photo_hull_voxels, s.photo_hull_passes, s.photo_hull_secs
    );
    println!(
        "{:<14} {:>12} {:>7} {:>9}",
        "surface", s.surface_voxels, "-", "-"
    );
    println!(
        "({} surface voxels seen by no camera took the nearest seen colour)",
        s.surface_unseen
    );
    println!("wrote {}/hull.ply and summary.json", a.out.display());
    Ok(())
}

/// Centroid of the model's surface voxels (where new cameras look).
fn model_centre(model: &VoxelModel) -> Vector3<f64> {
    let n = model.surface.len().max(1) as f64;
    model
        .surface
        .iter()
        .map(|v| model.centre(v))
        .sum::<Vector3<f64>>()
        / n
}

/// A new camera from `--camera`; `target` is where ring cameras look.
fn parse_camera(spec: &str, cams: &[Camera], scale: f64, target: &Vector3<f64>) -> Result<Camera> {
    let spec = spec.trim();
    if let Some(deg) = spec.strip_prefix("angle:") {
        let deg: f64 = deg
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| anyhow!("--camera {spec:?}: angle {deg:?} is not a number"))?;
        let ring = Ring::fit(cams).with_context(|| format!("--camera {spec:?}"))?;
        return ring
            .camera(deg, target)
            .with_context(|| format!("--camera {spec:?}"));
    }
    if let Some(rest) = spec.strip_prefix("between:") {
        let f: Vec<&str> = rest.split(',').map(str::trim).collect();
        if f.len() != 3 {
            bail!("--camera {spec:?}: expected between:I,J,T");
        }
        let idx = |s: &str| -> Result<usize> {
            let i: usize = s
                .parse()
                .map_err(|_| anyhow!("--camera {spec:?}: view {s:?} is not a whole number"))?;
            if i >= cams.len() {
                bail!(
                    "--camera {spec:?}: view {i} does not exist ({} views, 0-based)",
                    cams.len()
                );
            }
            Ok(i)
        };
        let (i, j) = (idx(f[0])?, idx(f[1])?);
        let t: f64 = f[2]
            .parse()
            .ok()
            .filter(|t| (0.0..=1.0).contains(t))
            .ok_or_else(|| anyhow!("--camera {spec:?}: T {:?} is not in [0, 1]", f[2]))?;
        return interpolate(&cams[i], &cams[j], t).with_context(|| format!("--camera {spec:?}"));
    }
    let cam = parse_par(&format!("1\n{spec}\n"))
        .map_err(|e| {
            // The spec is line 2 of the wrapped text; report it as the flag's value.
            let msg = e.to_string();
            anyhow!(
                "--camera par line: {}",
                msg.strip_prefix("camera file line 2: ").unwrap_or(&msg)
            )
        })?
        .remove(0);
    Ok(if scale == 1.0 { cam } else { cam.scaled(scale) })
}

fn synth_params(s: &SynthArgs, w: u32, h: u32) -> Result<SynthParams> {
    if s.patch.is_multiple_of(2) || s.patch < 3 {
        bail!("--patch {} must be odd and at least 3", s.patch);
    }
    if s.patch as u32 > w.min(h) {
        bail!(
            "--patch {} is larger than the {w}x{h} reference photos",
            s.patch
        );
    }
    let p = SynthParams {
        patch: s.patch,
        ..Default::default()
    };
    Ok(if s.exact {
        p
    } else {
        vt_fv::synthesis::SynthParams::fast_for(s.patch)
    })
}

/// Checks that an output folder's parent exists (the output itself is checked by vt-io).
fn temp_sibling(out: &Path) -> Result<PathBuf> {
    let name = out
        .file_name()
        .ok_or_else(|| anyhow!("{}: output has no file name", out.display()))?
        .to_string_lossy()
        .to_string();
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !parent.is_dir() {
        bail!("{}: output folder does not exist", parent.display());
    }
    Ok(parent.join(format!(".{name}.tmp-{}", std::process::id())))
}

fn check_image_ext(out: &Path) -> Result<()> {
    match image::ImageFormat::from_path(out) {
        Ok(image::ImageFormat::Png | image::ImageFormat::Jpeg) => Ok(()),
        _ => bail!("--out {}: use a .png or .jpg file name", out.display()),
    }
}

/// The volume a model will be built in (given, or found from the silhouettes).
fn volume(d: &Data, m: &ModelArgs) -> Result<Aabb> {
    match m.bounds {
        Some(b) => Ok(b),
        None => auto_bounds(&d.cams, &d.masks, &HullParams::default())
            .context("volume bounds from the silhouettes"),
    }
}

fn render(a: RenderArgs) -> Result<()> {
    check_grid(&a.model)?;
    check_image_ext(&a.out)?;
    // Checked before any work (nothing is created yet).
    drop(vt_io::output::Output::file(
        &a.out,
        vt_io::output::OutputKind::Image,
        &a.data.inputs(),
    )?);
    let d = load(&a.data)?;
    let (w, h) = d.images[0].dimensions();
    let view = view_params(&a.synth, w, h)?;
    // Check the camera against the volume before the expensive model build.
    let bounds = volume(&d, &a.model)?;
    let cam = parse_camera(&a.camera, &d.cams, a.data.scale, &bounds.centre())?;
    if !vt_fv::hull::sees_box(&cam, &bounds, w, h) {
        bail!(
            "--camera {}: camera sees none of the volume {:?}..{:?}",
            cam.name,
            <[f64; 3]>::from(bounds.min),
            <[f64; 3]>::from(bounds.max)
        );
    }
    let model_args = ModelArgs {
        bounds: Some(bounds),
        ..a.model.clone()
    };
    let (model, s) = build(
        &d.cams,
        &d.images,
        &d.masks,
        &model_args,
        &a.data.data.display().to_string(),
    )?;
    // Ring cameras look at the model's centre, now that it is known.
    let cam = if a.camera.trim().starts_with("angle:") {
        parse_camera(&a.camera, &d.cams, a.data.scale, &model_centre(&model))?
    } else {
        cam
    };
    let t = Instant::now();
    let (img, what) = if a.guided {
        let pb = bar(1, "guided synthesis");
        let v = novel_view(&model, &d.cams, &d.images, &cam, w, h, &view)
            .context("guided synthesis")?;
        pb.finish_and_clear();
        if v.rough.coverage.count() == 0 {
            bail!("--camera {}: camera sees none of the model", cam.name);
        }
        (
            v.guided,
            match view.method {
                Method::Paper => format!(
                    "guided (paper) from {} (patch {})",
                    d.cams[v.reference].name, view.synth.patch
                ),
                Method::Textured => format!(
                    "textured from {} and its {} nearest{}",
                    d.cams[v.reference].name,
                    view.texture.references.saturating_sub(1),
                    if view.refine {
                        ", refined by synthesis"
                    } else {
                        ""
                    }
                ),
            },
        )
    } else {
        let r = render_rough(&model, &cam, w, h);
        if r.coverage.count() == 0 {
            bail!("--camera {}: camera sees none of the model", cam.name);
        }
        (r.image, "rough".to_string())
    };
    let render_secs = t.elapsed().as_secs_f64();
    vt_io::writer::write_image(&a.out, &a.data.inputs(), &img)?;
    println!(
        "model: {} surface voxels ({} passes) in {:.2} s; {what} render in {:.2} s",
        s.surface_voxels,
        s.photo_hull_passes,
        s.visual_hull_secs + s.photo_hull_secs,
        render_secs
    );
    println!("wrote {} ({w}x{h})", a.out.display());
    Ok(())
}

fn orbit(a: OrbitArgs) -> Result<()> {
    check_grid(&a.model)?;
    let ext = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("mp4" | "gif")) {
        bail!("--out {}: use a .mp4 or .gif file name", a.out.display());
    }
    if a.frames == 0 || a.frames > 10_000 {
        bail!("--frames {} must be in 1..=10000", a.frames);
    }
    if a.fps == 0 || a.fps > 240 {
        bail!("--fps {} must be in 1..=240", a.fps);
    }
    // Checked before any work (nothing is created yet).
    drop(vt_io::output::Output::file(
        &a.out,
        vt_io::output::OutputKind::Video,
        &a.data.inputs(),
    )?);
    let d = load(&a.data)?;
    let (w, h) = d.images[0].dimensions();
    let view = view_params(&a.synth, w, h)?;
    let ring = Ring::fit(&d.cams).context("orbit: the cameras' ring")?;
    let (model, _) = build(
        &d.cams,
        &d.images,
        &d.masks,
        &a.model,
        &a.data.data.display().to_string(),
    )?;
    let target = model_centre(&model);
    // vt-io's one video writer: H.264 at CRF 18 (or GIF), marked as vt's, atomic.
    let mut video =
        vt_io::writer::VideoWriter::create(&a.out, &a.data.inputs(), w, h, a.fps as f64)?;
    let pb = bar(a.frames as u64, "orbit frames");
    for i in 0..a.frames {
        let angle = 360.0 * i as f64 / a.frames as f64;
        let cam = ring.camera(angle, &target)?;
        let img = if a.guided {
            novel_view(&model, &d.cams, &d.images, &cam, w, h, &view)
                .with_context(|| format!("frame {i} (angle {angle:.1})"))?
                .guided
        } else {
            render_rough(&model, &cam, w, h).image
        };
        video.write(&img)?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    video.finish()?;
    println!(
        "wrote {} ({} frames, {w}x{h}, {} fps, {})",
        a.out.display(),
        a.frames,
        a.fps,
        if a.guided { "guided" } else { "rough" }
    );
    Ok(())
}

/// PSNR and SSIM of one image.
#[derive(Serialize, Clone, Copy)]
struct ScoreJson {
    psnr: f64,
    ssim: f64,
}

impl From<vt_fv::pipeline::Score> for ScoreJson {
    fn from(s: vt_fv::pipeline::Score) -> Self {
        Self {
            psnr: s.psnr,
            ssim: s.ssim,
        }
    }
}

/// One withheld view in `vt fv eval --json`.
#[derive(Serialize)]
struct ViewJson {
    withheld: usize,
    name: String,
    reference: usize,
    rough: ScoreJson,
    rough_blur2: ScoreJson,
    nearest_photo: ScoreJson,
    guide: ScoreJson,
    guided: ScoreJson,
    /// The same five over the whole image.
    whole: std::collections::BTreeMap<&'static str, ScoreJson>,
    silhouette_iou: f64,
    surface_voxels: usize,
    /// Seconds per stage.
    secs: std::collections::BTreeMap<&'static str, f64>,
    total_secs: f64,
}

/// `vt fv eval --json` output: means over the withheld views inside their silhouettes, and
/// every view.
#[derive(Serialize)]
struct EvalJson {
    method: &'static str,
    rough: ScoreJson,
    rough_blur2: ScoreJson,
    nearest_photo: ScoreJson,
    guide: ScoreJson,
    guided: ScoreJson,
    silhouette_iou: f64,
    views: Vec<ViewJson>,
}

/// The named candidates of a report, in table order.
fn candidates(r: &EvalReport) -> [(&'static str, vt_fv::pipeline::Scores); 5] {
    [
        ("nearest_photo", r.nearest_photo),
        ("rough", r.rough),
        ("rough_blur2", r.rough_blur2),
        ("guide", r.guide),
        ("guided", r.guided),
    ]
}

fn view_json(r: &EvalReport, name: &str) -> ViewJson {
    ViewJson {
        withheld: r.withheld,
        name: name.to_string(),
        reference: r.reference,
        rough: r.rough.inside.into(),
        rough_blur2: r.rough_blur2.inside.into(),
        nearest_photo: r.nearest_photo.inside.into(),
        guide: r.guide.inside.into(),
        guided: r.guided.inside.into(),
        whole: candidates(r)
            .iter()
            .map(|(n, s)| (*n, s.whole.into()))
            .collect(),
        silhouette_iou: r.silhouette_iou,
        surface_voxels: r.surface_voxels,
        secs: r.times.iter().copied().collect(),
        total_secs: r.times.iter().map(|t| t.1).sum(),
    }
}

/// The method's settings from the flags.
fn view_params(s: &SynthArgs, w: u32, h: u32) -> Result<ViewParams> {
    let synth = synth_params(s, w, h)?;
    if s.references == 0 || s.references > 64 {
        bail!("--references {} must be in 1..=64", s.references);
    }
    if s.refine && s.method == MethodArg::Paper {
        bail!("--refine applies to --method textured only");
    }
    Ok(match s.method {
        MethodArg::Paper => ViewParams::paper(synth),
        MethodArg::Textured => {
            let mut p = ViewParams {
                method: Method::Textured,
                synth,
                refine: s.refine,
                ..ViewParams::default()
            };
            p.texture.references = s.references;
            p
        }
    })
}

fn eval(a: EvalArgs) -> Result<()> {
    check_grid(&a.model)?;
    let d = load(&a.data)?;
    let n = d.cams.len();
    if n < 3 {
        bail!(
            "--leave-out needs at least 3 views, {} has {n}",
            d.par.display()
        );
    }
    for &k in &a.leave_out {
        if k >= n {
            bail!(
                "--leave-out {k}: there are {n} views (0-based, 0..{})",
                n.saturating_sub(1)
            );
        }
    }
    if let Some(dir) = &a.save {
        if dir.exists() && !dir.is_dir() {
            bail!("--save {}: exists and is not a folder", dir.display());
        }
        temp_sibling(dir)?;
    }
    let (w, h) = d.images[a.leave_out[0]].dimensions();
    let view = view_params(&a.synth, w, h)?;
    let save = a.save.as_deref().map(AtomicDir::create).transpose()?;
    let pb = bar(a.leave_out.len() as u64, "leave one out");
    let mut reports = Vec::new();
    for &k in &a.leave_out {
        let keep: Vec<usize> = (0..n).filter(|&i| i != k).collect();
        let sub_cams: Vec<Camera> = keep.iter().map(|&i| d.cams[i].clone()).collect();
        let sub_masks: Vec<Mask> = keep.iter().map(|&i| d.masks[i].clone()).collect();
        let t = Instant::now();
        let bounds = match a.model.bounds {
            Some(b) => b,
            None => auto_bounds(&sub_cams, &sub_masks, &HullParams::default())
                .context("volume bounds from the silhouettes")?,
        };
        let bounds_secs = t.elapsed().as_secs_f64();
        let hull = HullParams {
            dims: dims_for(&bounds, a.model.grid),
            bounds: Some(bounds),
            ..Default::default()
        };
        let photo = PhotoParams {
            threshold: a.model.photo_threshold,
            keep_silhouettes: !a.model.paper_carving,
            ..Default::default()
        };
        // The model is carved from the other views' silhouettes; view k is scored inside its
        // scoring silhouette.
        let mut masks = d.masks.clone();
        masks[k] = d.score_masks[k].clone();
        let (mut r, imgs) = leave_one_out(&d.cams, &d.images, &masks, k, &hull, &photo, &view)
            .with_context(|| format!("leaving out view {k} ({})", d.cams[k].name))?;
        r.times.insert(0, ("bounds", bounds_secs));
        if let Some(dir) = &save {
            let sub = dir.path().join(format!("view_{k:02}"));
            std::fs::create_dir(&sub).with_context(|| sub.display().to_string())?;
            let mask = &d.score_masks[k];
            let files = [
                ("truth.png", imgs.truth.clone()),
                ("nearest_photo.png", imgs.nearest_photo.clone()),
                ("rough.png", imgs.rough.clone()),
                ("rough_blur2.png", imgs.rough_blur2.clone()),
                ("guide.png", imgs.guide.clone()),
                ("guided.png", imgs.guided.clone()),
                (
                    "rough_error.png",
                    vt_fv::pipeline::error_map(&imgs.rough, &imgs.truth, mask),
                ),
                (
                    "rough_blur2_error.png",
                    vt_fv::pipeline::error_map(&imgs.rough_blur2, &imgs.truth, mask),
                ),
                (
                    "guided_error.png",
                    vt_fv::pipeline::error_map(&imgs.guided, &imgs.truth, mask),
                ),
            ];
            for (name, img) in files {
                let p = sub.join(name);
                img.save(&p).with_context(|| p.display().to_string())?;
            }
            let p = sub.join("silhouette.png");
            mask.to_image()
                .save(&p)
                .with_context(|| p.display().to_string())?;
        }
        reports.push(r);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let views: Vec<ViewJson> = reports
        .iter()
        .map(|r| view_json(r, &d.cams[r.withheld].name))
        .collect();
    if let Some(dir) = save {
        std::fs::write(
            dir.path().join("eval.json"),
            serde_json::to_string_pretty(&views)?,
        )
        .context("eval.json")?;
        dir.commit()?;
    }
    let method = match (view.method, view.refine) {
        (Method::Paper, _) => "paper",
        (Method::Textured, false) => "textured",
        (Method::Textured, true) => "textured+synthesis",
    };
    let nv = reports.len() as f64;
    let mean = |f: &dyn Fn(&EvalReport) -> vt_fv::pipeline::Score| ScoreJson {
        psnr: reports.iter().map(|r| f(r).psnr).sum::<f64>() / nv,
        ssim: reports.iter().map(|r| f(r).ssim).sum::<f64>() / nv,
    };
    if a.json {
        let j = EvalJson {
            method,
            rough: mean(&|r| r.rough.inside),
            rough_blur2: mean(&|r| r.rough_blur2.inside),
            nearest_photo: mean(&|r| r.nearest_photo.inside),
            guide: mean(&|r| r.guide.inside),
            guided: mean(&|r| r.guided.inside),
            silhouette_iou: reports.iter().map(|r| r.silhouette_iou).sum::<f64>() / nv,
            views,
        };
        println!("{}", serde_json::to_string(&j)?);
        return Ok(());
    }
    for r in &reports {
        println!(
            "withheld view {} ({}); nearest photo view {} ({}); method {method}",
            r.withheld, d.cams[r.withheld].name, r.reference, d.cams[r.reference].name
        );
        println!(
            "{:<14} {:>10} {:>8} {:>10} {:>8}",
            "image", "PSNR in", "SSIM in", "PSNR all", "SSIM all"
        );
        for (name, s) in candidates(r) {
            println!(
                "{:<14} {:>10.2} {:>8.3} {:>10.2} {:>8.3}",
                name, s.inside.psnr, s.inside.ssim, s.whole.psnr, s.whole.ssim
            );
        }
        println!(
            "silhouette IoU (rough render vs withheld photo) {:.3}; {} surface voxels",
            r.silhouette_iou, r.surface_voxels
        );
        let total: f64 = r.times.iter().map(|t| t.1).sum();
        let stages: Vec<String> = r.times.iter().map(|(n, s)| format!("{n} {s:.2}")).collect();
        println!("seconds: {} (total {total:.2})\n", stages.join(", "));
    }
    if reports.len() > 1 {
        println!(
            "mean over {} views, inside the silhouettes: PSNR dB / SSIM",
            reports.len()
        );
        for (name, f) in [
            (
                "nearest_photo",
                &(|r: &EvalReport| r.nearest_photo.inside) as &dyn Fn(&EvalReport) -> _,
            ),
            ("rough", &|r: &EvalReport| r.rough.inside),
            ("rough_blur2", &|r: &EvalReport| r.rough_blur2.inside),
            ("guide", &|r: &EvalReport| r.guide.inside),
            ("guided", &|r: &EvalReport| r.guided.inside),
        ] {
            let m = mean(f);
            println!("{name:<14} {:>10.2} {:>8.3}", m.psnr, m.ssim);
        }
        println!(
            "silhouette IoU {:.3}",
            reports.iter().map(|r| r.silhouette_iou).sum::<f64>() / nv
        );
    }
    Ok(())
}
