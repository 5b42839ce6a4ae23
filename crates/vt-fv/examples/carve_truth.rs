//! Photo hull against the synthetic object's true surface: the visual hull and photo hulls
//! with the given settings, each with its two-way surface distance (voxels), unseen surface
//! share and silhouette IoU at the truth viewpoints:
//!
//! ```sh
//! cargo run --release -p vt-fv --example carve_truth -- VIEWS SIZE GRID [name:key=value,...]...
//! ```
//!
//! Keys: `thr` (threshold), `keep` (0/1, keep silhouettes), `splat` (splat scale).

use std::time::Instant;

use vt_fv::hull::{visual_hull, HullParams};
use vt_fv::{photo_hull_keeping, render_rough, Camera, PhotoParams, VoxelGrid};
use vt_synth::object::{generate, RingParams};

fn iou(a: &vt_fv::Mask, b: &vt_fv::Mask) -> f64 {
    let (mut i, mut u) = (0u64, 0u64);
    for y in 0..a.height() as i64 {
        for x in 0..a.width() as i64 {
            let (p, q) = (a.get_or_false(x, y), b.get_or_false(x, y));
            i += (p && q) as u64;
            u += (p || q) as u64;
        }
    }
    i as f64 / u.max(1) as f64
}

fn surface_points(g: &VoxelGrid, idx: &[usize]) -> Vec<nalgebra::Vector3<f64>> {
    idx.iter().map(|&i| g.centre(g.coords(i))).collect()
}

/// Cameras from which the ray from the voxel centre to the camera centre leaves the grid
/// without crossing another occupied voxel (and whose image holds the centre).
fn ray_visible(g: &VoxelGrid, i: usize, cams: &[Camera], w: u32, h: u32) -> u32 {
    let vs = g.voxel_size();
    let step = 0.4 * vs.x.min(vs.y).min(vs.z);
    let c = g.centre(g.coords(i));
    let me = g.coords(i);
    let mut n = 0;
    for cam in cams {
        let Some((u, v, _)) = cam.project(&c) else {
            continue;
        };
        if u < -0.5 || v < -0.5 || u >= w as f64 - 0.5 || v >= h as f64 - 0.5 {
            continue;
        }
        let to = cam.centre() - c;
        let dir = to.normalize();
        let mut t = step;
        let mut blocked = false;
        loop {
            let p = c + dir * t;
            match g.voxel_of(&p) {
                None => break,
                Some(q) => {
                    if q != me && g.get(q[0] as i64, q[1] as i64, q[2] as i64) {
                        blocked = true;
                        break;
                    }
                }
            }
            t += step;
        }
        if !blocked {
            n += 1;
        }
    }
    n
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let views: usize = args[1].parse().unwrap();
    let size: u32 = args[2].parse().unwrap();
    let grid: usize = args[3].parse().unwrap();
    let ring = RingParams {
        views,
        size,
        seed: 0,
    };
    let d = generate(&ring.scene())
        .unwrap()
        .try_map_cameras(|c| Camera::new(c.name.clone(), c.k, c.r, c.t))
        .unwrap();
    let t = Instant::now();
    let vh = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [grid; 3],
            ..Default::default()
        },
    )
    .unwrap();
    let vh_secs = t.elapsed().as_secs_f64();
    let vs = vh.voxel_size();
    let unit = (vs.x * vs.y * vs.z).cbrt();
    let report = |name: &str, g: &VoxelGrid, surf: &[usize], unseen: usize, secs: f64| {
        let dist = d
            .object
            .compare_surface(&surface_points(g, surf), unit, 200_000, 1)
            .unwrap();
        println!(
            "{name:<28} to {:.2} ({:.2})  from {:.2} ({:.2})  two-way {:.2} ({:.2})  unseen {:.3} ({unseen}/{})  voxels {}  {secs:.1} s",
            dist.to_truth.mean,
            dist.to_truth.p90,
            dist.from_truth.mean,
            dist.from_truth.p90,
            dist.mean(),
            dist.p90(),
            unseen as f64 / surf.len() as f64,
            surf.len(),
            g.count()
        );
    };
    let vh_surf: Vec<usize> = vh
        .occupied()
        .into_iter()
        .filter(|&i| vh.is_surface(vh.coords(i)))
        .collect();
    report("visual hull", &vh, &vh_surf, 0, vh_secs);
    for spec in &args[4..] {
        let (name, kv) = spec.split_once(':').unwrap_or((spec, ""));
        let mut p = PhotoParams::default();
        for pair in kv.split(',').filter(|s| !s.is_empty()) {
            let (k, v) = pair.split_once('=').unwrap();
            match k {
                "thr" => p.threshold = v.parse().unwrap(),
                "keep" => p.keep_silhouettes = v == "1",
                "splat" => p.splat_scale = v.parse().unwrap(),
                "partly" => p.colour_partly_seen = v == "1",
                "agree" => p.consistency = vt_fv::Consistency::Agree(v.parse().unwrap()),
                "agreefrom" => {
                    let (a, b) = v.split_once('/').expect("share/min");
                    p.consistency = vt_fv::Consistency::AgreeFrom {
                        share: a.parse().unwrap(),
                        min: b.parse().unwrap(),
                    }
                }
                "share" => p.visibility = vt_fv::Visibility::Footprint(v.parse().unwrap()),
                _ => panic!("unknown key {k}"),
            }
        }
        let t = Instant::now();
        let m = photo_hull_keeping(
            vh.clone(),
            &d.cameras,
            &d.photos,
            Some(&d.masks),
            &p,
            &mut |_, _, _| {},
        )
        .unwrap();
        let secs = t.elapsed().as_secs_f64();
        let surf: Vec<usize> = m.surface.iter().map(|v| v.index).collect();
        let unseen = m.surface.iter().filter(|v| v.seen_by == 0).count();
        let (w0, h0) = d.photos[0].dimensions();
        let vis: Vec<u32> = {
            use rayon::prelude::*;
            m.surface
                .par_iter()
                .map(|v| ray_visible(&m.grid, v.index, &d.cameras, w0, h0))
                .collect()
        };
        let geo_unseen = vis.iter().filter(|&&n| n == 0).count();
        let both = m
            .surface
            .iter()
            .zip(&vis)
            .filter(|(v, &n)| v.seen_by == 0 && n > 0)
            .count();
        let seen_sum: u64 = m.surface.iter().map(|v| v.seen_by as u64).sum();
        let vis_sum: u64 = vis.iter().map(|&n| n as u64).sum();
        println!(
            "{:<28} ray-unseen {:.3}  id-unseen but ray-visible {:.3}  mean cams: id {:.2} ray {:.2}",
            "",
            geo_unseen as f64 / vis.len() as f64,
            both as f64 / vis.len() as f64,
            seen_sum as f64 / vis.len() as f64,
            vis_sum as f64 / vis.len() as f64
        );
        report(name, &m.grid, &surf, unseen, secs);
        let (w, h) = d.photos[0].dimensions();
        let mut io = 0.0;
        let mut ps = 0.0;
        for (k, cam) in d.extra_cameras.iter().enumerate() {
            let r = render_rough(&m, cam, w, h);
            io += iou(&r.coverage, &d.extra_masks[k]);
            ps += vt_fv::eval::psnr(&r.image, &d.extra_truth[k], Some(&d.extra_masks[k])).unwrap();
        }
        let n = d.extra_cameras.len() as f64;
        println!(
            "{:<28} IoU {:.4}  rough PSNR {:.2}  passes {} removed {}",
            "",
            io / n,
            ps / n,
            m.passes,
            m.removed
        );
    }
}
