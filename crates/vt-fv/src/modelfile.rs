//! The model file `vt fv hull` writes and `render`, `orbit` and `eval` read with `--model`: the
//! carved voxel model (occupancy, surface voxels with colours and visibility counts, the grid and
//! its bounds) and fingerprints of the views it was built from, so that a model is only used
//! with the data it came from. Encoding and decoding only; [`crate::dataset`] reads and writes
//! the file.
//!
//! Layout (little-endian), version 2 (version 1, read too, ends after `removed`):
//!
//! ```text
//! "VTFVMODL"  u32 version  u32 header length  header (compact JSON, ModelHeader)
//! body: 6 x f64 bounds (min, max)  3 x u32 dims
//!       occupancy as run lengths (varints, alternating empty / occupied, empty first)
//!       varint surface count, then per surface voxel: varint index delta (the first is the
//!       index), 3 bytes colour, varint seen_by
//!       varint passes  varint removed
//!       varint depth map count, then per map: varint w, h, step, and its cells as runs
//!       (varints, alternating none / some, none first), each run of some followed by its
//!       depths as f32 bits
//! u64 checksum of everything before it
//! ```
//!
//! Floats travel as their bits (in the body, not the JSON), so a model read back renders the
//! same bytes as the one built in process.

use serde::{Deserialize, Serialize};

use crate::hull::{grid_bytes, Aabb, HullParams, VoxelGrid};
use crate::photo::{SurfaceVoxel, VoxelModel};
use crate::{Camera, Error, Mask, Result};

/// The file's first 8 bytes.
pub const MAGIC: &[u8; 8] = b"VTFVMODL";
/// The version this build writes (it reads 1 as well: a model without depth maps).
pub const VERSION: u32 = 2;
/// Most depth-map cells a model file may hold, all maps together (256 MB of depths: 8 photos of
/// 8K x 4K at a cell every 2 pixels take 16 million).
const MAX_DEPTH_CELLS: u64 = 1 << 26;
/// Largest JSON header read (bytes).
pub const MAX_HEADER_BYTES: usize = 1 << 24;

/// One view a model was built from: its place in the data folder and fingerprints of its
/// camera, photo and carving silhouette as loaded (after scaling and undistortion).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ViewPrint {
    /// Index in the data folder (camera order).
    pub index: usize,
    /// Photo name.
    pub name: String,
    /// Fingerprint of the camera (name, K, R, t as bits).
    pub camera: u64,
    /// Fingerprint of the photo (size and pixels).
    pub photo: u64,
    /// Fingerprint of the carving silhouette (size and bits).
    pub silhouette: u64,
}

/// What a model file says about itself besides the voxels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelHeader {
    /// The camera file the data folder's cameras came from, as given when the model was built
    /// (for messages only).
    pub cameras: String,
    /// Views in the data folder.
    pub all_views: usize,
    /// The views the model was built from, in camera order.
    pub views: Vec<ViewPrint>,
    /// The view left out of the build (`vt fv hull --leave-out`), if any.
    pub withheld: Option<usize>,
    /// Photo size.
    pub image_size: [u32; 2],
    /// Where the silhouettes came from, in words.
    pub silhouettes: String,
    /// Photo-consistency threshold of the build.
    pub photo_threshold: f64,
    /// Whether the paper's carving rule was used.
    pub paper_carving: bool,
    /// Whether the hull was carved by stereo first (files from before it: false).
    #[serde(default)]
    pub stereo: bool,
    /// Seconds the build took (visual hull and photo hull).
    pub build_secs: f64,
}

/// Fingerprint of a camera: its name and matrices, bit for bit.
pub fn camera_print(c: &Camera) -> u64 {
    let mut parts: Vec<u64> = c.name.bytes().map(u64::from).collect();
    parts.push(c.name.len() as u64);
    parts.extend(
        c.k.iter()
            .chain(c.r.iter())
            .chain(c.t.iter())
            .map(|v| v.to_bits()),
    );
    vt_core::rng::hash(&parts)
}

fn fold_bytes(seed: u64, bytes: &[u8]) -> u64 {
    let mut h = seed;
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        h = vt_core::rng::mix(h ^ u64::from_le_bytes(c.try_into().expect("8 bytes")));
    }
    let mut last = [0u8; 8];
    last[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
    vt_core::rng::mix(h ^ u64::from_le_bytes(last) ^ (bytes.len() as u64).rotate_left(32))
}

