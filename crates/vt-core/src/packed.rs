//! Frames held losslessly compressed, in bands of rows, for readers that need a few pixels of
//! many frames: the per-region loop's source window of an HD view ([`crate::regions::Frames`]).
//!
//! A window of a hundred 1080p frames takes 300 MiB even as 4:2:0; the frame cache is 256 MiB.
//! Packed, each band of [`BAND`] rows of a frame (its luma rows and their chroma rows, or its RGB
//! rows) is stored as the difference of each byte to the one on its left in its plane, deflated
//! ([`fdeflate`], built for such filtered image rows): about half the bytes on real video, to
//! the byte the same frames. A reader unpacks the bands it touches into a small per-thread
//! cache, so that the pixels of one band of a few frames cost one unpacking each.

use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};

use image::RgbImage;
use rayon::prelude::*;

use crate::analysis::FrameRef;
use crate::yuv::{Yuv420Image, YuvMatrix, YuvRange};
use crate::{Error, Result};

/// Rows per band (even: a 4:2:0 band holds whole chroma rows).
pub const BAND: u32 = 16;

/// Unpacked bands a thread keeps (about 6 MB at 1080p 4:2:0).
const CACHED_BANDS: usize = 128;

/// How a packed frame's pixels are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    Rgb,
    Yuv420(YuvMatrix, YuvRange),
}

/// Frames of one size, each band deflated.
#[derive(Debug)]
pub struct PackedFrames {
    id: u64,
    width: u32,
    height: u32,
    layout: Option<Layout>,
    /// Every band's deflated bytes, frame after frame, in one buffer: one allocation, which the
    /// allocator maps apart and gives back whole (many small ones would stay in its heap, and
    /// the process's resident memory with them, after the window is dropped).
    data: Vec<u8>,
    /// Per frame, per band, its bytes' range in `data`.
    bands: Vec<std::ops::Range<usize>>,
}

static NEXT_ID: AtomicU64 = AtomicU64::new(0);

/// A thread's unpacked bands: `(packed id, frame, band)` and the band's bytes, most recent last.
type BandCache = Vec<((u64, usize, u32), Vec<u8>)>;

thread_local! {
    static CACHE: RefCell<BandCache> = const { RefCell::new(Vec::new()) };
}

impl Default for PackedFrames {
    fn default() -> Self {
        Self::new()
    }
}

impl PackedFrames {
    /// No frames yet.
    pub fn new() -> Self {
        Self {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            width: 0,
            height: 0,
            layout: None,
            data: Vec::new(),
            bands: Vec::new(),
        }
    }

    /// How many frames.
    pub fn len(&self) -> usize {
        self.bands.len() / (self.bands().max(1) as usize)
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.bands.is_empty()
    }

    /// `(width, height)` of every frame (0 x 0 before the first).
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Bytes the packed frames take.
    pub fn byte_len(&self) -> usize {
        self.data.len()
    }

    fn bands(&self) -> u32 {
        self.height.div_ceil(BAND)
    }

    /// Packs `frame` after the others; it must have their size and form.
    pub fn push(&mut self, frame: FrameRef<'_>) -> Result<()> {
        let layout = match frame {
            FrameRef::Rgb(_) => Layout::Rgb,
            FrameRef::Yuv420(f) => Layout::Yuv420(f.matrix(), f.range()),
        };
        let dims = frame.dimensions();
        match self.layout {
            None => {
                (self.width, self.height) = dims;
                self.layout = Some(layout);
            }
            Some(l) if l != layout || dims != (self.width, self.height) => {
                return Err(Error::InvalidParameter {
                    name: "packed frame",
                    value: format!("{}x{} {layout:?}", dims.0, dims.1),
                    why: format!("the packed frames are {}x{} {l:?}", self.width, self.height),
                });
            }
            Some(_) => {}
        }
        let step = match layout {
            Layout::Rgb => 3,
            Layout::Yuv420(..) => 1,
        };
        let bands: Vec<Vec<u8>> = (0..self.bands())
            .into_par_iter()
            .map(|b| {
                let mut raw = Vec::new();
                for (plane, stride, rows) in planes(frame, b) {
                    let band = &plane[rows.start * stride..rows.end * stride];
                    let at = raw.len();
                    raw.resize(at + band.len(), 0);
                    predict(band, stride, step, &mut raw[at..], true);
                }
                fdeflate::compress_to_vec(&raw)
            })
            .collect();
        for band in bands {
            let at = self.data.len();
            self.data.extend_from_slice(&band);
            self.bands.push(at..self.data.len());
        }
        Ok(())
    }

    /// Keeps the first `len` frames.
    pub fn truncate(&mut self, len: usize) {
        if len < self.len() {
            let keep = len * self.bands() as usize;
            self.data.truncate(self.bands[keep].start);
            self.bands.truncate(keep);
        }
    }

