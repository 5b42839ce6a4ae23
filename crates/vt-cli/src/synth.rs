//! `vt synth ...`: write synthetic scenes with their truth.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use vt_io::frames::write_png;
use vt_io::output::{Output, OutputKind};
use vt_synth::{Rig, TextureParams};

use crate::progress::bar;

#[derive(Subcommand)]
pub enum SynthCommand {
    /// System A test scene: M cameras on a line filming a swaying planar object, asynchronously.
    Textures(TexturesArgs),
    /// System B test object: a textured sphere and box photographed from a ring of calibrated
    /// cameras, with masks and ground truth for extra viewpoints.
    Object(ObjectArgs),
    /// System A test scene from a real video: M views of a slanted plane textured with the video,
    /// known homographies, clock offsets, gains and marking noise, encoded to H.264, with truth.
    Real(crate::synth_real::RealArgs),
}

#[derive(Args)]
pub struct ObjectArgs {
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Cameras on the ring (paper: 8).
    #[arg(long, default_value_t = 8)]
    views: usize,
    /// Square image side in pixels (paper: 400).
    #[arg(long, default_value_t = 400)]
    size: u32,
    /// Seed: turns the whole ring by a seed-determined angle (0: first camera at angle 0).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

#[derive(Args)]
pub struct TexturesArgs {
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Number of views M.
    #[arg(long, default_value_t = 3)]
    views: usize,
    /// Frames per view.
    #[arg(long, default_value_t = 150)]
    frames: usize,
    /// Frame size, WxH.
    #[arg(long, default_value = "320x180", value_parser = parse_size)]
    size: (u32, u32),
    /// Motion period in frames.
    #[arg(long, default_value_t = 24)]
    period: usize,
    /// Random seed (same seed, same bytes).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Camera rig: parallel (views differ by a translation) or converging (a homography).
    #[arg(long, default_value = "parallel", value_parser = parse_rig)]
    rig: Rig,
    /// Put the background on the object's plane, so one homography explains the whole scene.
    #[arg(long)]
    planar: bool,
    /// Sensor noise, grey levels.
    #[arg(long, default_value_t = 2.0)]
    noise: f64,
    /// Largest per-view exposure gain difference (0.04 = up to +-4%).
    #[arg(long, default_value_t = 0.04)]
    exposure: f64,
}

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WxH (e.g. 320x180)"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("width '{w}' is not a whole number"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("height '{h}' is not a whole number"))?;
    if w < 8 || h < 8 || w > 16384 || h > 16384 {
        return Err(format!(
            "size {w}x{h} is out of range (8 to 16384 per side)"
        ));
    }
    Ok((w, h))
}

fn parse_rig(s: &str) -> Result<Rig, String> {
    match s {
        "parallel" => Ok(Rig::Parallel),
        "converging" => Ok(Rig::Converging),
        _ => Err(format!("rig '{s}' is not parallel or converging")),
    }
}

pub fn run(cmd: SynthCommand) -> Result<()> {
    match cmd {
        SynthCommand::Real(a) => crate::synth_real::run(&a),
        SynthCommand::Object(a) => {
            write_object(&a)?;
            println!(
                "wrote {} views of {}x{} (+ truth) to {}",
                a.views,
                a.size,
                a.size,
                a.out.display()
            );
            Ok(())
        }
        SynthCommand::Textures(a) => {
            let params = TextureParams {
                views: a.views,
                frames: a.frames,
                width: a.size.0,
                height: a.size.1,
                period: a.period,
                seed: a.seed,
                rig: a.rig,
                planar: a.planar,
                noise: a.noise,
                exposure: a.exposure,
                ..Default::default()
            };
            write_textures(&a.out, &params)?;
            println!(
                "wrote {} views x {} frames to {}",
                a.views,
                a.frames,
                a.out.display()
            );
            Ok(())
        }
    }
}

/// Most pixels in one synthetic frame (3840 x 2160).
pub const MAX_SYNTH_PIXELS: u64 = 3840 * 2160;
/// Most pixels of a synthetic object's photos and truth images together (2 x views + 1 images).
pub const MAX_SYNTH_OBJECT_PIXELS: u64 = 1 << 28;
/// Most views of a synthetic texture scene.
pub const MAX_SYNTH_VIEWS: usize = 64;
/// Most frames of a synthetic texture scene, all views together.
pub const MAX_SYNTH_FRAMES: usize = 100_000;

/// Checks a texture scene's sizes against the limits above before anything is allocated.
fn check_texture_size(p: &TextureParams) -> Result<()> {
    let px = p.width as u64 * p.height as u64;
    if px > MAX_SYNTH_PIXELS {
        bail!(
            "--size {}x{} is {px} pixels per frame, more than {MAX_SYNTH_PIXELS} (3840x2160)",
            p.width,
            p.height
        );
    }
    if p.views == 0 || p.views > MAX_SYNTH_VIEWS {
        bail!("--views {} must be in 1..={MAX_SYNTH_VIEWS}", p.views);
    }
    let total = p.views.saturating_mul(p.frames);
    if p.frames == 0 || total > MAX_SYNTH_FRAMES {
        bail!(
            "--views {} x --frames {} = {total} frames, more than {MAX_SYNTH_FRAMES} (or no frames)",
            p.views,
            p.frames
        );
    }
    Ok(())
}

