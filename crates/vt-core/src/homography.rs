//! Plane homographies (A-3 `H_(p,p')`, B-1 `H_(p,q)`): the type, and estimation from point pairs
//! by Hartley-normalised DLT with SVD, refined by Levenberg-Marquardt on the transfer error.
//!
//! Invariant of [`Homography`]: its matrix is finite and invertible (relative smallest singular
//! value above [`Homography::MIN_CONDITION`]), and the inverse is stored beside it, so mapping
//! either way never fails except at the line at infinity.

use nalgebra::{DMatrix, Matrix3, SMatrix, SVector, Vector3};

type Vec9 = SVector<f64, 9>;
type Matrix9 = SMatrix<f64, 9, 9>;

use crate::{Error, Result};

/// A 2-D point in pixels, origin top-left, pixel centres at integers.
pub type Point = nalgebra::Point2<f64>;

/// An invertible 3x3 projective map, `x' ~ H x`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    m: Matrix3<f64>,
    inv: Matrix3<f64>,
}

impl Homography {
    /// Smallest accepted ratio of smallest to largest singular value.
    pub const MIN_CONDITION: f64 = 1e-13;

    /// The identity map.
    pub fn identity() -> Self {
        Self {
            m: Matrix3::identity(),
            inv: Matrix3::identity(),
        }
    }

    /// A homography from its matrix; fails for a non-finite or (numerically) singular matrix.
    /// The matrix is scaled to unit Frobenius norm with a non-negative last element.
    pub fn from_matrix(m: Matrix3<f64>) -> Result<Self> {
        if m.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "homography matrix {:?}",
                m.as_slice()
            )));
        }
        let norm = m.norm();
        if norm == 0.0 {
            return Err(Error::SingularHomography("zero matrix".into()));
        }
        let sign = if m[(2, 2)] < 0.0 { -1.0 } else { 1.0 };
        let m = m * (sign / norm);
        let sv = m.singular_values();
        let (smax, smin) = (sv.max(), sv.min());
        let ratio = smin / smax;
        // NaN (a NaN matrix slipped past) fails too.
        if ratio.is_nan() || ratio <= Self::MIN_CONDITION {
            return Err(Error::SingularHomography(format!(
                "singular values {smax:.3e} .. {smin:.3e}, ratio {:.3e} below {:.0e}",
                smin / smax,
                Self::MIN_CONDITION
            )));
        }
        let inv = m
            .try_inverse()
            .ok_or_else(|| Error::SingularHomography("not invertible".into()))?;
        if inv.iter().any(|v| !v.is_finite()) {
            return Err(Error::SingularHomography("inverse is not finite".into()));
        }
        Ok(Self { m, inv })
    }

    /// A pure translation.
    pub fn translation(tx: f64, ty: f64) -> Self {
        Self::from_matrix(Matrix3::new(1.0, 0.0, tx, 0.0, 1.0, ty, 0.0, 0.0, 1.0))
            .expect("a translation is always invertible")
    }

    /// The matrix, scaled so that its last element is 1 when that element is not tiny
    /// (the familiar form), else to unit norm.
    pub fn matrix(&self) -> Matrix3<f64> {
        let h22 = self.m[(2, 2)];
        if h22.abs() > 1e-12 * self.m.norm() {
            self.m / h22
        } else {
            self.m
        }
    }

    /// The inverse map.
    pub fn inverse(&self) -> Homography {
        Self::from_matrix(self.inv).unwrap_or(Homography {
            m: self.inv,
            inv: self.m,
        })
    }

    /// `self` after `first`: maps `x` to `self(first(x))`.
    pub fn after(&self, first: &Homography) -> Result<Homography> {
        Self::from_matrix(self.m * first.m)
    }

    /// Maps a point; `None` on (or numerically at) the line at infinity.
    #[inline]
    pub fn apply(&self, p: Point) -> Option<Point> {
        map(&self.m, p)
    }

    /// Maps a point by the inverse.
    #[inline]
    pub fn apply_inverse(&self, p: Point) -> Option<Point> {
        map(&self.inv, p)
    }

    /// The raw (unit-norm) matrix and inverse, for tight loops.
    pub fn raw(&self) -> (&Matrix3<f64>, &Matrix3<f64>) {
        (&self.m, &self.inv)
    }

    /// Root-mean-square transfer error `sqrt(mean ||dst_i - H src_i||^2)`; infinite if a point
    /// maps to infinity.
    pub fn rms_error(&self, src: &[Point], dst: &[Point]) -> f64 {
        let mut sum = 0.0;
        for (s, d) in src.iter().zip(dst) {
            match self.apply(*s) {
                Some(p) => sum += (p - d).norm_squared(),
                None => return f64::INFINITY,
            }
        }
        (sum / src.len().max(1) as f64).sqrt()
    }

    /// Estimates `H` with `dst ~ H src` from K >= 4 pairs (see [`HomographyFit`]).
    pub fn from_correspondences(src: &[Point], dst: &[Point]) -> Result<HomographyFit> {
        estimate(src, dst)
    }
}

