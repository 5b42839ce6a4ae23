//! Whole-pipeline helpers: new views from a model, and leave-one-out evaluation.

use std::time::Instant;

use image::RgbImage;

use crate::camera::Camera;
use crate::eval::{psnr, ssim};
use crate::hull::HullParams;
use crate::photo::{PhotoParams, VoxelModel};
use crate::render::{render_rough, Rendered};
use crate::silhouette::Mask;
use crate::synthesis::{guided_synthesis, SynthParams};
use crate::{build_model, Error, Result};

/// The reference camera whose viewing direction is closest in angle to `cam`'s (the paper picks
/// the nearest reference photo as the synthesis input).
pub fn nearest_reference(cams: &[Camera], cam: &Camera) -> Option<usize> {
    let f = cam.forward();
    (0..cams.len()).max_by(|&a, &b| {
        cams[a]
            .forward()
            .dot(&f)
            .total_cmp(&cams[b].forward().dot(&f))
    })
}

/// A new view: the rough render and its guided synthesis.
#[derive(Debug, Clone)]
pub struct NovelView {
    /// The rough render (the guide).
    pub rough: Rendered,
    /// The guided synthesis result.
    pub guided: RgbImage,
    /// Index of the reference photo used as synthesis input.
    pub reference: usize,
}

/// Renders `model` from `cam` and synthesises the view from the nearest reference photo.
pub fn novel_view(
    model: &VoxelModel,
    cams: &[Camera],
    images: &[RgbImage],
    cam: &Camera,
    w: u32,
    h: u32,
    synth: &SynthParams,
) -> Result<NovelView> {
    let reference = nearest_reference(cams, cam).ok_or(Error::TooFew {
        what: "reference cameras".into(),
        got: 0,
        need: 1,
    })?;
    let rough = render_rough(model, cam, w, h);
    let guided = guided_synthesis(&images[reference], &rough.image, synth)?;
    Ok(NovelView {
        rough,
        guided,
        reference,
    })
}

/// Scores of a withheld view, measured inside its silhouette.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalReport {
    /// The withheld view.
    pub withheld: usize,
    /// The reference photo used as synthesis input (index into all views).
    pub reference: usize,
    /// PSNR of the rough render, dB.
    pub psnr_rough: f64,
    /// PSNR of the guided synthesis, dB.
    pub psnr_guided: f64,
    /// SSIM of the rough render.
    pub ssim_rough: f64,
    /// SSIM of the guided synthesis.
    pub ssim_guided: f64,
    /// Surface voxels of the model.
    pub surface_voxels: usize,
    /// Seconds to build the model.
    pub model_secs: f64,
    /// Seconds to render and synthesise.
    pub synth_secs: f64,
}

/// Builds the model from every view but `withheld`, renders that view rough and guided, and
/// scores both against the withheld photo inside its silhouette.
pub fn leave_one_out(
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    withheld: usize,
    hull: &HullParams,
    photo: &PhotoParams,
    synth: &SynthParams,
) -> Result<EvalReport> {
    if withheld >= cams.len() || cams.len() != images.len() || cams.len() != masks.len() {
        return Err(Error::CountMismatch {
            what: format!("withheld view {withheld} of cameras/images/masks"),
            a: cams.len(),
            b: images.len().min(masks.len()),
        });
    }
    let keep: Vec<usize> = (0..cams.len()).filter(|&i| i != withheld).collect();
    let sub_cams: Vec<Camera> = keep.iter().map(|&i| cams[i].clone()).collect();
    let sub_imgs: Vec<RgbImage> = keep.iter().map(|&i| images[i].clone()).collect();
    let sub_masks: Vec<Mask> = keep.iter().map(|&i| masks[i].clone()).collect();
    let t = Instant::now();
    let model = build_model(
        &sub_cams,
        &sub_imgs,
        &sub_masks,
        hull,
        photo,
        &mut |_, _, _| {},
    )?;
    let model_secs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (w, h) = images[withheld].dimensions();
    let view = novel_view(&model, &sub_cams, &sub_imgs, &cams[withheld], w, h, synth)?;
    let synth_secs = t.elapsed().as_secs_f64();
    let truth = &images[withheld];
    let m = Some(&masks[withheld]);
    Ok(EvalReport {
        withheld,
        reference: keep[view.reference],
        psnr_rough: psnr(&view.rough.image, truth, m)?,
        psnr_guided: psnr(&view.guided, truth, m)?,
        ssim_rough: ssim(&view.rough.image, truth, m)?,
        ssim_guided: ssim(&view.guided, truth, m)?,
        surface_voxels: model.surface.len(),
        model_secs,
        synth_secs,
    })
}
