//! Whole-pipeline helpers: new views from a model (the paper's method or view-dependent
//! texturing), and leave-one-out evaluation against the obvious baselines.

use std::time::Instant;

use image::{Rgb, RgbImage};

use crate::camera::Camera;
use crate::eval::{psnr, ssim};
use crate::guided::{guided_synthesis, GuidedParams};
use crate::hull::{visual_hull, HullParams};
use crate::photo::{photo_hull_keeping, PhotoParams, VoxelModel};
use crate::render::{
    clip_to_free_space, clip_to_hull, grow_to_silhouettes, render_rough, ClipParams,
    DepthClipParams, HullTest, Rendered,
};
use crate::silhouette::Mask;
use crate::texture::{model_centre, nearest_by_direction, texture_view, TextureParams};
use crate::voting::{voting_synthesis, VotingParams};
use crate::{Error, Result};

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

/// How a new view is made from the model and the photos.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// The rough render alone: the voxel model's own colours (each voxel the mean of the photos
    /// that see it), trimmed to the silhouettes when they are given. Blocky; the baseline.
    Rough,
    /// The paper (SPEC B.4-B.6): the rough render (flat voxel colours) is the guide; guided
    /// synthesis re-textures it from the one nearest reference photo.
    Paper,
    /// View-dependent texturing ([`crate::texture`]): the nearest reference photos projected
    /// onto the voxel surface with visibility, holes filled; optionally refined by guided
    /// synthesis ([`ViewParams::refine`]).
    Textured,
}

/// New-view settings. [`Default`] is the measured best (see docs/system-b.md): view-dependent
/// texturing without synthesis refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewParams {
    /// The method.
    pub method: Method,
    /// Guided synthesis settings (the paper's method, and [`Method::Textured`] with `refine`).
    pub guided: GuidedParams,
    /// View-dependent texturing settings ([`Method::Textured`]).
    pub texture: TextureParams,
    /// [`Method::Textured`]: run guided synthesis from the nearest photo with the textured view
    /// as the guide.
    pub refine: bool,
    /// Trim the rough render to the visual hull at pixel accuracy when the reference
    /// silhouettes are given ([`novel_view_in`]; `Some` by default, `None` = splats as they
    /// fall).
    pub clip: Option<ClipParams>,
    /// [`Method::Textured`] with the reference silhouettes: before texturing, grow the
    /// (clipped) render's coverage this many pixel rings out to the visual hull
    /// ([`grow_to_silhouettes`], searched as `clip` says) so the texturing fills the rim and
    /// cracks no splat covers (4; 0 = off). The rough render itself is left as it is.
    pub grow: u32,
    /// With `refine`: refine by patch voting ([`crate::voting`]) with these settings instead
    /// of the paper's synthesis (`None`, the default).
    pub voting: Option<VotingParams>,
    /// With `clip` and a model that holds the photos' depth maps (stereo on): move the render
    /// past the free space they prove, at pixel accuracy
    /// ([`crate::render::clip_to_depths`]; on, `None` = off).
    pub depth_clip: Option<DepthClipParams>,
}

impl Default for ViewParams {
    fn default() -> Self {
        Self {
            method: Method::Textured,
            guided: GuidedParams::fast_for(7),
            texture: TextureParams::default(),
            refine: false,
            clip: Some(ClipParams::default()),
            grow: 0,
            voting: None,
            depth_clip: Some(DepthClipParams::default()),
        }
    }
}

