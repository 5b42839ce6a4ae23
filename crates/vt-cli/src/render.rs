//! `vt render`: play a scene along a viewpoint path into a video, GIF or PNG folder.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use vt_app::render::RenderJob;
use vt_core::render::RenderParams;
use vt_core::warp::Interpolation;

use crate::flags::flagged;
use crate::progress::Bars;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene directory written by `vt analyze`.
    scene: PathBuf,
    /// Viewpoint path: keyframes `0s:0,4s:14,8s:0` (time:q, linear between), `sweep[:SPEED]`
    /// (0 to M-1 and back at SPEED views per second, default 1), or `@FILE` with one q per line
    /// (one per output frame).
    #[arg(long)]
    path: String,
    /// Output: `.mp4` (H.264), `.gif`, `.apng` (lossless animated PNG), or a folder of PNG frames (no extension).
    #[arg(long)]
    out: PathBuf,
    /// Output frame rate (default: the scene's source frame rate, else 30).
    #[arg(long)]
    fps: Option<f64>,
    /// mp4 quality, x264's CRF 0..=51: lower is closer to the rendered frames and larger. On
    /// the demo's sweep: 18 gives 38.8 dB at 165 KB, 12 40.0 dB at 421 KB, 0 41.0 dB at 2.8 MB
    /// (4:2:0 chroma caps it); PNG frames (`--out` a folder) are exact.
    #[arg(long, default_value_t = vt_io::writer::MP4_CRF)]
    crf: u32,
    /// Total length in seconds (default: the path's own length; keyframe paths then hold their
    /// last q, sweeps go on back and forth).
    #[arg(long)]
    duration: Option<f64>,
    /// Allow a render longer than 10 minutes of output (up to 24 hours).
    #[arg(long)]
    long: bool,
    /// Exactly one cycle of the view's loop at the path's one viewpoint (`--path 0s:0`), so the
    /// file repeats seamlessly where a player loops it (a GIF does by itself; `<video loop>`);
    /// the seam score printed is the file's join.
    #[arg(long)]
    cycle: bool,
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
    /// Replace this many frames after a loop wrap or view switch by in-between frames that
    /// dissolve the last frame into the new sequence (0 = off; for footage that never repeats).
    #[arg(long, default_value_t = 0, conflicts_with = "crossfade")]
    dissolve: usize,
    /// Crossfade the object over this many frames after a view switch only, from the old view's
    /// continuation into the new view (0 = a hard switch, the thesis).
    #[arg(long, default_value_t = vt_core::render::DEFAULT_SWITCH_FADE)]
    switch_fade: usize,
    /// Compensate per-view exposure differences (estimated from the backgrounds; the default).
    #[arg(long)]
    gain_compensation: bool,
    /// Show the static background where the shown view does not see at fractional q, not the
    /// other view's matching frame (the thesis).
    #[arg(long)]
    no_neighbour_fill: bool,
    /// Do not compensate exposure differences (the thesis).
    #[arg(long, conflicts_with = "gain_compensation")]
    no_gain_compensation: bool,
}

impl RenderOptions {
    /// The renderer's parameters these flags describe (checked by `RenderParams::check`).
    pub fn params(&self) -> RenderParams {
        RenderParams {
            interpolation: if self.nearest {
                Interpolation::Nearest
            } else {
                Interpolation::Bilinear
            },
            crossfade: self.crossfade,
            dissolve: self.dissolve,
            switch_fade: self.switch_fade,
            neighbour_fill: !self.no_neighbour_fill,
            gain_compensation: self.gain_compensation || !self.no_gain_compensation,
            ..RenderParams::default()
        }
    }
}

pub fn run(args: RenderArgs) -> Result<()> {
    let job = RenderJob {
        scene: args.scene,
        path: args.path,
        out: args.out.clone(),
        fps: args.fps,
        duration: args.duration,
        long: args.long,
        cycle: args.cycle,
        params: args.options.params(),
        encode: vt_io::writer::EncodeParams { crf: args.crf },
    };
    let done = vt_app::render::render(&job, &mut Bars::default()).map_err(flagged)?;
    if args.cycle {
        // The one wrap the player made is the file's join, not in the file.
        let join = match done.playback.mean_seam {
            Some(m) => format!("seam score {m:.3}, 1 = as large as an ordinary step"),
            None => "not measured".into(),
        };
        println!(
            "rendered {} frames to {}: one cycle of the loop, whose join when it repeats has {join}",
            done.playback.frames,
            args.out.display()
        );
    } else {
        print_rendered(&done.playback, &args.out);
    }
    Ok(())
}

/// `vt render`'s line: frames, where, jumps and their seam score (the same score as `vt
/// analyze` prints, [`vt_core::seam`]'s, over this render's own frames).
pub fn print_rendered(played: &vt_app::play::Playback, shown: &Path) {
    let seam = match played.mean_seam {
        Some(m) => format!(
            "seam score {m:.3} over {} jumps (1 = as large as the ordinary steps it stands in for)",
            played.measured
        ),
        None => "no jumps".into(),
    };
    println!(
        "rendered {} frames to {} ({} loop wraps, {} view switches, {seam})",
        played.frames,
        shown.display(),
        played.wraps,
        played.switches,
    );
}
