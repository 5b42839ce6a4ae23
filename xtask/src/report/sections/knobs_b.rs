//! System B's knobs on vt-fv's synthetic object (8 ring photos, truth ray cast at 5 and 10
//! degrees from camera 0): grid size and photo-consistency threshold scored by the rough render,
//! the carving rule by the distance to the true surface (and the temple's leave-one-out), the
//! synthesis settings by the guided result. To add a knob, write a function and list it in
//! [`knobs`].

use anyhow::Result;
use image::RgbImage;
use vt_fv::eval::{psnr, ssim};
use vt_fv::hull::{visual_hull, HullParams};
use vt_fv::{
    guided_synthesis, photo_hull, photo_hull_keeping, render_rough, Consistency, GuidedParams,
    PhotoParams, VoxelModel,
};

use super::Knob;
use crate::report::data::{synth_b, synth_b_model, temple};
use crate::report::model::{Axis, Better, Curve, Setting};
use crate::report::{timed, Ctx};

/// System B's knobs, in page order.
pub fn knobs() -> Vec<Knob> {
    vec![
        Knob::new("Voxel grid size", grid_size),
        Knob::new("Photo-consistency threshold", photo_threshold),
        Knob::new("Photo hull carving rule", carving_rule),
        Knob::new("Patch size", patch_size),
        Knob::new("Patch subsampling step", patch_step),
        Knob::new("Pyramid levels", pyramid_levels),
        Knob::new("Iteration cap M and stop threshold T", iterations),
        Knob::new("New-view method and number of reference photos", references),
    ]
}

fn object(ctx: &Ctx) -> String {
    let s = ctx.pick(200, 400);
    format!(
        "vt-fv's synthetic object (8 ring photos, {s}x{s}), scored inside the true silhouette \
         at 5 and 10 degrees from camera 0 (mean of the two)"
    )
}

