use super::*;

fn pair() -> (RgbImage, RgbImage) {
    super::test_pair()
}

#[test]
fn sgm_finds_the_parallax_of_a_nearer_plane() {
    let (a, b) = pair();
    let h = Homography::identity();
    let par = estimate(
        &a,
        &b,
        &h,
        &Geometry::straight([1.0, 0.0], -4, 12),
        &ParallaxParams::default(),
    );
    let w = 160usize;
    let (mut good, mut n) = (0, 0);
    for y in 8..88 {
        for x in 8..152 {
            if !(70..=92).contains(&x) {
                let want = if x >= 80 - 6 + 6 { 6.0 } else { 0.0 };
                n += 1;
                good += ((par.a.disparity[y * w + x] - want).abs() < 0.5) as usize;
            }
        }
    }
    assert!(good * 100 >= 95 * n, "{good} of {n} within 0.5 px");
}

/// A registration's homography that shears across the parallax (incompatible with the rig:
/// the true matches move along x only): the fitted lines pass through the true matches,
/// straight lines along the mean direction miss them by pixels.
#[test]
fn fitted_lines_absorb_a_sheared_plane() {
    let h = Homography::from_matrix(nalgebra::Matrix3::new(
        1.0, -0.03, -12.0, 0.012, 1.03, -6.0, 0.0, 2e-5, 1.0,
    ))
    .unwrap();
    let (w, hgt) = (640u32, 480u32);
    let mut matches = Vec::new();
    for i in 0..400u64 {
        let a = Point::new(
            10.0 + 620.0 * crate::rng::unit(crate::rng::mix_at(1, i)),
            10.0 + 460.0 * crate::rng::unit(crate::rng::mix_at(2, i)),
        );
        let depth = 4.0 + 24.0 * crate::rng::unit(crate::rng::mix_at(3, i));
        matches.push((a, Point::new(a.x - depth, a.y)));
    }
    let geo = geometry(&matches, &h, (w, hgt)).unwrap();
    let lines = geo.lines.expect("fitted lines");
    let across = |m: Option<&[f64; 9]>| -> f64 {
        matches
            .iter()
            .map(|&(a, b)| {
                let q = h.apply_inverse(b).unwrap();
                let f = line_frame(m, geo.direction, a.x, a.y);
                let (rx, ry) = (
                    q.x - a.x - f64::from(f.offset[0]),
                    q.y - a.y - f64::from(f.offset[1]),
                );
                (rx * f64::from(f.along[1]) - ry * f64::from(f.along[0])).abs()
            })
            .fold(0.0, f64::max)
    };
    let (fitted, straight) = (across(Some(&lines[0])), across(None));
    assert!(
        fitted < 0.5 && straight > 3.0,
        "fitted {fitted} px, straight {straight} px"
    );
}

/// An occluded run between a far (smaller motion than the plane's) and a near surface takes
/// the far one's disparity.
#[test]
fn occlusions_are_filled_from_the_farther_side() {
    // The plane moves +x (near = +), far surface d = -3, near surface d = +5.
    let mut d = vec![-3.0, -3.0, 0.0, 0.0, 5.0, 5.0];
    let valid = [true, true, false, false, true, true];
    fill(&mut d, &valid, 6, 1.0);
    assert_eq!(d, [-3.0, -3.0, -3.0, -3.0, 5.0, 5.0]);
    let mut d = vec![5.0, 0.0, -3.0];
    fill(&mut d, &[true, false, true], 3, -1.0);
    assert_eq!(d, [5.0, 5.0, -3.0]);
}

#[test]
fn a_field_refuses_what_does_not_fit_and_derives_its_flow() {
    let ok = |d: Vec<f32>, dir: [f32; 2], lines: Option<[f64; 9]>| {
        Field::new(3, 2, dir, lines, d, vec![true; 6])
    };
    assert!(ok(vec![0.0; 5], [1.0, 0.0], None).is_err());
    assert!(ok(vec![0.0; 6], [2.0, 0.0], None).is_err());
    assert!(ok(vec![0.0, f32::NAN, 0.0, 0.0, 0.0, 0.0], [1.0, 0.0], None).is_err());
    let mut nan_lines = [0.0; 9];
    nan_lines[4] = f64::INFINITY;
    assert!(ok(vec![0.0; 6], [1.0, 0.0], Some(nan_lines)).is_err());
    // Straight along (0, -1): d = 2 moves 2 px up; a line model's constant offset of 1.5 px
    // moves the line across, along the direction's normal (-vy, vx) = (1, 0).
    let f = ok(vec![2.0; 6], [0.0, -1.0], None).unwrap();
    assert_eq!(f.flow_px(4), [0.0, -2.0]);
    let mut m = [0.0; 9];
    m[0] = 1.5;
    let f = ok(vec![2.0; 6], [0.0, -1.0], Some(m)).unwrap();
    assert_eq!(f.flow_px(4), [1.5, -2.0]);
}

