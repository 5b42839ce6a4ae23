//! Writing a store frame by frame, and the analysis observer that writes one per view.

use super::*;

/// Where a store's bytes go: its file, or memory (a probe's trial store).
enum Sink {
    File(std::fs::File),
    Memory(std::io::Cursor<Vec<u8>>),
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Sink::File(f) => f.write(buf),
            Sink::Memory(m) => m.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Sink::File(f) => f.flush(),
            Sink::Memory(m) => m.flush(),
        }
    }
}

impl std::io::Seek for Sink {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        match self {
            Sink::File(f) => f.seek(to),
            Sink::Memory(m) => m.seek(to),
        }
    }
}

/// What a quality target chose for a store ([`StoreQuality::Target`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetChoice {
    /// The target, dB.
    pub target_db: u8,
    /// The quantiser chosen.
    pub qp: u8,
    /// The PSNR predicted at it under the masks, dB (below the target where even the finest
    /// quantiser is predicted to fall short).
    pub predicted_db: f64,
}

/// The first group of a store at a quality target, held until its quantiser is chosen.
struct Probe {
    db: u8,
    encoder: H264Encoder,
    frames: Vec<(Mask, RgbImage)>,
}

/// Writes a store frame by frame.
pub struct ObjectWriter {
    path: PathBuf,
    out: BufWriter<Sink>,
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
    /// A quality target's first group, until its quantiser is chosen.
    probe: Option<Probe>,
    /// What the quality target chose, once it has.
    choice: Option<TargetChoice>,
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
        let (encoding, probe) = match quality {
            StoreQuality::Lossless => (None, None),
            StoreQuality::H264 { qp } => {
                (Some(open_encoder(path, width, height, qp, encoder)?), None)
            }
            StoreQuality::Target { db } => (
                None,
                Some(Probe {
                    db,
                    encoder,
                    frames: Vec::new(),
                }),
            ),
        };
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        Self::start(
            path.to_path_buf(),
            Sink::File(file),
            (width, height),
            quality,
            encoding,
            probe,
        )
    }

    /// A store at the fixed quantiser `qp` in memory, encoded by `encoder`: a probe's trial.
    fn in_memory(width: u32, height: u32, qp: u8, encoder: H264Encoder) -> Result<Self> {
        let path = PathBuf::from("(probe)");
        let encoding = Some(open_encoder(&path, width, height, qp, encoder)?);
        let memory = Sink::Memory(std::io::Cursor::new(Vec::new()));
        let quality = StoreQuality::H264 { qp };
        Self::start(path, memory, (width, height), quality, encoding, None)
    }

    /// A writer into `sink`, its header written.
    fn start(
        path: PathBuf,
        sink: Sink,
        (width, height): (u32, u32),
        quality: StoreQuality,
        encoding: Option<H264Writer>,
        probe: Option<Probe>,
    ) -> Result<Self> {
        let head = header(width, height, quality);
        let mut out = BufWriter::new(sink);
        out.write_all(&head).map_err(|e| Error::io(&path, e))?;
        Ok(Self {
            path,
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
            probe,
            choice: None,
        })
    }

    /// Chooses the quantiser of a quality target's store from its first group (all of it, or
    /// what came before [`ObjectWriter::finish`]), starts its encoder, records the quantiser in
    /// the header and encodes the group.
    fn settle(&mut self) -> Result<()> {
        let Some(probe) = self.probe.take() else {
            return Ok(());
        };
        let choice = target_qp(self.width, self.height, &probe)?;
        self.choice = Some(choice);
        let qp = choice.qp;
        self.encoding = Some(open_encoder(
            &self.path,
            self.width,
            self.height,
            qp,
            probe.encoder,
        )?);
        use std::io::Seek;
        let io = |e| Error::io(&self.path, e);
        self.out.seek(std::io::SeekFrom::Start(20)).map_err(io)?;
        self.out
            .write_all(&u32::from(qp).to_le_bytes())
            .map_err(io)?;
        self.out.seek(std::io::SeekFrom::End(0)).map_err(io)?;
        for (mask, raw) in &probe.frames {
            self.push_h264(mask, raw)?;
        }
        Ok(())
    }

    /// What the quality target chose (choosing it now from the frames so far when its first
    /// group is not complete); None for a lossless or fixed-quantiser store.
    pub fn target_choice(&mut self) -> Result<Option<TargetChoice>> {
        self.settle()?;
        Ok(self.choice)
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
        if let Some(probe) = self.probe.as_mut() {
            probe.frames.push((mask.clone(), raw.clone()));
            if probe.frames.len() == GOP as usize {
                self.settle()?;
            }
            return Ok(());
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
        self.offsets.len() + self.waiting.len() + self.probe.as_ref().map_or(0, |p| p.frames.len())
    }

    /// True before the first push.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes the offset table and trailer and closes the file.
    pub fn finish(mut self) -> Result<()> {
        self.close()
    }

    /// [`ObjectWriter::finish`] of an in-memory store: its bytes.
    fn finish_bytes(mut self) -> Result<Vec<u8>> {
        self.close()?;
        match self.out.into_inner() {
            Ok(Sink::Memory(m)) => Ok(m.into_inner()),
            _ => Err(Error::Scene {
                path: self.path.clone(),
                message: "not a store in memory".into(),
            }),
        }
    }

    fn close(&mut self) -> Result<()> {
        self.settle()?;
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

/// An analysis observer that writes each view's moving-object store (`objects_NNN.bin`) into a
/// scene directory as its masks arrive, one view at a time: what `vt analyze` keeps of every
/// frame. Call [`StoreWriter::finish`] after the analysis to close the last store.
pub struct StoreWriter {
    dir: PathBuf,
    quality: StoreQuality,
    writer: Option<(usize, ObjectWriter)>,
    /// Per view, what its quality target chose (views finished so far).
    choices: Vec<Option<TargetChoice>>,
    /// The choice of the view being written, from a store of it dropped when it started again.
    carried: Option<TargetChoice>,
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
            choices: Vec::new(),
            carried: None,
        }
    }

    /// Per view, what its quality target chose (None for a lossless or fixed-quantiser
    /// store), for the views whose stores are closed.
    pub fn choices(&self) -> &[Option<TargetChoice>] {
        &self.choices
    }

    /// Closes the last store.
    pub fn finish(&mut self) -> vt_core::Result<()> {
        if let Some((p, mut w)) = self.writer.take() {
            let to_core = |e| vt_core::Error::external(format!("view {p}"), e);
            let choice = w.target_choice().map_err(to_core)?.or(self.carried.take());
            w.finish().map_err(to_core)?;
            if self.choices.len() <= p {
                self.choices.resize(p + 1, None);
            }
            self.choices[p] = choice;
        }
        Ok(())
    }
}

