//! `vt view`: parses the arguments and serves the scene with vt-view's live viewer (routes,
//! limits and the page are documented in `crates/vt-view`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::flags::flagged;
use crate::progress::Bars;
use crate::render::RenderOptions;

#[derive(Args)]
pub struct ViewArgs {
    /// Scene directory written by `vt analyze`.
    scene: PathBuf,
    /// Port on 127.0.0.1 (0 = any free port; the URL is printed).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Frame rate at speed 1 (default: the scene's source frame rate, else 30).
    #[arg(long)]
    fps: Option<f64>,
    /// Starting viewpoint.
    #[arg(long, default_value_t = 0.0)]
    q: f64,
    /// JPEG quality of the page's moving-object frames and of the fallback stream (1-100).
    #[arg(long, default_value_t = vt_web::DEFAULT_QUALITY)]
    quality: u8,
    /// GPU memory the page may hold decoded moving-object frames in, MB: frames are decoded
    /// around what is shown and the least recently used dropped beyond this.
    #[arg(long, default_value_t = vt_web::DEFAULT_GPU_MB)]
    gpu_mb: u32,
    #[command(flatten)]
    options: RenderOptions,
}

pub fn run(args: ViewArgs) -> Result<()> {
    let job = vt_app::view::ViewJob {
        port: args.port,
        fps: args.fps,
        q: args.q,
        quality: args.quality,
        params: args.options.params(),
        gpu_mb: args.gpu_mb,
    };
    let viewer = vt_app::view::open(&args.scene, &job, &mut Bars::default()).map_err(flagged)?;
    println!(
        "vt view: serving {} at http://127.0.0.1:{}/ (Ctrl-C to stop)",
        args.scene.display(),
        viewer.port()
    );
    std::io::stdout().flush().ok();
    vt_io::output::interrupt_means_stop();
    viewer.serve();
    Ok(())
}
