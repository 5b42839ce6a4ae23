//! The scene directory written by `vt analyze` and read by the renderer.
//!
//! ```text
//! SCENE/
//!   scene.json            format "vt-scene", version 1 (see [`SceneFile`])
//!   background_000.png    B_p, the unsmoothed median of view p
//!   objects_000.bin       the moving object of every frame of view p (see [`crate::objects`])
//!   dynamic_000.png       optional: alpha of view p's dynamic region (see [`vt_core::noise`]);
//!                         the object store then also holds the frames' pixels under it
//! ```
//! Fields added after version 1 first shipped are optional (`serde(default)`), so every version-1
//! scene still loads: a scene without `dynamic` renders objects only, as before.
//! A reader refuses other format versions with a message saying which it found and which it
//! reads, rather than guessing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use vt_core::analysis::{AnalyzeParams, SceneAnalysis};
use vt_core::model::MotionModel;
use vt_core::{Homography, Point};

use crate::{Error, Result};

/// The `format` string of scene.json.
pub const FORMAT: &str = "vt-scene";
/// The version this build writes and reads.
pub const VERSION: u32 = 1;

/// scene.json.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`VERSION`] when written by this build.
    pub version: u32,
    /// The program that wrote it.
    pub created_by: String,
    /// Frame width, all views.
    pub width: u32,
    /// Frame height, all views.
    pub height: u32,
    /// The analysis parameters used.
    pub params: AnalyzeParams,
    /// The geometric model of the scene (absent for a single view).
    pub model: Option<ModelEntry>,
    /// Mean seam score over every loop wrap and view switch of the scene ([`vt_core::seam`]: a
    /// wrap's rendered step over the median ordinary rendered step, a switch's rendered steps
    /// over the ones it replaced; 1 = no larger than ordinary playback), as `vt render`
    /// measures it.
    #[serde(default)]
    pub seam_score: f64,
    /// The source videos' frame rate (median real frame interval, median over the views;
    /// absent for frame folders and older scenes): what `vt render` and `vt view` play at.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// One entry per view, in order.
    pub views: Vec<ViewEntry>,
}

/// Which model explains the points, and the evidence.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelEntry {
    /// The chosen model.
    pub chosen: MotionModel,
    /// True when forced by the user.
    pub forced: bool,
    /// Summed GRIC of each model tried (lower is better).
    pub gric: BTreeMap<String, f64>,
}

/// One view.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ViewEntry {
    /// Display name (the input path).
    pub name: String,
    /// `N_p`.
    pub frames: usize,
    /// Marked points (x, y).
    pub points: Vec<[f64; 2]>,
    /// Background image file, relative to the scene.
    pub background: String,
    /// Object store file, relative to the scene.
    pub objects: String,
    /// Mean fraction of pixels in the moving-object mask.
    pub moving_fraction: f64,
    /// Mean XOR between consecutive masks (pixels): the unit of the loop and transition costs
    /// the analysis chooses by (the printed seam scores are measured on rendered frames).
    #[serde(default)]
    pub mean_step: f64,
    /// Seam score of the loop wrap, rendered at the view ([`record_seams`]).
    #[serde(default)]
    pub loop_seam: f64,
    /// `(m_p, n_p)` and its eq. (1) cost.
    #[serde(rename = "loop")]
    pub loop_: LoopEntry,
    /// Next-best distinct loops, best first (empty unless asked for).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub alternatives: Vec<LoopEntry>,
    /// `H_(p,p+1)` (absent for the last view).
    pub to_next: Option<LinkEntry>,
    /// `H_(p,p-1)` (absent for the first view).
    pub to_prev: Option<LinkEntry>,
    /// Eq. (2) tables.
    pub transitions: Transitions,
    /// Points consistent with the refined homographies, the renderer's `x_p` (absent: the
    /// marked points are used).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_points: Option<Vec<[f64; 2]>>,
    /// Dynamic-region alpha image, relative to the scene (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dynamic: Option<String>,
    /// Share of the image in the dynamic region.
    #[serde(default)]
    pub dynamic_fraction: f64,
    /// Share of the real frame-to-frame change the view keeps at its own viewpoint (absent in
    /// scenes analysed before it was measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_kept: Option<f64>,
    /// Sensor noise estimate of the noise model, grey levels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_sigma: Option<f32>,
}

