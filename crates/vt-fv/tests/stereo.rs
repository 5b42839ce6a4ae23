//! Stereo carving against the synthetic object's exact geometry (vt-synth's ray casting and
//! inside test, independent of vt-fv): the depth maps lie on the true surface, the carving
//! removes hull volume that is not the object and almost none that is, and a photo set without
//! texture measures nothing and carves nothing.

use nalgebra::Vector3;
use vt_fv::hull::{visual_hull, HullParams};
use vt_fv::stereo::{carve_by_stereo, depth_maps, StereoParams};
use vt_fv::{Camera, VoxelGrid};
use vt_synth::object::{generate, RingParams, SynthData};

/// `vt synth object`'s ring (8 views, seed 0) at 200x200, and its visual hull at 96^3.
fn scene() -> (SynthData<Camera>, VoxelGrid) {
    ring(8)
}

/// `vt synth object`'s ring of `views` views (seed 0) at `size` x `size`.
fn photos(views: usize, size: u32) -> SynthData<Camera> {
    let ring = RingParams {
        views,
        size,
        seed: 0,
    };
    generate(&ring.scene())
        .unwrap()
        .try_map_cameras(|c| Camera::new(c.name.clone(), c.k, c.r, c.t))
        .unwrap()
}

/// The default model (stereo carving on) of `d` at `grid` voxels along the longest side.
fn model(d: &SynthData<Camera>, grid: usize) -> vt_fv::VoxelModel {
    use vt_fv::dataset::{build_summarised, volume, ModelParams};
    let m = ModelParams {
        grid,
        ..Default::default()
    };
    let bounds = volume(None, &d.cameras, &d.masks).unwrap();
    let (model, _) = build_summarised(
        &d.cameras,
        &d.photos,
        &d.masks,
        bounds,
        &m,
        &mut |_, _, _| {},
    )
    .unwrap();
    assert_eq!(model.depths.len(), d.cameras.len());
    model
}

/// The ring of `views` views (seed 0) at 200x200, and its visual hull at 96^3.
fn ring(views: usize) -> (SynthData<Camera>, VoxelGrid) {
    let d = photos(views, 200);
    let vh = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [96; 3],
            ..Default::default()
        },
    )
    .unwrap();
    (d, vh)
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Each confirmed depth's error against the ray-cast truth, in voxels (positive: too deep), the
/// sweep's summary, and the share of the silhouette's cells (one every `step` pixels each way)
/// confirmed.
fn depth_errors(p: &StereoParams) -> (Vec<f64>, vt_fv::stereo::StereoSummary, f64) {
    let (d, vh) = scene();
    let (maps, summary) = depth_maps(&vh, &d.cameras, &d.photos, &d.masks, p).unwrap();
    let vs = vh.voxel_size().min();
    let mut errors = Vec::new();
    for (cam, m) in d.cameras.iter().zip(&maps) {
        let kinv = cam.k.try_inverse().unwrap();
        for y in 0..m.h {
            for x in 0..m.w {
                let depth = m.depth[y * m.w + x];
                if !depth.is_finite() {
                    continue;
                }
                let (u, v) = ((x * m.step) as f64, (y * m.step) as f64);
                // The true depth along the pixel's ray: vt-synth's ray cast, turned into camera
                // depth by the ray's own z (the ray's z component is 1 before rotation).
                let dir = cam.r.transpose() * (kinv * Vector3::new(u, v, 1.0));
                let t = d
                    .object
                    .intersect(&cam.centre(), &dir.normalize())
                    .expect("a silhouette pixel's ray hits the object");
                errors.push((depth as f64 - t / dir.norm()) / vs);
            }
        }
    }
    assert_eq!(summary.confirmed, errors.len());
    assert!(summary.confirmed <= summary.matched && summary.matched <= summary.silhouette);
    let step = maps[0].step as f64;
    let share = summary.confirmed as f64 / (summary.silhouette as f64 / (step * step));
    (errors, summary, share)
}

