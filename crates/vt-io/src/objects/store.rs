//! Reading a store: the file's index, the records, and the frames on request.

use super::*;

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
    pub(super) bytes: std::sync::Arc<Bytes>,
    pub(super) index: std::sync::Arc<Index>,
    /// Version 2's decoder; None for version 1.
    codec: Option<Decoding>,
}

/// Where a store's bytes are.
pub(super) enum Bytes {
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
    pub(super) fn with<R>(
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
pub(super) struct Index {
    /// Byte offset of each record, and where the table starts.
    offsets: Vec<u64>,
    /// Version 2's record heads (box and deflated mask length), read once; empty in version 1.
    heads: Vec<((u32, u32, u32, u32), u32)>,
}

impl Index {
    /// Version 2's record `i`: its deflated mask's bytes and its access unit's, as ranges.
    pub(super) fn parts_v2(&self, i: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
        let (start, end) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        let mask_end = start + RECORD_HEAD_V2 + self.heads[i].1 as usize;
        (start + RECORD_HEAD_V2..mask_end, mask_end..end)
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
        // [`vt_core::yuv::rgb_to_full_range_yuv420`]'s inverse, row by row (RGB 0 where the mask is).
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
    /// Decoders the store's thread has started (a second only for interleaved runs).
    #[cfg(test)]
    pub(super) fn decoders_started(&self) -> usize {
        self.codec.as_ref().map_or(0, |c| {
            let q = c.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
            q.decoders
        })
    }

    fn request<'a>(&'a self, codec: &'a Decoding, i: usize) -> Result<Pending<'a>> {
        let mut worker = codec.worker.lock().unwrap_or_else(|e| e.into_inner());
        if worker.is_none() {
            let w = Worker::new(
                self.bytes.clone(),
                self.index.clone(),
                codec.shared.clone(),
                codec.gop,
                padded_size(self.width, self.height),
            );
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
