//! Renderer speed (eq. 3-6) at 640x360, 1280x720 and 1920x1080: frames per second for exact
//! bilinear, fixed-point bilinear and nearest warping, crossfade on and off, a moving and a still
//! viewpoint, on a translation scene (parallel rig) and a homography scene (converging rig), and
//! heap allocations per frame after warm-up (counted by a wrapping global allocator). Prints one
//! table:
//! - `fps`: frames over the wall-clock time of all 100 timed frames;
//! - `fast fps`: one over the 10th-percentile frame time, the frames the other processes on a
//!   shared machine disturbed least;
//! - `cpu ms`: the process's CPU time per frame, all threads (the process CPU clock): the work
//!   itself, whatever the load;
//! - `2-core fps`: `2000 / cpu ms`, the rate that work allows when both cores are free for it
//!   (an upper bound: it assumes the frame's work splits perfectly over two threads).
//!
//! The load average is printed with the table: on a loaded machine read `cpu ms`.
// A counting global allocator needs `unsafe impl GlobalAlloc`; it only forwards to `System`.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use image::RgbImage;
use vt_core::model::MotionModel;
use vt_core::render::{
    ObjectFrames, ObjectPatch, Player, RenderParams, RenderScene, RenderView, Renderer,
};
use vt_core::warp::Interpolation;
use vt_core::Point;

struct Counting;
static ALLOCS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Object patches of an ellipse swaying with period 30, per view and frame.
struct Objects(Vec<Vec<ObjectPatch>>);

impl ObjectFrames for Objects {
    fn decode_into(
        &self,
        view: usize,
        frame: usize,
        patch: &mut ObjectPatch,
    ) -> vt_core::Result<()> {
        let src = &self.0[view][frame];
        patch.reset(src.x0, src.y0, src.width, src.height);
        patch.rgb.copy_from_slice(&src.rgb);
        patch.mask.copy_from_slice(&src.mask);
        Ok(())
    }
}

fn scene(
    w: u32,
    h: u32,
    views: usize,
    frames: usize,
    model: MotionModel,
) -> (RenderScene, Objects) {
    let s = w as f64 / 640.0;
    let mut vs = Vec::new();
    let mut objects = Vec::new();
    for p in 0..views {
        let dx = p as f64 * 20.0 * s;
        let background = RgbImage::from_fn(w, h, |x, y| {
            let v = ((x as f64 * 0.05 + dx * 0.05).sin() * 60.0
                + (y as f64 * 0.08).cos() * 50.0
                + 128.0) as u8;
            image::Rgb([v, v / 2 + 40, 255 - v])
        });
        // A converging rig sees the plane as a trapezoid that turns from view to view.
        let persp = match model {
            MotionModel::Homography => (p as f64 - 1.0) * 30.0,
            _ => 0.0,
        };
        let points = [
            (100.0, 60.0 + persp),
            (540.0, 70.0 - persp),
            (520.0, 300.0 + persp),
            (110.0, 290.0 - persp),
        ]
        .iter()
        .map(|&(x, y)| Point::new(x * s + dx, y * s))
        .collect();
        let next = (0..frames).map(|f| Some(f.min(frames - 3))).collect();
        vs.push(RenderView {
            background,
            loop_start: 5,
            loop_end: frames - 5,
            to_next: next,
            to_prev: vec![Some(10); frames],
            points,
            dynamic: None,
            to_next_seam: Vec::new(),
            to_prev_seam: Vec::new(),
        });
        objects.push(
            (0..frames)
                .map(|f| {
                    let (pw, ph) = ((120.0 * s) as u32, (80.0 * s) as u32);
                    let ph_ = f as f64 / 30.0 * std::f64::consts::TAU;
                    let mut patch = ObjectPatch::default();
                    patch.reset(
                        (w / 2 - pw / 2) + (40.0 * s * ph_.sin()) as u32,
                        h / 2 - ph / 2,
                        pw,
                        ph,
                    );
                    for y in 0..ph {
                        for x in 0..pw {
                            let (u, v) = (x as f64 / pw as f64 - 0.5, y as f64 / ph as f64 - 0.5);
                            if u * u + v * v < 0.25 {
                                let i = (y * pw + x) as usize;
                                patch.mask[i] = 1;
                                patch.rgb[i * 3..i * 3 + 3].copy_from_slice(&[
                                    40,
                                    160 + (x % 60) as u8,
                                    50,
                                ]);
                            }
                        }
                    }
                    patch
                })
                .collect(),
        );
    }
    (RenderScene { views: vs, model }, Objects(objects))
}

