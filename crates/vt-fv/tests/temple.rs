//! The real Middlebury templeSparseRing views in testdata/: camera conventions, automatic bounds
//! and a leave-one-out render of a withheld view.

use std::path::PathBuf;
use std::time::Instant;

use image::RgbImage;
use nalgebra::Vector3;
use vt_fv::camera::parse_par;
use vt_fv::hull::{auto_bounds, HullParams};
use vt_fv::pipeline::score as score_in;
use vt_fv::silhouette::{threshold_silhouette, SilhouetteParams};
use vt_fv::{leave_one_out, Camera, GuidedParams, Mask, PhotoParams, ViewParams};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/templeSparseRing")
}

/// The cameras whose photos are in testdata (all 16), with photos and silhouettes (thresholded
/// as `sil` says at full size), all downscaled by `factor`.
fn load(factor: u32, sil: &SilhouetteParams) -> (Vec<Camera>, Vec<RgbImage>, Vec<Mask>) {
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
        let m = threshold_silhouette(&img, sil);
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
            (0..f * f).any(|i| m.get_or_false((x * f + i % f) as i64, (y * f + i / f) as i64))
        });
        cams.push(c.scaled(1.0 / factor as f64));
        imgs.push(small);
        masks.push(sm);
    }
    (cams, imgs, masks)
}

