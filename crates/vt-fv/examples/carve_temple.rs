//! Leave-one-out on a data folder (templeSparseRing) for the photo hull settings of the
//! environment: mean PSNR/SSIM inside the withheld photo's scoring silhouette of the rough
//! render and of the default new view, and the silhouette IoU, over every `STEP`-th view.
//!
//! ```sh
//! cargo run --release -p vt-fv --example carve_temple -- DATA GRID STEP [SCALE]
//! ```

use std::path::Path;

use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::ViewParams;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scale: f64 = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(1.0);
    let data = Dataset::load(
        Path::new(&args[1]),
        &DataOptions {
            scale,
            ..Default::default()
        },
    )
    .unwrap();
    let grid: usize = args[2].parse().unwrap();
    let step: usize = args[3].parse().unwrap();
    let model = ModelParams {
        grid,
        ..Default::default()
    };
    let view = ViewParams::default();
    let (mut n, mut acc) = (0.0, [0.0f64; 6]);
    let t = std::time::Instant::now();
    for k in (0..data.cams.len()).step_by(step) {
        let (r, _) = data.leave_one_out(k, &model, &view).unwrap();
        for (a, v) in acc.iter_mut().zip([
            r.rough.inside.psnr,
            r.rough.inside.ssim,
            r.guided.inside.psnr,
            r.guided.inside.ssim,
            r.silhouette_iou,
            r.rough_blur2.inside.psnr,
        ]) {
            *a += v;
        }
        n += 1.0;
    }
    let m = acc.map(|a| a / n);
    println!(
        "rough {:.2} dB / {:.3}  default {:.2} dB / {:.3}  IoU {:.4}  blur2 {:.2}  ({} views, {:.1} s)",
        m[0],
        m[1],
        m[2],
        m[3],
        m[4],
        m[5],
        n,
        t.elapsed().as_secs_f64()
    );
}
