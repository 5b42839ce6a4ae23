//! Real photos with a real COLMAP model (testdata/kettle: 28 photos, SIMPLE_RADIAL cameras
//! recorded at 1280x960, photos 312x234): the cameras vt reads are checked against COLMAP's own
//! 2-D observations (points triangulated from them reproject onto them), and the photos as
//! `Dataset::load` fits and undistorts them show the same point alike in every view (the
//! triangulated points land on matching texture), which a camera off by a pixel or two does not.

use std::path::PathBuf;

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};
use vt_fv::colmap::{parse_cameras_text, parse_images_text, views, ColmapImage, View};
use vt_fv::dataset::{CameraFormat, DataOptions, Dataset};
use vt_fv::lens::Lens;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/kettle")
}

fn model() -> (Vec<ColmapImage>, Vec<View>) {
    let cams =
        parse_cameras_text(&std::fs::read_to_string(dir().join("cameras.txt")).unwrap()).unwrap();
    let imgs =
        parse_images_text(&std::fs::read_to_string(dir().join("images.txt")).unwrap()).unwrap();
    let v = views(&cams, &imgs).unwrap();
    let mut imgs = imgs;
    imgs.sort_by_key(|m| m.id);
    (imgs, v)
}

/// A COLMAP observation (corner convention) as vt's ideal normalised coordinates of `v`.
fn normalised(v: &View, x: f64, y: f64, lens: bool) -> (f64, f64) {
    let kinv = v.camera.k.try_inverse().unwrap();
    let n = kinv * Vector3::new(x - 0.5, y - 0.5, 1.0);
    if lens {
        v.lens.undistort(n.x, n.y).unwrap()
    } else {
        (n.x, n.y)
    }
}

/// Projects `p` into `v` through its lens: vt pixel coordinates at the recorded size.
fn project(v: &View, p: &Vector3<f64>, lens: bool) -> Option<(f64, f64)> {
    let c = v.camera.to_camera(p);
    if c.z <= 0.0 {
        return None;
    }
    let (x, y) = if lens {
        v.lens.distort(c.x / c.z, c.y / c.z)
    } else {
        (c.x / c.z, c.y / c.z)
    };
    let q = v.camera.k * Vector3::new(x, y, 1.0);
    Some((q.x, q.y))
}

/// Tracks as (point id, [(view index, x, y)]) with at least 3 views.
/// A 3D point's id and its observations: (view, x, y).
type Track = (u64, Vec<(usize, f64, f64)>);

fn tracks(imgs: &[ColmapImage]) -> Vec<Track> {
    let mut t: std::collections::BTreeMap<u64, Vec<(usize, f64, f64)>> = Default::default();
    for (i, m) in imgs.iter().enumerate() {
        for p in &m.points {
            if let Some(id) = p.point3d {
                t.entry(id).or_default().push((i, p.x, p.y));
            }
        }
    }
    t.into_iter().filter(|(_, o)| o.len() >= 3).collect()
}

/// Linear triangulation (DLT on normalised coordinates, least squares by SVD).
fn triangulate(views: &[View], obs: &[(usize, f64, f64)], lens: bool) -> Vector3<f64> {
    let mut a = Matrix4::zeros();
    for &(i, x, y) in obs {
        let v = &views[i];
        let (nx, ny) = normalised(v, x, y, lens);
        let mut rt = nalgebra::Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&v.camera.r);
        rt.set_column(3, &v.camera.t);
        for row in [rt.row(0) - rt.row(2) * nx, rt.row(1) - rt.row(2) * ny] {
            let r: Vector4<f64> = row.transpose();
            a += r * r.transpose();
        }
    }
    let e = a.symmetric_eigen();
    let h = e.eigenvectors.column(e.eigenvalues.imin()).into_owned();
    Vector3::new(h.x / h.w, h.y / h.w, h.z / h.w)
}

fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Reprojection errors (pixels, recorded size) of every observation of every track.
fn reprojection(views: &[View], tr: &[Track], lens: bool) -> Vec<f64> {
    let mut e = Vec::new();
    for (_, obs) in tr {
        let p = triangulate(views, obs, lens);
        for &(i, x, y) in obs {
            e.push(match project(&views[i], &p, lens) {
                Some((u, v)) => ((u - (x - 0.5)).powi(2) + (v - (y - 0.5)).powi(2)).sqrt(),
                None => f64::INFINITY,
            });
        }
    }
    e
}

