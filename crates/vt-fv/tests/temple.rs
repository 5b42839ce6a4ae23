//! The real Middlebury templeSparseRing views in testdata/: camera conventions, automatic bounds
//! and a leave-one-out render of a withheld view.

use std::path::PathBuf;
use std::time::Instant;

use image::RgbImage;
use nalgebra::Vector3;
use vt_fv::camera::parse_par;
use vt_fv::hull::{auto_bounds, HullParams};
use vt_fv::silhouette::{threshold_silhouette, SilhouetteParams};
use vt_fv::{leave_one_out, Camera, Mask, PhotoParams, SynthParams, ViewParams};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/templeSparseRing")
}

/// The cameras whose photos are in testdata (a subset of the 16), with photos and silhouettes
/// (Middlebury recipe at full size), all downscaled by `factor`.
fn load(factor: u32) -> (Vec<Camera>, Vec<RgbImage>, Vec<Mask>) {
    let text = std::fs::read_to_string(dir().join("templeSR_par.txt")).unwrap();
    let all = parse_par(&text).unwrap();
    assert_eq!(all.len(), 16);
    let (mut cams, mut imgs, mut masks) = (Vec::new(), Vec::new(), Vec::new());
    for c in all {
        let path = dir().join(&c.name);
        if !path.exists() {
            continue;
        }
        let img = image::open(&path).unwrap().to_rgb8();
        let m = threshold_silhouette(&img, &SilhouetteParams::default());
        let (w, h) = (img.width() / factor, img.height() / factor);
        let f = factor;
        let small = RgbImage::from_fn(w, h, |x, y| {
            let mut acc = [0u32; 3];
            for dy in 0..f {
                for dx in 0..f {
                    let p = img.get_pixel(x * f + dx, y * f + dy).0;
                    (0..3).for_each(|k| acc[k] += p[k] as u32);
                }
            }
            image::Rgb(acc.map(|a| (a / (f * f)) as u8))
        });
        let sm = Mask::from_fn(w, h, |x, y| {
            (0..f * f).any(|i| m.get((x * f + i % f) as i64, (y * f + i / f) as i64))
        });
        cams.push(c.scaled(1.0 / factor as f64));
        imgs.push(small);
        masks.push(sm);
    }
    (cams, imgs, masks)
}

#[test]
fn temple_cameras_see_the_object_and_bounds_hold_it() {
    let (cams, _, masks) = load(2);
    assert_eq!(cams.len(), 9);
    // The data set's tight bounding box (its README).
    let (lo, hi) = (
        Vector3::new(-0.073568, 0.021728, -0.012445),
        Vector3::new(0.028855, 0.181892, 0.062736),
    );
    for (c, m) in cams.iter().zip(&masks) {
        // The temple has gaps between its columns, so test against the silhouette's box.
        let (x0, y0, x1, y1) = m.bbox().unwrap();
        let (u, v, _) = c.project(&((lo + hi) / 2.0)).unwrap();
        let inside = u >= x0 as f64 && u <= x1 as f64 && v >= y0 as f64 && v <= y1 as f64;
        assert!(
            inside,
            "{}: box centre projects outside the silhouette's box at {u},{v}",
            c.name
        );
    }
    let b = auto_bounds(&cams, &masks, &HullParams::default()).unwrap();
    for a in 0..3 {
        assert!(
            b.min[a] <= lo[a] && b.max[a] >= hi[a],
            "automatic bounds {b:?} miss the tight box on axis {a}"
        );
        assert!(
            b.max[a] - b.min[a] < 1.5 * (hi[a] - lo[a]) + 0.02,
            "automatic bounds {b:?} loose on axis {a}"
        );
    }
}

#[test]
fn temple_leave_one_out_guided_beats_rough() {
    let slow = std::env::var("VT_SLOW_TESTS").is_ok_and(|v| v == "1");
    let (cams, imgs, masks) = load(if slow { 1 } else { 2 });
    let withheld = cams
        .iter()
        .position(|c| c.name == "templeSR0004.png")
        .unwrap();
    let t = Instant::now();
    let hull = HullParams {
        dims: if slow { [256; 3] } else { [96; 3] },
        ..Default::default()
    };
    let synth = if slow {
        SynthParams::fast()
    } else {
        SynthParams {
            patch: 7,
            ..Default::default()
        }
    };
    let (r, _) = leave_one_out(
        &cams,
        &imgs,
        &masks,
        withheld,
        &hull,
        &PhotoParams::default(),
        &ViewParams::paper(synth),
    )
    .unwrap();
    eprintln!("{r:?} in {:?}", t.elapsed());
    let (g, rough) = (r.guided.inside.ssim, r.rough.inside.ssim);
    assert!(g > rough, "guided SSIM {g} <= rough {rough}");
}
