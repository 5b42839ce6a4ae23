//! View-dependent texturing: a new view coloured by projecting the reference photos onto the
//! voxel model's surface, instead of painting each voxel one flat colour (the rough view).
//!
//! For every pixel the rough render covers, its surface point is the back-projection of the
//! pixel at the rendered depth. The point is projected into the `references` reference cameras (and the next one)
//! nearest in viewing direction (angle between the directions from the model's centre to the
//! cameras); a camera contributes when the point is not hidden in it (its depth is within
//! `depth_tolerance` voxels of the camera's own render of the model at that pixel) and the
//! sample lies inside the camera's photo. Samples are bilinear and blended with weights
//! `fade / (angle^2 + eps^2)`, `angle` being the angle at the surface point between the new ray
//! and the reference ray (unstructured-lumigraph style: a camera that looks along the same ray
//! dominates) and `fade` the reference's [`fading_references`] weight, which reaches 0 as the
//! photo leaves the set, so the blend varies continuously with the viewpoint. Pixels no camera sees keep the voxel colour; cracks of the rough render inside
//! its closed coverage (closing radius `fill_radius`) are filled by push-pull interpolation.

use image::{Rgb, RgbImage};
use nalgebra::{Matrix3, Matrix3x4, Vector3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::photo::VoxelModel;
use crate::render::{render_rough, Rendered};
use crate::silhouette::Mask;
use crate::{Error, Result};

/// View-dependent texturing parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureParams {
    /// Reference photos blended per pixel (the nearest by viewing direction), at least 1 (2).
    pub references: usize,
    /// Visibility slack in voxel sizes: a reference sees a surface point when the point's depth
    /// is at most its own render's depth plus this (4; leave-one-out PSNR inside the silhouette
    /// against 2: kettle 21.18 vs 21.05 dB, temple 21.33 vs 21.26, synthetic object 21.68 vs
    /// 21.49, every view of each scored).
    pub depth_tolerance: f64,
    /// Angle in degrees below which a reference counts as looking along the same ray (the eps
    /// of the blending weights, 2).
    pub eps_deg: f64,
    /// Closing radius in pixels of the rough render's coverage: uncovered pixels inside the
    /// closed coverage are holes and get filled (3; 0 fills nothing).
    pub fill_radius: u32,
    /// Radius in pixels of the box filter that smooths the rough render's depth (voxel-centre
    /// depths, flat per splat) before back-projection (0, the default, keeps the splat depths).
    /// With the snapping to the photos' depth maps ([`TextureParams::snap`]) each photo finds
    /// its own surface near the splat's depth, and the box no longer helps. Against 2: lego
    /// 8-view 22.37 -> 22.42 dB (inside the silhouettes 18.62 -> 18.71; radius 1: 22.40);
    /// leave-one-out inside the silhouette kettle 24.77 -> 24.80 (radius 1 the same; worst
    /// lead over blur2 +0.89 -> +0.90), templeSparseRing 22.59 -> 22.60 (worst lead +0.22 ->
    /// +0.17; over the silhouette and the view's own coverage 21.62 -> 21.68). Before the
    /// snapping, 2 was measured against 3: lego 21.73 -> 21.78 dB, kettle 24.67 -> 24.75,
    /// temple 22.18 -> 22.19.
    pub depth_smooth: u32,
    /// Depth refinement: candidate depths tried on each side of the splat depth (smoothed by
    /// `depth_smooth`) (4; 0 = none); per pixel the candidate whose reference colours agree
    /// best (variance across the references, summed over a `(2 sweep_window + 1)^2` window)
    /// wins.
    pub sweep: usize,
    /// Spacing of the candidate depths in voxel sizes (0.25).
    pub sweep_step: f64,
    /// Window radius in pixels of the refinement's agreement cost (2).
    pub sweep_window: u32,
    /// Sigma in pixels of the Gaussian that softens the textured image where the references
    /// disagree (1.5; 0 = never). Misregistered texture (the model is only voxel-accurate) scores
    /// worse than its local mean; where the photos agree the texture stays sharp.
    pub soften_sigma: f64,
    /// Standard deviation (0..255, mean over channels) of the references' colours at which a
    /// pixel is fully softened; softening grows linearly up to it (24; 0 = soften everywhere).
    /// Pixels seen by one photo or none count as disagreeing. (Leave-one-out with the other
    /// defaults, 16 / 24 / 32: kettle 24.13 / 24.34 / 24.44 dB, worst view over blur2 +0.89 /
    /// +1.01 / +1.02; templeSparseRing 21.73 at 24 and 32; the synthetic object at 400x400,
    /// 256^3, 26.99 / 26.87 / 26.75.)
    pub agree_sd: f64,
    /// Angle in degrees within which every reference photo is blended besides the nearest
    /// `references` (10; 0 = only those; see [`fading_references`]). The kettle's 28 photos lie
    /// 4-7 degrees apart, several about equally near any new view; blending them all averages
    /// out their differences in exposure and registration (worst view +0.18 -> +0.79 dB over
    /// blur2, mean 24.10 -> 24.13). Rings spaced wider (the temple's 22.5 degrees, the
    /// synthetic object's 45) are unchanged.
    pub reach_deg: f64,
    /// Share (0..=1) of the softened colour taken from the model's own colours (the rough
    /// render blurred by `soften_sigma` over its coverage: each voxel the mean over every photo
    /// that sees it) instead of the blurred texture (0.2). Where the references disagree (a
    /// photo lit or exposed unlike its neighbours, backdrop seen through the handle in some of
    /// them), the mean over all photos predicts an unseen view better. Against 0: kettle worst
    /// view over blur2 +0.88 -> +1.01 dB, mean 24.33 -> 24.34, over silhouette + own coverage
    /// 22.47 -> 22.60; temple 21.68 -> 21.73 (own coverage 20.29 -> 20.19: the rim past the
    /// outline is less dark, and the temple's backdrop is black).
    pub consensus: f64,
    /// Soften within the object region (false): the softening's blur is normalised over the
    /// region's pixels, so nothing from outside it bleeds into the rim. By default the photos'
    /// backdrop bleeds there, as it does in the photos ([`texture_view`]'s `backdrop`); against
    /// that, lego 8-view 22.02 -> 22.00 dB, kettle leave-one-out inside the silhouette 24.74 ->
    /// 24.88 but over silhouette + own coverage 24.51 -> 24.33. It was measured better than
    /// black bleeding on a light backdrop (kettle, agree_sd 32: 24.44 -> 24.55 dB inside the
    /// silhouette, 22.82 -> 23.57 over silhouette + own coverage) and worse on a black one,
    /// which the bled rim matches (temple 21.73 -> 21.67, 20.19 -> 19.83).
    pub soften_within: bool,
    /// Registration to the references' own depth maps, in voxel sizes (8; 0 = off): each
    /// reference is sampled where the pixel's ray meets that reference's depth map (the model's
    /// confirmed depths), at the crossing nearest the refined depth within this reach, searched
    /// every `sweep_step`; else at the refined depth. The voxel surface is only voxel-accurate
    /// and the refinement needs two references that see the point; a photo's own depths put its
    /// texture where it saw it. Against 0: lego 8-view 22.23 -> 22.37 dB (reach 2 / 4 / 12:
    /// 22.29 / 22.34 / 22.36); leave-one-out inside the silhouette templeSparseRing 22.23 ->
    /// 22.59 (worst lead over blur2 +0.09 -> +0.22), kettle 24.74 -> 24.77 (+0.94 -> +0.89);
    /// the synthetic object (400x400, 8 views) 26.95 -> 26.98.
    pub snap: f64,
}

