//! The moving-object store: per frame of a view, the object's mask and its pixels, in a binary
//! file that the renderer reads frame by frame in any order.
//!
//! Two versions, both read. Version 2 (the default, [`StoreQuality::H264`]) keeps the pixels as
//! H.264, version 1 ([`StoreQuality::Lossless`]) as raw RGB. Version 1 is read whole; version 2
//! keeps its index in memory and reads a record when it decodes it, on a thread of its own that
//! decodes the next frame ahead (see [`ObjectStore`]).
//!
//! Version 1 (little endian):
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
//!
//! Version 2 stores the same masks, deflated, and the whole frame as H.264 (constrained
//! baseline, no B-frames, 4:2:0, one fixed quantiser per store), with an IDR frame every [`GOP`] frames
//! so that every group decodes on its own: a jump or a loop wrap decodes at most one group.
//! The whole frame rather than the box, because inter coding needs pictures of one size; the
//! pixels outside the masks are mostly still background, which costs next to nothing.
//! The pictures are encoded by x264 through ffmpeg when it has libx264 (preset ultrafast, one
//! thread, a process of its own, so encoding runs beside the analysis: on tree.avi upscaled to
//! 720p 8.6 against 15.4 ms a frame, the same size and quality), else by openh264 in this
//! process ([`H264Encoder`]); the format and the decoder are the same.
//! ```text
//! magic "VTOBJ2\0\0" | u32 width | u32 height | u32 gop | u32 qp
//! frame records:
//!     u32 x0 y0 x1 y1                  (the mask's box, as in version 1)
//!     u32 mask_len | mask bits of the box as in version 1, raw deflate, mask_len bytes
//!     the frame's H.264 access unit    (Annex B; picture padded to even sides, 16 at least, by
//!                                       repeating the last column and row)
//! u64 offsets[n_frames + 1] | u64 n_frames | magic "VTOBJEND"   (as in version 1)
//! ```

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use image::RgbImage;
use vt_core::Mask;

use crate::{Error, Result};

mod decode;
mod encode;
mod store;
#[cfg(test)]
mod tests;
mod writer;

use decode::*;
pub use encode::x264_args;
use encode::*;
pub use store::ObjectStore;
use store::*;
pub use writer::{H264Encoder, ObjectWriter, StoreWriter, TargetChoice, MAX_TARGET_QP, PROBE_QP};

const MAGIC: &[u8; 8] = b"VTOBJ1\0\0";
const MAGIC_V2: &[u8; 8] = b"VTOBJ2\0\0";
const END: &[u8; 8] = b"VTOBJEND";
const HEADER: usize = 16;
const HEADER_V2: usize = 24;
/// Version 2's record head: the box and the deflated mask's length.
const RECORD_HEAD_V2: usize = 20;

/// Frames per group of pictures in version 2: the most frames one access decodes.
pub const GOP: u32 = 8;

/// openh264's finest quantiser in its quality mode (it raises lower ones to this), and so
/// version 2's. Per quantiser on real footage (x264, whole frames, `examples/store_rate`; bytes
/// against the video's, mean PSNR against the decoded frames): tree.avi (320x240): 12: 2.02x,
/// 43.7 dB; 16: 1.57x, 40.4; 20: 1.14x, 37.1; tree.avi upscaled to 1080p (H.264, 20.9 MB): 12:
/// 4.58x, 45.6 dB; 16: 3.14x, 43.3; 20: 2.09x, 41.1. The default, [`StoreQuality::Target`],
/// chooses per store.
pub const MIN_QP: u8 = 12;

