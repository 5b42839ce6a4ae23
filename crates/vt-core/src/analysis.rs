//! The offline half of System A (seed thesis Sec. 3.2, SPEC A-1..A-3) as one pipeline over
//! frame sources: backgrounds, masks, loops, the scene's geometric model, homographies between
//! neighbouring views, and transition tables.
//!
//! Frames stream: a view is read once for its median background and once more for its masks,
//! unless its frames fit in [`AnalyzeParams::cache_bytes`], in which case the first pass keeps them
//! and the second pass reads memory. Only masks (one bit per pixel) are kept for all views.

use std::time::{Duration, Instant};

use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::appearance::{self, change_thumb, thumb_factor, Thumb};
use crate::blur::{gaussian_blur, gaussian_blur_into, BlurScratch, GaussianBlur, GaussianParams};
use crate::loops::{check_loop_input, loops_from_pair_costs, pair_costs, Loop, LoopParams};
use crate::median::{temporal_median, temporal_median_frames, MedianAccumulator};
use crate::model::{select_model, ModelParams, MotionModel, Selection};
use crate::noise::{
    noise_mask, noise_model, pair_change, FrameSample, MotionKept, NoiseModel, NoiseParams,
};
use crate::parallax::{BackgroundMode, PairParallax, ParallaxFigures};
use crate::register::RegisterParams;
use crate::transition::{
    seam_score, transition_range, transitions_from_pair_costs, warp_masks, xor_pair_costs,
};
use crate::yuv::Yuv420Image;
use crate::{Error, Homography, Mask, Point, Result};

/// Where a view's frames come from. Implemented by the decoders in `vt-io` and by in-memory
/// sequences in tests. [`FrameSource::for_each_frame`] may be called more than once and must yield
/// the same frames each time.
pub trait FrameSource {
    /// A name for messages (usually the path).
    fn name(&self) -> &str;
    /// Calls `f(index, frame)` for every frame in order and returns how many there were.
    fn for_each_frame(
        &mut self,
        f: &mut dyn FnMut(usize, &RgbImage) -> Result<()>,
    ) -> Result<usize>;
    /// Like [`FrameSource::for_each_frame`], but in the form the source holds its frames: a video
    /// decoder may give 4:2:0 frames, half the bytes of RGB, which the analysis keeps between its
    /// passes as they are. The frames must be the ones [`FrameSource::for_each_frame`] gives
    /// once converted ([`FrameRef::to_rgb_into`]). The default hands out the RGB frames.
    fn for_each_native(
        &mut self,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        self.for_each_frame(&mut |i, rgb| f(i, FrameRef::Rgb(rgb)))
    }
}

/// A frame as its source holds it.
#[derive(Debug, Clone, Copy)]
pub enum FrameRef<'a> {
    /// Interleaved RGB.
    Rgb(&'a RgbImage),
    /// Planar 4:2:0, as video decoders give it.
    Yuv420(&'a Yuv420Image),
}

impl FrameRef<'_> {
    /// `(width, height)`.
    pub fn dimensions(&self) -> (u32, u32) {
        match self {
            FrameRef::Rgb(f) => f.dimensions(),
            FrameRef::Yuv420(f) => f.dimensions(),
        }
    }

    /// Bytes the frame takes.
    pub fn byte_len(&self) -> usize {
        match self {
            FrameRef::Rgb(f) => f.as_raw().len(),
            FrameRef::Yuv420(f) => f.as_raw().len(),
        }
    }

    /// An owned copy.
    pub fn to_owned(&self) -> Frame {
        match self {
            FrameRef::Rgb(f) => Frame::Rgb((*f).clone()),
            FrameRef::Yuv420(f) => Frame::Yuv420((*f).clone()),
        }
    }

    /// The frame in RGB, in `out` (resized if needed).
    pub fn to_rgb_into(&self, out: &mut RgbImage) {
        match self {
            FrameRef::Rgb(f) => {
                if out.dimensions() == f.dimensions() {
                    out.copy_from_slice(f.as_raw());
                } else {
                    *out = (*f).clone();
                }
            }
            FrameRef::Yuv420(f) => f.to_rgb_into(out),
        }
    }

    /// The frame in RGB: borrowed when it is RGB already, else converted into `buf`.
    pub fn rgb<'b>(&'b self, buf: &'b mut RgbImage) -> &'b RgbImage {
        match self {
            FrameRef::Rgb(f) => f,
            FrameRef::Yuv420(f) => {
                f.to_rgb_into(buf);
                buf
            }
        }
    }
}

/// An owned frame in its source's form (the analysis's frame cache).
#[derive(Debug, Clone)]
pub enum Frame {
    /// Interleaved RGB.
    Rgb(RgbImage),
    /// Planar 4:2:0.
    Yuv420(Yuv420Image),
}

impl Frame {
    /// Borrowed.
    pub fn as_ref(&self) -> FrameRef<'_> {
        match self {
            Frame::Rgb(f) => FrameRef::Rgb(f),
            Frame::Yuv420(f) => FrameRef::Yuv420(f),
        }
    }
}

/// Frames already in memory.
pub struct MemorySource {
    /// Name for messages.
    pub name: String,
    /// The frames.
    pub frames: Vec<RgbImage>,
}

impl FrameSource for MemorySource {
    fn name(&self) -> &str {
        &self.name
    }
    fn for_each_frame(
        &mut self,
        f: &mut dyn FnMut(usize, &RgbImage) -> Result<()>,
    ) -> Result<usize> {
        for (i, fr) in self.frames.iter().enumerate() {
            f(i, fr)?;
        }
        Ok(self.frames.len())
    }
}

/// Background subtraction. The thesis gives no threshold; vt's rule, documented here and
/// in the README: after both are smoothed, a pixel is *moving* when
/// `max over R,G,B of |frame - background| > threshold`. Then an optional opening (removes
/// specks) and closing (fills holes), radii in pixels, 0 = off (the thesis has neither).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MaskParams {
    /// Grey levels; default 25, about 10% of full scale, well above sensor noise after a 3x3 blur.
    pub threshold: u8,
    /// Opening radius (square of side 2r+1), 0 = off.
    pub open_radius: u32,
    /// Closing radius, 0 = off.
    pub close_radius: u32,
}

impl Default for MaskParams {
    fn default() -> Self {
        Self {
            threshold: 25,
            open_radius: 0,
            close_radius: 0,
        }
    }
}

/// The raw threshold step of [`MaskParams`] (no clean-up) on two smoothed images.
pub fn threshold_mask(frame: &RgbImage, background: &RgbImage, threshold: u8) -> Result<Mask> {
    if frame.dimensions() != background.dimensions() {
        return Err(Error::SizeMismatch {
            what: "mask frame vs background".into(),
            expected_w: background.width(),
            expected_h: background.height(),
            got_w: frame.width(),
            got_h: frame.height(),
        });
    }
    Mask::from_rgb_difference(
        frame.width(),
        frame.height(),
        frame.as_raw(),
        background.as_raw(),
        threshold,
    )
}

/// [`threshold_mask`] followed by the clean-up of `params`.
pub fn foreground_mask(
    frame: &RgbImage,
    background: &RgbImage,
    params: &MaskParams,
) -> Result<Mask> {
    let m = threshold_mask(frame, background, params.threshold)?;
    Ok(m.open(params.open_radius).close(params.close_radius))
}

