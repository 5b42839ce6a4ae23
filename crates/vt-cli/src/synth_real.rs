//! `vt synth real`: a System A test scene with truth made from one real video
//! ([`vt_synth::real`], written by [`vt_synth::files::write_real`]).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use vt_synth::real::RealParams;

use crate::flags::flagged;
use crate::progress::Bars;

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
    let job = vt_app::synth::SynthRealJob {
        source: a.source.clone(),
        out: a.out.clone(),
        params: RealParams {
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
        },
        fps: a.fps,
        crf: a.crf,
        png: a.png,
    };
    let done = vt_app::synth::real(&job, &mut Bars::default()).map_err(flagged)?;
    let (w, h) = done.size;
    println!(
        "wrote {} views x {} frames ({}x{}, {:.3} fps, from {} source frames of {}) to {}",
        a.views,
        a.frames,
        w,
        h,
        done.fps,
        done.used,
        a.source.display(),
        a.out.display()
    );
    Ok(())
}
