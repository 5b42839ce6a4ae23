//! The rig's epipolar geometry: the fundamental matrix of two backgrounds from their matches,
//! and the plane homographies it allows.
//!
//! Two views of a static scene taken from two camera positions relate every point by the
//! fundamental matrix `F` (`x_b^T F x_a = 0`): a point's match lies on its epipolar line, and
//! the parallax of points off any plane runs along those lines. A plane's homography is then
//! not free: `H = A - e_b v^T` with `A = [e_b]_x F` and `e_b` the epipole in b (Hartley and
//! Zisserman, result 13.6), three parameters `v` instead of eight. A homography fitted without
//! that constraint to the matches within a few pixels of a plane bends where the matches are
//! few, across the parallax: an intermediate view then shears (issue #33).

use super::*;
use crate::homography::normalizer;
use nalgebra::{Matrix3, Vector3};

fn hom(m: &Matrix3<f64>, p: &Point) -> Vector3<f64> {
    m * Vector3::new(p.x, p.y, 1.0)
}

/// The fundamental matrix through `src -> dst` (at least 8 pairs) by the normalised eight-point
/// algorithm (least squares), rank 2 enforced. None when degenerate.
pub fn eight_point(src: &[Point], dst: &[Point]) -> Option<Matrix3<f64>> {
    let n = src.len().min(dst.len());
    if n < 8 {
        return None;
    }
    let (ts, td) = (normalizer(&src[..n]), normalizer(&dst[..n]));
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (s, d) in src.iter().zip(dst).take(n) {
        let (a, b) = (hom(&ts, s), hom(&td, d));
        let row = SVector::<f64, 9>::from([
            b.x * a.x,
            b.x * a.y,
            b.x,
            b.y * a.x,
            b.y * a.y,
            b.y,
            a.x,
            a.y,
            1.0,
        ]);
        ata += row * row.transpose();
    }
    // The eigenvector of the smallest eigenvalue of A^T A.
    let eig = ata.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    let f = eig.eigenvectors.column(k);
    let fn_ = Matrix3::new(f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8]);
    let svd = fn_.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut sv = svd.singular_values;
    sv[2] = 0.0;
    let f2 = u * Matrix3::from_diagonal(&sv) * vt;
    let f = td.transpose() * f2 * ts;
    let norm = f.norm();
    (norm.is_finite() && norm > 0.0).then(|| f / norm)
}

/// The squared Sampson distance of a pair under `f` (first-order geometric error, px²).
pub fn sampson2(f: &Matrix3<f64>, s: &Point, d: &Point) -> f64 {
    let a = Vector3::new(s.x, s.y, 1.0);
    let b = Vector3::new(d.x, d.y, 1.0);
    let fa = f * a;
    let ftb = f.transpose() * b;
    let e = b.dot(&fa);
    let g = fa.x * fa.x + fa.y * fa.y + ftb.x * ftb.x + ftb.y * ftb.y;
    if g <= 0.0 {
        return f64::INFINITY;
    }
    e * e / g
}

/// A robust fundamental matrix: RANSAC on eight-point samples (Sampson distance under
/// `threshold` px), then least squares on the inliers until they stop changing. None with fewer
/// than 16 inliers.
pub fn fundamental(
    src: &[Point],
    dst: &[Point],
    threshold: f64,
    iterations: usize,
    seed: u64,
) -> Option<(Matrix3<f64>, Vec<bool>)> {
    let n = src.len().min(dst.len());
    if n < 16 {
        return None;
    }
    let t2 = threshold * threshold;
    let flags_of = |f: &Matrix3<f64>| -> Vec<bool> {
        (0..n)
            .map(|i| sampson2(f, &src[i], &dst[i]) <= t2)
            .collect()
    };
    let mut f = best_sample::<8, _>(
        n,
        iterations,
        seed,
        |idx| eight_point(&idx.map(|i| src[i]), &idx.map(|i| dst[i])),
        |f| {
            let count = inliers(&flags_of(f)).count();
            (count, count)
        },
    )?;
    let mut flags = flags_of(&f);
    refit_on_inliers(
        &src[..n],
        &dst[..n],
        &mut f,
        &mut flags,
        eight_point,
        flags_of,
    );
    (inliers(&flags).count() >= 16).then_some((f, flags))
}