impl ViewParams {
    /// The method's name: `rough`, `paper`, `textured` or `textured+synthesis`.
    pub fn name(&self) -> &'static str {
        match (self.method, self.refine) {
            (Method::Rough, _) => "rough",
            (Method::Paper, _) => "paper",
            (Method::Textured, false) => "textured",
            (Method::Textured, true) => "textured+synthesis",
        }
    }

    /// What the method does, in plain words (no photo names: those are
    /// [`NovelView::describe`]'s).
    pub fn describe(&self) -> String {
        match self.method {
            Method::Rough => "rough: the voxel model's own colours (each voxel the mean of the photos that see it), no photo texture".to_string(),
            Method::Paper => format!(
                "paper: the rough render re-textured by guided synthesis (PatchMatch, patch {}) from the nearest photo",
                self.guided.patch
            ),
            Method::Textured => format!(
                "textured: the {} photo{} nearest in viewing direction (and the next one, fading in or out as the view moves){} projected onto the voxel model's surface, blended per pixel and softened where they disagree{}",
                self.texture.references,
                if self.texture.references == 1 { "" } else { "s" },
                if self.texture.reach_deg > 0.0 {
                    format!(", with every other within {} degrees,", self.texture.reach_deg)
                } else {
                    String::new()
                },
                if self.refine {
                    ", then refined by guided synthesis"
                } else {
                    ""
                }
            ),
        }
    }

    /// The paper's method with these synthesis settings (the rough render as the paper makes
    /// it: splats, no [`ViewParams::clip`]).
    pub fn paper(guided: GuidedParams) -> Self {
        Self {
            method: Method::Paper,
            guided,
            clip: None,
            grow: 0,
            depth_clip: None,
            ..Self::default()
        }
    }
}

/// The choices behind [`ViewParams`], as a user gives them (checked by [`ViewOptions::params`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewOptions {
    /// The method.
    pub method: Method,
    /// Patch side of the guided synthesis, odd, at least 3.
    pub patch: usize,
    /// Paper-exact synthesis (no speed options).
    pub exact: bool,
    /// [`ViewParams::refine`] ([`Method::Textured`] only).
    pub refine: bool,
    /// [`TextureParams::references`], 1..=64.
    pub references: usize,
}

impl ViewOptions {
    /// The settings for `w x h` photos, or the first option out of range.
    pub fn params(&self, w: u32, h: u32) -> Result<ViewParams> {
        let bad = |name: &str, value: String, why: String| Error::BadParam {
            name: name.into(),
            value,
            why,
        };
        let patch = self.patch;
        if patch.is_multiple_of(2) || patch < 3 {
            return Err(bad(
                "patch",
                patch.to_string(),
                "must be odd and at least 3".into(),
            ));
        }
        if patch as u32 > w.min(h) {
            let why = format!("larger than the {w}x{h} reference photos");
            return Err(bad("patch", patch.to_string(), why));
        }
        if self.references == 0 || self.references > 64 {
            let why = "must be in 1..=64".to_string();
            return Err(bad("references", self.references.to_string(), why));
        }
        if self.refine && self.method != Method::Textured {
            let why = "applies to the textured method only".to_string();
            return Err(bad("refine", String::new(), why));
        }
        let guided = if self.exact {
            GuidedParams {
                patch,
                ..Default::default()
            }
        } else {
            GuidedParams::fast_for(patch)
        };
        Ok(match self.method {
            Method::Rough => ViewParams {
                method: Method::Rough,
                guided,
                ..ViewParams::default()
            },
            Method::Paper => ViewParams::paper(guided),
            Method::Textured => {
                let mut p = ViewParams {
                    guided,
                    refine: self.refine,
                    ..ViewParams::default()
                };
                p.texture.references = self.references;
                p
            }
        })
    }
}