/// A loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct LoopEntry {
    /// `m`.
    pub start: usize,
    /// `n`.
    pub end: usize,
    /// Eq. (1) cost.
    pub cost: u64,
}

impl From<vt_core::loops::Loop> for LoopEntry {
    fn from(l: vt_core::loops::Loop) -> Self {
        Self {
            start: l.start,
            end: l.end,
            cost: l.cost,
        }
    }
}

/// A homography to a neighbour.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LinkEntry {
    /// Row-major 3x3, last element 1.
    pub homography: [[f64; 3]; 3],
    /// RMS transfer error of the points, pixels.
    pub rms: f64,
    /// Mean seam score of switching between the two views (both directions), rendered at the
    /// tie between them ([`record_seams`]).
    #[serde(default)]
    pub seam: f64,
    /// The homography fitted to the marked points, when `homography` is the refined one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points_homography: Option<[[f64; 3]; 3]>,
    /// The background alignment's figures (absent when refinement was off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refinement: Option<vt_core::analysis::Refinement>,
    /// How the link was registered without marked points (absent: from the points file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub registration: Option<RegistrationEntry>,
    /// The pair's parallax beyond the plane (absent: the plane warp was asked for).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parallax: Option<ParallaxEntry>,
}

/// A pair's parallax in scene.json: the figures and, when morphed, the two fields' files and
/// directions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParallaxEntry {
    /// What the analysis measured.
    pub figures: vt_core::parallax::ParallaxFigures,
    /// The fields in this view's and the next view's frame (16-bit PNG, [`parallax_name`]), and
    /// their unit directions; absent when the pair uses the plane.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fields: Option<[ParallaxFieldEntry; 2]>,
}

/// One parallax field: the file and its direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParallaxFieldEntry {
    /// File, relative to the scene.
    pub file: String,
    /// Unit direction of the disparity in that view's frame.
    pub direction: [f32; 2],
    /// The field's line map (row-major 3x3: pixel `x`'s search line is `m x`, its epipolar line
    /// carried into that view's plane-aligned frame); absent: straight along `direction`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lines: Option<[f64; 9]>,
}

/// File name of link p's parallax field in view p's (`side` 0) or view p + 1's (1) frame.
pub fn parallax_name(p: usize, side: usize) -> String {
    format!("parallax_{p:03}_{}.png", ["a", "b"][side])
}

/// Disparities are stored in 1/8 px around this offset, with one bit for "confirmed by both
/// views".
const PARALLAX_OFFSET: i32 = 16384;

