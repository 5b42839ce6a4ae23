//! `vt`: the command-line tool of vt (image-based rendering: viewpoint-varying video textures
//! and free-viewpoint images).

mod analyze;
mod export;
mod flags;
mod fv;
mod mark;
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
    /// Write a web page that plays a scene in any browser, from disk or a static host (no server).
    Export(export::ExportArgs),
    /// Mark or fix the points that register the views, in the browser; saves a points file.
    Mark(mark::MarkArgs),
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

/// Every command and subcommand takes negative numbers as values (`--point-sigma -1` is a bad
/// value of `--point-sigma`, not an unknown flag `-1`).
fn negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.allow_negative_numbers(true)
        .mut_subcommands(negative_numbers)
}

fn main() {
    use clap::{CommandFactory, FromArgMatches};
    let parsed = negative_numbers(Cli::command())
        .try_get_matches()
        .and_then(|m| Cli::from_arg_matches(&m));
    let cli = match parsed {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            let bare = std::env::args_os().len() <= 1;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion)
                || (bare && e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand)
            {
                e.exit();
            }
            let text = e.to_string();
            let line = if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                // `vt synth`: one line, not the whole help.
                let usage = text
                    .lines()
                    .find_map(|l| l.trim().strip_prefix("Usage: "))
                    .unwrap_or("vt <COMMAND>");
                format!("a subcommand is needed (usage: {usage}; see --help)")
            } else {
                usage_error_line(&text)
            };
            eprintln!("error: {line}");
            std::process::exit(2);
        }
    };
    // Ctrl-C or SIGTERM: remove this run's temporaries and kill its encoders, then exit 130.
    if let Err(e) = vt_io::output::install_interrupt_cleanup() {
        eprintln!("warning: {e}");
    }
    let result = match cli.command {
        Command::Synth { what } => synth::run(what),
        Command::Analyze(args) => analyze::run(args),
        Command::Render(args) => render::run(args),
        Command::View(args) => view::run(args),
        Command::Export(args) => export::run(args),
        Command::Mark(args) => mark::run(args),
        Command::Fv { what } => fv::run(what),
        Command::Demo { out, frames } => demo(out, frames),
    };
    if let Err(e) = result {
        if vt_io::output::interrupted() {
            // The failure came from the interruption removing our temporaries: the handler
            // reports it and exits with 130.
            loop {
                std::thread::sleep(std::time::Duration::from_secs(1));
            }
        }
        eprintln!("error: {}", error_line(&e));
        std::process::exit(1);
    }
}

/// The chain of causes, outermost first, each said once: a cause whose text the message already
/// holds (a wrapper that formats its source and also exposes it) is not repeated.
fn error_line(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if text.is_empty() || msg.contains(&text) {
            continue;
        }
        if text.contains(&msg) && !msg.is_empty() {
            msg = text;
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    msg
}

/// clap's usage error as one line: its first paragraph, with long quoted values shortened.
fn usage_error_line(text: &str) -> String {
    let para: Vec<&str> = text
        .lines()
        .take_while(|l| !l.trim().is_empty())
        .map(str::trim)
        .collect();
    let line = para.join(" ");
    let line = line.strip_prefix("error: ").unwrap_or(&line);
    // Shorten every '...' segment (clap quotes the values it echoes).
    let parts: Vec<&str> = line.split('\'').collect();
    parts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if i % 2 == 1 {
                vt_io::output::shorten(p)
            } else {
                p.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("'")
}

/// `vt demo`: synthesise, analyse, check against the truth, render a sweep (vt-app's demo);
/// prints what `vt analyze` and `vt render` would, with the final paths.
fn demo(out: PathBuf, frames: usize) -> anyhow::Result<()> {
    let done =
        vt_app::demo::demo(&out, frames, &mut progress::Bars::default()).map_err(flags::flagged)?;
    let a = &done.analyzed;
    print!(
        "{}",
        vt_app::analyze::AnalysisSummary {
            analysis: &a.analysis,
            scene: &a.scene,
            total_secs: a.total_secs,
            seams_secs: a.seams_secs,
            stores: &a.stores,
        }
    );
    println!("scene: {}", done.scene.display());
    println!("{}", done.check);
    render::print_rendered(&done.rendered.playback, &done.video);
    println!("video: {}", done.video.display());
    Ok(())
}
