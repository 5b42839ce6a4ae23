//! `vt synth real`: a System A test scene with truth made from one real video
//! ([`vt_synth::real`], written by [`vt_synth::files::write_real`]).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use vt_io::frames::ViewSource;
use vt_synth::files::{write_real, RealFiles};
use vt_synth::real::{RealParams, RealScene};

use crate::progress::bar;

#[derive(Args)]
pub struct RealArgs {
    /// The real video (or folder of frames) to build the views from, e.g. testdata/tree.avi.
    source: PathBuf,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Number of views M.
    #[arg(long, default_value_t = 5)]
    views: usize,
    /// Frames per view.
    #[arg(long, default_value_t = 120)]
    frames: usize,
    /// Use only the first N source frames, looped for length (tree.avi: 54, before the hand); 0 = all.
    #[arg(long, default_value_t = 0)]
    usable: usize,
    /// Random seed (offsets, gains, points, marking noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Slant of the textured plane, degrees.
    #[arg(long, default_value_t = 35.0)]
    slant: f64,
    /// Distance between neighbouring cameras (the plane is 1 unit wide, 2 units away).
    #[arg(long, default_value_t = 0.12)]
    baseline: f64,
    /// Largest per-view exposure gain difference (0.06 = gains in 0.94..1.06).
    #[arg(long, default_value_t = 0.06)]
    exposure: f64,
    /// Number of marked points (4 to 8).
    #[arg(long, default_value_t = 6)]
    points: usize,
    /// Gaussian marking noise on every marked coordinate, pixels (standard deviation).
    #[arg(long, default_value_t = 0.0)]
    marking_noise: f64,
    /// H.264 quality (x264 CRF: 0 lossless, 18 visually lossless, 51 worst).
    #[arg(long, default_value_t = 16)]
    crf: u8,
    /// Frames per second of the views (default: the source's median real frame rate).
    #[arg(long)]
    fps: Option<f64>,
    /// Write PNG frame folders instead of H.264 videos.
    #[arg(long)]
    png: bool,
}

pub fn run(a: &RealArgs) -> Result<()> {
    let frames = ViewSource::open(&a.source)?.read_all()?;
    let n_source = frames.len();
    let fps = match a.fps {
        Some(f) if f.is_finite() && f > 0.0 && f <= 1000.0 => f,
        Some(f) => bail!("--fps {f} must be in (0, 1000]"),
        None if a.source.is_file() => vt_io::video::median_frame_rate(&a.source)?.unwrap_or(25.0),
        None => 25.0,
    };
    let params = RealParams {
        views: a.views,
        frames: a.frames,
        usable: a.usable,
        seed: a.seed,
        slant_deg: a.slant,
        baseline: a.baseline,
        exposure: a.exposure,
        points: a.points,
        marking_noise: a.marking_noise,
        ..Default::default()
    };
    let scene = RealScene::new(frames, params)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.source.display()))?;
    let files = RealFiles {
        fps,
        crf: a.crf,
        png: a.png,
    };
    let pb = bar((a.views * a.frames) as u64, "synth real views");
    let source = a.source.display().to_string();
    write_real(&a.out, &scene, &source, &files, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let (w, h) = scene.size();
    println!(
        "wrote {} views x {} frames ({}x{}, {:.3} fps, from {} source frames of {}) to {}",
        a.views,
        a.frames,
        w,
        h,
        fps,
        scene.usable().min(n_source),
        source,
        a.out.display()
    );
    Ok(())
}
