//! The background beyond the plane: vt-core's dense parallax and morph against OpenCV's DIS
//! optical-flow morph, both after the same plane (vt-core's automatic registration), both
//! scored against held-out real views (Middlebury 2005/2006: the even views in, the odd views
//! the truth at q = 0.5, 1.5, 2.5), beside the plane warp of eq. (3) alone.

#[allow(unused_imports)]
use super::*;

use vt_core::parallax::{direction_and_range, ParallaxParams};
use vt_core::register::{register_pair, RegisterParams};

fn load(scene: &str, view: usize) -> Result<RgbImage> {
    load_png(
        &testdata()
            .join("middlebury-line")
            .join(scene)
            .join(format!("view{view}.png")),
    )
}

/// PSNR of the plane warp, vt-core's morph and OpenCV's at q = k + 0.5 between views 2k and
/// 2k + 2, against view 2k + 1.
fn scores(scene: &str, k: usize) -> Result<(f64, f64, f64)> {
    let (a, b, truth) = (
        load(scene, 2 * k)?,
        load(scene, 2 * k + 2)?,
        load(scene, 2 * k + 1)?,
    );
    let (w, h) = a.dimensions();
    let params = RegisterParams::default();
    let reg = register_pair(&a, &b, None, &params, (0, 1))?;
    let hab = reg.homography;
    // The plane homographies to q = 0.5 through four virtual points (B-1).
    let xa: Vec<Point> = [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8)]
        .iter()
        .map(|&(u, v)| Point::new(u * f64::from(w), v * f64::from(h)))
        .collect();
    let xb: Vec<Point> = xa
        .iter()
        .map(|p| hab.apply(*p).context("the plane sends a point to infinity"))
        .collect::<Result<_>>()?;
    let xq: Vec<Point> = xa
        .iter()
        .zip(&xb)
        .map(|(p, q)| Point::new((p.x + q.x) / 2.0, (p.y + q.y) / 2.0))
        .collect();
    let haq = Homography::from_correspondences(&xa, &xq)?.homography;
    let hbq = Homography::from_correspondences(&xb, &xq)?.homography;
    let wa = vt_core::warp::warp_rgb(&a, &haq, w, h, Interpolation::Bilinear);
    let wb = vt_core::warp::warp_rgb(&b, &hbq, w, h, Interpolation::Bilinear);
    let plane = RgbImage::from_fn(w, h, |x, y| {
        let (p, q) = (wa.get_pixel(x, y).0, wb.get_pixel(x, y).0);
        image::Rgb([0, 1, 2].map(|i| (u16::from(p[i]) + u16::from(q[i])).div_ceil(2) as u8))
    });
    // vt-core: the matches of both backgrounds give the direction and range.
    let (ga, gb) = (vt_core::register::grey(&a), vt_core::register::grey(&b));
    let (fa, fb) = (
        vt_core::register::detect(&ga, &params),
        vt_core::register::detect(&gb, &params),
    );
    let matches: Vec<(Point, Point)> =
        vt_core::register::match_features(&fa, &fb, params.ratio, params.max_distance)
            .into_iter()
            .map(|(i, j)| (fa[i].pos, fb[j].pos))
            .collect();
    let dr = direction_and_range(&matches, &hab).context("no parallax off the plane")?;
    let par = vt_core::parallax::estimate(&a, &b, &hab, dr, &ParallaxParams::default());
    let vt = vt_core::parallax::morph(&a, &b, &par, &haq, &hbq, 0.5, w, h);
    let flows = vt_cv::parallax::estimate(&a, &b, &hab)?;
    let cv = vt_cv::parallax::morph(&a, &b, &flows, &haq, &hbq, 0.5, w, h)?;
    let psnr = |img: &RgbImage| vt_core::metrics::psnr(img, &truth, None);
    Ok((psnr(&plane)?, psnr(&vt)?, psnr(&cv)?))
}

pub(super) fn morphs(t: &mut Table) -> Result<()> {
    // How far OpenCV's DIS morph may be ahead. On Reindeer it is (29.6 against 26.7 dB, mean):
    // large untextured areas, where DIS's variational smoothing fills in better than census
    // costs, and the near paper at the right edge; recorded here as a regression guard until
    // vt-core's correspondence catches up (issue #19).
    for (scene, behind_db) in [("Dolls", 0.0), ("Moebius", 0.0), ("Reindeer", 4.0)] {
        let mut rows = Vec::new();
        for k in 0..3 {
            rows.push(scores(scene, k)?);
        }
        let mean = |f: fn(&(f64, f64, f64)) -> f64| rows.iter().map(f).sum::<f64>() / 3.0;
        let (p, v, c) = (mean(|r| r.0), mean(|r| r.1), mean(|r| r.2));
        t.add(
            "background morph (parallax)",
            &format!("Middlebury {scene}, views 0-2-4-6 -> 1, 3, 5"),
            format!(
                "PSNR mean over q = 0.5, 1.5, 2.5: plane {p:.2} dB, vt-core morph {v:.2} dB, OpenCV DIS morph {c:.2} dB (per q: {:.2?})",
                rows
            ),
            &if behind_db > 0.0 {
                format!("vt-core's morph beats the plane by 1 dB and is within {behind_db} dB of OpenCV's DIS morph (known gap)")
            } else {
                "vt-core's morph beats the plane by 1 dB and OpenCV's DIS morph".to_string()
            },
            v >= p + 1.0 && v >= c - behind_db,
        );
    }
    Ok(())
}
