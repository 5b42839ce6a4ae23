//! Times `measure_seams` on a scene: `seam_time SCENE [SAMPLES]`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let loaded = vt_io::scene::LoadedScene::open(std::path::Path::new(&args[1])).unwrap();
    let samples: usize = args.get(2).map_or(32, |s| s.parse().unwrap());
    let t = std::time::Instant::now();
    let seams = vt_core::seam::measure_seams(
        &loaded.render,
        &loaded.objects,
        vt_core::render::RenderParams::default(),
        samples,
    )
    .unwrap();
    println!("{:.2} s: {seams:.3?}", t.elapsed().as_secs_f64());
}
