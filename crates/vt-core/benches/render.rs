//! Renderer speed (eq. 3-6) at 640x360, 1280x720 and 1920x1080: frames per second for exact
//! bilinear, fixed-point bilinear and nearest warping, crossfade on and off, a moving and a still
//! viewpoint, on a translation scene (parallel rig) and a homography scene (converging rig), and
//! heap allocations per frame after warm-up (counted by a wrapping global allocator).
//!
//! The moving viewpoint steps q by 0.013 views every frame, as a user dragging the viewpoint
//! does: a sweep across the 3-view scene (q 0..2) in 2.6 s at 60 fps, the background sliding
//! about half a pixel per frame at 1280x720 (a view is 40 px of shift there). Every frame has
//! a new q, so every frame re-warps and re-blends both backgrounds. `still` keeps q at 0.7:
//! only the objects change.
//!
//! Each row is measured `VT_RENDER_REPS` times (default 5) over 40 frames after 20 warm-up
//! frames; the table shows medians over the repetitions, so a burst of load on this shared
//! machine moves one repetition, not the figure:
//! - `fps`: frames over the wall-clock time of a repetition;
//! - `cpu ms`: the process's CPU time per frame, all threads (the process CPU clock, which counts
//!   every thread's running time): the work itself, whatever the load;
//! - `1-core fps`, `2-core fps`: `1000 / cpu ms` and `2000 / cpu ms`, the rates that work
//!   allows on one or two free cores (the second an upper bound: it assumes the frame's work
//!   splits perfectly over two threads);
//! - `spread`: the repetitions' CPU times, lowest and highest over the median (%).
//!
//! Then, for the goal rows (exact bilinear, moving, no crossfade), the time per stage: the
//! background (homographies and the two-source warp blend, written straight into the frame):
//! moving minus still; the objects (decode, warp, composite) and the frame copy: still.
//! The load average is printed before and after: on a loaded machine read `cpu ms`.
//!
//! `VT_RENDER_REUSE=1` measures the background-reuse knob (`RenderParams::background_reuse_px`)
//! instead: on the homography scene at 1280x720 and 1920x1080, for the drag above (0.013 views
//! per frame) and a slow one (0.002), per threshold the share of frames that re-blend, the CPU
//! time per frame, and the error against the exact render of the same frames (mean and largest
//! absolute difference over all pixels and channels, grey levels, and the share of values off
//! by more than 2).
//!
//! `VT_RENDER_HASH=1` times nothing: it prints a checksum (FNV-1a) of the 60 frames each row
//! renders, so a speed change can be shown to keep every output byte (run it before and after).
//!
//! Measured on the 2-core shared development machine (Intel Xeon Processor @ 2.10GHz, 2 vCPUs,
//! AVX-512), 2026-11-22, under load average 3.8-4.8 from other builds (never quiet): this
//! bench built from the code before this round and after it, run alternately twice each
//! (`VT_RENDER_REPS=7`, goal rows: exact bilinear, moving, no crossfade), 0 allocations per
//! frame. CPU ms per frame (both runs), wall fps (both runs):
//!
//! | row | before: CPU ms | after: CPU ms | before: wall fps | after: wall fps |
//! | --- | --- | --- | --- | --- |
//! | 1280x720 translation | 17.0, 17.0 | 8.9, 9.3 | 56, 57 | 112, 109 |
//! | 1280x720 homography | 18.6, 18.5 | 9.3, 9.3 | 53, 71 | 107, 107 |
//! | 1920x1080 translation | 38.4, 39.5 | 20.3, 20.6 | 26, 23 | 46, 47 |
//! | 1920x1080 homography | 47.4, 47.2 | 22.0, 23.6 | 21, 21 | 68, 43 |
//!
//! Per stage after (CPU ms): background (moving - still) 7.4-7.9 at 720p, 17.0-20.2 at 1080p
//! (before: 15.3-16.9 and 34.8-43.5); objects (still, which also copies the kept background)
//! 1.4-1.5 and 3.2-3.4 (before 1.6-1.7 and 3.6-3.9). After, the CPU time per frame fits one
//! free core for both goals (60 fps at 720p: 16.7 ms; 30 fps at 1080p: 33.3 ms), so the goals
//! held in wall fps at this load; at load 5-5.5 a full run gave 47-74 wall fps at 720p and
//! 31-42 at 1080p. What changed: the padded backgrounds (no border branch in the gather, which
//! AVX-512 then gathers 8 pixels at a time), the background written straight into the frame
//! (once), AVX-512 dispatch, and the objects' rows under the dispatch.
//!
//! Quiet machine (same machine and day, load average 1.0-1.1, `VT_RENDER_REPS=5`), goal rows:
//! 1280x720 translation 217 fps (9.0 CPU ms), homography 203 fps (9.5); 1920x1080 translation
//! 95 fps (20.6), homography 92 fps (21.1); 0 allocations per frame.

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

