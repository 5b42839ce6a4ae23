//! Photo hull and rough render on the synthetic object.

use std::time::Instant;
use vt_fv::eval::psnr;
use vt_fv::hull::HullParams;
use vt_fv::{build_model, render_rough, Camera, PhotoParams};
use vt_synth::object::{generate, SceneParams};

#[test]
fn photo_hull_is_tighter_and_renders_close_to_truth() {
    let d = generate(&SceneParams {
        width: 128,
        height: 128,
        extra_angles_deg: vec![22.5],
        supersample: 2,
        ..Default::default()
    })
    .unwrap()
    .try_map_cameras(|c| Camera::new(c.name.clone(), c.k, c.r, c.t))
    .unwrap();
    let hull = HullParams {
        dims: [96; 3],
        ..Default::default()
    };
    let t = Instant::now();
    let vh = build_model(
        &d.cameras,
        &d.photos,
        &d.masks,
        &hull,
        &PhotoParams {
            max_passes: 0,
            ..Default::default()
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let t_vh = t.elapsed();
    let t = Instant::now();
    // The paper's carving rule: on this object, keeping every silhouette pixel covered (the
    // default) keeps the render at the visual hull's (21.01 vs 21.06 dB measured), while
    // carving freely gains; the temple needs the default (see the README).
    let ph = build_model(
        &d.cameras,
        &d.photos,
        &d.masks,
        &hull,
        &PhotoParams {
            keep_silhouettes: false,
            ..Default::default()
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let t_ph = t.elapsed();
    let truth = d.object.volume(200);
    eprintln!(
        "visual hull {} voxels ({:.3} of truth, {t_vh:?}); photo hull {} voxels ({:.3}), {} passes, {} removed ({t_ph:?})",
        vh.grid.count(),
        vh.grid.volume() / truth,
        ph.grid.count(),
        ph.grid.volume() / truth,
        ph.passes,
        ph.removed
    );
    assert!(ph.removed > 0 && ph.grid.volume() < vh.grid.volume());
    assert!(
        ph.grid.volume() > 0.9 * truth,
        "photo hull carved into the object: {} vs {truth}",
        ph.grid.volume()
    );
    let cam = &d.extra_cameras[0];
    let r_vh = render_rough(&vh, cam, 128, 128);
    let r_ph = render_rough(&ph, cam, 128, 128);
    let p_vh = psnr(&r_vh.image, &d.extra_truth[0], Some(&d.extra_masks[0])).unwrap();
    let p_ph = psnr(&r_ph.image, &d.extra_truth[0], Some(&d.extra_masks[0])).unwrap();
    eprintln!("rough PSNR: visual hull {p_vh:.2} dB, photo hull {p_ph:.2} dB");
    assert!(
        p_ph > p_vh,
        "photo hull render {p_ph} should beat visual hull render {p_vh}"
    );
    let mut ply = Vec::new();
    ph.to_ply(&mut ply).unwrap();
    let text = String::from_utf8(ply).unwrap();
    assert!(text.starts_with("ply\n") && text.lines().count() == ph.surface.len() + 11);
}
