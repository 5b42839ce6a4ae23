//! `vt synth ...`: write synthetic scenes with their truth.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Args, Subcommand};
use vt_synth::object::RingParams;
use vt_synth::{Rig, TextureParams};

use crate::progress::bar;

#[derive(Subcommand)]
pub enum SynthCommand {
    /// System A test scene: M cameras on a line filming a swaying planar object, asynchronously.
    Textures(TexturesArgs),
    /// System B test object: a textured sphere and box photographed from a ring of calibrated
    /// cameras, with masks and ground truth for extra viewpoints.
    Object(ObjectArgs),
    /// System A test scene from a real video: M views of a slanted plane textured with the video,
    /// known homographies, clock offsets, gains and marking noise, encoded to H.264, with truth.
    Real(crate::synth_real::RealArgs),
}

#[derive(Args)]
pub struct ObjectArgs {
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Cameras on the ring (paper: 8).
    #[arg(long, default_value_t = 8)]
    views: usize,
    /// Square image side in pixels (paper: 400).
    #[arg(long, default_value_t = 400)]
    size: u32,
    /// Seed: turns the whole ring by a seed-determined angle (0: first camera at angle 0).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

#[derive(Args)]
pub struct TexturesArgs {
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Number of views M.
    #[arg(long, default_value_t = 3)]
    views: usize,
    /// Frames per view.
    #[arg(long, default_value_t = 150)]
    frames: usize,
    /// Frame size, WxH.
    #[arg(long, default_value = "320x180", value_parser = vt_io::limits::parse_size)]
    size: (u32, u32),
    /// Motion period in frames.
    #[arg(long, default_value_t = 24)]
    period: usize,
    /// Random seed (same seed, same bytes).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Camera rig: parallel (views differ by a translation) or converging (a homography).
    #[arg(long, default_value = "parallel", value_parser = <Rig as std::str::FromStr>::from_str)]
    rig: Rig,
    /// Put the background on the object's plane, so one homography explains the whole scene.
    #[arg(long)]
    planar: bool,
    /// Sensor noise, grey levels.
    #[arg(long, default_value_t = 2.0)]
    noise: f64,
    /// Largest per-view exposure gain difference (0.04 = up to +-4%).
    #[arg(long, default_value_t = 0.04)]
    exposure: f64,
}

pub fn run(cmd: SynthCommand) -> Result<()> {
    match cmd {
        SynthCommand::Real(a) => crate::synth_real::run(&a),
        SynthCommand::Object(a) => {
            let ring = RingParams {
                views: a.views,
                size: a.size,
                seed: a.seed,
            };
            let pb = bar(1, "ray casting");
            vt_synth::files::write_object(&a.out, &ring)?;
            pb.finish_and_clear();
            println!(
                "wrote {} views of {}x{} (+ truth) to {}",
                a.views,
                a.size,
                a.size,
                a.out.display()
            );
            Ok(())
        }
        SynthCommand::Textures(a) => {
            let params = TextureParams {
                views: a.views,
                frames: a.frames,
                width: a.size.0,
                height: a.size.1,
                period: a.period,
                seed: a.seed,
                rig: a.rig,
                planar: a.planar,
                noise: a.noise,
                exposure: a.exposure,
                ..Default::default()
            };
            write_textures(&a.out, &params)?;
            println!(
                "wrote {} views x {} frames to {}",
                a.views,
                a.frames,
                a.out.display()
            );
            Ok(())
        }
    }
}

/// Writes a texture scene into `out` (checked against the limits first), with a progress bar.
pub fn write_textures(out: &Path, params: &TextureParams) -> Result<()> {
    let pb = bar(
        params.views.saturating_mul(params.frames) as u64,
        "synth frames",
    );
    vt_synth::files::write_textures(out, params, &|| pb.inc(1))?;
    pb.finish_and_clear();
    Ok(())
}
