//! New views of the synthetic object (vt-synth's ray-cast scene, 8 photos, truth at extra
//! angles) for several texturing settings, as the report's "references" knob measures them:
//!
//! ```sh
//! cargo run --release -p vt-fv --example synth_tex -- SIZE GRID [name:key=value,...]...
//! ```
//!
//! Keys: `common/settings.rs`'s texturing and clip keys (the model is built here). Prints the
//! mean PSNR and SSIM inside the true silhouettes.

use vt_fv::dataset::ModelParams;
use vt_fv::eval::{psnr, ssim};
use vt_fv::pipeline::{novel_view, ViewParams};
use vt_synth::object::{generate, SceneParams};

#[path = "common/settings.rs"]
mod settings;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: u32 = args.get(1).map_or(200, |v| v.parse().unwrap());
    let grid: usize = args.get(2).map_or(128, |v| v.parse().unwrap());
    let d = generate(&SceneParams {
        width: size,
        height: size,
        extra_angles_deg: vec![5.0, 10.0],
        ..Default::default()
    })
    .unwrap()
    .try_map_cameras(|c| vt_fv::Camera::new(c.name.clone(), c.k, c.r, c.t))
    .unwrap();
    let model = vt_fv::build_model(
        &d.cameras,
        &d.photos,
        &d.masks,
        &vt_fv::hull::HullParams {
            dims: [grid; 3],
            ..Default::default()
        },
        &vt_fv::PhotoParams::default(),
        &mut |_, _, _| {},
    )
    .unwrap();
    let configs: Vec<String> = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec!["default:".into()]
    };
    for cfg in &configs {
        let (name, kv) = cfg.split_once(':').unwrap_or((cfg, ""));
        let mut view = ViewParams::default();
        settings::apply(kv, &mut view, &mut ModelParams::default());
        let (w, h) = d.photos[0].dimensions();
        let (mut p, mut s) = (0.0, 0.0);
        for (k, cam) in d.extra_cameras.iter().enumerate() {
            let v = novel_view(&model, &d.cameras, &d.photos, cam, w, h, &view).unwrap();
            let mask = Some(&d.extra_masks[k]);
            p += psnr(&v.guided, &d.extra_truth[k], mask).unwrap();
            s += ssim(&v.guided, &d.extra_truth[k], mask).unwrap();
        }
        let n = d.extra_cameras.len() as f64;
        println!("{name:<12} PSNR {:.2} SSIM {:.3}", p / n, s / n);
    }
}