/// Intersection over union of a render's coverage and the true silhouette.
fn iou(a: &vt_fv::Mask, b: &vt_fv::Mask) -> f64 {
    let (mut inter, mut union) = (0u64, 0u64);
    for y in 0..a.height() as i64 {
        for x in 0..a.width() as i64 {
            let (p, q) = (a.get_or_false(x, y), b.get_or_false(x, y));
            inter += (p && q) as u64;
            union += (p || q) as u64;
        }
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// Mean PSNR, SSIM and IoU of rough renders of `model` at the extra viewpoints.
fn rough_scores(
    d: &vt_synth::object::SynthData<vt_fv::Camera>,
    model: &vt_fv::VoxelModel,
) -> Result<(f64, f64, f64)> {
    let (w, h) = d.photos[0].dimensions();
    let (mut p, mut s, mut i) = (0.0, 0.0, 0.0);
    for (k, cam) in d.extra_cameras.iter().enumerate() {
        let r = render_rough(model, cam, w, h);
        let m = Some(&d.extra_masks[k]);
        p += psnr(&r.image, &d.extra_truth[k], m)?;
        s += ssim(&r.image, &d.extra_truth[k], m)?;
        i += iou(&r.coverage, &d.extra_masks[k]);
    }
    let n = d.extra_cameras.len() as f64;
    Ok((p / n, s / n, i / n))
}

fn grid_size(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sb = synth_b(ctx)?;
    let d = &sb.data;
    let sizes: Vec<usize> = ctx.pick(
        vec![32, 64, 128, 256],
        vec![32, 48, 64, 96, 128, 192, 256, 384],
    );
    let mut pts = Vec::new();
    for &n in &sizes {
        let hull = HullParams {
            dims: [n; 3],
            ..Default::default()
        };
        let (secs, model) = timed(1, || {
            vt_fv::build_model(
                &d.cameras,
                &d.photos,
                &d.masks,
                &hull,
                &PhotoParams::default(),
                &mut |_, _, _| {},
            )
        });
        let model = model?;
        let (p, s, i) = rough_scores(d, &model)?;
        pts.push(
            Setting::new(
                format!("{n}^3"),
                secs,
                p,
                n == HullParams::default().dims[0],
            )
            .with("SSIM", s)
            .with("silhouette IoU", i)
            .with("surface voxels", model.surface.len() as f64),
        );
    }
    Ok(vec![Curve::new(
        "b-grid",
        "Voxel grid size",
        format!(
            "Visual hull + photo hull (threshold 15, to convergence) at n^3 voxels, then the rough \
             render (flat voxel colours), on {}. x: model build time; y: PSNR of the rough render. \
             The paper and vt's default: 256^3.",
            object(ctx)
        ),
        Axis::log("model build time (s)", Better::Lower),
        Axis::new("rough render PSNR (dB)", Better::Higher),
        pts,
    )])
}

fn photo_threshold(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sb = synth_b(ctx)?;
    let d = &sb.data;
    let n = ctx.pick(128, 256);
    let thresholds: Vec<f64> = ctx.pick(
        vec![5.0, 10.0, 20.0, 40.0, 1e9],
        vec![3.0, 5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 60.0, 1e9],
    );
    let vh = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [n; 3],
            ..Default::default()
        },
    )?;
    let (mut psnr_pts, mut iou_pts) = (Vec::new(), Vec::new());
    for &th in &thresholds {
        let params = PhotoParams {
            threshold: th,
            ..Default::default()
        };
        let (secs, model) = timed(1, || {
            photo_hull(
                vh.clone(),
                &d.cameras,
                &d.photos,
                &params,
                &mut |_, _, _| {},
            )
        });
        let model = model?;
        let (p, s, i) = rough_scores(d, &model)?;
        let label = if th >= 1e8 {
            "off (visual hull)".to_string()
        } else {
            format!("{th}")
        };
        let default = th == PhotoParams::default().threshold;
        psnr_pts.push(
            Setting::new(label.clone(), secs, p, default)
                .with("SSIM", s)
                .with("voxels removed", model.removed as f64),
        );
        iou_pts.push(Setting::new(label, secs, i, default).with("PSNR (dB)", p));
    }
    let caption = |what: &str| {
        format!(
            "Photo hull (voxel colouring) at {n}^3 from the same visual hull, with the \
             photo-consistency threshold (standard deviation per channel, 0..255; 'off' keeps the \
             visual hull), on {}. x: photo hull time; y: {what}. Default 15.",
            object(ctx)
        )
    };
    Ok(vec![
        Curve::new(
            "b-photo-threshold-psnr",
            "Photo-consistency threshold: rough render PSNR",
            caption("PSNR of the rough render"),
            Axis::new("photo hull time (s)", Better::Lower),
            Axis::new("rough render PSNR (dB)", Better::Higher),
            psnr_pts,
        ),
        Curve::new(
            "b-photo-threshold-iou",
            "Photo-consistency threshold: silhouette IoU",
            caption(
                "intersection over union of the rough render's coverage and the true silhouette",
            ),
            Axis::new("photo hull time (s)", Better::Lower),
            Axis::new("silhouette IoU", Better::Higher),
            iou_pts,
        ),
    ])
}

/// Two-way distance of a model's surface to the synthetic object's true surface, in voxels.
fn surface_distance(
    d: &vt_synth::object::SynthData<vt_fv::Camera>,
    model: &VoxelModel,
    samples: usize,
) -> Result<vt_synth::surface::SurfaceDistance> {
    let g = &model.grid;
    let vs = g.voxel_size();
    let points: Vec<nalgebra::Vector3<f64>> =
        model.surface.iter().map(|v| model.centre(v)).collect();
    d.object
        .compare_surface(&points, (vs.x * vs.y * vs.z).cbrt(), samples, 1)
        .ok_or_else(|| anyhow::anyhow!("empty model surface"))
}

/// Share of a model's surface voxels seen by no camera.
fn unseen_share(model: &VoxelModel) -> f64 {
    let unseen = model.surface.iter().filter(|v| v.seen_by == 0).count();
    unseen as f64 / model.surface.len().max(1) as f64
}

