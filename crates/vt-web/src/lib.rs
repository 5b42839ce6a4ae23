//! `vt export`: an analysed scene as a folder with `index.html` and its assets that plays the
//! scene in a browser with no server, opened from disk (file://) or from any static host.
//!
//! # Why the assets are scripts
//! A page opened from file:// may not read files by `fetch` or XHR, and images or videos it loads
//! from file:// taint WebGL (`texImage2D` throws). Scripts do load, so every asset is a small
//! script `data/*.js` that hands a base64 payload to the player (`vtPayload(...)`); the player
//! turns it into a `Blob` (same-origin) and decodes it with `createImageBitmap` for textures.
//!
//! # What the page does
//! The player (`player.js`, with one fragment shader per warp: `blend.frag` eq. (3),
//! `morph.frag` the background morph along the stored parallax fields, `composite.frag` the
//! object and dynamic region of eq. (4)-(5) with the feathered alpha, `mix.frag` the switch fade,
//! crossfade and dissolve) is a port of [`vt_core::render`]'s `Player` (eq. 6 with the switch policy) and
//! `Renderer` with the same [`RenderParams`]. What it cannot compute cheaply in the browser is
//! computed here and shipped: the per-view gains ([`vt_core::render::estimate_gains`]) and
//! `H_(p,q)^-1` on a grid of [`Q_STEPS`] viewpoints per view interval (the page interpolates
//! between grid points; at grid points it is vt's own homography).
//!
//! # Object frames on demand
//! The page decodes an object frame when a render needs it (its JPEG, or the H.264 group of
//! [`H264_GROUP`] frames that holds it), decodes the next frames and the neighbours' switch
//! targets ahead, and keeps decoded frames as textures up to [`ExportOptions::gpu_mb`], dropping
//! the least recently used: it starts playing once the first frame is decoded, and its GPU
//! memory is bounded by the setting, not by the scene's length. A view's object payload is one
//! small script (boxes, groups) and one script per group (its masks and pictures), loaded when a
//! frame of the group is first needed, so opening the page reads none of the frames.
//!
//! # Media
//! Backgrounds and dynamic-region alphas as vt's PNGs; masks bit-packed per frame box, the frames
//! of a group deflated together; parallax fields as their per-pixel displacement (`i16`, 1/32 px),
//! deflated. Object pixels ([`Media`]): by default one H.264 stream per view over the union of
//! its boxes ([`h264`]) at, per view, the largest CRF whose decoded object pixels keep
//! [`TARGET_DB`] against the scene's, decoded by the browser's WebCodecs into I420 planes that
//! the shader converts (BT.601 limited range, each chroma sample for its 2x2 block, as vt's own
//! 4:2:0 conversion: the browser's conversion cost 4.7 dB at CRF 10, bilinear chroma 6 dB on a
//! tree frame); or one JPEG per frame box. Either way the pixels outside the object are filled
//! from the background, so the edge costs no bits. Measured against vt's frames (docs/system-a.md has
//! the table): tree.avi 5 views 45.5-47.9 dB at 1.02x its scene; a fixed CRF 12 with bilinear
//! chroma was 41.3-43.8 dB at 0.72x, JPEG quality 92 43.4-46.0 dB at 2.6x.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use image::RgbImage;
use vt_core::render::{ObjectFrames, ObjectPatch, RenderParams};
use vt_core::warp::Interpolation;
use vt_io::output::{Output, OutputKind};
use vt_io::scene::LoadedScene;

pub mod fv;
mod h264;

/// Grid points per view interval at which `H_(p,q)^-1` is stored (the page interpolates).
pub const Q_STEPS: usize = 64;

/// Default JPEG quality of the object frames ([`Media::Jpeg`]).
pub const DEFAULT_QUALITY: u8 = 92;

/// What the object video keeps by default ([`Media::H264`] without a fixed CRF): per view, the
/// largest constant rate factor (in steps of 2) whose decoded frames are this close to the
/// scene's over the object pixels, dB.
pub const TARGET_DB: f64 = 42.0;

/// How the object frames travel to the browser.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Media {
    /// One H.264 stream per view (the default), decoded by the browser's WebCodecs.
    H264 {
        /// libx264's constant rate factor, 0..=51 (lower: better and larger); None: per view
        /// the largest that keeps [`TARGET_DB`].
        crf: Option<u8>,
    },
    /// One JPEG per frame (any browser with WebGL2).
    Jpeg {
        /// Quality, 1..=100.
        quality: u8,
    },
}

