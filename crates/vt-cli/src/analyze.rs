//! `vt analyze`: videos (or frame folders) + points -> scene directory.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use vt_core::analysis::{analyze, AnalyzeParams, MaskParams};
use vt_core::blur::GaussianParams;
use vt_core::loops::LoopParams;
use vt_core::model::{ModelParams, MotionModel};
use vt_io::frames::ViewSource;
use vt_io::output::{Output, OutputKind};
use vt_io::scene::{write_analysis, AnalysisSummary, SceneFile};

use crate::progress::AnalysisObserver;

#[derive(Args)]
pub struct AnalyzeArgs {
    /// One video (mp4/avi/mov/mkv) or folder of PNG/JPEG/BMP/TIFF frames per view, in camera
    /// order.
    #[arg(required = true)]
    views: Vec<PathBuf>,
    /// Points file: one line per view with the same K >= 4 points as x y pairs (without it,
    /// neighbouring views are registered automatically from their median backgrounds).
    #[arg(long)]
    points: Option<PathBuf>,
    /// Output scene directory (written atomically; an existing one is replaced only on success).
    #[arg(long)]
    out: PathBuf,
    /// Window w of eq. (1) and (2) (thesis: 3).
    #[arg(long, default_value_t = 3)]
    window: usize,
    /// Minimum loop length k of eq. (1) (thesis: 100).
    #[arg(long, default_value_t = 100)]
    min_length: usize,
    /// Also store this many next-best distinct loops per view in scene.json.
    #[arg(long, default_value_t = 0)]
    alternatives: usize,
    /// Background-subtraction threshold, grey levels: moving if max over RGB |frame - bg| > T.
    #[arg(long, default_value_t = 25)]
    threshold: u8,
    /// Gaussian kernel size (odd; thesis: 3).
    #[arg(long, default_value_t = 3)]
    blur_size: usize,
    /// Gaussian sigma (<= 0: derived from the size as OpenCV does).
    #[arg(long, default_value_t = 0.0)]
    blur_sigma: f64,
    /// Mask opening radius in pixels (0 = off, as in the thesis).
    #[arg(long, default_value_t = 0)]
    open: u32,
    /// Mask closing radius in pixels (0 = off, as in the thesis).
    #[arg(long, default_value_t = 0)]
    close: u32,
    /// Geometric model between views: auto (simplest that explains the points, by GRIC),
    /// translation, similarity, affine or homography.
    #[arg(long, default_value = "auto")]
    model: String,
    /// Marking noise of the points, pixels (GRIC's sigma).
    #[arg(long, default_value_t = 1.0)]
    point_sigma: f64,
    /// Median background from at most this many evenly spaced frames per view (0 = every frame,
    /// the thesis; slower, and the error it saves is in the report's median curve).
    #[arg(long, default_value_t = vt_core::analysis::DEFAULT_MEDIAN_FRAMES)]
    median_frames: usize,
    /// Keep a view's frames in memory between the two passes when they fit in this many MiB.
    #[arg(long, default_value_t = 768)]
    cache_mb: usize,
    /// Per-pixel noise-model masks: moving where |frame - bg| > K noise deviations of that pixel
    /// (0 = off: the global --threshold, the thesis).
    #[arg(long, default_value_t = 3.0)]
    noise_k: f32,
    /// Dynamic region (pixels that move often, shown from the source frames): on or off.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    dynamic: String,
    /// Weight of the appearance term (colour change) in eq. (1) and (2), in units of an ordinary
    /// frame step (0 = masks only, the thesis).
    #[arg(long, default_value_t = 1.0)]
    appearance: f32,
    /// The background between views: plane (the thesis's warp, eq. 3), morph (along the dense
    /// parallax of each neighbour pair) or auto (morph where parallax off the plane is measured).
    #[arg(long, default_value = "auto", value_parser = ["plane", "morph", "auto"])]
    background: String,
    /// Frame rate of the source, frames per second (default: the videos' median real frame
    /// rate; frame folders have none, so their scenes play at 30 unless this is given).
    #[arg(long)]
    fps: Option<f64>,
    /// Refine the homographies by aligning the median backgrounds (kept only where it lowers the
    /// photometric error and agrees with the points): on or off.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    refine: String,
    /// How the moving-object stores keep the pixels: an H.264 quantiser 0-51 (lower keeps more,
    /// larger files) or lossless (raw RGB, tens of times the video's size).
    #[arg(long, default_value_t = vt_io::objects::StoreQuality::default())]
    store_quality: vt_io::objects::StoreQuality,
}

