//! `vt fv export`: System B's model as a static page (file://, no server) where the user turns
//! around the object and zooms, rendered live in WebGL2 by `vt fv render`'s default method, step
//! for step: the surface voxels splatted as [`vt_fv::render::render_rough`] splats them, the
//! render trimmed to the silhouettes and to the free space of the depth maps
//! ([`vt_fv::render::clip_to_silhouettes`], [`vt_fv::render::clip_to_depths`]), the photos
//! projected onto that surface as [`vt_fv::texture::texture_view`] projects them (the
//! references chosen and faded as [`vt_fv::texture::fading_references`] does, each photo seen
//! only where its own splat render of the model puts nothing in front, unstructured-lumigraph
//! weights, the depth refined where the photos agree, holes filled, softened where the photos
//! disagree, a share of the model's own colours there), and the outline as
//! [`vt_fv::composite`]'s soft alpha over the background. The page's picture is measured
//! against `vt fv render`'s by `crates/vt-cli/tests/fv_page.rs`.
//!
//! Files: `index.html`, `data/viewer.js` (the viewer), `data/fv.js` (cameras, preset views,
//! settings), `data/voxels.js` (surface voxel centres as `f32` and colours), one
//! `data/photo_NNN.js` per photo (PNG, lossless: the texture is the photos themselves),
//! `data/silhouettes.js` (as the trims test them, bit-packed, deflated) and `data/depths.js`
//! (the photos' depth maps and the model's occupied voxels, deflated).

use std::collections::BTreeMap;
use std::path::Path;

use image::RgbImage;
use vt_fv::camera::Camera;
use vt_fv::render::{tested_silhouettes, ClipParams, DepthClipParams, DEFAULT_SPLAT_SCALE};
use vt_fv::texture::{model_centre, TextureParams, FULL_FADE};
use vt_fv::Mask;
use vt_fv::VoxelModel;
use vt_io::output::{Output, OutputKind};

use crate::{
    base64, deflate, encode_png_rgb, html_escape, pack_bits, Error, Folder, Result, Sink, Written,
};

const PAGE: &str = include_str!("fv.html");
const VIEWER: &str = include_str!("fv.js");

/// What the page shows: the photos with their cameras, the model, and the views it offers.
pub struct FvModel<'a> {
    /// The photos' cameras (ideal pinholes, as the model was built from).
    pub cams: &'a [Camera],
    /// The photos, all one size.
    pub images: &'a [RgbImage],
    /// The model.
    pub model: &'a VoxelModel,
    /// Preset views (keys 1-9 on the page; the first is shown first), at least one.
    pub views: &'a [Camera],
    /// The colour around the object (`None`: black).
    pub background: Option<[u8; 3]>,
    /// The silhouettes the model was carved from (`vt fv render` trims its views to them).
    pub masks: &'a [Mask],
    /// The trim of each view to the silhouettes (`None`: splats as they fall).
    pub clip: Option<&'a ClipParams>,
    /// With `clip` and the model's depth maps: the trim to the free space they prove.
    pub depth_clip: Option<&'a DepthClipParams>,
    /// The texturing settings the page renders with.
    pub texture: &'a TextureParams,
    /// The page's title.
    pub title: &'a str,
}

/// What an export wrote.
#[derive(Debug, Clone, Copy)]
pub struct FvSummary {
    /// Files written.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
    /// Surface voxels.
    pub voxels: usize,
}

/// Writes the page into the new folder `out` (refused if it exists; nothing is left behind on
/// failure). `inputs` are the folders and files read, which `out` may not replace.
pub fn fv_export(m: &FvModel<'_>, out: &Path, inputs: &[&Path]) -> Result<FvSummary> {
    check(m)?;
    let output = Output::dir(out, OutputKind::WebExport, inputs)?;
    let root = output.path().to_path_buf();
    std::fs::create_dir(root.join("data")).map_err(|e| vt_io::Error::io(root.join("data"), e))?;
    let summary = write(m, &mut Folder(root))?;
    output.commit()?;
    Ok(summary)
}

