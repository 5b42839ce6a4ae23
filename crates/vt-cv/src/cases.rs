//! Inputs shared by the cross-check and the report, so both measure the same cases: the point
//! sets at the numerical extremes used to compare vt-core's and OpenCV's homography estimation.

use nalgebra::Matrix3;
use vt_core::Point;

/// One point-correspondence case.
#[derive(Debug, Clone)]
pub struct PointSet {
    /// What the case is ("6 pts 1e5 px from origin", ...).
    pub name: String,
    /// Points in the first image.
    pub src: Vec<Point>,
    /// Their correspondences.
    pub dst: Vec<Point>,
    /// Input no homography can come from (non-finite, duplicate or too few points): a clear
    /// refusal is the right answer.
    pub degenerate: bool,
}

/// Deterministic noise in [-1, 1) from the workspace's SplitMix64.
pub fn noise(seed: u64, i: u64) -> f64 {
    2.0 * vt_core::rng::unit(vt_core::rng::hash(&[seed, i])) - 1.0
}

/// Points mapped by a 3x3 matrix (homogeneous division, no checks).
pub fn map_points(h: &Matrix3<f64>, pts: &[Point]) -> Vec<Point> {
    pts.iter()
        .map(|p| {
            let v = h * nalgebra::Vector3::new(p.x, p.y, 1.0);
            Point::new(v.x / v.z, v.y / v.z)
        })
        .collect()
}

/// The cross-check's extreme point sets (crates/vt-cv/src/bin/cross-check.rs, `extreme_points`),
/// plus non-finite, duplicate and too-few points.
pub fn extreme_point_sets() -> Vec<PointSet> {
    let base = [
        (0.0, 0.0),
        (300.0, 10.0),
        (280.0, 250.0),
        (-20.0, 270.0),
        (150.0, 120.0),
        (60.0, 200.0),
    ];
    let h = Matrix3::new(1.01, 0.02, 5.0, -0.01, 0.99, -3.0, 1e-7, -2e-7, 1.0);
    let mut cases: Vec<(String, Vec<Point>, Vec<Point>)> = Vec::new();
    let plain: Vec<Point> = base.iter().map(|&(x, y)| Point::new(x, y)).collect();
    cases.push((
        "6 pts, well conditioned".to_string(),
        plain.clone(),
        map_points(&h, &plain),
    ));
    for off in [1e4, 1e5] {
        let src: Vec<Point> = base
            .iter()
            .map(|&(x, y)| Point::new(x + off, y + 0.8 * off))
            .collect();
        let dst = map_points(&h, &src);
        cases.push((
            format!("6 pts {off:.0e} px from origin"),
            src.clone(),
            dst.clone(),
        ));
        cases.push((
            format!("4 pts {off:.0e} px from origin"),
            src[..4].to_vec(),
            dst[..4].to_vec(),
        ));
        let noisy: Vec<Point> = dst
            .iter()
            .enumerate()
            .map(|(i, p)| {
                Point::new(
                    p.x + 0.3 * noise(3, 2 * i as u64),
                    p.y + 0.3 * noise(3, 2 * i as u64 + 1),
                )
            })
            .collect();
        cases.push((format!("6 pts {off:.0e} px, noise 0.3"), src, noisy));
    }
    for eps in [1e-2, 1e-5, 1e-9] {
        let src: Vec<Point> = (0..6)
            .map(|i| Point::new(50.0 * i as f64, 20.0 + 10.0 * i as f64 + eps * noise(5, i)))
            .collect();
        let dst: Vec<Point> = (0..6)
            .map(|i| {
                Point::new(
                    40.0 * i as f64 + 3.0,
                    30.0 + 12.0 * i as f64 + eps * noise(6, i),
                )
            })
            .collect();
        cases.push((format!("near-collinear, {eps:.0e} px off a line"), src, dst));
    }
    for s in [1e-1, 1e-3, 1e-6] {
        let src: Vec<Point> = base
            .iter()
            .map(|&(x, y)| Point::new(320.0 + s * x / 300.0, 180.0 + s * y / 300.0))
            .collect();
        let dst = map_points(&h, &src);
        cases.push((format!("6 pts spread {s:.0e} px"), src, dst));
    }
    for eps in [1e-6, 1e-10] {
        let r = |a: f64| nalgebra::Rotation3::from_euler_angles(a, 0.3 * a, -0.7 * a).into_inner();
        let m = r(0.4) * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, eps)) * r(-0.9);
        let src: Vec<Point> = base
            .iter()
            .map(|&(x, y)| Point::new(x * 1e-3, y * 1e-3))
            .collect();
        let dst = map_points(&m, &src);
        cases.push((format!("nearly singular H (cond {eps:.0e})"), src, dst));
    }
    let dst = map_points(&h, &plain);
    for (name, bad) in [
        ("a NaN coordinate", f64::NAN),
        ("an infinite coordinate", f64::INFINITY),
    ] {
        let mut src = plain.clone();
        src[2].x = bad;
        cases.push((format!("6 pts, {name}"), src, dst.clone()));
    }
    let mut dup = plain[..4].to_vec();
    dup[3] = dup[1];
    cases.push(("4 pts, two identical".into(), dup, dst[..4].to_vec()));
    cases.push((
        "3 pts (too few)".into(),
        plain[..3].to_vec(),
        dst[..3].to_vec(),
    ));
    cases.push(("6 identical pts".into(), vec![plain[1]; 6], vec![dst[1]; 6]));
    let degenerate = [
        "a NaN coordinate",
        "an infinite coordinate",
        "two identical",
        "too few",
        "6 identical pts",
    ];
    cases
        .into_iter()
        .map(|(name, src, dst)| PointSet {
            degenerate: degenerate.iter().any(|d| name.contains(d)),
            name,
            src,
            dst,
        })
        .collect()
}

