//! `vt analyze`: videos (or frame folders) + points -> scene directory.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Args;
use vt_app::analyze::{AnalysisSummary, AnalyzeJob};
use vt_core::analysis::{AnalyzeParams, MaskParams, MAX_CACHE_BYTES};
use vt_core::blur::GaussianParams;
use vt_core::loops::LoopParams;
use vt_core::model::{ModelParams, MotionModel};

use crate::flags::flagged;
use crate::progress::Bars;

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
    #[arg(long, default_value_t = vt_core::analysis::DEFAULT_CACHE_MB)]
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
    /// How the moving-object stores keep the pixels: a PSNR target such as 40db (each view's
    /// store at the coarsest H.264 quantiser predicted to keep its frames that close to the
    /// analysed ones, chosen from its first 8 frames), a fixed quantiser 12-51 (lower keeps
    /// more, larger files) or lossless (raw RGB, tens of times the video's size).
    #[arg(long, default_value_t = vt_io::objects::StoreQuality::default())]
    store_quality: vt_io::objects::StoreQuality,
    /// Loops per view: regions (each tile its own start and period, baked offline into one
    /// seamless loop of length L), single (the thesis's one loop (m, n), eq. 1), or auto: per
    /// region where that measures better than the thesis's loop and fits --cache-mb.
    #[arg(long, default_value = "auto", value_parser = ["auto", "single", "regions"])]
    loops: String,
    /// Per-region loops: tile side, pixels.
    #[arg(long, default_value_t = vt_core::regions::RegionParams::default().tile)]
    region_tile: u32,
    /// Per-region loops: weight of the spatial consistency between neighbouring tiles.
    #[arg(long, default_value_t = vt_core::regions::RegionParams::default().spatial)]
    region_spatial: f32,
    /// Per-region loops: feather between tiles, pixels.
    #[arg(long, default_value_t = vt_core::regions::RegionParams::default().feather)]
    region_feather: u32,
    /// Per-region loops: each tile's wrap mismatch spread over its period, low-passed by a
    /// Gaussian of this many pixels (0: not low-passed), or off.
    #[arg(long, default_value = "0")]
    region_blend: String,
    /// Per-region loops: the most a frame of a tile's wrap correction may add, in the tile's
    /// ordinary steps (spread over as few frames around the wrap as that allows; 0: over the
    /// whole cycle).
    #[arg(long, default_value_t = vt_core::regions::DEFAULT_SPREAD)]
    region_spread: f32,
    /// Handheld clips: auto measures each view's camera shake and, when the camera moves,
    /// warps every frame to one still camera and crops to the area every frame covers (a cut
    /// or a pan is refused); off takes the frames as they are.
    #[arg(long, default_value = "auto", value_parser = ["auto", "off"])]
    stabilize: String,
}

impl AnalyzeArgs {
    /// The job these flags describe (parsing only: the rules are `AnalyzeJob::check`'s).
    fn job(&self) -> Result<AnalyzeJob> {
        let force = match self.model.as_str() {
            "auto" => None,
            m => Some(m.parse::<MotionModel>().map_err(|_| {
                anyhow!("--model '{m}' is not auto, translation, similarity, affine or homography")
            })?),
        };
        let blend = match self.region_blend.as_str() {
            "off" => None,
            v => Some(
                v.parse::<f32>()
                    .map_err(|_| anyhow!("--region-blend '{v}' is not off or a sigma in pixels"))?,
            ),
        };
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
            cache_bytes: self.cache_mb.saturating_mul(1 << 20),
            appearance: self.appearance,
            refine: self.refine == "on",
            noise: vt_core::noise::NoiseParams {
                k: self.noise_k,
                dynamic: self.dynamic == "on",
                ..Default::default()
            },
            register: Default::default(),
            stabilize: vt_core::stabilize::StabilizeParams {
                mode: self.stabilize.parse()?,
                ..Default::default()
            },
            regions: (self.loops != "single").then(|| vt_core::regions::RegionParams {
                tile: self.region_tile,
                spatial: self.region_spatial,
                feather: self.region_feather,
                blend,
                only_if_better: self.loops == "auto",
                spread: self.region_spread,
                ..Default::default()
            }),
            background: self.background.parse().map_err(|_| {
                anyhow!(
                    "--background '{}' is not plane, morph or auto",
                    self.background
                )
            })?,
        };
        Ok(AnalyzeJob {
            views: self.views.clone(),
            points: self.points.clone(),
            out: self.out.clone(),
            params,
            fps: self.fps,
            store: self.store_quality,
        })
    }
}

/// Runs `vt analyze`.
pub fn run(args: AnalyzeArgs) -> Result<()> {
    let job = args.job()?;
    let done = vt_app::analyze::analyze(&job, &mut Bars::default()).map_err(|e| match e {
        // The flag counts MiB.
        vt_app::Error::Core(vt_core::Error::InvalidParameter {
            name: "cache_bytes",
            ..
        }) => anyhow!(
            "--cache-mb {}: at most {} MiB (1 TiB)",
            args.cache_mb,
            MAX_CACHE_BYTES >> 20
        ),
        e => flagged(e),
    })?;
    print!(
        "{}",
        AnalysisSummary {
            analysis: &done.analysis,
            scene: &done.scene,
            total_secs: done.total_secs,
            seams_secs: done.seams_secs,
            stores: &done.stores,
        }
    );
    println!("scene: {}", args.out.display());
    Ok(())
}