impl TextureParams {
    /// Steps of `sweep_step` the snapping searches each way ([`TextureParams::snap`]; 0 = off).
    pub fn snap_steps(&self) -> i64 {
        if self.snap > 0.0 {
            (self.snap / self.sweep_step).round() as i64
        } else {
            0
        }
    }
}

impl Default for TextureParams {
    fn default() -> Self {
        Self {
            references: 2,
            depth_tolerance: 4.0,
            eps_deg: 2.0,
            fill_radius: 3,
            depth_smooth: 0,
            sweep: 4,
            sweep_step: 0.25,
            sweep_window: 2,
            soften_sigma: 1.5,
            agree_sd: 24.0,
            reach_deg: 10.0,
            consensus: 0.2,
            soften_within: false,
            snap: 8.0,
        }
    }
}

/// A view-dependently textured new view.
#[derive(Debug, Clone)]
pub struct Textured {
    /// The image: photo texture where some reference sees the surface, the voxel colour where
    /// none does, filled holes, black outside the (closed) coverage.
    pub image: RgbImage,
    /// Pixels coloured from at least one reference photo.
    pub textured: Mask,
    /// The object region: the rough render's coverage after closing.
    pub region: Mask,
    /// The reference cameras used, nearest first.
    pub references: Vec<usize>,
}

/// Indices of the `n` cameras whose direction from `centre` is closest in angle to `cam`'s,
/// nearest first. A camera that duplicates the pose of one already chosen (same centre and
/// orientation, as templeSparseRing's views 1 and 11) is skipped: a second photo from the same
/// pose adds no parallax, and the references' disagreement, which the texturing measures, would
/// read as agreement everywhere.
pub fn nearest_by_direction(
    cams: &[Camera],
    cam: &Camera,
    centre: &Vector3<f64>,
    n: usize,
) -> Vec<usize> {
    let d = (cam.centre() - centre).normalize();
    let mut order: Vec<(f64, usize)> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| (-(c.centre() - centre).normalize().dot(&d), i))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut chosen: Vec<usize> = Vec::with_capacity(n);
    for (_, i) in order {
        if chosen.len() == n {
            break;
        }
        if !chosen.iter().any(|&j| same_pose(&cams[i], &cams[j])) {
            chosen.push(i);
        }
    }
    chosen
}

/// Fade at or above which a reference counts fully as a second view for the softening (0.25).
pub const FULL_FADE: f64 = 0.25;

/// Largest [`TextureParams::snap`] in voxel sizes (64).
pub const MAX_SNAP: f64 = 64.0;

