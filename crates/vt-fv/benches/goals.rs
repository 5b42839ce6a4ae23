//! System B's speed goals (issue #24 item 7) on a 36-photo 400x300 set, through the same library
//! calls as `vt fv hull`, `render --model`, `orbit` and `eval`: the model once (visual hull and
//! photo hull at the default grid), each further view (textured, the default method), a
//! 72-frame orbit (no encoding) and one leave-one-out. Each figure is the median of `RUNS`
//! runs, printed beside its goal; the machine's cores are whatever rayon finds.
//!
//! The set is `vt synth object`'s scene with 36 cameras at 400x300, written to a temporary
//! folder with its par file and masks and loaded as a user's folder is.
//!
//! ```sh
//! cargo bench -p vt-fv --bench goals
//! ```

use std::time::Instant;

use vt_fv::camera::Ring;
use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::{novel_view_in, ViewParams};
use vt_fv::texture::model_centre;
use vt_synth::object::{format_par, generate, SceneParams};

const RUNS: usize = 5;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn timed<T>(mut f: impl FnMut() -> T) -> (f64, T) {
    let mut secs = Vec::new();
    let mut last = None;
    for _ in 0..RUNS {
        let t = Instant::now();
        last = Some(f());
        secs.push(t.elapsed().as_secs_f64());
    }
    (median(secs), last.expect("RUNS > 0"))
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` passes nothing: run either way.
    let dir = tempfile::tempdir().expect("a temporary folder");
    let scene = generate(&SceneParams {
        n_views: 36,
        width: 400,
        height: 300,
        extra_angles_deg: vec![],
        ..Default::default()
    })
    .expect("the synthetic scene");
    std::fs::create_dir(dir.path().join("masks")).unwrap();
    let mut cams = scene.cameras.clone();
    for (i, cam) in cams.iter_mut().enumerate() {
        cam.name = format!("view_{i:02}.png");
        scene.photos[i].save(dir.path().join(&cam.name)).unwrap();
        let m = &scene.masks[i];
        image::GrayImage::from_raw(m.width(), m.height(), m.to_bytes())
            .unwrap()
            .save(dir.path().join("masks").join(&cam.name))
            .unwrap();
    }
    std::fs::write(dir.path().join("object_par.txt"), format_par(&cams)).unwrap();
    let d = Dataset::load(dir.path(), &DataOptions::default()).expect("the set loads");
    let (w, h) = d.size();
    let m = ModelParams::default();
    let view = ViewParams::default();
    println!(
        "System B speed goals: {} photos {w}x{h} (synthetic object), grid {}, median of {RUNS} runs, {} threads",
        d.cams.len(),
        m.grid,
        rayon::current_num_threads()
    );

    let (model_secs, (model, _)) = timed(|| d.build_without(None, &m, &mut |_, _, _| {}).unwrap());
    let ring = Ring::fit(&d.cams).unwrap();
    let target = model_centre(&model);
    let cam = ring.camera(15.0, &target).unwrap();
    let (view_secs, _) = timed(|| {
        novel_view_in(
            &model,
            &d.cams,
            &d.images,
            Some(&d.masks),
            &cam,
            w,
            h,
            &view,
        )
        .unwrap()
    });
    let (orbit_secs, steady) = timed(|| {
        vt_fv::orbit::orbit::<vt_fv::Error>(
            &model,
            &d.cams,
            &d.images,
            Some(&d.masks),
            &ring,
            &target,
            72,
            (w, h),
            &view,
            &mut |_, _, _| Ok(()),
        )
        .unwrap()
    });
    let (loo_secs, _) = timed(|| d.leave_one_out(5, &m, &view).unwrap());
    let row = |what: &str, secs: f64, goal: f64| {
        println!(
            "  {what:<34} {secs:>7.3} s   goal <= {goal:>4.1} s   {}",
            if secs <= goal { "met" } else { "MISSED" }
        )
    };
    row("model once (visual + photo hull)", model_secs, 3.0);
    row("each further view (textured)", view_secs, 0.2);
    row("72-frame orbit (no encoding)", orbit_secs, 15.0);
    row("leave-one-out (model + view + scores)", loo_secs, 4.0);
    println!(
        "  orbit steadiness: largest/median frame step {:.2} (goal <= 2)",
        steady.ratio()
    );
}
