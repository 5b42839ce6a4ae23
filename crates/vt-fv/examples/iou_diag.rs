//! Diagnostic for templeSparseRing (reads templeSR_par.txt): per withheld view, the silhouette IoU of the visual hull, the photo hull (silhouette keeping) and the paper's carving, against several thresholded silhouettes. `cargo run --release -p vt-fv --example iou_diag -- DATA VIEWS GRID CARVE_THRESHOLD DILATE ERODE`; env VT_CLIP (clip the renders), VT_PT (photo threshold), VT_SPLAT, VT_SCORER, VT_SAVE (write IoU maps).
use std::path::Path;
use vt_fv::camera::parse_par;
use vt_fv::hull::{auto_bounds, dims_for, visual_hull, HullParams};
use vt_fv::photo::{photo_hull_keeping, PhotoParams};
use vt_fv::pipeline::iou;
use vt_fv::render::render_rough_with;
use vt_fv::silhouette::{mask_image, threshold_silhouette, SilhouetteParams};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = Path::new(&args[1]);
    let views: Vec<usize> = args[2].split(',').map(|v| v.parse().unwrap()).collect();
    let grid: usize = args[3].parse().unwrap();
    let ct: f64 = args[4].parse().unwrap();
    let (dil, ero): (u32, u32) = (args[5].parse().unwrap(), args[6].parse().unwrap());
    let save = std::env::var("VT_SAVE").ok();
    let cams = parse_par(&std::fs::read_to_string(dir.join("templeSR_par.txt")).unwrap()).unwrap();
    let images: Vec<_> = cams
        .iter()
        .map(|c| image::open(dir.join(&c.name)).unwrap().to_rgb8())
        .collect();
    let sil = |t, d, e| -> Vec<_> {
        images
            .iter()
            .map(|i| {
                threshold_silhouette(
                    i,
                    &SilhouetteParams {
                        threshold: t,
                        dilate: d,
                        erode: e,
                    },
                )
            })
            .collect()
    };
    let scorers = [
        (0.19, 10, 7),
        (0.19, 3, 3),
        (0.25, 3, 3),
        (0.25, 5, 5),
        (0.25, 10, 7),
        (0.3, 3, 3),
        (0.3, 5, 5),
    ];
    let scores: Vec<Vec<_>> = scorers.iter().map(|&(t, d, e)| sil(t, d, e)).collect();
    let carve = sil(ct, dil, ero);
    println!("scorers {scorers:?}");
    let mut acc = vec![vec![0.0; scorers.len()]; 3];
    let mut mins = vec![vec![1.0f64; scorers.len()]; 3];
    for &k in &views {
        let keep: Vec<usize> = (0..cams.len()).filter(|&i| i != k).collect();
        let sc: Vec<_> = keep.iter().map(|&i| cams[i].clone()).collect();
        let sm: Vec<_> = keep.iter().map(|&i| carve[i].clone()).collect();
        let si: Vec<_> = keep.iter().map(|&i| images[i].clone()).collect();
        let bounds = auto_bounds(&sc, &sm, &HullParams::default()).unwrap();
        let hull = HullParams {
            dims: dims_for(&bounds, grid),
            bounds: Some(bounds),
            ..Default::default()
        };
        let g = visual_hull(&sc, &sm, &hull).unwrap();
        let (w, h) = images[k].dimensions();
        let t = std::time::Instant::now();
        let vh = photo_hull_keeping(
            g.clone(),
            &sc,
            &si,
            Some(&sm),
            &PhotoParams {
                max_passes: 0,
                ..Default::default()
            },
            &mut |_, _, _| {},
        )
        .unwrap();
        let pt: f64 = std::env::var("VT_PT")
            .map(|v| v.parse().unwrap())
            .unwrap_or(20.0);
        let ph = photo_hull_keeping(
            g.clone(),
            &sc,
            &si,
            Some(&sm),
            &PhotoParams {
                threshold: pt,
                ..Default::default()
            },
            &mut |_, _, _| {},
        )
        .unwrap();
        let tp = t.elapsed().as_secs_f64();
        let pp = photo_hull_keeping(
            g.clone(),
            &sc,
            &si,
            Some(&sm),
            &PhotoParams {
                keep_silhouettes: false,
                ..Default::default()
            },
            &mut |_, _, _| {},
        )
        .unwrap();
        let sp: f64 = std::env::var("VT_SPLAT")
            .map(|v| v.parse().unwrap())
            .unwrap_or(1.5);
        let mut renders = [
            render_rough_with(&vh, &cams[k], w, h, sp),
            render_rough_with(&ph, &cams[k], w, h, sp),
            render_rough_with(&pp, &cams[k], w, h, sp),
        ];
        if std::env::var("VT_CLIP").is_ok() {
            let t = std::time::Instant::now();
            let cd: u32 = std::env::var("VT_CLIP").unwrap().parse().unwrap();
            let smd: Vec<_> = sm.to_vec();
            let _ = cd;
            for (r, m) in renders.iter_mut().zip([&vh, &ph, &pp]) {
                let cp = vt_fv::render::ClipParams {
                    behind: std::env::var("VT_BEHIND")
                        .map(|v| v.parse().unwrap())
                        .unwrap_or(3.0),
                    ..Default::default()
                };
                let n = vt_fv::render::clip_to_silhouettes(r, m, &cams[k], &sc, &smd, &cp);
                print!("clip {n} ");
            }
            println!("{:.2}s", t.elapsed().as_secs_f64());
        }
        {
            let j = std::env::var("VT_SCORER")
                .map(|v| v.parse().unwrap())
                .unwrap_or(0usize);
            let (c, m) = (&renders[1].coverage, &scores[j][k]);
            let (mut over, mut under) = (0, 0);
            for y in 0..h {
                for x in 0..w {
                    match (c.get(x, y), m.get(x, y)) {
                        (true, false) => over += 1,
                        (false, true) => under += 1,
                        _ => {}
                    }
                }
            }
            println!(
                "   ph vs scorer {j}: over {over} under {under} mask {}",
                m.count_ones()
            );
        }
        for (ri, (name, r)) in ["vh", "ph", "paper"].iter().zip(&renders).enumerate() {
            let v: Vec<f64> = scores.iter().map(|s| iou(&r.coverage, &s[k])).collect();
            for (j, x) in v.iter().enumerate() {
                acc[ri][j] += x / views.len() as f64;
                mins[ri][j] = mins[ri][j].min(*x);
            }
            let vs: Vec<String> = v.iter().map(|x| format!("{x:.3}")).collect();
            println!(
                "{k:>2} {name:<5} {}  {}",
                vs.join(" "),
                if ri == 1 {
                    format!("(vh+ph {tp:.2}s)")
                } else {
                    String::new()
                }
            );
        }
        if std::env::var("VT_H2").is_ok() {
            // rows: max bins 48..64, 64..96, 96+; cols: (R-B)/max bins of 0.05 from 0
            let mut hin = [[0u32; 10]; 3];
            let mut hout = [[0u32; 10]; 3];
            let m0 = &scores[1][k];
            for y in 0..h {
                for x in 0..w {
                    let p = images[k].get_pixel(x, y).0;
                    let mx = p[0].max(p[1]).max(p[2]) as f64;
                    if mx <= 48.0 || !m0.get(x, y) {
                        continue;
                    }
                    let r = if mx < 64.0 {
                        0
                    } else if mx < 96.0 {
                        1
                    } else {
                        2
                    };
                    let c = (((p[0] as f64 - p[2] as f64) / mx) * 20.0).clamp(0.0, 9.0) as usize;
                    if renders[1].coverage.get(x, y) {
                        hin[r][c] += 1
                    } else {
                        hout[r][c] += 1
                    }
                }
            }
            for r in 0..3 {
                println!("   max bin {r}: in {:?} out {:?}", hin[r], hout[r]);
            }
        }
        if let Some(out) = &save {
            let s = &scores[std::env::var("VT_SCORER")
                .map(|v| v.parse().unwrap())
                .unwrap_or(0usize)][k];
            let img = image::RgbImage::from_fn(w, h, |x, y| {
                let (a, b) = (s.get(x, y), renders[1].coverage.get(x, y));
                image::Rgb([
                    if a { 255 } else { 0 },
                    if b { 255 } else { 0 },
                    if a && b { 255 } else { 0 },
                ])
            });
            img.save(format!("{out}/iou_{k}.png")).unwrap();
            mask_image(s).save(format!("{out}/score_{k}.png")).unwrap();
        }
    }
    for (ri, name) in ["vh", "ph", "paper"].iter().enumerate() {
        let vs: Vec<String> = acc[ri]
            .iter()
            .zip(&mins[ri])
            .map(|(x, m)| format!("{x:.3}/{m:.3}"))
            .collect();
        println!("mean/min {name:<5} {}", vs.join(" "));
    }
}
