//! Guided synthesis against ground truth on the synthetic object.
//!
//! Measured (96x96 views, 96^3 voxels, patch 7): at 5 degrees from reference camera 0 the guided
//! result beats the rough render on PSNR (about 21.9 vs 21.1 dB) and SSIM (0.86 vs 0.77); at 10
//! degrees SSIM still wins clearly (0.83 vs 0.75) while PSNR is about even (20.9 vs 21.0 dB): the
//! paper's known weakness, quality falling as the view moves away from the reference camera.

use std::time::Instant;
use vt_fv::eval::{psnr, ssim};
use vt_fv::hull::HullParams;
use vt_fv::{build_model, novel_view, Camera, GuidedParams, PhotoParams, ViewParams, VoxelModel};
use vt_synth::object::{generate, SceneParams, SynthData};

/// The synthetic object (`size` x `size` photos, extra views at `extra` degrees) and its voxel
/// model on a `grid`^3 hull.
fn object_and_model(size: u32, extra: &[f64], grid: usize) -> (SynthData<Camera>, VoxelModel) {
    let d = generate(&SceneParams {
        width: size,
        height: size,
        extra_angles_deg: extra.to_vec(),
        ..Default::default()
    })
    .unwrap()
    .try_map_cameras(|c| Camera::new(c.name.clone(), c.k, c.r, c.t))
    .unwrap();
    let model = build_model(
        &d.cameras,
        &d.photos,
        &d.masks,
        &HullParams {
            dims: [grid; 3],
            ..Default::default()
        },
        &PhotoParams::default(),
        &mut |_, _, _| {},
    )
    .unwrap();
    (d, model)
}

#[test]
fn guided_synthesis_beats_rough_render_on_synthetic_object() {
    let (d, model) = object_and_model(96, &[5.0, 10.0], 96);
    let configs = [
        (
            "exact",
            GuidedParams {
                patch: 7,
                ..Default::default()
            },
        ),
        (
            "fast",
            GuidedParams {
                patch: 7,
                levels: 2,
                step: 2,
                strips: 0,
                ..Default::default()
            },
        ),
    ];
    for (k, cam) in d.extra_cameras.iter().enumerate() {
        for (name, p) in &configs {
            let t = Instant::now();
            let v = novel_view(
                &model,
                &d.cameras,
                &d.photos,
                cam,
                96,
                96,
                &ViewParams::paper(p.clone()),
            )
            .unwrap();
            let secs = t.elapsed().as_secs_f64();
            let m = Some(&d.extra_masks[k]);
            let truth = &d.extra_truth[k];
            let (pr, pg) = (
                psnr(&v.rough.image, truth, m).unwrap(),
                psnr(&v.guided, truth, m).unwrap(),
            );
            let (sr, sg) = (
                ssim(&v.rough.image, truth, m).unwrap(),
                ssim(&v.guided, truth, m).unwrap(),
            );
            eprintln!("view {k} (ref {}), {name}: PSNR rough {pr:.2} guided {pg:.2}; SSIM rough {sr:.3} guided {sg:.3}; {secs:.2}s", v.reference);
            assert!(
                sg > sr + 0.03,
                "view {k} {name}: guided SSIM {sg} not above rough {sr}"
            );
            if k == 0 {
                assert!(pg > pr, "view {k} {name}: guided PSNR {pg} <= rough {pr}");
            } else {
                assert!(
                    pg > pr - 0.5,
                    "view {k} {name}: guided PSNR {pg} far below rough {pr}"
                );
            }
        }
    }
}

/// Stage (ii) with a patch larger than 2L + 1 must not drift away from the guide: the output
/// part of the mixed patch is limited to distance L. (With the whole upper half of the patch
/// from the output, patch 41 at 400x400 lost 1.3 dB against its own stage (i).)
#[test]
fn synthesis_stage_keeps_large_patches_on_the_guide() {
    let (d, model) = object_and_model(160, &[5.0], 128);
    let base = GuidedParams {
        patch: 17,
        ..GuidedParams::fast()
    };
    let score = |p: &GuidedParams| {
        let v = novel_view(
            &model,
            &d.cameras,
            &d.photos,
            &d.extra_cameras[0],
            160,
            160,
            &ViewParams::paper(p.clone()),
        )
        .unwrap();
        psnr(&v.guided, &d.extra_truth[0], Some(&d.extra_masks[0])).unwrap()
    };
    let stage_i = score(&GuidedParams {
        max_synth_iters: 0,
        ..base.clone()
    });
    let both = score(&base);
    eprintln!("patch 17: stage (i) only {stage_i:.2} dB, with stage (ii) {both:.2} dB");
    assert!(
        both > stage_i - 0.3,
        "stage (ii) lost {:.2} dB against stage (i)",
        stage_i - both
    );
}

/// The default method (view-dependent texturing) against the ray-cast truth: it beats the
/// rough render on PSNR and SSIM at 5 and 10 degrees from reference camera 0.
#[test]
fn textured_view_beats_rough_render_on_synthetic_object() {
    let (d, model) = object_and_model(96, &[5.0, 10.0], 96);
    for (k, cam) in d.extra_cameras.iter().enumerate() {
        let v = novel_view(
            &model,
            &d.cameras,
            &d.photos,
            cam,
            96,
            96,
            &ViewParams::default(),
        )
        .unwrap();
        let (m, truth) = (Some(&d.extra_masks[k]), &d.extra_truth[k]);
        let (pr, pg) = (
            psnr(&v.rough.image, truth, m).unwrap(),
            psnr(&v.guided, truth, m).unwrap(),
        );
        let (sr, sg) = (
            ssim(&v.rough.image, truth, m).unwrap(),
            ssim(&v.guided, truth, m).unwrap(),
        );
        eprintln!(
            "view {k}: PSNR rough {pr:.2} textured {pg:.2}; SSIM rough {sr:.3} textured {sg:.3}"
        );
        assert!(pg > pr, "view {k}: textured PSNR {pg} <= rough {pr}");
        assert!(sg > sr, "view {k}: textured SSIM {sg} <= rough {sr}");
    }
}
