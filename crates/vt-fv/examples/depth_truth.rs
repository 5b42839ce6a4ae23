//! Diagnostic: the photos' depth maps (the model's, after confirmation) against a proxy truth,
//! the first surface along each cell's ray in a model built from another folder of the same
//! scene (e.g. all 100 lego training views): per photo the cells inside the silhouette, the
//! share with a depth, and of those the share within 1 and 3 voxels of the truth, too deep and
//! too shallow. The too shallow are classed further: on DATA's own visual hull's near side
//! (within 1 voxel of where the ray enters it), at an edge of the truth's depth (its depths at
//! the centre, corners and edge midpoints of the 7x7 window about the cell span more than 3
//! voxels, or one of those rays misses the truth; of those, how many take the truth's depth at
//! one of those points, within 1.5 voxels: a foreground's depth bled over the edge), or
//! neither.
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
    let hull_params = ModelParams {
        stereo: false,
        photo_threshold: 255.0,
        bounds: Some(bounds),
        ..ModelParams::default()
    };
    let (hull, _) = data
        .build_without(None, &hull_params, &mut |_, _, _| {})
        .unwrap();
    let vs = model.grid.voxel_size().min();
    let tvs = truth.grid.voxel_size().min();
    println!("voxel {vs:.4} (truth {tvs:.4})");
    let mut all = [0usize; 9];
    for (i, (cam, dm)) in data.cams.iter().zip(&model.depths).enumerate() {
        let mut c = [0usize; 9]; // cells in silhouette, with depth, within 1, within 3, too deep, too shallow, of those on the hull, at an edge, of those the truth 3 px away
        let mask = &data.masks[i];
        for y in 0..dm.h {
            for x in 0..dm.w {
                let (u, v) = ((x * dm.step) as f64, (y * dm.step) as f64);
                if !mask.get(u as u32, v as u32) {
                    continue;
                }
                let Some(z_true) = first_hit(&truth.grid, cam, u, v, 0.25 * tvs) else {
                    continue;
                };
                c[0] += 1;
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
                    let near = first_hit(&hull.grid, cam, u, v, 0.25 * vs);
                    let r = 3.0;
                    // The centre's truth is z_true; the eight points around it are marched.
                    let (mut lo, mut hi) = (z_true, z_true);
                    let mut neighbour = false;
                    for dy in [-r, 0.0, r] {
                        for dx in [-r, 0.0, r] {
                            if dx == 0.0 && dy == 0.0 {
                                continue;
                            }
                            if let Some(zt) =
                                first_hit(&truth.grid, cam, u + dx, v + dy, 0.25 * tvs)
                            {
                                lo = lo.min(zt);
                                hi = hi.max(zt);
                                neighbour |= (z as f64 - zt).abs() <= 1.5 * vs;
                            } else {
                                hi = f64::INFINITY;
                            }
                        }
                    }
                    if near.is_some_and(|n| (z as f64 - n).abs() <= vs) {
                        c[6] += 1;
                    } else if hi - lo > 3.0 * vs {
                        c[7] += 1;
                        if neighbour {
                            c[8] += 1;
                        }
                    }
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

/// Camera depth of the first occupied voxel along pixel `(u, v)`'s ray, marched in steps of
/// `dt`.
fn first_hit(
    grid: &vt_fv::hull::VoxelGrid,
    cam: &vt_fv::camera::Camera,
    u: f64,
    v: f64,
    dt: f64,
) -> Option<f64> {
    let o = cam.centre();
    let d = cam.ray(u, v);
    let (t0, t1) = grid.bounds().ray_span(&o, &d)?;
    let mut t = t0.max(0.0);
    while t < t1 {
        let p = o + d * t;
        if let Some(vx) = grid.voxel_of(&p) {
            if grid.get(vx[0] as i64, vx[1] as i64, vx[2] as i64) {
                return Some(cam.project(&p)?.2);
            }
        }
        t += dt;
    }
    None
}

fn print_row(name: &str, c: &[usize; 9]) {
    let s = |k: usize| 100.0 * c[k] as f64 / c[1].max(1) as f64;
    println!(
        "{name:>16}: {} cells, {:.1}% with depth; of those {:.1}% within 1 voxel, {:.1}% within 3, {:.1}% too deep, {:.1}% too shallow ({:.1}% on the hull's near side, {:.1}% at a depth edge, {:.1}% the truth 3 px away)",
        c[0],
        100.0 * c[1] as f64 / c[0].max(1) as f64,
        s(2),
        s(3),
        s(4),
        s(5),
        s(6),
        s(7),
        s(8)
    );
}
