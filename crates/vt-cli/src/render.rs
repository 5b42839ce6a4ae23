//! `vt render`: play a scene along a viewpoint path into a video, GIF or PNG folder.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::Args;
use image::RgbImage;
use vt_core::render::{Player, RenderParams, Renderer, Step};
use vt_core::warp::Interpolation;
use vt_io::scene::LoadedScene;
use vt_io::writer::FrameWriter;

use crate::progress::bar;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene directory written by `vt analyze`.
    scene: PathBuf,
    /// Viewpoint path: keyframes `0s:0,4s:14,8s:0` (time:q, linear between), `sweep[:SPEED]`
    /// (0 to M-1 and back at SPEED views per second, default 1), or `@FILE` with one q per line
    /// (one per output frame).
    #[arg(long)]
    path: String,
    /// Output: `.mp4` (H.264), `.gif`, or a folder of PNG frames (no extension).
    #[arg(long)]
    out: PathBuf,
    /// Output frame rate (default: the scene's source frame rate, else 30).
    #[arg(long)]
    fps: Option<f64>,
    /// Total length in seconds (default: the path's own length; keyframe paths then hold their
    /// last q, sweeps go on back and forth).
    #[arg(long)]
    duration: Option<f64>,
    /// Allow a render longer than 10 minutes of output (up to 24 hours).
    #[arg(long)]
    long: bool,
    #[command(flatten)]
    options: RenderOptions,
}

/// Rendering options shared by `vt render` and `vt view`.
#[derive(Args, Clone)]
pub struct RenderOptions {
    /// Nearest-neighbour warping (faster) instead of bilinear.
    #[arg(long)]
    nearest: bool,
    /// Crossfade the object over this many frames after a loop wrap or view switch (0 = off).
    #[arg(long, default_value_t = 0)]
    crossfade: usize,
    /// Compensate per-view exposure differences (estimated from the backgrounds; the default).
    #[arg(long)]
    gain_compensation: bool,
    /// Do not compensate exposure differences (the thesis).
    #[arg(long, conflicts_with = "gain_compensation")]
    no_gain_compensation: bool,
}

/// Longest `--crossfade`, frames (the renderer's own limit).
pub const MAX_CROSSFADE: usize = vt_core::render::MAX_CROSSFADE;

impl RenderOptions {
    /// Checks the options against their limits.
    pub fn check(&self) -> Result<()> {
        if self.crossfade > MAX_CROSSFADE {
            bail!(
                "--crossfade {} is more than {MAX_CROSSFADE} frames",
                self.crossfade
            );
        }
        Ok(())
    }

    pub fn params(&self) -> RenderParams {
        RenderParams {
            interpolation: if self.nearest {
                Interpolation::Nearest
            } else {
                Interpolation::Bilinear
            },
            crossfade: self.crossfade,
            gain_compensation: self.gain_compensation || !self.no_gain_compensation,
        }
    }
}

impl RenderArgs {
    /// The demo's sweep across all views.
    pub fn demo_sweep(scene: PathBuf, out: PathBuf) -> Self {
        Self {
            scene,
            path: "sweep:0.5".into(),
            out,
            fps: Some(30.0),
            duration: None,
            long: false,
            options: RenderOptions {
                nearest: false,
                crossfade: 0,
                gain_compensation: true,
                no_gain_compensation: false,
            },
        }
    }
}

/// Longest render without `--long`, seconds of output.
pub const MAX_SECONDS: f64 = 600.0;
/// Longest render with `--long`, seconds of output (a day).
pub const MAX_SECONDS_LONG: f64 = 86_400.0;
/// Most frames of any render (a day at 60 fps); the path is checked against it before it is
/// built.
pub const MAX_FRAMES: usize = 5_184_000;

