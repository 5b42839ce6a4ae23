//! Visual hull by volume intersection on a bit-packed voxel grid (SPEC B.1).
//!
//! Rule for voxels outside a camera's frame: a camera votes on a voxel only when the voxel's
//! centre projects inside its image and lies in front of it ("visible in frame"); a voxel is kept
//! when every voting camera sees object there and at least [`HullParams::min_views`] cameras vote.
//!
//! Carving is coarse to fine: a block of voxels is projected (the 8 corners of its extreme voxel
//! centres) into every camera; a block whose projected rectangle is all background in any camera
//! is removed whole, a camera whose rectangle is all object stops being checked inside the block,
//! and only undecided blocks are split, down to single voxels.

use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::camera::{Camera, MIN_DEPTH};
use crate::silhouette::{check_masks, Integral, Mask};
use crate::{Error, Result};

/// An axis-aligned box in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vector3<f64>,
    /// Maximum corner.
    pub max: Vector3<f64>,
}

impl Aabb {
    /// Where the ray `o + t d` (`t >= 0`) is inside the box: its entry and exit `t`, or None.
    pub fn ray_span(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for k in 0..3 {
            if d[k].abs() < 1e-12 {
                if o[k] < self.min[k] || o[k] > self.max[k] {
                    return None;
                }
                continue;
            }
            let (a, c) = ((self.min[k] - o[k]) / d[k], (self.max[k] - o[k]) / d[k]);
            t0 = t0.max(a.min(c));
            t1 = t1.min(a.max(c));
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// A box from its corners.
    pub fn new(min: Vector3<f64>, max: Vector3<f64>) -> Self {
        Self { min, max }
    }

    /// Box centre.
    pub fn centre(&self) -> Vector3<f64> {
        (self.min + self.max) * 0.5
    }

    /// The 8 corners.
    pub fn corners(&self) -> [Vector3<f64>; 8] {
        let (a, b) = (self.min, self.max);
        std::array::from_fn(|i| {
            Vector3::new(
                if i & 1 == 0 { a.x } else { b.x },
                if i & 2 == 0 { a.y } else { b.y },
                if i & 4 == 0 { a.z } else { b.z },
            )
        })
    }

    fn check(&self) -> Result<()> {
        let bad = |what: &str| {
            Err(Error::BadBounds {
                min: self.min.into(),
                max: self.max.into(),
                what: what.into(),
            })
        };
        if self
            .min
            .iter()
            .chain(self.max.iter())
            .any(|v| !v.is_finite())
        {
            return bad("not finite");
        }
        if (0..3).any(|i| self.max[i] <= self.min[i]) {
            return bad("max must exceed min on every axis");
        }
        Ok(())
    }
}

/// A bit-packed occupancy grid over a world box; voxel `(x, y, z)` has bit
/// `(z * ny + y) * nx + x` and centre `min + (i + 0.5) * voxel_size`.
#[derive(Clone, PartialEq)]
pub struct VoxelGrid {
    dims: [usize; 3],
    bounds: Aabb,
    words: Vec<u64>,
}

impl std::fmt::Debug for VoxelGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "VoxelGrid({:?}, {:?}, {} set)",
            self.dims,
            self.bounds,
            self.count()
        )
    }
}

/// Bytes of the bit array of a grid, or an error when over `limit` (checked before allocating).
pub fn grid_bytes(dims: [usize; 3], limit: u64) -> Result<u64> {
    let [nx, ny, nz] = dims;
    let bytes = nx
        .checked_mul(ny)
        .and_then(|v| v.checked_mul(nz))
        .map(|n| (n as u64).div_ceil(64).saturating_mul(8))
        .unwrap_or(u64::MAX);
    if bytes > limit || dims.contains(&0) {
        return Err(Error::GridTooLarge {
            nx,
            ny,
            nz,
            bytes,
            limit,
        });
    }
    Ok(bytes)
}