/// Everything the analysis can be tuned by.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AnalyzeParams {
    /// Smoothing before subtraction (thesis: 3x3).
    pub blur: GaussianParams,
    /// Background subtraction.
    pub mask: MaskParams,
    /// Eq. (1) and (2) window and minimum loop length.
    pub loops: LoopParams,
    /// Geometric model selection.
    pub model: ModelParams,
    /// Per-pixel noise-model masks and the dynamic region ([`crate::noise`]); scenes written
    /// before it existed read as [`NoiseParams::off`].
    #[serde(default = "NoiseParams::off")]
    pub noise: NoiseParams,
    /// Weight of the appearance term in eq. (1) and (2) ([`crate::appearance`]; 0 = masks only,
    /// the thesis, and what scenes written before it existed used).
    #[serde(default)]
    pub appearance: f32,
    /// Refine each `H_(p,p+1)` by aligning the two median backgrounds ([`crate::align`]); scenes
    /// written before it existed read as off.
    #[serde(default)]
    pub refine: bool,
    /// Also report this many next-best *distinct* loops per view (see
    /// [`crate::loops::find_loops`]; distinct = more than `window` frames apart in m or n).
    #[serde(default)]
    pub alternative_loops: usize,
    /// The median background from at most this many evenly spaced frames of each view (the
    /// middle frame of each of that many equal spans when the frames fit the cache; streamed,
    /// every k-th frame with k a power of two, [`FrameSample`]); 0 = every frame (the thesis).
    /// Scenes written before it existed used every frame.
    #[serde(default)]
    pub median_frames: usize,
    /// Keep a view's frames in memory between the two passes when they fit in this many bytes
    /// (not serialised into scenes: it changes speed, never results).
    #[serde(skip, default = "default_cache")]
    pub cache_bytes: usize,
    /// Automatic registration, used when several views come without marked points (its
    /// figures go into the scene per link).
    #[serde(skip, default)]
    pub register: RegisterParams,
    /// The background between views: the plane warp, the morph along the dense parallax, or
    /// per pair as measured ([`crate::parallax`]); scenes written before it existed read as
    /// the plane.
    #[serde(default)]
    pub background: BackgroundMode,
}

fn default_cache() -> usize {
    768 << 20
}

/// Default [`AnalyzeParams::median_frames`].
pub const DEFAULT_MEDIAN_FRAMES: usize = 128;

/// Most frames of a view the median histograms can count (`u16` counts).
pub const MAX_FRAMES_PER_VIEW: usize = MedianAccumulator::MAX_FRAMES;

/// Largest Gaussian kernel size of the analysis (OpenCV allows any odd size; beyond this the
/// kernel is wider than any useful smoothing and its cost grows with it).
pub const MAX_BLUR_SIZE: usize = 255;
/// Largest Gaussian sigma of the analysis, pixels.
pub const MAX_BLUR_SIGMA: f64 = 1000.0;
/// Largest window w of eq. (1) and (2).
pub const MAX_WINDOW: usize = 1000;
/// Largest mask opening or closing radius, pixels.
pub const MAX_RADIUS: u32 = 255;
/// Most alternative loops per view.
pub const MAX_ALTERNATIVES: usize = 100;

impl AnalyzeParams {
    /// Checks every value against its rule and the limits above; [`analyze`] calls it first.
    /// Errors are [`Error::InvalidParameter`] named by the field's path (`"blur.ksize"`).
    pub fn check(&self) -> Result<()> {
        let bad =
            |name, value: String, why: String| Err(Error::InvalidParameter { name, value, why });
        let (ksize, sigma) = (self.blur.ksize, self.blur.sigma);
        if ksize.is_multiple_of(2) || ksize > MAX_BLUR_SIZE {
            return bad(
                "blur.ksize",
                ksize.to_string(),
                format!("odd and at most {MAX_BLUR_SIZE}"),
            );
        }
        if !(sigma.is_finite() && sigma <= MAX_BLUR_SIGMA) {
            let why = format!("a finite number of pixels, at most {MAX_BLUR_SIGMA} (<= 0: derived from the kernel size)");
            return bad("blur.sigma", sigma.to_string(), why);
        }
        if self.loops.window > MAX_WINDOW {
            return bad(
                "loops.window",
                self.loops.window.to_string(),
                format!("at most {MAX_WINDOW}"),
            );
        }
        for (name, r) in [
            ("mask.open_radius", self.mask.open_radius),
            ("mask.close_radius", self.mask.close_radius),
        ] {
            if r > MAX_RADIUS {
                return bad(name, r.to_string(), format!("at most {MAX_RADIUS} pixels"));
            }
        }
        if self.alternative_loops > MAX_ALTERNATIVES {
            return bad(
                "alternative_loops",
                self.alternative_loops.to_string(),
                format!("at most {MAX_ALTERNATIVES}"),
            );
        }
        if !(self.model.sigma.is_finite() && self.model.sigma > 0.0) {
            return bad(
                "model.sigma",
                self.model.sigma.to_string(),
                "a positive number of pixels".into(),
            );
        }
        if matches!(self.median_frames, 1 | 2) || self.median_frames > MAX_FRAMES_PER_VIEW {
            return bad(
                "median_frames",
                self.median_frames.to_string(),
                format!("0 (every frame) or 3 to {MAX_FRAMES_PER_VIEW} frames"),
            );
        }
        self.noise.check()?;
        self.register.check()?;
        if !(self.appearance.is_finite() && (0.0..=1000.0).contains(&self.appearance)) {
            let why = "the appearance weight must be in 0..=1000 (0 = masks only)";
            return bad("appearance", self.appearance.to_string(), why.into());
        }
        Ok(())
    }
}

impl Default for AnalyzeParams {
    fn default() -> Self {
        Self {
            blur: GaussianParams::default(),
            mask: MaskParams::default(),
            noise: NoiseParams::default(),
            appearance: 1.0,
            refine: true,
            loops: LoopParams::default(),
            model: ModelParams::default(),
            alternative_loops: 0,
            median_frames: DEFAULT_MEDIAN_FRAMES,
            cache_bytes: default_cache(),
            register: RegisterParams::default(),
            background: BackgroundMode::Auto,
        }
    }
}

/// Pipeline stages, for progress reporting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Reading frames and accumulating the median.
    Background,
    /// Blurring and subtracting.
    Masks,
    /// Eq. (1).
    Loop,
    /// Model selection and homographies.
    Homographies,
    /// Automatic registration of neighbouring backgrounds (no marked points).
    Registration,
    /// Eq. (2).
    Transitions,
}

impl std::fmt::Display for Stage {
    /// What the stage does, in a few words (progress bars name it so).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stage::Background => "decode + median",
            Stage::Masks => "masks",
            Stage::Loop => "loop search",
            Stage::Homographies => "model + homographies",
            Stage::Registration => "registration",
            Stage::Transitions => "transitions",
        })
    }
}

/// Receives progress and the per-frame object data. All methods default to doing nothing.
pub trait Observer {
    /// A stage of `view` (None for scene-wide stages) started; `total` units if known.
    fn start(&mut self, _stage: Stage, _view: Option<usize>, _total: Option<u64>) {}
    /// One unit done.
    fn tick(&mut self) {}
    /// The stage finished.
    fn finish(&mut self) {}
    /// Frame `frame` of `view` has moving-object mask `mask` (pixels of `raw` under it are the
    /// object, eq. (4)-(5)); frames arrive in order. An error aborts the analysis.
    fn object_frame(
        &mut self,
        _view: usize,
        _frame: usize,
        _mask: &Mask,
        _raw: &RgbImage,
    ) -> Result<()> {
        Ok(())
    }
}