/// Fingerprint of a photo: size and pixels.
pub fn photo_print(img: &image::RgbImage) -> u64 {
    let seed = vt_core::rng::hash(&[img.width() as u64, img.height() as u64]);
    fold_bytes(seed, img.as_raw())
}

/// Fingerprint of a silhouette: size and bits.
pub fn mask_print(m: &Mask) -> u64 {
    let seed = vt_core::rng::hash(&[m.width() as u64, m.height() as u64, 1]);
    m.words()
        .iter()
        .fold(seed, |h, &w| vt_core::rng::mix(h ^ w))
}

/// The fingerprints of views `indices` of a loaded data folder.
pub fn view_prints(
    indices: &[usize],
    cams: &[Camera],
    images: &[image::RgbImage],
    masks: &[Mask],
) -> Vec<ViewPrint> {
    use rayon::prelude::*;
    indices
        .par_iter()
        .map(|&i| ViewPrint {
            index: i,
            name: cams[i].name.clone(),
            camera: camera_print(&cams[i]),
            photo: photo_print(&images[i]),
            silhouette: mask_print(&masks[i]),
        })
        .collect()
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Encodes a model and its header.
pub fn encode(model: &VoxelModel, header: &ModelHeader) -> Vec<u8> {
    let json = serde_json::to_vec(header).expect("the header serialises");
    let mut out = Vec::with_capacity(64 + json.len() + model.surface.len() * 6);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    let g = &model.grid;
    let b = g.bounds();
    for v in b.min.iter().chain(b.max.iter()) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for d in g.dims() {
        out.extend_from_slice(&(d as u32).to_le_bytes());
    }
    // Runs of equal bits, empty first.
    let n = g.dims().iter().product::<usize>();
    let (mut state, mut run) = (false, 0u64);
    for i in 0..n {
        if g.get_index(i) != state {
            put_varint(&mut out, run);
            state = !state;
            run = 0;
        }
        run += 1;
    }
    put_varint(&mut out, run);
    put_varint(&mut out, model.surface.len() as u64);
    let mut prev = 0usize;
    for (k, v) in model.surface.iter().enumerate() {
        put_varint(
            &mut out,
            (if k == 0 { v.index } else { v.index - prev }) as u64,
        );
        prev = v.index;
        out.extend_from_slice(&v.colour);
        put_varint(&mut out, v.seen_by as u64);
    }
    put_varint(&mut out, model.passes as u64);
    put_varint(&mut out, model.removed as u64);
    put_varint(&mut out, model.depths.len() as u64);
    for m in &model.depths {
        for v in [m.w, m.h, m.step] {
            put_varint(&mut out, v as u64);
        }
        let mut k = 0;
        while k < m.depth.len() {
            let none = m.depth[k..].iter().take_while(|d| !d.is_finite()).count();
            k += none;
            let some = m.depth[k..].iter().take_while(|d| d.is_finite()).count();
            put_varint(&mut out, none as u64);
            put_varint(&mut out, some as u64);
            for d in &m.depth[k..k + some] {
                out.extend_from_slice(&d.to_le_bytes());
            }
            k += some;
        }
    }
    let sum = fold_bytes(0, &out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

fn bad(what: impl Into<String>) -> Error {
    Error::ModelFile { what: what.into() }
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        let end = end.ok_or_else(|| bad(format!("cut short at byte {}", self.at)))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }

    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().expect("8")))
    }

    fn varint(&mut self) -> Result<u64> {
        let (mut v, mut shift) = (0u64, 0u32);
        loop {
            let at = self.at;
            let byte = self.take(1)?[0];
            if shift > 63 || (shift == 63 && byte > 1) {
                return Err(bad(format!("number too large at byte {at}")));
            }
            v |= ((byte & 0x7f) as u64) << shift;
            if byte & 0x80 == 0 {
                return Ok(v);
            }
            shift += 7;
        }
    }
}

