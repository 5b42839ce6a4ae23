//! Diagnostic: the exact (image-based) visual hull's coverage of each test view, rays marched
//! at a quarter voxel against the photos' silhouettes, against the test silhouettes (IoU), beside
//! the default render's coverage.
//! `cargo run --release -p vt-fv --example ibvh_diag -- DATA TESTFILE`
use std::path::Path;

use rayon::prelude::*;
use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::{iou, novel_view_in, ViewParams};
use vt_fv::Mask;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = Path::new(&args[1]);
    let train = Dataset::load(dir, &DataOptions::default()).unwrap();
    let test = Dataset::load_set(&dir.join(&args[2]), &DataOptions::default()).unwrap();
    let (model, _) = train
        .build_without(None, &ModelParams::default(), &mut |_, _, _| {})
        .unwrap();
    let bounds = model.grid.bounds();
    let vs = model.grid.voxel_size();
    let step = vs.x.min(vs.y).min(vs.z) / 4.0;
    let inside = |x: &nalgebra::Vector3<f64>| {
        train
            .cams
            .iter()
            .zip(&train.masks)
            .all(|(c, m)| match c.project(x) {
                Some((u, v, _))
                    if u > -0.5
                        && v > -0.5
                        && u < m.width() as f64 - 0.5
                        && v < m.height() as f64 - 0.5 =>
                {
                    m.get((u + 0.5) as u32, (v + 0.5) as u32)
                }
                _ => true,
            })
    };
    let (mut s_ib, mut s_r) = (0.0, 0.0);
    for (i, cam) in test.cams.iter().enumerate() {
        let (w, h) = test.images[i].dimensions();
        let o = cam.centre();
        let cov: Vec<bool> = (0..(w * h) as usize)
            .into_par_iter()
            .map(|k| {
                let d = cam.ray((k % w as usize) as f64, (k / w as usize) as f64);
                let Some((t0, t1)) = bounds.ray_span(&o, &d) else {
                    return false;
                };
                let mut t = t0;
                while t <= t1 {
                    if inside(&(o + d * t)) {
                        return true;
                    }
                    t += step;
                }
                false
            })
            .collect();
        let ib = Mask::from_fn(w, h, |x, y| cov[(y * w + x) as usize]);
        let v = novel_view_in(
            &model,
            &train.cams,
            &train.images,
            Some(&train.masks),
            cam,
            w,
            h,
            &ViewParams::default(),
        )
        .unwrap();
        let (a, b) = (
            iou(&ib, &test.score_masks[i]),
            iou(&v.rough.coverage, &test.score_masks[i]),
        );
        s_ib += a;
        s_r += b;
        println!(
            "{:>16}: exact visual hull IoU {a:.3}, render {b:.3}",
            cam.name
        );
    }
    let n = test.cams.len() as f64;
    println!(
        "mean: exact visual hull {:.3}, render {:.3}",
        s_ib / n,
        s_r / n
    );
}
