//! The online half of System A (seed thesis Sec. 3.3, SPEC B-1..B-3, eq. 3-6): which source frame
//! to show ([`Player`], eq. 6) and the intermediate-view image ([`Renderer`], eq. 3-5).
//!
//! # Exact behaviour at the special points
//! - `f = floor(q)`, `c = ceil(q)`. At an integer q, `f = c = q` and the background is
//!   `H_(q,q)(B_q)` alone; just off the integer the blend weights are `(1, 0)` or `(0, 1)`, so the
//!   background is continuous in q.
//! - `qbar = f` if `q - f < 0.5`, else `c` (eq. 5): at exactly `q - f = 0.5` the object comes from
//!   the *right* view `c`. This is the one place where the source view changes; the transition
//!   tables (eq. 2) make the object's phase continue, so the image changes only by what the two
//!   views disagree on.
//! - Eq. (6): the first frame shows `m_qbar + 1`. When `qbar` moves by more than one view between two
//!   output frames, the transitions are chained view by view (`s <- t_{p±1}(s, p)` per hop) and the
//!   `+ 1` of eq. (6) is applied once, after the last hop. A missing table entry (a target loop too
//!   short for any t) restarts the target's loop at `m + 1`.
//!
//! # Beyond the thesis (each switchable, see [`RenderParams`])
//! - Gain compensation: each view's exposure gain relative to its neighbours is estimated from the
//!   overlap of the warped backgrounds (median ratio per channel) and divided out.
//! - Crossfade: for `crossfade` frames after a loop wrap or view switch, the object is blended from
//!   the continuation of the old sequence into the new one (Schödl et al. 2000).
//! - Dissolve: the first `dissolve` frames after a loop wrap or view switch are in-between frames,
//!   blended from the last frame shown before the jump into the new sequence's frame `dissolve`,
//!   so a jump of D is spread over `dissolve + 1` steps of `D / (dissolve + 1)`. On footage that
//!   never repeats (tree.avi: the best 30-frame wrap is 1.86 ordinary steps of the render), no
//!   crossfade of continuing sequences brings a wrap under 1.19 steps (1-6 frames); one
//!   in-between frame brings it to 0.95, two to 0.69. Loop length and timing are unchanged.
//! - Both blend two whole layers, each composited over the background:
//!   `(1 - alpha) old + alpha new`.
//!
//! Per output frame the renderer allocates nothing once warm: warps write into owned buffers, and
//! the homographies and the warped, blended background are recomputed only when q changes.

use image::RgbImage;
use rayon::prelude::*;

use crate::model::{fit_model, MotionModel};
use crate::round_u8;
use crate::warp::{
    nearest_cell, sample_value, state, Interpolation, Mapping, Padded, Run, Sampler, BILINEAR,
    BILINEAR_FIXED, CHUNK, NEAREST, ROWS_PER_JOB,
};
use crate::{Error, Homography, Point, Result};

/// A view as the renderer needs it.
#[derive(Debug, Clone)]
pub struct RenderView {
    /// `B_p`.
    pub background: RgbImage,
    /// `m_p`.
    pub loop_start: usize,
    /// `n_p`.
    pub loop_end: usize,
    /// `t_{p+1}(s, p)` for every frame s.
    pub to_next: Vec<Option<usize>>,
    /// `t_{p-1}(s, p)` for every frame s.
    pub to_prev: Vec<Option<usize>>,
    /// The marked points `x_p`.
    pub points: Vec<Point>,
    /// Alpha of the view's dynamic region ([`crate::noise`]): where it is set, the object store
    /// holds the frame's own pixels, shown with this alpha over the background (None: objects
    /// only, the thesis).
    pub dynamic: Option<std::sync::Arc<image::GrayImage>>,
    /// Seam score of the switch `s -> to_next[s] + 1` per frame s (empty: unknown, every switch is
    /// acceptable).
    pub to_next_seam: Vec<f32>,
    /// Seam score of the switch `s -> to_prev[s] + 1` per frame s (empty: unknown).
    pub to_prev_seam: Vec<f32>,
}

/// Everything the online stage needs from an analysed scene.
#[derive(Debug, Clone)]
pub struct RenderScene {
    /// Views in order along the line.
    pub views: Vec<RenderView>,
    /// The model used for `H_(p,q)` (the scene's chosen model).
    pub model: MotionModel,
    /// The dense parallax of each neighbour pair `(p, p + 1)` that is morphed
    /// ([`crate::parallax`]); empty or None: the plane warp of eq. (3).
    pub parallax: Vec<Option<std::sync::Arc<crate::parallax::PairParallax>>>,
}

impl RenderScene {
    /// Largest valid q, `M - 1`.
    pub fn q_max(&self) -> f64 {
        (self.views.len() - 1) as f64
    }

    /// Checks a viewpoint.
    pub fn check_q(&self, q: f64) -> Result<()> {
        if !q.is_finite() || q < 0.0 || q > self.q_max() {
            return Err(Error::InvalidParameter {
                name: "q",
                value: q.to_string(),
                why: format!(
                    "the viewpoint must lie in [0, {}] (views 0 to {})",
                    self.q_max(),
                    self.q_max()
                ),
            });
        }
        Ok(())
    }

    /// The virtual points `x(q)` of B-1.
    pub fn virtual_points(&self, q: f64) -> Vec<Point> {
        let mut v = Vec::new();
        self.virtual_points_into(q, &mut v);
        v
    }

    /// [`RenderScene::virtual_points`] into a reused buffer.
    pub fn virtual_points_into(&self, q: f64, out: &mut Vec<Point>) {
        out.clear();
        let m1 = self.q_max();
        if m1 == 0.0 {
            out.extend_from_slice(&self.views[0].points);
            return;
        }
        let (a, b) = (
            &self.views[0].points,
            &self.views[self.views.len() - 1].points,
        );
        out.extend(
            a.iter()
                .zip(b)
                .map(|(p0, p1)| Point::from((p0.coords * (m1 - q) + p1.coords * q) / m1)),
        );
    }

    /// `H_(p,q)`: view p's points to the virtual points at q, with the scene's model.
    pub fn homography_to(&self, p: usize, q: f64) -> Result<Homography> {
        self.homography_to_with(p, q, &mut Vec::new())
    }

    /// [`RenderScene::homography_to`] with a reused buffer for the virtual points.
    pub fn homography_to_with(&self, p: usize, q: f64, buf: &mut Vec<Point>) -> Result<Homography> {
        if self.views.len() == 1 {
            return Ok(Homography::identity());
        }
        self.virtual_points_into(q, buf);
        Ok(fit_model(self.model, &self.views[p].points, buf, 1.0)?.homography)
    }
}

/// The views around a viewpoint q, as eq. (3)-(5) name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QSplit {
    /// `f = floor(q)`: the view at or left of q.
    pub floor: usize,
    /// `c = ceil(q)`: the view at or right of q.
    pub ceil: usize,
    /// `qbar`: the nearest view, the right one at the 0.5 tie; the moving object comes from it.
    pub nearest: usize,
}

/// `f`, `c` and `qbar` of eq. (3)-(5) for `q >= 0`.
pub fn split_q(q: f64) -> QSplit {
    let f = q.floor();
    let c = q.ceil();
    let qbar = if q - f < 0.5 { f } else { c };
    QSplit {
        floor: f as usize,
        ceil: c as usize,
        nearest: qbar as usize,
    }
}

/// What the player did to reach this frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// The first frame.
    Start,
    /// `j = j_prev + 1` in the same view.
    Play,
    /// `j = m + 1` after `n`: a loop wrap.
    Wrap,
    /// A view switch across `hops` views.
    Switch {
        /// Views crossed (|qbar - qbar_prev|).
        hops: usize,
    },
}

/// The source frame of one output frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameChoice {
    /// `qbar_i`.
    pub view: usize,
    /// `j_i`.
    pub frame: usize,
    /// How it was reached.
    pub step: Step,
    /// For a wrap or switch: the frame the old sequence would have shown next in the old view
    /// (`(view, frame)`), if it exists; used by the crossfade and the seam score.
    pub continuation: Option<(usize, usize)>,
}

