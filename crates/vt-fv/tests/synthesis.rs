//! Guided synthesis against ground truth on the synthetic object.

use std::time::Instant;
use vt_fv::eval::{psnr, ssim};
use vt_fv::hull::HullParams;
use vt_fv::synth::{generate, SynthParams as SceneParams};
use vt_fv::{build_model, novel_view, PhotoParams, SynthParams};

#[test]
fn guided_synthesis_beats_rough_render_on_synthetic_object() {
    let d = generate(&SceneParams { width: 96, height: 96, extra_angles_deg: vec![10.0, 22.5], supersample: 2, ..Default::default() }).unwrap();
    let model = build_model(&d.cameras, &d.photos, &d.masks, &HullParams { dims: [96; 3], ..Default::default() }, &PhotoParams::default(), &mut |_, _, _| {}).unwrap();
    for (k, cam) in d.extra_cameras.iter().enumerate() {
        for p in [SynthParams { patch: 7, ..Default::default() }, SynthParams { patch: 7, levels: 2, step: 2, strips: 0, ..Default::default() }] {
            let t = Instant::now();
            let v = novel_view(&model, &d.cameras, &d.photos, cam, 96, 96, &p).unwrap();
            let secs = t.elapsed().as_secs_f64();
            let m = Some(&d.extra_masks[k]);
            let truth = &d.extra_truth[k];
            let (pr, pg) = (psnr(&v.rough.image, truth, m).unwrap(), psnr(&v.guided, truth, m).unwrap());
            let (sr, sg) = (ssim(&v.rough.image, truth, m).unwrap(), ssim(&v.guided, truth, m).unwrap());
            eprintln!("view {k} (ref {}), levels {} step {}: PSNR rough {pr:.2} guided {pg:.2}; SSIM rough {sr:.3} guided {sg:.3}; {secs:.2}s", v.reference, p.levels, p.step);
            assert!(pg > pr, "view {k}: guided PSNR {pg} <= rough {pr}");
        }
    }
}