impl Default for Media {
    fn default() -> Self {
        Media::H264 { crf: None }
    }
}

impl Media {
    /// Checks the setting's range.
    pub fn check(&self) -> Result<()> {
        let (name, value, ok, why) = match *self {
            Media::H264 { crf } => (
                "crf",
                crf.unwrap_or(0),
                crf.is_none_or(|c| c <= 51),
                "a constant rate factor from 0 to 51",
            ),
            Media::Jpeg { quality } => (
                "quality",
                quality,
                (1..=100).contains(&quality),
                "a JPEG quality from 1 to 100",
            ),
        };
        if ok {
            return Ok(());
        }
        Err(Error::InvalidParameter {
            name,
            value: value.to_string(),
            why: why.into(),
        })
    }
}

/// Appends `'b64','b64',...` (each item base64-encoded and quoted) to a payload's JS text.
fn push_base64_list<'a>(text: &mut String, items: impl Iterator<Item = &'a Vec<u8>>) {
    for (i, item) in items.enumerate() {
        if i > 0 {
            text.push(',');
        }
        text.push('\'');
        text.push_str(&base64(item));
        text.push('\'');
    }
}

const PAGE: &str = include_str!("index.html");
const PLAYER: &str = include_str!("player.js");
/// The pages' shared helpers, written ahead of each page's script.
const UTIL: &str = include_str!("util.js");
const VERTEX: &str = include_str!("quad.vert");
const COMMON: &str = include_str!("common.glsl");
const BLEND: &str = include_str!("blend.frag");
const MORPH: &str = include_str!("morph.frag");
const COMPOSITE: &str = include_str!("composite.frag");
const MIX: &str = include_str!("mix.frag");
const PRESENT: &str = include_str!("present.frag");

/// What can go wrong in an export.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading the scene or writing the output.
    #[error(transparent)]
    Io(#[from] vt_io::Error),
    /// The renderer's tables (homographies, gains, object frames).
    #[error(transparent)]
    Core(#[from] vt_core::Error),
    /// A parameter out of its range.
    #[error("{name} {value}: {why}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: String,
        /// The rule it breaks.
        why: String,
    },
    /// An image could not be encoded.
    #[error("cannot encode {what}: {message}")]
    Encode {
        /// What was being encoded.
        what: String,
        /// The encoder's message.
        message: String,
    },
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// How to export.
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// The render parameters the page plays with (switch fade, crossfade, dissolve, neighbour fill, gains,
    /// interpolation); background reuse is not exported (the page blends every new q).
    pub params: RenderParams,
    /// How the object frames are encoded.
    pub media: Media,
    /// The page's title (the scene's name).
    pub title: String,
    /// Frames per second at speed 1, in (0, [`MAX_FPS`]] (None: the scene's source rate).
    pub fps: Option<f64>,
    /// The viewpoint the page opens at (None: the middle of the views).
    pub start_q: Option<f64>,
    /// GPU memory the page's object frames may hold, MB, at least [`MIN_GPU_MB`]: frames are
    /// decoded when a render needs them (a JPEG each, or the H.264 group of [`H264_GROUP`]
    /// frames that holds one) and the least recently used are dropped beyond this.
    pub gpu_mb: u32,
    /// Where the page sends a browser that cannot play it (no WebGL2, or no WebCodecs for
    /// H.264 frames), relative to the page: `vt view`'s CPU-rendered stream. None: the page says
    /// what is missing.
    pub fallback: Option<String>,
}

/// Frames from one key frame to the next in the H.264 object streams: the page decodes a frame's
/// whole group when it needs the frame, so this bounds the work of a jump (a loop wrap, a switch).
pub const H264_GROUP: usize = 16;

/// Default of [`ExportOptions::gpu_mb`].
pub const DEFAULT_GPU_MB: u32 = 256;
/// Least [`ExportOptions::gpu_mb`]: a few HD frames.
pub const MIN_GPU_MB: u32 = 1;
/// Most [`ExportOptions::gpu_mb`].
pub const MAX_GPU_MB: u32 = 65536;

/// Fastest frame rate a page plays at speed 1.
pub const MAX_FPS: f64 = 240.0;

