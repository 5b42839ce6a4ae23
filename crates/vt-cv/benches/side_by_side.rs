//! vt-core and vt-cv (OpenCV) side by side on the same inputs, one criterion group per
//! operation, then a table of time ratios (vt-core / OpenCV) from a short `Instant` loop
//! (median of several runs), so the ratio can be read without digging in criterion's files:
//! wall-clock and CPU time (all threads, the process CPU clock) per call, with the load
//! average, since on a shared machine the CPU times are the figures the load does not move.
//!
//! Inputs follow the thesis's scale: 640x360 frames, a 3x3 Gaussian, 100 frames for the median
//! (at 320x180 to bound memory), 200 masks for the XOR cost matrix.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, Criterion, Throughput};
use image::RgbImage;
use nalgebra::Matrix3;
use vt_core::analysis::MaskParams;
use vt_core::blur::GaussianParams;
use vt_core::warp::Interpolation;
use vt_core::{Homography, Mask};

use vt_core::rng::mix_at as mix;

/// A textured frame with a blob at `shift`, plus noise: real-looking enough for timing.
fn frame(w: u32, h: u32, seed: u64, shift: f64) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let (xf, yf) = (x as f64, y as f64);
        let base = 110.0 + 60.0 * (xf * 0.07).sin() * (yf * 0.05).cos();
        let blob = if (xf - w as f64 * 0.3 - shift).powi(2) + (yf - h as f64 * 0.5).powi(2)
            < (h as f64 * 0.15).powi(2)
        {
            80.0
        } else {
            0.0
        };
        let n = (mix(seed, (y * w + x) as u64) % 7) as f64;
        let v = |o: f64| (base + blob + n + o).clamp(0.0, 255.0) as u8;
        image::Rgb([v(0.0), v(-30.0), v(20.0)])
    })
}

fn masks(n: usize, w: u32, h: u32) -> Vec<Mask> {
    (0..n)
        .map(|f| {
            let ph = f as f64 / 23.0 * std::f64::consts::TAU;
            let (cx, cy) = (
                w as f64 * (0.5 + 0.2 * ph.sin()),
                h as f64 * (0.5 + 0.1 * (2.0 * ph).cos()),
            );
            Mask::from_fn(w, h, |x, y| {
                (x as f64 - cx).powi(2) / 4900.0 + (y as f64 - cy).powi(2) / 1600.0 < 1.0
            })
        })
        .collect()
}

fn homography() -> Homography {
    Homography::from_matrix(Matrix3::new(
        0.97, -0.05, 12.0, 0.04, 1.01, -8.0, 3e-5, -2e-5, 1.0,
    ))
    .expect("well-conditioned")
}

/// CPU time of this process so far, nanoseconds (all threads: rayon's and OpenCV's pools
/// alike; `CLOCK_PROCESS_CPUTIME_ID`, which counts the running threads' current slices too).
fn cpu_ns() -> u64 {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ProcessCPUTime);
    t.tv_sec as u64 * 1_000_000_000 + t.tv_nsec as u64
}

/// Median wall time and median CPU time (all threads) per call of `f`, over 11 samples of
/// enough calls to last about 5 ms each (after warm-up calls).
fn time(mut f: impl FnMut()) -> (Duration, Duration) {
    let t = Instant::now();
    f();
    f();
    let once = t.elapsed() / 2;
    let reps = (5_000_000 / once.as_nanos().max(1)).clamp(1, 1000) as u32;
    let (mut wall, mut cpu): (Vec<Duration>, Vec<Duration>) = (0..11)
        .map(|_| {
            let (t, c) = (Instant::now(), cpu_ns());
            for _ in 0..reps {
                f();
            }
            (
                t.elapsed() / reps,
                Duration::from_nanos((cpu_ns() - c) / reps as u64),
            )
        })
        .unzip();
    wall.sort();
    cpu.sort();
    (wall[5], cpu[5])
}

struct Case {
    name: &'static str,
    elements: u64,
    vt: Box<dyn FnMut()>,
    cv: Box<dyn FnMut()>,
}