/// The epipole in the second image: `e_b` with `F^T e_b = 0`, unit length.
pub fn epipole_b(f: &Matrix3<f64>) -> Vector3<f64> {
    let eig = (f * f.transpose()).symmetric_eigen();
    eig.eigenvectors.column(eig.eigenvalues.imin()).into_owned()
}

/// `d` moved onto its epipolar line `F s` (the nearest point of the line).
pub fn onto_line(f: &Matrix3<f64>, s: &Point, d: &Point) -> Point {
    let l = f * Vector3::new(s.x, s.y, 1.0);
    let g = l.x * l.x + l.y * l.y;
    if g <= 0.0 {
        return *d;
    }
    let e = (l.x * d.x + l.y * d.y + l.z) / g;
    Point::new(d.x - e * l.x, d.y - e * l.y)
}

/// The plane homography allowed by `f` that best fits `src -> dst` (at least 3 pairs, consistent
/// with `f`): `H = A - e_b v^T`, `v` by least squares (Hartley and Zisserman, algorithm 13.1,
/// in normalised coordinates). None when degenerate.
pub fn plane_through(f: &Matrix3<f64>, src: &[Point], dst: &[Point]) -> Option<Matrix3<f64>> {
    let n = src.len().min(dst.len());
    if n < 3 {
        return None;
    }
    let (ts, td) = (normalizer(&src[..n]), normalizer(&dst[..n]));
    let (ts_inv, td_inv) = (ts.try_inverse()?, td.try_inverse()?);
    let fnm = td_inv.transpose() * f * ts_inv;
    let e = epipole_b(&fnm);
    let ex = Matrix3::new(0.0, -e.z, e.y, e.z, 0.0, -e.x, -e.y, e.x, 0.0);
    let a = ex * fnm;
    let mut mtm = Matrix3::<f64>::zeros();
    let mut mtb = Vector3::<f64>::zeros();
    for (s, d) in src.iter().zip(dst).take(n) {
        let (x, xb) = (hom(&ts, s), hom(&td, d));
        let c = xb.cross(&e);
        let cc = c.dot(&c);
        if cc <= 1e-18 {
            continue;
        }
        let b = xb.cross(&(a * x)).dot(&c) / cc;
        mtm += x * x.transpose();
        mtb += b * x;
    }
    let v = mtm.lu().solve(&mtb)?;
    let hn = a - e * v.transpose();
    let h = td_inv * hn * ts;
    let h = h / h[(2, 2)];
    h.iter().all(|v| v.is_finite()).then_some(h)
}

/// A grid of [`PLANE_CELLS`]² cells over the points' bounding box: a plane is scored by the
/// cells its inliers cover before their number, so the plane that spans the scene wins over
/// a cluster of features on one textured thing (as a person marks the dominant plane).
struct Cells {
    x0: f64,
    y0: f64,
    sx: f64,
    sy: f64,
}

/// Cells per side of [`Cells`].
const PLANE_CELLS: usize = 16;

impl Cells {
    fn over(pts: &[Point]) -> Self {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in pts {
            (x0, x1, y0, y1) = (x0.min(p.x), x1.max(p.x), y0.min(p.y), y1.max(p.y));
        }
        let k = PLANE_CELLS as f64;
        Self {
            x0,
            y0,
            sx: k / (x1 - x0).max(1e-9),
            sy: k / (y1 - y0).max(1e-9),
        }
    }

    /// How many cells hold at least one of `pts`.
    fn covered<'a>(&self, pts: impl Iterator<Item = &'a Point>) -> usize {
        let mut seen = [false; PLANE_CELLS * PLANE_CELLS];
        for p in pts {
            let cx = (((p.x - self.x0) * self.sx) as usize).min(PLANE_CELLS - 1);
            let cy = (((p.y - self.y0) * self.sy) as usize).min(PLANE_CELLS - 1);
            seen[cy * PLANE_CELLS + cx] = true;
        }
        seen.iter().filter(|&&b| b).count()
    }
}