/// A do-nothing observer.
pub struct Quiet;
impl Observer for Quiet {}

/// Wall time per stage, summed over views.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timings {
    /// Time spent inside frame sources (decoding), not in our callbacks.
    pub decode: Duration,
    /// Median accumulation and extraction.
    pub median: Duration,
    /// Blur and subtraction.
    pub masks: Duration,
    /// Eq. (1).
    pub loops: Duration,
    /// Model selection, homographies.
    pub homographies: Duration,
    /// Mask warping and eq. (2).
    pub transitions: Duration,
    /// The dense parallax between neighbouring backgrounds.
    pub parallax: Duration,
}

/// One view's results.
#[derive(Debug, Clone)]
pub struct ViewResult {
    /// Source name.
    pub name: String,
    /// `N_p`.
    pub n_frames: usize,
    /// `B_p`, the unsmoothed median.
    pub background: RgbImage,
    /// `I_p(m)` for every frame.
    pub masks: Vec<Mask>,
    /// `(m_p, n_p)` and its cost.
    pub best_loop: Loop,
    /// The next-best distinct loops, best first ([`AnalyzeParams::alternative_loops`] of them at most).
    pub alternatives: Vec<Loop>,
    /// Fraction of pixels set, averaged over frames (how much of the view moves).
    pub moving_fraction: f64,
    /// Mean pair cost of an ordinary step `(s, s+1)` inside the loop (`XOR + kappa * A`): the unit
    /// of seam scores, taken inside the loop so frames playback never shows cannot distort it.
    pub mean_step: f64,
    /// The appearance term's unit factor ([`crate::appearance::kappa`]; 0 when off).
    pub kappa: f64,
    /// Change thumbnails of every frame (empty when the appearance term is off).
    pub thumbs: Vec<Thumb>,
    /// Their block factor.
    pub thumb_factor: u32,
    /// Seam score of the loop wrap ([`crate::transition::seam_score`] of the eq. (1) cost).
    pub loop_seam: f64,
    /// Sensor noise estimate of the noise model, grey levels (None when the model is off).
    pub noise_sigma: Option<f32>,
    /// Feathered alpha of the dynamic region (None when off or nothing moves often).
    pub dynamic_alpha: Option<image::GrayImage>,
    /// Share of the image in the dynamic region.
    pub dynamic_fraction: f64,
    /// Share of the real frame-to-frame change the view keeps at its own viewpoint
    /// ([`crate::noise::MotionKept`]).
    pub motion_kept: f64,
}

/// A neighbour link `p -> p + 1`.
#[derive(Debug, Clone)]
pub struct Link {
    /// `H_(p,p+1)` in use: refined from the backgrounds when that was kept, else from the points.
    pub homography: Homography,
    /// `H_(p,p+1)` fitted to the marked points.
    pub points_homography: Homography,
    /// The background alignment (None when refinement is off).
    pub refinement: Option<Refinement>,
    /// RMS transfer error of the points, pixels.
    pub rms: f64,
    /// `t_{p+1}(s, p)` for every frame `s` of view `p`.
    pub to_next: Vec<Option<usize>>,
    /// `t_p(s, p+1)` for every frame `s` of view `p + 1`.
    pub to_prev: Vec<Option<usize>>,
    /// Mean seam score of the switches both ways over the frames on each loop.
    pub seam: f64,
    /// Seam score of every switch to the next view (`s -> to_next[s] + 1`), in the target's step
    /// unit.
    pub to_next_seam: Vec<f32>,
    /// Seam score of every switch to the previous view.
    pub to_prev_seam: Vec<f32>,
    /// The pair's parallax beyond the plane, as measured (None: the plane was asked for).
    pub parallax_figures: Option<ParallaxFigures>,
    /// The dense parallax fields when the pair is morphed.
    pub parallax: Option<std::sync::Arc<PairParallax>>,
}

/// How a link's homography was refined from the backgrounds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Refinement {
    /// RMS photometric error (grey levels) with the points' homography.
    pub error_before: f64,
    /// RMS photometric error with the refined homography.
    pub error_after: f64,
    /// RMS transfer error of the marked points under the refined homography, pixels.
    pub points_rms: f64,
    /// Whether the refined homography is used (it lowered the error and agrees with the points).
    pub kept: bool,
}

/// The whole analysis.
#[derive(Debug, Clone)]
pub struct SceneAnalysis {
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Per view, in input order.
    pub views: Vec<ViewResult>,
    /// The model chosen for the scene (None for a single view).
    pub selection: Option<Selection>,
    /// `links[p]` joins view p and p + 1.
    pub links: Vec<Link>,
    /// The points of each view: the marked ones, or, registered automatically, four points
    /// around the plane's inliers in view 0 carried through the homographies in use (the same
    /// K physical points in every view, as B-1's `x(q)` needs).
    pub points: Vec<Vec<Point>>,
    /// Points consistent with the refined homographies (the marked points carried through the
    /// chain and averaged over the views; None unless some link was refined). The renderer's
    /// `x_p`.
    pub refined_points: Option<Vec<Vec<Point>>>,
    /// The automatic registration of each link (empty when points were marked).
    pub registration: Vec<crate::register::PairRegistration>,
    /// The moving object's own plane per link, when registered automatically (None where
    /// nothing moves; [`ObjectPlane::kept`] says whether it replaced the background's).
    pub object_planes: Vec<Option<ObjectPlane>>,
    /// Where the time went.
    pub timings: Timings,
}

fn size_err(what: String, expected: (u32, u32), got: (u32, u32)) -> Error {
    Error::SizeMismatch {
        what,
        expected_w: expected.0,
        expected_h: expected.1,
        got_w: got.0,
        got_h: got.1,
    }
}

