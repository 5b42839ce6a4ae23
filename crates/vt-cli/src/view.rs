//! `vt view`: parses the arguments and serves the scene with vt-view's live viewer (routes,
//! limits and the page are documented in `crates/vt-view`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Args;
use vt_io::scene::LoadedScene;
use vt_view::{Viewer, ViewerParams, MAX_FPS};

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
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = 85)]
    quality: u8,
    #[command(flatten)]
    options: RenderOptions,
}

pub fn run(args: ViewArgs) -> Result<()> {
    args.options.check()?;
    let scene = LoadedScene::open(&args.scene)?;
    let params = ViewerParams {
        port: args.port,
        fps: args.fps.unwrap_or_else(|| scene.source_fps(MAX_FPS)),
        q: args.q,
        quality: args.quality,
        render: args.options.params(),
    };
    let name = args.scene.display().to_string();
    // The viewer checks its parameters; they are this command's flags of the same names.
    let viewer = Viewer::bind(scene, &name, &params).map_err(|e| match e {
        vt_view::Error::Param { name, value, why } => anyhow!("--{name} {value} {why}"),
        vt_view::Error::Listen { port, cause } => {
            anyhow!("--port {port}: cannot listen on 127.0.0.1: {cause}")
        }
        e => e.into(),
    })?;
    println!(
        "vt view: serving {name} at http://127.0.0.1:{}/ (Ctrl-C to stop)",
        viewer.port()
    );
    std::io::stdout().flush().ok();
    vt_io::output::interrupt_means_stop();
    viewer.serve();
    Ok(())
}