fn write_field(path: &Path, f: &vt_core::parallax::Field) -> Result<()> {
    let img =
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(f.width(), f.height(), |x, y| {
            let i = (y * f.width() + x) as usize;
            let q = ((f.disparity()[i] * 8.0).round() as i32 + PARALLAX_OFFSET).clamp(0, 32767);
            image::Luma([((q as u16) << 1) | f.valid()[i] as u16])
        });
    img.save(path).map_err(|e| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

fn read_field(
    path: &Path,
    entry: &ParallaxFieldEntry,
    size: (u32, u32),
) -> Result<vt_core::parallax::Field> {
    let bytes =
        crate::limits::read_bytes(path, crate::limits::MAX_IMAGE_FILE_BYTES, "parallax field")?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?
        .to_luma16();
    let corrupt = |why: String| Error::Scene {
        path: path.to_path_buf(),
        message: format!("corrupted parallax field: {why}"),
    };
    if img.dimensions() != size {
        return Err(corrupt(format!(
            "{}x{}, the scene is {}x{}",
            img.width(),
            img.height(),
            size.0,
            size.1
        )));
    }
    let raw = img.into_raw();
    vt_core::parallax::Field::new(
        size.0,
        size.1,
        entry.direction,
        entry.lines,
        raw.iter()
            .map(|&v| ((v >> 1) as i32 - PARALLAX_OFFSET) as f32 / 8.0)
            .collect(),
        raw.iter().map(|&v| v & 1 == 1).collect(),
    )
    .map_err(|e| corrupt(e.to_string()))
}

/// The figures of an automatic registration ([`vt_core::register`]), in scene.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegistrationEntry {
    /// Where the plane was estimated: "focus" (around the moving region) or "whole".
    pub plane: String,
    /// Features detected in the two backgrounds.
    pub features: [usize; 2],
    /// Mutual-best matches passing the ratio test.
    pub matches: usize,
    /// Inlier matches of the plane.
    pub inliers: usize,
    /// Cells of an 8x8 grid holding an inlier.
    pub cells: usize,
    /// RMS transfer error of the inliers under the robust homography, pixels.
    pub rms: f64,
    /// Matches outside the focus region that the plane explains, and all of them.
    pub rest: [usize; 2],
    /// The fit picture, relative to the scene.
    pub picture: String,
    /// The moving object's own plane (footprint, then silhouettes at matching phases): its
    /// model, the silhouettes' error under the background's homography and under it, and
    /// whether it was used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object_plane: Option<vt_core::analysis::ObjectPlane>,
    /// The fundamental matrix (a to b, rows) when the matches showed parallax and the plane is
    /// one that the epipolar geometry allows ([`vt_core::register::epipolar`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub epipolar: Option<[[f64; 3]; 3]>,
}

impl RegistrationEntry {
    fn new(
        r: &vt_core::register::PairRegistration,
        object: Option<vt_core::analysis::ObjectPlane>,
        p: usize,
    ) -> Self {
        Self {
            object_plane: object,
            plane: match r.plane {
                vt_core::register::PlaneSource::Focus => "focus",
                vt_core::register::PlaneSource::Whole => "whole",
            }
            .into(),
            features: [r.features.0, r.features.1],
            matches: r.matches,
            inliers: r.inliers.len(),
            cells: r.cells,
            rms: r.rms,
            rest: [r.rest_inliers.0, r.rest_inliers.1],
            picture: fit_name(p),
            epipolar: r
                .epipolar
                .map(|f| std::array::from_fn(|i| std::array::from_fn(|j| f[(i, j)]))),
        }
    }
}

/// File name of the fit picture of link p -> p + 1 ([`vt_core::register::fit_picture`]).
pub fn fit_name(p: usize) -> String {
    format!("fit_{p:03}.png")
}

fn rows(h: &Homography) -> [[f64; 3]; 3] {
    let m = h.matrix();
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

impl LinkEntry {
    fn from_h(h: &Homography, rms: f64, seam: f64) -> Self {
        Self {
            seam,
            homography: rows(h),
            rms,
            points_homography: None,
            refinement: None,
            registration: None,
            parallax: None,
        }
    }

    /// A link entry from an analysis link, `forward` for `H_(p,p+1)`, else its inverse.
    fn from_link(l: &vt_core::analysis::Link, forward: bool) -> Self {
        let pick = |h: Homography| if forward { h } else { h.inverse() };
        let refined = l.refinement.is_some_and(|r| r.kept);
        Self {
            points_homography: refined.then(|| rows(&pick(l.points_homography))),
            refinement: l.refinement,
            ..Self::from_h(&pick(l.homography), l.rms, l.seam)
        }
    }

    /// The homography, validated.
    pub fn homography(&self) -> vt_core::Result<Homography> {
        let h = &self.homography;
        Homography::from_matrix(nalgebra_matrix(h))
    }
}

fn nalgebra_matrix(h: &[[f64; 3]; 3]) -> nalgebra::Matrix3<f64> {
    nalgebra::Matrix3::new(
        h[0][0], h[0][1], h[0][2], h[1][0], h[1][1], h[1][2], h[2][0], h[2][1], h[2][2],
    )
}

/// Eq. (2) tables, one entry per frame of this view.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Transitions {
    /// `t_{p+1}(s, p)`: all null for the last view.
    pub next: Vec<Option<usize>>,
    /// `t_{p-1}(s, p)`: all null for the first view.
    pub prev: Vec<Option<usize>>,
    /// Seam score of each `next` switch (ordinary steps of the target; empty in scenes analysed
    /// before seams were kept per switch).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub next_seam: Vec<f32>,
    /// Seam score of each `prev` switch.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub prev_seam: Vec<f32>,
}

/// File name of view p's background.
pub fn background_name(p: usize) -> String {
    format!("background_{p:03}.png")
}

/// File name of view p's dynamic-region alpha image.
pub fn dynamic_name(p: usize) -> String {
    format!("dynamic_{p:03}.png")
}

/// Writes an analysis into a scene directory (whose object stores
/// [`crate::objects::StoreWriter`] wrote as the masks arrived): each view's median background,
/// its dynamic-region alpha, each link's fit picture (the next view's background warped onto
/// this one in a checkerboard, the points drawn: [`fit_name`]), and scene.json with the views'
/// source frame rate `fps`. The seams (`loop_seam`, each link's `seam`, `seam_score`) are left at
/// 0: they are measured on rendered frames once the scene exists (`vt_app::analyze`).
pub fn write_analysis(
    dir: &Path,
    a: &SceneAnalysis,
    params: &AnalyzeParams,
    fps: Option<f64>,
) -> Result<SceneFile> {
    for (p, v) in a.views.iter().enumerate() {
        crate::frames::write_png(&dir.join(background_name(p)), &v.background)?;
    }
    write_dynamic(dir, a)?;
    for (p, l) in a.links.iter().enumerate() {
        let pts: Vec<Point> = match a.registration.get(p) {
            Some(r) => r.inliers.iter().map(|(s, _)| *s).collect(),
            None => a.points.get(p).cloned().unwrap_or_default(),
        };
        let (bg, next) = (&a.views[p].background, &a.views[p + 1].background);
        let cell = (a.width.max(a.height) / 12).max(8);
        let pic = vt_core::register::fit_picture(bg, next, &l.homography, &pts, cell);
        crate::frames::write_png(&dir.join(fit_name(p)), &pic)?;
        if let Some(par) = &l.parallax {
            write_field(&dir.join(parallax_name(p, 0)), &par.a)?;
            write_field(&dir.join(parallax_name(p, 1)), &par.b)?;
        }
    }
    let mut scene = SceneFile::from_analysis(a, params);
    scene.fps = fps;
    scene.write(dir)?;
    Ok(scene)
}

/// Writes the dynamic-region alpha images of an analysis into a scene directory.
pub fn write_dynamic(dir: &Path, a: &SceneAnalysis) -> Result<()> {
    for (p, v) in a.views.iter().enumerate() {
        if let Some(alpha) = &v.dynamic_alpha {
            let path = dir.join(dynamic_name(p));
            alpha.save(&path).map_err(|e| Error::Image {
                path: path.clone(),
                message: e.to_string(),
            })?;
        }
    }
    Ok(())
}

/// File name of view p's object store.
pub fn objects_name(p: usize) -> String {
    format!("objects_{p:03}.bin")
}

impl SceneFile {
    /// Builds scene.json's contents from an analysis.
    pub fn from_analysis(a: &SceneAnalysis, params: &AnalyzeParams) -> Self {
        let points = &a.points;
        let model = a.selection.as_ref().map(|s| ModelEntry {
            chosen: s.model,
            forced: s.forced,
            gric: s
                .scores
                .iter()
                .map(|(k, v)| (k.name().to_string(), *v))
                .collect(),
        });
        let views = a
            .views
            .iter()
            .enumerate()
            .map(|(p, v)| {
                let none = vec![None; v.n_frames];
                let next = a.links.get(p);
                let prev = if p > 0 { a.links.get(p - 1) } else { None };
                ViewEntry {
                    name: v.name.clone(),
                    frames: v.n_frames,
                    points: points
                        .get(p)
                        .map(|ps| ps.iter().map(|q| [q.x, q.y]).collect())
                        .unwrap_or_default(),
                    background: background_name(p),
                    objects: objects_name(p),
                    moving_fraction: v.moving_fraction,
                    mean_step: v.mean_step,
                    loop_seam: v.loop_seam,
                    loop_: v.best_loop.into(),
                    alternatives: v.alternatives.iter().map(|&l| l.into()).collect(),
                    to_next: next.map(|l| LinkEntry {
                        parallax: l.parallax_figures.map(|figures| ParallaxEntry {
                            figures,
                            fields: l.parallax.as_ref().map(|par| {
                                [0, 1].map(|side| ParallaxFieldEntry {
                                    file: parallax_name(p, side),
                                    direction: [&par.a, &par.b][side].direction(),
                                    lines: [&par.a, &par.b][side].lines(),
                                })
                            }),
                        }),
                        registration: a.registration.get(p).map(|r| {
                            RegistrationEntry::new(r, a.object_planes.get(p).copied().flatten(), p)
                        }),
                        ..LinkEntry::from_link(l, true)
                    }),
                    to_prev: prev.map(|l| LinkEntry::from_link(l, false)),
                    refined_points: a
                        .refined_points
                        .as_ref()
                        .and_then(|r| r.get(p).map(|ps| ps.iter().map(|q| [q.x, q.y]).collect())),
                    transitions: Transitions {
                        next: next
                            .map(|l| l.to_next.clone())
                            .unwrap_or_else(|| none.clone()),
                        prev: prev.map(|l| l.to_prev.clone()).unwrap_or(none),
                        next_seam: next.map(|l| l.to_next_seam.clone()).unwrap_or_default(),
                        prev_seam: prev.map(|l| l.to_prev_seam.clone()).unwrap_or_default(),
                    },
                    dynamic: v.dynamic_alpha.as_ref().map(|_| dynamic_name(p)),
                    dynamic_fraction: v.dynamic_fraction,
                    motion_kept: Some(v.motion_kept),
                    noise_sigma: v.noise_sigma,
                }
            })
            .collect();
        SceneFile {
            format: FORMAT.into(),
            version: VERSION,
            created_by: format!("vt {}", env!("CARGO_PKG_VERSION")),
            width: a.width,
            height: a.height,
            params: *params,
            model,
            seam_score: {
                let all: Vec<f64> = a
                    .views
                    .iter()
                    .map(|v| v.loop_seam)
                    .chain(a.links.iter().map(|l| l.seam))
                    .collect();
                all.iter().sum::<f64>() / all.len().max(1) as f64
            },
            fps: None,
            views,
        }
    }

    /// Writes scene.json into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join("scene.json");
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::Scene {
            path: path.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(&path, text).map_err(|e| Error::io(&path, e))
    }

    /// Reads and validates `dir/scene.json` (format, version, and internal consistency).
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join("scene.json");
        let text =
            crate::limits::read_text(&path, crate::limits::MAX_SCENE_JSON_BYTES, "scene.json")?;
        Self::parse(&text, &path)
    }

    /// Parses and validates scene.json's text (format, version, limits, internal consistency);
    /// `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let path = path.to_path_buf();
        let bad = |message: String| Error::Scene {
            path: path.clone(),
            message,
        };
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| bad(format!("corrupted: not valid JSON ({e})")))?;
        if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(bad(format!("not a vt scene (format is not \"{FORMAT}\")")));
        }
        let version = value.get("version").and_then(|v| v.as_u64()).unwrap_or(0);
        if version != VERSION as u64 {
            return Err(bad(format!(
                "scene format version {version}, but this vt reads version {VERSION}: re-run `vt analyze` to rebuild it"
            )));
        }
        let scene: SceneFile =
            serde_json::from_value(value).map_err(|e| bad(format!("corrupted: {e}")))?;
        scene.validate().map_err(bad)?;
        Ok(scene)
    }

    fn validate(&self) -> std::result::Result<(), String> {
        use crate::limits::{MAX_FRAMES, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_POINTS, MAX_VIEWS};
        if self.views.is_empty() {
            return Err("no views".into());
        }
        let m = self.views.len();
        if m > MAX_VIEWS {
            return Err(format!("{m} views, more than the {MAX_VIEWS} vt reads"));
        }
        let (w, h) = (self.width, self.height);
        if w == 0
            || h == 0
            || w > MAX_IMAGE_SIDE
            || h > MAX_IMAGE_SIDE
            || w as u64 * h as u64 > MAX_IMAGE_PIXELS
        {
            return Err(format!(
                "frame size {w}x{h} is out of range (1 to {MAX_IMAGE_SIDE} per side, at most {MAX_IMAGE_PIXELS} pixels)"
            ));
        }
        for (p, v) in self.views.iter().enumerate() {
            if v.frames > MAX_FRAMES {
                return Err(format!(
                    "view {p}: {} frames, more than the {MAX_FRAMES} vt reads",
                    v.frames
                ));
            }
            if v.points.len() > MAX_POINTS {
                return Err(format!(
                    "view {p}: {} points, more than the {MAX_POINTS} vt reads",
                    v.points.len()
                ));
            }
            for (what, name) in [("background", &v.background), ("objects", &v.objects)] {
                if !is_plain_file_name(name) {
                    return Err(format!(
                        "view {p}: {what} '{}' is not a file name inside the scene folder",
                        crate::output::shorten(name)
                    ));
                }
            }
            let l = v.loop_;
            if !(l.start < l.end && l.end < v.frames) {
                return Err(format!(
                    "view {p}: loop ({}, {}) does not fit {} frames",
                    l.start, l.end, v.frames
                ));
            }
            for (side, table, exists) in [
                ("next", &v.transitions.next, p + 1 < m),
                ("prev", &v.transitions.prev, p > 0),
            ] {
                if table.len() != v.frames {
                    return Err(format!(
                        "view {p}: {} {side} transitions for {} frames",
                        table.len(),
                        v.frames
                    ));
                }
                if exists {
                    let q = if side == "next" { p + 1 } else { p - 1 };
                    let end = self.views[q].loop_.end;
                    if let Some((s, t)) = table
                        .iter()
                        .enumerate()
                        .find_map(|(s, t)| t.filter(|&t| t + 1 >= end).map(|t| (s, t)))
                    {
                        return Err(format!("view {p}: {side} transition of frame {s} is {t}, beyond view {q}'s loop end {end}"));
                    }
                }
            }
            for (side, link, exists) in [
                ("to_next", &v.to_next, p + 1 < m),
                ("to_prev", &v.to_prev, p > 0),
            ] {
                match (link, exists) {
                    (Some(l), true) => {
                        l.homography()
                            .map_err(|e| format!("view {p}: {side}: {e}"))?;
                    }
                    (None, false) => {}
                    _ => {
                        return Err(format!(
                            "view {p}: {side} homography is {}",
                            if exists { "missing" } else { "unexpected" }
                        ))
                    }
                }
            }
        }
        Ok(())
    }

    /// Path of a file of the scene.
    pub fn file(dir: &Path, name: &str) -> PathBuf {
        dir.join(name)
    }
}

