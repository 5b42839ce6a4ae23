//! Real data from testdata/: tree.avi, the graf pair with its true homography, temple photos.

#[allow(unused_imports)]
use super::*;

pub(super) fn tree(t: &mut Table) -> Result<()> {
    let path = testdata().join("tree.avi");
    let mut src = vt_io::frames::VideoSource::open(&path)
        .with_context(|| format!("opening {}", path.display()))?;
    let mut frames = Vec::new();
    src.for_each_frame(&mut |_, f| {
        frames.push(f.clone());
        Ok(())
    })?;
    if frames.len() < 30 {
        bail!("{}: only {} frames decoded", path.display(), frames.len());
    }
    let input = format!(
        "tree.avi {}x{} {} frames",
        frames[0].width(),
        frames[0].height(),
        frames.len()
    );
    view_checks(
        t,
        &input,
        &[frames],
        &LoopParams {
            window: 3,
            min_length: 20,
        },
    )?;
    Ok(())
}

pub(super) fn read_h1to3p(path: &Path) -> Result<Matrix3<f64>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let data = text
        .split("<data>")
        .nth(1)
        .and_then(|s| s.split("</data>").next())
        .context("no <data> in H1to3p.xml")?;
    let v: Vec<f64> = data
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .context("H1to3p.xml numbers")?;
    if v.len() != 9 {
        bail!("H1to3p.xml: {} numbers, expected 9", v.len());
    }
    Ok(Matrix3::from_row_slice(&v))
}

pub(super) fn load_png(path: &Path) -> Result<RgbImage> {
    Ok(image::open(path)
        .with_context(|| format!("reading {}", path.display()))?
        .to_rgb8())
}

pub(super) fn graf(t: &mut Table) -> Result<()> {
    let dir = testdata();
    let truth = read_h1to3p(&dir.join("H1to3p.xml"))?;
    let g1 = load_png(&dir.join("graf1.png"))?;
    let g3 = load_png(&dir.join("graf3.png"))?;
    let h = Homography::from_matrix(truth)?;
    let (w, hh) = g3.dimensions();
    let input = format!("graf1 {}x{} by H1to3p", g1.width(), g1.height());
    check_warp_bilinear(t, &input, &g1, &h, w, hh)?;
    let vt_nn = vt_core::warp::warp_rgb(&g1, &h, w, hh, Interpolation::Nearest);
    let cv_nn = vt_cv::warp::warp_rgb(&g1, &h, w, hh, Interpolation::Nearest)?;
    check_identical_rgb(t, "warp RGB nearest", &input, &vt_nn, &cv_nn);
    check_blur(
        t,
        "Gaussian 3x3",
        "graf3 800x640",
        &vt_core::blur::gaussian_blur(&g3, &GaussianParams::default())?,
        &vt_cv::blur::gaussian_blur(&g3, &GaussianParams::default())?,
    );

    // Points over graf1 mapped by the true homography; then with noise.
    let grid: Vec<Point> = (0..5)
        .flat_map(|i| {
            (0..4).map(move |j| Point::new(60.0 + 170.0 * i as f64, 50.0 + 170.0 * j as f64))
        })
        .collect();
    let mapped = map_points(&truth, &grid);
    homography_agreement(t, "graf 20 pts by H1to3p", &grid, &mapped, Some(&truth));
    homography_agreement(
        t,
        "graf 4 pts by H1to3p",
        &[grid[0], grid[3], grid[16], grid[19]],
        &[mapped[0], mapped[3], mapped[16], mapped[19]],
        Some(&truth),
    );
    let noisy: Vec<Point> = mapped
        .iter()
        .enumerate()
        .map(|(i, p)| {
            Point::new(
                p.x + 0.5 * noise(7, 2 * i as u64),
                p.y + 0.5 * noise(7, 2 * i as u64 + 1),
            )
        })
        .collect();
    homography_agreement(
        t,
        "graf 20 pts, noise +-0.5 px",
        &grid,
        &noisy,
        Some(&truth),
    );
    homography_stability(t, "graf 20 pts, noise +-0.5 px", &grid, &noisy);
    homography_stability(t, "graf 20 pts by H1to3p (f64)", &grid, &mapped);
    Ok(())
}

pub(super) fn temple(t: &mut Table) -> Result<()> {
    let dir = testdata().join("templeSparseRing");
    let a = load_png(&dir.join("templeSR0001.png"))?;
    let b = load_png(&dir.join("templeSR0003.png"))?;
    let input = format!("templeSR0001 {}x{}", a.width(), a.height());
    check_blur(
        t,
        "Gaussian 3x3",
        &input,
        &vt_core::blur::gaussian_blur(&a, &GaussianParams::default())?,
        &vt_cv::blur::gaussian_blur(&a, &GaussianParams::default())?,
    );
    let g7 = GaussianParams {
        ksize: 7,
        sigma: 2.5,
    };
    check_blur(
        t,
        "Gaussian 7x7 s2.5",
        &input,
        &vt_core::blur::gaussian_blur(&a, &g7)?,
        &vt_cv::blur::gaussian_blur(&a, &g7)?,
    );
    check_blur_exact(t, &input, &a, &GaussianParams::default())?;
    check_blur_exact(
        t,
        &input,
        &a,
        &GaussianParams {
            ksize: 15,
            sigma: 4.0,
        },
    )?;
    // A mild projective map (rotation, scale, perspective) about the image centre.
    let m = Matrix3::new(0.97, -0.12, 40.0, 0.1, 1.02, -15.0, 8e-5, -5e-5, 1.0);
    let h = Homography::from_matrix(m)?;
    let (w, hh) = a.dimensions();
    check_warp_bilinear(t, &format!("{input} projective"), &a, &h, w, hh)?;
    // Two views as frame and background: a mask on real photos.
    let (ba, bb) = (
        vt_core::blur::gaussian_blur(&a, &GaussianParams::default())?,
        vt_core::blur::gaussian_blur(&b, &GaussianParams::default())?,
    );
    let params = MaskParams {
        threshold: 20,
        open_radius: 2,
        close_radius: 1,
    };
    check_identical_masks(
        t,
        "mask (same blur, open 2 close 1)",
        "templeSR0001 vs 0003",
        &[foreground_mask(&ba, &bb, &params)?],
        &[vt_cv::mask::foreground_mask(&ba, &bb, &params)?],
    );
    Ok(())
}
