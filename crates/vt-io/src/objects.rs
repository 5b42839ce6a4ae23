//! The moving-object store: per frame of a view, the object's mask and its pixels, in a compact
//! binary file the renderer loads in one read.
//!
//! Layout (little endian), version 1:
//! ```text
//! magic "VTOBJ1\0\0" | u32 width | u32 height
//! frame records, one after the other:
//!     u32 x0 y0 x1 y1                  (bounding box, exclusive; all 0 for an empty mask)
//!     mask bits of the box             (row-major, LSB first, (x1-x0)*(y1-y0) bits, byte-padded)
//!     RGB of the set pixels            (in the same row-major order)
//! u64 offsets[n_frames + 1]            (byte offset of each record, from the file start; the
//!                                       last one is where the table starts)
//! u64 n_frames | magic "VTOBJEND"
//! ```
//! The table sits at the end so frames can be written as they are decoded, count unknown.
//! Only the box is stored, so a frame costs what moves in it, not the frame size.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use image::RgbImage;
use vt_core::Mask;

use crate::{Error, Result};

const MAGIC: &[u8; 8] = b"VTOBJ1\0\0";
const END: &[u8; 8] = b"VTOBJEND";
const HEADER: usize = 16;

/// The 64 mask bits from bit `at` on (bits past the end read as 0).
fn bits_at(words: &[u64], at: usize) -> u64 {
    let (w, o) = (at / 64, at % 64);
    let lo = words.get(w).copied().unwrap_or(0) >> o;
    if o == 0 {
        lo
    } else {
        lo | (words.get(w + 1).copied().unwrap_or(0) << (64 - o))
    }
}

/// Writes a store frame by frame.
pub struct ObjectWriter {
    path: PathBuf,
    out: BufWriter<std::fs::File>,
    width: u32,
    height: u32,
    offsets: Vec<u64>,
    pos: u64,
    /// The record being built (reused).
    rec: Vec<u8>,
    /// Its box's mask bits as words (reused).
    box_words: Vec<u64>,
}

impl ObjectWriter {
    /// Creates the file.
    pub fn create(path: &Path, width: u32, height: u32) -> Result<Self> {
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        let mut out = BufWriter::new(file);
        let mut head = Vec::with_capacity(HEADER);
        head.extend_from_slice(MAGIC);
        head.extend_from_slice(&width.to_le_bytes());
        head.extend_from_slice(&height.to_le_bytes());
        out.write_all(&head).map_err(|e| Error::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            out,
            width,
            height,
            offsets: Vec::new(),
            pos: HEADER as u64,
            rec: Vec::new(),
            box_words: Vec::new(),
        })
    }

    /// Appends the next frame: the pixels of `raw` under `mask`.
    pub fn push(&mut self, mask: &Mask, raw: &RgbImage) -> Result<()> {
        if (mask.width(), mask.height()) != (self.width, self.height)
            || raw.dimensions() != (self.width, self.height)
        {
            return Err(Error::Scene {
                path: self.path.clone(),
                message: "object frame of the wrong size".into(),
            });
        }
        let (x0, y0, x1, y1) = mask.bounding_box().unwrap_or((0, 0, 0, 0));
        let n_bits = ((x1 - x0) * (y1 - y0)) as usize;
        let nb = n_bits.div_ceil(8);
        // One record buffer and one bit buffer, reused from frame to frame: the header, the
        // box's bits (filled in below), then its set pixels' RGB appended as found.
        let (rec, box_words) = (&mut self.rec, &mut self.box_words);
        rec.clear();
        for v in [x0, y0, x1, y1] {
            rec.extend_from_slice(&v.to_le_bytes());
        }
        rec.resize(16 + nb, 0);
        box_words.clear();
        box_words.resize(n_bits.div_ceil(64), 0);
        // 64 mask bits at a time: bits copied as words, pixels as runs.
        let (words, px) = (mask.words(), raw.as_raw());
        let (w, bw) = (self.width as usize, (x1 - x0) as usize);
        let mut i = 0;
        for y in y0 as usize..y1 as usize {
            let row = y * w + x0 as usize;
            for c in (0..bw).step_by(64) {
                let n = (bw - c).min(64);
                let mut bits = bits_at(words, row + c);
                if n < 64 {
                    bits &= (1u64 << n) - 1;
                }
                let (at, off) = ((i + c) / 64, (i + c) % 64);
                box_words[at] |= bits << off;
                if off > 0 && n > 64 - off {
                    box_words[at + 1] |= bits >> (64 - off);
                }
                let mut k = 0;
                while bits != 0 {
                    let skip = bits.trailing_zeros() as usize;
                    bits >>= skip;
                    let len = bits.trailing_ones() as usize;
                    bits = if len == 64 { 0 } else { bits >> len };
                    let start = row + c + k + skip;
                    rec.extend_from_slice(&px[3 * start..3 * (start + len)]);
                    k += skip + len;
                }
            }
            i += bw;
        }
        for (dst, src) in rec[16..16 + nb]
            .iter_mut()
            .zip(box_words.iter().flat_map(|w| w.to_le_bytes()))
        {
            *dst = src;
        }
        let rec = &self.rec;
        self.offsets.push(self.pos);
        self.pos += rec.len() as u64;
        self.out
            .write_all(rec)
            .map_err(|e| Error::io(&self.path, e))
    }

    /// Frames pushed so far.
    pub fn len(&self) -> usize {
        self.offsets.len()
    }

    /// True before the first push.
    pub fn is_empty(&self) -> bool {
        self.offsets.is_empty()
    }

    /// Writes the offset table and trailer and closes the file.
    pub fn finish(mut self) -> Result<()> {
        let n = self.offsets.len() as u64;
        self.offsets.push(self.pos);
        let mut tail: Vec<u8> = self.offsets.iter().flat_map(|o| o.to_le_bytes()).collect();
        tail.extend_from_slice(&n.to_le_bytes());
        tail.extend_from_slice(END);
        let io = |e| Error::io(&self.path, e);
        self.out.write_all(&tail).map_err(io)?;
        self.out.flush().map_err(io)?;
        Ok(())
    }
}