/// Leave-one-out on templeSparseRing with photo hull `photo` (model as `vt fv eval` builds it,
/// new view by the default method): mean PSNR and SSIM inside the withheld photos' scoring
/// silhouettes, and the views scored.
fn temple_scores(ctx: &mut Ctx, photo: &PhotoParams, grid: usize) -> Result<(f64, f64, usize)> {
    let tp = temple(ctx)?;
    let ds = &tp.ds;
    let n = ds.cams.len();
    let withheld: Vec<usize> = (0..n).step_by(ctx.pick(n / 2, 2).max(1)).collect();
    let (mut p, mut s) = (0.0, 0.0);
    for &k in &withheld {
        let keep: Vec<usize> = (0..n).filter(|&i| i != k).collect();
        let cams: Vec<vt_fv::Camera> = keep.iter().map(|&i| ds.cams[i].clone()).collect();
        let masks: Vec<vt_fv::Mask> = keep.iter().map(|&i| ds.masks[i].clone()).collect();
        let bounds = vt_fv::dataset::volume(None, &cams, &masks)?;
        let hull = vt_fv::dataset::ModelParams {
            grid,
            ..Default::default()
        }
        .hull(bounds);
        let mut masks = ds.masks.clone();
        masks[k] = ds.score_masks[k].clone();
        let (r, _) = vt_fv::pipeline::leave_one_out(
            &ds.cams,
            &ds.images,
            &masks,
            k,
            &hull,
            photo,
            &vt_fv::pipeline::ViewParams::default(),
        )?;
        p += r.guided.inside.psnr;
        s += r.guided.inside.ssim;
    }
    let m = withheld.len() as f64;
    Ok((p / m, s / m, withheld.len()))
}

