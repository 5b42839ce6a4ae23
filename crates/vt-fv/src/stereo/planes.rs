//! PatchMatch stereo with a slanted plane per pixel (Bleyer et al. 2011; Schönberger et al.
//! 2016's multi-view form): each cell of a photo's depth map holds a plane, a depth and a
//! normal, and its window is compared with the sources through the homography that plane
//! induces, so a surface seen at a slant matches across wide baselines, where the plane sweep's
//! fronto-parallel window smears. Planes start at random inside the hull's stretch of the ray,
//! then spread to neighbours (red-black: every cell of one colour updates in parallel from the
//! other colour's planes, the four nearest and four three cells away) and are refined by random
//! perturbations that shrink every iteration. A second round starts from the first's planes and
//! docks each source's score for how far the point, carried into the source by the plane and
//! back by the source's own first-round depth, lands from where it started (geometric
//! consistency, as COLMAP's PatchMatch stereo). The rounds measure a cell every
//! `pixel_step` pixels; [`StereoParams::fine`] then carries each cell's plane to the pixels
//! around it and iterates there, with the geometric term, so the map holds every pixel.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use vt_core::rng::{hash, Rng};

use super::{
    best_mean, hull_interval, ncc, reference_window, setup, DepthMap, Plane, StereoParams,
    Transfer, Window,
};
use crate::camera::Camera;
use crate::hull::VoxelGrid;
use crate::silhouette::Mask;

/// Largest photo whose depth map [`StereoParams::fine`] measures at every pixel (4.2 million
/// pixels: a cell's window and plane take about 150 bytes while it is measured).
const FINE_PHOTO_PIXELS: usize = 1 << 22;
/// Most pixels all photos together may hold for [`StereoParams::fine`] (33.5 million: half what
/// a model file's depth maps may hold).
const FINE_TOTAL_PIXELS: usize = 1 << 25;

/// One cell's plane: camera depth at the cell's pixel, unit normal in camera axes (facing the
/// camera), and the plane's score (mean NCC of the best sources; `-inf` when unscored).
#[derive(Clone, Copy)]
pub(super) struct Hyp {
    d: f64,
    n: Vector3<f64>,
    score: f64,
}

/// What a cell needs to score planes: its pixel, ray, the reference window (centred) and its
/// energy, and the hull's stretch of its ray.
struct Cell {
    x: f64,
    y: f64,
    ray: Vector3<f64>,
    refv: Vec<f32>,
    var: f32,
    near: f64,
    far: f64,
}

struct Scorer<'a> {
    planes: &'a [Plane],
    transfers: Vec<Transfer>,
    /// Per source, the map back from it to the reference (for the geometric term).
    backs: Vec<Transfer>,
    /// The other photos' depth maps from a first round, and the weight of the forward-backward
    /// reprojection error (pixels, capped at 3, scaled to 0..1) taken off each source's NCC.
    geo: Option<(&'a [DepthMap], f64)>,
    window: Window,
    kinv: Matrix3<f64>,
    best: usize,
}

impl Scorer<'_> {
    /// Mean NCC of the best sources for plane `(d, n)` at `cell`; `-inf` when the plane is
    /// seen edge-on or too few sources see the window.
    fn score(&self, cell: &Cell, d: f64, n: &Vector3<f64>, scores: &mut Vec<f32>) -> f64 {
        let nr = n.dot(&cell.ray);
        if nr > -1e-3 {
            return f64::NEG_INFINITY;
        }
        // The plane's depth along the ray of pixel p is c / (g . p), g = K^-T n: every window
        // point must lie in front of the camera, which the lattice's corners decide (g . p is
        // linear in the offset).
        let g = self.kinv.transpose() * n;
        let c = d * nr;
        for &(dx, dy) in &self.window.corners {
            if nr + g.x * dx as f64 + g.y * dy as f64 > -1e-6 {
                return f64::NEG_INFINITY;
            }
        }
        scores.clear();
        let centre = Vector3::new(cell.x, cell.y, 1.0);
        for (t, tr) in self.transfers.iter().enumerate() {
            let h = plane_homography(tr, &g, c, &centre);
            let src = &self.planes[tr.src];
            let Some(mut ncc) = ncc(src, &cell.refv, cell.var, &self.window, h) else {
                continue;
            };
            if let Some((maps, weight)) = self.geo {
                let q0 = tr.a * centre * d + tr.b;
                let (u, v) = (q0.x / q0.z, q0.y / q0.z);
                let ds = maps[tr.src].nearest(u, v) as f64;
                let err = if ds.is_finite() {
                    let bk = &self.backs[t];
                    let pb = bk.a * Vector3::new(u, v, 1.0) * ds + bk.b;
                    ((pb.x / pb.z - cell.x).powi(2) + (pb.y / pb.z - cell.y).powi(2)).sqrt()
                } else {
                    3.0
                };
                ncc -= (weight * err.min(3.0) / 3.0) as f32;
            }
            scores.push(ncc);
        }
        best_mean(scores, self.best)
    }
}

