//! Orbits: new views around the cameras' ring from one model, and how steady they are.
//!
//! The step between two consecutive frames is the mean absolute difference (over pixels and
//! channels, 0..255) inside the union of the two frames' object regions (the rough render's
//! coverage). A turning object changes every frame by about the same amount; a pop (the
//! texture jumping when the photos it is made from change) shows as one step far above the
//! others, so the summary is the largest step over the median step.

use image::RgbImage;
use nalgebra::Vector3;

use crate::camera::Ring;
use crate::photo::VoxelModel;
use crate::pipeline::{novel_view_in, NovelView, ViewParams};
use crate::{Camera, Error, Mask, Result};

/// Mean absolute difference of `a` and `b` inside the union of `ra` and `rb` (0 when both are
/// empty).
pub fn frame_step(a: &RgbImage, ra: &Mask, b: &RgbImage, rb: &Mask) -> Result<f64> {
    if a.dimensions() != b.dimensions()
        || (ra.width(), ra.height()) != a.dimensions()
        || (rb.width(), rb.height()) != a.dimensions()
    {
        return Err(Error::CountMismatch {
            what: "frame step: image and region sizes (pixels)".into(),
            a: (a.width() * a.height()) as usize,
            b: (b.width() * b.height()) as usize,
        });
    }
    let (mut sum, mut n) = (0u64, 0u64);
    let (pa, pb) = (a.as_raw(), b.as_raw());
    for i in 0..(a.width() * a.height()) as usize {
        if crate::silhouette::bit(ra, i) || crate::silhouette::bit(rb, i) {
            sum += (0..3)
                .map(|k| pa[3 * i + k].abs_diff(pb[3 * i + k]) as u64)
                .sum::<u64>();
            n += 3;
        }
    }
    Ok(if n == 0 { 0.0 } else { sum as f64 / n as f64 })
}

/// Frame-to-frame steps of an orbit ([`frame_step`]); built frame by frame with
/// [`Steadiness::push`].
#[derive(Debug, Clone, Default)]
pub struct Steadiness {
    /// Step from frame `i` to frame `i + 1`; with [`Steadiness::close`], the last one is from
    /// the last frame back to the first.
    pub steps: Vec<f64>,
    first: Option<(RgbImage, Mask)>,
    prev: Option<(RgbImage, Mask)>,
}

impl Steadiness {
    /// Adds the next frame and its object region.
    pub fn push(&mut self, img: &RgbImage, region: &Mask) -> Result<()> {
        if let Some((p, pr)) = &self.prev {
            self.steps.push(frame_step(p, pr, img, region)?);
        }
        let cur = Some((img.clone(), region.clone()));
        if self.first.is_none() {
            self.first = cur.clone();
        }
        self.prev = cur;
        Ok(())
    }

    /// Adds the step from the last frame back to the first (a whole turn).
    pub fn close(&mut self) -> Result<()> {
        if let (Some((a, ra)), Some((b, rb))) = (self.prev.take(), self.first.take()) {
            if self.steps.is_empty() {
                return Ok(());
            }
            self.steps.push(frame_step(&a, &ra, &b, &rb)?);
        }
        Ok(())
    }

    /// The median step (0 without steps).
    pub fn median(&self) -> f64 {
        let mut s = self.steps.clone();
        if s.is_empty() {
            return 0.0;
        }
        s.sort_by(f64::total_cmp);
        let m = s.len() / 2;
        if s.len() % 2 == 1 {
            s[m]
        } else {
            (s[m - 1] + s[m]) / 2.0
        }
    }

    /// The largest step and its index (step `i` is from frame `i` to the next).
    pub fn largest(&self) -> (usize, f64) {
        self.steps
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0))
    }

    /// Largest step over median step (1 when all are equal; 0 without steps).
    pub fn ratio(&self) -> f64 {
        let m = self.median();
        if m > 0.0 {
            self.largest().1 / m
        } else {
            0.0
        }
    }
}

/// One line: median and largest step and their ratio.
impl std::fmt::Display for Steadiness {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (i, big) = self.largest();
        let n = self.steps.len();
        write!(
            f,
            "steadiness: frame-to-frame change inside the object (mean absolute difference, 0-255) median {:.2}, largest {big:.2} (frames {i}-{}), largest/median {:.2}",
            self.median(),
            (i + 1) % n.max(1),
            self.ratio()
        )
    }
}

/// Renders `frames` views evenly around `ring` (frame `i` at `360 i / frames` degrees, looking at
/// `target`), each made as `view` says from the model and the reference photos, handing each to
/// `each(i, angle, view)`; returns the steps of the whole turn.
#[allow(clippy::too_many_arguments)]
pub fn orbit<E: From<Error>>(
    model: &VoxelModel,
    cams: &[Camera],
    images: &[RgbImage],
    silhouettes: Option<&[Mask]>,
    ring: &Ring,
    target: &Vector3<f64>,
    frames: usize,
    (w, h): (u32, u32),
    view: &ViewParams,
    each: &mut dyn FnMut(usize, f64, &NovelView) -> std::result::Result<(), E>,
) -> std::result::Result<Steadiness, E> {
    let mut steady = Steadiness::default();
    for i in 0..frames {
        let angle = 360.0 * i as f64 / frames as f64;
        let cam = ring.camera(angle, target)?;
        let v = novel_view_in(model, cams, images, silhouettes, &cam, w, h, view)?;
        steady.push(&v.guided, &v.rough.coverage)?;
        each(i, angle, &v)?;
    }
    steady.close()?;
    Ok(steady)
}
