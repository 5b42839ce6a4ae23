//! Numerical extremes: far, near-collinear and tiny point sets, 1x1 and 8K images, empty and full masks, the line at infinity.

#[allow(unused_imports)]
use super::*;

pub(super) fn extreme_points(t: &mut Table) -> Result<()> {
    // The well-formed point sets of vt_cv::cases (far from the origin, noisy, near-collinear,
    // tiny spread, nearly singular maps); the report shows the same cases, degenerate ones too.
    for case in vt_cv::cases::extreme_point_sets() {
        if !case.degenerate && case.name != "6 pts, well conditioned" {
            homography_stability(t, &case.name, &case.src, &case.dst);
        }
    }
    Ok(())
}

pub(super) fn extreme_images(t: &mut Table) -> Result<()> {
    // 1x1 images.
    let one = RgbImage::from_pixel(1, 1, image::Rgb([7, 200, 33]));
    let other = RgbImage::from_pixel(1, 1, image::Rgb([7, 150, 33]));
    check_identical_rgb(
        t,
        "Gaussian 3x3",
        "1x1",
        &vt_core::blur::gaussian_blur(&one, &GaussianParams::default())?,
        &vt_cv::blur::gaussian_blur(&one, &GaussianParams::default())?,
    );
    check_identical_rgb(
        t,
        "median",
        "1x1, 3 frames",
        &vt_core::median::temporal_median([&one, &other, &one])?,
        &vt_cv::median::temporal_median([&one, &other, &one])?,
    );
    for (name, h) in [
        ("identity", Homography::identity()),
        ("shift 0.4 px", Homography::translation(0.4, -0.4)),
    ] {
        check_identical_rgb(
            t,
            "warp RGB nearest",
            &format!("1x1 {name}"),
            &vt_core::warp::warp_rgb(&one, &h, 1, 1, Interpolation::Nearest),
            &vt_cv::warp::warp_rgb(&one, &h, 1, 1, Interpolation::Nearest)?,
        );
        check_warp_bilinear(t, &format!("1x1 {name}"), &one, &h, 1, 1)?;
    }
    let params = MaskParams {
        threshold: 25,
        open_radius: 1,
        close_radius: 1,
    };
    check_identical_masks(
        t,
        "mask (open 1 close 1)",
        "1x1",
        &[foreground_mask(&other, &one, &params)?],
        &[vt_cv::mask::foreground_mask(&other, &one, &params)?],
    );

    // 8K (7680x4320): blur, mask, warps, median of 3 frames.
    let (w, h) = (7680u32, 4320u32);
    let t0 = Instant::now();
    // A smooth pattern (tables per column and row), noise, and one channel of hard edges.
    let cols: Vec<f64> = (0..w)
        .map(|x| (x as f64 * 0.05).sin() * 60.0 + 128.0)
        .collect();
    let rows: Vec<f64> = (0..h).map(|y| (y as f64 * 0.031).cos() * 50.0).collect();
    let tex = |seed: u64| {
        RgbImage::from_fn(w, h, |x, y| {
            let v = (cols[x as usize] + rows[y as usize]) as i32;
            let n = (vt_core::rng::mix(seed ^ ((y as u64) << 16 | x as u64)) % 41) as i32 - 20;
            image::Rgb([
                (v + n).clamp(0, 255) as u8,
                (255 - v + n).clamp(0, 255) as u8,
                ((x ^ y) & 255) as u8,
            ])
        })
    };
    let (a, b, c) = (tex(1), tex(2), tex(3));
    let input = "8K 7680x4320";
    let g = GaussianParams::default();
    let (vt_a, cv_a) = (
        vt_core::blur::gaussian_blur(&a, &g)?,
        vt_cv::blur::gaussian_blur(&a, &g)?,
    );
    check_blur(t, "Gaussian 3x3", input, &vt_a, &cv_a);
    let vt_b = vt_core::blur::gaussian_blur(&b, &g)?;
    let mp = MaskParams {
        threshold: 25,
        open_radius: 1,
        close_radius: 1,
    };
    check_identical_masks(
        t,
        "mask (same blur, open 1 close 1)",
        input,
        &[foreground_mask(&vt_a, &vt_b, &mp)?],
        &[vt_cv::mask::foreground_mask(&vt_a, &vt_b, &mp)?],
    );
    check_identical_rgb(
        t,
        "median",
        &format!("{input}, 3 frames"),
        &vt_core::median::temporal_median([&a, &b, &c])?,
        &vt_cv::median::temporal_median([&a, &b, &c])?,
    );
    let hm = Homography::from_matrix(Matrix3::new(
        0.98, 0.05, 60.0, -0.04, 1.01, 30.0, 4e-6, -3e-6, 1.0,
    ))?;
    check_warp_bilinear(t, input, &a, &hm, w, h)?;
    check_identical_rgb(
        t,
        "warp RGB nearest",
        input,
        &vt_core::warp::warp_rgb(&a, &hm, w, h, Interpolation::Nearest),
        &vt_cv::warp::warp_rgb(&a, &hm, w, h, Interpolation::Nearest)?,
    );
    eprintln!("8K rows in {:.1?}", t0.elapsed());

    // Warps by a nearly singular homography (the image folds onto a narrow band).
    let small = RgbImage::from_fn(320, 180, |x, y| {
        image::Rgb([(x * 3) as u8, (y * 5) as u8, ((x + y) * 2) as u8])
    });
    for eps in [1e-4, 1e-8] {
        let m = Matrix3::new(1.0, 0.5, 10.0, 1.0, 0.5 + eps, 12.0, 1e-4, 5e-5, 1.0);
        match Homography::from_matrix(m) {
            Ok(hs) => {
                let name = format!("320x180 nearly singular H ({eps:.0e})");
                check_warp_bilinear(t, &name, &small, &hs, 320, 180)?;
                let ms = Mask::from_fn(320, 180, |x, y| (x / 7 + y / 5) % 3 == 0);
                check_identical_masks(
                    t,
                    "warp masks (nearest)",
                    &name,
                    &[vt_core::warp::warp_mask(&ms, &hs, 320, 180)],
                    &[vt_cv::warp::warp_mask(&ms, &hs, 320, 180)?],
                );
            }
            Err(e) => t.add(
                "warp (nearly singular H)",
                &format!("eps {eps:.0e}"),
                format!("vt refuses: {e}"),
                "Err is fine",
                true,
            ),
        }
    }
    Ok(())
}

