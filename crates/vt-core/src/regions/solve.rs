//! Choosing the labels: the tiles, their temporal and spatial costs, and ICM over loop lengths.

use super::*;

/// One labelling problem: a loop length, its labels, the unary and pairwise costs.
pub struct Problem {
    /// Tiles across and down.
    pub grid: (usize, usize),
    /// Loop length `L`.
    pub length: usize,
    /// The candidate labels.
    pub labels: Vec<Label>,
    /// `unary[tile * labels + l]`: the temporal cost.
    pub unary: Vec<f64>,
    /// Neighbouring tile pairs `(a, b)`, `a < b`.
    pub edges: Vec<(usize, usize)>,
    /// Per edge, the weighted differences of source frame pairs on the edge's strip (shared
    /// by the lengths; see [`Strips`]).
    edge_d: std::sync::Arc<Vec<Vec<f32>>>,
    /// Frames considered.
    n: usize,
    /// The spatial weight.
    lambda: f64,
    /// Per tile, its edges (index, the other tile).
    adj: Vec<Vec<(usize, usize)>>,
}

/// Tiles of `tile_r` reduced pixels over a `size` reduction: each tile's pixel indices.
fn tiles(size: (usize, usize), tile_r: usize) -> ((usize, usize), Vec<Vec<usize>>) {
    let (rw, rh) = size;
    let (cols, rows) = (rw.div_ceil(tile_r), rh.div_ceil(tile_r));
    let mut px = vec![Vec::new(); cols * rows];
    for y in 0..rh {
        for x in 0..rw {
            px[(y / tile_r) * cols + x / tile_r].push(y * rw + x);
        }
    }
    ((cols, rows), px)
}

/// The neighbouring tile pairs and the reduced pixels either side of their shared edge.
fn edge_strips(
    size: (usize, usize),
    grid: (usize, usize),
    tile_r: usize,
) -> Vec<((usize, usize), Vec<usize>)> {
    let (rw, rh) = size;
    let (cols, rows) = grid;
    let mut out = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let a = r * cols + c;
            if c + 1 < cols {
                let xb = (c + 1) * tile_r;
                let strip = (r * tile_r..((r + 1) * tile_r).min(rh))
                    .flat_map(|y| [y * rw + xb - 1, y * rw + xb])
                    .collect();
                out.push(((a, a + 1), strip));
            }
            if r + 1 < rows {
                let yb = (r + 1) * tile_r;
                let strip = (c * tile_r..((c + 1) * tile_r).min(rw))
                    .flat_map(|x| [(yb - 1) * rw + x, yb * rw + x])
                    .collect();
                out.push(((a, a + cols), strip));
            }
        }
    }
    out
}

/// Loop lengths tried: highly divisible lengths up to `max_length`, `max_length` itself, and
/// `own` (the thesis's period) when given.
fn lengths(max_length: usize, own: Option<usize>) -> Vec<usize> {
    let mut v: Vec<usize> = [24, 36, 48, 60, 72, 96, 120, 144, 180, 240, 360, 480, 720]
        .into_iter()
        .filter(|&l| l <= max_length)
        .collect();
    for o in own.into_iter().chain([max_length]) {
        if o >= 2 && o <= max_length && !v.contains(&o) {
            v.push(o);
        }
    }
    v
}

/// Periods usable with loop length `l`: its divisors `p` with `min_period <= p` and room for a
/// start (`1 <= s`, `s + p <= n - 1`).
fn periods(l: usize, min_period: usize, n: usize) -> Vec<usize> {
    (min_period.max(2)..=l)
        .filter(|p| l.is_multiple_of(*p) && p + 2 <= n)
        .collect()
}

/// Per tile and period `p` (indexed by `p`; empty where not asked for): the weighted difference
/// of source frames `i` and `i + p` on the tile, for `i` in `0..n - p`. Shared by every loop
/// length whose periods include `p`.
pub struct Temporal(Vec<Vec<Vec<f32>>>);