/// Writes a texture scene into `out` (checked against the limits first), with a progress bar.
pub fn write_textures(out: &Path, params: &TextureParams) -> Result<()> {
    check_texture_size(params)?;
    let pb = bar((params.views * params.frames) as u64, "synth frames");
    vt_synth::files::write_textures(out, params, &|| pb.inc(1))?;
    pb.finish_and_clear();
    Ok(())
}

/// Writes the System B synthetic object into `a.out`, atomically: `object_par.txt` and
/// `view_NN.png` (reference photos), `masks/view_NN.png` (exact silhouettes), and `truth/` with
/// `truth_par.txt`, `truth_NN.png` and `masks/` for viewpoints between the cameras (each
/// midpoint, and 10 degrees past the first camera), plus `scene.json` with the angles.
fn write_object(a: &ObjectArgs) -> Result<()> {
    if a.views < 3 || a.views > 360 {
        bail!("--views {} must be in 3..=360", a.views);
    }
    if a.size < 16 || a.size > 4096 {
        bail!("--size {} must be in 16..=4096", a.size);
    }
    // Photos, masks and truth of every view and midpoint are held in memory together.
    let pixels = (2 * a.views as u64 + 1) * a.size as u64 * a.size as u64;
    if pixels > MAX_SYNTH_OBJECT_PIXELS {
        bail!(
            "--views {} at --size {} is {pixels} pixels of photos and truth, more than {MAX_SYNTH_OBJECT_PIXELS}",
            a.views,
            a.size
        );
    }
    let spacing = 360.0 / a.views as f64;
    // splitmix64 of the seed, as a fraction of the spacing; seed 0 keeps angle 0.
    let start = if a.seed == 0 {
        0.0
    } else {
        vt_core::rng::unit(vt_core::rng::mix(a.seed)) * spacing
    };
    let mut extra = vec![10.0f64.min(spacing / 2.0)];
    extra.extend((0..a.views).map(|i| (i as f64 + 0.5) * spacing));
    extra.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
    let params = vt_fv::synth::SceneParams {
        n_views: a.views,
        width: a.size,
        height: a.size,
        extra_angles_deg: extra.clone(),
        start_angle_deg: start,
        ..Default::default()
    };
    // The output is checked (and its temporary made) before the ray casting.
    let dir = Output::dir(&a.out, OutputKind::SynthObject, &[])?;
    let pb = bar(1, "ray casting");
    let data = vt_fv::synth::generate(&params).map_err(|e| anyhow::anyhow!(e))?;
    pb.finish_and_clear();
    let root = dir.path().to_path_buf();
    let write_set = |folder: &Path,
                     par: &str,
                     prefix: &str,
                     cams: &[vt_fv::Camera],
                     photos: &[image::RgbImage],
                     masks: &[vt_fv::Mask]|
     -> Result<()> {
        let mdir = folder.join("masks");
        std::fs::create_dir_all(&mdir).with_context(|| mdir.display().to_string())?;
        let named: Vec<vt_fv::Camera> = cams
            .iter()
            .enumerate()
            .map(|(i, c)| vt_fv::Camera {
                name: format!("{prefix}_{i:02}.png"),
                ..c.clone()
            })
            .collect();
        for (i, c) in named.iter().enumerate() {
            write_png(&folder.join(&c.name), &photos[i])?;
            let m = vt_fv::silhouette::mask_image(&masks[i]);
            let p = mdir.join(&c.name);
            m.save(&p).with_context(|| p.display().to_string())?;
        }
        std::fs::write(folder.join(par), vt_fv::camera::format_par(&named))
            .with_context(|| par.to_string())
    };
    write_set(
        &root,
        "object_par.txt",
        "view",
        &data.cameras,
        &data.photos,
        &data.masks,
    )?;
    let tdir = root.join("truth");
    std::fs::create_dir(&tdir).context("truth/")?;
    write_set(
        &tdir,
        "truth_par.txt",
        "truth",
        &data.extra_cameras,
        &data.extra_truth,
        &data.extra_masks,
    )?;
    let scene = serde_json::json!({
        "format": "vt-synth-object",
        "version": 1,
        "views": a.views,
        "size": a.size,
        "seed": a.seed,
        "view_angles_deg": (0..a.views).map(|i| start + i as f64 * spacing).collect::<Vec<_>>(),
        "truth_angles_deg": extra.iter().map(|e| start + e).collect::<Vec<_>>(),
        "distance": params.distance,
        "elevation_deg": params.elevation_deg,
    });
    std::fs::write(
        root.join("scene.json"),
        serde_json::to_string_pretty(&scene)?,
    )
    .context("scene.json")?;
    dir.commit()?;
    Ok(())
}
