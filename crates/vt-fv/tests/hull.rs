//! Visual hull on the synthetic object: containment, volume, agreement with naive carving, and
//! bad-input errors.

use nalgebra::Vector3;
use vt_fv::hull::{visual_hull, visual_hull_naive, Aabb, HullParams};
use vt_fv::{Camera, Error, Mask};
use vt_synth::object::{generate, SceneParams};

fn small() -> vt_synth::object::SynthData<Camera> {
    generate(&SceneParams {
        width: 160,
        height: 160,
        extra_angles_deg: vec![],
        supersample: 1,
        ..Default::default()
    })
    .unwrap()
    .try_map_cameras(|c| Camera::new(c.name.clone(), c.k, c.r, c.t))
    .unwrap()
}

#[test]
fn hull_contains_true_surface_and_volume_is_close() {
    let d = small();
    let params = HullParams {
        dims: [96; 3],
        ..Default::default()
    };
    let g = visual_hull(&d.cameras, &d.masks, &params).unwrap();
    let b = g.bounds();
    let tb = d.object.bounds();
    // Automatic bounds hold the object and are not much larger.
    for a in 0..3 {
        assert!(
            b.min[a] <= tb.min[a] && b.max[a] >= tb.max[a],
            "bounds {b:?} miss object {tb:?}"
        );
        assert!(
            b.max[a] - b.min[a] < 1.6 * (tb.max[a] - tb.min[a]),
            "bounds {b:?} loose around {tb:?}"
        );
    }
    let outside: Vec<_> = d
        .object
        .surface_samples(5000, 7)
        .into_iter()
        .filter(|p| !g.contains_point_within(p, 1))
        .collect();
    assert!(
        outside.is_empty(),
        "{} of 5000 surface points outside the hull, e.g. {:?}",
        outside.len(),
        outside.first()
    );
    let truth = d.object.volume(200);
    let ratio = g.volume() / truth;
    // A hull from 8 ring views is larger than the object, but not by more than a factor 1.6.
    assert!(
        (0.97..1.6).contains(&ratio),
        "hull volume {} vs true {truth}: ratio {ratio}",
        g.volume()
    );
}

#[test]
fn block_carving_equals_naive_carving() {
    let d = small();
    let bounds = d.object.bounds();
    let pad = Vector3::repeat(0.1);
    let bounds = Aabb::new(bounds.min - pad, bounds.max + pad);
    for dims in [[40, 33, 17], [64, 64, 64]] {
        let fast = visual_hull(
            &d.cameras,
            &d.masks,
            &HullParams {
                dims,
                bounds: Some(bounds),
                ..Default::default()
            },
        )
        .unwrap();
        let slow = visual_hull_naive(&d.cameras, &d.masks, bounds, dims, 1).unwrap();
        assert_eq!(fast.count(), slow.count(), "dims {dims:?}");
        assert!(
            fast == slow,
            "dims {dims:?}: block carving differs from per-voxel carving"
        );
    }
}

#[test]
fn bad_inputs_are_refused() {
    let d = small();
    let mut masks = d.masks.clone();
    masks[3] = Mask::new(160, 160);
    let e = visual_hull(&d.cameras, &masks, &HullParams::default()).unwrap_err();
    assert!(matches!(e, Error::EmptySilhouette { index: 3, .. }), "{e}");

    // A camera looking away from the object.
    let mut cams = d.cameras.clone();
    cams[2] = Camera::look_at(
        "away",
        cams[2].k,
        cams[2].centre(),
        cams[2].centre() * 2.0,
        -Vector3::z(),
    )
    .unwrap();
    let params = HullParams {
        dims: [32; 3],
        bounds: Some(Aabb::new(d.object.bounds().min, d.object.bounds().max)),
        ..Default::default()
    };
    let e = visual_hull(&cams, &d.masks, &params).unwrap_err();
    assert!(
        matches!(e, Error::CameraSeesNoVolume { index: 2, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("away"), "{e}");

    // 100000^3 voxels are refused before any allocation.
    let e = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [100_000; 3],
            ..Default::default()
        },
    )
    .unwrap_err();
    match e {
        Error::GridTooLarge {
            nx: 100_000,
            bytes,
            limit,
            ..
        } => assert!(bytes > limit),
        other => panic!("expected GridTooLarge, got {other}"),
    }
    let e = visual_hull(
        &d.cameras,
        &d.masks,
        &HullParams {
            dims: [usize::MAX / 2, 4, 4],
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            Error::GridTooLarge {
                bytes: u64::MAX,
                ..
            }
        ),
        "{e}"
    );
    let e = visual_hull(&d.cameras[..3], &d.masks, &HullParams::default()).unwrap_err();
    assert!(matches!(e, Error::CountMismatch { .. }), "{e}");
}

