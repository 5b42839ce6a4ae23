//! Handheld clips made still, against the shake that made them: a real photo (graf1 of the
//! Mikolajczyk benchmark) cut into frames along a known smooth random walk of shifts and turns.

use image::RgbImage;
use nalgebra::Matrix3;
use vt_core::analysis::{FrameSource, MemorySource};
use vt_core::stabilize::{crop_maps, measure, Probing, StabilizeParams, Steady, Verdict};
use vt_core::warp::{warp_rgb, Interpolation};
use vt_core::{Homography, Point};

fn load(name: &str) -> RgbImage {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name);
    image::open(path).unwrap().to_rgb8()
}

/// Frame size cut from the photo, and the photo's offset of the unshaken frame.
const W: u32 = 480;
const H: u32 = 360;
const OFFSET: (f64, f64) = (160.0, 140.0);

/// The map from the photo to frame k: a turn of `deg` about the frame's centre and a shift.
fn shake(deg: f64, dx: f64, dy: f64) -> Homography {
    let a = deg.to_radians();
    let (cx, cy) = (OFFSET.0 + W as f64 / 2.0, OFFSET.1 + H as f64 / 2.0);
    let (c, s) = (a.cos(), a.sin());
    // Turn about (cx, cy), shift, then take the frame's window.
    let m = Matrix3::new(
        c,
        -s,
        cx - c * cx + s * cy + dx - OFFSET.0,
        s,
        c,
        cy - s * cx - c * cy + dy - OFFSET.1,
        0.0,
        0.0,
        1.0,
    );
    Homography::from_matrix(m).unwrap()
}

/// A smooth walk: up to about 4 px and 1 degree.
fn walk(k: usize) -> (f64, f64, f64) {
    let t = k as f64;
    (
        0.9 * (0.23 * t).sin() * (0.05 * t + 0.4).cos(),
        3.5 * (0.17 * t + 1.0).sin(),
        2.5 * (0.29 * t + 2.0).cos(),
    )
}

fn shaken(photo: &RgbImage, frames: usize) -> (Vec<RgbImage>, Vec<Homography>) {
    (0..frames)
        .map(|k| {
            let (deg, dx, dy) = walk(k);
            let t = shake(deg, dx, dy);
            (warp_rgb(photo, &t, W, H, Interpolation::Bilinear), t)
        })
        .unzip()
}

fn corner_distance(a: &Homography, b: &Homography) -> f64 {
    [
        (0.0, 0.0),
        (W as f64, 0.0),
        (0.0, H as f64),
        (W as f64, H as f64),
    ]
    .iter()
    .map(|&(x, y)| {
        let p = Point::new(x + OFFSET.0, y + OFFSET.1);
        (a.apply(p).unwrap() - b.apply(p).unwrap()).norm()
    })
    .fold(0.0, f64::max)
}

#[test]
fn a_shaken_photo_is_held_still_to_a_fifth_of_a_pixel() {
    let photo = load("graf1.png");
    let (frames, truth) = shaken(&photo, 24);
    let mut src = MemorySource {
        name: "shaken".into(),
        frames,
    };
    let shake = measure(&mut src, &StabilizeParams::default()).unwrap();
    assert_eq!(shake.verdict, Verdict::Steadied, "{}", shake.describe());
    assert_eq!(shake.frames, 24);
    // Turns and shifts: GRIC needs more than a translation and no perspective (it may take an
    // affine map: sub-pixel tracking of resampled patches has a small bias of its own).
    use vt_core::model::MotionModel;
    assert!(
        matches!(
            shake.model,
            Some(MotionModel::Similarity | MotionModel::Affine)
        ),
        "{:?}",
        shake.model
    );
    // Photo -> frame k -> still camera is one map for every k.
    let through: Vec<Homography> = truth
        .iter()
        .zip(&shake.maps)
        .map(|(t, g)| g.after(t).unwrap())
        .collect();
    let errs: Vec<f64> = through
        .iter()
        .map(|m| corner_distance(m, &through[0]))
        .collect();
    let worst = errs.iter().cloned().fold(0.0, f64::max);
    // At the frame's corners, where the map is extrapolated; the median frame is within
    // 0.03 px, a few reach 0.13 (sub-pixel tracking of resampled patches is biased by their
    // phase).
    assert!(worst < 0.2, "frames disagree by up to {worst:.3} px");
    // The walk reaches about 4 px and 1 degree; the measure says so.
    assert!(
        (2.0..12.0).contains(&shake.largest_px) && shake.largest_deg > 0.3,
        "{}",
        shake.describe()
    );
    // The crop keeps most of the frame and lies where every frame has pixels.
    let a = shake.area;
    assert!(a.width > W * 8 / 10 && a.height > H * 8 / 10, "{a:?}");
    assert!(a.width.is_multiple_of(2) && a.height.is_multiple_of(2));

    // The frames through Steady agree with each other where the photo is (bilinear twice).
    let maps = crop_maps(&shake, a);
    let mut steady = Steady::new(&mut src, Some(maps), (a.width, a.height));
    let mut first: Option<RgbImage> = None;
    let mut worst_mean = 0.0f64;
    steady
        .for_each_frame(&mut |_, f| {
            assert_eq!(f.dimensions(), (a.width, a.height));
            match &first {
                None => first = Some(f.clone()),
                Some(f0) => {
                    let d: f64 = f
                        .as_raw()
                        .iter()
                        .zip(f0.as_raw())
                        .map(|(x, y)| (*x as f64 - *y as f64).abs())
                        .sum::<f64>()
                        / f.as_raw().len() as f64;
                    worst_mean = worst_mean.max(d);
                }
            }
            Ok(())
        })
        .unwrap();
    assert!(
        worst_mean < 2.0,
        "steadied frames differ by {worst_mean:.2} levels"
    );
}

