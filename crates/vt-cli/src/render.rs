//! `vt render`: play a scene along a viewpoint path into a video, GIF or PNG folder.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::Args;
use image::RgbImage;
use vt_core::render::{Player, RenderParams, Renderer, Step};
use vt_core::warp::Interpolation;
use vt_io::scene::LoadedScene;
use vt_io::writer::FrameWriter;

use crate::progress::bar;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene directory written by `vt analyze`.
    scene: PathBuf,
    /// Viewpoint path: keyframes `0s:0,4s:14,8s:0` (time:q, linear between), `sweep[:SPEED]`
    /// (0 to M-1 and back at SPEED views per second, default 1), or `@FILE` with one q per line
    /// (one per output frame).
    #[arg(long)]
    path: String,
    /// Output: `.mp4` (H.264), `.gif`, or a folder of PNG frames (no extension).
    #[arg(long)]
    out: PathBuf,
    /// Output frame rate (default: the scene's source frame rate, else 30).
    #[arg(long)]
    fps: Option<f64>,
    /// Total length in seconds (default: the path's own length; keyframe paths then hold their
    /// last q, sweeps go on back and forth).
    #[arg(long)]
    duration: Option<f64>,
    /// Allow a render longer than 10 minutes of output (up to 24 hours).
    #[arg(long)]
    long: bool,
    #[command(flatten)]
    options: RenderOptions,
}

/// Rendering options shared by `vt render` and `vt view`.
#[derive(Args, Clone)]
pub struct RenderOptions {
    /// Nearest-neighbour warping (faster) instead of bilinear.
    #[arg(long)]
    nearest: bool,
    /// Crossfade the object over this many frames after a loop wrap or view switch (0 = off).
    #[arg(long, default_value_t = 0)]
    crossfade: usize,
    /// Compensate per-view exposure differences (estimated from the backgrounds; the default).
    #[arg(long)]
    gain_compensation: bool,
    /// Do not compensate exposure differences (the thesis).
    #[arg(long, conflicts_with = "gain_compensation")]
    no_gain_compensation: bool,
}

/// Longest `--crossfade`, frames (the renderer's own limit).
pub const MAX_CROSSFADE: usize = vt_core::render::MAX_CROSSFADE;

impl RenderOptions {
    /// Checks the options against their limits.
    pub fn check(&self) -> Result<()> {
        if self.crossfade > MAX_CROSSFADE {
            bail!(
                "--crossfade {} is more than {MAX_CROSSFADE} frames",
                self.crossfade
            );
        }
        Ok(())
    }

    pub fn params(&self) -> RenderParams {
        RenderParams {
            interpolation: if self.nearest {
                Interpolation::Nearest
            } else {
                Interpolation::Bilinear
            },
            crossfade: self.crossfade,
            gain_compensation: self.gain_compensation || !self.no_gain_compensation,
        }
    }
}

impl RenderArgs {
    /// The demo's sweep across all views.
    pub fn demo_sweep(scene: PathBuf, out: PathBuf) -> Self {
        Self {
            scene,
            path: "sweep:0.5".into(),
            out,
            fps: Some(30.0),
            duration: None,
            long: false,
            options: RenderOptions {
                nearest: false,
                crossfade: 0,
                gain_compensation: true,
                no_gain_compensation: false,
            },
        }
    }
}

/// Counts and seams of a render.
pub struct RenderSummary {
    pub frames: usize,
    pub wraps: u64,
    pub switches: u64,
    pub mean_seam: f64,
}

pub fn run(args: RenderArgs) -> Result<RenderSummary> {
    args.options.check()?;
    let scene = LoadedScene::open(&args.scene)?;
    let fps = args
        .fps
        .or(scene
            .file
            .fps
            .filter(|f| f.is_finite() && *f > 0.0 && *f <= 1000.0))
        .unwrap_or(30.0);
    let qs = vt_io::path::viewpoints(
        &args.path,
        scene.render.views.len(),
        fps,
        args.duration,
        args.long,
    )?;
    let mut renderer = Renderer::new(scene.render.clone(), args.options.params())?;
    let (w, h) = renderer.size();
    let mut inputs: Vec<&Path> = vec![args.scene.as_path()];
    if let Some(f) = args.path.strip_prefix('@') {
        inputs.push(Path::new(f));
    }
    let mut sink = FrameWriter::create(&args.out, &inputs, w, h, fps)?;
    let mut player = Player::new();
    let mut frame = RgbImage::new(w, h);
    let mut seams = Vec::new();
    let mask_steps = scene.mask_steps();
    let pb = bar(qs.len() as u64, "render");
    // On a rayon worker, the renderer's parallel passes queue locally: no allocation per frame.
    rayon::scope(|_| -> Result<()> {
        for &q in &qs {
            let choice = player.advance(&scene.render, q)?;
            if matches!(choice.step, Step::Wrap | Step::Switch { .. }) {
                seams.extend(scene.jump_seam(&choice, &mask_steps));
            }
            renderer.render_into(&scene.objects, q, &choice, &mut frame)?;
            sink.write(&frame)?;
            pb.inc(1);
        }
        Ok(())
    })?;
    pb.finish_and_clear();
    sink.finish()?;
    let summary = RenderSummary {
        frames: qs.len(),
        wraps: player.wraps,
        switches: player.switches,
        mean_seam: seams.iter().sum::<f64>() / seams.len().max(1) as f64,
    };
    println!(
        "rendered {} frames to {} ({} loop wraps, {} view switches, mean seam score {:.3})",
        summary.frames,
        args.out.display(),
        summary.wraps,
        summary.switches,
        summary.mean_seam
    );
    Ok(summary)
}
