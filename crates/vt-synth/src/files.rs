//! Synthetic scenes on disk, and the check of an analysis against its truth. System A's scene
//! ([`write_textures`]): the frames (`view_NN/frame_NNNNN.png`), `points.txt` in the user
//! format, `truth.json` ([`TextureTruth`]) and ground-truth renders in `truth/`. System B's
//! object ([`write_object`]): photos, cameras and silhouettes in the layout `vt fv` reads, with
//! truth views. A real video's scene ([`write_real`]): views, points and ideal views. Written
//! through vt-io's outputs, so a scene appears only when complete and replaces only an earlier
//! synthetic scene of the same kind.

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use vt_io::frames::write_png;
use vt_io::output::{Output, OutputKind};
use vt_io::scene::SceneFile;

use crate::object::{format_par, PinholeCamera, RingParams};
use crate::real::{rows, IdealView, RealScene};
use crate::{TextureParams, TextureScene};
use image::{GrayImage, RgbImage};

/// What can go wrong writing a synthetic scene or checking against one.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Parameters the generator refuses.
    #[error("synthetic scene parameters: {0}")]
    Params(String),
    /// A parameter outside its limits; the message names it as `vt synth`'s flag.
    #[error("{0}")]
    Param(String),
    /// A file could not be read or written.
    #[error(transparent)]
    Io(#[from] vt_io::Error),
    /// A truth file that does not parse. The parser's error is part of the message.
    #[error("{path}: not a synthetic scene's truth.json: {cause}")]
    Truth {
        /// The file.
        path: String,
        /// What the parser said.
        cause: serde_json::Error,
    },
    /// A scene that does not match the truth it was made from.
    #[error("{what}")]
    Mismatch {
        /// Which link or view.
        what: String,
    },
}

/// Folder name of view p's frames.
pub fn view_dir(p: usize) -> String {
    format!("view_{p:02}")
}

/// truth.json of a texture scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TextureTruth {
    /// "vt-synth-textures".
    pub format: String,
    /// 1.
    pub version: u32,
    /// The generator's parameters.
    pub params: TextureParams,
    /// Motion period, frames.
    pub period: usize,
    /// Per view: the frame where the motion is at phase 0; frame s of view p has phase
    /// `(s - phase[p]) mod period`.
    pub phase: Vec<usize>,
    /// Per view exposure gain.
    pub gains: Vec<f64>,
    /// `H_(p,p+1)` of the object plane, row-major, for p = 0..M-2.
    pub homographies_next: Vec<[[f64; 3]; 3]>,
    /// Ground-truth renders of intermediate viewpoints (noise-free, at the exposure of a camera there).
    pub renders: Vec<TruthRender>,
}

/// One ground-truth render.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TruthRender {
    /// Viewpoint in [0, M-1].
    pub q: f64,
    /// Motion phase, frames.
    pub phase: usize,
    /// File, relative to the scene directory.
    pub file: String,
}

fn io(path: &Path, e: std::io::Error) -> Error {
    Error::Io(vt_io::Error::io(path, e))
}

