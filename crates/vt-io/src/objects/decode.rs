//! Version 2's decoding thread, its queue and its cache of decoded frames.

use super::*;

/// Version 2's reading side: the decoding thread (started on the first decode) and what it
/// shares with the callers.
pub(super) struct Decoding {
    pub(super) gop: usize,
    pub(super) qp: u8,
    pub(super) shared: std::sync::Arc<Shared>,
    pub(super) worker: std::sync::Mutex<Option<std::thread::JoinHandle<()>>>,
    /// The mask bits of the box being decoded, and a record's bytes read from the file (reused).
    pub(super) scratch: std::sync::Mutex<(Vec<u8>, Vec<u8>)>,
}

/// What the decoding thread and the callers share.
pub(super) struct Shared {
    pub(super) queue: std::sync::Mutex<Queue>,
    pub(super) changed: std::sync::Condvar,
}

/// The decoding thread's requests and results.
#[derive(Default)]
pub(super) struct Queue {
    /// The frames callers wait for.
    pub(super) wants: Vec<usize>,
    /// The frame to decode when no caller waits (the one after the last asked for).
    pub(super) ahead: Option<usize>,
    /// Recently decoded frames as 4:2:0 planes of the padded size, oldest first (at most a
    /// group and three).
    cache: std::collections::VecDeque<(usize, std::sync::Arc<Vec<u8>>)>,
    /// Buffers of frames dropped from the cache, for the next ones.
    spare: Vec<Vec<u8>>,
    /// A frame that did not decode, and what of it.
    pub(super) failed: Option<(usize, &'static str)>,
    /// Set when the store is dropped, or by the thread when it ends.
    pub(super) stop: bool,
    /// Decoders started so far.
    pub(super) decoders: usize,
}

impl Queue {
    pub(super) fn cached(&self, f: usize) -> Option<&std::sync::Arc<Vec<u8>>> {
        self.cache.iter().find(|(g, _)| *g == f).map(|(_, b)| b)
    }

    /// The frame (and what of it) that did not decode on the way to `f`: `f` or one before it
    /// in its group.
    pub(super) fn blocked(&self, f: usize, gop: usize) -> Option<(usize, &'static str)> {
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

/// One decoder and where it stands.
#[derive(Default)]
struct Cursor {
    decoder: Option<openh264::decoder::Decoder>,
    /// The frame the decoder would output next if fed the next access unit (its references are
    /// those of the frame before); None when it holds nothing usable.
    next: Option<usize>,
    /// When it last decoded (the worker's count of runs).
    used: u64,
}

/// Decoders a store keeps: a player reads two runs of frames of one view at once during a
/// switch fade at a fractional viewpoint (the view's own frames, and the ones it fills in for
/// its neighbour with), and each run goes on from its own decoder instead of restarting its group
/// whenever the other was read. The second starts only when runs are seen to interleave (a run
/// comes back to where the other took its decoder from): at 1080p a decoder holds about 25 MB.
const CURSORS: usize = 2;

/// The decoding thread's own state: its decoders and where they stand.
pub(super) struct Worker {
    bytes: std::sync::Arc<Bytes>,
    index: std::sync::Arc<Index>,
    shared: std::sync::Arc<Shared>,
    gop: usize,
    size: (usize, usize),
    cursors: [Cursor; CURSORS],
    /// Where the last restarted decoder stood before (the frame it would have output next).
    abandoned: Option<usize>,
    /// Runs of [`Worker::decode_to`] so far.
    runs: u64,
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
    /// A decoding thread's state for a store's bytes and index, pictures of `size` (padded).
    pub(super) fn new(
        bytes: std::sync::Arc<Bytes>,
        index: std::sync::Arc<Index>,
        shared: std::sync::Arc<Shared>,
        gop: usize,
        size: (usize, usize),
    ) -> Self {
        Self {
            bytes,
            index,
            shared,
            gop,
            size,
            cursors: Default::default(),
            abandoned: None,
            runs: 0,
            unit: Vec::new(),
        }
    }
    pub(super) fn run(mut self) {
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

    /// Decodes frame `f` into the cache: on from where a decoder stands when that is in `f`'s
    /// group at or before `f`, else from the group's start with the started decoder used least
    /// recently, or a new one when `f` lies past where the last restart took a decoder from in
    /// its group (two runs interleave).
    /// Stops early when a caller comes to wait for a frame this run will not reach.
    fn decode_to(&mut self, f: usize) {
        let group_start = f - f % self.gop;
        let going = self.cursors.iter().position(|c| {
            c.decoder.is_some() && c.next.is_some_and(|n| (group_start..=f).contains(&n))
        });
        let (k, from) = match going {
            Some(k) => (k, self.cursors[k].next.expect("checked")),
            None => {
                let interleaved = self
                    .abandoned
                    .is_some_and(|n| (group_start..=f).contains(&n));
                let started = |k: &usize| self.cursors[*k].decoder.is_some();
                let any_started = (0..CURSORS).any(|k| started(&k));
                let k = (0..CURSORS)
                    .filter(|k| interleaved || !any_started || started(k))
                    .min_by_key(|&k| self.cursors[k].used)
                    .expect("cursors");
                self.abandoned = self.cursors[k].next;
                (k, group_start)
            }
        };
        self.runs += 1;
        self.cursors[k].used = self.runs;
        self.cursors[k].next = None;
        for g in from..=f {
            let mut buf = {
                let mut q = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
                q.spare.pop().unwrap_or_default()
            };
            if let Err(what) = self.decode_one(k, g, &mut buf) {
                self.cursors[k].decoder = None;
                let mut q = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
                q.failed = Some((g, what));
                drop(q);
                self.shared.changed.notify_all();
                return;
            }
            self.cursors[k].next = Some(g + 1);
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

    /// Decodes record `g`'s access unit with decoder `k` into `out`: its planes without the
    /// strides' padding.
    fn decode_one(
        &mut self,
        k: usize,
        g: usize,
        out: &mut Vec<u8>,
    ) -> std::result::Result<(), &'static str> {
        let range = self.index.parts_v2(g).1;
        let mut unit = std::mem::take(&mut self.unit);
        let bytes = self.bytes.clone();
        let result = bytes
            .with(range.start, range.len(), &mut unit, |unit| {
                self.decode_unit(k, unit, out)
            })
            .map_err(|_| "frame")
            .and_then(|r| r);
        self.unit = unit;
        result
    }

    fn decode_unit(
        &mut self,
        k: usize,
        unit: &[u8],
        out: &mut Vec<u8>,
    ) -> std::result::Result<(), &'static str> {
        let decoder = &mut self.cursors[k].decoder;
        if decoder.is_none() {
            *decoder = Some(openh264::decoder::Decoder::new().map_err(|_| "frame")?);
            let mut q = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
            q.decoders += 1;
        }
        let dec = decoder.as_mut().expect("set above");
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