    /// Band `b` of frame `f` unpacked (the planes' rows, as [`planes`] lists them), in this
    /// thread's cache.
    fn with_band<T>(&self, f: usize, b: u32, read: impl FnOnce(&[u8]) -> T) -> T {
        CACHE.with(|cache| {
            let mut cache = cache.borrow_mut();
            let key = (self.id, f, b);
            let at = match cache.iter().rposition(|(k, _)| *k == key) {
                Some(at) => at,
                None => {
                    let raw = self.unpack(f, b);
                    if cache.len() == CACHED_BANDS {
                        cache.remove(0);
                    }
                    cache.push((key, raw));
                    cache.len() - 1
                }
            };
            read(&cache[at].1)
        })
    }

    /// Band `b` of frame `f`: the planes' rows, as [`planes`] lists them.
    fn unpack(&self, f: usize, b: u32) -> Vec<u8> {
        let range = self.bands[f * self.bands() as usize + b as usize].clone();
        let residual =
            fdeflate::decompress_to_vec(&self.data[range]).expect("packed by PackedFrames::push");
        let step = match self.layout {
            Some(Layout::Yuv420(..)) => 1,
            _ => 3,
        };
        let mut out = vec![0u8; residual.len()];
        let mut at = 0;
        for (stride, rows) in self.band_rows(b) {
            let n = stride * rows;
            predict(
                &residual[at..at + n],
                stride,
                step,
                &mut out[at..at + n],
                false,
            );
            at += n;
        }
        out
    }

    /// Per plane of band `b`: its row length and its number of rows.
    fn band_rows(&self, b: u32) -> Vec<(usize, usize)> {
        let w = self.width as usize;
        let (y0, y1) = (
            (b * BAND) as usize,
            ((b + 1) * BAND).min(self.height) as usize,
        );
        match self.layout {
            Some(Layout::Rgb) | None => vec![(3 * w, y1 - y0)],
            Some(Layout::Yuv420(..)) => {
                let c = (y1 - y0) / 2;
                vec![(w, y1 - y0), (w / 2, c), (w / 2, c)]
            }
        }
    }

    /// Pixel `(x, y)` of frame `f`, RGB (a 4:2:0 frame converted as
    /// [`Yuv420Image::to_rgb_into`] converts it).
    pub fn pixel(&self, f: usize, x: u32, y: u32) -> [u8; 3] {
        let b = y / BAND;
        let r = (y - b * BAND) as usize;
        let (w, x) = (self.width as usize, x as usize);
        self.with_band(f, b, |raw| match self.layout {
            Some(Layout::Yuv420(matrix, range)) => {
                let rows = ((b + 1) * BAND).min(self.height) as usize - (b * BAND) as usize;
                let cw = w / 2;
                let u0 = rows * w;
                let v0 = u0 + rows / 2 * cw;
                let c = r / 2 * cw + x / 2;
                crate::yuv::yuv_to_rgb(matrix, range, raw[r * w + x], raw[u0 + c], raw[v0 + c])
            }
            _ => {
                let i = 3 * (r * w + x);
                [raw[i], raw[i + 1], raw[i + 2]]
            }
        })
    }

    /// Frame `f` in RGB, into `out` (resized if needed).
    pub fn rgb_into(&self, f: usize, out: &mut RgbImage) {
        let (w, h) = (self.width, self.height);
        if out.dimensions() != (w, h) {
            *out = RgbImage::new(w, h);
        }
        let row_bytes = 3 * w as usize;
        // A 4:2:0 band's RGB, reused from band to band (the last may be shorter).
        let mut rgb = RgbImage::new(0, 0);
        for b in 0..self.bands() {
            let (y0, y1) = (b * BAND, ((b + 1) * BAND).min(h));
            let rows = self.unpack(f, b);
            let dst = &mut out.as_mut()[y0 as usize * row_bytes..y1 as usize * row_bytes];
            match self.layout {
                Some(Layout::Yuv420(matrix, range)) => {
                    // The band's planes, as unpacked, are a 4:2:0 frame of its rows.
                    Yuv420Image::from_raw(w, y1 - y0, matrix, range, rows)
                        .expect("a band of an even-sized frame")
                        .to_rgb_into(&mut rgb);
                    dst.copy_from_slice(rgb.as_raw());
                }
                _ => dst.copy_from_slice(&rows),
            }
        }
    }
}