fn carving_rule(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let sb = synth_b(ctx)?;
    let d = &sb.data;
    let n = ctx.pick(128, 256);
    let temple_grid = ctx.pick(64, 128);
    let samples = ctx.pick(50_000, 200_000);
    let paper_colours = PhotoParams {
        colour_partly_seen: false,
        ..Default::default()
    };
    let settings: Vec<(&str, PhotoParams)> = vec![
        (
            "visual hull (no carving)",
            PhotoParams {
                max_passes: 0,
                ..paper_colours.clone()
            },
        ),
        (
            "before: paper's visibility and colours",
            paper_colours.clone(),
        ),
        (
            "default (partly seen voxels coloured)",
            PhotoParams::default(),
        ),
        (
            "Agree(0.8): 4 in 5 cameras must agree",
            PhotoParams {
                consistency: Consistency::Agree(0.8),
                ..Default::default()
            },
        ),
        (
            "AgreeFrom(0.8, 10): Agree when 10+ cameras judge",
            PhotoParams {
                consistency: Consistency::AgreeFrom {
                    share: 0.8,
                    min: 10,
                },
                ..Default::default()
            },
        ),
    ];
    let hull = HullParams {
        dims: [n; 3],
        ..Default::default()
    };
    let vh = visual_hull(&d.cameras, &d.masks, &hull)?;
    // The case: many cameras on the ring (full report only: 36 ray-cast photos).
    let ring36 = if ctx.quick {
        None
    } else {
        let s = d.photos[0].width();
        let data = vt_synth::object::generate(&vt_synth::object::SceneParams {
            n_views: 36,
            width: s,
            height: s,
            extra_angles_deg: vec![],
            ..Default::default()
        })
        .map_err(anyhow::Error::msg)?
        .try_map_cameras(|c| vt_fv::Camera::new(c.name.clone(), c.k, c.r, c.t))?;
        let vh = visual_hull(&data.cameras, &data.masks, &hull)?;
        Some((data, vh))
    };
    let (mut pts, mut scored) = (Vec::new(), 0);
    for (label, params) in &settings {
        let (secs, model) = timed(1, || {
            photo_hull_keeping(
                vh.clone(),
                &d.cameras,
                &d.photos,
                Some(&d.masks),
                params,
                &mut |_, _, _| {},
            )
        });
        let model = model?;
        let dist = surface_distance(d, &model, samples)?;
        let (p, _, i) = rough_scores(d, &model)?;
        let (tp, ts, views) = temple_scores(ctx, params, temple_grid)?;
        scored = views;
        let mut pt = Setting::new(*label, secs, dist.mean(), *params == PhotoParams::default())
            .with("two-way 90th pct (voxels)", dist.p90())
            .with("model to truth mean (voxels)", dist.to_truth.mean)
            .with("truth to model mean (voxels)", dist.from_truth.mean)
            .with("unseen surface share", unseen_share(&model))
            .with("silhouette IoU", i)
            .with("rough render PSNR (dB)", p)
            .with("temple PSNR inside (dB)", tp)
            .with("temple SSIM inside", ts);
        if let Some((data, vh)) = &ring36 {
            let (secs, model) = timed(1, || {
                photo_hull_keeping(
                    vh.clone(),
                    &data.cameras,
                    &data.photos,
                    Some(&data.masks),
                    params,
                    &mut |_, _, _| {},
                )
            });
            let model = model?;
            let dist = surface_distance(data, &model, samples)?;
            pt = pt
                .with("36 views: two-way mean (voxels)", dist.mean())
                .with("36 views: two-way 90th pct (voxels)", dist.p90())
                .with("36 views: unseen surface share", unseen_share(&model))
                .with("36 views: photo hull time (s)", secs);
        }
        pts.push(pt);
    }
    let s = d.photos[0].width();
    Ok(vec![Curve::new(
        "b-carving",
        "Photo hull carving rule",
        format!(
            "The photo hull's rules from the same visual hull ({n}^3) of vt synth object's ring \
             (8 photos, {s}x{s}): the visual hull alone, the paper's rule as vt had it before \
             issue #24 (a camera sees a voxel when the voxel's ID wins its centre pixel; all \
             cameras' colours within threshold 15; a voxel no camera sees so takes the nearest \
             seen colour), the default (the same carving, but a voxel whose ID holds part of \
             its footprint takes its colour from those pixels and counts as seen), and \
             Consistency::Agree(0.8) (the 80 % of cameras nearest the median must agree), and \
             AgreeFrom(0.8, 10) (Agree only for voxels judged by 10 or more cameras). \
             y: the two-way mean distance between the model's surface voxel centres and the \
             true surface, in voxels (exact from each voxel, from 1 in {samples} true-surface \
             points to the nearest voxel; the underside, which no camera sees, counts too); \
             x: photo hull time (noisy: shared machine). Extra figures: silhouette IoU and \
             rough-render PSNR at 5 and 10 degrees, the share of surface voxels seen by no \
             camera, templeSparseRing's leave-one-out with the default new view ({scored} \
             withheld photos, model {temple_grid}^3, PSNR/SSIM inside the scoring silhouette){}. \
             Agree(0.8) fixes the 36-view case (the paper's rule carves into the object once \
             many cameras see each voxel) but costs the temple a little, so it is an option; \
             AgreeFrom(0.8, 10) fixes it too (vt-fv's carve_truth: 2.60 against the visual \
             hull's 2.82) and leaves the temple as it is, but on the kettle's 28 photos a few \
             degrees apart, where many cameras judge every voxel, the textured leave-one-out \
             drops 24.34 -> 24.04 dB, so it is an option too.",
            if ctx.quick {
                ""
            } else {
                ", and the same for a ring of 36 photos"
            }
        ),
        Axis::new("photo hull time (s)", Better::Lower),
        Axis::new(
            "two-way mean distance to the true surface (voxels)",
            Better::Lower,
        ),
        pts,
    )])
}

/// Guided synthesis of every extra view with `params`: mean seconds, PSNR and SSIM.
fn synth_scores(ctx: &mut Ctx, params: &GuidedParams) -> Result<(f64, f64, f64)> {
    let sb = synth_b(ctx)?;
    let m = synth_b_model(ctx)?;
    let d = &sb.data;
    let (mut t, mut p, mut s) = (0.0, 0.0, 0.0);
    for k in 0..d.extra_cameras.len() {
        let (secs, out) = timed(1, || {
            guided_synthesis(&d.photos[m.reference[k]], &m.rough[k], params)
        });
        let out: RgbImage = out?;
        let mask = Some(&d.extra_masks[k]);
        t += secs;
        p += psnr(&out, &d.extra_truth[k], mask)?;
        s += ssim(&out, &d.extra_truth[k], mask)?;
    }
    let n = d.extra_cameras.len() as f64;
    Ok((t / n, p / n, s / n))
}