impl ExportOptions {
    /// Checks every setting against `scene` (the media's range, the frame rate, the starting
    /// viewpoint, the renderer's own limits on crossfade and dissolve).
    pub fn check(&self, scene: &LoadedScene) -> Result<()> {
        self.media.check()?;
        let bad = |name, value: f64, why: String| {
            Err(Error::InvalidParameter {
                name,
                value: vt_io::output::num(value),
                why,
            })
        };
        if !(MIN_GPU_MB..=MAX_GPU_MB).contains(&self.gpu_mb) {
            return bad(
                "gpu-mb",
                self.gpu_mb.into(),
                format!("must be in {MIN_GPU_MB}..={MAX_GPU_MB}"),
            );
        }
        if let Some(fps) = self.fps {
            if !(fps.is_finite() && fps > 0.0 && fps <= MAX_FPS) {
                return bad("fps", fps, format!("must be in (0, {MAX_FPS}]"));
            }
        }
        if let Some(q) = self.start_q {
            if scene.render.check_q(q).is_err() {
                let (q_max, n) = (scene.render.q_max(), scene.render.views.len());
                return bad(
                    "q",
                    q,
                    format!("is outside [0, {q_max}] (the scene has {n} views)"),
                );
            }
        }
        vt_core::render::Renderer::new(scene.render.clone(), self.params)?;
        Ok(())
    }
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            params: RenderParams::default(),
            media: Media::default(),
            title: "scene".into(),
            fps: None,
            start_q: None,
            gpu_mb: DEFAULT_GPU_MB,
            fallback: None,
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportSummary {
    /// Bytes of the folder (every file).
    pub bytes: u64,
    /// Files written.
    pub files: usize,
    /// Bytes of the object frames' payloads (JPEG and masks, base64 included).
    pub object_bytes: u64,
    /// Object frames exported.
    pub frames: usize,
    /// The H.264 constant rate factor of each view with moving pixels (empty for JPEG).
    pub crfs: Vec<u8>,
}

/// Progress of an export: `(done, total)` object frames.
pub type Progress<'a> = &'a mut (dyn FnMut(usize, usize) + Send);

/// Writes the page for `scene` (read from `scene_dir`) to the folder `out` through
/// [`vt_io::output`] (built under a temporary name, renamed into place; never replaces what vt
/// did not write).
pub fn export(
    scene: &LoadedScene,
    scene_dir: &Path,
    out: &Path,
    opts: &ExportOptions,
    progress: Progress<'_>,
) -> Result<ExportSummary> {
    opts.check(scene)?;
    // Inside the scene the export would change the folder it reads (and its size).
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let (Ok(scene), Ok(parent)) = (scene_dir.canonicalize(), parent.canonicalize()) {
        if parent.starts_with(&scene) {
            return Err(Error::InvalidParameter {
                name: "--out",
                value: out.display().to_string(),
                why: format!("is inside the scene folder {}", scene_dir.display()),
            });
        }
    }
    let output = Output::dir(out, OutputKind::WebExport, &[scene_dir])?;
    let root = output.path().to_path_buf();
    std::fs::create_dir(root.join("data")).map_err(|e| vt_io::Error::io(root.join("data"), e))?;
    let summary = write_page(scene, opts, &mut Folder(root), progress)?;
    output.commit()?;
    Ok(summary)
}

/// The page for `scene` in memory, each file under its path in the page (`index.html`,
/// `data/scene.js`, ...): what `vt view` serves on loopback, the same files [`export`] writes.
pub fn page(
    scene: &LoadedScene,
    opts: &ExportOptions,
    progress: Progress<'_>,
) -> Result<(BTreeMap<String, Vec<u8>>, ExportSummary)> {
    let mut files = BTreeMap::new();
    let summary = write_page(scene, opts, &mut files, progress)?;
    Ok((files, summary))
}

/// Where a page's files go: a folder ([`export`]) or memory ([`page`]).
trait Sink {
    /// Stores one file under its path in the page (`/`-separated).
    fn put(&mut self, name: &str, bytes: Vec<u8>) -> Result<()>;
}

/// The folder being exported.
struct Folder(PathBuf);

impl Sink for Folder {
    fn put(&mut self, name: &str, bytes: Vec<u8>) -> Result<()> {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).map_err(|e| vt_io::Error::io(&path, e).into())
    }
}