/// A loaded store.
pub struct ObjectStore {
    width: u32,
    height: u32,
    data: Vec<u8>,
    offsets: Vec<u64>,
}

/// One frame's object: box, mask bits of the box, and the RGB of set pixels.
pub struct ObjectFrame<'a> {
    /// Bounding box `(x0, y0, x1, y1)`, exclusive.
    pub bbox: (u32, u32, u32, u32),
    /// Mask bits of the box, row-major, LSB first.
    pub bits: &'a [u8],
    /// RGB triples of the set pixels in row-major order.
    pub rgb: &'a [u8],
}

impl ObjectFrame<'_> {
    /// Calls `f(x, y, rgb)` for every object pixel, in row-major order.
    pub fn for_each_pixel(&self, mut f: impl FnMut(u32, u32, [u8; 3])) {
        let (x0, y0, x1, y1) = self.bbox;
        let (mut i, mut k) = (0usize, 0usize);
        for y in y0..y1 {
            for x in x0..x1 {
                if self.bits[i / 8] >> (i % 8) & 1 == 1 {
                    f(x, y, [self.rgb[k], self.rgb[k + 1], self.rgb[k + 2]]);
                    k += 3;
                }
                i += 1;
            }
        }
    }
}

impl ObjectStore {
    /// Loads and validates a store.
    pub fn load(path: &Path) -> Result<Self> {
        let data =
            crate::limits::read_bytes(path, crate::limits::MAX_OBJECT_STORE_BYTES, "object store")?;
        Self::from_bytes(data, path)
    }

    /// Validates a store's bytes (every offset, box and pixel count checked, so no later access
    /// can fail); `path` names it in errors.
    pub fn from_bytes(data: Vec<u8>, path: &Path) -> Result<Self> {
        let bad = |m: String| Error::Scene {
            path: path.to_path_buf(),
            message: m,
        };
        if data.len() < HEADER || &data[..8] != MAGIC {
            return Err(bad("not a vt object store (bad magic)".into()));
        }
        if data.len() < HEADER + 24 || &data[data.len() - 8..] != END {
            return Err(bad(
                "corrupted or truncated object store (no end marker)".into()
            ));
        }
        let u32_at = |o: usize| u32::from_le_bytes(data[o..o + 4].try_into().expect("4 bytes"));
        let u64_at = |o: usize| u64::from_le_bytes(data[o..o + 8].try_into().expect("8 bytes"));
        let (width, height) = (u32_at(8), u32_at(12));
        let side = crate::limits::MAX_IMAGE_SIDE;
        if width == 0 || height == 0 || width > side || height > side {
            return Err(bad(format!(
                "corrupted: frame size {width}x{height} (1 to {side} per side)"
            )));
        }
        let n = u64_at(data.len() - 16) as usize;
        let table_len = n
            .checked_add(1)
            .and_then(|k| k.checked_mul(8))
            .filter(|&l| l.checked_add(16 + HEADER).is_some_and(|t| t <= data.len()));
        let Some(table_len) = table_len else {
            return Err(bad(format!(
                "corrupted: {n} frames do not fit in {} bytes",
                data.len()
            )));
        };
        let table_start = data.len() - 16 - table_len;
        let offsets: Vec<u64> = (0..=n).map(|i| u64_at(table_start + 8 * i)).collect();
        if offsets.windows(2).any(|w| w[1] < w[0].saturating_add(16))
            || offsets.first() != Some(&(HEADER as u64))
            || offsets[n] != table_start as u64
        {
            return Err(bad("corrupted: offset table does not match the file".into()));
        }
        let store = Self {
            width,
            height,
            data,
            offsets,
        };
        for i in 0..n {
            let (x0, y0, x1, y1) = store.raw_bbox(i);
            let ok = x0 <= x1 && y0 <= y1 && x1 <= width && y1 <= height;
            // Sizes are at most MAX_IMAGE_SIDE^2 = 2^28 bits: no overflow.
            let n_bits = ok.then(|| (x1 - x0) as usize * (y1 - y0) as usize);
            let need = n_bits.map(|b| 16 + b.div_ceil(8));
            let len = (store.offsets[i + 1] - store.offsets[i]) as usize;
            if need.is_none_or(|need| len < need || !(len - need).is_multiple_of(3)) {
                return Err(bad(format!("corrupted: frame {i} record is inconsistent")));
            }
            // Every set bit needs its RGB triple, no more, no less.
            let (n_bits, need) = (n_bits.unwrap_or(0), need.unwrap_or(16));
            let o = store.offsets[i] as usize + 16;
            let bits = &store.data[o..o + n_bits.div_ceil(8)];
            let full = n_bits / 8;
            let mut set: usize = bits[..full].iter().map(|b| b.count_ones() as usize).sum();
            if n_bits % 8 != 0 {
                set += (bits[full] & ((1u8 << (n_bits % 8)) - 1)).count_ones() as usize;
            }
            if set * 3 != len - need {
                return Err(bad(format!(
                    "corrupted: frame {i} has {set} object pixels but {} colours",
                    (len - need) / 3
                )));
            }
        }
        Ok(store)
    }

