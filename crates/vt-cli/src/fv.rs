//! `vt fv ...`: free-viewpoint images from calibrated photos (SPEC System B): build the voxel
//! model, render new views (textured by default, `--method rough` or `paper`), encode orbits, and
//! score withheld views.
//!
//! Input is a folder holding the photos and their cameras: a Middlebury `*_par.txt`, a COLMAP
//! sparse model (text or binary, in the folder, `sparse/` or `sparse/0/`; photos in `images/`)
//! or a `cameras/` folder of 3x4 projection matrices (`vt_fv::dataset::find_cameras`).
//! Silhouettes come from `--masks DIR` (same-named images, non-zero = object), else from a
//! `masks/` folder inside the data folder when there is one (as `vt synth object` writes it),
//! else from thresholding the photos (the Middlebury recipe).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use vt_fv::camera::Ring;
use vt_fv::dataset::{
    parse_bounds, read_model, write_eval_images, write_hull, write_json, BuildSummary, DataOptions,
    Dataset, EvalSummary, ModelParams,
};
use vt_fv::hull::Aabb;
use vt_fv::modelfile::ModelHeader;
use vt_fv::pipeline::{novel_view_in, Method, ViewOptions, ViewParams};
use vt_fv::texture::model_centre;
use vt_fv::VoxelModel;
use vt_io::output::{Output, OutputKind};

use crate::progress::{bar, StageBars};

/// Free-viewpoint commands.
#[derive(Subcommand)]
pub enum FvCommand {
    /// Build the visual hull and the photo hull; write DIR/model.vtfv (for --model),
    /// DIR/hull.ply and DIR/summary.json.
    Hull(HullArgs),
    /// Render one new view (textured by default; --method rough|paper) into an image file.
    Render(RenderArgs),
    /// Views around the cameras' ring (made by --method, textured by default), encoded as an mp4 or gif (needs ffmpeg).
    Orbit(OrbitArgs),
    /// Leave one view out: rebuild without it, make it by --method, and score it and the baselines.
    Eval(EvalArgs),
}

/// Where the photos, cameras and silhouettes come from.
#[derive(Args, Clone)]
pub struct DataArgs {
    /// Folder holding the photos and their cameras: one *_par.txt (Middlebury), a COLMAP model
    /// (cameras.txt + images.txt or cameras.bin + images.bin, here or in sparse/ or sparse/0/,
    /// photos in images/), or a cameras/ folder with a 3x4 projection matrix per photo
    /// (<photo stem>.txt, photos in images/ or beside cameras/).
    data: PathBuf,
    /// Folder of silhouette images named like the photos (non-zero = object). Default: DATA/masks
    /// when it exists, else threshold the photos.
    #[arg(long)]
    masks: Option<PathBuf>,
    /// Without mask images: `auto` (a photo's alpha channel when it has transparency; else the
    /// dark-backdrop threshold when the photo's border is dark, else automatic segmentation
    /// from a plain backdrop of any colour, estimated from the border), `threshold` (always the
    /// dark-backdrop threshold) or `backdrop` (always the plain-backdrop segmentation).
    #[arg(long, value_enum, default_value_t = SilhouettesArg::Auto)]
    silhouettes: SilhouettesArg,
    /// Threshold the silhouettes the model is carved from at this fraction of full scale
    /// (Middlebury: 0.19).
    #[arg(long, default_value_t = 0.19)]
    threshold: f64,
    /// Thresholded silhouettes the model is carved from: dilate by this many pixels (the
    /// Middlebury recipe's 10 px dilation then 7 px erosion closes the gaps between the
    /// temple's columns, so carving keeps them filled).
    #[arg(long, default_value_t = 3)]
    carve_dilate: u32,
    /// Thresholded silhouettes the model is carved from: then erode by this many pixels.
    #[arg(long, default_value_t = 3)]
    carve_erode: u32,
    /// Scale the photos (and cameras) by this factor first, e.g. 0.5 for half size.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// COLMAP photos whose size differs from their camera's recorded size: `scale` (resized
    /// after calibration: intrinsics scaled; the two axes must agree within 0.5%) or `crop`
    /// (centred crops of the recorded frame: principal point moved).
    #[arg(long, value_enum, default_value_t = PhotoFitArg::Scale)]
    photo_fit: PhotoFitArg,
    /// Thresholded silhouettes scores are measured inside (eval): threshold as a fraction of
    /// full scale (0.25 leaves out the temple's lit background cloth, which 0.19 takes in; the
    /// Middlebury recipe is 0.19 with dilate 10, erode 7).
    #[arg(long, default_value_t = 0.25)]
    score_threshold: f64,
    /// Scoring silhouettes: dilate by this many pixels.
    #[arg(long, default_value_t = 5)]
    score_dilate: u32,
    /// Scoring silhouettes: then erode by this many pixels.
    #[arg(long, default_value_t = 5)]
    score_erode: u32,
}