#[test]
fn direction_comes_from_the_off_plane_matches() {
    let h = Homography::identity();
    let mut matches = Vec::new();
    for i in 0..60 {
        let a = Point::new(10.0 + 7.0 * i as f64, 20.0 + 3.0 * (i % 9) as f64);
        // A third on the plane, the rest moved along (0.96, 0.28) by 3..12 px, plus a few
        // mismatches.
        let d = if i % 3 == 0 {
            0.0
        } else {
            3.0 + (i % 10) as f64
        };
        let b = if i % 17 == 5 {
            Point::new(a.x - 40.0, a.y + 25.0)
        } else {
            Point::new(a.x + 0.96 * d, a.y + 0.28 * d)
        };
        matches.push((a, b));
    }
    let (v, lo, hi) = direction_and_range(&matches, &h).unwrap();
    assert!(
        (v[0] - 0.96).abs() < 0.02 && (v[1] - 0.28).abs() < 0.03,
        "{v:?}"
    );
    assert!(lo <= -2 && hi >= 12, "{lo}..{hi}");
    // On the plane: no parallax to model.
    let flat: Vec<(Point, Point)> = matches.iter().map(|&(a, _)| (a, a)).collect();
    assert!(direction_and_range(&flat, &h).is_none());
}

/// An occluding edge between views whose plane moves (+2 px from a to b) and a nearer surface
/// that moves farther (+8 px): at f = 0.5 the nearer surface covers the output from x = 84 on,
/// and beside the edge, where both traces converge on different surfaces, the nearer surface
/// must win alone, not be blended with what it hides.
#[test]
fn the_nearer_surface_hides_what_lies_behind_it() {
    let (w, h) = (160u32, 96u32);
    let tex = |x: i64, y: i64| {
        let v = crate::rng::mix_at(11, (y.div_euclid(2) * 1000 + x.div_euclid(2)) as u64);
        let g = (v % 200) as u8 + 30;
        image::Rgb([g, 255 - g, g / 2 + 60])
    };
    // The background is seen at its own x, the nearer surface (right of the edge) too: each
    // view shifts them by its own amount.
    let view = |bg: i64, fg: i64| {
        RgbImage::from_fn(w, h, |x, y| {
            let (x, y) = (x as i64, y as i64);
            if x - fg >= 80 {
                tex(x - fg + 5000, y)
            } else {
                tex(x - bg, y)
            }
        })
    };
    let (a, b) = (view(0, 0), view(2, 8));
    let truth = view(1, 4);
    let hab = Homography::translation(2.0, 0.0);
    let par = estimate(
        &a,
        &b,
        &hab,
        &Geometry::straight([1.0, 0.0], -4, 12),
        &ParallaxParams::default(),
    );
    let (haq, hbq) = (
        Homography::translation(1.0, 0.0),
        Homography::translation(-1.0, 0.0),
    );
    // The nearer side: the surface right of the edge (relative disparity +6) is nearer.
    let t = nearer_towards(&par, &haq, &hbq, (w, h));
    let fg = par.a.flow_at(120.0, 48.0);
    let bg = par.a.flow_at(40.0, 48.0);
    assert!(
        fg[0] * t[0][0] + fg[1] * t[0][1] > bg[0] * t[0][0] + bg[1] * t[0][1] + 4.0,
        "towards {t:?}, flows {fg:?} / {bg:?}"
    );
    let out = morph(&a, &b, &par, &haq, &hbq, 0.5, w, h);
    // The nearer surface's first 8 columns in the output, away from the top and bottom rows:
    // there b's trace also converges, on the background it still sees beside the edge (left of
    // its x = 88), which the nearer surface hides at this viewpoint. (Left of x = 84 only b
    // sees the background, and a's trace does not converge: the other rule.)
    let (mut right, mut n) = (0, 0);
    for y in 8..88 {
        for x in 84..92 {
            let (o, g) = (out.get_pixel(x, y), truth.get_pixel(x, y));
            let e = (0..3)
                .map(|k| (o[k] as i32 - g[k] as i32).abs())
                .max()
                .unwrap();
            n += 1;
            right += (e <= 2) as usize;
        }
    }
    assert!(
        right * 100 >= 95 * n,
        "{right} of {n} pixels beside the edge right"
    );
}
