//! How far a reconstructed surface lies from [`SynthObject`]'s true surface, both ways: from
//! each reconstructed point to the true surface (exact, analytic), and from points spread evenly
//! over the true surface to the nearest reconstructed point (a Monte Carlo estimate over
//! [`SynthObject::surface_samples`], exact per sample). A voxel model passes its surface voxels'
//! centres and its voxel size, and reads the distances in voxels.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::object::SynthObject;

/// Mean and 90th percentile of a set of distances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// 90th percentile (the value at rank `floor(0.9 * (n - 1))` of the sorted distances).
    pub p90: f64,
}

impl Spread {
    /// Mean and 90th percentile of `d` (NaN for none).
    pub fn of(mut d: Vec<f64>) -> Self {
        if d.is_empty() {
            return Self {
                mean: f64::NAN,
                p90: f64::NAN,
            };
        }
        d.sort_by(f64::total_cmp);
        Self {
            mean: d.iter().sum::<f64>() / d.len() as f64,
            p90: d[(0.9 * (d.len() - 1) as f64) as usize],
        }
    }
}

/// Distances between a reconstructed surface and the true one, in the caller's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceDistance {
    /// From each reconstructed point to the true surface (how far the model's surface strays).
    pub to_truth: Spread,
    /// From evenly spread true-surface points to the nearest reconstructed point (how much of
    /// the true surface the model misses or covers from afar).
    pub from_truth: Spread,
}

impl SurfaceDistance {
    /// The two-way mean: the average of the two directions' means.
    pub fn mean(&self) -> f64 {
        0.5 * (self.to_truth.mean + self.from_truth.mean)
    }

    /// The two-way 90th percentile: the average of the two directions' 90th percentiles.
    pub fn p90(&self) -> f64 {
        0.5 * (self.to_truth.p90 + self.from_truth.p90)
    }
}

impl SynthObject {
    /// Exact distance from `p` to the solid's surface (the boundary of the union of the sphere
    /// and the box), inside or outside.
    ///
    /// The nearest surface point is the minimum over a finite candidate set: the surface is the
    /// part of the sphere outside the open box and the part of the box's faces outside the
    /// open sphere, so the minimum lies at a local minimum of a smooth piece (the radial
    /// projection onto the sphere, the orthogonal projection onto a face or an edge) or on
    /// where the pieces meet (the circle in which the sphere cuts a face's plane, the points
    /// where it cuts an edge, the corners). Each candidate is kept only if it is on the surface.
    pub fn surface_distance(&self, p: &Vector3<f64>) -> f64 {
        let (c, r) = (self.sphere_centre, self.sphere_radius);
        let (lo, hi) = (self.cuboid.min, self.cuboid.max);
        let tol = 1e-9 * (r + (hi - lo).norm());
        let in_open_sphere = |q: &Vector3<f64>| (q - c).norm() < r - tol;
        let in_open_box =
            |q: &Vector3<f64>| (0..3).all(|i| q[i] > lo[i] + tol && q[i] < hi[i] - tol);
        let mut best = f64::INFINITY;
        let mut consider = |q: Vector3<f64>| best = best.min((p - q).norm());
        // The sphere: radial projection (any point when p is the centre).
        let dir = (p - c).try_normalize(1e-300).unwrap_or_else(Vector3::x);
        let q = c + dir * r;
        if !in_open_box(&q) {
            consider(q);
        }
        // The faces, and the circles the sphere cuts from their planes.
        for a in 0..3 {
            let (b, d) = ((a + 1) % 3, (a + 2) % 3);
            for s in [lo[a], hi[a]] {
                let mut q = *p;
                q[a] = s;
                q[b] = q[b].clamp(lo[b], hi[b]);
                q[d] = q[d].clamp(lo[d], hi[d]);
                if !in_open_sphere(&q) {
                    consider(q);
                }
                let h = s - c[a];
                if h.abs() < r {
                    let rc = (r * r - h * h).sqrt();
                    let mut centre = c;
                    centre[a] = s;
                    let mut in_plane = *p;
                    in_plane[a] = s;
                    let mut fallback = Vector3::zeros();
                    fallback[b] = 1.0;
                    let dir = (in_plane - centre)
                        .try_normalize(1e-300)
                        .unwrap_or(fallback);
                    let q = centre + dir * rc;
                    let within = |i: usize| q[i] >= lo[i] - tol && q[i] <= hi[i] + tol;
                    if within(b) && within(d) {
                        consider(q);
                    }
                }
            }
        }
        // The edges: orthogonal projection, and where the sphere cuts them. (Corners are the
        // projection clamped to an end.)
        for a in 0..3 {
            let (b, d) = ((a + 1) % 3, (a + 2) % 3);
            for sb in [lo[b], hi[b]] {
                for sd in [lo[d], hi[d]] {
                    let mut e0 = Vector3::zeros();
                    e0[b] = sb;
                    e0[d] = sd;
                    e0[a] = lo[a];
                    let len = hi[a] - lo[a];
                    let mut q = e0;
                    q[a] = p[a].clamp(lo[a], hi[a]);
                    if !in_open_sphere(&q) {
                        consider(q);
                    }
                    // |e0 + t x_a - c|^2 = r^2 along the edge's axis.
                    let off = (e0[b] - c[b]).powi(2) + (e0[d] - c[d]).powi(2);
                    if off <= r * r {
                        let w = (r * r - off).sqrt();
                        for x in [c[a] - w, c[a] + w] {
                            if x >= lo[a] && x <= lo[a] + len {
                                let mut q = e0;
                                q[a] = x;
                                consider(q);
                            }
                        }
                    }
                }
            }
        }
        best
    }