/// The homography a plane induces from the reference to a source, on a window's offsets: the
/// plane meets the ray of reference pixel `p` at camera depth `c / (g . p)` (`g = K^-T n`, `c`
/// the depth at the window's centre times `n . ray`), so `x_s ~ (A + b g^T / c) p`; returned as
/// the columns acting on `(dx, dy, 1)` about pixel `centre`.
fn plane_homography(
    tr: &Transfer,
    g: &Vector3<f64>,
    c: f64,
    centre: &Vector3<f64>,
) -> [Vector3<f64>; 3] {
    let m = tr.a + tr.b * (g.transpose() / c);
    [
        m.column(0).into_owned(),
        m.column(1).into_owned(),
        m * centre,
    ]
}

/// A random unit normal facing the camera along `ray` (at most about 80 degrees off it).
fn random_normal(rng: &mut Rng, ray: &Vector3<f64>) -> Vector3<f64> {
    let back = -ray.normalize();
    for _ in 0..8 {
        let v = Vector3::new(rng.normal(), rng.normal(), rng.normal());
        let Some(mut v) = v.try_normalize(1e-9) else {
            continue;
        };
        if v.dot(&back) < 0.0 {
            v = -v;
        }
        if v.dot(&back) > 0.17 {
            return v;
        }
    }
    back
}

/// `n` turned by a random small angle (about `sigma` radians), still facing the camera.
fn perturb_normal(rng: &mut Rng, n: &Vector3<f64>, sigma: f64, ray: &Vector3<f64>) -> Vector3<f64> {
    let v = n + Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
    match v.try_normalize(1e-9) {
        Some(v) if v.dot(&-ray.normalize()) > 0.17 => v,
        _ => *n,
    }
}

