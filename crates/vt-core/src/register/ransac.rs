//! The robust fit: RANSAC on 4-point homographies with local optimisation.

use super::*;

/// The homography through exactly four pairs (None when degenerate).
pub(super) fn four_point(src: [&Point; 4], dst: [&Point; 4]) -> Option<nalgebra::Matrix3<f64>> {
    // Refuse samples with three nearly collinear points in either image.
    for pts in [&src, &dst] {
        for (i, j, k) in [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)] {
            let (a, b, c) = (pts[i], pts[j], pts[k]);
            let area = ((b - a).x * (c - a).y - (b - a).y * (c - a).x).abs();
            if area < 4.0 {
                return None;
            }
        }
    }
    // Centre and scale for conditioning.
    let norm = |p: [&Point; 4]| {
        let c = (p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0;
        let d = p.iter().map(|q| (q.coords - c).norm()).sum::<f64>() / 4.0;
        let s = std::f64::consts::SQRT_2 / d.max(1e-12);
        (c, s)
    };
    let ((cs, ss), (cd, sd)) = (norm(src), norm(dst));
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut b = SVector::<f64, 8>::zeros();
    for i in 0..4 {
        let (x, y) = ((src[i].x - cs.x) * ss, (src[i].y - cs.y) * ss);
        let (u, v) = ((dst[i].x - cd.x) * sd, (dst[i].y - cd.y) * sd);
        let r = 2 * i;
        a.set_row(
            r,
            &SVector::<f64, 8>::from([x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]).transpose(),
        );
        a.set_row(
            r + 1,
            &SVector::<f64, 8>::from([0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]).transpose(),
        );
        b[r] = u;
        b[r + 1] = v;
    }
    let h = a.lu().solve(&b)?;
    let hn = nalgebra::Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
    let ts = nalgebra::Matrix3::new(ss, 0.0, -ss * cs.x, 0.0, ss, -ss * cs.y, 0.0, 0.0, 1.0);
    let td_inv = nalgebra::Matrix3::new(1.0 / sd, 0.0, cd.x, 0.0, 1.0 / sd, cd.y, 0.0, 0.0, 1.0);
    let m = td_inv * hn * ts;
    m.iter().all(|v| v.is_finite()).then_some(m)
}

#[inline]
pub(super) fn transfer2(m: &nalgebra::Matrix3<f64>, s: &Point, d: &Point) -> f64 {
    let w = m[(2, 0)] * s.x + m[(2, 1)] * s.y + m[(2, 2)];
    if w.abs() < 1e-12 {
        return f64::INFINITY;
    }
    let x = (m[(0, 0)] * s.x + m[(0, 1)] * s.y + m[(0, 2)]) / w;
    let y = (m[(1, 0)] * s.x + m[(1, 1)] * s.y + m[(1, 2)]) / w;
    (x - d.x).powi(2) + (y - d.y).powi(2)
}

fn inliers_of(m: &nalgebra::Matrix3<f64>, src: &[Point], dst: &[Point], t2: f64) -> Vec<bool> {
    src.iter()
        .zip(dst)
        .map(|(s, d)| transfer2(m, s, d) <= t2)
        .collect()
}

/// A robust homography: RANSAC on 4-point samples (adaptive count, confidence 0.999) then
/// local optimisation on the inliers. Returns the homography and the inlier flags, or None when
/// no sample gives a finite, invertible map with at least 4 inliers.
pub fn ransac(
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
    let mut m = best_sample::<4, _>(
        n,
        iterations,
        seed,
        |idx| four_point(idx.map(|i| &src[i]), idx.map(|i| &dst[i])),
        |m| {
            let count = inliers(&inliers_of(m, &src[..n], &dst[..n], t2)).count();
            (count, count)
        },
    )?;
    let mut flags = inliers_of(&m, &src[..n], &dst[..n], t2);
    refit_on_inliers(
        &src[..n],
        &dst[..n],
        &mut m,
        &mut flags,
        |s, d| {
            Homography::from_correspondences(s, d)
                .ok()
                .map(|f| f.homography.matrix())
        },
        |m| inliers_of(m, &src[..n], &dst[..n], t2),
    );
    let h = Homography::from_matrix(m).ok()?;
    (inliers(&flags).count() >= 4).then_some((h, flags))
}

/// RANSAC's hypotheses: samples of `K` distinct pairs of `n`, each made a model by
/// `hypothesis` (None: degenerate, skipped) and scored by `score` as (what is maximised, the
/// inlier count); as many samples as confidence 0.999 needs at the best model's inlier share,
/// at most `iterations`. The best model, None when no sample gave one.
pub(super) fn best_sample<const K: usize, M>(
    n: usize,
    iterations: usize,
    seed: u64,
    hypothesis: impl Fn([usize; K]) -> Option<M>,
    score: impl Fn(&M) -> (usize, usize),
) -> Option<M> {
    let mut rng = crate::rng::Rng::new(seed);
    let mut best: Option<(usize, M)> = None;
    let (mut it, mut need) = (0, iterations);
    while it < need.min(iterations) {
        it += 1;
        let Some(m) = hypothesis(draw::<K>(&mut rng, n)) else {
            continue;
        };
        let (value, count) = score(&m);
        if best.as_ref().is_none_or(|(b, _)| value > *b) {
            best = Some((value, m));
            need = needed(count as f64 / n as f64, K as i32);
        }
    }
    best.map(|(_, m)| m)
}

/// The indices of the set `flags`.
pub(super) fn inliers(flags: &[bool]) -> impl Iterator<Item = usize> + '_ {
    flags.iter().enumerate().filter(|(_, &f)| f).map(|(i, _)| i)
}

/// `K` distinct indices below `n` (`n >= K`).
fn draw<const K: usize>(rng: &mut crate::rng::Rng, n: usize) -> [usize; K] {
    let mut idx = [0usize; K];
    for k in 0..K {
        loop {
            let c = rng.range(0, n as i64 - 1) as usize;
            if !idx[..k].contains(&c) {
                idx[k] = c;
                break;
            }
        }
    }
    idx
}

/// Adaptive RANSAC iteration count at confidence 0.999 for samples of `k` with inlier share `w`
/// (at least 50).
fn needed(w: f64, k: i32) -> usize {
    let p_fail = 1.0 - w.powi(k);
    if p_fail <= 0.0 {
        0
    } else {
        (((0.001f64).ln() / p_fail.ln()).ceil() as usize).max(50)
    }
}

/// Local optimisation of a RANSAC model `m` with inlier `flags`: `fit` on the inliers, the
/// inliers recomputed by `flags_of`, until they stop changing (8 rounds at most); a refit that
/// keeps fewer inliers is not taken.
pub(super) fn refit_on_inliers<M>(
    src: &[Point],
    dst: &[Point],
    m: &mut M,
    flags: &mut Vec<bool>,
    fit: impl Fn(&[Point], &[Point]) -> Option<M>,
    flags_of: impl Fn(&M) -> Vec<bool>,
) {
    let count = |v: &[bool]| inliers(v).count();
    for _ in 0..8 {
        let (s, d): (Vec<Point>, Vec<Point>) = inliers(flags).map(|i| (src[i], dst[i])).unzip();
        let Some(m2) = fit(&s, &d) else {
            break;
        };
        let f2 = flags_of(&m2);
        if count(&f2) < count(flags) {
            break;
        }
        let same = f2 == *flags;
        (*m, *flags) = (m2, f2);
        if same {
            break;
        }
    }
}
