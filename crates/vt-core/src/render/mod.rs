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
//!   overlap of the warped backgrounds (median ratio per channel). Each view's samples are brought
//!   to the exposure at q, its pair's gains interpolated in log ([`Renderer::exposure_at`]): an
//!   input viewpoint shows its photo as taken, a view between two takes lies between their
//!   exposures, and no seam shows where the two views' samples meet.
//! - Crossfade: for `crossfade` frames after a loop wrap or view switch, the object is blended from
//!   the continuation of the old sequence into the new one (Schödl et al. 2000).
//! - Dissolve: the first `dissolve` frames after a loop wrap or view switch are in-between frames,
//!   blended from the last frame shown before the jump into the new sequence's frame `dissolve`,
//!   so a jump of D is spread over `dissolve + 1` steps of `D / (dissolve + 1)`. On footage that
//!   never repeats (tree.avi: the best 30-frame wrap is 1.86 ordinary steps of the render), no
//!   crossfade of continuing sequences brings a wrap under 1.19 steps (1-6 frames); one
//!   in-between frame brings it to 0.95, two to 0.69. Loop length and timing are unchanged.
//! - Switch fade (on by default, [`DEFAULT_SWITCH_FADE`] frames): after a view switch, the object
//!   fades from what the old view would have shown (its own loop continued) into the new view.
//!   Eq. (2) puts both at the same moment of the motion, so only what the views disagree on
//!   (resampling, registration, exposure) changes, over the fade instead of at once. Measured in
//!   the report ("Switch fade between views").
//! - All three blend two whole layers, each composited over the background:
//!   `(1 - alpha) old + alpha new`.
//!
//! Per output frame the renderer allocates nothing once warm: warps write into owned buffers, and
//! the homographies and the warped, blended background are recomputed only when q changes.

use image::RgbImage;

mod gain;
mod kernels;
mod player;
mod scene;
#[cfg(test)]
mod tests;

pub use gain::estimate_gains;
pub use player::*;
pub use scene::*;

use kernels::{blend_warps, composite, morph_blend, Source};

use rayon::prelude::*;

use crate::round_u8;
use crate::warp::{Interpolation, Padded};
use crate::{Error, Homography, Point, Result};

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
    /// Frames of object crossfade after a view switch only, from what the old view would have
    /// shown next (its own loop continued) into the new view ([`DEFAULT_SWITCH_FADE`]; 0 = a
    /// hard switch, the thesis). The transition table (eq. 2) puts both views at the same moment
    /// of the motion, so the two layers agree but for what the views themselves disagree on,
    /// which fades in instead of popping. `crossfade` or `dissolve`, when set, take switches too.
    pub switch_fade: usize,
    /// Where the shown view does not see a pixel at fractional q (near its image edges), show the
    /// other view of the pair's matching frame (its transition-table frame) instead of the
    /// static background. Scenes with dynamic regions only (objects would double).
    pub neighbour_fill: bool,
    /// Bring each view's samples to the exposure at q ([`Renderer::exposure_at`]) through
    /// per-view gains estimated from the backgrounds (off = the thesis; on by default: on the
    /// 5-view scene made from tree.avi, +-6% gains, it lifts the worst PSNR at fractional q from
    /// 30.4 to 35.4 dB; on Middlebury's line scenes, the exposure at q rather than the views'
    /// common one adds 0.0-0.5 dB to the held-out views, `tests/depth.rs`).
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

/// [`RenderParams::switch_fade`]'s default, frames.
pub const DEFAULT_SWITCH_FADE: usize = 4;

impl RenderParams {
    /// How many frames after a view switch blend the old view's continuation in: `crossfade`,
    /// else `dissolve`, else `switch_fade` (0: a hard switch).
    pub fn switch_blend_frames(&self) -> usize {
        if self.crossfade > 0 {
            self.crossfade
        } else if self.dissolve > 0 {
            self.dissolve
        } else {
            self.switch_fade
        }
    }
}

/// Largest [`RenderParams::background_reuse_px`]: beyond a few pixels the reused background
/// visibly lags the objects.
pub const MAX_BACKGROUND_REUSE_PX: f64 = 4.0;

impl RenderParams {
    /// Checks the values: crossfade, dissolve and switch fade at most [`MAX_CROSSFADE`] frames,
    /// crossfade and dissolve not both,
    /// background reuse within `0..=`[`MAX_BACKGROUND_REUSE_PX`]. [`Renderer::new`] calls it;
    /// callers that do work before making a renderer call it first.
    pub fn check(&self) -> Result<()> {
        for (name, n) in [
            ("crossfade", self.crossfade),
            ("dissolve", self.dissolve),
            ("switch_fade", self.switch_fade),
        ] {
            if n > MAX_CROSSFADE {
                return Err(Error::InvalidParameter {
                    name,
                    value: n.to_string(),
                    why: format!("at most {MAX_CROSSFADE} frames"),
                });
            }
        }
        let reuse = self.background_reuse_px;
        if !(reuse.is_finite() && (0.0..=MAX_BACKGROUND_REUSE_PX).contains(&reuse)) {
            return Err(Error::InvalidParameter {
                name: "background_reuse_px",
                value: reuse.to_string(),
                why: format!("a displacement from 0 (off) to {MAX_BACKGROUND_REUSE_PX} pixels"),
            });
        }
        if self.crossfade > 0 && self.dissolve > 0 {
            return Err(Error::InvalidParameter {
                name: "dissolve",
                value: self.dissolve.to_string(),
                why: format!(
                    "a wrap is either crossfaded or dissolved, not both (crossfade {})",
                    self.crossfade
                ),
            });
        }
        Ok(())
    }
}