/// Most references [`fading_references`] blends (16).
pub const MAX_REFERENCES: usize = 16;

/// The references of a new view with their fades: the `n + 1` cameras nearest by direction from
/// `centre` ([`nearest_by_direction`]), and beyond them every camera within `reach` radians,
/// each faded by `1 - angle / limit`, `limit` being the larger of `reach` and the angle of the
/// camera after the nearest `n + 1` (180 degrees when there is none); those whose fade is 0
/// are left out, and at most [`MAX_REFERENCES`] are kept. A camera's fade reaches 0 exactly
/// when it leaves the nearest `n + 1` (another one is then as near) or, with `reach`, the cone
/// of that angle, so blending weights multiplied by the fades vary continuously with the
/// viewpoint: no pop when the set changes. Between two cameras of an evenly spaced ring
/// (spaced wider than `reach`) the two get equal fades and the third none; at a camera, it
/// gets 1 and both neighbours equal fades. Where cameras are dense (photos a few degrees
/// apart), `reach` blends all that look at the object from about the same direction.
pub fn fading_references(
    cams: &[Camera],
    cam: &Camera,
    centre: &Vector3<f64>,
    n: usize,
    reach: f64,
) -> (Vec<usize>, Vec<f64>) {
    let d = (cam.centre() - centre).normalize();
    let all = nearest_by_direction(cams, cam, centre, cams.len());
    let angle = |i: usize| (cams[i].centre() - centre).normalize().angle(&d);
    let next = all.get(n + 1).map_or(std::f64::consts::PI, |&i| angle(i));
    let limit = next.max(reach);
    let (mut chosen, mut fade) = (Vec::new(), Vec::new());
    for &i in all.iter().take(MAX_REFERENCES) {
        let f = if limit > 0.0 {
            (1.0 - angle(i) / limit).max(0.0)
        } else {
            1.0
        };
        if f <= 0.0 {
            break;
        }
        chosen.push(i);
        fade.push(f);
    }
    if chosen.is_empty() {
        // Every candidate as far as the next one: they tie, all count equally.
        chosen = all.into_iter().take(n + 1).collect();
        fade = vec![1.0; chosen.len()];
    }
    (chosen, fade)
}

/// Whether two cameras share a pose: centres within 1e-6 of their distance from the origin
/// (at least 1e-9) and forward directions within 1e-6 rad.
pub fn same_pose(a: &Camera, b: &Camera) -> bool {
    let (ca, cb) = (a.centre(), b.centre());
    let scale = ca.norm().max(cb.norm()).max(1e-3);
    (ca - cb).norm() <= 1e-6 * scale && a.forward().angle(&b.forward()) <= 1e-6
}

/// The centroid of the model's surface voxels.
pub fn model_centre(model: &VoxelModel) -> Vector3<f64> {
    let n = model.surface.len().max(1) as f64;
    model
        .surface
        .iter()
        .map(|v| model.centre(v))
        .sum::<Vector3<f64>>()
        / n
}

/// One reference camera prepared for sampling.
struct Reference<'a> {
    p: Matrix3x4<f64>,
    centre: Vector3<f64>,
    image: &'a RgbImage,
    depth: Vec<f32>,
}

#[inline]
pub(crate) fn bilinear(img: &RgbImage, u: f64, v: f64) -> [f64; 3] {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let px = |x: i64, y: i64| {
        img.get_pixel(x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32)
            .0
    };
    let (a, b, c, d) = (
        px(x0, y0),
        px(x0 + 1, y0),
        px(x0, y0 + 1),
        px(x0 + 1, y0 + 1),
    );
    let mut out = [0.0; 3];
    for k in 0..3 {
        let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
        let bottom = c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx;
        out[k] = top * (1.0 - fy) + bottom * fy;
    }
    out
}

/// Where the ray `at(d)` (a world point per depth along the new view's pixel ray) meets
/// `map`, `r`'s depth map, as `r`'s pixel: the sign change of `r`'s camera depth less the map's
/// depth (at the nearest cell) nearest `d`, searched outward in steps of `step` up to `steps`
/// steps each way (the far side first at equal distance), linearly interpolated. `None` where
/// no crossing lies within reach or it projects outside the photo.
fn snapped(
    r: &Reference,
    map: &crate::stereo::DepthMap,
    at: &dyn Fn(f64) -> Vector3<f64>,
    d: f64,
    step: f64,
    steps: i64,
) -> Option<(f64, f64)> {
    // r's camera depth less the map's there: negative in front of the photo's surface.
    let gap = |j: i64| -> Option<f64> {
        let q = r.p * at(d + j as f64 * step).push(1.0);
        if q.z <= 0.0 {
            return None;
        }
        let z = map.nearest(q.x / q.z, q.y / q.z);
        z.is_finite().then(|| q.z - z as f64)
    };
    let g0 = gap(0);
    let (mut up, mut down) = (g0, g0);
    for j in 1..=steps {
        for (dir, last) in [(1, &mut up), (-1, &mut down)] {
            let g = gap(dir * j);
            if let (Some(a), Some(b)) = (*last, g) {
                if (a < 0.0) != (b < 0.0) {
                    let t = a / (a - b);
                    let dd = d + (dir as f64) * ((j - 1) as f64 + t) * step;
                    let q = r.p * at(dd).push(1.0);
                    let (u, v) = (q.x / q.z, q.y / q.z);
                    let (rw, rh) = r.image.dimensions();
                    let inside =
                        u >= 0.0 && v >= 0.0 && u <= (rw - 1) as f64 && v <= (rh - 1) as f64;
                    return inside.then_some((u, v));
                }
            }
            *last = g;
        }
    }
    None
}

