//! Leave-one-out over every view of any data folder `vt fv` reads (par, COLMAP, matrices), for
//! several texturing settings side by side:
//!
//! ```sh
//! cargo run --release -p vt-fv --example loo_data -- DATA GRID [name:key=value,...]...
//! ```
//!
//! Keys: `common/settings.rs`'s (texturing, photo threshold, clip). Prints, per setting, the
//! mean PSNR inside the silhouette of the result and of the rough render blurred (sigma 2), and
//! the smallest per-view lead; then checks that do not reward an outline grown past the object:
//! the lead over the silhouette united with each image's own coverage, the result's PSNR there,
//! the IoU of the result's coverage with the silhouette, and the PSNR of the result pasted onto
//! the truth's mean backdrop colour over the silhouette grown by 8 px (a missing object pixel
//! and a painted backdrop pixel cost alike).

use std::path::Path;

use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::{score_with_region, ViewParams};

#[path = "common/settings.rs"]
mod settings;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: loo_data DATA GRID [name:key=value,...]...");
        std::process::exit(2);
    }
    let data = Dataset::load(Path::new(&args[1]), &DataOptions::default()).unwrap();
    let grid: usize = args[2].parse().unwrap();
    let configs: Vec<String> = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec!["default:".into()]
    };
    for cfg in &configs {
        let (name, kv) = cfg.split_once(':').unwrap_or((cfg, ""));
        let mut view = ViewParams::default();
        let mut model = ModelParams {
            grid,
            ..Default::default()
        };
        settings::apply(kv, &mut view, &mut model);
        let (mut sum, mut min, mut below, mut base, mut secs) = (0.0, f64::INFINITY, 0, 0.0, 0.0);
        let n = data.cams.len();
        let mut per = Vec::new();
        let (mut ulead, mut usum) = (Vec::new(), 0.0);
        let (mut iou_sum, mut uabs, mut cabs) = (0.0, 0.0, 0.0);
        let mut ssim_sum = 0.0;
        for k in 0..n {
            let t = std::time::Instant::now();
            let (r, imgs) = data.leave_one_out(k, &model, &view).unwrap();
            secs += t.elapsed().as_secs_f64();
            let lead = r.guided.inside.psnr - r.rough_blur2.inside.psnr;
            // Fair to a region grown past the object: PSNR over the truth's silhouette united
            // with the image's own coverage (the rough render's for the blurred baseline).
            let sil = &data.score_masks[k];
            let ug = score_with_region(&imgs.guided, &imgs.truth, sil, &imgs.guided).unwrap();
            let ub = score_with_region(&imgs.rough_blur2, &imgs.truth, sil, &imgs.rough).unwrap();
            ulead.push(format!("{:+.1}", ug.psnr - ub.psnr));
            let cover = vt_fv::silhouette::Mask::from_fn(sil.width(), sil.height(), |x, y| {
                imgs.guided.get_pixel(x, y).0 != [0, 0, 0]
            });
            iou_sum += vt_fv::pipeline::iou(&cover, sil);
            // Symmetric check: the result pasted onto the truth's mean backdrop colour, scored
            // over the silhouette grown by 8 px (missing object pixels and painted backdrop
            // pixels cost alike).
            let band = sil.dilate(8);
            let (mut bg, mut nb) = ([0.0f64; 3], 0.0f64);
            for (x, y, p) in imgs.truth.enumerate_pixels() {
                if !band.get(x, y) {
                    (0..3).for_each(|c| bg[c] += p.0[c] as f64);
                    nb += 1.0;
                }
            }
            let bg = bg.map(|v| (v / nb.max(1.0)).round() as u8);
            let comp = image::RgbImage::from_fn(sil.width(), sil.height(), |x, y| {
                if cover.get(x, y) {
                    *imgs.guided.get_pixel(x, y)
                } else {
                    image::Rgb(bg)
                }
            });
            cabs += vt_fv::eval::psnr(&comp, &imgs.truth, Some(&band)).unwrap();
            usum += ug.psnr - ub.psnr;
            uabs += ug.psnr;
            per.push(format!("{lead:+.2}"));
            sum += r.guided.inside.psnr;
            ssim_sum += r.guided.inside.ssim;
            base += r.rough_blur2.inside.psnr;
            min = min.min(lead);
            below += usize::from(lead < 1.0);
        }
        println!(
            "{name:<12} result {:.2} (SSIM {:.3}) blur2 {:.2} lead mean {:+.2} min {:+.2} below 1 dB {below}/{n} | {:.2} s/view | {}",
            sum / n as f64,
            ssim_sum / n as f64,
            base / n as f64,
            (sum - base) / n as f64,
            min,
            secs / n as f64,
            per.join(" ")
        );
        println!(
            "{:<12} over silhouette + own coverage: lead mean {:+.2}, result {:.2}, result IoU {:.4}, on the backdrop {:.2} | {}",
            "",
            usum / n as f64,
            uabs / n as f64,
            iou_sum / n as f64,
            cabs / n as f64,
            ulead.join(" ")
        );
    }
}