/// The median edge detector of LOCO-I (JPEG-LS): each byte predicted from its left `a`, upper
/// `b` and upper-left `c` neighbours (`step` bytes apart along a row, `stride` between rows;
/// the band's first row from its left alone), the residual stored. `forward`: `input` holds
/// the bytes, `out` gets residuals; else `input` holds residuals and `out` gets the bytes back.
fn predict(input: &[u8], stride: usize, step: usize, out: &mut [u8], forward: bool) {
    #[inline(always)]
    fn med(a: u8, b: u8, c: u8) -> u8 {
        let (lo, hi) = (a.min(b), a.max(b));
        if c >= hi {
            lo
        } else if c <= lo {
            hi
        } else {
            (a as i16 + b as i16 - c as i16) as u8
        }
    }
    // The neighbours of (row, x) in `bytes` (this row `cur`, the one above `up`).
    #[inline(always)]
    fn guess(cur: &[u8], up: Option<&[u8]>, x: usize, step: usize) -> u8 {
        match up {
            None if x >= step => cur[x - step],
            None => 0,
            Some(up) if x >= step => med(cur[x - step], up[x], up[x - step]),
            Some(up) => up[x],
        }
    }
    let rows = input.len() / stride;
    for row in 0..rows {
        let (done, rest) = out.split_at_mut(row * stride);
        let res = &mut rest[..stride];
        let line = &input[row * stride..(row + 1) * stride];
        if forward {
            let up = (row > 0).then(|| &input[(row - 1) * stride..row * stride]);
            for x in 0..stride {
                res[x] = line[x].wrapping_sub(guess(line, up, x, step));
            }
        } else {
            let up = (row > 0).then(|| &done[(row - 1) * stride..]);
            for x in 0..stride {
                res[x] = line[x].wrapping_add(guess(res, up, x, step));
            }
        }
    }
}

/// Band `b`'s rows of each plane of `frame`: the plane, its row length, its rows.
fn planes<'a>(frame: FrameRef<'a>, b: u32) -> Vec<(&'a [u8], usize, std::ops::Range<usize>)> {
    let (w, h) = frame.dimensions();
    let (y0, y1) = ((b * BAND) as usize, ((b + 1) * BAND).min(h) as usize);
    match frame {
        FrameRef::Rgb(img) => vec![(img.as_raw().as_slice(), 3 * w as usize, y0..y1)],
        FrameRef::Yuv420(img) => {
            let (w, h) = (w as usize, h as usize);
            let (y_plane, chroma) = img.as_raw().split_at(w * h);
            let (u, v) = chroma.split_at(w * h / 4);
            vec![
                (y_plane, w, y0..y1),
                (u, w / 2, y0 / 2..y1 / 2),
                (v, w / 2, y0 / 2..y1 / 2),
            ]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random_yuv(w: u32, h: u32, seed: u64) -> Yuv420Image {
        let mut rng = Rng::new(seed);
        let data = (0..Yuv420Image::byte_len(w, h))
            .map(|i| (i as u64 / 7 + rng.next_u64() % 9) as u8)
            .collect();
        Yuv420Image::from_raw(w, h, YuvMatrix::Bt709, YuvRange::Limited, data).unwrap()
    }

    #[test]
    fn packed_frames_read_back_exactly() {
        // 38 x 42: three bands, the last of 10 rows.
        let yuv: Vec<Yuv420Image> = (0..3).map(|s| random_yuv(38, 42, s)).collect();
        let mut packed = PackedFrames::new();
        for f in &yuv {
            packed.push(FrameRef::Yuv420(f)).unwrap();
        }
        let rgb: Vec<RgbImage> = yuv.iter().map(Yuv420Image::to_rgb).collect();
        let mut packed_rgb = PackedFrames::new();
        for f in &rgb {
            packed_rgb.push(FrameRef::Rgb(f)).unwrap();
        }
        let mut out = RgbImage::new(0, 0);
        for (i, want) in rgb.iter().enumerate() {
            packed.rgb_into(i, &mut out);
            assert_eq!(&out, want, "frame {i} whole");
            packed_rgb.rgb_into(i, &mut out);
            assert_eq!(&out, want, "RGB frame {i} whole");
            // Pixel by pixel, frames interleaved so that the cache turns over.
            for (x, y, px) in want.enumerate_pixels() {
                assert_eq!(packed.pixel(i, x, y), px.0, "frame {i} at ({x}, {y})");
                assert_eq!(
                    packed_rgb.pixel(i, x, y),
                    px.0,
                    "RGB frame {i} at ({x}, {y})"
                );
            }
        }
        assert!(packed.byte_len() > 0);
        // Truncated, the frames kept read back as before.
        let whole = packed.byte_len();
        packed.truncate(2);
        assert_eq!(packed.len(), 2);
        assert!(packed.byte_len() < whole);
        packed.rgb_into(1, &mut out);
        assert_eq!(out, rgb[1]);
        // A frame of another size or form is refused.
        let other = random_yuv(40, 42, 9);
        assert!(packed.push(FrameRef::Yuv420(&other)).is_err());
        assert!(packed.push(FrameRef::Rgb(&rgb[0])).is_err());
    }
}