    fn raw_bbox(&self, i: usize) -> (u32, u32, u32, u32) {
        let o = self.offsets[i] as usize;
        let g = |k: usize| {
            u32::from_le_bytes(
                self.data[o + 4 * k..o + 4 * k + 4]
                    .try_into()
                    .expect("4 bytes"),
            )
        };
        (g(0), g(1), g(2), g(3))
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when the store has no frames.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Frame size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Frame `i`'s object. Panics when `i >= len()`.
    pub fn frame(&self, i: usize) -> ObjectFrame<'_> {
        let bbox = self.raw_bbox(i);
        let (o, end) = (self.offsets[i] as usize + 16, self.offsets[i + 1] as usize);
        let nb = (((bbox.2 - bbox.0) * (bbox.3 - bbox.1)) as usize).div_ceil(8);
        ObjectFrame {
            bbox,
            bits: &self.data[o..o + nb],
            rgb: &self.data[o + nb..end],
        }
    }

    /// Frame `i`'s mask as a full-size [`Mask`].
    pub fn mask(&self, i: usize) -> Mask {
        let mut m = Mask::new(self.width, self.height);
        self.frame(i).for_each_pixel(|x, y, _| m.set(x, y, true));
        m
    }
}

impl ObjectFrame<'_> {
    /// Decodes into a renderer patch (box-sized RGB + mask), reusing its storage.
    pub fn decode_into(&self, patch: &mut vt_core::render::ObjectPatch) {
        let (x0, y0, x1, y1) = self.bbox;
        patch.reset(x0, y0, x1 - x0, y1 - y0);
        let (bw, mut k) = ((x1 - x0) as usize, 0usize);
        for i in 0..bw * (y1 - y0) as usize {
            if self.bits[i / 8] >> (i % 8) & 1 == 1 {
                patch.mask[i] = 1;
                patch.rgb[i * 3..i * 3 + 3].copy_from_slice(&self.rgb[k..k + 3]);
                k += 3;
            }
        }
    }
}

/// The object stores of all views of a scene, as the renderer's [`vt_core::render::ObjectFrames`].
pub struct SceneObjects {
    /// One store per view.
    pub stores: Vec<ObjectStore>,
}