/// Writes frames, points.txt and truth.json of a texture scene into `out`, atomically, after
/// checking its sizes ([`TextureParams::check_limits`]); `tick` is called once per frame
/// written (for progress).
pub fn write_textures(
    out: &Path,
    params: &TextureParams,
    tick: &(dyn Fn() + Sync),
) -> Result<(), Error> {
    params.check_limits().map_err(Error::Param)?;
    let scene = TextureScene::new(*params).map_err(Error::Params)?;
    let dir = Output::dir(out, OutputKind::SynthTextures, &[])?;
    let root = dir.path().to_path_buf();
    for p in 0..params.views {
        let vdir = root.join(view_dir(p));
        std::fs::create_dir(&vdir).map_err(|e| io(&vdir, e))?;
        (0..params.frames).into_par_iter().try_for_each(|s| {
            write_png(&vdir.join(format!("frame_{s:05}.png")), &scene.frame(p, s))?;
            tick();
            Ok::<_, Error>(())
        })?;
    }
    let points = scene.marked_points();
    let points_path = root.join("points.txt");
    std::fs::write(&points_path, vt_io::points::format_points(&points))
        .map_err(|e| io(&points_path, e))?;

    let tdir = root.join("truth");
    std::fs::create_dir(&tdir).map_err(|e| io(&tdir, e))?;
    // Truth at half-view steps, at two phases, so renders can be checked at and between views.
    let m = params.views;
    let qs: Vec<f64> = (0..(2 * m - 1).max(1)).map(|i| i as f64 * 0.5).collect();
    let mut renders = Vec::new();
    for &q in &qs {
        for phase in [0, params.period / 3] {
            let file = format!("truth/q{q:05.2}_phase{phase:03}.png");
            write_png(&root.join(&file), &scene.truth(q, phase))?;
            renders.push(TruthRender { q, phase, file });
        }
    }
    let homographies_next = (0..m.saturating_sub(1))
        .map(|p| {
            let h = scene.plane_homography(p as f64, p as f64 + 1.0);
            [
                [h[(0, 0)], h[(0, 1)], h[(0, 2)]],
                [h[(1, 0)], h[(1, 1)], h[(1, 2)]],
                [h[(2, 0)], h[(2, 1)], h[(2, 2)]],
            ]
        })
        .collect();
    let truth = TextureTruth {
        format: "vt-synth-textures".into(),
        version: 1,
        params: *params,
        period: params.period,
        phase: scene.phase_offsets().to_vec(),
        gains: scene.gains().to_vec(),
        homographies_next,
        renders,
    };
    let truth_path = root.join("truth.json");
    let text = serde_json::to_string_pretty(&truth).expect("truth serialises (plain data)");
    std::fs::write(&truth_path, text).map_err(|e| io(&truth_path, e))?;
    dir.commit()?;
    Ok(())
}

/// Writes the System B synthetic object ([`crate::object`]) into `out`, atomically:
/// `object_par.txt` and `view_NN.png` (reference photos), `masks/view_NN.png` (exact
/// silhouettes), and `truth/` with `truth_par.txt`, `truth_NN.png` and `masks/` for the truth
/// viewpoints ([`RingParams::scene`]), plus `scene.json` with the angles. The parameters are
/// checked ([`RingParams::check`]) and the output claimed before the ray casting.
pub fn write_object(out: &Path, ring: &RingParams) -> Result<(), Error> {
    ring.check().map_err(Error::Param)?;
    let params = ring.scene();
    let dir = Output::dir(out, OutputKind::SynthObject, &[])?;
    let data = crate::object::generate(&params).map_err(Error::Params)?;
    let root = dir.path().to_path_buf();
    let write_set = |folder: &Path,
                     par: &str,
                     prefix: &str,
                     cams: &[PinholeCamera],
                     photos: &[RgbImage],
                     masks: &[vt_core::Mask]|
     -> Result<(), Error> {
        let mask_dir = folder.join("masks");
        std::fs::create_dir_all(&mask_dir).map_err(|e| io(&mask_dir, e))?;
        let mut named = cams.to_vec();
        for (i, cam) in named.iter_mut().enumerate() {
            cam.name = format!("{prefix}_{i:02}.png");
            write_png(&folder.join(&cam.name), &photos[i])?;
            let m = &masks[i];
            let grey = GrayImage::from_raw(m.width(), m.height(), m.to_bytes())
                .expect("one byte per pixel");
            let path = mask_dir.join(&cam.name);
            grey.save(&path).map_err(|e| vt_io::Error::Image {
                path: path.clone(),
                message: e.to_string(),
            })?;
        }
        let par_path = folder.join(par);
        std::fs::write(&par_path, format_par(&named)).map_err(|e| io(&par_path, e))
    };
    write_set(
        &root,
        "object_par.txt",
        "view",
        &data.cameras,
        &data.photos,
        &data.masks,
    )?;
    let truth_dir = root.join("truth");
    std::fs::create_dir(&truth_dir).map_err(|e| io(&truth_dir, e))?;
    write_set(
        &truth_dir,
        "truth_par.txt",
        "truth",
        &data.extra_cameras,
        &data.extra_truth,
        &data.extra_masks,
    )?;
    let start = params.start_angle_deg;
    let scene = serde_json::json!({
        "format": "vt-synth-object",
        "version": 1,
        "views": ring.views,
        "size": ring.size,
        "seed": ring.seed,
        "view_angles_deg": (0..ring.views).map(|i| start + i as f64 * ring.spacing()).collect::<Vec<_>>(),
        "truth_angles_deg": params.extra_angles_deg.iter().map(|e| start + e).collect::<Vec<_>>(),
        "distance": params.distance,
        "elevation_deg": params.elevation_deg,
    });
    let scene_path = root.join("scene.json");
    let text = serde_json::to_string_pretty(&scene).expect("plain data serialises");
    std::fs::write(&scene_path, text).map_err(|e| io(&scene_path, e))?;
    dir.commit()?;
    Ok(())
}

