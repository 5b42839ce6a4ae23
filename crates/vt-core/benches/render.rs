//! Renderer speed (eq. 3-6) at 640x360 and 1280x720: frames per second for bilinear and nearest
//! warping, crossfade on and off, a moving and a still viewpoint, and heap allocations per frame
//! after warm-up (counted by a wrapping global allocator). Prints one table.
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

fn scene(w: u32, h: u32, views: usize, frames: usize) -> (RenderScene, Objects) {
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
        let points = [(100.0, 60.0), (540.0, 70.0), (520.0, 300.0), (110.0, 290.0)]
            .iter()
            .map(|&(x, y)| Point::new(x * s + dx, y * s))
            .collect();
        let next = (0..frames).map(|f| Some(f.min(frames - 3))).collect();
        vs.push(RenderView {
            background,
            loop_start: 5,
            loop_end: frames - 5,
            next,
            prev: vec![Some(10); frames],
            points,
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
            dynamic: None,
            next_seam: Vec::new(),
            prev_seam: Vec::new(),
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
            model: MotionModel::Translation,
        },
        Objects(objects),
    )
}

fn main() {
    // Run on a rayon worker, as `vt render` and `vt view` do: jobs then go to the worker's own
    // queue instead of the global injector, which allocates a block every 63 jobs.
    rayon::scope(|_| run());
}

fn run() {
    let frames = 120;
    println!(
        "{:<10} {:<9} {:<10} {:<8} {:>9} {:>14}",
        "size", "interp", "crossfade", "q", "fps", "allocs/frame"
    );
    for (w, h) in [(640, 360), (1280, 720)] {
        let (scene, objects) = scene(w, h, 3, frames);
        for interp in [Interpolation::Bilinear, Interpolation::Nearest] {
            for crossfade in [0usize, 4] {
                for moving in [true, false] {
                    let params = RenderParams {
                        interpolation: interp,
                        crossfade,
                        gain_compensation: false,
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
                    let a0 = ALLOCS.load(Ordering::Relaxed);
                    let t = Instant::now();
                    for i in 20..20 + n {
                        let q = q_at(i);
                        let c = player.advance(&scene, q).unwrap();
                        renderer.render_into(&objects, q, &c, &mut out).unwrap();
                    }
                    let fps = n as f64 / t.elapsed().as_secs_f64();
                    let allocs = (ALLOCS.load(Ordering::Relaxed) - a0) as f64 / n as f64;
                    println!(
                        "{:<10} {:<9} {:<10} {:<8} {:>9.1} {:>14.1}",
                        format!("{w}x{h}"),
                        format!("{interp:?}").to_lowercase(),
                        if crossfade > 0 { "on" } else { "off" },
                        if moving { "moving" } else { "still" },
                        fps,
                        allocs
                    );
                }
            }
        }
    }
    println!(
        "goals: >= 60 fps at 640x360 and >= 25 fps at 1280x720 (bilinear), 0 allocations per frame"
    );
}
