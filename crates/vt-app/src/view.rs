//! A scene served live to the browser (`vt view`, [`vt_view`]).

use std::path::Path;

use vt_core::render::RenderParams;
use vt_io::scene::LoadedScene;
use vt_view::{Viewer, ViewerParams};

use crate::Result;

/// `vt view`'s settings.
#[derive(Debug, Clone, Copy)]
pub struct ViewJob {
    /// Port on 127.0.0.1 (0: any free port).
    pub port: u16,
    /// Frame rate at speed 1 (None: the scene's source frame rate, else 30).
    pub fps: Option<f64>,
    /// Starting viewpoint.
    pub q: f64,
    /// JPEG quality, 1-100.
    pub quality: u8,
    /// The renderer's options.
    pub params: RenderParams,
}

/// Loads the scene at `scene` and binds the viewer (parameters checked by vt-view, which names
/// them); [`Viewer::serve`] then serves until stopped.
pub fn open(scene: &Path, job: &ViewJob) -> Result<Viewer> {
    job.params.check()?;
    let loaded = LoadedScene::open(scene)?;
    let params = ViewerParams {
        port: job.port,
        fps: job
            .fps
            .unwrap_or_else(|| loaded.source_fps(vt_view::MAX_FPS)),
        q: job.q,
        quality: job.quality,
        render: job.params,
    };
    Ok(Viewer::bind(loaded, &scene.display().to_string(), &params)?)
}
