//! Homography estimation by OpenCV, mirroring [`vt_core::Homography::from_correspondences`].
//!
//! Four pairs go to `getPerspectiveTransform` (an exact 8x8 solve with `h33 = 1`), more to
//! `findHomography` with method 0 (all points: normalised DLT, then Levenberg-Marquardt on the
//! transfer error). Both take *`f32`* points (`findHomography` converts any input to `CV_32F`),
//! so far from the origin OpenCV loses precision that vt-core (all `f64`) keeps; the
//! cross-check measures that.

use nalgebra::Matrix3;
use opencv::calib3d;
use opencv::core::{self, Mat, Point2f, Vector, DECOMP_LU};
use opencv::imgproc;
use opencv::prelude::*;
use vt_core::homography::HomographyFit;
use vt_core::{Error as CoreError, Homography, Point};

use crate::error::{Context, Error, Result};

/// Estimates `H` with `dst ~ H src` (twin of [`vt_core::Homography::from_correspondences`]):
/// the OpenCV matrix of [`estimate_matrix`], checked by [`Homography::from_matrix`], and its
/// RMS transfer error.
pub fn from_correspondences(src: &[Point], dst: &[Point]) -> Result<HomographyFit> {
    let m = estimate_matrix(src, dst)?;
    let homography = Homography::from_matrix(m).map_err(|e| {
        CoreError::DegeneratePoints(format!("OpenCV's homography is unusable: {e}"))
    })?;
    let rms = homography.rms_error(src, dst);
    if !rms.is_finite() {
        return Err(CoreError::DegeneratePoints(format!(
            "OpenCV's homography sends a point to infinity (rms {rms})"
        ))
        .into());
    }
    Ok(HomographyFit { homography, rms })
}

/// OpenCV's raw matrix (`h33 = 1` as OpenCV returns it), unchecked beyond finiteness, so the
/// cross-check can measure it even where [`Homography::from_matrix`] would refuse it.
/// Fails for fewer than 4 pairs, unequal counts or non-finite points (as vt-core does) and when
/// OpenCV returns an empty matrix (its way of saying "degenerate").
pub fn estimate_matrix(src: &[Point], dst: &[Point]) -> Result<Matrix3<f64>> {
    if src.len() != dst.len() {
        return Err(CoreError::DegeneratePoints(format!(
            "{} source points but {} destination points",
            src.len(),
            dst.len()
        ))
        .into());
    }
    if src.len() < 4 {
        return Err(CoreError::DegeneratePoints(format!(
            "a homography needs at least 4 point pairs, got {}",
            src.len()
        ))
        .into());
    }
    for (side, pts) in [("source", src), ("destination", dst)] {
        if let Some((i, p)) = pts
            .iter()
            .enumerate()
            .find(|(_, p)| !p.x.is_finite() || !p.y.is_finite())
        {
            return Err(
                CoreError::NonFinite(format!("{side}: point {i} ({}, {})", p.x, p.y)).into(),
            );
        }
    }
    let to_cv = |pts: &[Point]| {
        Vector::<Point2f>::from_iter(pts.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)))
    };
    let (s, d) = (to_cv(src), to_cv(dst));
    let (op, m) = if src.len() == 4 {
        let op = "getPerspectiveTransform";
        (
            op,
            imgproc::get_perspective_transform(&s, &d, DECOMP_LU).ctx(op)?,
        )
    } else {
        let op = "findHomography (method 0)";
        (
            op,
            calib3d::find_homography(&s, &d, &mut core::no_array(), 0, 3.0)
                .with_ctx(|| format!("{op}, {} points", src.len()))?,
        )
    };
    mat_to_matrix3(&m, op)
}

/// A 3x3 `CV_64F` mat as a nalgebra matrix; empty or non-finite is [`Error::NoResult`].
pub(crate) fn mat_to_matrix3(m: &Mat, op: &str) -> Result<Matrix3<f64>> {
    if m.empty() || m.rows() != 3 || m.cols() != 3 || m.typ() != core::CV_64F {
        return Err(Error::NoResult {
            op: op.into(),
            why: format!(
                "expected a 3x3 CV_64F matrix, got {}x{} of type {} (degenerate points?)",
                m.rows(),
                m.cols(),
                m.typ()
            ),
        });
    }
    let mut out = Matrix3::zeros();
    for r in 0..3 {
        for c in 0..3 {
            out[(r, c)] = *m.at_2d::<f64>(r as i32, c as i32).ctx("Mat::at_2d")?;
        }
    }
    if out.iter().any(|v| !v.is_finite()) {
        return Err(Error::NoResult {
            op: op.into(),
            why: format!("non-finite matrix {:?}", out.as_slice()),
        });
    }
    Ok(out)
}

/// A nalgebra matrix as a 3x3 `CV_64F` mat.
pub(crate) fn matrix3_to_mat(m: &Matrix3<f64>) -> Result<Mat> {
    let rows: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]));
    Mat::from_slice_2d(&rows).ctx("Mat::from_slice_2d (3x3)")
}