/// A viewpoint path, sampled per output frame. Its length is checked (at most [`MAX_SECONDS`] of
/// output, [`MAX_SECONDS_LONG`] with `long`, and [`MAX_FRAMES`] frames) before any of it is built.
pub fn path_qs(
    spec: &str,
    n_views: usize,
    fps: f64,
    duration: Option<f64>,
    long: bool,
) -> Result<Vec<f64>> {
    use vt_io::output::{num, shorten};
    if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
        bail!("--fps {} must be in (0, 1000]", num(fps));
    }
    let max_secs = if long { MAX_SECONDS_LONG } else { MAX_SECONDS };
    let hint = if long {
        "the most vt renders"
    } else {
        "the most vt renders without --long (up to 86400 s with it)"
    };
    if let Some(d) = duration {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration {} must be a positive number of seconds", num(d));
        }
        if d > max_secs {
            bail!(
                "--duration {} s is longer than {max_secs} s, {hint}",
                num(d)
            );
        }
    }
    let q_max = n_views.saturating_sub(1) as f64;
    // Frames of `secs` seconds, checked against the limits before anything is allocated.
    let frames = |secs: f64, what: &str| -> Result<usize> {
        if !(secs.is_finite() && secs <= max_secs) {
            bail!("{what} is {secs:.4e} s long, longer than {max_secs} s, {hint}");
        }
        let n = (secs * fps).round().max(1.0);
        if n > MAX_FRAMES as f64 {
            bail!(
                "{what} is {n} frames at {} fps, more than {MAX_FRAMES}",
                num(fps)
            );
        }
        Ok(n as usize)
    };
    let check_q = |q: f64, what: &str| -> Result<f64> {
        if !q.is_finite() || q < 0.0 || q > q_max {
            bail!(
                "--path: {what}: viewpoint {} is outside [0, {q_max}] (the scene has {n_views} views)",
                num(q)
            );
        }
        Ok(q)
    };
    if let Some(file) = spec.strip_prefix('@') {
        let text = vt_io::limits::read_text(
            Path::new(file),
            vt_io::limits::MAX_TEXT_BYTES,
            "viewpoint file",
        )?;
        let max_lines = if long {
            MAX_FRAMES
        } else {
            (MAX_SECONDS * fps) as usize
        };
        let mut qs = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let t = line.split('#').next().unwrap_or("").trim();
            if t.is_empty() {
                continue;
            }
            let q: f64 = t.parse().map_err(|_| {
                anyhow::anyhow!("{file}:{}: '{}' is not a number", i + 1, shorten(t))
            })?;
            qs.push(check_q(q, &format!("{file}:{}", i + 1))?);
            if qs.len() > max_lines {
                bail!("{file}: more than {max_lines} viewpoints (one per frame), {hint}");
            }
        }
        if qs.is_empty() {
            bail!("{file}: no viewpoints (one q per line)");
        }
        if let Some(d) = duration {
            let n = frames(d, "--duration")?;
            let last = *qs.last().expect("non-empty");
            qs.resize(n, last);
        }
        return Ok(qs);
    }
    if let Some(rest) = spec.strip_prefix("sweep") {
        let speed = match rest.strip_prefix(':') {
            Some(s) => s.parse::<f64>().map_err(|_| {
                anyhow::anyhow!("--path sweep:{}: speed is not a number", shorten(s))
            })?,
            None if rest.is_empty() => 1.0,
            None => bail!("--path '{}': expected sweep or sweep:SPEED", shorten(spec)),
        };
        if !(speed.is_finite() && speed > 0.0) {
            bail!(
                "--path sweep:{}: speed must be positive (views per second)",
                num(speed)
            );
        }
        let one_way = if q_max > 0.0 { q_max / speed } else { 1.0 };
        let n = match duration {
            Some(d) => frames(d, "--duration")?,
            None => frames(2.0 * one_way, &format!("--path sweep:{}", num(speed)))?,
        };
        return Ok((0..n)
            .map(|i| {
                let t = (i as f64 / fps) % (2.0 * one_way);
                let q = if t <= one_way {
                    t * speed
                } else {
                    (2.0 * one_way - t) * speed
                };
                q.clamp(0.0, q_max)
            })
            .collect());
    }
    let mut keys: Vec<(f64, f64)> = Vec::new();
    for part in spec.split(',') {
        let (t, q) = part.split_once(':').ok_or_else(|| {
            anyhow::anyhow!(
                "--path: '{}' is not TIME:Q (e.g. 0s:0,4s:14,8s:0)",
                shorten(part)
            )
        })?;
        let t = t.trim().trim_end_matches('s');
        let t: f64 = t.parse().map_err(|_| {
            anyhow::anyhow!("--path: time '{}' is not a number of seconds", shorten(t))
        })?;
        let q: f64 = q
            .trim()
            .parse()
            .map_err(|_| anyhow::anyhow!("--path: viewpoint '{}' is not a number", shorten(q)))?;
        if !t.is_finite() || t < 0.0 || keys.last().is_some_and(|&(pt, _)| t <= pt) {
            bail!(
                "--path: keyframe times must be finite, >= 0 and increasing ('{}')",
                shorten(part)
            );
        }
        keys.push((t, check_q(q, &shorten(part))?));
    }
    let end = keys.last().map(|k| k.0).unwrap_or(0.0);
    let n = match duration {
        Some(d) => frames(d, "--duration")?,
        None => frames(end.max(1.0 / fps), "--path")?,
    };
    Ok((0..n)
        .map(|i| {
            let t = i as f64 / fps;
            match keys.iter().position(|k| k.0 > t) {
                None => keys[keys.len() - 1].1,
                Some(0) => keys[0].1,
                Some(k) => {
                    let ((t0, q0), (t1, q1)) = (keys[k - 1], keys[k]);
                    q0 + (q1 - q0) * (t - t0) / (t1 - t0)
                }
            }
        })
        .collect())
}

