//! The moving object's own plane per link, from its footprint and silhouettes, when the
//! views are registered automatically.

use super::*;

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
pub(super) fn align_models(
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
pub(super) fn simplest_within(
    errors: &[Vec<(Homography, MotionModel, f64)>],
) -> Option<MotionModel> {
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
pub(super) fn choose_object_planes(
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
pub(super) const OBJECT_ALIGN: crate::align::AlignParams = crate::align::AlignParams {
    levels: 4,
    iterations: 15,
    max_pixels: 12_000,
};

/// Silhouette pairs per link for the object's plane.
pub(super) const SILHOUETTE_PAIRS: usize = 32;
/// Rounds of phase matching and silhouette alignment.
pub(super) const SILHOUETTE_ROUNDS: usize = 2;

/// The moving object's silhouettes at matching phases of two views, blurred (for
/// [`crate::align::align_stack`]), and the region of view a they cover.
pub(super) struct SilhouetteStack {
    pairs: Vec<(RgbImage, RgbImage)>,
    region: Mask,
}

/// The frame pairs of [`matching_frames`], blurred, and the region they cover.
pub(super) fn silhouette_stack(
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
pub(super) fn matching_frames(
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
pub(super) fn carried_points(
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