fn synth_caption(ctx: &mut Ctx, what: &str) -> Result<String> {
    let m = synth_b_model(ctx)?;
    Ok(format!(
        "Guided texture synthesis (SPEC B.6, PatchMatch) of the rough render from the nearest \
         reference photo, {what}, on {} (model {}^3). x: synthesis time per view; y: PSNR of the \
         result. The rough render itself scores {:.2} dB here: a setting below that line makes \
         the image worse than its guide.",
        object(ctx),
        m.grid,
        {
            let sb = synth_b(ctx)?;
            let d = &sb.data;
            let mut p = 0.0;
            for k in 0..d.extra_cameras.len() {
                p += psnr(&m.rough[k], &d.extra_truth[k], Some(&d.extra_masks[k]))?;
            }
            p / d.extra_cameras.len() as f64
        }
    ))
}

fn patch_size(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let patches: Vec<usize> = ctx.pick(vec![5, 7, 13, 21, 41], vec![5, 7, 9, 13, 21, 31, 41]);
    let mut pts = Vec::new();
    for &patch in &patches {
        let (t, p, s) = synth_scores(ctx, &GuidedParams::fast_for(patch))?;
        pts.push(
            Setting::new(
                format!("{patch}"),
                t,
                p,
                patch == GuidedParams::default().patch,
            )
            .with("SSIM", s),
        );
    }
    Ok(vec![Curve::new(
        "b-patch",
        "Patch size",
        synth_caption(
            ctx,
            "patch side p with GuidedParams::fast_for(p) (up to 9: full resolution, parallel \
             strips, black skipped; above: 3 pyramid levels and step 2 as well); default: the \
             paper's 41",
        )?,
        Axis::log("synthesis time (s)", Better::Lower),
        Axis::new("guided PSNR (dB)", Better::Higher),
        pts,
    )])
}

fn patch_step(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let patch = ctx.pick(13, 21);
    let mut pts = Vec::new();
    for step in [1, 2, 3, 4] {
        let params = GuidedParams {
            patch,
            step,
            ..GuidedParams::fast()
        };
        let (t, p, s) = synth_scores(ctx, &params)?;
        pts.push(
            Setting::new(
                format!("step {step}"),
                t,
                p,
                step == GuidedParams::default().step,
            )
            .with("SSIM", s),
        );
    }
    Ok(vec![Curve::new(
        "b-step",
        "Patch subsampling step",
        synth_caption(
            ctx,
            &format!(
                "patch {patch} compared on every step-th pixel (GuidedParams::fast() otherwise: 3 \
                 levels, strips, black skipped); default step 1"
            ),
        )?,
        Axis::new("synthesis time (s)", Better::Lower),
        Axis::new("guided PSNR (dB)", Better::Higher),
        pts,
    )])
}

fn pyramid_levels(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let patch = ctx.pick(13, 21);
    let mut pts = Vec::new();
    for levels in [1, 2, 3, 4] {
        let params = GuidedParams {
            patch,
            levels,
            ..GuidedParams::fast()
        };
        let (t, p, s) = synth_scores(ctx, &params)?;
        pts.push(
            Setting::new(
                format!("{levels} level{}", if levels > 1 { "s" } else { "" }),
                t,
                p,
                levels == GuidedParams::default().levels,
            )
            .with("SSIM", s),
        );
    }
    Ok(vec![Curve::new(
        "b-levels",
        "Pyramid levels",
        synth_caption(
            ctx,
            &format!(
                "patch {patch}, coarse-to-fine over this many levels (GuidedParams::fast() \
                 otherwise: step 2, strips, black skipped); default 1 (the paper)"
            ),
        )?,
        Axis::new("synthesis time (s)", Better::Lower),
        Axis::new("guided PSNR (dB)", Better::Higher),
        pts,
    )])
}

