//! The scene as the renderer sees it: views, tables, and the object frames it reads.

use image::RgbImage;

use crate::model::{fit_model, MotionModel};
use crate::{Error, Homography, Point, Result};

/// A view as the renderer needs it.
#[derive(Debug, Clone)]
pub struct RenderView {
    /// `B_p`.
    pub background: RgbImage,
    /// `m_p`.
    pub loop_start: usize,
    /// `n_p`.
    pub loop_end: usize,
    /// `t_{p+1}(s, p)` for every frame s.
    pub to_next: Vec<Option<usize>>,
    /// `t_{p-1}(s, p)` for every frame s.
    pub to_prev: Vec<Option<usize>>,
    /// The marked points `x_p`.
    pub points: Vec<Point>,
    /// Alpha of the view's dynamic region ([`crate::noise`]): where it is set, the object store
    /// holds the frame's own pixels, shown with this alpha over the background (None: objects
    /// only, the thesis).
    pub dynamic: Option<std::sync::Arc<image::GrayImage>>,
    /// Seam score of the switch `s -> to_next[s] + 1` per frame s (empty: unknown, every switch is
    /// acceptable).
    pub to_next_seam: Vec<f32>,
    /// Seam score of the switch `s -> to_prev[s] + 1` per frame s (empty: unknown).
    pub to_prev_seam: Vec<f32>,
}

/// Everything the online stage needs from an analysed scene.
#[derive(Debug, Clone)]
pub struct RenderScene {
    /// Views in order along the line.
    pub views: Vec<RenderView>,
    /// The model used for `H_(p,q)` (the scene's chosen model).
    pub model: MotionModel,
    /// The dense parallax of each neighbour pair `(p, p + 1)` that is morphed
    /// ([`crate::parallax`]); empty or None: the plane warp of eq. (3).
    pub parallax: Vec<Option<std::sync::Arc<crate::parallax::PairParallax>>>,
}

impl RenderScene {
    /// The frame view `view` plays after `frame` (eq. 6 within a view): `m + 1` after the loop's
    /// end `n`, else the next frame.
    pub fn next_in_loop(&self, view: usize, frame: usize) -> usize {
        let v = &self.views[view];
        if frame == v.loop_end {
            v.loop_start + 1
        } else {
            frame + 1
        }
    }

    /// Largest valid q, `M - 1`.
    pub fn q_max(&self) -> f64 {
        (self.views.len() - 1) as f64
    }

    /// Checks a viewpoint.
    pub fn check_q(&self, q: f64) -> Result<()> {
        if !q.is_finite() || q < 0.0 || q > self.q_max() {
            return Err(Error::InvalidParameter {
                name: "q",
                value: q.to_string(),
                why: format!(
                    "the viewpoint must lie in [0, {}] (views 0 to {})",
                    self.q_max(),
                    self.q_max()
                ),
            });
        }
        Ok(())
    }

    /// The virtual points `x(q)` of B-1.
    pub fn virtual_points(&self, q: f64) -> Vec<Point> {
        let mut v = Vec::new();
        self.virtual_points_into(q, &mut v);
        v
    }

    /// [`RenderScene::virtual_points`] into a reused buffer.
    pub fn virtual_points_into(&self, q: f64, out: &mut Vec<Point>) {
        out.clear();
        let m1 = self.q_max();
        if m1 == 0.0 {
            out.extend_from_slice(&self.views[0].points);
            return;
        }
        let (a, b) = (
            &self.views[0].points,
            &self.views[self.views.len() - 1].points,
        );
        out.extend(
            a.iter()
                .zip(b)
                .map(|(p0, p1)| Point::from((p0.coords * (m1 - q) + p1.coords * q) / m1)),
        );
    }

    /// `H_(p,q)`: view p's points to the virtual points at q, with the scene's model.
    pub fn homography_to(&self, p: usize, q: f64) -> Result<Homography> {
        self.homography_to_with(p, q, &mut Vec::new())
    }

    /// [`RenderScene::homography_to`] with a reused buffer for the virtual points.
    pub fn homography_to_with(&self, p: usize, q: f64, buf: &mut Vec<Point>) -> Result<Homography> {
        if self.views.len() == 1 {
            return Ok(Homography::identity());
        }
        self.virtual_points_into(q, buf);
        Ok(fit_model(self.model, &self.views[p].points, buf, 1.0)?.homography)
    }
}

/// A moving object's pixels for one frame, decoded into a box: what [`ObjectFrames`] yields.
#[derive(Debug, Clone, Default)]
pub struct ObjectPatch {
    /// Box origin in the view's image.
    pub x0: u32,
    /// Box origin in the view's image.
    pub y0: u32,
    /// Box width (0 for no object).
    pub width: u32,
    /// Box height.
    pub height: u32,
    /// RGB, row-major over the box (undefined where `mask` is 0).
    pub rgb: Vec<u8>,
    /// 1 where the object is, row-major over the box.
    pub mask: Vec<u8>,
}

impl ObjectPatch {
    /// Sets the box and zeroes it (reusing storage).
    pub fn reset(&mut self, x0: u32, y0: u32, width: u32, height: u32) {
        let n = width as usize * height as usize;
        (self.x0, self.y0, self.width, self.height) = (x0, y0, width, height);
        self.rgb.clear();
        self.rgb.resize(n * 3, 0);
        self.mask.clear();
        self.mask.resize(n, 0);
    }
}

/// Source of moving-object pixels per (view, frame): the scene's object stores.
pub trait ObjectFrames {
    /// Decodes frame `frame` of view `view` into `patch` (reusing its storage).
    fn decode_into(&self, view: usize, frame: usize, patch: &mut ObjectPatch) -> Result<()>;

    /// Frames of `view` decode in groups of this many, each from a frame whose number is a
    /// multiple of it (a compressed store's group of pictures): a frame costs the decoding of
    /// its group's earlier frames too, unless they were just decoded. 1: every frame on its own.
    fn group(&self, _view: usize) -> usize {
        1
    }
}
