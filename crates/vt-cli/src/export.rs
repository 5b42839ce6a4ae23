//! `vt export`: a scene as a static web page (vt_web) that plays it in the browser, with no
//! server, from disk or any static host.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::flags::flagged;
use crate::progress::Bars;
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
    /// GPU memory the page may hold decoded moving-object frames in, MB: frames are decoded
    /// around what is shown and the least recently used dropped beyond this.
    #[arg(long, default_value_t = vt_web::DEFAULT_GPU_MB)]
    gpu_mb: u32,
    #[command(flatten)]
    options: RenderOptions,
}

pub fn run(args: ExportArgs) -> Result<()> {
    let media = match args.media.as_str() {
        "jpeg" => vt_web::Media::Jpeg {
            quality: args.quality,
        },
        _ => vt_web::Media::H264 { crf: args.crf },
    };
    let job = vt_app::export::ExportJob {
        scene: args.scene,
        out: args.out,
        media,
        params: args.options.params(),
        gpu_mb: args.gpu_mb,
    };
    let done = vt_app::export::export(&job, &mut Bars::default()).map_err(flagged)?;
    let (summary, scene_bytes) = (&done.summary, done.scene_bytes);
    let mb = |b: u64| b as f64 / 1e6;
    let media = if summary.crfs.is_empty() {
        "JPEG".to_string()
    } else {
        let crfs: Vec<String> = summary.crfs.iter().map(u8::to_string).collect();
        format!("H.264 at CRF {}", crfs.join(", "))
    };
    println!(
        "exported {} frames of {} view{} to {} ({} files, {:.2} MB, {:.2} MB of it object frames \
         ({media}); the scene is {:.2} MB, {:.2}x)",
        summary.frames,
        done.views,
        if done.views == 1 { "" } else { "s" },
        job.out.join("index.html").display(),
        summary.files,
        mb(summary.bytes),
        mb(summary.object_bytes),
        mb(scene_bytes),
        summary.bytes as f64 / scene_bytes.max(1) as f64,
    );
    Ok(())
}