/// PSNR (dB) of four intermediate views at q = 0.5 between backgrounds `a` and `b` against the
/// real view `truth` between them, all after the same plane (vt-core's automatic registration,
/// B-1's virtual points): the plane warp of eq. (3), a plain 50/50 blend without warping,
/// vt-core's morph ([`vt_core::parallax`]) and OpenCV's DIS morph ([`crate::parallax`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MorphScores {
    /// The plane warp.
    pub plane: f64,
    /// The unwarped 50/50 blend.
    pub blend: f64,
    /// vt-core's morph.
    pub vt: f64,
    /// OpenCV's DIS morph.
    pub cv: f64,
    /// The same on and off the plane, where the truth's disparity is known.
    pub split: Option<PlaneSplit>,
}

/// [`MorphScores`] split by the true depth: pixels on the registration's plane (true disparity
/// within a pixel of the plane's) and off it; pixels of unknown disparity in neither.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneSplit {
    /// Share of the known pixels on the plane.
    pub on_share: f64,
    /// PSNR on the plane: plane warp, vt-core's morph, OpenCV's morph, 50/50 blend.
    pub on: [f64; 4],
    /// The same off the plane.
    pub off: [f64; 4],
}

/// The four intermediate views [`morph_scores`] scores.
#[derive(Debug, Clone)]
pub struct MorphImages {
    /// The plane warp.
    pub plane: image::RgbImage,
    /// vt-core's morph.
    pub vt: image::RgbImage,
    /// OpenCV's DIS morph.
    pub cv: image::RgbImage,
    /// The unwarped 50/50 blend.
    pub blend: image::RgbImage,
}