/// A new view: the rough render, the guide and the result.
#[derive(Debug, Clone)]
pub struct NovelView {
    /// The rough render (flat voxel colours).
    pub rough: Rendered,
    /// The synthesis guide: the rough image ([`Method::Paper`]) or the textured view.
    pub guide: RgbImage,
    /// The result.
    pub guided: RgbImage,
    /// The nearest reference photo (the synthesis input), index into the cameras.
    pub reference: usize,
    /// The reference photos the view was made from, nearest first ([`Method::Textured`]: the
    /// ones blended; otherwise the nearest alone, or none for [`Method::Rough`]).
    pub references: Vec<usize>,
    /// Seconds per stage, in order: rough render, clip and grow (with silhouettes), texturing,
    /// synthesis.
    pub times: Vec<(&'static str, f64)>,
}

impl NovelView {
    /// How the view was made, in plain words, e.g. `textured: the 2 photos nearest in viewing
    /// direction (a.png, b.png) projected onto the voxel model's surface and blended per pixel`.
    pub fn describe(&self, cams: &[Camera], p: &ViewParams) -> String {
        let names: Vec<&str> = self
            .references
            .iter()
            .map(|&i| cams[i].name.as_str())
            .collect();
        match p.method {
            Method::Rough => "rough: the voxel model's own colours (each voxel the mean of the photos that see it), no photo texture".to_string(),
            Method::Paper => format!(
                "paper: the rough render re-textured by guided synthesis (PatchMatch, patch {}) from the nearest photo ({})",
                p.guided.patch,
                cams[self.reference].name
            ),
            Method::Textured => format!(
                "textured: the {} photo{} nearest in viewing direction ({}) projected onto the voxel model's surface, blended per pixel (weights fading as the view moves) and softened where they disagree{}",
                p.texture.references.min(names.len()),
                if p.texture.references.min(names.len()) == 1 { "" } else { "s" },
                if names.len() > p.texture.references {
                    format!(
                        "{}; the next, fading: {}",
                        names[..p.texture.references].join(", "),
                        names[p.texture.references..].join(", ")
                    )
                } else {
                    names.join(", ")
                },
                if p.refine {
                    ", then refined by guided synthesis"
                } else {
                    ""
                }
            ),
        }
    }
}

/// Renders `model` from `cam` and makes the new view as `p` says.
pub fn novel_view(
    model: &VoxelModel,
    cams: &[Camera],
    images: &[RgbImage],
    cam: &Camera,
    w: u32,
    h: u32,
    p: &ViewParams,
) -> Result<NovelView> {
    novel_view_in(model, cams, images, None, cam, w, h, p)
}

/// [`novel_view`] with the reference cameras' silhouettes (the ones the model was carved
/// from): the rough render is then trimmed to them at pixel accuracy as [`ViewParams::clip`]
/// says ([`crate::render::clip_to_silhouettes`]) before anything is made from it.
#[allow(clippy::too_many_arguments)]
pub fn novel_view_in(
    model: &VoxelModel,
    cams: &[Camera],
    images: &[RgbImage],
    silhouettes: Option<&[Mask]>,
    cam: &Camera,
    w: u32,
    h: u32,
    p: &ViewParams,
) -> Result<NovelView> {
    if let Some(m) = silhouettes {
        if m.len() != cams.len() {
            return Err(Error::CountMismatch {
                what: "cameras vs silhouettes".into(),
                a: cams.len(),
                b: m.len(),
            });
        }
    }
    let reference = nearest_reference(cams, cam).ok_or(Error::TooFew {
        what: "reference cameras".into(),
        got: 0,
        need: 1,
    })?;
    let mut times = Vec::new();
    let t = Instant::now();
    let mut rough = render_rough(model, cam, w, h);
    times.push(("rough render", t.elapsed().as_secs_f64()));
    // The clip as the silhouettes allow (exact ones need no closing or slack).
    let clip = match (silhouettes, &p.clip) {
        (Some(m), Some(c)) => Some(c.for_silhouettes(cams, m, &model.grid.bounds())),
        _ => None,
    };
    if let (Some(m), Some(c)) = (silhouettes, &clip) {
        let t = Instant::now();
        // The silhouettes closed and grown once for both clips.
        let hull = HullTest::new(cams, m, c.close, c.slack);
        clip_to_hull(&mut rough, model, cam, &hull, c);
        if let Some(dc) = &p.depth_clip {
            clip_to_free_space(&mut rough, model, cam, &hull, dc);
        }
        times.push(("clip", t.elapsed().as_secs_f64()));
    }
    let (guide, references, synthesise) = match p.method {
        Method::Rough => (rough.image.clone(), Vec::new(), false),
        Method::Paper => (rough.image.clone(), vec![reference], true),
        Method::Textured => {
            let grown = match (silhouettes, &clip) {
                (Some(m), Some(c)) if p.grow > 0 => {
                    let t = Instant::now();
                    let mut g = rough.clone();
                    grow_to_silhouettes(&mut g, model, cam, cams, m, c, p.grow);
                    times.push(("grow", t.elapsed().as_secs_f64()));
                    Some(g)
                }
                _ => None,
            };
            let t = Instant::now();
            let base = grown.as_ref().unwrap_or(&rough);
            let backdrop = silhouettes
                .and_then(|m| crate::silhouette::colour_outside(images, m))
                .unwrap_or([0; 3]);
            let tex = texture_view(model, cams, images, cam, base, &p.texture, backdrop)?;
            times.push(("texturing", t.elapsed().as_secs_f64()));
            (tex.image, tex.references, p.refine)
        }
    };
    let reference = references.first().copied().unwrap_or(reference);
    let guided = if synthesise {
        let t = Instant::now();
        let g = match (&p.voting, p.method) {
            (Some(v), Method::Textured) => voting_synthesis(&images[reference], &guide, v)?,
            _ => guided_synthesis(&images[reference], &guide, &p.guided)?,
        };
        times.push(("synthesis", t.elapsed().as_secs_f64()));
        g
    } else {
        guide.clone()
    };
    Ok(NovelView {
        rough,
        guide,
        guided,
        reference,
        references,
        times,
    })
}

/// PSNR (dB) and SSIM of one image against the withheld photo.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Score {
    /// PSNR in dB.
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
}