/// The page in memory, each file under its path (what `vt fv view` serves).
pub fn fv_page(m: &FvModel<'_>) -> Result<(BTreeMap<String, Vec<u8>>, FvSummary)> {
    check(m)?;
    let mut files = BTreeMap::new();
    let summary = write(m, &mut files)?;
    Ok((files, summary))
}

fn check(m: &FvModel<'_>) -> Result<()> {
    let bad = |name, value: String, why: &str| {
        Err(Error::InvalidParameter {
            name,
            value,
            why: why.into(),
        })
    };
    if m.cams.is_empty() || m.cams.len() != m.images.len() {
        let value = format!("{} cameras, {} photos", m.cams.len(), m.images.len());
        return bad("photos", value, "need one photo per camera, at least one");
    }
    let size = m.images[0].dimensions();
    if m.images.iter().any(|i| i.dimensions() != size) {
        return bad("photos", format!("{size:?}"), "must all be one size");
    }
    if m.views.is_empty() {
        return bad("views", "0".into(), "need at least one");
    }
    if m.model.surface.is_empty() {
        return bad("model", "0 voxels".into(), "has no surface");
    }
    if m.masks.len() != m.cams.len() || m.masks.iter().any(|k| (k.width(), k.height()) != size) {
        let value = format!("{} silhouettes", m.masks.len());
        return bad(
            "silhouettes",
            value,
            "need one per photo, of the photos' size",
        );
    }
    Ok(())
}

fn camera_json(c: &Camera) -> serde_json::Value {
    let row = |m: &nalgebra::Matrix3<f64>| -> Vec<f64> {
        (0..3)
            .flat_map(|r| (0..3).map(move |k| m[(r, k)]))
            .collect()
    };
    serde_json::json!({
        "name": c.name,
        "k": row(&c.k),
        "r": row(&c.r),
        "t": [c.t.x, c.t.y, c.t.z],
    })
}

