//! One seam score, with one meaning, for `vt analyze` and `vt render` alike: how large the
//! rendered change at a jump (a loop wrap or a view switch) is, in units of the ordinary rendered
//! change it stands in for. 1 is as large as ordinary playback (an exact loop's wrap, a switch
//! between views that agree), above 1 shows as a jump, 0 is a frozen frame.
//!
//! A step is [`frame_step`]: the mean absolute difference between two rendered frames over all
//! pixels and channels, so what the renderer shows is what is measured (background, dynamic
//! region, object, gain, morph, the switch fade), not the masks the analysis chose by.
//!
//! - A **loop wrap** happens at one place of the loop: its rendered step over the median
//!   ordinary step (one frame to the next within the loop).
//! - A **view switch** can happen at any frame, so it is measured against the steps it replaces:
//!   the sum of the rendered steps from the frame before the switch through the switch and its
//!   fade frames ([`crate::render::RenderParams::switch_fade`]), over the sum of the steps the
//!   old view would have shown over the same frames (its loop continued, at the same
//!   viewpoint). Paired this way, a switch between views that agree scores exactly 1 however
//!   uneven the footage's own steps are; a switch's single step over the median ordinary step
//!   would score a perfect switch above 1 on footage whose steps vary (tree.avi's real frame
//!   steps range over 7x: an exact switch measured 1.35).
//!
//! Where:
//! - While rendering ([`SeamMeter`]): fed each output frame with how the player reached it and,
//!   for a switch's frames, the frame the old view would have shown; the score is the mean over
//!   the render's jumps.
//! - After analysis ([`measure_seams`]): per view, its loop wrap at its own viewpoint, and its
//!   switches to each neighbour at the tie between them, sampled evenly.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::sync::Arc;

use image::RgbImage;

use crate::metrics::gradient_energy;
use crate::render::{
    FrameChoice, ObjectFrames, ObjectPatch, RenderParams, RenderScene, Renderer, Step,
};
use crate::{Error, Result};

/// Mean absolute difference of two frames of the same size (0..255, over every channel).
pub fn frame_step(a: &RgbImage, b: &RgbImage) -> f64 {
    debug_assert_eq!(a.dimensions(), b.dimensions());
    let total: u64 = a
        .as_raw()
        .chunks(4096)
        .zip(b.as_raw().chunks(4096))
        .map(|(x, y)| {
            // A chunk's sum fits in 32 bits (4096 * 255), which the compiler vectorises; the
            // total is exact either way.
            x.iter()
                .zip(y)
                .map(|(&p, &q)| p.abs_diff(q) as u32)
                .sum::<u32>() as u64
        })
        .sum();
    total as f64 / a.as_raw().len().max(1) as f64
}

/// [`frame_step`] over rows `0, every, 2 every, ...` only (every row for `every <= 1`): the
/// frames a [`Renderer::sample_rows`] renderer makes, measured where it wrote them.
pub fn frame_step_rows(a: &RgbImage, b: &RgbImage, every: usize) -> f64 {
    if every <= 1 {
        return frame_step(a, b);
    }
    debug_assert_eq!(a.dimensions(), b.dimensions());
    let row = 3 * a.width() as usize;
    let (mut total, mut n) = (0u64, 0usize);
    for (x, y) in a
        .as_raw()
        .chunks(row.max(1))
        .zip(b.as_raw().chunks(row.max(1)))
        .step_by(every)
    {
        total += x
            .iter()
            .zip(y)
            .map(|(&p, &q)| p.abs_diff(q) as u64)
            .sum::<u64>();
        n += x.len();
    }
    total as f64 / n.max(1) as f64
}

/// The smallest ordinary step a ratio is taken against (grey levels): a scene whose ordinary
/// playback changes less than this (a still picture) has jumps measured against this instead of
/// 0, so an invisible jump scores 0 and a visible one a large finite number.
pub const MIN_UNIT: f64 = 1.0 / 256.0;