impl Default for RenderParams {
    fn default() -> Self {
        Self {
            interpolation: Interpolation::Bilinear,
            crossfade: 0,
            dissolve: 0,
            switch_fade: DEFAULT_SWITCH_FADE,
            neighbour_fill: true,
            gain_compensation: true,
            background_reuse_px: 0.0,
        }
    }
}
/// Renders output frames; owns every buffer it needs. A clone renders alike from its own
/// buffers (the gains are estimated once).
#[derive(Clone)]
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
    /// Objects and layer blends are written on rows that are multiples of this (1: all).
    rows: usize,
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

/// An object blend in progress: a switch fade, a crossfade or a dissolve, `k` frames in.
#[derive(Debug, Clone, Copy)]
enum Blend {
    /// The old sequence's continuation `old` fading out under the new sequence over `len`
    /// frames; `looped`: `old` advances as its view's loop plays (a switch fade), else frame by
    /// frame past the loop (a crossfade, whose wrap continuation runs past `n`).
    Fade {
        old: (usize, usize),
        k: usize,
        len: usize,
        looped: bool,
    },
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
        params.check()?;
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
            layer: if params.crossfade > 0 || params.dissolve > 0 || params.switch_fade > 0 {
                RgbImage::new(width, height)
            } else {
                RgbImage::new(0, 0)
            },
            vpoints: Vec::with_capacity(k_points),
            patch: ObjectPatch::default(),
            patch_old: ObjectPatch::default(),
            patch_fill: ObjectPatch::default(),
            blend: None,
            rows: 1,
        })
    }

    /// The blend state after `choice`: a wrap or switch starts a crossfade or dissolve (when
    /// enabled), a played frame advances it, anything else ends it.
    fn next_blend(&self, choice: &FrameChoice) -> Option<Blend> {
        let (cf, d, sf) = (
            self.params.crossfade,
            self.params.dissolve,
            self.params.switch_fade,
        );
        let scene = &self.scene;
        match (choice.step, choice.continuation, self.blend) {
            (Step::Wrap | Step::Switch { .. }, Some((v, j)), _) if cf > 0 => Some(Blend::Fade {
                old: (v, j),
                k: 0,
                len: cf,
                looped: false,
            }),
            (Step::Wrap | Step::Switch { .. }, Some((v, j)), _) if d > 0 && j > 0 => {
                Some(Blend::Dissolve {
                    from: (v, j - 1),
                    to: (choice.view, choice.frame + d),
                    k: 0,
                })
            }
            (Step::Switch { .. }, Some((v, j)), _) if sf > 0 && d == 0 && j > 0 => {
                Some(Blend::Fade {
                    old: (v, scene.next_in_loop(v, j - 1)),
                    k: 0,
                    len: sf,
                    looped: true,
                })
            }
            (
                Step::Play,
                _,
                Some(Blend::Fade {
                    old,
                    k,
                    len,
                    looped,
                }),
            ) if k + 1 < len => Some(Blend::Fade {
                old: (
                    old.0,
                    if looped {
                        scene.next_in_loop(old.0, old.1)
                    } else {
                        old.1 + 1
                    },
                ),
                k: k + 1,
                len,
                looped,
            }),
            (Step::Play, _, Some(Blend::Dissolve { from, to, k }))
                if k + 1 < d && choice.view == to.0 =>
            {
                Some(Blend::Dissolve { from, to, k: k + 1 })
            }
            _ => None,
        }
    }

    /// The frame the old view shows under a switch fade in progress (its loop continued from
    /// where the switch left it), None when no switch fade is: what the switch replaced, for
    /// measuring it ([`crate::seam::SeamMeter`]).
    pub fn switch_fade_from(&self) -> Option<(usize, usize)> {
        match self.blend {
            Some(Blend::Fade {
                old, looped: true, ..
            }) => Some(old),
            _ => None,
        }
    }

    /// Renders `(view, frame)` at `q` as a plain played frame, leaving any blend in progress
    /// as it was (the next [`Renderer::render_into`] goes on with it).
    pub fn render_plain_into(
        &mut self,
        objects: &dyn ObjectFrames,
        q: f64,
        view: usize,
        frame: usize,
        out: &mut RgbImage,
    ) -> Result<()> {
        let blend = self.blend.take();
        let choice = FrameChoice {
            view,
            frame,
            step: Step::Start,
            continuation: None,
        };
        let r = self.render_into(objects, q, &choice, out);
        self.blend = blend;
        r
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

    /// Renders only every `every`-th row (rows `0, every, 2 every, ...`; 1, the default, renders
    /// all): the other rows of a frame hold the background, or whatever the buffer held where a
    /// layer blend would have written. For measuring frames by a sample of their rows
    /// ([`crate::seam`]), at a fraction of the cost; never for frames that are shown.
    pub fn sample_rows(&mut self, every: usize) {
        self.rows = every.max(1);
    }

    /// The row stride [`Renderer::sample_rows`] set (1: every row).
    pub fn sampled_rows(&self) -> usize {
        self.rows
    }

    /// The scene.
    pub fn scene(&self) -> &RenderScene {
        &self.scene
    }

    /// The per-view gains in use (all 1 without compensation).
    pub fn gains(&self) -> &[[f32; 3]] {
        &self.gains
    }

    /// The exposure shown at q, per channel: the gains of q's pair interpolated in log, so q = p
    /// shows view p as taken and a view between two takes lies between their exposures. The
    /// real line scenes' held-out views lie there: rendering Middlebury's odd views at the even
    /// views' common exposure instead cost Moebius 0.5 dB with marked points (`tests/depth.rs`).
    pub fn exposure_at(&self, q: f64) -> [f32; 3] {
        let QSplit {
            floor: f, ceil: c, ..
        } = split_q(q);
        if f == c {
            return self.gains[f];
        }
        let t = q - f as f64;
        std::array::from_fn(|k| {
            let (a, b) = (f64::from(self.gains[f][k]), f64::from(self.gains[c][k]));
            ((1.0 - t) * a.ln() + t * b.ln()).exp() as f32
        })
    }

    /// View `p`'s gain against the exposure at q: what its samples are divided by.
    fn gain_at(&self, p: usize, q: f64) -> [f32; 3] {
        let e = self.exposure_at(q);
        std::array::from_fn(|k| self.gains[p][k] / e[k])
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
                gain_inv: self.gain_at(f, q).map(|g| 1.0 / g),
                weight: wf,
            },
            Source {
                image: &self.padded[c],
                h: &hc,
                gain_inv: self.gain_at(c, q).map(|g| 1.0 / g),
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
        // What the object shows: the chosen frame, or a blend of two (a fade or a dissolve).
        self.blend = self.next_blend(choice);
        self.prepare_q(q, out, self.blend.is_some())?;
        let view = choice.view;
        // The player's view is one of q's pair (prepared); a plain render of the old view a
        // switch left (for measuring it) may lie beyond, as q moved on.
        let h = match self.h_to_q[view] {
            Some(h) => h,
            None => self.scene.homography_to_with(view, q, &mut self.vpoints)?,
        };
        let views = &self.scene.views;
        let (shown, old, alpha) = match self.blend {
            Some(Blend::Fade { old, k, len, .. }) if old.1 < views[old.0].to_next.len() => (
                (view, choice.frame),
                Some(old),
                (k + 1) as f32 / (len + 1) as f32,
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
        let (gain_fill, gain_shown) = (
            fill.map(|(fv, _)| self.gain_at(fv, q)),
            self.gain_at(view, q),
        );
        let composite_shown =
            |patch: &ObjectPatch, fill_patch: &ObjectPatch, out: &mut RgbImage| {
                if let (Some((fv, _)), Some(gain)) = (fill, gain_fill) {
                    composite(
                        fill_patch,
                        &self.h_to_q[fv].expect("q's pair is prepared"),
                        self.params.interpolation,
                        gain,
                        fill_alpha,
                        self.scene.views[fv].dynamic.as_deref(),
                        self.rows,
                        out,
                    );
                }
                composite(
                    patch,
                    &h,
                    self.params.interpolation,
                    gain_shown,
                    1.0,
                    self.scene.views[view].dynamic.as_deref(),
                    self.rows,
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
            self.gain_at(ov, q),
            1.0,
            self.scene.views[ov].dynamic.as_deref(),
            self.rows,
            out,
        );
        let (a, b) = (1.0 - alpha, alpha);
        let mix = |o: &mut [u8], l: &[u8]| {
            for (o, &l) in o.iter_mut().zip(l) {
                *o = round_u8(a * *o as f32 + b * l as f32);
            }
        };
        if self.rows > 1 {
            let row = 3 * self.width as usize;
            let every = self.rows;
            out.as_mut()
                .par_chunks_mut(row)
                .zip(self.layer.as_raw().par_chunks(row))
                .enumerate()
                .filter(|(y, _)| y.is_multiple_of(every))
                .for_each(|(_, (o, l))| mix(o, l));
        } else {
            out.as_mut()
                .par_chunks_mut(1 << 16)
                .zip(self.layer.as_raw().par_chunks(1 << 16))
                .for_each(|(o, l)| mix(o, l));
        }
        Ok(())
    }
}