/// How to build the voxel model.
#[derive(Args, Clone)]
pub struct ModelArgs {
    /// Voxels along the longest side of the volume (paper: 256); voxels are cubes. 128 is
    /// measured best under the time budget: on templeSparseRing the result scores the same at
    /// 128, 192 and 256 and one leave-one-out takes 2.4x longer at 256 (vt-fv's README).
    #[arg(long, default_value_t = ModelParams::default().grid)]
    grid: usize,
    /// Volume to carve, x0,y0,z0,x1,y1,z1 in world units. Default: found from the silhouettes.
    #[arg(long, value_parser = parse_bounds, allow_hyphen_values = true)]
    bounds: Option<Aabb>,
    /// Photo-consistency threshold: largest per-channel standard deviation (0..255) of a
    /// voxel's colours across the cameras that see it (vt-fv's default).
    #[arg(long, default_value_t = vt_fv::PhotoParams::default().threshold)]
    photo_threshold: f64,
    /// Carve as the paper does: remove every inconsistent voxel, even where that leaves part of
    /// a camera's silhouette empty (default: keep what the silhouettes prove is there).
    #[arg(long)]
    paper_carving: bool,
}

/// Guided synthesis settings.
#[derive(Args, Clone)]
pub struct ViewArgs {
    /// Patch side of the guided synthesis, odd (paper: 41; 7 is faster and scores better on
    /// our data).
    #[arg(long, default_value_t = 7)]
    patch: usize,
    /// Paper-exact synthesis: sequential scanline order, full patches, one resolution level
    /// (default: the speed options, see vt-fv's README).
    #[arg(long)]
    exact: bool,
    /// How new views are made, the same for render, orbit and eval: `textured` (default, the
    /// best measured: the nearest reference photos projected onto the voxel surface, blended,
    /// trimmed to the silhouettes), `rough` (the voxel model's own colours: blocky) or `paper`
    /// (guided synthesis of the rough render from the nearest photo, as in the paper).
    #[arg(long, value_enum, default_value_t = MethodArg::Textured)]
    method: MethodArg,
    /// Accepted for old scripts: the textured view it asked for is the default now (`--method
    /// rough` gives the voxel render).
    #[arg(long, hide = true)]
    guided: bool,
    /// With `--method textured`: also run guided synthesis with the textured view as guide.
    #[arg(long)]
    refine: bool,
    /// With `--method textured`: reference photos blended per pixel (nearest by direction).
    #[arg(long, default_value_t = 2)]
    references: usize,
}

/// `--photo-fit`.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PhotoFitArg {
    /// Resized photos: intrinsics scaled.
    Scale,
    /// Centred crops: principal point moved.
    Crop,
}

/// `--silhouettes`.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SilhouettesArg {
    /// Alpha channel, else dark threshold or plain-backdrop segmentation by the border.
    Auto,
    /// The dark-backdrop threshold.
    Threshold,
    /// The plain-backdrop segmentation.
    Backdrop,
}

/// `--method`.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// View-dependent texturing (the default).
    Textured,
    /// The rough render: the voxel model's colours.
    Rough,
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
    /// Build the model without this view (0-based in camera order), for `vt fv eval
    /// --leave-out I --model DIR/model.vtfv`.
    #[arg(long, value_name = "I")]
    leave_out: Option<usize>,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
}

