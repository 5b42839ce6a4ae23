//! Colours for surface voxels no camera sees (B.3): the nearest seen voxel, through a cell grid.

use super::*;

/// Gives every unseen surface voxel the colour of the nearest seen one (SPEC B.3), searching a
/// table of relative offsets sorted by distance, then by a linear scan beyond `radius`.
pub(super) fn fill_unseen(grid: &VoxelGrid, voxels: &mut [SurfaceVoxel], radius: usize) {
    let seen: HashMap<usize, [u8; 3]> = voxels
        .iter()
        .filter(|v| v.seen_by > 0)
        .map(|v| (v.index, v.colour))
        .collect();
    if seen.is_empty() {
        return;
    }
    let r = radius as i64;
    let mut offsets: Vec<(i64, i64, i64)> = Vec::new();
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                if (dx, dy, dz) != (0, 0, 0) && dx * dx + dy * dy + dz * dz <= r * r {
                    offsets.push((dx, dy, dz));
                }
            }
        }
    }
    offsets.sort_by_key(|&(x, y, z)| (x * x + y * y + z * z, z, y, x));
    let cells = SeenCells::new(grid, voxels, 2 * radius.max(1));
    let fills: Vec<(usize, [u8; 3])> = voxels
        .par_iter()
        .enumerate()
        .filter(|(_, v)| v.seen_by == 0)
        .map(|(k, v)| {
            let [x, y, z] = grid.coords(v.index).map(|c| c as i64);
            for &(dx, dy, dz) in &offsets {
                if grid.get(x + dx, y + dy, z + dz) {
                    let j = grid.index((x + dx) as usize, (y + dy) as usize, (z + dz) as usize);
                    if let Some(c) = seen.get(&j) {
                        return (k, *c);
                    }
                }
            }
            (k, cells.nearest([x, y, z]))
        })
        .collect();
    for (k, c) in fills {
        voxels[k].colour = c;
    }
}

/// Seen surface voxels bucketed in cubic cells, for exact nearest-neighbour queries beyond the
/// offset table's radius (searching shells of cells outwards until no closer cell can exist).
struct SeenCells {
    side: i64,
    n: [i64; 3],
    cells: Vec<Vec<([i64; 3], [u8; 3])>>,
}

impl SeenCells {
    fn new(grid: &VoxelGrid, voxels: &[SurfaceVoxel], side: usize) -> Self {
        let side = side as i64;
        let n = grid.dims().map(|d| (d as i64 + side - 1) / side);
        let mut cells = vec![Vec::new(); (n[0] * n[1] * n[2]) as usize];
        for v in voxels.iter().filter(|v| v.seen_by > 0) {
            let c = grid.coords(v.index).map(|c| c as i64);
            let k = ((c[2] / side * n[1] + c[1] / side) * n[0] + c[0] / side) as usize;
            cells[k].push((c, v.colour));
        }
        Self { side, n, cells }
    }

    /// Colour of the seen voxel nearest to `p` (ties: first found); callers ensure one exists.
    fn nearest(&self, p: [i64; 3]) -> [u8; 3] {
        let home = p.map(|c| c / self.side);
        let mut best = (i64::MAX, [0u8; 3]);
        let reach = self.n.iter().copied().max().unwrap_or(1);
        for r in 0..=reach {
            // Every voxel in shell r is at least (r - 1) * side away.
            let lower = ((r - 1).max(0) * self.side).pow(2);
            if lower > best.0 {
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
                        for &(c, col) in &self.cells[k] {
                            let d =
                                (c[0] - p[0]).pow(2) + (c[1] - p[1]).pow(2) + (c[2] - p[2]).pow(2);
                            if d < best.0 {
                                best = (d, col);
                            }
                        }
                    }
                }
            }
        }
        best.1
    }
}