impl vt_core::analysis::Observer for StoreWriter {
    fn object_frame(
        &mut self,
        view: usize,
        frame: usize,
        mask: &Mask,
        raw: &RgbImage,
    ) -> vt_core::Result<()> {
        let to_core = |e: Error| vt_core::Error::external(format!("view {view}"), e);
        // Frame 0 of the view being written: the analysis has started the view again (a
        // handheld view found later restarts every view through the still camera, or a
        // per-region loop's baked frames replace the view's). The unfinished store is dropped
        // and its file made anew.
        // A quality target's choice carries over to the new store (the same footage, steadied
        // or baked): its probe is not run again.
        if frame == 0 && self.writer.as_ref().is_some_and(|(p, _)| *p == view) {
            let dropped = self.writer.take().and_then(|(_, w)| w.choice);
            self.carried = dropped.or(self.carried);
        }
        if self.writer.as_ref().is_none_or(|(p, _)| *p != view) {
            self.finish()?;
            let path = self.dir.join(crate::scene::objects_name(view));
            let quality = match self.carried {
                Some(c) => StoreQuality::H264 { qp: c.qp },
                None => self.quality,
            };
            self.writer = Some((
                view,
                ObjectWriter::create_with(&path, raw.width(), raw.height(), quality)
                    .map_err(to_core)?,
            ));
        }
        let (_, w) = self.writer.as_mut().expect("set above");
        w.push(mask, raw).map_err(to_core)
    }
}

/// A store's header: magic and size, and for version 2 the group length and quantiser (a
/// quality target's is the probe's until [`ObjectWriter::settle`] records its own).
fn header(width: u32, height: u32, quality: StoreQuality) -> Vec<u8> {
    let mut head = Vec::with_capacity(HEADER_V2);
    let qp = match quality {
        StoreQuality::Lossless => None,
        StoreQuality::H264 { qp } => Some(qp.clamp(MIN_QP, 51)),
        StoreQuality::Target { .. } => Some(PROBE_QP),
    };
    head.extend_from_slice(if qp.is_some() { MAGIC_V2 } else { MAGIC });
    head.extend_from_slice(&width.to_le_bytes());
    head.extend_from_slice(&height.to_le_bytes());
    if let Some(qp) = qp {
        head.extend_from_slice(&GOP.to_le_bytes());
        head.extend_from_slice(&u32::from(qp).to_le_bytes());
    }
    head
}

