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
//! baseline, no B-frames, 4:2:0, one fixed quantiser), with an IDR frame every [`GOP`] frames
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

const MAGIC: &[u8; 8] = b"VTOBJ1\0\0";
const MAGIC_V2: &[u8; 8] = b"VTOBJ2\0\0";
const END: &[u8; 8] = b"VTOBJEND";
const HEADER: usize = 16;
const HEADER_V2: usize = 24;
/// Version 2's record head: the box and the deflated mask's length.
const RECORD_HEAD_V2: usize = 20;

/// Frames per group of pictures in version 2: the most frames one access decodes.
pub const GOP: u32 = 8;

/// The default quantiser of version 2 (see [`StoreQuality`]).
/// openh264's finest quantiser in its quality mode (it raises lower ones to this).
pub const MIN_QP: u8 = 12;

/// The default quantiser of version 2 (see [`StoreQuality`]): the finest. On tree.avi (444
/// frames, 320x240, 1.25 MB) a scene is 2.12x the video's bytes and its renders 43.7 dB (mean;
/// worst frame 43.5) from the lossless store's (12.3x); quantiser 16: 1.68x, 40.3 dB (40.0);
/// 20: 1.25x, 37.0 dB; 24: 0.86x, 33.8 dB (openh264; x264 at 12 on its first 96 frames: 43.52
/// dB and 2.52 MB against openh264's 43.57 dB and 2.49 MB, tests/store_quality.rs).
pub const DEFAULT_QP: u8 = MIN_QP;

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
}

impl Default for StoreQuality {
    fn default() -> Self {
        Self::H264 { qp: DEFAULT_QP }
    }
}

impl std::str::FromStr for StoreQuality {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "lossless" {
            return Ok(Self::Lossless);
        }
        match s.parse::<u8>() {
            Ok(qp) if (MIN_QP..=51).contains(&qp) => Ok(Self::H264 { qp }),
            _ => Err(format!(
                "'{s}': expected lossless or an H.264 quantiser {MIN_QP} to 51 (lower keeps \
                 more; default {DEFAULT_QP})"
            )),
        }
    }
}

impl std::fmt::Display for StoreQuality {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Lossless => write!(f, "lossless"),
            Self::H264 { qp } => write!(f, "{qp}"),
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

/// RGB to full-range BT.601 4:2:0 (JPEG's matrix, all 256 levels: a limited range would cost
/// a quantisation of its own): luma per pixel, chroma from each 2x2 block's mean colour.
/// `rgb` is `width` x `height` with even sides; `out` gets the Y, U and V planes. Integer
/// arithmetic with the coefficients in 1/2^16 (each level within one of the exact matrix's
/// rounding; two rows at a time, so the chroma of a row pair reads pixels already in cache).
fn rgb_to_yuv420(rgb: &[u8], width: usize, height: usize, out: &mut Vec<u8>) {
    const S: i32 = 16;
    const HALF: i32 = 1 << (S - 1);
    // 0.299, 0.587, 0.114; -0.168736, -0.331264, 0.5; 0.5, -0.418688, -0.081312 (x 2^16).
    const Y: [i32; 3] = [19595, 38470, 7471];
    const U: [i32; 3] = [-11058, -21710, 32768];
    const V: [i32; 3] = [32768, -27440, -5328];
    let (cw, ch) = (width / 2, height / 2);
    out.clear();
    out.resize(width * height + 2 * cw * ch, 0);
    let (luma, chroma) = out.split_at_mut(width * height);
    let (u_plane, v_plane) = chroma.split_at_mut(cw * ch);
    let stride = 3 * width;
    for cy in 0..ch {
        let rows = &rgb[2 * cy * stride..(2 * cy + 2) * stride];
        let (r0, r1) = rows.split_at(stride);
        let (l0, l1) = luma[2 * cy * width..(2 * cy + 2) * width].split_at_mut(width);
        for (src, dst) in [(r0, l0), (r1, l1)] {
            for (p, y) in src.chunks_exact(3).zip(dst.iter_mut()) {
                let v = Y[0] * p[0] as i32 + Y[1] * p[1] as i32 + Y[2] * p[2] as i32;
                *y = ((v + HALF) >> S).clamp(0, 255) as u8;
            }
        }
        let us = &mut u_plane[cy * cw..(cy + 1) * cw];
        let vs = &mut v_plane[cy * cw..(cy + 1) * cw];
        for (((a, b), u), v) in r0
            .chunks_exact(6)
            .zip(r1.chunks_exact(6))
            .zip(us.iter_mut())
            .zip(vs.iter_mut())
        {
            // Sums of the four pixels per channel: the mean is the sum / 4, folded into the shift.
            let m =
                [0, 1, 2].map(|k| a[k] as i32 + a[k + 3] as i32 + b[k] as i32 + b[k + 3] as i32);
            let cu = U[0] * m[0] + U[1] * m[1] + U[2] * m[2];
            let cv = V[0] * m[0] + V[1] * m[1] + V[2] * m[2];
            let round = |c: i32| (((c + (HALF << 2)) >> (S + 2)) + 128).clamp(0, 255) as u8;
            *u = round(cu);
            *v = round(cv);
        }
    }
}

/// Version 2's encoder state.
struct Encoding {
    encoder: openh264::encoder::Encoder,
    /// The frame padded to even sides (reused).
    padded: Vec<u8>,
    /// Its 4:2:0 planes.
    planes: Vec<u8>,
}

impl Encoding {
    fn new(qp: u8) -> std::result::Result<Self, openh264::Error> {
        use openh264::encoder::{
            BitRate, Complexity, EncoderConfig, IntraFramePeriod, Level, Profile, QpRange,
            RateControlMode,
        };
        // Quality mode with the quantiser pinned: every frame at `qp`. Frame skipping is on only
        // because openh264 otherwise warns on stderr that it cannot hold the bit rate; the rate
        // is far above anything a frame needs, and a skipped frame is an error all the same.
        let config = EncoderConfig::new()
            .rate_control_mode(RateControlMode::Quality)
            .qp(QpRange::new(qp, qp))
            .skip_frames(true)
            .bitrate(BitRate::from_bps(200_000_000))
            .profile(Profile::Baseline)
            .level(Level::Level_5_2)
            .complexity(Complexity::High)
            .adaptive_quantization(false)
            .background_detection(false)
            .scene_change_detect(false)
            .intra_frame_period(IntraFramePeriod::from_num_frames(GOP));
        let encoder = openh264::encoder::Encoder::with_api_config(
            openh264::OpenH264API::from_source(),
            config,
        )?;
        Ok(Self {
            encoder,
            padded: Vec::new(),
            planes: Vec::new(),
        })
    }

