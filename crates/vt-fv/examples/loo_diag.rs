//! Leave-one-out diagnostics for chosen views of a data folder: saves the withheld photo, the
//! result, the rough render blurred, their error maps, the nearest photo and the silhouettes
//! as PNGs, and prints per-view scores:
//!
//! ```sh
//! cargo run --release -p vt-fv --example loo_diag -- DATA GRID OUTDIR VIEW...
//! ```

use std::path::Path;

use image::{Rgb, RgbImage};
use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::{error_map, ViewParams};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 5 {
        eprintln!("usage: loo_diag DATA GRID OUTDIR VIEW...");
        std::process::exit(2);
    }
    let data = Dataset::load(Path::new(&args[1]), &DataOptions::default()).unwrap();
    let grid: usize = args[2].parse().unwrap();
    let out = Path::new(&args[3]);
    std::fs::create_dir_all(out).unwrap();
    let model = ModelParams {
        grid,
        ..Default::default()
    };
    let mut view = ViewParams::default();
    // VT_CFG=key=value,...: texturing settings as loo_data's keys (a subset).
    if let Ok(cfg) = std::env::var("VT_CFG") {
        for pair in cfg.split(',').filter(|p| !p.is_empty()) {
            let (k, v) = pair.split_once('=').expect("key=value");
            let f = || v.parse::<f64>().unwrap();
            let t = &mut view.texture;
            match k {
                "refs" => t.references = f() as usize,
                "soft" => t.soften_sigma = f(),
                "agree" => t.agree_sd = f(),
                "reach" => t.reach_deg = f(),
                "eps" => t.eps_deg = f(),
                "slack" => view.clip.as_mut().expect("clip").slack = f() as u32,
                _ => panic!("unknown key {k}"),
            }
        }
    }
    if args[4] == "masks" {
        // Every photo darkened outside its carving silhouette.
        for (k, (img, m)) in data.images.iter().zip(&data.masks).enumerate() {
            let o = RgbImage::from_fn(img.width(), img.height(), |x, y| {
                let p = img.get_pixel(x, y).0;
                if m.get(x, y) {
                    Rgb(p)
                } else {
                    Rgb(p.map(|c| c / 4))
                }
            });
            o.save(out.join(format!("mask_{k:02}.png"))).unwrap();
            img.save(out.join(format!("photo_{k:02}.png"))).unwrap();
            let b = image::GrayImage::from_fn(img.width(), img.height(), |x, y| {
                image::Luma([if m.get(x, y) { 255 } else { 0 }])
            });
            b.save(out.join(format!("bin_{k:02}.png"))).unwrap();
        }
        return;
    }
    for v in &args[4..] {
        let k: usize = v.parse().unwrap();
        let (r, imgs) = data.leave_one_out(k, &model, &view).unwrap();
        let sil = &data.score_masks[k];
        let carve = &data.masks[k];
        println!(
            "view {k} ({}): result {:.2} blur2 {:.2} rough {:.2} nearest {:.2} (ref {}) iou {:.3}",
            data.cams[k].name,
            r.guided.inside.psnr,
            r.rough_blur2.inside.psnr,
            r.rough.inside.psnr,
            r.nearest_photo.inside.psnr,
            r.reference,
            r.silhouette_iou
        );
        let save = |name: &str, img: &RgbImage| {
            img.save(out.join(format!("v{k:02}_{name}.png"))).unwrap();
        };
        save("truth", &imgs.truth);
        save("result", &imgs.guided);
        save("blur2", &imgs.rough_blur2);
        save("nearest", &imgs.nearest_photo);
        save("err_result", &error_map(&imgs.guided, &imgs.truth, sil));
        save("err_blur2", &error_map(&imgs.rough_blur2, &imgs.truth, sil));
        let (w, h) = imgs.truth.dimensions();
        // Silhouettes: red = scoring only, green = carving only, white = both.
        let m = RgbImage::from_fn(w, h, |x, y| {
            let (a, b) = (sil.get(x, y), carve.get(x, y));
            Rgb([
                if a { 255 } else { 0 },
                if b { 255 } else { 0 },
                if a && b { 255 } else { 0 },
            ])
        });
        save("sil", &m);
        // Where the result is worse than the blur (red) or better (green), scaled.
        let d = RgbImage::from_fn(w, h, |x, y| {
            if !sil.get(x, y) {
                return Rgb([0, 0, 0]);
            }
            let t = imgs.truth.get_pixel(x, y).0;
            let e = |p: [u8; 3]| -> f64 {
                (0..3)
                    .map(|c| (p[c] as f64 - t[c] as f64).powi(2))
                    .sum::<f64>()
            };
            let diff = e(imgs.guided.get_pixel(x, y).0) - e(imgs.rough_blur2.get_pixel(x, y).0);
            let g = (diff.abs().sqrt() * 2.0).min(255.0) as u8;
            if diff > 0.0 {
                Rgb([g, 0, 0])
            } else {
                Rgb([0, g, 0])
            }
        });
        save("diff", &d);
    }
}
