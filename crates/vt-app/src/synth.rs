//! Synthetic scenes with their truth, made from a user's own video (`vt synth real`): the views a
//! System A test needs, from one real clip.

use std::path::PathBuf;

use vt_io::frames::ViewSource;
use vt_synth::files::{write_real, RealFiles};
use vt_synth::real::{RealParams, RealScene};

use crate::{Error, Progress, Result};

/// `vt synth real`'s job.
#[derive(Debug, Clone)]
pub struct SynthRealJob {
    /// The real video (or folder of frames) the views are made from.
    pub source: PathBuf,
    /// The output folder.
    pub out: PathBuf,
    /// The scene: views, frames, plane, offsets, gains, points, marking noise.
    pub params: RealParams,
    /// Frames per second of the views (None: the source's median real frame rate, else 25).
    pub fps: Option<f64>,
    /// H.264 quality of the views (x264 CRF).
    pub crf: u8,
    /// PNG frame folders instead of videos.
    pub png: bool,
}

/// Highest frame rate of the views.
pub const MAX_FPS: f64 = 1000.0;

/// What [`real`] wrote.
#[derive(Debug, Clone, Copy)]
pub struct SynthReal {
    /// The views' frame size.
    pub size: (u32, u32),
    /// Their frame rate.
    pub fps: f64,
    /// Source frames used (looped for length).
    pub used: usize,
}

/// Reads the source, builds the scene and writes its views and truth (atomic).
pub fn real(job: &SynthRealJob, progress: &mut dyn Progress) -> Result<SynthReal> {
    if let Some(f) = job.fps {
        if !(f.is_finite() && f > 0.0 && f <= MAX_FPS) {
            return Err(Error::Param {
                name: "fps",
                value: f.to_string(),
                why: format!("must be in (0, {MAX_FPS}]"),
            });
        }
    }
    let (mut source, rate) = ViewSource::open_timed(&job.source)?;
    let frames = source.read_all()?;
    let n_source = frames.len();
    let fps = job.fps.or(rate).unwrap_or(25.0);
    let scene = RealScene::new(frames, job.params).map_err(|e| Error::In {
        what: job.source.display().to_string(),
        cause: Box::new(Error::Synth(e.to_string())),
    })?;
    let files = RealFiles {
        fps,
        crf: job.crf,
        png: job.png,
    };
    let p = &job.params;
    let source = job.source.display().to_string();
    let written = crate::progress::with_ticks(
        progress,
        "synth real views",
        (p.views * p.frames) as u64,
        |tick| write_real(&job.out, &scene, &source, &files, tick),
    );
    written.map_err(|e| Error::Synth(e.to_string()))?;
    Ok(SynthReal {
        size: scene.size(),
        fps,
        used: scene.usable().min(n_source),
    })
}