impl Sink for BTreeMap<String, Vec<u8>> {
    fn put(&mut self, name: &str, bytes: Vec<u8>) -> Result<()> {
        self.insert(name.to_string(), bytes);
        Ok(())
    }
}

/// Every file of the page for `scene` into `sink`.
fn write_page(
    scene: &LoadedScene,
    opts: &ExportOptions,
    sink: &mut dyn Sink,
    progress: Progress<'_>,
) -> Result<ExportSummary> {
    opts.check(scene)?;
    let mut written = Written {
        sink,
        bytes: 0,
        files: 0,
        object_bytes: 0,
    };
    let render = &scene.render;
    let m = render.views.len();
    let (w, h) = (scene.file.width, scene.file.height);

    // Per view: background, dynamic alpha, object frames.
    let total: usize = render.views.iter().map(|v| v.to_next.len()).sum();
    let mut done = 0;
    let mut frames_per_view = Vec::with_capacity(m);
    let mut crfs = Vec::new();
    for (p, view) in render.views.iter().enumerate() {
        let png = encode_png_rgb(&view.background, &format!("background of view {p}"))?;
        written.script(
            &format!("background_{p:03}.js"),
            &format!("vtPayload('background',{p},'{}');", base64(&png)),
        )?;
        if let Some(d) = &view.dynamic {
            let png = encode_png_gray(d, &format!("dynamic region of view {p}"))?;
            written.script(
                &format!("dynamic_{p:03}.js"),
                &format!("vtPayload('dynamic',{p},'{}');", base64(&png)),
            )?;
        }
        let n = view.to_next.len();
        frames_per_view.push(n);
        let objects = match opts.media {
            Media::Jpeg { quality } => objects_jpeg(scene, p, n, quality, &mut |_| {
                done += 1;
                progress(done, total)
            })?,
            Media::H264 { crf } => {
                let (objects, used) = objects_h264(scene, p, n, crf, &mut |_| {
                    done += 1;
                    progress(done, total)
                })?;
                crfs.extend(used);
                objects
            }
        };
        objects.write(p, &mut written)?;
    }

    // Parallax fields of the morphed pairs.
    let mut parallax = Vec::new();
    for p in 0..m.saturating_sub(1) {
        match render.parallax.get(p).and_then(Option::as_ref) {
            Some(par) => {
                let mut raw = Vec::with_capacity(par.a.flow().len() * 8);
                for field in [&par.a, &par.b] {
                    for u in field.flow() {
                        raw.extend_from_slice(&u[0].to_le_bytes());
                        raw.extend_from_slice(&u[1].to_le_bytes());
                    }
                }
                written.script(
                    &format!("parallax_{p:03}.js"),
                    &format!("vtPayload('parallax',{p},'{}');", base64(&deflate(&raw))),
                )?;
                let (da, db) = (par.a.direction(), par.b.direction());
                parallax.push(Some(serde_json::json!([
                    par.a.width(),
                    par.a.height(),
                    da[0],
                    da[1],
                    db[0],
                    db[1]
                ])));
            }
            None => parallax.push(None),
        }
    }

    // The scene's tables, gains and the homography grid.
    let gains = if opts.params.gain_compensation {
        vt_core::render::estimate_gains(render)?
    } else {
        vec![[1.0; 3]; m]
    };
    let grid = homography_grid(scene)?;
    let views: Vec<serde_json::Value> = render
        .views
        .iter()
        .enumerate()
        .map(|(p, v)| {
            let seam = |s: &[f32]| s.iter().map(|&x| x as f64).collect::<Vec<f64>>();
            serde_json::json!({
                "loop_start": v.loop_start,
                "loop_end": v.loop_end,
                "frames": frames_per_view[p],
                "to_next": v.to_next,
                "to_prev": v.to_prev,
                "to_next_seam": seam(&v.to_next_seam),
                "to_prev_seam": seam(&v.to_prev_seam),
                "dynamic": v.dynamic.is_some(),
                "gain": gains[p].map(f64::from),
            })
        })
        .collect();
    let policy = vt_core::render::SwitchPolicy::default();
    let meta = serde_json::json!({
        "title": opts.title,
        "width": w,
        "height": h,
        "fps": opts.fps.unwrap_or_else(|| scene.source_fps(120.0)),
        "start_q": opts.start_q,
        "gpu_bytes": u64::from(opts.gpu_mb) << 20,
        "fallback": opts.fallback,
        "media": match opts.media { Media::H264 { .. } => "h264", Media::Jpeg { .. } => "jpeg" },
        "views": views,
        "parallax": parallax,
        "q_steps": Q_STEPS,
        "policy": {
            "max_seam": policy.max_seam,
            "max_past_tie": policy.max_past_tie,
            "max_frames": policy.max_frames,
        },
        "params": {
            "crossfade": opts.params.crossfade,
            "dissolve": opts.params.dissolve,
            "switch_fade": opts.params.switch_fade,
            "neighbour_fill": opts.params.neighbour_fill,
            "nearest": opts.params.interpolation == Interpolation::Nearest,
        },
        "flow_unit": vt_core::parallax::FLOW_UNIT,
        "morph_steps": vt_core::parallax::FIXED_POINT_STEPS,
        "converged_px": vt_core::parallax::CONVERGED_PX,
        "unconverged_weight": vt_core::parallax::UNCONVERGED_WEIGHT,
        "occlusion_px": vt_core::parallax::OCCLUSION_PX,
    });
    let mut grid_bytes = Vec::with_capacity(grid.len() * 4);
    for v in &grid {
        grid_bytes.extend_from_slice(&v.to_le_bytes());
    }
    written.script(
        "scene.js",
        &format!(
            "var vtScene={};vtScene.hinv='{}';",
            meta,
            base64(&grid_bytes)
        ),
    )?;
    let shaders = serde_json::json!({
        "vert": VERTEX, "common": COMMON, "blend": BLEND, "morph": MORPH, "composite": COMPOSITE,
        "mix": MIX, "present": PRESENT,
    });
    written.script(
        "player.js",
        &format!("var vtShaders={shaders};\n{UTIL}\n{PLAYER}"),
    )?;
    let page = PAGE.replace("__TITLE__", &html_escape(&opts.title));
    written.file("index.html", page.into_bytes())?;
    Ok(ExportSummary {
        bytes: written.bytes,
        files: written.files,
        object_bytes: written.object_bytes,
        frames: total,
        crfs,
    })
}