/// Runs A-1..A-3 on `sources` (one per view, in order) with `points[p]` the marked points of view p
/// (the same K physical points in every view). With several views and `points` empty, each
/// neighbour pair is registered from its median backgrounds ([`crate::register`]): the model is
/// selected by GRIC on the inlier matches and refined as for marked points.
pub fn analyze(
    sources: &mut [&mut dyn FrameSource],
    points: &[Vec<Point>],
    params: &AnalyzeParams,
    observer: &mut dyn Observer,
) -> Result<SceneAnalysis> {
    let m = sources.len();
    if m == 0 {
        return Err(Error::InvalidParameter {
            name: "views",
            value: "0".into(),
            why: "at least one view is needed".into(),
        });
    }
    let auto = m > 1 && points.is_empty();
    if m > 1 && !auto {
        if points.len() != m {
            return Err(Error::DegeneratePoints(format!(
                "{m} views but points for {} views",
                points.len()
            )));
        }
        let k0 = points[0].len();
        if let Some((p, pts)) = points.iter().enumerate().find(|(_, v)| v.len() != k0) {
            return Err(Error::DegeneratePoints(format!(
                "view 0 has {k0} points but view {p} has {}",
                pts.len()
            )));
        }
    }
    params.check()?;
    let mut timings = Timings::default();
    // The points are cheap to check: select the model and fit homographies before any decoding.
    let mut selection = None;
    if m > 1 && !auto {
        let t0 = Instant::now();
        observer.start(Stage::Homographies, None, Some((m - 1) as u64));
        let pairs: Vec<(&[Point], &[Point])> = (0..m - 1)
            .map(|p| (points[p].as_slice(), points[p + 1].as_slice()))
            .collect();
        let sel = select_model(&pairs, &params.model)?;
        observer.finish();
        timings.homographies += t0.elapsed();
        selection = Some(sel);
    }

    let mut views = Vec::with_capacity(m);
    let mut size: Option<(u32, u32)> = None;
    for (p, src) in sources.iter_mut().enumerate() {
        let v = analyze_view(p, &mut **src, params, &mut size, observer, &mut timings)?;
        views.push(v);
    }
    let (width, height) = size.expect("every view has at least one frame");

    // Features of every background, detected once, when registration or the parallax needs
    // them (timed with the homographies).
    let t_features = Instant::now();
    let grey: Vec<image::GrayImage> = if auto || params.background != BackgroundMode::Plane {
        views
            .par_iter()
            .map(|v| crate::register::grey(&v.background))
            .collect()
    } else {
        Vec::new()
    };
    let features: Vec<Vec<crate::register::Feature>> = grey
        .par_iter()
        .map(|g| crate::register::detect(g, &params.register))
        .collect();
    timings.homographies += t_features.elapsed();
    // Correspondences per link: the marked points of both views, or the automatic inliers.
    let mut registration = Vec::new();
    let pair_points: Vec<(Vec<Point>, Vec<Point>)> = if auto {
        let t0 = Instant::now();
        observer.start(Stage::Registration, None, Some((m - 1) as u64));
        let focus: Vec<Option<Mask>> = views
            .iter()
            .map(|v| {
                v.dynamic_alpha.as_ref().map(|al| {
                    let raw = al.as_raw();
                    Mask::from_fn(width, height, |x, y| raw[(y * width + x) as usize] > 0)
                })
            })
            .collect();
        for p in 0..m - 1 {
            let mut r = crate::register::register_features(
                &features[p],
                &features[p + 1],
                (width, height),
                focus[p].as_ref(),
                &params.register,
                (p, p + 1),
            )?;
            crate::register::refine_inliers(&grey[p], &grey[p + 1], &mut r, &params.register);
            observer.tick();
            registration.push(r);
        }
        let pairs: Vec<(Vec<Point>, Vec<Point>)> = registration
            .iter()
            .map(|r| r.inliers.iter().copied().unzip())
            .collect();
        // GRIC's sigma from the matches themselves: a transfer residual carries both views'
        // localisation noise (RMS about 2 sigma), corrected for the homography's 8 parameters.
        let (mut sq, mut dof) = (0.0, 0.0);
        for r in &registration {
            let n = r.inliers.len() as f64;
            sq += r.rms * r.rms * n;
            dof += n - 4.0;
        }
        let sigma = ((sq / dof.max(1.0)).sqrt() / 2.0).max(0.05);
        let refs: Vec<(&[Point], &[Point])> = pairs
            .iter()
            .map(|(a, b)| (a.as_slice(), b.as_slice()))
            .collect();
        let model = ModelParams {
            sigma,
            ..params.model
        };
        selection = Some(select_model(&refs, &model)?);
        observer.finish();
        timings.homographies += t0.elapsed();
        pairs
    } else {
        (0..m.saturating_sub(1))
            .map(|p| (points[p].clone(), points[p + 1].clone()))
            .collect()
    };

    // Refinement of H_(p,p+1) from the backgrounds, inside the marked points' hull and outside
    // the dynamic region (the whole hull when too little of it is static).
    let refine_all = |sel: &Selection| -> Result<(Vec<Homography>, Vec<Option<Refinement>>)> {
        let mut used: Vec<Homography> = Vec::new();
        let mut refinements: Vec<Option<Refinement>> = Vec::new();
        // Marking deviation implied by the fits: the RMS residual over all links, scaled up by
        // the residual degrees of freedom (2K measurements, `dof` used by the model), and halved
        // because a residual carries the noise of both views' points (about 2 sigma).
        let k2 = 2.0 * pair_points.iter().map(|(a, _)| a.len()).sum::<usize>() as f64
            / pair_points.len().max(1) as f64;
        let dof = sel.model.dof() as f64;
        let mean_sq = sel.fits.iter().map(|f| f.rms * f.rms).sum::<f64>() / sel.fits.len() as f64;
        let sigma_hat = mean_sq.sqrt() * (k2 / (k2 - dof).max(1.0)).sqrt() / 2.0;
        for p in 0..m - 1 {
            let init = sel.fits[p].homography;
            if !params.refine {
                used.push(init);
                refinements.push(None);
                continue;
            }
            let (src, dst) = (&pair_points[p].0, &pair_points[p].1);
            let hull = crate::align::hull_mask(src, width, height);
            let region = match &views[p].dynamic_alpha {
                Some(al) => {
                    let raw = al.as_raw();
                    let r = Mask::from_fn(width, height, |x, y| {
                        hull.get(x, y) && raw[(y * width + x) as usize] == 0
                    });
                    if r.count_ones() * 4 >= hull.count_ones() {
                        r
                    } else {
                        hull
                    }
                }
                None => hull,
            };
            let a = crate::align::align_backgrounds(
                &views[p].background,
                &views[p + 1].background,
                &init,
                &region,
                sel.model,
                &crate::align::AlignParams::default(),
            )?;
            // Keep it only if it also agrees with the points: their transfer error may grow to
            // twice the fit's, or by three marking deviations, no more (a background off the
            // marked plane aligns well but to the wrong plane). The marking deviation is the one
            // the fits' residuals imply: exact points (synthetic scenes, or just enough points
            // for the model) leave no room, and the points decide.
            let points_rms = a.homography.rms_error(src, dst);
            let fit_rms = sel.fits[p].rms;
            let bound = (2.0 * fit_rms).max(fit_rms + 3.0 * sigma_hat);
            let kept = a.improved && points_rms <= bound;
            used.push(if kept { a.homography } else { init });
            refinements.push(Some(Refinement {
                error_before: a.error_before,
                error_after: a.error_after,
                points_rms,
                kept,
            }));
        }
        Ok((used, refinements))
    };
    let mut used: Vec<Homography> = Vec::new();
    let mut refinements: Vec<Option<Refinement>> = Vec::new();
    let mut refined_points = None;
    let mut object_planes: Vec<Option<ObjectPlane>> = Vec::new();
    if let Some(sel) = selection.clone() {
        let t0 = Instant::now();
        (used, refinements) = refine_all(&sel)?;
        // The backgrounds may ask for more than the points do: exact or precise points on a
        // slanted plane can leave GRIC preferring an affine map whose error only shows away from
        // the points. When a simpler model was selected, refine under the full homography too
        // and take it if it lowers the photometric error over all links by 5% or more.
        if params.refine && !sel.forced && sel.model != MotionModel::Homography {
            let pairs: Vec<(&[Point], &[Point])> = pair_points
                .iter()
                .map(|(a, b)| (a.as_slice(), b.as_slice()))
                .collect();
            let force = ModelParams {
                force: Some(MotionModel::Homography),
                ..params.model
            };
            if let Ok(full) = select_model(&pairs, &force) {
                let (u2, r2) = refine_all(&full)?;
                let error = |r: &[Option<Refinement>]| -> f64 {
                    r.iter()
                        .flatten()
                        .map(|r| {
                            if r.kept {
                                r.error_after
                            } else {
                                r.error_before
                            }
                        })
                        .sum()
                };
                if error(&r2) <= 0.95 * error(&refinements) {
                    selection = Some(Selection {
                        forced: false,
                        scores: sel.scores.clone(),
                        ..full
                    });
                    (used, refinements) = (u2, r2);
                }
            }
        }
        if auto {
            let model = selection
                .as_ref()
                .map_or(MotionModel::Homography, |s| s.model);
            object_planes = choose_object_planes(
                &views,
                &used,
                &pair_points,
                model,
                (width, height),
                params.loops.window,
            )?;
            for (p, o) in object_planes.iter().enumerate() {
                if let Some(o) = o.filter(|o| o.kept) {
                    used[p] = o.homography;
                }
            }
        }
        if !auto && refinements.iter().flatten().any(|r| r.kept) {
            refined_points = crate::align::consistent_points(points, &used);
        }
        timings.homographies += t0.elapsed();
    }
    let points = if auto {
        carried_points(&registration[0], &used, width, height)?
    } else {
        points.to_vec()
    };

    let mut links = Vec::new();
    if let Some(sel) = &selection {
        let t0 = Instant::now();
        observer.start(Stage::Transitions, None, Some(2 * (m - 1) as u64));
        for p in 0..m - 1 {
            let h = used[p];
            let (a, b) = (&views[p], &views[p + 1]);
            let w = params.loops.window;
            let fwd = transitions(a, b, &h, width, height, w)?;
            observer.tick();
            let back = transitions(b, a, &h.inverse(), width, height, w)?;
            observer.tick();
            // Seam of switching from the frames playback can show (the loop m+1..=n).
            let on_loop = |v: &ViewResult, table: &[Option<(usize, u64)>], to: &ViewResult| {
                table[v.best_loop.start + 1..=v.best_loop.end]
                    .iter()
                    .flatten()
                    .map(|&(_, c)| seam_score(c, w, to.mean_step))
                    .collect::<Vec<f64>>()
            };
            let seams: Vec<f64> = on_loop(a, &fwd, b)
                .into_iter()
                .chain(on_loop(b, &back, a))
                .collect();
            let seam = seams.iter().sum::<f64>() / seams.len().max(1) as f64;
            let seams_of = |t: &[Option<(usize, u64)>], to: &ViewResult| -> Vec<f32> {
                t.iter()
                    .map(|e| e.map_or(f32::MAX, |(_, c)| seam_score(c, w, to.mean_step) as f32))
                    .collect()
            };
            let (to_next_seam, to_prev_seam) = (seams_of(&fwd, b), seams_of(&back, a));
            let strip =
                |t: Vec<Option<(usize, u64)>>| t.into_iter().map(|e| e.map(|(t, _)| t)).collect();
            let t1 = Instant::now();
            let matches: Vec<(Point, Point)> = match features.get(p..p + 2) {
                Some([fa, fb]) => crate::register::match_features(
                    fa,
                    fb,
                    params.register.ratio,
                    params.register.max_distance,
                )
                .into_iter()
                .map(|(i, j)| (fa[i].pos, fb[j].pos))
                .collect(),
                _ => Vec::new(),
            };
            let par = crate::parallax::analyse_pair(
                &a.background,
                &b.background,
                &h,
                &matches,
                params.background,
                &crate::parallax::ParallaxParams::default(),
            );
            timings.parallax += t1.elapsed();
            let (parallax_figures, parallax) = match par {
                Some((f, p)) => (Some(f), p.map(std::sync::Arc::new)),
                None => (None, None),
            };
            links.push(Link {
                parallax_figures,
                parallax,
                homography: h,
                points_homography: sel.fits[p].homography,
                refinement: refinements[p],
                rms: sel.fits[p].rms,
                to_next: strip(fwd),
                to_prev: strip(back),
                seam,
                to_next_seam,
                to_prev_seam,
            });
        }
        observer.finish();
        timings.transitions += t0.elapsed().saturating_sub(timings.parallax);
    }
    Ok(SceneAnalysis {
        width,
        height,
        views,
        selection,
        links,
        points,
        refined_points,
        registration,
        object_planes,
        timings,
    })
}

