//! Leave-one-out measurement over several settings, for the tables in the README:
//!
//! ```sh
//! cargo run --release -p vt-fv --example loo -- DATA VIEWS GRID [CONFIG...]
//! ```
//!
//! DATA: a folder with one `*_par.txt` and its images (scored inside
//! `SilhouetteParams::scoring()` unless the keys `sthr`, `sdil`, `sero` say otherwise, carved
//! from `SilhouetteParams::carving()` unless `dil`/`ero`/`thr` say otherwise); VIEWS: `1,2,3` (0-based); GRID: voxels along the longest side; CONFIG:
//! `name:key=value,...` with keys `method` (textured|paper|refine), `common/settings.rs`'s
//! texturing and clip keys, `threshold`, `keep` (0|1), `patch`, `cagree` (carving: `Consistency::Agree` share), `cagreemin` (its fewest cameras). Prints one row per view
//! and configuration, then the means.

use std::path::Path;

use vt_fv::camera::parse_par;
use vt_fv::guided::GuidedParams;
use vt_fv::hull::{auto_bounds, dims_for, HullParams};
use vt_fv::pipeline::{leave_one_out, Method, ViewParams};
use vt_fv::silhouette::{threshold_silhouette, SilhouetteParams};
use vt_fv::PhotoParams;

