//! `vt view`: parses the arguments and serves the scene with vt-view's live viewer (routes,
//! limits and the page are documented in `crates/vt-view`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use vt_io::scene::LoadedScene;
use vt_view::{Viewer, ViewerParams};

use crate::render::RenderOptions;

/// Fastest frame rate the viewer streams at speed 1.
const MAX_FPS: f64 = 240.0;

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
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = 85)]
    quality: u8,
    #[command(flatten)]
    options: RenderOptions,
}

pub fn run(args: ViewArgs) -> Result<()> {
    use vt_io::output::num;
    if let Some(fps) = args
        .fps
        .filter(|f| !(f.is_finite() && *f > 0.0 && *f <= MAX_FPS))
    {
        bail!("--fps {} must be in (0, {MAX_FPS}]", num(fps));
    }
    if !(1..=100).contains(&args.quality) {
        bail!("--quality {} must be in 1..=100", args.quality);
    }
    args.options.check()?;
    let scene = LoadedScene::open(&args.scene)?;
    if scene.render.check_q(args.q).is_err() {
        bail!(
            "--q {} is outside [0, {}] (the scene has {} views)",
            num(args.q),
            scene.render.q_max(),
            scene.render.views.len()
        );
    }
    let fps = args
        .fps
        .or(scene
            .file
            .fps
            .filter(|f| f.is_finite() && *f > 0.0 && *f <= MAX_FPS))
        .unwrap_or(30.0);
    let params = ViewerParams {
        port: args.port,
        fps,
        q: args.q,
        quality: args.quality,
        render: args.options.params(),
    };
    let viewer =
        Viewer::bind(scene, &args.scene.display().to_string(), &params).map_err(|e| match e {
            vt_view::Error::Listen { port, cause } => {
                anyhow::anyhow!("--port {port}: cannot listen on 127.0.0.1: {cause}")
            }
            e => e.into(),
        })?;
    println!(
        "vt view: serving {} at http://127.0.0.1:{}/ (Ctrl-C to stop)",
        args.scene.display(),
        viewer.port()
    );
    std::io::stdout().flush().ok();
    viewer.serve();
    Ok(())
}
