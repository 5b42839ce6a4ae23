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
use crate::blur::{gaussian_blur, BlurScratch, GaussianBlur, GaussianParams};
use crate::loops::{check_loop_input, loops_from_pair_costs, pair_costs, Loop, LoopParams};
use crate::median::{temporal_median_frames, MedianAccumulator};
use crate::model::{select_model, ModelParams, MotionModel, Selection};
use crate::noise::{
    max_abs_diff, noise_mask, noise_model_from_diffs, pair_change, FrameSample, MotionKept,
    NoiseModel, NoiseParams,
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
    /// [`FrameSource::for_each_native`] of frames `0..end` alone: a source may stop reading
    /// past them (a video decoder stops decoding). Returns how many of them it gave: `end`, or
    /// fewer when the clip is shorter. The default reads every frame and hands out the first
    /// `end`.
    fn for_each_native_to(
        &mut self,
        end: usize,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> Result<()>,
    ) -> Result<usize> {
        let n = self.for_each_native(&mut |i, frame| if i < end { f(i, frame) } else { Ok(()) })?;
        Ok(n.min(end))
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

    /// Becomes a copy of `frame`, in this frame's buffer when it has the same form and size
    /// (no allocation: a stream of frames copied into a few).
    pub fn copy_from(&mut self, frame: FrameRef<'_>) {
        match (self, frame) {
            (Frame::Rgb(dst), FrameRef::Rgb(src)) if dst.dimensions() == src.dimensions() => {
                dst.copy_from_slice(src.as_raw())
            }
            (Frame::Yuv420(dst), FrameRef::Yuv420(src))
                if dst.dimensions() == src.dimensions()
                    && dst.matrix() == src.matrix()
                    && dst.range() == src.range() =>
            {
                dst.as_raw_mut().copy_from_slice(src.as_raw())
            }
            (this, frame) => *this = frame.to_owned(),
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
/// in docs/system-a.md: after both are smoothed, a pixel is *moving* when
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
    /// (not serialised into scenes: it changes speed and memory, and which frames the median
    /// samples: a cache's the middle of equal spans, a stream's every k-th, k a power of two).
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
    /// Per-region loops baked into one seamless loop per view ([`crate::regions`]), by default
    /// only where they measure better than the thesis's loop; None: the thesis's one loop
    /// (m, n) per view. Its source window (the frames around the thesis's loop) comes from the
    /// frame cache, or is decoded again and packed within `cache_bytes` (otherwise that view
    /// keeps its one loop).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regions: Option<crate::regions::RegionParams>,
    /// Handheld views made still before anything else reads their frames
    /// ([`crate::stabilize`]); what was measured goes into each view's result.
    #[serde(skip, default)]
    pub stabilize: crate::stabilize::StabilizeParams,
}

fn default_cache() -> usize {
    DEFAULT_CACHE_MB << 20
}

/// Default [`AnalyzeParams::cache_bytes`] in MiB (`vt analyze --cache-mb`): 246 frames of
/// 960x720 video, 185 of 1280x720. Analysis memory is about this plus 90 MB at 960x720,
/// whatever the video's length (frames past it stream: the two passes decode the video
/// twice; the report's real-size table has the time a larger cache saves).
pub const DEFAULT_CACHE_MB: usize = 256;

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
/// Largest [`AnalyzeParams::cache_bytes`] (1 TiB).
pub const MAX_CACHE_BYTES: usize = 1 << 40;
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
        for (name, n) in [
            ("loops.window", self.loops.window),
            ("loops.min_length", self.loops.min_length),
        ] {
            if n == 0 {
                return bad(name, "0".into(), "at least 1 frame".into());
            }
        }
        if self.loops.min_length > MAX_FRAMES_PER_VIEW {
            return bad(
                "loops.min_length",
                self.loops.min_length.to_string(),
                format!("at most {MAX_FRAMES_PER_VIEW} frames, the longest view"),
            );
        }
        if self.cache_bytes > MAX_CACHE_BYTES {
            return bad(
                "cache_bytes",
                self.cache_bytes.to_string(),
                format!("at most {MAX_CACHE_BYTES} bytes (1 TiB)"),
            );
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
        self.stabilize.check()?;
        if let Some(r) = &self.regions {
            r.check()?;
        }
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
            regions: Some(crate::regions::RegionParams {
                only_if_better: true,
                ..Default::default()
            }),
            stabilize: crate::stabilize::StabilizeParams::default(),
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
    /// Measuring the camera's shake and the still camera ([`crate::stabilize`]).
    Shake,
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
            Stage::Shake => "camera shake",
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
    /// object, eq. (4)-(5)); frames arrive in order. Frame 0 of a view arriving again starts
    /// the view over: a handheld view restarted through the still camera, or a per-region
    /// loop's baked frames replacing the frames already sent. An error aborts the analysis.
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
    /// Measuring the camera's shake ([`crate::stabilize::measure`]; warping the frames of a
    /// steadied view counts as decoding). The first pass's probe runs on a thread of its own
    /// beside the pass ([`crate::stabilize::Probing`]): its time overlaps the others'.
    pub shake: Duration,
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
    /// The per-region loop baked into this view's frames (then `masks` are the baked frames'
    /// and `best_loop` is `(0, L)`), with its measured quality; None: the thesis's loop.
    pub region_loop: Option<RegionResult>,
    /// The per-region loop made and measured but not kept, no better than the thesis's loop
    /// ([`crate::regions::RegionParams::only_if_better`]); the view keeps the thesis's loop.
    pub region_rejected: Option<RegionResult>,
    /// Per-region loops were asked for where better, and not tried: the thesis's loop, measured
    /// as they would be, already wraps as it steps ([`crate::regions::Quality::shows`]).
    pub region_not_needed: Option<crate::regions::Quality>,
    /// Per-region loops were asked for but not made for this view: the cache budget
    /// ([`AnalyzeParams::cache_bytes`]) their source window would need (the frames around the
    /// thesis's loop, packed: [`crate::packed`]); it keeps the thesis's loop. None when they
    /// were made or not asked for.
    pub regions_over_cache: Option<u64>,
    /// The camera's measured shake and the still camera the frames were warped to (None
    /// until the pipeline sets it).
    pub shake: Option<crate::stabilize::Shake>,
}

/// A view's per-region loop ([`crate::regions`]) and what it measures, beside the thesis's
/// single loop measured the same way on the same frames.
#[derive(Debug, Clone)]
pub struct RegionResult {
    /// The labels (source frame numbers of the view).
    pub chosen: crate::regions::RegionLoop,
    /// The baked loop measured.
    pub quality: crate::regions::Quality,
    /// The thesis's loop (m, n) measured the same way (its wrap is its one seam).
    pub single: crate::regions::Quality,
    /// Seconds of the whole bake (labels, composition, measures).
    pub secs: f64,
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

mod pipeline;
mod planes;
#[cfg(test)]
mod tests;
mod view;

pub use pipeline::analyze;
use pipeline::*;
pub use planes::ObjectPlane;
use planes::*;
use view::*;
