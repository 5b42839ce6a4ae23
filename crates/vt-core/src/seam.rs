//! One seam score, with one meaning, for `vt analyze` and `vt render` alike: how large the
//! rendered step at a jump (a loop wrap or a view switch) is, in units of the median ordinary
//! rendered step (one frame to the next within a loop). 1 is as large as an ordinary frame step
//! (an exact loop's wrap: the frame after the wrap is the one that would have come next), above
//! 1 shows as a jump, 0 is a frozen frame.
//!
//! A step is [`frame_step`]: the mean absolute difference between two rendered frames over all
//! pixels and channels, so what the renderer shows is what is measured (background, dynamic
//! region, object, gain, morph), not the masks the analysis chose by.
//!
//! - While rendering ([`SeamMeter`]): each output frame's step from the one before, as an ordinary
//!   step or a jump by how the player reached it; the score is the mean jump step over the median
//!   ordinary step of the same render.
//! - After analysis ([`measure_seams`]): per view, the rendered step of its loop wrap at its own
//!   viewpoint, and of its switches to each neighbour at the tie between them, over the median
//!   ordinary step at its own viewpoint (sampled evenly, at most `samples` steps).

use std::sync::Arc;

use image::RgbImage;

use crate::render::{FrameChoice, ObjectFrames, RenderParams, RenderScene, Renderer, Step};
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

/// Seam scores of a render, frame by frame: feed it every output frame with how the player
/// reached it. Keeps one frame (reused), so it allocates only when the size first is known.
#[derive(Debug, Default)]
pub struct SeamMeter {
    prev: Option<RgbImage>,
    ordinary: Vec<f64>,
    jumps: Vec<f64>,
}

impl SeamMeter {
    /// An empty meter.
    pub fn new() -> Self {
        Self::default()
    }

    /// The next output frame, reached by `step`.
    pub fn push(&mut self, frame: &RgbImage, step: Step) {
        match &mut self.prev {
            Some(prev) if prev.dimensions() == frame.dimensions() => {
                let d = frame_step(prev, frame);
                match step {
                    Step::Play => self.ordinary.push(d),
                    Step::Wrap | Step::Switch { .. } => self.jumps.push(d),
                    Step::Start => {}
                }
                prev.copy_from_slice(frame.as_raw());
            }
            _ => self.prev = Some(frame.clone()),
        }
    }

    /// Jumps measured.
    pub fn jumps(&self) -> usize {
        self.jumps.len()
    }

    /// The mean jump step over the median ordinary step (None without jumps).
    pub fn score(&self) -> Option<f64> {
        if self.jumps.is_empty() {
            return None;
        }
        let mean = self.jumps.iter().sum::<f64>() / self.jumps.len() as f64;
        Some(ratio(mean, median(&mut self.ordinary.clone())))
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

/// Per view, the seam scores of its loop wrap and its switches, measured on frames the renderer
/// makes with `params` (crossfade and dissolve off: they act over several frames of a render, see
/// [`SeamMeter`] for those), sampling at most `samples` ordinary steps and switches per view.
pub fn measure_seams(
    scene: &Arc<RenderScene>,
    objects: &dyn ObjectFrames,
    params: RenderParams,
    samples: usize,
) -> Result<Vec<ViewSeams>> {
    if samples == 0 {
        return Err(Error::InvalidParameter {
            name: "samples",
            value: "0".into(),
            why: "at least one step must be measured".into(),
        });
    }
    let params = RenderParams {
        crossfade: 0,
        dissolve: 0,
        ..params
    };
    let mut renderer = Renderer::new(scene.clone(), params)?;
    let (w, h) = renderer.size();
    let (mut a, mut b) = (RgbImage::new(w, h), RgbImage::new(w, h));
    let mut step = |(pa, fa): (usize, usize), (pb, fb): (usize, usize), q: f64| -> Result<f64> {
        let choice = |view, frame| FrameChoice {
            view,
            frame,
            step: Step::Play,
            continuation: None,
        };
        renderer.render_into(objects, q, &choice(pa, fa), &mut a)?;
        renderer.render_into(objects, q, &choice(pb, fb), &mut b)?;
        Ok(frame_step(&a, &b))
    };
    let views = &scene.views;
    let mut out = Vec::with_capacity(views.len());
    for (p, v) in views.iter().enumerate() {
        let (m, n) = (v.loop_start, v.loop_end);
        let q = p as f64;
        // Ordinary steps i -> i + 1 for i in m+1..n.
        let mut ordinary = Vec::new();
        for i in sample_steps(m + 1, n, samples, objects.group(p)) {
            ordinary.push(step((p, i), (p, i + 1), q)?);
        }
        let unit = median(&mut ordinary);
        let wrap = if n > m {
            Some(ratio(step((p, n), (p, m + 1), q)?, unit))
        } else {
            None
        };
        let mut switch = |table: &[Option<usize>], to: usize, q: f64| -> Result<Option<f64>> {
            let frames = views[to].to_next.len().max(views[to].to_prev.len());
            let mut scores = Vec::new();
            for s in sample_steps(m + 1, n + 1, samples, objects.group(p)) {
                let Some(Some(t)) = table.get(s) else {
                    continue;
                };
                if frames > 0 && t + 1 >= frames {
                    continue;
                }
                let d = step((p, s), (to, t + 1), q)?;
                scores.push(ratio(d, unit));
            }
            Ok((!scores.is_empty()).then(|| scores.iter().sum::<f64>() / scores.len() as f64))
        };
        let to_next = if p + 1 < views.len() {
            switch(&v.to_next, p + 1, q + 0.5)?
        } else {
            None
        };
        let to_prev = if p > 0 {
            switch(&v.to_prev, p - 1, q - 0.5)?
        } else {
            None
        };
        out.push(ViewSeams {
            wrap,
            to_next,
            to_prev,
        });
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
    fn meter_scores_jumps_against_the_median_ordinary_step() {
        let mut m = SeamMeter::new();
        // Ordinary steps of 2, 2, 4 (median 2); one wrap of 6 and one switch of 2: mean 4 -> 2.
        for (v, s) in [
            (0, Step::Start),
            (2, Step::Play),
            (4, Step::Play),
            (8, Step::Play),
            (14, Step::Wrap),
            (16, Step::Switch { hops: 1 }),
        ] {
            m.push(&grey(v), s);
        }
        assert_eq!(m.jumps(), 2);
        assert_eq!(m.score(), Some(2.0));
        // Nothing moves: an invisible jump scores 0, a visible one large (against MIN_UNIT).
        let mut still = SeamMeter::new();
        for s in [Step::Start, Step::Play, Step::Wrap] {
            still.push(&grey(5), s);
        }
        assert_eq!(still.score(), Some(0.0));
        still.push(&grey(9), Step::Wrap);
        assert_eq!(still.score(), Some(2.0 / MIN_UNIT));
        assert_eq!(SeamMeter::new().score(), None);
    }
}
