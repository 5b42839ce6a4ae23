//! Benchmarks of System B on the synthetic object (8 ring views, 400x400, as in the paper):
//! visual hull 256^3, photo hull, and guided synthesis at patch 41 and 7, with quality (PSNR and
//! SSIM against the ray-cast truth) per speed option printed alongside.
//!
//! `VT_BENCH_FULL=1` adds the paper-exact patch-41 synthesis at 400x400 (minutes).

use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use vt_fv::eval::{psnr, ssim};
use vt_fv::hull::{visual_hull, HullParams};
use vt_synth::object::{generate, SceneParams};

type SynthData = vt_synth::object::SynthData<Camera>;
use vt_fv::{photo_hull, render_rough, Camera, GuidedParams, PhotoParams, VoxelModel};

fn data() -> SynthData {
    generate(&SceneParams {
        extra_angles_deg: vec![5.0, 10.0],
        ..Default::default()
    })
    .unwrap()
    .try_map_cameras(|c| Camera::new(c.name.clone(), c.k, c.r, c.t))
    .unwrap()
}

fn model(d: &SynthData, n: usize) -> VoxelModel {
    let g = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [n; 3],
            ..Default::default()
        },
    )
    .unwrap();
    photo_hull(
        g,
        &d.cameras,
        &d.photos,
        &PhotoParams::default(),
        &mut |_, _, _| {},
    )
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let d = data();
    let mut g = c.benchmark_group("fv");
    g.sample_size(10);
    for n in [128, 256] {
        let params = HullParams {
            dims: [n; 3],
            ..Default::default()
        };
        g.bench_function(format!("visual_hull_{n}^3_8x400x400"), |b| {
            b.iter(|| visual_hull(&d.cameras, &d.masks, &params).unwrap())
        });
    }
    let vh128 = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [128; 3],
            ..Default::default()
        },
    )
    .unwrap();
    g.bench_function("photo_hull_128^3", |b| {
        b.iter(|| {
            photo_hull(
                vh128.clone(),
                &d.cameras,
                &d.photos,
                &PhotoParams::default(),
                &mut |_, _, _| {},
            )
            .unwrap()
        })
    });
    g.finish();

    let t = Instant::now();
    let vh = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [256; 3],
            ..Default::default()
        },
    )
    .unwrap();
    let t_vh = t.elapsed().as_secs_f64();
    let capped = photo_hull(
        vh,
        &d.cameras,
        &d.photos,
        &PhotoParams {
            max_passes: 64,
            ..Default::default()
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    println!(
        "photo hull 256^3 capped at 64 passes (the old default): {:.2} s after the visual hull ({t_vh:.3} s), {} surface voxels",
        t.elapsed().as_secs_f64() - t_vh,
        capped.surface.len()
    );
    let t = Instant::now();
    let m = model(&d, 256);
    println!("photo hull 256^3 to convergence (visual hull included): {:.2} s, {} passes, {} voxels removed, {} surface voxels", t.elapsed().as_secs_f64(), m.passes, m.removed, m.surface.len());

    let full = std::env::var("VT_BENCH_FULL").is_ok_and(|v| v == "1");
    let mut configs: Vec<(&str, GuidedParams)> = vec![
        (
            "patch 7 exact (sequential, every pixel)",
            GuidedParams {
                patch: 7,
                ..Default::default()
            },
        ),
        (
            "patch 7 fast_for (strips, skip black)",
            GuidedParams::fast_for(7),
        ),
        (
            "patch 7 stage (i) only",
            GuidedParams {
                max_synth_iters: 0,
                ..GuidedParams::fast_for(7)
            },
        ),
        (
            "patch 7 + 3 levels, step 2",
            GuidedParams {
                patch: 7,
                ..GuidedParams::fast()
            },
        ),
        (
            "patch 21 fast (3 levels, step 2, strips, skip black)",
            GuidedParams {
                patch: 21,
                ..GuidedParams::fast()
            },
        ),
        (
            "patch 41 fast (3 levels, step 2, strips, skip black)",
            GuidedParams::fast(),
        ),
        (
            "patch 41 fast, step 4",
            GuidedParams {
                step: 4,
                ..GuidedParams::fast()
            },
        ),
        (
            "patch 41 fast, 1 level",
            GuidedParams {
                levels: 1,
                ..GuidedParams::fast()
            },
        ),
        (
            "patch 41 stage (i) only",
            GuidedParams {
                max_synth_iters: 0,
                ..GuidedParams::fast()
            },
        ),
    ];
    if full {
        configs.push(("patch 41 exact (paper)", GuidedParams::default()));
    }
    for (k, cam) in d.extra_cameras.iter().enumerate() {
        let rough = render_rough(&m, cam, 400, 400);
        let (truth, mask) = (&d.extra_truth[k], Some(&d.extra_masks[k]));
        let reference = vt_fv::pipeline::nearest_reference(&d.cameras, cam).unwrap();
        println!(
            "view at {} deg (reference {reference}): rough PSNR {:.2} dB SSIM {:.3}",
            [5, 10][k],
            psnr(&rough.image, truth, mask).unwrap(),
            ssim(&rough.image, truth, mask).unwrap()
        );
        for (name, p) in &configs {
            let t = Instant::now();
            let out = vt_fv::guided_synthesis(&d.photos[reference], &rough.image, p).unwrap();
            println!(
                "  guided {name}: {:.2} s, PSNR {:.2} dB SSIM {:.3}",
                t.elapsed().as_secs_f64(),
                psnr(&out, truth, mask).unwrap(),
                ssim(&out, truth, mask).unwrap()
            );
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