fn iterations(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    let combos: Vec<(usize, f64)> = ctx.pick(
        vec![(1, 0.06), (3, 0.06), (10, 0.06), (10, 0.3), (10, 0.01)],
        vec![
            (1, 0.06),
            (2, 0.06),
            (3, 0.06),
            (5, 0.06),
            (10, 0.06),
            (10, 0.3),
            (10, 0.15),
            (10, 0.02),
            (20, 0.01),
        ],
    );
    let base = GuidedParams::fast_for(7);
    let mut pts = Vec::new();
    for &(m, t) in &combos {
        let params = GuidedParams {
            max_init_iters: m,
            stop_ratio: t,
            ..base
        };
        let (secs, p, s) = synth_scores(ctx, &params)?;
        let d = GuidedParams::default();
        pts.push(
            Setting::new(
                format!("M {m}, T {t}"),
                secs,
                p,
                m == d.max_init_iters && t == d.stop_ratio,
            )
            .with("SSIM", s),
        );
    }
    Ok(vec![Curve::new(
        "b-iterations",
        "Iteration cap M and stop threshold T",
        synth_caption(
            ctx,
            "patch 7 (GuidedParams::fast_for(7)) with at most M initialisation-correction \
             iterations and a stage stopping when the update ratio falls to T; default M 10, \
             T 0.06 (the paper)",
        )?,
        Axis::new("synthesis time (s)", Better::Lower),
        Axis::new("guided PSNR (dB)", Better::Higher),
        pts,
    )])
}

fn references(ctx: &mut Ctx) -> Result<Vec<Curve>> {
    use vt_fv::pipeline::{novel_view, Method, ViewParams};
    use vt_fv::texture::TextureParams;
    let sb = synth_b(ctx)?;
    let m = synth_b_model(ctx)?;
    let d = &sb.data;
    let (w, h) = d.photos[0].dimensions();
    let counts: Vec<usize> = ctx.pick(vec![1, 2, 3, 4], vec![1, 2, 3, 4, 6, 8]);
    let mut settings: Vec<(String, ViewParams)> = vec![(
        "paper (rough guide, 1 photo)".into(),
        ViewParams::paper(GuidedParams::fast_for(7)),
    )];
    for &n in &counts {
        settings.push((
            format!("textured, {n} photo{}", if n > 1 { "s" } else { "" }),
            ViewParams {
                method: Method::Textured,
                texture: TextureParams {
                    references: n,
                    ..Default::default()
                },
                refine: false,
                ..Default::default()
            },
        ));
    }
    settings.push((
        "textured, 2 photos + synthesis".into(),
        ViewParams {
            refine: true,
            ..Default::default()
        },
    ));
    let mut pts = Vec::new();
    for (label, vp) in &settings {
        let (mut t, mut p, mut s) = (0.0, 0.0, 0.0);
        for (k, cam) in d.extra_cameras.iter().enumerate() {
            let (secs, v) = timed(1, || {
                novel_view(&m.model, &d.cameras, &d.photos, cam, w, h, vp)
            });
            let v = v?;
            let mask = Some(&d.extra_masks[k]);
            t += secs;
            p += psnr(&v.guided, &d.extra_truth[k], mask)?;
            s += ssim(&v.guided, &d.extra_truth[k], mask)?;
        }
        let n = d.extra_cameras.len() as f64;
        pts.push(
            Setting::new(label.clone(), t / n, p / n, *vp == ViewParams::default())
                .with("SSIM", s / n),
        );
    }
    Ok(vec![Curve::new(
        "b-references",
        "New-view method and number of reference photos",
        format!(
            "The new view made from the model ({}^3) by the paper's method (rough render re-textured \
             by guided synthesis, patch 7, from the one nearest photo) or by vt-fv's view-dependent \
             texturing from the n nearest photos (optionally refined by synthesis), on {}. x: time \
             per view (rough render, texturing, synthesis); y: PSNR of the result. Default: \
             vt-fv's ViewParams::default().",
            m.grid,
            object(ctx)
        ),
        Axis::log("time per view (s)", Better::Lower),
        Axis::new("PSNR (dB)", Better::Higher),
        pts,
    )])
}
