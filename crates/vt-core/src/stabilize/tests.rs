use super::crop::covered;
use super::*;
use crate::yuv::Yuv420Image;
use image::RgbImage;

#[test]
fn the_largest_covered_rectangle_of_shifted_frames_is_their_overlap() {
    // Frames shifted by (+3, -2) and (-4, +1) against the still camera: every frame covers
    // x in [3, 95 - 4] and y in [1, 63 - 2].
    let maps = vec![
        Homography::identity(),
        Homography::translation(3.0, -2.0),
        Homography::translation(-4.0, 1.0),
    ];
    let c = covered(&maps, (96, 64)).unwrap();
    assert_eq!((c.x, c.y), (3, 1));
    // 3..=91 is 89 columns, even: 88; 1..=61 is 61 rows: 60.
    assert_eq!((c.width, c.height), (88, 60));
    let far = vec![Homography::identity(), Homography::translation(200.0, 0.0)];
    assert!(covered(&far, (96, 64)).is_none());
}

#[test]
fn a_turned_frame_keeps_a_rectangle_inside_it() {
    let (w, h) = (320u32, 240u32);
    let c = (w as f64 / 2.0, h as f64 / 2.0);
    let a = 2f64.to_radians();
    let turn = Homography::from_matrix(nalgebra::Matrix3::new(
        a.cos(),
        -a.sin(),
        c.0 - a.cos() * c.0 + a.sin() * c.1,
        a.sin(),
        a.cos(),
        c.1 - a.sin() * c.0 - a.cos() * c.1,
        0.0,
        0.0,
        1.0,
    ))
    .unwrap();
    let maps = vec![Homography::identity(), turn];
    let r = covered(&maps, (w, h)).unwrap();
    // Every corner of the crop lies inside the turned frame.
    let inv = turn.inverse();
    for (x, y) in [
        (r.x, r.y),
        (r.x + r.width - 1, r.y),
        (r.x, r.y + r.height - 1),
        (r.x + r.width - 1, r.y + r.height - 1),
    ] {
        let q = inv.apply(Point::new(x as f64, y as f64)).unwrap();
        assert!(q.x >= -1e-6 && q.y >= -1e-6 && q.x <= 319.0 + 1e-6 && q.y <= 239.0 + 1e-6);
    }
    // And it is not much smaller than it must be: a 2 degree turn of a 320x240 frame leaves
    // more than 85% of each side.
    assert!(r.width > 272 && r.height > 204, "{r:?}");
}

#[test]
fn planes_warp_as_the_rgb_frame_does() {
    // A smooth 4:2:0 frame, shifted by a sub-pixel translation both ways: the converted
    // result matches the RGB warp of the converted source within rounding and the conversion's
    // nearest-neighbour chroma (smooth chroma, so that stays small).
    let (w, h) = (64u32, 48u32);
    let mut src = Yuv420Image::new(
        w,
        h,
        crate::yuv::YuvMatrix::Bt601,
        crate::yuv::YuvRange::Limited,
    )
    .unwrap();
    {
        let raw = src.as_raw_mut();
        let n = (w * h) as usize;
        for y in 0..h as usize {
            for x in 0..w as usize {
                raw[y * w as usize + x] =
                    (60.0 + 40.0 * ((x as f64) * 0.2).sin() + 30.0 * ((y as f64) * 0.15).cos())
                        as u8;
            }
        }
        for y in 0..(h / 2) as usize {
            for x in 0..(w / 2) as usize {
                raw[n + y * (w / 2) as usize + x] = (128.0 + 20.0 * (x as f64 * 0.1).sin()) as u8;
                raw[n + n / 4 + y * (w / 2) as usize + x] =
                    (128.0 + 20.0 * (y as f64 * 0.1).cos()) as u8;
            }
        }
    }
    let shift = Homography::translation(1.3, -0.7);
    let mut out = Yuv420Image::new(w, h, src.matrix(), src.range()).unwrap();
    warp_yuv420(&src, &shift, &mut out);
    let mut want = RgbImage::new(w, h);
    warp_rgb_cubic(&src.to_rgb(), &shift, &mut want);
    let got = out.to_rgb();
    let worst = got
        .as_raw()
        .iter()
        .zip(want.as_raw())
        .enumerate()
        .filter(|(i, _)| {
            let (x, y) = ((i / 3) as u32 % w, (i / 3) as u32 / w);
            (3..w - 3).contains(&x) && (3..h - 3).contains(&y)
        })
        .map(|(_, (a, b))| (*a as i32 - *b as i32).abs())
        .max()
        .unwrap();
    assert!(worst <= 4, "largest difference {worst}");
}

#[test]
fn bad_parameters_are_named() {
    let e = StabilizeParams {
        min_kept: 0.0,
        ..Default::default()
    }
    .check()
    .unwrap_err()
    .to_string();
    assert!(e.contains("stabilize.min_kept"), "{e}");
    assert!(StabilizeParams::default().check().is_ok());
    assert!("sideways".parse::<StabilizeMode>().is_err());
}

#[test]
fn the_cubic_warp_keeps_integer_shifts_exact_and_ramps_straight() {
    // An integer shift moves pixels as they are; a linear ramp stays linear at any fraction
    // (Keys' kernel reproduces polynomials up to degree 2).
    let img = RgbImage::from_fn(40, 30, |x, y| {
        image::Rgb([(3 * x + 2 * y) as u8, (5 * x) as u8, 200])
    });
    let mut out = RgbImage::new(30, 20);
    warp_rgb_cubic(&img, &Homography::translation(-4.0, -6.0), &mut out);
    for (x, y, p) in out.enumerate_pixels() {
        assert_eq!(p, img.get_pixel(x + 4, y + 6));
    }
    warp_rgb_cubic(&img, &Homography::translation(-4.25, -6.5), &mut out);
    for (x, y, p) in out.enumerate_pixels() {
        let (u, v) = (x as f64 + 4.25, y as f64 + 6.5);
        let want = [3.0 * u + 2.0 * v, 5.0 * u, 200.0];
        for c in 0..3 {
            assert!(
                (p[c] as f64 - want[c]).abs() <= 0.5 + 1e-9,
                "{x},{y}: {p:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn probes_thin_out_as_the_clip_grows() {
    let probed =
        |n: usize, every: usize| -> Vec<usize> { (0..n).filter(|&i| probes(i, every)).collect() };
    // Every 8th of the first 8 probes, then the spacing doubles with the frame index.
    assert_eq!(
        probed(300, 8),
        [0, 8, 16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256]
    );
    // Between any frame past the first span and its double, the same number of probes: the
    // count grows with the log of the length.
    for k in 0..6 {
        let from = 64 << k;
        assert_eq!(
            (from..2 * from).filter(|&i| probes(i, 8)).count(),
            4,
            "{from}"
        );
    }
    assert_eq!(probed(800, 8).len(), 23);
    // Every frame at spacing 1 for the first 8, then thinning the same way.
    assert_eq!(probed(20, 1), [0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16]);
}