/// The ratio of a jump step to the ordinary unit (floored at [`MIN_UNIT`]).
fn ratio(jump: f64, unit: f64) -> f64 {
    jump / unit.max(MIN_UNIT)
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// A switch's seam from its step sums: shown over replaced, with the replaced steps floored at
/// [`MIN_UNIT`] a frame (a still scene: an invisible switch scores 0, a visible one large).
fn switch_ratio(shown: f64, replaced: f64, frames: usize) -> f64 {
    shown / replaced.max(MIN_UNIT * frames.max(1) as f64)
}

/// A switch being measured: its frames so far, and the step sums.
#[derive(Debug, Clone, Copy)]
struct OpenSwitch {
    frames: usize,
    shown: f64,
    replaced: f64,
}

/// Seam scores of a render, frame by frame: feed it every output frame with how the player
/// reached it. Keeps two frames (reused), so it allocates only when the size first is known.
#[derive(Debug, Default)]
pub struct SeamMeter {
    prev: Option<RgbImage>,
    prev_replaced: Option<RgbImage>,
    ordinary: Vec<f64>,
    wraps: Vec<f64>,
    switches: Vec<f64>,
    open: Option<OpenSwitch>,
}

impl SeamMeter {
    /// An empty meter.
    pub fn new() -> Self {
        Self::default()
    }

    /// The next output frame, reached by `step`. `replaced`: for a switch and the fade frames
    /// after it, the frame the old view would have shown instead (its loop continued, at the
    /// same viewpoint); None for every other frame. A switch without it is scored like a wrap.
    pub fn push(&mut self, frame: &RgbImage, step: Step, replaced: Option<&RgbImage>) {
        let Some(mut prev) = self
            .prev
            .take()
            .filter(|p| p.dimensions() == frame.dimensions())
        else {
            self.close();
            self.prev = Some(frame.clone());
            return;
        };
        let d = frame_step(&prev, frame);
        let replaced = replaced.filter(|r| r.dimensions() == frame.dimensions());
        match (step, replaced) {
            (Step::Switch { .. }, Some(r)) => {
                self.close();
                self.open = Some(OpenSwitch {
                    frames: 1,
                    shown: d,
                    replaced: frame_step(&prev, r),
                });
            }
            (Step::Play, Some(r)) if self.open.is_some() => {
                let last = self
                    .prev_replaced
                    .as_ref()
                    .expect("kept while a switch is open");
                let o = self.open.as_mut().expect("checked");
                o.frames += 1;
                o.shown += d;
                o.replaced += frame_step(last, r);
            }
            (Step::Play, _) => {
                self.close();
                self.ordinary.push(d);
            }
            (Step::Wrap | Step::Switch { .. }, _) => {
                self.close();
                self.wraps.push(d);
            }
            (Step::Start, _) => self.close(),
        }
        prev.copy_from_slice(frame.as_raw());
        self.prev = Some(prev);
        if let (true, Some(r)) = (self.open.is_some(), replaced) {
            match &mut self.prev_replaced {
                Some(k) if k.dimensions() == r.dimensions() => k.copy_from_slice(r.as_raw()),
                k => *k = Some(r.clone()),
            }
        }
    }

    /// Ends the switch being measured, if any.
    fn close(&mut self) {
        if let Some(o) = self.open.take() {
            self.switches
                .push(switch_ratio(o.shown, o.replaced, o.frames));
        }
    }

    /// Jumps measured (wraps and switches).
    pub fn jumps(&self) -> usize {
        self.wraps.len() + self.switches.len() + usize::from(self.open.is_some())
    }

    /// The mean seam score over the jumps: each wrap's step over the median ordinary step, each
    /// switch's steps over the ones it replaced (None without jumps).
    pub fn score(&self) -> Option<f64> {
        let unit = median(&mut self.ordinary.clone());
        let open = self
            .open
            .map(|o| switch_ratio(o.shown, o.replaced, o.frames));
        let all: Vec<f64> = self
            .wraps
            .iter()
            .map(|&w| ratio(w, unit))
            .chain(self.switches.iter().copied())
            .chain(open)
            .collect();
        (!all.is_empty()).then(|| all.iter().sum::<f64>() / all.len() as f64)
    }
}

/// One view's seam scores ([`measure_seams`]); None where there is no such jump.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ViewSeams {
    /// The loop wrap `n -> m + 1` at the view's own viewpoint.
    pub wrap: Option<f64>,
    /// Mean over the sampled switches to the next view, at the tie between them (None for the
    /// last view, or when no frame has a transition).
    pub to_next: Option<f64>,
    /// The same towards the previous view.
    pub to_prev: Option<f64>,
}