/// When the player may postpone a view switch (beyond the thesis): a switch whose seam score
/// (the eq. (2) cost of the transition from the current frame, in ordinary steps) exceeds
/// `max_seam` is postponed, and the current view keeps playing, while q stays within
/// `max_past_tie` views past the 0.5 tie and for at most `max_frames` output frames; then the
/// switch happens at the first acceptable frame, or when a bound is reached. Only one-view
/// switches are postponed (a jump across several views follows eq. (6) at once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwitchPolicy {
    /// Largest acceptable seam score (`f64::INFINITY`: always switch at the tie, the thesis).
    pub max_seam: f64,
    /// How far past the tie the old view may still be shown, views (at most 0.45).
    pub max_past_tie: f64,
    /// Longest postponement, output frames.
    pub max_frames: usize,
}

impl SwitchPolicy {
    /// Eq. (6) exactly: switch at the tie, whatever the seam.
    pub fn thesis() -> Self {
        Self {
            max_seam: f64::INFINITY,
            ..Self::default()
        }
    }
}

impl Default for SwitchPolicy {
    fn default() -> Self {
        Self {
            max_seam: 1.5,
            max_past_tie: 0.25,
            max_frames: 12,
        }
    }
}

/// Eq. (6) as a state machine, with counters for the render summary.
#[derive(Debug, Clone, Default)]
pub struct Player {
    state: Option<(usize, usize)>,
    /// Loop wraps so far.
    pub wraps: u64,
    /// View switches so far (a multi-view jump counts once per hop).
    pub switches: u64,
    /// When to postpone a bad switch.
    pub policy: SwitchPolicy,
    delayed: usize,
    /// Output frames shown from the old view while a bad switch was postponed.
    pub postponed_frames: u64,
}

impl Player {
    /// A player before its first frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// A player with a switch policy.
    pub fn with_policy(policy: SwitchPolicy) -> Self {
        Self {
            policy,
            ..Self::default()
        }
    }

    /// Whether to postpone the switch from `(pv, pj)` to `qbar` at viewpoint q.
    fn postpone(&self, scene: &RenderScene, q: f64, pv: usize, pj: usize, qbar: usize) -> bool {
        let pol = &self.policy;
        if !pol.max_seam.is_finite() || pv.abs_diff(qbar) != 1 || self.delayed >= pol.max_frames {
            return false;
        }
        if (q - pv as f64).abs() > 0.5 + pol.max_past_tie.clamp(0.0, 0.45) {
            return false;
        }
        let v = &scene.views[pv];
        let seams = if qbar > pv {
            &v.to_next_seam
        } else {
            &v.to_prev_seam
        };
        seams.get(pj).is_some_and(|&s| s as f64 > pol.max_seam)
    }

    /// The last choice's `(view, frame)`.
    pub fn current(&self) -> Option<(usize, usize)> {
        self.state
    }

    /// Chooses the source frame for viewpoint `q` (eq. 6).
    pub fn advance(&mut self, scene: &RenderScene, q: f64) -> Result<FrameChoice> {
        scene.check_q(q)?;
        let qbar = split_q(q).nearest;
        // Switch where it matches: keep the current view a little longer if this switch is bad.
        let qbar = match self.state {
            Some((pv, pj)) if pv != qbar && self.postpone(scene, q, pv, pj, qbar) => {
                self.delayed += 1;
                self.postponed_frames += 1;
                pv
            }
            _ => {
                self.delayed = 0;
                qbar
            }
        };
        let v = &scene.views[qbar];
        let (frame, step, continuation) = match self.state {
            None => (v.loop_start + 1, Step::Start, None),
            Some((pv, pj)) if pv == qbar => {
                if pj == v.loop_end {
                    self.wraps += 1;
                    let cont = (pj + 1 < v.to_next.len()).then_some((pv, pj + 1));
                    (v.loop_start + 1, Step::Wrap, cont)
                } else {
                    (pj + 1, Step::Play, None)
                }
            }
            Some((pv, pj)) => {
                let mut s = pj;
                let mut p = pv;
                while p != qbar {
                    let (table, np) = if qbar > p {
                        (&scene.views[p].to_next, p + 1)
                    } else {
                        (&scene.views[p].to_prev, p - 1)
                    };
                    match table.get(s).copied().flatten() {
                        Some(t) => s = t,
                        None => s = scene.views[np].loop_start,
                    }
                    p = np;
                    self.switches += 1;
                }
                let cont = (pj + 1 < scene.views[pv].to_next.len()).then_some((pv, pj + 1));
                (
                    s + 1,
                    Step::Switch {
                        hops: pv.abs_diff(qbar),
                    },
                    cont,
                )
            }
        };
        self.state = Some((qbar, frame));
        Ok(FrameChoice {
            view: qbar,
            frame,
            step,
            continuation,
        })
    }
}

/// A moving object's pixels for one frame, decoded into a box: what [`ObjectFrames`] yields.
#[derive(Debug, Clone, Default)]
pub struct ObjectPatch {
    /// Box origin in the view's image.
    pub x0: u32,
    /// Box origin in the view's image.
    pub y0: u32,
    /// Box width (0 for no object).
    pub width: u32,
    /// Box height.
    pub height: u32,
    /// RGB, row-major over the box (undefined where `mask` is 0).
    pub rgb: Vec<u8>,
    /// 1 where the object is, row-major over the box.
    pub mask: Vec<u8>,
}

impl ObjectPatch {
    /// Sets the box and zeroes it (reusing storage).
    pub fn reset(&mut self, x0: u32, y0: u32, width: u32, height: u32) {
        let n = width as usize * height as usize;
        (self.x0, self.y0, self.width, self.height) = (x0, y0, width, height);
        self.rgb.clear();
        self.rgb.resize(n * 3, 0);
        self.mask.clear();
        self.mask.resize(n, 0);
    }
}

/// Source of moving-object pixels per (view, frame): the scene's object stores.
pub trait ObjectFrames {
    /// Decodes frame `frame` of view `view` into `patch` (reusing its storage).
    fn decode_into(&self, view: usize, frame: usize, patch: &mut ObjectPatch) -> Result<()>;
}

/// Rendering options. [`Default`] is the thesis's method with bilinear warping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderParams {
    /// Warp interpolation (bilinear default, nearest is faster).
    pub interpolation: Interpolation,
    /// Frames of object crossfade after a wrap or switch (0 = off, the thesis).
    pub crossfade: usize,
    /// In-between frames after a wrap or switch, dissolving the last frame shown into the new
    /// sequence (0 = off, the thesis; exclusive with `crossfade`).
    pub dissolve: usize,
    /// Where the shown view does not see a pixel at fractional q (near its image edges), show the
    /// other view of the pair's matching frame (its transition-table frame) instead of the
    /// static background. Scenes with dynamic regions only (objects would double).
    pub neighbour_fill: bool,
    /// Divide out per-view exposure gains (off = the thesis; on by default: on the 5-view scene
    /// made from tree.avi, +-6% gains, it lifts the worst PSNR at fractional q from 28.4 to
    /// 34.5 dB).
    pub gain_compensation: bool,
    /// Background reuse, pixels (0 = off, the default: every new q is blended exactly). While
    /// the viewpoint stays within q's pair of views and no background pixel would move by more
    /// than this from the kept background's viewpoint (measured at the image's corners and
    /// centre, through both views' homographies), the kept background `B_q` is shown again
    /// instead of re-blending; objects are still placed at the exact q. Errors measured by the
    /// render bench (`VT_RENDER_REUSE=1`) and in ARCHITECTURE.md; at most
    /// [`MAX_BACKGROUND_REUSE_PX`].
    pub background_reuse_px: f64,
}

/// Largest [`RenderParams::background_reuse_px`]: beyond a few pixels the reused background
/// visibly lags the objects.
pub const MAX_BACKGROUND_REUSE_PX: f64 = 4.0;

impl Default for RenderParams {
    fn default() -> Self {
        Self {
            interpolation: Interpolation::Bilinear,
            crossfade: 0,
            dissolve: 0,
            neighbour_fill: true,
            gain_compensation: true,
            background_reuse_px: 0.0,
        }
    }
}

