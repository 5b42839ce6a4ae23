//! `vt synth real`: a System A test scene with truth made from one real video
//! ([`vt_synth::real`]): `view_NN.mp4` (H.264) or `view_NN/` PNG folders, `points.txt` (marked
//! points, with the asked marking noise), `truth.json` ([`vt_synth::real::RealTruth`]) and
//! `truth/` with ideal views at half-view steps.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use image::RgbImage;
use vt_io::atomic::AtomicDir;
use vt_io::frames::{write_png, ViewSource};
use vt_synth::real::{rows, IdealView, RealParams, RealScene};

use crate::progress::bar;

#[derive(Args)]
pub struct RealArgs {
    /// The real video (or folder of frames) to build the views from, e.g. testdata/tree.avi.
    source: PathBuf,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Number of views M.
    #[arg(long, default_value_t = 5)]
    views: usize,
    /// Frames per view.
    #[arg(long, default_value_t = 120)]
    frames: usize,
    /// Use only the first N source frames, looped for length (tree.avi: 54, before the hand); 0 = all.
    #[arg(long, default_value_t = 0)]
    usable: usize,
    /// Random seed (offsets, gains, points, marking noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Slant of the textured plane, degrees.
    #[arg(long, default_value_t = 35.0)]
    slant: f64,
    /// Distance between neighbouring cameras (the plane is 1 unit wide, 2 units away).
    #[arg(long, default_value_t = 0.12)]
    baseline: f64,
    /// Largest per-view exposure gain difference (0.06 = gains in 0.94..1.06).
    #[arg(long, default_value_t = 0.06)]
    exposure: f64,
    /// Number of marked points (4 to 8).
    #[arg(long, default_value_t = 6)]
    points: usize,
    /// Gaussian marking noise on every marked coordinate, pixels (standard deviation).
    #[arg(long, default_value_t = 0.0)]
    marking_noise: f64,
    /// H.264 quality (x264 CRF: 0 lossless, 18 visually lossless, 51 worst).
    #[arg(long, default_value_t = 16)]
    crf: u8,
    /// Frames per second of the views (default: the source's median real frame rate).
    #[arg(long)]
    fps: Option<f64>,
    /// Write PNG frame folders instead of H.264 videos.
    #[arg(long)]
    png: bool,
}

/// Decodes every frame of a video or frame folder.
pub fn read_all_frames(path: &std::path::Path) -> Result<Vec<RgbImage>> {
    let mut src = ViewSource::open(path)?;
    let mut frames = Vec::new();
    src.as_source().for_each_frame(&mut |_, f| {
        frames.push(f.clone());
        Ok(())
    })?;
    Ok(frames)
}

pub fn run(a: &RealArgs) -> Result<()> {
    let frames = read_all_frames(&a.source)?;
    let n_source = frames.len();
    let fps = match a.fps {
        Some(f) if f.is_finite() && f > 0.0 && f <= 1000.0 => f,
        Some(f) => bail!("--fps {f} must be in (0, 1000]"),
        None if a.source.is_file() => vt_io::video::median_frame_rate(&a.source)?.unwrap_or(25.0),
        None => 25.0,
    };
    let params = RealParams {
        views: a.views,
        frames: a.frames,
        usable: a.usable,
        seed: a.seed,
        slant_deg: a.slant,
        baseline: a.baseline,
        exposure: a.exposure,
        points: a.points,
        marking_noise: a.marking_noise,
        ..Default::default()
    };
    let scene = RealScene::new(frames, params)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.source.display()))?;
    let (w, h) = scene.size();
    let dir = AtomicDir::create(&a.out)?;
    let root = dir.path().to_path_buf();
    let pb = bar((a.views * a.frames) as u64, "synth real views");
    for p in 0..a.views {
        if a.png {
            let vdir = root.join(vt_synth::files::view_dir(p));
            std::fs::create_dir(&vdir).with_context(|| vdir.display().to_string())?;
            for s in 0..a.frames {
                write_png(&vdir.join(format!("frame_{s:05}.png")), &scene.frame(p, s))?;
                pb.inc(1);
            }
        } else {
            let file = root.join(format!("{}.mp4", vt_synth::files::view_dir(p)));
            vt_io::video::encode_h264(&file, w, h, fps, a.crf, a.frames, &mut |s| {
                pb.inc(1);
                Ok(scene.frame(p, s))
            })?;
        }
    }
    pb.finish_and_clear();
    let to_points = |pts: Vec<(f64, f64)>| -> Vec<vt_core::Point> {
        pts.into_iter()
            .map(|(x, y)| vt_core::Point::new(x, y))
            .collect()
    };
    let marked: Vec<_> = (0..a.views)
        .map(|p| to_points(scene.marked_points(p)))
        .collect();
    std::fs::write(
        root.join("points.txt"),
        vt_io::points::format_points(&marked),
    )
    .context("points.txt")?;
    let tdir = root.join("truth");
    std::fs::create_dir(&tdir).context("truth/")?;
    let exact: Vec<_> = (0..a.views)
        .map(|p| to_points(scene.true_points(p)))
        .collect();
    std::fs::write(
        tdir.join("points_true.txt"),
        vt_io::points::format_points(&exact),
    )
    .context("truth/points_true.txt")?;
    let mut truth = scene.truth(&a.source.display().to_string(), fps);
    let m = a.views;
    for i in 0..(2 * m - 1).max(1) {
        let q = i as f64 * 0.5;
        for source_frame in [0, scene.usable() / 2] {
            let file = format!("truth/ideal_q{q:05.2}_src{source_frame:04}.png");
            write_png(&root.join(&file), &scene.ideal(q, source_frame))?;
            truth.ideals.push(IdealView {
                q,
                homography: rows(&scene.ideal_homography(q)),
                source_frame,
                file,
            });
        }
    }
    std::fs::write(
        root.join("truth.json"),
        serde_json::to_string_pretty(&truth)?,
    )
    .context("truth.json")?;
    dir.commit()?;
    println!(
        "wrote {} views x {} frames ({}x{}, {:.3} fps, from {} source frames of {}) to {}",
        a.views,
        a.frames,
        w,
        h,
        fps,
        scene.usable().min(n_source),
        a.source.display(),
        a.out.display()
    );
    Ok(())
}