impl VoxelGrid {
    /// An empty grid; refuses grids whose bit array would exceed `max_bytes` before allocating.
    pub fn new(dims: [usize; 3], bounds: Aabb, max_bytes: u64) -> Result<Self> {
        bounds.check()?;
        let bytes = grid_bytes(dims, max_bytes)?;
        Ok(Self {
            dims,
            bounds,
            words: vec![0; (bytes / 8) as usize],
        })
    }

    /// Voxels along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The world box the grid covers.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Edge lengths of one voxel.
    pub fn voxel_size(&self) -> Vector3<f64> {
        let e = self.bounds.max - self.bounds.min;
        Vector3::new(
            e.x / self.dims[0] as f64,
            e.y / self.dims[1] as f64,
            e.z / self.dims[2] as f64,
        )
    }

    /// Linear index of voxel `(x, y, z)`.
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    /// Voxel coordinates of a linear index.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        let x = i % self.dims[0];
        let yz = i / self.dims[0];
        [x, yz % self.dims[1], yz / self.dims[1]]
    }

    /// World centre of voxel `(x, y, z)`.
    #[inline]
    pub fn centre(&self, v: [usize; 3]) -> Vector3<f64> {
        let s = self.voxel_size();
        self.bounds.min
            + Vector3::new(
                (v[0] as f64 + 0.5) * s.x,
                (v[1] as f64 + 0.5) * s.y,
                (v[2] as f64 + 0.5) * s.z,
            )
    }

    /// Whether voxel `(x, y, z)` is occupied; `false` outside the grid.
    #[inline]
    pub fn get(&self, x: i64, y: i64, z: i64) -> bool {
        if x < 0
            || y < 0
            || z < 0
            || x >= self.dims[0] as i64
            || y >= self.dims[1] as i64
            || z >= self.dims[2] as i64
        {
            return false;
        }
        self.get_index(self.index(x as usize, y as usize, z as usize))
    }

    /// Whether the voxel with linear index `i` is occupied.
    #[inline]
    pub fn get_index(&self, i: usize) -> bool {
        self.words[i / 64] >> (i % 64) & 1 != 0
    }

    /// Sets or clears the voxel with linear index `i`.
    #[inline]
    pub fn set_index(&mut self, i: usize, v: bool) {
        if v {
            self.words[i / 64] |= 1 << (i % 64);
        } else {
            self.words[i / 64] &= !(1 << (i % 64));
        }
    }

    /// Number of occupied voxels.
    pub fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Occupied volume in world units.
    pub fn volume(&self) -> f64 {
        let s = self.voxel_size();
        self.count() as f64 * s.x * s.y * s.z
    }

    /// Linear indices of the occupied voxels, ascending.
    pub fn occupied(&self) -> Vec<usize> {
        let mut out = Vec::new();
        for (wi, &w) in self.words.iter().enumerate() {
            let mut w = w;
            while w != 0 {
                out.push(wi * 64 + w.trailing_zeros() as usize);
                w &= w - 1;
            }
        }
        out
    }

    /// Whether an occupied voxel is on the surface: some 6-neighbour is empty or outside the grid.
    #[inline]
    pub fn is_surface(&self, v: [usize; 3]) -> bool {
        let (x, y, z) = (v[0] as i64, v[1] as i64, v[2] as i64);
        !(self.get(x - 1, y, z)
            && self.get(x + 1, y, z)
            && self.get(x, y - 1, z)
            && self.get(x, y + 1, z)
            && self.get(x, y, z - 1)
            && self.get(x, y, z + 1))
    }

    /// The voxel holding a world point, if inside the grid.
    pub fn voxel_of(&self, p: &Vector3<f64>) -> Option<[usize; 3]> {
        let s = self.voxel_size();
        let r = p - self.bounds.min;
        let f = [r.x / s.x, r.y / s.y, r.z / s.z];
        if f.iter()
            .zip(self.dims)
            .any(|(&c, n)| !(c >= 0.0 && c < n as f64))
        {
            return None;
        }
        Some([f[0] as usize, f[1] as usize, f[2] as usize])
    }

    /// Whether a world point lies in an occupied voxel or within `tolerance` voxels (Chebyshev)
    /// of one. Carving tests voxel centres, so a true surface point can sit in a voxel whose
    /// centre was carved; a tolerance of 1 accounts for that.
    pub fn contains_point_within(&self, p: &Vector3<f64>, tolerance: usize) -> bool {
        let s = self.voxel_size();
        let r = p - self.bounds.min;
        let f = [
            (r.x / s.x).floor() as i64,
            (r.y / s.y).floor() as i64,
            (r.z / s.z).floor() as i64,
        ];
        let t = tolerance as i64;
        for dz in -t..=t {
            for dy in -t..=t {
                for dx in -t..=t {
                    if self.get(f[0] + dx, f[1] + dy, f[2] + dz) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Bounding box (inclusive voxel coordinates) of the occupied voxels.
    pub fn occupied_bbox(&self) -> Option<([usize; 3], [usize; 3])> {
        let mut lo = [usize::MAX; 3];
        let mut hi = [0; 3];
        for i in self.occupied() {
            let c = self.coords(i);
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        (lo[0] != usize::MAX).then_some((lo, hi))
    }
}

/// Visual hull parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct HullParams {
    /// Voxels along x, y and z (paper: 256^3).
    pub dims: [usize; 3],
    /// World box to carve; `None` finds it from the silhouettes (see [`auto_bounds`]).
    pub bounds: Option<Aabb>,
    /// A voxel needs at least this many cameras seeing it in frame (1).
    pub min_views: usize,
    /// Largest bit array allowed, in bytes (512 MiB: about 1600^3 voxels). The photo hull needs
    /// about three times the bit array plus per-surface-voxel data.
    pub max_bytes: u64,
    /// Voxels along the longest side of the coarse grids used by [`auto_bounds`] (64).
    pub bounds_resolution: usize,
}

impl Default for HullParams {
    fn default() -> Self {
        Self {
            dims: [256; 3],
            bounds: None,
            min_views: 1,
            max_bytes: 512 << 20,
            bounds_resolution: 64,
        }
    }
}

/// A camera prepared for carving.
struct View<'a> {
    p: [f64; 12],
    w: i64,
    h: i64,
    integral: Integral,
    mask: &'a Mask,
}

impl View<'_> {
    #[inline]
    fn project(&self, x: &Vector3<f64>) -> Option<(f64, f64)> {
        let p = &self.p;
        let z = p[8] * x.x + p[9] * x.y + p[10] * x.z + p[11];
        if z <= MIN_DEPTH {
            return None;
        }
        let u = p[0] * x.x + p[1] * x.y + p[2] * x.z + p[3];
        let v = p[4] * x.x + p[5] * x.y + p[6] * x.z + p[7];
        Some((u / z, v / z))
    }
}

fn views<'a>(cams: &[Camera], masks: &'a [Mask]) -> Vec<View<'a>> {
    cams.iter()
        .zip(masks)
        .map(|(c, m)| {
            let pm = c.projection();
            View {
                p: std::array::from_fn(|i| pm[(i / 4, i % 4)]),
                w: m.width() as i64,
                h: m.height() as i64,
                integral: Integral::new(m),
                mask: m,
            }
        })
        .collect()
}