/// How [`write_real`] stores a real-footage scene's views.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RealFiles {
    /// Frames per second of the views.
    pub fps: f64,
    /// H.264 quality (x264 CRF: 0 lossless, 18 visually lossless, 51 worst).
    pub crf: u8,
    /// PNG frame folders instead of H.264 videos.
    pub png: bool,
}

/// Writes a real-footage scene ([`crate::real::RealScene`]) into `out`, atomically:
/// `view_NN.mp4` (H.264) or `view_NN/` PNG folders, `points.txt` (the marked points, with the
/// scene's marking noise), `truth/points_true.txt`, `truth.json`
/// ([`crate::real::RealTruth`], naming `source`) and ideal views in `truth/` at half-view
/// steps; `tick` is called once per view frame written (for progress).
pub fn write_real(
    out: &Path,
    scene: &RealScene,
    source: &str,
    files: &RealFiles,
    tick: &(dyn Fn() + Sync),
) -> Result<(), Error> {
    let (views, frames) = (scene.params().views, scene.params().frames);
    let (w, h) = scene.size();
    let dir = vt_io::atomic::AtomicDir::create(out)?;
    let root = dir.path().to_path_buf();
    for p in 0..views {
        if files.png {
            let vdir = root.join(view_dir(p));
            std::fs::create_dir(&vdir).map_err(|e| io(&vdir, e))?;
            for s in 0..frames {
                write_png(&vdir.join(format!("frame_{s:05}.png")), &scene.frame(p, s))?;
                tick();
            }
        } else {
            let file = root.join(format!("{}.mp4", view_dir(p)));
            vt_io::video::encode_h264(&file, w, h, files.fps, files.crf, frames, &mut |s| {
                tick();
                Ok(scene.frame(p, s))
            })?;
        }
    }
    let points = |pts: Vec<(f64, f64)>| -> Vec<vt_core::Point> {
        pts.into_iter()
            .map(|(x, y)| vt_core::Point::new(x, y))
            .collect()
    };
    let marked: Vec<_> = (0..views).map(|p| points(scene.marked_points(p))).collect();
    let exact: Vec<_> = (0..views).map(|p| points(scene.true_points(p))).collect();
    let truth_dir = root.join("truth");
    std::fs::create_dir(&truth_dir).map_err(|e| io(&truth_dir, e))?;
    for (path, pts) in [
        (root.join("points.txt"), &marked),
        (truth_dir.join("points_true.txt"), &exact),
    ] {
        std::fs::write(&path, vt_io::points::format_points(pts)).map_err(|e| io(&path, e))?;
    }
    let mut truth = scene.truth(source, files.fps);
    for i in 0..(2 * views - 1).max(1) {
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
    let truth_path = root.join("truth.json");
    let text = serde_json::to_string_pretty(&truth).expect("truth serialises (plain data)");
    std::fs::write(&truth_path, text).map_err(|e| io(&truth_path, e))?;
    dir.commit()?;
    Ok(())
}

/// Reads a texture scene's truth.json.
pub fn read_truth(path: &Path) -> Result<TextureTruth, Error> {
    let text = vt_io::limits::read_text(path, vt_io::limits::MAX_TEXT_BYTES, "truth file")?;
    serde_json::from_str(&text).map_err(|cause| Error::Truth {
        path: path.display().to_string(),
        cause,
    })
}

/// The outcome of [`check_against_truth`]: one line per check, and whether all passed.
#[derive(Debug, Clone)]
pub struct TruthCheck {
    /// Printable lines (loop lengths in periods, transition phase errors, corner errors).
    pub lines: Vec<String>,
    /// Every loop within a frame of a whole number of periods, every transition within a frame
    /// of the true phase, every homography within 0.5 px at the image corners.
    pub pass: bool,
}

/// Reads `truth_path` and compares `scene` with it: the printable report when every check
/// passes, else [`Error::Mismatch`] carrying the report.
pub fn check_scene(truth_path: &Path, scene: &SceneFile) -> Result<String, Error> {
    let check = check_against_truth(&read_truth(truth_path)?, scene)?;
    let report = check.lines.join("\n");
    if !check.pass {
        return Err(Error::Mismatch {
            what: format!("the analysis does not match the synthetic truth:\n{report}"),
        });
    }
    Ok(report)
}

/// Compares an analysed scene with the truth of the synthetic scene it was made from.
pub fn check_against_truth(truth: &TextureTruth, scene: &SceneFile) -> Result<TruthCheck, Error> {
    let period = truth.period.max(1);
    let phase_of = |p: usize, s: usize| {
        let offset = truth.phase.get(p).copied().unwrap_or(0) as i64;
        (s as i64 - offset).rem_euclid(period as i64) as usize
    };
    let circ = |a: usize, b: usize| {
        let d = a.abs_diff(b) % period;
        d.min(period - d)
    };
    let mut lines = vec!["truth check (synthetic scene):".to_string()];
    let mut pass = true;
    let w = scene.params.loops.window;
    for (p, v) in scene.views.iter().enumerate() {
        let len = v.loop_.end - v.loop_.start;
        let off = circ(len % period, 0);
        pass &= off <= 1;
        let mut worst = 0;
        for (side, table, q) in [
            ("next", &v.transitions.next, p + 1),
            ("prev", &v.transitions.prev, p.wrapping_sub(1)),
        ] {
            if q >= scene.views.len() {
                continue;
            }
            for (s, t) in table
                .iter()
                .enumerate()
                .take((v.frames + 1).saturating_sub(w))
            {
                let t = t.ok_or_else(|| Error::Mismatch {
                    what: format!("view {p} {side} transition of frame {s} missing"),
                })?;
                worst = worst.max(circ(phase_of(p, s), phase_of(q, t)));
            }
        }
        pass &= worst <= 1;
        lines.push(format!(
            "  view {p}: loop length {len} = {:.2} periods (off by {off} frame(s)); worst transition phase error {worst} frame(s)",
            len as f64 / period as f64
        ));
    }
    for (p, th) in truth.homographies_next.iter().enumerate() {
        let Some(link) = scene.views.get(p).and_then(|v| v.to_next.as_ref()) else {
            continue;
        };
        let h = link.homography().map_err(vt_io::Error::from)?;
        let t = vt_core::Homography::from_matrix(nalgebra::Matrix3::from_row_slice(&th.concat()))
            .map_err(vt_io::Error::from)?;
        let (w, hh) = (scene.width as f64, scene.height as f64);
        let err = [(0.0, 0.0), (w, 0.0), (0.0, hh), (w, hh)]
            .iter()
            .map(|&(x, y)| {
                let pt = vt_core::Point::new(x, y);
                match (h.apply(pt), t.apply(pt)) {
                    (Some(a), Some(b)) => (a - b).norm(),
                    _ => f64::INFINITY,
                }
            })
            .fold(0.0, f64::max);
        pass &= err < 0.5;
        lines.push(format!(
            "  H({p},{}) corner error vs truth: {err:.4} px",
            p + 1
        ));
    }
    lines.push(format!("  result: {}", if pass { "PASS" } else { "FAIL" }));
    Ok(TruthCheck { lines, pass })
}
