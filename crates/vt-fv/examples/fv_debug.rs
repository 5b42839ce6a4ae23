//! Writes debug images of the synthetic pipeline to a folder (first argument, default /tmp/fv).
use vt_fv::eval::{psnr, ssim};
use vt_fv::hull::HullParams;
use vt_fv::synth::{generate, SynthParams as SceneParams};
use vt_fv::{build_model, novel_view, PhotoParams, SynthParams};

fn main() {
    let dir = std::env::args().nth(1).unwrap_or("/tmp/fv".into());
    let size: u32 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(96);
    let res: usize = std::env::args()
        .nth(3)
        .and_then(|s| s.parse().ok())
        .unwrap_or(96);
    let thr: f64 = std::env::args()
        .nth(4)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20.0);
    let patch: usize = std::env::args()
        .nth(5)
        .and_then(|s| s.parse().ok())
        .unwrap_or(7);
    std::fs::create_dir_all(&dir).unwrap();
    let d = generate(&SceneParams {
        width: size,
        height: size,
        extra_angles_deg: vec![5.0, 10.0],
        ..Default::default()
    })
    .unwrap();
    let t = std::time::Instant::now();
    let model = build_model(
        &d.cameras,
        &d.photos,
        &d.masks,
        &HullParams {
            dims: [res; 3],
            ..Default::default()
        },
        &PhotoParams {
            threshold: thr,
            ..Default::default()
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    println!(
        "model {:?} passes {} removed {} in {:?}",
        model.grid,
        model.passes,
        model.removed,
        t.elapsed()
    );
    for (k, cam) in d.extra_cameras.iter().enumerate() {
        let t = std::time::Instant::now();
        let v = novel_view(
            &model,
            &d.cameras,
            &d.photos,
            cam,
            size,
            size,
            &SynthParams {
                patch,
                ..Default::default()
            },
        )
        .unwrap();
        let m = Some(&d.extra_masks[k]);
        let truth = &d.extra_truth[k];
        println!(
            "view {k} ref {}: PSNR rough {:.2} guided {:.2} SSIM rough {:.3} guided {:.3} ({:?})",
            v.reference,
            psnr(&v.rough.image, truth, m).unwrap(),
            psnr(&v.guided, truth, m).unwrap(),
            ssim(&v.rough.image, truth, m).unwrap(),
            ssim(&v.guided, truth, m).unwrap(),
            t.elapsed()
        );
        let oracle = vt_fv::guided_synthesis(
            truth,
            &v.rough.image,
            &SynthParams {
                patch,
                ..Default::default()
            },
        )
        .unwrap();
        println!(
            "  oracle (input = truth): PSNR {:.2} SSIM {:.3}",
            psnr(&oracle, truth, m).unwrap(),
            ssim(&oracle, truth, m).unwrap()
        );
        for (pp, ms) in [(5, 20), (7, 0), (9, 20), (11, 20), (11, 0), (15, 20)] {
            let g = vt_fv::guided_synthesis(
                &d.photos[v.reference],
                &v.rough.image,
                &SynthParams {
                    patch: pp,
                    max_synth_iters: ms,
                    ..Default::default()
                },
            )
            .unwrap();
            println!(
                "  patch {pp} synth iters {ms}: PSNR {:.2} SSIM {:.3}",
                psnr(&g, truth, m).unwrap(),
                ssim(&g, truth, m).unwrap()
            );
        }
        let cam_near = &d.cameras[v.reference];
        let rr = vt_fv::render_rough(&model, cam_near, size, size);
        println!(
            "  rough at the reference camera: PSNR {:.2}",
            psnr(
                &rr.image,
                &d.photos[v.reference],
                Some(&d.masks[v.reference])
            )
            .unwrap()
        );
        v.rough.image.save(format!("{dir}/v{k}_rough.png")).unwrap();
        v.guided.save(format!("{dir}/v{k}_guided.png")).unwrap();
        truth.save(format!("{dir}/v{k}_truth.png")).unwrap();
        d.photos[v.reference]
            .save(format!("{dir}/v{k}_ref.png"))
            .unwrap();
    }
}

#[allow(dead_code)]
fn unused() {}