    /// Distances between a reconstructed surface, given as points (e.g. a voxel model's surface
    /// voxel centres), and the true surface, divided by `unit` (e.g. the voxel size): exact from
    /// each point; from `samples` evenly spread true-surface points (`seed` picks them) to the
    /// nearest point, found exactly through a uniform cell grid. `None` for no points, no
    /// samples or a `unit` that is not a positive number.
    pub fn compare_surface(
        &self,
        points: &[Vector3<f64>],
        unit: f64,
        samples: usize,
        seed: u64,
    ) -> Option<SurfaceDistance> {
        if points.is_empty() || samples == 0 || !(unit > 0.0 && unit.is_finite()) {
            return None;
        }
        let to_truth: Vec<f64> = points
            .par_iter()
            .map(|p| self.surface_distance(p) / unit)
            .collect();
        let index = PointIndex::new(points, 2.0 * unit);
        let truth = self.surface_samples(samples, seed);
        let from_truth: Vec<f64> = truth.par_iter().map(|q| index.nearest(q) / unit).collect();
        Some(SurfaceDistance {
            to_truth: Spread::of(to_truth),
            from_truth: Spread::of(from_truth),
        })
    }
}

/// Points bucketed in cubic cells, for exact nearest-point queries (shells of cells searched
/// outwards until no nearer cell can exist).
struct PointIndex<'a> {
    points: &'a [Vector3<f64>],
    min: Vector3<f64>,
    side: f64,
    n: [i64; 3],
    /// Point indices sorted by cell, and each cell's start in that list (`n` cells + 1).
    order: Vec<u32>,
    start: Vec<u32>,
}