/// The moving object's own plane, from its footprint and its silhouettes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ObjectPlane {
    /// The homography found (view p to p + 1).
    #[serde(skip, default = "Homography::identity")]
    pub homography: Homography,
    /// The model it was found under (the simplest within 2% of the best error).
    pub model: MotionModel,
    /// RMS error of the silhouettes at matching phases (grey levels of the blurred masks)
    /// under the background's homography.
    pub error_before: f64,
    /// The same under the object's plane.
    pub error_after: f64,
    /// Whether it replaced the background's homography (it lowered the silhouettes' error by
    /// at least a fifth).
    pub kept: bool,
}

/// Aligns the image pairs under each model, from `start` or, without it, from that model's fit
/// to the feature matches: (homography, model, error) per model that could be aligned.
fn align_models(
    pairs: &[(RgbImage, RgbImage)],
    region: &Mask,
    start: Option<&Homography>,
    matches: &(Vec<Point>, Vec<Point>),
) -> Result<Vec<(Homography, MotionModel, f64)>> {
    let refs: Vec<(&RgbImage, &RgbImage)> = pairs.iter().map(|(x, y)| (x, y)).collect();
    let mut results = Vec::new();
    for model in MotionModel::ALL {
        let init = match start {
            Some(h) => *h,
            None => match crate::model::fit_model(model, &matches.0, &matches.1, 1.0) {
                Ok(f) => f.homography,
                Err(_) => continue,
            },
        };
        let al = crate::align::align_stack(&refs, &init, region, model, &OBJECT_ALIGN)?;
        if al.error_after.is_finite() {
            results.push((al.homography, model, al.error_after));
        }
    }
    Ok(results)
}

/// The simplest model whose summed error is within 2% of the best (`errors[link][model]`).
fn simplest_within(errors: &[Vec<(Homography, MotionModel, f64)>]) -> Option<MotionModel> {
    let total = |model: MotionModel| -> Option<f64> {
        errors
            .iter()
            .map(|l| l.iter().find(|r| r.1 == model).map(|r| r.2))
            .sum()
    };
    let sums: Vec<(MotionModel, f64)> = MotionModel::ALL
        .into_iter()
        .filter_map(|m| total(m).map(|t| (m, t)))
        .collect();
    let best = sums.iter().map(|s| s.1).min_by(f64::total_cmp)?;
    sums.into_iter().find(|s| s.1 <= 1.02 * best).map(|s| s.0)
}

