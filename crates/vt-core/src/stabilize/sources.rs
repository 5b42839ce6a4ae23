//! The frame sources of the still camera: [`Probing`] carries the probe through the analysis's
//! first pass, [`Steady`] hands out the warped, cropped frames.

use image::RgbImage;

use super::*;
use crate::yuv::Yuv420Image;

/// A frame source whose first pass also probes the camera ([`Probe`]): the analysis's first
/// pass carries the measurement, so a still camera costs no decoding of its own, and the probe
/// tracks its frames on a thread of its own while the pass goes on. When the
/// probe finds the camera moving, that pass ends in an error and [`Probing::moved`] is true:
/// the caller measures the clip in full ([`measure`]) and starts again through [`Steady`].
pub struct Probing<'a> {
    source: &'a mut dyn FrameSource,
    probe: Option<Probe>,
    shake: Option<Shake>,
    /// The first pass is over (later passes go straight to the source).
    probed: bool,
    moved: bool,
}

impl<'a> Probing<'a> {
    /// Wraps `source`; with the mode off, frames pass as they are and the shake says so.
    pub fn new(source: &'a mut dyn FrameSource, params: &StabilizeParams) -> Self {
        let off = params.mode == StabilizeMode::Off;
        let shake = off.then(|| Shake::still(source.name(), 0, (0, 0), Verdict::Off, 0.0));
        Self {
            probe: (!off).then(|| Probe::new(params)),
            source,
            shake,
            probed: off,
            moved: false,
        }
    }

    /// Whether the first pass found the camera moving (and so ended in an error).
    pub fn moved(&self) -> bool {
        self.moved
    }

    /// The shake the first pass measured (None before it, or when the camera moved).
    pub fn shake(&mut self) -> Option<Shake> {
        self.shake.take()
    }

    /// Seconds the probe took.
    pub fn secs(&self) -> f64 {
        self.probe.as_ref().map_or(0.0, |p| p.secs)
    }

    fn first(&mut self, n: usize) -> Result<usize> {
        let name = self.source.name().to_string();
        let probe = self.probe.as_mut().expect("probing");
        let t = std::time::Instant::now();
        let verdict = probe.finish(&name, n);
        probe.secs += t.elapsed().as_secs_f64();
        self.probed = true;
        match verdict {
            Probed::Still(shake) => {
                self.shake = Some(shake);
                Ok(n)
            }
            Probed::Moves { motion, .. } => {
                self.moved = true;
                Err(unsteady(
                    &name,
                    format!("the camera moves ({motion:.1} px): measured again to hold it still"),
                ))
            }
        }
    }
}

impl FrameSource for Probing<'_> {
    fn name(&self) -> &str {
        self.source.name()
    }

    fn for_each_frame(
        &mut self,
        f: &mut dyn FnMut(usize, &RgbImage) -> Result<()>,
    ) -> Result<usize> {
        if self.probed {
            return self.source.for_each_frame(f);
        }
        let name = self.source.name().to_string();
        let probe = self.probe.as_mut().expect("probing");
        let source = &mut *self.source;
        let n = carry(probe, &name, |hook| {
            source.for_each_frame(&mut |i, rgb| {
                hook(i, FrameRef::Rgb(rgb));
                f(i, rgb)
            })
        })?;
        self.first(n)
    }

    fn for_each_native(
        &mut self,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        if self.probed {
            return self.source.for_each_native(f);
        }
        let name = self.source.name().to_string();
        let probe = self.probe.as_mut().expect("probing");
        let source = &mut *self.source;
        let n = carry(probe, &name, |hook| {
            source.for_each_native(&mut |i, frame| {
                hook(i, frame);
                f(i, frame)
            })
        })?;
        self.first(n)
    }

    fn for_each_native_to(
        &mut self,
        end: usize,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        if self.probed {
            return self.source.for_each_native_to(end, f);
        }
        // The probe needs the whole clip.
        let n = self.for_each_native(&mut |i, frame| if i < end { f(i, frame) } else { Ok(()) })?;
        Ok(n.min(end))
    }
}