/// Estimates each view's exposure gain (per channel) relative to the geometric mean of all views,
/// from the overlap of neighbouring backgrounds warped into each other: median of per-pixel ratios
/// over pixels both images see with values in 16..240 (clear of noise floor and saturation).
pub fn estimate_gains(scene: &RenderScene) -> Result<Vec<[f32; 3]>> {
    let m = scene.views.len();
    let mut rel = vec![[1.0f64; 3]; m];
    for p in 0..m.saturating_sub(1) {
        let (a, b) = (&scene.views[p].background, &scene.views[p + 1].background);
        let h = fit_model(
            scene.model,
            &scene.views[p + 1].points,
            &scene.views[p].points,
            1.0,
        )?
        .homography;
        let warped = crate::warp::warp_rgb(b, &h, a.width(), a.height(), Interpolation::Bilinear);
        let mut ratios: [Vec<f32>; 3] = Default::default();
        for (pa, pb) in a.pixels().zip(warped.pixels()) {
            if pb.0 == [0, 0, 0] {
                continue;
            }
            for c in 0..3 {
                let (x, y) = (pa.0[c], pb.0[c]);
                if (16..=240).contains(&x) && (16..=240).contains(&y) {
                    ratios[c].push(y as f32 / x as f32);
                }
            }
        }
        for c in 0..3 {
            let r = &mut ratios[c];
            let ratio = if r.len() < 100 {
                1.0
            } else {
                let mid = r.len() / 2;
                *r.select_nth_unstable_by(mid, f32::total_cmp).1 as f64
            };
            rel[p + 1][c] = rel[p][c] * ratio;
        }
    }
    let mut out = vec![[1.0f32; 3]; m];
    for c in 0..3 {
        let log_mean = rel.iter().map(|g| g[c].ln()).sum::<f64>() / m as f64;
        for p in 0..m {
            out[p][c] = (rel[p][c].ln() - log_mean).exp() as f32;
        }
    }
    Ok(out)
}

/// Renders output frames; owns every buffer it needs.
pub struct Renderer {
    scene: std::sync::Arc<RenderScene>,
    params: RenderParams,
    gains: Vec<[f32; 3]>,
    width: u32,
    height: u32,
    cached_q: Option<f64>,
    h_to_q: Vec<Option<Homography>>,
    /// The kept background `B_q` when `kept` says at which q: kept only once q stays (or a
    /// layer blend or background reuse needs it), so a moving viewpoint writes its background
    /// once, straight into the frame.
    background_q: RgbImage,
    kept: Option<Kept>,
    blends: u64,
    /// Each view's background with its edge replicated around it ([`Padded`]), made once, so the
    /// per-frame blend reads its taps without a border test.
    padded: Vec<Padded>,
    /// The new layer during a blend (allocated up front when blends are on).
    layer: RgbImage,
    vpoints: Vec<Point>,
    patch: ObjectPatch,
    patch_old: ObjectPatch,
    patch_fill: ObjectPatch,
    blend: Option<Blend>,
}

/// What `background_q` holds: `B_q` blended at `q` from the pair `(f, c)` through `h`.
#[derive(Debug, Clone, Copy)]
struct Kept {
    q: f64,
    pair: (usize, usize),
    h: [Homography; 2],
}

impl Kept {
    /// Largest displacement, output pixels, between the kept background and the one `h` would
    /// blend, at the corners and centre of a `w x h` image (`None`: a point left the plane).
    fn displacement(&self, h: [&Homography; 2], (w, hh): (u32, u32)) -> Option<f64> {
        let (w, hh) = (w as f64 - 1.0, hh as f64 - 1.0);
        let mut d: f64 = 0.0;
        for (old, new) in self.h.iter().zip(h) {
            for (x, y) in [
                (0.0, 0.0),
                (w, 0.0),
                (0.0, hh),
                (w, hh),
                (w / 2.0, hh / 2.0),
            ] {
                let p = Point::new(x, y);
                let moved = new.apply(old.apply_inverse(p)?)?;
                d = d.max((moved - p).norm());
            }
        }
        Some(d)
    }
}

/// An object blend in progress: a crossfade or a dissolve, `k` frames in.
#[derive(Debug, Clone, Copy)]
enum Blend {
    /// The old sequence's continuation `old` fading out under the new sequence.
    Fade { old: (usize, usize), k: usize },
    /// A still dissolve from `from` (the last frame before the jump) into `to`.
    Dissolve {
        from: (usize, usize),
        to: (usize, usize),
        k: usize,
    },
}

/// Longest object crossfade, frames (the blend weight `(k + 1) / (crossfade + 1)` stays exact in
/// `f32` and its counters far from overflow).
pub const MAX_CROSSFADE: usize = 1000;

impl Renderer {
    /// Prepares a renderer (estimates gains when asked). It takes the scene by `Arc` so callers
    /// that keep the scene (players, viewers) share its tables and backgrounds instead of copying
    /// them. Errors for a scene without views or a crossfade longer than [`MAX_CROSSFADE`] frames.
    pub fn new(
        scene: impl Into<std::sync::Arc<RenderScene>>,
        params: RenderParams,
    ) -> Result<Self> {
        let scene: std::sync::Arc<RenderScene> = scene.into();
        for (name, n) in [
            ("crossfade", params.crossfade),
            ("dissolve", params.dissolve),
        ] {
            if n > MAX_CROSSFADE {
                return Err(Error::InvalidParameter {
                    name,
                    value: n.to_string(),
                    why: format!("at most {MAX_CROSSFADE} frames"),
                });
            }
        }
        let reuse = params.background_reuse_px;
        if !(reuse.is_finite() && (0.0..=MAX_BACKGROUND_REUSE_PX).contains(&reuse)) {
            return Err(Error::InvalidParameter {
                name: "background_reuse_px",
                value: reuse.to_string(),
                why: format!("a displacement from 0 (off) to {MAX_BACKGROUND_REUSE_PX} pixels"),
            });
        }
        if params.crossfade > 0 && params.dissolve > 0 {
            return Err(Error::InvalidParameter {
                name: "dissolve",
                value: params.dissolve.to_string(),
                why: format!(
                    "a wrap is either crossfaded or dissolved, not both (crossfade {})",
                    params.crossfade
                ),
            });
        }
        let first = scene.views.first().ok_or_else(|| Error::InvalidParameter {
            name: "views",
            value: "0".into(),
            why: "a scene needs a view".into(),
        })?;
        let (width, height) = first.background.dimensions();
        let k_points = first.points.len();
        let gains = if params.gain_compensation {
            estimate_gains(&scene)?
        } else {
            vec![[1.0; 3]; scene.views.len()]
        };
        let m = scene.views.len();
        let padded = scene
            .views
            .iter()
            .map(|v| Padded::new(&v.background))
            .collect();
        Ok(Self {
            scene,
            params,
            gains,
            width,
            height,
            cached_q: None,
            kept: None,
            blends: 0,
            h_to_q: vec![None; m],
            background_q: RgbImage::new(width, height),
            padded,
            layer: if params.crossfade > 0 || params.dissolve > 0 {
                RgbImage::new(width, height)
            } else {
                RgbImage::new(0, 0)
            },
            vpoints: Vec::with_capacity(k_points),
            patch: ObjectPatch::default(),
            patch_old: ObjectPatch::default(),
            patch_fill: ObjectPatch::default(),
            blend: None,
        })
    }

    /// The blend state after `choice`: a wrap or switch starts a crossfade or dissolve (when
    /// enabled), a played frame advances it, anything else ends it.
    fn next_blend(&self, choice: &FrameChoice) -> Option<Blend> {
        let (cf, d) = (self.params.crossfade, self.params.dissolve);
        match (choice.step, choice.continuation, self.blend) {
            (Step::Wrap | Step::Switch { .. }, Some((v, j)), _) if cf > 0 => {
                Some(Blend::Fade { old: (v, j), k: 0 })
            }
            (Step::Wrap | Step::Switch { .. }, Some((v, j)), _) if d > 0 && j > 0 => {
                Some(Blend::Dissolve {
                    from: (v, j - 1),
                    to: (choice.view, choice.frame + d),
                    k: 0,
                })
            }
            (Step::Play, _, Some(Blend::Fade { old, k })) if k + 1 < cf => Some(Blend::Fade {
                old: (old.0, old.1 + 1),
                k: k + 1,
            }),
            (Step::Play, _, Some(Blend::Dissolve { from, to, k }))
                if k + 1 < d && choice.view == to.0 =>
            {
                Some(Blend::Dissolve { from, to, k: k + 1 })
            }
            _ => None,
        }
    }

