//! Times `measure_seams` on a scene: `seam_time SCENE [STEPS [ROWS [SWITCHES]]]`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let loaded = vt_io::scene::LoadedScene::open(std::path::Path::new(&args[1])).unwrap();
    let mut sampling = vt_core::seam::SeamSampling::default();
    if let Some(s) = args.get(2) {
        sampling.steps = s.parse().unwrap();
    }
    if let Some(r) = args.get(3) {
        sampling.rows = r.parse().unwrap();
    }
    if let Some(r) = args.get(4) {
        sampling.switches = r.parse().unwrap();
    }
    let t = std::time::Instant::now();
    let seams = vt_core::seam::measure_seams(
        &loaded.render,
        &loaded.objects,
        vt_core::render::RenderParams::default(),
        sampling,
    )
    .unwrap();
    println!("{:.2} s: {seams:.3?}", t.elapsed().as_secs_f64());
}