fn write(m: &FvModel<'_>, sink: &mut dyn Sink) -> Result<FvSummary> {
    let mut written = Written {
        sink,
        bytes: 0,
        files: 0,
        object_bytes: 0,
    };
    let (w, h) = m.images[0].dimensions();
    let grid = &m.model.grid;
    let vs = grid.voxel_size();
    let size = (vs.x * vs.y * vs.z).cbrt();
    let bounds = grid.bounds();
    let t = m.texture;
    let meta = serde_json::json!({
        "title": m.title,
        "width": w,
        "height": h,
        "background": m.background,
        "cams": m.cams.iter().map(camera_json).collect::<Vec<_>>(),
        "views": m.views.iter().map(camera_json).collect::<Vec<_>>(),
        "centre": <[f64; 3]>::from(model_centre(m.model)),
        "bounds": { "min": <[f64; 3]>::from(bounds.min), "max": <[f64; 3]>::from(bounds.max) },
        "voxel": size,
        "splat_scale": DEFAULT_SPLAT_SCALE,
        "texture": {
            "references": t.references,
            "tol": t.depth_tolerance * size,
            "eps": t.eps_deg.to_radians(),
            "reach": t.reach_deg.to_radians(),
            "agree_sd": t.agree_sd,
            "soften_sigma": t.soften_sigma,
            "consensus": t.consensus,
            "depth_smooth": t.depth_smooth,
            "sweep": t.sweep,
            "sweep_step": t.sweep_step * size,
            "sweep_window": t.sweep_window,
            "full_fade": FULL_FADE,
            "fill_radius": t.fill_radius,
            // Steps of `sweep_step` each way texture_view's snapping searches (0 = off);
            // the page snaps only when the depth maps are written (`maps`).
            "snap_steps": t.snap_steps(),
            "backdrop": vt_fv::silhouette::colour_outside(m.images, m.masks).unwrap_or([0; 3]),
        },
    });
    let mut meta = meta;
    // The trims of `vt fv render`: the silhouettes as its clip tests them, and for the trim to
    // free space the model's depth maps and occupied voxels.
    let clip = m.clip.map(|c| c.for_silhouettes(m.cams, m.masks, &bounds));
    if let Some(c) = &clip {
        let mut bits = Vec::new();
        for k in tested_silhouettes(m.cams, m.masks, c) {
            let (mw, mh) = (k.width(), k.height());
            let px: Vec<u8> = (0..mh)
                .flat_map(|y| (0..mw).map(move |x| (x, y)))
                .map(|(x, y)| k.get(x, y) as u8)
                .collect();
            pack_bits(&px, &mut bits);
        }
        written.script(
            "silhouettes.js",
            &format!(
                "vtFvPayload('silhouettes',0,'{}');",
                base64(&deflate(&bits))
            ),
        )?;
        meta["clip"] = serde_json::json!({
            "before": c.before, "behind": c.behind, "step": c.step, "size": size,
        });
    }
    let maps = &m.model.depths;
    let same_maps = maps.first().map(|f| (f.w, f.h, f.step));
    // The depth maps serve the trim to free space (with the silhouettes' clip) and the
    // texturing's snapping; the page reads them as one texture array, so all of one size.
    let depth_clip = m.depth_clip.filter(|_| clip.is_some());
    if let (true, Some((mw, mh, step))) = (depth_clip.is_some() || t.snap > 0.0, same_maps) {
        if maps.len() == m.cams.len() && maps.iter().all(|f| (f.w, f.h, f.step) == (mw, mh, step)) {
            let mut depth = Vec::with_capacity(maps.len() * mw * mh * 4);
            for f in maps {
                for &d in &f.depth {
                    // Non-finite (no confirmed depth) as -1.
                    let d = if d.is_finite() { d } else { -1.0 };
                    depth.extend_from_slice(&d.to_le_bytes());
                }
            }
            let [nx, ny, nz] = grid.dims();
            let mut occ = Vec::with_capacity(nx * ny * nz);
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        occ.push(grid.get(x as i64, y as i64, z as i64) as u8);
                    }
                }
            }
            let mut occ_bits = Vec::new();
            pack_bits(&occ, &mut occ_bits);
            written.script(
                "depths.js",
                &format!(
                    "vtFvPayload('depths',0,{{maps:'{}',occupied:'{}'}});",
                    base64(&deflate(&depth)),
                    base64(&deflate(&occ_bits))
                ),
            )?;
            meta["maps"] = serde_json::json!([mw, mh, step]);
            meta["dims"] = serde_json::json!([nx, ny, nz]);
            if let Some(dc) = depth_clip {
                meta["depth_clip"] = serde_json::json!({
                    "margin": dc.margin, "protect": dc.protect, "through": dc.through,
                    "voxel": vs.min(),
                });
            }
        }
    }
    let meta = meta.to_string().replace('<', "\\u003c");
    written.script("fv.js", &format!("window.vtFvScene = {meta};"))?;
    written.script("viewer.js", &format!("{}\n{VIEWER}", crate::UTIL))?;
    let mut xyz = Vec::with_capacity(m.model.surface.len() * 12);
    let mut rgb = Vec::with_capacity(m.model.surface.len() * 3);
    for v in &m.model.surface {
        let c = m.model.centre(v);
        for x in [c.x, c.y, c.z] {
            xyz.extend_from_slice(&(x as f32).to_le_bytes());
        }
        rgb.extend_from_slice(&v.colour);
    }
    let voxels = format!(
        "vtFvPayload('voxels',0,{{n:{},xyz:'{}',rgb:'{}'}});",
        m.model.surface.len(),
        base64(&xyz),
        base64(&rgb)
    );
    written.script("voxels.js", &voxels)?;
    for (i, img) in m.images.iter().enumerate() {
        let png = encode_png_rgb(img, &format!("photo {i}"))?;
        written.script(
            &format!("photo_{i:03}.js"),
            &format!("vtFvPayload('photo',{i},'{}');", base64(&png)),
        )?;
    }
    let html = PAGE.replace("__TITLE__", &html_escape(m.title));
    written.file("index.html", html.into_bytes())?;
    Ok(FvSummary {
        files: written.files,
        bytes: written.bytes,
        voxels: m.model.surface.len(),
    })
}