#[test]
fn depth_maps_lie_on_the_true_surface() {
    // The sweep: most silhouette cells (one every 2 pixels) get a depth, half within a voxel and
    // a half.
    let sweep = StereoParams {
        patchmatch: 0,
        ..Default::default()
    };
    let (errors, s, share) = depth_errors(&sweep);
    let mut abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
    let median = percentile(&mut abs, 0.5);
    assert!(share > 0.4, "confirmed {share:.2} of the silhouette cells");
    assert!(median < 1.5, "median depth error {median:.2} voxels");
    // The texture repeats (sines, a checker): some matches land a period away. Asking for a
    // distinct best depth drops them: the tail goes from tens of voxels to a few.
    let (strict, s2, _) = depth_errors(&StereoParams {
        distinct: 0.2,
        ..sweep
    });
    let mut abs2: Vec<f64> = strict.iter().map(|e| e.abs()).collect();
    let (m2, p90) = (percentile(&mut abs2, 0.5), percentile(&mut abs2, 0.9));
    let p90_default = percentile(&mut abs, 0.9);
    assert!(s2.confirmed > 200 && s2.confirmed < s.confirmed);
    assert!(
        m2 < 1.0 && p90 < 3.0 && p90 < p90_default / 2.0,
        "distinct 0.2: median {m2:.2}, 90th percentile {p90:.2} (default's {p90_default:.2})"
    );
}