impl Temporal {
    /// The differences of `r` tiled by `tile_r` reduced pixels, for the periods `ps`.
    pub fn new(r: &Reduced, tile_r: usize, ps: &[usize]) -> Self {
        let n = r.frames.len();
        let (_, tile_px) = tiles(r.size, tile_r);
        Self(
            tile_px
                .par_iter()
                .map(|px| {
                    let g = Gathered::new(r, px);
                    let mut per = vec![Vec::new(); n];
                    for &p in ps {
                        if p < n {
                            // Frames i and i + p, for every i.
                            let mut d = vec![0.0; n - p];
                            g.diffs(0, 1, p, &mut d);
                            per[p] = d;
                        }
                    }
                    per
                })
                .collect(),
        )
    }
}

impl Problem {
    /// Builds the problem for loop length `length` over `r` (source frames `0..n`), tiles of
    /// `tile_r` reduced pixels, periods at least `min_period`. None if no period fits.
    pub fn new(
        r: &Reduced,
        tile_r: usize,
        length: usize,
        min_period: usize,
        lambda: f64,
        strips: &Strips,
    ) -> Option<Self> {
        let n = r.frames.len();
        let temporal = Temporal::new(r, tile_r, &periods(length, min_period, n));
        Self::with(r, tile_r, length, min_period, lambda, strips, &temporal)
    }

    /// [`Problem::new`] from differences already computed (holding this length's periods).
    pub fn with(
        r: &Reduced,
        tile_r: usize,
        length: usize,
        min_period: usize,
        lambda: f64,
        strips: &Strips,
        temporal: &Temporal,
    ) -> Option<Self> {
        let n = r.frames.len();
        let ps = periods(length, min_period, n);
        if ps.is_empty() {
            return None;
        }
        let labels: Vec<Label> = ps
            .iter()
            .flat_map(|&p| {
                (1..n - p).map(move |s| Label {
                    start: s,
                    period: p,
                })
            })
            .collect();
        let ((cols, rows), _) = tiles(r.size, tile_r);
        let tl = cols * rows;
        // Temporal costs per tile, period and start.
        let unary: Vec<f64> = temporal
            .0
            .par_iter()
            .flat_map_iter(|per| {
                labels
                    .iter()
                    .map(|l| (per[l.period][l.start] + per[l.period][l.start - 1]) as f64)
                    .collect::<Vec<f64>>()
            })
            .collect();
        let mut adj = vec![Vec::new(); tl];
        for (e, &(a, b)) in strips.edges.iter().enumerate() {
            adj[a].push((e, b));
            adj[b].push((e, a));
        }
        Some(Self {
            grid: (cols, rows),
            length,
            labels,
            unary,
            edges: strips.edges.clone(),
            edge_d: strips.d.clone(),
            n,
            lambda,
            adj,
        })
    }

    /// The spatial cost of edge `e` with labels `a` and `b` on its two tiles.
    pub fn pair(&self, e: usize, a: usize, b: usize) -> f64 {
        if a == b {
            return 0.0;
        }
        let (la, lb) = (self.labels[a], self.labels[b]);
        let d = &self.edge_d[e];
        // The pair of frames shown repeats every lcm(pa, pb) frames (a divisor of `L`), so the
        // mean over `L` is the mean over one such cycle.
        let cycle = la.period / gcd(la.period, lb.period) * lb.period;
        let (mut fa, mut fb) = (la.frame(0), lb.frame(0));
        let (ea, eb) = (la.start + la.period, lb.start + lb.period);
        let mut sum = 0f64;
        for _ in 0..cycle {
            sum += d[pair_index(self.n, fa, fb)] as f64;
            fa += 1;
            if fa == ea {
                fa = la.start;
            }
            fb += 1;
            if fb == eb {
                fb = lb.start;
            }
        }
        self.lambda * sum / cycle as f64
    }

    /// The energy of a labelling (one label index per tile).
    pub fn energy(&self, lab: &[usize]) -> f64 {
        let nl = self.labels.len();
        let unary: f64 = lab
            .iter()
            .enumerate()
            .map(|(t, &l)| self.unary[t * nl + l])
            .sum();
        let pair: f64 = self
            .edges
            .iter()
            .enumerate()
            .map(|(e, &(a, b))| self.pair(e, lab[a], lab[b]))
            .sum();
        unary + pair
    }