/// Bytes of every file under `dir` (a scene folder, to compare an export with).
pub fn folder_bytes(dir: &Path) -> Result<u64> {
    let mut total = 0;
    let mut stack: Vec<PathBuf> = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).map_err(|e| vt_io::Error::io(&d, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| vt_io::Error::io(&d, e))?;
            let meta = entry
                .metadata()
                .map_err(|e| vt_io::Error::io(entry.path(), e))?;
            if meta.is_dir() {
                stack.push(entry.path());
            } else {
                total += meta.len();
            }
        }
    }
    Ok(total)
}

/// Calls `f` with every object frame of view `p`, in order.
fn each_frame(
    scene: &LoadedScene,
    p: usize,
    n: usize,
    f: &mut dyn FnMut(usize, &ObjectPatch) -> Result<()>,
) -> Result<()> {
    let mut patch = ObjectPatch::default();
    for i in 0..n {
        scene.objects.decode_into(p, i, &mut patch)?;
        f(i, &patch)?;
    }
    Ok(())
}

/// A view's object frames as the page loads them: `objects_PPP.js` with the boxes, the groups and
/// how the pictures are coded, and per group `objects_PPP_GGGG.js` with its frames' masks
/// (bit-packed, each frame from a byte, deflated) and pictures, loaded when a frame of the group
/// is first needed.
struct Objects {
    boxes: Vec<[u32; 4]>,
    /// Per frame, bit-packed.
    masks: Vec<Vec<u8>>,
    /// Per frame: a JPEG (empty where the frame has no object pixel) or an H.264 access unit.
    pictures: Vec<Vec<u8>>,
    /// The H.264 stream's codec string, union box and coded size; None for JPEG.
    video: Option<serde_json::Value>,
    /// First frame of each group (0 first): the H.264 key frames, or every [`H264_GROUP`]
    /// frames for JPEG.
    groups: Vec<usize>,
}