/// Textures the view of `cam` (rendered rough as `rough`, `w x h`) from the reference photos.
/// `backdrop` is the colour around the object in the photos ([`crate::silhouette::colour_outside`],
/// black when unknown): the softening's blur sees it beyond the object region, as it would in
/// the photos.
pub fn texture_view(
    model: &VoxelModel,
    cams: &[Camera],
    images: &[RgbImage],
    cam: &Camera,
    rough: &Rendered,
    p: &TextureParams,
    backdrop: [u8; 3],
) -> Result<Textured> {
    if cams.len() != images.len() {
        return Err(Error::CountMismatch {
            what: "cameras vs images".into(),
            a: cams.len(),
            b: images.len(),
        });
    }
    if p.references == 0 || cams.is_empty() {
        return Err(Error::TooFew {
            what: "reference photos for texturing".into(),
            got: p.references.min(cams.len()),
            need: 1,
        });
    }
    for (name, v) in [
        ("depth_tolerance", p.depth_tolerance),
        ("eps_deg", p.eps_deg),
    ] {
        if !(v > 0.0 && v.is_finite()) {
            return Err(Error::BadParam {
                name: name.into(),
                value: v.to_string(),
                why: "must be > 0".into(),
            });
        }
    }
    if !(p.snap >= 0.0 && p.snap <= MAX_SNAP) {
        return Err(Error::BadParam {
            name: "snap".into(),
            value: p.snap.to_string(),
            why: format!("must be in 0..={MAX_SNAP} voxels"),
        });
    }
    if p.snap > 0.0 && !(p.sweep_step >= 0.01 && p.sweep_step.is_finite()) {
        return Err(Error::BadParam {
            name: "sweep_step".into(),
            value: p.sweep_step.to_string(),
            why: "must be >= 0.01 voxels when snapping to the depth maps".into(),
        });
    }
    let (w, h) = rough.image.dimensions();
    let centre = model_centre(model);
    let (chosen, fade) =
        fading_references(cams, cam, &centre, p.references, p.reach_deg.to_radians());
    let refs: Vec<Reference> = chosen
        .par_iter()
        .map(|&i| {
            let (rw, rh) = images[i].dimensions();
            Reference {
                p: cams[i].projection(),
                centre: cams[i].centre(),
                image: &images[i],
                depth: render_rough(model, &cams[i], rw, rh).depth,
            }
        })
        .collect();
    let vs = model.grid.voxel_size();
    let tol = p.depth_tolerance * (vs.x * vs.y * vs.z).cbrt();
    let eps2 = p.eps_deg.to_radians().powi(2);
    // X = A (u, v, 1) d + b: the back-projection with K inverted once.
    let kinv: Matrix3<f64> = cam
        .k
        .try_inverse()
        .expect("K is invertible: checked by Camera::new");
    let a = cam.r.transpose() * kinv;
    let b = -(cam.r.transpose() * cam.t);
    let own = cam.centre();
    let wu = w as usize;
    let n = wu * h as usize;
    let depth = smooth_depth(&rough.depth, wu, h as usize, p.depth_smooth as usize);
    let step = p.sweep_step * (vs.x * vs.y * vs.z).cbrt();
    let point = |i: usize, d: f64| a * Vector3::new((i % wu) as f64, (i / wu) as f64, 1.0) * d + b;
    // The references that see a point, with their pixel and blending weight.
    let seen = |pt: &Vector3<f64>| -> Vec<(usize, f64, f64, f64)> {
        let view = (own - pt).normalize();
        let mut out = Vec::with_capacity(refs.len());
        for (k, r) in refs.iter().enumerate() {
            let q = r.p * pt.push(1.0);
            if q.z <= 0.0 {
                continue;
            }
            let (u, v) = (q.x / q.z, q.y / q.z);
            let (rw, rh) = r.image.dimensions();
            if u < 0.0 || v < 0.0 || u > (rw - 1) as f64 || v > (rh - 1) as f64 {
                continue;
            }
            let (ix, iy) = ((u + 0.5) as usize, (v + 0.5) as usize);
            let rd = r.depth[iy.min(rh as usize - 1) * rw as usize + ix.min(rw as usize - 1)];
            // q.z is the camera-space depth: P's third row is (0, 0, 1) K times [R | t].
            if !rd.is_finite() || q.z > rd as f64 + tol {
                continue;
            }
            let angle = view.angle(&(r.centre - pt).normalize());
            out.push((k, u, v, fade[k] / (angle * angle + eps2)));
        }
        out
    };
    let refined: Vec<f64> = if p.sweep > 0 && refs.len() >= 2 {
        // Cost volume: per candidate, the variance of the references' colours (NaN where
        // fewer than two see the point), box-filtered over the window.
        let nc = 2 * p.sweep + 1;
        let costs: Vec<Vec<f32>> = (0..nc)
            .into_par_iter()
            .map(|c| {
                let off = (c as f64 - p.sweep as f64) * step;
                let raw: Vec<f32> = (0..n)
                    .map(|i| {
                        let d = depth[i];
                        if !d.is_finite() {
                            return f32::NAN;
                        }
                        let s = seen(&point(i, d + off));
                        if s.len() < 2 {
                            return f32::NAN;
                        }
                        // Weighted by the references' fade, so a reference fading out of the
                        // set stops counting gradually.
                        let cols: Vec<([f64; 3], f64)> = s
                            .iter()
                            .map(|&(k, u, v, _)| (bilinear(refs[k].image, u, v), fade[k]))
                            .collect();
                        let m = cols.iter().map(|c| c.1).sum::<f64>();
                        let mut var = 0.0;
                        for ch in 0..3 {
                            let mean = cols.iter().map(|c| c.1 * c.0[ch]).sum::<f64>() / m;
                            var += cols
                                .iter()
                                .map(|c| c.1 * (c.0[ch] - mean).powi(2))
                                .sum::<f64>()
                                / m;
                        }
                        var as f32
                    })
                    .collect();
                box_mean_nan(&raw, wu, h as usize, p.sweep_window as usize)
            })
            .collect();
        (0..n)
            .into_par_iter()
            .map(|i| {
                let mut best = (f32::INFINITY, p.sweep);
                for (c, cost) in costs.iter().enumerate() {
                    let v = cost[i];
                    // Ties (and no information) keep the hull's depth.
                    let better = v < best.0
                        || (v == best.0 && c.abs_diff(p.sweep) < best.1.abs_diff(p.sweep));
                    if v.is_finite() && better {
                        best = (v, c);
                    }
                }
                depth[i] + (best.1 as f64 - p.sweep as f64) * step
            })
            .collect()
    } else {
        depth.clone()
    };
    // Each reference's sample moved to where the pixel's ray meets that reference's own depth
    // map (the model's, one per camera in `cams`' order; none in a model without them).
    let maps = (p.snap > 0.0 && model.depths.len() == cams.len()).then_some(&model.depths);
    let snap_steps = p.snap_steps();
    // Per pixel: Some((colour, softening in [0, 1])) when some reference sees it.
    let samples: Vec<Option<([u8; 3], f64)>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let d = refined[i];
            if !d.is_finite() {
                return None;
            }
            let (mut acc, mut sq, mut wsum, mut m) = ([0.0f64; 3], [0.0f64; 3], 0.0f64, 0);
            // The two largest fades among the references that see the point.
            let mut top = [0.0f64; 2];
            for (k, u, v, wt) in seen(&point(i, d)) {
                let (u, v) = match maps {
                    Some(m) => {
                        let at = |d: f64| point(i, d);
                        snapped(&refs[k], &m[chosen[k]], &at, d, step, snap_steps).unwrap_or((u, v))
                    }
                    None => (u, v),
                };
                if fade[k] > top[0] {
                    top = [fade[k], top[0]];
                } else if fade[k] > top[1] {
                    top[1] = fade[k];
                }
                let c = bilinear(refs[k].image, u, v);
                for ch in 0..3 {
                    acc[ch] += wt * c[ch];
                    sq[ch] += wt * c[ch] * c[ch];
                }
                wsum += wt;
                m += 1;
            }
            (wsum > 0.0).then(|| {
                let mean = acc.map(|c| c / wsum);
                let sd = if m < 2 {
                    f64::INFINITY
                } else {
                    (0..3)
                        .map(|ch| (sq[ch] / wsum - mean[ch] * mean[ch]).max(0.0).sqrt())
                        .sum::<f64>()
                        / 3.0
                };
                // Softening: where the references disagree, and where only one reference
                // (counted by fade, so a reference fading out of the set counts less and less)
                // sees the point.
                let single = 1.0 - (top[1] / FULL_FADE).min(1.0);
                let t = if p.agree_sd > 0.0 {
                    (sd / p.agree_sd).min(1.0).max(single)
                } else {
                    1.0
                };
                (mean.map(|c| c.round().clamp(0.0, 255.0) as u8), t)
            })
        })
        .collect();
    let region = if p.fill_radius > 0 {
        rough.coverage.dilate(p.fill_radius).erode(p.fill_radius)
    } else {
        rough.coverage.clone()
    };
    let textured = Mask::from_fn(w, h, |x, y| samples[(y * w + x) as usize].is_some());
    // Known colours: photo samples, else the voxel colour where the rough render covers.
    let mut known: Vec<Option<[f64; 3]>> = samples
        .iter()
        .enumerate()
        .map(|(i, s)| match s {
            Some((c, _)) => Some(c.map(|v| v as f64)),
            None if rough.depth[i].is_finite() => {
                let c = rough.image.as_raw();
                Some([c[3 * i] as f64, c[3 * i + 1] as f64, c[3 * i + 2] as f64])
            }
            None => None,
        })
        .collect();
    push_pull(&mut known, wu, h as usize);
    let mut image = RgbImage::from_fn(w, h, |x, y| {
        let i = (y * w + x) as usize;
        if !region.get(x, y) {
            // Only the softening's blur reads it: black again after it.
            return Rgb(if p.soften_sigma > 0.0 {
                backdrop
            } else {
                [0; 3]
            });
        }
        Rgb(known[i]
            .unwrap_or([0.0; 3])
            .map(|v| v.round().clamp(0.0, 255.0) as u8))
    });
    if p.soften_sigma > 0.0 {
        let ksize = 2 * (3.0 * p.soften_sigma).ceil() as usize + 1;
        let soft = vt_core::blur::gaussian_blur(
            &image,
            &vt_core::blur::GaussianParams {
                ksize,
                sigma: p.soften_sigma,
            },
        )
        .map_err(|e| Error::BadParam {
            name: "soften_sigma".into(),
            value: p.soften_sigma.to_string(),
            why: e.to_string(),
        })?;
        let within = if p.soften_within {
            Some(masked_blur(&image, &region, ksize, p.soften_sigma)?)
        } else {
            None
        };
        let model_soft = if p.consensus > 0.0 {
            Some(masked_blur(
                &rough.image,
                &rough.coverage,
                ksize,
                p.soften_sigma,
            )?)
        } else {
            None
        };
        for (i, (px, sp)) in image.pixels_mut().zip(soft.pixels()).enumerate() {
            if !crate::silhouette::bit(&region, i) {
                // The backdrop served the blur; outside the region stays black.
                px.0 = [0; 3];
                continue;
            }
            let t = samples[i].map_or(1.0, |(_, t)| t);
            for ch in 0..3 {
                let mut s = within
                    .as_ref()
                    .and_then(|m| m[i])
                    .map_or(sp.0[ch] as f64, |c| c[ch]);
                if let Some(m) = &model_soft {
                    if let Some(c) = m[i] {
                        s = (1.0 - p.consensus) * s + p.consensus * c[ch];
                    }
                }
                px.0[ch] = ((1.0 - t) * px.0[ch] as f64 + t * s)
                    .round()
                    .clamp(0.0, 255.0) as u8;
            }
        }
    }
    Ok(Textured {
        image,
        textured,
        region,
        references: chosen,
    })
}

