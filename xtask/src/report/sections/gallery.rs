//! Section 5: the gallery. The demo scene and tree.avi: median background, masks, the loop cost
//! matrix of eq. (1) as a heat map with the chosen loop circled, rendered intermediate views
//! beside their truth; System B's visual and photo hull views, rough render, guided result and
//! truth with their scores.

use anyhow::Result;
use image::RgbImage;
use vt_core::analysis::{analyze, MemorySource, Quiet};
use vt_core::mask::xor_count;
use vt_core::metrics::psnr;
use vt_core::render::{Player, RenderParams, Renderer};
use vt_core::Mask;
use vt_fv::hull::{visual_hull, HullParams};
use vt_fv::{guided_synthesis, photo_hull, render_rough, GuidedParams, PhotoParams};

use crate::report::data::{synth_a, synth_b, synth_b_model, tree};
use crate::report::model::{Gallery, Item};
use crate::report::plot::heatmap_png;
use crate::report::Ctx;

fn mask_image(m: &Mask) -> RgbImage {
    RgbImage::from_fn(m.width(), m.height(), |x, y| {
        if m.get(x, y) {
            image::Rgb([255, 255, 255])
        } else {
            image::Rgb([0, 0, 0])
        }
    })
}

/// Eq. (1)'s windowed cost for every (m, n) with both windows inside the clip; `None` where
/// `|n - m| < min_length` (not a loop eq. (1) may pick).
fn cost_matrix(masks: &[Mask], window: usize, min_length: usize) -> Vec<Vec<Option<u64>>> {
    let n = masks.len() + 1 - window.min(masks.len());
    (0..n)
        .map(|a| {
            (0..n)
                .map(|b| {
                    (a.abs_diff(b) >= min_length).then(|| {
                        (0..window)
                            .map(|i| xor_count(&masks[a + i], &masks[b + i]))
                            .sum()
                    })
                })
                .collect()
        })
        .collect()
}

fn system_a(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let sa = synth_a(ctx)?;
    let mut images = Vec::new();
    for (p, v) in sa.analysis.views.iter().enumerate() {
        images.push((
            ctx.save_image(&format!("demo-background-{p}"), &v.background)?,
            format!("median background of view {p}"),
        ));
    }
    let v0 = &sa.analysis.views[0];
    for s in [0, v0.masks.len() / 3, 2 * v0.masks.len() / 3] {
        images.push((
            ctx.save_image(&format!("demo-mask-{s}"), &mask_image(&v0.masks[s]))?,
            format!("mask of view 0, frame {s}"),
        ));
    }
    let lp = sa.params.loops;
    let heat = "images/demo-costs.png".to_string();
    heatmap_png(
        &cost_matrix(&v0.masks, lp.window, lp.min_length),
        (v0.best_loop.start, v0.best_loop.end),
        &ctx.dir.join(&heat),
    )?;
    images.push((
        heat,
        format!(
            "eq. (1) cost of view 0 (row m, column n; dark = similar, grey = shorter than {}), \
             chosen loop ({}, {}) circled",
            lp.min_length, v0.best_loop.start, v0.best_loop.end
        ),
    ));
    let mut strip = Vec::new();
    let scene = &sa.loaded;
    let mut renderer = Renderer::new(scene.render.clone(), RenderParams::default())?;
    let (w, h) = renderer.size();
    for q in [0.0, 0.5, 1.0, 1.5, 2.0] {
        let choice = Player::new().advance(&scene.render, q)?;
        let mut out = RgbImage::new(w, h);
        renderer.render_into(&scene.objects, q, &choice, &mut out)?;
        let truth = sa
            .scene
            .truth(q, sa.scene.phase_of(choice.view, choice.frame));
        let p = psnr(&out, &truth, None)?;
        strip.push((
            ctx.save_image(&format!("demo-render-q{q}"), &out)?,
            format!("rendered q = {q} ({p:.1} dB vs truth)"),
        ));
        strip.push((
            ctx.save_image(&format!("demo-truth-q{q}"), &truth)?,
            format!("ray-cast truth q = {q}"),
        ));
    }

    let tr = tree(ctx)?;
    let mut params = crate::report::data::thesis_params();
    params.loops.min_length = 20;
    let mut src = MemorySource {
        name: "tree.avi".into(),
        frames: tr.frames.clone(),
    };
    let a = analyze(&mut [&mut src], &[], &params, &mut Quiet)?;
    let tv = &a.views[0];
    let mut tree_imgs = vec![(
        ctx.save_image("tree-background", &tv.background)?,
        "tree.avi: median background".to_string(),
    )];
    for s in [10, 30, 50] {
        tree_imgs.push((
            ctx.save_image(&format!("tree-mask-{s}"), &mask_image(&tv.masks[s]))?,
            format!("tree.avi: mask of frame {s}"),
        ));
    }
    let heat = "images/tree-costs.png".to_string();
    heatmap_png(
        &cost_matrix(&tv.masks, params.loops.window, params.loops.min_length),
        (tv.best_loop.start, tv.best_loop.end),
        &ctx.dir.join(&heat),
    )?;
    tree_imgs.push((
        heat,
        format!(
            "tree.avi: eq. (1) cost (min length 20), chosen loop ({}, {}) circled, seam score {:.2}",
            tv.best_loop.start, tv.best_loop.end, tv.loop_seam
        ),
    ));
    Ok(vec![
        Item::Gallery(Gallery {
            title: "System A: the demo scene".into(),
            caption: "vt demo's synthetic scene: backgrounds, masks, the loop cost matrix.".into(),
            images,
        }),
        Item::Gallery(Gallery {
            title: "System A: rendered intermediate views and their truth".into(),
            caption: "Bilinear rendering (eq. 3-6) of the demo scene across the views, each \
                      beside the ray-cast truth at the same viewpoint and motion phase. Off-plane \
                      background (pillars, wall) ghosts: one plane cannot explain it."
                .into(),
            images: strip,
        }),
        Item::Gallery(Gallery {
            title: "System A: tree.avi".into(),
            caption: "A real video of a tree in wind (one view).".into(),
            images: tree_imgs,
        }),
    ])
}