/// A model written by `vt fv hull`, used instead of carving again.
#[derive(Args, Clone)]
pub struct ModelFileArgs {
    /// Use this model (`vt fv hull`'s DIR/model.vtfv, or DIR) instead of building one: it must
    /// come from the same data folder loaded the same way (cameras, photos and silhouettes are
    /// checked by fingerprint).
    #[arg(
        long = "model",
        value_name = "FILE",
        conflicts_with_all = ["grid", "bounds", "photo_threshold", "paper_carving"]
    )]
    file: Option<PathBuf>,
}

/// `vt fv render`.
#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    from: ModelFileArgs,
    #[command(flatten)]
    view: ViewArgs,
    /// The new camera: a par line `name k11..k33 r11..r33 t1 t2 t3`, `angle:DEG` (on the
    /// cameras' ring, 0 = first camera, growing towards the second) or `between:I,J,T` (between
    /// views I and J, 0-based in camera order (the par file's lines, COLMAP's image ids, the matrix files' names), at T in [0, 1]).
    #[arg(long, allow_hyphen_values = true)]
    camera: String,
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
    from: ModelFileArgs,
    #[command(flatten)]
    view: ViewArgs,
    /// Frames in one turn.
    #[arg(long, default_value_t = 48)]
    frames: usize,
    /// Frames per second of the output.
    #[arg(long, default_value_t = 24)]
    fps: u32,
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
    from: ModelFileArgs,
    #[command(flatten)]
    view: ViewArgs,
    /// The views to withhold one at a time, 0-based in camera order (the par file's lines,
    /// COLMAP's image ids, the matrix files' names): `2` or `1,2,5`.
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

/// A parameter error as the flag's: `--carve-dilate 200: at most 100 pixels`.
fn flag(e: vt_fv::Error) -> anyhow::Error {
    match e {
        vt_fv::Error::BadParam { name, value, why } => {
            let value = if value.is_empty() {
                value
            } else {
                format!(" {value}")
            };
            anyhow!("--{}{value}: {why}", name.replace('_', "-"))
        }
        e => e.into(),
    }
}

impl DataArgs {
    /// The run's inputs, which no output may replace: the data folder and the masks folder.
    fn inputs(&self) -> Vec<&Path> {
        [Some(self.data.as_path()), self.masks.as_deref()]
            .into_iter()
            .flatten()
            .collect()
    }

    /// Checks the flags, then loads the data folder.
    fn load(&self) -> Result<Dataset> {
        let opt = DataOptions {
            masks: self.masks.clone(),
            threshold: self.threshold,
            carve_dilate: self.carve_dilate,
            carve_erode: self.carve_erode,
            scale: self.scale,
            fit: match self.photo_fit {
                PhotoFitArg::Scale => vt_fv::dataset::PhotoFit::Scale,
                PhotoFitArg::Crop => vt_fv::dataset::PhotoFit::Crop,
            },
            score: vt_fv::silhouette::SilhouetteParams {
                threshold: self.score_threshold,
                dilate: self.score_dilate,
                erode: self.score_erode,
            },
            silhouettes: match self.silhouettes {
                SilhouettesArg::Auto => vt_fv::dataset::SilhouetteMode::Auto,
                SilhouettesArg::Threshold => vt_fv::dataset::SilhouetteMode::Threshold,
                SilhouettesArg::Backdrop => vt_fv::dataset::SilhouetteMode::Backdrop,
            },
            backdrop: Default::default(),
        };
        opt.check().map_err(flag)?;
        if let Some(d) = self.masks.as_ref().filter(|d| !d.is_dir()) {
            bail!("--masks {}: not a folder", d.display());
        }
        let d = Dataset::load(&self.data, &opt)?;
        // On stderr, so that `eval --json` prints exactly one JSON object on stdout.
        for n in &d.notes {
            eprintln!("{n}");
        }
        Ok(d)
    }
}

impl ModelArgs {
    /// The checked settings (a grid too large is refused before anything is loaded).
    fn params(&self) -> Result<ModelParams> {
        let p = ModelParams {
            grid: self.grid,
            bounds: self.bounds,
            photo_threshold: self.photo_threshold,
            paper_carving: self.paper_carving,
        };
        p.check().map_err(flag)?;
        Ok(p)
    }
}

