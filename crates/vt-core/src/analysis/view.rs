//! One view: pass 1 (median background, noise model, frame cache), pass 2 (masks, loop).

use image::GrayImage;

use super::*;
use crate::regions::Bake;

/// Pass 1's consumers of frames that do not stay in the cache.
pub(super) struct Streamed {
    /// The noise model's sample, in the source's form (4:2:0 video frames: half of RGB).
    noise: Option<FrameSample<Frame>>,
    /// The median's sample (None: every frame), in the source's form.
    median: Option<FrameSample<Frame>>,
    /// The every-frame median, once frames stream.
    all: Option<MedianAccumulator>,
    every_frame: bool,
    /// Conversion buffer.
    rgb: RgbImage,
}

impl Streamed {
    /// Frame `i`, in order; copied only if a sample keeps it, converted to RGB only for the
    /// every-frame median.
    fn take(&mut self, i: usize, frame: FrameRef<'_>) -> Result<()> {
        for s in [&mut self.noise, &mut self.median].into_iter().flatten() {
            s.offer_with(i, || frame.to_owned());
        }
        if self.every_frame {
            let rgb = frame.rgb(&mut self.rgb);
            let (w, h) = rgb.dimensions();
            self.all
                .get_or_insert_with(|| MedianAccumulator::new(w, h))
                .push(rgb)?;
        }
        Ok(())
    }
}

/// The noise model's sample: frames kept as they streamed, or indices into the frame cache.
enum Sample {
    Kept(FrameSample<Frame>),
    Cached(Vec<usize>),
}