impl vt_core::render::ObjectFrames for SceneObjects {
    fn decode_into(
        &self,
        view: usize,
        frame: usize,
        patch: &mut vt_core::render::ObjectPatch,
    ) -> vt_core::Result<()> {
        let store = self
            .stores
            .get(view)
            .ok_or_else(|| vt_core::Error::InvalidParameter {
                name: "view",
                value: view.to_string(),
                why: format!("the scene has {} views", self.stores.len()),
            })?;
        if frame >= store.len() {
            return Err(vt_core::Error::InvalidParameter {
                name: "frame",
                value: frame.to_string(),
                why: format!("view {view} has {} frames", store.len()),
            });
        }
        store.frame(frame).decode_into(patch);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The record layout written pixel by pixel, as the format describes it.
    fn reference_record(mask: &Mask, raw: &RgbImage) -> Vec<u8> {
        let (x0, y0, x1, y1) = mask.bounding_box().unwrap_or((0, 0, 0, 0));
        let mut rec: Vec<u8> = [x0, y0, x1, y1]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let n = ((x1 - x0) * (y1 - y0)) as usize;
        let mut bits = vec![0u8; n.div_ceil(8)];
        let mut rgb = Vec::new();
        let mut i = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                if mask.get(x, y) {
                    bits[i / 8] |= 1 << (i % 8);
                    rgb.extend_from_slice(&raw.get_pixel(x, y).0);
                }
                i += 1;
            }
        }
        rec.extend(bits);
        rec.extend(rgb);
        rec
    }

    #[test]
    fn records_match_the_per_pixel_layout() {
        let dir = tempfile::tempdir().unwrap();
        let mut rng = vt_core::rng::Rng::new(17);
        for (w, h) in [(13u32, 9u32), (64, 3), (70, 9), (131, 5), (200, 2)] {
            let raw = RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, (x * y) as u8]));
            let path = dir.path().join(format!("o{w}x{h}.bin"));
            let mut writer = ObjectWriter::create(&path, w, h).unwrap();
            let mut want = Vec::new();
            // Sparse, dense, runs across words, a full box, an empty one.
            for density in [3u64, 50, 97, 100, 0] {
                let seed = rng.next_u64();
                let m = Mask::from_fn(w, h, |x, y| {
                    vt_core::rng::mix(seed ^ ((x as u64) << 20) ^ y as u64) % 100 < density
                });
                writer.push(&m, &raw).unwrap();
                want.push(reference_record(&m, &raw));
            }
            writer.finish().unwrap();
            let bytes = std::fs::read(&path).unwrap();
            let mut at = HEADER;
            for rec in &want {
                assert_eq!(&bytes[at..at + rec.len()], &rec[..], "{w}x{h}");
                at += rec.len();
            }
        }
    }

    #[test]
    fn round_trip_and_corruption() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.bin");
        let raw = RgbImage::from_fn(13, 9, |x, y| image::Rgb([x as u8, y as u8, 7]));
        let masks = [
            Mask::from_fn(13, 9, |x, y| (x + y) % 3 == 0 && x > 2),
            Mask::new(13, 9),
            Mask::from_fn(13, 9, |_, _| true),
        ];
        let mut w = ObjectWriter::create(&path, 13, 9).unwrap();
        for m in &masks {
            w.push(m, &raw).unwrap();
        }
        w.finish().unwrap();
        let s = ObjectStore::load(&path).unwrap();
        assert_eq!(s.len(), 3);
        for (i, m) in masks.iter().enumerate() {
            assert_eq!(&s.mask(i), m);
            s.frame(i)
                .for_each_pixel(|x, y, c| assert_eq!(c, raw.get_pixel(x, y).0));
        }
        let bytes = std::fs::read(&path).unwrap();
        for (cut, flip) in [(5, None), (0, Some(20)), (0, Some(bytes.len() - 20))] {
            let mut b = bytes[..bytes.len() - cut].to_vec();
            if let Some(i) = flip {
                b[i] ^= 0x5a;
            }
            std::fs::write(&path, &b).unwrap();
            let err = ObjectStore::load(&path)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(
                err.contains("corrupted"),
                "cut {cut} flip {flip:?}: {err:?}"
            );
        }
    }
}

/// An analysis observer that writes each view's moving-object store (`objects_NNN.bin`) into a
/// scene directory as its masks arrive, one view at a time: what `vt analyze` keeps of every
/// frame. Call [`StoreWriter::finish`] after the analysis to close the last store.
pub struct StoreWriter {
    dir: PathBuf,
    writer: Option<(usize, ObjectWriter)>,
}

impl StoreWriter {
    /// Writes stores into `dir` (usually a scene's temporary directory).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            writer: None,
        }
    }

    /// Closes the last store.
    pub fn finish(&mut self) -> vt_core::Result<()> {
        if let Some((p, w)) = self.writer.take() {
            w.finish()
                .map_err(|e| vt_core::Error::external(format!("view {p}"), e))?;
        }
        Ok(())
    }
}

impl vt_core::analysis::Observer for StoreWriter {
    fn object_frame(
        &mut self,
        view: usize,
        _frame: usize,
        mask: &Mask,
        raw: &RgbImage,
    ) -> vt_core::Result<()> {
        let to_core = |e: Error| vt_core::Error::external(format!("view {view}"), e);
        if self.writer.as_ref().is_none_or(|(p, _)| *p != view) {
            self.finish()?;
            let path = self.dir.join(crate::scene::objects_name(view));
            self.writer = Some((
                view,
                ObjectWriter::create(&path, raw.width(), raw.height()).map_err(to_core)?,
            ));
        }
        let (_, w) = self.writer.as_mut().expect("set above");
        w.push(mask, raw).map_err(to_core)
    }
}
