//! `vt export`: a scene as a static web page (vt_web) that plays it in the browser, with no
//! server, from disk or any static host.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use vt_io::scene::LoadedScene;

use crate::progress::bar;
use crate::render::RenderOptions;

#[derive(Args)]
pub struct ExportArgs {
    /// Scene directory written by `vt analyze`.
    scene: PathBuf,
    /// Output folder: index.html and data/ (open index.html in a browser).
    #[arg(long)]
    out: PathBuf,
    /// How the moving-object frames are stored: h264 (one video per view, decoded by the
    /// browser's WebCodecs; needs ffmpeg here) or jpeg (one image per frame: larger, for browsers
    /// without WebCodecs).
    #[arg(long, default_value = "h264", value_parser = ["h264", "jpeg"])]
    media: String,
    /// H.264 constant rate factor with --media h264, 0-51 (lower: better and larger). Default:
    /// per view, the largest that keeps the moving pixels at 42 dB or more against the scene's.
    #[arg(long)]
    crf: Option<u8>,
    /// JPEG quality with --media jpeg, 1-100.
    #[arg(long, default_value_t = vt_web::DEFAULT_QUALITY)]
    quality: u8,
    #[command(flatten)]
    options: RenderOptions,
}

pub fn run(args: ExportArgs) -> Result<()> {
    args.options.check()?;
    let media = match args.media.as_str() {
        "jpeg" => vt_web::Media::Jpeg {
            quality: args.quality,
        },
        _ => vt_web::Media::H264 { crf: args.crf },
    };
    // Checked before any work, named as the flag that sets it.
    media.check().map_err(|e| match e {
        vt_web::Error::InvalidParameter { name, value, why } => {
            anyhow::anyhow!("--{name} {value}: {why}")
        }
        e => e.into(),
    })?;
    let scene = LoadedScene::open(&args.scene)?;
    let title = args
        .scene
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "scene".into());
    let opts = vt_web::ExportOptions {
        params: args.options.params(),
        media,
        title,
    };
    let pb = bar(0, "export");
    let summary = vt_web::export(&scene, &args.scene, &args.out, &opts, &mut |done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    })?;
    pb.finish_and_clear();
    let scene_bytes = vt_web::folder_bytes(&args.scene)?;
    let mb = |b: u64| b as f64 / 1e6;
    let media = if summary.crfs.is_empty() {
        "JPEG".to_string()
    } else {
        let crfs: Vec<String> = summary.crfs.iter().map(u8::to_string).collect();
        format!("H.264 at CRF {}", crfs.join(", "))
    };
    println!(
        "exported {} frames of {} views to {} ({} files, {:.2} MB, {:.2} MB of it object frames \
         ({media}); the scene is {:.2} MB, {:.2}x)",
        summary.frames,
        scene.render.views.len(),
        args.out.join("index.html").display(),
        summary.files,
        mb(summary.bytes),
        mb(summary.object_bytes),
        mb(scene_bytes),
        summary.bytes as f64 / scene_bytes.max(1) as f64,
    );
    Ok(())
}
