//! Model only what the scene requires: fit translation, similarity, affine and homography to the
//! marked points and keep the simplest that explains them.
//!
//! # The rule (GRIC, Torr 1998)
//! For a model with `k` parameters fitted to `n` pairs with transfer residuals `e_i` (pixels):
//!
//! `GRIC = sum_i e_i^2 / sigma^2 + n d ln(r) + k ln(r n)`, with `r = 4` (a pair is a point in
//! 4-D) and `d = 2` (every model here is a 2-D map).
//!
//! Torr clamps each data term at `2 (r - d) = 4` to be robust to outliers. vt does not: the points
//! are marked by hand, so they are inliers, and with the usual n = 4 the clamp caps any model's
//! data term at 16, below the homography's extra penalty over a translation (`6 ln 16 = 16.6`),
//! so a homography could never be chosen however badly the simpler models fit.
//!
//! `sigma` is the marking noise in pixels ([`ModelParams::sigma`], default 1 px for points
//! clicked by hand). The model with the lowest GRIC summed over all neighbouring view pairs is
//! chosen for the whole scene; ties go to the simpler model. `k` is 2, 4, 6, 8.
//! A homography that the residuals do not need costs `2 ln(4n)` per extra parameter
//! (about 11 for 4 points), so it is chosen only when simpler models leave real error.

use nalgebra::{Matrix3, Matrix4, Matrix6, Vector4, Vector6};
use serde::{Deserialize, Serialize};

use crate::homography::{check_named_points, check_points, Homography, Point};
use crate::{Error, Result};

/// The geometric models, simplest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MotionModel {
    /// `x' = x + t` (2 parameters): cameras translated parallel to a fronto-parallel plane.
    Translation,
    /// Rotation, uniform scale and translation (4 parameters).
    Similarity,
    /// General affine map (6 parameters): a distant plane, weak perspective.
    Affine,
    /// Full projective map (8 parameters).
    Homography,
}

impl MotionModel {
    /// All models, simplest first.
    pub const ALL: [MotionModel; 4] = [
        MotionModel::Translation,
        MotionModel::Similarity,
        MotionModel::Affine,
        MotionModel::Homography,
    ];

    /// Degrees of freedom.
    pub fn dof(self) -> usize {
        match self {
            MotionModel::Translation => 2,
            MotionModel::Similarity => 4,
            MotionModel::Affine => 6,
            MotionModel::Homography => 8,
        }
    }

    /// Lower-case name, as in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            MotionModel::Translation => "translation",
            MotionModel::Similarity => "similarity",
            MotionModel::Affine => "affine",
            MotionModel::Homography => "homography",
        }
    }
}

impl std::str::FromStr for MotionModel {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        MotionModel::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| Error::InvalidParameter {
                name: "model",
                value: s.to_string(),
                why: "expected translation, similarity, affine or homography".into(),
            })
    }
}

impl std::fmt::Display for MotionModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Model-selection parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ModelParams {
    /// Expected marking noise per coordinate, pixels (GRIC's sigma).
    pub sigma: f64,
    /// Use this model instead of selecting one.
    pub force: Option<MotionModel>,
}

impl Default for ModelParams {
    fn default() -> Self {
        Self {
            sigma: 1.0,
            force: None,
        }
    }
}

/// One model fitted to one set of pairs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelFit {
    /// Which model.
    pub model: MotionModel,
    /// The fitted map as a homography matrix, `dst ~ H src`.
    pub homography: Homography,
    /// RMS transfer error, pixels.
    pub rms: f64,
    /// GRIC score (lower is better).
    pub gric: f64,
}