#[test]
fn carving_removes_what_is_not_the_object_and_keeps_what_is() {
    let (d, vh) = scene();
    let vs = vh.voxel_size().min();
    // A voxel is surely object when a ball of half a voxel diagonal around its centre is inside;
    // surely not when the same ball is outside (both tested on the ball's 6 extreme points and
    // the centre, enough at this scale).
    let probe = |c: Vector3<f64>, inside: bool| {
        let r = 0.87 * vs;
        std::iter::once(c)
            .chain((0..3).flat_map(|k| {
                let mut e = Vector3::zeros();
                e[k] = r;
                [c + e, c - e]
            }))
            .all(|p| d.object.contains(&p) == inside)
    };
    // (surely object, surely empty, on the surface: the ball straddles it).
    let classify = |g: &VoxelGrid| {
        let (mut object, mut empty, mut surface) = (0usize, 0usize, 0usize);
        for i in g.occupied() {
            let c = g.centre(g.coords(i));
            let (inside, outside) = (probe(c, true), probe(c, false));
            object += inside as usize;
            empty += outside as usize;
            surface += (!inside && !outside) as usize;
        }
        (object, empty, surface)
    };
    let (object_before, empty_before, surface_before) = classify(&vh);
    assert!(
        empty_before > 1000,
        "the 8-view hull is fat: {empty_before} empty voxels"
    );
    let carve = |p: &StereoParams| {
        let mut g = vh.clone();
        let (_, s) = carve_by_stereo(&mut g, &d.cameras, &d.photos, &d.masks, p).unwrap();
        assert_eq!(s.carved + s.unseen, vh.count() - g.count());
        let (o, e, sf) = classify(&g);
        (
            1.0 - o as f64 / object_before as f64,
            1.0 - e as f64 / empty_before as f64,
            1.0 - sf as f64 / surface_before as f64,
        )
    };
    let lines = |what: &str, (object, empty, surface): (f64, f64, f64)| {
        format!(
            "{what}: carved {:.2} % of the object, {:.2} % of its surface, {:.1} % of the hull's empty voxels",
            100.0 * object,
            100.0 * surface,
            100.0 * empty
        )
    };
    // Free space alone (no unseen carving): much of the empty hull, a sliver of the object
    // where a repeated pattern matched a period too deep.
    let free = carve(&StereoParams {
        unseen_keep: None,
        ..Default::default()
    });
    let free_sweep = carve(&StereoParams {
        unseen_keep: None,
        patchmatch: 0,
        ..Default::default()
    });
    eprintln!(
        "{}\n{}",
        lines("free space", free),
        lines("free space, sweep", free_sweep)
    );
    assert!(
        free.0 < 0.04 && free.1 > 0.15,
        "{}",
        lines("free space", free)
    );
    // PatchMatch's planes against the sweep's fronto-parallel windows: more of the empty hull,
    // less of the object (measured: 1.46 % against 2.76 % of the object, 8.0 % against 10.4 %
    // of its surface, 30.9 % against 19.0 % of the empty voxels; with the maps at every second
    // pixel, without the fine iterations, 0.86 %, 5.0 % and 23.7 %: a map at every pixel
    // carves closer to the surface, both ways).
    assert!(
        free.0 < free_sweep.0 * 0.6 && free.2 < free_sweep.2 * 0.85 && free.1 > free_sweep.1 + 0.05,
        "{}\n{}",
        lines("free space", free),
        lines("free space, sweep", free_sweep)
    );
    // The sweep with distinct depths only: nearly nothing of the object.
    let strict = carve(&StereoParams {
        unseen_keep: None,
        distinct: 0.2,
        patchmatch: 0,
        ..Default::default()
    });
    assert!(
        strict.0 < 0.002 && strict.0 < free.0,
        "{}",
        lines("distinct 0.2", strict)
    );
    // The default also drops what no photo sees beyond 3 voxels from what they see: much more
    // of the empty hull, the object's inside (never seen, never shown), and the part of its
    // surface that lies deeper than 3 voxels under phantom volume every photo sees first (on
    // this object, with free space carved only where its repeated texture lets stereo work,
    // about 40 % of the surface voxels). Measured here so that a change shows.
    let all = carve(&StereoParams::default());
    eprintln!(
        "{}\n{}\n{}",
        lines("free space", free),
        lines("distinct 0.2", strict),
        lines("default", all)
    );
    assert!(
        all.1 > free.1 + 0.3 && all.2 < 0.45,
        "{}",
        lines("default", all)
    );
    // The last pass's carving in front of the depth maps' holes, filled from around them. A
    // filled cell holds the nearest depth around the hole, so it also keeps what lies behind
    // it: on this object it carves less of the surface (measured: 28.4 % against 30.0 %) and
    // a little less of the empty hull (78.0 % against 80.2 %).
    let unfilled = carve(&StereoParams {
        hole_fill: 0,
        ..Default::default()
    });
    eprintln!(
        "{}\n{}",
        lines("default", all),
        lines("no hole filling", unfilled)
    );
    assert!(
        all.2 < unfilled.2 && all.1 > unfilled.1 - 0.05,
        "{}\n{}",
        lines("default", all),
        lines("no hole filling", unfilled)
    );
}

#[test]
fn photos_without_texture_measure_nothing_and_carve_nothing() {
    let (d, vh) = scene();
    let flat: Vec<image::RgbImage> = d
        .photos
        .iter()
        .map(|p| image::RgbImage::from_pixel(p.width(), p.height(), image::Rgb([180, 90, 40])))
        .collect();
    let mut g = vh.clone();
    let p = StereoParams {
        unseen_keep: None,
        ..Default::default()
    };
    let (_, s) = carve_by_stereo(&mut g, &d.cameras, &flat, &d.masks, &p).unwrap();
    assert_eq!((s.matched, s.confirmed, s.carved), (0, 0, 0));
    assert_eq!(g.count(), vh.count());
}