/// A robust plane allowed by `f`: RANSAC on three-pair samples of `src -> dst` (transfer error
/// under `threshold` px; the plane whose inliers cover the most cells of a grid over the points,
/// then the most inliers), then least squares on the inliers until they stop changing. Returns
/// the homography and the inlier flags, or None without a finite, invertible map of at least 4
/// inliers.
pub fn plane_ransac(
    f: &Matrix3<f64>,
    src: &[Point],
    dst: &[Point],
    threshold: f64,
    iterations: usize,
    seed: u64,
) -> Option<(Homography, Vec<bool>)> {
    let n = src.len().min(dst.len());
    if n < 4 {
        return None;
    }
    let t2 = threshold * threshold;
    let flags_of = |m: &Matrix3<f64>| -> Vec<bool> {
        (0..n)
            .map(|i| transfer2(m, &src[i], &dst[i]) <= t2)
            .collect()
    };
    let cells = Cells::over(&src[..n]);
    let mut m = best_sample::<3, _>(
        n,
        iterations,
        seed,
        |idx| plane_through(f, &idx.map(|i| src[i]), &idx.map(|i| dst[i])),
        |m| {
            let flags = flags_of(m);
            let count = inliers(&flags).count();
            let covered = cells.covered(inliers(&flags).map(|i| &src[i]));
            (covered * (n + 1) + count, count)
        },
    )?;
    let mut flags = flags_of(&m);
    refit_on_inliers(
        &src[..n],
        &dst[..n],
        &mut m,
        &mut flags,
        |s, d| plane_through(f, s, d),
        flags_of,
    );
    let h = Homography::from_matrix(m).ok()?;
    (inliers(&flags).count() >= 4).then_some((h, flags))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two cameras on a line, points at random depths: F recovered, the planes it allows exact.
    #[test]
    fn fundamental_of_a_sideways_rig() {
        let mut rng = crate::rng::Rng::new(3);
        let (f, cx, cy) = (500.0, 320.0, 240.0);
        let mut src = Vec::new();
        let mut dst = Vec::new();
        for _ in 0..200 {
            let x = rng.range(-300, 300) as f64;
            let y = rng.range(-200, 200) as f64;
            let z = rng.range(800, 2000) as f64;
            let p = |bx: f64, by: f64| Point::new(f * (x - bx) / z + cx, f * (y - by) / z + cy);
            src.push(p(0.0, 0.0));
            dst.push(p(40.0, 3.0));
        }
        let (fm, flags) = fundamental(&src, &dst, 1.0, 2000, 1).expect("F");
        assert!(flags.iter().all(|&b| b));
        for (s, d) in src.iter().zip(&dst) {
            assert!(sampson2(&fm, s, d) < 1e-6);
        }
    }

    /// A rectified rig (cameras 30 units apart along x): a wall at depth 1000 spanning the image
    /// and a cluster of points on a nearer slanted board. The plane allowed by F that covers the
    /// most cells is the wall, a pure shift along x; and every match moved onto its line stays.
    #[test]
    fn the_plane_of_a_rectified_rig_is_a_shift_along_its_lines() {
        let mut rng = crate::rng::Rng::new(9);
        let f = 500.0;
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        let mut push = |x: f64, y: f64, z: f64| {
            src.push(Point::new(f * x / z + 320.0, f * y / z + 240.0));
            dst.push(Point::new(f * (x - 30.0) / z + 320.0, f * y / z + 240.0));
        };
        for _ in 0..120 {
            push(
                rng.range(-600, 600) as f64,
                rng.range(-450, 450) as f64,
                1000.0,
            );
        }
        // More matches on the board than on the wall, in one corner of the image.
        for _ in 0..200 {
            let (x, y) = (rng.range(-100, 0) as f64, rng.range(-80, 0) as f64);
            push(x * 0.5, y * 0.5, 500.0 + 0.5 * y);
        }
        let (fm, _) = fundamental(&src, &dst, 1.0, 4000, 2).expect("F");
        let (h, flags) = plane_ransac(&fm, &src, &dst, 1.0, 4000, 3).expect("plane");
        assert_eq!(flags[..120].iter().filter(|&&b| b).count(), 120);
        let m = h.matrix();
        // x' = x - 15 on the wall, y' = y everywhere.
        for (x, y) in [(0.0, 0.0), (640.0, 0.0), (0.0, 480.0), (640.0, 480.0)] {
            let p = h.apply(Point::new(x, y)).unwrap();
            assert!(
                (p.x - (x - 15.0)).abs() < 1e-6 && (p.y - y).abs() < 1e-6,
                "{m}"
            );
        }
        let moved = onto_line(&fm, &src[150], &Point::new(dst[150].x, dst[150].y + 2.0));
        assert!((moved.y - dst[150].y).abs() < 1e-6 && (moved.x - dst[150].x).abs() < 1e-6);
    }
}
