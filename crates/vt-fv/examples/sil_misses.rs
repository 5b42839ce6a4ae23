//! Diagnostic: [`vt_fv::render::silhouette_misses`] of a data folder at slacks 0..=3.
//! `cargo run --release -p vt-fv --example sil_misses -- DATA [STRIDE]`
use std::path::Path;

use vt_fv::dataset::{DataOptions, Dataset};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let d = Dataset::load(Path::new(&args[1]), &DataOptions::default()).unwrap();
    let stride = args.get(2).map_or(1, |v| v.parse().unwrap());
    let bounds = d.volume(None).unwrap();
    let t = std::time::Instant::now();
    let close = std::env::var("CLOSE").map_or(4, |v| v.parse().unwrap());
    let m = vt_fv::render::silhouette_misses(&d.cams, &d.masks, &bounds, close, 3, stride);
    println!("{}: {m:.4?} in {:.2} s", args[1], t.elapsed().as_secs_f64());
}
