//! `hd-memory` (run by `cargo xtask bench`): `vt analyze` at default settings on 1080p clips of
//! 300 and 600 frames, its peak resident memory and time, and which loop each view got.
//!
//! The clips are tree.avi's hand-free frames (0-53) upscaled to 1920x1080 and looped, once as
//! they are (an exact repeat: the thesis's loop already wraps as it steps) and once brightening
//! steadily (a drift that never repeats: the thesis's loop shows at its wrap, so the per-region
//! loop is tried and kept), encoded to H.264 by ffmpeg and cached under
//! `target/vt-bench-data/`. The `vt` binary must be built beside this one
//! (`cargo build --release -p vt-cli`). The goal: at most 400 MiB at both lengths.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Result};

#[path = "../clips.rs"]
mod clips;
use clips::{timed, tree_clip};

fn clip(dir: &Path, tree: &Path, frames: usize, drift: bool) -> Result<PathBuf> {
    let name = format!(
        "tree-1080p-{frames}{}.mp4",
        if drift { "-drift" } else { "" }
    );
    let extra = if drift {
        "eq=brightness='0.0008*n-0.12':eval=frame"
    } else {
        ""
    };
    let h264 = ["-c:v", "libx264", "-crf", "18", "-preset", "veryfast"];
    tree_clip(dir, tree, &name, frames, "1920:1080", extra, &h264)
}

fn main() -> Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let vt = std::env::current_exe()?.with_file_name("vt");
    if !vt.exists() {
        bail!(
            "{} is missing: cargo build --release -p vt-cli first",
            vt.display()
        );
    }
    let dir = root.join("target/vt-bench-data");
    std::fs::create_dir_all(&dir)?;
    let tree = root.join("testdata/tree.avi");
    println!("vt analyze at defaults on 1080p clips (tree.avi frames 0-53 upscaled and looped)");
    println!(
        "| clip | frames | peak RSS (MiB) | seconds | loop |\n| --- | --- | --- | --- | --- |"
    );
    for drift in [false, true] {
        for frames in [300, 600] {
            let input = clip(&dir, &tree, frames, drift)?;
            let out = dir.join("hd-memory-scene");
            if out.exists() {
                std::fs::remove_dir_all(&out)?;
            }
            let mut c = Command::new(&vt);
            c.arg("analyze").arg(&input).arg("--out").arg(&out);
            let (secs, peak, summary) = timed(c)?;
            let verdict = summary
                .lines()
                .find(|l| l.contains("per-region loop"))
                .map(|l| {
                    let l = l.trim_start_matches("view 0: ");
                    l.split([';', ',']).next().unwrap_or(l).to_string()
                })
                .unwrap_or_else(|| "thesis's loop".into());
            println!(
                "| {} | {frames} | {:.0} | {secs:.1} | {verdict} |",
                if drift { "brightening" } else { "exact repeat" },
                peak
            );
            std::fs::remove_dir_all(&out).ok();
        }
    }
    println!("goal: peak RSS <= 400 MiB at both lengths");
    Ok(())
}
