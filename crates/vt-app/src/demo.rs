//! `vt demo`: the whole of System A on a built-in synthetic scene, checked against its truth:
//! synthesise three views, analyse them, compare the scene with the truth, render a sweep. The
//! whole folder is one output, moved into place only when every step succeeded.

use std::path::{Path, PathBuf};

use vt_core::analysis::AnalyzeParams;
use vt_io::output::{Output, OutputKind};
use vt_synth::TextureParams;

use crate::analyze::{AnalyzeJob, Analyzed};
use crate::render::{RenderJob, Rendered};
use crate::{Error, Progress, Result};

/// Frames per view the demo accepts. The scene's motion has a period of 24 frames, and a loop
/// needs a whole period plus the loop search's margin (26 frames pass the truth check, 25 do
/// not), so the lowest accepted count keeps a few frames to spare.
pub const FRAMES: std::ops::RangeInclusive<usize> = 32..=2000;

/// What [`demo`] made; paths are the final ones, under the demo's folder.
pub struct Demo {
    /// The analysis of the synthetic views.
    pub analyzed: Analyzed,
    /// The scene checked against the truth, line by line.
    pub check: String,
    /// The sweep rendered across all views.
    pub rendered: Rendered,
    /// The scene folder.
    pub scene: PathBuf,
    /// The sweep: an mp4, or a folder of PNG frames without ffmpeg.
    pub video: PathBuf,
}

/// Runs the demo into `out` with `frames` frames per view; each step is announced through
/// `progress.note`.
pub fn demo(out: &Path, frames: usize, progress: &mut dyn Progress) -> Result<Demo> {
    if !FRAMES.contains(&frames) {
        return Err(Error::Param {
            name: "frames",
            value: frames.to_string(),
            why: format!("must be in {}..={}", FRAMES.start(), FRAMES.end()),
        });
    }
    let output = Output::dir(out, OutputKind::Demo, &[])?;
    let root = output.path().to_path_buf();
    let data = root.join("textures");
    let params = TextureParams {
        views: 3,
        frames,
        ..Default::default()
    };
    progress.note(&format!(
        "1/3 synthesising a {}-view scene ({} frames of {}x{} each) in {}",
        params.views,
        frames,
        params.width,
        params.height,
        out.join("textures").display()
    ));
    let written = crate::progress::with_ticks(
        progress,
        "synth frames",
        (params.views * frames) as u64,
        |tick| vt_synth::files::write_textures(&data, &params, tick),
    );
    written.map_err(|e| Error::Synth(e.to_string()))?;

    progress.note(&format!(
        "2/3 analysing it into {}",
        out.join("scene").display()
    ));
    let mut analysis = AnalyzeParams {
        alternative_loops: 2,
        ..Default::default()
    };
    analysis.loops.min_length = (frames / 2).clamp(4, 100);
    let job = AnalyzeJob {
        views: (0..params.views)
            .map(|p| data.join(vt_synth::files::view_dir(p)))
            .collect(),
        points: Some(data.join("points.txt")),
        out: root.join("scene"),
        params: analysis,
        fps: None,
        store: Default::default(),
    };
    let analyzed = crate::analyze::analyze(&job, progress)?;
    let check = vt_synth::files::check_scene(&data.join("truth.json"), &analyzed.scene)
        .map_err(|e| Error::Synth(e.to_string()))?;

    // A sweep across all views; mp4 when ffmpeg is there, PNG frames otherwise.
    let video_name = if vt_io::video::ffmpeg_available() {
        "sweep.mp4"
    } else {
        "sweep_frames"
    };
    progress.note(&format!(
        "3/3 rendering a sweep across all views to {}",
        out.join(video_name).display()
    ));
    let render = RenderJob {
        scene: root.join("scene"),
        path: "sweep:0.5".into(),
        out: root.join(video_name),
        fps: Some(30.0),
        duration: None,
        long: false,
        cycle: false,
        params: Default::default(),
        encode: Default::default(),
    };
    let rendered = crate::render::render(&render, progress)?;
    output.commit()?;
    Ok(Demo {
        analyzed,
        check,
        rendered,
        scene: out.join("scene"),
        video: out.join(video_name),
    })
}