impl ViewArgs {
    /// The checked new-view settings for `w x h` photos.
    fn params(&self, w: u32, h: u32) -> Result<ViewParams> {
        let method = match self.method {
            MethodArg::Paper => Method::Paper,
            MethodArg::Textured => Method::Textured,
            MethodArg::Rough => Method::Rough,
        };
        if self.guided {
            if method == Method::Rough {
                bail!("--guided and --method rough: --guided asked for the textured view, which is the default now; drop --guided");
            }
            eprintln!("--guided: the textured view is the default now; the flag changes nothing (--method rough gives the voxel render)");
        }
        let (patch, exact, refine, references) =
            (self.patch, self.exact, self.refine, self.references);
        let o = ViewOptions {
            method,
            patch,
            exact,
            refine,
            references,
        };
        o.params(w, h).map_err(flag)
    }
}

/// The model from all views, or all but `withheld`, with progress bars (the volume from the
/// silhouettes of the views it is built from unless `--bounds` is given).
fn build(
    d: &Dataset,
    withheld: Option<usize>,
    m: &ModelParams,
) -> Result<(VoxelModel, BuildSummary)> {
    let mut bars = StageBars::default();
    let r = d.build_without(withheld, m, &mut |s, i, n| bars.update(s, i, n));
    bars.finish();
    r.with_context(|| {
        format!(
            "{}",
            d.cameras_file.parent().unwrap_or(&d.cameras_file).display()
        )
    })
}

/// A model: read from `--model` (checked against the data folder) or built from every view.
/// Returns it with one line saying where it came from and how long that took.
fn model_for(
    d: &Dataset,
    m: &ModelParams,
    from: &ModelFileArgs,
) -> Result<(VoxelModel, Option<ModelHeader>, String)> {
    let Some(f) = &from.file else {
        let (model, s) = build(d, None, m)?;
        let line = format!(
            "model: built, {} surface voxels ({} passes, {}) in {:.2} s",
            s.surface_voxels,
            s.photo_hull_passes,
            unseen_words(&model),
            s.visual_hull_secs + s.photo_hull_secs
        );
        return Ok((model, None, line));
    };
    let t = Instant::now();
    let (model, h) = read_model(f, d)?;
    let line = format!(
        "model: read from {} in {:.2} s ({} surface voxels, {}; building it took {:.2} s)",
        f.display(),
        t.elapsed().as_secs_f64(),
        model.surface.len(),
        unseen_words(&model),
        h.build_secs
    );
    Ok((model, Some(h), line))
}

/// The share of a model's surface seen by no camera, in words.
fn unseen_words(model: &VoxelModel) -> String {
    let unseen = model.surface.iter().filter(|v| v.seen_by == 0).count();
    format!(
        "{:.1} % seen by no camera",
        100.0 * unseen as f64 / model.surface.len().max(1) as f64
    )
}

/// Refuses a model built without a view where every view is needed (render, orbit).
fn whole(h: Option<&ModelHeader>, from: &ModelFileArgs) -> Result<()> {
    if let (Some(k), Some(f)) = (h.and_then(|h| h.withheld), &from.file) {
        bail!(
            "--model {}: built without view {k} (for `vt fv eval --leave-out {k}`); render and orbit take a model of every view",
            f.display()
        );
    }
    Ok(())
}

/// The run's inputs with the model file.
fn inputs_with<'a>(data: &'a DataArgs, from: &'a ModelFileArgs) -> Vec<&'a Path> {
    let mut v = data.inputs();
    v.extend(from.file.as_deref());
    v
}

