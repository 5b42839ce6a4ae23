//! The object store's size and fidelity at several qualities on one video:
//! `store_rate VIDEO [QUALITY...]` (qualities as `vt analyze --store-quality` takes them; default
//! 12 16 crf14 crf16 crf18 crf20). Every frame stored whole (x264 where ffmpeg has it), read
//! back and compared with the decoded source: bytes against the video's, mean and worst-frame
//! PSNR, encode seconds.
use std::path::Path;

use vt_io::objects::{H264Encoder, ObjectStore, ObjectWriter, StoreQuality};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let video = Path::new(&args[1]);
    let mut frames = Vec::new();
    let mut src = vt_io::frames::ViewSource::open(video).unwrap();
    src.as_source()
        .for_each_frame(&mut |_, f| {
            frames.push(f.clone());
            Ok(())
        })
        .unwrap();
    let (w, h) = frames[0].dimensions();
    let source = std::fs::metadata(video).unwrap().len() as f64;
    let qualities: Vec<StoreQuality> = if args.len() > 2 {
        args[2..].iter().map(|q| q.parse().unwrap()).collect()
    } else {
        ["12", "16", "crf14", "crf16", "crf18", "crf20"]
            .iter()
            .map(|q| q.parse().unwrap())
            .collect()
    };
    let mask = vt_core::Mask::from_fn(w, h, |_, _| true);
    let dir = tempfile::tempdir().unwrap();
    println!(
        "{} ({} frames, {w}x{h}, {:.1} MB)",
        video.display(),
        frames.len(),
        source / 1e6
    );
    for q in qualities {
        let path = dir.path().join("o.bin");
        let t = std::time::Instant::now();
        let mut writer =
            ObjectWriter::create_with_encoder(&path, w, h, q, H264Encoder::Auto).unwrap();
        for f in &frames {
            writer.push(&mask, f).unwrap();
        }
        writer.finish().unwrap();
        let secs = t.elapsed().as_secs_f64();
        let bytes = std::fs::metadata(&path).unwrap().len() as f64;
        let store = ObjectStore::load(&path).unwrap();
        let mut patch = vt_core::render::ObjectPatch::default();
        let (mut sum, mut worst) = (0.0, f64::MAX);
        for (i, f) in frames.iter().enumerate() {
            store.decode_into(i, &mut patch).unwrap();
            let se: f64 = patch
                .rgb
                .iter()
                .zip(f.as_raw())
                .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
                .sum();
            let mse = se / f.as_raw().len() as f64;
            let psnr = 10.0 * (255.0f64 * 255.0 / mse.max(1e-10)).log10();
            sum += psnr;
            worst = worst.min(psnr);
        }
        println!(
            "{q:>6} ({}): {:.2}x the video ({:.1} MB), {:.2} dB mean, {:.2} worst frame, encode {secs:.2} s",
            store.quality(),
            bytes / source,
            bytes / 1e6,
            sum / frames.len() as f64,
            worst
        );
    }
}
