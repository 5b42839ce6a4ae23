//! A data folder's test set (`vt fv eval DATA --test FILE`) under several settings side by
//! side:
//!
//! ```sh
//! cargo run --release -p vt-fv --example test_knobs -- DATA TESTFILE [name:key=value,...]...
//! ```
//!
//! Keys: `common/settings.rs`'s (a model is built for each distinct model setting). Prints per setting the means of the whole-image PSNR and SSIM,
//! the PSNR inside the test silhouettes, and the seconds per view.

use std::path::Path;

use vt_fv::dataset::{DataOptions, Dataset, ModelParams, TestSummary};
use vt_fv::pipeline::ViewParams;

#[path = "common/settings.rs"]
mod settings;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: test_knobs DATA TESTFILE [name:key=value,...]...");
        std::process::exit(2);
    }
    let dir = Path::new(&args[1]);
    let train = Dataset::load(dir, &DataOptions::default()).unwrap();
    let test = Dataset::load_set(&dir.join(&args[2]), &DataOptions::default()).unwrap();
    // GEOMETRY=DIR builds the model from another folder's photos of the same scene (the same
    // world frame, e.g. all the training views) and textures from DATA's: the texturing's
    // ceiling with better geometry.
    let geometry = std::env::var_os("GEOMETRY")
        .map(|d| Dataset::load(Path::new(&d), &DataOptions::default()).unwrap());
    let configs: Vec<String> = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec!["default:".into()]
    };
    // One model per distinct model setting, each setting's views from its own.
    let mut models: Vec<(ModelParams, vt_fv::VoxelModel, f64)> = Vec::new();
    for cfg in &configs {
        let (name, kv) = cfg.split_once(':').unwrap_or((cfg, ""));
        let mut view = ViewParams::default();
        let mut m = ModelParams::default();
        settings::apply(kv, &mut view, &mut m);
        if !models.iter().any(|(p, _, _)| *p == m) {
            let t = std::time::Instant::now();
            let (model, _) = geometry
                .as_ref()
                .unwrap_or(&train)
                .build_without(None, &m, &mut |_, _, _| {})
                .unwrap();
            models.push((m.clone(), model, t.elapsed().as_secs_f64()));
        }
        let (_, model, model_secs) = models.iter().find(|(p, _, _)| *p == m).unwrap();
        let (model, model_secs) = (model, *model_secs);
        let (views, imgs) = train
            .score_test_set(model, &test, &view, &mut |_| {})
            .unwrap();
        let s = TestSummary::new(
            view.name(),
            train.background,
            train.cams.len(),
            model_secs,
            views,
        );
        if let Some(d) = std::env::var_os("SAVE") {
            let d = Path::new(&d).join(name);
            std::fs::create_dir_all(&d).unwrap();
            vt_fv::dataset::write_test_outputs(&d, &s, &imgs, 4).unwrap();
        }
        println!(
            "{name:>12}: whole {:.2} dB / {:.3}, inside {:.2} dB, IoU {:.3}, model {:.1} s, {:.2} s a view",
            s.whole.psnr, s.whole.ssim, s.inside.psnr, s.coverage_iou, model_secs, s.view_secs_median
        );
    }
}