impl Objects {
    fn write(&self, p: usize, written: &mut Written<'_>) -> Result<()> {
        let head = format!(
            "vtPayload('objects',{p},{});",
            serde_json::json!({
                "boxes": self.boxes,
                "groups": self.groups,
                "video": self.video,
            })
        );
        written.object_bytes += head.len() as u64;
        written.script(&format!("objects_{p:03}.js"), &head)?;
        let n = self.boxes.len();
        for (g, &start) in self.groups.iter().enumerate() {
            let end = self.groups.get(g + 1).copied().unwrap_or(n);
            let masks: Vec<u8> = self.masks[start..end].concat();
            let mut text = format!(
                "vtPayload('group','{p},{g}',{{masks:'{}',pictures:[",
                base64(&deflate(&masks))
            );
            push_base64_list(&mut text, self.pictures[start..end].iter());
            text.push_str("]});");
            written.object_bytes += text.len() as u64;
            written.script(&format!("objects_{p:03}_{g:04}.js"), &text)?;
        }
        Ok(())
    }
}

/// Every [`H264_GROUP`] frames of `n`.
fn fixed_groups(n: usize) -> Vec<usize> {
    (0..n.max(1)).step_by(H264_GROUP).collect()
}

/// A frame's mask bit-packed.
fn packed(mask: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(mask.len().div_ceil(8));
    pack_bits(mask, &mut out);
    out
}

/// View `p`'s object payload with one JPEG per frame's box.
fn objects_jpeg(
    scene: &LoadedScene,
    p: usize,
    n: usize,
    quality: u8,
    tick: &mut dyn FnMut(usize),
) -> Result<Objects> {
    let background = &scene.render.views[p].background;
    let mut boxes = Vec::with_capacity(n);
    let mut jpegs = Vec::with_capacity(n);
    let mut masks = Vec::with_capacity(n);
    // Frames in chunks: decoded in order, encoded in parallel.
    const CHUNK: usize = 16;
    let mut patches = Vec::with_capacity(CHUNK);
    let mut flush = |patches: &mut Vec<(usize, ObjectPatch)>| -> Result<()> {
        use rayon::prelude::*;
        let encoded: Vec<Result<Vec<u8>>> = patches
            .par_iter()
            .map(|(i, pt)| encode_patch(pt, background, quality, p, *i))
            .collect();
        for ((i, pt), jpeg) in patches.drain(..).zip(encoded) {
            boxes.push([pt.x0, pt.y0, pt.width, pt.height]);
            jpegs.push(jpeg?);
            masks.push(packed(&pt.mask));
            tick(i);
        }
        Ok(())
    };
    each_frame(scene, p, n, &mut |i, pt| {
        patches.push((i, pt.clone()));
        if patches.len() == CHUNK {
            flush(&mut patches)?;
        }
        Ok(())
    })?;
    flush(&mut patches)?;
    Ok(Objects {
        boxes,
        masks,
        pictures: jpegs,
        video: None,
        groups: fixed_groups(n),
    })
}