    /// A lower bound of [`Problem::energy`] over all labellings: each tile's lowest temporal
    /// cost, summed.
    pub fn energy_bound(&self) -> f64 {
        let nl = self.labels.len();
        self.unary
            .chunks(nl)
            .map(|u| u.iter().cloned().fold(f64::INFINITY, f64::min))
            .sum()
    }

    /// The label with the lowest total temporal cost, for every tile (the best single loop
    /// among the labels).
    pub fn single(&self) -> Vec<usize> {
        let nl = self.labels.len();
        let tl = self.unary.len() / nl;
        let best = (0..nl)
            .min_by(|&a, &b| {
                let sa: f64 = (0..tl).map(|t| self.unary[t * nl + a]).sum();
                let sb: f64 = (0..tl).map(|t| self.unary[t * nl + b]).sum();
                sa.total_cmp(&sb)
            })
            .expect("at least one label");
        vec![best; tl]
    }

    /// Each tile's own lowest temporal cost, neighbours ignored.
    pub fn independent(&self) -> Vec<usize> {
        let nl = self.labels.len();
        self.unary
            .chunks(nl)
            .map(|u| {
                (0..nl)
                    .min_by(|&a, &b| u[a].total_cmp(&u[b]))
                    .expect("labels")
            })
            .collect()
    }

