//! Background alignment by OpenCV's `findTransformECC`, the twin of
//! [`vt_core::align::align_backgrounds`].
//!
//! Both refine an initial homography `H` (view a to view b) so that `b(H x)` matches `a(x)` over
//! a region of a's pixels, on a coarse-to-fine pyramid, invariant to a per-view exposure gain and
//! offset. They differ in criterion and solver, which is why one checks the other: vt-core
//! minimises the squared error after a least-squares gain and offset (Gauss-Newton, damped);
//! OpenCV maximises the enhanced correlation coefficient (Evangelidis and Psarakis 2008), which is
//! invariant to gain and offset by construction. Here the pyramid is `pyrDown` (level-l pixel
//! `x` sits at full-resolution `2^l x`), the region is resized by nearest neighbour, and ECC runs
//! at each level from the level above's result. ECC's own pre-blur is off (`gaussFiltSize` 1):
//! blurring both images with one isotropic kernel does not commute with a strongly
//! foreshortening warp, and on the real graf pair (H1to3p) the default 5 moved ECC's optimum
//! from 0.54 px to 0.82 px of the published homography (mean over the overlap; vt-core 0.33 px).
//!
//! ECC has no similarity model (its `MOTION_EUCLIDEAN` has no scale), so
//! [`MotionModel::Similarity`] is refused rather than silently run under another model.

use image::RgbImage;
use nalgebra::Matrix3;
use opencv::core::{self, Mat, Size, TermCriteria, CV_32F};
use opencv::imgproc;
use opencv::prelude::*;
use opencv::video;
use vt_core::align::AlignParams;
use vt_core::model::MotionModel;
use vt_core::{Homography, Mask};

use crate::convert::{mask_to_mat, rgb_view};
use crate::error::{Context, Error, Result};

/// What ECC found.
#[derive(Debug, Clone, Copy)]
pub struct EccAlignment {
    /// The refined homography (a to b).
    pub homography: Homography,
    /// The enhanced correlation coefficient at full resolution (1 = a perfect match up to gain
    /// and offset), as `findTransformECC` returns it.
    pub correlation: f64,
}

/// Refines `init` (view a to view b) over `region` (a's pixels) by `findTransformECC` on a
/// pyramid of `params.levels` levels, with at most `params.iterations` iterations per level
/// (`params.max_pixels` is vt-core's subsampling and has no OpenCV counterpart: ECC uses every
/// region pixel).
pub fn align_backgrounds(
    a: &RgbImage,
    b: &RgbImage,
    init: &Homography,
    region: &Mask,
    model: MotionModel,
    params: &AlignParams,
) -> Result<EccAlignment> {
    vt_core::align::check_inputs(a, b, region)?;
    let motion = match model {
        MotionModel::Translation => video::MOTION_TRANSLATION,
        MotionModel::Affine => video::MOTION_AFFINE,
        MotionModel::Homography => video::MOTION_HOMOGRAPHY,
        MotionModel::Similarity => {
            return Err(Error::NoResult {
                op: "findTransformECC".into(),
                why: "ECC has no similarity model (MOTION_EUCLIDEAN has no scale)".into(),
            })
        }
    };
    let levels = params.levels.clamp(1, 8);
    let mut pyr_a = vec![grey(a)?];
    let mut pyr_b = vec![grey(b)?];
    let mut pyr_m = vec![mask_to_mat(region)?];
    for l in 1..levels {
        let size = pyr_a[l - 1].size().ctx("Mat::size")?;
        if size.width < 32 || size.height < 32 {
            break;
        }
        let (mut da, mut db, mut dm) = (Mat::default(), Mat::default(), Mat::default());
        let down = Size::new((size.width + 1) / 2, (size.height + 1) / 2);
        imgproc::pyr_down(&pyr_a[l - 1], &mut da, down, core::BORDER_DEFAULT).ctx("pyrDown")?;
        imgproc::pyr_down(&pyr_b[l - 1], &mut db, down, core::BORDER_DEFAULT).ctx("pyrDown")?;
        imgproc::resize(
            &pyr_m[l - 1],
            &mut dm,
            down,
            0.0,
            0.0,
            imgproc::INTER_NEAREST,
        )
        .ctx("resize (mask)")?;
        pyr_a.push(da);
        pyr_b.push(db);
        pyr_m.push(dm);
    }
    let criteria = TermCriteria::new(
        core::TermCriteria_COUNT + core::TermCriteria_EPS,
        params.iterations.clamp(1, 10_000) as i32,
        1e-6,
    )
    .ctx("TermCriteria")?;
    let full = init.matrix() / init.matrix()[(2, 2)];
    let mut correlation = f64::NAN;
    let mut h = full;
    for l in (0..pyr_a.len()).rev() {
        let s = f64::from(1u32 << l);
        let to_level = Matrix3::new(1.0 / s, 0.0, 0.0, 0.0, 1.0 / s, 0.0, 0.0, 0.0, 1.0);
        let to_full = Matrix3::new(s, 0.0, 0.0, 0.0, s, 0.0, 0.0, 0.0, 1.0);
        let hl = to_level * h * to_full;
        let mut warp = Mat::new_rows_cols_with_default(3, 3, CV_32F, core::Scalar::all(0.0))
            .ctx("Mat::new (warp)")?;
        for r in 0..3 {
            for c in 0..3 {
                *warp.at_2d_mut::<f32>(r, c).ctx("Mat::at (warp)")? =
                    hl[(r as usize, c as usize)] as f32;
            }
        }
        if motion != video::MOTION_HOMOGRAPHY {
            warp = warp
                .row_bounds(0, 2)
                .ctx("Mat::row_bounds")?
                .try_clone()
                .ctx("clone")?;
        }
        correlation = video::find_transform_ecc(
            &pyr_a[l], &pyr_b[l], &mut warp, motion, criteria, &pyr_m[l], 1,
        )
        .with_ctx(|| format!("findTransformECC (level {l})"))?;
        let mut out = Matrix3::identity();
        for r in 0..warp.rows() {
            for c in 0..3 {
                out[(r as usize, c as usize)] =
                    f64::from(*warp.at_2d::<f32>(r, c).ctx("Mat::at (warp)")?);
            }
        }
        h = to_full * out * to_level;
    }
    let homography = Homography::from_matrix(h).map_err(|e| Error::NoResult {
        op: "findTransformECC".into(),
        why: format!("the refined homography is unusable: {e}"),
    })?;
    Ok(EccAlignment {
        homography,
        correlation,
    })
}

/// The grey image ECC aligns, in f32: the channel mean, as vt-core's alignment uses
/// (`transform` with weights 1/3).
fn grey(img: &RgbImage) -> Result<Mat> {
    let view = rgb_view(img)?;
    let mut f = Mat::default();
    view.convert_to(&mut f, core::CV_32FC3, 1.0, 0.0)
        .ctx("convertTo CV_32FC3")?;
    let weights = Mat::from_slice_2d(&[[1.0f32 / 3.0; 3]]).ctx("Mat::from_slice_2d")?;
    let mut g = Mat::default();
    core::transform(&f, &mut g, &weights).ctx("transform (channel mean)")?;
    Ok(g)
}
