//! Automatic registration through OpenCV, the twin of [`vt_core::register::register_pair`]:
//! what a user gets from the usual thirty lines of OpenCV. ORB features (`ORB::create` with
//! vt-core's feature budget, 8 levels at 1.2, Harris ranking), a brute-force Hamming matcher
//! (`BFMatcher` with `knnMatch`, k = 2: vt-core's ratio test and mutual-best rule), then
//! `findHomography` with RANSAC at vt-core's threshold. No sub-pixel refinement: OpenCV's ORB
//! keypoints sit at pyramid-level pixels, as vt-core's do before `refine_inliers`.

use image::RgbImage;
use nalgebra::Matrix3;
use opencv::calib3d;
use opencv::core::{self, DMatch, KeyPoint, Mat, Point2f, Vector};
use opencv::features2d::{self, BFMatcher, ORB};
use opencv::imgproc;
use opencv::prelude::*;
use vt_core::register::RegisterParams;
use vt_core::{Error as CoreError, Homography, Point};

use crate::convert::rgb_view;
use crate::error::{Context, Error, Result};

/// What OpenCV's registration found.
#[derive(Debug, Clone)]
pub struct CvRegistration {
    /// `findHomography`'s RANSAC homography (a to b).
    pub homography: Homography,
    /// Keypoints in a and b.
    pub features: (usize, usize),
    /// Matches passing the ratio test and the mutual check.
    pub matches: usize,
    /// RANSAC inliers (the pairs as a's and b's points).
    pub inliers: Vec<(Point, Point)>,
}

fn orb_features(img: &RgbImage, params: &RegisterParams) -> Result<(Vector<KeyPoint>, Mat)> {
    let view = rgb_view(img)?;
    let mut grey = Mat::default();
    imgproc::cvt_color_def(&view, &mut grey, imgproc::COLOR_RGB2GRAY).ctx("cvtColor RGB2GRAY")?;
    let mut orb = ORB::create(
        params.max_features.min(i32::MAX as usize) as i32,
        1.2,
        8,
        31,
        0,
        2,
        features2d::ORB_ScoreType::HARRIS_SCORE,
        31,
        i32::from(params.fast_threshold),
    )
    .ctx("ORB::create")?;
    let mut keypoints = Vector::<KeyPoint>::new();
    let mut descriptors = Mat::default();
    orb.detect_and_compute_def(&grey, &core::no_array(), &mut keypoints, &mut descriptors)
        .ctx("ORB::detectAndCompute")?;
    Ok((keypoints, descriptors))
}

/// Best and second-best matches of every query descriptor among the train descriptors.
fn knn(query: &Mat, train: &Mat) -> Result<Vector<Vector<DMatch>>> {
    let matcher = BFMatcher::new(core::NORM_HAMMING, false).ctx("BFMatcher")?;
    let mut out = Vector::<Vector<DMatch>>::new();
    matcher
        .knn_train_match_def(query, train, &mut out, 2)
        .ctx("BFMatcher::knnMatch")?;
    Ok(out)
}

/// Registers `a` to `b` through OpenCV under vt-core's parameters (feature budget, FAST
/// threshold, ratio, largest distance, RANSAC threshold and iterations). `pair` names the views
/// in errors, as vt-core's does; too few inliers give vt-core's registration error.
pub fn register_pair(
    a: &RgbImage,
    b: &RgbImage,
    params: &RegisterParams,
    pair: (usize, usize),
) -> Result<CvRegistration> {
    let (ka, da) = orb_features(a, params)?;
    let (kb, db) = orb_features(b, params)?;
    let fail = |why: String| -> Error {
        CoreError::Registration {
            pair,
            why: format!("OpenCV: {} and {} features: {why}", ka.len(), kb.len()),
        }
        .into()
    };
    if ka.len() < 4 || kb.len() < 4 {
        return Err(fail("too few features".into()));
    }
    let fwd = knn(&da, &db)?;
    let back = knn(&db, &da)?;
    let best_back: Vec<i32> = back
        .iter()
        .map(|m| m.get(0).map(|d| d.train_idx).unwrap_or(-1))
        .collect();
    let (mut src, mut dst) = (Vector::<Point2f>::new(), Vector::<Point2f>::new());
    for m in fwd.iter() {
        let Ok(best) = m.get(0) else { continue };
        let ok_ratio = match m.get(1) {
            Ok(second) => best.distance < params.ratio * second.distance,
            Err(_) => true,
        };
        let mutual = best_back.get(best.train_idx as usize) == Some(&best.query_idx);
        if ok_ratio && mutual && best.distance <= params.max_distance as f32 {
            src.push(ka.get(best.query_idx as usize).ctx("keypoint")?.pt());
            dst.push(kb.get(best.train_idx as usize).ctx("keypoint")?.pt());
        }
    }
    let matches = src.len();
    if matches < 4 {
        return Err(fail(format!("{matches} matches")));
    }
    let mut mask = Mat::default();
    let h = calib3d::find_homography_ext(
        &src,
        &dst,
        calib3d::RANSAC,
        params.threshold,
        &mut mask,
        params.iterations.min(i32::MAX as usize) as i32,
        0.999,
    )
    .ctx("findHomography RANSAC")?;
    if h.empty() {
        return Err(fail(format!("{matches} matches, no homography")));
    }
    let m = Matrix3::from_fn(|r, c| *h.at_2d::<f64>(r as i32, c as i32).unwrap_or(&f64::NAN));
    let homography = Homography::from_matrix(m).map_err(|e| fail(format!("{e}")))?;
    let flags = mask.data_bytes().ctx("inlier mask")?;
    let inliers: Vec<(Point, Point)> = flags
        .iter()
        .zip(src.iter().zip(dst.iter()))
        .filter(|(f, _)| **f != 0)
        .map(|(_, (s, d))| {
            (
                Point::new(f64::from(s.x), f64::from(s.y)),
                Point::new(f64::from(d.x), f64::from(d.y)),
            )
        })
        .collect();
    if inliers.len() < params.min_inliers {
        return Err(fail(format!(
            "{matches} matches, {} inliers (a verified fit needs {})",
            inliers.len(),
            params.min_inliers
        )));
    }
    Ok(CvRegistration {
        homography,
        features: (ka.len(), kb.len()),
        matches,
        inliers,
    })
}