/// Fits `model` to the pairs by linear least squares (translation, similarity, affine; in
/// Hartley-normalised coordinates) or normalised DLT + Levenberg-Marquardt (homography).
pub fn fit_model(model: MotionModel, src: &[Point], dst: &[Point], sigma: f64) -> Result<ModelFit> {
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(Error::InvalidParameter {
            name: "sigma",
            value: sigma.to_string(),
            why: "marking noise must be a positive number of pixels".into(),
        });
    }
    let homography = match model {
        MotionModel::Homography => Homography::from_correspondences(src, dst)?.homography,
        MotionModel::Translation => {
            check_points(src, dst, 1, "a translation")?;
            let n = src.len() as f64;
            let t = src
                .iter()
                .zip(dst)
                .fold(nalgebra::Vector2::zeros(), |acc, (s, d)| acc + (d - s))
                / n;
            Homography::translation(t.x, t.y)
        }
        MotionModel::Similarity => {
            check_points(src, dst, 2, "a similarity")?;
            let (ts, td) = (
                crate::homography::normalizer(src),
                crate::homography::normalizer(dst),
            );
            // Unknowns (a, b, tx, ty): x' = a x - b y + tx, y' = b x + a y + ty.
            let mut ata = Matrix4::<f64>::zeros();
            let mut atb = Vector4::<f64>::zeros();
            for (s, d) in src.iter().zip(dst) {
                let (s, d) = (norm_pt(&ts, s), norm_pt(&td, d));
                let r0 = Vector4::new(s.x, -s.y, 1.0, 0.0);
                let r1 = Vector4::new(s.y, s.x, 0.0, 1.0);
                ata += r0 * r0.transpose() + r1 * r1.transpose();
                atb += r0 * d.x + r1 * d.y;
            }
            let p = ata.lu().solve(&atb).ok_or_else(|| {
                Error::DegeneratePoints("similarity normal equations are singular".into())
            })?;
            let m = Matrix3::new(p[0], -p[1], p[2], p[1], p[0], p[3], 0.0, 0.0, 1.0);
            denormalize(&ts, &td, m)?
        }
        MotionModel::Affine => {
            check_points(src, dst, 3, "an affine map")?;
            let (ts, td) = (
                crate::homography::normalizer(src),
                crate::homography::normalizer(dst),
            );
            let mut ata = Matrix6::<f64>::zeros();
            let mut atb = Vector6::<f64>::zeros();
            for (s, d) in src.iter().zip(dst) {
                let (s, d) = (norm_pt(&ts, s), norm_pt(&td, d));
                let r0 = Vector6::new(s.x, s.y, 1.0, 0.0, 0.0, 0.0);
                let r1 = Vector6::new(0.0, 0.0, 0.0, s.x, s.y, 1.0);
                ata += r0 * r0.transpose() + r1 * r1.transpose();
                atb += r0 * d.x + r1 * d.y;
            }
            let p = ata.lu().solve(&atb).ok_or_else(|| {
                Error::DegeneratePoints("affine normal equations are singular".into())
            })?;
            let m = Matrix3::new(p[0], p[1], p[2], p[3], p[4], p[5], 0.0, 0.0, 1.0);
            denormalize(&ts, &td, m)?
        }
    };
    let rms = homography.rms_error(src, dst);
    if !rms.is_finite() {
        return Err(Error::DegeneratePoints(format!(
            "the fitted {model} sends a point to infinity"
        )));
    }
    let n = src.len() as f64;
    let (r, d) = (4.0f64, 2.0f64);
    let data: f64 = src
        .iter()
        .zip(dst)
        .map(|(s, t)| {
            let e2 =
                (homography.apply(*s).expect("finite rms implies finite map") - t).norm_squared();
            e2 / (sigma * sigma)
        })
        .sum();
    let gric = data + n * d * r.ln() + model.dof() as f64 * (r * n).ln();
    Ok(ModelFit {
        model,
        homography,
        rms,
        gric,
    })
}

fn norm_pt(t: &Matrix3<f64>, p: &Point) -> Point {
    Point::new(t[(0, 0)] * p.x + t[(0, 2)], t[(1, 1)] * p.y + t[(1, 2)])
}

fn denormalize(ts: &Matrix3<f64>, td: &Matrix3<f64>, m: Matrix3<f64>) -> Result<Homography> {
    let ti = td
        .try_inverse()
        .expect("normaliser is a similarity, always invertible");
    Homography::from_matrix(ti * m * ts)
        .map_err(|e| Error::DegeneratePoints(format!("the points give a singular map ({e})")))
}

/// The outcome of selecting one model for a whole scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The chosen model.
    pub model: MotionModel,
    /// Whether it was forced by the user rather than selected.
    pub forced: bool,
    /// GRIC summed over all pairs, per model tried (the forced model alone when forced).
    pub scores: Vec<(MotionModel, f64)>,
    /// The chosen model's fit for each pair, in input order.
    pub fits: Vec<ModelFit>,
    /// The marking noise GRIC scored with, pixels (see [`select_model_for_points`]).
    pub sigma: f64,
}

/// The marking deviation per coordinate that fits' residuals imply, pixels: their RMS over all
/// links, scaled up by the residual degrees of freedom (`2K` measurements a link for K points,
/// the model's `dof` used) and halved, since a residual carries the noise of both views' points.
pub fn implied_sigma(fits: &[ModelFit], points_per_link: f64) -> f64 {
    let Some(first) = fits.first() else {
        return f64::NAN;
    };
    let k2 = 2.0 * points_per_link;
    let dof = first.model.dof() as f64;
    let mean_sq = fits.iter().map(|f| f.rms * f.rms).sum::<f64>() / fits.len() as f64;
    mean_sq.sqrt() * (k2 / (k2 - dof).max(1.0)).sqrt() / 2.0
}

