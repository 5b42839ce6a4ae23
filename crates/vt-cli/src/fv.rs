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

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Subcommand};
use vt_app::fv::FvData;
use vt_fv::dataset::{parse_bounds, DataOptions, ModelParams};
use vt_fv::hull::Aabb;
use vt_fv::pipeline::{Method, ViewOptions};

use crate::flags::flagged;
use crate::progress::Bars;

/// Free-viewpoint commands.
#[derive(Subcommand)]
pub enum FvCommand {
    /// Build the visual hull and the photo hull; write DIR/model.vtfv (for --model),
    /// DIR/hull.ply and DIR/summary.json.
    Hull(HullArgs),
    /// Render one new view (textured by default; --method rough|paper) into an image file.
    Render(RenderArgs),
    /// Views around the cameras' ring (made by --method, textured by default), encoded as an mp4, gif or apng (needs ffmpeg).
    Orbit(OrbitArgs),
    /// Leave one view out: rebuild without it, make it by --method, and score it and the baselines.
    Eval(EvalArgs),
    /// A static page (open DIR/index.html from disk, no server) where you turn around the object
    /// and zoom, rendered live in WebGL2 as `vt fv render` textures its views.
    Export(PageExportArgs),
    /// Serve the `vt fv export` page on 127.0.0.1 (built in memory; nothing is written).
    View(PageViewArgs),
}

/// What `vt fv export` and `vt fv view` make their page from.
#[derive(Args)]
pub struct PageArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    from: ModelFileArgs,
    /// Reference photos blended per pixel (nearest by direction), as `vt fv render --references`.
    #[arg(long, default_value_t = 2)]
    references: usize,
}

impl PageArgs {
    fn data(&self) -> FvData {
        self.data.data(&self.model, Some(&self.from))
    }
}

/// `vt fv export`.
#[derive(Args)]
pub struct PageExportArgs {
    #[command(flatten)]
    page: PageArgs,
    /// Output folder (index.html and data/); must not exist. Written to a temporary folder and
    /// renamed.
    #[arg(long)]
    out: PathBuf,
}

/// `vt fv view`.
#[derive(Args)]
pub struct PageViewArgs {
    #[command(flatten)]
    page: PageArgs,
    /// Port on 127.0.0.1 (0 = any free port; the URL is printed).
    #[arg(long, default_value_t = 8080)]
    port: u16,
}

/// The page's view settings: `vt fv render`'s textured default with `references`.
fn page_view(references: usize) -> ViewOptions {
    ViewOptions {
        method: Method::Textured,
        patch: 7,
        exact: false,
        refine: false,
        references,
    }
}

fn page_export(a: PageExportArgs) -> Result<()> {
    let job = vt_app::fv::FvExportJob {
        data: a.page.data(),
        view: page_view(a.page.references),
        out: a.out.clone(),
    };
    let done = vt_app::fv::fv_export(&job, &mut Bars::default())?;
    println!("{}", done.model_line);
    let s = done.summary;
    println!(
        "wrote {} ({} files, {:.2} MB; {} surface voxels); its views 1-{} are `vt fv render --camera` {}",
        a.out.join("index.html").display(),
        s.files,
        s.bytes as f64 / 1e6,
        s.voxels,
        done.views.len(),
        done.views.join(", ")
    );
    Ok(())
}

fn page_view_serve(a: PageViewArgs) -> Result<()> {
    let data = a.page.data();
    let view = page_view(a.page.references);
    let (files, line) = vt_app::fv::fv_page(&data, &view, &mut Bars::default())?;
    let server = vt_view::PageServer::bind(a.port, files).map_err(vt_app::Error::from)?;
    eprintln!("{line}");
    println!(
        "vt fv view: serving {} at http://127.0.0.1:{}/ (Ctrl-C to stop)",
        data.data.display(),
        server.port()
    );
    std::io::Write::flush(&mut std::io::stdout()).ok();
    vt_io::output::interrupt_means_stop();
    server.serve();
    Ok(())
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
    /// Build from these views only, in this order: 0-based indices in camera order, photo
    /// names or their stems, e.g. `--views 26,86,2,55,75,93,16,73` or `--views r_26,r_86`.
    /// Indices elsewhere (--leave-out, between:I,J,T) count within the chosen views.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    views: Vec<String>,
    /// What uncovered pixels of a new view become: `data` (the data's own: white for NeRF
    /// transforms files, as that data is scored; else transparent), `transparent` (a PNG gets
    /// the view's coverage as a soft-edged alpha channel; black in JPEG and video), `white`,
    /// `black`, `grey`, `#rrggbb` or `r,g,b`. Photos with an alpha channel are composited over
    /// the colour.
    #[arg(long, default_value = "data")]
    background: vt_fv::composite::Background,
}