#[test]
fn settings_out_of_range_are_refused_by_name() {
    let (d, vh) = scene();
    for (p, name) in [
        (
            StereoParams {
                best: 5,
                sources: 4,
                ..Default::default()
            },
            "stereo_best",
        ),
        (
            StereoParams {
                radius: 0,
                ..Default::default()
            },
            "stereo_radius",
        ),
        (
            StereoParams {
                step: f64::NAN,
                ..Default::default()
            },
            "stereo_step",
        ),
        (
            StereoParams {
                margin: -1.0,
                ..Default::default()
            },
            "stereo_margin",
        ),
        (
            StereoParams {
                pixel_step: 0,
                ..Default::default()
            },
            "stereo_coarse",
        ),
        (
            StereoParams {
                fine: 17,
                ..Default::default()
            },
            "stereo_fine",
        ),
        (
            StereoParams {
                hole_fill: 65,
                ..Default::default()
            },
            "stereo_hole_fill",
        ),
    ] {
        let e = depth_maps(&vh, &d.cameras, &d.photos, &d.masks, &p)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{e}");
    }
    let e = depth_maps(
        &vh,
        &d.cameras[..3],
        &d.photos,
        &d.masks,
        &StereoParams::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("cameras vs photos"), "{e}");
}

/// The geometry check, measured against vt-synth's analytic surface (two-way mean
/// distance in voxels, model to truth / truth to model) on 8 and 36 views at 96^3. Known gap,
/// guarded here so that it can only shrink: on this object's repeating texture vt's default model
/// (stereo carving, then the photo hull) lies farther from the truth than the visual hull
/// (measured: 8 views 2.02 / 2.01 against 1.72 / 1.59; 36 views 2.07 / 1.84 against 1.46 /
/// 1.41; without `protect` 2.26 / 2.09 and 3.04 / 2.15), while on the real photos (lego,
/// temple, kettle) it scores better (the report). The photo hull alone is already off at 36
/// views (3.47 / 1.51): colour carving with many grazing views carves pits.
#[test]
fn default_model_distance_to_the_truth_is_guarded() {
    use vt_fv::dataset::ModelParams;
    for (views, bound) in [(8usize, [2.3, 2.3]), (36, [2.4, 2.1])] {
        let (d, vh) = ring(views);
        let vs = vh.voxel_size().min();
        let distance = |g: &VoxelGrid, surface: &[usize]| {
            let pts: Vec<Vector3<f64>> = surface.iter().map(|&i| g.centre(g.coords(i))).collect();
            d.object.compare_surface(&pts, vs, 50_000, 1).unwrap()
        };
        let vh_surface: Vec<usize> = vh
            .occupied()
            .into_iter()
            .filter(|&i| vh.is_surface(vh.coords(i)))
            .collect();
        let before = distance(&vh, &vh_surface);
        let photo = ModelParams::default().photo();
        assert!(photo.stereo.is_some(), "vt's models carve by stereo");
        let model = vt_fv::photo_hull_keeping(
            vh.clone(),
            &d.cameras,
            &d.photos,
            Some(&d.masks),
            &photo,
            &mut |_, _, _| {},
        )
        .unwrap();
        let surface: Vec<usize> = model.surface.iter().map(|v| v.index).collect();
        let after = distance(&model.grid, &surface);
        let line = format!(
            "{views} views: visual hull {:.2} / {:.2}, default model {:.2} / {:.2} voxels",
            before.to_truth.mean,
            before.from_truth.mean,
            after.to_truth.mean,
            after.from_truth.mean
        );
        eprintln!("{line}");
        assert!(
            after.to_truth.mean < bound[0] && after.from_truth.mean < bound[1],
            "{line}: beyond the guard {bound:?}"
        );
    }
}

/// Slanted planes (PatchMatch) against the fronto-parallel sweep on the same photos, hull and
/// acceptance: more cells confirmed, and their depths nearer the ray-cast truth, in the middle
/// and in the tail (the sweep's window smears across the object's curved, slanted sides; a
/// plane follows them).
#[test]
fn patchmatch_planes_lie_on_the_true_surface_closer_than_the_sweep() {
    let sweep = StereoParams {
        patchmatch: 0,
        ..Default::default()
    };
    let planes = StereoParams {
        patchmatch: 3,
        ..Default::default()
    };
    let stats = |p: &StereoParams| {
        let (errors, _, share) = depth_errors(p);
        let mut abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
        (share, percentile(&mut abs, 0.5), percentile(&mut abs, 0.9))
    };
    let (s0, m0, p0) = stats(&sweep);
    let (s1, m1, p1) = stats(&planes);
    let line = format!("sweep: confirmed {s0:.3}, median {m0:.2}, p90 {p0:.2} voxels; planes: confirmed {s1:.3}, median {m1:.2}, p90 {p1:.2}");
    eprintln!("{line}");
    // Measured: sweep 0.52, 1.24, 19.9; planes 0.86, 0.44, 2.7 with the fine iterations at every
    // pixel (0.84, 0.49, 3.4 at every second pixel; 0.63, 0.60, 5.6 without the geometric round
    // either).
    assert!(s1 > s0 + 0.05, "{line}");
    assert!(m1 < 0.8 && m1 < 0.7 * m0, "{line}");
    assert!(p1 < p0 / 2.0, "{line}");
}