/// [`MorphScores`] and [`MorphImages`] of one pair (the cross-check's morph rows and the
/// report's depth table). `truth_disparity`: the truth view's disparity map for a rectified,
/// horizontal rig (0 = unknown) and the factor from its values to pixels of disparity between
/// `a` and `b`; it gives the on/off-plane split.
pub fn morph_scores(
    a: &image::RgbImage,
    b: &image::RgbImage,
    truth: &image::RgbImage,
    truth_disparity: Option<(&image::GrayImage, f64)>,
) -> crate::Result<(MorphScores, MorphImages)> {
    use vt_core::register::{register_pair, RegisterParams};
    use vt_core::Homography;
    let (w, h) = a.dimensions();
    let params = RegisterParams::default();
    let reg = register_pair(a, b, None, &params, (0, 1))?;
    let hab = reg.homography;
    let none = |what: &str| vt_core::Error::DegeneratePoints(what.into());
    let xa: Vec<Point> = [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8)]
        .iter()
        .map(|&(u, v)| Point::new(u * f64::from(w), v * f64::from(h)))
        .collect();
    let xb: Vec<Point> = xa
        .iter()
        .map(|p| {
            hab.apply(*p)
                .ok_or_else(|| none("the plane sends a point to infinity"))
        })
        .collect::<Result<_, _>>()?;
    let xq: Vec<Point> = xa
        .iter()
        .zip(&xb)
        .map(|(p, q)| Point::new((p.x + q.x) / 2.0, (p.y + q.y) / 2.0))
        .collect();
    let haq = Homography::from_correspondences(&xa, &xq)?.homography;
    let hbq = Homography::from_correspondences(&xb, &xq)?.homography;
    let bilinear = vt_core::warp::Interpolation::Bilinear;
    let wa = vt_core::warp::warp_rgb(a, &haq, w, h, bilinear);
    let wb = vt_core::warp::warp_rgb(b, &hbq, w, h, bilinear);
    let mean = |x: &image::RgbImage, y: &image::RgbImage| {
        image::RgbImage::from_fn(w, h, |i, j| {
            let (p, q) = (x.get_pixel(i, j).0, y.get_pixel(i, j).0);
            image::Rgb([0, 1, 2].map(|k| (u16::from(p[k]) + u16::from(q[k])).div_ceil(2) as u8))
        })
    };
    let (plane, blend) = (mean(&wa, &wb), mean(a, b));
    // vt-core: the matches of both backgrounds give the search geometry.
    let (ga, gb) = (vt_core::register::grey(a), vt_core::register::grey(b));
    let (fa, fb) = (
        vt_core::register::detect(&ga, &params),
        vt_core::register::detect(&gb, &params),
    );
    let matches: Vec<(Point, Point)> =
        vt_core::register::match_features(&fa, &fb, params.ratio, params.max_distance)
            .into_iter()
            .map(|(i, j)| (fa[i].pos, fb[j].pos))
            .collect();
    let geo = vt_core::parallax::geometry(&matches, &hab, (w, h))
        .ok_or_else(|| none("no parallax off the plane"))?;
    let par = vt_core::parallax::estimate(
        a,
        b,
        &hab,
        &geo,
        &vt_core::parallax::ParallaxParams::default(),
    );
    let vt = vt_core::parallax::morph(a, b, &par, &haq, &hbq, 0.5, w, h);
    let flows = crate::parallax::estimate(a, b, &hab)?;
    let cv = crate::parallax::morph(a, b, &flows, &haq, &hbq, 0.5, w, h)?;
    let psnr = |img: &image::RgbImage, m: Option<&vt_core::mask::Mask>| {
        vt_core::metrics::psnr(img, truth, m)
    };
    let split = match truth_disparity {
        None => None,
        Some((disp, scale)) => {
            // The plane's disparity at the output pixel z: a's point H_aq^-1 z against its
            // image H(.) in b, along x.
            let on_off = |z: (u32, u32)| -> Option<bool> {
                let v = f64::from(disp.get_pixel(z.0, z.1).0[0]);
                if v == 0.0 {
                    return None;
                }
                let pa = haq.apply_inverse(Point::new(f64::from(z.0), f64::from(z.1)))?;
                let pb = hab.apply(pa)?;
                Some((v * scale - (pa.x - pb.x)).abs() <= 1.0)
            };
            let labels: Vec<Option<bool>> = (0..w * h).map(|i| on_off((i % w, i / w))).collect();
            let mask =
                |want: bool| vt_core::mask::Mask::from_index_fn(w, h, |i| labels[i] == Some(want));
            let (on, off) = (mask(true), mask(false));
            let known = labels.iter().filter(|l| l.is_some()).count().max(1);
            let four = |m: &vt_core::mask::Mask| -> crate::Result<[f64; 4]> {
                Ok([
                    psnr(&plane, Some(m))?,
                    psnr(&vt, Some(m))?,
                    psnr(&cv, Some(m))?,
                    psnr(&blend, Some(m))?,
                ])
            };
            Some(PlaneSplit {
                on_share: labels.iter().filter(|l| **l == Some(true)).count() as f64 / known as f64,
                on: four(&on)?,
                off: four(&off)?,
            })
        }
    };
    Ok((
        MorphScores {
            plane: psnr(&plane, None)?,
            blend: psnr(&blend, None)?,
            vt: psnr(&vt, None)?,
            cv: psnr(&cv, None)?,
            split,
        },
        MorphImages {
            plane,
            vt,
            cv,
            blend,
        },
    ))
}