    /// The frame that fills in for `frame` of `view` at `q` where `view` does not see: the other
    /// view of q's pair at the transition table's frame, when both have dynamic regions.
    fn fill_frame(&self, q: f64, view: usize, frame: usize) -> Option<(usize, usize)> {
        if !self.params.neighbour_fill {
            return None;
        }
        let QSplit { floor, ceil, .. } = split_q(q);
        let other = match view {
            _ if floor == ceil => return None,
            v if v == floor => ceil,
            v if v == ceil => floor,
            _ => return None,
        };
        let views = &self.scene.views;
        if views[view].dynamic.is_none() || views[other].dynamic.is_none() {
            return None;
        }
        let table = if other > view {
            &views[view].to_next
        } else {
            &views[view].to_prev
        };
        let t = table.get(frame).copied().flatten()?;
        (t < views[other].to_next.len()).then_some((other, t))
    }

    /// The scene.
    pub fn scene(&self) -> &RenderScene {
        &self.scene
    }

    /// The per-view gains in use (all 1 without compensation).
    pub fn gains(&self) -> &[[f32; 3]] {
        &self.gains
    }

    /// Backgrounds blended so far (the frames that did not copy a kept one).
    pub fn background_blends(&self) -> u64 {
        self.blends
    }

    /// Output size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Writes the blended background `B_q` (eq. 3) into `out`, recomputing `H_(f,q)` and
    /// `H_(c,q)` when q changed. `B_q` is blended straight into `out`; it is also kept (written
    /// in the same pass) when q is the previous frame's, when `keep` asks (a blend of layers
    /// reads it) or when background reuse is on, and then copied while q stays (or, with reuse,
    /// while the viewpoint stays near it).
    fn prepare_q(&mut self, q: f64, out: &mut RgbImage, keep: bool) -> Result<()> {
        let same = self.cached_q == Some(q);
        if !same {
            self.prepare_homographies(q)?;
        }
        let QSplit {
            floor: f,
            ceil: c,
            nearest: _,
        } = split_q(q);
        let hf = self.h_to_q[f].expect("computed with q");
        let hc = self.h_to_q[c].expect("computed with q");
        let reuse = self.params.background_reuse_px;
        if let Some(k) = &self.kept {
            let near = || {
                reuse > 0.0
                    && k.pair == (f, c)
                    && k.displacement([&hf, &hc], out.dimensions())
                        .is_some_and(|d| d <= reuse)
            };
            if k.q == q || near() {
                out.as_mut().copy_from_slice(self.background_q.as_raw());
                return Ok(());
            }
        }
        let keep = same || keep || reuse > 0.0;
        let (wf, wc) = if f == c {
            (1.0, 0.0)
        } else {
            ((c as f64 - q) as f32, (q - f as f64) as f32)
        };
        let sources = [
            Source {
                image: &self.padded[f],
                h: &hf,
                gain_inv: self.gains[f].map(|g| 1.0 / g),
                weight: wf,
            },
            Source {
                image: &self.padded[c],
                h: &hc,
                gain_inv: self.gains[c].map(|g| 1.0 / g),
                weight: wc,
            },
        ];
        match self.scene.parallax.get(f).and_then(Option::as_ref) {
            Some(par) if f != c => morph_blend(
                [&self.padded[f], &self.padded[c]],
                par,
                [&hf, &hc],
                [sources[0].gain_inv, sources[1].gain_inv],
                q - f as f64,
                out,
                keep.then_some(self.background_q.as_mut()),
            ),
            _ => blend_warps(
                &sources[..if f == c { 1 } else { 2 }],
                self.params.interpolation,
                out,
                keep.then_some(self.background_q.as_mut()),
            ),
        }
        self.blends += 1;
        self.kept = keep.then_some(Kept {
            q,
            pair: (f, c),
            h: [hf, hc],
        });
        Ok(())
    }

    /// `H_(p,q)` for q's pair and nearest view; the others cleared.
    fn prepare_homographies(&mut self, q: f64) -> Result<()> {
        self.cached_q = None;
        let QSplit {
            floor: f,
            ceil: c,
            nearest: qbar,
        } = split_q(q);
        self.h_to_q.iter_mut().for_each(|h| *h = None);
        for p in [f, c, qbar] {
            if self.h_to_q[p].is_none() {
                self.h_to_q[p] = Some(self.scene.homography_to_with(p, q, &mut self.vpoints)?);
            }
        }
        self.cached_q = Some(q);
        Ok(())
    }

    /// Renders viewpoint `q` showing `choice` (from [`Player::advance`]) into `out`.
    pub fn render_into(
        &mut self,
        objects: &dyn ObjectFrames,
        q: f64,
        choice: &FrameChoice,
        out: &mut RgbImage,
    ) -> Result<()> {
        self.scene.check_q(q)?;
        if out.dimensions() != (self.width, self.height) {
            return Err(Error::SizeMismatch {
                what: "render output".into(),
                expected_w: self.width,
                expected_h: self.height,
                got_w: out.width(),
                got_h: out.height(),
            });
        }
        // What the object shows: the chosen frame, or a blend of two (crossfade or dissolve).
        self.blend = self.next_blend(choice);
        self.prepare_q(q, out, self.blend.is_some())?;
        let view = choice.view;
        let h = self.h_to_q[view].expect("qbar's homography is prepared");
        let views = &self.scene.views;
        let (shown, old, alpha) = match self.blend {
            Some(Blend::Fade { old, k }) if old.1 < views[old.0].to_next.len() => (
                (view, choice.frame),
                Some(old),
                (k + 1) as f32 / (self.params.crossfade + 1) as f32,
            ),
            Some(Blend::Dissolve { from, to, k })
                if from.1 < views[from.0].to_next.len() && to.1 < views[to.0].to_next.len() =>
            {
                (
                    to,
                    Some(from),
                    (k + 1) as f32 / (self.params.dissolve + 1) as f32,
                )
            }
            _ => {
                self.blend = None;
                ((view, choice.frame), None, 1.0)
            }
        };
        objects.decode_into(shown.0, shown.1, &mut self.patch)?;
        let fill = self.fill_frame(q, view, shown.1);
        if let Some((fv, fj)) = fill {
            objects.decode_into(fv, fj, &mut self.patch_fill)?;
        }
        // The shown layer: the neighbour's fill (if any) under the shown frame, faded in with the
        // distance from the shown view (0 at an integer q, 1 at the tie) so q moves continuously.
        let fill_alpha = (2.0 * (q - view as f64).abs()).min(1.0) as f32;
        let composite_shown =
            |patch: &ObjectPatch, fill_patch: &ObjectPatch, out: &mut RgbImage| {
                if let Some((fv, _)) = fill {
                    composite(
                        fill_patch,
                        &self.h_to_q[fv].expect("q's pair is prepared"),
                        self.params.interpolation,
                        self.gains[fv],
                        fill_alpha,
                        self.scene.views[fv].dynamic.as_deref(),
                        out,
                    );
                }
                composite(
                    patch,
                    &h,
                    self.params.interpolation,
                    self.gains[view],
                    1.0,
                    self.scene.views[view].dynamic.as_deref(),
                    out,
                )
            };
        let Some((ov, oj)) = old else {
            composite_shown(&self.patch, &self.patch_fill, out);
            return Ok(());
        };
        // A blend mixes two whole layers, each composited over the background:
        // (1 - alpha) old + alpha new, so neither is dimmed towards the background.
        if self.layer.dimensions() != out.dimensions() {
            self.layer = RgbImage::new(out.width(), out.height());
        }
        if self.kept.is_none() {
            // A blend that started after prepare_q's check (never: it keeps B_q for any blend).
            return Err(Error::InvalidParameter {
                name: "render state",
                value: "background".into(),
                why: "the blended background was not kept for a layer blend".into(),
            });
        }
        self.layer.copy_from_slice(self.background_q.as_raw());
        composite_shown(&self.patch, &self.patch_fill, &mut self.layer);
        objects.decode_into(ov, oj, &mut self.patch_old)?;
        let ho = match self.h_to_q[ov] {
            Some(hh) => hh,
            None => self.scene.homography_to_with(ov, q, &mut self.vpoints)?,
        };
        composite(
            &self.patch_old,
            &ho,
            self.params.interpolation,
            self.gains[ov],
            1.0,
            self.scene.views[ov].dynamic.as_deref(),
            out,
        );
        let (a, b) = (1.0 - alpha, alpha);
        out.as_mut()
            .par_chunks_mut(1 << 16)
            .zip(self.layer.as_raw().par_chunks(1 << 16))
            .for_each(|(o, l)| {
                for (o, &l) in o.iter_mut().zip(l) {
                    *o = round_u8(a * *o as f32 + b * l as f32);
                }
            });
        Ok(())
    }
}