#[inline]
fn map(m: &Matrix3<f64>, p: Point) -> Option<Point> {
    let v = m * Vector3::new(p.x, p.y, 1.0);
    let scale = m[(2, 0)].abs() * p.x.abs() + m[(2, 1)].abs() * p.y.abs() + m[(2, 2)].abs();
    if v.z.abs() <= 1e-14 * scale || !v.z.is_finite() {
        return None;
    }
    Some(Point::new(v.x / v.z, v.y / v.z))
}

/// An estimated homography and how well it explains its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomographyFit {
    /// The homography, `dst ~ H src`.
    pub homography: Homography,
    /// RMS transfer error in pixels (see [`Homography::rms_error`]).
    pub rms: f64,
}

/// Checks shared by every estimator: same count, at least `min` points, all finite,
/// no duplicates, not all on one line (in either image).
pub(crate) fn check_points(src: &[Point], dst: &[Point], min: usize, what: &str) -> Result<()> {
    check_named_points(src, dst, min, what, ("source", "destination"))
}

/// [`check_points`] with the two sides named in messages (e.g. "view 0", "view 1").
pub(crate) fn check_named_points(
    src: &[Point],
    dst: &[Point],
    min: usize,
    what: &str,
    names: (&str, &str),
) -> Result<()> {
    if src.len() != dst.len() {
        return Err(Error::DegeneratePoints(format!(
            "{} {} points but {} {} points",
            src.len(),
            names.0,
            dst.len(),
            names.1
        )));
    }
    if src.len() < min {
        return Err(Error::DegeneratePoints(format!(
            "{what} needs at least {min} point pairs, got {}",
            src.len()
        )));
    }
    for (side, pts) in [(names.0, src), (names.1, dst)] {
        for (i, p) in pts.iter().enumerate() {
            if !p.x.is_finite() || !p.y.is_finite() {
                return Err(Error::NonFinite(format!(
                    "{side}: point {i} ({}, {})",
                    p.x, p.y
                )));
            }
        }
        let spread = spread(pts);
        for i in 0..pts.len() {
            for j in i + 1..pts.len() {
                if (pts[i] - pts[j]).norm() <= 1e-9 * spread.max(1e-300) {
                    return Err(Error::DegeneratePoints(format!(
                        "{side}: points {i} and {j} coincide at ({}, {})",
                        pts[i].x, pts[i].y
                    )));
                }
            }
        }
        if min >= 3 && collinear(pts) {
            return Err(Error::DegeneratePoints(format!(
                "{side}: all points lie on one line"
            )));
        }
    }
    Ok(())
}

fn spread(pts: &[Point]) -> f64 {
    let c = centroid(pts);
    pts.iter().map(|p| (p - c).norm()).fold(0.0, f64::max)
}

fn centroid(pts: &[Point]) -> Point {
    let n = pts.len() as f64;
    Point::new(
        pts.iter().map(|p| p.x).sum::<f64>() / n,
        pts.iter().map(|p| p.y).sum::<f64>() / n,
    )
}