/// Runs `pass` (a decoding pass that calls its hook with every frame before using it) with
/// `probe` tracking the frames it wants on a thread of its own: the pass hands over each such
/// frame's luma proxy (two in flight) and goes on, so the tracking overlaps the pass's own work
/// instead of holding it up. A frame the probe cannot register ends it with that error, which
/// comes first (it is at a frame the pass had reached). On a rayon worker the probe runs inside
/// the pass as before: a worker must not wait on a thread whose tracking needs the pool.
fn carry(
    probe: &mut Probe,
    name: &str,
    pass: impl FnOnce(&mut dyn FnMut(usize, FrameRef<'_>)) -> Result<usize>,
) -> Result<usize> {
    if rayon::current_thread_index().is_some() {
        let mut failed = None;
        let n = pass(&mut |i, frame| {
            if failed.is_none() {
                failed = probe.frame(name, i, frame).err();
            }
        });
        return failed.map_or(n, Err);
    }
    std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<(usize, GrayImage, (u32, u32))>(2);
        let every = probe.params.probe_every;
        let mut factor = None;
        let mut hook = |i: usize, frame: FrameRef<'_>| {
            if probes(i, every) {
                let full = frame.dimensions();
                let f = *factor.get_or_insert_with(|| proxy_factor(full));
                // A probe that stopped (its error is returned below) takes no more.
                let _ = tx.send((i, proxy(frame, f), full));
            }
        };
        let worker = scope.spawn(move || -> Result<()> {
            for (i, g, full) in rx {
                probe.take(name, i, g, full)?;
            }
            Ok(())
        });
        let n = pass(&mut hook);
        drop(tx);
        worker
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e))?;
        n
    })
}

/// A frame source made still: each frame warped by its map (frame pixels to output pixels) into
/// a `size` frame ([`warp_rgb_cubic`], [`warp_yuv420`]); without maps, the source as it is.
pub struct Steady<'a> {
    source: &'a mut dyn FrameSource,
    maps: Option<Vec<Homography>>,
    size: (u32, u32),
}

impl<'a> Steady<'a> {
    /// Wraps `source`; `maps[k]` maps frame k's pixels to the output's (`size`, even). None
    /// passes the frames through.
    pub fn new(
        source: &'a mut dyn FrameSource,
        maps: Option<Vec<Homography>>,
        size: (u32, u32),
    ) -> Self {
        Self { source, maps, size }
    }
}

impl FrameSource for Steady<'_> {
    fn name(&self) -> &str {
        self.source.name()
    }

    fn for_each_frame(
        &mut self,
        f: &mut dyn FnMut(usize, &RgbImage) -> Result<()>,
    ) -> Result<usize> {
        let Some(maps) = &self.maps else {
            return self.source.for_each_frame(f);
        };
        let mut out = RgbImage::new(self.size.0, self.size.1);
        let name = self.source.name().to_string();
        self.source.for_each_frame(&mut |i, frame| {
            let h = maps.get(i).ok_or_else(|| past_end(&name, i, maps.len()))?;
            warp_rgb_cubic(frame, h, &mut out);
            f(i, &out)
        })
    }

    fn for_each_native(
        &mut self,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        self.native(None, f)
    }

    fn for_each_native_to(
        &mut self,
        end: usize,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        self.native(Some(end), f)
    }
}

impl Steady<'_> {
    /// The warped frames in their source's form: every frame, or frames `0..end`.
    fn native(
        &mut self,
        end: Option<usize>,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        let name = self.source.name().to_string();
        let source = &mut *self.source;
        let mut read = |g: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>| match end {
            Some(end) => source.for_each_native_to(end, g),
            None => source.for_each_native(g),
        };
        let Some(maps) = &self.maps else {
            return read(f);
        };
        let size = self.size;
        let mut rgb = RgbImage::new(size.0, size.1);
        let mut yuv: Option<Yuv420Image> = None;
        read(&mut |i, frame| {
            let h = maps.get(i).ok_or_else(|| past_end(&name, i, maps.len()))?;
            match frame {
                FrameRef::Rgb(src) => {
                    warp_rgb_cubic(src, h, &mut rgb);
                    f(i, FrameRef::Rgb(&rgb))
                }
                FrameRef::Yuv420(src) => {
                    let out = match &mut yuv {
                        Some(o) => o,
                        None => {
                            yuv.insert(Yuv420Image::new(size.0, size.1, src.matrix(), src.range())?)
                        }
                    };
                    warp_yuv420(src, h, out);
                    f(i, FrameRef::Yuv420(out))
                }
            }
        })
    }
}

/// The error of a source that gives more frames than were measured.
fn past_end(name: &str, i: usize, n: usize) -> Error {
    unsteady(
        name,
        format!("the source gave frame {i}, past the {n} frames measured"),
    )
}