/// `count` frames of `lo..hi` to measure steps from, for a view whose frames decode in groups
/// of `group` (all of them when there are few): the groups' first frames first, then their
/// second frames, and so on, each set evenly spread; in order. A step from a group's first frame
/// decodes two frames, where one from the middle of a group decodes half the group.
fn sample_steps(lo: usize, hi: usize, count: usize, group: usize) -> Vec<usize> {
    let n = hi.saturating_sub(lo);
    if n <= count {
        return (lo..hi).collect();
    }
    let group = group.max(1);
    let mut picked = Vec::with_capacity(count);
    for offset in 0..group {
        let set: Vec<usize> = (lo..hi).filter(|i| i % group == offset).collect();
        let want = (count - picked.len()).min(set.len());
        picked.extend((0..want).map(|k| set[k * set.len() / want]));
        if picked.len() == count {
            break;
        }
    }
    picked.sort_unstable();
    picked
}

/// The frames a measurement decoded last, so each is decoded once: a switch's renders read
/// the old view's continuation twice (under the fade, and plain, as what the switch replaced)
/// and the neighbour that fills in for both views at the tie.
struct Memo<'a> {
    objects: &'a dyn ObjectFrames,
    kept: RefCell<VecDeque<((usize, usize), ObjectPatch)>>,
}

impl<'a> Memo<'a> {
    /// Frames kept: a switch's fade reads at most six distinct frames a step (the shown frame,
    /// the old view's, and their neighbours'), and the next step's are new.
    const FRAMES: usize = 8;
    /// Bytes kept at most (fewer frames when they are large: at 1080p a whole-frame patch is
    /// 8 MB, and the analysis's peak memory is measured at the seams).
    const BYTES: usize = 24 << 20;

    fn new(objects: &'a dyn ObjectFrames) -> Self {
        Self {
            objects,
            kept: RefCell::new(VecDeque::with_capacity(Self::FRAMES)),
        }
    }
}

impl ObjectFrames for Memo<'_> {
    fn decode_into(&self, view: usize, frame: usize, patch: &mut ObjectPatch) -> Result<()> {
        let mut kept = self.kept.borrow_mut();
        if let Some((_, p)) = kept.iter().find(|(k, _)| *k == (view, frame)) {
            patch.clone_from(p);
            return Ok(());
        }
        self.objects.decode_into(view, frame, patch)?;
        let size = |p: &ObjectPatch| p.rgb.len() + p.mask.len();
        let mut held: usize = kept.iter().map(|(_, p)| size(p)).sum();
        let mut slot = ObjectPatch::default();
        while !kept.is_empty() && (kept.len() == Self::FRAMES || held + size(patch) > Self::BYTES) {
            slot = kept.pop_front().expect("not empty").1;
            held -= size(&slot);
        }
        if size(patch) > Self::BYTES {
            return Ok(());
        }
        slot.clone_from(patch);
        kept.push_back(((view, frame), slot));
        Ok(())
    }

    fn group(&self, view: usize) -> usize {
        self.objects.group(view)
    }
}

/// How much of a scene [`measure_seams`] renders.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeamSampling {
    /// Most ordinary steps measured per view.
    pub steps: usize,
    /// Most switches measured per view and direction (each renders its fade twice: as shown
    /// and as replaced).
    pub switches: usize,
    /// Fewest rows of each frame measured (0: all): every `height / rows`-th row is rendered
    /// and compared ([`Renderer::sample_rows`], [`frame_step_rows`]).
    pub rows: usize,
}