/// View `p`'s object payload as one H.264 stream over the union of its frames' boxes
/// ([`h264`]), masks bit-packed and deflated.
fn objects_h264(
    scene: &LoadedScene,
    p: usize,
    n: usize,
    crf: Option<u8>,
    tick: &mut dyn FnMut(usize),
) -> Result<(Objects, Option<u8>)> {
    let background = &scene.render.views[p].background;
    // Pass 1: boxes, masks and their union.
    let mut boxes = Vec::with_capacity(n);
    let mut masks = Vec::with_capacity(n);
    let (mut lo, mut hi) = ([u32::MAX; 2], [0u32; 2]);
    each_frame(scene, p, n, &mut |_, pt| {
        boxes.push([pt.x0, pt.y0, pt.width, pt.height]);
        masks.push(packed(&pt.mask));
        if pt.width > 0 && pt.height > 0 {
            lo = [lo[0].min(pt.x0), lo[1].min(pt.y0)];
            hi = [hi[0].max(pt.x0 + pt.width), hi[1].max(pt.y0 + pt.height)];
        }
        Ok(())
    })?;
    if hi[0] <= lo[0] || hi[1] <= lo[1] {
        (0..n).for_each(&mut *tick);
        let objects = Objects {
            boxes,
            masks,
            pictures: vec![Vec::new(); n],
            video: None,
            groups: fixed_groups(n),
        };
        return Ok((objects, None));
    }
    // Pass 2: each frame over the union box, the background where it has no object pixel.
    // From even coordinates: the store's 4:2:0 chroma blocks stay the video's blocks.
    let lo = [lo[0] & !1, lo[1] & !1];
    let (ux, uy, uw, uh) = (lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1]);
    let mut crop = Vec::with_capacity(uw as usize * uh as usize * 3);
    for y in uy..uy + uh {
        let row = (y * background.width() + ux) as usize * 3;
        crop.extend_from_slice(&background.as_raw()[row..row + uw as usize * 3]);
    }
    let what = format!("object frames of view {p}");
    let mut patch = ObjectPatch::default();
    // The view's frames over the union box, from the store.
    let mut framer = |i: usize, buf: &mut Vec<u8>| -> Result<()> {
        scene.objects.decode_into(p, i, &mut patch)?;
        buf.extend_from_slice(&crop);
        for y in 0..patch.height {
            for x in 0..patch.width {
                let k = (y * patch.width + x) as usize;
                if patch.mask[k] != 0 {
                    let o = ((patch.y0 + y - uy) * uw + (patch.x0 + x - ux)) as usize * 3;
                    buf[o..o + 3].copy_from_slice(&patch.rgb[3 * k..3 * k + 3]);
                }
            }
        }
        Ok(())
    };
    let mut encode = |crf: u8| h264::encode(uw, uh, crf, n, &what, &mut |i, buf| framer(i, buf));
    let chosen;
    let stream = match crf {
        Some(c) => {
            chosen = c;
            encode(c)?
        }
        None => {
            // From CRF 12 up while the target holds, or down until it does.
            let mut crf = 12u8;
            let mut best: Option<(u8, h264::Stream)> = None;
            loop {
                let s = encode(crf)?;
                let db = object_psnr(scene, p, &s, [ux, uy, uw, uh], &what)?;
                if db >= TARGET_DB {
                    best = Some((crf, s));
                    if !(12..30).contains(&crf) {
                        break;
                    }
                    crf += 2;
                } else if best.is_some() || crf <= 4 {
                    best = best.or(Some((crf, s)));
                    break;
                } else {
                    crf -= 2;
                }
            }
            let (c, s) = best.expect("the loop ends with a stream");
            chosen = c;
            s
        }
    };
    (0..n).for_each(&mut *tick);
    let groups: Vec<usize> = (0..n).filter(|&i| stream.key[i]).collect();
    if groups.first() != Some(&0) {
        return Err(Error::Encode {
            what,
            message: "the stream does not start with a key frame".into(),
        });
    }
    let video = serde_json::json!({
        "codec": stream.codec,
        "x0": ux,
        "y0": uy,
        "width": uw + uw % 2,
        "height": uh + uh % 2,
    });
    let objects = Objects {
        boxes,
        masks,
        pictures: stream.units,
        video: Some(video),
        groups,
    };
    Ok((objects, Some(chosen)))
}

/// PSNR of the stream's decoded frames against the store's over every object pixel, dB.
fn object_psnr(
    scene: &LoadedScene,
    p: usize,
    stream: &h264::Stream,
    [ux, uy, uw, uh]: [u32; 4],
    what: &str,
) -> Result<f64> {
    let bytes: Vec<u8> = stream.units.concat();
    let (pw, ph) = (uw + uw % 2, uh + uh % 2);
    let mut patch = ObjectPatch::default();
    let (mut sse, mut count) = (0f64, 0u64);
    h264::decode(&bytes, pw, ph, what, &mut |i, rgb| {
        scene.objects.decode_into(p, i, &mut patch)?;
        for y in 0..patch.height {
            for x in 0..patch.width {
                let k = (y * patch.width + x) as usize;
                if patch.mask[k] == 0 {
                    continue;
                }
                let o = ((patch.y0 + y - uy) * pw + (patch.x0 + x - ux)) as usize * 3;
                for c in 0..3 {
                    let d = rgb[o + c] as f64 - patch.rgb[3 * k + c] as f64;
                    sse += d * d;
                }
                count += 3;
            }
        }
        Ok(())
    })?;
    if sse == 0.0 || count == 0 {
        return Ok(f64::INFINITY);
    }
    Ok(10.0 * (255.0f64 * 255.0 / (sse / count as f64)).log10())
}