/// Finest marking noise GRIC is given, pixels: below it (points exact to rounding) every model's
/// residual would weigh as an outlier.
pub const MIN_POINT_SIGMA: f64 = 0.1;

/// [`select_model`] for marked points: when the points' own residuals under the most general
/// model imply marking noise under a third of `params.sigma` (the points are far more precise
/// than assumed: exact, or marked with care), GRIC scores with that noise instead (at least
/// [`MIN_POINT_SIGMA`]), so residuals a simpler model leaves are weighed as the misfit they
/// are. On the 5-view tree.avi scene with exact points, `sigma` 1 picked an affine map 0.7 px
/// off the true homography on average (2 px at the corners). Noisier points than assumed keep
/// `params.sigma`.
pub fn select_model_for_points(
    pairs: &[(&[Point], &[Point])],
    params: &ModelParams,
) -> Result<Selection> {
    if params.force.is_none() {
        let general: Result<Vec<ModelFit>> = pairs
            .iter()
            .map(|(s, d)| fit_model(MotionModel::Homography, s, d, params.sigma))
            .collect();
        if let Ok(fits) = general {
            let k = pairs.iter().map(|(s, _)| s.len()).sum::<usize>() as f64
                / pairs.len().max(1) as f64;
            let implied = implied_sigma(&fits, k);
            if implied.is_finite() && implied < params.sigma / 3.0 {
                let sigma = implied.max(MIN_POINT_SIGMA).min(params.sigma);
                return select_model(pairs, &ModelParams { sigma, ..*params });
            }
        }
    }
    select_model(pairs, params)
}