#[derive(Clone, Copy, PartialEq)]
enum Vote {
    /// Every centre in the block projects outside this image.
    Outside,
    /// Every centre lands on background: the block goes.
    Background,
    /// Every centre lands on object, in frame.
    Object,
    /// Undecided.
    Mixed,
}

struct Carver<'a> {
    views: Vec<View<'a>>,
    min: Vector3<f64>,
    size: Vector3<f64>,
    dims: [usize; 3],
    min_views: usize,
    words: Vec<AtomicU64>,
}

const TOP_BLOCK: usize = 16;

impl Carver<'_> {
    fn centre(&self, x: usize, y: usize, z: usize) -> Vector3<f64> {
        self.min
            + Vector3::new(
                (x as f64 + 0.5) * self.size.x,
                (y as f64 + 0.5) * self.size.y,
                (z as f64 + 0.5) * self.size.z,
            )
    }

    fn classify(&self, v: &View, lo: [usize; 3], hi: [usize; 3]) -> Vote {
        let a = self.centre(lo[0], lo[1], lo[2]);
        let b = self.centre(hi[0] - 1, hi[1] - 1, hi[2] - 1);
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for c in (Aabb { min: a, max: b }).corners() {
            let Some((u, vv)) = v.project(&c) else {
                return Vote::Mixed;
            };
            u0 = u0.min(u);
            u1 = u1.max(u);
            v0 = v0.min(vv);
            v1 = v1.max(vv);
        }
        let (x0, x1) = ((u0 + 0.5).floor() as i64, (u1 + 0.5).floor() as i64);
        let (y0, y1) = ((v0 + 0.5).floor() as i64, (v1 + 0.5).floor() as i64);
        if x1 < 0 || y1 < 0 || x0 >= v.w || y0 >= v.h {
            return Vote::Outside;
        }
        let inside = x0 >= 0 && y0 >= 0 && x1 < v.w && y1 < v.h;
        if !inside {
            return Vote::Mixed;
        }
        let (count, area) = v.integral.count(x0, y0, x1, y1);
        if count == 0 {
            Vote::Background
        } else if count == area {
            Vote::Object
        } else {
            Vote::Mixed
        }
    }

    fn fill(&self, lo: [usize; 3], hi: [usize; 3]) {
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                let base = (z * self.dims[1] + y) * self.dims[0];
                set_range(&self.words, base + lo[0], base + hi[0]);
            }
        }
    }

    fn visit(&self, lo: [usize; 3], hi: [usize; 3], active: &[u32], satisfied: usize) {
        let mut next = Vec::with_capacity(active.len());
        let mut sat = satisfied;
        for &c in active {
            match self.classify(&self.views[c as usize], lo, hi) {
                Vote::Background => return,
                Vote::Outside => {}
                Vote::Object => sat += 1,
                Vote::Mixed => next.push(c),
            }
        }
        if next.is_empty() {
            if sat >= self.min_views {
                self.fill(lo, hi);
            }
            return;
        }
        let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        if ext.iter().product::<usize>() <= 8 {
            for z in lo[2]..hi[2] {
                for y in lo[1]..hi[1] {
                    for x in lo[0]..hi[0] {
                        if self.voxel(x, y, z, &next, sat) {
                            set_range(&self.words, self.index(x, y, z), self.index(x, y, z) + 1);
                        }
                    }
                }
            }
            return;
        }
        // Split every axis longer than one voxel in half.
        let mid = [lo[0] + ext[0] / 2, lo[1] + ext[1] / 2, lo[2] + ext[2] / 2];
        for oct in 0..8 {
            let mut clo = lo;
            let mut chi = hi;
            let mut skip = false;
            for a in 0..3 {
                if oct >> a & 1 == 0 {
                    chi[a] = if ext[a] > 1 { mid[a] } else { hi[a] };
                } else if ext[a] > 1 {
                    clo[a] = mid[a];
                } else {
                    skip = true;
                }
            }
            if !skip {
                self.visit(clo, chi, &next, sat);
            }
        }
    }

    fn index(&self, x: usize, y: usize, z: usize) -> usize {
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    fn voxel(&self, x: usize, y: usize, z: usize, active: &[u32], mut sat: usize) -> bool {
        let c = self.centre(x, y, z);
        for &ci in active {
            let v = &self.views[ci as usize];
            let Some((u, vv)) = v.project(&c) else {
                continue;
            };
            let (px, py) = ((u + 0.5).floor() as i64, (vv + 0.5).floor() as i64);
            if px < 0 || py < 0 || px >= v.w || py >= v.h {
                continue;
            }
            if !crate::silhouette::bit(v.mask, (py * v.w + px) as usize) {
                return false;
            }
            sat += 1;
        }
        sat >= self.min_views
    }
}

