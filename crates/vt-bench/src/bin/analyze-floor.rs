//! `analyze-floor` (run by `cargo xtask bench`): `vt analyze` at defaults against its floor,
//! side by side, on the inputs of issue #34: ffmpeg decoding the same files and encoding them
//! with the object store's x264 settings (`vt_io::objects::x264_args`: ultrafast, constrained
//! baseline, an IDR every 8 frames, one thread) at the finest quantiser, 12, as the issue
//! defines it (the stores' default quality target takes 15-18 on these inputs, which encodes
//! a little faster), which `vt analyze` must do at least. Whole processes, timed in
//! alternating pairs (floor, then vt), medians; with vt's own stage times (seams), the scene's
//! bytes on disk against the source's, and the peak memory.
//!
//! The clips are made once by ffmpeg from testdata/tree.avi and cached under
//! `target/vt-bench-data/`: its hand-free frames (0-53) looped and upscaled, as MPEG-4 part 2 at
//! 1280x720 (260 frames) and 768x576 (800 frames) and as H.264 at 1920x1080 (260 frames); and
//! the 5-view 320x240 scene `vt synth real` makes from it. The `vt` binary must be built beside
//! this one (`cargo build --release -p vt-cli`). `--pairs N` sets the pairs (default 3).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{bail, Context, Result};

/// One input: its name and video files.
struct Input {
    name: String,
    videos: Vec<PathBuf>,
}

#[path = "../clips.rs"]
mod clips;
use clips::{timed, tree_clip};

/// The floor: each video decoded and encoded with the store's x264 settings, one after another.
fn floor(videos: &[PathBuf]) -> Result<f64> {
    let mut total = 0.0;
    for v in videos {
        let mut c = Command::new("ffmpeg");
        c.args(["-v", "error", "-nostdin", "-i"])
            .arg(v)
            .args(vt_io::objects::x264_args(vt_io::objects::MIN_QP))
            .args(["-f", "h264", "-y", "/dev/null"]);
        total += timed(c)?.0;
    }
    Ok(total)
}

fn bytes(path: &Path) -> u64 {
    if path.is_dir() {
        std::fs::read_dir(path)
            .map(|d| d.flatten().map(|e| bytes(&e.path())).sum())
            .unwrap_or(0)
    } else {
        path.metadata().map_or(0, |m| m.len())
    }
}

/// A stage's seconds from vt's summary line `time: T s (stage S, ...)`.
fn stage(summary: &str, name: &str) -> Option<f64> {
    let line = summary.lines().find(|l| l.starts_with("time: "))?;
    let inner = line.split_once('(')?.1.trim_end_matches(')');
    inner.split(", ").find_map(|p| {
        let (n, v) = p.rsplit_once(' ')?;
        (n == name).then(|| v.parse().ok()).flatten()
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let pairs: usize = match args.iter().position(|a| a == "--pairs") {
        Some(i) => args.get(i + 1).context("--pairs N")?.parse()?,
        None => 3,
    };
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
    let mpeg4 = ["-c:v", "mpeg4", "-q:v", "3"];
    let h264 = ["-c:v", "libx264", "-crf", "18", "-preset", "veryfast"];
    let synth = dir.join("tree-5x320x240");
    if !synth.join("view_04.mp4").exists() {
        let part = dir.join("part-tree-5x320x240");
        let _ = std::fs::remove_dir_all(&part);
        let ok = Command::new(&vt)
            .args(["synth", "real"])
            .arg(&tree)
            .arg("--out")
            .arg(&part)
            .stdout(Stdio::null())
            .status()?
            .success();
        if !ok {
            bail!("vt synth real failed");
        }
        std::fs::rename(&part, &synth)?;
    }
    let inputs = [
        Input {
            name: "1280x720 MPEG-4, 260 frames".into(),
            videos: vec![tree_clip(
                &dir,
                &tree,
                "tree-720p-260.avi",
                260,
                "1280:720",
                "",
                &mpeg4,
            )?],
        },
        Input {
            name: "768x576 MPEG-4, 800 frames".into(),
            videos: vec![tree_clip(
                &dir,
                &tree,
                "tree-576p-800.avi",
                800,
                "768:576",
                "",
                &mpeg4,
            )?],
        },
        Input {
            name: "1920x1080 H.264, 260 frames".into(),
            videos: vec![tree_clip(
                &dir,
                &tree,
                "tree-1080p-260.mp4",
                260,
                "1920:1080",
                "",
                &h264,
            )?],
        },
        Input {
            name: "5 views x 120 frames, 320x240 H.264 (vt synth real)".into(),
            videos: (0..5)
                .map(|p| synth.join(format!("view_{p:02}.mp4")))
                .collect(),
        },
    ];
    println!(
        "vt analyze at defaults against the floor (decode + the store's x264 encode), {pairs} alternating pairs, medians, {} threads",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!("| input | floor (s) | vt (s) | vt / floor | seams (share) | scene / source bytes | peak RSS (MiB) |");
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for input in &inputs {
        let out = dir.join("analyze-floor-scene");
        let (mut f, mut v, mut seams, mut peaks) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut scene_bytes = 0;
        for _ in 0..pairs {
            f.push(floor(&input.videos)?);
            if out.exists() {
                std::fs::remove_dir_all(&out)?;
            }
            let mut c = Command::new(&vt);
            c.arg("analyze").args(&input.videos).arg("--out").arg(&out);
            let (secs, peak, summary) = timed(c)?;
            v.push(secs);
            peaks.push(peak);
            seams.push(stage(&summary, "seams").unwrap_or(f64::NAN));
            scene_bytes = bytes(&out);
        }
        std::fs::remove_dir_all(&out).ok();
        let source: u64 = input.videos.iter().map(|p| bytes(p)).sum();
        let (fm, vm, sm) = (median(f), median(v), median(seams));
        println!(
            "| {} | {fm:.2} | {vm:.2} | {:.2}x | {sm:.2} s ({:.0}%) | {:.1}x ({:.1} / {:.1} MB) | {:.0} |",
            input.name,
            vm / fm,
            100.0 * sm / vm,
            scene_bytes as f64 / source.max(1) as f64,
            scene_bytes as f64 / 1e6,
            source as f64 / 1e6,
            median(peaks),
        );
    }
    println!("goals (issue #34): vt <= 1.3x the floor, seams <= 10%, scene <= 3x the source, peak <= 400 MiB at 720p");
    Ok(())
}