/// Decodes a model file's bytes: magic, version, checksum, then every count and index checked
/// against the grid (no panic, no allocation beyond the grid limit on bad input).
pub fn decode(bytes: &[u8]) -> Result<(VoxelModel, ModelHeader)> {
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(bad(
            "not a vt fv model file (written by `vt fv hull` as DIR/model.vtfv)",
        ));
    }
    let mut r = Reader {
        b: bytes,
        at: MAGIC.len(),
    };
    let version = r.u32()?;
    if version != VERSION && version != 1 {
        return Err(bad(format!(
            "model file version {version}; this vt reads versions 1 and {VERSION} (build the model again with `vt fv hull`)"
        )));
    }
    if bytes.len() < 8 + 16 {
        return Err(bad("cut short: no checksum"));
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fold_bytes(0, body) != u64::from_le_bytes(sum.try_into().expect("8")) {
        return Err(bad(
            "damaged or cut short (checksum mismatch); build it again with `vt fv hull`",
        ));
    }
    let mut r = Reader { b: body, at: r.at };
    let hlen = r.u32()? as usize;
    if hlen > MAX_HEADER_BYTES {
        return Err(bad(format!(
            "header of {hlen} bytes (at most {MAX_HEADER_BYTES})"
        )));
    }
    let header: ModelHeader =
        serde_json::from_slice(r.take(hlen)?).map_err(|e| bad(format!("header: {e}")))?;
    let mut f = [0.0; 6];
    for v in &mut f {
        *v = r.f64()?;
    }
    let bounds = Aabb::new(
        nalgebra::Vector3::new(f[0], f[1], f[2]),
        nalgebra::Vector3::new(f[3], f[4], f[5]),
    );
    let dims = [r.u32()? as usize, r.u32()? as usize, r.u32()? as usize];
    grid_bytes(dims, HullParams::default().max_bytes)?;
    let mut grid = VoxelGrid::new(dims, bounds, HullParams::default().max_bytes)?;
    let n = dims.iter().product::<usize>();
    let (mut i, mut state) = (0usize, false);
    while i < n {
        let run = r.varint()?;
        let end = (i as u64)
            .checked_add(run)
            .filter(|&e| e <= n as u64)
            .ok_or_else(|| bad("occupancy runs exceed the grid"))? as usize;
        if state {
            (i..end).for_each(|j| grid.set_index(j, true));
        }
        i = end;
        state = !state;
    }
    let count = r.varint()?;
    if count > grid.count() as u64 {
        return Err(bad(format!(
            "{count} surface voxels but {} occupied",
            grid.count()
        )));
    }
    let mut surface = Vec::with_capacity(count as usize);
    let mut prev = 0u64;
    for k in 0..count {
        let d = r.varint()?;
        let index = if k == 0 { d } else { prev.saturating_add(d) };
        if (k > 0 && d == 0) || index >= n as u64 || !grid.get_index(index as usize) {
            return Err(bad(format!(
                "surface voxel {k}: index {index} is not an occupied voxel in ascending order"
            )));
        }
        prev = index;
        let c = r.take(3)?;
        let colour = [c[0], c[1], c[2]];
        let seen_by = u32::try_from(r.varint()?).map_err(|_| bad("camera count too large"))?;
        surface.push(SurfaceVoxel {
            index: index as usize,
            colour,
            seen_by,
        });
    }
    let passes = r.varint()? as usize;
    let removed = r.varint()? as usize;
    let mut depths = Vec::new();
    if version >= 2 {
        let count = r.varint()?;
        if count > header.views.len() as u64 {
            return Err(bad(format!(
                "{count} depth maps for {} views",
                header.views.len()
            )));
        }
        let mut total = 0u64;
        for k in 0..count {
            let (w, h, step) = (r.varint()?, r.varint()?, r.varint()?);
            // A map has a cell every `step` pixels of the photos the model was built from.
            let [iw, ih] = header.image_size.map(|v| v as u64);
            if !(1..=64).contains(&step) || w != iw.div_ceil(step) || h != ih.div_ceil(step) {
                return Err(bad(format!(
                    "depth map {k}: {w}x{h} cells every {step} pixels, for {iw}x{ih} photos"
                )));
            }
            // The maps together hold at most MAX_DEPTH_CELLS cells (a file cannot ask for more
            // memory than that, whatever its header says).
            let cells = w
                .checked_mul(h)
                .filter(|&c| total + c <= MAX_DEPTH_CELLS)
                .ok_or_else(|| {
                    bad(format!(
                        "depth map {k}: {w}x{h} cells, over {MAX_DEPTH_CELLS} in all"
                    ))
                })?;
            total += cells;
            let cells = cells as usize;
            let mut depth = Vec::with_capacity(cells);
            while depth.len() < cells {
                let none = r.varint()?;
                let some = r.varint()?;
                if none.saturating_add(some) > (cells - depth.len()) as u64 || none + some == 0 {
                    return Err(bad(format!("depth map {k}: runs exceed its cells")));
                }
                depth.extend(std::iter::repeat_n(f32::NAN, none as usize));
                for _ in 0..some {
                    let d = f32::from_le_bytes(r.take(4)?.try_into().expect("4"));
                    if !(d.is_finite() && d > 0.0) {
                        return Err(bad(format!("depth map {k}: depth {d}")));
                    }
                    depth.push(d);
                }
            }
            depths.push(crate::stereo::DepthMap {
                w: w as usize,
                h: h as usize,
                step: step as usize,
                depth,
            });
        }
    }
    if r.at != body.len() {
        return Err(bad(format!("{} bytes after the model", body.len() - r.at)));
    }
    Ok((
        VoxelModel {
            grid,
            surface,
            passes,
            removed,
            stereo: None,
            depths,
        },
        header,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stereo::DepthMap;

    /// A one-voxel model with the given depth maps, for `views` views of `size` photos.
    fn model(depths: Vec<DepthMap>, views: usize, size: [u32; 2]) -> (VoxelModel, ModelHeader) {
        let bounds = Aabb::new(nalgebra::Vector3::zeros(), nalgebra::Vector3::repeat(1.0));
        let mut grid = VoxelGrid::new([2, 2, 2], bounds, 1 << 20).unwrap();
        grid.set_index(0, true);
        let print = |index| ViewPrint {
            index,
            name: format!("{index}.png"),
            camera: 1,
            photo: 2,
            silhouette: 3,
        };
        let header = ModelHeader {
            cameras: "c".into(),
            all_views: views,
            views: (0..views).map(print).collect(),
            withheld: None,
            image_size: size,
            silhouettes: "s".into(),
            photo_threshold: 15.0,
            paper_carving: false,
            stereo: true,
            build_secs: 0.0,
        };
        let model = VoxelModel {
            grid,
            surface: vec![SurfaceVoxel {
                index: 0,
                colour: [1, 2, 3],
                seen_by: 1,
            }],
            passes: 1,
            removed: 0,
            stereo: None,
            depths,
        };
        (model, header)
    }

    #[test]
    fn depth_maps_round_trip_and_bad_ones_are_refused() {
        let map = DepthMap {
            w: 3,
            h: 2,
            step: 2,
            depth: vec![f32::NAN, 1.5, 2.25, f32::NAN, f32::NAN, 0.125],
        };
        let (m, h) = model(vec![map.clone()], 1, [5, 4]);
        let (back, _) = decode(&encode(&m, &h)).unwrap();
        let bits = |d: &[f32]| -> Vec<u32> {
            d.iter()
                .map(|v| if v.is_nan() { 0 } else { v.to_bits() })
                .collect()
        };
        assert_eq!(
            (back.depths[0].w, back.depths[0].h, back.depths[0].step),
            (3, 2, 2)
        );
        assert_eq!(bits(&back.depths[0].depth), bits(&map.depth));
        let refused = |m: &VoxelModel, h: &ModelHeader, needle: &str| {
            let e = decode(&encode(m, h)).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        };
        // Not the photos' size at its step.
        let (m, h) = model(vec![map.clone()], 1, [8, 4]);
        refused(&m, &h, "3x2 cells every 2 pixels, for 8x4 photos");
        // More maps than views.
        let (m, h) = model(vec![map.clone(), map.clone()], 1, [5, 4]);
        refused(&m, &h, "2 depth maps for 1 views");
        // A depth that is no depth.
        let mut bad = map.clone();
        bad.depth[1] = -1.0;
        let (m, h) = model(vec![bad], 1, [5, 4]);
        refused(&m, &h, "depth -1");
        // A header whose photos would need more cells than any model holds: refused before
        // anything is allocated.
        let huge = DepthMap {
            w: 1 << 20,
            h: 1 << 20,
            step: 2,
            depth: Vec::new(),
        };
        let (m, h) = model(vec![huge], 1, [1 << 21, 1 << 21]);
        refused(&m, &h, "over 67108864 in all");
    }
}