/// What a two-view morph with perfect geometry can show at the view between two others on a
/// rectified horizontal rig (issue #33), from that view's true disparity: each known pixel
/// sampled (bilinear) in both outer views where the disparity puts it.
#[derive(Debug, Clone)]
pub struct DisparityReference {
    /// Per pixel the sample nearer the truth: a reference for what the two views can show (not
    /// a strict bound: exposure differences between the views count against it).
    pub best_of_two: image::RgbImage,
    /// The two samples blended 50/50: a naive morph with perfect geometry.
    pub naive: image::RgbImage,
    /// The pixels both references cover: known disparity, both samples inside their images.
    pub mask: vt_core::mask::Mask,
}

/// [`DisparityReference`] of the view `truth` between `a` (left) and `b` (right): a pixel
/// `(x, y)` with disparity value `v` (0 = unknown) lies at `x + v * scale / 2` in a and at
/// `x - v * scale / 2` in b (`scale`: the factor from values to pixels of disparity between a and
/// b). Elsewhere both images are black.
pub fn disparity_references(
    a: &image::RgbImage,
    b: &image::RgbImage,
    truth: &image::RgbImage,
    disparity: &image::GrayImage,
    scale: f64,
) -> DisparityReference {
    let (w, h) = truth.dimensions();
    let sample = |img: &image::RgbImage, x: f64, y: u32| -> Option<[f64; 3]> {
        if !(0.0..=f64::from(img.width() - 1)).contains(&x) || y >= img.height() {
            return None;
        }
        let x0 = (x.floor() as u32).min(img.width() - 2);
        let t = x - f64::from(x0);
        let (p, q) = (img.get_pixel(x0, y).0, img.get_pixel(x0 + 1, y).0);
        Some([0, 1, 2].map(|k| f64::from(p[k]) * (1.0 - t) + f64::from(q[k]) * t))
    };
    let mut best_of_two = image::RgbImage::new(w, h);
    let mut naive = image::RgbImage::new(w, h);
    let mut known = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let v = f64::from(disparity.get_pixel(x, y).0[0]);
            if v == 0.0 {
                continue;
            }
            let half = v * scale / 2.0;
            let (Some(sa), Some(sb)) = (
                sample(a, f64::from(x) + half, y),
                sample(b, f64::from(x) - half, y),
            ) else {
                continue;
            };
            let t = truth.get_pixel(x, y).0;
            let err =
                |s: &[f64; 3]| -> f64 { (0..3).map(|k| (s[k] - f64::from(t[k])).powi(2)).sum() };
            let best = if err(&sa) <= err(&sb) { sa } else { sb };
            let px = |s: [f64; 3]| image::Rgb(s.map(|c| c.round().clamp(0.0, 255.0) as u8));
            best_of_two.put_pixel(x, y, px(best));
            naive.put_pixel(x, y, px([0, 1, 2].map(|k| (sa[k] + sb[k]) / 2.0)));
            known[(y * w + x) as usize] = true;
        }
    }
    DisparityReference {
        best_of_two,
        naive,
        mask: vt_core::mask::Mask::from_index_fn(w, h, |i| known[i]),
    }
}
