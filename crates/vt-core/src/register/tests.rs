use super::*;
use nalgebra::Matrix3;

fn corner_error(a: &Homography, b: &Homography, w: f64, h: f64) -> f64 {
    [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|&(x, y)| {
            let p = Point::new(x, y);
            (a.apply(p).unwrap() - b.apply(p).unwrap()).norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn ransac_recovers_a_homography_through_40_percent_outliers() {
    let truth = Homography::from_matrix(Matrix3::new(
        0.97, 0.02, -14.0, -0.01, 1.01, 3.0, -4e-5, 2e-5, 1.0,
    ))
    .unwrap();
    let mut rng = crate::rng::Rng::new(3);
    let (mut src, mut dst, mut truly) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..300 {
        let p = Point::new(rng.f64() * 640.0, rng.f64() * 480.0);
        let inlier = i % 5 >= 2;
        let q = if inlier {
            let t = truth.apply(p).unwrap();
            Point::new(t.x + 0.3 * rng.normal(), t.y + 0.3 * rng.normal())
        } else {
            Point::new(rng.f64() * 640.0, rng.f64() * 480.0)
        };
        src.push(p);
        dst.push(q);
        truly.push(inlier);
    }
    let (h, flags) = ransac(&src, &dst, 3.0, 4000, 1).unwrap();
    assert!(corner_error(&h, &truth, 640.0, 480.0) < 0.5);
    let agree = flags.iter().zip(&truly).filter(|(a, b)| a == b).count();
    assert!(agree >= 295, "{agree} of 300 flags right");
    // Same seed, same answer.
    let (h2, _) = ransac(&src, &dst, 3.0, 4000, 1).unwrap();
    assert_eq!(h.matrix(), h2.matrix());
}

#[test]
fn four_points_give_the_exact_map_and_collinear_ones_none() {
    let truth = Matrix3::new(1.1, 0.1, 5.0, -0.05, 0.9, -3.0, 1e-4, -2e-4, 1.0);
    let h = Homography::from_matrix(truth).unwrap();
    let src = [
        Point::new(10.0, 20.0),
        Point::new(300.0, 40.0),
        Point::new(280.0, 200.0),
        Point::new(30.0, 220.0),
    ];
    let dst = src.map(|p| h.apply(p).unwrap());
    let m = four_point(
        [&src[0], &src[1], &src[2], &src[3]],
        [&dst[0], &dst[1], &dst[2], &dst[3]],
    )
    .unwrap();
    assert!((m / m[(2, 2)] - truth).abs().max() < 1e-9);
    let line = [0.0, 1.0, 2.0, 3.0].map(|t| Point::new(10.0 * t, 5.0 * t + 1.0));
    assert!(four_point(
        [&line[0], &line[1], &line[2], &line[3]],
        [&dst[0], &dst[1], &dst[2], &dst[3]]
    )
    .is_none());
}

#[test]
fn matches_are_mutual_and_pass_the_ratio_test() {
    let f = |bits: [u64; 4], x: f64| Feature {
        pos: Point::new(x, 0.0),
        angle: 0.0,
        level: 0,
        score: 1.0,
        descriptor: bits,
    };
    let a = vec![
        f([0, 0, 0, 0], 0.0),
        f([u64::MAX, 0, 0, 0], 1.0),
        f([0xFF, 0, 0, 0], 2.0),
    ];
    // b[0] matches a[0] exactly; b[1] is as close to a[0] as to a[2] (ratio test fails for
    // it); b[2] matches a[1] exactly.
    let b = vec![
        f([0, 0, 0, 0], 0.0),
        f([0xF, 0, 0, 0], 1.0),
        f([u64::MAX, 0, 0, 0], 2.0),
    ];
    let m = match_features(&a, &b, 0.8, 80);
    assert_eq!(m, vec![(0, 0), (1, 2)]);
}

#[test]
fn footprint_is_the_share_of_frames_each_pixel_moves() {
    let mut m1 = Mask::new(4, 2);
    let mut m2 = Mask::new(4, 2);
    m1.set(1, 0, true);
    m2.set(1, 0, true);
    m2.set(3, 1, true);
    let fp = footprint(&[m1, m2.clone(), Mask::new(4, 2), m2]).unwrap();
    assert_eq!(fp.get_pixel(1, 0).0, [191, 191, 191]);
    assert_eq!(fp.get_pixel(3, 1).0, [128, 128, 128]);
    assert_eq!(fp.get_pixel(0, 0).0, [0, 0, 0]);
    assert!(footprint(&[Mask::new(4, 2)]).is_none());
    assert!(footprint(&[]).is_none());
}

#[test]
fn bad_parameters_are_named() {
    let bad = RegisterParams {
        ratio: 1.5,
        ..Default::default()
    };
    let e = bad.check().unwrap_err().to_string();
    assert!(e.contains("register.ratio") && e.contains("1.5"), "{e}");
    assert!(RegisterParams::default().check().is_ok());
}