/// True when the points' second principal extent is below 1e-9 of the first.
fn collinear(pts: &[Point]) -> bool {
    let c = centroid(pts);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = p - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let tr = sxx + syy;
    let det = sxx * syy - sxy * sxy;
    let disc = ((tr * tr / 4.0) - det).max(0.0).sqrt();
    let (l1, l2) = (tr / 2.0 + disc, (tr / 2.0 - disc).max(0.0));
    l1 == 0.0 || (l2 / l1).sqrt() < 1e-9
}

/// Hartley's normalisation: centroid to the origin, mean distance sqrt(2).
pub(crate) fn normalizer(pts: &[Point]) -> Matrix3<f64> {
    let c = centroid(pts);
    let mean = pts.iter().map(|p| (p - c).norm()).sum::<f64>() / pts.len() as f64;
    let s = if mean > 0.0 {
        std::f64::consts::SQRT_2 / mean
    } else {
        1.0
    };
    Matrix3::new(s, 0.0, -s * c.x, 0.0, s, -s * c.y, 0.0, 0.0, 1.0)
}

fn apply_raw(m: &Matrix3<f64>, p: &Point) -> Point {
    let v = m * Vector3::new(p.x, p.y, 1.0);
    Point::new(v.x / v.z, v.y / v.z)
}

fn estimate(src: &[Point], dst: &[Point]) -> Result<HomographyFit> {
    check_points(src, dst, 4, "a homography")?;
    let (ts, td) = (normalizer(src), normalizer(dst));
    // Normalised points: on the stack for up to 8 pairs (the usual K), else on the heap.
    let (mut small_s, mut small_d) = ([Point::origin(); 8], [Point::origin(); 8]);
    let (big_s, big_d): (Vec<Point>, Vec<Point>);
    let (ns, nd): (&[Point], &[Point]) = if src.len() <= 8 {
        for (i, (s, d)) in src.iter().zip(dst).enumerate() {
            small_s[i] = apply_raw(&ts, s);
            small_d[i] = apply_raw(&td, d);
        }
        (&small_s[..src.len()], &small_d[..src.len()])
    } else {
        big_s = src.iter().map(|p| apply_raw(&ts, p)).collect();
        big_d = dst.iter().map(|p| apply_raw(&td, p)).collect();
        (&big_s, &big_d)
    };

    // DLT: two rows per pair. Up to 8 pairs the matrix is a fixed 16x9 (zero rows for missing
    // pairs change nothing) so the renderer's per-viewpoint refits allocate nothing; beyond, a
    // heap matrix padded to at least 9 rows so the SVD yields a full V.
    let rows_of = |i: usize| {
        let (s, d) = (ns[i], nd[i]);
        let (x, y, u, v) = (s.x, s.y, d.x, d.y);
        (
            [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u],
            [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v],
        )
    };
    let (singular, v_t): (Vec9, Matrix9) = if ns.len() <= 8 {
        let mut a = SMatrix::<f64, 16, 9>::zeros();
        for i in 0..ns.len() {
            let (r0, r1) = rows_of(i);
            for j in 0..9 {
                a[(2 * i, j)] = r0[j];
                a[(2 * i + 1, j)] = r1[j];
            }
        }
        let svd = a.svd(false, true);
        (svd.singular_values, svd.v_t.expect("SVD asked for V^T"))
    } else {
        let mut a = DMatrix::<f64>::zeros(2 * ns.len(), 9);
        for i in 0..ns.len() {
            let (r0, r1) = rows_of(i);
            for j in 0..9 {
                a[(2 * i, j)] = r0[j];
                a[(2 * i + 1, j)] = r1[j];
            }
        }
        let svd = a.svd(false, true);
        let v_t = svd.v_t.expect("SVD asked for V^T");
        (
            Vec9::from_column_slice(svd.singular_values.as_slice()),
            Matrix9::from_column_slice(v_t.as_slice()),
        )
    };
    let mut order = [0usize, 1, 2, 3, 4, 5, 6, 7, 8];
    order.sort_by(|&i, &j| singular[i].total_cmp(&singular[j]));
    let (smallest, second) = (singular[order[0]], singular[order[1]]);
    let largest = singular[order[8]];
    // A second (near-)null vector means the points do not pin H down (e.g. 3 of 4 collinear).
    if second <= 1e-10 * largest {
        return Err(Error::DegeneratePoints(format!(
            "the point configuration does not determine a homography (two null directions, \
             singular values {smallest:.2e} and {second:.2e} of {largest:.2e}); \
             are three of four points on one line?"
        )));
    }
    let h = v_t.row(order[0]);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let hn = refine_lm(hn, ns, nd);
    let ti = td
        .try_inverse()
        .expect("normaliser is a similarity, always invertible");
    let homography = Homography::from_matrix(ti * hn * ts).map_err(|e| {
        Error::DegeneratePoints(format!(
            "the point configuration does not determine a homography ({e}); are three of four points on one line?"
        ))
    })?;
    let rms = homography.rms_error(src, dst);
    if !rms.is_finite() {
        return Err(Error::DegeneratePoints(format!(
            "the fitted homography sends a point to infinity (rms {rms})"
        )));
    }
    Ok(HomographyFit { homography, rms })
}