#[test]
fn temple_cameras_see_the_object_and_bounds_hold_it() {
    let (cams, _, masks) = load(2, &SilhouetteParams::default());
    assert_eq!(cams.len(), 16);
    // The data set's tight bounding box (its README).
    let (lo, hi) = (
        Vector3::new(-0.073568, 0.021728, -0.012445),
        Vector3::new(0.028855, 0.181892, 0.062736),
    );
    for (c, m) in cams.iter().zip(&masks) {
        // The temple has gaps between its columns, so test against the silhouette's box.
        let (x0, y0, x1, y1) = m.bounding_box().unwrap();
        let (u, v, _) = c.project(&((lo + hi) / 2.0)).unwrap();
        let inside = u >= x0 as f64 && u < x1 as f64 && v >= y0 as f64 && v < y1 as f64;
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

/// The full 16-view ring at 640x480: model silhouettes by [`SilhouetteParams::carving`], the
/// withheld view scored inside [`SilhouetteParams::scoring`]'s.
fn load_full() -> (Vec<Camera>, Vec<RgbImage>, Vec<Mask>, Vec<Mask>) {
    let text = std::fs::read_to_string(dir().join("templeSR_par.txt")).unwrap();
    let cams = parse_par(&text).unwrap();
    let imgs: Vec<RgbImage> = cams
        .iter()
        .map(|c| image::open(dir().join(&c.name)).unwrap().to_rgb8())
        .collect();
    let carve = imgs
        .iter()
        .map(|i| threshold_silhouette(i, &SilhouetteParams::carving()))
        .collect();
    let score = imgs
        .iter()
        .map(|i| threshold_silhouette(i, &SilhouetteParams::scoring()))
        .collect();
    (cams, imgs, carve, score)
}

/// The "done when" on two views whose pose no other camera shares: the default result
/// beats the rough render and its sigma-2 blur by >= 1 dB PSNR and >= 0.03 SSIM inside the
/// withheld silhouette, both [`SilhouetteParams::scoring`]'s and the Middlebury recipe's
/// ([`SilhouetteParams::default`], which takes in lit background cloth and grows the outline),
/// and the rough render's IoU with the scoring silhouette is >= 0.9. templeSR0010 sits next to
/// the pose that views 1 and 11 share (its two nearest cameras): textured from that pose twice
/// it scored 16.6 dB, below blur2's 19.0. Measured (scoring / recipe silhouette):
/// templeSR0009 rough 16.89 / 16.07, blur2 18.38 / 17.69, result 20.59 / 19.29 dB (SSIM 0.662 /
/// 0.612 against blur2 0.435 / 0.431), IoU 0.935; templeSR0010 rough 17.42 / 16.84, blur2
/// 18.99 / 18.50, result 20.75 / 19.98 dB (SSIM 0.642 / 0.581 against 0.456 / 0.435), IoU
/// 0.946; about 3 s per view in release, minutes unoptimised, so it is ignored by a plain
/// `cargo test` (the harness says so) and `scripts/test-all` runs it optimised (its `checked` profile) with `--ignored`.
#[test]
#[ignore = "slow unoptimised; run: cargo test --profile checked -p vt-fv --test temple -- --ignored"]
fn temple_default_beats_rough_and_blur_by_a_margin() {
    let (cams, imgs, carve, score) = load_full();
    for name in ["templeSR0009.png", "templeSR0010.png"] {
        let k = cams.iter().position(|c| c.name == name).unwrap();
        let mut masks = carve.clone();
        masks[k] = score[k].clone();
        let keep: Vec<Mask> = (0..cams.len())
            .filter(|&i| i != k)
            .map(|i| carve[i].clone())
            .collect();
        let keep_cams: Vec<Camera> = (0..cams.len())
            .filter(|&i| i != k)
            .map(|i| cams[i].clone())
            .collect();
        let bounds = auto_bounds(&keep_cams, &keep, &HullParams::default()).unwrap();
        let hull = HullParams {
            dims: vt_fv::hull::dims_for(&bounds, 128),
            bounds: Some(bounds),
            ..Default::default()
        };
        let t = Instant::now();
        let (r, imgs_k) = leave_one_out(
            &cams,
            &imgs,
            &masks,
            k,
            &hull,
            &PhotoParams::default(),
            &ViewParams::default(),
        )
        .unwrap();
        eprintln!("{name}: {r:#?} in {:?}", t.elapsed());
        let recipe = threshold_silhouette(&imgs[k], &SilhouetteParams::default());
        let in_recipe = |img: &RgbImage| score_in(img, &imgs_k.truth, &recipe).unwrap().inside;
        let sets = [
            (
                "scoring",
                r.guided.inside,
                r.rough.inside,
                r.rough_blur2.inside,
            ),
            (
                "recipe",
                in_recipe(&imgs_k.guided),
                in_recipe(&imgs_k.rough),
                in_recipe(&imgs_k.rough_blur2),
            ),
        ];
        for (sil, g, rough, blur) in sets {
            for (base_name, base) in [("rough", rough), ("rough_blur2", blur)] {
                assert!(
                    g.psnr >= base.psnr + 1.0,
                    "{name}, {sil} silhouette: PSNR {:.2} not 1 dB above {base_name} {:.2}",
                    g.psnr,
                    base.psnr
                );
                assert!(
                    g.ssim >= base.ssim + 0.03,
                    "{name}, {sil} silhouette: SSIM {:.3} not 0.03 above {base_name} {:.3}",
                    g.ssim,
                    base.ssim
                );
            }
        }
        assert!(
            r.silhouette_iou >= 0.9,
            "{name}: IoU {:.3}",
            r.silhouette_iou
        );
    }
}

/// Always on, small: 16 views at 320x240, 64^3 voxels, view 4 withheld; the default result
/// beats the sigma-2 blur of the rough render on PSNR and SSIM, the paper's method (patch 7)
/// beats the rough render on SSIM.
#[test]
fn temple_leave_one_out_small() {
    let (cams, imgs, masks) = load(2, &SilhouetteParams::scoring());
    let carve: Vec<Mask> = imgs
        .iter()
        .map(|i| {
            // Downscaled photos: the carving recipe at half the radii.
            threshold_silhouette(
                i,
                &SilhouetteParams {
                    dilate: 2,
                    erode: 2,
                    ..SilhouetteParams::default()
                },
            )
        })
        .collect();
    let k = cams
        .iter()
        .position(|c| c.name == "templeSR0005.png")
        .unwrap();
    let mut mm = carve.clone();
    mm[k] = masks[k].clone();
    let hull = HullParams {
        dims: [64; 3],
        ..Default::default()
    };
    let t = Instant::now();
    let (r, _) = leave_one_out(
        &cams,
        &imgs,
        &mm,
        k,
        &hull,
        &PhotoParams::default(),
        &ViewParams::default(),
    )
    .unwrap();
    eprintln!("default: {r:?} in {:?}", t.elapsed());
    let (g, blur) = (r.guided.inside, r.rough_blur2.inside);
    assert!(g.psnr > blur.psnr, "PSNR {} <= blur2 {}", g.psnr, blur.psnr);
    assert!(
        g.ssim > blur.ssim + 0.03,
        "SSIM {} not above blur2 {}",
        g.ssim,
        blur.ssim
    );
    let synth = GuidedParams::fast_for(7);
    // The paper's colours too (as `ModelParams::paper_carving` gives them): vt's default
    // colours partly seen voxels from their pixels, a better guide (rough SSIM 0.331 -> 0.353
    // here) that synthesis at patch 7 improves less (0.335 -> 0.347).
    let (p, _) = leave_one_out(
        &cams,
        &imgs,
        &mm,
        k,
        &hull,
        &PhotoParams {
            colour_partly_seen: false,
            ..Default::default()
        },
        &ViewParams::paper(synth),
    )
    .unwrap();
    eprintln!("paper: {p:?}");
    assert!(
        p.guided.inside.ssim > p.rough.inside.ssim,
        "paper: guided SSIM not above rough"
    );
}
