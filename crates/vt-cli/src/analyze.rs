//! `vt analyze`: videos (or frame folders) + points -> scene directory.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use vt_core::analysis::{analyze, AnalyzeParams, MaskParams, SceneAnalysis, Timings};
use vt_core::blur::GaussianParams;
use vt_core::loops::LoopParams;
use vt_core::model::{ModelParams, MotionModel};
use vt_io::frames::{write_png, ViewSource};
use vt_io::output::{Output, OutputKind};
use vt_io::scene::{background_name, SceneFile};

use crate::progress::AnalysisObserver;

#[derive(Args)]
pub struct AnalyzeArgs {
    /// One video (mp4/avi/mov/mkv) or folder of PNG/JPG frames per view, in camera order.
    #[arg(required = true)]
    views: Vec<PathBuf>,
    /// Points file: one line per view with the same K >= 4 points as x y pairs (needed for 2+ views).
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
    /// Refine the homographies by aligning the median backgrounds (kept only where it lowers the
    /// photometric error and agrees with the points): on or off.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    refine: String,
}

impl AnalyzeArgs {
    /// Arguments for `vt demo`: defaults, with k scaled to the demo's length.
    pub fn for_demo(views: Vec<PathBuf>, points: PathBuf, out: PathBuf, frames: usize) -> Self {
        Self {
            views,
            points: Some(points),
            out,
            window: 3,
            min_length: (frames / 2).clamp(4, 100),
            alternatives: 2,
            threshold: 25,
            blur_size: 3,
            blur_sigma: 0.0,
            open: 0,
            close: 0,
            model: "auto".into(),
            point_sigma: 1.0,
            cache_mb: 768,
            noise_k: 3.0,
            dynamic: "on".into(),
            appearance: 1.0,
            refine: "on".into(),
        }
    }

    fn params(&self) -> Result<AnalyzeParams> {
        let force = match self.model.as_str() {
            "auto" => None,
            m => Some(m.parse::<MotionModel>().map_err(|_| {
                anyhow::anyhow!(
                    "--model '{m}' is not auto, translation, similarity, affine or homography"
                )
            })?),
        };
        if !(self.point_sigma.is_finite() && self.point_sigma > 0.0) {
            bail!(
                "--point-sigma {} must be a positive number of pixels",
                vt_io::output::num(self.point_sigma)
            );
        }
        if self.blur_size.is_multiple_of(2) || self.blur_size > MAX_BLUR_SIZE {
            bail!(
                "--blur-size {} must be odd and at most {MAX_BLUR_SIZE}",
                self.blur_size
            );
        }
        if !(self.blur_sigma.is_finite() && self.blur_sigma <= MAX_BLUR_SIGMA) {
            bail!(
                "--blur-sigma {} must be a finite number of pixels, at most {MAX_BLUR_SIGMA} (<= 0: derived from --blur-size)",
                vt_io::output::num(self.blur_sigma)
            );
        }
        if self.window == 0 || self.min_length == 0 {
            bail!(
                "--window ({}) and --min-length ({}) must be at least 1",
                self.window,
                self.min_length
            );
        }
        if self.window > MAX_WINDOW || self.min_length > vt_io::limits::MAX_FRAMES {
            bail!(
                "--window {} (at most {MAX_WINDOW}) or --min-length {} (at most {}) is too large",
                self.window,
                self.min_length,
                vt_io::limits::MAX_FRAMES
            );
        }
        if self.open > MAX_RADIUS || self.close > MAX_RADIUS {
            bail!(
                "--open {} / --close {}: radii are at most {MAX_RADIUS} pixels",
                self.open,
                self.close
            );
        }
        if self.alternatives > MAX_ALTERNATIVES {
            bail!(
                "--alternatives {} is more than {MAX_ALTERNATIVES}",
                self.alternatives
            );
        }
        if self.cache_mb > MAX_CACHE_MB {
            bail!(
                "--cache-mb {} is more than {MAX_CACHE_MB} (1 TiB)",
                self.cache_mb
            );
        }
        Ok(AnalyzeParams {
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
            cache_bytes: self.cache_mb << 20,
            appearance: self.appearance,
            refine: self.refine == "on",
            noise: vt_core::noise::NoiseParams {
                k: self.noise_k,
                dynamic: self.dynamic == "on",
                ..Default::default()
            },
        })
    }
}