/// A parallax field pair for the morph rows: smooth disparities of up to 8 px (scaled with the
/// width) along x, a tenth of the pixels unconfirmed.
fn parallax(w: u32, h: u32) -> vt_core::parallax::PairParallax {
    let s = w as f32 / 640.0;
    let field = |dir: [f32; 2]| {
        vt_core::parallax::Field::new(
            w,
            h,
            dir,
            None,
            (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    8.0 * s * (x / (60.0 * s)).sin() * (y / (90.0 * s)).cos()
                })
                .collect(),
            (0..w * h).map(|i| (i % w) % 10 != 3).collect(),
        )
        .expect("a valid field")
    };
    vt_core::parallax::PairParallax {
        a: field([1.0, 0.0]),
        b: field([-1.0, 0.0]),
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
    (
        RenderScene {
            views: vs,
            model,
            parallax: Vec::new(),
        },
        Objects(objects),
    )
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

fn load() -> String {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    load.split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// One row's medians: wall fps, CPU ms per frame, CPU spread (low, high, %), allocations.
struct Row {
    fps: f64,
    cpu_ms: f64,
    spread: (f64, f64),
    allocs: f64,
}

/// q of frame i: moving by 0.013 views per frame (see the module doc), or still at 0.7.
fn q_at(moving: bool, i: usize) -> f64 {
    if moving {
        (i as f64 * 0.013) % 2.0
    } else {
        0.7
    }
}

fn measure(
    scene: &RenderScene,
    objects: &Objects,
    params: RenderParams,
    moving: bool,
    reps: usize,
) -> Row {
    const WARM: usize = 20;
    const FRAMES: usize = 40;
    let (w, h) = scene.views[0].background.dimensions();
    let mut renderer = Renderer::new(scene.clone(), params).unwrap();
    let mut player = Player::new();
    let mut out = RgbImage::new(w, h);
    let mut frame = |i: usize| {
        let q = q_at(moving, i);
        let c = player.advance(scene, q).unwrap();
        renderer.render_into(objects, q, &c, &mut out).unwrap();
    };
    for i in 0..WARM {
        frame(i);
    }
    let (mut fps, mut cpu) = (Vec::new(), Vec::new());
    let a0 = ALLOCS.load(Ordering::Relaxed);
    let mut i = WARM;
    for _ in 0..reps {
        let cpu0 = cpu_ns();
        let t = Instant::now();
        for _ in 0..FRAMES {
            frame(i);
            i += 1;
        }
        fps.push(FRAMES as f64 / t.elapsed().as_secs_f64());
        cpu.push((cpu_ns() - cpu0) as f64 * 1e-6 / FRAMES as f64);
    }
    let allocs = (ALLOCS.load(Ordering::Relaxed) - a0) as f64 / (reps * FRAMES) as f64;
    let cpu_ms = median(&mut cpu);
    let spread = (
        (cpu[0] / cpu_ms - 1.0) * 100.0,
        (cpu[cpu.len() - 1] / cpu_ms - 1.0) * 100.0,
    );
    Row {
        fps: median(&mut fps),
        cpu_ms,
        spread,
        allocs,
    }
}

/// FNV-1a of the 60 frames a row renders (after the same 20 warm-up frames as the timing).
fn checksum(scene: &RenderScene, objects: &Objects, params: RenderParams, moving: bool) -> u64 {
    let (w, h) = scene.views[0].background.dimensions();
    let mut renderer = Renderer::new(scene.clone(), params).unwrap();
    let mut player = Player::new();
    let mut out = RgbImage::new(w, h);
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for i in 0..80 {
        let q = q_at(moving, i);
        let c = player.advance(scene, q).unwrap();
        renderer.render_into(objects, q, &c, &mut out).unwrap();
        if i >= 20 {
            for &b in out.as_raw() {
                hash = (hash ^ b as u64).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    hash
}

/// The background-reuse table (see the module doc).
fn reuse_table() {
    println!(
        "background reuse (homography scene, exact bilinear, 120 frames after 20); load {}",
        load()
    );
    println!(
        "{:<10} {:<7} {:>9} {:>9} {:>8} {:>11} {:>10} {:>9}",
        "size", "q step", "reuse px", "blended", "cpu ms", "mean error", "max error", "off > 2"
    );
    for (w, h) in [(1280, 720), (1920, 1080)] {
        let (scene, objects) = scene(w, h, 3, 120, MotionModel::Homography);
        for step in [0.013, 0.002] {
            for reuse in [0.0, 0.1, 0.25, 0.5, 1.0] {
                let exact = RenderParams::default();
                let params = RenderParams {
                    background_reuse_px: reuse,
                    ..exact
                };
                let mut a = Renderer::new(scene.clone(), exact).unwrap();
                let mut b = Renderer::new(scene.clone(), params).unwrap();
                let (mut pa, mut pb) = (Player::new(), Player::new());
                let (mut oa, mut ob) = (RgbImage::new(w, h), RgbImage::new(w, h));
                let (mut cpu, mut sum, mut max, mut off, mut n) = (0u64, 0u64, 0u8, 0u64, 0u64);
                let mut blends0 = 0;
                for i in 0..140 {
                    let q = 0.2 + (i as f64 * step) % 1.6;
                    let ca = pa.advance(&scene, q).unwrap();
                    let cb = pb.advance(&scene, q).unwrap();
                    a.render_into(&objects, q, &ca, &mut oa).unwrap();
                    let c0 = cpu_ns();
                    b.render_into(&objects, q, &cb, &mut ob).unwrap();
                    if i < 20 {
                        blends0 = b.background_blends();
                        continue;
                    }
                    cpu += cpu_ns() - c0;
                    for (x, y) in oa.as_raw().iter().zip(ob.as_raw()) {
                        let d = x.abs_diff(*y);
                        sum += d as u64;
                        max = max.max(d);
                        off += (d > 2) as u64;
                    }
                    n += oa.as_raw().len() as u64;
                }
                println!(
                    "{:<10} {:<7} {:>9} {:>8.0}% {:>8.2} {:>11.3} {:>10} {:>8.3}%",
                    format!("{w}x{h}"),
                    step,
                    reuse,
                    (b.background_blends() - blends0) as f64 / 120.0 * 100.0,
                    cpu as f64 * 1e-6 / 120.0,
                    sum as f64 / n as f64,
                    max,
                    off as f64 / n as f64 * 100.0
                );
            }
        }
    }
}

fn run() {
    if std::env::var_os("VT_RENDER_REUSE").is_some() {
        reuse_table();
        return;
    }
    let frames = 120;
    let hash = std::env::var_os("VT_RENDER_HASH").is_some();
    let filter = std::env::var("VT_RENDER_ROWS").unwrap_or_default();
    let reps: usize = std::env::var("VT_RENDER_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5)
        .max(1);
    println!(
        "load average {} on {} cpus; rayon threads: {}; medians of {reps} repetitions of 40 frames",
        load(),
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        rayon::current_num_threads()
    );
    println!(
        "{:<10} {:<12} {:<15} {:<10} {:<7} {:>7} {:>7} {:>10} {:>10} {:>12} {:>7}",
        "size",
        "scene",
        "interp",
        "crossfade",
        "q",
        "fps",
        "cpu ms",
        "1-core fps",
        "2-core fps",
        "spread %",
        "allocs"
    );
    // (size, scene) -> (moving cpu ms, still cpu ms, moving fps) of the goal rows.
    let mut goals: Vec<(String, f64, f64, f64)> = Vec::new();
    for (w, h) in [(640, 360), (1280, 720), (1920, 1080)] {
        for (model, morph) in [
            (MotionModel::Translation, false),
            (MotionModel::Homography, false),
            (MotionModel::Homography, true),
        ] {
            let (mut scene, objects) = scene(w, h, 3, frames, model);
            if morph {
                scene.parallax = (0..2)
                    .map(|_| Some(std::sync::Arc::new(parallax(w, h))))
                    .collect();
            }
            for interp in [
                Interpolation::Bilinear,
                Interpolation::BilinearFixed,
                Interpolation::Nearest,
            ] {
                for crossfade in [0usize, 4] {
                    let mut goal = (f64::NAN, f64::NAN, f64::NAN);
                    for moving in [true, false] {
                        // The full grid at 640x360 on the translation scene; elsewhere the
                        // rows the goals are about (no crossfade).
                        let full = w == 640 && model == MotionModel::Translation;
                        if crossfade > 0 && !full {
                            continue;
                        }
                        let name = match interp {
                            Interpolation::Bilinear => "bilinear",
                            Interpolation::BilinearFixed => "bilinear-fixed",
                            Interpolation::Nearest => "nearest",
                        };
                        let scene_name = if morph {
                            "homography+morph".to_string()
                        } else {
                            format!("{model:?}").to_lowercase()
                        };
                        let cf = if crossfade > 0 { "on" } else { "off" };
                        let q = if moving { "moving" } else { "still" };
                        // VT_RENDER_ROWS=a,b keeps the rows whose label ("1280x720 homography
                        // bilinear off moving") contains a or b.
                        let key = format!("{w}x{h} {scene_name} {name} {cf} {q}");
                        if !filter.split(',').any(|f| key.contains(f)) {
                            continue;
                        }
                        let params = RenderParams {
                            interpolation: interp,
                            crossfade,
                            ..RenderParams::default()
                        };
                        if hash {
                            let sum = checksum(&scene, &objects, params, moving);
                            println!("{key:<45} {sum:016x}");
                            continue;
                        }
                        let r = measure(&scene, &objects, params, moving, reps);
                        println!(
                            "{:<10} {:<12} {:<15} {:<10} {:<7} {:>7.1} {:>7.2} {:>10.1} {:>10.1} {:>12} {:>7.1}",
                            format!("{w}x{h}"),
                            scene_name,
                            name,
                            cf,
                            q,
                            r.fps,
                            r.cpu_ms,
                            1000.0 / r.cpu_ms,
                            2000.0 / r.cpu_ms,
                            format!("{:+.0}/{:+.0}", r.spread.0, r.spread.1),
                            r.allocs
                        );
                        if interp == Interpolation::Bilinear && crossfade == 0 {
                            if moving {
                                goal.0 = r.cpu_ms;
                                goal.2 = r.fps;
                            } else {
                                goal.1 = r.cpu_ms;
                            }
                        }
                    }
                    if interp == Interpolation::Bilinear && crossfade == 0 && w >= 1280 {
                        let scene_name = if morph {
                            "homography+morph".to_string()
                        } else {
                            format!("{model:?}").to_lowercase()
                        };
                        goals.push((format!("{w}x{h} {scene_name}"), goal.0, goal.1, goal.2));
                    }
                }
            }
        }
    }
    println!("load average after: {}", load());
    println!(
        "stages (exact bilinear, moving, CPU ms per frame): background = moving - still, \
         objects and copy = still"
    );
    for (name, moving, still, fps) in goals.iter().filter(|g| g.1.is_finite() && g.2.is_finite()) {
        println!(
            "  {name:<22} total {moving:>6.2}  background {:>6.2}  objects+copy {still:>5.2}  \
             wall fps {fps:>6.1}  1-core fps {:>6.1}",
            moving - still,
            1000.0 / moving
        );
    }
    println!(
        "goals: >= 60 fps at 1280x720 and >= 30 fps at 1920x1080 (bilinear, moving, 2 threads), \
         0 allocations per frame"
    );
}