/// The moving object's own plane for every link, starting from the background's homographies
/// `hs`: the footprints (share of frames each pixel moves: phase-free) are aligned first, then
/// the silhouettes at matching phases (eq. (2) under the footprints' estimate), twice. The
/// model is chosen for the whole scene: the simplest whose summed error is within 2% of the
/// best. A link's plane is kept when it lowers its silhouettes' error by at least a fifth
/// against the background's homography (an object standing on the background's plane keeps
/// the background's, finer estimate). None for a link where nothing moves.
fn choose_object_planes(
    views: &[ViewResult],
    hs: &[Homography],
    matches: &[(Vec<Point>, Vec<Point>)],
    model: MotionModel,
    (width, height): (u32, u32),
    window: usize,
) -> Result<Vec<Option<ObjectPlane>>> {
    let links = hs.len();
    // First a cheap look: the silhouettes at the phases the background's homographies match,
    // aligned from them under the scene's model. When no link's error drops by a tenth, the
    // object stands on the background's plane (or too little moves to tell): keep it.
    let mut quick = Vec::new();
    for p in 0..links {
        let Some(st) = silhouette_stack(&views[p], &views[p + 1], &hs[p], width, height, window)?
        else {
            quick.push(None);
            continue;
        };
        let refs: Vec<(&RgbImage, &RgbImage)> = st.pairs.iter().map(|(x, y)| (x, y)).collect();
        let al = crate::align::align_stack(&refs, &hs[p], &st.region, model, &OBJECT_ALIGN)?;
        quick.push(Some(ObjectPlane {
            homography: al.homography,
            model,
            error_before: al.error_before,
            error_after: al.error_after,
            kept: false,
        }));
    }
    if quick
        .iter()
        .flatten()
        .all(|o| o.error_after.is_nan() || o.error_after >= 0.9 * o.error_before)
    {
        return Ok(quick);
    }
    let footprints: Vec<Option<RgbImage>> = views
        .iter()
        .map(|v| crate::register::footprint(&v.masks))
        .collect();
    // Stage 1: footprints.
    let mut fp: Vec<Vec<(Homography, MotionModel, f64)>> = Vec::new();
    for p in 0..links {
        let (Some(fa), Some(fb)) = (&footprints[p], &footprints[p + 1]) else {
            fp.push(Vec::new());
            continue;
        };
        let raw = fa.as_raw();
        let region =
            Mask::from_fn(width, height, |x, y| raw[3 * (y * width + x) as usize] > 0).dilate(6);
        fp.push(align_models(
            &[(fa.clone(), fb.clone())],
            &region,
            None,
            &matches[p],
        )?);
    }
    let Some(model) = simplest_within(&fp) else {
        return Ok(vec![None; links]);
    };
    let mut current: Vec<Option<Homography>> = fp
        .iter()
        .map(|l| l.iter().find(|r| r.1 == model).map(|r| r.0))
        .collect();
    // Stage 2: silhouettes at matching phases, phases found again after the first round.
    let mut chosen = vec![None; links];
    for _round in 0..SILHOUETTE_ROUNDS {
        let mut stacks = Vec::new();
        let mut results = Vec::new();
        for p in 0..links {
            let stack = match current[p] {
                Some(h) => silhouette_stack(&views[p], &views[p + 1], &h, width, height, window)?,
                None => None,
            };
            results.push(match &stack {
                Some(st) => align_models(&st.pairs, &st.region, current[p].as_ref(), &matches[p])?,
                None => Vec::new(),
            });
            stacks.push(stack);
        }
        let Some(model) = simplest_within(&results) else {
            return Ok(vec![None; links]);
        };
        for p in 0..links {
            let (Some(st), Some(r)) = (&stacks[p], results[p].iter().find(|r| r.1 == model)) else {
                chosen[p] = None;
                continue;
            };
            let refs: Vec<(&RgbImage, &RgbImage)> = st.pairs.iter().map(|(x, y)| (x, y)).collect();
            let score = crate::align::AlignParams {
                iterations: 0,
                ..Default::default()
            };
            let error_before = crate::align::align_stack(
                &refs,
                &hs[p],
                &st.region,
                MotionModel::Homography,
                &score,
            )?
            .error_before;
            current[p] = Some(r.0);
            chosen[p] = Some(ObjectPlane {
                homography: r.0,
                model,
                error_before,
                error_after: r.2,
                kept: r.2 < 0.8 * error_before,
            });
        }
    }
    Ok(chosen)
}

/// The object-plane alignments' settings: fewer pixels and iterations than the background's
/// refinement (four models, three stages; blurred silhouettes are smooth).
const OBJECT_ALIGN: crate::align::AlignParams = crate::align::AlignParams {
    levels: 4,
    iterations: 15,
    max_pixels: 12_000,
};

/// Silhouette pairs per link for the object's plane.
const SILHOUETTE_PAIRS: usize = 32;
/// Rounds of phase matching and silhouette alignment.
const SILHOUETTE_ROUNDS: usize = 2;

/// The moving object's silhouettes at matching phases of two views, blurred (for
/// [`crate::align::align_stack`]), and the region of view a they cover.
struct SilhouetteStack {
    pairs: Vec<(RgbImage, RgbImage)>,
    region: Mask,
}

/// The frame pairs of [`matching_frames`], blurred, and the region they cover.
fn silhouette_stack(
    a: &ViewResult,
    b: &ViewResult,
    h: &Homography,
    width: u32,
    height: u32,
    window: usize,
) -> Result<Option<SilhouetteStack>> {
    let candidates = matching_frames(a, b, h, width, height, window);
    if candidates.len() < 4 {
        return Ok(None);
    }
    let blur = GaussianParams {
        ksize: 7,
        sigma: 1.5,
    };
    let image = |m: &Mask| -> Result<RgbImage> {
        let mut img = RgbImage::new(width, height);
        for y in 0..height {
            for x in 0..width {
                if m.get(x, y) {
                    img.put_pixel(x, y, image::Rgb([255, 255, 255]));
                }
            }
        }
        gaussian_blur(&img, &blur)
    };
    let mut pairs = Vec::new();
    let mut region = Mask::new(width, height);
    for &(s, t) in &candidates {
        region = region.union(&a.masks[s]);
        pairs.push((image(&a.masks[s])?, image(&b.masks[t])?));
    }
    Ok(Some(SilhouetteStack {
        pairs,
        region: region.dilate(4),
    }))
}

/// Frames of a's loop (at most [`SILHOUETTE_PAIRS`], evenly spaced, with something moving)
/// and the frame of b that matches each by eq. (2)'s windowed mask XOR under `h`: the same rule
/// as the transition tables, computed for these frames only (the whole table costs as much as
/// the analysis's own transitions).
fn matching_frames(
    a: &ViewResult,
    b: &ViewResult,
    h: &Homography,
    width: u32,
    height: u32,
    window: usize,
) -> Vec<(usize, usize)> {
    let (na, nb) = (a.masks.len(), b.masks.len());
    let half = window / 2;
    if nb <= 2 * half || na <= 2 * half {
        return Vec::new();
    }
    let lo = a.best_loop.start.max(half);
    let hi = a.best_loop.end.min(na - 1 - half);
    if hi < lo {
        return Vec::new();
    }
    let span = hi - lo + 1;
    let k = SILHOUETTE_PAIRS.min(span);
    let samples: Vec<usize> = (0..k)
        .map(|i| lo + ((2 * i + 1) * span) / (2 * k))
        .filter(|&s| a.masks[s].count_ones() > 0)
        .collect();
    samples
        .par_iter()
        .filter_map(|&s| {
            let warped: Vec<Mask> = (s - half..=s + half)
                .map(|i| crate::warp::warp_mask(&a.masks[i], h, width, height))
                .collect();
            let best = (half..nb - half)
                .map(|t| {
                    let cost: u64 = warped
                        .iter()
                        .enumerate()
                        .map(|(k, m)| crate::mask::xor_count(m, &b.masks[t - half + k]))
                        .sum();
                    (cost, t)
                })
                .min()?;
            (b.masks[best.1].count_ones() > 0).then_some((s, best.1))
        })
        .collect()
}