/// Largest `--blur-size` (OpenCV allows any odd size; beyond this the kernel is wider than any
/// useful smoothing and its cost grows with it).
pub const MAX_BLUR_SIZE: usize = 255;
/// Largest `--blur-sigma`, pixels.
pub const MAX_BLUR_SIGMA: f64 = 1000.0;
/// Largest `--window`.
pub const MAX_WINDOW: usize = 1000;
/// Largest `--open` / `--close` radius, pixels.
pub const MAX_RADIUS: u32 = 255;
/// Largest `--alternatives`.
pub const MAX_ALTERNATIVES: usize = 100;
/// Largest `--cache-mb` (1 TiB).
pub const MAX_CACHE_MB: usize = 1 << 20;
/// How far beyond the frame's edges a marked point may lie, as a fraction of the frame's side.
pub const POINT_MARGIN: f64 = 0.1;

/// What `run` returns, for the demo's truth check.
pub struct AnalyzeResult {
    pub scene: SceneFile,
}

pub fn run(args: AnalyzeArgs) -> Result<AnalyzeResult> {
    let params = args.params()?;
    let m = args.views.len();
    let points = match &args.points {
        Some(p) => {
            let pts = vt_io::points::read_points(p)?;
            if pts.len() != m {
                bail!(
                    "{}: {} lines of points, but {} views were given (one line per view)",
                    p.display(),
                    pts.len(),
                    m
                );
            }
            pts
        }
        None if m > 1 => bail!(
            "--points is required with {m} views (the homographies between views come from them)"
        ),
        None => Vec::new(),
    };
    let mut sources: Vec<ViewSource> = args
        .views
        .iter()
        .enumerate()
        .map(|(p, path)| ViewSource::open(path).with_context(|| format!("view {p}")))
        .collect::<Result<_>>()?;
    // Sizes are known before decoding: refuse mismatched views before any work.
    let first = sources[0].size();
    if let Some((p, src)) = sources.iter().enumerate().find(|(_, s)| s.size() != first) {
        let size = src.size();
        bail!(
            "views have different sizes: view 0 ({}) is {}x{}, view {p} ({}) is {}x{}",
            args.views[0].display(),
            first.0,
            first.1,
            args.views[p].display(),
            size.0,
            size.1
        );
    }
    if let Some(path) = &args.points {
        check_points_in_frame(path, &points, first)?;
    }
    if m > vt_io::limits::MAX_VIEWS {
        bail!("{m} views is more than {}", vt_io::limits::MAX_VIEWS);
    }
    let started = Instant::now();
    let mut inputs: Vec<&Path> = args.views.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.points.as_deref());
    let dir = Output::dir(&args.out, OutputKind::Scene, &inputs)?;
    let mut observer = AnalysisObserver::new(dir.path().to_path_buf());
    let mut refs: Vec<&mut dyn vt_core::analysis::FrameSource> =
        sources.iter_mut().map(|s| s.as_source()).collect();
    let analysis = analyze(&mut refs, &points, &params, &mut observer);
    vt_core::analysis::Observer::finish(&mut observer);
    let analysis = analysis.map_err(|e| match (&e, &args.points) {
        (vt_core::Error::DegeneratePoints(_) | vt_core::Error::NonFinite(_), Some(p)) => {
            anyhow::anyhow!("{}: {e}", p.display())
        }
        _ => e.into(),
    })?;
    observer.finish_objects()?;
    for (p, v) in analysis.views.iter().enumerate() {
        write_png(&dir.path().join(background_name(p)), &v.background)?;
    }
    vt_io::scene::write_dynamic(dir.path(), &analysis)?;
    let mut scene = SceneFile::from_analysis(&analysis, &points, &params);
    scene.fps = source_fps(&args.views);
    scene.write(dir.path())?;
    dir.commit()?;
    print_summary(&analysis, &scene, started.elapsed().as_secs_f64());
    println!("scene: {}", args.out.display());
    Ok(AnalyzeResult { scene })
}

/// The views' frame rate: the median of each video's median real frame interval (None for
/// frame folders or when no video has timestamps).
fn source_fps(views: &[PathBuf]) -> Option<f64> {
    let mut rates: Vec<f64> = views
        .iter()
        .filter(|v| v.is_file())
        .filter_map(|v| vt_io::video::median_frame_rate(v).ok().flatten())
        .collect();
    if rates.is_empty() {
        return None;
    }
    rates.sort_by(f64::total_cmp);
    Some(rates[(rates.len() - 1) / 2])
}