fn set_range(words: &[AtomicU64], start: usize, end: usize) {
    let mut i = start;
    while i < end {
        let w = i / 64;
        let b = i % 64;
        let n = (64 - b).min(end - i);
        let mask = if n == 64 {
            u64::MAX
        } else {
            ((1u64 << n) - 1) << b
        };
        words[w].fetch_or(mask, Ordering::Relaxed);
        i += n;
    }
}

/// Carves the grid `dims` over `bounds` with the given views (no checks; see [`visual_hull`]).
fn carve(
    views: Vec<View>,
    bounds: Aabb,
    dims: [usize; 3],
    min_views: usize,
    max_bytes: u64,
) -> Result<VoxelGrid> {
    let bytes = grid_bytes(dims, max_bytes)?;
    bounds.check()?;
    let words: Vec<AtomicU64> = (0..bytes / 8).map(|_| AtomicU64::new(0)).collect();
    let e = bounds.max - bounds.min;
    let size = Vector3::new(
        e.x / dims[0] as f64,
        e.y / dims[1] as f64,
        e.z / dims[2] as f64,
    );
    let carver = Carver {
        views,
        min: bounds.min,
        size,
        dims,
        min_views,
        words,
    };
    let nb = dims.map(|n| n.div_ceil(TOP_BLOCK));
    let all: Vec<u32> = (0..carver.views.len() as u32).collect();
    (0..nb[0] * nb[1] * nb[2]).into_par_iter().for_each(|b| {
        let bx = b % nb[0];
        let by = b / nb[0] % nb[1];
        let bz = b / nb[0] / nb[1];
        let lo = [bx * TOP_BLOCK, by * TOP_BLOCK, bz * TOP_BLOCK];
        let hi = [
            (lo[0] + TOP_BLOCK).min(dims[0]),
            (lo[1] + TOP_BLOCK).min(dims[1]),
            (lo[2] + TOP_BLOCK).min(dims[2]),
        ];
        carver.visit(lo, hi, &all, 0);
    });
    let words = carver
        .words
        .into_iter()
        .map(AtomicU64::into_inner)
        .collect();
    Ok(VoxelGrid {
        dims,
        bounds,
        words,
    })
}