/// The fine iterations measure every pixel, not every second one, and their depths lie on the
/// ray-cast truth as closely as the cells' they start from.
#[test]
fn fine_iterations_measure_every_pixel_as_closely_as_the_cells() {
    let stats = |p: &StereoParams| {
        let (errors, s, share) = depth_errors(p);
        let mut abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
        (
            s.confirmed,
            share,
            percentile(&mut abs, 0.5),
            percentile(&mut abs, 0.9),
        )
    };
    let cells = StereoParams {
        fine: 0,
        ..Default::default()
    };
    let (n0, s0, m0, p0) = stats(&cells);
    let (n1, s1, m1, p1) = stats(&StereoParams::default());
    let line = format!(
        "cells: {n0} confirmed ({s0:.3}), median {m0:.2}, p90 {p0:.2} voxels; \
         every pixel: {n1} ({s1:.3}), median {m1:.2}, p90 {p1:.2}"
    );
    eprintln!("{line}");
    assert!(n1 > 3 * n0 && s1 > s0 - 0.05, "{line}");
    assert!(m1 < m0 * 1.1 && p1 < p0 * 1.2, "{line}");
}

/// The view's clip to the depth maps' free space, on the synthetic object's extra viewpoints
/// (exact masks from vt-synth's ray casting): the coverage meets the true outline better, and
/// what the clip uncovers is mostly not the object.
#[test]
fn depth_clip_takes_back_coverage_that_is_not_the_object() {
    use vt_fv::pipeline::{iou, novel_view_in, ViewParams};
    let (d, _) = scene();
    let model = model(&d, 96);
    let (mut with, mut without, mut cut, mut cut_object) = (0.0, 0.0, 0usize, 0usize);
    for (cam, truth) in d.extra_cameras.iter().zip(&d.extra_masks) {
        let (w, h) = (truth.width(), truth.height());
        let view = |p: &ViewParams| {
            novel_view_in(&model, &d.cameras, &d.photos, Some(&d.masks), cam, w, h, p)
                .unwrap()
                .rough
                .coverage
        };
        let a = view(&ViewParams::default());
        let b = view(&ViewParams {
            depth_clip: None,
            ..Default::default()
        });
        with += iou(&a, truth);
        without += iou(&b, truth);
        for y in 0..h {
            for x in 0..w {
                if b.get(x, y) && !a.get(x, y) {
                    cut += 1;
                    cut_object += truth.get(x, y) as usize;
                }
            }
        }
    }
    let n = d.extra_cameras.len() as f64;
    let (with, without) = (with / n, without / n);
    let line = format!(
        "IoU with the depth clip {with:.4}, without {without:.4}; uncovered {cut} pixels, {cut_object} of them object"
    );
    eprintln!("{line}");
    assert!(with > without + 0.005 && cut > 500, "{line}");
    assert!((cut_object as f64) < 0.2 * cut as f64, "{line}");
}