use crate::parallax::{CONVERGED_PX, FIXED_POINT_STEPS as MORPH_STEPS, UNCONVERGED_WEIGHT};

/// The background beyond the plane (the morph of [`crate::parallax`]) at fraction `frac` of
/// the pair: each output pixel `z` is traced into both views (`x0 = H_(p,q)^-1 z`, then the
/// fixed point `x = x0 - frac u(x)` along that view's parallax field; `1 - frac` from the
/// other), sampled bilinearly, divided by the view's gain and blended with weights
/// `(1 - frac, frac)` (one view alone where the other's sample falls outside its image; both
/// from their replicated edges where neither sees; the view whose trace converged preferred
/// where only one did, as in [`crate::parallax::morph`]). Rows in parallel; written to `out` and
/// `copy` when given.
fn morph_blend(
    images: [&Padded; 2],
    par: &crate::parallax::PairParallax,
    h: [&Homography; 2],
    gain_inv: [[f32; 3]; 2],
    frac: f64,
    out: &mut RgbImage,
    copy: Option<&mut [u8]>,
) {
    let w = out.width() as usize;
    let size = out.dimensions();
    let side = |s: usize| {
        let fld = [&par.a, &par.b][s];
        MorphSide {
            sampler: Sampler::padded(
                images[s],
                h[s],
                Interpolation::Bilinear,
                Mapping::Division,
                size,
            ),
            iw: fld.width() as usize,
            ih: fld.height() as usize,
            flow: fld.flow(),
            frac: if s == 0 { frac } else { 1.0 - frac },
            gain_inv: gain_inv[s],
        }
    };
    let sides = [side(0), side(1)];
    let job = |y: usize, row: &mut [u8], copy: Option<&mut [u8]>| {
        crate::simd::dispatch(MorphRow {
            sides: &sides,
            frac: frac as f32,
            y,
            row,
            copy,
            w,
        })
    };
    match copy {
        Some(copy) => out
            .as_mut()
            .par_chunks_mut(3 * w)
            .zip(copy.par_chunks_mut(3 * w))
            .enumerate()
            .for_each(|(y, (row, c))| job(y, row, Some(c))),
        None => out
            .as_mut()
            .par_chunks_mut(3 * w)
            .enumerate()
            .for_each(|(y, row)| job(y, row, None)),
    }
}

/// One view's constants for the morph's pixel loop.
struct MorphSide<'a> {
    /// The view's background through `H_(p,q)` (exact bilinear, replicated edges).
    sampler: Sampler<'a>,
    iw: usize,
    ih: usize,
    flow: &'a [[i16; 2]],
    frac: f64,
    gain_inv: [f32; 3],
}

/// One output row of the morph ([`morph_blend`]), as a [`crate::simd::Kernel`]: runs of
/// [`CHUNK`] pixels, each step of the fixed point done for the whole run before the next (the
/// run's independent chains of load, multiply, load overlap in the CPU), sampled by the plane
/// warp's sampler at the traced points.
struct MorphRow<'a, 'b> {
    sides: &'a [MorphSide<'b>; 2],
    frac: f32,
    y: usize,
    row: &'a mut [u8],
    copy: Option<&'a mut [u8]>,
    w: usize,
}

impl crate::simd::Kernel for MorphRow<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let MorphRow {
            sides,
            frac,
            y,
            row,
            copy,
            w,
        } = self;
        // On the stack, once per row: rayon's per-job init would allocate.
        let mut runs = [Run::default(), Run::default()];
        let mut converged = [[false; CHUNK]; 2];
        let c2 = (CONVERGED_PX * CONVERGED_PX) as f32;
        let mut x_start = 0;
        while x_start < w {
            let n = CHUNK.min(w - x_start);
            for (s, (sd, run)) in sides.iter().zip(runs.iter_mut()).enumerate() {
                sd.sampler.map_into(y, x_start, run);
                // The trace in f32 (16 lanes with AVX-512): a pixel's position to 1/4096 px
                // below 4096 px.
                let (bx, by) = (run.sx.map(|v| v as f32), run.sy.map(|v| v as f32));
                let (mut sx, mut sy) = (bx, by);
                let (iw, ih) = (sd.iw, sd.ih);
                let fr = sd.frac as f32 * crate::parallax::FLOW_UNIT;
                let flow = sd.flow;
                let last = flow.len() - 1;
                let (mut px, mut py) = (sx, sy);
                for _ in 0..MORPH_STEPS {
                    (px, py) = (sx, sy);
                    for i in 0..CHUNK {
                        // `min(last)`: the index is provably in the slice, so the loop has no
                        // bounds-check branch and vectorises with gathers.
                        let u = flow[nearest_cell(sx[i], sy[i], iw, ih).min(last)];
                        sx[i] = bx[i] - f32::from(u[0]) * fr;
                        sy[i] = by[i] - f32::from(u[1]) * fr;
                    }
                }
                // Converged: the last step moved it less than CONVERGED_PX (see
                // `parallax::morph`).
                for i in 0..CHUNK {
                    let (ex, ey) = (sx[i] - px[i], sy[i] - py[i]);
                    converged[s][i] = ex * ex + ey * ey < c2;
                }
                run.sx = sx.map(f64::from);
                run.sy = sy.map(f64::from);
                sd.sampler.taps_at(n, run);
            }
            let [ra, rb] = &runs;
            let (ga, gb) = (sides[0].gain_inv, sides[1].gain_inv);
            for i in 0..n {
                let (ia, ib) = (ra.state[i] == state::INSIDE, rb.state[i] == state::INSIDE);
                let (mut wa, mut wb) = (1.0 - frac, frac);
                // Outside its image a view gives its replicated edge, used only where neither
                // view sees.
                if ia != ib {
                    (wa, wb) = (ia as u8 as f32, ib as u8 as f32);
                } else if converged[0][i] != converged[1][i] {
                    wa *= if converged[0][i] {
                        1.0
                    } else {
                        UNCONVERGED_WEIGHT
                    };
                    wb *= if converged[1][i] {
                        1.0
                    } else {
                        UNCONVERGED_WEIGHT
                    };
                }
                let norm = 1.0 / (wa + wb);
                let x = x_start + i;
                for k in 0..3 {
                    let va = sample_value::<BILINEAR>(ra, i, k) * ga[k];
                    let vb = sample_value::<BILINEAR>(rb, i, k) * gb[k];
                    row[3 * x + k] = round_u8((va * wa + vb * wb) * norm);
                }
            }
            x_start += n;
        }
        if let Some(copy) = copy {
            copy.copy_from_slice(row);
        }
    }
}

/// One background of eq. (3): the image, its `H_(p,q)`, its inverse gain and blend weight.
struct Source<'a> {
    image: &'a Padded,
    h: &'a Homography,
    gain_inv: [f32; 3],
    weight: f32,
}

/// Eq. (3) in one pass: each output pixel samples every source through its homography
/// (edges replicated), and blends with the sources' weights renormalised over the sources whose
/// sample really falls inside their image (`-0.5 <= x < w - 0.5`), so a strip only one view sees
/// takes that view alone instead of fading to black. Where no source sees the pixel, all are
/// blended from their replicated edges.
///
/// Sampling is [`crate::warp`]'s sampler (runs of [`CHUNK`] pixels, the renderer's
/// division mapping, replicated border, read from the padded backgrounds); rows in parallel.
/// Each run is written to `out` and, when given, to `copy` (the same size): the frame starts
/// from the background without a second pass over it.
fn blend_warps<'a>(
    sources: &[Source<'a>],
    interp: Interpolation,
    out: &mut RgbImage,
    copy: Option<&mut [u8]>,
) {
    let w = out.width() as usize;
    if w == 0 || sources.is_empty() {
        return;
    }
    let size = out.dimensions();
    let sampler = |s: &Source<'a>| {
        let sampler = Sampler::padded(s.image, s.h, interp, Mapping::Division, size);
        // weight * gain_inv[k], in the order the per-pixel formula multiplies them.
        let wg = s.gain_inv.map(|g| s.weight * g);
        (sampler, wg, s.weight)
    };
    let first = sampler(&sources[0]);
    // One source: the second contributes nothing (its state stays NONE).
    let second = sources.get(1).map(sampler);
    let band = w * 3 * ROWS_PER_JOB;
    let job = |(i, (rows, copy)): (usize, (&mut [u8], Option<&mut [u8]>))| {
        crate::simd::dispatch(BlendBand {
            first: &first,
            second: second.as_ref(),
            y0: i * ROWS_PER_JOB,
            rows,
            copy,
            w,
        })
    };
    match copy {
        Some(copy) => out
            .as_mut()
            .par_chunks_mut(band)
            .zip(copy.par_chunks_mut(band).map(Some))
            .enumerate()
            .for_each(job),
        None => out
            .as_mut()
            .par_chunks_mut(band)
            .map(|rows| (rows, None))
            .enumerate()
            .for_each(job),
    }
}