/// Checks the inputs shared by the hull functions.
fn check_inputs(cams: &[Camera], masks: &[Mask]) -> Result<()> {
    if cams.is_empty() {
        return Err(Error::TooFew {
            what: "cameras".into(),
            got: 0,
            need: 1,
        });
    }
    let sizes: Vec<(u32, u32)> = masks.iter().map(|m| (m.width(), m.height())).collect();
    let names: Vec<&str> = cams.iter().map(|c| c.name.as_str()).collect();
    if cams.len() != masks.len() {
        return Err(Error::CountMismatch {
            what: "cameras vs silhouettes".into(),
            a: cams.len(),
            b: masks.len(),
        });
    }
    check_masks(masks, &sizes, &names)
}

/// Whether any part of the box projects into a camera's `w x h` image.
pub fn sees_box(cam: &Camera, b: &Aabb, w: u32, h: u32) -> bool {
    let pts: Vec<(f64, f64)> = b
        .corners()
        .iter()
        .filter_map(|c| cam.project(c).map(|(u, v, _)| (u, v)))
        .collect();
    if pts.is_empty() {
        return false;
    }
    if pts.len() < 8 {
        // The box straddles the camera plane: part of it is in front, assume it is seen.
        return true;
    }
    let u0 = pts.iter().map(|p| p.0).fold(f64::MAX, f64::min);
    let u1 = pts.iter().map(|p| p.0).fold(f64::MIN, f64::max);
    let v0 = pts.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    let v1 = pts.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    u1 >= -0.5 && v1 >= -0.5 && u0 < w as f64 - 0.5 && v0 < h as f64 - 0.5
}