    /// Iterated conditional modes from `lab`: each tile in turn takes the label that minimises
    /// its temporal cost plus the spatial costs with its neighbours' current labels, until a
    /// sweep changes nothing or `sweeps` sweeps. Never raises the energy.
    pub fn icm(&self, mut lab: Vec<usize>, sweeps: usize) -> Vec<usize> {
        let nl = self.labels.len();
        // Per tile and neighbour: the neighbour's label the costs were computed for, and the
        // spatial cost of each of this tile's labels against it (recomputed only when the
        // neighbour's label changed).
        let mut cache: Vec<Vec<(usize, Vec<f64>)>> = self
            .adj
            .iter()
            .map(|a| vec![(usize::MAX, Vec::new()); a.len()])
            .collect();
        let mut costs = vec![0f64; nl];
        for _ in 0..sweeps {
            let mut changed = false;
            for t in 0..lab.len() {
                for (j, &(e, o)) in self.adj[t].iter().enumerate() {
                    let slot = &mut cache[t][j];
                    if slot.0 != lab[o] {
                        let first = self.edges[e].0 == t;
                        slot.1 = (0..nl)
                            .map(|l| {
                                if first {
                                    self.pair(e, l, lab[o])
                                } else {
                                    self.pair(e, lab[o], l)
                                }
                            })
                            .collect();
                        slot.0 = lab[o];
                    }
                }
                for (l, c) in costs.iter_mut().enumerate() {
                    *c = self.unary[t * nl + l] + cache[t].iter().map(|(_, v)| v[l]).sum::<f64>();
                }
                let (best, &c) = costs
                    .iter()
                    .enumerate()
                    .min_by(|a, b| a.1.total_cmp(b.1))
                    .expect("labels");
                if best != lab[t] && c < costs[lab[t]] {
                    lab[t] = best;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        lab
    }
}

/// Where the difference of frames `i` and `j` (either order) lies in a [`Strips`] edge's
/// triangle of `n` frames: pairs `i < j` row by row, then one 0 for `i == j`.
#[inline]
fn pair_index(n: usize, i: usize, j: usize) -> usize {
    let (i, j) = if i < j { (i, j) } else { (j, i) };
    if i == j {
        return n * n.saturating_sub(1) / 2;
    }
    // Rows 0..i hold n - 1, n - 2, .., n - i pairs.
    i * (2 * n - i - 1) / 2 + (j - i - 1)
}

/// The edges of a tiling and their frame-pair differences (shared by every loop length).
pub struct Strips {
    /// Neighbouring tiles `(a, b)`.
    pub edges: Vec<(usize, usize)>,
    /// Per edge, the weighted differences on its strip of every frame pair, once each (the
    /// difference is symmetric: [`pair_index`]'s triangle, half an `n x n` matrix).
    d: std::sync::Arc<Vec<Vec<f32>>>,
}

impl Strips {
    /// The strips of `r` tiled by `tile_r` reduced pixels.
    pub fn new(r: &Reduced, tile_r: usize) -> Self {
        let n = r.frames.len();
        let ((cols, rows), _) = tiles(r.size, tile_r);
        let strips = edge_strips(r.size, (cols, rows), tile_r);
        let d = strips
            .par_iter()
            .map(|(_, px)| {
                let g = Gathered::new(r, px);
                // Row i of the triangle: frames i and j, for j in i + 1..n.
                let mut m = vec![0.0; n * n.saturating_sub(1) / 2 + 1];
                let mut at = 0;
                for i in 0..n {
                    let row = n - 1 - i;
                    g.diffs(i, 0, i + 1, &mut m[at..at + row]);
                    at += row;
                }
                m
            })
            .collect();
        Self {
            edges: strips.into_iter().map(|(e, _)| e).collect(),
            d: std::sync::Arc::new(d),
        }
    }
}

/// The reduction and the tile side (full-resolution pixels) the labels of `frame`-sized frames
/// are chosen at. Larger frames are reduced further so that the reduced frames hold at most
/// 32,768 pixels, and their tiles grow with the reduction: a tile keeps its reduced pixels, the
/// grid stays as coarse as at the base size (a 1080p view gets 64-pixel tiles where 320x240
/// gets 16, about 500 tiles either way, not 8,000 whose pairwise costs would not fit).
pub fn reduction((w, h): (u32, u32), params: &RegionParams) -> (u32, u32) {
    let (mut scale, mut tile) = (params.scale, params.tile);
    while (w.div_ceil(scale) * h.div_ceil(scale)) as usize > MAX_REDUCED && tile <= 128 {
        scale *= 2;
        tile *= 2;
    }
    (scale, tile)
}

/// Bytes the label search of [`solve`] holds for `frames` frames of size `dims`: the reduced
/// frames and the edges' frame-pair differences, the two parts that grow with the frames (the
/// rest is per tile and small). About 39 MB for 101 frames at 1080p.
pub fn search_bytes(dims: (u32, u32), frames: usize, params: &RegionParams) -> usize {
    let (scale, tile) = reduction(dims, params);
    let (rw, rh) = (
        dims.0.div_ceil(scale) as usize,
        dims.1.div_ceil(scale) as usize,
    );
    let tile_r = (tile / scale) as usize;
    let (cols, rows) = (rw.div_ceil(tile_r), rh.div_ceil(tile_r));
    let edges = cols.saturating_sub(1) * rows + cols * rows.saturating_sub(1);
    let reduced = frames * rw * rh * 3 * std::mem::size_of::<u16>();
    let pairs = edges * (frames * frames.saturating_sub(1) / 2 + 1) * std::mem::size_of::<f32>();
    reduced + pairs
}

/// Chooses the per-region loop of `frames` (the view's source frames, `first` the number of
/// frames[0]) weighted by the dynamic region `alpha`; `own` is the thesis loop's period (a
/// candidate length), `min_period` the shortest period allowed.
pub fn solve<F: Frames + ?Sized>(
    frames: &F,
    alpha: Option<&image::GrayImage>,
    own: Option<usize>,
    min_period: usize,
    params: &RegionParams,
) -> Result<RegionLoop> {
    params.check()?;
    let started = std::time::Instant::now();
    if frames.count() < 4 {
        return Err(Error::TooFewFrames {
            what: "per-region loops".into(),
            got: frames.count(),
            need: 4,
            why: "a loop needs a few frames".into(),
        });
    }
    let (scale, tile) = reduction(frames.dimensions(), params);
    let r = reduce(frames, alpha, scale);
    let tile_r = (tile / scale) as usize;
    let strips = Strips::new(&r, tile_r);
    // Each loop length is its own problem. Every labelling's energy is at least the sum of its
    // tiles' lowest temporal costs (the spatial costs are not negative), so the lengths are
    // solved in the order of that bound, and one whose bound is no lower than the best energy
    // reached is skipped: its ICM could not do better (the result is that of solving all,
    // the first of equal energies in the order of `lengths` kept).
    let ls = lengths(params.max_length, own);
    let mut all_periods: Vec<usize> = ls
        .iter()
        .flat_map(|&l| periods(l, min_period, r.frames.len()))
        .collect();
    all_periods.sort_unstable();
    all_periods.dedup();
    let temporal = Temporal::new(&r, tile_r, &all_periods);
    let problems: Vec<(usize, Problem, f64)> = ls
        .into_iter()
        .enumerate()
        .filter_map(|(i, l)| {
            let pb = Problem::with(
                &r,
                tile_r,
                l,
                min_period,
                params.spatial as f64,
                &strips,
                &temporal,
            )?;
            let bound = pb.energy_bound();
            Some((i, pb, bound))
        })
        .collect();
    let mut order: Vec<usize> = (0..problems.len()).collect();
    order.sort_by(|&a, &b| problems[a].2.total_cmp(&problems[b].2).then(a.cmp(&b)));
    // (energy, single-label energy, index into problems, labels)
    let mut best: Option<(f64, f64, usize, Vec<usize>)> = None;
    for k in order {
        let (i, pb, bound) = &problems[k];
        if let Some(b) = &best {
            if *bound > b.0 || (*bound == b.0 && *i > problems[b.2].0) {
                continue;
            }
        }
        let single = pb.single();
        let single_e = pb.energy(&single);
        // ICM from the best single label and from each tile's own best label; the lower.
        let indep = pb.independent();
        let (a, b) = rayon::join(
            || {
                let lab = pb.icm(single, params.sweeps);
                (pb.energy(&lab), lab)
            },
            || {
                let lab = pb.icm(indep, params.sweeps);
                (pb.energy(&lab), lab)
            },
        );
        let (e, lab) = if b.0 < a.0 { b } else { a };
        let better = best
            .as_ref()
            .is_none_or(|b| e < b.0 || (e == b.0 && *i < problems[b.2].0));
        if better {
            best = Some((e, single_e, k, lab));
        }
    }
    let best = best.map(|(e, se, k, lab)| (e, se, &problems[k].1, lab));
    let Some((energy, single_energy, pb, lab)) = best else {
        return Err(Error::TooFewFrames {
            what: "per-region loops".into(),
            got: frames.count(),
            need: min_period.max(2) + 2,
            why: "no period of any loop length fits".into(),
        });
    };
    let labels: Vec<Label> = lab.iter().map(|&l| pb.labels[l]).collect();
    let mut periods: Vec<usize> = labels.iter().map(|l| l.period).collect();
    periods.sort_unstable();
    periods.dedup();
    // The periods used all divide the length; the output repeats after their least common
    // multiple, which is all the baked loop needs to hold.
    let length = periods.iter().fold(1, |l, &p| l / gcd(l, p) * p);
    debug_assert!(pb.length.is_multiple_of(length));
    Ok(RegionLoop {
        length,
        tile,
        grid: pb.grid,
        labels,
        energy,
        single_energy,
        periods,
        solve_secs: started.elapsed().as_secs_f64(),
        phase: 0,
        blend: params.blend,
        spread: params.spread,
    })
}

fn gcd(mut a: usize, mut b: usize) -> usize {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::pair_index;

    #[test]
    fn pair_index_walks_the_triangle_in_order() {
        for n in 1..12 {
            let mut next = 0;
            for i in 0..n {
                for j in i + 1..n {
                    assert_eq!(pair_index(n, i, j), next, "{n}: ({i}, {j})");
                    assert_eq!(pair_index(n, j, i), next, "{n}: ({j}, {i})");
                    next += 1;
                }
            }
            for i in 0..n {
                assert_eq!(pair_index(n, i, i), n * (n - 1) / 2, "{n}: diagonal");
            }
        }
    }
}