/// The virtual points of automatic registration: the corners of the box around view 0's inliers
/// (the plane's matches), carried to every view through `hs` (view p to p + 1), so they are the
/// same four physical points of the plane in every view.
fn carried_points(
    first: &crate::register::PairRegistration,
    hs: &[Homography],
    width: u32,
    height: u32,
) -> Result<Vec<Vec<Point>>> {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (a, _) in &first.inliers {
        (x0, y0, x1, y1) = (x0.min(a.x), y0.min(a.y), x1.max(a.x), y1.max(a.y));
    }
    // At least a tenth of the image each way, centred on the inliers' box.
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let hw = ((x1 - x0) / 2.0).max(width as f64 / 20.0);
    let hh = ((y1 - y0) / 2.0).max(height as f64 / 20.0);
    let base = vec![
        Point::new(cx - hw, cy - hh),
        Point::new(cx + hw, cy - hh),
        Point::new(cx + hw, cy + hh),
        Point::new(cx - hw, cy + hh),
    ];
    let mut out = vec![base];
    for (p, h) in hs.iter().enumerate() {
        let next: Option<Vec<Point>> = out[p].iter().map(|&q| h.apply(q)).collect();
        out.push(next.ok_or_else(|| Error::Registration {
            pair: (p, p + 1),
            why: "the plane's points leave the image plane (a point maps to infinity)".into(),
        })?);
    }
    Ok(out)
}

/// Eq. (2) from view `a` to view `b` (`h` maps a to b), with the appearance term when both views
/// have thumbnails (the target's kappa puts it in the target's unit).
fn transitions(
    a: &ViewResult,
    b: &ViewResult,
    h: &Homography,
    width: u32,
    height: u32,
    window: usize,
) -> Result<Vec<Option<(usize, u64)>>> {
    let warped = warp_masks(&a.masks, h, width, height);
    let Some((t_max, t_frames)) = transition_range(&warped, &b.masks, b.best_loop.end, window)?
    else {
        return Ok(vec![None; warped.len()]);
    };
    let mut d = xor_pair_costs(&warped, &b.masks, t_frames);
    if b.kappa > 0.0 && !a.thumbs.is_empty() && !b.thumbs.is_empty() {
        let (wt, valid) = appearance::warp_thumbs(&a.thumbs, h, a.thumb_factor);
        let app = appearance::cross_pair_costs(&wt, &valid, &b.thumbs, t_frames);
        appearance::combine(&mut d, &app, b.kappa);
    }
    Ok(transitions_from_pair_costs(
        &d,
        warped.len(),
        t_frames,
        t_max,
        window,
    ))
}

/// The model chosen, if any.
impl SceneAnalysis {
    /// The scene's model (None for a single view).
    pub fn model(&self) -> Option<MotionModel> {
        self.selection.as_ref().map(|s| s.model)
    }
}

/// The frames of an `n`-frame view the median background uses when they are all at hand
/// ([`AnalyzeParams::median_frames`] = `k`): the middle frame of each of `k` equal spans, or
/// every frame when `k` is 0 or at least `n`.
pub fn median_frame_indices(n: usize, k: usize) -> Vec<usize> {
    let k = if k == 0 { n } else { k.min(n) };
    (0..k).map(|i| ((2 * i + 1) * n) / (2 * k)).collect()
}

/// Pass 1's consumers of frames that do not stay in the cache.
struct Streamed {
    /// The noise model's sample.
    noise: Option<FrameSample>,
    /// The median's sample (None: every frame).
    median: Option<FrameSample>,
    /// The every-frame median, once frames stream.
    all: Option<MedianAccumulator>,
    every_frame: bool,
    /// Conversion buffer.
    rgb: RgbImage,
}

impl Streamed {
    /// Frame `i`, in order; converted to RGB only if something keeps it.
    fn take(&mut self, i: usize, frame: FrameRef<'_>) -> Result<()> {
        let wanted = self.noise.as_ref().is_some_and(|s| s.wants(i))
            || self.median.as_ref().is_some_and(|s| s.wants(i));
        if !(wanted || self.every_frame) {
            return Ok(());
        }
        let rgb = frame.rgb(&mut self.rgb);
        for s in [&mut self.noise, &mut self.median].into_iter().flatten() {
            s.offer(i, rgb);
        }
        if self.every_frame {
            let (w, h) = rgb.dimensions();
            self.all
                .get_or_insert_with(|| MedianAccumulator::new(w, h))
                .push(rgb)?;
        }
        Ok(())
    }
}

