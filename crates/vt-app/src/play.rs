//! The one render driver: a viewpoint path played through eq. (6)'s player and the renderer,
//! every frame handed to a sink. `vt render` writes the frames to a file, the report times this
//! same loop, the tests compare its frames.

use image::RgbImage;
use vt_core::render::{FrameChoice, Player, RenderParams, Renderer};
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
    /// Their seam score, [`vt_core::seam`]'s: the mean jump step over the median ordinary step
    /// (None without jumps).
    pub mean_seam: Option<f64>,
}

/// Plays the viewpoint path `qs` (one viewpoint per output frame) over `scene` with a renderer
/// of `params`, handing every frame to `sink` with the player's choice for it (view, frame,
/// step), and scores the seams of its jumps on the frames
/// it rendered ([`SeamMeter`]: each jump's step over the median ordinary step of this render).
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
    let mut meter = SeamMeter::new();
    // On a rayon worker, the renderer's parallel passes queue locally: no allocation per frame.
    rayon::scope(|_| -> std::result::Result<(), E> {
        for &q in qs {
            let choice = player
                .advance(&scene.render, q)
                .map_err(crate::Error::from)?;
            renderer
                .render_into(&scene.objects, q, &choice, &mut frame)
                .map_err(crate::Error::from)?;
            meter.push(&frame, choice.step);
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
    })
}