/// Counts and seams of a render.
pub struct RenderSummary {
    pub frames: usize,
    pub wraps: u64,
    pub switches: u64,
    pub mean_seam: f64,
}

pub fn run(args: RenderArgs) -> Result<RenderSummary> {
    args.options.check()?;
    let scene = LoadedScene::open(&args.scene)?;
    let fps = args
        .fps
        .or(scene
            .file
            .fps
            .filter(|f| f.is_finite() && *f > 0.0 && *f <= 1000.0))
        .unwrap_or(30.0);
    let qs = path_qs(
        &args.path,
        scene.render.views.len(),
        fps,
        args.duration,
        args.long,
    )?;
    let mut renderer = Renderer::new(scene.render.clone(), args.options.params())?;
    let (w, h) = renderer.size();
    let mut inputs: Vec<&Path> = vec![args.scene.as_path()];
    if let Some(f) = args.path.strip_prefix('@') {
        inputs.push(Path::new(f));
    }
    let mut sink = FrameWriter::create(&args.out, &inputs, w, h, fps)?;
    let mut player = Player::new();
    let mut frame = RgbImage::new(w, h);
    let mut seams = Vec::new();
    let mask_steps = scene.mask_steps();
    let pb = bar(qs.len() as u64, "render");
    // On a rayon worker, the renderer's parallel passes queue locally: no allocation per frame.
    rayon::scope(|_| -> Result<()> {
        for &q in &qs {
            let choice = player.advance(&scene.render, q)?;
            if matches!(choice.step, Step::Wrap | Step::Switch { .. }) {
                seams.extend(scene.jump_seam(&choice, &mask_steps));
            }
            renderer.render_into(&scene.objects, q, &choice, &mut frame)?;
            sink.write(&frame)?;
            pb.inc(1);
        }
        Ok(())
    })?;
    pb.finish_and_clear();
    sink.finish()?;
    let summary = RenderSummary {
        frames: qs.len(),
        wraps: player.wraps,
        switches: player.switches,
        mean_seam: seams.iter().sum::<f64>() / seams.len().max(1) as f64,
    };
    println!(
        "rendered {} frames to {} ({} loop wraps, {} view switches, mean seam score {:.3})",
        summary.frames,
        args.out.display(),
        summary.wraps,
        summary.switches,
        summary.mean_seam
    );
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths() {
        let qs = path_qs("0s:0,1s:2,2s:2", 3, 4.0, None, false).unwrap();
        assert_eq!(qs, vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0]);
        let sweep = path_qs("sweep:2", 3, 2.0, None, false).unwrap();
        assert_eq!(sweep, vec![0.0, 1.0, 2.0, 1.0]);
        assert_eq!(
            path_qs("sweep", 1, 10.0, Some(0.5), false).unwrap(),
            vec![0.0; 5]
        );
        for (bad, want) in [
            ("0s:0,1s:5", "outside [0, 2]"),
            ("0s:0,0s:1", "increasing"),
            ("zero", "TIME:Q"),
            ("sweep:-1", "positive"),
            ("sweep:x", "not a number"),
            ("sweep:1e-300", "longer than 600 s"),
            ("0s:0,1e9s:1", "longer than 600 s"),
        ] {
            let e = path_qs(bad, 3, 30.0, None, false).unwrap_err().to_string();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }
}