/// Levenberg-Marquardt on the one-sided transfer error in normalised coordinates, with the
/// 9 entries as parameters (the scale freedom is held by re-normalising after each step).
/// Only steps that lower the error are taken, so the result is never worse than the DLT.
fn refine_lm(h0: Matrix3<f64>, src: &[Point], dst: &[Point]) -> Matrix3<f64> {
    let residuals = |h: &Matrix3<f64>| -> Option<f64> {
        let mut sum = 0.0;
        for (s, d) in src.iter().zip(dst) {
            let v = h * Vector3::new(s.x, s.y, 1.0);
            if v.z.abs() < 1e-12 {
                return None;
            }
            sum += (v.x / v.z - d.x).powi(2) + (v.y / v.z - d.y).powi(2);
        }
        Some(sum)
    };
    let mut h = h0 / h0.norm();
    let Some(mut err) = residuals(&h) else {
        return h0;
    };
    let mut lambda = 1e-3;
    for _ in 0..50 {
        if err < 1e-30 {
            break;
        }
        let mut jtj = SMatrix::<f64, 9, 9>::zeros();
        let mut jtr = SVector::<f64, 9>::zeros();
        for (s, d) in src.iter().zip(dst) {
            let p = [s.x, s.y, 1.0];
            let v = h * Vector3::new(s.x, s.y, 1.0);
            let (u, w) = (v.x / v.z, v.y / v.z);
            let mut jx = SVector::<f64, 9>::zeros();
            let mut jy = SVector::<f64, 9>::zeros();
            for k in 0..3 {
                jx[k] = p[k] / v.z;
                jx[6 + k] = -u * p[k] / v.z;
                jy[3 + k] = p[k] / v.z;
                jy[6 + k] = -w * p[k] / v.z;
            }
            let (rx, ry) = (u - d.x, w - d.y);
            jtj += jx * jx.transpose() + jy * jy.transpose();
            jtr += jx * rx + jy * ry;
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj;
            for k in 0..9 {
                a[(k, k)] += lambda * (jtj[(k, k)] + 1e-12);
            }
            let Some(delta) = a.cholesky().map(|c| c.solve(&(-jtr))) else {
                lambda *= 10.0;
                continue;
            };
            let cand = h + Matrix3::from_iterator(delta.iter().copied()).transpose();
            let cand = cand / cand.norm();
            match residuals(&cand) {
                Some(e) if e < err => {
                    let gain = (err - e) / err;
                    h = cand;
                    err = e;
                    lambda = (lambda * 0.3).max(1e-12);
                    improved = gain > 1e-12;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn corners_error(a: &Homography, b: &Homography, w: f64, h: f64) -> f64 {
        [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .iter()
            .map(|&(x, y)| {
                (a.apply(Point::new(x, y)).unwrap() - b.apply(Point::new(x, y)).unwrap()).norm()
            })
            .fold(0.0, f64::max)
    }

    pub(crate) fn arbitrary_homography() -> impl Strategy<Value = Homography> {
        (
            0.7f64..1.4,
            -0.3f64..0.3,
            -0.2f64..0.2,
            -100f64..100.0,
            -100f64..100.0,
            -4e-4f64..4e-4,
            -4e-4f64..4e-4,
        )
            .prop_map(|(s, r, sh, tx, ty, p0, p1)| {
                let m = Matrix3::new(
                    s * r.cos(),
                    -s * r.sin() + sh,
                    tx,
                    s * r.sin(),
                    s * r.cos(),
                    ty,
                    p0,
                    p1,
                    1.0,
                );
                Homography::from_matrix(m).unwrap()
            })
    }

    proptest! {
        #[test]
        fn recovers_a_known_homography_exactly(h in arbitrary_homography(), k in 4usize..9, seed in any::<u32>()) {
            // Points spread over a 640x360 image, from a simple hash of the seed.
            let src: Vec<Point> = (0..k).map(|i| {
                let a = (seed as f64 + i as f64 * 2.399).sin() * 0.5 + 0.5;
                let b = (seed as f64 * 0.37 + i as f64 * 1.7).cos() * 0.5 + 0.5;
                Point::new(40.0 + 560.0 * a, 30.0 + 300.0 * b)
            }).collect();
            let dst: Vec<Point> = src.iter().map(|p| h.apply(*p).unwrap()).collect();
            match Homography::from_correspondences(&src, &dst) {
                Ok(fit) => {
                    prop_assert!(fit.rms < 1e-6, "rms {}", fit.rms);
                    prop_assert!(corners_error(&fit.homography, &h, 640.0, 360.0) < 1e-5);
                }
                // Random points can be (nearly) degenerate; then an error, never garbage.
                Err(e) => prop_assert!(matches!(e, Error::DegeneratePoints(_))),
            }
        }

        #[test]
        fn inverse_composes_to_identity(h in arbitrary_homography(), x in -500f64..500.0, y in -500f64..500.0) {
            let p = Point::new(x, y);
            if let Some(q) = h.apply(p) {
                let back = h.apply_inverse(q).unwrap();
                prop_assert!((back - p).norm() < 1e-6 * (1.0 + p.coords.norm()));
            }
        }
    }

    #[test]
    fn far_from_origin_points_are_stable() {
        let h = Homography::from_matrix(Matrix3::new(
            1.01, 0.02, 5.0, -0.01, 0.99, -3.0, 1e-7, -2e-7, 1.0,
        ))
        .unwrap();
        let src: Vec<Point> = [
            (0.0, 0.0),
            (300.0, 10.0),
            (280.0, 250.0),
            (-20.0, 270.0),
            (150.0, 120.0),
        ]
        .iter()
        .map(|&(x, y)| Point::new(x + 5e4, y + 8e4))
        .collect();
        let dst: Vec<Point> = src.iter().map(|p| h.apply(*p).unwrap()).collect();
        let fit = Homography::from_correspondences(&src, &dst).unwrap();
        assert!(fit.rms < 1e-6, "rms {}", fit.rms);
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let p = |v: &[(f64, f64)]| v.iter().map(|&(x, y)| Point::new(x, y)).collect::<Vec<_>>();
        let sq = p(&[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]);
        let line = p(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0), (3.0, 3.0)]);
        let three_on_line = p(&[(0.0, 0.0), (5.0, 0.0), (10.0, 0.0), (3.0, 7.0)]);
        let dup = p(&[(0.0, 0.0), (0.0, 0.0), (10.0, 10.0), (0.0, 10.0)]);
        let nan = p(&[(0.0, 0.0), (f64::NAN, 0.0), (10.0, 10.0), (0.0, 10.0)]);
        for (name, src, want) in [
            ("collinear", &line, "one line"),
            ("three collinear of four", &three_on_line, "determine"),
            ("duplicate", &dup, "coincide"),
            ("non-finite", &nan, "non-finite"),
            ("too few", &sq[..3].to_vec(), "at least 4"),
        ] {
            let err = Homography::from_correspondences(src, &sq[..src.len()])
                .unwrap_err()
                .to_string();
            assert!(err.contains(want), "{name}: {err}");
        }
        assert!(Homography::from_matrix(Matrix3::zeros()).is_err());
        assert!(
            Homography::from_matrix(Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 1.0))
                .is_err()
        );
        assert!(Homography::from_matrix(Matrix3::new(
            f64::INFINITY,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            1.0
        ))
        .is_err());
    }
}