pub(super) fn analyze_view(
    p: usize,
    src: &mut dyn FrameSource,
    params: &AnalyzeParams,
    size: &mut Option<(u32, u32)>,
    observer: &mut dyn Observer,
    timings: &mut Timings,
) -> Result<ViewResult> {
    let name = src.name().to_string();
    let label = |extra: &str| format!("view {p} ({name}){extra}");

    // Pass 1: keep frames (in the source's form: 4:2:0 video frames take half the bytes of RGB)
    // while they fit the cache budget. Past it, frames stream: the ones held so far and every
    // later one go to the samples (and, for an every-frame median, a histogram median), and the
    // second pass decodes again. Cached frames are sampled only once the pass is over.
    observer.start(Stage::Background, Some(p), None);
    let every_frame = params.median_frames == 0;
    let mut cache: Option<Vec<Frame>> = Some(Vec::new());
    let mut cached_bytes = 0usize;
    let mut streamed = Streamed {
        noise: params
            .noise
            .enabled()
            .then(|| FrameSample::new(params.noise.sample_frames)),
        median: (!every_frame).then(|| FrameSample::new(params.median_frames)),
        all: None,
        every_frame,
        rgb: RgbImage::new(0, 0),
    };
    let mut inside = Duration::ZERO;
    let t_pass = Instant::now();
    let too_many = |e: Error| match e {
        Error::TooManyFrames { got, max, .. } => Error::TooManyFrames {
            what: label(""),
            got,
            max,
        },
        other => other,
    };
    let n1 = src.for_each_native(&mut |i, frame| {
        let t = Instant::now();
        let dims = frame.dimensions();
        if dims.0 == 0 || dims.1 == 0 {
            return Err(Error::EmptyImage {
                what: label(&format!(" frame {i}")),
                w: dims.0,
                h: dims.1,
            });
        }
        match size {
            None => *size = Some(dims),
            Some(s) if *s != dims && i == 0 => {
                return Err(Error::ViewSizes {
                    first: *s,
                    view: label(""),
                    size: dims,
                })
            }
            Some(s) if *s != dims => return Err(size_err(label(&format!(" frame {i}")), *s, dims)),
            _ => {}
        }
        cached_bytes += frame.byte_len();
        match cache.as_mut() {
            Some(c) if cached_bytes <= params.cache_bytes => c.push(frame.to_owned()),
            _ => {
                if cache.is_some() {
                    // Frames start to stream: the samples are held within the cache's budget,
                    // or the default's when that is larger (at 1080p 4:2:0 about 57 frames for
                    // the median and 28 for the noise model, where frames up to 960x720 get
                    // the 128 and 48 asked for, 4:2:0).
                    let budget = params.cache_bytes.max(DEFAULT_CACHE_MB << 20);
                    let fit = (budget / frame.byte_len().max(1)).max(9);
                    if let Some(s) = streamed.median.as_mut() {
                        *s = FrameSample::new(params.median_frames.min(2 * fit / 3));
                    }
                    if let Some(s) = streamed.noise.as_mut() {
                        *s = FrameSample::new(params.noise.sample_frames.min(fit / 3));
                    }
                }
                for (j, f) in cache.take().unwrap_or_default().into_iter().enumerate() {
                    streamed.take(j, f.as_ref()).map_err(too_many)?;
                }
                streamed.take(i, frame).map_err(too_many)?;
            }
        }
        observer.tick();
        inside += t.elapsed();
        Ok(())
    })?;
    timings.decode += t_pass.elapsed().saturating_sub(inside);
    observer.finish();
    let need = params.loops.window + params.loops.min_length;
    if n1 < need {
        return Err(Error::TooFewFrames {
            what: label(""),
            got: n1,
            need,
            why: format!(
                "a loop needs w + k = {} + {} frames",
                params.loops.window, params.loops.min_length
            ),
        });
    }
    let t = Instant::now();
    let (background, sample) = match &cache {
        // Cached: the median from exactly evenly spaced frames (the middle of each of K equal
        // spans, which a stream of unknown length cannot pick), the noise sample as streamed.
        Some(frames) => {
            let refs: Vec<FrameRef<'_>> = median_frame_indices(frames.len(), params.median_frames)
                .into_iter()
                .map(|i| frames[i].as_ref())
                .collect();
            let background = temporal_median_frames(&refs).map_err(too_many)?;
            // The noise sample: the frames a streamed sample would keep, read from the cache
            // when blurred (no copies).
            let sample = streamed.noise.is_some().then(|| {
                Sample::Cached(FrameSample::indices(
                    frames.len(),
                    params.noise.sample_frames,
                ))
            });
            (background, sample)
        }
        None => {
            let background = match (streamed.median, streamed.all) {
                (Some(s), _) => {
                    let refs: Vec<FrameRef<'_>> = s.frames().iter().map(Frame::as_ref).collect();
                    temporal_median_frames(&refs).map_err(too_many)?
                }
                (None, Some(acc)) => acc.median()?,
                (None, None) => unreachable!("streamed frames go to a sample or the accumulator"),
            };
            (background, streamed.noise.map(Sample::Kept))
        }
    };
    let bg_blur = gaussian_blur(&background, &params.blur)?;
    timings.median += t.elapsed() + inside;
    // The noise model and dynamic region, from the evenly spaced sample.
    let model: Option<NoiseModel> = match sample {
        Some(s) => {
            let t = Instant::now();
            // Each frame blurred and dropped once its differences to the background are made
            // (a byte per pixel: a third of the blurred frame).
            let diff = |f: &RgbImage| -> Result<Vec<u8>> {
                let mut row = Vec::new();
                max_abs_diff(&gaussian_blur(f, &params.blur)?, &bg_blur, &mut row);
                Ok(row)
            };
            let rows: Vec<Vec<u8>> = match s {
                Sample::Kept(s) => s
                    .into_frames()
                    .into_par_iter()
                    .map(|f| diff(f.as_ref().rgb(&mut RgbImage::new(0, 0))))
                    .collect::<Result<_>>()?,
                Sample::Cached(at) => {
                    let frames = cache.as_deref().expect("a cached sample has its cache");
                    at.into_par_iter()
                        .map(|i| diff(frames[i].as_ref().rgb(&mut RgbImage::new(0, 0))))
                        .collect::<Result<_>>()?
                }
            };
            let (w, h) = bg_blur.dimensions();
            let m = noise_model_from_diffs(w, h, &rows, &params.noise)?;
            drop(rows);
            timings.masks += t.elapsed();
            Some(m)
        }
        None => None,
    };
    let thresholds = model
        .as_ref()
        .filter(|_| params.noise.k > 0.0)
        .map(|m| m.thresholds.as_slice());
    let alpha = model.as_ref().and_then(|m| m.alpha.as_ref());
    // What the object store keeps per frame: the mask, plus the dynamic region's alpha support.
    let support = alpha.map(|a| {
        let raw = a.as_raw();
        Mask::from_index_fn(a.width(), a.height(), |i| raw[i] > 0)
    });
    let shown = |m: &Mask| -> Mask {
        match &support {
            Some(s) => m.union(s),
            None => m.clone(),
        }
    };
    let mask_of = |blurred: &RgbImage| -> Result<Mask> {
        match thresholds {
            Some(t) => Ok(noise_mask(blurred, &bg_blur, t)?
                .open(params.mask.open_radius)
                .close(params.mask.close_radius)),
            None => foreground_mask(blurred, &bg_blur, &params.mask),
        }
    };
    let mut kept = MotionKept::new();
    let with_thumbs = params.appearance > 0.0;
    let factor = thumb_factor(bg_blur.width(), bg_blur.height());
    let mut thumbs: Vec<Thumb> = Vec::new();

    // Pass 2: masks. Frames in chunks: each chunk's frames converted, blurred and masked in
    // parallel (one frame per thread, buffers reused) while the previous chunk goes to the
    // observer in order (object store writes, the motion tally) on this thread. The chunks are
    // the frame cache's, which stays for the per-region loop's window; without a cache, the
    // frames decoded once more, a chunk at a time in the source's form.
    observer.start(Stage::Masks, Some(p), Some(n1 as u64));
    let t = Instant::now();
    // A cached view that may get a per-region loop sends its frames to the object store once
    // the loop is settled: the loop's baked frames would replace them, and they are written
    // only when it is not kept (the cache holds them until then either way).
    let defer_store = cache.is_some() && params.regions.is_some();
    let mut masks = Vec::with_capacity(n1);
    let blur = GaussianBlur::new(&params.blur)?;
    let (w, h) = bg_blur.dimensions();
    let threads = rayon::current_num_threads();
    let chunk = match &cache {
        Some(frames) => (4 * threads).max(8).min(frames.len()),
        // Streamed frames are held a chunk at a time beside their RGB and blur buffers (about
        // 10 bytes a pixel each): one frame, computed on the pool while the one before is
        // written (a frame per thread raised the peak at 1080p from 373 to 420 MB, and was no
        // faster on 2 cores).
        None => 1,
    };
    let buffers = || -> Vec<RgbImage> { (0..chunk).map(|_| RgbImage::new(w, h)).collect() };
    let (mut ready, mut spare) = (buffers(), buffers());
    // Blur buffers, one per frame of a chunk (one chunk is computed at a time).
    let mut blurs: Vec<(BlurScratch, RgbImage)> = (0..chunk)
        .map(|_| (BlurScratch::default(), RgbImage::new(w, h)))
        .collect();
    // A chunk's masks (and thumbnails), and the motion tally of its frames' pairs, the first
    // with `prev`, the previous chunk's last frame and mask.
    type Computed = (Vec<(Mask, Option<Thumb>)>, (u64, u64));
    let compute = |part: &[Frame],
                   rgb: &mut Vec<RgbImage>,
                   blurs: &mut Vec<(BlurScratch, RgbImage)>,
                   prev: Option<(&RgbImage, &Mask)>|
     -> Result<Computed> {
        let masks: Vec<(Mask, Option<Thumb>)> = part
            .par_iter()
            .zip(rgb.par_iter_mut())
            .zip(blurs.par_iter_mut())
            .map(|((f, out), (scratch, blurred))| {
                f.as_ref().to_rgb_into(out);
                blur.apply_into(out, blurred, scratch)?;
                let thumb = with_thumbs.then(|| change_thumb(blurred, &bg_blur, factor));
                Ok((mask_of(blurred)?, thumb))
            })
            .collect::<Result<_>>()?;
        let rgb: &[RgbImage] = rgb;
        let change = (0..masks.len())
            .into_par_iter()
            .map(|k| {
                let before = match k {
                    0 => prev,
                    _ => Some((&rgb[k - 1], &masks[k - 1].0)),
                };
                before.map_or((0, 0), |(f0, m0)| {
                    pair_change(f0, m0, &rgb[k], &masks[k].0, &background, alpha)
                })
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        Ok((masks, change))
    };
    // The chunk computed last, waiting to be flushed.
    let mut pending: Vec<(Mask, Option<Thumb>)> = Vec::new();
    let mut i = 0;
    // Computes `part` while the pending chunk is flushed; `part` empty: flushes the last.
    let mut step = |part: &[Frame]| -> Result<()> {
        let last_mask = pending.last().map(|(m, _)| m.clone());
        let prev = pending
            .len()
            .checked_sub(1)
            .map(|k| &ready[k])
            .zip(last_mask.as_ref());
        // The chunk is computed on the thread pool, not on a thread of its own: a thread
        // spawned per chunk gets a malloc arena of its own, and those arenas held 100 MB more
        // over a 600-frame 1080p clip.
        let mut next = None;
        let flushed = rayon::in_place_scope(|scope| {
            scope.spawn(|_| next = Some(compute(part, &mut spare, &mut blurs, prev)));
            let mut flush = || -> Result<()> {
                for ((m, thumb), f) in pending.drain(..).zip(&ready) {
                    if !defer_store {
                        observer.object_frame(p, i, &shown(&m), f)?;
                    }
                    masks.push(m);
                    thumbs.extend(thumb);
                    observer.tick();
                    i += 1;
                }
                Ok(())
            };
            flush()
        });
        flushed?;
        let (next, change) = next.expect("the chunk was computed")?;
        kept.add(change);
        pending = next;
        std::mem::swap(&mut ready, &mut spare);
        Ok(())
    };
    if let Some(frames) = cache.as_deref() {
        for part in frames.chunks(chunk.max(1)) {
            step(part)?;
        }
        step(&[])?;
        timings.masks += t.elapsed();
    } else {
        // The chunk's frames, copied into buffers reused from chunk to chunk.
        let mut batch: Vec<Frame> = Vec::with_capacity(chunk);
        let mut filled = 0;
        let mut inside = Duration::ZERO;
        let t_pass = Instant::now();
        let n2 = src.for_each_native(&mut |i, frame| {
            let t = Instant::now();
            if frame.dimensions() != bg_blur.dimensions() {
                return Err(size_err(
                    label(&format!(" frame {i}")),
                    bg_blur.dimensions(),
                    frame.dimensions(),
                ));
            }
            match batch.get_mut(filled) {
                Some(f) => f.copy_from(frame),
                None => batch.push(frame.to_owned()),
            }
            filled += 1;
            if filled == chunk {
                step(&batch)?;
                filled = 0;
            }
            inside += t.elapsed();
            Ok(())
        })?;
        let t_rest = Instant::now();
        step(&batch[..filled])?;
        step(&[])?;
        drop(batch);
        inside += t_rest.elapsed();
        if n2 != n1 {
            return Err(Error::Source {
                view: label(""),
                message: format!("gave {n1} frames on the first read and {n2} on the second"),
            });
        }
        timings.decode += t_pass.elapsed().saturating_sub(inside);
        timings.masks += inside;
    }
    observer.finish();

    let t = Instant::now();
    observer.start(Stage::Loop, Some(p), None);
    // Eq. (1), with the appearance term in the unit of the masks' ordinary step.
    check_loop_input(masks.len(), &params.loops, &label(""))?;
    crate::mask::check_same_size(&masks, &label(""))?;
    let mut xor_steps: Vec<u64> = masks
        .par_windows(2)
        .map(|w| crate::mask::xor_count(&w[0], &w[1]))
        .collect();
    let mut app_steps: Vec<u64> = thumbs
        .par_windows(2)
        .map(|w| appearance::thumb_cost(&w[0], &w[1], None))
        .collect();
    let mean = |v: &[u64]| v.iter().sum::<u64>() as f64 / v.len().max(1) as f64;
    let mut kappa = appearance::kappa(params.appearance as f64, mean(&xor_steps), mean(&app_steps));
    let mut d = pair_costs(&masks, params.loops.min_length);
    if kappa > 0.0 {
        let app = appearance::loop_pair_costs(&thumbs, params.loops.min_length);
        appearance::combine(&mut d, &app, kappa);
    }
    let mut loops = loops_from_pair_costs(
        &d,
        masks.len(),
        &params.loops,
        1 + params.alternative_loops,
        params.loops.window,
    );
    let alternatives = loops.split_off(1);
    let mut best_loop = loops[0];
    let mut n_frames = n1;
    let mut region_loop = None;
    let mut regions_worse = None;
    let mut thesis_smooth = None;
    let mut regions_over_cache = None;
    if let Some(rp) = params.regions.as_ref() {
        let t_bake = Instant::now();
        // The source window (at most `max_frames`, or the thesis's loop and its neighbours when
        // longer, holding that loop's start): the frame cache's own frames, or decoded once
        // more and packed losslessly within what the cache's budget leaves beside the masks
        // held (the window then ends where the budget does, past the loop's last frame).
        let mut span = rp.max_frames.max(best_loop.len() + 2).min(n1);
        let first = best_loop.start.min(n1 - span);
        let own = crate::regions::Label {
            start: best_loop.start + 1 - first,
            period: best_loop.len(),
        };
        let need = own.start + own.period + 1;
        // Asked only where better, without a frame cache: whether the thesis's loop already
        // wraps as it steps is measured on its frames as they are decoded once more, nothing
        // kept; only a loop whose wraps show has its window packed for the label search.
        let streamed = match (&cache, rp.only_if_better) {
            (None, true) => {
                let dims = (masks[0].width(), masks[0].height());
                let one =
                    crate::regions::single_loop(own, dims, crate::regions::reduction(dims, rp).1);
                let start = first + own.start;
                Some(streamed_wraps(src, dims, &one, start, n1, alpha, &label)?)
            }
            _ => None,
        };
        if let Some(wraps) = streamed.filter(|w| !w.shows()) {
            thesis_smooth = Some(wraps);
        } else {
            let packed = match &cache {
                Some(_) => None,
                None => {
                    let held: usize = masks.iter().map(|m| m.len().div_ceil(64) * 8).sum();
                    let budget = params.cache_bytes.saturating_sub(held);
                    let dims = (masks[0].width(), masks[0].height());
                    // A packed window holds the loop and a few frames past it: the labels' pairwise
                    // costs grow with the square of the window's length. (The label search's own
                    // memory is checked against what the window leaves once the search is asked
                    // for: a loop that already wraps as it steps needs none.)
                    let want = span.min(need + PACKED_SLACK);
                    let (packed, last) = read_window(src, first..first + want, n1, budget, &label)?;
                    if packed.len() < need {
                        // Over the budget: what the loop's frames would take at the rate so far
                        // (the frame left out counted), their label search, and the masks beside
                        // them.
                        let rate = (packed.byte_len() as u64 + last as u64)
                            .div_ceil(packed.len() as u64 + 1);
                        let search = crate::regions::search_bytes(dims, need, rp);
                        regions_over_cache = Some(rate * need as u64 + search as u64 + held as u64);
                        None
                    } else {
                        span = packed.len();
                        // What the budget leaves the label search, and what the view holds
                        // besides.
                        let room = budget.saturating_sub(packed.byte_len());
                        let besides = (packed.byte_len() + held) as u64;
                        Some((packed, room, besides))
                    }
                }
            };
            let window_masks = &masks[first..first + span];
            let window = match (&cache, &packed) {
                (Some(frames), _) => Some(Window::Cached(&frames[first..first + span])),
                (None, Some((packed, _, _))) => Some(Window::Packed(packed)),
                (None, None) => None,
            };
            let room = packed.as_ref().map(|&(_, room, _)| room);
            // What the cache's budget leaves to hold the baked frames for the store: beside the
            // cached frames and the masks, or the packed window (its label search done by then).
            let keep = match (&cache, &packed) {
                (Some(frames), _) => {
                    let held: usize = masks.iter().map(|m| m.len().div_ceil(64) * 8).sum();
                    let cached: usize = frames.iter().map(|f| f.as_ref().byte_len()).sum();
                    params.cache_bytes.saturating_sub(cached + held)
                }
                (None, Some((_, room, _))) => *room,
                (None, None) => 0,
            };
            let made = match &window {
                Some(w) => Some(bake_regions(
                    w,
                    window_masks,
                    own,
                    alpha,
                    rp,
                    params.loops.min_length,
                    room,
                    keep,
                )?),
                None => None,
            };
            if let Some(made) = made {
                let secs = t_bake.elapsed().as_secs_f64();
                match made {
                    Baked::OverCache(search) => {
                        let besides = packed.as_ref().map_or(0, |&(_, _, b)| b);
                        regions_over_cache = Some(besides + search as u64);
                    }
                    Baked::ThesisSmooth(single) => thesis_smooth = Some(single),
                    Baked::Worse(chosen, quality, single) => {
                        regions_worse = Some(RegionResult {
                            chosen,
                            quality,
                            single,
                            secs,
                        })
                    }
                    Baked::Kept(rl, quality, single, held) => {
                        // The player's wrap onto the smoothest step of the cycle; the baked frames
                        // replace the view's frames in the store (its file made anew): the
                        // frames measured, rotated (frame t of the rotated loop is frame
                        // (t + smoothest) mod L of the measured one), or made again.
                        let frames = window.as_ref().expect("made from a window");
                        let bake = held.is_none().then(|| {
                            Bake::new(frames, window_masks, &rl, rp.feather)
                                .rotated(quality.smoothest)
                        });
                        let mut baked_masks = Vec::with_capacity(rl.length + 1);
                        let mut baked_thumbs = Vec::new();
                        let blur = GaussianBlur::new(&params.blur)?;
                        let (mut made, mut blurred) = (RgbImage::new(0, 0), RgbImage::new(0, 0));
                        let mut scratch = BlurScratch::default();
                        for t in 0..=rl.length {
                            let (f, m) = match (&bake, &held) {
                                (Some(bake), _) => {
                                    let m = bake.frame_into(t, &mut made);
                                    (&made, m)
                                }
                                (None, Some(held)) => {
                                    let (f, m) = &held[(t + quality.smoothest) % rl.length];
                                    (f, m.clone())
                                }
                                (None, None) => unreachable!("a bake or the frames held"),
                            };
                            observer.object_frame(p, t, &shown(&m), f)?;
                            if with_thumbs {
                                if blurred.dimensions() != f.dimensions() {
                                    blurred = RgbImage::new(f.width(), f.height());
                                }
                                blur.apply_into(f, &mut blurred, &mut scratch)?;
                                baked_thumbs.push(change_thumb(&blurred, &bg_blur, factor));
                            }
                            baked_masks.push(m);
                        }
                        drop((bake, held));
                        // The loop the stored frames show (as `Bake::rotated` puts its phase).
                        let mut rl = crate::regions::RegionLoop {
                            phase: (rl.phase + quality.smoothest) % rl.length,
                            ..rl
                        };
                        for l in &mut rl.labels {
                            l.start += first;
                        }
                        thumbs = baked_thumbs;
                        masks = baked_masks;
                        xor_steps = masks
                            .par_windows(2)
                            .map(|w| crate::mask::xor_count(&w[0], &w[1]))
                            .collect();
                        app_steps = thumbs
                            .par_windows(2)
                            .map(|w| appearance::thumb_cost(&w[0], &w[1], None))
                            .collect();
                        kappa = appearance::kappa(
                            params.appearance as f64,
                            mean(&xor_steps),
                            mean(&app_steps),
                        );
                        // Frame L is frame 0 again: the wrap L -> 1 is the step 0 -> 1.
                        best_loop = Loop {
                            start: 0,
                            end: rl.length,
                            cost: 0,
                        };
                        n_frames = masks.len();
                        region_loop = Some(RegionResult {
                            chosen: rl,
                            quality,
                            single,
                            secs: t_bake.elapsed().as_secs_f64(),
                        });
                    }
                }
            }
        }
    }
    // The deferred store writes count as the masks stage's, where a streamed view's are.
    let t_store = Instant::now();
    if let (true, None, Some(frames)) = (defer_store, &region_loop, cache.as_deref()) {
        // The source's frames after all: converted a chunk at a time on the pool, sent in order.
        let chunk = (4 * rayon::current_num_threads()).max(8);
        let mut rgb: Vec<RgbImage> = Vec::new();
        for (k, part) in frames.chunks(chunk).enumerate() {
            rgb.resize_with(part.len(), || RgbImage::new(0, 0));
            part.par_iter()
                .zip(rgb.par_iter_mut())
                .for_each(|(f, out)| f.as_ref().to_rgb_into(out));
            for (j, f) in rgb.iter().enumerate() {
                let i = k * chunk + j;
                observer.object_frame(p, i, &shown(&masks[i]), f)?;
            }
        }
    }
    let stored = t_store.elapsed();
    timings.masks += stored;
    drop(cache);
    observer.finish();
    timings.loops += t.elapsed().saturating_sub(stored);
    let total_px = masks.len() as f64 * masks[0].len() as f64;
    let moving_fraction = masks.iter().map(|m| m.count_ones() as f64).sum::<f64>() / total_px;
    // The seam unit: an ordinary step of the frames playback shows (the loop m+1..=n).
    let step = {
        let range = best_loop.start + 1..best_loop.end;
        let n = range.len().max(1) as f64;
        range
            .map(|s| xor_steps[s] as f64 + kappa * app_steps.get(s).copied().unwrap_or(0) as f64)
            .sum::<f64>()
            / n
    };
    let loop_seam = seam_score(best_loop.cost, params.loops.window, step);
    Ok(ViewResult {
        name,
        n_frames,
        background,
        masks,
        best_loop,
        alternatives,
        moving_fraction,
        mean_step: step,
        kappa,
        thumbs,
        thumb_factor: factor,
        loop_seam,
        noise_sigma: model.as_ref().map(|m| m.sigma0),
        dynamic_fraction: support
            .as_ref()
            .map_or(0.0, |s| s.count_ones() as f64 / s.len() as f64),
        dynamic_alpha: model.and_then(|m| m.alpha),
        motion_kept: kept.share(),
        region_loop,
        region_rejected: regions_worse,
        region_not_needed: thesis_smooth,
        regions_over_cache,
        shake: None,
    })
}

/// Frames a packed per-region window holds past the thesis's loop (a cached window holds up to
/// [`crate::regions::RegionParams::max_frames`]).
const PACKED_SLACK: usize = 8;

/// The per-region loop's source window: the frame cache's frames, or frames decoded again and
/// packed.
enum Window<'a> {
    Cached(&'a [Frame]),
    Packed(&'a crate::packed::PackedFrames),
}

impl crate::regions::Frames for Window<'_> {
    fn count(&self) -> usize {
        match self {
            Window::Cached(f) => f.count(),
            Window::Packed(f) => f.count(),
        }
    }
    fn dimensions(&self) -> (u32, u32) {
        match self {
            Window::Cached(f) => f.dimensions(),
            Window::Packed(f) => crate::regions::Frames::dimensions(*f),
        }
    }
    #[inline(always)]
    fn px(&self, f: usize, x: u32, y: u32) -> [u8; 3] {
        match self {
            Window::Cached(w) => w.px(f, x, y),
            Window::Packed(w) => w.pixel(f, x, y),
        }
    }
    fn rgb_into(&self, f: usize, out: &mut RgbImage) {
        match self {
            Window::Cached(w) => w.rgb_into(f, out),
            Window::Packed(w) => w.rgb_into(f, out),
        }
    }
    fn rect_into(&self, f: usize, rect: [usize; 4], out: &mut Vec<u8>) {
        match self {
            Window::Cached(w) => w.rect_into(f, rect, out),
            Window::Packed(w) => w.rect_into(f, rect, out),
        }
    }
}

/// What trying a per-region loop came to.
enum Baked {
    /// The thesis's loop already wraps as it steps: nothing tried.
    ThesisSmooth(crate::regions::Quality),
    /// Tried, measured no better than the thesis's loop: the labels, their quality, the
    /// thesis's.
    Worse(
        crate::regions::RegionLoop,
        crate::regions::Quality,
        crate::regions::Quality,
    ),
    /// Asked for, but the label search (this many bytes) does not fit what the cache's budget
    /// leaves beside the packed window.
    OverCache(usize),
    /// Kept: the labels (counted in the window), their quality, the thesis's, and the baked
    /// frames `0..=L` with their masks when they were held.
    Kept(
        crate::regions::RegionLoop,
        crate::regions::Quality,
        crate::regions::Quality,
        Option<Vec<(RgbImage, Mask)>>,
    ),
}

/// Chooses and measures the per-region loop of `window` (source frames holding the thesis's
/// loop `own`, counted from the window's first frame; `masks` theirs) against the thesis's loop
/// measured alike, when the label search fits `room` bytes (None: no bound). The baked frames
/// are made to be measured, and held for the store only when they fit `keep` bytes.
fn bake_regions<F: crate::regions::Frames + ?Sized>(
    window: &F,
    masks: &[Mask],
    own: crate::regions::Label,
    alpha: Option<&GrayImage>,
    rp: &crate::regions::RegionParams,
    min_length: usize,
    room: Option<usize>,
    keep: usize,
) -> Result<Baked> {
    use crate::regions::{
        quality_of_single, quality_with, single_frame, single_loop, wraps_of, Quality, SourceEnergy,
    };
    let dims = window.dimensions();
    let one = single_loop(own, dims, crate::regions::reduction(dims, rp).1);
    let frame = |t, out: &mut RgbImage| window.rgb_into(single_frame(&one, t), out);
    // Asked only where better: a thesis's loop that already wraps as it steps (an exact repeat
    // among them; not every loop whose eq. (1) cost is 0: a looped clip's own jump can fall
    // inside it) is kept without trying, on its wraps alone.
    if rp.only_if_better {
        let wraps = wraps_of(frame, window, &one, alpha);
        if !Quality::shows(&wraps) {
            return Ok(Baked::ThesisSmooth(wraps));
        }
    }
    let search = crate::regions::search_bytes(dims, window.count(), rp);
    if room.is_some_and(|r| search > r) {
        return Ok(Baked::OverCache(search));
    }
    // The source's sharpness, measured once for both loops.
    let energy = SourceEnergy::of(window, one.tile, alpha);
    let single = quality_of_single(window, &energy, &one, alpha);
    let rl = crate::regions::solve(window, alpha, Some(own.period), min_length, rp)?;
    let bake = Bake::new(window, masks, &rl, rp.feather);
    // The frames as measured, kept for the store when they fit `keep` (else made again).
    let (w, h) = dims;
    let frame_bytes =
        3 * w as usize * h as usize + masks.first().map_or(0, |m| m.len().div_ceil(64) * 8);
    let mut held = ((rl.length + 1).saturating_mul(frame_bytes) <= keep)
        .then(|| Vec::with_capacity(rl.length + 1));
    let quality = quality_with(
        |t, out: &mut RgbImage| {
            let m = bake.frame_into(t, out);
            if let Some(h) = held.as_mut() {
                h.push((out.clone(), m));
            }
        },
        window,
        &energy,
        &rl,
        alpha,
    );
    drop(bake);
    Ok(if rp.only_if_better && !quality.better_than(&single) {
        Baked::Worse(rl, quality, single)
    } else {
        Baked::Kept(rl, quality, single, held)
    })
}

/// [`crate::regions::wraps_of`] of the single-label loop `one` over frames `start..start +
/// one.length` of `src` (`w x h`, `n` frames), decoded once more up to the loop's last frame and
/// measured as they come on another thread, two frames in flight.
fn streamed_wraps(
    src: &mut dyn FrameSource,
    (w, h): (u32, u32),
    one: &crate::regions::RegionLoop,
    start: usize,
    n: usize,
    alpha: Option<&GrayImage>,
    label: &dyn Fn(&str) -> String,
) -> Result<crate::regions::Quality> {
    let l = one.length;
    // Frames go to the meter two at a time, and their buffers come back for the next ones.
    let (tx, rx) = std::sync::mpsc::sync_channel::<RgbImage>(2);
    let (back, spent) = std::sync::mpsc::channel::<RgbImage>();
    let (got, wraps) = std::thread::scope(|scope| {
        let meter = scope.spawn(move || {
            let mut first: Option<RgbImage> = None;
            crate::regions::wraps_in(
                |t, out: &mut RgbImage| {
                    // Output frame L is frame 0 again.
                    if t == l {
                        if let Some(f) = &first {
                            out.clone_from(f);
                        }
                        return;
                    }
                    // A read that stopped early leaves black frames: its error is returned.
                    let next = rx
                        .recv()
                        .unwrap_or_else(|_| RgbImage::new(out.width(), out.height()));
                    let _ = back.send(std::mem::replace(out, next));
                    if t == 0 {
                        first = Some(out.clone());
                    }
                },
                (w, h),
                one,
                alpha,
            )
        });
        let got = src.for_each_native_to(start + l, &mut |i, frame| {
            if (start..start + l).contains(&i) {
                let mut rgb = spent.try_recv().unwrap_or_else(|_| RgbImage::new(0, 0));
                frame.to_rgb_into(&mut rgb);
                // The meter only stops early when it panicked, which join reports.
                let _ = tx.send(rgb);
            }
            Ok(())
        });
        drop(tx);
        let wraps = meter
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (got, wraps)
    });
    let got = got?;
    if got != (start + l).min(n) {
        return Err(Error::Source {
            view: label(""),
            message: format!("gave {n} frames on the first read and {got} on the third"),
        });
    }
    Ok(wraps)
}

/// Frames `range` of `src` (decoded again up to the range's end, of `n`), packed losslessly while they take
/// at most `budget` bytes (the frames past it are left out), and the packed size of the first
/// frame left out (0 when none was).
fn read_window(
    src: &mut dyn FrameSource,
    range: std::ops::Range<usize>,
    n: usize,
    budget: usize,
    label: &dyn Fn(&str) -> String,
) -> Result<(crate::packed::PackedFrames, usize)> {
    let mut window = crate::packed::PackedFrames::new();
    let (mut full, mut left_out) = (false, 0);
    // Decoded up to the window's end (of the `n` frames the first read gave).
    let end = range.end.min(n);
    let got = src.for_each_native_to(end, &mut |i, frame| {
        if range.contains(&i) && !full {
            let before = window.byte_len();
            window.push(frame)?;
            if window.byte_len() > budget {
                left_out = window.byte_len() - before;
                window.truncate(window.len() - 1);
                full = true;
            }
        }
        Ok(())
    })?;
    if got != end {
        return Err(Error::Source {
            view: label(""),
            message: format!("gave {n} frames on the first read and {got} on the third"),
        });
    }
    Ok((window, left_out))
}
