//! Handheld clips made still: every frame registered to the first, the camera path replaced by
//! its mean (a still camera, not a smoothed path: the loops and view switches need one), the
//! frames warped to it and cropped to the area every frame covers.
//!
//! # Steps ([`measure`])
//! Frames are measured on a luma proxy of at most [`PROXY_SIDE`] pixels on its longer side.
//! 1. **Anchors.** Up to [`ANCHORS`] corners of frame 0 (FAST, spread over a grid). Each is
//!    looked for in a frame as a patch ([`crate::register::refine_point`]: sub-pixel, gain and
//!    offset, within 3 px, correlation at least 0.8), where it was in the frame before. When
//!    fewer than half are found, the frame is registered to frame 0 by features (steered BRIEF,
//!    RANSAC) and the anchors looked for under that map.
//! 2. **What holds still** is chosen jointly over the frames ([`still_anchors`]): per frame, a
//!    registration fits whatever moves most, which in a tree in wind is the tree; over time,
//!    only the background follows one map in every frame.
//! 3. **Probe.** Every [`StabilizeParams::probe_every`]-th frame is tracked first, at a
//!    spacing that doubles from the 8th probe on each time the frame index does ([`probes`]).
//!    When the still anchors' median motion stays within [`StabilizeParams::still_px`] in each,
//!    or [`IN_PLACE`] corners never leave their place, the camera is still and nothing is
//!    warped: a tripod clip costs one decoding pass and a few patch searches.
//! 4. **Every frame** is tracked otherwise, each from the one before, and one model is selected
//!    for the clip by GRIC on the still anchors ([`crate::model::select_model`]: translation,
//!    similarity, affine or homography), with GRIC's noise taken from the residuals.
//! 5. **The still camera** is the mean of the frames' maps to frame 0; each frame's map to it is
//!    `G_k = A^-1 H_k`, so no frame moves farther than the shake requires.
//! 6. **The crop** is the largest rectangle every mapped frame covers (a uniform margin by
//!    bisection, then each side pushed out as far as it stays covered), even-sized.
//!
//! A frame that cannot be registered (a cut, a pan that leaves frame 0's view) is an error
//! naming it, and so is a crop that keeps less than [`StabilizeParams::min_kept`] of the width or
//! height: vt refuses rather than analyse a scene that is not one. A frame 0 with too few
//! corners, or a clip where nothing holds still through every frame, is taken as still, and
//! [`Shake::verdict`] says so.
//!
//! [`Steady`] wraps the frame source and hands out the warped, cropped frames (bicubic, edge
//! replicated: a bilinear warp at a half-pixel shift blurs like a 2-tap box filter), 4:2:0
//! frames warped plane by plane so the analysis keeps their half size.

use image::GrayImage;
use nalgebra::Matrix3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::align::Grey;
use crate::analysis::{FrameRef, FrameSource};
use crate::model::{select_model, ModelParams, MotionModel};
use crate::register::{detect, grey, refine_point, register_features, Feature, RegisterParams};
use crate::{Error, Homography, Point, Result};

/// Whether clips are made still.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StabilizeMode {
    /// Measure the shake; warp when the camera moves (the default).
    #[default]
    Auto,
    /// Take the frames as they are.
    Off,
}

impl std::str::FromStr for StabilizeMode {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(StabilizeMode::Auto),
            "off" => Ok(StabilizeMode::Off),
            _ => Err(Error::InvalidParameter {
                name: "stabilize",
                value: s.into(),
                why: "expected auto or off".into(),
            }),
        }
    }
}

/// Settings of [`measure`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilizeParams {
    /// Auto or off.
    pub mode: StabilizeMode,
    /// A camera whose frame corners move at most this many pixels is still (0.5).
    pub still_px: f64,
    /// Frames probed for motion: every this many (8) for the first 8 probes, then a spacing
    /// that doubles each time the frame index does.
    pub probe_every: usize,
    /// Least fraction of the frame's width and of its height the crop keeps (0.6); a camera
    /// that moves farther (a pan) is refused.
    pub min_kept: f64,
    /// The registration of each frame to frame 0.
    pub register: RegisterParams,
}

impl Default for StabilizeParams {
    fn default() -> Self {
        Self {
            mode: StabilizeMode::Auto,
            still_px: 0.5,
            probe_every: 8,
            min_kept: 0.6,
            register: RegisterParams::default(),
        }
    }
}

impl StabilizeParams {
    /// Checks the ranges (errors name the field as `stabilize.<name>`).
    pub fn check(&self) -> Result<()> {
        let bad = |name, value: String, why: &str| {
            Err(Error::InvalidParameter {
                name,
                value,
                why: why.into(),
            })
        };
        if !(self.still_px.is_finite() && self.still_px >= 0.0 && self.still_px <= 100.0) {
            return bad(
                "stabilize.still_px",
                self.still_px.to_string(),
                "0 to 100 pixels",
            );
        }
        if self.probe_every == 0 {
            return bad("stabilize.probe_every", "0".into(), "at least 1");
        }
        if !(self.min_kept > 0.0 && self.min_kept <= 1.0) {
            return bad("stabilize.min_kept", self.min_kept.to_string(), "in (0, 1]");
        }
        self.register.check()
    }
}