impl AnalyzeArgs {
    fn params(&self) -> Result<AnalyzeParams> {
        let force = match self.model.as_str() {
            "auto" => None,
            m => Some(m.parse::<MotionModel>().map_err(|_| {
                anyhow::anyhow!(
                    "--model '{m}' is not auto, translation, similarity, affine or homography"
                )
            })?),
        };
        // The flags the library does not see as such: frame counts and MiB.
        if self.window == 0 || self.min_length == 0 {
            bail!(
                "--window ({}) and --min-length ({}) must be at least 1",
                self.window,
                self.min_length
            );
        }
        if self.min_length > vt_io::limits::MAX_FRAMES {
            let max = vt_io::limits::MAX_FRAMES;
            bail!("--min-length {} is more than {max} frames", self.min_length);
        }
        if let Some(fps) = self.fps {
            if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
                bail!("--fps {fps}: a frame rate above 0 and at most 1000 frames per second");
            }
        }
        if self.cache_mb > MAX_CACHE_MB {
            bail!(
                "--cache-mb {} is more than {MAX_CACHE_MB} (1 TiB)",
                self.cache_mb
            );
        }
        let params = AnalyzeParams {
            blur: GaussianParams {
                ksize: self.blur_size,
                sigma: self.blur_sigma,
            },
            mask: MaskParams {
                threshold: self.threshold,
                open_radius: self.open,
                close_radius: self.close,
            },
            loops: LoopParams {
                window: self.window,
                min_length: self.min_length,
            },
            model: ModelParams {
                sigma: self.point_sigma,
                force,
            },
            alternative_loops: self.alternatives,
            median_frames: self.median_frames,
            cache_bytes: self.cache_mb << 20,
            appearance: self.appearance,
            refine: self.refine == "on",
            noise: vt_core::noise::NoiseParams {
                k: self.noise_k,
                dynamic: self.dynamic == "on",
                ..Default::default()
            },
            register: Default::default(),
            background: self.background.parse().map_err(|_| {
                anyhow::anyhow!(
                    "--background '{}' is not plane, morph or auto",
                    self.background
                )
            })?,
        };
        params.check().map_err(|e| match e {
            vt_core::Error::InvalidParameter { name, value, why } => match flag_of(name) {
                Some(flag) => anyhow::anyhow!("{flag} {value}: {why}"),
                None => vt_core::Error::InvalidParameter { name, value, why }.into(),
            },
            e => e.into(),
        })?;
        Ok(params)
    }
}

/// The flag that sets an analysis parameter, by vt-core's name of it
/// ([`AnalyzeParams::check`]).
fn flag_of(name: &str) -> Option<&'static str> {
    Some(match name {
        "blur.ksize" => "--blur-size",
        "blur.sigma" => "--blur-sigma",
        "loops.window" => "--window",
        "mask.open_radius" => "--open",
        "mask.close_radius" => "--close",
        "alternative_loops" => "--alternatives",
        "model.sigma" => "--point-sigma",
        "appearance" => "--appearance",
        "median_frames" => "--median-frames",
        _ => return None,
    })
}

/// Largest `--cache-mb` (1 TiB).
pub const MAX_CACHE_MB: usize = 1 << 20;

/// Runs `vt analyze`; returns the scene written (for the demo's truth check).
pub fn run(args: AnalyzeArgs) -> Result<SceneFile> {
    let shown = args.out.clone();
    run_as(args, &shown)
}

/// [`run`], naming the scene `shown` in what it prints (`vt demo` writes inside its own
/// temporary folder, which the user never sees).
pub fn run_as(args: AnalyzeArgs, shown: &Path) -> Result<SceneFile> {
    let params = args.params()?;
    let m = args.views.len();
    let mut sources: Vec<ViewSource> = args
        .views
        .iter()
        .enumerate()
        .map(|(p, path)| ViewSource::open(path).with_context(|| format!("view {p}")))
        .collect::<Result<_>>()?;
    // Sizes are known before decoding: refuse mismatched views before any work.
    let first = vt_io::frames::common_size(&args.views, &sources)?;
    let points = match &args.points {
        Some(path) => vt_io::points::read_for_views(path, m, first)?,
        None => Vec::new(),
    };
    if m > vt_io::limits::MAX_VIEWS {
        bail!("{m} views is more than {}", vt_io::limits::MAX_VIEWS);
    }
    let started = Instant::now();
    let mut inputs: Vec<&Path> = args.views.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.points.as_deref());
    let dir = Output::dir(&args.out, OutputKind::Scene, &inputs)?;
    let mut observer = AnalysisObserver::new(dir.path().to_path_buf(), args.store_quality);
    let mut refs: Vec<&mut dyn vt_core::analysis::FrameSource> =
        sources.iter_mut().map(|s| s.as_source()).collect();
    let analysis = analyze(&mut refs, &points, &params, &mut observer);
    vt_core::analysis::Observer::finish(&mut observer);
    let analysis = analysis.map_err(|e| match (&e, &args.points) {
        (vt_core::Error::DegeneratePoints(_) | vt_core::Error::NonFinite(_), Some(p)) => {
            anyhow::anyhow!("{}: {e}", p.display())
        }
        // The way out, in the flag's words: a shorter minimum loop.
        (vt_core::Error::TooFewFrames { got, .. }, _) if *got > params.loops.window => {
            anyhow::anyhow!(
                "{e}; for a clip this short pass --min-length {} or less",
                got - params.loops.window
            )
        }
        _ => e.into(),
    })?;
    observer.finish_objects()?;
    let fps = args
        .fps
        .or_else(|| vt_io::video::views_frame_rate(&args.views));
    let scene = write_analysis(dir.path(), &analysis, &params, fps)?;
    dir.commit()?;
    let total_secs = started.elapsed().as_secs_f64();
    print!(
        "{}",
        AnalysisSummary {
            analysis: &analysis,
            scene: &scene,
            total_secs
        }
    );
    println!("scene: {}", shown.display());
    Ok(scene)
}