/// `H_(p,q)^-1` (row-major, scaled so its last entry is 1 where it is not near 0) for every view
/// p and every `q = k / Q_STEPS` in `[0, M - 1]`: `[p][k][9]` as `f32`.
fn homography_grid(scene: &LoadedScene) -> Result<Vec<f32>> {
    let render = &scene.render;
    let m = render.views.len();
    let steps = Q_STEPS * (m - 1) + 1;
    let mut out = Vec::with_capacity(m * steps * 9);
    let mut buf = Vec::new();
    for p in 0..m {
        for k in 0..steps {
            let q = k as f64 / Q_STEPS as f64;
            let h = render.homography_to_with(p, q, &mut buf)?;
            let inv = h.raw().1;
            let s = if inv[(2, 2)].abs() > 1e-12 {
                inv[(2, 2)]
            } else {
                1.0
            };
            for r in 0..3 {
                for c in 0..3 {
                    out.push((inv[(r, c)] / s) as f32);
                }
            }
        }
    }
    Ok(out)
}

/// The object frame's box as a JPEG: object pixels, the rest from the view's background (so
/// the edge of the object is smooth for the encoder; the page reads only object pixels).
fn encode_patch(
    patch: &ObjectPatch,
    background: &RgbImage,
    quality: u8,
    view: usize,
    frame: usize,
) -> Result<Vec<u8>> {
    if patch.width == 0 || patch.height == 0 {
        return Ok(Vec::new());
    }
    let (pw, ph) = (patch.width, patch.height);
    let mut img = RgbImage::new(pw, ph);
    for y in 0..ph {
        for x in 0..pw {
            let i = (y * pw + x) as usize;
            let px = if patch.mask[i] != 0 {
                [patch.rgb[3 * i], patch.rgb[3 * i + 1], patch.rgb[3 * i + 2]]
            } else {
                background
                    .get_pixel_checked(patch.x0 + x, patch.y0 + y)
                    .map_or([0; 3], |p| p.0)
            };
            img.put_pixel(x, y, image::Rgb(px));
        }
    }
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality)
        .encode_image(&img)
        .map_err(|e| Error::Encode {
            what: format!("object frame {frame} of view {view}"),
            message: e.to_string(),
        })?;
    Ok(bytes)
}

fn encode_png_rgb(img: &RgbImage, what: &str) -> Result<Vec<u8>> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|e| Error::Encode {
            what: what.into(),
            message: e.to_string(),
        })?;
    Ok(bytes.into_inner())
}

fn encode_png_gray(img: &image::GrayImage, what: &str) -> Result<Vec<u8>> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|e| Error::Encode {
            what: what.into(),
            message: e.to_string(),
        })?;
    Ok(bytes.into_inner())
}

/// Appends `mask` (0 or 1 per pixel) as bits, least significant first, padded to a byte.
fn pack_bits(mask: &[u8], out: &mut Vec<u8>) {
    for chunk in mask.chunks(8) {
        let mut b = 0u8;
        for (i, &v) in chunk.iter().enumerate() {
            if v != 0 {
                b |= 1 << i;
            }
        }
        out.push(b);
    }
}

/// zlib-deflated bytes (what the browser's `DecompressionStream('deflate')` inflates).
fn deflate(bytes: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    enc.write_all(bytes).expect("writing to a Vec cannot fail");
    enc.finish().expect("writing to a Vec cannot fail")
}

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        s.push(A[(n >> 18) as usize & 63] as char);
        s.push(A[(n >> 12) as usize & 63] as char);
        s.push(if c.len() > 1 {
            A[(n >> 6) as usize & 63] as char
        } else {
            '='
        });
        s.push(if c.len() > 2 {
            A[n as usize & 63] as char
        } else {
            '='
        });
    }
    s
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Files written so far and their bytes.
struct Written<'a> {
    sink: &'a mut dyn Sink,
    bytes: u64,
    files: usize,
    object_bytes: u64,
}

impl Written<'_> {
    fn file(&mut self, name: &str, bytes: Vec<u8>) -> Result<()> {
        self.bytes += bytes.len() as u64;
        self.files += 1;
        self.sink.put(name, bytes)
    }

    /// A script under `data/`.
    fn script(&mut self, name: &str, text: &str) -> Result<()> {
        self.file(&format!("data/{name}"), text.as_bytes().to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_standard_alphabet() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn bits_are_least_significant_first() {
        let mut out = Vec::new();
        pack_bits(&[1, 0, 0, 0, 0, 0, 0, 1, 1], &mut out);
        assert_eq!(out, vec![0x81, 0x01]);
    }
}