#[test]
fn colmap_cameras_reproduce_colmaps_observations() {
    let (imgs, v) = model();
    assert_eq!(v.len(), 28);
    assert!(v
        .iter()
        .all(|v| v.size == (1280, 960) && v.model == "SIMPLE_RADIAL"));
    let tr = tracks(&imgs);
    assert!(tr.len() >= 300, "{} tracks", tr.len());
    let e = reprojection(&v, &tr, true);
    let (med, p95) = (quantile(e.clone(), 0.5), quantile(e.clone(), 0.95));
    eprintln!("kettle: {} tracks, {} observations: reprojection median {med:.3} px, 95th percentile {p95:.3} px", tr.len(), e.len());
    // COLMAP's bundle adjustment leaves under a pixel (linear triangulation here, not its own).
    assert!(med < 1.0 && p95 < 4.0, "median {med}, p95 {p95}");
    // Controls. The lens matters away from the centre: there its removal fits COLMAP's
    // observations better than ignoring it or applying it with the opposite sign.
    let outer = |v: &[View]| {
        let mut e = Vec::new();
        for (_, obs) in &tr {
            let p = triangulate(v, obs, true);
            for &(i, x, y) in obs {
                if (x - 640.0).hypot(y - 480.0) > 350.0 {
                    let (u, w) = project(&v[i], &p, true).unwrap();
                    e.push((u - (x - 0.5)).hypot(w - (y - 0.5)));
                }
            }
        }
        (e.iter().sum::<f64>() / e.len() as f64, e.len())
    };
    let with = |f: f64| -> Vec<View> {
        v.iter()
            .map(|x| {
                let mut y = x.clone();
                if let Lens::Radial { k1, k2 } = x.lens {
                    y.lens = Lens::Radial { k1: k1 * f, k2 };
                }
                y
            })
            .collect()
    };
    let (right, n) = outer(&v);
    let (none, _) = outer(&with(0.0));
    let (flipped, _) = outer(&with(-1.0));
    eprintln!("{n} observations over 350 px from the centre: mean error {right:.3} px with the lens, {none:.3} without, {flipped:.3} with k negated");
    assert!(n > 500 && right < 0.8 * none && none < 0.8 * flipped);
    let inverted: Vec<View> = v
        .iter()
        .map(|x| {
            let mut y = x.clone();
            y.camera.r = x.camera.r.transpose();
            y.camera.t = -(x.camera.r.transpose() * x.camera.t);
            y
        })
        .collect();
    let inv = quantile(reprojection(&inverted, &tr, true), 0.5);
    eprintln!("camera-to-world: median {inv:.3}");
    assert!(inv > 20.0, "camera-to-world: median {inv}");
}

/// Normalised cross-correlation of the 7x7 grey patches around two points.
fn ncc(a: &image::RgbImage, pa: (f64, f64), b: &image::RgbImage, pb: (f64, f64)) -> Option<f64> {
    let patch = |img: &image::RgbImage, (u, v): (f64, f64)| -> Option<Vec<f64>> {
        let (x, y) = (u.round() as i64, v.round() as i64);
        let (w, h) = (img.width() as i64, img.height() as i64);
        if x < 3 || y < 3 || x + 3 >= w || y + 3 >= h {
            return None;
        }
        let mut p = Vec::with_capacity(49);
        for dy in -3..=3 {
            for dx in -3..=3 {
                // Bilinear at the sub-pixel position.
                let (fx, fy) = (u + dx as f64, v + dy as f64);
                let (x0, y0) = (fx.floor(), fy.floor());
                let (ax, ay) = (fx - x0, fy - y0);
                let g = |xx: f64, yy: f64| {
                    let q = img.get_pixel(xx as u32, yy as u32).0;
                    (q[0] as f64 + q[1] as f64 + q[2] as f64) / 3.0
                };
                let top = g(x0, y0) * (1.0 - ax) + g(x0 + 1.0, y0) * ax;
                let bot = g(x0, y0 + 1.0) * (1.0 - ax) + g(x0 + 1.0, y0 + 1.0) * ax;
                p.push(top * (1.0 - ay) + bot * ay);
            }
        }
        let m = p.iter().sum::<f64>() / p.len() as f64;
        p.iter_mut().for_each(|x| *x -= m);
        let n = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        (n > 20.0).then(|| p.into_iter().map(|x| x / n).collect())
    };
    let (x, y) = (patch(a, pa)?, patch(b, pb)?);
    Some(x.iter().zip(&y).map(|(p, q)| p * q).sum())
}