impl Default for SeamSampling {
    /// 32 steps, 6 switches a direction, at least 30 rows: on the 5-view 320x240 scene of
    /// tree.avi (`vt synth real`), 1.7 s against 5.2 s for 32 steps, 8 switches and every row
    /// (decoding each frame again), and against the exact scores (every step, every switch,
    /// every row: 43 s) within 0.07 for a wrap (the median step of 32) and 0.02 for a link;
    /// the rows alone move a score by less than 0.01.
    fn default() -> Self {
        Self {
            steps: 32,
            switches: 6,
            rows: 30,
        }
    }
}

impl SeamSampling {
    /// The row stride for frames `height` rows tall.
    pub fn every(&self, height: u32) -> usize {
        match self.rows {
            0 => 1,
            r => (height as usize / r).max(1),
        }
    }
}

/// Per view, the seam scores of its loop wrap and its switches, measured on frames the renderer
/// makes with `params` (crossfade and dissolve off, the switch fade on, as switches play), as
/// much of them as `sampling` says: its ordinary steps per view, its switches per view and
/// direction (a switch renders its fade twice over: as shown and as replaced), on its rows.
pub fn measure_seams(
    scene: &Arc<RenderScene>,
    objects: &(dyn ObjectFrames + Sync),
    params: RenderParams,
    sampling: SeamSampling,
) -> Result<Vec<ViewSeams>> {
    if sampling.steps == 0 {
        return Err(Error::InvalidParameter {
            name: "samples",
            value: "0".into(),
            why: "at least one step must be measured".into(),
        });
    }
    let (mut renderer, fade, mut bufs) = measuring(scene, params)?;
    let (w, h) = renderer.size();
    let every = sampling.every(h);
    renderer.sample_rows(every);
    let views = 0..scene.views.len();
    // Views at once where a renderer's working set is small (its five frames and the memo's
    // eight), each on a clone of the one prepared here; else one at a time on it, so the peak
    // memory of an HD analysis, measured here, does not grow.
    if (w as usize * h as usize) <= PARALLEL_PIXELS {
        use rayon::prelude::*;
        views
            .into_par_iter()
            .map_init(
                || (renderer.clone(), bufs.clone()),
                |(r, b), p| view_seams(scene, objects, r, fade, b, sampling, every, p),
            )
            .collect()
    } else {
        views
            .map(|p| {
                let (r, b) = (&mut renderer, &mut bufs);
                view_seams(scene, objects, r, fade, b, sampling, every, p)
            })
            .collect()
    }
}

/// Frame size in pixels up to which [`measure_seams`] measures views at once (640x480).
const PARALLEL_PIXELS: usize = 640 * 480;

/// [`measure_seams`] of view `p`, on `renderer` (from [`measuring`], rows sampled `every`).
#[allow(clippy::too_many_arguments)]
fn view_seams(
    scene: &Arc<RenderScene>,
    objects: &dyn ObjectFrames,
    renderer: &mut Renderer,
    fade: usize,
    bufs: &mut [RgbImage; 5],
    sampling: SeamSampling,
    every: usize,
    p: usize,
) -> Result<ViewSeams> {
    let memo = Memo::new(objects);
    let objects = &memo;
    let views = &scene.views;
    let v = &views[p];
    let (m, n) = (v.loop_start, v.loop_end);
    let q = p as f64;
    // Ordinary steps i -> i + 1 for i in m+1..n.
    let [a, b, ..] = bufs;
    let mut ordinary = Vec::new();
    for i in sample_steps(m + 1, n, sampling.steps, objects.group(p)) {
        renderer.render_plain_into(objects, q, p, i, a)?;
        renderer.render_plain_into(objects, q, p, i + 1, b)?;
        ordinary.push(frame_step_rows(a, b, every));
    }
    let unit = median(&mut ordinary);
    let wrap = if n > m {
        renderer.render_plain_into(objects, q, p, n, a)?;
        renderer.render_plain_into(objects, q, p, m + 1, b)?;
        Some(ratio(frame_step_rows(a, b, every), unit))
    } else {
        None
    };
    let count = sampling.switches;
    let mut switch = |to: usize, q: f64| -> Result<Option<f64>> {
        let (r, b) = (&mut *renderer, &mut *bufs);
        let scores = direction_switches(r, scene, fade, objects, (p, to), q, count, b, None)?;
        Ok((!scores.is_empty()).then(|| scores.iter().sum::<f64>() / scores.len() as f64))
    };
    let to_next = if p + 1 < views.len() {
        switch(p + 1, q + 0.5)?
    } else {
        None
    };
    let to_prev = if p > 0 { switch(p - 1, q - 0.5)? } else { None };
    Ok(ViewSeams {
        wrap,
        to_next,
        to_prev,
    })
}

