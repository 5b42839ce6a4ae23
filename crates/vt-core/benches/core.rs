//! Criterion benches of vt-core's hot loops at thesis scale (640x360, 500 frames).

use criterion::{criterion_group, criterion_main, Criterion};
use image::RgbImage;
use vt_core::blur::{gaussian_blur_into, GaussianParams};
use vt_core::loops::{find_loop, LoopParams};
use vt_core::median::MedianAccumulator;
use vt_core::Mask;

/// Masks of an ellipse swaying with period 37 over 640x360, like a plant in wind.
fn masks(n: usize) -> Vec<Mask> {
    (0..n)
        .map(|f| {
            let ph = (f % 37) as f64 / 37.0 * std::f64::consts::TAU;
            let (cx, cy) = (320.0 + 60.0 * ph.sin(), 180.0 + 20.0 * (2.0 * ph).sin());
            Mask::from_fn(640, 360, |x, y| {
                let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                dx * dx / 6400.0 + dy * dy / 3600.0 < 1.0
            })
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let ms = masks(500);
    let mut g = c.benchmark_group("system_a");
    g.sample_size(10);
    g.bench_function("loop_search_500x640x360", |b| {
        b.iter(|| find_loop(&ms, &LoopParams::default(), "bench").unwrap())
    });
    let frame = RgbImage::from_fn(640, 360, |x, y| {
        image::Rgb([x as u8, y as u8, (x ^ y) as u8])
    });
    let mut out = RgbImage::new(640, 360);
    g.bench_function("gaussian3_640x360", |b| {
        b.iter(|| gaussian_blur_into(&frame, &GaussianParams::default(), &mut out).unwrap())
    });
    let mut acc = MedianAccumulator::new(640, 360);
    g.bench_function("median_push_640x360", |b| {
        b.iter(|| {
            if acc.n_frames() >= MedianAccumulator::MAX_FRAMES - 1 {
                acc = MedianAccumulator::new(640, 360);
            }
            acc.push(&frame).unwrap()
        })
    });
    let yuv = vt_core::yuv::Yuv420Image::from_raw(
        768,
        576,
        vt_core::yuv::YuvMatrix::Bt601,
        vt_core::yuv::YuvRange::Limited,
        (0..vt_core::yuv::Yuv420Image::byte_len(768, 576))
            .map(|i| (i * 7 % 251) as u8)
            .collect(),
    )
    .unwrap();
    let mut rgb = RgbImage::new(768, 576);
    g.bench_function("yuv420_to_rgb_768x576", |b| {
        b.iter(|| yuv.to_rgb_into(&mut rgb))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