/// Gaussian blur of `img` over the pixels of `mask` only (normalised by the blurred mask);
/// `None` where the mask's blurred weight is negligible.
fn masked_blur(
    img: &RgbImage,
    mask: &Mask,
    ksize: usize,
    sigma: f64,
) -> Result<Vec<Option<[f64; 3]>>> {
    let (w, h) = img.dimensions();
    let gp = vt_core::blur::GaussianParams { ksize, sigma };
    let err = |e: vt_core::Error| Error::BadParam {
        name: "soften_sigma".into(),
        value: sigma.to_string(),
        why: e.to_string(),
    };
    let masked = RgbImage::from_fn(w, h, |x, y| {
        if mask.get(x, y) {
            *img.get_pixel(x, y)
        } else {
            Rgb([0, 0, 0])
        }
    });
    let weight = RgbImage::from_fn(w, h, |x, y| Rgb([if mask.get(x, y) { 255 } else { 0 }; 3]));
    let a = vt_core::blur::gaussian_blur(&masked, &gp).map_err(err)?;
    let b = vt_core::blur::gaussian_blur(&weight, &gp).map_err(err)?;
    Ok(a.pixels()
        .zip(b.pixels())
        .map(|(c, m)| {
            let m = m.0[0] as f64 / 255.0;
            (m > 0.02).then(|| c.0.map(|v| v as f64 / m))
        })
        .collect())
}