/// The renderer seams are measured with: `params` without crossfade and dissolve (they act on
/// wraps over several frames of a render, see [`SeamMeter`] for those; the switch fade stays, as
/// switches play), the frames a switch spans (the jump and its fade), and five frame buffers.
fn measuring(
    scene: &Arc<RenderScene>,
    params: RenderParams,
) -> Result<(Renderer, usize, [RgbImage; 5])> {
    let params = RenderParams {
        crossfade: 0,
        dissolve: 0,
        ..params
    };
    let renderer = Renderer::new(scene.clone(), params)?;
    let (w, h) = renderer.size();
    let bufs = std::array::from_fn(|_| RgbImage::new(w, h));
    Ok((renderer, params.switch_blend_frames() + 1, bufs))
}

/// The seams ([`switch_seam`]) of at most `count` switches from view `from` to its neighbour
/// `to` at `q`, from frames sampled evenly over `from`'s loop (those eq. (2) sends somewhere
/// the new view has a next frame).
#[allow(clippy::too_many_arguments)]
fn direction_switches(
    renderer: &mut Renderer,
    scene: &RenderScene,
    frames: usize,
    objects: &dyn ObjectFrames,
    (from, to): (usize, usize),
    q: f64,
    count: usize,
    bufs: &mut [RgbImage; 5],
    mut sharpness: Option<&mut Vec<f64>>,
) -> Result<Vec<f64>> {
    let v = &scene.views[from];
    let table = if to > from { &v.to_next } else { &v.to_prev };
    let target = &scene.views[to];
    let mut scores = Vec::new();
    for s in sample_steps(v.loop_start + 1, v.loop_end + 1, count, objects.group(from)) {
        let Some(Some(t)) = table.get(s) else {
            continue;
        };
        if t + 1 >= target.to_next.len().max(target.to_prev.len()) {
            continue;
        }
        scores.push(switch_seam(
            renderer,
            scene,
            frames,
            objects,
            q,
            (from, s),
            (to, t + 1),
            bufs,
            sharpness.as_deref_mut(),
        )?);
    }
    Ok(scores)
}