fn hull(a: HullArgs) -> Result<()> {
    let m = a.model.params()?;
    // The output is checked before any work: never the data folder, never a foreign path.
    let dir = Output::dir(&a.out, OutputKind::Hull, &a.data.inputs())?;
    let d = a.data.load()?;
    if let Some(k) = a.leave_out {
        d.check_withheld(&[k]).map_err(flag)?;
    }
    let (model, s) = build(&d, a.leave_out, &m)?;
    let bounds = Aabb::new(s.bounds_min.into(), s.bounds_max.into());
    // Fewer than 3 views leave nothing to check against.
    let check = if d.cams.len() >= 3 {
        Some(d.check_silhouettes(bounds).context("silhouette check")?)
    } else {
        None
    };
    let header = d.model_header(a.leave_out, &m, &s);
    write_hull(dir.path(), &d, &model, &header, &s, check.as_ref())?;
    dir.commit()?;
    let (w, h) = d.size();
    let [gx, gy, gz] = s.grid;
    let without = a
        .leave_out
        .map(|k| format!(" (without view {k}, {})", d.cams[k].name))
        .unwrap_or_default();
    println!(
        "{} views{without} {w}x{h}, grid {gx}x{gy}x{gz}, silhouettes from {}",
        d.cams.len(),
        d.silhouettes
    );
    println!("{s}");
    if let Some(c) = &check {
        println!("{c}");
    }
    println!(
        "wrote {}/model.vtfv (for --model), hull.ply and summary.json",
        a.out.display()
    );
    Ok(())
}

fn render(a: RenderArgs) -> Result<()> {
    let m = a.model.params()?;
    if !matches!(
        image::ImageFormat::from_path(&a.out),
        Ok(image::ImageFormat::Png | image::ImageFormat::Jpeg)
    ) {
        bail!("--out {}: use a .png or .jpg file name", a.out.display());
    }
    let inputs = inputs_with(&a.data, &a.from);
    // Checked before any work (nothing is created yet).
    drop(Output::file(&a.out, OutputKind::Image, &inputs)?);
    let d = a.data.load()?;
    let (w, h) = d.size();
    let view = a.view.params(w, h)?;
    let camera = |target: nalgebra::Vector3<f64>, bounds: &Aabb| {
        d.camera(&a.camera, a.data.scale, &target, bounds)
            .map_err(|e| anyhow!("--camera {e}"))
    };
    let (model, model_line) = if a.from.file.is_some() {
        let (model, header, line) = model_for(&d, &m, &a.from)?;
        whole(header.as_ref(), &a.from)?;
        (model, line)
    } else {
        // Check the camera against the volume before the expensive model build.
        let bounds = d
            .volume(m.bounds)
            .context("volume bounds from the silhouettes")?;
        camera(bounds.centre(), &bounds)?;
        let (model, _, line) = model_for(&d, &m, &a.from)?;
        (model, line)
    };
    // Ring cameras look at the model's centre.
    let cam = camera(model_centre(&model), &model.grid.bounds())?;
    let t = Instant::now();
    let pb = bar(1, view.name());
    // What eval scores: the model's render trimmed to the reference silhouettes, then the
    // method's image.
    let v = novel_view_in(
        &model,
        &d.cams,
        &d.images,
        Some(&d.masks),
        &cam,
        w,
        h,
        &view,
    )
    .with_context(|| format!("--method {}", view.name()))?;
    pb.finish_and_clear();
    let what = v.describe(&d.cams, &view);
    let (img, coverage) = (v.guided, v.rough.coverage.count_ones());
    if coverage == 0 {
        bail!("--camera {}: camera sees none of the model", cam.name);
    }
    let render_secs = t.elapsed().as_secs_f64();
    vt_io::writer::write_image(&a.out, &inputs, &img)?;
    println!("{model_line}; view in {render_secs:.2} s, {what}");
    println!("wrote {} ({w}x{h})", a.out.display());
    Ok(())
}