/// Cubic-voxel grid dimensions with `n` voxels along the longest side of `b`.
pub fn dims_for(b: &Aabb, n: usize) -> [usize; 3] {
    let e = b.max - b.min;
    let s = e.max() / n as f64;
    [
        (e.x / s).ceil().max(1.0) as usize,
        (e.y / s).ceil().max(1.0) as usize,
        (e.z / s).ceil().max(1.0) as usize,
    ]
}

/// Finds a box around the object: a first guess from the least-squares meeting point of the
/// rays through the silhouettes' bounding-box centres (size from the silhouettes' extents at that
/// depth), then coarse carving (`bounds_resolution` voxels on the longest side, every camera
/// that sees the box must see a voxel in frame), growing the box while the coarse hull touches
/// its border, and shrinking it to the coarse hull padded by 1.5 coarse voxels; twice.
pub fn auto_bounds(cams: &[Camera], masks: &[Mask], params: &HullParams) -> Result<Aabb> {
    check_inputs(cams, masks)?;
    // Least-squares point nearest to all rays: sum (I - d d^T) (X - C) = 0.
    let mut a = nalgebra::Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    let mut rays = Vec::new();
    for (c, m) in cams.iter().zip(masks) {
        // Inclusive box of the set pixels (vt-core's upper bounds are exclusive).
        let (x0, y0, x1, y1) = m
            .bounding_box()
            .map(|(x0, y0, x1, y1)| (x0, y0, x1 - 1, y1 - 1))
            .expect("silhouettes are not empty: checked above");
        let d = c.ray((x0 + x1) as f64 / 2.0, (y0 + y1) as f64 / 2.0);
        let proj = nalgebra::Matrix3::identity() - d * d.transpose();
        a += proj;
        rhs += proj * c.centre();
        rays.push((x0, y0, x1, y1));
    }
    let centre = a.try_inverse().map(|ai| ai * rhs).unwrap_or_else(|| {
        cams.iter()
            .map(|c| c.centre() + c.forward())
            .sum::<Vector3<f64>>()
            / cams.len() as f64
    });
    let mut radius: f64 = 0.0;
    for (c, &(x0, y0, x1, y1)) in cams.iter().zip(&rays) {
        let depth = (centre - c.centre()).dot(&c.forward()).abs().max(1e-9);
        let half = ((x1 - x0) as f64).hypot((y1 - y0) as f64) / 2.0 + 2.0;
        radius = radius.max(half / c.k[(0, 0)].abs().min(c.k[(1, 1)].abs()) * depth);
    }
    let mut bounds = Aabb::new(
        centre - Vector3::repeat(radius * 1.5),
        centre + Vector3::repeat(radius * 1.5),
    );
    let n = params.bounds_resolution.max(8);
    for _pass in 0..2 {
        let mut grown = 0;
        loop {
            let seeing: Vec<usize> = (0..cams.len())
                .filter(|&i| sees_box(&cams[i], &bounds, masks[i].width(), masks[i].height()))
                .collect();
            if seeing.is_empty() {
                return Err(Error::EmptyModel {
                    stage: "automatic bounds (no camera sees the first guess)".into(),
                });
            }
            let sub_cams: Vec<Camera> = seeing.iter().map(|&i| cams[i].clone()).collect();
            let sub_masks: Vec<Mask> = seeing.iter().map(|&i| masks[i].clone()).collect();
            let dims = dims_for(&bounds, n);
            let g = carve(
                views(&sub_cams, &sub_masks),
                bounds,
                dims,
                seeing.len(),
                params.max_bytes,
            )?;
            let Some((lo, hi)) = g.occupied_bbox() else {
                return Err(Error::EmptyModel {
                    stage: "automatic bounds (coarse carving)".into(),
                });
            };
            let touches = (0..3).any(|a| lo[a] == 0 || hi[a] + 1 == dims[a]);
            if touches && grown < 4 {
                grown += 1;
                let c = bounds.centre();
                let h = (bounds.max - bounds.min) * 1.0;
                bounds = Aabb::new(c - h, c + h);
                continue;
            }
            let s = g.voxel_size();
            let pad = s * 1.5;
            let min = bounds.min
                + Vector3::new(lo[0] as f64 * s.x, lo[1] as f64 * s.y, lo[2] as f64 * s.z)
                - pad;
            let max = bounds.min
                + Vector3::new(
                    (hi[0] + 1) as f64 * s.x,
                    (hi[1] + 1) as f64 * s.y,
                    (hi[2] + 1) as f64 * s.z,
                )
                + pad;
            bounds = Aabb::new(min, max);
            break;
        }
    }
    Ok(bounds)
}