/// A sampler with its weights times inverse gains, and its weight.
type Weighted<'a> = (Sampler<'a>, [f32; 3], f32);

/// Rows of [`blend_warps`] as a [`crate::simd::Kernel`].
struct BlendBand<'a, 'b> {
    first: &'a Weighted<'b>,
    second: Option<&'a Weighted<'b>>,
    y0: usize,
    rows: &'a mut [u8],
    copy: Option<&'a mut [u8]>,
    w: usize,
}

impl crate::simd::Kernel for BlendBand<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        match self.first.0.interpolation() {
            Interpolation::Nearest => self.blend::<NEAREST>(),
            Interpolation::Bilinear => self.blend::<BILINEAR>(),
            Interpolation::BilinearFixed => self.blend::<BILINEAR_FIXED>(),
        }
    }
}

impl BlendBand<'_, '_> {
    /// The band's rows, sampled and blended in one pass per run of pixels.
    #[inline(always)]
    fn blend<const MODE: u8>(self) {
        let BlendBand {
            first,
            second,
            y0,
            rows,
            mut copy,
            w,
        } = self;
        // On the stack, once per band: rayon's per-job init would allocate.
        let (r0, r1) = (&mut Run::default(), &mut Run::default());
        let (wg0, weight0) = (first.1, first.2);
        let (wg1, weight1) = second.map_or(([0.0; 3], 0.0), |s| (s.1, s.2));
        let (mut sel0, mut sel1, mut ws) = ([false; CHUNK], [false; CHUNK], [0f32; CHUNK]);
        let mut bytes = [[0u8; CHUNK]; 3];
        let mut buf = [0u8; CHUNK * 3];
        for (r, row) in rows.chunks_mut(w * 3).enumerate() {
            let y = y0 + r;
            for (c, px) in row.chunks_mut(CHUNK * 3).enumerate() {
                let n = px.len() / 3;
                // A source without a sample (empty image, or no second source) has states NONE
                // and is never selected below, whatever its taps hold.
                first.0.taps(y, c * CHUNK, n, r0);
                match second {
                    Some(s) => {
                        s.0.taps(y, c * CHUNK, n, r1);
                    }
                    None => r1.state = [state::NONE; CHUNK],
                }
                // Per pixel: the sum runs over the sources whose sample is inside if any
                // weight is there, else over all with a sample; divided by their weights' sum.
                for i in 0..CHUNK {
                    let pick = |c: bool, v: f32| if c { v } else { 0.0 };
                    let (s0, s1) = (r0.state[i], r1.state[i]);
                    let (in0, in1) = (s0 == state::INSIDE, s1 == state::INSIDE);
                    let (has0, has1) = (s0 != state::NONE, s1 != state::NONE);
                    let ws_in = (0.0 + pick(in0, weight0)) + pick(in1, weight1);
                    let ws_all = (0.0 + pick(has0, weight0)) + pick(has1, weight1);
                    let use_in = ws_in > 0.0;
                    sel0[i] = if use_in { in0 } else { has0 };
                    sel1[i] = if use_in { in1 } else { has1 };
                    ws[i] = if use_in { ws_in } else { ws_all };
                }
                for (k, bytes) in bytes.iter_mut().enumerate() {
                    for i in 0..CHUNK {
                        // v = weight * gain_inv * sample, summed over the selected sources in
                        // order. Selects instead of branches (so it vectorises); `0 + v` and
                        // `v + 0` are `v`, so the sum equals the branchy one bit for bit.
                        let pick = |c: bool, v: f32| if c { v } else { 0.0 };
                        let v0 = wg0[k] * sample_value::<MODE>(r0, i, k);
                        let v1 = wg1[k] * sample_value::<MODE>(r1, i, k);
                        let acc = (0.0 + pick(sel0[i], v0)) + pick(sel1[i], v1);
                        let v = round_u8(acc / ws[i]);
                        bytes[i] = if ws[i] > 0.0 { v } else { 0 };
                    }
                }
                // Interleaved into RGB (a strided store the compiler shuffles), then copied.
                for i in 0..CHUNK {
                    for k in 0..3 {
                        buf[3 * i + k] = bytes[k][i];
                    }
                }
                px.copy_from_slice(&buf[..px.len()]);
                if let Some(copy) = copy.as_deref_mut() {
                    let at = r * w * 3 + c * CHUNK * 3;
                    copy[at..at + px.len()].copy_from_slice(&buf[..px.len()]);
                }
            }
        }
    }
}

/// Warps the object patch by `h` (inverse mapping over the forward image of the box) and writes
/// it over `out` with opacity `alpha`. Colours are sampled bilinearly from object pixels only
/// (mask-weighted); a pixel belongs to the object where the bilinear mask coverage is >= 0.5
/// (nearest: where the nearest source pixel is object). Where the view's dynamic-region alpha
/// (sampled at the nearest source pixel) is set, it scales the opacity: the region's feathered
/// edge blends the source frame into the background instead of cutting it.
fn composite(
    patch: &ObjectPatch,
    h: &Homography,
    interp: Interpolation,
    gain: [f32; 3],
    alpha: f32,
    dynamic: Option<&image::GrayImage>,
    out: &mut RgbImage,
) {
    if patch.width == 0 || patch.height == 0 {
        return;
    }
    let (ow, oh) = out.dimensions();
    let (pw, ph) = (patch.width as i64, patch.height as i64);
    let (x0, y0) = (patch.x0 as f64, patch.y0 as f64);
    // Output region: forward image of the box corners (w > 0 at all corners, else everything).
    let m = h.raw().0;
    let corners = [
        (x0 - 1.0, y0 - 1.0),
        (x0 + pw as f64, y0 - 1.0),
        (x0 - 1.0, y0 + ph as f64),
        (x0 + pw as f64, y0 + ph as f64),
    ];
    let mut region = (0u32, 0u32, ow, oh);
    if corners
        .iter()
        .all(|&(x, y)| m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)] > 0.0)
    {
        let (mut lx, mut ly, mut hx, mut hy) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for &(x, y) in &corners {
            if let Some(p) = h.apply(Point::new(x, y)) {
                lx = lx.min(p.x);
                ly = ly.min(p.y);
                hx = hx.max(p.x);
                hy = hy.max(p.y);
            }
        }
        let cl = |v: f64, hi: u32| v.clamp(0.0, hi as f64) as u32;
        region = (
            cl(lx.floor() - 1.0, ow),
            cl(ly.floor() - 1.0, oh),
            cl(hx.ceil() + 2.0, ow),
            cl(hy.ceil() + 2.0, oh),
        );
    }
    let inv = h.raw().1;
    let row_len = ow as usize * 3;
    let rows = &mut out.as_mut()[region.1 as usize * row_len..region.3 as usize * row_len];
    let ctx = CompositeCtx {
        patch,
        inv,
        interp,
        gain,
        alpha,
        dynamic,
        x0,
        y0,
        pw,
        ph,
        region,
    };
    // Rows in parallel (each pixel is its own computation, so the same bytes), each through
    // the SIMD dispatch (floor and rounding inline instead of library calls).
    rows.par_chunks_mut(row_len)
        .enumerate()
        .for_each(|(r, raw)| {
            crate::simd::dispatch(CompositeRow {
                ctx: &ctx,
                y: region.1 + r as u32,
                raw,
            })
        });
}

/// What every row of [`composite`] reads.
#[derive(Clone, Copy)]
struct CompositeCtx<'a> {
    patch: &'a ObjectPatch,
    inv: &'a nalgebra::Matrix3<f64>,
    interp: Interpolation,
    gain: [f32; 3],
    alpha: f32,
    dynamic: Option<&'a image::GrayImage>,
    x0: f64,
    y0: f64,
    pw: i64,
    ph: i64,
    region: (u32, u32, u32, u32),
}