fn cases() -> Vec<Case> {
    let (w, h) = (640u32, 360u32);
    let img = frame(w, h, 1, 0.0);
    let bg = frame(w, h, 2, 90.0);
    let hm = homography();
    let g = GaussianParams::default();
    let mp = MaskParams::default();
    let small: Vec<RgbImage> = (0..100)
        .map(|i| frame(320, 180, 10 + i, (i % 23) as f64 * 4.0))
        .collect();
    let ms = masks(200, w, h);
    let (i1, i2, i3, i4) = (img.clone(), img.clone(), img.clone(), img.clone());
    let (b1, b2) = (bg.clone(), bg.clone());
    let (s1, s2) = (small.clone(), small);
    let mats: Vec<_> = ms
        .iter()
        .map(|m| vt_cv::convert::mask_to_mat(m).expect("mat"))
        .collect();
    let m1 = ms;
    let px = (w * h) as u64;
    // Masks for the warp and morphology rows: OpenCV gets its 0/255 mat built once, outside
    // the timing (its cost alone); vt-core works on its own bit-packed masks.
    let mask = m1[7].clone();
    let mask_mat = vt_cv::convert::mask_to_mat(&mask).expect("mat");
    let (mask2, mask_mat2) = (mask.clone(), mask_mat.clone());
    let noisy = Mask::from_fn(w, h, |x, y| mask.get(x, y) ^ ((x * 7 + y * 13) % 29 == 0));
    let noisy_mat = vt_cv::convert::mask_to_mat(&noisy).expect("mat");
    let rgb = |_: ()| img.clone();
    let (n1, n2, f1, f2, g1, g2) = (rgb(()), rgb(()), rgb(()), rgb(()), rgb(()), rgb(()));
    let g7 = GaussianParams {
        ksize: 7,
        sigma: 0.0,
    };
    let interp_case = |name, interp: Interpolation, a: RgbImage, b: RgbImage| Case {
        name,
        elements: px,
        vt: Box::new(move || {
            black_box(vt_core::warp::warp_rgb(&a, &hm, w, h, interp));
        }),
        cv: Box::new(move || {
            black_box(vt_cv::warp::warp_rgb(&b, &hm, w, h, interp).expect("warp"));
        }),
    };
    let extra = vec![
        interp_case("warp nearest 640x360", Interpolation::Nearest, n1, n2),
        interp_case(
            "warp bilinear-fixed 640x360",
            Interpolation::BilinearFixed,
            f1,
            f2,
        ),
        Case {
            name: "warp mask 640x360",
            elements: px,
            vt: Box::new(move || {
                black_box(vt_core::warp::warp_mask(&mask2, &hm, w, h));
            }),
            cv: Box::new(move || {
                black_box(
                    vt_cv::warp::warp_mat(&mask_mat2, &hm, w, h, Interpolation::Nearest)
                        .expect("warp"),
                );
            }),
        },
        Case {
            name: "blur 7x7 640x360",
            elements: px,
            vt: Box::new(move || {
                black_box(vt_core::blur::gaussian_blur(&g1, &g7).expect("blur"));
            }),
            cv: Box::new(move || {
                black_box(vt_cv::blur::gaussian_blur(&g2, &g7).expect("blur"));
            }),
        },
        Case {
            name: "morphology open+close r=2 640x360",
            elements: px,
            vt: Box::new(move || {
                black_box(noisy.open(2).close(2));
            }),
            cv: Box::new(move || {
                use vt_cv::mask::{morph_mat, Morph};
                let o = morph_mat(&noisy_mat, 2, Morph::Open).expect("open");
                black_box(morph_mat(&o, 2, Morph::Close).expect("close"));
            }),
        },
    ];
    let mut all = vec![
        Case {
            name: "warp bilinear 640x360",
            elements: px,
            vt: Box::new(move || {
                black_box(vt_core::warp::warp_rgb(
                    &i1,
                    &hm,
                    w,
                    h,
                    Interpolation::Bilinear,
                ));
            }),
            cv: Box::new(move || {
                black_box(
                    vt_cv::warp::warp_rgb(&i2, &hm, w, h, Interpolation::Bilinear).expect("warp"),
                );
            }),
        },
        Case {
            name: "blur 3x3 640x360",
            elements: px,
            vt: Box::new(move || {
                black_box(vt_core::blur::gaussian_blur(&i3, &g).expect("blur"));
            }),
            cv: Box::new(move || {
                black_box(vt_cv::blur::gaussian_blur(&i4, &g).expect("blur"));
            }),
        },
        Case {
            name: "median 100 frames 320x180",
            elements: 100 * 320 * 180,
            vt: Box::new(move || {
                black_box(vt_core::median::temporal_median(&s1).expect("median"));
            }),
            cv: Box::new(move || {
                black_box(vt_cv::median::temporal_median(&s2).expect("median"));
            }),
        },
        Case {
            name: "XOR cost matrix 200 masks 640x360",
            elements: 200 * 199 / 2,
            vt: Box::new(move || {
                // All pairs (k = 1) as vt-core's loop search computes them: rows in parallel,
                // popcounts restricted to the words where any mask is set.
                use rayon::prelude::*;
                let n = m1.len();
                let active = vt_core::mask::union_active_words(&m1);
                let mut d = vec![0u64; n * n];
                d.par_chunks_mut(n).enumerate().for_each(|(a, row)| {
                    for b in a + 1..n {
                        row[b] = vt_core::mask::xor_count_in(&m1[a], &m1[b], active.clone());
                    }
                });
                black_box(d);
            }),
            cv: Box::new(move || {
                // Masks converted to Mats once, outside the timing: this is OpenCV's cost alone.
                black_box(vt_cv::loops::pair_costs(&mats, 1).expect("costs"));
            }),
        },
        Case {
            name: "mask extraction 640x360",
            elements: px,
            vt: Box::new(move || {
                black_box(vt_core::analysis::foreground_mask(&img, &b1, &mp).expect("mask"));
            }),
            cv: Box::new(move || {
                black_box(vt_cv::mask::foreground_mask(&bg, &b2, &mp).expect("mask"));
            }),
        },
    ];
    all.extend(extra);
    all
}

