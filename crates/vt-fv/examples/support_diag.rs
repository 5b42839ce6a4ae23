//! Diagnostic: per test view, the covered pixels of the new view by how many photos' confirmed
//! depths put its surface point on a surface (within TOL voxels), and the share of each group
//! inside the test silhouette.
//! The unsupported pixels (no photo's depth on their surface) are then split by what the
//! photos' depths say of their surface point: some photo sees past it (a depth more than TOL
//! voxels deeper: free space a carving missed), every photo with a depth there sees a nearer
//! surface (hidden), or no photo has a depth there.
//! Last, on object pixels, the two nearest photos' depth less the point's depth there: where
//! the rendered surface lies against the photos' own.
//! `cargo run --release -p vt-fv --example support_diag -- DATA TESTFILE [TOL [key=value,...]]`
//! (keys: `common/settings.rs`'s).
use std::path::Path;

use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::{novel_view_in, ViewParams};

#[path = "common/settings.rs"]
mod settings;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = Path::new(&args[1]);
    let tol: f64 = args.get(3).map_or(1.5, |v| v.parse().unwrap());
    let train = Dataset::load(dir, &DataOptions::default()).unwrap();
    let test = Dataset::load_set(&dir.join(&args[2]), &DataOptions::default()).unwrap();
    let mut view = ViewParams::default();
    let mut m = ModelParams::default();
    settings::apply(args.get(4).map_or("", |s| s.as_str()), &mut view, &mut m);
    let (model, _) = train.build_without(None, &m, &mut |_, _, _| {}).unwrap();
    let vs = model.grid.voxel_size().min();
    let centre = vt_fv::texture::model_centre(&model);
    // On object pixels: the two nearest photos' depth less the point's depth there, in voxels.
    let mut signed: Vec<f64> = Vec::new();
    let mut total = [[0usize; 2]; 5];
    // Unsupported pixels: [seen past, hidden, no depth] x [outside, inside].
    let mut unsupported = [[0usize; 2]; 3];
    for (i, cam) in test.cams.iter().enumerate() {
        let (w, h) = test.images[i].dimensions();
        let v = novel_view_in(
            &model,
            &train.cams,
            &train.images,
            Some(&train.masks),
            cam,
            w,
            h,
            &view,
        )
        .unwrap();
        let kinv = cam.k.try_inverse().unwrap();
        let a = cam.r.transpose() * kinv;
        let c = cam.centre();
        let sil = &test.score_masks[i];
        let near = vt_fv::texture::nearest_by_direction(&train.cams, cam, &centre, 2);
        let mut counts = [[0usize; 2]; 5];
        if let Ok(d) = std::env::var("SAVE") {
            // Grey: truth and coverage agree; red: covered, not object; blue: object, uncovered.
            let img = image::RgbImage::from_fn(w, h, |x, y| {
                let c = v.rough.coverage.get(x, y);
                let t = sil.get(x, y);
                image::Rgb(match (c, t) {
                    (true, true) => [128, 128, 128],
                    (true, false) => [255, 0, 0],
                    (false, true) => [0, 0, 255],
                    _ => [255, 255, 255],
                })
            });
            img.save(Path::new(&d).join(format!("cov_{i:03}.png")))
                .unwrap();
        }
        for y in 0..h {
            for x in 0..w {
                let d = v.rough.depth[(y * w + x) as usize] as f64;
                if !d.is_finite() {
                    continue;
                }
                let p = c + a * nalgebra::Vector3::new(x as f64, y as f64, 1.0) * d;
                let mut s = 0;
                let (mut past, mut nearer) = (false, false);
                for (j, (pc, map)) in train.cams.iter().zip(&model.depths).enumerate() {
                    let q = pc.projection() * p.push(1.0);
                    if q.z <= 0.0 {
                        continue;
                    }
                    let dd = map.nearest(q.x / q.z, q.y / q.z) as f64;
                    if sil.get(x, y) && near.contains(&j) && dd.is_finite() {
                        signed.push((dd - q.z) / vs);
                    }
                    if dd.is_finite() && (dd - q.z).abs() <= tol * vs {
                        s += 1;
                    }
                    past |= dd.is_finite() && dd > q.z + tol * vs;
                    nearer |= dd.is_finite() && dd < q.z - tol * vs;
                }
                if s == 0 {
                    let class = if past {
                        0
                    } else if nearer {
                        1
                    } else {
                        2
                    };
                    unsupported[class][sil.get(x, y) as usize] += 1;
                }
                let k = s.min(4);
                counts[k][sil.get(x, y) as usize] += 1;
            }
        }
        println!("{:>14}: {}", cam.name, groups(&counts));
        for k in 0..5 {
            total[k][0] += counts[k][0];
            total[k][1] += counts[k][1];
        }
    }
    println!("{:>14}: {}", "all", groups(&total));
    println!(
        "covered: {} outside the silhouette, {} inside",
        total.iter().map(|c| c[0]).sum::<usize>(),
        total.iter().map(|c| c[1]).sum::<usize>()
    );
    for (name, c) in ["seen past", "hidden", "no depth"].iter().zip(&unsupported) {
        println!(
            "unsupported, {name:>9}: {} outside the silhouette, {} inside",
            c[0], c[1]
        );
    }
    signed.sort_by(f64::total_cmp);
    if !signed.is_empty() {
        let q = |f: f64| signed[((signed.len() - 1) as f64 * f) as usize];
        println!(
            "object pixels, the two nearest photos' depth less the point's (voxels): 10 % {:.2}, 25 % {:.2}, median {:.2}, 75 % {:.2}, 90 % {:.2}",
            q(0.1), q(0.25), q(0.5), q(0.75), q(0.9)
        );
    }
}

/// Each support group's pixel count and its share inside the test silhouette.
fn groups(counts: &[[usize; 2]; 5]) -> String {
    let line: Vec<String> = counts
        .iter()
        .map(|c| {
            let n = c[0] + c[1];
            format!("{n:>6} {:.2}", c[1] as f64 / n.max(1) as f64)
        })
        .collect();
    line.join(" | ")
}