impl CompositeCtx<'_> {
    /// The patch index of object pixel `(x, y)` (view coordinates), if it is one.
    #[inline(always)]
    fn sample(&self, x: i64, y: i64) -> Option<usize> {
        let (lx, ly) = (x - self.patch.x0 as i64, y - self.patch.y0 as i64);
        if lx < 0 || ly < 0 || lx >= self.pw || ly >= self.ph {
            return None;
        }
        let i = (ly * self.pw + lx) as usize;
        (self.patch.mask[i] != 0).then_some(i)
    }
}

/// One output row of [`composite`] as a [`crate::simd::Kernel`].
struct CompositeRow<'a, 'b> {
    ctx: &'a CompositeCtx<'b>,
    y: u32,
    raw: &'a mut [u8],
}

impl crate::simd::Kernel for CompositeRow<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let CompositeRow { ctx, y, raw } = self;
        let CompositeCtx {
            patch,
            inv,
            interp,
            gain,
            alpha,
            dynamic,
            x0,
            y0,
            pw,
            ph,
            region,
        } = *ctx;
        let sample = |x: i64, y: i64| ctx.sample(x, y);
        let yf = y as f64;
        for x in region.0..region.2 {
            let xf = x as f64;
            let w = inv[(2, 0)] * xf + inv[(2, 1)] * yf + inv[(2, 2)];
            if w == 0.0 {
                continue;
            }
            let sx = (inv[(0, 0)] * xf + inv[(0, 1)] * yf + inv[(0, 2)]) / w;
            let sy = (inv[(1, 0)] * xf + inv[(1, 1)] * yf + inv[(1, 2)]) / w;
            if !(sx.is_finite() && sy.is_finite())
                || sx < x0 - 1.0
                || sy < y0 - 1.0
                || sx > x0 + pw as f64
                || sy > y0 + ph as f64
            {
                continue;
            }
            let mut colour = [0f32; 3];
            match interp {
                Interpolation::Nearest => {
                    let Some(i) = sample(sx.round_ties_even() as i64, sy.round_ties_even() as i64)
                    else {
                        continue;
                    };
                    for c in 0..3 {
                        colour[c] = patch.rgb[i * 3 + c] as f32;
                    }
                }
                Interpolation::Bilinear | Interpolation::BilinearFixed => {
                    let (fx0, fy0) = (sx.floor(), sy.floor());
                    let (fx, fy) = ((sx - fx0) as f32, (sy - fy0) as f32);
                    let (ix, iy) = (fx0 as i64, fy0 as i64);
                    let taps = [
                        (ix, iy, (1.0 - fx) * (1.0 - fy)),
                        (ix + 1, iy, fx * (1.0 - fy)),
                        (ix, iy + 1, (1.0 - fx) * fy),
                        (ix + 1, iy + 1, fx * fy),
                    ];
                    let mut cover = 0f32;
                    for &(tx, ty, wt) in &taps {
                        if let Some(i) = sample(tx, ty) {
                            cover += wt;
                            for c in 0..3 {
                                colour[c] += wt * patch.rgb[i * 3 + c] as f32;
                            }
                        }
                    }
                    if cover < 0.5 {
                        continue;
                    }
                    for v in &mut colour {
                        *v /= cover;
                    }
                }
            }
            let o = x as usize * 3;
            let alpha = match dynamic {
                Some(d) => {
                    let (dw, dh) = (d.width() as i64, d.height() as i64);
                    let (ax, ay) = (
                        (sx.round_ties_even() as i64).clamp(0, dw - 1),
                        (sy.round_ties_even() as i64).clamp(0, dh - 1),
                    );
                    let a = d.as_raw()[(ay * dw + ax) as usize];
                    if a > 0 {
                        alpha * a as f32 / 255.0
                    } else {
                        alpha
                    }
                }
                None => alpha,
            };
            for c in 0..3 {
                let v = colour[c] / gain[c];
                let blended = alpha * v + (1.0 - alpha) * raw[o + c] as f32;
                raw[o + c] = round_u8(blended);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_crossfade_is_an_error_not_an_overflow() {
        for crossfade in [MAX_CROSSFADE + 1, usize::MAX] {
            let params = RenderParams {
                crossfade,
                ..RenderParams::default()
            };
            let e = Renderer::new(tiny(), params).err().expect("refused");
            assert!(e.to_string().contains("crossfade"), "{e}");
        }
        let params = RenderParams {
            crossfade: MAX_CROSSFADE,
            gain_compensation: false,
            ..RenderParams::default()
        };
        assert!(Renderer::new(tiny(), params).is_ok());
    }

    /// Solid 4x4 objects whose grey level is 10 x (frame + 1), so a blend's weights show.
    struct Solid;
    impl ObjectFrames for Solid {
        fn decode_into(&self, _view: usize, frame: usize, patch: &mut ObjectPatch) -> Result<()> {
            patch.reset(0, 0, 4, 4);
            patch.rgb.fill(10 * (frame as u8 + 1));
            patch.mask.fill(1);
            Ok(())
        }
    }

    #[test]
    fn dissolve_spreads_the_wrap_over_in_between_frames() {
        // View 0 loops 1..=5: frames 2, 3, 4, 5, then the wrap to 2. With dissolve 2 the wrap
        // and the frame after show the last frame (5) dissolving into frame 2 + 2 = 4, weights
        // 1/3 and 2/3; then play goes on from 4 unblended.
        let grey = |params: RenderParams| {
            let s = std::sync::Arc::new(tiny());
            let mut r = Renderer::new(s.clone(), params).unwrap();
            let mut p = Player::new();
            let mut out = RgbImage::new(4, 4);
            (0..7)
                .map(|_| {
                    let c = p.advance(&s, 0.0).unwrap();
                    r.render_into(&Solid, 0.0, &c, &mut out).unwrap();
                    (c.frame, out.get_pixel(1, 1).0[0])
                })
                .collect::<Vec<_>>()
        };
        let plain = RenderParams {
            gain_compensation: false,
            ..RenderParams::default()
        };
        assert_eq!(
            grey(plain),
            [
                (2, 30),
                (3, 40),
                (4, 50),
                (5, 60),
                (2, 30),
                (3, 40),
                (4, 50)
            ]
        );
        let dissolved = RenderParams {
            dissolve: 2,
            ..plain
        };
        // 60 + (50 - 60) / 3 = 56.67 -> 57; 60 + 2 (50 - 60) / 3 = 53.33 -> 53.
        assert_eq!(
            grey(dissolved),
            [
                (2, 30),
                (3, 40),
                (4, 50),
                (5, 60),
                (2, 57),
                (3, 53),
                (4, 50)
            ]
        );
        let both = RenderParams {
            crossfade: 1,
            ..dissolved
        };
        let e = Renderer::new(tiny(), both).err().expect("refused");
        assert!(e.to_string().contains("dissolve"), "{e}");
    }

    /// No moving objects: the frame is the blended background alone.
    struct NoObjects;
    impl ObjectFrames for NoObjects {
        fn decode_into(&self, _view: usize, _frame: usize, patch: &mut ObjectPatch) -> Result<()> {
            patch.reset(0, 0, 0, 0);
            Ok(())
        }
    }

    #[test]
    fn kept_background_equals_a_fresh_render() {
        // The background is blended into the frame, kept only once q stays, then copied: every
        // frame of a path that moves, stays, jumps back and stays must equal the first frame of
        // a new renderer at that q (which blends it afresh).
        let mut scene = tiny();
        for (p, v) in scene.views.iter_mut().enumerate() {
            v.background = RgbImage::from_fn(23, 17, |x, y| {
                image::Rgb([(x * 11 + y * 3) as u8, (y * 13 + p as u32 * 40) as u8, 90])
            });
        }
        let scene = std::sync::Arc::new(scene);
        let params = RenderParams::default();
        let mut r = Renderer::new(scene.clone(), params).unwrap();
        let mut p = Player::new();
        let mut out = RgbImage::new(23, 17);
        for q in [0.3, 0.3, 0.3, 0.55, 0.55, 1.2, 0.3, 0.3, 2.0, 2.0, 2.0] {
            let c = p.advance(&scene, q).unwrap();
            r.render_into(&NoObjects, q, &c, &mut out).unwrap();
            let mut fresh = Renderer::new(scene.clone(), params).unwrap();
            let mut want = RgbImage::new(23, 17);
            fresh.render_into(&NoObjects, q, &c, &mut want).unwrap();
            assert!(out == want, "q {q}");
            assert!(
                out.as_raw().iter().any(|&v| v != 0),
                "q {q}: a textured frame"
            );
        }
    }

    #[test]
    fn background_reuse_shows_the_kept_background_only_within_its_threshold() {
        let mut scene = tiny();
        for (p, v) in scene.views.iter_mut().enumerate() {
            v.background = RgbImage::from_fn(23, 17, |x, y| {
                image::Rgb([(x * 11 + y * 3) as u8, (y * 13 + p as u32 * 40) as u8, 90])
            });
        }
        let scene = std::sync::Arc::new(scene);
        let params = RenderParams {
            background_reuse_px: 0.05,
            ..RenderParams::default()
        };
        let fresh = |q: f64| {
            let mut r = Renderer::new(scene.clone(), RenderParams::default()).unwrap();
            let c = Player::new().advance(&scene, q).unwrap();
            let mut out = RgbImage::new(23, 17);
            r.render_into(&NoObjects, q, &c, &mut out).unwrap();
            out
        };
        let mut r = Renderer::new(scene.clone(), params).unwrap();
        let mut p = Player::new();
        let mut out = RgbImage::new(23, 17);
        let mut show = |q: f64| {
            let c = p.advance(&scene, q).unwrap();
            r.render_into(&NoObjects, q, &c, &mut out).unwrap();
            (out.clone(), r.background_blends())
        };
        // The views' points are 1 px apart, so q moves the background 1 px per view.
        assert_eq!(show(0.3), (fresh(0.3), 1));
        // 0.0001 px: the kept background, not the exact one.
        let (frame, blends) = show(0.3001);
        assert_eq!((frame == fresh(0.3), blends), (true, 1));
        assert!(fresh(0.3001) != fresh(0.3), "the exact frames differ");
        // 0.1 px, over the threshold: blended again, exactly.
        assert_eq!(show(0.4), (fresh(0.4), 2));
        // Another pair of views: blended whatever the distance.
        assert_eq!(show(1.0), (fresh(1.0), 3));
        for bad in [-0.1, f64::NAN, MAX_BACKGROUND_REUSE_PX + 0.1] {
            let params = RenderParams {
                background_reuse_px: bad,
                ..RenderParams::default()
            };
            let e = Renderer::new(scene.clone(), params).err().expect("refused");
            assert!(e.to_string().contains("background_reuse_px"), "{e}");
        }
    }

    /// A 3-view scene with tiny hand-made tables, for eq. (6) step by step.
    fn tiny() -> RenderScene {
        let pts = |dx: f64| {
            vec![
                Point::new(dx, 0.0),
                Point::new(10.0 + dx, 0.0),
                Point::new(10.0 + dx, 10.0),
                Point::new(dx, 10.0),
            ]
        };
        let view = |m, n, next: Vec<Option<usize>>, prev: Vec<Option<usize>>, dx| RenderView {
            background: RgbImage::new(4, 4),
            loop_start: m,
            loop_end: n,
            to_next: next,
            to_prev: prev,
            points: pts(dx),
            dynamic: None,
            to_next_seam: Vec::new(),
            to_prev_seam: Vec::new(),
        };
        let none = vec![None; 8];
        RenderScene {
            parallax: Vec::new(),
            views: vec![
                view(
                    1,
                    5,
                    vec![
                        Some(0),
                        Some(1),
                        Some(2),
                        Some(3),
                        Some(4),
                        Some(5),
                        Some(5),
                        Some(5),
                    ],
                    none.clone(),
                    0.0,
                ),
                view(
                    2,
                    6,
                    vec![
                        Some(6),
                        Some(5),
                        Some(4),
                        Some(3),
                        Some(2),
                        Some(1),
                        Some(0),
                        Some(0),
                    ],
                    vec![Some(3); 8],
                    1.0,
                ),
                view(
                    0,
                    4,
                    none.clone(),
                    vec![
                        Some(2),
                        Some(2),
                        Some(2),
                        Some(2),
                        Some(2),
                        Some(2),
                        Some(2),
                        Some(2),
                    ],
                    2.0,
                ),
            ],
            model: MotionModel::Translation,
        }
    }

    #[test]
    fn eq6_step_by_step() {
        let s = tiny();
        let mut p = Player::new();
        let mut run = |q: f64| {
            let c = p.advance(&s, q).unwrap();
            (c.view, c.frame, c.step)
        };
        // Start in view 0 at m + 1 = 2, play to n = 5, wrap to 2.
        assert_eq!(run(0.0), (0, 2, Step::Start));
        assert_eq!(run(0.2), (0, 3, Step::Play));
        assert_eq!(run(0.49), (0, 4, Step::Play));
        assert_eq!(run(0.1), (0, 5, Step::Play));
        assert_eq!(run(0.0), (0, 2, Step::Wrap));
        // q - f = 0.5 exactly: qbar = c = 1. Switch: t_1(2, 0) = next[2] = 2, show 3.
        assert_eq!(run(0.5), (1, 3, Step::Switch { hops: 1 }));
        assert_eq!(run(1.0), (1, 4, Step::Play));
        // Jump from view 1 to view 2 ... and straight back to view 0 across two hops:
        // view 1 frame 4 -> next[4] = 2 in view 2, +1 = 3.
        assert_eq!(run(2.0), (2, 3, Step::Switch { hops: 1 }));
        // view 2 frame 3 -> prev[3] = 2 in view 1 -> prev[2] = 3 in view 0, +1 = 4.
        assert_eq!(run(0.0), (0, 4, Step::Switch { hops: 2 }));
        assert_eq!((p.wraps, p.switches), (1, 4));
    }

    #[test]
    fn split_q_tie_and_integers() {
        let s = |floor, ceil, nearest| QSplit {
            floor,
            ceil,
            nearest,
        };
        assert_eq!(split_q(1.0), s(1, 1, 1));
        assert_eq!(split_q(1.5), s(1, 2, 2));
        assert_eq!(split_q(1.4999999), s(1, 2, 1));
        assert_eq!(split_q(0.0), s(0, 0, 0));
    }

    #[test]
    fn out_of_range_q_is_an_error() {
        let s = tiny();
        let mut p = Player::new();
        for q in [-0.1, 2.0001, f64::NAN, f64::INFINITY] {
            let e = p.advance(&s, q).unwrap_err().to_string();
            assert!(e.contains("[0, 2]"), "{e}");
        }
    }

    /// The renderer's morph (fixed-point runs, f32 weights, gain) and the reference
    /// `parallax::morph` make the same picture: a textured pair whose right half is a nearer
    /// plane (6 px of parallax), estimated, then blended at three fractions under plane
    /// homographies that move the output.
    #[test]
    fn renderer_morph_matches_the_reference_morph() {
        let (a, b) = crate::parallax::test_pair();
        let (w, h) = a.dimensions();
        let hab = Homography::translation(-2.0, 0.0);
        let geo = crate::parallax::Geometry::straight([1.0, 0.0], -4, 12);
        let par = crate::parallax::estimate(
            &a,
            &b,
            &hab,
            &geo,
            &crate::parallax::ParallaxParams::default(),
        );
        for f in [0.25, 0.5, 0.75] {
            let h_aq = Homography::translation(-2.0 * f, 0.0);
            let h_bq = Homography::translation(2.0 * (1.0 - f), 0.0);
            let reference = crate::parallax::morph(&a, &b, &par, &h_aq, &h_bq, f, w, h);
            let mut out = RgbImage::new(w, h);
            let (pa, pb) = (Padded::new(&a), Padded::new(&b));
            morph_blend(
                [&pa, &pb],
                &par,
                [&h_aq, &h_bq],
                [[1.0; 3]; 2],
                f,
                &mut out,
                None,
            );
            let diffs: Vec<i32> = out
                .as_raw()
                .iter()
                .zip(reference.as_raw())
                .map(|(&p, &q)| (p as i32 - q as i32).abs())
                .collect();
            let close = diffs.iter().filter(|&&d| d <= 2).count();
            assert!(
                close * 1000 >= 995 * diffs.len(),
                "f = {f}: {close} of {} channel values within 2 levels",
                diffs.len()
            );
        }
    }
}