/// One switch's seam ([`switch_ratio`]): from `from` (shown before it) to `to` at `q`, played as
/// the player and renderer play it (the jump, then the fade frames, each view following its own
/// loop; a wrap of the new view ends the fade as it does in play), against what the old view
/// would have shown, over `frames` frames at most (the jump and its fade). `bufs`: frames of the
/// renderer's size. With `sharpness`, each blended frame's gradient energy over the blend of
/// the two layers' own (the old view's continuation and the new view's frame, unblended) is
/// pushed to it: 1 where blending loses no detail.
#[allow(clippy::too_many_arguments)]
fn switch_seam(
    renderer: &mut Renderer,
    scene: &RenderScene,
    frames: usize,
    objects: &dyn ObjectFrames,
    q: f64,
    from: (usize, usize),
    to: (usize, usize),
    bufs: &mut [RgbImage; 5],
    mut sharpness: Option<&mut Vec<f64>>,
) -> Result<f64> {
    let [prev, cur, prev_r, cur_r, new] = bufs;
    renderer.render_plain_into(objects, q, from.0, from.1, prev)?;
    prev_r.copy_from_slice(prev.as_raw());
    let (mut shown, mut replaced, mut done) = (0.0, 0.0, 0);
    let (mut j, mut r) = (to.1, scene.next_in_loop(from.0, from.1));
    for k in 0..frames {
        let step = if k == 0 {
            Step::Switch {
                hops: from.0.abs_diff(to.0),
            }
        } else if j == scene.views[to.0].loop_start + 1 {
            break;
        } else {
            Step::Play
        };
        let choice = FrameChoice {
            view: to.0,
            frame: j,
            step,
            continuation: Some((from.0, from.1 + 1)),
        };
        renderer.render_into(objects, q, &choice, cur)?;
        let blended = renderer.switch_fade_from().is_some();
        renderer.render_plain_into(objects, q, from.0, r, cur_r)?;
        let every = renderer.sampled_rows();
        shown += frame_step_rows(prev, cur, every);
        replaced += frame_step_rows(prev_r, cur_r, every);
        done += 1;
        if let (Some(out), true) = (sharpness.as_deref_mut(), blended) {
            renderer.render_plain_into(objects, q, to.0, j, new)?;
            let alpha = (k + 1) as f64 / frames as f64;
            let mix = (1.0 - alpha) * gradient_energy(cur_r) + alpha * gradient_energy(new);
            out.push(gradient_energy(cur) / mix.max(1e-9));
        }
        std::mem::swap(prev, cur);
        std::mem::swap(prev_r, cur_r);
        j = scene.next_in_loop(to.0, j);
        r = scene.next_in_loop(from.0, r);
    }
    Ok(switch_ratio(shown, replaced, done))
}

/// What a switch fade costs and gives, over the sampled switches of every link both ways
/// ([`measure_switch_fades`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FadeFigures {
    /// Each link direction's mean switch seam (as [`measure_seams`]), `0 -> 1, 1 -> 0, 1 -> 2,
    /// ...`.
    pub seams: Vec<f64>,
    /// Every blended frame's sharpness: its gradient energy over the blend of its two layers'
    /// own (empty without a fade).
    pub sharpness: Vec<f64>,
}