/// Scores inside the withheld photo's silhouette and over the whole image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// Inside the withheld photo's silhouette.
    pub inside: Score,
    /// Over the whole image.
    pub whole: Score,
}

/// Scores `img` against `truth`, inside `mask` and over the whole image.
pub fn score(img: &RgbImage, truth: &RgbImage, mask: &Mask) -> Result<Scores> {
    Ok(Scores {
        inside: Score {
            psnr: psnr(img, truth, Some(mask))?,
            ssim: ssim(img, truth, Some(mask))?,
        },
        whole: Score {
            psnr: psnr(img, truth, None)?,
            ssim: ssim(img, truth, None)?,
        },
    })
}

/// PSNR and SSIM over the withheld photo's silhouette `mask` united with the pixels `region`
/// covers (not black; pass the image itself, or the unblurred render a blurred baseline comes
/// from). [`score`]'s `inside` never sees pixels outside the silhouette, so an object region
/// grown past the true outline fills the silhouette's rim at no cost there; here it pays for
/// what it paints over the backdrop.
pub fn score_with_region(
    img: &RgbImage,
    truth: &RgbImage,
    mask: &Mask,
    region: &RgbImage,
) -> Result<Score> {
    if region.dimensions() != (mask.width(), mask.height()) {
        return Err(Error::BadParam {
            name: "region".into(),
            value: format!("{}x{}", region.width(), region.height()),
            why: format!(
                "must be the silhouette's {}x{}",
                mask.width(),
                mask.height()
            ),
        });
    }
    let union = Mask::from_fn(mask.width(), mask.height(), |x, y| {
        mask.get(x, y) || region.get_pixel(x, y).0 != [0, 0, 0]
    });
    Ok(score(img, truth, &union)?.inside)
}

