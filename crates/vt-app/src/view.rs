//! A scene served live to the browser (`vt view`, [`vt_view`]).

use std::path::Path;
use std::sync::Arc;

use vt_core::render::RenderParams;
use vt_io::scene::LoadedScene;
use vt_view::{Viewer, ViewerParams};

use crate::{Progress, Result};

/// `vt view`'s settings.
#[derive(Debug, Clone, Copy)]
pub struct ViewJob {
    /// Port on 127.0.0.1 (0: any free port).
    pub port: u16,
    /// Frame rate at speed 1 (None: the scene's source frame rate, else 30).
    pub fps: Option<f64>,
    /// Starting viewpoint.
    pub q: f64,
    /// JPEG quality of the page's object frames and of the fallback stream, 1-100.
    pub quality: u8,
    /// The renderer's options.
    pub params: RenderParams,
    /// GPU memory the page's object frames may hold, MB.
    pub gpu_mb: u32,
}

/// Loads the scene at `scene`, binds the viewer (parameters checked by vt-view, which names
/// them) and builds the page it serves: vt-web's player, the same page `vt export` writes, with
/// the object frames as JPEG at `job.quality` and `/mjpeg` as its fallback. [`Viewer::serve`]
/// then serves until stopped.
pub fn open(scene: &Path, job: &ViewJob, progress: &mut dyn Progress) -> Result<Viewer> {
    job.params.check()?;
    let loaded = Arc::new(LoadedScene::open(scene)?);
    let fps = job
        .fps
        .unwrap_or_else(|| loaded.source_fps(vt_view::MAX_FPS));
    let params = ViewerParams {
        port: job.port,
        fps,
        q: job.q,
        quality: job.quality,
        render: job.params,
    };
    let name = scene.display().to_string();
    let viewer = Viewer::bind(loaded.clone(), &name, &params)?;
    let opts = vt_web::ExportOptions {
        params: job.params,
        media: vt_web::Media::Jpeg {
            quality: job.quality,
        },
        title: crate::export::title(scene),
        fps: Some(fps),
        start_q: Some(job.q),
        fallback: Some("mjpeg".into()),
        gpu_mb: job.gpu_mb,
    };
    progress.start("page", None);
    let mut report = |done: usize, total: usize| progress.at(done as u64, Some(total as u64));
    let (files, _) = vt_web::page(&loaded, &opts, &mut report)?;
    progress.finish();
    Ok(viewer.with_page(files))
}
