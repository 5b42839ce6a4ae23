//! A viewpoint path rendered into an mp4, a GIF or a folder of PNG frames (`vt render`).

use std::path::{Path, PathBuf};

use vt_core::render::RenderParams;
use vt_io::scene::LoadedScene;
use vt_io::writer::{EncodeParams, FrameWriter};

use crate::play::{play, Playback};
use crate::{Error, Progress, Result};

/// `vt render`'s job.
#[derive(Debug, Clone)]
pub struct RenderJob {
    /// The scene directory.
    pub scene: PathBuf,
    /// The viewpoint path as [`vt_io::path::viewpoints`] reads it: keyframes, `sweep[:SPEED]`
    /// or `@FILE`.
    pub path: String,
    /// The output: `.mp4`, `.gif`, or a folder of PNG frames.
    pub out: PathBuf,
    /// Output frame rate (None: the scene's source frame rate, else 30).
    pub fps: Option<f64>,
    /// Total length in seconds (None: the path's own length).
    pub duration: Option<f64>,
    /// Allow more than 10 minutes of output.
    pub long: bool,
    /// Exactly one cycle of the shown view's loop at the path's one viewpoint, so that the file
    /// repeats seamlessly: it starts where the player starts after a wrap and ends on the
    /// frame before the wrap (with `duration` None and no crossfade or dissolve).
    pub cycle: bool,
    /// The renderer's options.
    pub params: RenderParams,
    /// The mp4 encoder's options.
    pub encode: EncodeParams,
}

/// Highest output frame rate, frames per second.
pub const MAX_FPS: f64 = 1000.0;

impl RenderJob {
    /// Checks the renderer's and the encoder's options (before any file is touched).
    pub fn check(&self) -> Result<()> {
        self.params.check()?;
        if self.cycle {
            let clash = if self.duration.is_some() {
                Some(("duration", "the cycle's length is the loop's"))
            } else if self.params.crossfade > 0 {
                Some(("crossfade", "it blends frames from before the file's start"))
            } else if self.params.dissolve > 0 {
                Some(("dissolve", "it blends frames from before the file's start"))
            } else {
                None
            };
            if let Some((name, why)) = clash {
                return Err(Error::Param {
                    name,
                    value: "with --cycle".into(),
                    why: why.into(),
                });
            }
        }
        self.encode.check().map_err(|why| Error::Param {
            name: "crf",
            value: self.encode.crf.to_string(),
            why,
        })?;
        Ok(())
    }
}

/// What [`render`] wrote.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The playback's counts and seam score.
    pub playback: Playback,
    /// The frame rate written.
    pub fps: f64,
    /// The file or folder written.
    pub out: PathBuf,
}

/// Renders `job.path` over the scene into `job.out` (atomic: a failed render leaves nothing).
pub fn render(job: &RenderJob, progress: &mut dyn Progress) -> Result<Rendered> {
    job.check()?;
    let scene = LoadedScene::open(&job.scene)?;
    let fps = job.fps.unwrap_or_else(|| scene.source_fps(MAX_FPS));
    let mut qs = vt_io::path::viewpoints(
        &job.path,
        scene.render.views.len(),
        fps,
        job.duration,
        job.long,
    )?;
    // One cycle: the loop's frames once, and one frame more, the wrap, rendered for the seam
    // meter only (the file's join when it repeats) and not written.
    let written = if job.cycle {
        let q = qs[0];
        if qs.iter().any(|&x| x != q) {
            return Err(Error::Param {
                name: "path",
                value: job.path.clone(),
                why: "--cycle plays one view at one viewpoint: give one, e.g. 0s:0".into(),
            });
        }
        let v = &scene.render.views[vt_core::render::split_q(q).nearest];
        let length = v.loop_end - v.loop_start;
        qs = vec![q; length + 1];
        length
    } else {
        qs.len()
    };
    let (w, h) = (scene.file.width, scene.file.height);
    let mut inputs: Vec<&Path> = vec![job.scene.as_path()];
    if let Some(f) = job.path.strip_prefix('@') {
        inputs.push(Path::new(f));
    }
    let mut sink = FrameWriter::create_with(&job.out, &inputs, w, h, fps, &job.encode)?;
    progress.start("render", Some(written as u64));
    let mut done = 0;
    let mut playback = play(&scene, &qs, job.params, &mut |frame, _| -> Result<()> {
        if done == written {
            return Ok(());
        }
        done += 1;
        progress.at(done as u64, None);
        Ok(sink.write(frame)?)
    })?;
    playback.frames = written;
    progress.finish();
    let out = sink.finish()?;
    Ok(Rendered { playback, fps, out })
}