/// How a store keeps the object pixels (`vt analyze --store-quality`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StoreQuality {
    /// Version 1: the pixels as raw RGB, bit-exact (large: a scene is tens of times its video).
    Lossless,
    /// Version 2: the frames as H.264 at this fixed quantiser ([`MIN_QP`] best, 51 smallest).
    H264 {
        /// The quantiser, [`MIN_QP`] to 51.
        qp: u8,
    },
    /// Version 2 at a quality target: each store at the largest fixed quantiser that keeps its
    /// frames at least `db` PSNR against the analysed frames under the masks (what renders
    /// show), chosen from its first group ([`GOP`] frames) stored at [`PROBE_QP`] in memory.
    /// A source with little detail (a compressed, upscaled video) gets a coarse quantiser and
    /// costs few bits; fine detail gets a fine one.
    Target {
        /// The PSNR to keep, dB ([`MIN_TARGET_DB`] to [`MAX_TARGET_DB`]).
        db: u8,
    },
}

/// The lowest quality target, dB.
pub const MIN_TARGET_DB: u8 = 30;
/// The highest quality target, dB.
pub const MAX_TARGET_DB: u8 = 50;
/// The default quality target, dB ([`StoreQuality::default`]).
pub const DEFAULT_TARGET_DB: u8 = 40;

impl Default for StoreQuality {
    fn default() -> Self {
        Self::Target {
            db: DEFAULT_TARGET_DB,
        }
    }
}

impl std::str::FromStr for StoreQuality {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "lossless" {
            return Ok(Self::Lossless);
        }
        if let Some(db) = s.strip_suffix("db") {
            return match db.parse::<u8>() {
                Ok(db) if (MIN_TARGET_DB..=MAX_TARGET_DB).contains(&db) => Ok(Self::Target { db }),
                _ => Err(format!(
                    "'{s}': expected a PSNR target of {MIN_TARGET_DB}db to {MAX_TARGET_DB}db"
                )),
            };
        }
        match s.parse::<u8>() {
            Ok(qp) if (MIN_QP..=51).contains(&qp) => Ok(Self::H264 { qp }),
            _ => Err(format!(
                "'{s}': expected lossless, a PSNR target such as {DEFAULT_TARGET_DB}db (the \
                 default) or an H.264 quantiser {MIN_QP} to 51 (lower keeps more)"
            )),
        }
    }
}

impl std::fmt::Display for StoreQuality {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Lossless => write!(f, "lossless"),
            Self::H264 { qp } => write!(f, "{qp}"),
            Self::Target { db } => write!(f, "{db}db"),
        }
    }
}

/// Frame sides rounded up to even and at least 16, as the 4:2:0 pictures of version 2 have
/// them (openh264 encodes nothing smaller than a macroblock).
fn padded_size(width: u32, height: u32) -> (usize, usize) {
    (
        width.next_multiple_of(2).max(16) as usize,
        height.next_multiple_of(2).max(16) as usize,
    )
}

/// The mask bits of `bbox` as words, row-major, LSB first (reusing `words`), handing each run of
/// up to 64 bits to `each` with the image index of its first bit (version 1 copies the set
/// pixels' RGB from there).
fn pack_box(
    mask: &Mask,
    bbox: (u32, u32, u32, u32),
    words: &mut Vec<u64>,
    mut each: impl FnMut(usize, u64),
) {
    let (x0, y0, x1, y1) = bbox;
    let (w, bw) = (mask.width() as usize, (x1 - x0) as usize);
    let n_bits = bw * (y1 - y0) as usize;
    words.clear();
    words.resize(n_bits.div_ceil(64), 0);
    let mut i = 0;
    for y in y0 as usize..y1 as usize {
        let row = y * w + x0 as usize;
        for c in (0..bw).step_by(64) {
            let n = (bw - c).min(64);
            let mut bits = bits_at(mask.words(), row + c);
            if n < 64 {
                bits &= (1u64 << n) - 1;
            }
            let (at, off) = ((i + c) / 64, (i + c) % 64);
            words[at] |= bits << off;
            if off > 0 && n > 64 - off {
                words[at + 1] |= bits >> (64 - off);
            }
            each(row + c, bits);
        }
        i += bw;
    }
}

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
        store
            .decode_into(frame, patch)
            .map_err(|e| vt_core::Error::external(format!("view {view}"), e))
    }

    fn group(&self, view: usize) -> usize {
        self.stores.get(view).map_or(1, ObjectStore::group)
    }
}