fn orbit(a: OrbitArgs) -> Result<()> {
    let m = a.model.params()?;
    let ext = a.out.extension().and_then(|e| e.to_str());
    if !matches!(
        ext.map(str::to_ascii_lowercase).as_deref(),
        Some("mp4" | "gif")
    ) {
        bail!("--out {}: use a .mp4 or .gif file name", a.out.display());
    }
    if a.frames == 0 || a.frames > 10_000 {
        bail!("--frames {} must be in 1..=10000", a.frames);
    }
    if a.fps == 0 || a.fps > 240 {
        bail!("--fps {} must be in 1..=240", a.fps);
    }
    let inputs = inputs_with(&a.data, &a.from);
    // Checked before any work (nothing is created yet).
    drop(Output::file(&a.out, OutputKind::Video, &inputs)?);
    let d = a.data.load()?;
    let (w, h) = d.size();
    let view = a.view.params(w, h)?;
    let ring = Ring::fit(&d.cams).context("orbit: the cameras' ring")?;
    // One model for every frame.
    let (model, header, model_line) = model_for(&d, &m, &a.from)?;
    whole(header.as_ref(), &a.from)?;
    let target = model_centre(&model);
    // vt-io's one video writer: H.264 at CRF 18 (or GIF), marked as vt's, atomic.
    let mut video = vt_io::writer::VideoWriter::create(&a.out, &inputs, w, h, a.fps as f64)?;
    let pb = bar(a.frames as u64, "orbit frames");
    let t = Instant::now();
    let steady = vt_fv::orbit::orbit::<anyhow::Error>(
        &model,
        &d.cams,
        &d.images,
        Some(&d.masks),
        &ring,
        &target,
        a.frames,
        (w, h),
        &view,
        &mut |i, angle, v| {
            video
                .write(&v.guided)
                .with_context(|| format!("frame {i} (angle {angle:.1})"))?;
            pb.inc(1);
            Ok(())
        },
    )?;
    let secs = t.elapsed().as_secs_f64();
    pb.finish_and_clear();
    video.finish()?;
    println!("{model_line}");
    println!(
        "wrote {} ({} frames, {w}x{h}, {} fps) in {secs:.2} s ({:.3} s a frame); each frame {}",
        a.out.display(),
        a.frames,
        a.fps,
        secs / a.frames as f64,
        view.describe()
    );
    println!("{steady}");
    Ok(())
}

fn eval(a: EvalArgs) -> Result<()> {
    let m = a.model.params()?;
    let inputs = inputs_with(&a.data, &a.from);
    let save = match &a.save {
        Some(dir) if dir.exists() && !dir.is_dir() => {
            bail!("--save {}: exists and is not a folder", dir.display())
        }
        Some(dir) => Some(Output::dir(dir, OutputKind::Folder, &inputs)?),
        None => None,
    };
    if a.from.file.is_some() && a.leave_out.len() != 1 {
        bail!("--model: a model is built without one view; give that one view to --leave-out");
    }
    let d = a.data.load()?;
    d.check_withheld(&a.leave_out).map_err(flag)?;
    let (w, h) = d.size();
    let view = a.view.params(w, h)?;
    let read = match &a.from.file {
        Some(f) => {
            let t = Instant::now();
            let (model, header) = read_model(f, &d)?;
            let line = format!(
                "model: read from {} in {:.2} s ({} surface voxels; building it took {:.2} s)",
                f.display(),
                t.elapsed().as_secs_f64(),
                model.surface.len(),
                header.build_secs
            );
            Some((f, model, header, line))
        }
        None => None,
    };
    let pb = bar(a.leave_out.len() as u64, "leave one out");
    let mut reports = Vec::new();
    for &k in &a.leave_out {
        let (r, imgs) = match &read {
            Some((f, model, header, _)) => d.leave_one_out_with(k, model, header, f, &view)?,
            None => d
                .leave_one_out(k, &m, &view)
                .with_context(|| format!("leaving out view {k} ({})", d.cams[k].name))?,
        };
        if let Some(dir) = &save {
            let sub = dir.path().join(format!("view_{k:02}"));
            std::fs::create_dir(&sub).with_context(|| sub.display().to_string())?;
            write_eval_images(&sub, &imgs, &d.score_masks[k])?;
        }
        reports.push(r);
        pb.inc(1);
    }
    pb.finish_and_clear();
    // On stderr, so that --json prints exactly one JSON object on stdout.
    if let Some((.., line)) = &read {
        eprintln!("{line}");
    }
    let summary = EvalSummary::new(view.name(), &reports, &d.cams);
    if let Some(dir) = save {
        write_json(&dir.path().join("eval.json"), &summary.views)?;
        dir.commit()?;
    }
    if a.json {
        println!("{}", serde_json::to_string(&summary)?);
        return Ok(());
    }
    println!("new views by {}", view.describe());
    for r in &reports {
        println!(
            "withheld view {} ({}); nearest photo view {} ({}); method {}",
            r.withheld,
            d.cams[r.withheld].name,
            r.reference,
            d.cams[r.reference].name,
            summary.method
        );
        println!("{r}\n");
    }
    if reports.len() > 1 {
        println!("{summary}");
    }
    Ok(())
}