fn main() {
    // Run on a rayon worker, as `vt render` and `vt view` do: jobs then go to the worker's own
    // queue instead of the global injector, which allocates a block every 63 jobs.
    rayon::scope(|_| run());
}

/// CPU time of this process so far, nanoseconds (all threads; `CLOCK_PROCESS_CPUTIME_ID`,
/// which counts the running threads' current slices too).
fn cpu_ns() -> u64 {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ProcessCPUTime);
    t.tv_sec as u64 * 1_000_000_000 + t.tv_nsec as u64
}

fn run() {
    let frames = 120;
    let filter = std::env::var("VT_RENDER_ROWS").unwrap_or_default();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let load: Vec<&str> = load.split_whitespace().take(3).collect();
    println!(
        "load average {} on {} cpus; rayon threads: {}",
        load.join(" "),
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        rayon::current_num_threads()
    );
    println!(
        "{:<10} {:<12} {:<15} {:<10} {:<8} {:>8} {:>9} {:>8} {:>10} {:>13}",
        "size",
        "scene",
        "interp",
        "crossfade",
        "q",
        "fps",
        "fast fps",
        "cpu ms",
        "2-core fps",
        "allocs/frame"
    );
    let mut times = Vec::with_capacity(100);
    for (w, h) in [(640, 360), (1280, 720), (1920, 1080)] {
        for model in [MotionModel::Translation, MotionModel::Homography] {
            let (scene, objects) = scene(w, h, 3, frames, model);
            for interp in [
                Interpolation::Bilinear,
                Interpolation::BilinearFixed,
                Interpolation::Nearest,
            ] {
                for crossfade in [0usize, 4] {
                    for moving in [true, false] {
                        // The full grid at 640x360 on the translation scene; elsewhere the
                        // rows the goals are about (no crossfade).
                        let full = w == 640 && model == MotionModel::Translation;
                        if crossfade > 0 && !full {
                            continue;
                        }
                        let label = format!(
                            "{:<10} {:<12} {:<15} {:<10} {:<8}",
                            format!("{w}x{h}"),
                            format!("{model:?}").to_lowercase(),
                            match interp {
                                Interpolation::Bilinear => "bilinear",
                                Interpolation::BilinearFixed => "bilinear-fixed",
                                Interpolation::Nearest => "nearest",
                            },
                            if crossfade > 0 { "on" } else { "off" },
                            if moving { "moving" } else { "still" },
                        );
                        // VT_RENDER_ROWS=text keeps only the rows whose label contains it.
                        if !filter.split(',').any(|f| label.contains(f)) {
                            continue;
                        }
                        let params = RenderParams {
                            interpolation: interp,
                            crossfade,
                            ..RenderParams::default()
                        };
                        let mut renderer = Renderer::new(scene.clone(), params).unwrap();
                        let mut player = Player::new();
                        let mut out = RgbImage::new(w, h);
                        let q_at = |i: usize| {
                            if moving {
                                (i as f64 * 0.013) % 2.0
                            } else {
                                0.7
                            }
                        };
                        for i in 0..20 {
                            let q = q_at(i);
                            let c = player.advance(&scene, q).unwrap();
                            renderer.render_into(&objects, q, &c, &mut out).unwrap();
                        }
                        let n = 100;
                        times.clear();
                        let cpu0 = cpu_ns();
                        let a0 = ALLOCS.load(Ordering::Relaxed);
                        let t = Instant::now();
                        for i in 20..20 + n {
                            let t_frame = Instant::now();
                            let q = q_at(i);
                            let c = player.advance(&scene, q).unwrap();
                            renderer.render_into(&objects, q, &c, &mut out).unwrap();
                            times.push(t_frame.elapsed().as_secs_f64());
                        }
                        let fps = n as f64 / t.elapsed().as_secs_f64();
                        let allocs = (ALLOCS.load(Ordering::Relaxed) - a0) as f64 / n as f64;
                        let cpu_ms = (cpu_ns() - cpu0) as f64 * 1e-6 / n as f64;
                        times.sort_by(f64::total_cmp);
                        let fast = 1.0 / times[n / 10];
                        let two_core = 2000.0 / cpu_ms;
                        println!(
                            "{label} {fps:>8.1} {fast:>9.1} {cpu_ms:>8.2} {two_core:>10.1} {allocs:>13.1}"
                        );
                    }
                }
            }
        }
    }
    println!(
        "goals: >= 60 fps at 1280x720 and >= 30 fps at 1920x1080 (bilinear, moving, 2 threads), \
         0 allocations per frame"
    );
}