/// What [`measure`] concluded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// No probed frame moved more than the still threshold: frames as they are.
    Still,
    /// The camera moves: frames warped to the mean camera and cropped.
    Steadied,
    /// Not measured (`--stabilize off`).
    Off,
    /// Frame 0 has too few corners to measure the shake by ([`MIN_ANCHORS`]): taken as still.
    Untextured,
    /// No set of frame 0's corners holds still through the frames (a scene that moves
    /// everywhere, or too blurred to follow): taken as still.
    Unanchored,
}

/// A rectangle of pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Crop {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

/// One clip's measured camera motion and the still camera made from it.
#[derive(Debug, Clone)]
pub struct Shake {
    /// The clip's name (its source's).
    pub name: String,
    /// Frames in the clip.
    pub frames: usize,
    /// The frames' size.
    pub size: (u32, u32),
    /// What was found.
    pub verdict: Verdict,
    /// The model selected by GRIC for the maps (None unless steadied).
    pub model: Option<MotionModel>,
    /// Per frame, the map from its pixels to the still camera's (identity unless steadied).
    pub maps: Vec<Homography>,
    /// Largest motion of a frame corner against the still camera, pixels (of the probed
    /// frames against frame 0 when still).
    pub largest_px: f64,
    /// Largest rotation of a frame against the still camera, degrees.
    pub largest_deg: f64,
    /// The area every frame covers, in the still camera's pixels (the whole frame unless
    /// steadied).
    pub area: Crop,
    /// Corners of frame 0 found to hold still with the camera (0 unless steadied), and the
    /// median over frames of their RMS distance from the selected model's map, pixels.
    pub registered: (usize, f64),
}

impl Shake {
    /// The clip as it is: identity maps, the whole frame.
    fn still(
        name: &str,
        frames: usize,
        size: (u32, u32),
        verdict: Verdict,
        largest_px: f64,
    ) -> Shake {
        Shake {
            name: name.to_string(),
            frames,
            size,
            verdict,
            model: None,
            maps: vec![Homography::identity(); frames],
            largest_px,
            largest_deg: 0.0,
            area: Crop {
                x: 0,
                y: 0,
                width: size.0,
                height: size.1,
            },
            registered: (0, 0.0),
        }
    }

    /// Whether the frames are warped.
    pub fn steadied(&self) -> bool {
        self.verdict == Verdict::Steadied
    }

    /// One line for a summary.
    pub fn describe(&self) -> String {
        match self.verdict {
            Verdict::Off => "camera taken as still (--stabilize off)".into(),
            Verdict::Untextured => {
                "camera taken as still: too little texture in frame 0 to measure it".into()
            }
            Verdict::Unanchored => "camera taken as still: nothing in the frame holds still \
                                     through the clip to measure the camera by"
                .into(),
            Verdict::Still => format!(
                "camera still (frame corners within {:.2} px)",
                self.largest_px
            ),
            Verdict::Steadied => format!(
                "camera shake up to {:.1} px and {:.2} deg, {} map per frame ({} still corners, \
                 median residual {:.2} px): steadied, cropped to {}x{} at ({}, {}) of {}x{}",
                self.largest_px,
                self.largest_deg,
                self.model.map_or("no", MotionModel::name),
                self.registered.0,
                self.registered.1,
                self.area.width,
                self.area.height,
                self.area.x,
                self.area.y,
                self.size.0,
                self.size.1,
            ),
        }
    }
}

/// An error naming the clip.
fn unsteady(name: &str, why: String) -> Error {
    Error::Unsteady {
        view: name.to_string(),
        why,
    }
}

/// Frame 0's registration data: the anchors tracked into every frame, and its features (found
/// only when a frame must be registered by them).
struct Reference {
    grey: GrayImage,
    fine: Grey,
    features: std::sync::OnceLock<Vec<Feature>>,
    anchors: Vec<(i64, i64)>,
}

impl Reference {
    fn new(grey: GrayImage, params: &RegisterParams) -> Reference {
        // The anchors: the strongest corners of a sparse detection, each pixel once.
        let sparse = RegisterParams {
            max_features: ANCHORS,
            ..*params
        };
        let mut anchors: Vec<(i64, i64)> = detect(&grey, &sparse)
            .iter()
            .map(|f| (f.pos.x.round() as i64, f.pos.y.round() as i64))
            .collect();
        anchors.sort_unstable();
        anchors.dedup();
        Reference {
            fine: Grey::from_luma(&grey),
            grey,
            features: std::sync::OnceLock::new(),
            anchors,
        }
    }

    fn features(&self, params: &RegisterParams) -> &[Feature] {
        self.features.get_or_init(|| detect(&self.grey, params))
    }
}

