//! The one render driver: a viewpoint path played through eq. (6)'s player and the renderer,
//! every frame handed to a sink. `vt render` writes the frames to a file, the report times this
//! same loop, the tests compare its frames.

use image::RgbImage;
use vt_core::render::{FrameChoice, Player, RenderParams, Renderer, Step};
use vt_core::seam::SeamMeter;
use vt_io::scene::LoadedScene;

/// What [`play`] played.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Playback {
    /// Frames rendered.
    pub frames: usize,
    /// Loop wraps of the player.
    pub wraps: u64,
    /// View switches of the player.
    pub switches: u64,
    /// Wraps and switches measured (all of them).
    pub measured: usize,
    /// Their seam score, [`vt_core::seam`]'s: the mean over the jumps of each wrap's step over
    /// the median ordinary step and each switch's steps over the ones it replaced (None without
    /// jumps).
    pub mean_seam: Option<f64>,
    /// Seconds of the playback spent rendering what switches replaced, for the seam score only
    /// (K + 1 frames a switch with a K-frame fade); a timing of the renderer leaves them out.
    pub measure_secs: f64,
}

/// Plays the viewpoint path `qs` (one viewpoint per output frame) over `scene` with a renderer
/// of `params`, handing every frame to `sink` with the player's choice for it (view, frame,
/// step), and scores the seams of its jumps on the frames
/// it rendered ([`SeamMeter`]: each wrap's step over the median ordinary step of this render,
/// each switch's steps over those of the old view's continuation, rendered for the meter).
/// Frames are the scene's size. A sink's error stops the playback and is returned.
pub fn play<E>(
    scene: &LoadedScene,
    qs: &[f64],
    params: RenderParams,
    sink: &mut (dyn FnMut(&RgbImage, &FrameChoice) -> std::result::Result<(), E> + Send),
) -> std::result::Result<Playback, E>
where
    E: From<crate::Error> + Send,
{
    let mut renderer = Renderer::new(scene.render.clone(), params).map_err(crate::Error::from)?;
    let (w, h) = renderer.size();
    let mut player = Player::new();
    let mut frame = RgbImage::new(w, h);
    let mut replaced_frame = RgbImage::new(0, 0);
    let mut meter = SeamMeter::new();
    // What the old view would show during a switch and its fade: (view, frame, frames left).
    let mut replaced: Option<(usize, usize, usize)> = None;
    let fade = params.switch_blend_frames();
    let mut measure_secs = 0.0;
    // On a rayon worker, the renderer's parallel passes queue locally: no allocation per frame.
    rayon::scope(|_| -> std::result::Result<(), E> {
        for &q in qs {
            let choice = player
                .advance(&scene.render, q)
                .map_err(crate::Error::from)?;
            renderer
                .render_into(&scene.objects, q, &choice, &mut frame)
                .map_err(crate::Error::from)?;
            replaced = match (choice.step, choice.continuation, replaced) {
                (Step::Switch { .. }, Some((v, j)), _) if j > 0 => {
                    Some((v, scene.render.next_in_loop(v, j - 1), fade))
                }
                (Step::Play, _, Some((v, j, left))) if left > 0 => {
                    Some((v, scene.render.next_in_loop(v, j), left - 1))
                }
                _ => None,
            };
            let shown_instead = match replaced {
                Some((v, j, _)) => {
                    let t = std::time::Instant::now();
                    if replaced_frame.dimensions() != (w, h) {
                        replaced_frame = RgbImage::new(w, h);
                    }
                    renderer
                        .render_plain_into(&scene.objects, q, v, j, &mut replaced_frame)
                        .map_err(crate::Error::from)?;
                    measure_secs += t.elapsed().as_secs_f64();
                    Some(&replaced_frame)
                }
                None => None,
            };
            meter.push(&frame, choice.step, shown_instead);
            sink(&frame, &choice)?;
        }
        Ok(())
    })?;
    Ok(Playback {
        frames: qs.len(),
        wraps: player.wraps,
        switches: player.switches,
        measured: meter.jumps(),
        mean_seam: meter.score(),
        measure_secs,
    })
}
