//! vt-core and vt-cv (OpenCV) side by side on the same inputs, one criterion group per
//! operation, then a table of time ratios (vt-core / OpenCV), so the ratio can be read without
//! digging in criterion's files: wall-clock and CPU time (all threads, the process CPU clock)
//! per call, with the load average before and after.
//!
//! The table's runs are interleaved: per operation, `VT_CV_ROUNDS` rounds (default 9), each
//! timing vt-core and OpenCV back to back (about 10 ms of calls each, the order alternating
//! round by round), so a burst of load on a shared machine hits both sides of a round alike.
//! Each round gives a ratio; the table shows the medians over the rounds (times and ratios)
//! and the range of the wall ratio. `VT_CV_TABLE=1` skips the criterion groups (only the
//! table).
//!
//! Inputs follow the thesis's scale: 640x360 frames, a 3x3 Gaussian, 100 frames for the median
//! (at 320x180 to bound memory), 200 masks for the XOR cost matrix.

use std::hint::black_box;
use std::time::Instant;

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

/// Calls of `f` that last about 10 ms (after two warm-up calls).
fn calls_for(f: &mut dyn FnMut()) -> u32 {
    let t = Instant::now();
    f();
    f();
    let once = t.elapsed() / 2;
    (10_000_000 / once.as_nanos().max(1)).clamp(1, 1000) as u32
}

/// Wall and CPU time (all threads) per call over `n` calls of `f`.
fn sample(f: &mut dyn FnMut(), n: u32) -> (f64, f64) {
    let (t, c) = (Instant::now(), cpu_ns());
    for _ in 0..n {
        f();
    }
    (
        t.elapsed().as_secs_f64() / n as f64,
        (cpu_ns() - c) as f64 * 1e-9 / n as f64,
    )
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// One operation's interleaved rounds: medians of vt-core's and OpenCV's wall and CPU times
/// per call, of the per-round wall and CPU ratios, and the lowest and highest wall ratio.
struct Interleaved {
    vt: (f64, f64),
    cv: (f64, f64),
    ratio: f64,
    cpu_ratio: f64,
    range: (f64, f64),
}

fn interleaved(case: &mut Case, rounds: usize) -> Interleaved {
    let (nv, nc) = (calls_for(&mut case.vt), calls_for(&mut case.cv));
    let mut t: [Vec<f64>; 6] = Default::default();
    for r in 0..rounds {
        let (a, b) = if r % 2 == 0 {
            let a = sample(&mut case.vt, nv);
            (a, sample(&mut case.cv, nc))
        } else {
            let b = sample(&mut case.cv, nc);
            (sample(&mut case.vt, nv), b)
        };
        for (v, x) in t.iter_mut().zip([a.0, a.1, b.0, b.1, a.0 / b.0, a.1 / b.1]) {
            v.push(x);
        }
    }
    let [mut vw, mut vc, mut cw, mut cc, mut r, mut rc] = t;
    let range = (
        r.iter().copied().fold(f64::INFINITY, f64::min),
        r.iter().copied().fold(0.0, f64::max),
    );
    Interleaved {
        vt: (median(&mut vw), median(&mut vc)),
        cv: (median(&mut cw), median(&mut cc)),
        ratio: median(&mut r),
        cpu_ratio: median(&mut rc),
        range,
    }
}

fn ms(v: f64) -> String {
    format!("{:.3} ms", v * 1e3)
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

fn load() -> String {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    load.split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

fn ratios() {
    let rounds: usize = std::env::var("VT_CV_ROUNDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(9)
        .max(1);
    println!(
        "\nvt-core / OpenCV time ratio, median over {rounds} interleaved rounds (> 1 means \
         vt-core is slower); load average {}",
        load()
    );
    println!(
        "wall: elapsed time per call (both sides use every core); cpu: CPU time per call summed \
         over all threads, which the other processes on a shared machine do not inflate; \
         range: the rounds' lowest and highest wall ratio"
    );
    println!(
        "| operation | vt-core | OpenCV | ratio | range | vt-core cpu | OpenCV cpu | cpu ratio |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    // A filter argument (as for criterion: `cargo bench -p vt-cv -- blur`) limits the table too.
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-') && a.parse::<f64>().is_err())
        .collect();
    for mut case in cases() {
        if !filter.is_empty() && !filter.iter().any(|f| case.name.contains(f.as_str())) {
            continue;
        }
        let r = interleaved(&mut case, rounds);
        println!(
            "| {} | {} | {} | {:.2} | {:.2}-{:.2} | {} | {} | {:.2} |",
            case.name,
            ms(r.vt.0),
            ms(r.cv.0),
            r.ratio,
            r.range.0,
            r.range.1,
            ms(r.vt.1),
            ms(r.cv.1),
            r.cpu_ratio
        );
    }
    println!("load average after: {}", load());
}

criterion_group!(benches, side_by_side);

fn main() {
    if std::env::var_os("VT_CV_TABLE").is_none() {
        benches();
        Criterion::default().configure_from_args().final_summary();
    }
    // `cargo test --benches` passes --bench too; only print ratios on a real bench run.
    if std::env::args().any(|a| a == "--bench") {
        ratios();
    }
}