/// Box-filtered depth over the covered (finite) pixels; uncovered pixels stay infinite.
fn smooth_depth(depth: &[f32], w: usize, h: usize, r: usize) -> Vec<f64> {
    let d: Vec<f32> = depth
        .iter()
        .map(|&v| if v.is_finite() { v } else { f32::NAN })
        .collect();
    let m = if r == 0 {
        d.clone()
    } else {
        box_mean_nan(&d, w, h, r)
    };
    depth
        .iter()
        .zip(m)
        .map(|(&o, v)| {
            if o.is_finite() {
                v as f64
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// Mean over a `(2r + 1)^2` box of the non-NaN values (NaN where the box holds none), by
/// summed-area tables.
fn box_mean_nan(v: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let (sw, sh) = (w + 1, h + 1);
    let mut sum = vec![0.0f64; sw * sh];
    let mut cnt = vec![0u32; sw * sh];
    for y in 0..h {
        let (mut rs, mut rc) = (0.0f64, 0u32);
        for x in 0..w {
            let a = v[y * w + x];
            if !a.is_nan() {
                rs += a as f64;
                rc += 1;
            }
            sum[(y + 1) * sw + x + 1] = sum[y * sw + x + 1] + rs;
            cnt[(y + 1) * sw + x + 1] = cnt[y * sw + x + 1] + rc;
        }
    }
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
            let (x1, y1) = ((x + r + 1).min(w), (y + r + 1).min(h));
            let c = cnt[y1 * sw + x1] + cnt[y0 * sw + x0] - cnt[y0 * sw + x1] - cnt[y1 * sw + x0];
            if c == 0 {
                return f32::NAN;
            }
            let s = sum[y1 * sw + x1] + sum[y0 * sw + x0] - sum[y0 * sw + x1] - sum[y1 * sw + x0];
            (s / c as f64) as f32
        })
        .collect()
}

/// Fills every `None` of a `w x h` image from its known neighbours by push-pull: average the
/// known pixels 2x2 down a pyramid until everything is known, then fill each level's gaps from
/// the coarser level on the way back up.
pub fn push_pull(px: &mut [Option<[f64; 3]>], w: usize, h: usize) {
    if px.iter().all(Option::is_some) || px.iter().all(Option::is_none) || w * h <= 1 {
        return;
    }
    let (hw, hh) = (w.div_ceil(2), h.div_ceil(2));
    let mut coarse: Vec<Option<[f64; 3]>> = vec![None; hw * hh];
    for (cy, row) in coarse.chunks_mut(hw).enumerate() {
        for (cx, c) in row.iter_mut().enumerate() {
            let (mut acc, mut n) = ([0.0; 3], 0.0);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (x, y) = (2 * cx + dx, 2 * cy + dy);
                if x < w && y < h {
                    if let Some(v) = px[y * w + x] {
                        (0..3).for_each(|k| acc[k] += v[k]);
                        n += 1.0;
                    }
                }
            }
            if n > 0.0 {
                *c = Some(acc.map(|a| a / n));
            }
        }
    }
    push_pull(&mut coarse, hw, hh);
    for y in 0..h {
        for x in 0..w {
            if px[y * w + x].is_none() {
                px[y * w + x] = coarse[(y / 2) * hw + x / 2];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_skip_a_duplicated_pose() {
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let origin = Vector3::zeros();
        let down = Vector3::new(0.0, 0.0, -1.0);
        let at = |deg: f64| {
            let a = deg.to_radians();
            let c = Vector3::new(a.cos(), a.sin(), 0.0);
            Camera::look_at(format!("{deg}"), k, c, origin, down).unwrap()
        };
        // Ring: -30, -30 (same pose again), 30, 60; the new view at 0.
        let cams = vec![at(-30.0), at(60.0), at(-30.0), at(30.0)];
        assert!(same_pose(&cams[0], &cams[2]) && !same_pose(&cams[0], &cams[3]));
        let chosen = nearest_by_direction(&cams, &at(0.0), &origin, 2);
        assert_eq!(chosen, vec![0, 3]);
        // Asking for more than there are distinct poses gives the distinct ones.
        assert_eq!(nearest_by_direction(&cams, &at(0.0), &origin, 4).len(), 3);
    }

    /// A ring of cameras every `step` degrees from -`span` to `span`, looking at the origin.
    fn ring(step: f64, span: f64) -> Vec<Camera> {
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let n = (2.0 * span / step).round() as i64;
        (0..=n).map(|i| at(k, -span + i as f64 * step)).collect()
    }

    fn at(k: Matrix3<f64>, deg: f64) -> Camera {
        let a = deg.to_radians();
        let c = Vector3::new(10.0 * a.cos(), 10.0 * a.sin(), 0.0);
        Camera::look_at(
            format!("{deg}"),
            k,
            c,
            Vector3::zeros(),
            Vector3::new(0.0, 0.0, -1.0),
        )
        .unwrap()
    }

    #[test]
    fn snapping_finds_where_the_ray_meets_the_references_depth_map() {
        // The wall x = 0.5 seen from 30 degrees round the ring; the new view from 0 degrees.
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let (cam, rc) = (at(k, 0.0), at(k, 30.0));
        let (w, h) = (640usize, 480usize);
        let kinv = k.try_inverse().unwrap();
        let wall = |c: &Camera, u: f64, v: f64| {
            let dir = c.r.transpose() * kinv * Vector3::new(u, v, 1.0);
            let t = (0.5 - c.centre().x) / dir.x;
            c.centre() + dir * t
        };
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                let x = wall(&rc, (i % w) as f64, (i / w) as f64);
                (rc.r * x + rc.t).z as f32
            })
            .collect();
        let mut map = crate::stereo::DepthMap {
            w,
            h,
            step: 1,
            depth,
        };
        let image = RgbImage::new(w as u32, h as u32);
        let r = Reference {
            p: rc.projection(),
            centre: rc.centre(),
            image: &image,
            depth: Vec::new(),
        };
        let (u, v) = (300.0, 200.0);
        let ray = cam.r.transpose() * kinv * Vector3::new(u, v, 1.0);
        let at_depth = |d: f64| cam.centre() + ray * d;
        let truth = wall(&cam, u, v);
        let d_true = (cam.r * truth + cam.t).z;
        let (tu, tv, _) = rc.project(&truth).unwrap();
        // From 0.3 in front or behind, within a reach of 16 steps of 0.05: the wall's pixel (to
        // a quarter pixel: the map is constant over each pixel), where the unsnapped point
        // projects pixels away.
        for off in [-0.3, 0.3] {
            let (ou, _, _) = rc.project(&at_depth(d_true + off)).unwrap();
            assert!((ou - tu).abs() > 5.0, "{off}: {ou} against {tu}");
            let got = snapped(&r, &map, &at_depth, d_true + off, 0.05, 16).unwrap();
            assert!(
                (got.0 - tu).abs() < 0.25 && (got.1 - tv).abs() < 0.25,
                "{off}: {got:?} against ({tu}, {tv})"
            );
        }
        // Out of reach, or no depth in the map: no crossing.
        assert_eq!(snapped(&r, &map, &at_depth, d_true + 1.0, 0.05, 16), None);
        map.depth.iter_mut().for_each(|d| *d = f32::NAN);
        assert_eq!(snapped(&r, &map, &at_depth, d_true + 0.3, 0.05, 16), None);
    }

    #[test]
    fn reach_blends_every_camera_within_it_and_leaves_sparse_rings_alone() {
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let origin = Vector3::zeros();
        // Cameras 5 degrees apart; the new view at 1 degree.
        let dense = ring(5.0, 30.0);
        let view = at(k, 1.0);
        let angle_of = |cams: &[Camera], i: usize| cams[i].name.parse::<f64>().unwrap();
        let (two, _) = fading_references(&dense, &view, &origin, 2, 0.0);
        let mut got: Vec<f64> = two.iter().map(|&i| angle_of(&dense, i)).collect();
        got.sort_by(f64::total_cmp);
        assert_eq!(got, vec![-5.0, 0.0, 5.0]);
        let (wide, fade) = fading_references(&dense, &view, &origin, 2, 10f64.to_radians());
        let mut got: Vec<f64> = wide.iter().map(|&i| angle_of(&dense, i)).collect();
        got.sort_by(f64::total_cmp);
        // Within 10 degrees of 1: -5, 0, 5, 10 (at 9); -10 (at 11) is out.
        assert_eq!(got, vec![-5.0, 0.0, 5.0, 10.0]);
        assert!(fade.iter().all(|&f| f > 0.0 && f <= 1.0));
        // A ring spaced wider than the reach: the same references and fades as without it.
        let sparse = ring(30.0, 180.0);
        let without = fading_references(&sparse, &view, &origin, 2, 0.0);
        let with = fading_references(&sparse, &view, &origin, 2, 10f64.to_radians());
        assert_eq!(without, with);
    }

    #[test]
    fn fades_with_reach_vary_continuously_with_the_viewpoint() {
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let origin = Vector3::zeros();
        let dense = ring(5.0, 30.0);
        let fades = |deg: f64| {
            let (c, f) = fading_references(&dense, &at(k, deg), &origin, 2, 10f64.to_radians());
            let mut all = vec![0.0; dense.len()];
            for (i, v) in c.into_iter().zip(f) {
                all[i] = v;
            }
            all
        };
        // Steps of 0.05 degrees across several cameras: no fade jumps (a camera entering or
        // leaving the set does so at fade 0).
        let mut prev = fades(-8.0);
        let mut largest = 0.0f64;
        for i in 1..=320 {
            let now = fades(-8.0 + i as f64 * 0.05);
            for (a, b) in prev.iter().zip(&now) {
                largest = largest.max((a - b).abs());
            }
            prev = now;
        }
        assert!(largest < 0.02, "largest fade step {largest}");
    }

    #[test]
    fn blur_within_a_region_keeps_its_colour_at_the_rim() {
        let (w, h) = (40u32, 30u32);
        let region = Mask::from_fn(w, h, |x, y| (8..30).contains(&x) && (5..25).contains(&y));
        let img = RgbImage::from_fn(w, h, |x, y| {
            if region.get(x, y) {
                Rgb([120, 90, 60])
            } else {
                Rgb([0, 0, 0])
            }
        });
        let b = masked_blur(&img, &region, 11, 1.5).unwrap();
        for y in 0..h {
            for x in 0..w {
                if region.get(x, y) {
                    let c = b[(y * w + x) as usize].expect("inside the region");
                    for (got, want) in c.iter().zip([120.0, 90.0, 60.0]) {
                        assert!((got - want).abs() <= 2.0, "({x}, {y}): {c:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn push_pull_fills_gaps_from_neighbours_and_keeps_known_pixels() {
        let (w, h) = (9, 7);
        let mut px: Vec<Option<[f64; 3]>> = (0..w * h)
            .map(|i| (i % 3 != 0).then_some([(i % w) as f64 * 10.0, 50.0, 0.0]))
            .collect();
        let before = px.clone();
        push_pull(&mut px, w, h);
        for (a, b) in px.iter().zip(&before) {
            let a = a.expect("every pixel filled");
            if let Some(b) = b {
                assert_eq!(a, *b);
            } else {
                // A filled value lies within the range of the known values.
                assert!((0.0..=80.0).contains(&a[0]) && a[1] == 50.0);
            }
        }
    }
}