/// Frames are measured on a proxy no larger than this on its longer side (an integer box
/// reduction): corners of blurry HD footage show there, and tracking costs the same at any size.
const PROXY_SIDE: u32 = 640;

/// The box factor that brings `size` within [`PROXY_SIDE`].
fn proxy_factor((w, h): (u32, u32)) -> u32 {
    w.max(h).div_ceil(PROXY_SIDE).max(1)
}

/// Probes at the first spacing ([`probes`]).
const FIRST_PROBES: usize = 8;

/// Whether the probe tracks frame `i`: every `every`-th of the first `FIRST_PROBES` of them,
/// then a spacing that doubles each time the frame index does (for `every` 8: 0, 8, ..., 56,
/// then 64, 80, 96, 112, then 128, 160, 192, 224, then 256, 320, ...). A camera that moves
/// shows in the frames of any stretch of the clip, so a long clip's probes grow with the log
/// of its length (23 for 800 frames, against 100 at one spacing), not with it.
fn probes(i: usize, every: usize) -> bool {
    let span = FIRST_PROBES.saturating_mul(every);
    // The spacing doubles at span, 2 span, 4 span, ...
    let doublings = match i / span {
        0 => 0,
        k => k.ilog2() + 1,
    };
    i.is_multiple_of(every << doublings)
}

/// A frame's luma, reduced by `f` in both directions (box means; the remainder columns and
/// rows dropped). A 4:2:0 frame's own Y plane; RGB frames' [`grey`].
fn proxy(frame: FrameRef<'_>, f: u32) -> GrayImage {
    let rgb_luma;
    let (plane, w, h) = match frame {
        FrameRef::Rgb(rgb) => {
            rgb_luma = grey(rgb);
            (rgb_luma.as_raw().as_slice(), rgb.width(), rgb.height())
        }
        FrameRef::Yuv420(yuv) => {
            let (w, h) = yuv.dimensions();
            (&yuv.as_raw()[..(w * h) as usize], w, h)
        }
    };
    let (sw, f) = (w as usize, f.max(1) as usize);
    let area = (f * f) as u32;
    GrayImage::from_fn((w / f as u32).max(1), (h / f as u32).max(1), |x, y| {
        let (x0, y0) = (x as usize * f, y as usize * f);
        let mut sum = 0u32;
        for row in plane[y0 * sw..].chunks(sw).take(f) {
            sum += row[x0..x0 + f].iter().map(|&v| v as u32).sum::<u32>();
        }
        image::Luma([((sum + area / 2) / area) as u8])
    })
}

/// Anchors (corners of frame 0) tracked into every frame.
const ANCHORS: usize = 600;

/// The probe looks for every this many anchors (half: the still test needs fewer than the
/// maps).
const PROBE_EVERY_ANCHOR: usize = 2;

/// Fewest anchors frame 0 must have for the shake to be measured: fewer (a plain or blurred
/// scene) and the clip is taken as still, and the summary says so.
const MIN_ANCHORS: usize = 150;

/// Where frame 0's anchors lie in one frame (None where not found).
struct Tracked {
    at: Vec<Option<Point>>,
}

impl Tracked {
    /// The homography from frame 0 to this frame fitted to every anchor found (a prior for the
    /// next frame, not the camera: moving anchors are in it).
    fn map(&self, reference: &Reference) -> Option<Homography> {
        let (src, dst): (Vec<Point>, Vec<Point>) = reference
            .anchors
            .iter()
            .zip(&self.at)
            .filter_map(|(&(x, y), q)| Some((Point::new(x as f64, y as f64), (*q)?)))
            .unzip();
        (src.len() >= 8)
            .then(|| Homography::from_correspondences(&src, &dst).ok())
            .flatten()
            .map(|f| f.homography)
    }
}