/// The switches of [`measure_seams`] with `params` (its switch fade), and the sharpness of
/// their blended frames; at most `samples` switches per link direction.
pub fn measure_switch_fades(
    scene: &Arc<RenderScene>,
    objects: &dyn ObjectFrames,
    params: RenderParams,
    samples: usize,
) -> Result<FadeFigures> {
    let (mut renderer, frames, mut bufs) = measuring(scene, params)?;
    let memo = Memo::new(objects);
    let objects = &memo;
    let mut out = FadeFigures::default();
    for p in 0..scene.views.len().saturating_sub(1) {
        for link in [(p, p + 1), (p + 1, p)] {
            let q = p as f64 + 0.5;
            let sharp = Some(&mut out.sharpness);
            let scores = direction_switches(
                &mut renderer,
                scene,
                frames,
                objects,
                link,
                q,
                samples,
                &mut bufs,
                sharp,
            )?;
            out.seams
                .push(scores.iter().sum::<f64>() / scores.len().max(1) as f64);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(v: u8) -> RgbImage {
        RgbImage::from_pixel(4, 2, image::Rgb([v; 3]))
    }

    #[test]
    fn steps_are_sampled_from_the_starts_of_decoding_groups_first() {
        // Without groups: evenly spread, as before groups were known.
        assert_eq!(sample_steps(1, 11, 5, 1), vec![1, 3, 5, 7, 9]);
        assert_eq!(sample_steps(3, 6, 5, 8), vec![3, 4, 5]);
        // 1..200 in groups of 8: 24 group starts (8..=192), then 8 second frames, spread.
        let got = sample_steps(1, 200, 32, 8);
        assert_eq!(got.len(), 32);
        assert!(got.windows(2).all(|w| w[0] < w[1]));
        assert!(got.iter().all(|&i| (1..200).contains(&i)));
        assert_eq!(got.iter().filter(|&&i| i % 8 == 0).count(), 24);
        assert_eq!(got.iter().filter(|&&i| i % 8 == 1).count(), 8);
        // Spread over the whole range, not bunched at its start.
        assert!(got.iter().filter(|&&i| i % 8 == 1).any(|&i| i > 150));
    }

    #[test]
    fn frame_step_is_the_mean_absolute_difference() {
        assert_eq!(frame_step(&grey(10), &grey(10)), 0.0);
        assert_eq!(frame_step(&grey(10), &grey(14)), 4.0);
        let mut half = grey(0);
        half.put_pixel(0, 0, image::Rgb([255, 0, 0]));
        assert!((frame_step(&grey(0), &half) - 255.0 / 24.0).abs() < 1e-12);
    }

    #[test]
    fn meter_scores_wraps_against_the_median_step_and_switches_against_what_they_replace() {
        let mut m = SeamMeter::new();
        // Ordinary steps of 2, 2, 4 (median 2); one wrap of 6: 3.
        for (v, s) in [
            (0, Step::Start),
            (2, Step::Play),
            (4, Step::Play),
            (8, Step::Play),
            (14, Step::Wrap),
        ] {
            m.push(&grey(v), s, None);
        }
        assert_eq!((m.jumps(), m.score()), (1, Some(3.0)));
        // A switch with a two-frame fade: shown 14 -> 20 -> 21 -> 30 (steps 6, 1, 9: 16), where
        // the old view would have shown 22, 30, 36 (steps 8, 8, 6: 22). Its seam is 16 / 22,
        // whatever the median ordinary step; the fade frames are not ordinary steps.
        for (v, r) in [(20, 22), (21, 30), (30, 36)] {
            let step = if v == 20 {
                Step::Switch { hops: 1 }
            } else {
                Step::Play
            };
            m.push(&grey(v), step, Some(&grey(r)));
        }
        assert_eq!(m.jumps(), 2);
        let switch = 16.0 / 22.0;
        assert!((m.score().unwrap() - (3.0 + switch) / 2.0).abs() < 1e-12);
        // The next played frame closes the switch and is an ordinary step again (2, 2, 4, 2:
        // median 2, the wrap still 3).
        m.push(&grey(32), Step::Play, None);
        assert!((m.score().unwrap() - (3.0 + switch) / 2.0).abs() < 1e-12);
        // A switch between views that agree (shown = replaced) scores exactly 1, however
        // uneven the ordinary steps: a paired measure, not one over the median.
        let mut even = SeamMeter::new();
        even.push(&grey(0), Step::Start, None);
        for v in [1, 2, 3] {
            even.push(&grey(v), Step::Play, None);
        }
        even.push(&grey(40), Step::Switch { hops: 1 }, Some(&grey(40)));
        assert_eq!(even.score(), Some(1.0));
        // A switch without what it replaced is scored like a wrap (37 over the median 1).
        let mut bare = SeamMeter::new();
        for (v, s) in [
            (0, Step::Start),
            (1, Step::Play),
            (38, Step::Switch { hops: 1 }),
        ] {
            bare.push(&grey(v), s, None);
        }
        assert_eq!(bare.score(), Some(37.0));
        // Nothing moves: an invisible jump scores 0, a visible one large (against MIN_UNIT).
        let mut still = SeamMeter::new();
        for s in [Step::Start, Step::Play, Step::Wrap] {
            still.push(&grey(5), s, None);
        }
        assert_eq!(still.score(), Some(0.0));
        still.push(&grey(9), Step::Wrap, None);
        assert_eq!(still.score(), Some(2.0 / MIN_UNIT));
        let mut still_switch = SeamMeter::new();
        still_switch.push(&grey(5), Step::Start, None);
        still_switch.push(&grey(5), Step::Switch { hops: 1 }, Some(&grey(5)));
        assert_eq!(still_switch.score(), Some(0.0));
        assert_eq!(SeamMeter::new().score(), None);
    }
}