/// The visual hull: voxels of `params.dims` over the given or automatic bounds that land on an
/// object pixel in every camera that sees them in frame (see the module doc for the rule).
///
/// Errors: count or size mismatches, an empty silhouette, a camera that sees none of the volume,
/// a grid over `max_bytes` (refused before allocating) and an empty result.
pub fn visual_hull(cams: &[Camera], masks: &[Mask], params: &HullParams) -> Result<VoxelGrid> {
    check_inputs(cams, masks)?;
    grid_bytes(params.dims, params.max_bytes)?;
    let bounds = match params.bounds {
        Some(b) => {
            b.check()?;
            b
        }
        None => auto_bounds(cams, masks, params)?,
    };
    for (i, (c, m)) in cams.iter().zip(masks).enumerate() {
        if !sees_box(c, &bounds, m.width(), m.height()) {
            return Err(Error::CameraSeesNoVolume {
                index: i,
                name: c.name.clone(),
                min: bounds.min.into(),
                max: bounds.max.into(),
            });
        }
    }
    let g = carve(
        views(cams, masks),
        bounds,
        params.dims,
        params.min_views,
        params.max_bytes,
    )?;
    if g.count() == 0 {
        return Err(Error::EmptyModel {
            stage: "visual hull".into(),
        });
    }
    Ok(g)
}

/// Below this IoU a view's silhouette disagrees with the visual hull of the others
/// ([`silhouette_agreement`]; 0.6). On the kettle's 28 real photos (automatic silhouettes) the
/// views score 0.71-0.94; a mirrored photo (paired with the wrong camera) scores 0.28 and a
/// silhouette with half the object cut away 0.44 (`tests/silhouettes.rs`).
pub const AGREEMENT_IOU: f64 = 0.6;