/// Tracks frame 0's anchors into frame `k` (grey `g`): each anchor's patch is looked for
/// ([`crate::register::refine_point`]: sub-pixel, gain and offset, within 3 px, correlation at
/// least 0.8) where it was in `previous` (a frame just before, tracked), else where the
/// previous frame's map puts it, else where it was in frame 0. When fewer than `enough` of
/// them are found, the frame is registered to frame 0 by features (RANSAC) and the anchors
/// looked for again under that map. A frame that cannot be, with fewer than `min_inliers`
/// anchors found near their place, is an error (a cut, or the camera has left frame 0's view).
fn track_frame(
    name: &str,
    reference: &Reference,
    k: usize,
    g: &GrayImage,
    previous: Option<&Tracked>,
    (every, enough): (usize, Enough),
    params: &RegisterParams,
) -> Result<Tracked> {
    let fine = Grey::from_luma(g);
    let prior = previous.and_then(|p| p.map(reference));
    // The anchors `i` with `pick(i)` looked for (None for the others).
    let track_some = |map: Option<&Homography>,
                      previous: Option<&Tracked>,
                      pick: &(dyn Fn(usize) -> bool + Sync)|
     -> Vec<Option<Point>> {
        reference
            .anchors
            .par_iter()
            .enumerate()
            .map(|(i, &a)| {
                if !pick(i) {
                    return None;
                }
                let base = map.copied().unwrap_or_else(Homography::identity);
                // The anchor's own last place, when it has one: the map shifted to it.
                let h = match (
                    previous.and_then(|p| p.at[i]),
                    base.apply(Point::new(a.0 as f64, a.1 as f64)),
                ) {
                    (Some(q), Some(p)) => Homography::translation(q.x - p.x, q.y - p.y)
                        .after(&base)
                        .unwrap_or(base),
                    _ => base,
                };
                refine_point(&reference.fine, &fine, &h, a)
            })
            .collect()
    };
    let track = |map: Option<&Homography>, previous: Option<&Tracked>| {
        track_some(map, previous, &|i| i.is_multiple_of(every))
    };
    let looked_for = reference.anchors.len().div_ceil(every);
    // Anchors found within AGREE_PX of their frame-0 place.
    let in_place = |at: &[Option<Point>]| {
        reference
            .anchors
            .iter()
            .zip(at)
            .filter(|(&(x, y), q)| {
                q.is_some_and(|q| (q - Point::new(x as f64, y as f64)).norm() <= AGREE_PX)
            })
            .count()
    };
    let is_enough = |at: &[Option<Point>]| match enough {
        Enough::Share => at.iter().flatten().count() as f64 >= FOUND_IN_PLACE * looked_for as f64,
        Enough::Still => in_place(at) >= params.min_inliers,
    };
    let at = track(prior.as_ref(), previous);
    if is_enough(&at) {
        return Ok(Tracked { at });
    }
    if matches!(enough, Enough::Still) && every > 1 {
        // Too few in place among those looked for: the others are looked for too before the
        // registration by features (a few milliseconds against tens). The frame's anchors
        // stay those looked for, as every probe's.
        let rest = track_some(prior.as_ref(), previous, &|i| !i.is_multiple_of(every));
        if in_place(&at) + in_place(&rest) >= params.min_inliers {
            return Ok(Tracked { at });
        }
    }
    let f = detect(g, params);
    let size = reference.grey.dimensions();
    let found = at.iter().flatten().count();
    let params = &RegisterParams {
        epipolar: false,
        ..*params
    };
    match register_features(&f, reference.features(params), size, None, params, (k, 0)) {
        Ok(r) => {
            let again = track(Some(&r.homography.inverse()), None);
            Ok(Tracked {
                at: if again.iter().flatten().count() >= found {
                    again
                } else {
                    at
                },
            })
        }
        // Few features (a plain scene) but enough anchors found near their place: a moving
        // object covers the rest. A cut leaves next to none where they were.
        Err(_) if found >= params.min_inliers => Ok(Tracked { at }),
        Err(e) => {
            let why = match e {
                Error::Registration { why, .. } => why,
                e => e.to_string(),
            };
            Err(unsteady(
                name,
                format!(
                    "frame {k} cannot be registered to frame 0 (a cut, or the camera moves \
                     too far): {why}"
                ),
            ))
        }
    }
}

/// Least share of the anchors found near their prior place for a frame to need no
/// registration by features ([`Enough::Share`]).
const FOUND_IN_PLACE: f64 = 0.5;

/// How many anchors found near their prior place spare a frame its registration by features.
#[derive(Debug, Clone, Copy)]
enum Enough {
    /// [`FOUND_IN_PLACE`] of those looked for: every frame of a moving camera, tracked from
    /// the one before, whose map is made from them.
    Share,
    /// `min_inliers` of them found within [`AGREE_PX`] of their frame-0 place: the probe's
    /// frames, tracked from there (no prior), where only the still-or-moving verdict is made.
    /// Those anchors put the camera where it was in frame 0, which is what registering the
    /// frame by features would find, and the anchors looked for again under it would be found
    /// where they are. A scene that mostly moves (a tree in wind fills 92% of the five-view
    /// scene's frames) leaves too few of all the anchors found for the share, which registered
    /// nearly every probe by features for nothing. A camera that moved leaves the found
    /// anchors off their places (a 4 px shake still finds 20 of them within the 3 px search,
    /// where they are not its map), and its frame is registered. When too few of the anchors
    /// looked for (every [`PROBE_EVERY_ANCHOR`]-th) are in place, the others are looked for as
    /// well before the registration: on the five-view scene most probes then have 20 in place.
    Still,
}

/// Largest distance a corner of a `w x h` frame moves under `h`, pixels.
fn corner_motion(h: &Homography, (w, hh): (u32, u32)) -> f64 {
    let (w, hh) = (w as f64 - 1.0, hh as f64 - 1.0);
    [(0.0, 0.0), (w, 0.0), (0.0, hh), (w, hh)]
        .into_iter()
        .map(|(x, y)| {
            h.apply(Point::new(x, y)).map_or(f64::INFINITY, |q| {
                ((q.x - x).powi(2) + (q.y - y).powi(2)).sqrt()
            })
        })
        .fold(0.0, f64::max)
}

