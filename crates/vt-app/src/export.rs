//! A scene as a static web page that plays it in any browser (`vt export`, [`vt_web`]).

use std::path::{Path, PathBuf};

use vt_core::render::RenderParams;
use vt_io::scene::LoadedScene;

use crate::{Progress, Result};

/// `vt export`'s job.
#[derive(Debug, Clone)]
pub struct ExportJob {
    /// The scene directory.
    pub scene: PathBuf,
    /// The output folder (index.html and data/).
    pub out: PathBuf,
    /// How the object frames are encoded.
    pub media: vt_web::Media,
    /// The render parameters the page plays with.
    pub params: RenderParams,
    /// GPU memory the page's object frames may hold, MB.
    pub gpu_mb: u32,
}

/// What [`export`] wrote.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The page's summary (files, bytes, the CRF chosen per view).
    pub summary: vt_web::ExportSummary,
    /// Views of the scene.
    pub views: usize,
    /// Bytes of the scene folder, to compare with the page's.
    pub scene_bytes: u64,
}

/// A page's title: the scene folder's name.
pub(crate) fn title(scene: &Path) -> String {
    scene
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "scene".into())
}

/// Writes the page for `job.scene` into `job.out`; options are checked before any work.
pub fn export(job: &ExportJob, progress: &mut dyn Progress) -> Result<Exported> {
    job.media.check()?;
    job.params.check()?;
    let scene = LoadedScene::open(&job.scene)?;
    let opts = vt_web::ExportOptions {
        params: job.params,
        media: job.media,
        title: title(&job.scene),
        gpu_mb: job.gpu_mb,
        ..vt_web::ExportOptions::default()
    };
    progress.start("export", None);
    let mut report = |done: usize, total: usize| progress.at(done as u64, Some(total as u64));
    let summary = vt_web::export(&scene, &job.scene, &job.out, &opts, &mut report)?;
    progress.finish();
    Ok(Exported {
        summary,
        views: scene.render.views.len(),
        scene_bytes: vt_web::folder_bytes(&job.scene)?,
    })
}