/// Refuses marked points outside the frame (beyond [`POINT_MARGIN`] of its size).
fn check_points_in_frame(
    path: &Path,
    points: &[Vec<vt_core::Point>],
    size: (u32, u32),
) -> Result<()> {
    let (w, h) = (size.0 as f64, size.1 as f64);
    let (mx, my) = (POINT_MARGIN * w, POINT_MARGIN * h);
    for (p, view) in points.iter().enumerate() {
        for (k, pt) in view.iter().enumerate() {
            if pt.x < -0.5 - mx || pt.x > w - 0.5 + mx || pt.y < -0.5 - my || pt.y > h - 0.5 + my {
                bail!(
                    "{}: view {p} point {k} ({}, {}) is outside the {}x{} frame (at most {:.0}% beyond its edges)",
                    path.display(),
                    vt_io::output::num(pt.x),
                    vt_io::output::num(pt.y),
                    size.0,
                    size.1,
                    100.0 * POINT_MARGIN
                );
            }
        }
    }
    Ok(())
}

fn print_summary(a: &SceneAnalysis, scene: &SceneFile, total_s: f64) {
    println!(
        "{:>4}  {:>6}  {:>12}  {:>6}  {:>10}  {:>9}  {:>11}  {:>7}  {:>9}  {:>8}",
        "view",
        "frames",
        "loop (m, n)",
        "length",
        "cost",
        "loop seam",
        "switch seam",
        "moving",
        "model",
        "rms px"
    );
    let model = a.model().map(|m| m.name()).unwrap_or("-");
    for (p, v) in a.views.iter().enumerate() {
        let rms = scene.views[p]
            .to_next
            .as_ref()
            .map(|l| format!("{:.3}", l.rms))
            .unwrap_or_else(|| "-".into());
        let switch = scene.views[p]
            .to_next
            .as_ref()
            .map(|l| format!("{:.3}", l.seam))
            .unwrap_or_else(|| "-".into());
        println!(
            "{:>4}  {:>6}  {:>12}  {:>6}  {:>10}  {:>9.3}  {:>11}  {:>6.1}%  {:>9}  {:>8}",
            p,
            v.n_frames,
            format!("({}, {})", v.best_loop.start, v.best_loop.end),
            v.best_loop.len(),
            v.best_loop.cost,
            v.loop_seam,
            switch,
            100.0 * v.moving_fraction,
            if p + 1 < a.views.len() { model } else { "-" },
            rms
        );
    }
    println!(
        "seam score (mean over wraps and switches; 0 = invisible, 1 = one ordinary frame step): {:.3}",
        scene.seam_score
    );
    let kept: Vec<String> = a
        .views
        .iter()
        .map(|v| format!("{:.1}%", 100.0 * v.motion_kept))
        .collect();
    let dynamic: Vec<String> = a
        .views
        .iter()
        .map(|v| format!("{:.1}%", 100.0 * v.dynamic_fraction))
        .collect();
    println!(
        "motion kept (share of the real frame-to-frame change shown at each view): {}; dynamic region: {} of the image",
        kept.join(" "),
        dynamic.join(" ")
    );
    if let Some(sel) = &a.selection {
        let scores: Vec<String> = sel
            .scores
            .iter()
            .map(|(m, s)| format!("{m} {s:.1}"))
            .collect();
        println!(
            "model: {}{} (GRIC: {})",
            sel.model,
            if sel.forced { ", forced" } else { "" },
            scores.join(", ")
        );
    }
    let Timings {
        decode,
        median,
        masks,
        loops,
        homographies,
        transitions,
    } = a.timings;
    println!(
        "time: {total_s:.2} s (decode {:.2}, median {:.2}, masks {:.2}, loops {:.2}, homographies {:.3}, transitions {:.2})",
        decode.as_secs_f64(),
        median.as_secs_f64(),
        masks.as_secs_f64(),
        loops.as_secs_f64(),
        homographies.as_secs_f64(),
        transitions.as_secs_f64()
    );
}

/// Compares a scene with the truth of a synthetic texture scene; returns a printable report and
/// fails when a check fails.
pub fn check_against_truth(truth_path: &Path, result: &AnalyzeResult) -> Result<String> {
    let truth = vt_synth::files::read_truth(truth_path)?;
    let check = vt_synth::files::check_against_truth(&truth, &result.scene)?;
    let report = check.lines.join("\n");
    if !check.pass {
        bail!("the analysis does not match the synthetic truth:\n{report}");
    }
    Ok(report)
}