/// The depth map of photo `i` by PatchMatch over slanted planes inside `grid`'s hull, against its
/// nearest photos: the same cells, sources, window and acceptance as the plane sweep. `start`:
/// the planes to go on from (a second round), `geo`: the first round's maps and the weight of
/// the geometric term. Returns the map and the planes.
#[allow(clippy::too_many_arguments)]
pub(super) fn patchmatch_map(
    i: usize,
    grid: &VoxelGrid,
    cams: &[Camera],
    planes: &[Plane],
    masks: &[Mask],
    centre: &Vector3<f64>,
    p: &StereoParams,
    start: Option<&[Hyp]>,
    geo: Option<(&[DepthMap], f64)>,
) -> (DepthMap, Vec<Hyp>) {
    let cam = &cams[i];
    let plane = &planes[i];
    let (w, h) = (plane.w, plane.h);
    let (kinv, transfers, window) = setup(i, cams, centre, p);
    let backs: Vec<Transfer> = transfers
        .iter()
        .map(|tr| Transfer::new(&cams[tr.src], cam, i))
        .collect();
    let scorer = Scorer {
        planes,
        transfers,
        backs,
        geo,
        window,
        kinv,
        best: p.best,
    };
    let nk = scorer.window.len();
    let nv = nk * plane.c;
    let step = p.pixel_step;
    let (mw, mh) = (w.div_ceil(step), h.div_ceil(step));
    let r = p.radius as usize;
    // The cells inside the silhouette, with texture and a stretch of hull on their ray.
    let cells: Vec<Option<Cell>> = (0..mw * mh)
        .into_par_iter()
        .map(|ci| {
            let (x, y) = ((ci % mw) * step, (ci / mw) * step);
            if !masks[i].get(x as u32, y as u32) || x < r || y < r || x + r >= w || y + r >= h {
                return None;
            }
            let mut refv = vec![0f32; nv];
            let (var, spread) = reference_window(plane, x, y, &scorer.window.offsets, &mut refv);
            if spread < p.min_texture {
                return None;
            }
            let (near, far) = hull_interval(grid, cam, &kinv, x as f64, y as f64)?;
            Some(Cell {
                x: x as f64,
                y: y as f64,
                ray: kinv * Vector3::new(x as f64, y as f64, 1.0),
                refv,
                var,
                near,
                far,
            })
        })
        .collect();
    let vs = grid.voxel_size().min();
    let seed = hash(&[0x5057_4d56, i as u64]);
    let unscored = Hyp {
        d: f64::NAN,
        n: Vector3::zeros(),
        score: f64::NEG_INFINITY,
    };
    // Random planes to start.
    let mut hyps: Vec<Hyp> = cells
        .par_iter()
        .enumerate()
        .map_init(Vec::new, |sc, (ci, c)| {
            let Some(c) = c else { return unscored };
            let mut rng = Rng::new(hash(&[seed, ci as u64, u64::MAX]));
            let (d, n) = match start {
                Some(h) if h[ci].score.is_finite() => (h[ci].d, h[ci].n),
                _ => (
                    c.near + rng.f64() * (c.far - c.near),
                    random_normal(&mut rng, &c.ray),
                ),
            };
            Hyp {
                d,
                n,
                score: scorer.score(c, d, &n, sc),
            }
        })
        .collect();
    // The slack a depth may leave the hull's stretch by (a voxel along the ray).
    let slack = |c: &Cell| vs / c.ray.norm();
    let neighbours: [(i64, i64); 8] = [
        (-1, 0),
        (1, 0),
        (0, -1),
        (0, 1),
        (-3, 0),
        (3, 0),
        (0, -3),
        (0, 3),
    ];
    let (first, iters) = if start.is_some() {
        (p.patchmatch, p.patchmatch + p.geo_iters)
    } else {
        (0, p.patchmatch)
    };
    for it in first..iters {
        let shrink = 0.5f64.powi(it as i32 + 1);
        for colour in 0..2 {
            let updates: Vec<(usize, Hyp)> = (0..mh)
                .into_par_iter()
                .flat_map_iter(|cy| {
                    let mut sc = Vec::new();
                    let mut out = Vec::new();
                    let hyps = &hyps;
                    let cells = &cells;
                    let scorer = &scorer;
                    for cx in ((cy + colour) % 2..mw).step_by(2) {
                        let ci = cy * mw + cx;
                        let Some(c) = &cells[ci] else { continue };
                        let mut best = hyps[ci];
                        let (lo, hi) = (c.near - slack(c), c.far + slack(c));
                        let mut rng = Rng::new(hash(&[seed, ci as u64, it as u64]));
                        let mut try_plane = |d: f64, n: Vector3<f64>, best: &mut Hyp| {
                            if !(d >= lo && d <= hi) {
                                return;
                            }
                            let s = scorer.score(c, d, &n, &mut sc);
                            if s > best.score {
                                *best = Hyp { d, n, score: s };
                            }
                        };
                        // Neighbours' planes, carried to this cell's ray.
                        for (dx, dy) in neighbours {
                            let (nx, ny) = (cx as i64 + dx, cy as i64 + dy);
                            if nx < 0 || ny < 0 || nx >= mw as i64 || ny >= mh as i64 {
                                continue;
                            }
                            let nb = &hyps[ny as usize * mw + nx as usize];
                            let Some(nc) = &cells[ny as usize * mw + nx as usize] else {
                                continue;
                            };
                            if !nb.score.is_finite() {
                                continue;
                            }
                            let den = nb.n.dot(&c.ray);
                            if den > -1e-6 {
                                continue;
                            }
                            let d = nb.d * nb.n.dot(&nc.ray) / den;
                            try_plane(d, nb.n, &mut best);
                        }
                        // Random refinement around the best so far, then a fresh guess.
                        let range = (c.far - c.near + 2.0 * slack(c)) * shrink;
                        let sigma = 0.6 * shrink;
                        let cur = best;
                        if cur.score.is_finite() {
                            let d = cur.d + (rng.f64() - 0.5) * range;
                            let n = perturb_normal(&mut rng, &cur.n, sigma, &c.ray);
                            try_plane(d, n, &mut best);
                            let d = cur.d + (rng.f64() - 0.5) * range;
                            try_plane(d, cur.n, &mut best);
                            let n = perturb_normal(&mut rng, &cur.n, sigma, &c.ray);
                            try_plane(cur.d, n, &mut best);
                        }
                        let d = c.near + rng.f64() * (c.far - c.near);
                        let n = random_normal(&mut rng, &c.ray);
                        try_plane(d, n, &mut best);
                        out.push((ci, best));
                    }
                    out
                })
                .collect();
            for (ci, hyp) in updates {
                hyps[ci] = hyp;
            }
        }
    }
    let map = DepthMap {
        w: mw,
        h: mh,
        step,
        depth: hyps
            .iter()
            .map(|h| {
                if h.score >= p.min_ncc {
                    h.d as f32
                } else {
                    f32::NAN
                }
            })
            .collect(),
    };
    (map, hyps)
}