/// True for a bare file name: not empty, no folder separators, not `.` or `..`, so joining it
/// to a folder stays inside that folder.
pub fn is_plain_file_name(name: &str) -> bool {
    !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\', '\0'])
        && !(name.len() >= 2 && name.as_bytes()[1] == b':')
}

/// A scene loaded for rendering: its file, the renderer's view of it, and the object stores.
/// Every table is held once: the transition tables move from `file` into `render`.
pub struct LoadedScene {
    /// scene.json, less its transition tables (each view's `transitions` is empty: the tables
    /// are `render`'s `to_next`/`to_prev` and their seams).
    pub file: SceneFile,
    /// Backgrounds, loops, tables, points, model; shared (`Arc`) with the renderers made from it.
    pub render: std::sync::Arc<vt_core::render::RenderScene>,
    /// Moving-object pixels.
    pub objects: crate::objects::SceneObjects,
}

impl LoadedScene {
    /// The frame rate to play at: the source's (scene.json's `fps`) when it is known and at most
    /// `max`, else 30.
    pub fn source_fps(&self, max: f64) -> f64 {
        self.file
            .fps
            .filter(|f| f.is_finite() && *f > 0.0 && *f <= max)
            .unwrap_or(30.0)
    }

    /// Loads and cross-checks every part of a scene directory.
    pub fn open(dir: &Path) -> Result<Self> {
        if !dir.is_dir() {
            return Err(Error::Scene {
                path: dir.to_path_buf(),
                message: "not a scene directory (run `vt analyze` first)".into(),
            });
        }
        let mut file = SceneFile::read(dir)?;
        let mut views = Vec::new();
        let mut stores = Vec::new();
        for v in &file.views {
            let bg_path = dir.join(&v.background);
            let background = crate::frames::read_rgb(&bg_path)?;
            if background.dimensions() != (file.width, file.height) {
                return Err(Error::Scene {
                    path: bg_path,
                    message: format!(
                        "background is {}x{}, the scene is {}x{}",
                        background.width(),
                        background.height(),
                        file.width,
                        file.height
                    ),
                });
            }
            let obj_path = dir.join(&v.objects);
            let store = crate::objects::ObjectStore::load(&obj_path)?;
            if store.len() != v.frames || store.size() != (file.width, file.height) {
                return Err(Error::Scene {
                    path: obj_path,
                    message: format!(
                        "corrupted: {} frames of {}x{}, scene.json says {} of {}x{}",
                        store.len(),
                        store.size().0,
                        store.size().1,
                        v.frames,
                        file.width,
                        file.height
                    ),
                });
            }
            stores.push(store);
            let dynamic = match &v.dynamic {
                Some(name) => {
                    let path = dir.join(name);
                    let img = image::open(&path)
                        .map_err(|e| Error::Image {
                            path: path.clone(),
                            message: e.to_string(),
                        })?
                        .to_luma8();
                    if img.dimensions() != (file.width, file.height) {
                        return Err(Error::Scene {
                            path,
                            message: format!(
                                "dynamic region is {}x{}, the scene is {}x{}",
                                img.width(),
                                img.height(),
                                file.width,
                                file.height
                            ),
                        });
                    }
                    Some(std::sync::Arc::new(img))
                }
                None => None,
            };
            views.push(vt_core::render::RenderView {
                dynamic,
                background,
                loop_start: v.loop_.start,
                loop_end: v.loop_.end,
                // Moved in below, once the file is checked.
                to_next: Vec::new(),
                to_prev: Vec::new(),
                to_next_seam: Vec::new(),
                to_prev_seam: Vec::new(),
                points: v
                    .refined_points
                    .as_ref()
                    .filter(|r| r.len() == v.points.len())
                    .unwrap_or(&v.points)
                    .iter()
                    .map(|p| Point::new(p[0], p[1]))
                    .collect(),
            });
        }
        let model = file
            .model
            .as_ref()
            .map(|m| m.chosen)
            .unwrap_or(MotionModel::Translation);
        if views.len() > 1 && views.iter().any(|v| v.points.len() < 4) {
            return Err(Error::Scene {
                path: dir.join("scene.json"),
                message: "corrupted: views without points".into(),
            });
        }
        for (view, entry) in views.iter_mut().zip(&mut file.views) {
            let t = std::mem::take(&mut entry.transitions);
            (view.to_next, view.to_prev) = (t.next, t.prev);
            (view.to_next_seam, view.to_prev_seam) = (t.next_seam, t.prev_seam);
        }
        let mut parallax = Vec::new();
        for v in file.views.iter().take(file.views.len().saturating_sub(1)) {
            let fields = v
                .to_next
                .as_ref()
                .and_then(|l| l.parallax.as_ref())
                .and_then(|e| e.fields.as_ref());
            parallax.push(match fields {
                Some([fa, fb]) => {
                    let size = (file.width, file.height);
                    let a = read_field(&dir.join(&fa.file), fa, size)?;
                    let b = read_field(&dir.join(&fb.file), fb, size)?;
                    Some(std::sync::Arc::new(vt_core::parallax::PairParallax {
                        a,
                        b,
                    }))
                }
                None => None,
            });
        }
        Ok(Self {
            file,
            render: std::sync::Arc::new(vt_core::render::RenderScene {
                views,
                model,
                parallax,
            }),
            objects: crate::objects::SceneObjects { stores },
        })
    }
}