impl<'a> PointIndex<'a> {
    fn new(points: &'a [Vector3<f64>], side: f64) -> Self {
        let mut min = Vector3::repeat(f64::INFINITY);
        let mut max = Vector3::repeat(f64::NEG_INFINITY);
        for p in points {
            min = min.inf(p);
            max = max.sup(p);
        }
        // At most about 2^24 cells: coarser cells for a sparse spread-out set.
        let ext = max - min;
        let mut side = side;
        while (0..3).map(|i| ext[i] / side + 1.0).product::<f64>() > 16.0e6 {
            side *= 2.0;
        }
        let n = [0, 1, 2].map(|i| (ext[i] / side).floor() as i64 + 1);
        let cells = (n[0] * n[1] * n[2]) as usize;
        let mut index = Self {
            points,
            min,
            side,
            n,
            order: Vec::new(),
            start: vec![0; cells + 1],
        };
        let cell_of: Vec<usize> = points.iter().map(|p| index.cell(p)).collect();
        for &k in &cell_of {
            index.start[k + 1] += 1;
        }
        for k in 0..cells {
            index.start[k + 1] += index.start[k];
        }
        let mut fill = index.start.clone();
        index.order = vec![0; points.len()];
        for (i, &k) in cell_of.iter().enumerate() {
            index.order[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        index
    }

    fn coords(&self, p: &Vector3<f64>) -> [i64; 3] {
        [0, 1, 2]
            .map(|i| (((p[i] - self.min[i]) / self.side).floor() as i64).clamp(0, self.n[i] - 1))
    }

    fn cell(&self, p: &Vector3<f64>) -> usize {
        let [x, y, z] = self.coords(p);
        ((z * self.n[1] + y) * self.n[0] + x) as usize
    }

    /// Distance from `q` to the nearest indexed point.
    fn nearest(&self, q: &Vector3<f64>) -> f64 {
        let home = self.coords(q);
        // How far q lies outside the indexed box: cells are clamped, so shells count from there.
        let outside = (0..3)
            .map(|i| {
                let below = self.min[i] - q[i];
                let above = q[i] - (self.min[i] + self.n[i] as f64 * self.side);
                below.max(above).max(0.0)
            })
            .fold(0.0f64, |a, b| a.hypot(b));
        let reach = self.n.iter().copied().max().unwrap_or(1);
        let mut best = f64::INFINITY;
        for r in 0..=reach {
            // Every point in shell r is at least (r - 1) cell sides from q's clamped cell.
            let lower = ((r - 1).max(0) as f64 * self.side).max(outside);
            if lower > best {
                break;
            }
            for cz in home[2] - r..=home[2] + r {
                for cy in home[1] - r..=home[1] + r {
                    for cx in home[0] - r..=home[0] + r {
                        let on_shell = (cx - home[0]).abs() == r
                            || (cy - home[1]).abs() == r
                            || (cz - home[2]).abs() == r;
                        if !on_shell
                            || cx < 0
                            || cy < 0
                            || cz < 0
                            || cx >= self.n[0]
                            || cy >= self.n[1]
                            || cz >= self.n[2]
                        {
                            continue;
                        }
                        let k = ((cz * self.n[1] + cy) * self.n[0] + cx) as usize;
                        for &i in &self.order[self.start[k] as usize..self.start[k + 1] as usize] {
                            best = best.min((self.points[i as usize] - q).norm());
                        }
                    }
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::object::Cuboid;

    /// Distance to the surface by brute force: the nearest of many surface samples (an upper
    /// bound that approaches the truth as samples grow).
    fn brute(samples: &[Vector3<f64>], p: &Vector3<f64>) -> f64 {
        samples
            .iter()
            .map(|s| (s - p).norm())
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn exact_distance_matches_dense_samples_inside_and_outside() {
        let obj = SynthObject::default();
        let samples = obj.surface_samples(400_000, 3);
        let mut rng = vt_core::rng::Rng::new(11);
        let b = obj.bounds();
        for _ in 0..300 {
            let p = Vector3::new(
                b.min.x - 0.2 + rng.f64() * (b.max.x - b.min.x + 0.4),
                b.min.y - 0.2 + rng.f64() * (b.max.y - b.min.y + 0.4),
                b.min.z - 0.2 + rng.f64() * (b.max.z - b.min.z + 0.4),
            );
            let exact = obj.surface_distance(&p);
            let approx = brute(&samples, &p);
            // The samples are about 0.004 apart: the nearest one is at most a little farther
            // than the true nearest point, never nearer.
            assert!(
                approx >= exact - 1e-9 && approx <= exact + 0.01,
                "{p}: exact {exact}, samples {approx}"
            );
        }
        // Known points: the sphere's centre is a radius from the surface (the box's top face
        // z = 0 passes through it, but inside the sphere that face is no surface).
        assert!((obj.surface_distance(&Vector3::zeros()) - 0.5).abs() < 1e-12);
        let above = Vector3::new(0.0, 0.0, 0.8);
        assert!((obj.surface_distance(&above) - 0.3).abs() < 1e-12);
        let tip = Vector3::new(-0.85, 0.0, -0.2);
        assert!((obj.surface_distance(&tip) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn a_sphere_shell_is_its_radius_difference_away_both_ways() {
        // A sphere with a box hidden inside it: the surface is the sphere alone.
        let obj = SynthObject {
            sphere_centre: Vector3::new(0.1, -0.2, 0.3),
            sphere_radius: 0.5,
            cuboid: Cuboid {
                min: Vector3::new(0.0, -0.3, 0.2),
                max: Vector3::new(0.2, -0.1, 0.4),
            },
        };
        // Points on a concentric sphere of radius 0.56: every point is 0.06 from the surface,
        // and every surface point is 0.06 from the nearest point (up to the points' spacing).
        let mut points = Vec::new();
        let n = 400;
        for i in 0..n {
            // A Fibonacci sphere: near-even spacing.
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let s = (1.0 - z * z).sqrt();
            points.push(obj.sphere_centre + Vector3::new(s * phi.cos(), s * phi.sin(), z) * 0.56);
        }
        let d = obj.compare_surface(&points, 0.01, 20_000, 5).unwrap();
        assert!((d.to_truth.mean - 6.0).abs() < 1e-9, "{d:?}");
        assert!((d.to_truth.p90 - 6.0).abs() < 1e-9, "{d:?}");
        // Spacing of 400 points on radius 0.56: about 0.1, so up to ~0.05 more from the truth.
        assert!(d.from_truth.mean > 6.0 && d.from_truth.mean < 8.0, "{d:?}");
        assert!((d.mean() - 0.5 * (d.to_truth.mean + d.from_truth.mean)).abs() < 1e-12);
        // Half the points gone (one hemisphere): the far side of the truth is a diameter away.
        let half: Vec<_> = points
            .iter()
            .copied()
            .filter(|p| p.z > obj.sphere_centre.z)
            .collect();
        let h = obj.compare_surface(&half, 0.01, 20_000, 5).unwrap();
        assert!((h.to_truth.mean - 6.0).abs() < 1e-9);
        assert!(h.from_truth.mean > 20.0 && h.from_truth.p90 > 40.0, "{h:?}");
        assert!(obj.compare_surface(&[], 0.01, 10, 1).is_none());
        assert!(obj.compare_surface(&points, 0.0, 10, 1).is_none());
    }
}