#[test]
fn exact_silhouettes_agree_and_a_miscalibrated_camera_shows() {
    use vt_fv::render::{silhouette_misses, ClipParams, EXACT_MISSES};
    let d = small();
    let bounds = Aabb::new(d.object.bounds().min, d.object.bounds().max);
    // Ray-cast silhouettes of exact cameras: every rim ray meets the hull.
    let exact = silhouette_misses(&d.cameras, &d.masks, &bounds, 0, 2, 1);
    assert!(exact[0] <= EXACT_MISSES, "{exact:?}");
    let clip = ClipParams::default().for_silhouettes(&d.cameras, &d.masks, &bounds);
    assert_eq!((clip.close, clip.slack), (0, 0));
    // Every camera turned by 1.5 pixels' worth, alternately left and right (a calibration's
    // error): rim rays miss the hull until the slack covers the error; the clip keeps its
    // closing and slack.
    let cams: Vec<Camera> = d
        .cameras
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let turn = if i % 2 == 0 { 1.5 } else { -1.5 } / c.k[(0, 0)];
            let r = *nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), turn).matrix();
            Camera::new("turned", c.k, r * c.r, r * c.t).unwrap()
        })
        .collect();
    let off = silhouette_misses(&cams, &d.masks, &bounds, 0, 2, 1);
    assert!(off[0] > 10.0 * EXACT_MISSES, "{off:?}");
    assert!(off[0] > off[1] && off[1] >= off[2], "{off:?}");
    let clip = ClipParams::default().for_silhouettes(&cams, &d.masks, &bounds);
    assert_eq!(clip, ClipParams::default());
    // Without the check, the clip is never changed.
    let never = ClipParams {
        exact: false,
        ..Default::default()
    };
    assert_eq!(never.for_silhouettes(&d.cameras, &d.masks, &bounds), never);
}

#[test]
fn ray_spans_through_a_box() {
    let b = Aabb::new(Vector3::new(-1.0, -1.0, -1.0), Vector3::new(1.0, 1.0, 1.0));
    let o = Vector3::new(-5.0, 0.0, 0.0);
    // Along x through the middle: enters at 4, leaves at 6.
    let (t0, t1) = b.ray_span(&o, &Vector3::x()).unwrap();
    assert!(
        (t0 - 4.0).abs() < 1e-12 && (t1 - 6.0).abs() < 1e-12,
        "{t0} {t1}"
    );
    // Parallel to a face outside the box, and pointing away: none.
    assert_eq!(
        b.ray_span(&Vector3::new(0.0, 2.0, 0.0), &Vector3::x()),
        None
    );
    assert_eq!(b.ray_span(&o, &-Vector3::x()), None);
    // From inside: from 0 to the exit.
    let (t0, t1) = b
        .ray_span(&Vector3::zeros(), &Vector3::new(0.0, 0.0, 2.0))
        .unwrap();
    assert!(t0 == 0.0 && (t1 - 0.5).abs() < 1e-12, "{t0} {t1}");
    // A diagonal ray meets the corner region: entry before exit, both on the box.
    let d = Vector3::new(1.0, 1.0, 1.0).normalize();
    let (t0, t1) = b.ray_span(&Vector3::new(-3.0, -3.0, -3.0), &d).unwrap();
    for t in [t0, t1] {
        let p = Vector3::new(-3.0, -3.0, -3.0) + d * t;
        assert!(p.iter().all(|v| v.abs() <= 1.0 + 1e-9), "{p:?}");
    }
}