/// Intersection over union of two masks of the same size (1 when both are empty).
pub fn iou(a: &Mask, b: &Mask) -> f64 {
    let (mut inter, mut union) = (0u64, 0u64);
    for (x, y) in a.words().iter().zip(b.words()) {
        inter += (x & y).count_ones() as u64;
        union += (x | y).count_ones() as u64;
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// The rough render blurred by a Gaussian of sigma 2 (kernel 13, OpenCV's size for 8-bit
/// images at that sigma): the baseline a smoothing method has to beat.
pub fn blur2(img: &RgbImage) -> Result<RgbImage> {
    vt_core::blur::gaussian_blur(
        img,
        &vt_core::blur::GaussianParams {
            ksize: 13,
            sigma: 2.0,
        },
    )
    .map_err(|e| Error::BadParam {
        name: "blur".into(),
        value: "sigma 2".into(),
        why: e.to_string(),
    })
}

/// An error map: per pixel, 4x the mean absolute channel difference as grey, with the truth
/// silhouette's outline in red.
pub fn error_map(img: &RgbImage, truth: &RgbImage, mask: &Mask) -> RgbImage {
    RgbImage::from_fn(truth.width(), truth.height(), |x, y| {
        let (a, b) = (img.get_pixel(x, y).0, truth.get_pixel(x, y).0);
        let e: u32 = (0..3).map(|k| a[k].abs_diff(b[k]) as u32).sum();
        let g = (e * 4 / 3).min(255) as u8;
        let (xi, yi) = (x as i64, y as i64);
        let edge = mask.get(x, y)
            && [(-1, 0), (1, 0), (0, -1), (0, 1)]
                .iter()
                .any(|(dx, dy)| !mask.get_or_false(xi + dx, yi + dy));
        if edge {
            Rgb([255, 0, 0])
        } else {
            Rgb([g, g, g])
        }
    })
}

/// Scores of a withheld view: the result and three baselines, and the model's silhouette.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalReport {
    /// The withheld view.
    pub withheld: usize,
    /// The nearest reference photo (index into all views).
    pub reference: usize,
    /// The nearest reference photo as it is (no warping).
    pub nearest_photo: Scores,
    /// The rough render (flat voxel colours).
    pub rough: Scores,
    /// The rough render blurred with a Gaussian of sigma 2.
    pub rough_blur2: Scores,
    /// The synthesis guide (the rough render for the paper's method, else the textured view).
    pub guide: Scores,
    /// The result.
    pub guided: Scores,
    /// IoU of the rough render's coverage against the withheld photo's silhouette.
    pub silhouette_iou: f64,
    /// Surface voxels of the model.
    pub surface_voxels: usize,
    /// Seconds per stage: visual hull, photo hull, rough render, clip, grow, texturing, synthesis,
    /// scoring.
    pub times: Vec<(&'static str, f64)>,
}

impl EvalReport {
    /// The scored images by name, in table order: `nearest_photo`, `rough`, `rough_blur2`,
    /// `guide`, `guided`.
    pub fn candidates(&self) -> [(&'static str, Scores); 5] {
        [
            ("nearest_photo", self.nearest_photo),
            ("rough", self.rough),
            ("rough_blur2", self.rough_blur2),
            ("guide", self.guide),
            ("guided", self.guided),
        ]
    }

    /// Seconds in all stages.
    pub fn total_secs(&self) -> f64 {
        self.times.iter().map(|t| t.1).sum()
    }

    /// Seconds to build the model (visual and photo hull).
    pub fn model_secs(&self) -> f64 {
        self.stage_secs(&["visual hull", "photo hull"])
    }

    /// Seconds to make the new view (render, texturing, synthesis).
    pub fn view_secs(&self) -> f64 {
        self.stage_secs(&["rough render", "clip", "grow", "texturing", "synthesis"])
    }

    fn stage_secs(&self, names: &[&str]) -> f64 {
        self.times
            .iter()
            .filter(|(n, _)| names.contains(n))
            .map(|(_, s)| s)
            .sum()
    }
}

/// The score table: PSNR and SSIM of each candidate inside the silhouette and over the whole
/// image, the silhouette IoU and the seconds per stage.
impl std::fmt::Display for EvalReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let head = ["image", "PSNR in", "SSIM in", "PSNR all", "SSIM all"];
        let [a, b, c, d, e] = head;
        writeln!(f, "{a:<14} {b:>10} {c:>8} {d:>10} {e:>8}")?;
        for (name, s) in self.candidates() {
            let (i, o) = (s.inside, s.whole);
            writeln!(
                f,
                "{name:<14} {:>10.2} {:>8.3} {:>10.2} {:>8.3}",
                i.psnr, i.ssim, o.psnr, o.ssim
            )?;
        }
        writeln!(
            f,
            "silhouette IoU (rough render vs withheld photo) {:.3}; {} surface voxels",
            self.silhouette_iou, self.surface_voxels
        )?;
        let stages: Vec<String> = self
            .times
            .iter()
            .map(|(n, s)| format!("{n} {s:.2}"))
            .collect();
        write!(
            f,
            "seconds: {} (total {:.2})",
            stages.join(", "),
            self.total_secs()
        )
    }
}

/// The images of a leave-one-out run, for saving.
#[derive(Debug, Clone)]
pub struct EvalImages {
    /// The withheld photo.
    pub truth: RgbImage,
    /// The nearest reference photo.
    pub nearest_photo: RgbImage,
    /// The rough render.
    pub rough: RgbImage,
    /// The rough render blurred (sigma 2).
    pub rough_blur2: RgbImage,
    /// The guide.
    pub guide: RgbImage,
    /// The result.
    pub guided: RgbImage,
}

/// Builds the model from every view but `withheld`, makes that view as `view` says, and scores
/// it and the baselines against the withheld photo.
pub fn leave_one_out(
    cams: &[Camera],
    images: &[RgbImage],
    masks: &[Mask],
    withheld: usize,
    hull: &HullParams,
    photo: &PhotoParams,
    view: &ViewParams,
) -> Result<(EvalReport, EvalImages)> {
    if withheld >= cams.len() || cams.len() != images.len() || cams.len() != masks.len() {
        return Err(Error::CountMismatch {
            what: format!("withheld view {withheld} of cameras/images/masks"),
            a: cams.len(),
            b: images.len().min(masks.len()),
        });
    }
    let keep: Vec<usize> = (0..cams.len()).filter(|&i| i != withheld).collect();
    let others = Others::of(cams, images, masks, &keep);
    let view_k = (
        withheld,
        &cams[withheld],
        &images[withheld],
        &masks[withheld],
    );
    leave_one_out_from(&others, &keep, view_k, hull, photo, view)
}

/// The views a model is built from when one is withheld: one copy of each of the others.
pub(crate) struct Others {
    pub cams: Vec<Camera>,
    pub images: Vec<RgbImage>,
    pub masks: Vec<Mask>,
}

impl Others {
    /// The views at `keep`.
    pub(crate) fn of(cams: &[Camera], images: &[RgbImage], masks: &[Mask], keep: &[usize]) -> Self {
        Self {
            cams: keep.iter().map(|&i| cams[i].clone()).collect(),
            images: keep.iter().map(|&i| images[i].clone()).collect(),
            masks: keep.iter().map(|&i| masks[i].clone()).collect(),
        }
    }
}

/// [`leave_one_out`] from the other views (`keep` are their indices among all views) and the
/// withheld view `(index, camera, photo, scoring silhouette)`.
pub(crate) fn leave_one_out_from(
    others: &Others,
    keep: &[usize],
    (withheld, cam, truth, mask): (usize, &Camera, &RgbImage, &Mask),
    hull: &HullParams,
    photo: &PhotoParams,
    view: &ViewParams,
) -> Result<(EvalReport, EvalImages)> {
    let (sub_cams, sub_imgs, sub_masks) = (&others.cams, &others.images, &others.masks);
    let mut times = Vec::new();
    let t = Instant::now();
    let grid = visual_hull(sub_cams, sub_masks, hull)?;
    times.push(("visual hull", t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let model = photo_hull_keeping(
        grid,
        sub_cams,
        sub_imgs,
        Some(sub_masks),
        photo,
        &mut |_, _, _| {},
    )?;
    times.push(("photo hull", t.elapsed().as_secs_f64()));
    score_withheld(
        others,
        keep,
        (withheld, cam, truth, mask),
        &model,
        view,
        times,
    )
}

/// The scoring half of [`leave_one_out_from`]: makes the withheld view from `model` (built from
/// `others`) and scores it and the baselines; `times` holds the build's stages.
pub(crate) fn score_withheld(
    others: &Others,
    keep: &[usize],
    (withheld, cam, truth, mask): (usize, &Camera, &RgbImage, &Mask),
    model: &VoxelModel,
    view: &ViewParams,
    mut times: Vec<(&'static str, f64)>,
) -> Result<(EvalReport, EvalImages)> {
    let (sub_cams, sub_imgs, sub_masks) = (&others.cams, &others.images, &others.masks);
    let (w, h) = truth.dimensions();
    let v = novel_view_in(model, sub_cams, sub_imgs, Some(sub_masks), cam, w, h, view)?;
    times.extend(v.times.iter().copied());
    let t = Instant::now();
    // The baseline photo: nearest by direction from the object, as the texturing picks it.
    let nearest = nearest_by_direction(sub_cams, cam, &model_centre(model), 1)[0];
    let blurred = blur2(&v.rough.image)?;
    let report = EvalReport {
        withheld,
        reference: keep[nearest],
        nearest_photo: score(&sub_imgs[nearest], truth, mask)?,
        rough: score(&v.rough.image, truth, mask)?,
        rough_blur2: score(&blurred, truth, mask)?,
        guide: score(&v.guide, truth, mask)?,
        guided: score(&v.guided, truth, mask)?,
        silhouette_iou: iou(&v.rough.coverage, mask),
        surface_voxels: model.surface.len(),
        times: {
            times.push(("scoring", t.elapsed().as_secs_f64()));
            times
        },
    };
    let imgs = EvalImages {
        truth: truth.clone(),
        nearest_photo: sub_imgs[nearest].clone(),
        rough: v.rough.image,
        rough_blur2: blurred,
        guide: v.guide,
        guided: v.guided,
    };
    Ok((report, imgs))
}