/// The camera's motion as the still anchors show it: per frame, the median distance its
/// agreeing still anchors have moved from their places in frame 0; the largest over frames,
/// pixels. (A median, since anchors on slow parts of a moving scene may pass as still.)
fn anchor_motion(reference: &Reference, tracks: &[Tracked], still: &StillAnchors) -> f64 {
    tracks
        .iter()
        .zip(&still.per_frame)
        .map(|(t, agree)| {
            let mut d: Vec<f64> = agree
                .iter()
                .filter_map(|&a| {
                    let (x, y) = reference.anchors[a];
                    t.at[a].map(|q| (q.x - x as f64).hypot(q.y - y as f64))
                })
                .collect();
            if d.is_empty() {
                return 0.0;
            }
            d.sort_by(f64::total_cmp);
            d[d.len() / 2]
        })
        .fold(0.0, f64::max)
}

/// Rotation of `h`'s linear part, degrees.
fn rotation_deg(h: &Homography) -> f64 {
    let m = h.matrix();
    (m[(1, 0)] - m[(0, 1)])
        .atan2(m[(0, 0)] + m[(1, 1)])
        .to_degrees()
}

/// The anchors that hold still with the camera, and each frame's map to frame 0 from them.
///
/// Per frame, the features' RANSAC fits whatever moves most, and in a clip of a tree in wind
/// that is the tree. What sets the background apart is time: its anchors follow one map per
/// frame in *every* frame, a leaf agrees with the crowd only now and then. So the anchors are
/// chosen jointly over the frames: a hypothesis is two anchors far apart (a similarity per
/// frame from their tracks), an anchor supports it when it lies within [`AGREE_PX`] of that map
/// in at least [`AGREE_SHARE`] of the frames it is found in; the best supported set is then
/// refined by homographies fitted to it per frame, twice, with the bound halved. None when
/// fewer than `min_inliers` anchors hold still (in some frame).
fn still_anchors(
    reference: &Reference,
    tracks: &[Tracked],
    min_inliers: usize,
    seed: u64,
) -> Option<StillAnchors> {
    let anchors: Vec<Point> = reference
        .anchors
        .iter()
        .map(|&(x, y)| Point::new(x as f64, y as f64))
        .collect();
    let frames = tracks.len();
    // Anchors found in most frames.
    let found: Vec<usize> = (0..anchors.len())
        .filter(|&a| {
            let n = tracks.iter().filter(|t| t.at[a].is_some()).count();
            n as f64 >= FOUND_SHARE * frames as f64 && n > 0
        })
        .collect();
    if found.len() < min_inliers {
        return None;
    }
    let supports = |a: usize, at: &dyn Fn(usize, Point) -> Option<Point>, bound: f64| {
        let (mut n, mut good) = (0usize, 0usize);
        for (k, t) in tracks.iter().enumerate() {
            if let (Some(q), Some(p)) = (t.at[a], at(k, anchors[a])) {
                n += 1;
                if (q - p).norm() <= bound {
                    good += 1;
                }
            }
        }
        n > 0 && good as f64 >= AGREE_SHARE * n as f64
    };
    // The still camera is a hypothesis of its own: the anchors that stay in place.
    let in_place = found
        .iter()
        .filter(|&&a| supports(a, &|_, p| Some(p), AGREE_PX))
        .count();
    let (w, h) = reference.grey.dimensions();
    let far = (w.min(h) as f64) / 3.0;
    let mut rng = crate::rng::Rng::new(seed);
    let mut best: Vec<usize> = Vec::new();
    let mut tries = 0;
    while tries < HYPOTHESES {
        let i = found[rng.range(0, found.len() as i64 - 1) as usize];
        let j = found[rng.range(0, found.len() as i64 - 1) as usize];
        if (anchors[i] - anchors[j]).norm() < far {
            tries += 1;
            continue;
        }
        tries += 1;
        // Per frame, the similarity taking anchors i and j (frame 0) to where they are found.
        let maps: Vec<Option<[f64; 4]>> = tracks
            .iter()
            .map(|t| {
                let (qi, qj) = (t.at[i]?, t.at[j]?);
                let (pi, pj) = (anchors[i], anchors[j]);
                let (dx, dy) = (pj.x - pi.x, pj.y - pi.y);
                let (ex, ey) = (qj.x - qi.x, qj.y - qi.y);
                let d2 = dx * dx + dy * dy;
                // s = e / d as complex numbers.
                let (a, b) = ((ex * dx + ey * dy) / d2, (ey * dx - ex * dy) / d2);
                Some([
                    a,
                    b,
                    qi.x - (a * pi.x - b * pi.y),
                    qi.y - (b * pi.x + a * pi.y),
                ])
            })
            .collect();
        let at = |k: usize, p: Point| {
            maps[k].map(|[a, b, tx, ty]| Point::new(a * p.x - b * p.y + tx, b * p.x + a * p.y + ty))
        };
        let set: Vec<usize> = found
            .iter()
            .copied()
            .filter(|&a| supports(a, &at, AGREE_PX))
            .collect();
        if set.len() > best.len() {
            best = set;
        }
    }
    // Refined: a homography per frame from the set, the set chosen again.
    let mut maps: Vec<Option<Homography>> = Vec::new();
    for bound in GROW_PX {
        if best.len() < min_inliers {
            return None;
        }
        maps = tracks
            .iter()
            .map(|t| {
                let (src, dst): (Vec<Point>, Vec<Point>) = best
                    .iter()
                    .filter_map(|&a| Some((anchors[a], t.at[a]?)))
                    .unzip();
                (src.len() >= min_inliers)
                    .then(|| Homography::from_correspondences(&src, &dst).ok())
                    .flatten()
                    .map(|f| f.homography)
            })
            .collect();
        let at = |k: usize, p: Point| maps[k].as_ref().and_then(|m| m.apply(p));
        best = found
            .iter()
            .copied()
            .filter(|&a| supports(a, &at, bound))
            .collect();
    }
    if best.len() < min_inliers {
        return None;
    }
    // Per frame, the set's anchors that agree in that frame (a still anchor may be mistracked
    // in a tenth of the frames).
    let mut per_frame = Vec::with_capacity(frames);
    for (t, m) in tracks.iter().zip(&maps) {
        let m = m.as_ref()?;
        let agree: Vec<usize> = best
            .iter()
            .copied()
            .filter(|&a| match (t.at[a], m.apply(anchors[a])) {
                (Some(q), Some(p)) => (q - p).norm() <= AGREE_PX,
                _ => false,
            })
            .collect();
        if agree.len() < min_inliers {
            return None;
        }
        per_frame.push(agree);
    }
    Some(StillAnchors {
        set: best,
        per_frame,
        in_place,
    })
}