    /// Encodes frame `index` of `raw`; returns its access unit.
    fn encode(
        &mut self,
        raw: &RgbImage,
        index: usize,
        out: &mut Vec<u8>,
    ) -> std::result::Result<(), openh264::Error> {
        use openh264::formats::YUVBuffer;
        let (pw, ph) = padded_size(raw.width(), raw.height());
        pad_to_yuv420(raw, &mut self.padded, &mut self.planes);
        let yuv = YUVBuffer::from_vec(std::mem::take(&mut self.planes), pw, ph);
        if index.is_multiple_of(GOP as usize) {
            self.encoder.force_intra_frame();
        }
        let stream = self.encoder.encode(&yuv)?;
        stream.write_vec(out);
        Ok(())
    }
}

/// Version 2's encoder through x264 (ffmpeg's libx264, a process of its own, so the encoding
/// runs beside the analysis): preset ultrafast (no motion search beyond a diamond, no
/// deblocking), constrained baseline, one thread (the same bytes on every machine), an IDR
/// with its parameter sets every [`GOP`] frames, access unit delimiters to split the stream.
/// Frames are written to ffmpeg's input as 4:2:0 planes; a thread reads its output and hands
/// back one access unit per frame (the delimiter taken off), in order.
struct X264 {
    child: std::process::Child,
    stdin: Option<std::process::ChildStdin>,
    units: std::sync::mpsc::Receiver<Vec<u8>>,
    reader: Option<std::thread::JoinHandle<std::io::Result<()>>>,
    stderr: Option<std::thread::JoinHandle<String>>,
    /// The frame padded to even sides (reused), and its 4:2:0 planes.
    padded: Vec<u8>,
    planes: Vec<u8>,
}

/// Whether ffmpeg runs and has libx264 (asked once per process).
fn x264_available() -> bool {
    static AVAILABLE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVAILABLE.get_or_init(|| {
        std::process::Command::new("ffmpeg")
            .args(["-hide_banner", "-h", "encoder=libx264"])
            .stdin(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .output()
            .is_ok_and(|o| {
                o.status.success() && String::from_utf8_lossy(&o.stdout).contains("libx264")
            })
    })
}

/// Splits an Annex B stream with access unit delimiters into access units, the delimiters
/// taken off: each unit is what lies between one delimiter's end and the next's start code.
/// `buf` holds the bytes not yet handed on; `end` says no more come.
fn split_units(buf: &mut Vec<u8>, end: bool, mut unit: impl FnMut(Vec<u8>) -> bool) -> bool {
    // Start codes 00 00 01 (a fourth zero before one belongs to it) of delimiter NALs (type 9).
    let delimiters = |b: &[u8]| -> Vec<usize> {
        let mut at = Vec::new();
        let mut i = 0;
        while i + 3 < b.len() {
            if b[i + 2] > 1 {
                i += 3;
            } else if b[i] == 0 && b[i + 1] == 0 && b[i + 2] == 1 {
                if b[i + 3] & 0x1f == 9 {
                    at.push(if i > 0 && b[i - 1] == 0 { i - 1 } else { i });
                }
                i += 3;
            } else {
                i += 1;
            }
        }
        at
    };
    let at = delimiters(buf);
    let mut bounds = at.clone();
    if end {
        bounds.push(buf.len());
    }
    let mut consumed = 0;
    for w in bounds.windows(2) {
        // The delimiter NAL: start code, header byte, one payload byte.
        let nal = &buf[w[0]..w[1]];
        let skip = if nal[0] == 0 && nal[1] == 0 && nal[2] == 0 {
            6
        } else {
            5
        };
        if !unit(nal[skip.min(nal.len())..].to_vec()) {
            return false;
        }
        consumed = w[1];
    }
    if let Some(&first) = at.first() {
        consumed = consumed.max(first);
    }
    buf.drain(..consumed);
    true
}

impl X264 {
    fn new(qp: u8, width: usize, height: usize) -> std::io::Result<Self> {
        use std::process::{Command, Stdio};
        let mut child = Command::new("ffmpeg")
            .args([
                "-v", "error", "-nostdin", "-f", "rawvideo", "-pix_fmt", "yuv420p",
            ])
            .args(["-s", &format!("{width}x{height}"), "-r", "25", "-i", "-"])
            .args(["-an", "-c:v", "libx264", "-preset", "ultrafast"])
            .args([
                "-profile:v",
                "baseline",
                "-pix_fmt",
                "yuv420p",
                "-threads",
                "1",
            ])
            .args(["-qp", &qp.to_string(), "-g", &GOP.to_string()])
            .args([
                "-keyint_min",
                &GOP.to_string(),
                "-sc_threshold",
                "0",
                "-bf",
                "0",
            ])
            .args([
                "-x264-params",
                "aud=1:repeat-headers=1:scenecut=0:ipratio=1",
            ])
            .args(["-f", "h264", "-"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()?;
        let stdin = child.stdin.take();
        let mut stdout = child.stdout.take().expect("stdout was piped");
        let err = child.stderr.take().expect("stderr was piped");
        let (send, units) = std::sync::mpsc::channel();
        let reader = std::thread::Builder::new()
            .name("vt-store-x264".into())
            .spawn(move || -> std::io::Result<()> {
                use std::io::Read;
                let mut buf = Vec::new();
                let mut chunk = vec![0u8; 1 << 16];
                loop {
                    let n = stdout.read(&mut chunk)?;
                    buf.extend_from_slice(&chunk[..n]);
                    let more = split_units(&mut buf, n == 0, |u| send.send(u).is_ok());
                    if n == 0 || !more {
                        return Ok(());
                    }
                }
            })?;
        let stderr = crate::video::drain(err);
        Ok(Self {
            child,
            stdin,
            units,
            reader: Some(reader),
            stderr: Some(stderr),
            padded: Vec::new(),
            planes: Vec::new(),
        })
    }

    /// What ffmpeg said, once it has ended.
    fn failure(&mut self, what: &str) -> String {
        self.stdin = None;
        let _ = self.child.wait();
        let said = self
            .stderr
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        let said = said.trim();
        if said.is_empty() {
            what.to_string()
        } else {
            format!("{what}: {said}")
        }
    }

    /// Sends frame `raw` to the encoder.
    fn send(&mut self, raw: &RgbImage) -> std::result::Result<(), String> {
        pad_to_yuv420(raw, &mut self.padded, &mut self.planes);
        let Some(stdin) = self.stdin.as_mut() else {
            return Err("x264 encoder closed".into());
        };
        if let Err(e) = stdin.write_all(&self.planes) {
            return Err(self.failure(&format!("x264 encoder (ffmpeg) stopped: {e}")));
        }
        Ok(())
    }

    /// Access units ready now (all the rest when `end`, after closing the input).
    fn units(&mut self, end: bool) -> std::result::Result<Vec<Vec<u8>>, String> {
        if !end {
            return Ok(self.units.try_iter().collect());
        }
        self.stdin = None;
        let units: Vec<Vec<u8>> = self.units.iter().collect();
        let read = self.reader.take().map(|r| r.join());
        let status = self.child.wait();
        match (read, status) {
            (Some(Ok(Ok(()))), Ok(s)) if s.success() => Ok(units),
            (Some(Ok(Err(e))), _) => Err(self.failure(&format!("x264 encoder output: {e}"))),
            _ => Err(self.failure("x264 encoder (ffmpeg) failed")),
        }
    }
}

impl Drop for X264 {
    fn drop(&mut self) {
        self.stdin = None;
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `raw` padded to even sides, at least 16 ([`padded_size`]), by repeating its last column
/// and row (into `padded`), as 4:2:0 planes (into `planes`).
fn pad_to_yuv420(raw: &RgbImage, padded: &mut Vec<u8>, planes: &mut Vec<u8>) {
    let (w, h) = (raw.width() as usize, raw.height() as usize);
    let (pw, ph) = padded_size(raw.width(), raw.height());
    let src = raw.as_raw();
    if (pw, ph) == (w, h) {
        rgb_to_yuv420(src, pw, ph, planes);
        return;
    }
    padded.clear();
    for y in 0..ph {
        let row = &src[3 * w * y.min(h - 1)..3 * w * (y.min(h - 1) + 1)];
        padded.extend_from_slice(row);
        for _ in w..pw {
            padded.extend_from_slice(&row[3 * (w - 1)..]);
        }
    }
    rgb_to_yuv420(padded, pw, ph, planes);
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
    /// Version 2's encoder; None for version 1.
    encoding: Option<H264Writer>,
    /// Version 2 through x264: the heads of the records (box, deflated mask) whose access
    /// units have not come back yet, oldest first.
    waiting: std::collections::VecDeque<Vec<u8>>,
    /// Frames handed to the encoder.
    sent: usize,
}

/// Which program encodes version 2's pictures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum H264Encoder {
    /// x264 through ffmpeg when ffmpeg has libx264 (about 3x less CPU than openh264, in a
    /// process of its own), else openh264.
    Auto,
    /// x264 through ffmpeg (an error when ffmpeg or its libx264 is missing).
    X264,
    /// openh264, in this process.
    OpenH264,
}

enum H264Writer {
    OpenH264(Box<Encoding>),
    X264(X264),
}

impl ObjectWriter {
    /// Creates a lossless (version 1) store.
    pub fn create(path: &Path, width: u32, height: u32) -> Result<Self> {
        Self::create_with(path, width, height, StoreQuality::Lossless)
    }

    /// Creates a store that keeps the pixels at `quality`.
    pub fn create_with(
        path: &Path,
        width: u32,
        height: u32,
        quality: StoreQuality,
    ) -> Result<Self> {
        Self::create_with_encoder(path, width, height, quality, H264Encoder::Auto)
    }

    /// Creates a store that keeps the pixels at `quality`, H.264 made by `encoder`.
    pub fn create_with_encoder(
        path: &Path,
        width: u32,
        height: u32,
        quality: StoreQuality,
        encoder: H264Encoder,
    ) -> Result<Self> {
        let side = crate::limits::MAX_IMAGE_SIDE;
        if width == 0 || height == 0 || width > side || height > side {
            return Err(Error::Scene {
                path: path.to_path_buf(),
                message: format!("object store of {width}x{height} (1 to {side} per side)"),
            });
        }
        let encoding = match quality {
            StoreQuality::Lossless => None,
            StoreQuality::H264 { qp } => {
                let qp = qp.clamp(MIN_QP, 51);
                let x264 = match encoder {
                    H264Encoder::Auto => x264_available(),
                    H264Encoder::X264 => true,
                    H264Encoder::OpenH264 => false,
                };
                let bad = |e: String| Error::Scene {
                    path: path.to_path_buf(),
                    message: format!("H.264 encoder for {width}x{height}: {e}"),
                };
                Some(if x264 {
                    let (pw, ph) = padded_size(width, height);
                    H264Writer::X264(
                        X264::new(qp, pw, ph).map_err(|e| bad(format!("ffmpeg: {e}")))?,
                    )
                } else {
                    H264Writer::OpenH264(Box::new(
                        Encoding::new(qp).map_err(|e| bad(e.to_string()))?,
                    ))
                })
            }
        };
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        let mut out = BufWriter::new(file);
        let mut head = Vec::with_capacity(HEADER_V2);
        head.extend_from_slice(if encoding.is_some() { MAGIC_V2 } else { MAGIC });
        head.extend_from_slice(&width.to_le_bytes());
        head.extend_from_slice(&height.to_le_bytes());
        if let StoreQuality::H264 { qp } = quality {
            head.extend_from_slice(&GOP.to_le_bytes());
            head.extend_from_slice(&u32::from(qp).to_le_bytes());
        }
        out.write_all(&head).map_err(|e| Error::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            out,
            width,
            height,
            offsets: Vec::new(),
            pos: head.len() as u64,
            rec: Vec::new(),
            box_words: Vec::new(),
            encoding,
            waiting: Default::default(),
            sent: 0,
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
        if self.encoding.is_some() {
            return self.push_h264(mask, raw);
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
        // 64 mask bits at a time: bits copied as words, pixels as runs.
        let px = raw.as_raw();
        pack_box(mask, (x0, y0, x1, y1), box_words, |start, mut bits| {
            let mut k = 0;
            while bits != 0 {
                let skip = bits.trailing_zeros() as usize;
                bits >>= skip;
                let len = bits.trailing_ones() as usize;
                bits = if len == 64 { 0 } else { bits >> len };
                let at = start + k + skip;
                rec.extend_from_slice(&px[3 * at..3 * (at + len)]);
                k += skip + len;
            }
        });
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

    /// Version 2's record: box, deflated mask bits, access unit.
    fn push_h264(&mut self, mask: &Mask, raw: &RgbImage) -> Result<()> {
        let bbox = mask.bounding_box().unwrap_or((0, 0, 0, 0));
        let n_bits = ((bbox.2 - bbox.0) * (bbox.3 - bbox.1)) as usize;
        pack_box(mask, bbox, &mut self.box_words, |_, _| {});
        let bytes: Vec<u8> = self
            .box_words
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .take(n_bits.div_ceil(8))
            .collect();
        let deflated = miniz_oxide::deflate::compress_to_vec(&bytes, 6);
        let rec = &mut self.rec;
        rec.clear();
        for v in [bbox.0, bbox.1, bbox.2, bbox.3] {
            rec.extend_from_slice(&v.to_le_bytes());
        }
        rec.extend_from_slice(&(deflated.len() as u32).to_le_bytes());
        rec.extend_from_slice(&deflated);
        let at = rec.len();
        let index = self.sent;
        self.sent += 1;
        let bad = |path: &Path, m: String| Error::Scene {
            path: path.to_path_buf(),
            message: format!("H.264 encoder, frame {index}: {m}"),
        };
        match self
            .encoding
            .as_mut()
            .expect("push_h264 only with an encoder")
        {
            H264Writer::OpenH264(encoding) => {
                let encoded = encoding.encode(raw, index, rec);
                if let Err(e) = encoded {
                    return Err(bad(&self.path, e.to_string()));
                }
                if rec.len() == at {
                    return Err(bad(&self.path, "skipped".into()));
                }
                self.write_record()
            }
            H264Writer::X264(x) => {
                x.send(raw).map_err(|e| bad(&self.path, e))?;
                self.waiting.push_back(rec.clone());
                let units = x.units(false).map_err(|e| bad(&self.path, e))?;
                self.write_units(units)
            }
        }
    }

    /// Appends `self.rec`, a whole record.
    fn write_record(&mut self) -> Result<()> {
        self.offsets.push(self.pos);
        self.pos += self.rec.len() as u64;
        self.out
            .write_all(&self.rec)
            .map_err(|e| Error::io(&self.path, e))
    }

    /// Completes the waiting records with `units`, in order, and appends them.
    fn write_units(&mut self, units: Vec<Vec<u8>>) -> Result<()> {
        for unit in units {
            let Some(head) = self.waiting.pop_front() else {
                return Err(Error::Scene {
                    path: self.path.clone(),
                    message: "H.264 encoder gave more pictures than frames".into(),
                });
            };
            if unit.is_empty() {
                return Err(Error::Scene {
                    path: self.path.clone(),
                    message: format!("H.264 encoder skipped frame {}", self.offsets.len()),
                });
            }
            self.rec = head;
            self.rec.extend_from_slice(&unit);
            self.write_record()?;
        }
        Ok(())
    }

    /// Whether [`H264Encoder::Auto`] picks x264 (ffmpeg runs and has libx264).
    pub fn x264_available() -> bool {
        x264_available()
    }

    /// Frames pushed so far.
    pub fn len(&self) -> usize {
        self.offsets.len() + self.waiting.len()
    }

    /// True before the first push.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes the offset table and trailer and closes the file.
    pub fn finish(mut self) -> Result<()> {
        if let Some(H264Writer::X264(x)) = self.encoding.as_mut() {
            let units = x.units(true).map_err(|e| Error::Scene {
                path: self.path.clone(),
                message: format!("H.264 encoder: {e}"),
            })?;
            self.write_units(units)?;
            if !self.waiting.is_empty() {
                return Err(Error::Scene {
                    path: self.path.clone(),
                    message: format!(
                        "H.264 encoder gave {} pictures for {} frames",
                        self.offsets.len(),
                        self.sent
                    ),
                });
            }
        }
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

/// A loaded store (either version). Version 1 is held in memory. Version 2 loaded from a file
/// keeps only its index (offsets and boxes, 28 bytes a frame) and reads each record when it is
/// decoded, so memory does not grow with the video's length; its frames are decoded by a
/// thread of the store's own, by group of pictures, into a small cache of decoded frames, and
/// the frame after the one asked for is decoded ahead while the caller renders; see
/// [`ObjectStore::decode_into`].
pub struct ObjectStore {
    path: PathBuf,
    width: u32,
    height: u32,
    bytes: std::sync::Arc<Bytes>,
    index: std::sync::Arc<Index>,
    /// Version 2's decoder; None for version 1.
    codec: Option<Decoding>,
}

/// Where a store's bytes are.
enum Bytes {
    /// All of them (version 1, and stores given as bytes).
    Memory(Vec<u8>),
    /// In the file, read record by record.
    File { file: std::fs::File, len: usize },
}

impl Bytes {
    fn len(&self) -> usize {
        match self {
            Self::Memory(d) => d.len(),
            Self::File { len, .. } => *len,
        }
    }

    /// Calls `f` with bytes `at..at + n` (read into `buf` from a file); an error when they
    /// cannot be read (a file shortened since it was loaded).
    fn with<R>(
        &self,
        at: usize,
        n: usize,
        buf: &mut Vec<u8>,
        f: impl FnOnce(&[u8]) -> R,
    ) -> std::io::Result<R> {
        match self {
            Self::Memory(d) => d
                .get(at..at.saturating_add(n))
                .map(f)
                .ok_or_else(|| std::io::ErrorKind::UnexpectedEof.into()),
            Self::File { file, .. } => {
                use std::os::unix::fs::FileExt;
                buf.clear();
                buf.resize(n, 0);
                file.read_exact_at(buf, at as u64)?;
                Ok(f(buf))
            }
        }
    }

    /// All the bytes (version 1 is always held in memory).
    fn memory(&self) -> &[u8] {
        match self {
            Self::Memory(d) => d,
            Self::File { .. } => unreachable!("version 1 stores are read whole"),
        }
    }
}

/// Where each record is.
struct Index {
    /// Byte offset of each record, and where the table starts.
    offsets: Vec<u64>,
    /// Version 2's record heads (box and deflated mask length), read once; empty in version 1.
    heads: Vec<((u32, u32, u32, u32), u32)>,
}

impl Index {
    /// Version 2's record `i`: its deflated mask's bytes and its access unit's, as ranges.
    fn parts_v2(&self, i: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
        let (start, end) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        let mask_end = start + RECORD_HEAD_V2 + self.heads[i].1 as usize;
        (start + RECORD_HEAD_V2..mask_end, mask_end..end)
    }
}

/// Version 2's reading side: the decoding thread (started on the first decode) and what it
/// shares with the callers.
struct Decoding {
    gop: usize,
    qp: u8,
    shared: std::sync::Arc<Shared>,
    worker: std::sync::Mutex<Option<std::thread::JoinHandle<()>>>,
    /// The mask bits of the box being decoded, and a record's bytes read from the file (reused).
    scratch: std::sync::Mutex<(Vec<u8>, Vec<u8>)>,
}

/// What the decoding thread and the callers share.
struct Shared {
    queue: std::sync::Mutex<Queue>,
    changed: std::sync::Condvar,
}

/// The decoding thread's requests and results.
#[derive(Default)]
struct Queue {
    /// The frames callers wait for.
    wants: Vec<usize>,
    /// The frame to decode when no caller waits (the one after the last asked for).
    ahead: Option<usize>,
    /// Recently decoded frames as 4:2:0 planes of the padded size, oldest first (at most a
    /// group and three).
    cache: std::collections::VecDeque<(usize, std::sync::Arc<Vec<u8>>)>,
    /// Buffers of frames dropped from the cache, for the next ones.
    spare: Vec<Vec<u8>>,
    /// A frame that did not decode, and what of it.
    failed: Option<(usize, &'static str)>,
    /// Set when the store is dropped, or by the thread when it ends.
    stop: bool,
}

impl Queue {
    fn cached(&self, f: usize) -> Option<&std::sync::Arc<Vec<u8>>> {
        self.cache.iter().find(|(g, _)| *g == f).map(|(_, b)| b)
    }

    /// The frame (and what of it) that did not decode on the way to `f`: `f` or one before it
    /// in its group.
    fn blocked(&self, f: usize, gop: usize) -> Option<(usize, &'static str)> {
        self.failed.filter(|&(g, _)| g <= f && g / gop == f / gop)
    }
}

impl Drop for Decoding {
    fn drop(&mut self) {
        if let Ok(mut q) = self.shared.queue.lock() {
            q.stop = true;
        }
        self.shared.changed.notify_all();
        if let Some(w) = self.worker.get_mut().ok().and_then(Option::take) {
            let _ = w.join();
        }
    }
}

/// The decoding thread's own state: the decoder and where it stands.
struct Worker {
    bytes: std::sync::Arc<Bytes>,
    index: std::sync::Arc<Index>,
    shared: std::sync::Arc<Shared>,
    gop: usize,
    size: (usize, usize),
    decoder: Option<openh264::decoder::Decoder>,
    /// The frame the decoder would output next if fed the next access unit (its references are
    /// those of the frame before); None when it holds nothing usable.
    next: Option<usize>,
    unit: Vec<u8>,
}

/// Marks the queue stopped when the decoding thread ends, a panic included, so no caller
/// waits for it.
struct StopOnExit(std::sync::Arc<Shared>);

impl Drop for StopOnExit {
    fn drop(&mut self) {
        let mut q = self.0.queue.lock().unwrap_or_else(|e| e.into_inner());
        q.stop = true;
        drop(q);
        self.0.changed.notify_all();
    }
}

impl Worker {
    fn run(mut self) {
        let _stop = StopOnExit(self.shared.clone());
        let shared = self.shared.clone();
        let mut q = shared.queue.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if q.stop {
                return;
            }
            let target = q
                .wants
                .iter()
                .copied()
                .chain(q.ahead)
                .find(|&f| q.cached(f).is_none() && q.blocked(f, self.gop).is_none());
            let Some(f) = target else {
                q = shared.changed.wait(q).unwrap_or_else(|e| e.into_inner());
                continue;
            };
            drop(q);
            self.decode_to(f);
            q = shared.queue.lock().unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Decodes frame `f` into the cache: from its group's start, or on from where the decoder
    /// stands when that is in the group before `f`. Stops early when a caller comes to wait for
    /// a frame this run will not reach.
    fn decode_to(&mut self, f: usize) {
        let group_start = f - f % self.gop;
        let from = match self.next {
            Some(n) if (group_start..=f).contains(&n) && self.decoder.is_some() => n,
            _ => group_start,
        };
        self.next = None;
        for g in from..=f {
            let mut buf = {
                let mut q = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
                q.spare.pop().unwrap_or_default()
            };
            if let Err(what) = self.decode_one(g, &mut buf) {
                self.decoder = None;
                let mut q = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
                q.failed = Some((g, what));
                drop(q);
                self.shared.changed.notify_all();
                return;
            }
            self.next = Some(g + 1);
            let mut q = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
            q.cache.retain(|(h, _)| *h != g);
            q.cache.push_back((g, std::sync::Arc::new(buf)));
            while q.cache.len() > self.gop + 3 {
                // The oldest frame no caller waits for.
                let Some(at) = q.cache.iter().position(|(h, _)| !q.wants.contains(h)) else {
                    break;
                };
                if let Some((_, b)) = q.cache.remove(at) {
                    if let Ok(b) = std::sync::Arc::try_unwrap(b) {
                        q.spare.push(b);
                    }
                }
            }
            let interrupted = q
                .wants
                .iter()
                .any(|&w| q.cached(w).is_none() && !(g + 1..=f).contains(&w));
            drop(q);
            self.shared.changed.notify_all();
            if interrupted {
                return;
            }
        }
    }

    /// Decodes record `g`'s access unit into `out`: its planes without the strides' padding.
    fn decode_one(&mut self, g: usize, out: &mut Vec<u8>) -> std::result::Result<(), &'static str> {
        let range = self.index.parts_v2(g).1;
        let mut unit = std::mem::take(&mut self.unit);
        let bytes = self.bytes.clone();
        let result = bytes
            .with(range.start, range.len(), &mut unit, |unit| {
                self.decode_unit(unit, out)
            })
            .map_err(|_| "frame")
            .and_then(|r| r);
        self.unit = unit;
        result
    }

    fn decode_unit(
        &mut self,
        unit: &[u8],
        out: &mut Vec<u8>,
    ) -> std::result::Result<(), &'static str> {
        if self.decoder.is_none() {
            self.decoder = Some(openh264::decoder::Decoder::new().map_err(|_| "frame")?);
        }
        let dec = self.decoder.as_mut().expect("set above");
        let yuv = match dec.decode(unit) {
            Ok(Some(yuv)) => yuv,
            _ => return Err("picture"),
        };
        use openh264::formats::YUVSource;
        let (pw, ph) = self.size;
        if yuv.dimensions() != (pw, ph) {
            return Err("picture size");
        }
        out.clear();
        let (sy, su, sv) = yuv.strides();
        for (plane, stride, w, h) in [
            (yuv.y(), sy, pw, ph),
            (yuv.u(), su, pw / 2, ph / 2),
            (yuv.v(), sv, pw / 2, ph / 2),
        ] {
            for row in 0..h {
                out.extend_from_slice(&plane[row * stride..row * stride + w]);
            }
        }
        Ok(())
    }
}

impl ObjectStore {
    /// Loads and validates a store: version 1 whole, version 2's index only (its records are
    /// read when decoded; each is read once here to check it).
    pub fn load(path: &Path) -> Result<Self> {
        let len = crate::limits::check_file_size(
            path,
            crate::limits::MAX_OBJECT_STORE_BYTES,
            "object store",
        )?;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut magic = [0u8; 8];
        {
            use std::os::unix::fs::FileExt;
            if len < 8 || file.read_exact_at(&mut magic, 0).is_err() || &magic != MAGIC_V2 {
                let data = crate::limits::read_bytes(
                    path,
                    crate::limits::MAX_OBJECT_STORE_BYTES,
                    "object store",
                )?;
                return Self::from_bytes(data, path);
            }
        }
        let len = usize::try_from(len).map_err(|_| Error::Scene {
            path: path.to_path_buf(),
            message: "object store too large for this machine".into(),
        })?;
        Self::parse(Bytes::File { file, len }, path)
    }

    /// Validates a store's bytes (every offset, box and pixel count checked, so no later access
    /// can fail); `path` names it in errors.
    pub fn from_bytes(data: Vec<u8>, path: &Path) -> Result<Self> {
        Self::parse(Bytes::Memory(data), path)
    }

    fn parse(bytes: Bytes, path: &Path) -> Result<Self> {
        let bad = |m: String| Error::Scene {
            path: path.to_path_buf(),
            message: m,
        };
        let len = bytes.len();
        let mut buf = Vec::new();
        let head = bytes
            .with(0, HEADER_V2.min(len), &mut buf, <[u8]>::to_vec)
            .map_err(|e| Error::io(path, e))?;
        let version2 = head.len() >= 8 && &head[..8] == MAGIC_V2;
        if head.len() >= 8 && head[..5] == MAGIC[..5] && !version2 && &head[..8] != MAGIC {
            return Err(bad(format!(
                "object store version '{}' is not one this vt reads (1 or 2); run vt analyze \
                 again to re-create the scene",
                String::from_utf8_lossy(&head[5..8]).trim_end_matches('\0')
            )));
        }
        if len < HEADER || (&head[..8] != MAGIC && !version2) {
            return Err(bad("not a vt object store (bad magic)".into()));
        }
        let header = if version2 { HEADER_V2 } else { HEADER };
        let tail = if len >= header + 24 {
            bytes
                .with(len - 16, 16, &mut buf, <[u8]>::to_vec)
                .map_err(|e| Error::io(path, e))?
        } else {
            Vec::new()
        };
        if tail.len() < 16 || &tail[8..] != END {
            return Err(bad(
                "corrupted or truncated object store (no end marker)".into()
            ));
        }
        let u32_at =
            |d: &[u8], o: usize| u32::from_le_bytes(d[o..o + 4].try_into().expect("4 bytes"));
        let u64_at =
            |d: &[u8], o: usize| u64::from_le_bytes(d[o..o + 8].try_into().expect("8 bytes"));
        let (width, height) = (u32_at(&head, 8), u32_at(&head, 12));
        let side = crate::limits::MAX_IMAGE_SIDE;
        if width == 0 || height == 0 || width > side || height > side {
            return Err(bad(format!(
                "corrupted: frame size {width}x{height} (1 to {side} per side)"
            )));
        }
        let n = u64_at(&tail, 0) as usize;
        let table_len = n
            .checked_add(1)
            .and_then(|k| k.checked_mul(8))
            .filter(|&l| l.checked_add(16 + header).is_some_and(|t| t <= len));
        let Some(table_len) = table_len else {
            return Err(bad(format!(
                "corrupted: {n} frames do not fit in {len} bytes"
            )));
        };
        let table_start = len - 16 - table_len;
        let offsets: Vec<u64> = bytes
            .with(table_start, table_len, &mut buf, |t| {
                (0..=n).map(|i| u64_at(t, 8 * i)).collect()
            })
            .map_err(|e| Error::io(path, e))?;
        let min_record = if version2 { RECORD_HEAD_V2 + 1 } else { 16 };
        if offsets
            .windows(2)
            .any(|w| w[1] < w[0].saturating_add(min_record as u64))
            || offsets.first() != Some(&(header as u64))
            || offsets[n] != table_start as u64
        {
            return Err(bad("corrupted: offset table does not match the file".into()));
        }
        let codec = if version2 {
            let (gop, qp) = (u32_at(&head, 16), u32_at(&head, 20));
            if !(1..=250).contains(&gop) || qp > 51 {
                return Err(bad(format!(
                    "corrupted: group of {gop} frames at quantiser {qp} (1 to 250, 0 to 51)"
                )));
            }
            Some(Decoding {
                gop: gop as usize,
                qp: qp as u8,
                shared: std::sync::Arc::new(Shared {
                    queue: Default::default(),
                    changed: Default::default(),
                }),
                worker: Default::default(),
                scratch: Default::default(),
            })
        } else {
            None
        };
        let mut store = Self {
            path: path.to_path_buf(),
            width,
            height,
            bytes: std::sync::Arc::new(bytes),
            index: std::sync::Arc::new(Index {
                offsets,
                heads: Vec::new(),
            }),
            codec,
        };
        if store.codec.is_some() {
            store.check_v2(&mut buf)?;
            return Ok(store);
        }
        for i in 0..n {
            let (x0, y0, x1, y1) = store.raw_bbox(i);
            let ok = x0 <= x1 && y0 <= y1 && x1 <= width && y1 <= height;
            // Sizes are at most MAX_IMAGE_SIDE^2 = 2^28 bits: no overflow.
            let n_bits = ok.then(|| (x1 - x0) as usize * (y1 - y0) as usize);
            let need = n_bits.map(|b| 16 + b.div_ceil(8));
            let offsets = &store.index.offsets;
            let len = (offsets[i + 1] - offsets[i]) as usize;
            if need.is_none_or(|need| len < need || !(len - need).is_multiple_of(3)) {
                return Err(bad(format!("corrupted: frame {i} record is inconsistent")));
            }
            // Every set bit needs its RGB triple, no more, no less.
            let (n_bits, need) = (n_bits.unwrap_or(0), need.unwrap_or(16));
            let o = offsets[i] as usize + 16;
            let bits = &store.bytes.memory()[o..o + n_bits.div_ceil(8)];
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

    /// Version 2's records, each read once: boxes inside the frame, masks that inflate to
    /// exactly their box's bits, an access unit in every record (its content is checked when
    /// decoded). Keeps the record heads.
    fn check_v2(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        let mut heads = Vec::with_capacity(self.len());
        for i in 0..self.len() {
            let bad = |m: &str| Error::Scene {
                path: self.path.clone(),
                message: format!("corrupted: frame {i} {m}"),
            };
            let offsets = &self.index.offsets;
            let (start, end) = (offsets[i] as usize, offsets[i + 1] as usize);
            let (width, height) = (self.width, self.height);
            let head = self
                .bytes
                .with(start, end - start, buf, |rec| {
                    let g = |k: usize| {
                        u32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().expect("4 bytes"))
                    };
                    let (x0, y0, x1, y1) = (g(0), g(1), g(2), g(3));
                    if !(x0 <= x1 && y0 <= y1 && x1 <= width && y1 <= height) {
                        return Err("has a box outside the frame");
                    }
                    let mask_len = g(4) as usize;
                    if mask_len >= end - start - RECORD_HEAD_V2 {
                        return Err("record is inconsistent");
                    }
                    let nb = ((x1 - x0) as usize * (y1 - y0) as usize).div_ceil(8);
                    let deflated = &rec[RECORD_HEAD_V2..RECORD_HEAD_V2 + mask_len];
                    match miniz_oxide::inflate::decompress_to_vec_with_limit(deflated, nb) {
                        Ok(bits) if bits.len() == nb => Ok(((x0, y0, x1, y1), mask_len as u32)),
                        _ => Err("has a damaged mask"),
                    }
                })
                .map_err(|e| Error::io(&self.path, e))?
                .map_err(bad)?;
            heads.push(head);
        }
        std::sync::Arc::get_mut(&mut self.index)
            .expect("not shared before the store is made")
            .heads = heads;
        Ok(())
    }

    /// How the store keeps its pixels.
    pub fn quality(&self) -> StoreQuality {
        match &self.codec {
            None => StoreQuality::Lossless,
            Some(c) => StoreQuality::H264 { qp: c.qp },
        }
    }

    /// Frames per group of pictures: frame `i` decodes from frame `i - i % group()` on (1 for a
    /// lossless store, whose frames stand alone).
    pub fn group(&self) -> usize {
        self.codec.as_ref().map_or(1, |c| c.gop)
    }

    /// Bytes of the file that decoding frame `i` alone reads (its record; version 2 also
    /// decodes the frames before it in its group when they are not cached).
    pub fn frame_bytes(&self, i: usize) -> usize {
        (self.index.offsets[i + 1] - self.index.offsets[i]) as usize
    }

    /// The store's size in bytes.
    pub fn byte_len(&self) -> usize {
        self.bytes.len()
    }

    fn raw_bbox(&self, i: usize) -> (u32, u32, u32, u32) {
        if self.codec.is_some() {
            return self.index.heads[i].0;
        }
        let o = self.index.offsets[i] as usize;
        let data = self.bytes.memory();
        let g = |k: usize| {
            u32::from_le_bytes(data[o + 4 * k..o + 4 * k + 4].try_into().expect("4 bytes"))
        };
        (g(0), g(1), g(2), g(3))
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.index.offsets.len() - 1
    }

    /// True when the store has no frames.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Frame size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Frame `i`'s object in a version 1 store (None in version 2, whose pixels need
    /// decoding: use [`ObjectStore::decode_into`]). Panics when `i >= len()`.
    pub fn frame(&self, i: usize) -> Option<ObjectFrame<'_>> {
        self.codec.is_none().then(|| self.raw_frame(i))
    }

    fn raw_frame(&self, i: usize) -> ObjectFrame<'_> {
        let bbox = self.raw_bbox(i);
        let offsets = &self.index.offsets;
        let (o, end) = (offsets[i] as usize + 16, offsets[i + 1] as usize);
        let nb = (((bbox.2 - bbox.0) * (bbox.3 - bbox.1)) as usize).div_ceil(8);
        let data = self.bytes.memory();
        ObjectFrame {
            bbox,
            bits: &data[o..o + nb],
            rgb: &data[o + nb..end],
        }
    }

    /// Frame `i`'s mask as a full-size [`Mask`] (empty where a version 2 file can no longer be
    /// read). Panics when `i >= len()`.
    pub fn mask(&self, i: usize) -> Mask {
        let mut m = Mask::new(self.width, self.height);
        if self.codec.is_none() {
            self.raw_frame(i)
                .for_each_pixel(|x, y, _| m.set(x, y, true));
            return m;
        }
        let (x0, y0, x1, y1) = self.raw_bbox(i);
        let nb = ((x1 - x0) as usize * (y1 - y0) as usize).div_ceil(8);
        let range = self.index.parts_v2(i).0;
        let bits = self
            .bytes
            .with(range.start, range.len(), &mut Vec::new(), |deflated| {
                miniz_oxide::inflate::decompress_to_vec_with_limit(deflated, nb).ok()
            })
            .ok()
            .flatten()
            .filter(|b| b.len() == nb);
        let Some(bits) = bits else {
            return m;
        };
        let mut k = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                if bits[k / 8] >> (k % 8) & 1 == 1 {
                    m.set(x, y, true);
                }
                k += 1;
            }
        }
        m
    }

    /// Decodes frame `i` into a renderer patch (box-sized RGB + mask), reusing its storage.
    /// Version 2 hands the frame to the store's decoding thread, which decodes from the frame's
    /// group start unless it is already there (the next frame in playback order) or the frame
    /// is cached, and then goes on to the frame after it while the caller converts and renders
    /// this one. Panics when `i >= len()`; an error is a damaged access unit.
    pub fn decode_into(&self, i: usize, patch: &mut vt_core::render::ObjectPatch) -> Result<()> {
        let Some(codec) = &self.codec else {
            self.raw_frame(i).decode_into(patch);
            return Ok(());
        };
        let (x0, y0, x1, y1) = self.raw_bbox(i);
        if x1 == x0 || y1 == y0 {
            patch.reset(x0, y0, x1 - x0, y1 - y0);
            return Ok(());
        }
        // Every byte of the box is written below: sized, not zeroed first.
        let n = (x1 - x0) as usize * (y1 - y0) as usize;
        (patch.x0, patch.y0, patch.width, patch.height) = (x0, y0, x1 - x0, y1 - y0);
        patch.rgb.resize(3 * n, 0);
        patch.mask.resize(n, 0);
        // The mask, while the thread decodes the picture.
        let planes = self.request(codec, i)?;
        let mut scratch = codec.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let (bits, record) = &mut *scratch;
        let nb = n.div_ceil(8);
        bits.resize(nb, 0);
        let range = self.index.parts_v2(i).0;
        let inflated = self
            .bytes
            .with(range.start, range.len(), record, |deflated| {
                miniz_oxide::inflate::decompress_slice_iter_to_slice(
                    bits,
                    std::iter::once(deflated),
                    false,
                    true,
                )
            })
            .ok();
        if inflated != Some(Ok(nb)) {
            return Err(self.damaged(i, "mask"));
        }
        let planes = planes.wait()?;
        let (pw, ph) = padded_size(self.width, self.height);
        let (y_plane, chroma) = planes.split_at(pw * ph);
        let (u_plane, v_plane) = chroma.split_at(pw * ph / 4);
        let (bw, x0) = ((x1 - x0) as usize, x0 as usize);
        // The box's bits, LSB first, as one byte per pixel.
        for (m, &bits) in patch.mask.chunks_mut(8).zip(bits.iter()) {
            for (j, m) in m.iter_mut().enumerate() {
                *m = bits >> j & 1;
            }
        }
        // [`rgb_to_yuv420`]'s inverse, row by row (RGB 0 where the mask is).
        for (r, (mask, rgb)) in patch
            .mask
            .chunks_exact(bw)
            .zip(patch.rgb.chunks_exact_mut(3 * bw))
            .enumerate()
        {
            let y = y0 as usize + r;
            let c_row = (y / 2) * (pw / 2) + x0 / 2;
            let nc = (bw + x0 % 2).div_ceil(2);
            vt_core::yuv::masked_full_range_row_to_rgb(
                &y_plane[y * pw + x0..y * pw + x0 + bw],
                &u_plane[c_row..c_row + nc],
                &v_plane[c_row..c_row + nc],
                x0 % 2 == 1,
                mask,
                rgb,
            );
        }
        Ok(())
    }

    /// Asks the decoding thread for frame `i` (and the one after it), starting the thread on
    /// the first call.
    fn request<'a>(&'a self, codec: &'a Decoding, i: usize) -> Result<Pending<'a>> {
        let mut worker = codec.worker.lock().unwrap_or_else(|e| e.into_inner());
        if worker.is_none() {
            let w = Worker {
                bytes: self.bytes.clone(),
                index: self.index.clone(),
                shared: codec.shared.clone(),
                gop: codec.gop,
                size: padded_size(self.width, self.height),
                decoder: None,
                next: None,
                unit: Vec::new(),
            };
            let handle = std::thread::Builder::new()
                .name("vt-store-decode".into())
                .spawn(move || w.run())
                .map_err(|e| Error::io(&self.path, e))?;
            *worker = Some(handle);
        }
        drop(worker);
        let mut q = codec.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
        if q.failed
            .is_some_and(|(g, _)| g / codec.gop != i / codec.gop)
        {
            // A damaged frame elsewhere does not stop this group.
            q.failed = None;
        }
        q.wants.push(i);
        q.ahead = (i + 1 < self.len()).then_some(i + 1);
        drop(q);
        codec.shared.changed.notify_all();
        Ok(Pending {
            store: self,
            codec,
            frame: i,
        })
    }

    fn damaged(&self, i: usize, what: &str) -> Error {
        Error::Scene {
            path: self.path.clone(),
            message: format!("corrupted: frame {i}'s {what} does not decode"),
        }
    }
}

/// A frame asked of the decoding thread.
struct Pending<'a> {
    store: &'a ObjectStore,
    codec: &'a Decoding,
    frame: usize,
}

impl Pending<'_> {
    /// The frame's planes, once decoded.
    fn wait(&self) -> Result<std::sync::Arc<Vec<u8>>> {
        let (shared, i) = (&self.codec.shared, self.frame);
        let mut q = shared.queue.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            let done = if let Some(planes) = q.cached(i) {
                Ok(planes.clone())
            } else if let Some((g, what)) = q.blocked(i, self.codec.gop) {
                q.ahead = None;
                Err(self.store.damaged(g, what))
            } else if q.stop {
                Err(self
                    .store
                    .damaged(i, "picture (the decoding thread stopped)"))
            } else {
                q = shared.changed.wait(q).unwrap_or_else(|e| e.into_inner());
                continue;
            };
            return done;
        }
    }
}

impl Drop for Pending<'_> {
    /// No longer waited for, whether it came or not.
    fn drop(&mut self) {
        let mut q = self
            .codec
            .shared
            .queue
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(at) = q.wants.iter().position(|&w| w == self.frame) {
            q.wants.swap_remove(at);
        }
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

/// An analysis observer that writes each view's moving-object store (`objects_NNN.bin`) into a
/// scene directory as its masks arrive, one view at a time: what `vt analyze` keeps of every
/// frame. Call [`StoreWriter::finish`] after the analysis to close the last store.
pub struct StoreWriter {
    dir: PathBuf,
    quality: StoreQuality,
    writer: Option<(usize, ObjectWriter)>,
}

impl StoreWriter {
    /// Writes stores at the default quality into `dir` (usually a scene's temporary directory).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self::with_quality(dir, StoreQuality::default())
    }

    /// Writes stores at `quality` into `dir`.
    pub fn with_quality(dir: impl Into<PathBuf>, quality: StoreQuality) -> Self {
        Self {
            dir: dir.into(),
            quality,
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
                ObjectWriter::create_with(&path, raw.width(), raw.height(), self.quality)
                    .map_err(to_core)?,
            ));
        }
        let (_, w) = self.writer.as_mut().expect("set above");
        w.push(mask, raw).map_err(to_core)
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

    /// A moving, textured scene: smooth shading, a sinusoidal texture drifting right and a
    /// disc whose mask moves with it (frames of a real camera are smoother than noise).
    fn moving_frames(w: u32, h: u32, n: usize) -> Vec<(Mask, RgbImage)> {
        (0..n)
            .map(|f| {
                let t = f as f32;
                let raw = RgbImage::from_fn(w, h, |x, y| {
                    let (xf, yf) = (x as f32 - 1.5 * t, y as f32);
                    let v = (xf * 0.21).sin() * (yf * 0.17).cos();
                    image::Rgb([
                        (128.0 + 90.0 * v) as u8,
                        (64.0 + yf * 0.5 + 40.0 * v) as u8,
                        (200.0 - xf.abs() * 0.3).clamp(0.0, 255.0) as u8,
                    ])
                });
                let (cx, cy) = (10.0 + 2.0 * t, h as f32 / 2.0);
                let mask = Mask::from_fn(w, h, |x, y| {
                    let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                    dx * dx + dy * dy < 150.0 || (f % 5 == 0 && x < 3)
                });
                (mask, raw)
            })
            .collect()
    }

    fn write(path: &Path, frames: &[(Mask, RgbImage)], quality: StoreQuality) {
        let (w, h) = frames[0].1.dimensions();
        let mut writer = ObjectWriter::create_with(path, w, h, quality).unwrap();
        for (m, raw) in frames {
            writer.push(m, raw).unwrap();
        }
        writer.finish().unwrap();
    }

    /// The patch's pixels as (x, y, rgb), for comparing decodes.
    fn patch_pixels(p: &vt_core::render::ObjectPatch) -> Vec<(u32, u32, [u8; 3])> {
        let mut v = Vec::new();
        for k in 0..(p.width * p.height) as usize {
            if p.mask[k] == 1 {
                let (x, y) = (p.x0 + k as u32 % p.width, p.y0 + k as u32 / p.width);
                v.push((x, y, [p.rgb[3 * k], p.rgb[3 * k + 1], p.rgb[3 * k + 2]]));
            }
        }
        v
    }

    #[test]
    fn both_versions_keep_the_masks_lossless_keeps_the_pixels() {
        let dir = tempfile::tempdir().unwrap();
        // Odd sides: version 2 pads its pictures.
        let frames = moving_frames(67, 41, 21);
        for quality in [StoreQuality::Lossless, StoreQuality::default()] {
            let path = dir.path().join(format!("o_{quality}.bin"));
            write(&path, &frames, quality);
            let store = ObjectStore::load(&path).unwrap();
            assert_eq!(store.quality(), quality);
            assert_eq!((store.len(), store.size()), (21, (67, 41)));
            let mut patch = vt_core::render::ObjectPatch::default();
            let (mut se, mut count) = (0.0f64, 0usize);
            for (i, (m, raw)) in frames.iter().enumerate() {
                assert_eq!(&store.mask(i), m, "{quality}: frame {i}'s mask");
                store.decode_into(i, &mut patch).unwrap();
                let pixels = patch_pixels(&patch);
                assert_eq!(pixels.len() as u64, m.count_ones(), "{quality}: frame {i}");
                for (x, y, c) in pixels {
                    assert!(m.get(x, y));
                    let want = raw.get_pixel(x, y).0;
                    if quality == StoreQuality::Lossless {
                        assert_eq!(c, want, "frame {i} at ({x}, {y})");
                    }
                    for k in 0..3 {
                        se += (c[k] as f64 - want[k] as f64).powi(2);
                    }
                    count += 3;
                }
            }
            // A floor only: this texture is harder than camera frames (saturated colour edges
            // that 4:2:0 blurs); tests/store_quality.rs holds real footage to 40 dB.
            let psnr = 10.0 * (255.0f64 * 255.0 / (se / count as f64).max(1e-12)).log10();
            assert!(
                psnr >= 37.0,
                "{quality}: {psnr:.2} dB against the raw frames"
            );
        }
    }

    #[test]
    fn both_encoders_store_frames_smaller_than_a_macroblock() {
        // 9x5: padded to 16x16 for the encoder, cropped back when decoded.
        let frames = moving_frames(9, 5, 11);
        let dir = tempfile::tempdir().unwrap();
        for encoder in [H264Encoder::OpenH264, H264Encoder::X264] {
            if encoder == H264Encoder::X264 && !x264_available() {
                continue;
            }
            let path = dir.path().join(format!("o_{encoder:?}.bin"));
            let mut w =
                ObjectWriter::create_with_encoder(&path, 9, 5, StoreQuality::default(), encoder)
                    .unwrap();
            for (m, raw) in &frames {
                w.push(m, raw).unwrap();
            }
            assert_eq!(w.len(), 11);
            w.finish().unwrap();
            let store = ObjectStore::load(&path).unwrap();
            let mut patch = vt_core::render::ObjectPatch::default();
            for (i, (m, raw)) in frames.iter().enumerate().rev() {
                store.decode_into(i, &mut patch).unwrap();
                let pixels = patch_pixels(&patch);
                assert_eq!(pixels.len() as u64, m.count_ones(), "{encoder:?} frame {i}");
                for (x, y, c) in pixels {
                    let want = raw.get_pixel(x, y).0;
                    for k in 0..3 {
                        assert!(c[k].abs_diff(want[k]) < 40, "{encoder:?} {i} ({x}, {y})");
                    }
                }
            }
        }
    }

    #[test]
    fn random_access_equals_sequential_decoding() {
        for encoder in [H264Encoder::OpenH264, H264Encoder::X264] {
            if encoder == H264Encoder::X264 && !x264_available() {
                println!("x264 skipped: ffmpeg with libx264 is not installed");
                continue;
            }
            random_access_with(encoder);
        }
    }

    fn random_access_with(encoder: H264Encoder) {
        let dir = tempfile::tempdir().unwrap();
        let frames = moving_frames(48, 32, 29);
        let path = dir.path().join("o.bin");
        let mut writer =
            ObjectWriter::create_with_encoder(&path, 48, 32, StoreQuality::default(), encoder)
                .unwrap();
        for (m, raw) in &frames {
            writer.push(m, raw).unwrap();
        }
        writer.finish().unwrap();
        let store = ObjectStore::load(&path).unwrap();
        assert_eq!(store.len(), frames.len(), "{encoder:?}");
        // Every group starts with an IDR picture and its parameter sets (NAL types 7, 8, 5),
        // the other frames are P pictures (type 1): the groups decode on their own.
        for i in 0..frames.len() {
            let unit = store.bytes.with(
                store.index.parts_v2(i).1.start,
                store.index.parts_v2(i).1.len(),
                &mut Vec::new(),
                |u| {
                    let mut types = Vec::new();
                    for k in 0..u.len().saturating_sub(3) {
                        if u[k..k + 3] == [0, 0, 1] {
                            types.push(u[k + 3] & 0x1f);
                        }
                    }
                    types
                },
            );
            let types = unit.unwrap();
            let picture: Vec<u8> = types
                .iter()
                .copied()
                .filter(|&t| t == 1 || t == 5)
                .collect();
            if i % GOP as usize == 0 {
                assert!(
                    types.contains(&7) && types.contains(&8),
                    "{encoder:?} {i}: {types:?}"
                );
                assert_eq!(picture, [5], "{encoder:?} frame {i}: {types:?}");
            } else {
                assert_eq!(picture, [1], "{encoder:?} frame {i}: {types:?}");
            }
            assert!(
                !types.contains(&9),
                "{encoder:?} frame {i}: a delimiter left"
            );
        }
        drop(store);
        let decode = |store: &ObjectStore, i: usize| {
            let mut patch = vt_core::render::ObjectPatch::default();
            store.decode_into(i, &mut patch).unwrap();
            patch_pixels(&patch)
        };
        let sequential: Vec<_> = {
            let store = ObjectStore::load(&path).unwrap();
            (0..frames.len()).map(|i| decode(&store, i)).collect()
        };
        // Jumps both ways, within and across groups, repeats, loop wraps; each on a fresh store
        // and on one that has decoded other frames before.
        let order = [28, 3, 4, 17, 9, 9, 0, 27, 8, 7, 16, 15, 24, 1, 28, 5];
        let shared = ObjectStore::load(&path).unwrap();
        for &i in &order {
            assert_eq!(decode(&shared, i), sequential[i], "frame {i} after jumps");
            let fresh = ObjectStore::load(&path).unwrap();
            assert_eq!(decode(&fresh, i), sequential[i], "frame {i} alone");
        }
        // Near the frames themselves (the real-footage bound of 40 dB is in tests/store_quality;
        // this tiny pattern with saturated colours gets 39 dB from openh264).
        let (mut se, mut count) = (0f64, 0f64);
        for (i, (_, raw)) in frames.iter().enumerate() {
            for (x, y, c) in &sequential[i] {
                let want = raw.get_pixel(*x, *y).0;
                for k in 0..3 {
                    se += (c[k] as f64 - want[k] as f64).powi(2);
                    count += 1.0;
                }
            }
        }
        let psnr = 10.0 * (255.0f64.powi(2) / (se / count).max(1e-12)).log10();
        assert!(psnr > 35.0, "{encoder:?}: {psnr:.2} dB");
    }

    #[test]
    fn yuv_conversion_is_the_full_range_matrix() {
        // Every level within one of the exact matrix, rounded (corners of the cube included).
        let (w, h) = (10usize, 6usize);
        let mut rng = vt_core::rng::Rng::new(7);
        let mut rgb: Vec<u8> = (0..3 * w * h).map(|_| rng.next_u64() as u8).collect();
        rgb[..6].copy_from_slice(&[255, 255, 255, 0, 0, 0]);
        rgb[3 * w..3 * w + 6].copy_from_slice(&[255, 0, 0, 0, 0, 255]);
        let mut out = Vec::new();
        rgb_to_yuv420(&rgb, w, h, &mut out);
        assert_eq!(out.len(), w * h * 3 / 2);
        let near = |got: u8, want: f64, what: &str| {
            assert!(
                (got as f64 - want.clamp(0.0, 255.0)).abs() <= 1.0,
                "{what}: {got} vs {want}"
            );
        };
        for i in 0..w * h {
            let p = &rgb[3 * i..3 * i + 3];
            let y = 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64;
            near(out[i], y, &format!("Y {i}"));
        }
        for cy in 0..h / 2 {
            for cx in 0..w / 2 {
                let mut m = [0f64; 3];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    for k in 0..3 {
                        m[k] += 0.25 * rgb[3 * ((2 * cy + dy) * w + 2 * cx + dx) + k] as f64;
                    }
                }
                let u = 128.0 - 0.168_736 * m[0] - 0.331_264 * m[1] + 0.5 * m[2];
                let v = 128.0 + 0.5 * m[0] - 0.418_688 * m[1] - 0.081_312 * m[2];
                let c = cy * w / 2 + cx;
                near(out[w * h + c], u, &format!("U {c}"));
                near(out[w * h + w * h / 4 + c], v, &format!("V {c}"));
            }
        }
    }

    #[test]
    fn access_units_split_at_their_delimiters() {
        // Two units behind delimiters (4- and 3-byte start codes), split across reads.
        let stream: Vec<u8> = [
            &[0, 0, 0, 1, 9, 0x10][..],
            &[0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x65, 3, 4],
            &[0, 0, 1, 9, 0x30],
            &[0, 0, 1, 0x41, 5, 6, 0],
        ]
        .concat();
        let mut units = Vec::new();
        let mut buf = Vec::new();
        for (k, part) in stream.chunks(4).enumerate() {
            buf.extend_from_slice(part);
            let end = (k + 1) * 4 >= stream.len();
            assert!(split_units(&mut buf, end, |u| {
                units.push(u);
                true
            }));
        }
        assert_eq!(
            units,
            vec![
                vec![0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x65, 3, 4],
                vec![0, 0, 1, 0x41, 5, 6, 0]
            ]
        );
        assert!(buf.is_empty());
    }

    #[test]
    fn version_2_reads_records_on_demand_from_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let frames = moving_frames(48, 32, 20);
        let path = dir.path().join("o.bin");
        write(&path, &frames, StoreQuality::default());
        let bytes = std::fs::read(&path).unwrap();
        let memory = ObjectStore::from_bytes(bytes.clone(), &path).unwrap();
        let file = ObjectStore::load(&path).unwrap();
        assert_eq!(file.byte_len(), bytes.len());
        let (mut a, mut b) = Default::default();
        // From the file: the same frames as from memory, from several threads at once.
        std::thread::scope(|s| {
            for t in 0..3 {
                let file = &file;
                s.spawn(move || {
                    let mut patch = vt_core::render::ObjectPatch::default();
                    for i in (t..20).chain((0..20).rev()) {
                        file.decode_into(i, &mut patch).unwrap();
                    }
                });
            }
        });
        for i in [0, 1, 2, 13, 7, 19, 8] {
            memory.decode_into(i, &mut a).unwrap();
            file.decode_into(i, &mut b).unwrap();
            assert_eq!(patch_pixels(&a), patch_pixels(&b), "frame {i}");
            assert_eq!(memory.mask(i), file.mask(i), "frame {i}");
        }
        // A file cut short after loading: an error naming it, not a panic.
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let fresh = ObjectStore::from_bytes(bytes, &path).unwrap();
        drop(fresh);
        let err = (0..20)
            .rev()
            .find_map(|i| file.decode_into(i, &mut b).err())
            .expect("the cut frames fail");
        assert!(err.to_string().contains("o.bin"), "{err}");
    }

    #[test]
    fn other_versions_are_refused_with_what_to_do() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.bin");
        write(&path, &moving_frames(16, 16, 3), StoreQuality::default());
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[5] = b'9';
        let err = ObjectStore::from_bytes(bytes, &path)
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("version '9'") && err.contains("run vt analyze again"),
            "{err}"
        );
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
                .unwrap()
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
