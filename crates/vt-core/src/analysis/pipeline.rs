//! The pipeline: every view analysed, then the model, the homographies between neighbours
//! (refined, or registered when no points are marked) and the transition tables.

use super::*;

pub(super) fn size_err(what: String, expected: (u32, u32), got: (u32, u32)) -> Error {
    Error::SizeMismatch {
        what,
        expected_w: expected.0,
        expected_h: expected.1,
        got_w: got.0,
        got_h: got.1,
    }
}

/// Each view's crop of its still camera, when some view is steadied: one size for all (the
/// smallest area any view keeps), centred in each view's own area. None for every view when no
/// view is steadied (frames as they are).
pub(super) fn view_crops(
    shakes: &[crate::stabilize::Shake],
) -> Result<Vec<Option<crate::stabilize::Crop>>> {
    if !shakes.iter().any(crate::stabilize::Shake::steadied) {
        return Ok(vec![None; shakes.len()]);
    }
    if let Some(s) = shakes.iter().find(|s| s.size != shakes[0].size) {
        return Err(size_err(
            format!("view {} (made still)", s.name),
            shakes[0].size,
            s.size,
        ));
    }
    let w = shakes.iter().map(|s| s.area.width).min().unwrap_or(0);
    let h = shakes.iter().map(|s| s.area.height).min().unwrap_or(0);
    Ok(shakes
        .iter()
        .map(|s| {
            let a = s.area;
            Some(crate::stabilize::Crop {
                x: a.x + (a.width - w) / 2,
                y: a.y + (a.height - h) / 2,
                width: w,
                height: h,
            })
        })
        .collect())
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
        let sel = crate::model::select_model_for_points(&pairs, &params.model)?;
        observer.finish();
        timings.homographies += t0.elapsed();
        selection = Some(sel);
    }

    // Each view's first pass also probes its camera: a still camera costs no pass of its own.
    let mut views = Vec::with_capacity(m);
    let mut size: Option<(u32, u32)> = None;
    let mut moved = None;
    for (p, src) in sources.iter_mut().enumerate() {
        let mut probing = crate::stabilize::Probing::new(&mut **src, &params.stabilize);
        let view = analyze_view(p, &mut probing, params, &mut size, observer, &mut timings);
        timings.shake += Duration::from_secs_f64(probing.secs());
        if probing.moved() {
            observer.finish();
            moved = Some(p);
            break;
        }
        let mut v = view?;
        v.shake = probing.shake();
        views.push(v);
    }
    // A handheld view: every view measured in full, one crop for all, analysed again through
    // the still camera.
    let moved_points: Vec<Vec<Point>>;
    let mut points = points;
    if let Some(first_moving) = moved {
        // The views before it were probed still; it moves; the ones after are measured whole.
        let mut shakes: Vec<crate::stabilize::Shake> =
            views.drain(..).map(|v| v.shake.expect("probed")).collect();
        size = None;
        let t_shake = Instant::now();
        for (p, src) in sources.iter_mut().enumerate().skip(first_moving) {
            observer.start(Stage::Shake, Some(p), None);
            let shake = if p == first_moving {
                crate::stabilize::measure_moving(&mut **src, &params.stabilize)
            } else {
                crate::stabilize::measure(&mut **src, &params.stabilize)
            };
            observer.finish();
            shakes.push(shake?);
        }
        let crops = view_crops(&shakes)?;
        timings.shake += t_shake.elapsed();
        let mut steady: Vec<crate::stabilize::Steady> = sources
            .iter_mut()
            .zip(&shakes)
            .zip(&crops)
            .map(|((src, shake), crop)| {
                let maps = crop.map(|c| crate::stabilize::crop_maps(shake, c));
                let size = crop.map_or(shake.size, |c| (c.width, c.height));
                crate::stabilize::Steady::new(&mut **src, maps, size)
            })
            .collect();
        // Marked points (on each view's first frame) follow it to the still camera.
        if crops.iter().any(Option::is_some) && !points.is_empty() {
            moved_points = points
                .iter()
                .zip(shakes.iter().zip(&crops))
                .map(|(pts, (shake, crop))| match crop {
                    Some(c) => {
                        let map = &crate::stabilize::crop_maps(shake, *c)[0];
                        pts.iter()
                            .map(|q| map.apply(*q).unwrap_or(*q))
                            .collect::<Vec<Point>>()
                    }
                    None => pts.clone(),
                })
                .collect();
            if m > 1 && !auto {
                let pairs: Vec<(&[Point], &[Point])> = (0..m - 1)
                    .map(|p| (moved_points[p].as_slice(), moved_points[p + 1].as_slice()))
                    .collect();
                selection = Some(crate::model::select_model_for_points(
                    &pairs,
                    &params.model,
                )?);
            }
            points = moved_points.as_slice();
        }
        for (p, (src, shake)) in steady.iter_mut().zip(shakes).enumerate() {
            let mut v = analyze_view(p, src, params, &mut size, observer, &mut timings)?;
            v.shake = Some(shake);
            views.push(v);
        }
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
            // The plane of the link before, as seen in view p: every link registers one plane.
            let prior: Option<Vec<Point>> = registration
                .last()
                .filter(|r: &&crate::register::PairRegistration| r.epipolar.is_some())
                .map(|r| r.inliers.iter().map(|(_, b)| *b).collect());
            let mut r = crate::register::register_features_on(
                &features[p],
                &features[p + 1],
                (width, height),
                focus[p].as_ref(),
                prior.as_deref(),
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
        if let Some(sel) = selection.as_mut() {
            keep_rig_planes(sel, &registration);
        }
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
        // Marking deviation implied by the fits.
        let k = pair_points.iter().map(|(a, _)| a.len()).sum::<usize>() as f64
            / pair_points.len().max(1) as f64;
        let sigma_hat = crate::model::implied_sigma(&sel.fits, k);
        for p in 0..m - 1 {
            let init = sel.fits[p].homography;
            // Nor is it refined photometrically: a background with parallax is no plane.
            if !params.refine || registration.get(p).is_some_and(|r| r.epipolar.is_some()) {
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
            if let Ok(mut full) = select_model(&pairs, &force) {
                keep_rig_planes(&mut full, &registration);
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

/// A link registered under its epipolar geometry keeps the plane that the rig allows (and the
/// other links share) in `sel`'s fits: a free refit of the model to the inliers would bend it
/// where they are few. Measured on the Middlebury line scenes (3 px plane threshold), mean dB
/// over three q: Dolls 36.51 -> 36.85, Moebius 36.40 -> 36.65, Reindeer 30.42 -> 30.40. When
/// every link keeps one, the model is the homography those planes are (GRIC's choice on the
/// inliers does not apply to them; unless forced), so the renderer's `H_(p,q)` is fitted under
/// it: Dolls, where GRIC chose the affine map, 37.21 -> 37.27 dB.
fn keep_rig_planes(sel: &mut Selection, registration: &[crate::register::PairRegistration]) {
    for (fit, r) in sel.fits.iter_mut().zip(registration) {
        if r.epipolar.is_some() {
            (fit.homography, fit.rms) = (r.homography, r.rms);
        }
    }
    if !sel.forced && !registration.is_empty() && registration.iter().all(|r| r.epipolar.is_some())
    {
        sel.model = MotionModel::Homography;
        for fit in &mut sel.fits {
            fit.model = MotionModel::Homography;
        }
    }
}

/// Eq. (2) from view `a` to view `b` (`h` maps a to b), with the appearance term when both views
/// have thumbnails (the target's kappa puts it in the target's unit).
pub(super) fn transitions(
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