/// Version 2's encoder for `width x height` pictures at quantiser `qp` (clamped to
/// [`MIN_QP`]..=51), made by `encoder`.
fn open_encoder(
    path: &Path,
    width: u32,
    height: u32,
    qp: u8,
    encoder: H264Encoder,
) -> Result<H264Writer> {
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
    Ok(if x264 {
        let (pw, ph) = padded_size(width, height);
        H264Writer::X264(X264::new(qp, pw, ph).map_err(|e| bad(format!("ffmpeg: {e}")))?)
    } else {
        H264Writer::OpenH264(Box::new(Encoding::new(qp).map_err(|e| bad(e.to_string()))?))
    })
}

/// The quantiser a quality target's store probes its first group at.
pub const PROBE_QP: u8 = 16;

/// The largest quantiser [`StoreQuality::Target`] may choose.
pub const MAX_TARGET_QP: u8 = 32;

/// PSNR (dB) a group loses per quantiser step above [`PROBE_QP`], and gains per step below it,
/// as the prediction assumes: the steepest loss and the gentlest gain measured on real footage
/// (tree.avi at 320x240 and upscaled to 768x576, 720p and 1080p, `examples/store_rate`: 0.47
/// to 1.0 dB a step), so the quantiser chosen keeps at least the predicted PSNR.
const LOSS_PER_QP: f64 = 1.0;
const GAIN_PER_QP: f64 = 0.45;

/// Headroom over the target (dB): a clip's frames spread about 0.5 dB around its mean.
const TARGET_MARGIN: f64 = 0.5;

/// PSNR of the probe's frames stored at [`PROBE_QP`] (in memory, by the store's own encoder)
/// against themselves, over the pixels under their masks (all pixels where every mask is
/// empty), from the summed squared error: what the renderer shows of them.
fn probe_psnr(width: u32, height: u32, probe: &Probe) -> Result<f64> {
    let frames = &probe.frames;
    let mut writer = ObjectWriter::in_memory(width, height, PROBE_QP, probe.encoder)?;
    let none = frames.iter().all(|(m, _)| m.bounding_box().is_none());
    let full = Mask::from_fn(width, height, |_, _| true);
    for (mask, raw) in frames {
        writer.push(if none { &full } else { mask }, raw)?;
    }
    let store = ObjectStore::from_bytes(writer.finish_bytes()?, Path::new("(probe)"))?;
    let mut patch = vt_core::render::ObjectPatch::default();
    let (mut se, mut n) = (0f64, 0u64);
    for (i, (_, raw)) in frames.iter().enumerate() {
        store.decode_into(i, &mut patch)?;
        let (bw, src) = (patch.width as usize, raw.as_raw());
        for (k, &m) in patch.mask.iter().enumerate() {
            if m == 0 {
                continue;
            }
            let (x, y) = (patch.x0 as usize + k % bw, patch.y0 as usize + k / bw);
            let at = 3 * (y * width as usize + x);
            for c in 0..3 {
                let d = patch.rgb[3 * k + c] as f64 - src[at + c] as f64;
                se += d * d;
            }
            n += 3;
        }
    }
    let mse = se / n.max(1) as f64;
    Ok(10.0 * (255.0 * 255.0 / mse.max(1e-6)).log10())
}

/// The largest quantiser whose predicted PSNR over the probe's frames (measured at
/// [`PROBE_QP`], then [`LOSS_PER_QP`] lost a step above it and [`GAIN_PER_QP`] gained a step
/// below) is at least the target and [`TARGET_MARGIN`]; [`MIN_QP`] when none is,
/// [`MAX_TARGET_QP`] at most.
fn target_qp(width: u32, height: u32, probe: &Probe) -> Result<TargetChoice> {
    let want = probe.db as f64 + TARGET_MARGIN;
    let measured = if probe.frames.is_empty() {
        want
    } else {
        probe_psnr(width, height, probe)?
    };
    let qp = qp_for(measured, want);
    Ok(TargetChoice {
        target_db: probe.db,
        qp,
        predicted_db: predicted(measured, qp),
    })
}

/// The PSNR predicted at `qp` from `measured` at [`PROBE_QP`].
fn predicted(measured: f64, qp: u8) -> f64 {
    if qp >= PROBE_QP {
        measured - LOSS_PER_QP * (qp - PROBE_QP) as f64
    } else {
        measured + GAIN_PER_QP * (PROBE_QP - qp) as f64
    }
}

/// [`target_qp`]'s choice from the PSNR measured at [`PROBE_QP`].
pub(super) fn qp_for(measured: f64, want: f64) -> u8 {
    (MIN_QP..=MAX_TARGET_QP)
        .rev()
        .find(|&qp| predicted(measured, qp) >= want)
        .unwrap_or(MIN_QP)
}