fn side_by_side(c: &mut Criterion) {
    for mut case in cases() {
        let mut group = c.benchmark_group(case.name);
        group.throughput(Throughput::Elements(case.elements));
        group.sample_size(10);
        group.bench_function("vt-core", |b| b.iter(&mut case.vt));
        group.bench_function("opencv", |b| b.iter(&mut case.cv));
        group.finish();
    }
}

fn ratios() {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let load: Vec<&str> = load.split_whitespace().take(3).collect();
    println!(
        "\nvt-core / OpenCV time ratio (median of 11 samples each; > 1 means vt-core is slower); \
         load average {}",
        load.join(" ")
    );
    println!(
        "wall: elapsed time per call (both sides use every core); cpu: CPU time per call summed \
         over all threads, which the other processes on a shared machine do not inflate"
    );
    println!("| operation | vt-core | OpenCV | ratio | vt-core cpu | OpenCV cpu | cpu ratio |");
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    // A filter argument (as for criterion: `cargo bench -p vt-cv -- blur`) limits the table too.
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-') && a.parse::<f64>().is_err())
        .collect();
    for mut case in cases() {
        if !filter.is_empty() && !filter.iter().any(|f| case.name.contains(f.as_str())) {
            continue;
        }
        let ((a, ac), (b, bc)) = (time(&mut case.vt), time(&mut case.cv));
        println!(
            "| {} | {:.2?} | {:.2?} | {:.2} | {:.2?} | {:.2?} | {:.2} |",
            case.name,
            a,
            b,
            a.as_secs_f64() / b.as_secs_f64(),
            ac,
            bc,
            ac.as_secs_f64() / bc.as_secs_f64()
        );
    }
}

criterion_group!(benches, side_by_side);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    // `cargo test --benches` passes --bench too; only print ratios on a real bench run.
    if std::env::args().any(|a| a == "--bench") {
        ratios();
    }
}