/// How to build the voxel model.
#[derive(Args, Clone)]
pub struct ModelArgs {
    /// Voxels along the longest side of the volume (paper: 256); voxels are cubes. 128 is
    /// measured best under the time budget: on templeSparseRing the result scores the same at
    /// 128, 192 and 256 and one leave-one-out takes 2.4x longer at 256 (docs/system-b.md).
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
    /// Skip the stereo carving: by default a depth map per photo (plane sweep inside the
    /// visual hull, checked against the other photos' maps) carves the free space in front of
    /// the surfaces the photos see, and what no photo can see, before the photo hull.
    #[arg(long)]
    no_stereo: bool,
}

/// Guided synthesis settings.
#[derive(Args, Clone)]
pub struct ViewArgs {
    /// Patch side of the guided synthesis, odd (paper: 41; 7 is faster and scores better on
    /// our data).
    #[arg(long, default_value_t = 7)]
    patch: usize,
    /// Paper-exact synthesis: sequential scanline order, full patches, one resolution level
    /// (default: the speed options, see docs/system-b.md).
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
        conflicts_with_all = ["grid", "bounds", "photo_threshold", "paper_carving", "no_stereo"]
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
    /// views I and J, 0-based in camera order (the par file's lines, COLMAP's image ids, the matrix files' names), at T in [0, 1], carried round the model's centre).
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
    /// Output .mp4 (H.264), .gif or .apng (lossless animated PNG), written to a temporary file and renamed.
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
    #[arg(long, value_delimiter = ',', num_args = 1.., required_unless_present = "test", conflicts_with = "test")]
    leave_out: Vec<usize>,
    /// Score against a test set instead: a NeRF transforms file (e.g. `transforms_test.json`,
    /// as given or inside DATA) or a data folder. The model is built from every (chosen) view,
    /// each test view is made and scored on the whole image over the background (the NeRF
    /// benchmarks' figure) and inside its silhouette, with the coverage's IoU; `--save DIR`
    /// writes every view, eval.json and contact_sheet.png (the worst views: truth, view, error).
    #[arg(long, value_name = "FILE|DIR")]
    test: Option<PathBuf>,
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
        FvCommand::Export(a) => page_export(a),
        FvCommand::View(a) => page_view_serve(a),
    }
    .map_err(|e| match e.downcast::<vt_app::Error>() {
        Ok(e) => flagged(e),
        Err(e) => e,
    })
}

impl DataArgs {
    /// The data folder, how to load it and how to build the model, as vt-app takes them.
    fn data(&self, model: &ModelArgs, from: Option<&ModelFileArgs>) -> FvData {
        FvData {
            data: self.data.clone(),
            options: DataOptions {
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
                views: self.views.clone(),
                background: self.background,
            },
            model: ModelParams {
                grid: model.grid,
                bounds: model.bounds,
                photo_threshold: model.photo_threshold,
                paper_carving: model.paper_carving,
                stereo: !model.no_stereo,
                ..Default::default()
            },
            model_file: from.and_then(|f| f.file.clone()),
        }
    }
}

impl ViewArgs {
    /// The new-view settings (checked against the photos' size once they are loaded).
    fn options(&self) -> Result<ViewOptions> {
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
        Ok(ViewOptions {
            method,
            patch,
            exact,
            refine,
            references,
        })
    }
}