/// A homography whose line at infinity passes exactly through output column 8 (`w = 0` there in
/// both implementations, as `H` is an involution with power-of-two entries). vt-core leaves those
/// pixels black / clear (they have no preimage); OpenCV's `W ? 1/W : 0` sends them to source pixel
/// (0, 0). The row asserts that this column is the only difference and that vt-core's answer there
/// is the empty one.
pub(super) fn line_at_infinity(t: &mut Table) -> Result<()> {
    let h = Homography::from_matrix(Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.125, 0.0, -1.0))?;
    let img = RgbImage::from_fn(16, 8, |x, y| image::Rgb([100 + x as u8, 50 + y as u8, 7]));
    let full = Mask::from_fn(16, 8, |_, _| true);
    let (mut other_cols, mut col8_vt_clear, mut col8_differ) = (0, true, 0);
    for interp in [Interpolation::Nearest, Interpolation::Bilinear] {
        let vt = vt_core::warp::warp_rgb(&img, &h, 16, 8, interp);
        let cv = vt_cv::warp::warp_rgb(&img, &h, 16, 8, interp)?;
        for (x, y, p) in vt.enumerate_pixels() {
            if *p != *cv.get_pixel(x, y) {
                if x == 8 {
                    col8_differ += 1;
                    col8_vt_clear &= p.0 == [0, 0, 0];
                } else {
                    other_cols += 1;
                }
            }
        }
    }
    let (vm, cm) = (
        vt_core::warp::warp_mask(&full, &h, 16, 8),
        vt_cv::warp::warp_mask(&full, &h, 16, 8)?,
    );
    for y in 0..8 {
        for x in 0..16 {
            if vm.get(x, y) != cm.get(x, y) {
                if x == 8 {
                    col8_differ += 1;
                    col8_vt_clear &= !vm.get(x, y);
                } else {
                    other_cols += 1;
                }
            }
        }
    }
    t.add(
        "warp on the line at infinity",
        "16x8, w = 0 on column 8",
        format!("{col8_differ} px differ on col 8 (vt empty, cv src(0,0)), {other_cols} elsewhere"),
        "only col 8; vt empty there",
        other_cols == 0 && col8_vt_clear,
    );
    Ok(())
}

pub(super) fn extreme_masks(t: &mut Table) -> Result<()> {
    let (w, h) = (64u32, 48u32);
    let empty = Mask::new(w, h);
    let full = Mask::from_fn(w, h, |_, _| true);
    for (name, m) in [("all-empty 64x48", &empty), ("all-full 64x48", &full)] {
        let mut differ = 0u64;
        for r in [1u32, 3] {
            use vt_cv::mask::Morph;
            for (vt, op) in [
                (m.erode(r), Morph::Erode),
                (m.dilate(r), Morph::Dilate),
                (m.open(r), Morph::Open),
                (m.close(r), Morph::Close),
            ] {
                differ += vt_core::mask::xor_count(&vt, &vt_cv::mask::morph(m, r, op)?);
            }
        }
        t.add(
            "erode/dilate/open/close r 1, 3",
            name,
            format!("{differ} pixels differ"),
            "identical",
            differ == 0,
        );
        for other in [&empty, &full] {
            let (a, b) = (
                vt_core::mask::xor_count(m, other),
                vt_cv::mask::xor_count(m, other)?,
            );
            t.add(
                "XOR cost",
                &format!(
                    "{name} vs {}",
                    if other.count_ones() == 0 {
                        "empty"
                    } else {
                        "full"
                    }
                ),
                format!("vt {a} / cv {b}"),
                "identical",
                a == b,
            );
        }
        let hm =
            Homography::from_matrix(Matrix3::new(0.9, 0.1, 3.0, -0.1, 1.1, -2.0, 1e-3, 0.0, 1.0))?;
        check_identical_masks(
            t,
            "warp masks (nearest)",
            name,
            &[vt_core::warp::warp_mask(m, &hm, w, h)],
            &[vt_cv::warp::warp_mask(m, &hm, w, h)?],
        );
        // Every cost ties: both must break ties the same way.
        let masks = vec![m.clone(); 30];
        let lp = LoopParams {
            window: 3,
            min_length: 10,
        };
        let (a, b) = (
            vt_core::loops::find_loop(&masks, &lp, name)?,
            vt_cv::loops::find_loop(&masks, &lp, name)?,
        );
        t.add(
            "loop eq. (1), all ties",
            name,
            format!("vt ({}, {}) / cv ({}, {})", a.start, a.end, b.start, b.end),
            "identical",
            a == b,
        );
        let (ta, tb) = (
            vt_core::transition::transition_table(&masks, &masks, 20, 3)?,
            vt_cv::transition::transition_table(&masks, &masks, 20, 3)?,
        );
        t.add(
            "transition eq. (2), all ties",
            name,
            format!(
                "{} entries differ",
                ta.iter().zip(&tb).filter(|(x, y)| x != y).count()
            ),
            "identical",
            ta == tb,
        );
    }
    Ok(())
}