#[test]
fn loaded_kettle_is_fitted_undistorted_and_photo_consistent() {
    let d = Dataset::load(&dir(), &DataOptions::default()).unwrap();
    assert_eq!(d.format, CameraFormat::ColmapText);
    assert_eq!(d.cams.len(), 28);
    assert_eq!(d.size(), (312, 234));
    let notes = d.notes.join("\n");
    assert!(notes.contains("28 of 28 photos differ in size from their camera's recorded size: intrinsics scaled by 0.2437 x 0.2437"), "{notes}");
    assert!(notes.contains("28 of 28 photos resampled"), "{notes}");
    // Every camera looks at one point: the least-squares meeting point of the optical axes lies
    // in front of every camera, within a tenth of its distance of every axis.
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for c in &d.cams {
        let f = c.forward();
        let m = Matrix3::identity() - f * f.transpose();
        a += m;
        b += m * c.centre();
    }
    let meet = a.try_inverse().unwrap() * b;
    for c in &d.cams {
        let to = meet - c.centre();
        let depth = c.to_camera(&meet).z;
        let off_axis = (to - c.forward() * to.dot(&c.forward())).norm();
        assert!(
            depth > 0.0 && off_axis < 0.1 * to.norm(),
            "{}: depth {depth}, {off_axis} off its axis",
            c.name
        );
    }
    // Photo consistency: the points triangulated from COLMAP's observations, projected by the
    // loaded cameras into the loaded photos, show matching texture across views.
    let (imgs, v) = model();
    let tr = tracks(&imgs);
    let score = |shift: f64| {
        let mut s = Vec::new();
        for (_, obs) in &tr {
            let p = triangulate(&v, obs, true);
            for w in obs.windows(2) {
                let (i, j) = (w[0].0, w[1].0);
                let pi = d.cams[i].project(&p).unwrap();
                let pj = d.cams[j].project(&p).unwrap();
                if let Some(c) = ncc(
                    &d.images[i],
                    (pi.0, pi.1),
                    &d.images[j],
                    (pj.0 + shift, pj.1 + shift),
                ) {
                    s.push(c);
                }
            }
        }
        (s.iter().sum::<f64>() / s.len() as f64, s.len())
    };
    let (right, n) = score(0.0);
    let (off, _) = score(1.0);
    eprintln!(
        "kettle photo consistency: mean NCC {right:.3} over {n} pairs; one view 1 px off: {off:.3}"
    );
    assert!(n > 1000, "{n} pairs");
    assert!(
        right > 0.6 && right > off + 0.1,
        "NCC {right} vs shifted {off}"
    );
}

#[test]
fn a_photo_not_a_uniform_rescale_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::create_dir(d.join("images")).unwrap();
    for f in ["cameras.txt", "images.txt"] {
        std::fs::copy(dir().join(f), d.join(f)).unwrap();
    }
    for e in std::fs::read_dir(dir().join("images")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, d.join("images").join(p.file_name().unwrap())).unwrap();
    }
    let name = "2021-05-19 20.24.07.jpg";
    let img = image::open(d.join("images").join(name)).unwrap().to_rgb8();
    let squashed = image::imageops::resize(&img, 312, 200, image::imageops::FilterType::Triangle);
    squashed.save(d.join("images").join(name)).unwrap();
    let e = Dataset::load(d, &DataOptions::default())
        .unwrap_err()
        .to_string();
    assert!(!e.contains('\n'), "{e}");
    assert!(
        e.contains(name) && e.contains("312x200") && e.contains("not a uniform rescale"),
        "{e}"
    );
}