fn hull(a: HullArgs) -> Result<()> {
    let job = vt_app::fv::HullJob {
        data: a.data.data(&a.model, None),
        leave_out: a.leave_out,
        out: a.out.clone(),
    };
    let done = vt_app::fv::hull(&job, &mut Bars::default())?;
    let (d, s) = (&done.dataset, &done.summary);
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
    if let Some(c) = &done.check {
        println!("{c}");
    }
    println!(
        "wrote {}/model.vtfv (for --model), hull.ply and summary.json",
        a.out.display()
    );
    Ok(())
}

fn render(a: RenderArgs) -> Result<()> {
    let data = a.data.data(&a.model, Some(&a.from));
    let job = vt_app::fv::FvRenderJob {
        data,
        view: a.view.options()?,
        camera: a.camera,
        out: a.out.clone(),
    };
    let done = vt_app::fv::render(&job, &mut Bars::default())?;
    let (w, h) = done.size;
    println!(
        "{}; view in {:.2} s, {}",
        done.model_line, done.view_secs, done.what
    );
    println!("wrote {} ({w}x{h})", a.out.display());
    Ok(())
}

fn orbit(a: OrbitArgs) -> Result<()> {
    let data = a.data.data(&a.model, Some(&a.from));
    let job = vt_app::fv::OrbitJob {
        data,
        view: a.view.options()?,
        frames: a.frames,
        fps: a.fps,
        out: a.out.clone(),
    };
    let done = vt_app::fv::orbit(&job, &mut Bars::default())?;
    let (w, h) = done.size;
    println!("{}", done.model_line);
    println!(
        "wrote {} ({} frames, {w}x{h}, {} fps) in {:.2} s ({:.3} s a frame); each frame {}",
        a.out.display(),
        a.frames,
        a.fps,
        done.secs,
        done.secs / a.frames as f64,
        done.describe
    );
    println!("{}", done.steadiness);
    Ok(())
}

fn eval(a: EvalArgs) -> Result<()> {
    let data = a.data.data(&a.model, Some(&a.from));
    let job = vt_app::fv::EvalJob {
        data,
        view: a.view.options()?,
        leave_out: a.leave_out.clone(),
        test: a.test.clone(),
        save: a.save.clone(),
    };
    if job.test.is_some() {
        let done = vt_app::fv::eval_test(&job, &mut Bars::default())?;
        eprintln!("{}", done.model_line);
        if a.json {
            println!("{}", serde_json::to_string(&done.summary)?);
            return Ok(());
        }
        println!(
            "test set {}; new views by {}",
            done.test.display(),
            done.describe
        );
        for (i, v) in done.summary.views.iter().enumerate() {
            println!(
                "  {i:3} {:<24} {:6.2} dB  SSIM {:.3}  inside {:6.2} dB  IoU {:.3}  ({:.2} s)",
                v.name, v.whole.psnr, v.whole.ssim, v.inside.psnr, v.coverage_iou, v.secs
            );
        }
        println!("{}", done.summary);
        if let Some(dir) = &a.save {
            println!(
                "wrote {}: every view, eval.json, contact_sheet.png (the {} worst views)",
                dir.display(),
                vt_app::fv::CONTACT_VIEWS
            );
        }
        return Ok(());
    }
    let done = vt_app::fv::eval(&job, &mut Bars::default())?;
    // On stderr, so that --json prints exactly one JSON object on stdout.
    if let Some(line) = &done.model_line {
        eprintln!("{line}");
    }
    if a.json {
        println!("{}", serde_json::to_string(&done.summary)?);
        return Ok(());
    }
    let d = &done.dataset;
    println!("new views by {}", done.describe);
    for r in &done.reports {
        println!(
            "withheld view {} ({}); nearest photo view {} ({}); method {}",
            r.withheld,
            d.cams[r.withheld].name,
            r.reference,
            d.cams[r.reference].name,
            done.summary.method
        );
        println!("{r}\n");
    }
    if done.reports.len() > 1 {
        println!("{}", done.summary);
    }
    Ok(())
}