/// What [`still_anchors`] found.
struct StillAnchors {
    /// The anchors that hold still with the camera.
    set: Vec<usize>,
    /// Per frame, those of them that agree with its map there.
    per_frame: Vec<Vec<usize>>,
    /// Anchors that stay where they were in frame 0 (the still camera's support).
    in_place: usize,
}

/// Least share of the frames an anchor must be found in.
const FOUND_SHARE: f64 = 0.8;
/// Least share of the frames it is found in where an anchor must agree with the camera.
const AGREE_SHARE: f64 = 0.9;
/// How near, in pixels, an anchor must lie to the camera's map to agree with it.
const AGREE_PX: f64 = 0.35;
/// The bounds of the refinements by homographies: looser first, so that anchors far from the
/// hypothesis's pair, where a similarity is not the camera's map, join.
const GROW_PX: [f64; 3] = [0.6, 0.6, AGREE_PX];
/// Pairs of anchors tried as the camera.
const HYPOTHESES: usize = 400;

/// Corners that never leave their place in the probes (within [`AGREE_PX`] in 90% of them) for
/// the camera to count as still: a moving camera leaves none (the shaken tree.avi: 0), a tripod
/// clip of a tree swaying in wind keeps its few truly still ones (tree.avi: 68 at 296x216, 13
/// at 768x576, where 52 swaying corners form the largest set).
const IN_PLACE: usize = 4;

/// The first pass of [`measure`]: frame 0's anchors and every
/// [`StabilizeParams::probe_every`]-th frame tracked, fed one frame at a time (so the
/// analysis's own first pass can carry it, [`Probing`]).
pub struct Probe {
    params: StabilizeParams,
    reference: Option<Reference>,
    tracks: Vec<Tracked>,
    untextured: bool,
    full: (u32, u32),
    factor: u32,
    /// Seconds spent measuring.
    pub secs: f64,
}

/// What the probe found.
enum Probed {
    /// The clip as it is.
    Still(Shake),
    /// The camera moves: measure every frame.
    Moves {
        reference: Reference,
        motion: f64,
        factor: u32,
    },
}

impl Probe {
    /// A probe with `params` (its mode must be auto).
    pub fn new(params: &StabilizeParams) -> Probe {
        Probe {
            params: *params,
            reference: None,
            tracks: Vec::new(),
            untextured: false,
            full: (0, 0),
            factor: 1,
            secs: 0.0,
        }
    }

    /// Takes frame `i` of the clip `name` (frames in order from 0).
    pub fn frame(&mut self, name: &str, i: usize, frame: FrameRef<'_>) -> Result<()> {
        if !self.wants(i) || self.untextured {
            return Ok(());
        }
        let full = frame.dimensions();
        let factor = proxy_factor(full);
        self.take(name, i, proxy(frame, factor), full)
    }

    /// Whether frame `i` is one the probe tracks.
    fn wants(&self, i: usize) -> bool {
        probes(i, self.params.probe_every)
    }

