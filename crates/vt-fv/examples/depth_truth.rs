//! Diagnostic: the photos' depth maps (the model's, after confirmation) against a proxy truth,
//! the first surface along each cell's ray in a model built from another folder of the same
//! scene (e.g. all 100 lego training views): per photo the cells inside the silhouette, the
//! share with a depth, and of those the share within 1 and 3 voxels of the truth, too deep and
//! too shallow.
//! `cargo run --release -p vt-fv --example depth_truth -- DATA TRUTH_DATA [TRUTH_GRID]`; the
//! truth's model at TRUTH_GRID (256) without stereo unless `TRUTH_STEREO` is set, photo
//! threshold `TRUTH_PTHR` (15; 255 leaves the visual hull).
use std::path::Path;

use vt_fv::dataset::{DataOptions, Dataset, ModelParams};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let data = Dataset::load(Path::new(&args[1]), &DataOptions::default()).unwrap();
    let truth_data = Dataset::load(Path::new(&args[2]), &DataOptions::default()).unwrap();
    let tgrid: usize = args.get(3).map_or(256, |g| g.parse().unwrap());
    let m = ModelParams::default();
    let (model, _) = data.build_without(None, &m, &mut |_, _, _| {}).unwrap();
    let bounds = model.grid.bounds();
    let tm = ModelParams {
        grid: tgrid,
        bounds: Some(bounds),
        stereo: std::env::var("TRUTH_STEREO").is_ok(),
        photo_threshold: std::env::var("TRUTH_PTHR").map_or(15.0, |t| t.parse().unwrap()),
        ..ModelParams::default()
    };
    let (truth, _) = truth_data
        .build_without(None, &tm, &mut |_, _, _| {})
        .unwrap();
    let vs = model.grid.voxel_size().min();
    let tvs = truth.grid.voxel_size().min();
    println!("voxel {vs:.4} (truth {tvs:.4})");
    let mut all = [0usize; 6];
    for (i, (cam, dm)) in data.cams.iter().zip(&model.depths).enumerate() {
        let mut c = [0usize; 6]; // cells in silhouette, with depth, within 1, within 3, too deep, too shallow
        let mask = &data.masks[i];
        for y in 0..dm.h {
            for x in 0..dm.w {
                let (u, v) = ((x * dm.step) as f64, (y * dm.step) as f64);
                if !mask.get(u as u32, v as u32) {
                    continue;
                }
                // Truth: first occupied voxel along the ray.
                let o = cam.centre();
                let d = cam.ray(u, v);
                let Some((t0, t1)) = truth.grid.bounds().ray_span(&o, &d) else {
                    continue;
                };
                let mut t = t0.max(0.0);
                let mut hit = None;
                while t < t1 {
                    let p = o + d * t;
                    if let Some(vx) = truth.grid.voxel_of(&p) {
                        if truth.grid.get(vx[0] as i64, vx[1] as i64, vx[2] as i64) {
                            hit = Some(p);
                            break;
                        }
                    }
                    t += 0.25 * tvs;
                }
                let Some(p) = hit else { continue };
                c[0] += 1;
                let z_true = cam.project(&p).unwrap().2;
                let z = dm.depth[y * dm.w + x];
                if !z.is_finite() {
                    continue;
                }
                c[1] += 1;
                let e = (z as f64 - z_true) / vs;
                if e.abs() <= 1.0 {
                    c[2] += 1;
                }
                if e.abs() <= 3.0 {
                    c[3] += 1;
                }
                if e > 3.0 {
                    c[4] += 1;
                }
                if e < -3.0 {
                    c[5] += 1;
                }
            }
        }
        for (a, b) in all.iter_mut().zip(c) {
            *a += b;
        }
        print_row(&data.cams[i].name, &c);
    }
    print_row("all", &all);
}

fn print_row(name: &str, c: &[usize; 6]) {
    let s = |k: usize| 100.0 * c[k] as f64 / c[1].max(1) as f64;
    println!(
        "{name:>16}: {} cells, {:.1}% with depth; of those {:.1}% within 1 voxel, {:.1}% within 3, {:.1}% too deep, {:.1}% too shallow",
        c[0],
        100.0 * c[1] as f64 / c[0].max(1) as f64,
        s(2),
        s(3),
        s(4),
        s(5)
    );
}
