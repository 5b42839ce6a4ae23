//! Version 2's encoders: RGB to 4:2:0, x264 in a child process, openh264 in this one.

use super::*;

/// Version 2's encoder state.
pub(super) struct Encoding {
    encoder: openh264::encoder::Encoder,
    /// The frame padded to even sides (reused).
    padded: Vec<u8>,
    /// Its 4:2:0 planes.
    planes: Vec<u8>,
}

impl Encoding {
    pub(super) fn new(qp: u8) -> std::result::Result<Self, openh264::Error> {
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
    pub(super) fn encode(
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
pub(super) struct X264 {
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
pub(super) fn x264_available() -> bool {
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
pub(super) fn split_units(
    buf: &mut Vec<u8>,
    end: bool,
    mut unit: impl FnMut(Vec<u8>) -> bool,
) -> bool {
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

/// ffmpeg's output options for the stores' x264 encoding at quantiser `qp`, as the encoder
/// uses them (and `vt-bench`'s floor, the same encoding of a whole video).
pub fn x264_args(qp: u8) -> Vec<String> {
    let gop = GOP.to_string();
    [
        "-an",
        "-c:v",
        "libx264",
        "-preset",
        "ultrafast",
        "-profile:v",
        "baseline",
        "-pix_fmt",
        "yuv420p",
        "-threads",
        "1",
        "-qp",
        &qp.to_string(),
        "-g",
        &gop,
        "-keyint_min",
        &gop,
        "-sc_threshold",
        "0",
        "-bf",
        "0",
        "-x264-params",
        "aud=1:repeat-headers=1:scenecut=0:ipratio=1",
    ]
    .map(String::from)
    .to_vec()
}

impl X264 {
    pub(super) fn new(qp: u8, width: usize, height: usize) -> std::io::Result<Self> {
        use std::process::{Command, Stdio};
        let mut child = Command::new("ffmpeg")
            .args([
                "-v", "error", "-nostdin", "-f", "rawvideo", "-pix_fmt", "yuv420p",
            ])
            .args(["-s", &format!("{width}x{height}"), "-r", "25", "-i", "-"])
            .args(x264_args(qp))
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
    pub(super) fn send(&mut self, raw: &RgbImage) -> std::result::Result<(), String> {
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
    pub(super) fn units(&mut self, end: bool) -> std::result::Result<Vec<Vec<u8>>, String> {
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
        vt_core::yuv::rgb_to_full_range_yuv420(src, pw, ph, planes);
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
    vt_core::yuv::rgb_to_full_range_yuv420(padded, pw, ph, planes);
}