/// Every photo's depth map by PatchMatch; with `geo_iters`, a second round from the first's
/// planes with the geometric term against the first round's maps (each photo's first round
/// runs without it, so the rounds do not depend on the order of the photos).
pub(super) fn patchmatch_all(
    grid: &VoxelGrid,
    cams: &[Camera],
    planes: &[Plane],
    masks: &[Mask],
    centre: &Vector3<f64>,
    p: &StereoParams,
) -> Vec<DepthMap> {
    // Photo i's map and planes under settings q, from start, against the maps geo.
    let run = |i: usize, q: &StereoParams, start: Option<&[Hyp]>, geo: Option<&[DepthMap]>| {
        patchmatch_map(
            i,
            grid,
            cams,
            planes,
            masks,
            centre,
            q,
            start,
            geo.map(|m| (m, p.geo_weight)),
        )
    };
    let (maps, first): (Vec<DepthMap>, Vec<Vec<Hyp>>) =
        (0..cams.len()).map(|i| run(i, p, None, None)).unzip();
    let (maps, last) = if p.geo_iters == 0 {
        (maps, first)
    } else {
        (0..cams.len())
            .map(|i| run(i, p, Some(&first[i]), Some(&maps)))
            .unzip()
    };
    let pixels: Vec<usize> = planes.iter().map(|pl| pl.w * pl.h).collect();
    if p.fine == 0
        || p.pixel_step == 1
        || pixels.iter().any(|&n| n > FINE_PHOTO_PIXELS)
        || pixels.iter().sum::<usize>() > FINE_TOTAL_PIXELS
    {
        return maps;
    }
    // Every pixel from its nearest cell's plane, then `fine` iterations there with the
    // geometric term against the rounds' maps; numbered on from the rounds' iterations, so the
    // random refinement keeps shrinking.
    let fine = StereoParams {
        pixel_step: 1,
        patchmatch: p.patchmatch + p.geo_iters,
        geo_iters: p.fine,
        ..*p
    };
    (0..cams.len())
        .map(|i| {
            let start = upsample(&last[i], &maps[i], &cams[i], planes[i].w, planes[i].h);
            run(i, &fine, Some(&start), Some(&maps)).0
        })
        .collect()
}