#[test]
fn a_still_clip_is_left_as_it_is() {
    let photo = load("graf1.png");
    let t = shake(0.0, 0.0, 0.0);
    let frame = warp_rgb(&photo, &t, W, H, Interpolation::Bilinear);
    let mut src = MemorySource {
        name: "still".into(),
        frames: vec![frame; 20],
    };
    let shake = measure(&mut src, &StabilizeParams::default()).unwrap();
    assert_eq!(shake.verdict, Verdict::Still, "{}", shake.describe());
    assert!(shake.largest_px < 0.05, "{}", shake.describe());
    assert_eq!((shake.area.width, shake.area.height), (W, H));
}

#[test]
fn a_cut_is_refused_naming_the_frame() {
    let photo = load("graf1.png");
    let other = load("middlebury-line/Dolls/view0.png");
    let (mut frames, _) = shaken(&photo, 20);
    // Dolls is smaller than graf1: its frames are its own shaken windows.
    let other = image::imageops::resize(&other, 800, 640, image::imageops::FilterType::Triangle);
    let (after, _) = shaken(&other, 20);
    frames.splice(12.., after.into_iter().skip(12));
    let mut src = MemorySource {
        name: "cut.mp4".into(),
        frames,
    };
    let e = measure(&mut src, &StabilizeParams::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cut.mp4") && e.contains("frame 16") && e.contains("--stabilize off"),
        "{e}"
    );
}

#[test]
fn a_pan_is_refused() {
    // The camera slides half the frame's width: the area every frame covers keeps half of it,
    // under the 60% asked for.
    let photo = load("graf1.png");
    let frames: Vec<RgbImage> = (0..17)
        .map(|k| {
            let t = shake(0.0, -(k as f64) * 0.5 * 300.0 / 16.0, 0.0);
            warp_rgb(&photo, &t, 300, H, Interpolation::Bilinear)
        })
        .collect();
    let mut src = MemorySource {
        name: "pan".into(),
        frames,
    };
    let e = measure(&mut src, &StabilizeParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("moves too far"), "{e}");
}

/// The analysis's first pass carries the probe ([`Probing`]), which tracks on a thread of its own
/// (inside the pass on a rayon worker): either way a still clip comes out still, a shaken one
/// moving, and a cut is refused naming the frame, as `measure` says.
#[test]
fn the_first_pass_probes_alike_on_its_own_thread_and_on_a_rayon_worker() {
    let photo = load("graf1.png");
    let still = vec![warp_rgb(&photo, &shake(0.0, 0.0, 0.0), W, H, Interpolation::Bilinear); 20];
    let (shaken, _) = shaken(&photo, 20);
    let other = load("middlebury-line/Dolls/view0.png");
    let other = image::imageops::resize(&other, 800, 640, image::imageops::FilterType::Triangle);
    let mut cut = shaken.clone();
    cut.splice(12.., self::shaken(&other, 20).0.into_iter().skip(12));
    let first_pass = |frames: &Vec<RgbImage>| {
        let mut src = MemorySource {
            name: "clip.mp4".into(),
            frames: frames.clone(),
        };
        let mut probing = Probing::new(&mut src, &StabilizeParams::default());
        let mut seen = 0;
        let r = probing.for_each_native(&mut |_, _| {
            seen += 1;
            Ok(())
        });
        let verdict = probing.shake().map(|s| s.verdict);
        (r.map_err(|e| e.to_string()), probing.moved(), verdict, seen)
    };
    let run_all = || [&still, &shaken, &cut].map(first_pass);
    let own_thread = run_all();
    let on_worker = rayon::scope(|_| {
        assert!(rayon::current_thread_index().is_some());
        run_all()
    });
    for outcome in [&own_thread, &on_worker] {
        let [s, m, c] = outcome;
        assert_eq!(
            (&s.0, s.1, s.2, s.3),
            (&Ok(20), false, Some(Verdict::Still), 20)
        );
        assert!(m.0.is_err() && m.1 && m.2.is_none(), "{m:?}");
        let e = c.0.as_ref().unwrap_err();
        assert!(e.contains("clip.mp4") && e.contains("frame 16"), "{e}");
    }
}