fn system_b(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let sb = synth_b(ctx)?;
    let m = synth_b_model(ctx)?;
    let d = &sb.data;
    let (w, h) = d.photos[0].dimensions();
    let vh = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [m.grid; 3],
            ..Default::default()
        },
    )?;
    // The visual hull coloured but not carved: photo hull with an unreachable threshold.
    let vh_model = photo_hull(
        vh,
        &d.cameras,
        &d.photos,
        &PhotoParams {
            threshold: 1e9,
            ..Default::default()
        },
        &mut |_, _, _| {},
    )?;
    let k = 0;
    let (cam, truth, mask) = (&d.extra_cameras[k], &d.extra_truth[k], &d.extra_masks[k]);
    let score = |img: &RgbImage| -> Result<String> {
        Ok(format!(
            "{:.2} dB / SSIM {:.3}",
            vt_fv::eval::psnr(img, truth, Some(mask))?,
            vt_fv::eval::ssim(img, truth, Some(mask))?
        ))
    };
    let vh_img = render_rough(&vh_model, cam, w, h).image;
    let guided = guided_synthesis(
        &d.photos[m.reference[k]],
        &m.rough[k],
        &GuidedParams::fast_for(7),
    )?;
    let angle = sb.angles[k];
    let images = vec![
        (
            ctx.save_image("fv-visual-hull", &vh_img)?,
            format!("visual hull, coloured, {}^3: {}", m.grid, score(&vh_img)?),
        ),
        (
            ctx.save_image("fv-rough", &m.rough[k])?,
            format!(
                "photo hull rough render ({} surface voxels): {}",
                m.model.surface.len(),
                score(&m.rough[k])?
            ),
        ),
        (
            ctx.save_image("fv-guided", &guided)?,
            format!("guided, patch 7: {}", score(&guided)?),
        ),
        (
            ctx.save_image("fv-reference", &d.photos[m.reference[k]])?,
            format!("reference photo {} (the synthesis input)", m.reference[k]),
        ),
        (
            ctx.save_image("fv-truth", truth)?,
            format!("truth at {angle} degrees"),
        ),
    ];
    Ok(vec![Item::Gallery(Gallery {
        title: "System B: the synthetic object".into(),
        caption: format!(
            "vt-fv's synthetic object seen {angle} degrees from camera 0; scores inside the true \
             silhouette. The temple's leave-one-out images are in section 4."
        ),
        images,
    })])
}

/// Builds the section.
pub fn build(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let mut items = system_a(ctx)?;
    items.extend(system_b(ctx)?);
    Ok(items)
}
