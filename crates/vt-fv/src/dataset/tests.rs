use super::*;
use crate::pipeline::Scores;

#[test]
fn bounds_text_is_checked() {
    let b = parse_bounds("-1, 0,0.5, 1,2,3").unwrap();
    assert_eq!(<[f64; 3]>::from(b.min), [-1.0, 0.0, 0.5]);
    assert_eq!(<[f64; 3]>::from(b.max), [1.0, 2.0, 3.0]);
    for (text, says) in [
        ("1,2,3", "six finite numbers"),
        ("0,0,0,1,1,x", "\"x\" is not a number"),
        ("0,0,0,-1,1,1", "must exceed"),
        ("0,0,0,1e-300,1,1", "the x side is 1e-300 wide"),
    ] {
        let e = parse_bounds(text).unwrap_err();
        assert!(e.contains(says), "{text}: {e}");
    }
}

#[test]
fn intrinsics_fit_resized_and_cropped_photos() {
    let k = nalgebra::Matrix3::new(1000.0, 0.0, 639.5, 0.0, 1000.0, 479.5, 0.0, 0.0, 1.0);
    // Half size, pixel centres at integers: c' = s (c + 0.5) - 0.5 = 0.5 * 640 - 0.5.
    let h = fit_intrinsics(&k, (1280, 960), (640, 480), PhotoFit::Scale).unwrap();
    assert_eq!((h[(0, 0)], h[(0, 2)], h[(1, 2)]), (500.0, 319.5, 239.5));
    let c = fit_intrinsics(&k, (1280, 960), (1250, 936), PhotoFit::Crop).unwrap();
    assert_eq!((c[(0, 0)], c[(0, 2)], c[(1, 2)]), (1000.0, 624.5, 467.5));
    let e = fit_intrinsics(&k, (1280, 960), (640, 400), PhotoFit::Scale).unwrap_err();
    assert!(e.contains("not a uniform rescale"), "{e}");
    assert_eq!(
        fit_intrinsics(&k, (1280, 960), (1280, 960), PhotoFit::Scale).unwrap(),
        k
    );
}

#[test]
fn option_ranges_name_the_field() {
    let name = |e: crate::Error| match e {
        crate::Error::BadParam { name, .. } => name,
        e => panic!("{e}"),
    };
    let d = DataOptions::default();
    assert!(d.check().is_ok());
    let bad = DataOptions {
        scale: 0.0,
        ..d.clone()
    };
    assert_eq!(name(bad.check().unwrap_err()), "scale");
    let bad = DataOptions {
        carve_erode: 101,
        ..d.clone()
    };
    assert_eq!(name(bad.check().unwrap_err()), "carve_erode");
    let m = ModelParams::default();
    assert!(m.check().is_ok());
    for grid in [1, MAX_GRID + 1] {
        let bad = ModelParams { grid, ..m.clone() };
        assert_eq!(name(bad.check().unwrap_err()), "grid");
    }
    let bad = ModelParams {
        photo_threshold: f64::NAN,
        ..m
    };
    assert_eq!(name(bad.check().unwrap_err()), "photo_threshold");
}

#[test]
fn summary_means_are_over_the_views() {
    let s = |p: f64, q: f64| Scores {
        inside: Score { psnr: p, ssim: q },
        whole: Score {
            psnr: 0.0,
            ssim: 0.0,
        },
    };
    let report = |k: usize, p: f64| EvalReport {
        withheld: k,
        reference: 0,
        nearest_photo: s(p, 0.1),
        rough: s(p + 1.0, 0.2),
        rough_blur2: s(p + 2.0, 0.3),
        guide: s(p + 3.0, 0.4),
        guided: s(p + 4.0, 0.5),
        silhouette_iou: p / 100.0,
        surface_voxels: 1,
        times: vec![("scoring", 1.0)],
    };
    let cam = |n: &str| {
        Camera::new(
            n,
            nalgebra::Matrix3::identity(),
            nalgebra::Matrix3::identity(),
            nalgebra::Vector3::zeros(),
        )
        .unwrap()
    };
    let cams = [cam("a.png"), cam("b.png")];
    let e = EvalSummary::new("textured", &[report(0, 10.0), report(1, 20.0)], &cams);
    assert_eq!(e.nearest_photo.psnr, 15.0);
    assert_eq!(e.guided.psnr, 19.0);
    assert!((e.guided.ssim - 0.5).abs() < 1e-12);
    assert!((e.silhouette_iou - 0.15).abs() < 1e-12);
    assert_eq!(e.views[1].name, "b.png");
    assert_eq!(e.views[1].rough.psnr, 21.0);
    assert_eq!(e.views[0].total_secs, 1.0);
}
