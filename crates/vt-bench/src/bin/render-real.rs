//! `render-real SCENE [FRAMES]`: the renderer on a scene made by `vt analyze` from real
//! footage, reading its object stores as `vt render` and `vt view` do (no encoding): CPU ms per
//! frame and fps of the whole frame, the share spent decoding the stores (timed apart, over the
//! same frames in the same order), and the store bytes each frame reads. The viewpoint sweeps
//! across the views (or stays at view 0 for a single view), so loop wraps and view switches
//! (jumps to other frames and views) are in the run. With `VT_RENDER_HASH=1` it also prints a
//! checksum (FNV-1a) of every rendered frame, outside the timing: a speed change must keep it.
//! `VT_SWITCH_FADE=K` sets the switch fade (default: the renderer's), to time its cost.

use std::time::Instant;

use anyhow::{Context, Result};
use vt_core::render::{ObjectFrames, ObjectPatch, Player, RenderParams, Renderer};
use vt_io::scene::LoadedScene;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = args.first().context("usage: render-real SCENE [FRAMES]")?;
    let frames: usize = args.get(1).map_or(Ok(600), |s| s.parse())?;
    let scene = LoadedScene::open(std::path::Path::new(dir))?;
    let views = scene.render.views.len();
    let q = |i: usize| {
        if views < 2 {
            0.0
        } else {
            // Back and forth across the views, one view per 60 frames.
            let span = (views - 1) as f64;
            let t = (i as f64 / 60.0) % (2.0 * span);
            if t > span {
                2.0 * span - t
            } else {
                t
            }
        }
    };
    let mut params = RenderParams::default();
    if let Some(k) = std::env::var_os("VT_SWITCH_FADE") {
        params.switch_fade = k
            .to_str()
            .and_then(|k| k.parse().ok())
            .context("VT_SWITCH_FADE: a number of frames")?;
    }
    let mut renderer = Renderer::new(scene.render.clone(), params)?;
    let mut player = Player::new();
    let (w, h) = renderer.size();
    let mut out = image::RgbImage::new(w, h);
    let mut choices = Vec::with_capacity(frames);
    let hash = std::env::var_os("VT_RENDER_HASH").is_some();
    let mut fnv = 0xcbf2_9ce4_8422_2325u64;
    let mut hashing = std::time::Duration::ZERO;
    let start = Instant::now();
    for i in 0..frames {
        let choice = player.advance(&scene.render, q(i))?;
        renderer.render_into(&scene.objects, q(i), &choice, &mut out)?;
        choices.push(choice);
        if hash {
            let t = Instant::now();
            for &b in out.as_raw() {
                fnv = (fnv ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
            hashing += t.elapsed();
        }
    }
    let render_s = (start.elapsed() - hashing).as_secs_f64();
    if hash {
        println!("{dir}: checksum of {frames} frames {fnv:016x}");
    }
    // The stores alone, over the shown frames in the same order, on a freshly loaded scene.
    let fresh = LoadedScene::open(std::path::Path::new(dir))?;
    let mut patch = ObjectPatch::default();
    let start = Instant::now();
    let mut bytes = 0usize;
    for c in &choices {
        fresh.objects.decode_into(c.view, c.frame, &mut patch)?;
        bytes += fresh.objects.stores[c.view].frame_bytes(c.frame);
    }
    let decode_s = start.elapsed().as_secs_f64();
    let store = &scene.objects.stores[0];
    println!(
        "{dir}: {w}x{h}, {views} view(s), store {} ({} bytes, view 0), {frames} frames: \
         {:.2} ms/frame ({:.1} fps) of which store decoding {:.2} ms/frame; {:.0} store bytes \
         read per frame",
        store.quality(),
        store.byte_len(),
        1e3 * render_s / frames as f64,
        frames as f64 / render_s,
        1e3 * decode_s / frames as f64,
        bytes as f64 / frames as f64,
    );
    Ok(())
}