#[path = "common/settings.rs"]
mod settings;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: loo DATA VIEWS GRID [name:key=value,...]...");
        std::process::exit(2);
    }
    let dir = Path::new(&args[1]);
    let par = std::fs::read_dir(dir)
        .expect("data folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.to_string_lossy().ends_with("_par.txt"))
        .expect("a *_par.txt");
    let cams = parse_par(&std::fs::read_to_string(&par).unwrap()).unwrap();
    let images: Vec<_> = cams
        .iter()
        .map(|c| image::open(dir.join(&c.name)).unwrap().to_rgb8())
        .collect();
    let views: Vec<usize> = args[2].split(',').map(|v| v.parse().unwrap()).collect();
    let grid: usize = args[3].parse().unwrap();
    let configs: Vec<String> = if args.len() > 4 {
        args[4..].to_vec()
    } else {
        vec!["default:".into()]
    };
    let mut means = Vec::new();
    for cfg in &configs {
        let (name, kv) = cfg.split_once(':').unwrap_or((cfg, ""));
        let mut view = ViewParams::default();
        let mut photo = PhotoParams::default();
        let mut sil = SilhouetteParams::carving();
        let mut scoring = SilhouetteParams::scoring();
        for pair in kv.split(',').filter(|p| !p.is_empty()) {
            let (k, v) = pair.split_once('=').expect("key=value");
            let f = || v.parse::<f64>().unwrap();
            match k {
                "method" => match v {
                    "paper" => view = ViewParams::paper(view.guided.clone()),
                    "refine" => view.refine = true,
                    "vote" => {
                        view.refine = true;
                        view.voting = Some(Default::default());
                    }
                    _ => view.method = Method::Textured,
                },
                "threshold" => photo.threshold = f(),
                "keep" => photo.keep_silhouettes = f() != 0.0,
                "cagree" => photo.consistency = vt_fv::Consistency::Agree(f()),
                "cagreemin" => {
                    let share = match photo.consistency {
                        vt_fv::Consistency::Agree(s) => s,
                        _ => 0.8,
                    };
                    photo.consistency = vt_fv::Consistency::AgreeFrom {
                        share,
                        min: f() as usize,
                    }
                }
                "dil" => sil.dilate = f() as u32,
                "thr" => sil.threshold = f(),
                "sthr" => scoring.threshold = f(),
                "sdil" => scoring.dilate = f() as u32,
                "sero" => scoring.erode = f() as u32,
                "clip" => {
                    if f() == 0.0 {
                        view.clip = None
                    }
                }
                "pthr" => photo.threshold = f(),
                "vlevels" => view.voting.as_mut().expect("method=vote first").levels = f() as usize,
                "vgw" => {
                    view.voting
                        .as_mut()
                        .expect("method=vote first")
                        .guide_weight = f()
                }
                "vem" => view.voting.as_mut().expect("method=vote first").em_iters = f() as usize,
                "ero" => sil.erode = f() as u32,
                "patch" => view.guided = GuidedParams::fast_for(f() as usize),
                _ if settings::apply_view(k, v, &mut view) => {}
                _ => panic!("unknown key {k}"),
            }
        }
        let masks: Vec<_> = images
            .iter()
            .map(|i| threshold_silhouette(i, &scoring))
            .collect();
        // Silhouettes for the model (the scored view keeps the scoring ones).
        let model_masks: Vec<_> = images
            .iter()
            .map(|i| threshold_silhouette(i, &sil))
            .collect();
        let mut acc = [0.0f64; 17];
        for &k in &views {
            let keep: Vec<usize> = (0..cams.len()).filter(|&i| i != k).collect();
            let sc: Vec<_> = keep.iter().map(|&i| cams[i].clone()).collect();
            let sm: Vec<_> = keep.iter().map(|&i| model_masks[i].clone()).collect();
            let mut mm = model_masks.clone();
            mm[k] = masks[k].clone();
            let t = std::time::Instant::now();
            let bounds = auto_bounds(&sc, &sm, &HullParams::default()).unwrap();
            let hull = HullParams {
                dims: dims_for(&bounds, grid),
                bounds: Some(bounds),
                ..Default::default()
            };
            let (r, imgs) = leave_one_out(&cams, &images, &mm, k, &hull, &photo, &view).unwrap();
            // Also inside the Middlebury recipe's silhouette (0.19, dilate 10, erode 7).
            let recipe = threshold_silhouette(&images[k], &SilhouetteParams::default());
            let sc = |img| {
                vt_fv::pipeline::score(img, &imgs.truth, &recipe)
                    .unwrap()
                    .inside
            };
            let (ob, og) = (sc(&imgs.rough_blur2), sc(&imgs.guided));
            if let Ok(out) = std::env::var("VT_SAVE") {
                let e = vt_fv::pipeline::error_map(&imgs.guided, &imgs.truth, &masks[k]);
                e.save(format!("{out}/{name}_{k}_error.png")).unwrap();
                imgs.guided.save(format!("{out}/{name}_{k}.png")).unwrap();
                imgs.truth.save(format!("{out}/truth_{k}.png")).unwrap();
            }
            let secs = t.elapsed().as_secs_f64();
            let row = [
                r.nearest_photo.inside.psnr,
                r.rough.inside.psnr,
                r.rough_blur2.inside.psnr,
                r.guided.inside.psnr,
                r.nearest_photo.inside.ssim,
                r.rough.inside.ssim,
                r.rough_blur2.inside.ssim,
                r.guided.inside.ssim,
                r.silhouette_iou,
                secs,
                r.model_secs(),
                r.rough_blur2.whole.psnr,
                r.guided.whole.psnr,
                ob.psnr,
                og.psnr,
                ob.ssim,
                og.ssim,
            ];
            println!(
                "{name:<14} view {k:>2}: PSNR photo {:.2} rough {:.2} blur2 {:.2} guided {:.2} | SSIM {:.3} {:.3} {:.3} {:.3} | IoU {:.3} | whole image blur2 {:.2} guided {:.2} | recipe sil. blur2 {:.2} / {:.3} guided {:.2} / {:.3} | {:.2} s (model {:.2}) {:?}",
                row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[11], row[12], row[13], row[15], row[14], row[16], row[9], row[10], r.times
            );
            for (a, v) in acc.iter_mut().zip(row) {
                *a += v / views.len() as f64;
            }
        }
        means.push((name.to_string(), acc));
    }
    println!("\nmeans over views {:?}, grid {grid}:", views);
    println!(
        "config          PSNR photo  rough  blur2 guided | SSIM photo rough blur2 guided | IoU | whole blur2 guided | recipe blur2 guided | s"
    );
    for (name, m) in means {
        println!(
            "{name:<14} {:>6.2} {:>6.2} {:>6.2} {:>6.2} | {:.3} {:.3} {:.3} {:.3} | {:.3} | {:>6.2} {:>6.2} | {:.2} / {:.3} {:.2} / {:.3} | {:.2}",
            m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[11], m[12], m[13], m[15], m[14], m[16], m[9]
        );
    }
}