/// Colour stereo ([`StereoParams::colour`]) sees texture that luma cannot: the object's
/// photos recoloured so that every pixel has the same luma and the texture lives in the chroma
/// alone. Luma measures next to nothing there; colour measures depths on the true surface.
#[test]
fn colour_windows_match_isoluminant_texture() {
    let (d, vh) = scene();
    // Along (0.587, -0.299, 0) the luma (0.299 R + 0.587 G + 0.114 B) does not change.
    let iso: Vec<image::RgbImage> = d
        .photos
        .iter()
        .map(|p| {
            image::RgbImage::from_fn(p.width(), p.height(), |x, y| {
                let q = p.get_pixel(x, y);
                let t = (0.299 * q[0] as f64 + 0.587 * q[1] as f64 + 0.114 * q[2] as f64) / 255.0;
                let s = 200.0 * (t - 0.5);
                image::Rgb([
                    (128.0 + 0.587 * s).round() as u8,
                    (128.0 - 0.299 * s).round() as u8,
                    128,
                ])
            })
        })
        .collect();
    let measure = |colour: bool| {
        let p = StereoParams {
            colour,
            ..Default::default()
        };
        let (maps, s) = depth_maps(&vh, &d.cameras, &iso, &d.masks, &p).unwrap();
        let vs = vh.voxel_size().min();
        let mut errors = Vec::new();
        for (cam, m) in d.cameras.iter().zip(&maps) {
            let kinv = cam.k.try_inverse().unwrap();
            for (i, &depth) in m.depth.iter().enumerate() {
                if !depth.is_finite() {
                    continue;
                }
                let (u, v) = (((i % m.w) * m.step) as f64, ((i / m.w) * m.step) as f64);
                let dir = cam.r.transpose() * (kinv * Vector3::new(u, v, 1.0));
                let t = d.object.intersect(&cam.centre(), &dir.normalize()).unwrap();
                errors.push((depth as f64 - t / dir.norm()).abs() / vs);
            }
        }
        let step = maps[0].step as f64;
        let share = s.confirmed as f64 / (s.silhouette as f64 / (step * step));
        let median = if errors.is_empty() {
            f64::NAN
        } else {
            percentile(&mut errors, 0.5)
        };
        (share, median)
    };
    let (luma, _) = measure(false);
    let (colour, median) = measure(true);
    let line =
        format!("confirmed: luma {luma:.3}, colour {colour:.3} (median error {median:.2} voxels)");
    eprintln!("{line}");
    assert!(luma < 0.05, "{line}");
    // Measured: luma 0.000, colour 0.586 with a median error of 0.49 voxels.
    assert!(colour > 0.45 && median < 1.0, "{line}");
}

/// The texturing's snapping to each photo's own depth map ([`vt_fv::texture::TextureParams::snap`],
/// which gains on the lego benchmark: the report's "benchmark" section) costs nothing on the
/// synthetic object at its report size (400x400, 8 views, grid 128): its new views against the
/// ray-cast truth, inside the truth's silhouette, score within 0.1 dB of the photos sampled at
/// the voxel surface or better. (At 200x200 on a 96^3 grid they scored 0.18 dB lower: the
/// voxels are finer against the photos there.)
#[test]
fn snapping_to_the_depth_maps_costs_nothing_against_the_truth() {
    use vt_fv::pipeline::{novel_view_in, ViewParams};
    let d = photos(8, 400);
    let model = model(&d, 128);
    let score = |snap: f64| {
        let mut p = ViewParams::default();
        p.texture.snap = snap;
        let mut sum = 0.0;
        for ((cam, truth), mask) in d
            .extra_cameras
            .iter()
            .zip(&d.extra_truth)
            .zip(&d.extra_masks)
        {
            let (w, h) = truth.dimensions();
            let v = novel_view_in(&model, &d.cameras, &d.photos, Some(&d.masks), cam, w, h, &p)
                .unwrap();
            sum += vt_fv::eval::psnr(&v.guided, truth, Some(mask)).unwrap();
        }
        sum / d.extra_cameras.len() as f64
    };
    let (with, without) = (score(8.0), score(0.0));
    let line =
        format!("inside the silhouette: snapped {with:.2} dB, at the voxel surface {without:.2}");
    eprintln!("{line}");
    assert!(with >= without - 0.1, "{line}");
}