/// A plane for every pixel of a `w x h` photo: the nearest cell's of `map`'s grid (`hyps`), its
/// depth carried along the plane to the pixel's ray (unscored where the cell has none).
fn upsample(hyps: &[Hyp], map: &DepthMap, cam: &Camera, w: usize, h: usize) -> Vec<Hyp> {
    let kinv = cam
        .k
        .try_inverse()
        .expect("K is invertible: checked by Camera::new");
    let ray = |x: usize, y: usize| kinv * Vector3::new(x as f64, y as f64, 1.0);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (cx, cy) = map.cell(x as f64, y as f64);
            let cx = cx.clamp(0, map.w as i64 - 1) as usize;
            let cy = cy.clamp(0, map.h as i64 - 1) as usize;
            let hyp = hyps[cy * map.w + cx];
            let den = hyp.n.dot(&ray(x, y));
            if !hyp.score.is_finite() || den > -1e-6 {
                return Hyp {
                    score: f64::NEG_INFINITY,
                    ..hyp
                };
            }
            let d = hyp.d * hyp.n.dot(&ray(cx * map.step, cy * map.step)) / den;
            Hyp { d, ..hyp }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    /// A textured photo: smooth, aperiodic luma.
    fn photo(w: u32, h: u32, seed: f64) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let (x, y) = (x as f64, y as f64);
            let v = 128.0
                + 60.0 * (0.21 * x + seed).sin() * (0.17 * y).cos()
                + 40.0 * (0.05 * (x + 2.0 * y) + seed).sin();
            image::Rgb([v as u8, (255.0 - v) as u8, (v * 0.5) as u8])
        })
    }

    fn look(name: &str, from: Vector3<f64>) -> Camera {
        let k = Matrix3::new(300.0, 0.0, 99.5, 0.0, 300.0, 79.5, 0.0, 0.0, 1.0);
        Camera::look_at(name, k, from, Vector3::zeros(), Vector3::new(0.0, 0.0, 1.0)).unwrap()
    }

    /// Brute force: each window sample's ray met with the plane in the reference camera's
    /// axes, the 3D point projected into the source, sampled bilinearly, NCC in f64.
    fn brute(
        r: &Camera,
        s: &Camera,
        src: &Plane,
        refv: &[f32],
        win: &Window,
        (x, y): (f64, f64),
        d: f64,
        n: &Vector3<f64>,
    ) -> Option<f64> {
        let kinv = r.k.try_inverse().unwrap();
        let ray0 = kinv * Vector3::new(x, y, 1.0);
        let x0 = ray0 * d; // the cell's point on the plane, camera axes
        let c = src.c;
        let mut samples = Vec::new();
        for &(dx, dy) in &win.offsets {
            let ray = kinv * Vector3::new(x + dx as f64, y + dy as f64, 1.0);
            let t = n.dot(&x0) / n.dot(&ray);
            let world = r.r.transpose() * (ray * t - r.t);
            let q = s.k * (s.r * world + s.t);
            let (u, v) = (q.x / q.z, q.y / q.z);
            if !(q.z > 0.0
                && u >= 0.0
                && v >= 0.0
                && u < (src.w - 1) as f64
                && v < (src.h - 1) as f64)
            {
                return None;
            }
            let (ui, vi) = (u.floor() as usize, v.floor() as usize);
            let (fx, fy) = (u - ui as f64, v - vi as f64);
            for ch in 0..c {
                let at = |x: usize, y: usize| src.v[(y * src.w + x) * c + ch] as f64;
                let a = at(ui, vi) * (1.0 - fx) + at(ui + 1, vi) * fx;
                let b = at(ui, vi + 1) * (1.0 - fx) + at(ui + 1, vi + 1) * fx;
                samples.push(a * (1.0 - fy) + b * fy);
            }
        }
        let k = samples.len() / c;
        let mut mean = vec![0.0; c];
        for (j, v) in samples.iter().enumerate() {
            mean[j % c] += v / k as f64;
        }
        let (mut cov, mut rv, mut sv) = (0.0, 0.0, 0.0);
        for (j, (v, r)) in samples.iter().zip(refv).enumerate() {
            let s = v - mean[j % c];
            cov += *r as f64 * s;
            rv += (*r as f64).powi(2);
            sv += s * s;
        }
        Some(cov / (rv * sv).sqrt())
    }

    #[test]
    fn plane_homography_ncc_matches_projecting_each_sample() {
        let r = look("r", Vector3::new(6.0, 0.5, 1.0));
        let s = look("s", Vector3::new(4.5, 4.0, 2.0));
        for colour in [false, true] {
            let (rp, sp) = (
                Plane::of(&photo(200, 160, 0.0), colour),
                Plane::of(&photo(200, 160, 1.3), colour),
            );
            // The default 4x4 lattice, and an 11x11 one (several runs of samples).
            let (half, stride) = if colour { (5, 1) } else { (3, 2) };
            let win = Window::new(
                (-half..=half)
                    .step_by(stride)
                    .flat_map(|dy| (-half..=half).step_by(stride).map(move |dx| (dx, dy)))
                    .collect(),
            );
            let kinv = r.k.try_inverse().unwrap();
            let tr = Transfer::new(&r, &s, 1);
            let (mut checked, mut outside) = (0, 0);
            for (i, (x, y)) in [
                (100usize, 80usize),
                (40, 30),
                (160, 120),
                (20, 140),
                (180, 20),
            ]
            .into_iter()
            .enumerate()
            {
                let mut refv = vec![0f32; win.len() * rp.c];
                let (var, _) = reference_window(&rp, x, y, &win.offsets, &mut refv);
                let ray = kinv * Vector3::new(x as f64, y as f64, 1.0);
                for (j, tilt) in [0.0, 0.4, -0.7].into_iter().enumerate() {
                    let n = (-ray.normalize()
                        + Vector3::new(tilt, 0.5 * tilt, 0.2 * (i as f64 - j as f64)))
                    .normalize();
                    let d = 5.0 + 0.3 * i as f64;
                    let g = kinv.transpose() * n;
                    let centre = Vector3::new(x as f64, y as f64, 1.0);
                    let h = plane_homography(&tr, &g, d * n.dot(&ray), &centre);
                    let fast = ncc(&sp, &refv, var, &win, h);
                    let slow = brute(&r, &s, &sp, &refv, &win, (x as f64, y as f64), d, &n);
                    match (fast, slow) {
                        (Some(a), Some(b)) => {
                            assert!(
                                (a as f64 - b).abs() < 2e-3,
                                "{colour} ({x}, {y}) tilt {tilt}: {a} vs {b}"
                            );
                            checked += 1;
                        }
                        (None, None) => outside += 1,
                        other => panic!("{colour} ({x}, {y}) tilt {tilt}: {other:?}"),
                    }
                }
            }
            assert!(
                checked >= 8,
                "only {checked} windows inside the source ({outside} outside)"
            );
        }
    }
}