fn analyze_view(
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
                for (j, f) in cache.take().unwrap_or_default().iter().enumerate() {
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
            streamed.median = None;
            streamed.every_frame = false;
            for (j, f) in frames.iter().enumerate() {
                streamed.take(j, f.as_ref())?;
            }
            (background, streamed.noise)
        }
        None => {
            let background = match (streamed.median, streamed.all) {
                (Some(s), _) => temporal_median(s.frames()).map_err(too_many)?,
                (None, Some(acc)) => acc.median()?,
                (None, None) => unreachable!("streamed frames go to a sample or the accumulator"),
            };
            (background, streamed.noise)
        }
    };
    let bg_blur = gaussian_blur(&background, &params.blur)?;
    timings.median += t.elapsed() + inside;
    // The noise model and dynamic region, from the evenly spaced sample.
    let model: Option<NoiseModel> = match sample {
        Some(s) => {
            let t = Instant::now();
            let blurred: Vec<RgbImage> = s
                .into_frames()
                .par_iter()
                .map(|f| gaussian_blur(f, &params.blur))
                .collect::<Result<_>>()?;
            let m = noise_model(&bg_blur, &blurred, &params.noise)?;
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

    // Pass 2: masks.
    observer.start(Stage::Masks, Some(p), Some(n1 as u64));
    let t = Instant::now();
    let mut masks = Vec::with_capacity(n1);
    let mut inside = Duration::ZERO;
    if let Some(frames) = cache {
        // Frames in chunks: each chunk's frames converted, blurred and masked in parallel (one
        // frame per thread, buffers reused) while the previous chunk goes to the observer in
        // order (object store writes, the motion tally) on this thread. The cache shrinks as it
        // goes: a chunk's frames are dropped once converted.
        let blur = GaussianBlur::new(&params.blur)?;
        let (w, h) = bg_blur.dimensions();
        let chunk = (4 * rayon::current_num_threads()).max(8);
        let buffers = || -> Vec<RgbImage> {
            (0..chunk.min(frames.len()))
                .map(|_| RgbImage::new(w, h))
                .collect()
        };
        let (mut ready, mut spare) = (buffers(), buffers());
        // Blur buffers, one per frame of a chunk (one chunk is computed at a time).
        let mut blurs: Vec<(BlurScratch, RgbImage)> = (0..ready.len())
            .map(|_| (BlurScratch::default(), RgbImage::new(w, h)))
            .collect();
        // A chunk's masks (and thumbnails), and the motion tally of its frames' pairs, the first
        // with `prev`, the previous chunk's last frame and mask.
        type Computed = (Vec<(Mask, Option<Thumb>)>, (u64, u64));
        let compute = |part: Vec<Frame>,
                       rgb: &mut Vec<RgbImage>,
                       blurs: &mut Vec<(BlurScratch, RgbImage)>,
                       prev: Option<(&RgbImage, &Mask)>|
         -> Result<Computed> {
            let masks: Vec<(Mask, Option<Thumb>)> = part
                .into_par_iter()
                .zip(rgb.par_iter_mut())
                .zip(blurs.par_iter_mut())
                .map(|((f, out), (scratch, blurred))| {
                    f.as_ref().to_rgb_into(out);
                    drop(f);
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
        let mut frames = frames.into_iter();
        let (mut pending, change) = compute(
            frames.by_ref().take(chunk).collect(),
            &mut ready,
            &mut blurs,
            None,
        )?;
        kept.add(change);
        let mut i = 0;
        while !pending.is_empty() {
            let part: Vec<Frame> = frames.by_ref().take(chunk).collect();
            let last_mask = pending.last().map(|(m, _)| m.clone());
            let prev = pending
                .len()
                .checked_sub(1)
                .map(|k| &ready[k])
                .zip(last_mask.as_ref());
            let (next, flushed) = std::thread::scope(|scope| {
                let worker = scope.spawn(|| compute(part, &mut spare, &mut blurs, prev));
                let mut flush = || -> Result<()> {
                    for ((m, thumb), f) in pending.drain(..).zip(&ready) {
                        observer.object_frame(p, i, &shown(&m), f)?;
                        masks.push(m);
                        thumbs.extend(thumb);
                        observer.tick();
                        i += 1;
                    }
                    Ok(())
                };
                let flushed = flush();
                (worker.join(), flushed)
            });
            flushed?;
            let (next, change) = next.unwrap_or_else(|panic| std::panic::resume_unwind(panic))?;
            kept.add(change);
            pending = next;
            std::mem::swap(&mut ready, &mut spare);
        }
        timings.masks += t.elapsed();
    } else {
        let mut blurred = RgbImage::new(bg_blur.width(), bg_blur.height());
        let t_pass = Instant::now();
        let n2 = src.for_each_frame(&mut |i, frame| {
            let t = Instant::now();
            if frame.dimensions() != bg_blur.dimensions() {
                return Err(size_err(
                    label(&format!(" frame {i}")),
                    bg_blur.dimensions(),
                    frame.dimensions(),
                ));
            }
            gaussian_blur_into(frame, &params.blur, &mut blurred)?;
            let m = mask_of(&blurred)?;
            if with_thumbs {
                thumbs.push(change_thumb(&blurred, &bg_blur, factor));
            }
            observer.object_frame(p, i, &shown(&m), frame)?;
            kept.push(frame, &m, &background, alpha);
            masks.push(m);
            observer.tick();
            inside += t.elapsed();
            Ok(())
        })?;
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
    let xor_steps: Vec<u64> = masks
        .par_windows(2)
        .map(|w| crate::mask::xor_count(&w[0], &w[1]))
        .collect();
    let app_steps: Vec<u64> = thumbs
        .par_windows(2)
        .map(|w| appearance::thumb_cost(&w[0], &w[1], None))
        .collect();
    let mean = |v: &[u64]| v.iter().sum::<u64>() as f64 / v.len().max(1) as f64;
    let kappa = appearance::kappa(params.appearance as f64, mean(&xor_steps), mean(&app_steps));
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
    let best_loop = loops[0];
    observer.finish();
    timings.loops += t.elapsed();
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
        n_frames: n1,
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
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tiny two-view scene: a square moving with period 10 over a gradient, view 1 shifted 5 px.
    fn view(shift: u32, offset: usize, n: usize) -> MemorySource {
        let frames = (0..n)
            .map(|f| {
                let ph = ((f + offset) % 10) as f64 / 10.0 * std::f64::consts::TAU;
                let cx = 20.0 + 8.0 * ph.sin() + shift as f64;
                let cy = 16.0 + 6.0 * ph.cos();
                RgbImage::from_fn(48, 32, |x, y| {
                    let inside = (x as f64 - cx).abs() < 4.0 && (y as f64 - cy).abs() < 4.0;
                    if inside {
                        image::Rgb([250, 20, 20])
                    } else {
                        image::Rgb([(x * 3) as u8, (y * 5) as u8, 90])
                    }
                })
            })
            .collect();
        MemorySource {
            name: format!("mem{shift}"),
            frames,
        }
    }

    #[test]
    fn two_view_scene_end_to_end() {
        let (mut a, mut b) = (view(0, 0, 40), view(5, 3, 40));
        let pts = |dx: f64| {
            vec![
                Point::new(2.0 + dx, 2.0),
                Point::new(40.0 + dx, 3.0),
                Point::new(41.0 + dx, 30.0),
                Point::new(3.0 + dx, 29.0),
            ]
        };
        let params = AnalyzeParams {
            loops: LoopParams {
                window: 3,
                min_length: 15,
            },
            ..Default::default()
        };
        let res = analyze(
            &mut [&mut a, &mut b],
            &[pts(0.0), pts(5.0)],
            &params,
            &mut Quiet,
        )
        .unwrap();
        assert_eq!(res.model(), Some(MotionModel::Translation));
        // Streaming (no frame cache) gives exactly the same analysis.
        let (mut a2, mut b2) = (view(0, 0, 40), view(5, 3, 40));
        let streamed = AnalyzeParams {
            cache_bytes: 0,
            ..params
        };
        let res2 = analyze(
            &mut [&mut a2, &mut b2],
            &[pts(0.0), pts(5.0)],
            &streamed,
            &mut Quiet,
        )
        .unwrap();
        for (x, y) in res.views.iter().zip(&res2.views) {
            assert_eq!(x.background, y.background);
            assert_eq!(x.masks, y.masks);
            assert_eq!(x.best_loop, y.best_loop);
        }
        assert_eq!(res.links[0].to_next, res2.links[0].to_next);
        for v in &res.views {
            assert_eq!(v.best_loop.len() % 10, 0);
            assert_eq!(v.best_loop.cost, 0);
        }
        // Frame s of view 0 has phase s; frame t of view 1 has phase t + 3.
        for (s, t) in res.links[0].to_next.iter().enumerate() {
            assert_eq!((t.unwrap() + 3) % 10, s % 10);
        }
        for (s, t) in res.links[0].to_prev.iter().enumerate() {
            assert_eq!(t.unwrap() % 10, (s + 3) % 10);
        }
    }

    #[test]
    fn views_of_different_sizes_are_named() {
        let mut a = view(0, 0, 20);
        let mut b = MemorySource {
            name: "small".into(),
            frames: vec![RgbImage::new(10, 10); 20],
        };
        let params = AnalyzeParams {
            loops: LoopParams {
                window: 2,
                min_length: 5,
            },
            ..Default::default()
        };
        let pts = vec![
            Point::new(0.0, 0.0),
            Point::new(9.0, 0.0),
            Point::new(9.0, 9.0),
            Point::new(0.0, 9.0),
        ];
        let err = analyze(
            &mut [&mut a, &mut b],
            &[pts.clone(), pts],
            &params,
            &mut Quiet,
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "views have different sizes: view 0 is 48x32, view 1 (small) is 10x10"
        );
    }
}
