//! `vt-bench` (run by `cargo xtask bench`): System A's offline analysis at thesis scale, measured
//! side by side with decoding the same frames, plus peak memory.
//!
//! Thesis scale (Table 2): 15 views x 500 frames x 640x360. The synthetic views are ray cast once,
//! encoded to H.264 with ffmpeg and cached under `target/vt-bench-data/`, so later runs time only
//! decoding and analysis. `--quick` uses 3 views x 200 frames.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use vt_core::analysis::{analyze, AnalyzeParams, FrameSource, Quiet};
use vt_core::loops::{find_loop, LoopParams};
use vt_io::frames::VideoSource;
use vt_synth::{TextureParams, TextureScene};

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .map(|l| l.to_string())
        })
        .and_then(|l| {
            l.split_whitespace()
                .nth(1)
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map(|kib| kib / 1024.0)
        .unwrap_or(f64::NAN)
}

fn encode(scene: &TextureScene, view: usize, path: &Path) -> Result<()> {
    let p = scene.params();
    let tmp = path.with_extension("part.mp4");
    let mut child = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24"])
        .args([
            "-s",
            &format!("{}x{}", p.width, p.height),
            "-r",
            "30",
            "-i",
            "-",
        ])
        .args([
            "-c:v", "libx264", "-preset", "veryfast", "-crf", "16", "-pix_fmt", "yuv420p",
        ])
        .arg(&tmp)
        .stdin(Stdio::piped())
        .spawn()
        .context("ffmpeg (apt-get install ffmpeg)")?;
    let mut stdin = child.stdin.take().expect("piped");
    for s in 0..p.frames {
        stdin.write_all(scene.frame(view, s).as_raw())?;
    }
    drop(stdin);
    if !child.wait()?.success() {
        bail!("ffmpeg failed encoding {}", path.display());
    }
    std::fs::rename(&tmp, path)?;
    Ok(())
}

fn main() -> Result<()> {
    let quick = std::env::args().any(|a| a == "--quick");
    let params = if quick {
        TextureParams {
            views: 3,
            frames: 200,
            width: 640,
            height: 360,
            period: 37,
            ..Default::default()
        }
    } else {
        TextureParams {
            views: 15,
            frames: 500,
            width: 640,
            height: 360,
            period: 37,
            baseline: 0.08,
            ..Default::default()
        }
    };
    let scene = TextureScene::new(params).map_err(anyhow::Error::msg)?;
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../target/vt-bench-data")
        .join(format!(
            "{}x{}x{}x{}",
            params.views, params.frames, params.width, params.height
        ));
    std::fs::create_dir_all(&dir)?;
    let videos: Vec<PathBuf> = (0..params.views)
        .map(|p| dir.join(format!("view_{p:02}.mp4")))
        .collect();
    for (p, v) in videos.iter().enumerate() {
        if !v.exists() {
            eprintln!(
                "encoding synthetic view {p} ({} frames) to {}",
                params.frames,
                v.display()
            );
            encode(&scene, p, v)?;
        }
    }
    let points = scene.marked_points();

    println!(
        "System A analysis, {} views x {} frames x {}x{}, {} threads",
        params.views,
        params.frames,
        params.width,
        params.height,
        rayon::current_num_threads()
    );
    // 1. Decoding alone.
    let t = Instant::now();
    let mut frames = 0;
    for v in &videos {
        frames += VideoSource::open(v)?.for_each_frame(&mut |_, _| Ok(()))?;
    }
    let decode = t.elapsed().as_secs_f64();
    let rss_decode = peak_rss_mib();

    // 2. The whole analysis (decoding included; frames cached per view when they fit).
    let mut sources: Vec<VideoSource> = videos
        .iter()
        .map(|v| VideoSource::open(v))
        .collect::<Result<_, _>>()?;
    let mut refs: Vec<&mut dyn FrameSource> = sources
        .iter_mut()
        .map(|s| s as &mut dyn FrameSource)
        .collect();
    let t = Instant::now();
    let loop_params = LoopParams::default();
    let a = analyze(
        &mut refs,
        &points,
        &AnalyzeParams {
            loops: loop_params,
            ..Default::default()
        },
        &mut Quiet,
    )?;
    let total = t.elapsed().as_secs_f64();
    let rss = peak_rss_mib();
    let tm = a.timings;
    let compute = total - tm.decode.as_secs_f64();

    // 3. The loop search of one view on its own.
    let t = Instant::now();
    let l = find_loop(&a.views[0].masks, &loop_params, "view 0")?;
    let one_loop = t.elapsed().as_secs_f64();

    println!("{:<40} {:>10}", "measure", "value");
    let row = |k: &str, v: String| println!("{k:<40} {v:>10}");
    row("frames decoded", frames.to_string());
    row("decode only (s)", format!("{decode:.2}"));
    row("analysis incl. decode (s)", format!("{total:.2}"));
    row(
        "  decode inside analysis (s)",
        format!("{:.2}", tm.decode.as_secs_f64()),
    );
    row("  median (s)", format!("{:.2}", tm.median.as_secs_f64()));
    row(
        "  blur + masks (s)",
        format!("{:.2}", tm.masks.as_secs_f64()),
    );
    row(
        "  loop search, all views (s)",
        format!("{:.2}", tm.loops.as_secs_f64()),
    );
    row(
        "  model + homographies (s)",
        format!("{:.4}", tm.homographies.as_secs_f64()),
    );
    row(
        "  transitions (s)",
        format!("{:.2}", tm.transitions.as_secs_f64()),
    );
    row(
        "analysis compute / decode (ratio)",
        format!("{:.2}", compute / decode),
    );
    row("loop search, one view (s)", format!("{one_loop:.3}"));
    row(
        "peak RSS after decode only (MiB)",
        format!("{rss_decode:.0}"),
    );
    row("peak RSS after analysis (MiB)", format!("{rss:.0}"));
    println!(
        "view 0 loop: ({}, {}) cost {}; true period {}",
        l.start, l.end, l.cost, params.period
    );
    println!("goals: compute/decode <= 1, one-view loop search < 0.5 s, peak RSS < 1536 MiB");
    Ok(())
}