    /// Tracks frame `i` (one it [`Probe::wants`]) from its luma proxy `g`, the frame
    /// `full` pixels large (reduced by [`proxy_factor`]).
    fn take(&mut self, name: &str, i: usize, g: GrayImage, full: (u32, u32)) -> Result<()> {
        if self.untextured {
            return Ok(());
        }
        let t = std::time::Instant::now();
        let reg = &self.params.register;
        if i == 0 {
            self.full = full;
            self.factor = proxy_factor(full);
        }
        match &self.reference {
            None => {
                let r = Reference::new(g, reg);
                self.untextured = r.anchors.len() < MIN_ANCHORS;
                self.reference = Some(r);
            }
            Some(r) => self.tracks.push(track_frame(
                name,
                r,
                i,
                &g,
                None,
                (PROBE_EVERY_ANCHOR, Enough::Still),
                reg,
            )?),
        }
        self.secs += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The verdict on the `n` frames seen.
    fn finish(&mut self, name: &str, n: usize) -> Probed {
        let reg = &self.params.register;
        let size = self.full;
        let Some(reference) = self.reference.take() else {
            return Probed::Still(Shake::still(name, 0, (0, 0), Verdict::Still, 0.0));
        };
        if self.untextured || n == 1 {
            return Probed::Still(Shake::still(name, n, size, Verdict::Untextured, 0.0));
        }
        let probes = std::mem::take(&mut self.tracks);
        let Some(probed) = still_anchors(&reference, &probes, reg.min_inliers, reg.seed) else {
            return Probed::Still(Shake::still(name, n, size, Verdict::Unanchored, 0.0));
        };
        // How far the still corners themselves move (the frame's corners would extrapolate
        // the map, and a background seen in one strip of the frame pins it down only there).
        let motion = self.factor as f64 * anchor_motion(&reference, &probes, &probed);
        // A still camera wins when some corners never leave their place: in a tripod clip of
        // a tree in wind, a cluster of branches that sway together can outnumber the few
        // corners of what truly stands still, but a moving camera leaves no corner in place.
        let in_place = probed.in_place >= IN_PLACE;
        if motion <= self.params.still_px || in_place {
            return Probed::Still(Shake::still(name, n, size, Verdict::Still, motion));
        }
        Probed::Moves {
            reference,
            motion,
            factor: self.factor,
        }
    }
}

/// Measures the camera motion of `source` and the still camera that removes it.
pub fn measure(source: &mut dyn FrameSource, params: &StabilizeParams) -> Result<Shake> {
    params.check()?;
    let name = source.name().to_string();
    if params.mode == StabilizeMode::Off {
        // Nothing read: the frames are the source's.
        return Ok(Shake::still(&name, 0, (0, 0), Verdict::Off, 0.0));
    }
    let mut probe = Probe::new(params);
    let n = source.for_each_native(&mut |i, frame| probe.frame(&name, i, frame))?;
    match probe.finish(&name, n) {
        Probed::Still(shake) => Ok(shake),
        Probed::Moves {
            reference,
            motion,
            factor,
        } => steady(
            source,
            params,
            Some((reference, factor, probe.full, n)),
            motion,
        ),
    }
}

/// [`measure`] for a clip already probed as moving (the analysis's first pass, [`Probing`]):
/// one pass tracks every frame, with no probe of its own.
pub fn measure_moving(source: &mut dyn FrameSource, params: &StabilizeParams) -> Result<Shake> {
    params.check()?;
    steady(source, params, None, 0.0)
}

/// The camera moves: every frame tracked, each from the one before, and the still camera made.
/// `probed` is the probe's reference, proxy factor, frame size and count (None: frame 0 of this
/// pass is the reference); `probed_motion` what it measured.
fn steady(
    source: &mut dyn FrameSource,
    params: &StabilizeParams,
    probed: Option<(Reference, u32, (u32, u32), usize)>,
    probed_motion: f64,
) -> Result<Shake> {
    let name = source.name().to_string();
    let reg = &params.register;
    let known = probed.as_ref().map(|p| p.3);
    let (mut reference, mut f, mut size) = match probed {
        Some((r, f, size, _)) => (Some(r), f, size),
        None => (None, 1, (0, 0)),
    };
    let mut tracks: Vec<Tracked> = Vec::new();
    let n = source.for_each_native(&mut |i, frame| {
        let Some(r) = &reference else {
            size = frame.dimensions();
            f = proxy_factor(size);
            reference = Some(Reference::new(proxy(frame, f), reg));
            return Ok(());
        };
        if i == 0 {
            return Ok(());
        }
        let t = track_frame(
            &name,
            r,
            i,
            &proxy(frame, f),
            tracks.last(),
            (1, Enough::Share),
            reg,
        )?;
        tracks.push(t);
        Ok(())
    })?;
    if let Some(k) = known.filter(|&k| k != n) {
        return Err(unsteady(
            &name,
            format!("the source gave {n} frames on its second reading, {k} on its first"),
        ));
    }
    let Some(reference) = reference else {
        return Ok(Shake::still(&name, 0, (0, 0), Verdict::Still, 0.0));
    };
    if reference.anchors.len() < MIN_ANCHORS || n < 2 {
        return Ok(Shake::still(&name, n, size, Verdict::Untextured, 0.0));
    }
    let scale = f as f64;
    debug_assert_eq!(tracks.len(), n - 1);
    let Some(still) = still_anchors(&reference, &tracks, reg.min_inliers, reg.seed) else {
        return Ok(Shake::still(
            &name,
            n,
            size,
            Verdict::Unanchored,
            probed_motion,
        ));
    };

    // One model for the clip, by GRIC on the still anchors' tracks, its noise from their
    // residuals under homographies.
    let pairs: Vec<(Vec<Point>, Vec<Point>)> = tracks
        .iter()
        .zip(&still.per_frame)
        .map(|(t, agree)| {
            agree
                .iter()
                .filter_map(|&a| {
                    let (x, y) = reference.anchors[a];
                    Some((t.at[a]?, Point::new(x as f64, y as f64)))
                })
                .unzip()
        })
        .collect();
    let general: Vec<crate::model::ModelFit> = pairs
        .iter()
        .map(|(a, b)| crate::model::fit_model(MotionModel::Homography, a, b, 1.0))
        .collect::<Result<_>>()
        .map_err(|e| unsteady(&name, format!("no map fits a frame's still corners: {e}")))?;
    let k = pairs.iter().map(|(a, _)| a.len()).sum::<usize>() as f64 / pairs.len() as f64;
    // Frame 0's anchors are exact pixels: a residual carries one tracked point's noise, not
    // two marked points' (implied_sigma halves for those).
    let sigma = (2.0 * crate::model::implied_sigma(&general, k)).max(0.02);
    let refs: Vec<(&[Point], &[Point])> = pairs
        .iter()
        .map(|(a, b)| (a.as_slice(), b.as_slice()))
        .collect();
    let selection = select_model(&refs, &ModelParams { sigma, force: None })
        .map_err(|e| unsteady(&name, format!("no map fits the frames' still corners: {e}")))?;
    let mut rms: Vec<f64> = selection.fits.iter().map(|f| f.rms).collect();
    rms.sort_by(f64::total_cmp);
    let median_rms = rms[rms.len() / 2];

    // The still camera: the mean of the maps to frame 0, at full size (proxy pixel p is the
    // mean of full pixels around f p + (f - 1) / 2).
    let up = Matrix3::new(
        scale,
        0.0,
        (scale - 1.0) / 2.0,
        0.0,
        scale,
        (scale - 1.0) / 2.0,
        0.0,
        0.0,
        1.0,
    );
    let down = up.try_inverse().expect("a scaling");
    let to_first: Vec<Matrix3<f64>> = std::iter::once(Matrix3::identity())
        .chain(selection.fits.iter().map(|fit| {
            let m = up * fit.homography.matrix() * down;
            m / m[(2, 2)]
        }))
        .collect();
    let mean = to_first.iter().sum::<Matrix3<f64>>() / n as f64;
    let mean = Homography::from_matrix(mean).map_err(|e| {
        unsteady(
            &name,
            format!("the frames' mean camera is degenerate ({e})"),
        )
    })?;
    let inv_mean = mean.inverse();
    let maps: Vec<Homography> = to_first
        .iter()
        .map(|m| Homography::from_matrix(inv_mean.matrix() * m))
        .collect::<Result<_>>()
        .map_err(|e| unsteady(&name, format!("a frame's map is degenerate ({e})")))?;
    let largest_px = maps
        .iter()
        .map(|h| corner_motion(h, size))
        .fold(0.0, f64::max);
    let largest_deg = maps
        .iter()
        .map(|h| rotation_deg(h).abs())
        .fold(0.0, f64::max);
    let area = covered(&maps, size).filter(|c| {
        c.width as f64 >= params.min_kept * size.0 as f64
            && c.height as f64 >= params.min_kept * size.1 as f64
    });
    let Some(area) = area else {
        return Err(unsteady(
            &name,
            format!(
                "the camera moves too far to hold still (frame corners up to {largest_px:.0} px \
                 from the mean camera): the area every frame covers keeps less than {:.0}% of \
                 the {}x{} frame",
                params.min_kept * 100.0,
                size.0,
                size.1
            ),
        ));
    };
    Ok(Shake {
        name,
        frames: n,
        size,
        verdict: Verdict::Steadied,
        model: Some(selection.model),
        maps,
        largest_px,
        largest_deg,
        area,
        registered: (still.set.len(), scale * median_rms),
    })
}

mod crop;
mod resample;
mod sources;
#[cfg(test)]
mod tests;

use crop::covered;
pub use crop::crop_maps;
pub use resample::{warp_rgb_cubic, warp_yuv420};
pub use sources::{Probing, Steady};