/// Selects one model for all pairs `(src, dst)` (one per neighbouring view pair) by summed GRIC.
/// Models that cannot be fitted (e.g. too few points) are skipped; if none fits, the error of the
/// simplest is returned.
pub fn select_model(pairs: &[(&[Point], &[Point])], params: &ModelParams) -> Result<Selection> {
    // Marked points must pin down the most general model whatever is chosen: at least 4 pairs,
    // finite, distinct, not all on one line. A simpler model is a finding, not an excuse.
    for (i, (s, d)) in pairs.iter().enumerate() {
        let names = (format!("view {i}"), format!("view {}", i + 1));
        check_named_points(s, d, 4, "the marked points", (&names.0, &names.1))?;
    }
    let candidates: Vec<MotionModel> = match params.force {
        Some(m) => vec![m],
        None => MotionModel::ALL.to_vec(),
    };
    let mut best: Option<(f64, MotionModel, Vec<ModelFit>)> = None;
    let mut scores = Vec::new();
    let mut first_err = None;
    for model in candidates {
        let fits: Result<Vec<ModelFit>> = pairs
            .iter()
            .map(|(s, d)| fit_model(model, s, d, params.sigma))
            .collect();
        match fits {
            Ok(fits) => {
                let total: f64 = fits.iter().map(|f| f.gric).sum();
                scores.push((model, total));
                if best.as_ref().is_none_or(|(b, _, _)| total < *b) {
                    best = Some((total, model, fits));
                }
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    match best {
        Some((_, model, fits)) => Ok(Selection {
            model,
            forced: params.force.is_some(),
            scores,
            fits,
            sigma: params.sigma,
        }),
        None => Err(first_err.unwrap_or_else(|| Error::DegeneratePoints("no view pairs".into()))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-Gaussian noise (sum of uniforms) so the test is reproducible.
    fn noise(i: usize, sigma: f64) -> f64 {
        let mut s = (i as u64 + 1).wrapping_mul(0x9E3779B97F4A7C15);
        let mut acc = 0.0;
        for _ in 0..4 {
            s ^= s >> 31;
            s = s.wrapping_mul(0xBF58476D1CE4E5B9);
            acc += (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        acc * sigma * (3.0f64).sqrt()
    }

    fn points(k: usize, seed: usize) -> Vec<Point> {
        (0..k)
            .map(|i| {
                let a = ((seed * 7 + i) as f64 * 2.399).sin() * 0.5 + 0.5;
                let b = ((seed * 3 + i) as f64 * 1.31).cos() * 0.5 + 0.5;
                Point::new(60.0 + 500.0 * a, 40.0 + 280.0 * b)
            })
            .collect()
    }

    fn check(truth: Matrix3<f64>, want: MotionModel) {
        let h = Homography::from_matrix(truth).unwrap();
        for (k, seed) in [(4, 1), (5, 2), (6, 3), (8, 4), (6, 5), (8, 6)] {
            let src = points(k, seed);
            let dst: Vec<Point> = src
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let q = h.apply(*p).unwrap();
                    Point::new(
                        q.x + noise(2 * i + seed * 100, 0.3),
                        q.y + noise(2 * i + 1 + seed * 100, 0.3),
                    )
                })
                .collect();
            // Two view pairs sharing one model, as in a three-view scene.
            let sel = select_model(&[(&src, &dst), (&src, &dst)], &ModelParams::default()).unwrap();
            assert_eq!(sel.model, want, "k={k} seed={seed} scores={:?}", sel.scores);
        }
    }

    #[test]
    fn selects_the_true_model() {
        check(
            Matrix3::new(1.0, 0.0, 37.5, 0.0, 1.0, -2.0, 0.0, 0.0, 1.0),
            MotionModel::Translation,
        );
        check(
            Matrix3::new(0.93, 0.12, 20.0, -0.08, 1.1, 5.0, 0.0, 0.0, 1.0),
            MotionModel::Affine,
        );
        check(
            Matrix3::new(0.95, 0.05, 15.0, -0.03, 1.02, 4.0, 4e-4, -3e-4, 1.0),
            MotionModel::Homography,
        );
    }

    #[test]
    fn precise_points_are_weighed_at_their_own_noise() {
        // A mild perspective (the 5-view tree scene's true H between neighbours): six exact
        // points over 320x240 fit an affine map to a fraction of a pixel, which GRIC at the
        // assumed 1 px marking noise cannot tell from noise. Their own homography residuals say
        // they are exact, so they are weighed at MIN_POINT_SIGMA and the homography is found.
        let truth = Homography::from_matrix(Matrix3::new(
            1.03551, 0.0, -7.63091, -0.00642, 0.99296, 0.39122, -5.0e-5, 0.0, 0.99624,
        ))
        .unwrap();
        let src: Vec<Point> = [
            (255.1, 131.6),
            (182.8, 213.7),
            (103.3, 209.3),
            (53.7, 101.4),
            (138.7, 27.7),
            (212.3, 34.5),
        ]
        .iter()
        .map(|&(x, y)| Point::new(x, y))
        .collect();
        let mark = |sigma: f64| -> Vec<Point> {
            src.iter()
                .enumerate()
                .map(|(i, p)| {
                    let q = truth.apply(*p).unwrap();
                    Point::new(q.x + noise(2 * i, sigma), q.y + noise(2 * i + 1, sigma))
                })
                .collect()
        };
        let exact = mark(0.0);
        let pairs: [(&[Point], &[Point]); 4] = [(&src, &exact); 4];
        let plain = select_model(&pairs, &ModelParams::default()).unwrap();
        assert_eq!(plain.model, MotionModel::Affine, "{:?}", plain.scores);
        let own = select_model_for_points(&pairs, &ModelParams::default()).unwrap();
        assert_eq!(own.model, MotionModel::Homography, "{:?}", own.scores);
        assert_eq!(own.sigma, MIN_POINT_SIGMA);
        // Points as noisy as assumed keep the assumed noise, and GRIC's choice.
        let noisy = mark(1.0);
        let pairs: [(&[Point], &[Point]); 4] = [(&src, &noisy); 4];
        let plain = select_model(&pairs, &ModelParams::default()).unwrap();
        let own = select_model_for_points(&pairs, &ModelParams::default()).unwrap();
        assert_eq!((own.model, own.sigma), (plain.model, 1.0));
        // A forced model is not second-guessed.
        let forced = ModelParams {
            force: Some(MotionModel::Affine),
            ..Default::default()
        };
        let pairs: [(&[Point], &[Point]); 4] = [(&src, &exact); 4];
        let sel = select_model_for_points(&pairs, &forced).unwrap();
        assert_eq!((sel.model, sel.sigma), (MotionModel::Affine, 1.0));
    }

    #[test]
    fn forced_model_is_used_and_reported() {
        let src = points(6, 9);
        let dst: Vec<Point> = src.iter().map(|p| Point::new(p.x + 3.0, p.y)).collect();
        let params = ModelParams {
            force: Some(MotionModel::Homography),
            ..Default::default()
        };
        let sel = select_model(&[(&src, &dst)], &params).unwrap();
        assert_eq!(
            (sel.model, sel.forced, sel.scores.len()),
            (MotionModel::Homography, true, 1)
        );
        assert!(sel.fits[0].rms < 1e-6);
        assert_eq!(
            "affine".parse::<MotionModel>().unwrap(),
            MotionModel::Affine
        );
        assert!("projective".parse::<MotionModel>().is_err());
    }
}
