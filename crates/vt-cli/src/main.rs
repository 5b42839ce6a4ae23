//! `vt`: the command-line tool of vt (image-based rendering: viewpoint-varying video textures
//! and free-viewpoint images).

mod analyze;
mod fv;
mod progress;
mod render;
mod synth;
mod synth_real;
mod view;

use std::path::PathBuf;

use clap::{Parser, Subcommand};

/// vt: viewpoint-varying video textures and free-viewpoint images.
#[derive(Parser)]
#[command(name = "vt", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate synthetic scenes with known truth (ray cast).
    Synth {
        #[command(subcommand)]
        what: synth::SynthCommand,
    },
    /// Analyse videos of a scene into a scene directory (System A, offline: A-1..A-3).
    Analyze(analyze::AnalyzeArgs),
    /// Render a scene along a viewpoint path to mp4, GIF or PNG frames (System A, online: eq. 3-6).
    Render(render::RenderArgs),
    /// Live viewer in the browser: move the viewpoint while the video texture plays.
    View(view::ViewArgs),
    /// Free-viewpoint images from calibrated photos (System B).
    Fv {
        #[command(subcommand)]
        what: fv::FvCommand,
    },
    /// Run the whole pipeline on a built-in synthetic scene and check it against its truth.
    Demo {
        /// Where to put the demo's files.
        #[arg(long, default_value = "vt-demo")]
        out: PathBuf,
        /// Frames per view.
        #[arg(long, default_value_t = 160)]
        frames: usize,
    },
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Synth { what } => synth::run(what),
        Command::Analyze(args) => analyze::run(args).map(|_| ()),
        Command::Render(args) => render::run(args).map(|_| ()),
        Command::View(args) => view::run(args),
        Command::Fv { what } => fv::run(what),
        Command::Demo { out, frames } => demo(out, frames),
    };
    if let Err(e) = result {
        // One line: the chain of causes, outermost first.
        let msg: Vec<String> = e.chain().map(|c| c.to_string()).collect();
        eprintln!("error: {}", msg.join(": "));
        std::process::exit(1);
    }
}

/// `vt demo`: synthesise, analyse, and compare with the truth.
fn demo(out: PathBuf, frames: usize) -> anyhow::Result<()> {
    std::fs::create_dir_all(&out).map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
    let data = out.join("textures");
    let params = vt_synth::TextureParams {
        views: 3,
        frames,
        ..Default::default()
    };
    eprintln!(
        "1/2 synthesising a {}-view scene ({} frames of {}x{} each) in {}",
        params.views,
        frames,
        params.width,
        params.height,
        data.display()
    );
    synth::write_textures(&data, &params)?;
    let scene = out.join("scene");
    eprintln!("2/3 analysing it into {}", scene.display());
    let views: Vec<PathBuf> = (0..params.views)
        .map(|p| data.join(synth::view_dir(p)))
        .collect();
    let args =
        analyze::AnalyzeArgs::for_demo(views, data.join("points.txt"), scene.clone(), frames);
    let result = analyze::run(args)?;
    let report = analyze::check_against_truth(&data.join("truth.json"), &result)?;
    println!("{report}");
    // A sweep across all views; mp4 when ffmpeg is there, PNG frames otherwise.
    let has_ffmpeg = std::process::Command::new("ffmpeg")
        .arg("-version")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let video = out.join(if has_ffmpeg {
        "sweep.mp4"
    } else {
        "sweep_frames"
    });
    eprintln!(
        "3/3 rendering a sweep across all views to {}",
        video.display()
    );
    render::run(render::RenderArgs::demo_sweep(scene.clone(), video.clone()))?;
    println!("scene: {}", scene.display());
    println!("video: {}", video.display());
    Ok(())
}