/// Cross-view consistency of the silhouettes: for each view, the IoU of its silhouette against
/// the projection of the visual hull carved from the other views (`grid` voxels along the
/// volume's longest side, within `bounds`; a voxel's centre tested). So that one bad view does
/// not spoil every other view's figure, the hull of the others tolerates a tenth of them
/// (rounded down) putting the voxel outside their silhouette. A view whose silhouette misses
/// part of the object, includes clutter, or whose camera is wrong scores low
/// ([`AGREEMENT_IOU`]); an empty hull gives 0.
pub fn silhouette_agreement(
    cams: &[Camera],
    masks: &[Mask],
    bounds: Aabb,
    grid: usize,
) -> Result<Vec<f64>> {
    check_inputs(cams, masks)?;
    let n = cams.len();
    if n < 3 {
        return Err(Error::TooFew {
            what: "views for the silhouette check".into(),
            got: n,
            need: 3,
        });
    }
    let dims = dims_for(&bounds, grid.clamp(8, 256));
    let template = VoxelGrid::new(dims, bounds, HullParams::default().max_bytes)?;
    let total = dims[0] * dims[1] * dims[2];
    // Per view, which voxels it puts outside its silhouette (in frame, centre on a clear pixel).
    let outside: Vec<Vec<bool>> = cams
        .par_iter()
        .zip(masks)
        .map(|(c, m)| {
            (0..total)
                .map(|i| {
                    let p = template.centre(template.coords(i));
                    match c.project(&p) {
                        Some((u, v, _)) => {
                            let (x, y) = (u.round() as i64, v.round() as i64);
                            x >= 0
                                && y >= 0
                                && x < m.width() as i64
                                && y < m.height() as i64
                                && !m.get(x as u32, y as u32)
                        }
                        None => false,
                    }
                })
                .collect()
        })
        .collect();
    let mut count = vec![0u32; total];
    for o in &outside {
        for (c, &b) in count.iter_mut().zip(o) {
            *c += b as u32;
        }
    }
    let tolerance = ((n - 1) / 10) as u32;
    Ok((0..n)
        .into_par_iter()
        .map(|k| {
            let mut g = template.clone();
            for i in 0..total {
                if count[i] - outside[k][i] as u32 <= tolerance {
                    g.set_index(i, true);
                }
            }
            let proj = project_grid(&g, &cams[k], masks[k].width(), masks[k].height());
            let inter = proj.count_ones() - proj.difference(&masks[k]).count_ones();
            let union = proj.union(&masks[k]).count_ones();
            if union == 0 {
                0.0
            } else {
                inter as f64 / union as f64
            }
        })
        .collect())
}

/// The pixels a voxel grid covers in a camera's `w x h` image: each occupied voxel's centre
/// projected, with a square of its projected size (half a voxel's width each way, rounded).
pub fn project_grid(g: &VoxelGrid, cam: &Camera, w: u32, h: u32) -> Mask {
    let half = g.voxel_size().max() * 0.5;
    let f = cam.k[(0, 0)].abs().max(cam.k[(1, 1)].abs());
    let mut m = Mask::new(w, h);
    for i in g.occupied() {
        let c = g.centre(g.coords(i));
        let Some((u, v, z)) = cam.project(&c) else {
            continue;
        };
        let r = (f * half / z).max(0.5);
        let (x0, x1) = (
            (u - r).round().max(0.0),
            (u + r).round().min(w as f64 - 1.0),
        );
        let (y0, y1) = (
            (v - r).round().max(0.0),
            (v + r).round().min(h as f64 - 1.0),
        );
        if x0 > x1 || y0 > y1 {
            continue;
        }
        for y in y0 as u32..=y1 as u32 {
            for x in x0 as u32..=x1 as u32 {
                m.set(x, y, true);
            }
        }
    }
    m
}

/// Reference carving, one voxel at a time with no block tests (for checking [`visual_hull`]).
pub fn visual_hull_naive(
    cams: &[Camera],
    masks: &[Mask],
    bounds: Aabb,
    dims: [usize; 3],
    min_views: usize,
) -> Result<VoxelGrid> {
    check_inputs(cams, masks)?;
    let mut g = VoxelGrid::new(dims, bounds, u64::MAX)?;
    let vs = views(cams, masks);
    let e = bounds.max - bounds.min;
    let size = Vector3::new(
        e.x / dims[0] as f64,
        e.y / dims[1] as f64,
        e.z / dims[2] as f64,
    );
    let carver = Carver {
        views: vs,
        min: bounds.min,
        size,
        dims,
        min_views,
        words: Vec::new(),
    };
    let all: Vec<u32> = (0..cams.len() as u32).collect();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                if carver.voxel(x, y, z, &all, 0) {
                    let i = g.index(x, y, z);
                    g.set_index(i, true);
                }
            }
        }
    }
    Ok(g)
}
